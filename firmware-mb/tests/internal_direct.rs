//! Issue 27: calls to the motherboard's own ports run the internal daughterboard in the
//! calling task (`Motherboard::serve_internal_directly`: no pending slot, no queue, no frame,
//! one yield). Checked here against the internal worker's path, which serves the same calls
//! without it: the same outcomes, the same counters, the same port operations, the same
//! keepalive; and the direct calls need no runtime task at all, yet let other tasks run.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use std::cell::{Cell, RefCell};
use std::future::poll_fn;
use std::task::Poll;

use common::{run, sim, LoopBus, TestClock};
use critical_section::Mutex;
use embassy_futures::join::join;
use firmware_db::{PortError, Ports};
use firmware_mb::{MbConfig, MbDiagnostics, Motherboard, X10};
use x10_devices::LinkError;
use x10_hal::time::{Clock, Instant};
use x10_microcode::{Address, Edge, Level, Op, Pin, PinRef, Port, Status};

/// Ports that record what they are asked, `Sync` as a board's are (the direct path needs
/// it): inputs read high on pin A and low on pin B, the ADC gives 0x0123 + the port's index,
/// and actuator port 2 pin B fails with `busy`.
struct SyncPorts {
    log: Mutex<RefCell<Vec<String>>>,
}

impl SyncPorts {
    fn new() -> SyncPorts {
        SyncPorts {
            log: Mutex::new(RefCell::new(Vec::new())),
        }
    }

    fn note(&self, what: String) {
        critical_section::with(|cs| self.log.borrow_ref_mut(cs).push(what));
    }

    fn log(&self) -> Vec<String> {
        critical_section::with(|cs| self.log.borrow_ref(cs).clone())
    }

    fn fails(pin: PinRef) -> Result<(), PortError> {
        if pin == a(2).pin(Pin::B) {
            Err(PortError::Busy)
        } else {
            Ok(())
        }
    }
}

impl Ports for SyncPorts {
    fn sensor_ports(&self) -> u8 {
        2
    }

    fn actuator_ports(&self) -> u8 {
        2
    }

    fn adc_bits(&self) -> u8 {
        10
    }

    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        self.note(format!("read {:#04x}", pin.to_byte()));
        Ok(Level::from_bool(pin.pin == Pin::A))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        Self::fails(pin)?;
        self.note(format!("write {:#04x} {level:?}", pin.to_byte()));
        Ok(())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        Self::fails(pin)?;
        self.note(format!("duty {:#04x} {duty}", pin.to_byte()));
        Ok(())
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        self.note(format!("frequency {} {hz}", port.number()));
        Ok(())
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        self.note(format!("width {:#04x} {us}", pin.to_byte()));
        Ok(())
    }

    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        self.note(format!("analog {}", port.number()));
        Ok(0x0123 + u16::from(port.index()))
    }

    async fn pulse_in(&self, _: PinRef, _: Edge, _: u16) -> Result<u32, PortError> {
        Err(PortError::Unsupported)
    }
}

fn s(n: u8) -> Port {
    Port::sensor(n).unwrap()
}

fn a(n: u8) -> Port {
    Port::actuator(n).unwrap()
}

type Mb = Motherboard<SyncPorts>;

/// A motherboard with the thesis's settings on [`SyncPorts`]; with the direct path when
/// `direct`.
fn motherboard(direct: bool) -> &'static Mb {
    let mb: &'static Mb = Box::leak(Box::new(Motherboard::new(
        MbConfig::thesis_compatible(common::mb_address()),
        SyncPorts::new(),
    )));
    if direct {
        mb.serve_internal_directly();
    }
    mb
}

/// The calls of the comparison, and what each must give.
fn calls() -> Vec<(Op<'static>, Result<Vec<u8>, LinkError>)> {
    vec![
        (Op::DigitalWrite(a(1).pin(Pin::A), Level::High), Ok(vec![])),
        (Op::DigitalRead(s(1).pin(Pin::A)), Ok(vec![1])),
        (Op::DigitalRead(s(2).pin(Pin::B)), Ok(vec![0])),
        (Op::PwmDuty(a(1).pin(Pin::B), 77), Ok(vec![])),
        (Op::AnalogRead(s(2)), Ok(vec![0x24, 0x01])),
        (Op::PwmFrequency(a(2), 1_000), Ok(vec![])),
        (Op::PwmPulseWidth(a(2).pin(Pin::A), 1_500), Ok(vec![])),
        (Op::Ping, Ok(vec![])),
        (Op::Heartbeat, Ok(vec![])),
        // Two sensor ports: levels A high, B low; analog 0x0123 and 0x0124.
        (Op::Scan, Ok(vec![2, 0b0101, 0, 0x23, 0x01, 0x24, 0x01])),
        // The port's own error is the board's status.
        (
            Op::DigitalWrite(a(2).pin(Pin::B), Level::Low),
            Err(LinkError::Status(Status::Busy)),
        ),
        // No third sensor port: refused as the board would refuse it.
        (
            Op::DigitalRead(s(3).pin(Pin::A)),
            Err(LinkError::Status(Status::PortOutOfRange)),
        ),
        // Nothing is sent for an operation that does not encode.
        (
            Op::PwmDuty(s(1).pin(Pin::A), 1),
            Err(LinkError::Invalid(x10_microcode::Error::WrongPortKind)),
        ),
        (
            Op::PwmFrequency(a(1), 0),
            Err(LinkError::Invalid(x10_microcode::Error::BadArgument)),
        ),
    ]
}

/// What the internal board's background work sets at start (two actuator ports; A2.B
/// fails, and is skipped).
const SAFE_STATE: [&str; 6] = [
    "duty 0x00 0",
    "duty 0x01 0",
    "write 0x00 Low",
    "write 0x01 Low",
    "duty 0x02 0",
    "write 0x02 Low",
];

/// Runs [`calls`] through the robot programs' handle; the outcomes.
async fn make_calls(x10: X10) -> Vec<Result<Vec<u8>, LinkError>> {
    let mut out = Vec::new();
    for (op, _) in calls() {
        out.push(x10.call(Address::INTERNAL, op).await.map(|p| p.to_vec()));
    }
    out
}

/// The counters a call moves.
fn call_counters(d: &MbDiagnostics) -> [u32; 5] {
    [
        d.requests,
        d.completed,
        d.status_errors,
        d.bad_replies,
        d.timeouts,
    ]
}

#[test]
fn direct_calls_end_as_the_internal_workers_do() {
    let want: Vec<_> = calls().into_iter().map(|(_, r)| r).collect();
    let mut seen = Vec::new();
    for direct in [false, true] {
        let clock = TestClock::new();
        let mb = motherboard(direct);
        let bus = LoopBus::new(&clock);
        let got = sim(&clock, mb.run(bus), make_calls(mb.handle()));
        assert_eq!(got, want, "direct: {direct}");
        let d = mb.diagnostics();
        // Ten ended `ok` and one refused by the board; the port the board does not have
        // was refused by the motherboard before any request (it knows the internal board's
        // ports from its boot event), and the invalid ones were never requests either.
        assert_eq!(call_counters(&d), [11, 10, 2, 0, 0], "direct: {direct}");
        let db = mb.internal().diagnostics();
        // The internal board's start-up safe state (PWM duty 0, then low, on each actuator
        // pin) is taken out: in this harness the program is polled before the runtime, and
        // the worker, polled before the board's background work, ran the first call before
        // it; the direct call, which yields first, runs after it.
        let mut log = mb.internal().ports().log();
        for safe in SAFE_STATE {
            let at = log.iter().position(|l| l == safe).unwrap();
            log.remove(at);
        }
        seen.push((log, db.frames_ok, db.port_errors));
    }
    assert_eq!(seen[0], seen[1]);
    assert_eq!(
        seen[1].0,
        [
            "write 0x00 High",
            "read 0x80",
            "read 0x83",
            "duty 0x01 77",
            "analog 2",
            "frequency 2 1000",
            "width 0x02 1500",
            "read 0x80",
            "read 0x81",
            "analog 1",
            "read 0x82",
            "read 0x83",
            "analog 2",
        ]
    );
    // The board counts its port's refusal with the other errors, not as a port error.
    assert_eq!((seen[1].1, seen[1].2), (10, 0));
}

/// The direct path needs no runtime task: the calls end without `Motherboard::run` (the
/// worker's path would wait for it until the request timeout).
#[test]
fn direct_calls_need_no_runtime_task() {
    let clock = TestClock::new();
    let mb = motherboard(true);
    let got = run(&clock, make_calls(mb.handle()));
    let want: Vec<_> = calls().into_iter().map(|(_, r)| r).collect();
    assert_eq!(got, want);
    assert_eq!(clock.now(), Instant(0));

    let clock = TestClock::new();
    let queued = motherboard(false);
    let op = Op::DigitalWrite(a(1).pin(Pin::A), Level::High);
    let r = run(&clock, queued.handle().call(Address::INTERNAL, op));
    assert_eq!(r, Err(LinkError::Timeout));
}

/// Issue 10's finding "internal board never yields", on the direct path: every call yields
/// once, so a loop of them lets another task run at every call.
#[test]
fn a_loop_of_direct_calls_lets_another_task_run() {
    let clock = TestClock::new();
    let mb = motherboard(true);
    let x10 = mb.handle();
    let done = Cell::new(false);
    let polls = Cell::new(0u32);
    let calls = 200u32;
    let polls_during = run(&clock, async {
        let program = async {
            for _ in 0..calls {
                x10.call(Address::INTERNAL, Op::DigitalRead(s(1).pin(Pin::A)))
                    .await
                    .unwrap();
            }
            done.set(true);
            polls.get()
        };
        let other = poll_fn(|cx| {
            if done.get() {
                return Poll::Ready(());
            }
            polls.set(polls.get() + 1);
            cx.waker().wake_by_ref();
            Poll::Pending
        });
        join(program, other).await.0
    });
    assert!(
        polls_during >= calls,
        "the other task ran {polls_during} times during {calls} direct calls"
    );
}

/// A failsafe set on the internal board is kept alive as before: the direct calls count as
/// transactions the board heard (its heartbeat is due later), and between them the worker
/// sends heartbeats; the board never trips, and both paths send the same heartbeats.
#[test]
fn direct_calls_keep_the_internal_failsafe_alive_as_the_worker_does() {
    let mut keepalives = Vec::new();
    for direct in [false, true] {
        let clock = TestClock::new();
        let mb = motherboard(direct);
        let bus = LoopBus::new(&clock);
        let x10 = mb.handle();
        let trips = RefCell::new(0u32);
        sim(&clock, mb.run(bus), async {
            x10.call(Address::INTERNAL, Op::SetFailsafe { timeout_ms: 300 })
                .await
                .unwrap();
            // Calls every 50 ms for 1 s (a heartbeat would be due 100 ms after the last
            // transaction), then quiet for 1 s (the worker's heartbeats keep it alive).
            for i in 1..=20u64 {
                clock.sleep_until(Instant(i * 50_000)).await;
                x10.call(Address::INTERNAL, Op::DigitalRead(s(1).pin(Pin::A)))
                    .await
                    .unwrap();
            }
            clock.sleep_until(Instant(2_000_000)).await;
            *trips.borrow_mut() = mb.diagnostics().failsafe_trips;
        });
        let d = mb.diagnostics();
        assert_eq!(*trips.borrow(), 0, "direct: {direct}");
        assert_eq!(d.keepalive_failures, 0, "direct: {direct}");
        assert_eq!(mb.internal().failsafe_timeout_ms(), 300);
        keepalives.push(d.keepalives);
    }
    // No heartbeat while the calls came, then one every 100 ms of the quiet second.
    assert_eq!(keepalives[0], keepalives[1]);
    assert!((9..=11).contains(&keepalives[1]), "{keepalives:?}");
}
