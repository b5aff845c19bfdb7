//! The motherboard runtime (firmware-mb) on the target, talking over a loopback bus to a real
//! daughterboard runtime (firmware-db) with fake ports: requests and their replies, an output,
//! a deferred pulse-in answered by an event from the DB (the DB writing to the MB's own
//! address, as a brief master), the internal daughterboard at address 0 (its requests queued
//! for the runtime's worker task), and a board that is not there (NACK after the retries).
//! The runtime's time is embassy-time, whose driver here is the SysTick clock.
#![no_std]
#![no_main]

use core::pin::pin;

use embassy_futures::select::{select3, Either3};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, TargetConfig};
use firmware_mb::{MbConfig, Motherboard};
use x10_devices::LinkError;
use x10_hal::time::Clock;
use x10_microcode::test_support::{a, s};
use x10_microcode::{Address, BoardKind, Edge, Level, Op, Pin};
use x10_qemu_tests::{block_on, FakePorts, PortOp, QemuClock, Wire};

type Mb = Motherboard<FakePorts>;
type Db = Daughterboard<NoopRawMutex, FakePorts>;

const MB: u8 = 0x08;
const DB: u8 = 0x09;

/// What a board's background task does first: every actuator port to its safe state.
fn safe_state() -> [PortOp; 8] {
    [
        PortOp::PwmDuty(a(1).pin(Pin::A), 0),
        PortOp::PwmDuty(a(1).pin(Pin::B), 0),
        PortOp::DigitalWrite(a(1).pin(Pin::A), Level::Low),
        PortOp::DigitalWrite(a(1).pin(Pin::B), Level::Low),
        PortOp::PwmDuty(a(2).pin(Pin::A), 0),
        PortOp::PwmDuty(a(2).pin(Pin::B), 0),
        PortOp::DigitalWrite(a(2).pin(Pin::A), Level::Low),
        PortOp::DigitalWrite(a(2).pin(Pin::B), Level::Low),
    ]
}

/// What the tests share: the clock, and the two runtimes in statics.
///
/// The micro:bit has 16 KiB of RAM. `cortex_m::singleton!` builds a runtime on the stack
/// before it moves it into its static; built in a test, that place stayed in the test's frame
/// (beside the future that runs the runtimes: the stack overflowed). So `init` builds both in
/// functions of their own, whose frames are gone before any test runs; `built` is the stack
/// that took.
struct State {
    clock: QemuClock,
    mb: &'static Mb,
    db: &'static Db,
    built: usize,
}

#[inline(never)]
fn motherboard() -> &'static Mb {
    let addr = Address::external(MB).unwrap();
    cortex_m::singleton!(: Mb = Mb::new(MbConfig::new(addr), FakePorts::new())).unwrap()
}

#[inline(never)]
fn daughterboard() -> &'static Db {
    let addr = Address::external(DB).unwrap();
    cortex_m::singleton!(
        : Db = Db::new(FakePorts::new(), DbConfig::new(addr, BoardKind::SIMULATED))
    )
    .unwrap()
}

#[defmt_test::tests]
mod tests {
    #[allow(unused_imports)]
    use super::*;
    use defmt::assert_eq;

    #[init]
    fn init() -> State {
        defmt::info!(
            "motherboard {=usize} B, daughterboard {=usize} B",
            core::mem::size_of::<Mb>(),
            core::mem::size_of::<Db>()
        );
        let clock = QemuClock::start();
        x10_qemu_tests::stack::paint();
        let mb = motherboard();
        let db = daughterboard();
        let (built, _) = x10_qemu_tests::stack::used();
        State {
            clock,
            mb,
            db,
            built,
        }
    }

    #[test]
    fn embassy_time_runs_on_the_systick_clock(state: &mut State) {
        let clock = state.clock;
        // The driver's ticks are the clock's µs, and a task sleeping on a Timer under the
        // suites' busy-polling executor wakes when its time has come, not before.
        let t0 = clock.now();
        let e0 = embassy_time::Instant::now().as_ticks();
        assert!(e0 >= t0.0 && e0 - t0.0 < 100);
        block_on(embassy_time::Timer::after_micros(1_500));
        let slept = clock.now().since(t0);
        assert!((1_500..2_000).contains(&slept));
        // Monotonic across millisecond boundaries (QEMU's counter and its SysTick exception
        // do not change together; readings in between once fell back by a millisecond), also
        // with interrupts masked across a boundary (the exception waits until the end).
        let start = clock.now().0;
        let mut last = start;
        while last < start + 5_000 {
            let t = clock.now().0;
            assert!(t >= last);
            last = t;
        }
        for _ in 0..3 {
            while clock.now().0 % 1_000 < 900 {}
            let (first, end) = cortex_m::interrupt::free(|_| {
                let first = clock.now().0;
                let mut last = first;
                while last < first + 300 {
                    let t = clock.now().0;
                    assert!(t >= last);
                    last = t;
                }
                (first, last)
            });
            assert!(end / 1_000 == first / 1_000 + 1);
            assert!(clock.now().0 >= end);
        }
        // Two timers at once: the later one still runs out after the earlier one ended.
        let t1 = clock.now();
        block_on(embassy_futures::join::join(
            embassy_time::Timer::after_micros(300),
            embassy_time::Timer::after_micros(900),
        ));
        let slept = clock.now().since(t1);
        assert!((900..1_400).contains(&slept));
    }

    #[test]
    fn requests_replies_events_internal_board_and_nack(state: &mut State) {
        let (clock, mb, db) = (state.clock, state.mb, state.db);
        let mb_addr = Address::external(MB).unwrap();
        let db_addr = Address::external(DB).unwrap();
        let wire = Wire::new(MB, DB);
        db.ports().set_analog(s(1), 700);
        db.ports().set_pulse(3_000, Ok(1_500));
        x10_qemu_tests::stack::paint();
        let t0 = clock.now();

        let script = async {
            assert_eq!(mb.call(db_addr, Op::Ping).await.map(|p| p.len()), Ok(0));
            let high = Op::DigitalWrite(a(1).pin(Pin::B), Level::High);
            assert_eq!(mb.call(db_addr, high).await.map(|p| p.len()), Ok(0));
            let v = mb.call(db_addr, Op::AnalogRead(s(1))).await.unwrap();
            assert_eq!(&v[..], &700u16.to_le_bytes());
            // Pending first, then the width in a deferred-reply event the DB writes to the MB.
            let pulse = Op::PulseIn {
                pin: s(2).pin(Pin::A),
                edge: Edge::Rising,
                timeout_ms: Some(100),
            };
            let w = mb.call(db_addr, pulse).await.unwrap();
            assert_eq!(&w[..], &1_500u32.to_le_bytes());
            // The internal daughterboard: no bus; `mb.run` serves the queued request.
            let duty = Op::PwmDuty(a(2).pin(Pin::A), 99);
            assert_eq!(
                mb.call(Address::INTERNAL, duty).await.map(|p| p.len()),
                Ok(0)
            );
            // Nobody at 0x30.
            let absent = Address::external(0x30).unwrap();
            assert_eq!(mb.call(absent, Op::Ping).await, Err(LinkError::Nack));
        };
        let target = TargetConfig::new(mb_addr);
        // The future that runs them is pinned where it is built (never moved), so the stack
        // holds it once.
        let all = pin!(select3(
            mb.run(wire.end(0)),
            firmware_db::run(db, wire.end(1), QemuClock, target),
            script,
        ));
        defmt::info!("future {=usize} B", core::mem::size_of_val(&*all));
        match block_on(all) {
            Either3::First(never) | Either3::Second(never) => never,
            Either3::Third(()) => {}
        }
        let (stack, room) = x10_qemu_tests::stack::used();
        defmt::info!(
            "script done after {=u64} µs; stack high-water mark {=usize} B of {=usize} B \
             (building the two runtimes: {=usize} B)",
            clock.now().since(t0),
            stack,
            room,
            state.built
        );

        let mut expected = heapless::Vec::<PortOp, 11>::new();
        expected.extend_from_slice(&safe_state()).unwrap();
        expected
            .extend_from_slice(&[
                PortOp::DigitalWrite(a(1).pin(Pin::B), Level::High),
                PortOp::AnalogRead(s(1)),
                PortOp::PulseIn(s(2).pin(Pin::A), Edge::Rising, 100),
            ])
            .unwrap();
        assert_eq!(&db.ports().take_log()[..], &expected[..]);

        let internal = mb.internal().ports().take_log();
        assert_eq!(
            internal.last(),
            Some(&PortOp::PwmDuty(a(2).pin(Pin::A), 99))
        );
        let d = mb.diagnostics();
        defmt::info!("motherboard diagnostics: {}", defmt::Debug2Format(&d));
    }
}
