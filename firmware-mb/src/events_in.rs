//! Reception bookkeeping of events: gaps in each board's event counter, and the drops the
//! boards report in their `overflow` events.

use x10_microcode::{Event, EventKind};

use crate::diag::MbDiagnostics;

const BOARDS: usize = 128;

/// Per board (by address): the event counter expected next (`None` until the first event),
/// and the cumulative drop count of its last `overflow` event since its boot.
pub(crate) struct EventBook {
    expected: [Option<u8>; BOARDS],
    dropped: [u32; BOARDS],
}

impl EventBook {
    pub(crate) const fn new() -> EventBook {
        EventBook {
            expected: [None; BOARDS],
            dropped: [0; BOARDS],
        }
    }

    /// Accounts for one event: a gap in the board's counter is added to `event_gaps`, the
    /// growth of an overflow's cumulative count to `events_lost`. A `boot` event restarts the
    /// board's counter and its cumulative count. `deferred_reply` and `rejected` carry a
    /// request's sequence number instead of the counter and are not counted here.
    pub(crate) fn received(&mut self, ev: &Event<'_>, diag: &mut MbDiagnostics) {
        let i = usize::from(ev.source.get()) % BOARDS;
        let counted = matches!(
            ev.kind,
            EventKind::PinChange
                | EventKind::AnalogThreshold
                | EventKind::FailsafeTripped
                | EventKind::Overflow
                | EventKind::Boot
        );
        if !counted {
            return;
        }
        if ev.kind == EventKind::Boot {
            if let Some(d) = self.dropped.get_mut(i) {
                *d = 0;
            }
        } else if let Some(Some(expected)) = self.expected.get(i).copied() {
            // Events never overtake each other; a number behind the expected one (a
            // retransmission the board did not know was received) is no gap.
            let gap = ev.seq.wrapping_sub(expected);
            if gap < 128 {
                diag.event_gaps = diag.event_gaps.saturating_add(u32::from(gap));
            }
        }
        if let Some(e) = self.expected.get_mut(i) {
            *e = Some(ev.seq.wrapping_add(1));
        }
        if ev.kind == EventKind::Overflow {
            let lost = match *ev.payload {
                // Cumulative since the board's boot: what grew since the last report.
                [_, _, a, b, c, d, ..] => {
                    let total = u32::from_le_bytes([a, b, c, d]);
                    let last = self.dropped.get(i).copied().unwrap_or(0);
                    if let Some(slot) = self.dropped.get_mut(i) {
                        *slot = total.max(last);
                    }
                    total.saturating_sub(last)
                }
                // A board of an earlier firmware: only the count since its last report.
                [a, b] => u32::from(u16::from_le_bytes([a, b])),
                _ => 0,
            };
            diag.events_lost = diag.events_lost.saturating_add(lost);
        }
    }
}
