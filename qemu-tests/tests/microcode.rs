//! x10-microcode on the target: byte vectors of every frame kind parse to the values written
//! next to them and emit the same bytes, truncated frames are errors, PEC matches the SMBus
//! CRC-8, and parsing pseudo-random bytes never panics (a panic would end QEMU with exit
//! code 1). The vectors are the ones of `x10-microcode/tests/vectors.rs`.
#![no_std]
#![no_main]

use x10_hal::time::Clock;
use x10_microcode::test_support::{a, s};
use x10_microcode::{
    pec, Address, Edge, Error, Event, EventConfig, EventKind, Level, Op, Pin, PinRef, Reply,
    Request, Status, MAX_FRAME_LEN,
};
use x10_qemu_tests::QemuClock;

/// (bytes, db, seq, op)
fn requests() -> [(&'static [u8], u8, u8, Op<'static>); 12] {
    [
        (&[0x00, 0x09, 0x00, 0x01], 9, 1, Op::Ping),
        (&[0x01, 0x09, 0x00, 0x02], 9, 2, Op::Identify),
        (
            &[0x03, 0x09, 0x00, 0x04, 0xf4, 0x01],
            9,
            4,
            Op::SetFailsafe { timeout_ms: 500 },
        ),
        (
            &[0x04, 0x09, 0x82, 0x05, 0x07, 0x64, 0x00, 0x84, 0x03],
            9,
            5,
            Op::EventEnable(
                s(2).pin(Pin::A),
                EventConfig {
                    rising: true,
                    falling: true,
                    analog_window: true,
                    low: 100,
                    high: 900,
                },
            ),
        ),
        (
            &[0x10, 0x09, 0x80, 0x09],
            9,
            9,
            Op::DigitalRead(s(1).pin(Pin::A)),
        ),
        (
            &[0x11, 0x09, 0x02, 0x0a],
            9,
            10,
            Op::DigitalWrite(a(2).pin(Pin::A), Level::Low),
        ),
        // The example: digitalOut HIGH to DB 9, actuator port 1, pin B, seq 2.
        (
            &[0x12, 0x09, 0x01, 0x02],
            9,
            2,
            Op::DigitalWrite(a(1).pin(Pin::B), Level::High),
        ),
        (
            &[0x14, 0x09, 0x85, 0x0c, 0xe8, 0x03],
            9,
            12,
            Op::PulseIn {
                pin: s(3).pin(Pin::B),
                edge: Edge::Falling,
                timeout_ms: Some(1_000),
            },
        ),
        (
            &[0x20, 0x09, 0x01, 0x03, 0x80],
            9,
            3,
            Op::PwmDuty(a(1).pin(Pin::B), 128),
        ),
        (
            &[0x21, 0x09, 0x00, 0x0d, 0x20, 0x4e],
            9,
            13,
            Op::PwmFrequency(a(1), 20_000),
        ),
        (&[0x30, 0x09, 0x80, 0x04], 9, 4, Op::AnalogRead(s(1))),
        (&[0x30, 0x00, 0x82, 0x10], 0, 16, Op::AnalogRead(s(2))),
    ]
}

/// (bytes, kind, pin, seq, status, payload)
type EventVector = (&'static [u8], EventKind, PinRef, u8, Status, &'static [u8]);

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
    fn requests_parse_emit_and_reject_truncation() {
        for (bytes, db, seq, op) in requests() {
            let r = Request::parse(bytes).unwrap();
            assert_eq!(r.db, Address::new(db).unwrap());
            assert_eq!(r.seq, seq);
            assert_eq!(r.op, op);
            let mut buf = [0xAAu8; MAX_FRAME_LEN];
            let n = r.emit(&mut buf).unwrap();
            assert_eq!(&buf[..n], bytes);
            // Shorter than the header, or missing data: an error, never a panic.
            for len in 0..bytes.len() {
                let prefix = &bytes[..len];
                let ok_prefix = len == 4 && matches!(op, Op::PulseIn { .. });
                assert_eq!(Request::parse(prefix).is_ok(), ok_prefix);
            }
        }
    }

    #[test]
    fn header_errors_are_values() {
        assert_eq!(
            Request::parse(&[0x12, 0x05, 0x01, 0x02]).err(),
            Some(Error::BadAddress(5))
        );
        assert_eq!(
            Request::parse(&[0xF0, 0x09, 0x00, 0x01]).err(),
            Some(Error::UnknownFunction(15))
        );
        assert_eq!(Request::parse(&[0x12, 0x09]).err(), Some(Error::Truncated));
    }

    #[test]
    fn replies_parse_and_emit() {
        let cases: [(&[u8], u8, Status, &[u8]); 4] = [
            (&[0x05, 0x00, 0x00], 5, Status::Ok, &[]),
            (&[0x07, 0x00, 0x01, 0x01], 7, Status::Ok, &[1]),
            (
                &[0x08, 0x00, 0x02, 0x23, 0x01],
                8,
                Status::Ok,
                &[0x23, 0x01],
            ),
            (&[0x0b, 0x01, 0x00], 11, Status::Pending, &[]),
        ];
        for (bytes, seq, status, payload) in cases {
            let r = Reply::parse(bytes).unwrap();
            assert_eq!((r.seq, r.status, r.payload), (seq, status, payload));
            let mut buf = [0x55u8; MAX_FRAME_LEN];
            let n = r.emit(&mut buf).unwrap();
            assert_eq!(&buf[..n], bytes);
            for len in 0..bytes.len() {
                assert!(Reply::parse(&bytes[..len]).is_err());
            }
        }
    }

    #[test]
    fn events_parse_and_emit() {
        let cases: [EventVector; 3] = [
            (
                &[0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01],
                EventKind::PinChange,
                s(1).pin(Pin::A),
                7,
                Status::Ok,
                &[1],
            ),
            (
                &[0x09, 0x03, 0x85, 0x0b, 0x00, 0x04, 0xf0, 0x05, 0x00, 0x00],
                EventKind::DeferredReply,
                s(3).pin(Pin::B),
                11,
                Status::Ok,
                &[0xf0, 0x05, 0x00, 0x00],
            ),
            (
                &[0x09, 0x04, 0x00, 0x09, 0x00, 0x02, 0xf4, 0x01],
                EventKind::FailsafeTripped,
                a(1).pin(Pin::A),
                9,
                Status::Ok,
                &[0xf4, 0x01],
            ),
        ];
        for (bytes, kind, pin, seq, status, payload) in cases {
            let e = Event::parse(bytes).unwrap();
            assert_eq!(e.source, Address::new(9).unwrap());
            assert_eq!(
                (e.kind, e.pin, e.seq, e.status, e.payload),
                (kind, pin, seq, status, payload)
            );
            let mut buf = [0x55u8; MAX_FRAME_LEN];
            let n = e.emit(&mut buf).unwrap();
            assert_eq!(&buf[..n], bytes);
            for len in 0..bytes.len() {
                assert!(Event::parse(&bytes[..len]).is_err());
            }
        }
    }

    #[test]
    fn pec_is_smbus_crc8() {
        // CRC-8 (poly 0x07, init 0) check value over "123456789" is 0xF4; the address byte
        // comes first.
        assert_eq!(pec::compute(b'1', b"23456789"), 0xF4);
        assert_eq!(pec::compute(0x13, &[0x09, 0x00, 0x01, 0x01]), 0x20);
        assert_eq!(
            pec::compute(0x10 << 1, &[0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01]),
            0x95
        );
    }

    #[test]
    fn arbitrary_bytes_never_panic(clock: &mut QemuClock) {
        // xorshift32 frames of every length up to the longest frame + 1.
        let mut x: u32 = 0x1234_5678;
        let mut ok = [0u32; 3];
        let start = clock.now();
        for i in 0..3_000u32 {
            let mut buf = [0u8; MAX_FRAME_LEN + 1];
            let len = (i as usize) % buf.len();
            for b in buf.iter_mut() {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                *b = x as u8;
            }
            let frame = &buf[..len];
            ok[0] += u32::from(Request::parse(frame).is_ok());
            ok[1] += u32::from(Reply::parse(frame).is_ok());
            ok[2] += u32::from(Event::parse(frame).is_ok());
        }
        let us = clock.now().since(start);
        defmt::info!(
            "3000 random frames × 3 parsers: {} requests, {} replies, {} events valid; {=u64} µs",
            ok[0],
            ok[1],
            ok[2],
            us
        );
        // Some random frames are valid replies (any seq/status, a length that fits).
        defmt::assert!(ok[1] > 0);
    }
}
