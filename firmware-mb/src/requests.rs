//! The pending requests and their sequence numbers: one slot per outstanding request, keyed
//! by (board, sequence number), the per-board sequence counters, and the ring of recently
//! ended requests that classifies stray replies. Owns [`Requests`]: pure bookkeeping, no
//! waiting, no I/O (the motherboard keeps it in its table, behind one blocking mutex; the
//! signals that hand a result to its caller are the motherboard's).
//!
//! A request ends exactly once: only a `Queued`, `Sending` or `Deferred` slot can become
//! `Done`, and a generation number on each slot stops a stale job or reply from completing a
//! slot that has been reused.
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

use x10_devices::LinkError;
use x10_hal::time::Instant;
use x10_microcode::{Address, Payload, PinRef};

use crate::board_set::{board_index, BOARDS};
use crate::diag::{bump, count_outcome, MbDiagnostics};

/// Requests outstanding at the same time (all boards together).
pub const MAX_PENDING: usize = 16;
/// Ended requests remembered to classify stray replies (late / duplicate / unknown); their
/// sequence numbers are not reused while remembered.
pub const RECENT_LEN: usize = 16;

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
    /// Deferred: its `pending` came with a check, so its deferred reply must carry one too
    /// (whatever the board's PEC state by then: a board that restarted has PEC off, and an
    /// unchecked reply with the old number proves nothing).
    checked: bool,
}

const FREE_SLOT: Slot = Slot {
    generation: 0,
    board: 0,
    seq: 0,
    state: SlotState::Free,
    pin: PinRef::from_byte(0),
    until: Instant(0),
    checked: false,
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

/// The pending slots, the sequence counters and the ring of recently ended requests.
pub(crate) struct Requests {
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
}

impl Requests {
    pub(crate) const fn new() -> Requests {
        Requests {
            slots: [FREE_SLOT; MAX_PENDING],
            generation: 0,
            next_seq: [0; BOARDS],
            recent: [None; RECENT_LEN],
            recent_next: 0,
            held: [0; HELD_BUCKETS],
        }
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

    /// The earliest instant an abandoned deferred request's slot frees itself, if any.
    pub(crate) fn next_expiry(&self) -> Option<Instant> {
        self.slots
            .iter()
            .filter(|s| s.state == SlotState::Abandoned && s.until != ON_THE_BUS)
            .map(|s| s.until)
            .min_by_key(|u| u.0)
    }

    /// Claims a slot and the next free sequence number of `board` (skipping numbers still
    /// pending, held by an abandoned deferred request, or recently ended). Counted in
    /// `requests`, or `busy`.
    ///
    /// # Errors
    /// [`LinkError::Busy`] when every slot is in use (abandoned deferred requests included),
    /// or every sequence number of the board.
    #[cfg(test)]
    pub(crate) fn alloc(
        &mut self,
        board: Address,
        now: Instant,
        diag: &mut MbDiagnostics,
    ) -> Result<(Ticket, u8), LinkError> {
        let r = self.try_alloc(board, now);
        bump(match r {
            Ok(_) => &mut diag.requests,
            Err(_) => &mut diag.busy,
        });
        r
    }

    /// [`Requests::alloc`] without counting (a caller that waits for a slot counts once).
    ///
    /// # Errors
    /// As [`Requests::alloc`].
    pub(crate) fn try_alloc(
        &mut self,
        board: Address,
        now: Instant,
    ) -> Result<(Ticket, u8), LinkError> {
        self.expire_abandoned(now);
        let Some(index) = self.slots.iter().position(|s| s.state == SlotState::Free) else {
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
            checked: false,
        };
        // Never wraps: at most MAX_PENDING + RECENT_LEN pairs are held.
        if let Some(h) = self.held.get_mut(held_bucket(b, seq)) {
            *h = h.wrapping_add(1);
        }
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

    /// The dispatcher (or the internal worker) took request `t` from the queue: a queued
    /// request is on the bus now.
    pub(crate) fn sending(&mut self, t: Ticket) {
        if let Some(s) = self.slot_mut(t) {
            if s.state == SlotState::Queued {
                s.state = SlotState::Sending;
            }
        }
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

    /// Marks the queued deferred request `t` as answered `pending` at `now` (`checked`: that
    /// reply carried its check): it waits for a deferred reply naming `pin` until `hold_us`
    /// after `now` (`deferred`: the request's pin and hold; `None`, not a deferred request:
    /// nothing happens). False if its caller
    /// already gave up: then the pair is held by a free slot as abandoned all the same (when
    /// one is free), since the board measures and will answer.
    pub(crate) fn defer(
        &mut self,
        t: Ticket,
        deferred: Option<(PinRef, u64)>,
        checked: bool,
        now: Instant,
    ) -> bool {
        let Some((pin, hold_us)) = deferred else {
            return false;
        };
        let until = now.plus_us(hold_us);
        let Some(s) = self.slot_mut(t) else {
            return false;
        };
        s.pin = pin;
        s.checked = checked;
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

    /// Request `t`, a deferred operation on `pin`, ends without a reply that proves the board
    /// refused it: the board may be measuring. Its pair stays held until `hold_us` after `now`
    /// (the board's deadline): once its caller is done with it, the slot is kept as
    /// `Abandoned` until then (see `release`), and a slot whose caller already gave up while
    /// it was on the bus is kept until then too.
    pub(crate) fn hold(&mut self, t: Ticket, (pin, hold_us): (PinRef, u64), now: Instant) {
        let until = now.plus_us(hold_us);
        let Some(s) = self.slot_mut(t) else {
            return;
        };
        match s.state {
            SlotState::Queued | SlotState::Sending => {
                s.pin = pin;
                s.until = until;
            }
            SlotState::Abandoned if s.until == ON_THE_BUS => {
                s.pin = pin;
                s.until = until;
            }
            _ => {}
        }
    }

    /// Ends a queued or deferred request with `result` (the caller signals it). Counts the
    /// outcome. False if the request already ended.
    pub(crate) fn complete(
        &mut self,
        t: Ticket,
        result: &Result<Payload, LinkError>,
        diag: &mut MbDiagnostics,
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
        if s.state == SlotState::Deferred {
            // Answered: nothing more to hold it for.
            s.until = Instant(0);
        }
        s.state = SlotState::Done;
        count_outcome(diag, result);
        true
    }

    /// The caller is done with a request: frees its slot and remembers how the request ended
    /// (in place of the oldest remembered one when the ring is full). A deferred request
    /// given up keeps its slot as `Abandoned` until the board can no longer answer it, and
    /// one given up on the bus until its transfer ends.
    pub(crate) fn release(&mut self, t: Ticket, ended: Ended) {
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
        if s.state == SlotState::Done && s.until.0 != 0 {
            // Held by `hold`: the board may still answer it.
            s.state = SlotState::Abandoned;
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
    /// caller still waits (`checked`: the reply carried its check; one without cannot answer
    /// a request whose `pending` had one, and is counted in `bad_events`). A reply for an abandoned request is counted as late and frees its
    /// slot; any other reply that matches no waiting request is classified as a stray.
    pub(crate) fn take_deferred(
        &mut self,
        board: Address,
        seq: u8,
        pin: PinRef,
        checked: bool,
        diag: &mut MbDiagnostics,
    ) -> Option<Ticket> {
        let found = self.slots.iter().enumerate().find_map(|(index, s)| {
            (matches!(s.state, SlotState::Deferred | SlotState::Abandoned)
                && s.board == board.get()
                && s.seq == seq
                && s.pin == pin)
                .then_some((index, s.generation, s.state, s.checked))
        });
        match found {
            // Its `pending` was checked: an unchecked reply cannot complete it (it waits on
            // for a checked one, or its deadline).
            Some((_, _, SlotState::Deferred, true)) if !checked => {
                bump(&mut diag.bad_events);
                None
            }
            Some((index, generation, SlotState::Deferred, _)) => Some(Ticket { index, generation }),
            Some((index, _, _, _)) => {
                bump(&mut diag.late_replies);
                self.retire(index, Ended::GaveUp);
                None
            }
            None => {
                self.stray(board, seq, diag);
                None
            }
        }
    }

    /// Counts a reply that matches no waiting request: late (its request gave up), duplicate
    /// (its request already completed) or unknown.
    pub(crate) fn stray(&self, board: Address, seq: u8, diag: &mut MbDiagnostics) {
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
        let d = diag;
        match ended {
            Some(Ended::GaveUp) => bump(&mut d.late_replies),
            Some(Ended::Completed) => bump(&mut d.duplicate_replies),
            None => bump(&mut d.unknown_replies),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use heapless::Vec;

    fn addr(a: u8) -> Address {
        Address::new(a).unwrap()
    }

    fn pin(byte: u8) -> PinRef {
        PinRef::from_byte(byte)
    }

    /// The requests with their counters.
    struct T {
        r: Requests,
        diag: MbDiagnostics,
    }

    impl T {
        fn new() -> T {
            T {
                r: Requests::new(),
                diag: MbDiagnostics::new(),
            }
        }

        fn alloc_at(&mut self, board: u8, now: u64) -> Result<(Ticket, u8), LinkError> {
            self.r.alloc(addr(board), Instant(now), &mut self.diag)
        }

        fn alloc(&mut self, board: u8) -> Result<(Ticket, u8), LinkError> {
            self.alloc_at(board, 0)
        }

        fn release(&mut self, t: Ticket, ended: Ended) {
            self.r.release(t, ended);
        }

        fn state(&self, t: Ticket) -> SlotState {
            self.r.state(t)
        }

        /// A pulse-in on `pin` answered `pending` at `now`; the board may answer until
        /// `hold_us` later.
        fn defer(&mut self, t: Ticket, pin: PinRef, hold_us: u64, now: u64) -> bool {
            self.r.defer(t, Some((pin, hold_us)), false, Instant(now))
        }

        fn take_deferred(&mut self, board: u8, seq: u8, pin: PinRef) -> Option<Ticket> {
            self.r
                .take_deferred(addr(board), seq, pin, false, &mut self.diag)
        }

        /// (late, duplicate, unknown) after classifying one stray reply.
        fn classify(&mut self, board: u8, seq: u8) -> (u32, u32, u32) {
            let d = &self.diag;
            let before = (d.late_replies, d.duplicate_replies, d.unknown_replies);
            self.r.stray(addr(board), seq, &mut self.diag);
            let d = &self.diag;
            (
                d.late_replies - before.0,
                d.duplicate_replies - before.1,
                d.unknown_replies - before.2,
            )
        }

        /// The held counts match those recomputed from the slots and the ring.
        fn check_held(&self) {
            let mut held = [0u8; HELD_BUCKETS];
            for s in self.r.slots.iter().filter(|s| s.state != SlotState::Free) {
                held[held_bucket(s.board, s.seq)] += 1;
            }
            for &(b, s, _) in self.r.recent.iter().flatten() {
                held[held_bucket(b, s)] += 1;
            }
            assert_eq!(self.r.held, held);
        }
    }

    #[test]
    fn sequence_numbers_skip_pending_and_recent_and_wrap() {
        let mut t = T::new();
        let (kept, seq) = t.alloc(9).unwrap();
        assert_eq!(seq, 0);
        let mut seen = [0u8; 300];
        for s in seen.iter_mut() {
            let (ticket, seq) = t.alloc(9).unwrap();
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
        t.r.next_seq[9] = 30;
        assert_eq!(t.alloc(9).unwrap().1, 46);
        t.r.next_seq[9] = 0;
        assert_eq!(t.alloc(9).unwrap().1, 1);
        t.release(kept, Ended::GaveUp);
        t.check_held();
    }

    #[test]
    fn the_ring_keeps_the_last_16_ended_requests() {
        let mut t = T::new();
        for _ in 0..RECENT_LEN + 4 {
            let (ticket, seq) = t.alloc(0x20).unwrap();
            let ended = if seq % 2 == 0 {
                Ended::Completed
            } else {
                Ended::GaveUp
            };
            t.release(ticket, ended);
        }
        // 0..=3 were pushed out by 16..=19.
        for seq in 0..4 {
            assert_eq!(t.classify(0x20, seq), (0, 0, 1), "seq {seq}");
        }
        for seq in 4..20 {
            let want = if seq % 2 == 0 { (0, 1, 0) } else { (1, 0, 0) };
            assert_eq!(t.classify(0x20, seq), want, "seq {seq}");
        }
        // Another board, or a number never used: unknown.
        assert_eq!(t.classify(0x21, 5), (0, 0, 1));
        assert_eq!(t.classify(0x20, 20), (0, 0, 1));
        // A pending request is not in the ring: a stray with its number is unknown.
        let (_, seq) = t.alloc(0x20).unwrap();
        assert_eq!(seq, 20);
        assert_eq!(t.classify(0x20, 20), (0, 0, 1));
    }

    #[test]
    fn a_deferred_reply_must_name_the_requests_pin() {
        let mut t = T::new();
        let (ticket, seq) = t.alloc(9).unwrap();
        assert!(t.defer(ticket, pin(0x80), 1_000, 100));
        // Same board and number, another pin: not this request's reply.
        assert_eq!(t.take_deferred(9, seq, pin(0x82)), None);
        assert_eq!(t.state(ticket), SlotState::Deferred);
        assert_eq!(t.diag.unknown_replies, 1);
        assert_eq!(t.take_deferred(9, seq, pin(0x80)), Some(ticket));
    }

    /// The fuzz finding `reboot-then-unchecked-deferred-reply`: a pulse-in whose `pending`
    /// came checked is completed only by a checked deferred reply; an unchecked one with its
    /// number (from a board that restarted, so has PEC off, or a corrupted frame) is counted
    /// and the request waits on.
    #[test]
    fn a_checked_pending_wants_a_checked_deferred_reply() {
        let mut t = T::new();
        let (ticket, seq) = t.alloc(9).unwrap();
        assert!(t
            .r
            .defer(ticket, Some((pin(0x80), 1_000)), true, Instant(100)));
        assert_eq!(
            t.r.take_deferred(addr(9), seq, pin(0x80), false, &mut t.diag),
            None
        );
        assert_eq!(t.diag.bad_events, 1);
        assert_eq!(t.state(ticket), SlotState::Deferred);
        assert_eq!(
            t.r.take_deferred(addr(9), seq, pin(0x80), true, &mut t.diag),
            Some(ticket)
        );
        // An unchecked `pending` takes either.
        let (other, seq) = t.alloc(9).unwrap();
        assert!(t
            .r
            .defer(other, Some((pin(0x82), 1_000)), false, Instant(100)));
        assert_eq!(
            t.r.take_deferred(addr(9), seq, pin(0x82), false, &mut t.diag),
            Some(other)
        );
    }

    #[test]
    fn a_given_up_deferred_request_holds_its_number_until_the_boards_deadline() {
        let mut t = T::new();
        let (ticket, seq) = t.alloc(9).unwrap();
        assert_eq!(seq, 0);
        // `pending` at 100; the board may answer until 1 100.
        assert!(t.defer(ticket, pin(0x80), 1_000, 100));
        t.release(ticket, Ended::GaveUp);
        assert_eq!(t.state(ticket), SlotState::Abandoned);
        t.check_held();
        // More than RECENT_LEN requests later, and with the counter back at 0, 0 is held.
        for _ in 0..RECENT_LEN + 1 {
            let (tk, s) = t.alloc_at(9, 1_099).unwrap();
            assert_ne!(s, 0);
            t.release(tk, Ended::Completed);
        }
        // (1 has left the ring; 0 has not, being held by its slot.)
        t.r.next_seq[9] = 0;
        let (tk, s) = t.alloc_at(9, 1_099).unwrap();
        assert_eq!(s, 1);
        t.release(tk, Ended::Completed);
        assert_eq!(t.state(ticket), SlotState::Abandoned);
        // At the deadline the slot is freed; the pair goes to the ring as given up.
        t.r.next_seq[9] = 0;
        let (tk, s) = t.alloc_at(9, 1_100).unwrap();
        assert_eq!(t.state(ticket), SlotState::Free);
        // 0 and 1 are the newest entries of the ring: not reused yet, and a reply is late.
        assert_eq!(s, 2);
        t.release(tk, Ended::Completed);
        assert_eq!(t.classify(9, 0), (1, 0, 0));
        t.check_held();
    }

    #[test]
    fn a_late_deferred_reply_within_the_hold_is_counted_late_and_frees_the_slot() {
        let mut t = T::new();
        let (ticket, seq) = t.alloc(9).unwrap();
        assert!(t.defer(ticket, pin(0x80), 1_000, 100));
        t.release(ticket, Ended::GaveUp);
        assert_eq!(t.take_deferred(9, seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, 1);
        assert_eq!(t.state(ticket), SlotState::Free);
        // The pair is in the ring: a duplicate of the same reply is late again.
        assert_eq!(t.take_deferred(9, seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, 2);
        t.check_held();
    }

    #[test]
    fn pending_for_a_request_already_given_up_holds_its_number_all_the_same() {
        let mut t = T::new();
        let (ticket, seq) = t.alloc(9).unwrap();
        // The request goes on the bus.
        t.r.sending(ticket);
        // The caller gave up while the request was on the bus; the board answered `pending`.
        t.release(ticket, Ended::GaveUp);
        assert!(!t.defer(ticket, pin(0x80), 1_000, 100));
        assert_eq!(
            t.r.slots
                .iter()
                .filter(|s| s.state == SlotState::Abandoned)
                .count(),
            1
        );
        assert!(t.r.seq_in_use(9, seq));
        t.check_held();
        // Its reply is late and ends the hold.
        assert_eq!(t.take_deferred(9, seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, 1);
        assert!(t.r.slots.iter().all(|s| s.state == SlotState::Free));
        t.check_held();
    }

    /// Finding "wrong caller": a pulse-in whose caller gave up while it was on the bus freed
    /// its slot; when its `pending` answer came, a free slot was needed to hold its number,
    /// and with every slot taken there was none. The board's numbers then wrapped, the
    /// number went to a new pulse-in on the same pin, and the late deferred reply completed
    /// that request. Now a request on the bus keeps its slot until its transfer ends.
    #[test]
    fn a_deferred_reply_never_reaches_another_caller_when_every_slot_was_taken() {
        let mut t = T::new();
        let (ticket, seq) = t.alloc(9).unwrap();
        assert_eq!(seq, 0);
        // The dispatcher takes it; its caller gives up while it is on the bus.
        t.r.sending(ticket);
        t.release(ticket, Ended::GaveUp);
        // Other tasks take every slot there is.
        let mut others = Vec::<Ticket, MAX_PENDING>::new();
        while let Ok((tk, _)) = t.alloc(0x20) {
            others.push(tk).unwrap();
        }
        // The board answers `pending` at 100: it will send the width by 1 000 100.
        assert!(!t.defer(ticket, pin(0x80), 1_000_000, 100));
        for tk in others {
            t.release(tk, Ended::Completed);
        }
        // Board 9's numbers wrap; a new pulse-in on the same pin is pending at the end.
        let mut last = None;
        for _ in 0..300 {
            let (tk, s) = t.alloc_at(9, 200).unwrap();
            assert_ne!(
                s, seq,
                "number 0 reused while the board may still answer it"
            );
            assert!(t.defer(tk, pin(0x80), 1_000_000, 200));
            if let Some((old, _)) = last.replace((tk, s)) {
                t.release(old, Ended::Completed);
            }
        }
        // The first pulse-in's reply comes: late, and nobody's.
        let late = t.diag.late_replies;
        assert_eq!(t.take_deferred(9, seq, pin(0x80)), None);
        assert_eq!(t.diag.late_replies, late + 1);
        t.check_held();
    }

    /// The requests against the plain rules they replace: a list of the last 16 ended
    /// requests (oldest dropped first) and a search of every slot and that list for the
    /// board's next free number. Boards 0 and 64 share every bucket, 9 and 0x77 share some.
    #[test]
    fn matches_the_plain_model_over_random_operations() {
        const BOARDS_USED: [u8; 4] = [0, 64, 9, 0x77];
        let mut t = T::new();
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
                    let r = t.alloc(board);
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
                    t.r.next_seq[usize::from(board)] = n;
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
                    assert_eq!(t.classify(board, seq), want);
                }
            }
            t.check_held();
        }
        // The run went through every case.
        assert!(
            allocs > 4_000 && busy > 1_000 && skipped > 100,
            "{allocs} {busy} {skipped}"
        );
    }
}
