//! The daughterboard interpreter (firmware-db) on the target, over a recording fake `Ports`:
//! exact reply bytes for reads, outputs executed in order, error statuses, PEC, batches, and
//! a pulse-in answered `pending` and then by a deferred-reply event while the background task
//! runs on the SysTick clock.
#![no_std]
#![no_main]

use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig};
use x10_hal::time::Clock;
use x10_microcode::test_support::{a, s};
use x10_microcode::{pec, Address, BoardKind, Edge, EventKind, Level, Pin, PinRef, Status};
use x10_qemu_tests::{block_on, FakePorts, PortOp, QemuClock};

type Db = Daughterboard<NoopRawMutex, FakePorts>;

fn board() -> Db {
    let cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    Daughterboard::new(FakePorts::new(), cfg)
}

/// A write-then-read: the reply bytes land in `buf`, their count is returned.
fn exchange(db: &Db, request: &[u8], buf: &mut [u8; 40]) -> usize {
    db.handle_write(request, true);
    db.take_reply(buf)
}

#[defmt_test::tests]
mod tests {
    #[allow(unused_imports)]
    use super::*;
    use defmt::assert_eq;

    #[init]
    fn init() -> QemuClock {
        QemuClock::start()
    }

    #[test]
    fn ping_and_reads_reply_exact_bytes() {
        let db = board();
        let mut buf = [0u8; 40];
        let n = exchange(&db, &[0x00, 0x09, 0x00, 0x05], &mut buf);
        assert_eq!(&buf[..n], &[0x05, 0x00, 0x00]);

        db.ports().set_level(s(1).pin(Pin::A), true);
        let n = exchange(&db, &[0x10, 0x09, 0x80, 0x07], &mut buf);
        assert_eq!(&buf[..n], &[0x07, 0x00, 0x01, 0x01]);
        let n = exchange(&db, &[0x10, 0x09, 0x81, 0x08], &mut buf);
        assert_eq!(&buf[..n], &[0x08, 0x00, 0x01, 0x00]);

        db.ports().set_analog(s(2), 0x0123);
        let n = exchange(&db, &[0x30, 0x09, 0x82, 0x09], &mut buf);
        assert_eq!(&buf[..n], &[0x09, 0x00, 0x02, 0x23, 0x01]);

        assert_eq!(
            &db.ports().take_log()[..],
            &[
                PortOp::DigitalRead(s(1).pin(Pin::A)),
                PortOp::DigitalRead(s(1).pin(Pin::B)),
                PortOp::AnalogRead(s(2)),
            ]
        );
        assert_eq!(db.diagnostics().frames_ok, 4);
    }

    #[test]
    fn outputs_execute_in_order_and_hold_no_reply() {
        let db = board();
        for frame in [
            &[0x12, 0x09, 0x01, 0x02][..],         // HIGH, A1.B
            &[0x11, 0x09, 0x02, 0x03],             // LOW, A2.A
            &[0x20, 0x09, 0x02, 0x04, 200],        // duty 200, A2.A
            &[0x21, 0x09, 0x00, 0x05, 0xE8, 0x03], // 1000 Hz, A1
            &[0x22, 0x09, 0x01, 0x06, 0xDC, 0x05], // 1500 µs, A1.B
        ] {
            db.handle_write(frame, false);
        }
        assert_eq!(
            &db.ports().take_log()[..],
            &[
                PortOp::DigitalWrite(a(1).pin(Pin::B), Level::High),
                PortOp::DigitalWrite(a(2).pin(Pin::A), Level::Low),
                PortOp::PwmDuty(a(2).pin(Pin::A), 200),
                PortOp::PwmFrequency(a(1), 1000),
                PortOp::PwmPulseWidth(a(1).pin(Pin::B), 1500),
            ]
        );
        // Nothing to read: no_request with sequence number 0.
        let mut buf = [0u8; 40];
        let n = db.take_reply(&mut buf);
        assert_eq!(&buf[..n], &[0x00, 0x0D, 0x00]);
    }

    #[test]
    fn every_error_has_its_status() {
        let db = board();
        let cases: [(&[u8], [u8; 3]); 8] = [
            (&[0x00, 0x09, 0x00], [0x00, 0x02, 0x00]), // truncated
            (&[0xF0, 0x09, 0x00, 0x05], [0x05, 0x03, 0x00]), // unknown function (15)
            (&[0x0F, 0x09, 0x00, 0x06], [0x06, 0x04, 0x00]), // unknown operand (system 15)
            (&[0x10, 0x09, 0x84, 0x07], [0x07, 0x05, 0x00]), // sensor port 3 of 2
            (&[0x30, 0x09, 0x00, 0x08], [0x08, 0x06, 0x00]), // analog on an actuator
            (&[0x00, 0x0A, 0x00, 0x09], [0x09, 0x07, 0x00]), // for board 10
            (&[0x00, 0x09, 0x01, 0x0B], [0x0B, 0x09, 0x00]), // ping with a port byte
            (&[0x41, 0x09, 0x80, 0x0C, 0x04], [0x0C, 0x0A, 0x00]), // serial: unsupported
        ];
        let mut buf = [0u8; 40];
        for (req, reply) in cases {
            let n = exchange(&db, req, &mut buf);
            assert_eq!(&buf[..n], &reply[..]);
        }
        assert!(db.ports().take_log().is_empty());
    }

    #[test]
    fn pec_once_negotiated_is_checked_and_added() {
        let db = board();
        let mut buf = [0u8; 40];
        let n = exchange(&db, &[0x07, 0x09, 0x00, 0x01, 0x01], &mut buf);
        // The reply to set_pec comes in the new mode: with its PEC byte (docs/protocol.md).
        assert_eq!(
            &buf[..n],
            &[0x01, 0x00, 0x00, pec::compute(0x13, &[0x01, 0x00, 0x00])]
        );
        let frame = [0x00, 0x09, 0x00, 0x02];
        let mut req = [0u8; 5];
        req[..4].copy_from_slice(&frame);
        req[4] = pec::compute(0x12, &frame);
        let n = exchange(&db, &req, &mut buf);
        assert_eq!(
            &buf[..n],
            &[0x02, 0x00, 0x00, pec::compute(0x13, &[0x02, 0x00, 0x00])]
        );
        // A wrong PEC byte: pec_mismatch.
        let n = exchange(&db, &[0x00, 0x09, 0x00, 0x03, 0x00], &mut buf);
        assert_eq!(
            &buf[..n],
            &[0x03, 0x08, 0x00, pec::compute(0x13, &[0x03, 0x08, 0x00])]
        );
    }

    #[test]
    fn batch_runs_items_in_order() {
        let db = board();
        db.ports().set_level(s(1).pin(Pin::A), true);
        db.ports().set_analog(s(2), 0x0456);
        let req = [
            0x50, 0x09, 0x00, 0x0E, // header
            0x10, 0x80, 0, // digital read S1.A
            0x12, 0x00, 0, // HIGH A1.A
            0x30, 0x82, 0, // analog S2
            0x10, 0x90, 0, // digital read S9.A: out of range
            0x20, 0x02, 1, 77, // duty 77 on A2.A
        ];
        let mut buf = [0u8; 40];
        x10_qemu_tests::stack::paint();
        let base = x10_qemu_tests::stack::depth();
        let n = exchange(&db, &req, &mut buf);
        let (used, _) = x10_qemu_tests::stack::used();
        // The DB core's own stack for a whole request (parse, five operations, reply):
        // docs/boards.md quotes it for the C011's 6 KiB.
        defmt::info!(
            "DB core stack high-water mark, batch of five: {=usize} B",
            used - base
        );
        assert_eq!(
            &buf[..n],
            &[0x0E, 0x00, 13, 0x00, 1, 1, 0x00, 0, 0x00, 2, 0x56, 0x04, 0x05, 0, 0x00, 0]
        );
    }

    #[test]
    fn pulse_in_is_pending_then_a_deferred_reply_event(clock: &mut QemuClock) {
        let db = board();
        db.ports().set_pulse(2_000, Ok(1_234));
        let t0 = clock.now();
        let script = async {
            let mut buf = [0u8; 40];
            // Pulse-in rising on S1.B, timeout 50 ms, sequence 0x2A.
            db.handle_write(&[0x13, 0x09, 0x81, 0x2A, 50, 0], true);
            let n = db.take_reply(&mut buf);
            assert_eq!(&buf[..n], &[0x2A, 0x01, 0x00]);
            loop {
                let ev = db.next_event().await;
                if ev.kind == EventKind::DeferredReply {
                    break ev;
                }
                // The boot event comes first.
                assert_eq!(ev.kind, EventKind::Boot);
            }
        };
        x10_qemu_tests::stack::paint();
        let base = x10_qemu_tests::stack::depth();
        let ev = match block_on(select(script, db.run_background(&QemuClock))) {
            Either::First(ev) => ev,
            Either::Second(never) => never,
        };
        let (used, _) = x10_qemu_tests::stack::used();
        // Request, background task and event together, their future on this stack too.
        defmt::info!(
            "DB core stack high-water mark, pulse-in with its background task: {=usize} B",
            used - base
        );
        let waited = clock.now().since(t0);
        defmt::info!("deferred reply after {=u64} µs", waited);
        defmt::assert!((2_000..50_000).contains(&waited));
        assert_eq!(
            (ev.seq, ev.status, ev.pin),
            (0x2A, Status::Ok, PinRef::from_byte(0x81))
        );
        let mut buf = [0u8; 40];
        let n = db.encode_event(&ev, Address::external(8).unwrap(), &mut buf);
        assert_eq!(
            &buf[..n],
            &[0x09, 0x03, 0x81, 0x2A, 0x00, 0x04, 0xD2, 0x04, 0x00, 0x00]
        );
        defmt::assert!(db.ports().take_log().contains(&PortOp::PulseIn(
            s(1).pin(Pin::B),
            Edge::Rising,
            50
        )));
    }
}
