//! The failsafe keepalive: a daughterboard whose failsafe is armed hears from the motherboard
//! at least every third of its timeout, even when the program sends nothing.
//!
//! A board's failsafe trips when no transaction has been addressed to it for its timeout. A
//! program that only sends on change (a motor command when the wanted speed changes) would
//! trip it although the motherboard is alive. So the motherboard remembers every failsafe in
//! force (the default one it sets when it prepares a board, and any `Op::SetFailsafe` a
//! program sent, alone or in a batch, once the board confirmed it) and, whenever nothing has
//! been sent to that board for a third of the timeout, sends it `Op::Heartbeat`.
//! `SetFailsafe` 0 stops it. When the board reports a `boot` event (it restarted, and its
//! failsafe is off again), the motherboard sets it again at once (with the safe defaults it
//! prepares the board again: PEC, then the failsafe).
//!
//! The keepalive needs no pending slot and no caller's sequence number: the dispatcher sends
//! it itself, between two jobs, for every external board (a fresh sequence number, as for
//! its own set-up requests), and the internal daughterboard's worker for the internal board.
//! Callers that keep every slot busy, or a long queue, delay a heartbeat by one transfer at
//! most. The state is one fixed entry per 7-bit address (no cap below the bus's 111 boards):
//! [`KEEPALIVE_RAM_BYTES`] bytes.
//!
//! Owns [`Keepalives`], the schedule: which board has a failsafe kept alive, when its next
//! keepalive is due and what it is. Part of the per-board state (`boards`); the sending is
//! the dispatcher's and the internal worker's.

use x10_hal::time::Instant;
use x10_microcode::Address;

use crate::board_set::{board_index as index, BoardSet, BOARDS};
use crate::diag::{bump, MbDiagnostics};

/// The static RAM the keepalive state takes: a timeout (2 bytes) and a due time (4 bytes)
/// per address, and four bitmaps.
pub const KEEPALIVE_RAM_BYTES: usize = core::mem::size_of::<Keepalives>();

/// What to do next for a group of boards (the external ones, or the internal one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Next {
    /// Send `op` to `board` now, giving up after `timeout_us` (see [`keepalive_timeout_us`]).
    Send(Address, KeepaliveOp, u64),
    /// Nothing before this instant.
    At(Instant),
    /// No failsafe to keep alive.
    Idle,
}

/// What the keepalive sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum KeepaliveOp {
    Heartbeat,
    /// The board rebooted: set its failsafe again (with the safe defaults: prepare it).
    SetFailsafe(u16),
}

/// The failsafes being kept alive, one entry per address (part of the per-board state, under
/// the motherboard's lock).
pub(crate) struct Keepalives {
    /// The timeout each board accepted, in ms (0: none kept alive).
    timeout_ms: [u16; BOARDS],
    /// When each board's next keepalive is due: the low 32 bits of the instant in µs. Read
    /// relative to now (see [`Keepalives::due`]): right while within ±35 minutes of it, and
    /// a due time is never more than a third of a 65 s timeout away.
    due: [u32; BOARDS],
    /// Boards with a timeout kept alive.
    active: BoardSet,
    /// Boards that rebooted: their failsafe must be set again.
    resend: BoardSet,
    /// Keepalives lost in a row since the board last acknowledged one (0 to 3: bit 0 in
    /// `lost_lo`, bit 1 in `lost_hi`).
    lost_lo: BoardSet,
    lost_hi: BoardSet,
}

/// A third of `timeout_ms`, in µs.
fn interval_us(timeout_ms: u16) -> u64 {
    u64::from(timeout_ms) * 1_000 / 3
}

/// How long a keepalive to a board with failsafe `timeout_ms` may take in all (bus
/// retries): a quarter of the keepalive interval (a twelfth of the failsafe), at most
/// `request_timeout_us`, so that a lost one ends before the next try (half an interval
/// later, see [`Keepalives::done`]). The dispatcher stops retrying it by then, so a board that
/// does not answer holds back the others' keepalives (and the jobs) by its NACK retries at
/// most.
pub(crate) fn keepalive_timeout_us(timeout_ms: u16, request_timeout_us: u64) -> u64 {
    (interval_us(timeout_ms) / 4).min(request_timeout_us)
}

/// Keepalives tried half an interval apart after one is lost, before the schedule goes back
/// to one per interval: with the first at a third of the failsafe, the tries are at 1/3, 1/2,
/// 2/3 and 5/6 of it after the last transaction the board acknowledged, so four in a row
/// must be lost before a live board trips.
const FAST_RETRIES: u8 = 3;

impl Keepalives {
    pub(crate) const fn new() -> Keepalives {
        Keepalives {
            timeout_ms: [0; BOARDS],
            due: [0; BOARDS],
            active: BoardSet::new(),
            resend: BoardSet::new(),
            lost_lo: BoardSet::new(),
            lost_hi: BoardSet::new(),
        }
    }

    /// Keepalives lost in a row to entry `i` (0 to 3).
    fn lost(&self, i: usize) -> u8 {
        u8::from(self.lost_lo.contains(i)) | u8::from(self.lost_hi.contains(i)) << 1
    }

    fn set_lost(&mut self, i: usize, n: u8) {
        self.lost_lo.set(i, n & 1 != 0);
        self.lost_hi.set(i, n & 2 != 0);
    }

    /// The due time of entry `i`, as an instant near `now`.
    fn due(&self, i: usize, now: Instant) -> Instant {
        let d = self.due.get(i).copied().unwrap_or(0);
        // Truncation intended: both sides wrap at 2^32 µs.
        let delta = d.wrapping_sub(now.as_micros() as u32) as i32;
        if delta >= 0 {
            now.plus_us(delta.unsigned_abs().into())
        } else {
            Instant(
                now.as_micros()
                    .saturating_sub(u64::from(delta.unsigned_abs())),
            )
        }
    }

    fn set_due(&mut self, i: usize, at: Instant) {
        if let Some(d) = self.due.get_mut(i) {
            // Truncation intended: see `due`.
            *d = at.as_micros() as u32;
        }
    }

    /// The board confirmed `SetFailsafe { timeout_ms }` at `now`: keep it alive (or stop,
    /// for 0).
    pub(crate) fn set(&mut self, board: Address, timeout_ms: u16, now: Instant) {
        let i = index(board);
        if let Some(t) = self.timeout_ms.get_mut(i) {
            *t = timeout_ms;
        }
        self.active.set(i, timeout_ms > 0);
        self.resend.set(i, false);
        self.set_lost(i, 0);
        self.set_due(i, now.plus_us(interval_us(timeout_ms)));
    }

    /// A `set_failsafe` of `timeout_ms` to `board` ended at `now` without an answer that
    /// says whether the board applied it (a lost or garbled reply): the board may run either
    /// failsafe. The faster keepalive of the two is kept (a failsafe that is off does not
    /// count), so the board trips with neither.
    pub(crate) fn maybe_set(&mut self, board: Address, timeout_ms: u16, now: Instant) {
        let old = self.timeout_ms(board);
        let keep = match (old, timeout_ms) {
            (0, new) => new,
            (old, 0) => old,
            (old, new) => old.min(new),
        };
        if keep != old {
            self.set(board, keep, now);
        }
    }

    /// True when a failsafe is kept alive on `board`: only then does
    /// [`Keepalives::sent`] record anything.
    pub(crate) fn tracks(&self, board: Address) -> bool {
        self.active.contains(index(board))
    }

    /// Something was sent to `board` (a transaction it acknowledged) at `now`: its next
    /// heartbeat is due a third of its timeout later.
    pub(crate) fn sent(&mut self, board: Address, now: Instant) {
        let i = index(board);
        if self.active.contains(i) && !self.resend.contains(i) {
            let ms = self.timeout_ms.get(i).copied().unwrap_or(0);
            self.set_lost(i, 0);
            self.set_due(i, now.plus_us(interval_us(ms)));
        }
    }

    /// `board` rebooted at `now`: its failsafe, if one was kept alive, must be set again at
    /// once. True when it must.
    pub(crate) fn booted(&mut self, board: Address, now: Instant) -> bool {
        let i = index(board);
        if !self.active.contains(i) {
            return false;
        }
        self.resend.set(i, true);
        self.set_due(i, now);
        true
    }

    /// What to do at `now` for the internal board (`internal`) or for the external ones: the
    /// board whose keepalive is due first (a re-send, or a heartbeat a third of the timeout
    /// after the last transaction), or when to look again.
    pub(crate) fn next(&self, now: Instant, internal: bool, request_timeout_us: u64) -> Next {
        let mut best: Option<(Instant, usize)> = None;
        for (w, &word) in self.active.words().iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let i = w * 32 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if (i == 0) != internal {
                    continue;
                }
                let at = self.due(i, now);
                if best.is_none_or(|(b, _)| at < b) {
                    best = Some((at, i));
                }
            }
        }
        let Some((at, i)) = best else {
            return Next::Idle;
        };
        if at > now {
            return Next::At(at);
        }
        // `i` < 128: a valid 7-bit address.
        let Ok(board) = Address::new(i as u8) else {
            return Next::Idle;
        };
        let ms = self.timeout_ms.get(i).copied().unwrap_or(0);
        let op = if self.resend.contains(i) {
            KeepaliveOp::SetFailsafe(ms)
        } else {
            KeepaliveOp::Heartbeat
        };
        Next::Send(board, op, keepalive_timeout_us(ms, request_timeout_us))
    }

    /// A keepalive to `board` ended at `now` (`ok`: the board acknowledged it, and for a
    /// re-send confirmed it). Counted. After a lost heartbeat the next try is due half an
    /// interval (a sixth of the timeout) after the lost one was due, [`FAST_RETRIES`] times
    /// in a row, so that a live board hears one of four tries before it trips; after that
    /// (the board is gone or has tripped) one try per interval, so a board that does not
    /// answer is not flooded. A re-send stays due until it succeeds.
    pub(crate) fn done(
        &mut self,
        board: Address,
        op: KeepaliveOp,
        ok: bool,
        now: Instant,
        diag: &mut MbDiagnostics,
    ) {
        let i = index(board);
        let ms = self.timeout_ms.get(i).copied().unwrap_or(0);
        let lost = self.lost(i);
        let next = match (op, ok) {
            (KeepaliveOp::Heartbeat, true) => {
                bump(&mut diag.keepalives);
                self.set_lost(i, 0);
                now.plus_us(interval_us(ms))
            }
            (KeepaliveOp::SetFailsafe(_), true) => {
                bump(&mut diag.failsafe_resends);
                self.resend.set(i, false);
                self.set_lost(i, 0);
                now.plus_us(interval_us(ms))
            }
            (KeepaliveOp::Heartbeat, false) if lost < FAST_RETRIES => {
                bump(&mut diag.keepalive_failures);
                self.set_lost(i, lost + 1);
                // Half an interval after the lost one was due (at once if that has passed).
                self.due(i, now).plus_us(interval_us(ms) / 2).max(now)
            }
            (_, false) => {
                bump(&mut diag.keepalive_failures);
                now.plus_us(interval_us(ms))
            }
        };
        if self.active.contains(i) {
            self.set_due(i, next);
        }
    }

    /// The timeout kept alive for `board` (0: none).
    pub(crate) fn timeout_ms(&self, board: Address) -> u16 {
        self.timeout_ms.get(index(board)).copied().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(b: u8) -> Address {
        Address::new(b).unwrap()
    }

    #[test]
    fn due_times_wrap_with_the_low_32_bits() {
        let mut k = Keepalives::new();
        let near_wrap = Instant((5 << 32) - 50_000);
        k.set(a(9), 300, near_wrap);
        assert_eq!(
            k.next(near_wrap, false, 100_000),
            Next::At(near_wrap.plus_us(100_000))
        );
        let later = near_wrap.plus_us(100_001);
        assert_eq!(
            k.next(later, false, 100_000),
            Next::Send(a(9), KeepaliveOp::Heartbeat, 25_000)
        );
        assert_eq!(k.next(later, true, 100_000), Next::Idle);
    }

    /// Issue 22 item 10: with a 300 ms failsafe, a board that acknowledged a transaction at
    /// 0 gets heartbeats tried at 100, 150, 200 and 250 ms when they are lost (each given up
    /// after 25 ms), so four must be lost before it trips at 300 ms; then one per 100 ms.
    #[test]
    fn lost_heartbeats_are_tried_again_half_an_interval_later_four_before_the_trip() {
        let mut k = Keepalives::new();
        let mut diag = MbDiagnostics::new();
        k.set(a(9), 300, Instant(0));
        let mut tries: heapless::Vec<u64, 8> = heapless::Vec::new();
        let mut now = Instant(0);
        for _ in 0..6 {
            let at = match k.next(now, false, 100_000) {
                Next::At(at) => at,
                other => panic!("{other:?}"),
            };
            assert_eq!(
                k.next(at, false, 100_000),
                Next::Send(a(9), KeepaliveOp::Heartbeat, 25_000)
            );
            tries.push(at.as_micros() / 1_000).unwrap();
            // lost: given up after its 25 ms
            now = at.plus_us(25_000);
            k.done(a(9), KeepaliveOp::Heartbeat, false, now, &mut diag);
        }
        assert_eq!(tries[..], [100, 150, 200, 250, 375, 500]);
        // One acknowledged: back to one per third of the failsafe, and four fast tries again.
        k.sent(a(9), Instant(600_000));
        assert_eq!(
            k.next(Instant(600_000), false, 100_000),
            Next::At(Instant(700_000))
        );
        assert_eq!(k.lost(9), 0);
    }

    /// A `set_failsafe` whose answer was lost: the faster of the two keepalives is kept.
    #[test]
    fn an_unconfirmed_failsafe_keeps_the_faster_keepalive() {
        let mut k = Keepalives::new();
        k.set(a(9), 300, Instant(0));
        k.maybe_set(a(9), 100, Instant(10_000));
        assert_eq!(k.timeout_ms(a(9)), 100);
        k.maybe_set(a(9), 500, Instant(20_000));
        k.maybe_set(a(9), 0, Instant(20_000));
        assert_eq!(k.timeout_ms(a(9)), 100);
        let mut k = Keepalives::new();
        k.maybe_set(a(9), 200, Instant(0));
        assert_eq!(k.timeout_ms(a(9)), 200);
    }

    #[test]
    fn the_state_stays_small() {
        assert_eq!(KEEPALIVE_RAM_BYTES, 128 * 2 + 128 * 4 + 4 * 16);
    }
}
