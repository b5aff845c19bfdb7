//! The dispatcher: the only user of the bus controller role, and, while idle, the
//! DB-interrupt listener at the motherboard's own address. Owns the bus once
//! [`MbCore::run_dispatcher`] runs: the jobs, their retries (listening meanwhile), the
//! preparation of each external board (PEC, failsafe) and its keepalives. Keeps no state of
//! its own besides the bus: what a transfer means is [`crate::transfer`]'s, where a received
//! event goes [`crate::routing`]'s.

use embassy_futures::select::{select, select3, Either, Either3};
use heapless::Vec;
use x10_devices::LinkError;
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::retry::{Backoff, RetryPolicy};
use x10_hal::time::Instant;
use x10_microcode::sweep::GENERAL_CALL;
use x10_microcode::{pec, Address, Op, Request, Status, MAX_FRAME_LEN, REPLY_HEADER_LEN};

use crate::boards::{pec_change, REMEMBERED_ENABLES};
use crate::diag::bump;
use crate::jobs::{Job, JobKind};
use crate::keepalive::{KeepaliveOp, Next};
use crate::mb_core::{now, sleep_until, MbCore};
use crate::transfer::{link_error, request_op, Outcome};

impl MbCore {
    /// The dispatcher and the DB-interrupt listener on `bus`; never returns. Part of
    /// [`crate::Motherboard::run`].
    ///
    /// Idle, it waits to be addressed at the motherboard's address
    /// ([`MultiMaster::addressed`], polled before the request queue; the only bus call that is
    /// ever raced). Once addressed, the transaction is received ([`MultiMaster::listen`]) and
    /// served to the end before anything else, so a transfer under way is never cut by a
    /// request, a timer or anything else: writes are events or deferred replies and are
    /// routed; reads get nothing. A request from the queue goes out as one `write`
    /// (outputs) or one `write_read` with a repeated START (inputs, reading the reply header,
    /// the operation's reply capacity and the PEC byte if negotiated). After a NACK or a lost
    /// arbitration the listener runs again (the winner of the arbitration is usually a
    /// daughterboard writing an event to us), for the [`Backoff`] delay, and after a lost
    /// arbitration for at least `MbConfig::arbitration_wait_us`:
    ///
    /// * if a write to the motherboard arrives meanwhile (after a NACK: an event from the
    ///   board addressed, which was busy sending it), the transaction is retried right after
    ///   it and the attempt does not count (`yields`);
    /// * otherwise the attempt counts, and when the attempts are used up the request ends in
    ///   `Nack` (at once) or `ArbitrationLost` (after that last wait).
    ///
    /// Retries go on only while the caller waits, so forgiven attempts are bounded by the
    /// request's deadline. A bus timeout ends the request in `Timeout`, a bus fault in
    /// `Bus`. A request whose caller already gave up is not sent.
    ///
    /// Between two jobs it keeps the external boards' failsafes alive (see
    /// the module `keepalive`): a keepalive that is due goes before the next job, with a
    /// sequence number of its own and no pending slot, so callers that keep every slot busy
    /// delay it by one transfer at most.
    pub async fn run_dispatcher<B: MultiMaster>(&self, mut bus: B) -> ! {
        let mut rx = [0u8; MAX_FRAME_LEN];
        let mut nth: u32 = 0;
        loop {
            if self.plug_and_play(&mut bus).await {
                continue;
            }
            let t_now = now();
            let timeout = self.config.request_timeout_us;
            let next = self.with(|t| t.boards.keepalive.next(t_now, false, timeout));
            let wake = match next {
                Next::Send(board, op, timeout_us) => {
                    nth = nth.wrapping_add(1);
                    self.keepalive(&mut bus, board, op, timeout_us, nth, &mut rx)
                        .await;
                    continue;
                }
                Next::At(at) => Some(at),
                Next::Idle => None,
            };
            // A board that stopped answering is asked again (`Directory::next_recheck`).
            let wake = match (wake, self.with(|t| t.directory.recheck_at())) {
                (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
                (a, b) => a.or(b),
            };
            let keepalive_due = async {
                match wake {
                    Some(at) => {
                        select(sleep_until(at), self.keepalive_changed.wait()).await;
                    }
                    None => self.keepalive_changed.wait().await,
                }
            };
            let r = select3(bus.addressed(), self.next_job(), keepalive_due).await;
            match r {
                Either3::First(addressed) => {
                    self.receive(&mut bus, addressed, &mut rx).await;
                }
                Either3::Second(job) => {
                    nth = nth.wrapping_add(1);
                    self.dispatch(&mut bus, &job, nth, &mut rx).await;
                }
                Either3::Third(()) => {}
            }
        }
    }

    /// Sends the keepalive due for external board `board`, giving up after `timeout_us`: a
    /// heartbeat (a single write, with PEC when the board has it), or after a reboot the
    /// board's failsafe set again (with the safe defaults: the board prepared again, PEC
    /// then failsafe), read back. Counted in the keepalive counters.
    async fn keepalive<B: MultiMaster>(
        &self,
        bus: &mut B,
        board: Address,
        op: KeepaliveOp,
        timeout_us: u64,
        nth: u32,
        rx: &mut [u8],
    ) {
        let seed = self.config.seed ^ nth.rotate_left(16) ^ (u32::from(board.get()) << 8);
        let deadline = now().plus_us(timeout_us);
        let r = match op {
            KeepaliveOp::SetFailsafe(_) if self.config.manages_boards() => {
                self.with(|t| t.boards.set_ready(board, false));
                self.ensure_ready(bus, board, seed, rx).await
            }
            KeepaliveOp::SetFailsafe(ms) => {
                let r = self
                    .own_op(
                        bus,
                        board,
                        Op::SetFailsafe { timeout_ms: ms },
                        deadline,
                        seed,
                        rx,
                    )
                    .await;
                if r.is_ok() {
                    let t_now = now();
                    self.with(|t| t.boards.failsafe_set(board, ms, t_now));
                }
                r
            }
            KeepaliveOp::Heartbeat
                if !self.with(|t| t.boards.ready(board)) && self.config.manages_boards() =>
            {
                self.ensure_ready(bus, board, seed, rx).await
            }
            KeepaliveOp::Heartbeat => {
                self.own_op(bus, board, Op::Heartbeat, deadline, seed, rx)
                    .await
            }
        };
        if let Err(e) = r {
            warn!("keepalive of board {} failed: {}", board.get(), e);
            if e == LinkError::Nack {
                self.board_gone(board);
            }
        }
        let t_now = now();
        self.with(|t| {
            t.boards
                .keepalive
                .done(board, op, r.is_ok(), t_now, &mut t.diag)
        });
    }

    /// Plug-and-play work, before anything else (see [`crate::directory`]): an `assign` to
    /// send to the unaddressed boards, else the next address of the start-up sweep. True when
    /// there was some. One attempt each, a single write, never retried here (no second copy
    /// of the retry path in the dispatcher):
    ///
    /// * `assign`: written to [`Address::UNADDRESSED`] with its check, never read (several
    ///   unaddressed boards may acknowledge it). Lost (a NACK, a bus error), it is sent again
    ///   at the board's next `announce`.
    /// * The sweep: `who_is_there` (no check: a board takes it with or without one, and it
    ///   changes nothing) written once to each address `0x08..=0x76` but the motherboard's;
    ///   every board there answers with an `announce` (routed as any event). Nobody there: a
    ///   NACK.
    /// * Then, once a second, `who_is_there` to one board that stopped answering (in turn):
    ///   its `announce` makes it present again ([`crate::directory::RECHECK_US`]).
    ///
    /// After a lost arbitration (an event won the bus) the work is put back and the loop
    /// serves the listener first.
    async fn plug_and_play<B: MultiMaster>(&self, bus: &mut B) -> bool {
        let mb = self.config.address;
        let work = self.with(|t| {
            t.directory
                .take_assign()
                .map(Ok)
                .or_else(|| t.directory.next_sweep(mb).map(Err))
                .or_else(|| {
                    t.directory
                        .recheck_at()
                        .and_then(|_| t.directory.next_recheck(now()))
                        .map(Err)
                })
        });
        let (db, op) = match work {
            None => return false,
            Some(Ok((uid, address))) => (Address::UNADDRESSED, Op::Assign { uid, address }),
            Some(Err(a)) => (a, Op::WhoIsThere),
        };
        let seq = self.with(|t| t.requests.fresh_seq(db));
        let mut frame = [0u8; MAX_FRAME_LEN];
        let req = Request { db, seq, op };
        let emitted = if op == Op::WhoIsThere {
            req.emit(&mut frame)
        } else {
            req.emit_with_pec(&mut frame)
        };
        let Some(bytes) = emitted.ok().and_then(|n| frame.get(..n)) else {
            return true;
        };
        let r = bus.write(db.get(), bytes).await;
        self.with(|t| match (r, op) {
            (Ok(()), Op::Assign { .. }) => bump(&mut t.diag.assigns),
            (Err(BusError::ArbitrationLost), op) => {
                bump(&mut t.diag.arbitration_lost);
                t.directory.put_back(&op);
            }
            _ => {}
        });
        if r == Err(BusError::ArbitrationLost) {
            // Back to the loop: its listener receives what won the bus, then the work again.
            self.keepalive_changed.signal(());
            return false;
        }
        true
    }

    /// A request to `board` went unanswered (NACK after every retry): a board the directory
    /// knows there is reported gone (counted in `boards_lost`, logged).
    fn board_gone(&self, board: Address) {
        self.went_silent(board.get());
        if self.with(|t| {
            let lost = t.directory.lost(board);
            if lost {
                bump(&mut t.diag.boards_lost);
            }
            lost
        }) {
            warn!("board {} stopped answering", board.get());
        }
    }

    /// The retry policy of a transaction to `addr`: `MbConfig::retry`, or a single attempt
    /// while `addr` is silent (its last request or preparation was NACKed at every attempt:
    /// an absent board). Without this every call to an absent board would hold the bus queue
    /// through all its attempts and their backoff (2.4 ms with the default), delaying every
    /// other board's requests behind it (measured on the emulated Pico: the update's chunks
    /// waited 8.75 ms instead of 4.07 ms behind Figure 4.4's calls to its absent board 9).
    #[inline(never)]
    fn retry_for(&self, addr: u8) -> RetryPolicy {
        let (word, bit) = silent_bit(addr);
        if self.with(|t| t.silent.get(word).is_some_and(|w| w & bit != 0)) {
            RetryPolicy {
                attempts: 1,
                ..self.config.retry
            }
        } else {
            self.config.retry
        }
    }

    /// `addr` acknowledged a transaction or wrote to us: it is not silent (any more).
    #[inline(never)]
    fn heard_from(&self, addr: u8) {
        let (word, bit) = silent_bit(addr);
        self.with(|t| {
            if let Some(w) = t.silent.get_mut(word) {
                *w &= !bit;
            }
        });
    }

    /// `addr` was NACKed at every attempt: silent from now on ([`MbCore::retry_for`]).
    #[inline(never)]
    fn went_silent(&self, addr: u8) {
        let (word, bit) = silent_bit(addr);
        self.with(|t| {
            if let Some(w) = t.silent.get_mut(word) {
                *w |= bit;
            }
        });
    }

    /// After [`MultiMaster::addressed`] returned: receives and serves that transaction, never
    /// raced. The source (first byte) of a write, if one was received.
    async fn receive<B: MultiMaster>(
        &self,
        bus: &mut B,
        addressed: Result<(), BusError>,
        rx: &mut [u8],
    ) -> Option<u8> {
        let incoming = match addressed {
            Ok(()) => bus.listen(rx).await,
            Err(e) => Err(e),
        };
        let source = match incoming {
            Ok(Incoming::Write(n)) if n > 0 => rx.first().copied(),
            _ => None,
        };
        if let Some(s) = source {
            self.heard_from(s);
        }
        self.serve_listener(bus, incoming, rx).await;
        source
    }

    async fn serve_listener<B: MultiMaster>(
        &self,
        bus: &mut B,
        incoming: Result<Incoming, BusError>,
        rx: &[u8],
    ) {
        match incoming {
            Ok(Incoming::Write(n)) => self.route_event_bytes(rx.get(..n).unwrap_or(rx)),
            Ok(Incoming::Read | Incoming::WriteRead(_)) => {
                self.with(|t| bump(&mut t.diag.unexpected_reads));
                let _ = bus.respond(&[]).await;
            }
            Err(_) => self.with(|t| bump(&mut t.diag.listener_errors)),
        }
    }

    /// Listens until `until`, or until a write to the motherboard whose first byte (an
    /// event's source) satisfies `wanted` has been served. True when one was.
    async fn listen_until<B: MultiMaster>(
        &self,
        bus: &mut B,
        until: Instant,
        rx: &mut [u8],
        wanted: impl Fn(u8) -> bool,
    ) -> bool {
        loop {
            let r = select(bus.addressed(), sleep_until(until)).await;
            match r {
                Either::First(addressed) => {
                    // Past `until` if need be: a transaction under way is received whole.
                    let source = self.receive(bus, addressed, rx).await;
                    if source.is_some_and(&wanted) {
                        return true;
                    }
                }
                Either::Second(()) => return false,
            }
        }
    }

    async fn dispatch<B: MultiMaster>(&self, bus: &mut B, job: &Job, nth: u32, rx: &mut [u8]) {
        let meta = &job.meta;
        if !self.is_queued(meta.ticket) {
            self.with(|t| bump(&mut t.diag.abandoned));
            return;
        }
        let seed = self.config.seed
            ^ nth.rotate_left(16)
            ^ (u32::from(meta.db.get()) << 8)
            ^ u32::from(meta.seq);
        let mut backoff = Backoff::new(self.retry_for(meta.db.get()), seed);
        let mut read = [0u8; MAX_FRAME_LEN];
        if meta.kind != JobKind::Request {
            self.dispatch_raw(bus, job, &mut backoff, &mut read, rx)
                .await;
            return;
        }
        let addr = meta.db.get();
        let switches_pec_on = request_op(&job.frame).and_then(|op| pec_change(&op)) == Some(true);
        loop {
            // The board is prepared (PEC on, failsafe set) before anything else reaches it,
            // at first contact and after each boot; the frame gets its PEC byte as the board
            // is now (a boot event may have come in while this job waited or backed off).
            if let Err(e) = self.ensure_ready(bus, meta.db, seed, rx).await {
                self.end_job(meta, Outcome::Complete(Err(e)), false, false);
                return;
            }
            // The preparation may have told the board's ports (identify): a request for a
            // port it lacks never goes out.
            let missing = request_op(&job.frame)
                .is_some_and(|op| self.with(|t| t.boards.check_ports(meta.db, &op).is_err()));
            if missing {
                let refused = Err(LinkError::Status(Status::PortOutOfRange));
                self.end_job(meta, Outcome::Complete(refused), false, false);
                return;
            }
            let (frame, pec) = self.frame_to_send(job);
            // A reply to `set_pec(1)` comes in the new mode, with PEC.
            let pec_read = pec || switches_pec_on;
            let op = request_op(&job.frame);
            let read_len = meta
                .read
                .map(|cap| reply_read_len(op.as_ref(), cap, pec_read));
            match self.attempt(bus, addr, &frame, read_len, &mut read).await {
                Ok(bytes) => {
                    self.finish_transfer(job, pec, Ok(bytes));
                    return;
                }
                Err(e) => {
                    if !self.after_failure(bus, e, &mut backoff, addr, rx).await {
                        warn!("request {} to {} failed", meta.seq, addr);
                        if e == BusError::Nack {
                            self.board_gone(meta.db);
                        }
                        self.finish_transfer(job, pec, Err(e));
                        return;
                    }
                }
            }
            if !self.is_queued(meta.ticket) {
                self.with(|t| bump(&mut t.diag.abandoned));
                return;
            }
        }
    }

    /// A general call (its frame with its check over the address byte 0x00, to every board)
    /// or a plain read of a board (`meta.read` bytes, no write first), retried as requests
    /// are; no board is prepared for it (that would take a sample held for the read). A NACK
    /// of a plain read marks the board gone; of a general call, it means no board took it.
    async fn dispatch_raw<B: MultiMaster>(
        &self,
        bus: &mut B,
        job: &Job,
        backoff: &mut Backoff,
        read: &mut [u8],
        rx: &mut [u8],
    ) {
        let meta = &job.meta;
        let general = meta.kind == JobKind::GeneralCall;
        let addr = if general { GENERAL_CALL } else { meta.db.get() };
        let mut frame = job.frame.clone();
        if general {
            let n = frame.len();
            let _ = frame.resize(n + 1, 0);
            if pec::append(GENERAL_CALL, &mut frame, n).is_err() {
                self.finish_transfer(job, true, Err(BusError::Overrun));
                return;
            }
        }
        loop {
            match self.attempt(bus, addr, &frame, meta.read, read).await {
                Ok(bytes) => {
                    self.finish_transfer(job, true, Ok(bytes));
                    return;
                }
                // A general call nobody acknowledges: no board takes them (built without
                // `together`); not retried, the caller reads each board on its own.
                Err(BusError::Nack) if general => {
                    self.finish_transfer(job, true, Err(BusError::Nack));
                    return;
                }
                Err(e) => {
                    if !self.after_failure(bus, e, backoff, addr, rx).await {
                        if e == BusError::Nack && !general {
                            self.board_gone(meta.db);
                        }
                        self.finish_transfer(job, true, Err(e));
                        return;
                    }
                }
            }
            if !self.is_queued(meta.ticket) {
                self.with(|t| bump(&mut t.diag.abandoned));
                return;
            }
        }
    }

    /// One transaction: `frame` written to `addr`, then `read_len` bytes read after a
    /// repeated START (`None`: a single write). The bytes read, if any.
    async fn attempt<'r, B: MultiMaster>(
        &self,
        bus: &mut B,
        addr: u8,
        frame: &[u8],
        read_len: Option<usize>,
        read: &'r mut [u8],
    ) -> Result<Option<&'r [u8]>, BusError> {
        let r = match read_len {
            Some(n) => match read.get_mut(..n) {
                Some(buf) if frame.is_empty() => bus.read(addr, buf).await.map(|()| Some(&*buf)),
                Some(buf) => bus.write_read(addr, frame, buf).await.map(|()| Some(&*buf)),
                None => Err(BusError::Overrun),
            },
            None => bus.write(addr, frame).await.map(|()| None),
        };
        // Acknowledged: the board is there (not silent, [`MbCore::retry_for`]).
        if r.is_ok() {
            self.heard_from(addr);
        }
        r
    }

    /// After a failed attempt with error `e`: listens for the backoff delay (after a lost
    /// arbitration at least `MbConfig::arbitration_wait_us`). A write to the motherboard
    /// that arrives meanwhile (after a NACK: from the board addressed) forgives the attempt.
    /// True to try again at once, false when the attempts are used up or `e` is not retried.
    async fn after_failure<B: MultiMaster>(
        &self,
        bus: &mut B,
        e: BusError,
        backoff: &mut Backoff,
        addr: u8,
        rx: &mut [u8],
    ) -> bool {
        let retry = match e {
            BusError::Nack => {
                self.with(|t| bump(&mut t.diag.nacked));
                true
            }
            BusError::ArbitrationLost => {
                self.with(|t| bump(&mut t.diag.arbitration_lost));
                true
            }
            BusError::Timeout | BusError::Bus | BusError::Overrun => false,
        };
        // The attempt counts only if no write to us arrives while we wait: decide on a
        // copy of the backoff.
        let mut counted = backoff.clone();
        let delay = if retry { counted.next_delay_us() } else { None };
        let wait = match (e, delay) {
            (BusError::ArbitrationLost, d) => {
                Some(d.unwrap_or(0).max(self.config.arbitration_wait_us))
            }
            (_, d) => d,
        };
        let Some(wait) = wait else {
            return false;
        };
        let until = now().plus_us(u64::from(wait));
        // After a lost arbitration any write to us may be what won the bus (or what a
        // single-role port was too busy to ACK); after a NACK only one from the board we
        // addressed is (it was busy sending it to us).
        let yielded = if e == BusError::ArbitrationLost {
            self.listen_until(bus, until, rx, |_| true).await
        } else {
            self.listen_until(bus, until, rx, |source| source == addr)
                .await
        };
        if yielded {
            // The bus is free again: retry at once, and the attempt does not count.
            self.with(|t| bump(&mut t.diag.yields));
        } else if delay.is_none() {
            return false;
        } else {
            *backoff = counted;
        }
        self.with(|t| bump(&mut t.diag.retries));
        true
    }

    /// Prepares external board `db` when the configuration asks for it and it has not been
    /// since its last boot: PEC on (`MbConfig::pec`), confirmed by the board's reply checked
    /// with PEC, then the failsafe (a program's own, else `MbConfig::failsafe_ms`),
    /// confirmed by its reply, and kept alive; then, unless its `boot` event told them, its
    /// ports (`identify`). A boot event that comes in meanwhile turns
    /// PEC off again and the preparation starts over (three rounds at most).
    async fn ensure_ready<B: MultiMaster>(
        &self,
        bus: &mut B,
        db: Address,
        seed: u32,
        rx: &mut [u8],
    ) -> Result<(), LinkError> {
        if db.is_internal() || !self.config.manages_boards() {
            return Ok(());
        }
        let mut last = Err(LinkError::BadReply);
        for _ in 0..3 {
            if self.with(|t| t.boards.ready(db)) {
                return Ok(());
            }
            last = self.prepare(bus, db, seed, rx).await;
            if last.is_err() {
                continue;
            }
            let pec_wanted = self.config.pec;
            if self.with(|t| {
                let done = !pec_wanted || t.boards.pec(db);
                if done {
                    t.boards.set_ready(db, true);
                }
                done
            }) {
                return Ok(());
            }
        }
        last
    }

    async fn prepare<B: MultiMaster>(
        &self,
        bus: &mut B,
        db: Address,
        seed: u32,
        rx: &mut [u8],
    ) -> Result<(), LinkError> {
        if self.config.pec && !self.with(|t| t.boards.pec(db)) {
            self.setup_op(bus, db, Op::SetPec(true), seed, rx).await?;
        }
        let ms = match self.with(|t| t.boards.keepalive.timeout_ms(db)) {
            0 => self.config.failsafe_ms,
            ms => ms,
        };
        if ms > 0 {
            self.setup_op(bus, db, Op::SetFailsafe { timeout_ms: ms }, seed, rx)
                .await?;
            let t_now = now();
            self.with(|t| t.boards.failsafe_set(db, ms, t_now));
            self.notify_keepalive();
        }
        // Its ports, unless its boot event told them: nothing to a port it lacks goes out.
        if !self.with(|t| t.boards.ports_known(db)) {
            self.setup_op(bus, db, Op::Identify, seed, rx).await?;
        }
        // The event enables it confirmed before it restarted: its pins report again, so a
        // task waiting for a button is not left waiting for good by a board's reset. One at a
        // time (no copy of the list held across the awaits).
        for i in 0..REMEMBERED_ENABLES {
            let Some((pin, cfg)) = self.with(|t| t.boards.enables_of(db).nth(i)) else {
                break;
            };
            self.setup_op(bus, db, Op::EventEnable(pin, cfg), seed, rx)
                .await?;
        }
        Ok(())
    }

    /// Sends one of the runtime's own set-up operations to `db` as a write-then-read and
    /// checks its reply ([`MbCore::interpret`]): Ok when the board confirmed it (for
    /// `set_pec(1)`: an `ok` checked with PEC, or a `pec_mismatch` checked with PEC, which
    /// shows PEC is on already). Gives up after the request timeout.
    async fn setup_op<B: MultiMaster>(
        &self,
        bus: &mut B,
        db: Address,
        op: Op<'_>,
        seed: u32,
        rx: &mut [u8],
    ) -> Result<(), LinkError> {
        let deadline = now().plus_us(self.config.request_timeout_us);
        self.own_op(bus, db, op, deadline, seed, rx).await
    }

    /// Sends an operation of the runtime's own to `db` with a fresh sequence number and no
    /// pending slot, retried until `deadline`: a heartbeat as a single write (Ok once
    /// acknowledged), anything else as a write-then-read whose reply is checked as in
    /// [`MbCore::setup_op`].
    async fn own_op<B: MultiMaster>(
        &self,
        bus: &mut B,
        db: Address,
        op: Op<'_>,
        deadline: Instant,
        seed: u32,
        rx: &mut [u8],
    ) -> Result<(), LinkError> {
        let seq = self.with(|t| t.requests.fresh_seq(db));
        let req = Request { db, seq, op };
        let mut frame: Vec<u8, MAX_FRAME_LEN> = Vec::new();
        let _ = frame.resize(req.buffer_len().min(MAX_FRAME_LEN), 0);
        let n = req.emit(&mut frame).map_err(LinkError::Invalid)?;
        frame.truncate(n);
        let reads = op != Op::Heartbeat;
        let job = Job::own(db, seq, reads.then(|| op.reply_capacity()), frame);
        let mut backoff = Backoff::new(self.retry_for(db.get()), seed ^ u32::from(seq));
        let mut read = [0u8; MAX_FRAME_LEN];
        loop {
            let (tx, pec) = self.frame_to_send(&job);
            let pec_read = pec || pec_change(&op) == Some(true);
            let read_len = reads.then(|| reply_read_len(Some(&op), op.reply_capacity(), pec_read));
            match self.attempt(bus, db.get(), &tx, read_len, &mut read).await {
                Ok(None) => {
                    let t_now = now();
                    self.with(|t| t.boards.keepalive.sent(db, t_now));
                    return Ok(());
                }
                Ok(Some(bytes)) => {
                    let (outcome, state) = self.interpret(&job.meta, pec, &op, bytes);
                    self.board_pec_is(db, state);
                    let t_now = now();
                    self.with(|t| t.boards.keepalive.sent(db, t_now));
                    if let (Op::Identify, Outcome::Complete(Ok(p))) = (op, &outcome) {
                        if let Ok(id) = x10_microcode::Identity::parse(p) {
                            self.with(|t| {
                                t.boards.identified(db, &id);
                                t.directory.identified(db, &id);
                            });
                        }
                    }
                    return match outcome {
                        Outcome::Complete(Ok(_)) => Ok(()),
                        Outcome::Complete(Err(LinkError::Status(Status::PecMismatch)))
                            if state == Some(true) && op == Op::SetPec(true) =>
                        {
                            Ok(())
                        }
                        Outcome::Complete(Err(e)) => Err(e),
                        Outcome::Defer { .. } => Err(LinkError::BadReply),
                    };
                }
                Err(e) => {
                    if now() >= deadline
                        || !self.after_failure(bus, e, &mut backoff, db.get(), rx).await
                    {
                        if e == BusError::Nack {
                            self.went_silent(db.get());
                        }
                        return Err(link_error(e));
                    }
                }
            }
        }
    }
}

/// How many bytes to read for a reply to `op` (of up to `capacity` payload bytes): the
/// header, the payload and, with the check on, the check of the longest such reply (a shorter
/// reply ends earlier, with its own check; the rest is padding). A reply whose length varies
/// always ends in a CRC-16 (`pec::append16`).
fn reply_read_len(op: Option<&Op<'_>>, capacity: usize, pec: bool) -> usize {
    let frame = REPLY_HEADER_LEN + capacity;
    if !pec {
        frame
    } else if op.is_some_and(|op| !op.reply_len().is_exact()) {
        frame + 2
    } else {
        frame + x10_microcode::pec::check_len(frame)
    }
}

/// Where 7-bit address `addr` is in `Table::silent`: its word and the bit in it.
const fn silent_bit(addr: u8) -> (usize, u32) {
    (((addr & 0x7f) >> 5) as usize, 1 << (addr & 31))
}
