//! Reception bookkeeping of events, per board: the event counter expected next (gaps are
//! counted), and the drops the boards report in their `overflow` events. Owns [`EventBook`];
//! the routing of the events themselves is `MbCore::route_event`'s.

use x10_microcode::{Event, EventKind};

use crate::board_set::{board_index, BoardSet, BOARDS};
use crate::diag::MbDiagnostics;

/// Per board (by address): the event counter expected next (known once a first event came:
/// one bit per board), and the low 16 bits of the cumulative drop count of its last
/// `overflow` event since its boot (the growth between two reports is their wrapping
/// difference: right while fewer than 32 768 events are dropped between two reports that
/// arrive; 16 bits rather than 32 keep the book at 416 bytes).
pub(crate) struct EventBook {
    expected: [u8; BOARDS],
    known: BoardSet,
    dropped: [u16; BOARDS],
}

impl EventBook {
    pub(crate) const fn new() -> EventBook {
        EventBook {
            expected: [0; BOARDS],
            known: BoardSet::new(),
            dropped: [0; BOARDS],
        }
    }

    /// Accounts for one event: a gap in the board's counter is added to `event_gaps`, the
    /// growth of an overflow's cumulative count to `events_lost`. A `boot` event restarts the
    /// board's counter and its cumulative count. `deferred_reply` and `rejected` carry a
    /// request's sequence number instead of the counter and are not counted here.
    pub(crate) fn received(&mut self, ev: &Event<'_>, diag: &mut MbDiagnostics) {
        let i = board_index(ev.source);
        let counted = matches!(
            ev.kind,
            EventKind::PinChange
                | EventKind::AnalogThreshold
                | EventKind::FailsafeTripped
                | EventKind::Overflow
                | EventKind::Boot
        ) || (ev.kind == EventKind::Announce && !ev.source.is_unaddressed());
        if !counted {
            return;
        }
        if ev.kind == EventKind::Boot {
            if let Some(d) = self.dropped.get_mut(i) {
                *d = 0;
            }
        } else if let Some(expected) = self
            .expected
            .get(i)
            .copied()
            .filter(|_| self.known.contains(i))
        {
            // Events never overtake each other; a number behind the expected one (a
            // retransmission the board did not know was received) is no gap.
            let gap = ev.seq.wrapping_sub(expected);
            if gap < 128 {
                diag.event_gaps = diag.event_gaps.saturating_add(u32::from(gap));
            }
        }
        if let Some(e) = self.expected.get_mut(i) {
            *e = ev.seq.wrapping_add(1);
        }
        self.known.set(i, true);
        if ev.kind == EventKind::Overflow {
            let lost = match *ev.payload {
                // Cumulative since the board's boot: what grew since the last report.
                [_, _, a, b, _, _, ..] => {
                    // The low 16 bits of the cumulative count (u32 LE on the wire).
                    let total = u16::from_le_bytes([a, b]);
                    let last = self.dropped.get(i).copied().unwrap_or(0);
                    let grown = total.wrapping_sub(last);
                    // A report older than the last one (a duplicate) adds nothing.
                    if grown < 0x8000 {
                        if let Some(slot) = self.dropped.get_mut(i) {
                            *slot = total;
                        }
                        u32::from(grown)
                    } else {
                        0
                    }
                }
                // A board of an earlier firmware: only the count since its last report.
                [a, b] => u32::from(u16::from_le_bytes([a, b])),
                _ => 0,
            };
            diag.events_lost = diag.events_lost.saturating_add(lost);
        }
    }
}
