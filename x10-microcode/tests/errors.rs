//! Error cases: every way a frame can be refused, the exact [`Error`] it gives, and the
//! [`Status`] a daughterboard answers with ([`Error::status`]).

use x10_microcode::{
    Address, Batch, BatchWriter, Error, Event, EventConfig, EventKind, Level, Op, Pin, Port,
    PortKind, Reply, Request, ScanResult, Status, MAX_PAYLOAD, MAX_REQUEST_DATA, MAX_REQUEST_LEN,
};

fn parse_err(bytes: &[u8]) -> Error {
    match Request::parse(bytes) {
        Ok(r) => panic!("{bytes:02x?} parsed as {r:?}"),
        Err(e) => e,
    }
}

#[test]
fn unknown_function() {
    // 7 is update, 8 and 9 are sweep and stage.
    for f in 10u8..=15 {
        let e = parse_err(&[f << 4, 0x09, 0x00, 0x01]);
        assert_eq!(e, Error::UnknownFunction(f));
        assert_eq!(e.status(), Status::UnknownFunction);
        assert_eq!(e.status().to_byte(), 0x03);
    }
    // The function is checked whatever the rest says.
    assert_eq!(
        parse_err(&[0xf3, 0x09, 0xff, 0x01, 1, 2, 3]),
        Error::UnknownFunction(0xf)
    );
}

#[test]
fn unknown_operand_of_every_function() {
    // First unused operand of each function, and the last one.
    let cases: &[(u8, u8)] = &[
        (0x0, 0xe),
        (0x1, 0x5),
        (0x2, 0x3),
        (0x3, 0x1),
        (0x4, 0x3),
        (0x5, 0x1),
        (0x6, 0x1),
        (0x7, 0x5),
    ];
    for &(function, first) in cases {
        for operand in first..=0xf {
            let e = parse_err(&[function << 4 | operand, 0x09, 0x00, 0x01]);
            assert_eq!(e, Error::UnknownOperand { function, operand });
            assert_eq!(e.status(), Status::UnknownOperand);
            assert_eq!(e.status().to_byte(), 0x04);
        }
    }
}

#[test]
fn bad_address() {
    for db in (0x01u8..=0x07).chain(0x78..=0xff) {
        let e = parse_err(&[0x12, db, 0x01, 0x02]);
        assert_eq!(e, Error::BadAddress(db));
        assert_eq!(e.status(), Status::WrongAddress);
        assert_eq!(Address::new(db), Err(Error::BadAddress(db)));
        assert_eq!(Address::external(db), Err(Error::BadAddress(db)));
    }
    assert_eq!(Address::external(0), Err(Error::BadAddress(0)));
    assert!(Address::new(0).unwrap().is_internal());
    assert_eq!(Address::new(0x08).unwrap().get(), 0x08);
    assert_eq!(Address::external(0x77).unwrap().get(), 0x77);
    assert_eq!(Address::new(0x09).unwrap().addr_byte(false), 0x12);
    assert_eq!(Address::new(0x09).unwrap().addr_byte(true), 0x13);
    // An event's source is checked the same way.
    assert_eq!(
        Event::parse(&[0x05, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01]),
        Err(Error::BadAddress(0x05))
    );
    assert_eq!(
        Event::parse(&[0x80, 0x01, 0x80, 0x07, 0x00, 0x00]),
        Err(Error::BadAddress(0x80))
    );
}

#[test]
fn bad_port_number() {
    for kind in [PortKind::Sensor, PortKind::Actuator] {
        assert_eq!(Port::new(kind, 0), Err(Error::BadPort(0)));
        assert_eq!(Port::new(kind, 65), Err(Error::BadPort(65)));
        assert_eq!(Port::new(kind, 255), Err(Error::BadPort(255)));
        assert_eq!(Port::new(kind, 1).unwrap().index(), 0);
        assert_eq!(Port::new(kind, 64).unwrap().index(), 63);
    }
    assert_eq!(Error::BadPort(0).status(), Status::PortOutOfRange);
    // Port 64 is the highest the wire can name: bits 6..1 all set.
    let p = Port::sensor(64).unwrap().pin(Pin::B);
    assert_eq!(p.to_byte(), 0xff);
    assert_eq!(Port::actuator(64).unwrap().pin(Pin::A).to_byte(), 0x7e);
}

#[test]
fn wrong_port_kind() {
    let cases: &[&[u8]] = &[
        // PWM duty on a sensor port.
        &[0x20, 0x09, 0x80, 0x01, 0x10],
        // PWM frequency on a sensor port.
        &[0x21, 0x09, 0x80, 0x01, 0x20, 0x4e],
        // Pulse width on a sensor port.
        &[0x22, 0x09, 0x81, 0x01, 0xdc, 0x05],
        // Analog read on an actuator port: the thesis `analog()` frame, which left out the
        // port-kind bit.
        &[0x30, 0x09, 0x00, 0x04],
    ];
    for &bytes in cases {
        let e = parse_err(bytes);
        assert_eq!(e, Error::WrongPortKind, "{bytes:02x?}");
        assert_eq!(e.status(), Status::WrongPortKind);
        assert_eq!(e.status().to_byte(), 0x06);
    }
    // Built in code, validate() reports the same.
    let s1 = Port::sensor(1).unwrap();
    assert_eq!(
        Op::PwmDuty(s1.pin(Pin::A), 1).validate(),
        Err(Error::WrongPortKind)
    );
    assert_eq!(
        Op::AnalogRead(Port::actuator(1).unwrap()).validate(),
        Err(Error::WrongPortKind)
    );
}

#[test]
fn reserved_bits_and_out_of_range_values() {
    let cases: &[(&str, &[u8])] = &[
        ("ping with a port byte", &[0x00, 0x09, 0x01, 0x01]),
        ("identify with a port byte", &[0x01, 0x09, 0x80, 0x01]),
        (
            "set_failsafe with a port byte",
            &[0x03, 0x09, 0x02, 0x01, 1, 0],
        ),
        ("set_pec with a port byte", &[0x07, 0x09, 0x02, 0x01, 1]),
        ("set_pec 2", &[0x07, 0x09, 0x00, 0x01, 2]),
        (
            "event_enable reserved flag",
            &[0x04, 0x09, 0x80, 0x01, 0x08, 0, 0, 0, 0],
        ),
        (
            "event_enable low > high",
            &[0x04, 0x09, 0x80, 0x01, 0x04, 2, 0, 1, 0],
        ),
        ("analog read of pin B", &[0x30, 0x09, 0x81, 0x01]),
        ("pwm frequency pin B", &[0x21, 0x09, 0x01, 0x01, 0x20, 0x4e]),
        ("pwm frequency 0 Hz", &[0x21, 0x09, 0x00, 0x01, 0, 0]),
        ("serial write pin B", &[0x40, 0x09, 0x87, 0x01, b'x']),
        ("serial read 0 bytes", &[0x41, 0x09, 0x86, 0x01, 0]),
        ("serial read 29 bytes", &[0x41, 0x09, 0x86, 0x01, 29]),
        (
            "serial config 0 baud",
            &[0x42, 0x09, 0x86, 0x01, 0, 0, 0, 0],
        ),
        (
            "batch with a port byte",
            &[0x50, 0x09, 0x01, 0x01, 0x12, 0x01, 0x00],
        ),
        ("scan with a port byte", &[0x60, 0x09, 0x80, 0x01]),
        (
            "pulse-in inside a batch",
            &[0x50, 0x09, 0x00, 0x01, 0x13, 0x85, 0x00],
        ),
    ];
    for &(what, bytes) in cases {
        let e = parse_err(bytes);
        assert_eq!(e, Error::BadArgument, "{what}");
        assert_eq!(e.status(), Status::BadArgument, "{what}");
        assert_eq!(e.status().to_byte(), 0x09, "{what}");
    }
    // Disabled analog windows may hold any bounds.
    assert!(Request::parse(&[0x04, 0x09, 0x80, 0x01, 0x01, 2, 0, 1, 0]).is_ok());
    // Serial read of exactly MAX_PAYLOAD bytes is fine.
    assert!(Request::parse(&[0x41, 0x09, 0x86, 0x01, MAX_PAYLOAD as u8]).is_ok());
}

#[test]
fn wrong_data_length() {
    let cases: &[(&str, &[u8])] = &[
        ("ping with data", &[0x00, 0x09, 0x00, 0x01, 0]),
        ("identify with data", &[0x01, 0x09, 0x00, 0x01, 0]),
        ("heartbeat with data", &[0x02, 0x09, 0x00, 0x01, 0]),
        ("set_failsafe 1 byte", &[0x03, 0x09, 0x00, 0x01, 0]),
        ("set_failsafe 3 bytes", &[0x03, 0x09, 0x00, 0x01, 0, 0, 0]),
        (
            "event_enable 4 bytes",
            &[0x04, 0x09, 0x80, 0x01, 0, 0, 0, 0],
        ),
        (
            "event_enable 6 bytes",
            &[0x04, 0x09, 0x80, 0x01, 0, 0, 0, 0, 0, 0],
        ),
        ("read_diagnostics with data", &[0x05, 0x09, 0x00, 0x01, 0]),
        ("clear_diagnostics with data", &[0x06, 0x09, 0x00, 0x01, 0]),
        ("set_pec no data", &[0x07, 0x09, 0x00, 0x01]),
        ("set_pec 2 bytes", &[0x07, 0x09, 0x00, 0x01, 1, 1]),
        ("input with data", &[0x10, 0x09, 0x80, 0x01, 0]),
        ("low with data", &[0x11, 0x09, 0x00, 0x01, 0]),
        ("high with data", &[0x12, 0x09, 0x01, 0x02, 0]),
        ("pulse-in 1 byte", &[0x13, 0x09, 0x85, 0x01, 0]),
        ("pulse-in 3 bytes", &[0x14, 0x09, 0x85, 0x01, 0, 0, 0]),
        ("pwm duty without duty", &[0x20, 0x09, 0x01, 0x01]),
        ("pwm duty 2 bytes", &[0x20, 0x09, 0x01, 0x01, 1, 2]),
        ("pwm frequency 1 byte", &[0x21, 0x09, 0x00, 0x01, 1]),
        ("pulse width 3 bytes", &[0x22, 0x09, 0x00, 0x01, 1, 2, 3]),
        ("analog with data", &[0x30, 0x09, 0x80, 0x01, 0]),
        ("serial write empty", &[0x40, 0x09, 0x86, 0x01]),
        ("serial read empty", &[0x41, 0x09, 0x86, 0x01]),
        (
            "serial config 2 bytes",
            &[0x42, 0x09, 0x86, 0x01, 0x80, 0x25],
        ),
        ("empty batch", &[0x50, 0x09, 0x00, 0x01]),
        ("scan with data", &[0x60, 0x09, 0x00, 0x01, 0]),
    ];
    for &(what, bytes) in cases {
        let e = parse_err(bytes);
        assert_eq!(e, Error::BadLength, "{what}");
        assert_eq!(e.status(), Status::BadLength, "{what}");
        assert_eq!(e.status().to_byte(), 0x02, "{what}");
    }
    // Reply and event frames with bytes after their declared payload.
    assert_eq!(
        Reply::parse(&[0x01, 0x00, 0x00, 0x00]),
        Err(Error::BadLength)
    );
    assert_eq!(
        Event::parse(&[0x09, 0x01, 0x80, 0x07, 0x00, 0x00, 0x00]),
        Err(Error::BadLength)
    );
}

#[test]
fn truncated() {
    assert_eq!(parse_err(&[]), Error::Truncated);
    assert_eq!(parse_err(&[0x12, 0x09, 0x01]), Error::Truncated);
    assert_eq!(Error::Truncated.status(), Status::BadLength);
    // A batch item cut short.
    assert_eq!(
        parse_err(&[0x50, 0x09, 0x00, 0x01, 0x20, 0x00, 0x01]),
        Error::Truncated
    );
    assert_eq!(
        parse_err(&[0x50, 0x09, 0x00, 0x01, 0x12, 0x01]),
        Error::Truncated
    );
    assert_eq!(
        Reply::parse(&[0x01, 0x00, 0x02, 0xaa]),
        Err(Error::Truncated)
    );
    assert_eq!(
        Event::parse(&[0x09, 0x01, 0x80, 0x07, 0x00, 0x01]),
        Err(Error::Truncated)
    );
}

#[test]
fn pec_mismatch() {
    let db = Address::new(0x09).unwrap();
    let e = Request::parse_with_pec(db, &[0x12, 0x09, 0x01, 0x02, 0x9d]).unwrap_err();
    assert_eq!(
        e,
        Error::PecMismatch {
            received: 0x9d,
            computed: 0x9c
        }
    );
    assert_eq!(e.status(), Status::PecMismatch);
    assert_eq!(e.status().to_byte(), 0x08);
    // The right bytes with PEC from the wrong address.
    let other = Address::new(0x0a).unwrap();
    assert!(matches!(
        Request::parse_with_pec(other, &[0x12, 0x09, 0x01, 0x02, 0x9c]),
        Err(Error::PecMismatch { received: 0x9c, .. })
    ));
    // A frame sent without PEC to a board that expects it: the last data byte is taken as
    // PEC and does not match (here the sequence number).
    assert!(matches!(
        Request::parse_with_pec(db, &[0x12, 0x09, 0x01, 0x02]),
        Err(Error::PecMismatch { received: 0x02, .. })
    ));
    assert_eq!(Request::parse_with_pec(db, &[]), Err(Error::Truncated));
    // Reply and event.
    assert!(matches!(
        Reply::parse_read(db, true, &[0x09, 0x00, 0x01, 0x01, 0x21]),
        Err(Error::PecMismatch {
            received: 0x21,
            computed: 0x20
        })
    ));
    let mb = Address::new(0x10).unwrap();
    assert!(matches!(
        Event::parse_with_pec(mb, &[0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01, 0x00]),
        Err(Error::PecMismatch {
            received: 0x00,
            computed: 0x95
        })
    ));
}

#[test]
fn nested_batch() {
    // A batch item that is itself a (valid-looking) batch.
    let e = parse_err(&[0x50, 0x09, 0x00, 0x01, 0x50, 0x00, 0x03, 0x12, 0x01, 0x00]);
    assert_eq!(e, Error::NestedBatch);
    assert_eq!(e.status(), Status::BadArgument);
    // An empty nested batch is still a nested batch.
    assert_eq!(
        parse_err(&[0x50, 0x09, 0x00, 0x01, 0x12, 0x01, 0x00, 0x50, 0x00, 0x00]),
        Error::NestedBatch
    );
    // Whatever its operand.
    assert_eq!(
        parse_err(&[0x50, 0x09, 0x00, 0x01, 0x5f, 0x00, 0x00]),
        Error::NestedBatch
    );
    // The writer refuses to nest too.
    let mut inner_buf = [0u8; 8];
    let mut w = BatchWriter::new(&mut inner_buf);
    w.push(&Op::Ping).unwrap();
    let inner = w.finish().unwrap();
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let mut w = BatchWriter::new(&mut buf);
    assert_eq!(w.push(&Op::Batch(inner)), Err(Error::NestedBatch));
    assert_eq!(
        Batch::new_checked(&[0x50, 0x00, 0x00]),
        Err(Error::NestedBatch)
    );
}

#[test]
fn deferred_operation_in_batch() {
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let mut w = BatchWriter::new(&mut buf);
    let pulse = Op::PulseIn {
        pin: Port::sensor(1).unwrap().pin(Pin::A),
        edge: x10_microcode::Edge::Rising,
        timeout_ms: Some(10),
    };
    assert_eq!(w.push(&pulse), Err(Error::BadArgument));
}

#[test]
fn analog_window_events_only_on_sensor_ports() {
    // event_enable with the analog window on actuator port 1: no analog input there.
    let e = parse_err(&[0x04, 0x09, 0x00, 0x05, 0x04, 0x64, 0x00, 0x84, 0x03]);
    assert_eq!(e, Error::WrongPortKind);
    assert_eq!(e.status(), Status::WrongPortKind);
    // Edges only on the same actuator pin are fine.
    Request::parse(&[0x04, 0x09, 0x00, 0x05, 0x03, 0x00, 0x00, 0x00, 0x00]).unwrap();
}

#[test]
fn batch_reply_too_long() {
    // Three identify items: 3 × (2 + 10) = 36 result bytes > 28.
    let e = parse_err(&[
        0x50, 0x09, 0x00, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00,
    ]);
    assert_eq!(e, Error::TooLong);
    assert_eq!(e.status(), Status::BadLength);
    // Two identify items fit: 24 bytes.
    let two =
        Request::parse(&[0x50, 0x09, 0x00, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00]).unwrap();
    assert_eq!(two.op.reply_capacity(), 24);
    // Diagnostics (28 bytes) never fits beside its result header; a scan (19) does, and so
    // does a scan beside an analog read (2 + 19 + 2 + 2 = 25), but not beside an identify.
    assert_eq!(Batch::new_checked(&[0x05, 0x00, 0x00]), Err(Error::TooLong));
    let scan = Batch::new_checked(&[0x60, 0x00, 0x00]).unwrap();
    assert_eq!(scan.reply_capacity(), 21);
    let scan_analog = Batch::new_checked(&[0x60, 0x00, 0x00, 0x30, 0x80, 0x00]).unwrap();
    assert_eq!(scan_analog.reply_capacity(), 25);
    assert_eq!(
        Batch::new_checked(&[0x60, 0x00, 0x00, 0x01, 0x00, 0x00]),
        Err(Error::TooLong)
    );
    // The writer accepts the items one by one and refuses at finish.
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let mut w = BatchWriter::new(&mut buf);
    for _ in 0..3 {
        w.push(&Op::Identify).unwrap();
    }
    assert_eq!(w.finish(), Err(Error::TooLong));
    // Serial reads add up as well: 2 × (2 + 14) = 32.
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let mut w = BatchWriter::new(&mut buf);
    let p = Port::sensor(4).unwrap();
    w.push(&Op::SerialRead(p, 14)).unwrap();
    w.push(&Op::SerialRead(p, 14)).unwrap();
    assert_eq!(w.finish(), Err(Error::TooLong));
}

#[test]
fn batch_data_too_long() {
    let high = Op::DigitalWrite(Port::actuator(1).unwrap().pin(Pin::B), Level::High);
    let mut buf = [0u8; 64];
    let mut w = BatchWriter::new(&mut buf);
    // 9 items of 3 bytes fill 27 of the 28 data bytes.
    for _ in 0..9 {
        w.push(&high).unwrap();
    }
    assert_eq!(w.push(&high), Err(Error::TooLong));
    let b = w.finish().unwrap();
    assert_eq!(b.len(), 9);
    assert_eq!(b.as_bytes().len(), 27);
    // A caller's buffer that is too small.
    let mut small = [0u8; 4];
    let mut w = BatchWriter::new(&mut small);
    w.push(&high).unwrap();
    assert_eq!(w.push(&high), Err(Error::BufferTooShort));
    // An invalid item is refused with its own error.
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let mut w = BatchWriter::new(&mut buf);
    assert_eq!(
        w.push(&Op::PwmDuty(Port::sensor(1).unwrap().pin(Pin::A), 3)),
        Err(Error::WrongPortKind)
    );
    // An empty writer finishes into an error, not an empty batch.
    let mut buf = [0u8; MAX_REQUEST_DATA];
    assert_eq!(BatchWriter::new(&mut buf).finish(), Err(Error::BadLength));
}

#[test]
fn data_too_long() {
    // A request frame over MAX_REQUEST_LEN bytes.
    let mut long = vec![0x40, 0x09, 0x86, 0x01];
    long.resize(MAX_REQUEST_LEN + 1, b'x');
    assert_eq!(parse_err(&long), Error::TooLong);
    assert_eq!(Error::TooLong.status(), Status::BadLength);
    // Exactly MAX_REQUEST_LEN is fine.
    assert!(Request::parse(&long[..MAX_REQUEST_LEN]).is_ok());
    // Emitting a serial write with more data than any board accepts.
    let data = [b'x'; MAX_REQUEST_DATA + 1];
    let r = Request {
        db: Address::new(0x09).unwrap(),
        seq: 1,
        op: Op::SerialWrite(Port::sensor(4).unwrap(), &data),
    };
    assert_eq!(r.op.validate(), Err(Error::TooLong));
    let mut buf = [0u8; 64];
    assert_eq!(r.emit(&mut buf), Err(Error::TooLong));
    assert_eq!(r.emit_with_pec(&mut buf), Err(Error::TooLong));
    assert_eq!(r.emit(&mut [0u8; 4]), Err(Error::TooLong));
    // Replies and events: declared or given payload over MAX_PAYLOAD.
    let payload = [0u8; MAX_PAYLOAD + 1];
    let reply = Reply {
        seq: 1,
        status: Status::Ok,
        payload: &payload,
    };
    assert_eq!(reply.emit(&mut buf), Err(Error::TooLong));
    let mut frame = vec![0x01, 0x00, MAX_PAYLOAD as u8 + 1];
    frame.extend_from_slice(&payload);
    assert_eq!(Reply::parse(&frame), Err(Error::TooLong));
    let event = Event {
        source: Address::new(0x09).unwrap(),
        kind: EventKind::PinChange,
        pin: Port::sensor(1).unwrap().pin(Pin::A),
        seq: 0,
        status: Status::Ok,
        payload: &payload,
    };
    assert_eq!(event.emit(&mut buf), Err(Error::TooLong));
    let mut frame = vec![0x09, 0x01, 0x80, 0x00, 0x00, MAX_PAYLOAD as u8 + 1];
    frame.extend_from_slice(&payload);
    assert_eq!(Event::parse(&frame), Err(Error::TooLong));
    // Scan results over 8 ports.
    let scan = ScanResult {
        ports: 9,
        ..ScanResult::default()
    };
    assert_eq!(scan.emit(&mut buf), Err(Error::TooLong));
    let mut payload = vec![9, 0, 0];
    payload.extend_from_slice(&[0; 18]);
    assert_eq!(ScanResult::parse(&payload), Err(Error::TooLong));
}

#[test]
fn event_config_errors() {
    assert_eq!(
        EventConfig::parse(&[0x08, 0, 0, 0, 0]),
        Err(Error::BadArgument)
    );
    assert_eq!(
        EventConfig::parse(&[0x80, 0, 0, 0, 0]),
        Err(Error::BadArgument)
    );
    assert_eq!(
        EventConfig::parse(&[0x04, 1, 0, 0, 0]),
        Err(Error::BadArgument)
    );
    assert_eq!(
        EventConfig::parse(&[0x04, 1, 0, 1, 0]).map(|c| c.low),
        Ok(1)
    );
    assert_eq!(EventConfig::parse(&[]), Err(Error::BadLength));
}

#[test]
fn error_status_table() {
    let table = [
        (Error::Truncated, Status::BadLength),
        (Error::BadLength, Status::BadLength),
        (Error::BufferTooShort, Status::BadLength),
        (Error::TooLong, Status::BadLength),
        (Error::UnknownFunction(9), Status::UnknownFunction),
        (
            Error::UnknownOperand {
                function: 1,
                operand: 9,
            },
            Status::UnknownOperand,
        ),
        (Error::BadAddress(3), Status::WrongAddress),
        (Error::BadPort(0), Status::PortOutOfRange),
        (Error::WrongPortKind, Status::WrongPortKind),
        (Error::BadArgument, Status::BadArgument),
        (Error::NestedBatch, Status::BadArgument),
        (
            Error::PecMismatch {
                received: 1,
                computed: 2,
            },
            Status::PecMismatch,
        ),
    ];
    for (e, s) in table {
        assert_eq!(e.status(), s, "{e:?}");
        assert!(!s.is_ok());
    }
    // Messages for people.
    assert_eq!(
        Error::UnknownOperand {
            function: 1,
            operand: 9
        }
        .to_string(),
        "unknown operand 0x9 of function 0x1"
    );
    assert_eq!(
        Error::BadAddress(3).to_string(),
        "bad daughterboard address 0x03"
    );
    assert_eq!(
        Error::PecMismatch {
            received: 0x9d,
            computed: 0x9c
        }
        .to_string(),
        "PEC mismatch: received 0x9d, computed 0x9c"
    );
}

#[test]
fn status_codes() {
    let names = [
        "ok",
        "pending",
        "bad_length",
        "unknown_function",
        "unknown_operand",
        "port_out_of_range",
        "wrong_port_kind",
        "wrong_address",
        "pec_mismatch",
        "bad_argument",
        "unsupported",
        "busy",
        "timeout",
        "no_request",
        "unknown",
        "unknown",
        "wrong_kind",
        "too_large",
        "bad_crc",
        "out_of_order",
        "too_old",
        "flash_error",
        "no_session",
        "incomplete",
    ];
    for (code, name) in names.iter().enumerate() {
        if *name == "unknown" {
            continue;
        }
        let s = Status::from_byte(code as u8);
        assert_eq!(s.name(), *name);
        assert_eq!(s.to_byte(), code as u8);
        assert_eq!(Status::from_name(name), Some(s));
        assert_eq!(s.to_string(), *name);
        assert_eq!(s.is_ok(), code == 0);
    }
    for b in (0x0eu8..=0x0f).chain(0x18..=0xff) {
        let s = Status::from(b);
        assert_eq!(s, Status::Unknown(b));
        assert_eq!(s.to_byte(), b);
        assert_eq!(s.name(), "unknown");
    }
    assert_eq!(Status::Unknown(0x42).to_string(), "unknown(0x42)");
    assert_eq!(Status::from_name("unknown"), None);
    assert_eq!(Status::from_name("nope"), None);
}

#[test]
fn event_kind_codes() {
    let names = [
        "pin_change",
        "analog_threshold",
        "deferred_reply",
        "failsafe_tripped",
        "rejected",
        "overflow",
        "boot",
        "announce",
    ];
    for (i, name) in names.iter().enumerate() {
        let code = i as u8 + 1;
        let k = EventKind::from_byte(code);
        assert_eq!(k.name(), *name);
        assert_eq!(k.to_byte(), code);
        assert_eq!(EventKind::from_name(name), Some(k));
        assert_eq!(k.to_string(), *name);
    }
    for b in std::iter::once(0u8).chain(9..=0xff) {
        assert_eq!(EventKind::from_byte(b), EventKind::Unknown(b));
        assert_eq!(EventKind::Unknown(b).to_byte(), b);
    }
    assert_eq!(EventKind::Unknown(0x20).to_string(), "unknown(0x20)");
    assert_eq!(EventKind::from_name("unknown"), None);
}

/// Issue 22 item 14: a `scan` reply whose LEN byte is misread (0x0d -> 0x09, one bit) while
/// a payload byte happens to be the PEC byte of the shorter frame. The check of a reply whose
/// length varies is always a CRC-16, found where the LEN byte puts it: the misread reply is
/// refused (before: accepted as a 5-port scan of 9 bytes, a 1-in-256 chance per misread LEN).
#[test]
fn a_misread_len_byte_cannot_move_the_check_of_a_scan_reply() {
    use x10_microcode::{pec, Address, Op, Reply, ReplyFrame, Status};
    let db = Address::new(9).unwrap();
    let payload = [5u8, 0x55, 0x01, 1, 0, 2, 0, 3, 0, 4, 0, 5, 0];
    let mut genuine = vec![0x21, 0x00, payload.len() as u8];
    genuine.extend_from_slice(&payload);
    let n = genuine.len();
    genuine.resize(n + 2, 0);
    pec::append16(db.addr_byte(true), &mut genuine, n).unwrap();
    let mut read = genuine.clone();
    read.resize(3 + 19 + 2, 0xFF);
    let r = Reply::parse_read_for(db, true, &read, &Op::Scan).unwrap();
    assert_eq!(
        (r.seq, r.status, r.payload),
        (0x21, Status::Ok, &payload[..])
    );
    // The LEN byte misread as 9, and the byte after the 9th payload byte equal to the PEC
    // byte of that 12-byte frame: the old, length-based check would have passed.
    let mut bad = read.clone();
    bad[2] = 0x09;
    bad[12] = pec::compute(db.addr_byte(true), &bad[..12]);
    assert!(ReplyFrame::new_checked(&bad[..12]).is_ok());
    assert!(pec::strip(db.addr_byte(true), &bad[..13]).is_ok());
    assert!(Reply::parse_read_for(db, true, &bad, &Op::Scan).is_err());
    // A status-only reply with a PEC byte (a board that could not parse the request) is
    // still read, but never as `ok`.
    let mut refused = vec![0x21, Status::BadLength.to_byte(), 0x00];
    refused.push(pec::compute(db.addr_byte(true), &refused));
    refused.resize(24, 0xFF);
    let r = Reply::parse_read_for(db, true, &refused, &Op::Scan).unwrap();
    assert_eq!(r.status, Status::BadLength);
    let mut ok_alone = vec![0x21, 0x00, 0x00];
    ok_alone.push(pec::compute(db.addr_byte(true), &ok_alone));
    ok_alone.resize(24, 0xFF);
    assert!(Reply::parse_read_for(db, true, &ok_alone, &Op::Scan).is_err());
}
