//! Test doubles for the daughterboard runtime: a manual clock with a tiny deterministic
//! virtual-time driver, a recording `Ports`, and a scripted `MultiMaster`.
#![allow(dead_code)]

use std::cell::{Cell, RefCell};
use std::collections::{HashMap, VecDeque};
use std::future::{poll_fn, Future};
use std::pin::pin;
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll, Wake, Waker};

use firmware_db::{PortError, Ports, SafeState};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::time::{Clock, Instant};
use x10_microcode::{Edge, Level, PinRef, Port};

/// A clock that moves only when told to.
#[derive(Clone, Default)]
pub struct TestClock(Rc<ClockInner>);

#[derive(Default)]
struct ClockInner {
    now: Cell<u64>,
    timers: RefCell<Vec<(u64, Waker)>>,
}

thread_local! {
    /// The clock embassy-time reads on this thread: the last one made (each test makes one).
    static CURRENT: RefCell<Option<TestClock>> = const { RefCell::new(None) };
}

/// embassy-time's driver in the tests: the thread's current [`TestClock`] (the motherboard
/// runtime sleeps with embassy-time, the daughterboard's with its `Clock`: one time).
struct TestTimeDriver;

impl embassy_time_driver::Driver for TestTimeDriver {
    fn now(&self) -> u64 {
        CURRENT.with(|c| c.borrow().as_ref().map_or(0, TestClock::now_us))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        CURRENT.with(|c| match c.borrow().as_ref() {
            Some(clock) if at > clock.now_us() => {
                let mut timers = clock.0.timers.borrow_mut();
                match timers.iter_mut().find(|(_, w)| w.will_wake(waker)) {
                    // Every pending future registers again when its task is polled, so the
                    // earliest deadline of a task is the one to keep.
                    Some(entry) => entry.0 = entry.0.min(at),
                    None => timers.push((at, waker.clone())),
                }
            }
            _ => waker.wake_by_ref(),
        });
    }
}

embassy_time_driver::time_driver_impl!(static DRIVER: TestTimeDriver = TestTimeDriver);

impl TestClock {
    /// A clock at 0, which embassy-time on this thread reads from now on.
    pub fn new() -> Self {
        let clock = Self::default();
        CURRENT.with(|c| *c.borrow_mut() = Some(clock.clone()));
        clock
    }

    pub fn now_us(&self) -> u64 {
        self.0.now.get()
    }

    /// Moves time forward to `t` and wakes every sleeper due by then.
    pub fn advance_to(&self, t: u64) {
        assert!(t >= self.0.now.get(), "time goes forward only");
        self.0.now.set(t);
        let due: Vec<Waker> = {
            let mut timers = self.0.timers.borrow_mut();
            let (due, keep): (Vec<_>, Vec<_>) = timers.drain(..).partition(|(at, _)| *at <= t);
            *timers = keep;
            due.into_iter().map(|(_, w)| w).collect()
        };
        for w in due {
            w.wake();
        }
    }

    fn next_deadline(&self) -> Option<u64> {
        self.0.timers.borrow().iter().map(|(t, _)| *t).min()
    }
}

impl Clock for TestClock {
    fn now(&self) -> Instant {
        Instant(self.0.now.get())
    }

    async fn sleep_until(&self, at: Instant) {
        poll_fn(|cx| {
            if self.0.now.get() >= at.0 {
                Poll::Ready(())
            } else {
                self.0.timers.borrow_mut().push((at.0, cx.waker().clone()));
                Poll::Pending
            }
        })
        .await
    }
}

struct Flag(AtomicBool);

impl Wake for Flag {
    fn wake(self: Arc<Self>) {
        self.0.store(true, Ordering::SeqCst);
    }
}

/// Polls `fut` to completion; whenever nothing is runnable, moves the clock to the earliest
/// sleeper. Deterministic: no threads, no wall clock.
pub fn run<F: Future>(clock: &TestClock, fut: F) -> F::Output {
    let flag = Arc::new(Flag(AtomicBool::new(false)));
    let waker = Waker::from(flag.clone());
    let mut cx = Context::from_waker(&waker);
    let mut fut = pin!(fut);
    for _ in 0..10_000_000u32 {
        flag.0.store(false, Ordering::SeqCst);
        if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
            return v;
        }
        if flag.0.load(Ordering::SeqCst) {
            continue;
        }
        match clock.next_deadline() {
            Some(t) => clock.advance_to(t.max(clock.now_us())),
            None => panic!(
                "deadlock: nothing runnable and no timer at t={}",
                clock.now_us()
            ),
        }
    }
    panic!("runaway test");
}

/// Runs `fut` (typically a never-ending runtime future) until virtual time `t_us`, including
/// everything that becomes due at `t_us` itself, then stops polling it (the test keeps the
/// state it borrowed and may go on polling it later).
pub fn run_until<F: Future>(clock: &TestClock, t_us: u64, fut: F) {
    let flag = Arc::new(Flag(AtomicBool::new(false)));
    let waker = Waker::from(flag.clone());
    let mut cx = Context::from_waker(&waker);
    let mut fut = pin!(fut);
    for _ in 0..10_000_000u32 {
        flag.0.store(false, Ordering::SeqCst);
        if fut.as_mut().poll(&mut cx).is_ready() {
            panic!("runtime future ended at t={}", clock.now_us());
        }
        if flag.0.load(Ordering::SeqCst) {
            continue;
        }
        match clock.next_deadline() {
            Some(d) if d <= t_us => clock.advance_to(d.max(clock.now_us())),
            _ if clock.now_us() < t_us => clock.advance_to(t_us),
            _ => return,
        }
    }
    panic!("runaway test");
}

/// One port operation as the runtime performed it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PortOp {
    DigitalRead(PinRef),
    DigitalWrite(PinRef, Level),
    PwmDuty(PinRef, u8),
    PwmFrequency(Port, u16),
    PwmPulseWidth(PinRef, u16),
    AnalogRead(Port),
    PulseIn(PinRef, Edge, u16),
}

/// A board whose pins are values in maps and whose operations are recorded.
pub struct FakePorts {
    pub clock: TestClock,
    pub sensors: u8,
    pub actuators: u8,
    pub log: RefCell<Vec<PortOp>>,
    /// Levels by pin byte (request byte 2).
    pub digital: RefCell<HashMap<u8, bool>>,
    /// Analog values by sensor port number (1-based).
    pub analog: RefCell<HashMap<u8, u16>>,
    /// Pulse-in outcomes in order: how long the measurement takes (µs) and its result.
    pub pulses: RefCell<VecDeque<(u64, Result<u32, PortError>)>>,
    /// Pins (by byte) whose operations fail with this error.
    pub failing: RefCell<HashMap<u8, PortError>>,
}

impl FakePorts {
    pub fn new(clock: TestClock, sensors: u8, actuators: u8) -> Self {
        FakePorts {
            clock,
            sensors,
            actuators,
            log: RefCell::default(),
            digital: RefCell::default(),
            analog: RefCell::default(),
            pulses: RefCell::default(),
            failing: RefCell::default(),
        }
    }

    pub fn take_log(&self) -> Vec<PortOp> {
        std::mem::take(&mut self.log.borrow_mut())
    }

    pub fn set_level(&self, pin: PinRef, high: bool) {
        self.digital.borrow_mut().insert(pin.to_byte(), high);
    }

    fn check(&self, pin: PinRef) -> Result<(), PortError> {
        match self.failing.borrow().get(&pin.to_byte()) {
            Some(e) => Err(*e),
            None => Ok(()),
        }
    }
}

impl Ports for FakePorts {
    fn sensor_ports(&self) -> u8 {
        self.sensors
    }

    fn actuator_ports(&self) -> u8 {
        self.actuators
    }

    fn adc_bits(&self) -> u8 {
        12
    }

    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        self.log.borrow_mut().push(PortOp::DigitalRead(pin));
        self.check(pin)?;
        let high = self
            .digital
            .borrow()
            .get(&pin.to_byte())
            .copied()
            .unwrap_or(false);
        Ok(Level::from_bool(high))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        self.log.borrow_mut().push(PortOp::DigitalWrite(pin, level));
        self.check(pin)?;
        self.set_level(pin, level.is_high());
        Ok(())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        self.log.borrow_mut().push(PortOp::PwmDuty(pin, duty));
        self.check(pin)
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        self.log.borrow_mut().push(PortOp::PwmFrequency(port, hz));
        self.check(port.into())
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        self.log.borrow_mut().push(PortOp::PwmPulseWidth(pin, us));
        self.check(pin)
    }

    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        self.log.borrow_mut().push(PortOp::AnalogRead(port));
        self.check(port.into())?;
        Ok(self
            .analog
            .borrow()
            .get(&port.number())
            .copied()
            .unwrap_or(0))
    }

    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        self.log
            .borrow_mut()
            .push(PortOp::PulseIn(pin, edge, timeout_ms));
        let next = self.pulses.borrow_mut().pop_front();
        let (took, r) = next.unwrap_or((u64::from(timeout_ms) * 1000, Err(PortError::Timeout)));
        let at = self.clock.now().plus_us(took);
        self.clock.sleep_until(at).await;
        r
    }

    fn safe_state(&self, port: Port) -> SafeState {
        if port.number() == 2 {
            SafeState {
                pwm: [10, 20],
                digital: [Level::High, Level::Low],
            }
        } else {
            SafeState::ALL_LOW
        }
    }
}

/// What the scripted bus saw.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusOp {
    Write(u8, Vec<u8>),
    Respond(Vec<u8>),
}

/// A transaction a controller makes to the node under test.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Txn {
    Write(Vec<u8>),
    WriteRead(Vec<u8>),
    Read,
    /// A write longer than the listen buffer.
    Overrun,
}

/// The result of one of the node's own writes, with a transaction addressed to the node that
/// arrives when the write fails (the reason it failed).
type WriteResult = (Result<(), BusError>, Option<Txn>);

#[derive(Default)]
struct BusInner {
    incoming: RefCell<VecDeque<Txn>>,
    listener: RefCell<Option<Waker>>,
    ops: RefCell<Vec<(u64, BusOp)>>,
    write_results: RefCell<VecDeque<WriteResult>>,
}

/// A scripted bus: transactions to the node are pushed by the test, results of the node's own
/// writes are scripted (default `Ok`), everything is recorded with its virtual time.
#[derive(Clone)]
pub struct FakeBus {
    inner: Rc<BusInner>,
    clock: TestClock,
}

impl FakeBus {
    pub fn new(clock: TestClock) -> Self {
        FakeBus {
            inner: Rc::default(),
            clock,
        }
    }

    pub fn push(&self, t: Txn) {
        self.inner.incoming.borrow_mut().push_back(t);
        if let Some(w) = self.inner.listener.borrow_mut().take() {
            w.wake();
        }
    }

    pub fn script_writes(&self, results: &[Result<(), BusError>]) {
        self.inner
            .write_results
            .borrow_mut()
            .extend(results.iter().map(|r| (*r, None)));
    }

    /// The node's next write fails with `error` because a controller addresses the node with
    /// `txn` (which the node's listener then receives).
    pub fn script_addressed(&self, error: BusError, txn: Txn) {
        self.inner
            .write_results
            .borrow_mut()
            .push_back((Err(error), Some(txn)));
    }

    pub fn ops(&self) -> Vec<(u64, BusOp)> {
        self.inner.ops.borrow().clone()
    }

    pub fn take_ops(&self) -> Vec<(u64, BusOp)> {
        std::mem::take(&mut self.inner.ops.borrow_mut())
    }

    fn record(&self, op: BusOp) {
        self.inner.ops.borrow_mut().push((self.clock.now_us(), op));
    }
}

impl MultiMaster for FakeBus {
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        self.record(BusOp::Write(addr, bytes.to_vec()));
        let next = self.inner.write_results.borrow_mut().pop_front();
        match next {
            Some((r, txn)) => {
                if let Some(t) = txn {
                    self.push(t);
                }
                r
            }
            None => Ok(()),
        }
    }

    async fn write_read(&mut self, _: u8, _: &[u8], _: &mut [u8]) -> Result<(), BusError> {
        Err(BusError::Bus)
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        poll_fn(|cx| {
            if self.inner.incoming.borrow().is_empty() {
                *self.inner.listener.borrow_mut() = Some(cx.waker().clone());
                Poll::Pending
            } else {
                Poll::Ready(Ok(()))
            }
        })
        .await
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        poll_fn(|cx| match self.inner.incoming.borrow_mut().pop_front() {
            Some(Txn::Write(b)) => {
                buf[..b.len()].copy_from_slice(&b);
                Poll::Ready(Ok(Incoming::Write(b.len())))
            }
            Some(Txn::WriteRead(b)) => {
                buf[..b.len()].copy_from_slice(&b);
                Poll::Ready(Ok(Incoming::WriteRead(b.len())))
            }
            Some(Txn::Read) => Poll::Ready(Ok(Incoming::Read)),
            Some(Txn::Overrun) => Poll::Ready(Err(BusError::Overrun)),
            None => {
                *self.inner.listener.borrow_mut() = Some(cx.waker().clone());
                Poll::Pending
            }
        })
        .await
    }

    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        self.record(BusOp::Respond(bytes.to_vec()));
        Ok(())
    }
}
