//! The daughterboard core: validation and execution of microcode on a board's [`Ports`], the
//! held reply, the event queue and the shared state of the background work.

use core::cell::RefCell;

use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use heapless::Vec;
use x10_microcode::{
    pec, sweep, Address, Batch, BatchResults, BootInfo, Capabilities, Diagnostics, Edge,
    EventConfig, EventKind, Identity, Op, PinRef, Port, PortKind, Reply, RequestFrame, ScanResult,
    Status, MAX_PAYLOAD, MAX_REPLY_LEN, PROTOCOL_VERSION,
};

use crate::config::DbConfig;
use crate::event::OutEvent;
use crate::record::{AddressRecord, NoRecord, StoreError};
use x10_hal::ports::{EdgeCount, PortError, Ports};

/// Events the queue holds before it overflows.
pub const EVENT_QUEUE_LEN: usize = 16;
/// Pulse-in measurements accepted but not yet finished (queued or running). A measurement's
/// timeout runs from its acceptance, not from the moment a worker starts it, so a deferred
/// reply never comes later than acceptance + timeout + 1 ms (plus the end of a measurement under way).
pub const DEFERRED_QUEUE_LEN: usize = 4;
/// Pulse-in measurements that run at the same time (on different pins).
pub const DEFERRED_WORKERS: usize = 2;
/// Pins that can have events enabled at the same time.
pub const MAX_EVENT_PINS: usize = 16;
/// Size of a reply frame buffer: the largest reply and its PEC byte.
pub const REPLY_BUF_LEN: usize = MAX_REPLY_LEN + 1;

/// The value of a request (reply payload).
type Value = Vec<u8, MAX_PAYLOAD>;

// An executed request (or batch item) is its status, and its value written into the
// caller's `Value` (empty unless `ok`): a status is returned in a register, where a status
// and a value returned together were copied at each level (about 275 instructions per copy
// on the Cortex-M0, issue 27).

/// Puts `bytes` into `value`: `ok`, or `bad_length` (`value` left empty) if they do not fit.
/// Byte by byte: a value is 1 to 28 bytes, mostly 1 or 2, where a `memcpy` call costs more
/// than the copy.
#[inline(never)]
fn set_value(value: &mut Value, bytes: &[u8]) -> Status {
    value.clear();
    if bytes.len() > MAX_PAYLOAD {
        return Status::BadLength;
    }
    for &b in bytes {
        // Never full: checked above.
        let _ = value.push(b);
    }
    Status::Ok
}

/// The status of a port setting: `ok`, or its error's.
fn port_done(r: Result<(), PortError>) -> Status {
    match r {
        Ok(()) => Status::Ok,
        Err(e) => port_status(e),
    }
}

/// The status a port error is answered with.
pub(crate) const fn port_status(e: PortError) -> Status {
    match e {
        PortError::NoSuchPin => Status::PortOutOfRange,
        PortError::Unsupported => Status::Unsupported,
        PortError::Busy => Status::Busy,
        PortError::Timeout => Status::Timeout,
    }
}

/// Adds one to a counter, stopping at its maximum.
pub(crate) fn bump(c: &mut u16) {
    *c = c.saturating_add(1);
}

/// Counts the outcome of one request (or batch item) in the diagnostics.
fn count_status(d: &mut Diagnostics, s: Status) {
    let c = match s {
        Status::Ok | Status::Pending => &mut d.frames_ok,
        Status::BadLength => &mut d.bad_length,
        Status::UnknownFunction => &mut d.unknown_function,
        Status::UnknownOperand => &mut d.unknown_operand,
        Status::PortOutOfRange | Status::WrongPortKind => &mut d.port_errors,
        Status::WrongAddress => &mut d.wrong_address,
        Status::PecMismatch => &mut d.pec_errors,
        Status::BadArgument
        | Status::Unsupported
        | Status::Busy
        | Status::Timeout
        | Status::NoRequest
        | Status::WrongKind
        | Status::TooLarge
        | Status::BadCrc
        | Status::OutOfOrder
        | Status::TooOld
        | Status::FlashError
        | Status::NoSession
        | Status::Incomplete
        | Status::Unknown(_) => &mut d.other_errors,
    };
    bump(c);
}

/// One pin with events enabled, and what its last sample saw.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Watch {
    pub(crate) pin: PinRef,
    pub(crate) cfg: EventConfig,
    /// Bumped at every (re)configuration so that a sample taken under an old configuration is
    /// not applied to a new one.
    pub(crate) generation: u16,
    pub(crate) level: Option<bool>,
    pub(crate) inside: Option<bool>,
    /// The port latches this pin's edges ([`Ports::latch_edges`]); otherwise they are
    /// counted from the level changes the samples see.
    pub(crate) latched: bool,
    /// Edges counted since the pin's last `pin_change` event went into the queue.
    pub(crate) edges: EdgeCount,
    /// A `pin_change` event of this pin is in the queue: the next one waits until it has been
    /// taken out, and carries every edge counted meanwhile (coalescing).
    pub(crate) queued: bool,
}

/// A pulse-in accepted with `pending`, waiting for a worker.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PulseJob {
    /// When the board accepted it (stamped by the background work, see
    /// [`Daughterboard::run_background`]); `None` until then.
    pub(crate) accepted: Option<x10_hal::time::Instant>,
    pub(crate) seq: u8,
    pub(crate) pin: PinRef,
    pub(crate) edge: Edge,
    pub(crate) timeout_ms: u16,
}

pub(crate) struct State {
    pub(crate) pec: bool,
    pub(crate) diag: Diagnostics,
    /// The reply held for the next read: its bytes in `reply`, its length here (`None`: no
    /// reply held).
    reply_len: Option<u8>,
    reply: [u8; REPLY_BUF_LEN],
    pub(crate) failsafe_ms: u16,
    event_seq: u8,
    /// Events dropped since the last overflow event went into the queue.
    overflow_pending: u16,
    /// Events dropped since boot (carried by every overflow event, so a lost report loses
    /// no count).
    dropped_total: u32,
    pub(crate) watches: Vec<Watch, MAX_EVENT_PINS>,
    watch_generation: u16,
    /// Pins with a pulse-in queued or running.
    pub(crate) pulse_pins: Vec<PinRef, DEFERRED_QUEUE_LEN>,
    /// The address the board keeps now and moves to once its answer has gone out.
    moving: Option<Address>,
    /// Outputs held by a `stage` (its batch items) until an `apply`, and its sequence number.
    #[cfg(feature = "together")]
    staged: Vec<u8, { x10_microcode::MAX_REQUEST_DATA }>,
    #[cfg(feature = "together")]
    stage_seq: u8,
    /// A `stage` came since the background work last looked: its timeout starts.
    #[cfg(feature = "together")]
    pub(crate) stage_fresh: bool,
}

impl State {
    /// Drops what a `stage` held (the failsafe's trip, the stage timeout): the `stage`'s
    /// sequence number, `None` when nothing was held.
    #[cfg(feature = "together")]
    pub(crate) fn drop_staged(&mut self) -> Option<u8> {
        if self.staged.is_empty() {
            return None;
        }
        self.staged.clear();
        Some(self.stage_seq)
    }
}

/// What the header of a request says, as far as it could be read.
/// The check a reply ends in.
#[derive(Clone, Copy)]
enum Check {
    /// PEC off.
    None,
    /// A PEC byte, or a CRC-16 after a frame of more than 13 bytes.
    ByLength,
    /// A CRC-16 whatever the length (an operation whose reply length varies).
    Crc16,
}

struct Head {
    seq: u8,
    port: u8,
    expects_reply: bool,
    /// The operation's reply length varies (scan, serial read, batch): its reply always ends
    /// in a CRC-16 when checked (`pec::append16`).
    crc16_reply: bool,
}

/// A daughterboard: the microcode interpreter on a board's [`Ports`].
///
/// The same core serves a daughterboard on the bus ([`crate::run_target`] feeds it from
/// `MultiMaster::listen`) and the internal daughterboard of a motherboard (address 0, fed by
/// direct calls). Three things drive it:
///
/// * the transport calls [`Daughterboard::handle_write`] for every write addressed to the
///   board and [`Daughterboard::take_reply`] for every read;
/// * [`Daughterboard::run_background`] runs pulse-in measurements, samples pins with events
///   enabled and watches the failsafe timeout;
/// * the transport drains [`Daughterboard::next_event`] and delivers each event to the MB.
///
/// `M` is the raw mutex guarding the shared state (`CriticalSectionRawMutex` on boards,
/// `NoopRawMutex` on a single-threaded executor). Nothing here blocks or panics on bus input.
///
/// `R` is where the board keeps an address given over the bus ([`AddressRecord`]); a board
/// built with [`Daughterboard::new`] keeps none ([`NoRecord`]).
pub struct Daughterboard<M: RawMutex, P: Ports, R: AddressRecord = NoRecord> {
    ports: P,
    config: DbConfig,
    record: Mutex<M, RefCell<R>>,
    /// Signalled with the new address once the board has answered the request that gave it
    /// one (see [`Daughterboard::moved`]).
    moved: Signal<M, Address>,
    state: Mutex<M, RefCell<State>>,
    events: Channel<M, OutEvent, EVENT_QUEUE_LEN>,
    pub(crate) jobs: Channel<M, PulseJob, DEFERRED_QUEUE_LEN>,
    /// Accepted pulse-ins with their acceptance time, for the workers. Never full: a job is in
    /// `jobs` or here only while its pin is in `pulse_pins` (at most [`DEFERRED_QUEUE_LEN`]).
    pub(crate) stamped: Channel<M, PulseJob, DEFERRED_QUEUE_LEN>,
    /// Signalled after every transaction addressed to the board (failsafe).
    pub(crate) heard: Signal<M, ()>,
    /// Wakes the sampler when it may have work other than a latched edge: event enables
    /// changed, an event left the queue (a pin's carried edges may go out; after a deferred
    /// reply, its pin is free to read again).
    pub(crate) wake: Signal<M, ()>,
}

impl<M: RawMutex, P: Ports> Daughterboard<M, P, NoRecord> {
    /// A daughterboard on `ports` that keeps no address of its own (`set_address` is answered
    /// `unsupported`). Nothing runs until the transport and
    /// [`Daughterboard::run_background`] are polled.
    pub fn new(ports: P, config: DbConfig) -> Self {
        Self::with_record(ports, config, NoRecord)
    }
}

impl<M: RawMutex, P: Ports, R: AddressRecord> Daughterboard<M, P, R> {
    /// A daughterboard on `ports` that keeps an address given over the bus in `record`
    /// (`config.address` is where it starts: [`crate::start_address`]).
    pub fn with_record(ports: P, config: DbConfig, record: R) -> Self {
        Daughterboard {
            ports,
            config,
            record: Mutex::new(RefCell::new(record)),
            moved: Signal::new(),
            state: Mutex::new(RefCell::new(State {
                pec: false,
                diag: Diagnostics::default(),
                reply_len: None,
                reply: [0; REPLY_BUF_LEN],
                failsafe_ms: config.failsafe_timeout_ms,
                event_seq: 0,
                overflow_pending: 0,
                dropped_total: 0,
                watches: Vec::new(),
                watch_generation: 0,
                pulse_pins: Vec::new(),
                moving: None,
                #[cfg(feature = "together")]
                staged: Vec::new(),
                #[cfg(feature = "together")]
                stage_seq: 0,
                #[cfg(feature = "together")]
                stage_fresh: false,
            })),
            events: Channel::new(),
            jobs: Channel::new(),
            stamped: Channel::new(),
            heard: Signal::new(),
            wake: Signal::new(),
        }
    }

    pub(crate) fn with<T>(&self, f: impl FnOnce(&mut State) -> T) -> T {
        self.state.lock(|s| f(&mut s.borrow_mut()))
    }

    /// The board's ports.
    pub fn ports(&self) -> &P {
        &self.ports
    }

    /// The configuration.
    pub fn config(&self) -> &DbConfig {
        &self.config
    }

    /// The board's own address.
    pub fn address(&self) -> Address {
        self.config.address
    }

    /// What `identify` answers.
    pub fn identity(&self) -> Identity {
        Identity {
            protocol_version: PROTOCOL_VERSION,
            firmware: self.config.firmware,
            board: self.config.board,
            sensor_ports: self.ports.sensor_ports().min(Port::MAX_PORTS),
            actuator_ports: self.ports.actuator_ports().min(Port::MAX_PORTS),
            capabilities: Capabilities(self.config.capabilities.0 & !Capabilities::SERIAL),
            adc_bits: self.ports.adc_bits(),
        }
    }

    /// The payload of `boot` and `announce` without the ID (which [`Self::encode_event`]
    /// appends, so the queue holds 8 bytes less per event).
    pub(crate) fn boot_info(&self) -> [u8; BootInfo::LEN_NO_UID] {
        let mut b = [0u8; BootInfo::LEN_NO_UID];
        let (id, reason) = b.split_at_mut(Identity::LEN);
        id.copy_from_slice(&self.identity().to_bytes());
        reason.fill(self.config.reset_reason.to_byte());
        b
    }

    /// A copy of the diagnostics counters.
    pub fn diagnostics(&self) -> Diagnostics {
        self.with(|s| s.diag)
    }

    /// True when PEC is negotiated (every request, reply and event carries one more byte).
    pub fn pec_enabled(&self) -> bool {
        self.with(|s| s.pec)
    }

    /// The failsafe timeout in ms (0: off).
    pub fn failsafe_timeout_ms(&self) -> u16 {
        self.with(|s| s.failsafe_ms)
    }

    /// Events waiting in the queue.
    pub fn events_queued(&self) -> usize {
        self.events.len()
    }

    /// True while the board has no address ([`Address::UNADDRESSED`]): it announces itself
    /// and takes nothing but an `assign` with its own ID.
    pub fn is_unaddressed(&self) -> bool {
        self.config.address.is_unaddressed()
    }

    /// Returns the address the board was given (`assign`, `set_address`) and has kept, once
    /// its answer is out: the image restarts the board there (on a chip: a reset; the
    /// simulator: a restart of the board on its node, at the new address).
    pub async fn moved(&self) -> Address {
        self.moved.wait().await
    }

    /// The transport calls this after each transaction addressed to the board has been
    /// served to its end ([`crate::run_target`] does): a move decided by it
    /// ([`Daughterboard::moved`]) takes effect once no reply is held any more (the reply to
    /// `set_address` has been read).
    pub fn served(&self) {
        if let Some(a) = self.with(|s| s.moving.filter(|_| s.reply_len.is_none())) {
            self.moved.signal(a);
        }
    }

    /// Keeps `address` in the record and marks the move; the status to answer.
    fn keep_address(&self, address: Address) -> Status {
        match self.record.lock(|r| r.borrow_mut().store(address)) {
            Ok(()) => {
                self.with(|s| s.moving = Some(address));
                Status::Ok
            }
            Err(StoreError::NoRecord) => Status::Unsupported,
            Err(StoreError::Failed) => Status::Busy,
        }
    }

    /// System 12 (`enter`) and 13 through the record's hooks; the status to answer. After
    /// `enter_update` the board resets once its reply has been read, as after a move to the
    /// address it has ([`Daughterboard::moved`]).
    fn firmware(&self, enter: bool) -> Status {
        let r = self.record.lock(|r| {
            let mut r = r.borrow_mut();
            if enter {
                r.enter_update()
            } else {
                r.confirm_firmware()
            }
        });
        match r {
            Ok(()) => {
                if enter {
                    self.with(|s| s.moving = Some(self.config.address));
                }
                Status::Ok
            }
            Err(StoreError::NoRecord) => Status::Unsupported,
            Err(StoreError::Failed) => Status::Busy,
        }
    }

    /// Executes one write addressed to this board (`bytes` as received, PEC byte included
    /// when PEC is on). `read_follows` is true when the transaction continues with a read
    /// after a repeated START (`Incoming::WriteRead`).
    ///
    /// Afterwards a reply is held for the next read when the request expects one, or when
    /// `read_follows` (so every read gets a reply, also for an output or a refused frame).
    /// A refused request that nobody will read (an output, or a frame too broken to tell) is
    /// reported by a `rejected` event instead. Every outcome is counted in the diagnostics.
    ///
    /// Calls must not overlap: the transport serves one transaction at a time (the
    /// motherboard holds a lock around the internal board).
    ///
    /// It is synchronous: the port calls are ([`Ports`]), and a pulse-in only starts here
    /// (its measurement runs in [`Daughterboard::run_background`]), so a request is executed
    /// at once. Not being an `async fn` saves the state machines of the execution path
    /// (0.55 KiB of flash on db-pico, issue 24).
    pub fn handle_write(&self, bytes: &[u8], read_follows: bool) {
        // An unaddressed board checks every frame (nothing reaches 0x77 without its check).
        let pec_on = self.pec_enabled() || self.is_unaddressed();
        let broadcast = is_broadcast(bytes) && !self.config.address.is_internal();
        if broadcast && self.is_unaddressed() {
            return;
        }
        let mut value = Value::new();
        let (head, status) = self.execute_frame(bytes, pec_on, broadcast, &mut value);
        self.with(|s| count_status(&mut s.diag, status));
        if self.is_unaddressed() {
            // Nothing is read at 0x77 and nothing is reported from there but `announce`.
        } else if head.expects_reply || read_follows {
            self.store_reply(head.seq, status, &value, broadcast, head.crc16_reply);
        } else if !matches!(status, Status::Ok | Status::Pending) && !broadcast {
            // A general call is answered by no event (every board would send one).
            self.push_event(
                EventKind::Rejected,
                PinRef::from_byte(head.port),
                Some(head.seq),
                status,
                &[],
            );
        }
        self.heard.signal(());
    }

    /// Executes `op`, an operation already parsed and addressed to this board, in the
    /// caller, and returns its status and value: what [`Daughterboard::handle_write`] does
    /// for a request with that operation, without the frame (no parsing, no PEC, no reply
    /// held, no `rejected` event: the caller has the status). The same checks (capability,
    /// port range, the port's own errors), counted in the diagnostics as a frame is, and the
    /// failsafe fed, as by any transaction addressed to the board.
    ///
    /// The motherboard runs its internal daughterboard this way (its direct path). `seq` is
    /// the number a deferred operation's later reply carries (a pulse-in answers `pending`
    /// and measures in [`Daughterboard::run_background`]); a batch is executed item by item
    /// as from the bus. A board without an address takes nothing but `assign` over the bus:
    /// here it refuses everything (`bad_argument`). Calls must not overlap with each other
    /// or with `handle_write` (the motherboard holds a lock around the internal board).
    ///
    /// The value goes into `value` (emptied first; it stays empty unless the status is `ok`).
    pub fn execute(&self, seq: u8, op: &Op<'_>, value: &mut x10_microcode::Payload) -> Status {
        value.clear();
        let status = if self.is_unaddressed() {
            Status::BadArgument
        } else {
            match *op {
                Op::Batch(b) => self.execute_batch(seq, b, value),
                _ => self.execute_op(seq, op, value),
            }
        };
        self.with(|s| {
            // The usual outcome without `count_status`'s look-up (which the bus path shares).
            if status == Status::Ok {
                bump(&mut s.diag.frames_ok);
            } else {
                count_status(&mut s.diag, status);
            }
        });
        self.heard.signal(());
        status
    }

    /// Answers a read: copies the held reply into `buf` (as much as fits) and returns its
    /// length. With no reply held the answer is status `no_request` with sequence number 0
    /// (counted in `no_request_reads`). The reply is given once.
    pub fn take_reply(&self, buf: &mut [u8]) -> usize {
        // The held reply is copied out under the lock, straight from where it was encoded;
        // with none held, the `no_request` answer is encoded there first (one copy path).
        let n = self.with(|s| {
            let len = match s.reply_len.take() {
                Some(len) => len,
                None => {
                    bump(&mut s.diag.no_request_reads);
                    let check = if s.pec { Check::ByLength } else { Check::None };
                    // At most REPLY_BUF_LEN (34) bytes.
                    self.encode_reply(&mut s.reply, 0, Status::NoRequest, &[], check) as u8
                }
            };
            let n = usize::from(len).min(buf.len());
            if let (Some(dst), Some(src)) = (buf.get_mut(..n), s.reply.get(..n)) {
                dst.copy_from_slice(src);
            }
            n
        });
        self.heard.signal(());
        n
    }

    /// Waits for the next event to deliver. Once one is taken out (so there is room), a
    /// pending overflow report goes into the queue.
    pub async fn next_event(&self) -> OutEvent {
        let ev = self.events.receive().await;
        self.taken_out(&ev);
        self.report_overflow();
        ev
    }

    /// An event left the queue: a `pin_change` lets its pin queue the next one, and any
    /// makes room. The sampler is woken so that edges carried meanwhile go out without
    /// waiting for another edge of the pin. (Not inlined: 56 B less on the C011.)
    #[inline(never)]
    fn taken_out(&self, ev: &OutEvent) {
        if ev.kind == EventKind::PinChange {
            self.with(|s| {
                if let Some(w) = s.watches.iter_mut().find(|w| w.pin == ev.pin) {
                    w.queued = false;
                }
            });
        }
        self.wake.signal(());
    }

    /// The next event, if one is queued (see [`Daughterboard::next_event`]).
    pub fn try_next_event(&self) -> Option<OutEvent> {
        let ev = self.events.try_receive().ok()?;
        self.taken_out(&ev);
        self.report_overflow();
        Some(ev)
    }

    /// Encodes `ev` as sent by this board to the motherboard at `mb` (with its check when
    /// PEC is on, and a `boot` event always: it is the one frame a board sends before the MB
    /// could switch PEC on, and one flipped bit in it must not go unseen) into `buf`; returns
    /// the length, 0 if `buf` is too short.
    pub fn encode_event(&self, ev: &OutEvent, mb: Address, buf: &mut [u8]) -> usize {
        let mut e = ev.as_event(self.config.address);
        // `boot` and `announce` carry the board's ID after what was queued.
        let mut with_uid = [0u8; BootInfo::LEN];
        if e.always_checked() {
            let (info, uid) = with_uid.split_at_mut(BootInfo::LEN_NO_UID);
            if let Some(src) = ev.payload.get(..BootInfo::LEN_NO_UID) {
                info.copy_from_slice(src);
            }
            uid.copy_from_slice(&self.config.uid.0);
            e.payload = &with_uid;
        }
        let r = if self.pec_enabled() || e.always_checked() {
            e.emit_with_pec(mb, buf)
        } else {
            e.emit(buf)
        };
        r.unwrap_or(0)
    }

    /// Encodes a reply into `buf` (room for [`REPLY_BUF_LEN`] bytes); returns its length.
    fn encode_reply(
        &self,
        buf: &mut [u8; REPLY_BUF_LEN],
        seq: u8,
        status: Status,
        value: &[u8],
        check: Check,
    ) -> usize {
        let reply = Reply {
            seq,
            status,
            payload: value,
        };
        // A value never exceeds MAX_PAYLOAD (it is a Vec of that capacity) and the buffer has
        // room for the longest reply and its check, so neither step fails; if one did, the
        // answer would be empty (padding, which the MB refuses).
        let addr = self.config.address.addr_byte(true);
        reply
            .emit(buf)
            .and_then(|n| match check {
                Check::None => Ok(n),
                Check::ByLength => pec::append(addr, buf, n),
                Check::Crc16 => pec::append16(addr, buf, n),
            })
            .unwrap_or(0)
    }

    /// Encodes the reply to hold in place, where [`Daughterboard::take_reply`] copies it from.
    /// Its check: in the PEC mode the board has now (read under the same lock), so the reply
    /// to a `set_pec` the board applied is sent in the new mode and a motherboard reading it
    /// back knows the switch happened (with PEC on: a reply with a valid PEC byte); always
    /// for the reply to a general call (`general`: `sample`, `apply`, held for a plain read);
    /// a CRC-16 for a reply whose length varies (`varies`).
    fn store_reply(&self, seq: u8, status: Status, value: &[u8], general: bool, varies: bool) {
        self.with(|s| {
            let check = match (s.pec || general, varies) {
                (false, _) => Check::None,
                (true, false) => Check::ByLength,
                (true, true) => Check::Crc16,
            };
            let len = self.encode_reply(&mut s.reply, seq, status, value, check);
            // At most REPLY_BUF_LEN (34) bytes.
            s.reply_len = Some(len as u8);
        });
    }

    /// Puts an event into the queue. `seq: None` numbers it with the board's event counter.
    /// A full queue drops it, counts it in `events_dropped`, and remembers to report it in an
    /// overflow event as soon as there is room; while such a report is waiting, a new event
    /// goes in only if the report fits in front of it. A dropped event still takes its
    /// number from the event counter, so the MB sees the gap. True when it was queued.
    pub(crate) fn push_event(
        &self,
        kind: EventKind,
        pin: PinRef,
        seq: Option<u8>,
        status: Status,
        payload: &[u8],
    ) -> bool {
        self.with(|s| {
            if s.overflow_pending > 0 {
                if self.events.free_capacity() >= 2 {
                    self.queue_overflow(s);
                } else {
                    let _ = seq.unwrap_or_else(|| next_seq(s));
                    count_dropped(s);
                    return false;
                }
            }
            let seq = seq.unwrap_or_else(|| next_seq(s));
            let ev = OutEvent::new(kind, pin, seq, status, payload);
            if self.events.try_send(ev).is_err() {
                count_dropped(s);
                return false;
            }
            true
        })
    }

    /// Queues an event that must not be lost (a deferred reply): waits for room.
    pub(crate) async fn send_event(&self, ev: OutEvent) {
        self.events.send(ev).await;
    }

    /// Counts an event that could not be delivered (retries used up) as dropped, to be
    /// reported in an overflow event.
    pub(crate) fn event_lost(&self) {
        self.with(count_dropped);
        self.report_overflow();
    }

    fn report_overflow(&self) {
        self.with(|s| {
            if s.overflow_pending > 0 && self.events.free_capacity() >= 1 {
                self.queue_overflow(s);
            }
        })
    }

    /// Queues an overflow report: the events dropped since the last report (u16) and since
    /// boot (u32), so that a report that is itself lost loses no count.
    fn queue_overflow(&self, s: &mut State) {
        if self.events.free_capacity() == 0 {
            return;
        }
        let seq = next_seq(s);
        let [a, b] = s.overflow_pending.to_le_bytes();
        let [c, d, e, f] = s.dropped_total.to_le_bytes();
        let payload = [a, b, c, d, e, f];
        let ev = OutEvent::new(
            EventKind::Overflow,
            PinRef::from_byte(0),
            seq,
            Status::Ok,
            &payload,
        );
        if self.events.try_send(ev).is_ok() {
            s.overflow_pending = 0;
        }
    }

    /// Validates and executes one frame.
    fn execute_frame(
        &self,
        bytes: &[u8],
        pec_on: bool,
        broadcast: bool,
        value: &mut Value,
    ) -> (Head, Status) {
        let mut head = Head {
            seq: bytes.get(3).copied().unwrap_or(0),
            port: bytes.get(2).copied().unwrap_or(0),
            expects_reply: false,
            crc16_reply: false,
        };
        let body = if pec_on || broadcast {
            // A general call always carries its check, over the address byte 0x00.
            let addr = if broadcast {
                sweep::GENERAL_CALL
            } else {
                self.config.address.addr_byte(false)
            };
            match pec::strip(addr, bytes) {
                Ok(b) => b,
                // `who_is_there` is taken without its check too: the motherboard's start-up
                // sweep cannot know the board's PEC setting, and it changes nothing.
                Err(_) if !self.is_unaddressed() && matches!(bytes, [0x0b, _, 0, _]) => bytes,
                Err(e) => return (head, e.status()),
            }
        } else {
            bytes
        };
        let frame = match RequestFrame::new_checked(body) {
            Ok(f) => f,
            Err(e) => return (head, e.status()),
        };
        if frame.db() != self.config.address.get() && !broadcast {
            return (head, Status::WrongAddress);
        }
        let op = match Op::parse(frame.fn_op(), frame.port_byte(), frame.data()) {
            // Only `sample` and `apply` are written to every board at once.
            Ok(op) if broadcast && !matches!(op, Op::Sample | Op::Apply) => {
                return (head, Status::BadArgument)
            }
            Ok(op) => op,
            Err(e) => return (head, e.status()),
        };
        if self.is_unaddressed() {
            // Only `assign`, and only with this board's ID: everything else is dropped (an
            // assign for another board is no error).
            let status = match op {
                Op::Assign { uid, address } if uid == self.config.uid => self.keep_address(address),
                Op::Assign { .. } => Status::Ok,
                _ => Status::BadArgument,
            };
            return (head, status);
        }
        head.expects_reply = op.expects_reply();
        head.crc16_reply = op.reply_len_varies();
        let status = match op {
            Op::Batch(b) => self.execute_batch(head.seq, b, value),
            op => self.execute_op(head.seq, &op, value),
        };
        (head, status)
    }

    fn has(&self, bits: u16) -> bool {
        self.config.capabilities.has(bits)
    }

    /// Port range check: the port must exist on this board for its kind.
    fn check_port(&self, port: Port) -> Result<(), Status> {
        let count = match port.kind() {
            PortKind::Sensor => self.ports.sensor_ports(),
            PortKind::Actuator => self.ports.actuator_ports(),
        };
        if port.index() < count {
            Ok(())
        } else {
            Err(Status::PortOutOfRange)
        }
    }

    /// `run()` when the board has the capability `bits` (0: none needed), else
    /// `unsupported`.
    #[inline(always)]
    fn needs(&self, bits: u16, run: impl FnOnce() -> Status) -> Status {
        if bits == 0 || self.has(bits) {
            run()
        } else {
            Status::Unsupported
        }
    }

    /// `run()` when the board has the capability `bits` (0: none needed) and the port
    /// `port`, else `unsupported` or `port_out_of_range`, in that order.
    #[inline(always)]
    fn on_port(&self, bits: u16, port: Port, run: impl FnOnce() -> Status) -> Status {
        self.needs(bits, || match self.check_port(port) {
            Ok(()) => run(),
            Err(s) => s,
        })
    }

    fn execute_batch(&self, seq: u8, batch: Batch<'_>, value: &mut Value) -> Status {
        if !self.has(Capabilities::BATCH) {
            return Status::Unsupported;
        }
        let mut buf = [0u8; MAX_PAYLOAD];
        let mut used = 0usize;
        let mut item = Value::new();
        for op in batch.iter() {
            item.clear();
            let status = self.execute_op(seq, &op, &mut item);
            if !status.is_ok() {
                self.with(|s| count_status(&mut s.diag, status));
            }
            let Some(rest) = buf.get_mut(used..) else {
                return Status::BadArgument;
            };
            match BatchResults::emit(rest, status, &item) {
                Ok(n) => used += n,
                // `Batch::new_checked` made sure every result fits one reply.
                Err(_) => return Status::BadArgument,
            }
        }
        set_value(value, buf.get(..used).unwrap_or(&[]))
    }

    /// Executes one operation (a request's, or one item of a batch): its status; its value
    /// in `value` (left empty unless `ok`).
    ///
    /// One `match` on the operation: each arm checks what its operation needs (a capability,
    /// then the port), where a capability match and a port match before it were two more
    /// jump tables (384 B of them in all on db-pico) and two more dispatches per request
    /// (issue 27).
    fn execute_op(&self, seq: u8, op: &Op<'_>, value: &mut Value) -> Status {
        let p = &self.ports;
        match *op {
            Op::Ping | Op::Heartbeat => Status::Ok,
            Op::Identify => set_value(value, &self.identity().to_bytes()),
            Op::SetFailsafe { timeout_ms } => self.needs(Capabilities::FAILSAFE, || {
                self.with(|s| s.failsafe_ms = timeout_ms);
                Status::Ok
            }),
            Op::EventEnable(pin, cfg) => self.on_port(Capabilities::EVENTS, pin.port, || {
                self.enable_events(pin, cfg)
            }),
            Op::ReadDiagnostics => set_value(value, &self.diagnostics().to_bytes()),
            Op::ClearDiagnostics => {
                self.with(|s| s.diag = Diagnostics::default());
                Status::Ok
            }
            Op::SetPec(on) => self.needs(if on { Capabilities::PEC } else { 0 }, || {
                self.with(|s| s.pec = on);
                Status::Ok
            }),
            Op::DigitalRead(pin) => self.on_port(0, pin.port, || match p.digital_read(pin) {
                Ok(l) => set_value(value, &[l.is_high() as u8]),
                Err(e) => port_status(e),
            }),
            Op::DigitalWrite(pin, level) => {
                self.on_port(0, pin.port, || port_done(p.digital_write(pin, level)))
            }
            Op::PulseIn {
                pin,
                edge,
                timeout_ms,
            } => self.on_port(Capabilities::PULSE_IN, pin.port, || {
                self.start_pulse(seq, pin, edge, timeout_ms)
            }),
            Op::PwmDuty(pin, duty) => {
                self.on_port(0, pin.port, || port_done(p.pwm_duty(pin, duty)))
            }
            Op::PwmFrequency(port, hz) => self.on_port(Capabilities::PWM_FREQUENCY, port, || {
                port_done(p.pwm_frequency(port, hz))
            }),
            Op::PwmPulseWidth(pin, us) => {
                self.on_port(Capabilities::PWM_PULSE_WIDTH, pin.port, || {
                    port_done(p.pwm_pulse_width(pin, us))
                })
            }
            Op::AnalogRead(port) => self.on_port(0, port, || match p.analog_read(port) {
                Ok(v) => set_value(value, &v.to_le_bytes()),
                Err(e) => port_status(e),
            }),
            Op::SerialWrite(port, _) | Op::SerialRead(port, _) | Op::SerialConfig(port, _) => {
                self.on_port(0, port, || Status::Unsupported)
            }
            // A batch cannot hold a batch (the parser refuses it).
            Op::Batch(_) => self.needs(Capabilities::BATCH, || Status::BadArgument),
            // An `assign` reaches only unaddressed boards (`execute_frame`): a board with an
            // address ignores it.
            Op::Assign { .. } => Status::BadArgument,
            Op::SetAddress(a) => self.keep_address(a),
            Op::EnterUpdate => self.firmware(true),
            Op::ConfirmFirmware => self.firmware(false),
            // Function 7 is the bootloader's.
            Op::Update(_) => Status::Unsupported,
            Op::Blink(secs) => port_done(p.blink(secs)),
            Op::WhoIsThere => {
                self.push_event(
                    EventKind::Announce,
                    PinRef::from_byte(0),
                    None,
                    Status::Ok,
                    &self.boot_info(),
                );
                Status::Ok
            }
            // A `sample` reads what a `scan` does, its values packed in 12 bits (one above:
            // `unsupported`, the MB scans that board instead).
            #[cfg(feature = "together")]
            Op::Scan | Op::Sample => self.needs(Capabilities::SCAN, || match self.read_sensors() {
                Ok(r) => {
                    let mut buf = [0u8; MAX_PAYLOAD];
                    let n = if matches!(op, Op::Sample) {
                        sweep::pack(&r, &mut buf)
                    } else {
                        r.emit(&mut buf)
                    };
                    match n {
                        Ok(len) => set_value(value, buf.get(..len).unwrap_or(&[])),
                        Err(_) => Status::Unsupported,
                    }
                }
                Err(s) => s,
            }),
            #[cfg(not(feature = "together"))]
            Op::Scan => self.needs(Capabilities::SCAN, || match self.read_sensors() {
                Ok(r) => {
                    let mut buf = [0u8; MAX_PAYLOAD];
                    match r.emit(&mut buf) {
                        Ok(len) => set_value(value, buf.get(..len).unwrap_or(&[])),
                        Err(_) => Status::BadLength,
                    }
                }
                Err(s) => s,
            }),
            #[cfg(feature = "together")]
            Op::Stage(b) => self.stage(seq, b),
            #[cfg(feature = "together")]
            Op::Apply => self.apply(seq),
            #[cfg(not(feature = "together"))]
            Op::Sample | Op::Stage(_) | Op::Apply => Status::Unsupported,
        }
    }

    /// `stage`: held (replacing what was held) until `apply` or the timeout; nothing is
    /// executed. Its items were parsed (outputs only); each is checked as it is executed.
    #[cfg(feature = "together")]
    fn stage(&self, seq: u8, b: Batch<'_>) -> Status {
        self.with(|s| {
            s.staged.clear();
            let _ = s.staged.extend_from_slice(b.as_bytes());
            s.stage_seq = seq;
            s.stage_fresh = true;
        });
        Status::Ok
    }

    /// `apply`: executes what is held, item by item; the first refusal is the status (held
    /// for the MB's plain read). With nothing held it does nothing (`ok`).
    #[cfg(feature = "together")]
    fn apply(&self, seq: u8) -> Status {
        let held = self.with(|s| core::mem::take(&mut s.staged));
        let mut status = Status::Ok;
        let mut item = Value::new();
        for op in x10_microcode::BatchItems::of_checked(&held) {
            let s = self.execute_op(seq, &op, &mut item);
            if status.is_ok() {
                status = s;
            }
        }
        status
    }

    /// Drops held outputs no `apply` took (see [`sweep::STAGE_TIMEOUT_MS`]): counted as a
    /// `timeout` and reported in a `rejected` event with the `stage`'s sequence number.
    #[cfg(feature = "together")]
    pub(crate) fn drop_stage(&self) {
        let seq = self.with(|s| {
            let seq = s.drop_staged()?;
            count_status(&mut s.diag, Status::Timeout);
            Some(seq)
        });
        if let Some(seq) = seq {
            self.push_event(
                EventKind::Rejected,
                PinRef::from_byte(0),
                Some(seq),
                Status::Timeout,
                &[],
            );
        }
    }

    fn enable_events(&self, pin: PinRef, cfg: EventConfig) -> Status {
        if cfg.analog_window && pin.port.kind() != PortKind::Sensor {
            return Status::WrongPortKind;
        }
        let off = !(cfg.rising || cfg.falling || cfg.analog_window);
        // Edges are latched from now on where the port can (counted from zero again at each
        // enable); otherwise they are counted from the samples.
        let latched = (cfg.rising || cfg.falling) && self.ports.latch_edges(pin).is_ok();
        let status = self.with(|s| {
            s.watch_generation = s.watch_generation.wrapping_add(1);
            let generation = s.watch_generation;
            let fresh = Watch {
                pin,
                cfg,
                generation,
                level: None,
                inside: None,
                latched,
                edges: EdgeCount::NONE,
                queued: false,
            };
            match s.watches.iter().position(|w| w.pin == pin) {
                Some(i) if off => {
                    s.watches.swap_remove(i);
                    Status::Ok
                }
                Some(i) => {
                    if let Some(w) = s.watches.get_mut(i) {
                        *w = fresh;
                    }
                    Status::Ok
                }
                None if off => Status::Ok,
                None => match s.watches.push(fresh) {
                    Ok(()) => Status::Ok,
                    Err(_) => Status::Busy,
                },
            }
        });
        self.wake.signal(());
        status
    }

    fn start_pulse(&self, seq: u8, pin: PinRef, edge: Edge, timeout_ms: Option<u16>) -> Status {
        let job = PulseJob {
            accepted: None,
            seq,
            pin,
            edge,
            timeout_ms: timeout_ms.unwrap_or(self.config.default_pulse_timeout_ms),
        };
        self.with(|s| {
            if s.pulse_pins.contains(&pin) || s.pulse_pins.push(pin).is_err() {
                return Status::Busy;
            }
            if self.jobs.try_send(job).is_err() {
                // The pin pushed just above is the last one.
                s.pulse_pins.pop();
                return Status::Busy;
            }
            Status::Pending
        })
    }

    /// Every sensor port's levels and analog value (what `scan` and `sample` report).
    fn read_sensors(&self) -> Result<ScanResult, Status> {
        let n = self.ports.sensor_ports().min(ScanResult::MAX_PORTS as u8);
        let mut r = ScanResult {
            ports: n,
            ..ScanResult::default()
        };
        for i in 0..n {
            // Sensor port i + 1 (byte 2: bit 7 sensor, bits 1-6 the index, bit 0 the pin;
            // at most 8 ports here).
            let port = Port::from_byte(0x80 | (i << 1));
            for bit in 0..2u8 {
                match self
                    .ports
                    .digital_read(PinRef::from_byte(0x80 | (i << 1) | bit))
                {
                    Ok(level) => {
                        if level.is_high() {
                            r.digital |= 1 << (2 * u32::from(i) + u32::from(bit));
                        }
                    }
                    Err(e) => return Err(port_status(e)),
                }
            }
            match self.ports.analog_read(port) {
                Ok(v) => {
                    if let Some(slot) = r.analog.get_mut(usize::from(i)) {
                        *slot = v;
                    }
                }
                Err(e) => return Err(port_status(e)),
            }
        }
        Ok(r)
    }
}

/// A frame written to the general call address: byte 1 (the DB address) is 0, which no board
/// on the bus has (only the motherboard's internal board, which is never on the bus).
fn is_broadcast(bytes: &[u8]) -> bool {
    cfg!(feature = "together") && bytes.get(1) == Some(&0)
}

fn count_dropped(s: &mut State) {
    s.overflow_pending = s.overflow_pending.saturating_add(1);
    s.dropped_total = s.dropped_total.saturating_add(1);
    bump(&mut s.diag.events_dropped);
}

fn next_seq(s: &mut State) -> u8 {
    let seq = s.event_seq;
    s.event_seq = seq.wrapping_add(1);
    seq
}
