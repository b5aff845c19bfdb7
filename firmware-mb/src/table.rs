//! The pending table: one slot per outstanding request, keyed by (board, sequence number),
//! the per-board sequence counters, the ring of recently ended requests that classifies stray
//! replies, the event waiters and the queue of unclaimed pin events. Pure bookkeeping: no
//! waiting, no I/O. The motherboard keeps it behind one blocking mutex.
//!
//! A deferred request whose caller gave up keeps its slot (state `Abandoned`) until the
//! board's own deadline for it has passed: its (board, sequence number) pair cannot be reused
//! while the board may still send the deferred reply, and a deferred reply must also name the
//! request's pin. So a late deferred reply is counted as late and never completes another
//! request, however many requests the board's sequence counter went through meanwhile.
//!
//! The ring of recently ended requests is a fixed array written round-robin (the oldest entry
//! is overwritten, nothing moves). A count per bucket of (board, sequence number) pairs that
//! are pending or in the ring lets `alloc` take the board's next sequence number without
//! looking through the slots and the ring when no pair in its bucket is held.

use core::task::Waker;

use heapless::{Deque, Vec};
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
    /// Payload bytes to read after a repeated START, besides the reply header and the PEC
    /// byte (`None`: the request is a single write). The PEC byte is added, or not, when the
    /// request goes on the bus, as the board's PEC state is then.
    pub(crate) read: Option<usize>,
    /// A deferred operation (pulse-in): the pin its deferred reply names and how long after
    /// the `pending` answer the board may still send it, in µs. Only such a request may be
    /// answered `pending`.
    pub(crate) deferred: Option<(PinRef, u64)>,
    /// Failsafe timeout the request sets (a `set_failsafe`), kept alive once the board has it.
    pub(crate) failsafe_change: Option<u16>,
}

/// A request for the dispatcher: its frame, ready to go on the bus.
#[derive(Clone, Debug)]
pub(crate) struct Job {
    pub(crate) meta: JobMeta,
    pub(crate) frame: Vec<u8, MAX_FRAME_LEN>,
}

/// Boards the table tracks: every 7-bit address.
const BOARDS: usize = 128;

/// Buckets of the held-pair counts (see [`held_bucket`]). At most
/// `MAX_PENDING + RECENT_LEN` pairs are held at a time, so a count never exceeds 32.
const HELD_BUCKETS: usize = 64;

/// The bucket of the pair (`board`, `seq`): for one board, 64 consecutive sequence numbers
/// fall in 64 different buckets; the board's part (times 37, odd) spreads the runs of
/// neighbouring addresses apart.
fn held_bucket(board: u8, seq: u8) -> usize {
    usize::from(seq.wrapping_add(board.wrapping_mul(37))) % HELD_BUCKETS
}

/// `until` of a slot whose caller gave up while its request was on the bus: held until the
/// transfer ends, whatever the time.
const ON_THE_BUS: Instant = Instant(u64::MAX);

/// A recently ended request: its board, its sequence number and how it ended.
type RecentEntry = Option<(u8, u8, Ended)>;

/// Where a request is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SlotState {
    Free,
    /// Waiting for the dispatcher (or the internal board).
    Queued,
    /// Taken by the dispatcher (or the internal worker): on the bus. A caller that gives up
    /// now leaves the slot `Abandoned` until the transfer ends, so that a `pending` answer
    /// always finds its request's slot to hold the number in.
    Sending,
    /// Answered `pending`: waiting for the deferred-reply event.
    Deferred,
    /// Answered `pending`, then given up by its caller: nobody waits, but the pair (board,
    /// sequence number) stays held until `until`, the latest the board may still answer.
    Abandoned,
    /// Ended; the result is in the slot's signal for the caller to take.
    Done,
}

#[derive(Clone, Copy, Debug)]
struct Slot {
    generation: u32,
    board: u8,
    seq: u8,
    state: SlotState,
    /// Deferred or abandoned: the pin the deferred reply must name.
    pin: PinRef,
    /// Deferred or abandoned: the latest the board may send the deferred reply.
    until: Instant,
}

const FREE_SLOT: Slot = Slot {
    generation: 0,
    board: 0,
    seq: 0,
    state: SlotState::Free,
    pin: PinRef::from_byte(0),
    until: Instant(0),
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
    Delivered(Address, PinRef),
    /// The slot's task took an event for this pin and has not called `wait_event` again yet:
    /// events for the pin meanwhile are held for it (one; a second is counted as dropped),
    /// so a task waiting on a pin in a loop misses none, whoever else waits on it.
    Lingering(Address, PinRef),
}

#[derive(Clone, Debug)]
struct WaiterSlot {
    generation: u32,
    state: Waiter,
    /// The task the slot belongs to (its waker): the task's next `wait_event` for the same
    /// pin takes this slot again.
    owner: Option<Waker>,
    /// An event that came while the slot was lingering.
    held: Option<PinEvent>,
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
    /// The last [`RECENT_LEN`] ended requests, written round-robin at `recent_next`.
    recent: [RecentEntry; RECENT_LEN],
    /// Where the next ended request goes (the oldest entry once the ring is full).
    recent_next: usize,
    /// Per bucket ([`held_bucket`]), the (board, seq) pairs that are pending (slot not free) or
    /// in `recent`: a sequence number whose bucket count is 0 is free.
    held: [u8; HELD_BUCKETS],
    /// PEC negotiated, one bit per board (32 boards per word: no 128-bit shifts on the M0).
    pec: [u32; BOARDS / 32],
    /// Boards the dispatcher has prepared (PEC on, failsafe set) since their last boot.
    ready: [u32; BOARDS / 32],
    pub(crate) diag: MbDiagnostics,
    waiters: [WaiterSlot; MAX_EVENT_WAITERS],
    unclaimed: Vec<PinEvent, UNCLAIMED_EVENTS>,
    /// Requests for the dispatcher, oldest first (a ring: taking the oldest moves nothing).
    /// Each holds a slot, so the queue never overflows; releasing the slot takes the job out.
    queue: Deque<Job, MAX_PENDING>,
    /// The failsafes the motherboard keeps alive.
    pub(crate) keepalive: Keepalives,
    /// A failsafe setting changed (the dispatcher must look at the keepalives again).
    keepalive_changed: bool,
    /// Per board: the event counter expected next, and the drops reported so far.
    pub(crate) events_in: crate::events_in::EventBook,
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
            recent: [None; RECENT_LEN],
            recent_next: 0,
            held: [0; HELD_BUCKETS],
            pec: [0; BOARDS / 32],
            ready: [0; BOARDS / 32],
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
                event_gaps: 0,
                events_lost: 0,
                pec_resyncs: 0,
                unexpected_reads: 0,
                listener_errors: 0,
            },
            waiters: [const {
                WaiterSlot {
                    generation: 0,
                    state: Waiter::Free,
                    owner: None,
                    held: None,
                }
            }; MAX_EVENT_WAITERS],
            unclaimed: Vec::new(),
            queue: Deque::new(),
            keepalive: Keepalives::new(),
            keepalive_changed: false,
            events_in: crate::events_in::EventBook::new(),
        }
    }

    /// True (once) when a failsafe setting changed since the last call.
    pub(crate) fn take_keepalive_changed(&mut self) -> bool {
        core::mem::take(&mut self.keepalive_changed)
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

    /// True when the dispatcher has prepared `board` since its last boot.
    pub(crate) fn ready(&self, board: Address) -> bool {
        let i = board_index(board);
        self.ready
            .get(i / 32)
            .is_some_and(|w| w >> (i % 32) & 1 != 0)
    }

    pub(crate) fn set_ready(&mut self, board: Address, on: bool) {
        let i = board_index(board);
        if let Some(w) = self.ready.get_mut(i / 32) {
            let bit = 1u32 << (i % 32);
            if on {
                *w |= bit;
            } else {
                *w &= !bit;
            }
        }
    }

    /// The failsafe of `board` was set to `ms` at `now`: keep it alive.
    pub(crate) fn failsafe_set(&mut self, board: Address, ms: u16, now: Instant) {
        self.keepalive.set(board, ms, now);
        self.keepalive_changed = true;
    }

    /// A sequence number for a request of the runtime's own (board set-up, keepalive), read
    /// back in the same transaction or not read at all: the board's next number not held by a pending or recent
    /// request. It is not held afterwards: its reply can only come in that transaction.
    pub(crate) fn fresh_seq(&mut self, board: Address) -> u8 {
        let b = board.get();
        let start = self.next_seq.get(board_index(board)).copied().unwrap_or(0);
        let mut seq = start;
        while self.seq_in_use(b, seq) {
            seq = seq.wrapping_add(1);
            if seq == start {
                break;
            }
        }
        if let Some(n) = self.next_seq.get_mut(board_index(board)) {
            *n = seq.wrapping_add(1);
        }
        seq
    }

    /// Queues a job (behind every job queued before) for the dispatcher, or for the internal
    /// daughterboard's worker when it is for address 0.
    ///
    /// # Errors
    /// The job back if the queue is full (it cannot be while each job holds a slot).
    pub(crate) fn enqueue(&mut self, job: Job) -> Result<(), Job> {
        self.queue.push_back(job)
    }

    /// Takes the oldest queued job that `wanted` accepts, keeping the others in their order.
    /// One queue serves the dispatcher and the internal daughterboard's worker (a second
    /// queue of 16 jobs would cost about 1.1 KiB of RAM): the oldest job is usually the one
    /// wanted; otherwise the queue is turned once around.
    fn take_first(&mut self, wanted: impl Fn(&Job) -> bool) -> Option<Job> {
        if self.queue.front().is_some_and(&wanted) {
            return self.queue.pop_front();
        }
        if !self.queue.iter().any(&wanted) {
            return None;
        }
        let mut found = None;
        for _ in 0..self.queue.len() {
            let Some(job) = self.queue.pop_front() else {
                break;
            };
            if found.is_none() && wanted(&job) {
                found = Some(job);
            } else {
                // Never full: one was just taken out.
                let _ = self.queue.push_back(job);
            }
        }
        found
    }

    /// The oldest job queued for the dispatcher, or for the internal daughterboard when
    /// `internal`.
    pub(crate) fn pop_job(&mut self, internal: bool) -> Option<Job> {
        let job = self.take_first(|j| j.meta.db.is_internal() == internal)?;
        if let Some(s) = self.slot_mut(job.meta.ticket) {
            if s.state == SlotState::Queued {
                s.state = SlotState::Sending;
            }
        }
        Some(job)
    }

    /// True while the request's caller still waits for it to be sent (queued or on the bus).
    pub(crate) fn wanted(&self, t: Ticket) -> bool {
        matches!(self.state(t), SlotState::Queued | SlotState::Sending)
    }

    /// The transfer of request `t` ended (or will not happen): a slot whose caller gave up
    /// while it was on the bus, and that no `pending` answer turned into a held deferred
    /// request, is freed now.
    pub(crate) fn transfer_ended(&mut self, t: Ticket) {
        let in_flight = self
            .slot(t)
            .is_some_and(|s| s.state == SlotState::Abandoned && s.until == ON_THE_BUS);
        if in_flight {
            self.retire(t.index, Ended::GaveUp);
        }
    }

    /// True when PEC is negotiated with `board`.
    pub(crate) fn pec(&self, board: Address) -> bool {
        let i = board_index(board);
        self.pec.get(i / 32).is_some_and(|w| w >> (i % 32) & 1 != 0)
    }

    pub(crate) fn set_pec(&mut self, board: Address, on: bool) {
        let i = board_index(board);
        let bit = 1u32 << (i % 32);
        if let Some(w) = self.pec.get_mut(i / 32) {
            if on {
                *w |= bit;
            } else {
                *w &= !bit;
            }
        }
    }

    /// True when (`board`, `seq`) is pending or among the recently ended. Looks through the
    /// slots and the ring only when a pair in its bucket is held.
    fn seq_in_use(&self, board: u8, seq: u8) -> bool {
        if self.held.get(held_bucket(board, seq)).copied().unwrap_or(1) == 0 {
            return false;
        }
        self.slots
            .iter()
            .any(|s| s.state != SlotState::Free && s.board == board && s.seq == seq)
            || self
                .recent
                .iter()
                .any(|r| matches!(*r, Some((b, s, _)) if b == board && s == seq))
    }

    /// Frees the abandoned deferred requests whose board can no longer answer (`until` is
    /// past); their pairs go to the ring as given up.
    fn expire_abandoned(&mut self, now: Instant) {
        for index in 0..MAX_PENDING {
            let expired = self
                .slots
                .get(index)
                .is_some_and(|s| s.state == SlotState::Abandoned && s.until.0 <= now.0);
            if expired {
                self.retire(index, Ended::GaveUp);
            }
        }
    }

    /// Claims a slot and the next free sequence number of `board` (skipping numbers still
    /// pending, held by an abandoned deferred request, or recently ended).
    ///
    /// # Errors
    /// [`LinkError::Busy`] when every slot is in use (abandoned deferred requests included),
    /// or every sequence number of the board.
    pub(crate) fn alloc(
        &mut self,
        board: Address,
        now: Instant,
    ) -> Result<(Ticket, u8), LinkError> {
        self.expire_abandoned(now);
        let Some(index) = self.slots.iter().position(|s| s.state == SlotState::Free) else {
            bump(&mut self.diag.busy);
            return Err(LinkError::Busy);
        };
        let b = board.get();
        let start = self.next_seq.get(board_index(board)).copied().unwrap_or(0);
        let mut candidate = start;
        let seq = loop {
            if !self.seq_in_use(b, candidate) {
                break candidate;
            }
            candidate = candidate.wrapping_add(1);
            if candidate == start {
                // All 256 numbers are pending or recently ended.
                bump(&mut self.diag.busy);
                return Err(LinkError::Busy);
            }
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
            pin: PinRef::from_byte(0),
            until: Instant(0),
        };
        // Never wraps: at most MAX_PENDING + RECENT_LEN pairs are held.
        if let Some(h) = self.held.get_mut(held_bucket(b, seq)) {
            *h = h.wrapping_add(1);
        }
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

    /// Marks the queued deferred request `meta` as answered `pending` at `now`: it waits for
    /// a deferred reply naming its pin until its hold time has passed. False if its caller
    /// already gave up: then the pair is held by a free slot as abandoned all the same (when
    /// one is free), since the board measures and will answer.
    pub(crate) fn defer(&mut self, meta: &JobMeta, now: Instant) -> bool {
        let Some((pin, hold_us)) = meta.deferred else {
            return false;
        };
        let until = now.plus_us(hold_us);
        let Some(s) = self.slot_mut(meta.ticket) else {
            return false;
        };
        s.pin = pin;
        match s.state {
            SlotState::Queued | SlotState::Sending => {
                s.state = SlotState::Deferred;
                s.until = until;
                true
            }
            // Its caller gave up while it was on the bus: the slot it kept holds the number
            // until the board's deadline.
            SlotState::Abandoned if s.until == ON_THE_BUS => {
                s.until = until;
                false
            }
            _ => false,
        }
    }

    /// Ends a queued or deferred request with `result` (the caller signals it). Counts the
    /// outcome. False if the request already ended.
    pub(crate) fn complete(
        &mut self,
        t: Ticket,
        result: &Result<x10_microcode::Payload, LinkError>,
    ) -> bool {
        let Some(s) = self.slot_mut(t) else {
            return false;
        };
        if !matches!(
            s.state,
            SlotState::Queued | SlotState::Sending | SlotState::Deferred
        ) {
            return false;
        }
        s.state = SlotState::Done;
        let d = &mut self.diag;
        match result {
            Ok(_) => bump(&mut d.completed),
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

    /// Applies what a request the board acknowledged changes on the motherboard's side: the
    /// PEC setting of a `set_pec`, the failsafe kept alive of a `set_failsafe`. Done when the
    /// transfer ends, whether or not the caller still waits (the board applied it either way).
    /// `now` gives the end of the transfer (read only for a `set_failsafe`).
    pub(crate) fn applied(
        &mut self,
        board: Address,
        meta: &JobMeta,
        now: impl FnOnce() -> Instant,
    ) {
        if let Some(ms) = meta.failsafe_change {
            self.keepalive.set(board, ms, now());
            self.keepalive_changed = true;
        }
    }

    /// The caller is done with a request: frees its slot, takes its job out of the queue if it
    /// is still there, and remembers how the request ended (in place of the oldest remembered
    /// one when the ring is full). A deferred request given up keeps its slot as `Abandoned`
    /// until the board can no longer answer it.
    pub(crate) fn release(&mut self, t: Ticket, ended: Ended) {
        if !self.queue.is_empty() {
            self.queue.retain(|j| j.meta.ticket != t);
        }
        let Some(s) = self.slot_mut(t) else {
            return;
        };
        if s.state == SlotState::Deferred && ended == Ended::GaveUp {
            s.state = SlotState::Abandoned;
            return;
        }
        if s.state == SlotState::Sending && ended == Ended::GaveUp {
            // On the bus: held until the transfer ends (see `transfer_ended`, `defer`).
            s.state = SlotState::Abandoned;
            s.until = ON_THE_BUS;
            return;
        }
        if s.state == SlotState::Abandoned {
            return;
        }
        self.retire(t.index, ended);
    }

    /// Frees slot `index` and moves its pair to the ring.
    fn retire(&mut self, index: usize, ended: Ended) {
        let Some(s) = self.slots.get_mut(index) else {
            return;
        };
        let (board, seq) = (s.board, s.seq);
        s.state = SlotState::Free;
        // The pair stays held: it moves from the slot to the ring. The entry it replaces is
        // no longer held.
        let at = self.recent_next;
        self.recent_next = if at + 1 >= RECENT_LEN { 0 } else { at + 1 };
        let Some(entry) = self.recent.get_mut(at) else {
            return;
        };
        if let Some((b, s, _)) = entry.replace((board, seq, ended)) {
            if let Some(h) = self.held.get_mut(held_bucket(b, s)) {
                *h = h.wrapping_sub(1);
            }
        }
    }

    /// The deferred request a deferred reply from `board` with `seq` for `pin` answers, if its
    /// caller still waits. A reply for an abandoned request is counted as late and frees its
    /// slot; any other reply that matches no waiting request is classified as a stray.
    pub(crate) fn take_deferred(&mut self, board: Address, seq: u8, pin: PinRef) -> Option<Ticket> {
        let found = self.slots.iter().enumerate().find_map(|(index, s)| {
            (matches!(s.state, SlotState::Deferred | SlotState::Abandoned)
                && s.board == board.get()
                && s.seq == seq
                && s.pin == pin)
                .then_some((index, s.generation, s.state))
        });
        match found {
            Some((index, generation, SlotState::Deferred)) => Some(Ticket { index, generation }),
            Some((index, _, _)) => {
                bump(&mut self.diag.late_replies);
                self.retire(index, Ended::GaveUp);
                None
            }
            None => {
                self.stray(board, seq);
                None
            }
        }
    }

    /// Counts a reply that matches no waiting request: late (its request gave up), duplicate
    /// (its request already completed) or unknown.
    pub(crate) fn stray(&mut self, board: Address, seq: u8) {
        // Newest first: the entries before `recent_next` (backwards), then those from it on.
        let (before, after) = self.recent.split_at(self.recent_next.min(RECENT_LEN));
        let ended = before
            .iter()
            .rev()
            .chain(after.iter().rev())
            .find_map(|r| match *r {
                Some((b, s, e)) if b == board.get() && s == seq => Some(e),
                _ => None,
            });
        let d = &mut self.diag;
        match ended {
            Some(Ended::GaveUp) => bump(&mut d.late_replies),
            Some(Ended::Completed) => bump(&mut d.duplicate_replies),
            None => bump(&mut d.unknown_replies),
        }
    }

    /// Registers the calling task (`task`, its waker) as waiting for the next event of
    /// `(board, pin)`, or returns an event at once: one held for this task since its last
    /// `wait_event` for the pin, or one nobody waited for (the unclaimed queue).
    ///
    /// # Errors
    /// [`LinkError::Busy`] when every waiter slot is taken by a task that waits.
    pub(crate) fn wait_for(
        &mut self,
        board: Address,
        pin: PinRef,
        task: &Waker,
    ) -> Result<Result<PinEvent, WaiterTicket>, LinkError> {
        let own = self.waiters.iter().position(|w| {
            matches!(w.state, Waiter::Lingering(b, p) if b == board && p == pin)
                && w.owner.as_ref().is_some_and(|o| o.will_wake(task))
        });
        if let Some(ev) = own
            .and_then(|i| self.waiters.get_mut(i))
            .and_then(|w| w.held.take())
        {
            return Ok(Ok(ev));
        }
        if let Some(i) = self
            .unclaimed
            .iter()
            .position(|e| e.source == board && e.pin == pin)
        {
            return Ok(Ok(self.unclaimed.remove(i)));
        }
        // Its own slot, else a free one, else one lingering for a task that stopped waiting
        // (an empty one first; a held event it drops is counted).
        let index = own
            .or_else(|| {
                self.waiters
                    .iter()
                    .position(|w| matches!(w.state, Waiter::Free))
            })
            .or_else(|| {
                self.waiters
                    .iter()
                    .position(|w| matches!(w.state, Waiter::Lingering(..)) && w.held.is_none())
            })
            .or_else(|| {
                self.waiters
                    .iter()
                    .position(|w| matches!(w.state, Waiter::Lingering(..)))
            });
        let Some(index) = index else {
            return Err(LinkError::Busy);
        };
        self.generation = self.generation.wrapping_add(1);
        let generation = self.generation;
        let mut dropped = false;
        if let Some(w) = self.waiters.get_mut(index) {
            dropped = w.held.is_some();
            *w = WaiterSlot {
                generation,
                state: Waiter::Waiting(board, pin),
                owner: Some(task.clone()),
                held: None,
            };
        }
        if dropped {
            bump(&mut self.diag.events_dropped);
        }
        Ok(Err(WaiterTicket { index, generation }))
    }

    /// The waiters an event for `(board, pin)` goes to: each is marked delivered. With none,
    /// the event is kept for a later `wait_event` (pushing out the oldest when full).
    pub(crate) fn deliver(&mut self, ev: &PinEvent, mut to: impl FnMut(usize)) {
        let mut any = false;
        let mut dropped = 0u32;
        for (i, w) in self.waiters.iter_mut().enumerate() {
            match w.state {
                Waiter::Waiting(b, p) if b == ev.source && p == ev.pin => {
                    w.state = Waiter::Delivered(b, p);
                    to(i);
                    any = true;
                }
                Waiter::Lingering(b, p) if b == ev.source && p == ev.pin => {
                    if w.held.is_some() {
                        // Its task has not come back for the last one: counted, not silent.
                        dropped += 1;
                    } else {
                        w.held = Some(ev.clone());
                    }
                    any = true;
                }
                _ => {}
            }
        }
        for _ in 0..dropped {
            bump(&mut self.diag.events_dropped);
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
                let delivered = matches!(w.state, Waiter::Delivered(..));
                w.state = Waiter::Free;
                w.owner = None;
                w.held = None;
                delivered
            }
            _ => false,
        }
    }

    /// The waiter took its event: the slot lingers for its task, holding the pin's next
    /// event until the task waits again.
    pub(crate) fn took(&mut self, t: WaiterTicket) {
        if let Some(w) = self.waiters.get_mut(t.index) {
            if w.generation == t.generation {
                if let Waiter::Delivered(b, p) = w.state {
                    w.state = Waiter::Lingering(b, p);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(a: u8) -> Address {
        Address::new(a).unwrap()
    }

    fn alloc(t: &mut Table, board: u8) -> Result<(Ticket, u8), LinkError> {
        t.alloc(addr(board), Instant(0))
    }

    fn alloc9(t: &mut Table, board: u8) -> (Ticket, u8) {
        alloc(t, board).unwrap()
    }

    /// (late, duplicate, unknown) after classifying one stray reply.
    fn classify(t: &mut Table, board: u8, seq: u8) -> (u32, u32, u32) {
        let before = (
            t.diag.late_replies,
            t.diag.duplicate_replies,
            t.diag.unknown_replies,
        );
        t.stray(addr(board), seq);
        (
            t.diag.late_replies - before.0,
            t.diag.duplicate_replies - before.1,
            t.diag.unknown_replies - before.2,
        )
    }

    /// The held counts recomputed from the slots and the ring.
    fn held_from_scratch(t: &Table) -> [u8; HELD_BUCKETS] {
        let mut held = [0u8; HELD_BUCKETS];
        for s in t.slots.iter().filter(|s| s.state != SlotState::Free) {
            held[held_bucket(s.board, s.seq)] += 1;
        }
        for &(b, s, _) in t.recent.iter().flatten() {
            held[held_bucket(b, s)] += 1;
        }
        held
    }

    #[test]
    fn sequence_numbers_skip_pending_and_recent_and_wrap() {
        let mut t = Table::new();
        let (kept, seq) = alloc(&mut t, 9).unwrap();
        assert_eq!(seq, 0);
        let mut seen = [0u8; 300];
        for s in seen.iter_mut() {
            let (ticket, seq) = alloc(&mut t, 9).unwrap();
            *s = seq;
            t.release(ticket, Ended::Completed);
        }
        // 1..=255, then 0 is still pending: 1, 2, ... again once they left the ring.
        let want: [u8; 300] = core::array::from_fn(|i| {
            if i < 255 {
                i as u8 + 1
            } else {
                (i - 254) as u8
            }
        });
        assert_eq!(seen, want);
        // The pending 0 and the last 16 ended (30..=45) are skipped by the next number.
        t.next_seq[9] = 30;
        assert_eq!(alloc(&mut t, 9).unwrap().1, 46);
        t.next_seq[9] = 0;
        assert_eq!(alloc(&mut t, 9).unwrap().1, 1);
        t.release(kept, Ended::GaveUp);
        assert_eq!(t.held, held_from_scratch(&t));
    }

    #[test]
    fn the_ring_keeps_the_last_16_ended_requests() {
        let mut t = Table::new();
        for _ in 0..RECENT_LEN + 4 {
            let (ticket, seq) = alloc(&mut t, 0x20).unwrap();
            let ended = if seq % 2 == 0 {
                Ended::Completed
            } else {
                Ended::GaveUp
            };
            t.release(ticket, ended);
        }
        // 0..=3 were pushed out by 16..=19.
        for seq in 0..4 {
            assert_eq!(classify(&mut t, 0x20, seq), (0, 0, 1), "seq {seq}");
        }
        for seq in 4..20 {
            let want = if seq % 2 == 0 { (0, 1, 0) } else { (1, 0, 0) };
            assert_eq!(classify(&mut t, 0x20, seq), want, "seq {seq}");
        }
        // Another board, or a number never used: unknown.
        assert_eq!(classify(&mut t, 0x21, 5), (0, 0, 1));
        assert_eq!(classify(&mut t, 0x20, 20), (0, 0, 1));
        // A pending request is not in the ring: a stray with its number is unknown.
        let (_, seq) = alloc(&mut t, 0x20).unwrap();
        assert_eq!(seq, 20);
        assert_eq!(classify(&mut t, 0x20, 20), (0, 0, 1));
    }

    fn pin(byte: u8) -> PinRef {
        PinRef::from_byte(byte)
    }

    /// A pulse-in's metadata: its deferred reply names `pin`, up to `hold_us` after `pending`.
    fn pulse_meta(ticket: Ticket, board: u8, seq: u8, pin: PinRef, hold_us: u64) -> JobMeta {
        JobMeta {
            ticket,
            db: addr(board),
            seq,
            read: Some(0),
            deferred: Some((pin, hold_us)),
            failsafe_change: None,
        }
    }

    #[test]
    fn the_dispatcher_and_the_internal_worker_each_take_their_oldest_job() {
        let mut t = Table::new();
        let queue = |t: &mut Table, board: u8| {
            let (ticket, seq) = alloc(t, board).unwrap();
            let meta = pulse_meta(ticket, board, seq, pin(0x80), 0);
            t.enqueue(Job {
                meta,
                frame: Vec::new(),
            })
            .unwrap();
            ticket
        };
        let a = queue(&mut t, 9);
        let b = queue(&mut t, 0);
        let c = queue(&mut t, 10);
        let d = queue(&mut t, 0);
        let ticket = |j: Option<Job>| j.map(|j| j.meta.ticket);
        assert_eq!(ticket(t.pop_job(true)), Some(b));
        assert_eq!(ticket(t.pop_job(false)), Some(a));
        assert_eq!(ticket(t.pop_job(true)), Some(d));
        assert_eq!(ticket(t.pop_job(true)), None);
        assert_eq!(ticket(t.pop_job(false)), Some(c));
        assert_eq!(ticket(t.pop_job(false)), None);
    }

    #[test]
    fn a_deferred_reply_must_name_the_requests_pin() {
        let mut t = Table::new();
        let (ticket, seq) = alloc(&mut t, 9).unwrap();
        assert!(t.defer(&pulse_meta(ticket, 9, seq, pin(0x80), 1_000), Instant(100)));
        // Same board and number, another pin: not this request's reply.
        assert_eq!(t.take_deferred(addr(9), seq, pin(0x82)), None);
        assert_eq!(t.state(ticket), SlotState::Deferred);
        assert_eq!(t.diag.unknown_replies, 1);
        assert_eq!(t.take_deferred(addr(9), seq, pin(0x80)), Some(ticket));
    }

    #[test]
    fn a_given_up_deferred_request_holds_its_number_until_the_boards_deadline() {
        let mut t = Table::new();
        let (ticket, seq) = alloc(&mut t, 9).unwrap();
        assert_eq!(seq, 0);
        // `pending` at 100; the board may answer until 1 100.
        assert!(t.defer(&pulse_meta(ticket, 9, seq, pin(0x80), 1_000), Instant(100)));
        t.release(ticket, Ended::GaveUp);
        assert_eq!(t.state(ticket), SlotState::Abandoned);
        assert_eq!(t.held, held_from_scratch(&t));
        // More than RECENT_LEN requests later, and with the counter back at 0, 0 is held.
        for _ in 0..RECENT_LEN + 1 {
            let (tk, s) = t.alloc(addr(9), Instant(1_099)).unwrap();
            assert_ne!(s, 0);
            t.release(tk, Ended::Completed);
        }
        // (1 has left the ring; 0 has not, being held by its slot.)
        t.next_seq[9] = 0;
        let (tk, s) = t.alloc(addr(9), Instant(1_099)).unwrap();
        assert_eq!(s, 1);
        t.release(tk, Ended::Completed);
        assert_eq!(t.state(ticket), SlotState::Abandoned);
        // At the deadline the slot is freed; the pair goes to the ring as given up.
        t.next_seq[9] = 0;
        let (tk, s) = t.alloc(addr(9), Instant(1_100)).unwrap();
        assert_eq!(t.state(ticket), SlotState::Free);
        // 0 and 1 are the newest entries of the ring: not reused yet, and a reply is late.
        assert_eq!(s, 2);
        t.release(tk, Ended::Completed);
        assert_eq!(classify(&mut t, 9, 0), (1, 0, 0));
        assert_eq!(t.held, held_from_scratch(&t));
    }

    #[test]
    fn a_late_deferred_reply_within_the_hold_is_counted_late_and_frees_the_slot() {
        let mut t = Table::new();
        let (ticket, seq) = alloc(&mut t, 9).unwrap();
        assert!(t.defer(&pulse_meta(ticket, 9, seq, pin(0x80), 1_000), Instant(100)));
        t.release(ticket, Ended::GaveUp);
        assert_eq!(t.take_deferred(addr(9), seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, 1);
        assert_eq!(t.state(ticket), SlotState::Free);
        // The pair is in the ring: a duplicate of the same reply is late again.
        assert_eq!(t.take_deferred(addr(9), seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, 2);
        assert_eq!(t.held, held_from_scratch(&t));
    }

    #[test]
    fn pending_for_a_request_already_given_up_holds_its_number_all_the_same() {
        let mut t = Table::new();
        let (ticket, seq) = alloc(&mut t, 9).unwrap();
        let meta = pulse_meta(ticket, 9, seq, pin(0x80), 1_000);
        t.enqueue(Job {
            meta,
            frame: Vec::new(),
        })
        .unwrap();
        assert!(t.pop_job(false).is_some());
        // The caller gave up while the request was on the bus; the board answered `pending`.
        t.release(ticket, Ended::GaveUp);
        assert!(!t.defer(&pulse_meta(ticket, 9, seq, pin(0x80), 1_000), Instant(100)));
        assert_eq!(
            t.slots
                .iter()
                .filter(|s| s.state == SlotState::Abandoned)
                .count(),
            1
        );
        assert!(t.seq_in_use(9, seq));
        assert_eq!(t.held, held_from_scratch(&t));
        // Its reply is late and ends the hold.
        assert_eq!(t.take_deferred(addr(9), seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, 1);
        assert!(t.slots.iter().all(|s| s.state == SlotState::Free));
        assert_eq!(t.held, held_from_scratch(&t));
    }

    /// Finding "wrong caller": a pulse-in whose caller gave up while it was on the bus freed
    /// its slot; when its `pending` answer came, a free slot was needed to hold its number,
    /// and with every slot taken there was none. The board's numbers then wrapped, the
    /// number went to a new pulse-in on the same pin, and the late deferred reply completed
    /// that request. Now a request on the bus keeps its slot until its transfer ends.
    #[test]
    fn a_deferred_reply_never_reaches_another_caller_when_every_slot_was_taken() {
        let mut t = Table::new();
        let (ticket, seq) = alloc9(&mut t, 9);
        assert_eq!(seq, 0);
        let meta = pulse_meta(ticket, 9, seq, pin(0x80), 1_000_000);
        t.enqueue(Job {
            meta,
            frame: Vec::new(),
        })
        .unwrap();
        // The dispatcher takes it; its caller gives up while it is on the bus.
        assert!(t.pop_job(false).is_some());
        t.release(ticket, Ended::GaveUp);
        // Other tasks take every slot there is.
        let mut others = Vec::<Ticket, MAX_PENDING>::new();
        while let Ok((tk, _)) = alloc(&mut t, 0x20) {
            others.push(tk).unwrap();
        }
        // The board answers `pending` at 100: it will send the width by 1 000 100.
        assert!(!t.defer(&meta, Instant(100)));
        for tk in others {
            t.release(tk, Ended::Completed);
        }
        // Board 9's numbers wrap; a new pulse-in on the same pin is pending at the end.
        let mut last = None;
        for _ in 0..300 {
            let (tk, s) = t.alloc(addr(9), Instant(200)).unwrap();
            assert_ne!(
                s, seq,
                "number 0 reused while the board may still answer it"
            );
            let m = pulse_meta(tk, 9, s, pin(0x80), 1_000_000);
            assert!(t.defer(&m, Instant(200)));
            if let Some((old, _)) = last.replace((tk, s)) {
                t.release(old, Ended::Completed);
            }
        }
        // The first pulse-in's reply comes: late, and nobody's.
        let late = t.diag.late_replies;
        assert_eq!(t.take_deferred(addr(9), seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, late + 1);
        assert_eq!(t.held, held_from_scratch(&t));
    }

    #[test]
    fn pec_bits_per_board() {
        let mut t = Table::new();
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

    /// The table against the plain rules it replaces: a list of the last 16 ended requests
    /// (oldest dropped first) and a search of every slot and that list for the board's next
    /// free number. Boards 0 and 64 share every bucket, 9 and 0x77 share some.
    #[test]
    fn matches_the_plain_model_over_random_operations() {
        const BOARDS_USED: [u8; 4] = [0, 64, 9, 0x77];
        let mut t = Table::new();
        let mut pending: [Option<(Ticket, u8, u8)>; MAX_PENDING] = [None; MAX_PENDING];
        let mut recent: Vec<(u8, u8, Ended), RECENT_LEN> = Vec::new();
        let mut next = [0u8; BOARDS];
        let mut rng: u32 = 0x1234_5678;
        let mut draw = |n: u32| {
            rng = rng.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (rng >> 8) % n
        };
        let (mut allocs, mut busy, mut skipped) = (0, 0, 0);
        for _ in 0..20_000 {
            let board = BOARDS_USED[draw(4) as usize];
            match draw(8) {
                // Allocate (more often than release, so the slots fill up at times).
                0..=3 => {
                    let free = pending.iter().position(Option::is_none);
                    let r = alloc(&mut t, board);
                    let Some(index) = free else {
                        assert_eq!(r, Err(LinkError::Busy));
                        busy += 1;
                        continue;
                    };
                    let in_use = |s: u8| {
                        pending
                            .iter()
                            .flatten()
                            .any(|&(_, b, q)| b == board && q == s)
                            || recent.iter().any(|&(b, q, _)| b == board && q == s)
                    };
                    let start = next[usize::from(board)];
                    let want = (0..=255u8)
                        .map(|i| start.wrapping_add(i))
                        .find(|&s| !in_use(s))
                        .unwrap();
                    if want != start {
                        skipped += 1;
                    }
                    next[usize::from(board)] = want.wrapping_add(1);
                    let (ticket, seq) = r.unwrap();
                    assert_eq!((ticket.index, seq), (index, want));
                    pending[index] = Some((ticket, board, seq));
                    allocs += 1;
                }
                // Release a random pending request (those in the first 4 slots rarely, so
                // that some stay pending while their board's numbers wrap).
                4..=6 => {
                    let i = draw(MAX_PENDING as u32) as usize;
                    if i < 4 && draw(32) != 0 {
                        continue;
                    }
                    if let Some((ticket, b, s)) = pending[i].take() {
                        let ended = if draw(2) == 0 {
                            Ended::Completed
                        } else {
                            Ended::GaveUp
                        };
                        t.release(ticket, ended);
                        // Released twice: nothing happens.
                        t.release(ticket, Ended::GaveUp);
                        if recent.is_full() {
                            recent.remove(0);
                        }
                        recent.push((b, s, ended)).unwrap();
                    }
                }
                // Move the board's next number back a little, onto numbers just used.
                7 if draw(4) == 0 => {
                    let n = next[usize::from(board)].wrapping_sub(draw(40) as u8);
                    next[usize::from(board)] = n;
                    t.next_seq[usize::from(board)] = n;
                }
                // A stray reply near the board's current numbers.
                _ => {
                    let seq = next[usize::from(board)].wrapping_sub(draw(24) as u8);
                    let want = match recent
                        .iter()
                        .rev()
                        .find(|&&(b, s, _)| b == board && s == seq)
                    {
                        Some((_, _, Ended::GaveUp)) => (1, 0, 0),
                        Some((_, _, Ended::Completed)) => (0, 1, 0),
                        None => (0, 0, 1),
                    };
                    assert_eq!(classify(&mut t, board, seq), want);
                }
            }
            assert_eq!(t.held, held_from_scratch(&t));
        }
        // The run went through every case.
        assert!(
            allocs > 4_000 && busy > 1_000 && skipped > 100,
            "{allocs} {busy} {skipped}"
        );
    }
}
