//! Function 8 (sweep: `sample`, `apply`) and 9 (`stage`): parsing and refusals.

use x10_microcode::{pec, Error, Op, Request, RequestFrame};

fn parse(bytes: &[u8]) -> Result<Op<'_>, Error> {
    let f = RequestFrame::new_checked(bytes)?;
    Op::parse(f.fn_op(), f.port_byte(), bytes.get(4..).unwrap_or(&[]))
}

#[test]
fn sample_and_apply_are_board_operations_without_data() {
    assert_eq!(parse(&[0x80, 0x00, 0x00, 0x05]), Ok(Op::Sample));
    assert_eq!(parse(&[0x81, 0x00, 0x00, 0x06]), Ok(Op::Apply));
    assert_eq!(parse(&[0x80, 0x00, 0x00, 0x05, 1]), Err(Error::BadLength));
    assert_eq!(parse(&[0x81, 0x00, 0x02, 0x06]), Err(Error::BadArgument));
    assert_eq!(
        parse(&[0x82, 0x00, 0x00, 0x06]),
        Err(Error::UnknownOperand {
            function: 8,
            operand: 2
        })
    );
    // Neither is the I2C general call's own second byte (0x06 reset, 0x04 address).
    assert_ne!(Op::Sample.fn_op_byte(), 0x06);
    assert_ne!(Op::Apply.fn_op_byte(), 0x04);
}

#[test]
fn a_stage_holds_outputs_only() {
    // io high on A1.B, pwm duty 200 on A1.A.
    let frame = [
        0x90, 0x09, 0x00, 0x07, 0x12, 0x01, 0x00, 0x20, 0x00, 0x01, 0xc8,
    ];
    let Ok(Op::Stage(b)) = parse(&frame) else {
        panic!("not a stage");
    };
    assert_eq!(b.iter().count(), 2);
    assert!(!Op::Stage(b).expects_reply());
    // An analog read, a ping, a scan, a pulse-in: refused.
    for item in [
        &[0x30, 0x80, 0x00][..],
        &[0x00, 0x00, 0x00],
        &[0x60, 0x00, 0x00],
        &[0x13, 0x80, 0x00],
    ] {
        let mut f = vec![0x90, 0x09, 0x00, 0x07];
        f.extend_from_slice(item);
        assert_eq!(parse(&f), Err(Error::BadArgument), "{item:02x?}");
    }
    // Empty: refused.
    assert_eq!(parse(&[0x90, 0x09, 0x00, 0x07]), Err(Error::BadLength));
}

#[test]
fn none_of_them_goes_in_a_batch_or_a_stage() {
    for inner in [[0x80u8, 0x00, 0x00], [0x81, 0x00, 0x00]] {
        for outer in [0x50u8, 0x90] {
            let mut f = vec![outer, 0x09, 0x00, 0x01];
            f.extend_from_slice(&inner);
            assert_eq!(
                parse(&f),
                Err(Error::BadArgument),
                "{outer:02x} {inner:02x?}"
            );
        }
    }
    let f = [0x50, 0x09, 0x00, 0x01, 0x90, 0x00, 0x03, 0x12, 0x01, 0x00];
    assert_eq!(parse(&f), Err(Error::BadArgument));
}

#[test]
fn the_broadcast_frames_with_their_check() {
    let mut buf = [0u8; 8];
    let req = Request {
        db: x10_microcode::Address::new(0).unwrap(),
        seq: 5,
        op: Op::Sample,
    };
    let n = req.emit(&mut buf).unwrap();
    let n = pec::append(0x00, &mut buf, n).unwrap();
    assert_eq!(
        &buf[..n],
        &[0x80, 0x00, 0x00, 0x05, pec::compute(0, &[0x80, 0, 0, 5])]
    );
    assert_eq!(pec::strip(0x00, &buf[..n]), Ok(&[0x80, 0, 0, 5][..]));
}
