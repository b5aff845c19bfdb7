//! The motherboard: request/response over the pending table, the internal daughterboard,
//! event routing.
//!
//! Two parts: [`MbCore`], everything robot tasks and the dispatcher share (configuration,
//! pending table, signals), which names no board type, so that the robot programs' handle
//! [`crate::X10`] is one concrete type; and [`Motherboard`], the core plus the internal
//! daughterboard on the board's own ports, whose tasks ([`Motherboard::run`]) serve it.

use core::cell::RefCell;
use core::ops::Deref;

use embassy_futures::join::join4;
use embassy_futures::select::{select, select3, Either, Either3};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex as BlockingMutex;
use embassy_sync::signal::Signal;
use firmware_db::{Daughterboard, Ports, REPLY_BUF_LEN};
use heapless::Vec;
use x10_devices::{LinkError, PinEvent};
use x10_hal::bus::{BusError, MultiMaster};
use x10_hal::time::{EmbassyClock, Instant};
use x10_microcode::{
    Address, Event, EventKind, Op, Payload, PinRef, Reply, Request, Status, MAX_FRAME_LEN,
};

use crate::config::MbConfig;
use crate::diag::{bump, MbDiagnostics};
use crate::keepalive::{failsafe_change, KeepaliveOp, Next};
use crate::observe::{CallObserver, CallRecord};
use crate::table::{
    Ended, Job, JobMeta, SlotState, Table, Ticket, WaiterTicket, MAX_EVENT_WAITERS, MAX_PENDING,
};

/// The raw mutex of every lock and signal of the motherboard: a critical section, so the
/// shared state can live in a `static` and robot tasks may run on any executor.
pub(crate) type M = CriticalSectionRawMutex;

/// Now, in µs since boot (embassy-time).
pub(crate) fn now() -> Instant {
    Instant(embassy_time::Instant::now().as_micros())
}

/// Sleeps until `at` (embassy-time).
pub(crate) async fn sleep_until(at: Instant) {
    embassy_time::Timer::at(embassy_time::Instant::from_micros(at.as_micros())).await
}

/// Requests that can wait for the dispatcher: one per pending slot, so a caller that holds a
/// slot never waits for room in the queue ([`MAX_PENDING`]).
pub const REQUEST_QUEUE_LEN: usize = MAX_PENDING;

/// What robot tasks, the dispatcher and the keepalive share: configuration, the pending
/// table, the request queues and the signals that end requests. It names no board type; a
/// [`Motherboard`] holds one (and dereferences to it), and [`crate::X10`] is a reference to it.
pub struct MbCore {
    pub(crate) config: MbConfig,
    /// Signalled when a job for the bus is queued (the dispatcher takes it from the table).
    job_ready: Signal<M, ()>,
    /// Signalled when a job for the internal daughterboard is queued.
    internal_ready: Signal<M, ()>,
    /// Signalled for the dispatcher when a failsafe kept alive changes (set, stopped, board
    /// rebooted): its next keepalive may be due sooner.
    pub(crate) keepalive_changed: Signal<M, ()>,
    /// The same for the internal daughterboard's worker.
    internal_keepalive_changed: Signal<M, ()>,
    table: BlockingMutex<M, RefCell<Table>>,
    done: [Signal<M, Result<Payload, LinkError>>; MAX_PENDING],
    waiters: [Signal<M, PinEvent>; MAX_EVENT_WAITERS],
    observer: Option<&'static dyn CallObserver>,
}

/// The motherboard runtime: the shared [`MbCore`] and the internal daughterboard (address 0)
/// on the board's own ports `P`. It names no chip.
///
/// Give it a `'static` home (a `StaticCell` on a board; the simulator leaks one per run), run
/// [`Motherboard::run`] once in a task of its own, and hand [`Motherboard::handle`] (an
/// [`crate::X10`]) to any number of robot tasks.
pub struct Motherboard<P: Ports> {
    core: MbCore,
    internal: Daughterboard<M, P>,
}

impl<P: Ports> Deref for Motherboard<P> {
    type Target = MbCore;

    fn deref(&self) -> &MbCore {
        &self.core
    }
}

/// Frees a request's slot when the caller's future is dropped before it ended.
struct SlotGuard<'a> {
    mb: &'a MbCore,
    ticket: Ticket,
    armed: bool,
}

impl SlotGuard<'_> {
    fn release(mut self, ended: Ended) {
        self.armed = false;
        self.mb.with(|t| t.release(self.ticket, ended));
    }

    /// The deadline passed: the request times out, unless it ended just now.
    fn expire(mut self) -> Result<Payload, LinkError> {
        self.armed = false;
        let mb = self.mb;
        let ticket = self.ticket;
        mb.with(|t| {
            let taken = if t.state(ticket) == SlotState::Done {
                mb.done.get(ticket.index).and_then(Signal::try_take)
            } else {
                None
            };
            match taken {
                Some(r) => {
                    t.release(ticket, Ended::Completed);
                    r
                }
                None => {
                    bump(&mut t.diag.timeouts);
                    t.release(ticket, Ended::GaveUp);
                    Err(LinkError::Timeout)
                }
            }
        })
    }
}

impl Drop for SlotGuard<'_> {
    fn drop(&mut self) {
        if self.armed {
            let ticket = self.ticket;
            self.mb.with(|t| {
                bump(&mut t.diag.cancelled);
                t.release(ticket, Ended::GaveUp);
            });
        }
    }
}

/// Unregisters an event waiter whose future is dropped; an event already delivered to it goes
/// back to the front of the unclaimed queue.
struct WaiterGuard<'a> {
    mb: &'a MbCore,
    ticket: WaiterTicket,
    armed: bool,
}

impl Drop for WaiterGuard<'_> {
    fn drop(&mut self) {
        if !self.armed {
            return;
        }
        let (mb, ticket) = (self.mb, self.ticket);
        mb.with(|t| {
            if t.unwait(ticket) {
                if let Some(ev) = mb.waiters.get(ticket.index).and_then(Signal::try_take) {
                    t.keep_unclaimed(ev, true);
                }
            }
        });
    }
}

/// The last `set_pec` of an operation (or of a batch's items).
pub(crate) fn pec_change(op: &Op<'_>) -> Option<bool> {
    match op {
        Op::SetPec(on) => Some(*on),
        Op::Batch(b) => b.iter().fold(None, |acc, item| match item {
            Op::SetPec(on) => Some(on),
            _ => acc,
        }),
        _ => None,
    }
}

pub(crate) fn link_error(e: BusError) -> LinkError {
    match e {
        BusError::Nack => LinkError::Nack,
        BusError::ArbitrationLost => LinkError::ArbitrationLost,
        BusError::Timeout => LinkError::Timeout,
        BusError::Bus | BusError::Overrun => LinkError::Bus,
    }
}

/// The operation of a request frame (PEC byte excluded).
pub(crate) fn request_op(frame: &[u8]) -> Option<Op<'_>> {
    let f = x10_microcode::RequestFrame::new_checked(frame).ok()?;
    let (fn_op, port) = (f.fn_op(), f.port_byte());
    let data = frame.get(x10_microcode::REQUEST_HEADER_LEN..)?;
    Op::parse(fn_op, port, data).ok()
}

/// What a finished transfer means for its request.
pub(crate) enum Outcome {
    Complete(Result<Payload, LinkError>),
    Defer,
}

impl<P: Ports> Motherboard<P> {
    /// A motherboard with its internal daughterboard on `internal_ports`.
    /// The internal board always has address 0, whatever `config.internal.address` says.
    pub fn new(config: MbConfig, internal_ports: P) -> Self {
        let mut internal = config.internal;
        internal.address = Address::INTERNAL;
        Motherboard {
            core: MbCore {
                config,
                job_ready: Signal::new(),
                internal_ready: Signal::new(),
                keepalive_changed: Signal::new(),
                internal_keepalive_changed: Signal::new(),
                table: BlockingMutex::new(RefCell::new(Table::new())),
                done: [const { Signal::new() }; MAX_PENDING],
                waiters: [const { Signal::new() }; MAX_EVENT_WAITERS],
                observer: None,
            },
            internal: Daughterboard::new(internal_ports, internal),
        }
    }

    /// The same motherboard, reporting every finished call to `observer` (the simulator
    /// traces robot calls this way; boards leave it unset).
    pub fn with_observer(mut self, observer: &'static dyn CallObserver) -> Self {
        self.core.observer = Some(observer);
        self
    }

    /// The shared part, which robot tasks reach through [`crate::X10`].
    pub fn core(&self) -> &MbCore {
        &self.core
    }

    /// The internal daughterboard (address 0).
    pub fn internal(&self) -> &Daughterboard<M, P> {
        &self.internal
    }

    /// The robot programs' handle: one concrete, `Copy` type whatever the board.
    pub fn handle(&'static self) -> crate::X10 {
        crate::X10::new(&self.core)
    }

    /// Runs the motherboard; never returns. Run it in a task of its own: the dispatcher with
    /// its DB-interrupt listener on `bus`, the internal daughterboard (its requests, its
    /// background work, the routing of its events). The failsafe keepalive needs no task of
    /// its own: the dispatcher sends it to external boards between jobs, the internal
    /// worker to the internal board.
    pub async fn run<B: MultiMaster>(&self, bus: B) -> ! {
        let (never, _, _, _) = join4(
            self.core.run_dispatcher(bus),
            self.run_internal_requests(),
            self.internal.run_background(EmbassyClock),
            self.run_internal_events(),
        )
        .await;
        never
    }

    /// Serves the requests to the internal daughterboard, oldest first: the same bytes as on
    /// the bus, the same reply parsing; and keeps a failsafe set on it alive, between two
    /// requests, as the dispatcher does for external boards. Never returns. Part of
    /// [`Motherboard::run`].
    pub async fn run_internal_requests(&self) -> ! {
        loop {
            let t_now = now();
            let timeout = self.core.config.request_timeout_us;
            let next = self.core.with(|t| t.keepalive.next(t_now, true, timeout));
            let changed = &self.core.internal_keepalive_changed;
            let job = match next {
                Next::Send(board, op, _) => {
                    self.internal_keepalive(board, op).await;
                    continue;
                }
                Next::At(at) => {
                    match select3(
                        self.core.next_internal_job(),
                        sleep_until(at),
                        changed.wait(),
                    )
                    .await
                    {
                        Either3::First(job) => job,
                        Either3::Second(()) | Either3::Third(()) => continue,
                    }
                }
                Next::Idle => match select(self.core.next_internal_job(), changed.wait()).await {
                    Either::First(job) => job,
                    Either::Second(()) => continue,
                },
            };
            let meta = &job.meta;
            if !self.core.is_queued(meta.ticket) {
                self.core.with(|t| bump(&mut t.diag.abandoned));
                continue;
            }
            let read = meta.read.is_some();
            let (frame, pec) = self.core.frame_to_send(&job);
            self.internal.handle_write(&frame, read).await;
            if read {
                let mut reply = [0u8; REPLY_BUF_LEN];
                let n = self.internal.take_reply(&mut reply);
                self.core.finish_transfer(&job, pec, Ok(reply.get(..n)));
            } else {
                self.core.finish_transfer(&job, pec, Ok(None));
            }
        }
    }

    /// A keepalive to the internal board: a heartbeat, or its failsafe set again, as a
    /// write with a fresh sequence number (the internal board always takes it).
    async fn internal_keepalive(&self, board: Address, op: KeepaliveOp) {
        let seq = self.core.with(|t| t.fresh_seq(board));
        let op_sent = match op {
            KeepaliveOp::Heartbeat => Op::Heartbeat,
            KeepaliveOp::SetFailsafe(timeout_ms) => Op::SetFailsafe { timeout_ms },
        };
        let req = Request {
            db: board,
            seq,
            op: op_sent,
        };
        let mut frame = [0u8; MAX_FRAME_LEN];
        let ok = match req.emit(&mut frame) {
            Ok(n) => {
                self.internal
                    .handle_write(frame.get(..n).unwrap_or(&[]), false)
                    .await;
                true
            }
            Err(_) => false,
        };
        let t_now = now();
        self.core
            .with(|t| t.keepalive.done(board, op, ok, t_now, &mut t.diag));
    }

    /// Routes the internal daughterboard's events (deferred replies, pin events, rejections)
    /// exactly as events that arrive over the bus. Never returns. Part of
    /// [`Motherboard::run`].
    pub async fn run_internal_events(&self) -> ! {
        loop {
            let ev = self.internal.next_event().await;
            self.core.route_event(&ev.as_event(Address::INTERNAL));
        }
    }
}

impl MbCore {
    pub(crate) fn with<R>(&self, f: impl FnOnce(&mut Table) -> R) -> R {
        self.table.lock(|t| f(&mut t.borrow_mut()))
    }

    /// The configuration.
    pub fn config(&self) -> &MbConfig {
        &self.config
    }

    /// A copy of the counters.
    pub fn diagnostics(&self) -> MbDiagnostics {
        self.with(|t| t.diag)
    }

    /// True when PEC is negotiated with `db` (set by a successful `set_pec`, cleared by the
    /// board's `boot` event).
    pub fn pec_enabled(&self, db: Address) -> bool {
        self.with(|t| t.pec(db))
    }

    /// The time a request may take: the configured request timeout, plus the pulse-in
    /// timeout for a deferred operation.
    pub fn timeout_us(&self, op: &Op<'_>) -> u64 {
        let extra_ms = match op {
            Op::PulseIn { timeout_ms, .. } => {
                u64::from(timeout_ms.unwrap_or(self.config.default_pulse_timeout_ms))
            }
            _ => 0,
        };
        self.config
            .request_timeout_us
            .saturating_add(extra_ms.saturating_mul(1000))
    }

    /// Sends `op` to board `db` and waits for its outcome, with the default timeout
    /// ([`Motherboard::timeout_us`]). See [`Motherboard::call_with_timeout`].
    ///
    /// # Errors
    /// As [`Motherboard::call_with_timeout`].
    pub async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        self.call_with_timeout(db, op, self.timeout_us(&op)).await
    }

    /// Sends `op` to board `db` (0: the internal daughterboard, without the bus) and waits at
    /// most `timeout_us` for its outcome. Ends exactly once:
    ///
    /// * outputs: `Ok` with an empty payload once the board acknowledged the write (a refusal
    ///   comes later as a `rejected` event, counted in [`MbDiagnostics::rejected`]);
    /// * reads: `Ok(payload)` for status `ok`;
    /// * deferred operations (`pending`): `Ok(payload)` of the deferred reply.
    ///
    /// Requests to external boards wait for the dispatcher in one queue, oldest first. The
    /// queue has room for every pending slot, so a caller never waits for room in it; a
    /// request whose caller times out (or is dropped) while it waits leaves the queue at once
    /// and never reaches the bus.
    ///
    /// Dropping the future gives the request up: its slot is freed and a reply that still
    /// comes is counted as late and dropped. A deferred request (pulse-in) given up after
    /// its `pending` answer keeps its slot and sequence number until the board's deadline
    /// for it (the time of `pending` + [`Motherboard::timeout_us`]) has passed, so its late
    /// deferred reply can never complete another request; while kept, the slot counts
    /// against [`crate::MAX_PENDING`]. A `set_pec` or `set_failsafe` the board acknowledged
    /// takes effect on the motherboard's side too, even when its caller gave up meanwhile.
    ///
    /// # Errors
    /// [`LinkError::Invalid`] (nothing sent: the operation does not encode, or `db` is the
    /// motherboard's own address), [`LinkError::Busy`] (no free slot or sequence
    /// number), [`LinkError::Timeout`], [`LinkError::Nack`] and
    /// [`LinkError::ArbitrationLost`] (after every retry), [`LinkError::Bus`],
    /// [`LinkError::BadReply`] (unparsable, wrong PEC or wrong sequence number),
    /// [`LinkError::Status`] (the board refused it).
    pub async fn call_with_timeout(
        &self,
        db: Address,
        op: Op<'_>,
        timeout_us: u64,
    ) -> Result<Payload, LinkError> {
        let Some(observer) = self.observer else {
            return self.call_inner(db, op, timeout_us).await;
        };
        let started = now();
        let result = self.call_inner(db, op, timeout_us).await;
        observer.observe(&CallRecord {
            db,
            op: &op,
            result: &result,
            started,
            ended: now(),
        });
        result
    }

    async fn call_inner(
        &self,
        db: Address,
        op: Op<'_>,
        timeout_us: u64,
    ) -> Result<Payload, LinkError> {
        op.validate()?;
        if self.config.pec && !db.is_internal() && pec_change(&op) == Some(false) {
            // PEC stays on with the safe defaults (MbConfig::pec).
            return Err(LinkError::Invalid(x10_microcode::Error::BadArgument));
        }
        if db == self.config.address {
            return Err(LinkError::Invalid(x10_microcode::Error::BadAddress(
                db.get(),
            )));
        }
        let now = now();
        let deadline = now.plus_us(timeout_us);
        let (ticket, seq) = self.with(|t| {
            let (ticket, seq) = t.alloc(db, now)?;
            if let Some(s) = self.done.get(ticket.index) {
                s.reset();
            }
            Ok::<_, LinkError>((ticket, seq))
        })?;
        let guard = SlotGuard {
            mb: self,
            ticket,
            armed: true,
        };
        let req = Request { db, seq, op };
        // The frame is encoded in place, into as many bytes as it needs (a request too long
        // for any board fails in `emit` as it would in a full-size buffer). Its PEC byte is
        // added when it goes to the board, as the board's PEC state is then.
        let mut frame: Vec<u8, MAX_FRAME_LEN> = Vec::new();
        let _ = frame.resize(req.buffer_len().min(MAX_FRAME_LEN), 0);
        let len = match req.emit(&mut frame) {
            Ok(n) => n,
            Err(e) => {
                guard.release(Ended::GaveUp);
                return Err(LinkError::Invalid(e));
            }
        };
        frame.truncate(len);
        let meta = JobMeta {
            ticket,
            db,
            seq,
            // A set_pec or set_failsafe is read back too: it takes effect on the
            // motherboard's side only once the board's reply confirms it. So is an
            // event_enable: a refused one (a corrupted frame, a wrong port) would otherwise
            // end `Ok` and leave a program waiting for events that never come.
            read: (op.expects_reply()
                || pec_change(&op).is_some()
                || failsafe_change(&op).is_some()
                || matches!(op, Op::EventEnable(..)))
            .then(|| op.reply_capacity()),
            // The board answers a pulse-in no later than acceptance + its pulse timeout
            // (firmware-db counts it from acceptance), and acceptance is before the `pending`
            // answer: the request timeout on top leaves room for the event's delivery.
            deferred: match op {
                Op::PulseIn { pin, .. } => Some((pin, self.timeout_us(&op))),
                _ => None,
            },
            failsafe_change: failsafe_change(&op),
        };
        let internal = db.is_internal();
        // Never full: every queued job holds one of the MAX_PENDING slots, and a job leaves
        // the queue when its slot is released. The internal board's worker and the
        // dispatcher each take the oldest job that is theirs.
        if self.with(|t| t.enqueue(Job { meta, frame })).is_err() {
            self.with(|t| bump(&mut t.diag.busy));
            guard.release(Ended::GaveUp);
            return Err(LinkError::Busy);
        }
        if internal {
            self.internal_ready.signal(());
        } else {
            self.job_ready.signal(());
        }
        let Some(signal) = self.done.get(ticket.index) else {
            return guard.expire();
        };
        match select(signal.wait(), sleep_until(deadline)).await {
            Either::First(r) => {
                guard.release(Ended::Completed);
                r
            }
            Either::Second(()) => guard.expire(),
        }
    }

    /// The oldest queued job; waits for one. Cancel-safe: a job is taken out only when this
    /// returns it.
    pub(crate) async fn next_job(&self) -> Job {
        loop {
            if let Some(job) = self.with(|t| t.pop_job(false)) {
                return job;
            }
            self.job_ready.wait().await;
        }
    }

    /// The oldest queued job for the internal daughterboard; waits for one. Cancel-safe.
    async fn next_internal_job(&self) -> Job {
        loop {
            if let Some(job) = self.with(|t| t.pop_job(true)) {
                return job;
            }
            self.internal_ready.wait().await;
        }
    }

    /// True while the request's caller still waits for it to be sent. When not, a slot the
    /// request kept while on the bus is freed ([`Table::transfer_ended`]).
    pub(crate) fn is_queued(&self, t: Ticket) -> bool {
        self.with(|tb| {
            let wanted = tb.wanted(t);
            if !wanted {
                tb.transfer_ended(t);
            }
            wanted
        })
    }

    /// Wakes the dispatcher and the internal worker when a failsafe setting changed: a
    /// keepalive may be due sooner than they planned.
    pub(crate) fn notify_keepalive(&self) {
        if self.with(Table::take_keepalive_changed) {
            self.keepalive_changed.signal(());
            self.internal_keepalive_changed.signal(());
        }
    }

    /// The failsafe timeout the motherboard keeps alive for `db`, in ms (0: none).
    pub fn keepalive_ms(&self, db: Address) -> u16 {
        self.with(|t| t.keepalive.timeout_ms(db))
    }

    /// The bytes of `job` as they go to its board now: with a PEC byte when PEC is on for
    /// the board at this moment (whatever it was when the job was queued), and that state.
    pub(crate) fn frame_to_send(&self, job: &Job) -> (Vec<u8, MAX_FRAME_LEN>, bool) {
        let db = job.meta.db;
        let pec = self.with(|t| t.pec(db));
        let mut frame = job.frame.clone();
        if pec {
            let _ = frame.push(x10_microcode::pec::compute(db.addr_byte(false), &job.frame));
        }
        (frame, pec)
    }

    /// Ends a transfer sent with PEC `pec`: `Ok(None)` a write acknowledged,
    /// `Ok(Some(bytes))` the bytes read, or the bus error after every retry.
    pub(crate) fn finish_transfer(&self, job: &Job, pec: bool, r: Result<Option<&[u8]>, BusError>) {
        let meta = &job.meta;
        let replied = matches!(r, Ok(Some(_)));
        // The board saw a transaction: that keeps its failsafe alive (recorded below).
        let acked = r.is_ok();
        let outcome = match r {
            Ok(None) => Outcome::Complete(Ok(Payload::new())),
            Ok(Some(read)) => match request_op(&job.frame) {
                Some(op) => {
                    let (outcome, state) = self.interpret(meta, pec, &op, read);
                    self.board_pec_is(meta.db, state);
                    outcome
                }
                None => Outcome::Complete(Err(LinkError::BadReply)),
            },
            Err(e) => Outcome::Complete(Err(link_error(e))),
        };
        self.end_job(meta, outcome, acked, replied);
    }

    /// Ends request `meta` with `outcome` (`acked`: the board saw the transaction;
    /// `replied`: a reply was read).
    pub(crate) fn end_job(&self, meta: &JobMeta, outcome: Outcome, acked: bool, replied: bool) {
        self.with(|t| {
            // The clock is read only for a board whose failsafe is kept alive.
            if acked && t.keepalive.tracks(meta.db) {
                t.keepalive.sent(meta.db, now());
            }
            match outcome {
                Outcome::Defer => {
                    if !t.defer(meta, now()) {
                        bump(&mut t.diag.late_replies);
                    }
                }
                Outcome::Complete(r) => {
                    if r.is_ok() {
                        // The board applied it, whether or not the caller still waits.
                        t.applied(meta.db, meta, now);
                    }
                    if t.complete(meta.ticket, &r) {
                        if let Some(s) = self.done.get(meta.ticket.index) {
                            s.signal(r);
                        }
                    } else {
                        if replied {
                            // The caller gave up while the transfer was on the bus.
                            bump(&mut t.diag.late_replies);
                        }
                        t.transfer_ended(meta.ticket);
                    }
                }
            }
        });
        self.notify_keepalive();
    }

    /// What the bytes read for request `meta` (operation `op`, sent with PEC `pec`) mean, and
    /// the PEC state of the board when the reply proves it.
    ///
    /// The reply must fit the operation ([`Reply::parse_read_for`]: an `ok` of a length the
    /// operation allows, anything else empty; the PEC byte located without trusting an
    /// unchecked byte). A `set_pec` is answered in its new mode: its reply is parsed that way
    /// first, and only a reply checked in the new mode (for `set_pec(1)`: with its PEC)
    /// confirms the switch. A `pec_mismatch` answer to a frame sent without PEC counts only
    /// with a valid PEC byte (only a board with PEC on sends it, and a flipped status bit
    /// must not turn it into `ok`): it proves the board has PEC on.
    pub(crate) fn interpret(
        &self,
        meta: &JobMeta,
        pec: bool,
        op: &Op<'_>,
        read: &[u8],
    ) -> (Outcome, Option<bool>) {
        let db = meta.db;
        let switch = pec_change(op);
        let mode = switch.unwrap_or(pec);
        // A board that refused the switch answers in the old mode.
        let parsed = match Reply::parse_read_for(db, mode, read, op) {
            Ok(r) => Some((r, mode)),
            Err(_) if mode != pec => Reply::parse_read_for(db, pec, read, op)
                .ok()
                .map(|r| (r, pec)),
            Err(_) => None,
        };
        let Some((reply, answered_in)) = parsed else {
            let state = self.pec_off_sign(meta, pec, op, read);
            return (Outcome::Complete(Err(LinkError::BadReply)), state);
        };
        if reply.seq != meta.seq {
            warn!(
                "reply from {} has seq {} for request {}",
                db.get(),
                reply.seq,
                meta.seq
            );
            self.with(|t| t.stray(db, reply.seq));
            return (Outcome::Complete(Err(LinkError::BadReply)), None);
        }
        match reply.status {
            // A switch is confirmed only by an `ok` in its new mode.
            Status::Ok if switch.is_some() && answered_in != mode => {
                (Outcome::Complete(Err(LinkError::BadReply)), None)
            }
            Status::Ok => match Payload::from_slice(reply.payload) {
                Ok(p) => (Outcome::Complete(Ok(p)), switch),
                Err(_) => (Outcome::Complete(Err(LinkError::BadReply)), None),
            },
            Status::Pending if meta.deferred.is_some() => (Outcome::Defer, None),
            Status::Pending => (Outcome::Complete(Err(LinkError::BadReply)), None),
            Status::PecMismatch if !pec => {
                // Only a board that checks PEC answers this, with its PEC byte: check it.
                match Reply::parse_read_for(db, true, read, op) {
                    Ok(r) if r.seq == meta.seq && r.status == Status::PecMismatch => {
                        warn!("board {} checks PEC: PEC on", db.get());
                        self.with(|t| bump(&mut t.diag.pec_resyncs));
                        (
                            Outcome::Complete(Err(LinkError::Status(Status::PecMismatch))),
                            Some(true),
                        )
                    }
                    _ => (Outcome::Complete(Err(LinkError::BadReply)), None),
                }
            }
            s => (Outcome::Complete(Err(LinkError::Status(s))), None),
        }
    }

    /// Records the PEC state a reply proved for `db`. With the safe defaults a board found
    /// with PEC off is prepared again before its next request.
    pub(crate) fn board_pec_is(&self, db: Address, state: Option<bool>) {
        let Some(on) = state else { return };
        let manages = self.config.pec;
        self.with(|t| {
            t.set_pec(db, on);
            if !on && manages {
                t.set_ready(db, false);
            }
        });
    }

    /// A reply that failed its PEC check but reads, without PEC, as `bad_length`: the board
    /// took our PEC byte for data, so it has PEC off (it restarted and its boot event was
    /// lost). `Some(false)` then (unchecked, so it only ever leads to switching PEC on
    /// again, never to accepting a value).
    fn pec_off_sign(&self, meta: &JobMeta, pec: bool, op: &Op<'_>, read: &[u8]) -> Option<bool> {
        if !pec {
            return None;
        }
        match Reply::parse_read_for(meta.db, false, read, op) {
            Ok(reply) if reply.seq == meta.seq && reply.status == Status::BadLength => {
                warn!("board {} has PEC off", meta.db.get());
                self.with(|t| bump(&mut t.diag.pec_resyncs));
                Some(false)
            }
            _ => None,
        }
    }

    /// Parses a write to the motherboard's own address as an event and routes it. Anything
    /// else is counted in `bad_events` and dropped.
    ///
    /// From a board with PEC negotiated ([`Motherboard::pec_enabled`]) an event must carry a
    /// valid PEC byte, with one exception: a `boot` event without PEC is accepted (a board
    /// that just restarted has PEC off) and turns PEC off for that board. From a board with
    /// PEC off, the frame is parsed without PEC first and, if that fails, with PEC: a board
    /// that has just executed a `set_pec(true)` the motherboard has not recorded yet sends
    /// its events with PEC. The two readings never both succeed: the LEN byte fixes the
    /// frame's length, and the PEC byte makes it exactly one longer.
    pub(crate) fn route_event_bytes(&self, bytes: &[u8]) {
        let pec_on = bytes
            .first()
            .and_then(|&b| Address::new(b).ok())
            .is_some_and(|source| self.with(|t| t.pec(source)));
        let with_pec = || Event::parse_with_pec(self.config.address, bytes);
        let parsed = if pec_on {
            with_pec().or_else(|e| match Event::parse(bytes) {
                Ok(ev) if ev.kind == EventKind::Boot => Ok(ev),
                _ => Err(e),
            })
        } else {
            Event::parse(bytes).or_else(|_| with_pec())
        };
        match parsed {
            Ok(ev) if !ev.source.is_internal() => self.route_event(&ev),
            _ => {
                warn!("bad event ({} bytes)", bytes.len());
                self.with(|t| bump(&mut t.diag.bad_events));
            }
        }
    }

    /// Routes one event: a deferred reply to its waiting request, a pin event to its waiters
    /// (or the unclaimed queue), the rest to the counters and the log.
    pub(crate) fn route_event(&self, ev: &Event<'_>) {
        self.with(|t| {
            bump(&mut t.diag.events);
            t.events_in.received(ev, &mut t.diag);
        });
        match ev.kind {
            EventKind::DeferredReply => self.with(|t| {
                // Matched by board, sequence number and pin; a reply for a request that gave
                // up is counted as late (see `Table::take_deferred`).
                let Some(ticket) = t.take_deferred(ev.source, ev.seq, ev.pin) else {
                    return;
                };
                let r = match ev.status {
                    Status::Ok => Payload::from_slice(ev.payload).map_err(|_| LinkError::BadReply),
                    s => Err(LinkError::Status(s)),
                };
                if t.complete(ticket, &r) {
                    if let Some(s) = self.done.get(ticket.index) {
                        s.signal(r);
                    }
                }
            }),
            EventKind::PinChange | EventKind::AnalogThreshold => {
                let Ok(value) = Payload::from_slice(ev.payload) else {
                    return;
                };
                let pe = PinEvent {
                    source: ev.source,
                    kind: ev.kind,
                    pin: ev.pin,
                    value,
                };
                self.with(|t| {
                    t.deliver(&pe, |i| {
                        if let Some(s) = self.waiters.get(i) {
                            s.signal(pe.clone());
                        }
                    })
                });
            }
            EventKind::Rejected => {
                warn!(
                    "board {} rejected request {}: {}",
                    ev.source.get(),
                    ev.seq,
                    ev.status.name()
                );
                self.with(|t| bump(&mut t.diag.rejected));
            }
            EventKind::FailsafeTripped => {
                warn!("board {} failsafe tripped", ev.source.get());
                self.with(|t| bump(&mut t.diag.failsafe_trips));
            }
            EventKind::Overflow => {
                warn!("board {} dropped events", ev.source.get());
                self.with(|t| bump(&mut t.diag.overflows));
            }
            EventKind::Boot => {
                info!("board {} booted", ev.source.get());
                self.with(|t| {
                    bump(&mut t.diag.boots);
                    t.booted(ev.source, now());
                });
            }
            EventKind::Unknown(_) => self.with(|t| bump(&mut t.diag.bad_events)),
        }
        self.notify_keepalive();
    }

    /// Waits for the next pin-change or analog-threshold event from `pin` on board `db`. An
    /// event that arrived while no task waited for it is kept (up to
    /// [`crate::UNCLAIMED_EVENTS`], oldest dropped first and counted) and returned at once.
    /// Every task waiting for the same pin gets the event.
    ///
    /// # Errors
    /// [`LinkError::Busy`] when [`crate::MAX_EVENT_WAITERS`] tasks already wait.
    pub async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        // The task's waker identifies it: its next wait for the same pin takes the same slot.
        let task = core::future::poll_fn(|cx| core::task::Poll::Ready(cx.waker().clone())).await;
        let registered = self.with(|t| {
            let r = t.wait_for(db, pin, &task);
            if let Ok(Err(ticket)) = r {
                if let Some(s) = self.waiters.get(ticket.index) {
                    s.reset();
                }
            }
            r
        })?;
        let ticket = match registered {
            Ok(ev) => return Ok(ev),
            Err(ticket) => ticket,
        };
        let Some(signal) = self.waiters.get(ticket.index) else {
            return Err(LinkError::Busy);
        };
        let mut guard = WaiterGuard {
            mb: self,
            ticket,
            armed: true,
        };
        let ev = signal.wait().await;
        guard.armed = false;
        self.with(|t| t.took(ticket));
        Ok(ev)
    }
}
