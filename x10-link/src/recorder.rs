//! The motherboard's side of the link, portable: [`Recorder`] keeps the frames waiting for the
//! laptop in one fixed ring of bytes, and [`serve`] answers the laptop's requests.
//!
//! The recorder is a `firmware_mb::CallObserver` (`Motherboard::with_observer`): robot tasks
//! tell it of every call and event themselves, inside their own poll, so it never waits: it
//! takes a critical section, writes the whole frame if it fits and counts it dropped if it
//! does not. While no laptop listens (before its hello, after its bye or an unplug) nothing
//! is encoded or kept: only the counters of [`Seen`] move. The USB task
//! drains the ring with [`Recorder::take`], woken by [`Recorder::wait_data`].

use core::cell::RefCell;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::signal::Signal;
use firmware_mb::update::{UpdateError, UpdateRefusal};
use firmware_mb::{AssignError, CallObserver, CallRecord, KnownBoard, MbDiagnostics, X10};
use x10_devices::LinkError;
use x10_microcode::{Address, Event, Op, Uid};

use crate::frame::{cobs_each, cobs_max, host_body, FrameError, MAX_LOG_CHUNK, MAX_MESSAGE};
use crate::msg::{
    AssignStatus, BoardEntry, BoardState, CallError, CallRec, DiagCounters, Dropped, EventRec,
    Hello, Outcome, OutputRec, OutputValue, ToDevice, ToHost, UpdateFailure, UpdatePhase,
    UpdateRec, UpdateStatus, WireOp, BOARDS_PER_LIST, LINK_VERSION,
};

/// What the recorder was told of since start, listening or not.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Seen {
    /// Calls.
    pub calls: u32,
    /// Events.
    pub events: u32,
    /// Output changes.
    pub outputs: u32,
}

/// `N` bytes in a circle: the oldest at `start`, `len` of them. Smaller in flash than
/// `heapless::Deque` (one index and a length; issue 26's budget), and without its panic
/// paths: every access is a checked one.
struct Ring<const N: usize> {
    buf: [u8; N],
    start: usize,
    len: usize,
}

impl<const N: usize> Ring<N> {
    fn len(&self) -> usize {
        self.len
    }

    fn clear(&mut self) {
        self.start = 0;
        self.len = 0;
    }

    /// Appends `b`; dropped when full (the callers check the room first).
    fn push(&mut self, b: u8) {
        if self.len < N {
            if let Some(slot) = self.buf.get_mut((self.start + self.len) % N) {
                *slot = b;
                self.len += 1;
            }
        }
    }

    fn pop(&mut self) -> Option<u8> {
        if self.len == 0 {
            return None;
        }
        let b = *self.buf.get(self.start)?;
        self.start = (self.start + 1) % N;
        self.len -= 1;
        Some(b)
    }
}

struct State<const N: usize> {
    listening: bool,
    ring: Ring<N>,
    dropped: Dropped,
    reported: Dropped,
    seen: Seen,
    /// The boards called or heard from: bit `a` of word `a / 32` (0, the motherboard's own
    /// ports, is listed always; all zero at start, so the recorder needs no initial values
    /// in flash).
    boards: [u32; 4],
}

impl<const N: usize> State<N> {
    /// Appends `msg`'s whole frame or nothing: COBS-encoded straight into the ring.
    fn push(&mut self, msg: &ToHost<'_>) -> Result<(), FrameError> {
        let mut raw = [0u8; MAX_MESSAGE + 2];
        let n = host_body(msg, &mut raw)?;
        // The frame's length: COBS's (exact below 254 bytes) and the final zero.
        if N - self.ring.len() <= cobs_max(n) {
            return Err(FrameError::TooLong);
        }
        let ring = &mut self.ring;
        cobs_each(raw.get(..n).unwrap_or(&[]), &mut |b| ring.push(b));
        Ok(())
    }

    fn saw_board(&mut self, db: u8) {
        if let Some(w) = self.boards.get_mut(usize::from(db / 32)) {
            *w |= 1 << (db % 32);
        }
    }
}

/// The frames waiting for the laptop: `N` bytes of ring (whole frames only) and the counters.
pub struct Recorder<const N: usize> {
    state: Mutex<CriticalSectionRawMutex, RefCell<State<N>>>,
    data: Signal<CriticalSectionRawMutex, ()>,
    room: Signal<CriticalSectionRawMutex, ()>,
}

impl<const N: usize> Default for Recorder<N> {
    fn default() -> Self {
        Self::new()
    }
}

fn add(c: &mut u32) {
    *c = c.saturating_add(1);
}

/// A `LinkError` as the link says it.
pub fn call_error(e: &LinkError) -> CallError {
    match e {
        LinkError::Nack => CallError::Nack,
        LinkError::Timeout => CallError::Timeout,
        LinkError::ArbitrationLost => CallError::ArbitrationLost,
        LinkError::Bus => CallError::Bus,
        LinkError::BadReply => CallError::BadReply,
        LinkError::Status(s) => CallError::Status(s.to_byte()),
        LinkError::Invalid(_) => CallError::Invalid,
        LinkError::Busy => CallError::Busy,
        LinkError::Unsupported => CallError::Unsupported,
        LinkError::Updating => CallError::Updating,
    }
}

/// The output change an `ok` operation made, if it is an output operation.
pub fn output_value(op: &Op<'_>) -> Option<OutputValue> {
    match op {
        Op::DigitalWrite(_, level) => Some(OutputValue::Level(level.is_high())),
        Op::PwmDuty(_, duty) => Some(OutputValue::Duty(*duty)),
        Op::PwmFrequency(_, hz) => Some(OutputValue::FrequencyHz(u32::from(*hz))),
        Op::PwmPulseWidth(_, us) => Some(OutputValue::PulseWidthUs(*us)),
        _ => None,
    }
}

impl<const N: usize> Recorder<N> {
    /// An idle recorder (nobody listening).
    pub const fn new() -> Self {
        Recorder {
            state: Mutex::new(RefCell::new(State {
                listening: false,
                ring: Ring {
                    buf: [0; N],
                    start: 0,
                    len: 0,
                },
                dropped: Dropped {
                    calls: 0,
                    events: 0,
                    outputs: 0,
                    log_bytes: 0,
                    bad_frames: 0,
                },
                reported: Dropped {
                    calls: 0,
                    events: 0,
                    outputs: 0,
                    log_bytes: 0,
                    bad_frames: 0,
                },
                seen: Seen {
                    calls: 0,
                    events: 0,
                    outputs: 0,
                },
                boards: [0; 4],
            })),
            data: Signal::new(),
            room: Signal::new(),
        }
    }

    /// Runs `f` on the state inside the critical section. A use from inside another (a
    /// panic while recording, logged through [`Recorder::log`]) gets `R`'s default instead
    /// of a second panic: no panic path.
    fn with<R: Default>(&self, f: impl FnOnce(&mut State<N>) -> R) -> R {
        self.state.lock(|s| match s.try_borrow_mut() {
            Ok(mut s) => f(&mut s),
            Err(_) => R::default(),
        })
    }

    /// True while a laptop listens.
    pub fn listening(&self) -> bool {
        self.with(|s| s.listening)
    }

    /// A laptop said hello (true) or went away (false: the ring is emptied, the drop counters
    /// start again at the next hello).
    #[inline(never)]
    pub fn set_listening(&self, on: bool) {
        self.with(|s| {
            s.listening = on;
            s.ring.clear();
            if on {
                s.dropped = Dropped::default();
                s.reported = Dropped::default();
            }
        });
    }

    /// What was dropped since the laptop's hello.
    pub fn dropped(&self) -> Dropped {
        self.with(|s| s.dropped)
    }

    /// What the recorder was told of since start.
    pub fn seen(&self) -> Seen {
        self.with(|s| s.seen)
    }

    /// Bytes waiting.
    #[inline(never)]
    pub fn pending(&self) -> usize {
        self.with(|s| s.ring.len())
    }

    /// The boards called or heard from since start (0 always), ascending.
    pub fn boards(&self) -> heapless::Vec<u8, 16> {
        let words = self.with(|s| s.boards);
        let mut out = heapless::Vec::new();
        for a in 0..128u8 {
            let set = words
                .get(usize::from(a / 32))
                .is_some_and(|w| w & (1 << (a % 32)) != 0);
            if (set || a == 0) && out.push(a).is_err() {
                break;
            }
        }
        out
    }

    /// Queues a message from the link itself (a reply, a hello). Returns false when it did
    /// not fit (nothing was queued). Queued even while nobody listens.
    pub fn send(&self, msg: &ToHost<'_>) -> bool {
        let ok = self.with(|s| s.push(msg).is_ok());
        if ok {
            self.data.signal(());
        }
        ok
    }

    /// Copies defmt log bytes to the link (in chunks of [`MAX_LOG_CHUNK`]), when a laptop
    /// listens; what does not fit is counted in [`Dropped::log_bytes`].
    ///
    /// Called by the images' defmt logger, possibly while the recorder itself is at work (a
    /// panic inside it): then the bytes are dropped, uncounted, instead of panicking again.
    pub fn log(&self, bytes: &[u8]) {
        let queued = self.state.lock(|s| {
            let Ok(mut s) = s.try_borrow_mut() else {
                return false;
            };
            if !s.listening {
                return false;
            }
            let mut any = false;
            for chunk in bytes.chunks(MAX_LOG_CHUNK) {
                if s.push(&ToHost::Log(chunk)).is_ok() {
                    any = true;
                } else {
                    let n = u32::try_from(chunk.len()).unwrap_or(u32::MAX);
                    s.dropped.log_bytes = s.dropped.log_bytes.saturating_add(n);
                }
            }
            any
        });
        if queued {
            self.data.signal(());
        }
    }

    /// Counts a laptop frame that did not decode.
    #[inline(never)]
    pub fn bad_frame(&self) {
        self.with(|s| add(&mut s.dropped.bad_frames));
    }

    /// Records a finished call (and the output change it made).
    pub fn call(
        &self,
        db: u8,
        op: &Op<'_>,
        result: &Result<x10_microcode::Payload, LinkError>,
        start_us: u64,
        end_us: u64,
    ) {
        let mut data = [0u8; x10_microcode::MAX_FRAME_LEN];
        let queued = self.with(|s| {
            add(&mut s.seen.calls);
            s.saw_board(db);
            let output = match result {
                Ok(_) => output_value(op),
                Err(_) => None,
            };
            if output.is_some() {
                add(&mut s.seen.outputs);
            }
            if !s.listening {
                return false;
            }
            let Ok(n) = op.emit_data(&mut data) else {
                add(&mut s.dropped.calls);
                return false;
            };
            let outcome = match result {
                Ok(p) => Outcome::Ok(p),
                Err(e) => Outcome::Err(call_error(e)),
            };
            let rec = CallRec {
                db,
                op: WireOp {
                    fn_op: op.fn_op_byte(),
                    port: op.port_byte(),
                    data: data.get(..n).unwrap_or(&[]),
                },
                outcome,
                start_us,
                end_us,
            };
            let mut any = false;
            if s.push(&ToHost::Call(rec)).is_ok() {
                any = true;
            } else {
                add(&mut s.dropped.calls);
            }
            if let Some(value) = output {
                let out = OutputRec {
                    db,
                    port: op.port_byte(),
                    value,
                    at_us: end_us,
                };
                if s.push(&ToHost::Output(out)).is_ok() {
                    any = true;
                } else {
                    add(&mut s.dropped.outputs);
                }
            }
            any
        });
        if queued {
            self.data.signal(());
        }
    }

    /// Records an event the motherboard routed.
    pub fn event(&self, ev: &Event<'_>, at_us: u64) {
        let queued = self.with(|s| {
            add(&mut s.seen.events);
            s.saw_board(ev.source.get());
            if !s.listening {
                return false;
            }
            let rec = EventRec {
                db: ev.source.get(),
                kind: ev.kind.to_byte(),
                port: ev.pin.to_byte(),
                seq: ev.seq,
                status: ev.status.to_byte(),
                payload: ev.payload,
                at_us,
            };
            if s.push(&ToHost::Event(rec)).is_ok() {
                true
            } else {
                add(&mut s.dropped.events);
                false
            }
        });
        if queued {
            self.data.signal(());
        }
    }

    /// Takes up to `out.len()` bytes of whole or partial frames, oldest first; first queues
    /// a [`ToHost::Dropped`] report when the counters moved since the last one and it fits.
    pub fn take(&self, out: &mut [u8]) -> usize {
        let n = self.with(|s| {
            if s.listening && s.dropped != s.reported {
                let d = s.dropped;
                if s.push(&ToHost::Dropped(d)).is_ok() {
                    s.reported = d;
                }
            }
            let mut n = 0;
            for slot in out.iter_mut() {
                match s.ring.pop() {
                    Some(b) => {
                        *slot = b;
                        n += 1;
                    }
                    None => break,
                }
            }
            n
        });
        if n > 0 {
            self.room.signal(());
        }
        n
    }

    /// Waits until something was queued since the last call.
    pub async fn wait_data(&self) {
        self.data.wait().await;
    }
}

impl<const N: usize> CallObserver for Recorder<N> {
    fn observe(&self, call: &CallRecord<'_>) {
        self.call(
            call.db.get(),
            call.op,
            call.result,
            call.started.as_micros(),
            call.ended.as_micros(),
        );
    }

    fn event(&self, ev: &Event<'_>, at: x10_hal::time::Instant) {
        Recorder::event(self, ev, at.as_micros());
    }

    fn update(
        &self,
        db: Address,
        from: x10_microcode::Version,
        to: x10_microcode::Version,
        end: Option<&Result<(), UpdateError>>,
        at: x10_hal::time::Instant,
    ) {
        let phase = match end {
            None => UpdatePhase::Started,
            Some(Ok(())) => UpdatePhase::Done,
            Some(Err(e)) => UpdatePhase::Failed(update_failure(e)),
        };
        let rec = UpdateRec {
            db: db.get(),
            from,
            to,
            phase,
            at_us: at.as_micros(),
        };
        // Kept as an event is (a full ring counts it in `Dropped::events`).
        let queued = self.with(|s| {
            if !s.listening {
                return false;
            }
            let ok = s.push(&ToHost::Update(rec)).is_ok();
            if !ok {
                add(&mut s.dropped.events);
            }
            ok
        });
        if queued {
            self.data.signal(());
        }
    }
}

/// An `UpdateError` as the link says it.
pub fn update_failure(e: &UpdateError) -> UpdateFailure {
    match e {
        UpdateError::NoMethod => UpdateFailure::NoMethod,
        UpdateError::Enter(_) => UpdateFailure::Enter,
        UpdateError::NoBootloader => UpdateFailure::NoBootloader,
        UpdateError::Refused(_) => UpdateFailure::Refused,
        UpdateError::Link(_) => UpdateFailure::Link,
        UpdateError::NotBack => UpdateFailure::NotBack,
        UpdateError::RolledBack(_) => UpdateFailure::RolledBack,
        UpdateError::Rom(_) => UpdateFailure::Rom,
    }
}

/// A `KnownBoard` as the link lists it; `updating`: the board being updated.
pub fn board_entry(b: &KnownBoard, updating: Option<Address>) -> BoardEntry {
    let state = if updating == Some(b.address) && b.present {
        BoardState::Updating
    } else if b.collided {
        BoardState::Collided
    } else if b.present {
        BoardState::Present
    } else {
        BoardState::Lost
    };
    BoardEntry {
        address: b.address.get(),
        uid: b.uid.0,
        kind: b.kind.0,
        firmware: b.firmware,
        state,
    }
}

/// An `AssignError` as the link says it.
pub fn assign_status(r: &Result<(), AssignError>) -> AssignStatus {
    match r {
        Ok(()) => AssignStatus::Done,
        Err(AssignError::UnknownUid) => AssignStatus::UnknownUid,
        Err(AssignError::Reserved) => AssignStatus::Reserved,
        Err(AssignError::Taken) => AssignStatus::Taken,
        Err(AssignError::Collided) => AssignStatus::Collided,
        Err(AssignError::NotConfirmed(e)) => AssignStatus::NotConfirmed(call_error(e)),
    }
}

/// An update request's answer as the link says it.
pub fn update_status(r: &Result<u8, UpdateRefusal>) -> UpdateStatus {
    match r {
        Ok(n) => UpdateStatus::Started(*n),
        Err(UpdateRefusal::NoImages) => UpdateStatus::NoImages,
        Err(UpdateRefusal::UnknownUid) => UpdateStatus::UnknownUid,
        Err(UpdateRefusal::NotPresent) => UpdateStatus::NotPresent,
        Err(UpdateRefusal::NoImage) => UpdateStatus::NoImage,
        Err(UpdateRefusal::UpToDate) => UpdateStatus::UpToDate,
        Err(UpdateRefusal::Busy(a)) => UpdateStatus::Busy(a.map_or(0, Address::get)),
    }
}

/// The counters in the order of [`crate::msg::DIAG_NAMES`].
pub fn diag_counters(d: &MbDiagnostics) -> DiagCounters {
    let all = [
        d.requests,
        d.completed,
        d.timeouts,
        d.nacks,
        d.arbitration_failures,
        d.bus_errors,
        d.bad_replies,
        d.status_errors,
        d.busy,
        d.arbitration_lost,
        d.nacked,
        d.keepalives,
        d.failsafe_resends,
        d.keepalive_failures,
        d.retries,
        d.yields,
        d.cancelled,
        d.abandoned,
        d.late_replies,
        d.duplicate_replies,
        d.unknown_replies,
        d.events,
        d.bad_events,
        d.events_dropped,
        d.rejected,
        d.failsafe_trips,
        d.boots,
        d.watchdog_resets,
        d.panic_resets,
        d.fault_resets,
        d.overflows,
        d.event_gaps,
        d.events_lost,
        d.pec_resyncs,
        d.unexpected_reads,
        d.listener_errors,
        d.announces,
        d.assigns,
        d.unassigned,
        d.boards_found,
        d.boards_lost,
        d.collisions,
    ];
    // Cannot fail: 42 counters, room for 48 (tests/recorder.rs checks one value per name).
    DiagCounters::from_slice(&all).unwrap_or_default()
}

/// Who the motherboard is, for its hello.
#[derive(Clone, Copy, Debug)]
pub struct Identity {
    /// Its bus address.
    pub address: u8,
    /// The board's name.
    pub board: &'static str,
    /// The robot program's name.
    pub robot: &'static str,
}

/// Answers one request from the laptop, as a robot task would: a call goes through
/// [`X10::call`] (so the recorder sees it too), its outcome comes back as
/// [`ToHost::Reply`]. Waits for room in the ring for the answer (it is the link's own task:
/// no robot task waits). A hello turns listening on, a bye off.
pub async fn serve<const N: usize>(rec: &Recorder<N>, x10: X10, who: Identity, req: ToDevice<'_>) {
    // The one call site (its future is embedded once): the laptop's call, or the
    // `set_address` of an assign to a board that answers at an address.
    let mut assign: Option<Result<Address, AssignError>> = None;
    let call: Result<(Address, Op<'_>), CallError> = match req {
        ToDevice::Call { db, op, .. } => {
            match (Address::new(db), Op::parse(op.fn_op, op.port, op.data)) {
                (Err(_), _) => Err(CallError::BadAddress),
                (_, Err(_)) => Err(CallError::Invalid),
                (Ok(a), Ok(op)) => Ok((a, op)),
            }
        }
        ToDevice::Assign { uid, address, .. } => {
            let uid = Uid(uid);
            let step = Address::new(address)
                .map_err(|_| AssignError::Reserved)
                .and_then(|to| Ok((to, x10.assign_step(uid, to)?)));
            assign = Some(step.map(|(to, _)| to));
            match step {
                Ok((to, Some(old))) => Ok((old, Op::SetAddress(to))),
                _ => Err(CallError::Unsupported),
            }
        }
        _ => Err(CallError::Unsupported),
    };
    let result = match call {
        Ok((a, op)) => Some(x10.call(a, op).await.map_err(|e| call_error(&e))),
        Err(e) => Some(Err(e)).filter(|_| assign.is_none()),
    };
    let answer = match req {
        ToDevice::Hello(_) => {
            rec.set_listening(true);
            ToHost::Hello(Hello {
                version: LINK_VERSION,
                address: who.address,
                board: who.board,
                robot: who.robot,
            })
        }
        ToDevice::Bye => {
            rec.set_listening(false);
            return;
        }
        ToDevice::Call { id, .. } => ToHost::Reply {
            id,
            outcome: match &result {
                Some(Ok(p)) => Outcome::Ok(p),
                Some(Err(e)) => Outcome::Err(*e),
                None => Outcome::Err(CallError::Unsupported),
            },
        },
        ToDevice::Diagnostics { id } => ToHost::Diagnostics {
            id,
            counters: diag_counters(&x10.diagnostics()),
        },
        ToDevice::ListBoards { id } => ToHost::Boards {
            id,
            addresses: rec.boards(),
        },
        ToDevice::Boards { id, first } => {
            let mut known = [KnownBoard::EMPTY; BOARDS_PER_LIST];
            let (n, total, updating) = x10.boards_from(usize::from(first), &mut known);
            ToHost::BoardList {
                id,
                total: u8::try_from(total).unwrap_or(u8::MAX),
                first,
                boards: known
                    .iter()
                    .take(n)
                    .map(|b| board_entry(b, updating))
                    .collect(),
            }
        }
        ToDevice::Assign { id, .. } => {
            let status = match (assign, &result, call) {
                (None, ..) => AssignStatus::UnknownUid,
                (Some(Err(e)), ..) => assign_status(&Err(e)),
                (Some(Ok(_)), Some(Err(e)), _) => AssignStatus::NotConfirmed(*e),
                (Some(Ok(to)), _, call) => {
                    if let Ok((old, _)) = call {
                        x10.moved(old, to);
                    }
                    AssignStatus::Done
                }
            };
            ToHost::Assigned { id, status }
        }
        ToDevice::Update { id, uid } => ToHost::UpdateAnswer {
            id,
            status: update_status(&x10.start_update(uid.map(Uid))),
        },
    };
    // Waits for room (the USB task drains the ring); an answer larger than the whole ring
    // is never sent.
    while !rec.send(&answer) {
        if rec.pending() == 0 {
            return;
        }
        rec.room.wait().await;
    }
}

#[cfg(test)]
mod tests {
    use super::Ring;

    #[test]
    fn the_ring_wraps_keeps_order_and_refuses_past_full() {
        let mut r: Ring<5> = Ring {
            buf: [0; 5],
            start: 0,
            len: 0,
        };
        for b in 1..=4 {
            r.push(b);
        }
        assert_eq!((r.pop(), r.pop(), r.pop()), (Some(1), Some(2), Some(3)));
        // Written across the end of the buffer: 4 5 6 7 8, then full.
        for b in 5..=9 {
            r.push(b);
        }
        assert_eq!(r.len(), 5);
        let mut got = [0u8; 6];
        for g in &mut got {
            *g = r.pop().unwrap_or(0);
        }
        assert_eq!(got, [4, 5, 6, 7, 8, 0]);
        assert_eq!(r.len(), 0);
        r.push(1);
        r.clear();
        assert_eq!((r.len(), r.pop()), (0, None));
    }
}
