//! What the motherboard knows of each board: PEC negotiated or not, prepared (PEC on,
//! failsafe set) since its last boot or not, and the failsafe kept alive on it
//! ([`crate::keepalive`]). Owns [`Boards`], and reads from an operation what it changes there
//! once the board confirmed it ([`pec_change`], [`failsafe_change`]). Pure bookkeeping, one
//! entry per 7-bit address; the dispatcher and the internal worker act on it.

use heapless::Vec;
use x10_hal::time::Instant;
use x10_microcode::{Address, EventConfig, Identity, Op, PinRef, PortKind};

/// Event enables the motherboard remembers, to set them again on a board that restarted
/// (all boards together).
pub const REMEMBERED_ENABLES: usize = 8;

use crate::board_set::{board_index, BoardSet, BOARDS};
use crate::keepalive::Keepalives;

/// The per-board state.
pub(crate) struct Boards {
    /// PEC negotiated: requests to the board carry their check.
    pec: BoardSet,
    /// Events from the board must carry their check: set when a checked reply showed PEC on,
    /// cleared only by what is itself trustworthy (a checked `boot` event, a confirmed
    /// `set_pec(0)`), never by an unchecked sign that the board lost PEC.
    events_checked: BoardSet,
    /// Boards the dispatcher has prepared (PEC on, failsafe set) since their last boot.
    ready: BoardSet,
    /// The failsafes the motherboard keeps alive.
    pub(crate) keepalive: Keepalives,
    /// A failsafe setting changed (the dispatcher must look at the keepalives again).
    keepalive_changed: bool,
    /// Each board's port counts, from its `boot` event or an `identify` reply: sensor ports
    /// in the high nibble, actuator ports in the low one (15: fifteen or more).
    ports: [u8; BOARDS],
    /// Boards whose port counts are known.
    ports_known: BoardSet,
    /// The event enables boards confirmed (board, pin, configuration), set again after a
    /// board restarts (with the safe defaults, as part of its preparation).
    enables: Vec<(Address, PinRef, EventConfig), REMEMBERED_ENABLES>,
}

impl Boards {
    pub(crate) const fn new() -> Boards {
        Boards {
            pec: BoardSet::new(),
            events_checked: BoardSet::new(),
            ready: BoardSet::new(),
            keepalive: Keepalives::new(),
            keepalive_changed: false,
            ports: [0; BOARDS],
            ports_known: BoardSet::new(),
            enables: Vec::new(),
        }
    }

    /// `board` confirmed `event_enable(pin, cfg)`: remembered (replacing the pin's previous
    /// one; an enable of nothing forgets it). False when no room was left to remember it.
    pub(crate) fn enabled(&mut self, board: Address, pin: PinRef, cfg: EventConfig) -> bool {
        self.enables.retain(|&(b, p, _)| !(b == board && p == pin));
        if cfg == EventConfig::OFF {
            return true;
        }
        self.enables.push((board, pin, cfg)).is_ok()
    }

    /// The event enables remembered for `board`.
    pub(crate) fn enables_of(
        &self,
        board: Address,
    ) -> impl Iterator<Item = (PinRef, EventConfig)> + '_ {
        self.enables
            .iter()
            .filter(move |e| e.0 == board)
            .map(|&(_, p, c)| (p, c))
    }

    /// `board` described itself (its `boot` event, an `identify` reply): its port counts.
    pub(crate) fn identified(&mut self, board: Address, id: &Identity) {
        let i = board_index(board);
        if let Some(p) = self.ports.get_mut(i) {
            *p = id.sensor_ports.min(15) << 4 | id.actuator_ports.min(15);
        }
        self.ports_known.set(i, true);
    }

    /// False when a `scan` reply's payload from `board` reports another number of sensor
    /// ports than the board has (as far as the motherboard knows: up to 8 are scanned).
    pub(crate) fn scan_fits(&self, board: Address, payload: &[u8]) -> bool {
        let i = board_index(board);
        if !self.ports_known.contains(i) {
            return true;
        }
        let sensors = self.ports.get(i).copied().unwrap_or(0) >> 4;
        // 15 stands for fifteen or more: 8 are scanned either way.
        payload.first() == Some(&sensors.min(8))
    }

    /// `board`'s sensor ports (up to 8 are scanned), when its port counts are known.
    pub(crate) fn sensor_ports(&self, board: Address) -> Option<u8> {
        let i = board_index(board);
        self.ports_known
            .contains(i)
            .then(|| (self.ports.get(i).copied().unwrap_or(0) >> 4).min(8))
    }

    /// True when `board`'s port counts are known.
    pub(crate) fn ports_known(&self, board: Address) -> bool {
        self.ports_known.contains(board_index(board))
    }

    /// Checks that every port `op` names (a batch: every item's) exists on `board`, as far as
    /// the motherboard knows the board's ports. `Err` with the port that does not.
    pub(crate) fn check_ports(
        &self,
        board: Address,
        op: &Op<'_>,
    ) -> Result<(), x10_microcode::Port> {
        let i = board_index(board);
        if !self.ports_known.contains(i) {
            return Ok(());
        }
        let packed = self.ports.get(i).copied().unwrap_or(0xFF);
        let check = |item: &Op<'_>| match item.pin_ref() {
            Some(pin) => {
                let count = match pin.port.kind() {
                    PortKind::Sensor => packed >> 4,
                    PortKind::Actuator => packed & 0x0F,
                };
                // 15 stands for fifteen or more: no port beyond it is refused.
                if pin.port.index() < count || count == 15 {
                    Ok(())
                } else {
                    Err(pin.port)
                }
            }
            None => Ok(()),
        };
        match op {
            Op::Batch(b) | Op::Stage(b) => b.iter().try_for_each(|item| check(&item)),
            _ => check(op),
        }
    }

    /// True when PEC is negotiated with `board`.
    pub(crate) fn pec(&self, board: Address) -> bool {
        self.pec.contains(board_index(board))
    }

    /// PEC is on (`on`, shown by a checked reply) or off (a checked `boot` event, a confirmed
    /// `set_pec(0)`) on `board`, for its requests and its events.
    pub(crate) fn set_pec(&mut self, board: Address, on: bool) {
        self.pec.set(board_index(board), on);
        self.events_checked.set(board_index(board), on);
    }

    /// An unchecked sign that `board` lost PEC (it restarted and its `boot` event was lost):
    /// requests go without a check (and with the safe defaults the board is prepared again
    /// first), but its events must still carry theirs until something checked says
    /// otherwise.
    pub(crate) fn pec_lost_unchecked(&mut self, board: Address) {
        self.pec.set(board_index(board), false);
        self.set_ready(board, false);
    }

    /// True when `board`'s events must carry their check.
    pub(crate) fn events_checked(&self, board: Address) -> bool {
        self.events_checked.contains(board_index(board))
    }

    /// True when the dispatcher has prepared `board` since its last boot.
    pub(crate) fn ready(&self, board: Address) -> bool {
        self.ready.contains(board_index(board))
    }

    pub(crate) fn set_ready(&mut self, board: Address, on: bool) {
        self.ready.set(board_index(board), on);
    }

    /// `board` rebooted at `now`: its PEC is off, and a failsafe kept alive must be set
    /// again, at once (by the dispatcher, or the internal worker for the internal board;
    /// with the safe defaults the dispatcher prepares the board again, at the latest before
    /// its next request).
    pub(crate) fn booted(&mut self, board: Address, now: Instant) {
        self.set_pec(board, false);
        self.set_ready(board, false);
        if self.keepalive.booted(board, now) {
            self.keepalive_changed = true;
        }
    }

    /// The failsafe of `board` was set to `ms` at `now`: keep it alive.
    pub(crate) fn failsafe_set(&mut self, board: Address, ms: u16, now: Instant) {
        self.keepalive.set(board, ms, now);
        self.keepalive_changed = true;
    }

    /// A failsafe setting changed through [`Boards::keepalive`] directly.
    pub(crate) fn keepalive_changed_now(&mut self) {
        self.keepalive_changed = true;
    }

    /// True (once) when a failsafe setting changed since the last call.
    pub(crate) fn take_keepalive_changed(&mut self) -> bool {
        core::mem::take(&mut self.keepalive_changed)
    }
}

/// The last `set_pec` of an operation (or of a batch's items).
pub(crate) fn pec_change(op: &Op<'_>) -> Option<bool> {
    last_setting(op, |item| match item {
        Op::SetPec(on) => Some(on),
        _ => None,
    })
}

/// The last `set_failsafe` of an operation (or of a batch's items).
pub(crate) fn failsafe_change(op: &Op<'_>) -> Option<u16> {
    last_setting(op, |item| match item {
        Op::SetFailsafe { timeout_ms } => Some(timeout_ms),
        _ => None,
    })
}

/// What `setting` finds in `op`, or in the last of a batch's items it finds it in.
fn last_setting<T>(op: &Op<'_>, setting: impl Fn(Op<'_>) -> Option<T>) -> Option<T> {
    match op {
        Op::Batch(b) => b.iter().fold(None, |acc, item| setting(item).or(acc)),
        _ => setting(*op),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(a: u8) -> Address {
        Address::new(a).unwrap()
    }

    #[test]
    fn pec_bits_per_board() {
        let mut t = Boards::new();
        for b in [0u8, 8, 31, 32, 63, 64, 0x77] {
            t.set_pec(addr(b), true);
        }
        for b in (0..=127u8).filter(|&b| Address::new(b).is_ok()) {
            assert_eq!(
                t.pec(addr(b)),
                matches!(b, 0 | 8 | 31 | 32 | 63 | 64 | 0x77),
                "board {b}"
            );
        }
        t.set_pec(addr(32), false);
        assert!(!t.pec(addr(32)));
        assert!(t.pec(addr(31)) && t.pec(addr(63)));
    }

    #[test]
    fn a_boot_turns_pec_off_and_asks_for_the_failsafe_again() {
        let mut t = Boards::new();
        t.set_pec(addr(9), true);
        t.set_ready(addr(9), true);
        // No failsafe kept alive: nothing to set again.
        t.booted(addr(9), Instant(0));
        assert!(!t.pec(addr(9)) && !t.ready(addr(9)));
        assert!(!t.take_keepalive_changed());
        t.failsafe_set(addr(9), 300, Instant(0));
        assert!(t.take_keepalive_changed());
        assert!(!t.take_keepalive_changed());
        t.booted(addr(9), Instant(10));
        assert!(t.take_keepalive_changed());
        assert_eq!(t.keepalive.timeout_ms(addr(9)), 300);
    }
}
