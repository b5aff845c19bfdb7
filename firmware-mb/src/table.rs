//! The motherboard's table: its bookkeeping, kept together behind the one blocking mutex of
//! [`crate::MbCore`]. Owns nothing of its own but the parts, each in the module that owns it:
//!
//! | part | module | what it owns |
//! |---|---|---|
//! | `requests` | [`crate::requests`] | pending slots, sequence numbers, the ring of ended requests |
//! | `jobs` | [`crate::jobs`] | the queue of requests for the dispatcher and the internal worker |
//! | `waiters` | [`crate::waiters`] | tasks waiting for pin events, the unclaimed pin events |
//! | `boards` | [`crate::boards`] | per board: PEC, prepared, the failsafe kept alive |
//! | `events_in` | [`crate::events_in`] | per board: the event counter expected, drops reported |
//! | `diag` | [`crate::diag`] | the counters, which every part counts in |
//!
//! and the operations that keep two parts in step: a request's job leaves the queue when its
//! slot is released, and goes on the bus (its slot `Sending`) when it is taken from the
//! queue. Pure bookkeeping: no waiting, no I/O.

use crate::boards::Boards;
use crate::diag::MbDiagnostics;
use crate::directory::Directory;
use crate::events_in::EventBook;
use embassy_sync::waitqueue::MultiWakerRegistration;

use crate::jobs::{Job, Jobs};
use crate::requests::{Ended, Requests, Ticket};
use crate::waiters::Waiters;

pub(crate) struct Table {
    pub(crate) requests: Requests,
    pub(crate) jobs: Jobs,
    pub(crate) waiters: Waiters,
    pub(crate) boards: Boards,
    pub(crate) events_in: EventBook,
    pub(crate) diag: MbDiagnostics,
    /// Boards known by their unique ID (plug and play).
    pub(crate) directory: Directory,
    /// Callers waiting for a pending slot (or a sequence number) to be free.
    pub(crate) slot_waiters: MultiWakerRegistration<SLOT_WAITERS>,
    /// How many callers wait for a slot: while any does, a new caller waits behind them, so
    /// a task that ends a call and makes the next at once cannot take every freed slot.
    pub(crate) slot_waiting: u16,
    /// The board whose firmware is being updated (`crate::update`): other callers' requests
    /// to it end in `LinkError::Updating`.
    pub(crate) updating: Option<x10_microcode::Address>,
    /// The images the updater carries (empty: none, or no updater runs), left by
    /// `update::run_updates` for [`crate::X10::start_update`].
    pub(crate) carried: &'static [crate::update::DbImage],
    /// The updater's policy.
    pub(crate) update_policy: crate::update::UpdatePolicy,
    /// A request to update now, for the updater's next look: one board (its ID) or every
    /// board (`None`).
    pub(crate) update_now: Option<Option<x10_microcode::Uid>>,
    /// Addresses whose last request (or preparation) ended NACKed after every attempt, one
    /// bit per 7-bit address (bit `a % 32` of word `a / 32`): the next transaction to one is tried once, not retried
    /// (`Dispatcher::retry_for`), until it is acknowledged or the board writes to us.
    pub(crate) silent: [u32; 4],
}

/// Callers whose wakers are kept while they wait for a slot; more wake all and register
/// again (embassy-sync's `MultiWakerRegistration`).
const SLOT_WAITERS: usize = 4;

impl Table {
    pub(crate) const fn new() -> Table {
        Table {
            requests: Requests::new(),
            jobs: Jobs::new(),
            waiters: Waiters::new(),
            boards: Boards::new(),
            events_in: EventBook::new(),
            diag: MbDiagnostics::new(),
            directory: Directory::new(),
            slot_waiters: MultiWakerRegistration::new(),
            slot_waiting: 0,
            updating: None,
            carried: &[],
            update_policy: crate::update::UpdatePolicy::Auto,
            update_now: None,
            silent: [0; 4],
        }
    }

    /// The caller is done with request `t`: its job leaves the queue if it is still there,
    /// and its slot is released ([`Requests::release`]).
    pub(crate) fn release(&mut self, t: Ticket, ended: Ended) {
        self.jobs.remove(t);
        self.requests.release(t, ended);
        self.slot_waiters.wake();
    }

    /// The oldest job queued for the dispatcher, or for the internal daughterboard when
    /// `internal`; its request is on the bus from now on.
    pub(crate) fn pop_job(&mut self, internal: bool) -> Option<Job> {
        let job = self.jobs.pop(internal)?;
        self.requests.sending(job.meta.ticket);
        Some(job)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::requests::SlotState;
    use heapless::Vec;
    use x10_hal::time::Instant;
    use x10_microcode::{Address, PinRef};

    fn addr(a: u8) -> Address {
        Address::new(a).unwrap()
    }

    /// Queues a pulse-in to `board` whose deferred reply names pin 0x80.
    fn queue(t: &mut Table, board: u8) -> Ticket {
        let (ticket, seq) = t
            .requests
            .alloc(addr(board), Instant(0), &mut t.diag)
            .unwrap();
        let meta = crate::jobs::JobMeta {
            ticket,
            kind: crate::jobs::JobKind::Request,
            db: addr(board),
            seq,
            read: Some(0),
            deferred: Some((PinRef::from_byte(0x80), 1_000)),
            failsafe_change: None,
        };
        t.jobs
            .push(Job {
                meta,
                frame: Vec::new(),
            })
            .unwrap();
        ticket
    }

    #[test]
    fn a_released_request_leaves_the_queue_and_a_popped_one_is_on_the_bus() {
        let mut t = Table::new();
        let a = queue(&mut t, 9);
        let b = queue(&mut t, 9);
        t.release(a, Ended::GaveUp);
        assert_eq!(t.requests.state(a), SlotState::Free);
        let job = t.pop_job(false).unwrap();
        assert_eq!(job.meta.ticket, b);
        assert_eq!(t.requests.state(b), SlotState::Sending);
        assert!(t.pop_job(false).is_none());
        // Given up on the bus: the slot is held until the transfer ends.
        t.release(b, Ended::GaveUp);
        assert_eq!(t.requests.state(b), SlotState::Abandoned);
        t.requests.transfer_ended(b);
        assert_eq!(t.requests.state(b), SlotState::Free);
    }
}
