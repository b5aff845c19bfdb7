//! The motherboard runtime (firmware-mb) on the target, talking over a loopback bus to a real
//! daughterboard runtime (firmware-db) with fake ports: requests and their replies, an output,
//! a deferred pulse-in answered by an event from the DB (the DB writing to the MB's own
//! address, as a brief master), the internal daughterboard at address 0, and a board that is
//! not there (NACK after the retries).
#![no_std]
#![no_main]

use core::pin::pin;

use embassy_futures::select::{select3, Either3};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, TargetConfig};
use firmware_mb::{MbConfig, Motherboard};
use x10_devices::LinkError;
use x10_hal::time::Clock;
use x10_microcode::{Address, BoardKind, Edge, Level, Op, Pin, Port};
use x10_qemu_tests::{block_on, FakePorts, PortOp, QemuClock, Wire};

type Mb = Motherboard<NoopRawMutex, FakePorts, QemuClock>;
type Db = Daughterboard<NoopRawMutex, FakePorts>;

const MB: u8 = 0x08;
const DB: u8 = 0x09;

fn s(n: u8) -> Port {
    Port::sensor(n).unwrap()
}

fn a(n: u8) -> Port {
    Port::actuator(n).unwrap()
}

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

#[defmt_test::tests]
mod tests {
    #[allow(unused_imports)]
    use super::*;
    use defmt::assert_eq;

    #[init]
    fn init() -> QemuClock {
        defmt::info!(
            "motherboard {=usize} B, daughterboard {=usize} B",
            core::mem::size_of::<Mb>(),
            core::mem::size_of::<Db>()
        );
        QemuClock::start()
    }

    #[test]
    fn requests_replies_events_internal_board_and_nack(clock: &mut QemuClock) {
        let mb_addr = Address::external(MB).unwrap();
        let db_addr = Address::external(DB).unwrap();
        let wire = Wire::new(MB, DB);
        // The micro:bit has 16 KiB of RAM: the two runtimes go into statics, and the future
        // that runs them is pinned where it is built (never moved), so the stack holds it once.
        let mb: &'static Mb = cortex_m::singleton!(
            : Mb = Mb::new(MbConfig::new(mb_addr), QemuClock, FakePorts::new())
        )
        .unwrap();
        let db: &'static Db = cortex_m::singleton!(
            : Db = Db::new(FakePorts::new(), DbConfig::new(db_addr, BoardKind::SIMULATED))
        )
        .unwrap();
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
            // The internal daughterboard: no bus.
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
            "script done after {=u64} µs; stack high-water mark {=usize} B of {=usize} B",
            clock.now().since(t0),
            stack,
            room
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
