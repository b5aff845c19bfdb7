//! [`MbCore`]: what robot tasks, the dispatcher and the internal daughterboard's worker share,
//! naming no board type: the configuration, the table ([`crate::table`]) behind its one
//! blocking mutex, and the signals that wake the dispatcher, the internal worker and the
//! callers. Owns those, and the call path of a request: a slot and a sequence number, the
//! frame, the queue, the wait for its outcome or its deadline. What a finished transfer
//! means is [`crate::transfer`]'s, where events go [`crate::routing`]'s.

use core::cell::RefCell;
use core::future::Future;
use core::task::Poll;

use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex as BlockingMutex;
use embassy_sync::once_lock::OnceLock;
use embassy_sync::signal::Signal;
use heapless::Vec;
use x10_devices::{LinkError, PinEvent};
use x10_hal::time::Instant;
use x10_microcode::{Address, Op, Payload, Request, Status, MAX_FRAME_LEN};

use crate::boards::{failsafe_change, pec_change};
use crate::config::MbConfig;
use crate::diag::{bump, count_outcome, MbDiagnostics};
use crate::jobs::{Job, JobMeta};
use crate::observe::{CallObserver, CallRecord};
use crate::requests::{Ended, SlotState, Ticket, MAX_PENDING};
use crate::table::Table;
use crate::waiters::MAX_EVENT_WAITERS;

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

/// The internal daughterboard as the calling task runs it (the direct path of
/// [`MbCore::call`]): a [`crate::Motherboard`] whose ports are `Sync` is one
/// ([`crate::Motherboard::serve_internal_directly`] hands it to its core).
pub trait InternalBoard: Sync {
    /// Executes `op` on the internal daughterboard now, in the calling task, under the lock
    /// that keeps its calls from overlapping (`firmware_db::Daughterboard::execute`): its
    /// status, its value in `value`. `None`: it cannot be run from here; the request then
    /// goes to the internal worker's queue, as a pulse-in does.
    fn execute(&self, op: &Op<'_>, value: &mut Payload) -> Option<Status>;
}

/// True for the operations a call to the internal daughterboard runs in the calling task
/// when its core has an [`InternalBoard`]: those whose outcome the motherboard only hands
/// back (ports, ping, heartbeat, scan). The others change the motherboard's view of the
/// board once confirmed (PEC, failsafe, event enables, identity, address), are deferred
/// (pulse-in) or carry borrowed data (batch, serial): they take the internal worker's queue.
fn runs_directly(op: &Op<'_>) -> bool {
    matches!(
        op,
        Op::DigitalWrite(..)
            | Op::DigitalRead(_)
            | Op::PwmDuty(..)
            | Op::AnalogRead(_)
            | Op::PwmFrequency(..)
            | Op::PwmPulseWidth(..)
            | Op::Ping
            | Op::Heartbeat
            | Op::Scan
    )
}

/// What robot tasks, the dispatcher and the keepalive share: configuration, the pending
/// table, the request queues and the signals that end requests. It names no board type; a
/// [`crate::Motherboard`] holds one (and dereferences to it), and [`crate::X10`] is a
/// reference to it.
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
    pub(crate) internal_keepalive_changed: Signal<M, ()>,
    table: BlockingMutex<M, RefCell<Table>>,
    /// Per pending slot: the request's outcome, for its caller.
    pub(crate) done: [Signal<M, Result<Payload, LinkError>>; MAX_PENDING],
    /// Per waiter slot: the pin event, for the waiting task.
    pub(crate) waiters: [Signal<M, PinEvent>; MAX_EVENT_WAITERS],
    pub(crate) observer: Option<&'static dyn CallObserver>,
    /// The internal daughterboard for the direct path, once given ([`InternalBoard`]).
    direct: OnceLock<&'static dyn InternalBoard>,
}

/// A caller counted among those waiting for a slot: uncounted when it gets one, gives up or
/// is dropped (the next waiter is then woken to look).
struct SlotWait<'a> {
    mb: &'a MbCore,
    counted: bool,
}

impl Drop for SlotWait<'_> {
    fn drop(&mut self) {
        if self.counted {
            self.mb.with(|t| {
                t.slot_waiting = t.slot_waiting.saturating_sub(1);
                t.slot_waiters.wake();
            });
        }
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
            let taken = if t.requests.state(ticket) == SlotState::Done {
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

impl MbCore {
    pub(crate) const fn new(config: MbConfig) -> MbCore {
        MbCore {
            config,
            job_ready: Signal::new(),
            internal_ready: Signal::new(),
            keepalive_changed: Signal::new(),
            internal_keepalive_changed: Signal::new(),
            table: BlockingMutex::new(RefCell::new(Table::new())),
            done: [const { Signal::new() }; MAX_PENDING],
            waiters: [const { Signal::new() }; MAX_EVENT_WAITERS],
            observer: None,
            direct: OnceLock::new(),
        }
    }

    /// Lets calls to the internal daughterboard run `board` in the calling task (see
    /// [`InternalBoard`]); once. False if the core has one already.
    pub fn set_internal_board(&self, board: &'static dyn InternalBoard) -> bool {
        self.direct.init(board).is_ok()
    }

    /// Runs `f` on the table, under the lock.
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
        self.with(|t| t.boards.pec(db))
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
    /// ([`MbCore::timeout_us`]). See [`MbCore::call_with_timeout`].
    ///
    /// # Errors
    /// As [`MbCore::call_with_timeout`].
    pub fn call<'a>(
        &'a self,
        db: Address,
        op: Op<'a>,
    ) -> impl Future<Output = Result<Payload, LinkError>> + 'a {
        // Not an `async fn` of its own: the future is `call_with`'s, one state machine less
        // to copy the operation and the result through (issue 27).
        call_with(self, db, op, None)
    }

    /// Sends `op` to board `db` (0: the internal daughterboard, without the bus) and waits at
    /// most `timeout_us` for its outcome. Ends exactly once:
    ///
    /// * outputs: with [`MbConfig::confirm_outputs`] (the default) `Ok` with an empty payload
    ///   once the board's reply says it executed it, else the board's status; without, `Ok`
    ///   once the board acknowledged the write (a refusal comes later as a `rejected` event,
    ///   counted in [`MbDiagnostics::rejected`]);
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
    /// for it (the time of `pending` + [`MbCore::timeout_us`]) has passed, so its late
    /// deferred reply can never complete another request; while kept, the slot counts
    /// against [`crate::MAX_PENDING`]. A `set_pec` or `set_failsafe` the board acknowledged
    /// takes effect on the motherboard's side too, even when its caller gave up meanwhile.
    ///
    /// # Errors
    /// [`LinkError::Invalid`] (nothing sent: the operation does not encode, or `db` is the
    /// motherboard's own address), [`LinkError::Busy`] (no pending slot or sequence number
    /// was free by the deadline: a caller that finds none waits for one, behind the callers
    /// already waiting), [`LinkError::Status`] with `port_out_of_range` (the board has no
    /// such port, as its `boot` event or `identify` said: nothing was sent), [`LinkError::Timeout`], [`LinkError::Nack`] and
    /// [`LinkError::ArbitrationLost`] (after every retry), [`LinkError::Bus`],
    /// [`LinkError::BadReply`] (unparsable, wrong PEC or wrong sequence number),
    /// [`LinkError::Status`] (the board refused it).
    pub fn call_with_timeout<'a>(
        &'a self,
        db: Address,
        op: Op<'a>,
        timeout_us: u64,
    ) -> impl Future<Output = Result<Payload, LinkError>> + 'a {
        call_with(self, db, op, Some(timeout_us))
    }

    /// [`call_with`]'s work.
    async fn call_body(
        &self,
        db: Address,
        op: Op<'_>,
        timeout_us: Option<u64>,
    ) -> Result<Payload, LinkError> {
        let started = self.observer.map(|_| now());
        let result = 'call: {
            if let Some(board) = self.direct_board(db, &op) {
                if let Err(e) = self.check(db, &op) {
                    break 'call Err(e);
                }
                // Other tasks run first: a loop of such calls cannot starve them.
                embassy_futures::yield_now().await;
                let mut value = Payload::new();
                if let Some(status) = board.execute(&op, &mut value) {
                    break 'call self.direct_outcome(&op, status, value);
                }
            }
            let timeout_us = timeout_us.unwrap_or_else(|| self.timeout_us(&op));
            self.call_inner(db, op, timeout_us).await
        };
        if let (Some(observer), Some(started)) = (self.observer, started) {
            observer.observe(&CallRecord {
                db,
                op: &op,
                result: &result,
                started,
                ended: now(),
            });
        }
        result
    }

    /// The internal daughterboard, when the direct path runs `op` to `db` (see
    /// [`runs_directly`]).
    fn direct_board(&self, db: Address, op: &Op<'_>) -> Option<&'static dyn InternalBoard> {
        if db.is_internal() && runs_directly(op) {
            self.direct.try_get().copied()
        } else {
            None
        }
    }

    /// What is checked before anything is sent: the operation encodes, PEC stays on with the
    /// safe defaults, `db` is not the motherboard's own address, the board has the port.
    ///
    /// # Errors
    /// As [`MbCore::call_with_timeout`]: `Invalid`, `Updating` (the board is being updated
    /// and `op` is not one of the update's), or `Status(port_out_of_range)` (counted).
    fn check(&self, db: Address, op: &Op<'_>) -> Result<(), LinkError> {
        op.validate()?;
        if self.config.pec && !db.is_internal() && pec_change(op) == Some(false) {
            // PEC stays on with the safe defaults (MbConfig::pec).
            return Err(LinkError::Invalid(x10_microcode::Error::BadArgument));
        }
        if db == self.config.address {
            return Err(LinkError::Invalid(x10_microcode::Error::BadAddress(
                db.get(),
            )));
        }
        // A board being updated takes only the update's own operations. A port the board
        // does not have (as its boot event or identify reply said): refused here, as the
        // board would refuse it, so that an output to it never returns `Ok`.
        let refused = self.with(|t| {
            if t.updating == Some(db) && !crate::update::is_update_op(op) {
                return Err(None);
            }
            let r = t.boards.check_ports(db, op);
            if r.is_err() {
                bump(&mut t.diag.status_errors);
            }
            r.map_err(Some)
        });
        match refused {
            Ok(()) => Ok(()),
            Err(None) => Err(LinkError::Updating),
            Err(Some(port)) => {
                warn!("board {} has no port {}", db.get(), port.number());
                Err(LinkError::Status(x10_microcode::Status::PortOutOfRange))
            }
        }
    }

    async fn call_inner(
        &self,
        db: Address,
        op: Op<'_>,
        timeout_us: u64,
    ) -> Result<Payload, LinkError> {
        self.check(db, &op)?;
        let t_now = now();
        let deadline = t_now.plus_us(timeout_us);
        // A free slot at once (the usual case) without the waiting machinery.
        let free = self.with(|t| {
            if t.slot_waiting > 0 {
                return None;
            }
            self.take_slot(t, db, t_now).ok()
        });
        let (ticket, seq) = match free {
            Some(claimed) => claimed,
            None => self.claim_slot(db, deadline).await?,
        };
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
            kind: crate::jobs::JobKind::Request,
            db,
            seq,
            // A set_pec or set_failsafe is read back too: it takes effect on the
            // motherboard's side only once the board's reply confirms it. So is an
            // event_enable: a refused one (a corrupted frame, a wrong port) would otherwise
            // end `Ok` and leave a program waiting for events that never come.
            // With `MbConfig::confirm_outputs` every output is read back too, so a refused
            // one never ends in `Ok`.
            read: (op.expects_reply()
                || self.config.confirm_outputs
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
        if self.with(|t| t.jobs.push(Job { meta, frame })).is_err() {
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

    /// The outcome of an operation the internal daughterboard executed in the calling task,
    /// checked and counted as the internal worker checks and counts its reply
    /// ([`MbCore::interpret`]): the value must fit the operation (a level is 0 or 1, a scan
    /// reports the ports the board has), a refusal is its status. The board heard a
    /// transaction: a failsafe kept alive on it is due again later.
    fn direct_outcome(
        &self,
        op: &Op<'_>,
        status: Status,
        value: Payload,
    ) -> Result<Payload, LinkError> {
        let db = Address::INTERNAL;
        // An operation that answers no value (an output, a heartbeat) answered without one
        // fits, whatever its status: what `check_reply` says of it, without the look at its
        // reply length (x10-microcode's tests/reply_len.rs holds the two together).
        let fits = if value.is_empty() && !op.expects_reply() {
            Ok(())
        } else {
            op.check_reply(status, &value)
        };
        // What the outcome is, decided and counted under the lock without moving the value
        // in and out of it (each move of a payload is a 32-byte copy).
        let outcome = self.with(|t| {
            if t.boards.keepalive.tracks(db) {
                t.boards.keepalive.sent(db, now());
            }
            let outcome = match (status, fits) {
                (_, Err(_)) | (Status::Pending, _) => Err(LinkError::BadReply),
                // A scan must report the ports the board has.
                (Status::Ok, Ok(()))
                    if matches!(op, Op::Scan) && !t.boards.scan_fits(db, &value) =>
                {
                    Err(LinkError::BadReply)
                }
                (Status::Ok, Ok(())) => Ok(()),
                (s, Ok(())) => Err(LinkError::Status(s)),
            };
            bump(&mut t.diag.requests);
            count_outcome(&mut t.diag, &outcome);
            outcome
        });
        outcome.map(|()| value)
    }

    /// Claims a slot and a sequence number for a request to `db`, under the lock: counted in
    /// `requests`, its result signal cleared. `Busy` is not counted here.
    fn take_slot(
        &self,
        t: &mut Table,
        db: Address,
        now: Instant,
    ) -> Result<(Ticket, u8), LinkError> {
        let (ticket, seq) = t.requests.try_alloc(db, now)?;
        bump(&mut t.diag.requests);
        if let Some(s) = self.done.get(ticket.index) {
            s.reset();
        }
        Ok((ticket, seq))
    }

    /// A pending slot and a sequence number for a request to `db`. When every slot (or every
    /// sequence number of the board) is taken, waits until one is free, at most until
    /// `deadline`: woken when a caller releases one, or when an abandoned deferred request's
    /// hold ends. A storm of callers therefore waits instead of spinning on `Busy`.
    ///
    /// # Errors
    /// [`LinkError::Busy`] when none was free by `deadline` (counted once in `busy`).
    pub(crate) async fn claim_slot(
        &self,
        db: Address,
        deadline: Instant,
    ) -> Result<(Ticket, u8), LinkError> {
        // Counted in `slot_waiting` while it waits (and uncounted if its caller goes away).
        let mut waiting = SlotWait {
            mb: self,
            counted: false,
        };
        loop {
            // Tries under the lock; when none is free (or others already wait), registers to
            // be woken by the next release in the same critical section, so none is missed.
            let claim = core::future::poll_fn(|cx| {
                let t_now = now();
                self.with(|t| {
                    if !waiting.counted && t.slot_waiting > 0 {
                        waiting.counted = true;
                        t.slot_waiting = t.slot_waiting.saturating_add(1);
                        t.slot_waiters.register(cx.waker());
                        return Poll::Pending;
                    }
                    // A failure is not counted here: a wait is counted once, below.
                    match self.take_slot(t, db, t_now) {
                        Ok((ticket, seq)) => {
                            if core::mem::take(&mut waiting.counted) {
                                t.slot_waiting = t.slot_waiting.saturating_sub(1);
                                // Others may find a slot too: let them look.
                                t.slot_waiters.wake();
                            }
                            Poll::Ready(Ok((ticket, seq)))
                        }
                        Err(LinkError::Busy) => {
                            if !waiting.counted {
                                waiting.counted = true;
                                t.slot_waiting = t.slot_waiting.saturating_add(1);
                            }
                            t.slot_waiters.register(cx.waker());
                            Poll::Pending
                        }
                        Err(e) => Poll::Ready(Err(e)),
                    }
                })
            });
            let wake = self
                .with(|t| t.requests.next_expiry())
                .map_or(deadline, |at| if at.0 < deadline.0 { at } else { deadline });
            match select(claim, sleep_until(wake)).await {
                Either::First(r) => return r,
                Either::Second(()) if now() >= deadline => {
                    self.with(|t| bump(&mut t.diag.busy));
                    return Err(LinkError::Busy);
                }
                // An abandoned request's hold ended: try again.
                Either::Second(()) => {}
            }
        }
    }

    /// Wakes the dispatcher for a job just queued.
    pub(crate) fn job_ready_signal(&self) {
        self.job_ready.signal(());
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
    pub(crate) async fn next_internal_job(&self) -> Job {
        loop {
            if let Some(job) = self.with(|t| t.pop_job(true)) {
                return job;
            }
            self.internal_ready.wait().await;
        }
    }

    /// True while the request's caller still waits for it to be sent. When not, a slot the
    /// request kept while on the bus is freed ([`crate::requests::Requests::transfer_ended`]).
    pub(crate) fn is_queued(&self, t: Ticket) -> bool {
        self.with(|tb| {
            let wanted = tb.requests.wanted(t);
            if !wanted {
                tb.requests.transfer_ended(t);
                tb.slot_waiters.wake();
            }
            wanted
        })
    }

    /// Wakes the dispatcher and the internal worker when a failsafe setting changed: a
    /// keepalive may be due sooner than they planned.
    pub(crate) fn notify_keepalive(&self) {
        if self.with(|t| t.boards.take_keepalive_changed()) {
            self.keepalive_changed.signal(());
            self.internal_keepalive_changed.signal(());
        }
    }

    /// The failsafe timeout the motherboard keeps alive for `db`, in ms (0: none).
    pub fn keepalive_ms(&self, db: Address) -> u16 {
        self.with(|t| t.boards.keepalive.timeout_ms(db))
    }

    /// The bytes of `job` as they go to its board now: with its check (a PEC byte, or a CRC-16
    /// after a frame of more than 13 bytes) when PEC is on for the board at this moment
    /// (whatever it was when the job was queued), and that state.
    pub(crate) fn frame_to_send(&self, job: &Job) -> (Vec<u8, MAX_FRAME_LEN>, bool) {
        use x10_microcode::pec;
        let db = job.meta.db;
        let on = self.with(|t| t.boards.pec(db));
        let mut frame = job.frame.clone();
        if on {
            let check = pec::check(db.addr_byte(false), &job.frame).to_le_bytes();
            let n = pec::check_len(job.frame.len());
            // Fits: MAX_FRAME_LEN has room for the longest frame's check.
            let _ = frame.extend_from_slice(check.get(..n).unwrap_or(&[]));
        }
        (frame, on)
    }
}

/// Every call of the motherboard ([`MbCore::call_with_timeout`], `None`: the default
/// timeout, [`MbCore::timeout_us`], worked out only for a call that can wait). A call to the
/// internal daughterboard that the direct path runs ([`InternalBoard`]) is checked as any
/// call, yields once, and is executed by the calling task; the others go through the pending
/// table and a queue.
///
/// A free `pub async fn`, not a method, so that its state machine's poll, and the one copy of
/// [`MbCore::call_body`]'s behind [`poll_once`], are compiled in this crate whatever the image
/// links: rustc compiles the future of a non-generic `pub async fn` (a free function, not a
/// method) in its own crate, and at opt-level "z" the crates above reuse this crate's copy of
/// a generic instance (`poll_once::<call_body's future>`) instead of making their own. As a
/// method, it was compiled only in the crates that poll it: x10-boards (the USB link's request
/// server) and x10-robots' library (x10-devices' `PortLink::call`), which does not use
/// x10-boards, each made its own 2.8 KiB copy of `poll_once`, and fat LTO kept both (issue 25:
/// until then the updater's `run_updates`, a non-generic `pub async fn` of this crate that
/// calls, had kept it here by chance; docs/boards.md, "The motherboard carries the images").
pub async fn call_with(
    mb: &MbCore,
    db: Address,
    op: Op<'_>,
    timeout_us: Option<u64>,
) -> Result<Payload, LinkError> {
    // Every caller's future embeds this one, and LLVM would inline its 2 KiB poll into
    // each caller's poll: the robot tasks' (x10-devices' `PortLink::call`) and the USB
    // link's request server made two copies (issue 26). Polled through one function
    // instead, it is in the image once.
    // The direct path (a port call to the internal board, no observer) before it: the
    // outlined poll's two extra polls cost a SELF call about 60 instructions on the M0
    // (issue 27's target: 600 for an output).
    if mb.observer.is_none() {
        if let Some(board) = mb.direct_board(db, &op) {
            mb.check(db, &op)?;
            // Other tasks run first: a loop of such calls cannot starve them.
            embassy_futures::yield_now().await;
            let mut value = Payload::new();
            if let Some(status) = board.execute(&op, &mut value) {
                return mb.direct_outcome(&op, status, value);
            }
        }
    }
    poll_outlined(core::pin::pin!(mb.call_body(db, op, timeout_us))).await
}

/// Waits for `fut`, polling it through [`poll_once`]: one copy of its state machine's poll
/// in the image however many callers' futures embed it (see [`call_with`]).
async fn poll_outlined<F: Future>(mut fut: core::pin::Pin<&mut F>) -> F::Output {
    core::future::poll_fn(|cx| poll_once(fut.as_mut(), cx)).await
}

/// `fut.poll(cx)`, never inlined: LLVM inlines a future's poll into every caller's poll
/// otherwise, and a call's is 2 KiB (issue 26, docs/boards.md "What the link costs").
#[inline(never)]
fn poll_once<F: Future>(
    fut: core::pin::Pin<&mut F>,
    cx: &mut core::task::Context<'_>,
) -> Poll<F::Output> {
    fut.poll(cx)
}
