//! The pending table: one slot per outstanding request, keyed by (board, sequence number),
//! the per-board sequence counters, the ring of recently ended requests that classifies stray
//! replies, the event waiters and the queue of unclaimed pin events. Pure bookkeeping: no
//! waiting, no I/O. The motherboard keeps it behind one blocking mutex.

use heapless::Vec;
use x10_devices::{LinkError, PinEvent};
use x10_microcode::{Address, PinRef, MAX_FRAME_LEN};

use crate::diag::{bump, MbDiagnostics};
use crate::keepalive::Keepalives;
use x10_hal::time::Instant;

/// Requests outstanding at the same time (all boards together).
pub const MAX_PENDING: usize = 16;
/// Ended requests remembered to classify stray replies (late / duplicate / unknown); their
/// sequence numbers are not reused while remembered.
pub const RECENT_LEN: usize = 16;
/// Tasks waiting for a pin event at the same time.
pub const MAX_EVENT_WAITERS: usize = 8;
/// Pin events kept for a later `wait_event` when no task was waiting.
pub const UNCLAIMED_EVENTS: usize = 8;

/// What the dispatcher needs to know about a request besides its bytes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct JobMeta {
    pub(crate) ticket: Ticket,
    pub(crate) db: Address,
    pub(crate) seq: u8,
    /// PEC state the frame was built with (the reply is checked the same way).
    pub(crate) pec: bool,
    /// Bytes to read after a repeated START (0: the request is a single write).
    pub(crate) read_len: usize,
}

/// A request for the dispatcher: its frame, ready to go on the bus.
#[derive(Clone, Debug)]
pub(crate) struct Job {
    pub(crate) meta: JobMeta,
    pub(crate) frame: Vec<u8, MAX_FRAME_LEN>,
}

/// Boards the table tracks: every 7-bit address.
const BOARDS: usize = 128;

/// Where a request is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SlotState {
    Free,
    /// Waiting for the dispatcher (or the internal board).
    Queued,
    /// Answered `pending`: waiting for the deferred-reply event.
    Deferred,
    /// Ended; the result is in the slot's signal for the caller to take.
    Done,
}

#[derive(Clone, Copy, Debug)]
struct Slot {
    generation: u32,
    board: u8,
    seq: u8,
    state: SlotState,
    /// PEC setting the request asks for (a `set_pec`), applied when it succeeds.
    pec_change: Option<bool>,
    /// Failsafe timeout the request sets (a `set_failsafe`), kept alive when it succeeds.
    failsafe_change: Option<u16>,
}

const FREE_SLOT: Slot = Slot {
    generation: 0,
    board: 0,
    seq: 0,
    state: SlotState::Free,
    pec_change: None,
    failsafe_change: None,
};

/// One request's claim on a slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Ticket {
    pub(crate) index: usize,
    pub(crate) generation: u32,
}

/// How a request ended, remembered for classifying strays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ended {
    /// Timed out, or its caller went away.
    GaveUp,
    /// Its outcome was delivered.
    Completed,
}

#[derive(Clone, Copy, Debug)]
enum Waiter {
    Free,
    Waiting(Address, PinRef),
    /// An event was put in the waiter's signal; the waiter has not taken it yet.
    Delivered,
}

#[derive(Clone, Copy, Debug)]
struct WaiterSlot {
    generation: u32,
    state: Waiter,
}

/// A registered event waiter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WaiterTicket {
    pub(crate) index: usize,
    pub(crate) generation: u32,
}

pub(crate) struct Table {
    slots: [Slot; MAX_PENDING],
    generation: u32,
    next_seq: [u8; BOARDS],
    recent: Vec<(u8, u8, Ended), RECENT_LEN>,
    pec: u128,
    pub(crate) diag: MbDiagnostics,
    waiters: [WaiterSlot; MAX_EVENT_WAITERS],
    unclaimed: Vec<PinEvent, UNCLAIMED_EVENTS>,
    /// Requests for the dispatcher, oldest first. Each holds a slot, so the queue never
    /// overflows; releasing the slot takes the job out.
    queue: Vec<Job, MAX_PENDING>,
    /// The failsafes the motherboard keeps alive.
    pub(crate) keepalive: Keepalives,
    /// A failsafe setting changed (the keepalive task must look again).
    keepalive_changed: bool,
}

fn board_index(a: Address) -> usize {
    usize::from(a.get()) % BOARDS
}

impl Table {
    pub(crate) const fn new() -> Table {
        Table {
            slots: [FREE_SLOT; MAX_PENDING],
            generation: 0,
            next_seq: [0; BOARDS],
            recent: Vec::new(),
            pec: 0,
            diag: MbDiagnostics {
                requests: 0,
                completed: 0,
                timeouts: 0,
                nacks: 0,
                arbitration_failures: 0,
                bus_errors: 0,
                bad_replies: 0,
                status_errors: 0,
                busy: 0,
                arbitration_lost: 0,
                nacked: 0,
                retries: 0,
                yields: 0,
                keepalives: 0,
                failsafe_resends: 0,
                keepalive_failures: 0,
                abandoned: 0,
                cancelled: 0,
                late_replies: 0,
                duplicate_replies: 0,
                unknown_replies: 0,
                events: 0,
                bad_events: 0,
                events_dropped: 0,
                rejected: 0,
                failsafe_trips: 0,
                boots: 0,
                overflows: 0,
                pec_resyncs: 0,
                unexpected_reads: 0,
                listener_errors: 0,
            },
            waiters: [WaiterSlot {
                generation: 0,
                state: Waiter::Free,
            }; MAX_EVENT_WAITERS],
            unclaimed: Vec::new(),
            queue: Vec::new(),
            keepalive: Keepalives::new(),
            keepalive_changed: false,
        }
    }

    /// True (once) when a failsafe setting changed since the last call.
    pub(crate) fn take_keepalive_changed(&mut self) -> bool {
        core::mem::take(&mut self.keepalive_changed)
    }

    /// `board` rebooted: its PEC is off, and a failsafe kept alive must be set again.
    pub(crate) fn booted(&mut self, board: Address) {
        self.set_pec(board, false);
        if self.keepalive.booted(board) {
            self.keepalive_changed = true;
        }
    }

    /// Queues a job for the dispatcher (behind every job queued before).
    ///
    /// # Errors
    /// The job back if the queue is full (it cannot be while each job holds a slot).
    pub(crate) fn enqueue(&mut self, job: Job) -> Result<(), Job> {
        self.queue.push(job)
    }

    /// The oldest queued job.
    pub(crate) fn pop_job(&mut self) -> Option<Job> {
        if self.queue.is_empty() {
            None
        } else {
            Some(self.queue.remove(0))
        }
    }

    /// True when PEC is negotiated with `board`.
    pub(crate) fn pec(&self, board: Address) -> bool {
        self.pec >> board_index(board) & 1 != 0
    }

    pub(crate) fn set_pec(&mut self, board: Address, on: bool) {
        let bit = 1u128 << board_index(board);
        if on {
            self.pec |= bit;
        } else {
            self.pec &= !bit;
        }
    }

    fn seq_in_use(&self, board: u8, seq: u8) -> bool {
        self.slots
            .iter()
            .any(|s| s.state != SlotState::Free && s.board == board && s.seq == seq)
            || self.recent.iter().any(|&(b, s, _)| b == board && s == seq)
    }

    /// Claims a slot and the next free sequence number of `board` (skipping numbers still
    /// pending or recently ended). A request that sets a failsafe (`failsafe_change` non-zero)
    /// also claims room to keep it alive.
    ///
    /// # Errors
    /// [`LinkError::Busy`] when every slot is in use, or every sequence number of the board,
    /// or (for a failsafe) [`crate::MAX_KEEPALIVES`] boards already have one.
    pub(crate) fn alloc(
        &mut self,
        board: Address,
        pec_change: Option<bool>,
        failsafe_change: Option<u16>,
        now: Instant,
    ) -> Result<(Ticket, u8), LinkError> {
        let Some(index) = self.slots.iter().position(|s| s.state == SlotState::Free) else {
            bump(&mut self.diag.busy);
            return Err(LinkError::Busy);
        };
        if failsafe_change.is_some_and(|t| t > 0) {
            let slots = &self.slots;
            let in_flight = |b: Address| {
                slots.iter().any(|s| {
                    s.state != SlotState::Free && s.board == b.get() && s.failsafe_change.is_some()
                })
            };
            if self.keepalive.reserve(board, now, in_flight).is_err() {
                bump(&mut self.diag.busy);
                return Err(LinkError::Busy);
            }
        }
        let b = board.get();
        let start = self.next_seq.get(board_index(board)).copied().unwrap_or(0);
        let Some(seq) = (0..=u8::MAX)
            .map(|i| start.wrapping_add(i))
            .find(|&s| !self.seq_in_use(b, s))
        else {
            bump(&mut self.diag.busy);
            return Err(LinkError::Busy);
        };
        if let Some(n) = self.next_seq.get_mut(board_index(board)) {
            *n = seq.wrapping_add(1);
        }
        self.generation = self.generation.wrapping_add(1);
        let generation = self.generation;
        let Some(slot) = self.slots.get_mut(index) else {
            return Err(LinkError::Busy);
        };
        *slot = Slot {
            generation,
            board: b,
            seq,
            state: SlotState::Queued,
            pec_change,
            failsafe_change,
        };
        bump(&mut self.diag.requests);
        Ok((Ticket { index, generation }, seq))
    }

    fn slot(&self, t: Ticket) -> Option<&Slot> {
        self.slots
            .get(t.index)
            .filter(|s| s.generation == t.generation && s.state != SlotState::Free)
    }

    fn slot_mut(&mut self, t: Ticket) -> Option<&mut Slot> {
        self.slots
            .get_mut(t.index)
            .filter(|s| s.generation == t.generation && s.state != SlotState::Free)
    }

    pub(crate) fn state(&self, t: Ticket) -> SlotState {
        self.slot(t).map_or(SlotState::Free, |s| s.state)
    }

    /// Marks a queued request as answered `pending`. False if it is no longer queued.
    pub(crate) fn defer(&mut self, t: Ticket) -> bool {
        match self.slot_mut(t) {
            Some(s) if s.state == SlotState::Queued => {
                s.state = SlotState::Deferred;
                true
            }
            _ => false,
        }
    }

    /// Ends a queued or deferred request with `result` (the caller signals it). Counts the
    /// outcome and applies a successful `set_pec`. False if the request already ended.
    pub(crate) fn complete(
        &mut self,
        t: Ticket,
        result: &Result<x10_microcode::Payload, LinkError>,
    ) -> bool {
        let Some(s) = self.slot_mut(t) else {
            return false;
        };
        if !matches!(s.state, SlotState::Queued | SlotState::Deferred) {
            return false;
        }
        s.state = SlotState::Done;
        let (board, pec_change, failsafe_change) = (s.board, s.pec_change, s.failsafe_change);
        let d = &mut self.diag;
        match result {
            Ok(_) => {
                bump(&mut d.completed);
                if let (Some(on), Ok(a)) = (pec_change, Address::new(board)) {
                    self.set_pec(a, on);
                }
                if let (Some(ms), Ok(a)) = (failsafe_change, Address::new(board)) {
                    self.keepalive.set(a, ms);
                    self.keepalive_changed = true;
                }
            }
            Err(LinkError::Timeout) => bump(&mut d.timeouts),
            Err(LinkError::Nack) => bump(&mut d.nacks),
            Err(LinkError::ArbitrationLost) => bump(&mut d.arbitration_failures),
            Err(LinkError::Bus) => bump(&mut d.bus_errors),
            Err(LinkError::BadReply) => bump(&mut d.bad_replies),
            Err(LinkError::Status(_)) => bump(&mut d.status_errors),
            Err(LinkError::Invalid(_) | LinkError::Busy | LinkError::Unsupported) => {}
        }
        true
    }

    /// Frees a slot, takes its job out of the queue if it is still there, and remembers how
    /// its request ended.
    pub(crate) fn release(&mut self, t: Ticket, ended: Ended) {
        self.queue.retain(|j| j.meta.ticket != t);
        let Some(s) = self.slot_mut(t) else {
            return;
        };
        let (board, seq) = (s.board, s.seq);
        s.state = SlotState::Free;
        if self.recent.is_full() {
            self.recent.remove(0);
        }
        let _ = self.recent.push((board, seq, ended));
    }

    /// The deferred request `(board, seq)`, if one waits.
    pub(crate) fn find_deferred(&self, board: Address, seq: u8) -> Option<Ticket> {
        self.slots.iter().enumerate().find_map(|(index, s)| {
            (s.state == SlotState::Deferred && s.board == board.get() && s.seq == seq).then_some(
                Ticket {
                    index,
                    generation: s.generation,
                },
            )
        })
    }

    /// Counts a reply that matches no waiting request: late (its request gave up), duplicate
    /// (its request already completed) or unknown.
    pub(crate) fn stray(&mut self, board: Address, seq: u8) {
        let ended = self
            .recent
            .iter()
            .rev()
            .find(|&&(b, s, _)| b == board.get() && s == seq)
            .map(|&(_, _, e)| e);
        let d = &mut self.diag;
        match ended {
            Some(Ended::GaveUp) => bump(&mut d.late_replies),
            Some(Ended::Completed) => bump(&mut d.duplicate_replies),
            None => bump(&mut d.unknown_replies),
        }
    }

    /// Takes a queued unclaimed event for `(board, pin)` or registers a waiter.
    ///
    /// # Errors
    /// [`LinkError::Busy`] when every waiter slot is in use.
    pub(crate) fn wait_for(
        &mut self,
        board: Address,
        pin: PinRef,
    ) -> Result<Result<PinEvent, WaiterTicket>, LinkError> {
        if let Some(i) = self
            .unclaimed
            .iter()
            .position(|e| e.source == board && e.pin == pin)
        {
            return Ok(Ok(self.unclaimed.remove(i)));
        }
        let Some(index) = self
            .waiters
            .iter()
            .position(|w| matches!(w.state, Waiter::Free))
        else {
            return Err(LinkError::Busy);
        };
        self.generation = self.generation.wrapping_add(1);
        let generation = self.generation;
        if let Some(w) = self.waiters.get_mut(index) {
            *w = WaiterSlot {
                generation,
                state: Waiter::Waiting(board, pin),
            };
        }
        Ok(Err(WaiterTicket { index, generation }))
    }

    /// The waiters an event for `(board, pin)` goes to: each is marked delivered. With none,
    /// the event is kept for a later `wait_event` (pushing out the oldest when full).
    pub(crate) fn deliver(&mut self, ev: &PinEvent, mut to: impl FnMut(usize)) {
        let mut any = false;
        for (i, w) in self.waiters.iter_mut().enumerate() {
            if let Waiter::Waiting(b, p) = w.state {
                if b == ev.source && p == ev.pin {
                    w.state = Waiter::Delivered;
                    to(i);
                    any = true;
                }
            }
        }
        if !any {
            self.keep_unclaimed(ev.clone(), false);
        }
    }

    /// Keeps an event for a later `wait_event`: at the back (newest), or at the front when a
    /// waiter went away before taking it.
    pub(crate) fn keep_unclaimed(&mut self, ev: PinEvent, front: bool) {
        if self.unclaimed.is_full() {
            self.unclaimed.remove(0);
            bump(&mut self.diag.events_dropped);
        }
        let at = if front { 0 } else { self.unclaimed.len() };
        let _ = self.unclaimed.insert(at, ev);
    }

    /// Frees a waiter slot. Returns true if an event had been delivered to it (the caller
    /// takes it from the signal).
    pub(crate) fn unwait(&mut self, t: WaiterTicket) -> bool {
        match self.waiters.get_mut(t.index) {
            Some(w) if w.generation == t.generation => {
                let delivered = matches!(w.state, Waiter::Delivered);
                w.state = Waiter::Free;
                delivered
            }
            _ => false,
        }
    }
}
