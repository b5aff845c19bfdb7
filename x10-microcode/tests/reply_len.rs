//! `Op::reply_len` for every operation, and `Reply::parse_read_for`: a reply whose length the
//! operation does not allow is refused, and the PEC byte is never looked for where an
//! unchecked byte says.

use x10_microcode::test_support::db9;
use x10_microcode::{
    pec, Batch, BatchWriter, Edge, Error, EventConfig, Level, Op, Pin, Port, Reply, ReplyLen,
    Status, MAX_FRAME_LEN,
};

fn s1() -> Port {
    Port::sensor(1).unwrap()
}

fn a1() -> Port {
    Port::actuator(1).unwrap()
}

/// Every operation, with the `ok` payload lengths its reply may have.
fn every_op(batch: Batch<'_>) -> Vec<(Op<'_>, ReplyLen)> {
    use ReplyLen::*;
    vec![
        (Op::Ping, Exact(0)),
        (Op::Identify, Exact(10)),
        (Op::Heartbeat, Exact(0)),
        (Op::SetFailsafe { timeout_ms: 300 }, Exact(0)),
        (
            Op::EventEnable(s1().pin(Pin::A), EventConfig::OFF),
            Exact(0),
        ),
        (Op::ReadDiagnostics, Exact(28)),
        (Op::ClearDiagnostics, Exact(0)),
        (Op::SetPec(true), Exact(0)),
        (Op::DigitalRead(s1().pin(Pin::A)), Exact(1)),
        (Op::DigitalWrite(a1().pin(Pin::B), Level::High), Exact(0)),
        (
            Op::PulseIn {
                pin: s1().pin(Pin::B),
                edge: Edge::Rising,
                timeout_ms: None,
            },
            Exact(0),
        ),
        (Op::PwmDuty(a1().pin(Pin::A), 128), Exact(0)),
        (Op::PwmFrequency(a1(), 20_000), Exact(0)),
        (Op::PwmPulseWidth(a1().pin(Pin::A), 1500), Exact(0)),
        (Op::AnalogRead(s1()), Exact(2)),
        (Op::SerialWrite(s1(), b"hi"), Exact(0)),
        (
            Op::SerialRead(s1(), 8),
            Range {
                min: 0,
                max: 8,
                step: 1,
            },
        ),
        (Op::SerialConfig(s1(), 9600), Exact(0)),
        (Op::Batch(batch), Batch { max: 2 + 2 + 4 }),
        (
            Op::Scan,
            Range {
                min: 3,
                max: 19,
                step: 2,
            },
        ),
    ]
}

/// A batch: HIGH on A1.B, duty 200 on A1.A, analog read of S1 (protocol.md's example).
fn batch(buf: &mut [u8]) -> Batch<'_> {
    let mut w = BatchWriter::new(buf);
    w.push(&Op::DigitalWrite(a1().pin(Pin::B), Level::High))
        .unwrap();
    w.push(&Op::PwmDuty(a1().pin(Pin::A), 200)).unwrap();
    w.push(&Op::AnalogRead(s1())).unwrap();
    w.finish().unwrap()
}

#[test]
fn every_operation_has_its_reply_length() {
    let mut buf = [0u8; 28];
    let ops = every_op(batch(&mut buf));
    // One row per operation code (the batch and scan included).
    assert_eq!(ops.len(), 20);
    for (op, want) in ops {
        assert_eq!(op.reply_len(), want, "{op:?}");
        assert_eq!(op.reply_len_varies(), !want.is_exact(), "{op:?}");
        // The MB reads as much as the longest allowed reply.
        assert_eq!(
            usize::from(op.reply_len().max()),
            op.reply_capacity(),
            "{op:?}"
        );
    }
}

#[test]
fn allowed_lengths() {
    let exact = ReplyLen::Exact(2);
    assert!(exact.allows(2) && !exact.allows(0) && !exact.allows(1) && !exact.allows(3));
    let scan = Op::Scan.reply_len();
    let allowed: Vec<u8> = (0..=40).filter(|&n| scan.allows(n)).collect();
    assert_eq!(allowed, [3, 5, 7, 9, 11, 13, 15, 17, 19]);
    let serial = Op::SerialRead(s1(), 3).reply_len();
    let allowed: Vec<u8> = (0..=40).filter(|&n| serial.allows(n)).collect();
    assert_eq!(allowed, [0, 1, 2, 3]);
    assert_eq!(Op::DigitalRead(s1().pin(Pin::A)).deferred_len(), None);
    let pulse = Op::PulseIn {
        pin: s1().pin(Pin::B),
        edge: Edge::Falling,
        timeout_ms: Some(5),
    };
    assert_eq!(pulse.deferred_len(), Some(4));
}

#[test]
fn check_reply_takes_ok_with_an_allowed_length_and_errors_empty() {
    let analog = Op::AnalogRead(s1());
    assert_eq!(analog.check_reply(Status::Ok, &[0, 2]), Ok(()));
    // The 4 analog reads that returned `Ok` with an empty payload (issue 10).
    assert_eq!(analog.check_reply(Status::Ok, &[]), Err(Error::BadLength));
    assert_eq!(
        analog.check_reply(Status::Ok, &[1, 2, 3]),
        Err(Error::BadLength)
    );
    assert_eq!(analog.check_reply(Status::Busy, &[]), Ok(()));
    assert_eq!(
        analog.check_reply(Status::Busy, &[1]),
        Err(Error::BadLength)
    );
    let mut buf = [0u8; 28];
    let b = Op::Batch(batch(&mut buf));
    // Two outputs done, analog 512.
    let good = [0, 0, 0, 0, 0, 2, 0, 2];
    assert_eq!(b.check_reply(Status::Ok, &good), Ok(()));
    // The analog item with one byte, an output with a value, a missing or extra result.
    for bad in [
        &[0, 0, 0, 0, 0, 1, 2][..],
        &[0, 1, 7, 0, 0, 0, 2, 0, 2],
        &[0, 0, 0, 0],
        &[0, 0, 0, 0, 0, 2, 0, 2, 0, 0],
        &[0, 0, 0, 0, 0x0c, 2, 0, 2],
    ] {
        assert_eq!(
            b.check_reply(Status::Ok, bad),
            Err(Error::BadLength),
            "{bad:?}"
        );
    }
    // A refused item carries no value.
    assert_eq!(b.check_reply(Status::Ok, &[0, 0, 0, 0, 6, 0]), Ok(()));
}

/// A read of `3 + capacity + 1` bytes holding `frame` (+ PEC), padded with 0xFF.
fn read(op: &Op<'_>, frame: &[u8], with_pec: bool) -> Vec<u8> {
    let mut r = frame.to_vec();
    if with_pec {
        r.push(pec::compute(db9().addr_byte(true), frame));
    }
    r.resize(3 + op.reply_capacity() + 1, 0xFF);
    r
}

#[test]
fn a_flipped_length_byte_never_moves_the_pec() {
    let analog = Op::AnalogRead(s1());
    let good = read(&analog, &[4, 0, 2, 0, 2], true);
    let r = Reply::parse_read_for(db9(), true, &good, &analog).unwrap();
    assert_eq!((r.seq, r.status, r.payload), (4, Status::Ok, &[0, 2][..]));
    // LEN 2 → 0: the PEC is looked for after 2 payload bytes (it no longer matches: the LEN
    // byte is covered), then after the header (payload byte 0 is no PEC of the header).
    let mut flipped = good.clone();
    flipped[2] = 0;
    assert!(matches!(
        Reply::parse_read_for(db9(), true, &flipped, &analog),
        Err(Error::PecMismatch { .. })
    ));
    // Even when the byte after the header happens to be the PEC of the flipped header, the
    // reply is refused: `ok` with no payload is not an answer to an analog read.
    let mut chance = flipped.clone();
    chance[3] = pec::compute(db9().addr_byte(true), &chance[..3]);
    assert_eq!(
        Reply::parse_read_for(db9(), true, &chance, &analog),
        Err(Error::BadLength)
    );
    // Without PEC, a length the operation does not allow is refused before it is used.
    let no_pec = read(&analog, &[4, 0, 0], false);
    assert_eq!(
        Reply::parse_read_for(db9(), false, &no_pec, &analog),
        Err(Error::BadLength)
    );
    // A status-only reply is found after the header.
    let busy = read(&analog, &[4, 0x0b, 0], true);
    let r = Reply::parse_read_for(db9(), true, &busy, &analog).unwrap();
    assert_eq!((r.status, r.payload), (Status::Busy, &[][..]));
    // A scan whose LEN says 4 (not 3 + 2n) is refused before the PEC is located.
    let scan = read(&Op::Scan, &[5, 0, 4, 1, 0, 0, 9], true);
    assert_eq!(
        Reply::parse_read_for(db9(), true, &scan, &Op::Scan),
        Err(Error::BadLength)
    );
    assert!(scan.len() <= MAX_FRAME_LEN);
}

/// The motherboard's direct path (issue 27) takes an operation that expects no reply,
/// answered with no value, as fitting without calling `check_reply`: here `check_reply` says
/// so for every such operation and every status.
#[test]
fn an_operation_without_a_reply_fits_an_empty_answer_whatever_its_status() {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let b = batch(&mut buf);
    let mut without = 0;
    for (op, len) in every_op(b) {
        if op.expects_reply() {
            continue;
        }
        without += 1;
        assert_eq!(len, ReplyLen::Exact(0), "{op:?}");
        for code in 0..=255u8 {
            let status = Status::from_byte(code);
            assert_eq!(op.check_reply(status, &[]), Ok(()), "{op:?} {status:?}");
        }
    }
    // Heartbeat, set_failsafe, event_enable, clear_diagnostics, set_pec, digital write,
    // three PWM settings, serial write and config.
    assert_eq!(without, 11);
}

/// The sweep's operations (issue 27), outside the table above: a `sample`'s reply varies
/// with the board's sensor ports, `stage` and `apply` answer no value.
#[test]
fn the_sweeps_replies_vary_as_their_lengths_say() {
    let mut buf = [0u8; 28];
    let b = batch(&mut buf);
    for op in [Op::Sample, Op::Apply, Op::Stage(b)] {
        assert_eq!(op.reply_len_varies(), !op.reply_len().is_exact(), "{op:?}");
    }
    assert!(Op::Sample.reply_len_varies());
    assert!(!Op::Apply.reply_len_varies());
}
