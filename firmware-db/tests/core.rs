//! The interpreter: exact reply bytes for every function, every error status, PEC, batch,
//! scan, rejected outputs, diagnostics and event-queue overflow.

mod common;

use common::{FakePorts, PortOp, TestClock};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, OutEvent, EVENT_QUEUE_LEN};
use x10_microcode::test_support::{a, s};
use x10_microcode::{
    pec, Address, BoardKind, Capabilities, Diagnostics, EventConfig, EventKind, Level, PinRef,
    Port, Status,
};

type Db = Daughterboard<NoopRawMutex, FakePorts>;

fn board() -> Db {
    let clock = TestClock::new();
    let cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    Daughterboard::new(FakePorts::new(clock, 2, 2), cfg)
}

/// A write-then-read: the request, then the reply bytes.
fn exchange(db: &Db, request: &[u8]) -> Vec<u8> {
    db.handle_write(request, true);
    read(db)
}

/// A plain write (no read follows).
fn write(db: &Db, request: &[u8]) {
    db.handle_write(request, false);
}

fn read(db: &Db) -> Vec<u8> {
    let mut buf = [0u8; 40];
    let n = db.take_reply(&mut buf);
    buf[..n].to_vec()
}

fn events(db: &Db) -> Vec<OutEvent> {
    std::iter::from_fn(|| db.try_next_event()).collect()
}

fn pin(p: Port, b: bool) -> PinRef {
    p.pin(if b {
        x10_microcode::Pin::B
    } else {
        x10_microcode::Pin::A
    })
}

#[test]
fn ping_replies_ok_with_the_sequence_number() {
    let db = board();
    assert_eq!(exchange(&db, &[0x00, 0x09, 0x00, 0x05]), [0x05, 0x00, 0x00]);
    assert_eq!(db.diagnostics().frames_ok, 1);
}

#[test]
fn identify_reports_protocol_firmware_board_ports_capabilities_adc() {
    let db = board();
    assert_eq!(
        exchange(&db, &[0x01, 0x09, 0x00, 0x06]),
        [0x06, 0x00, 0x0A, 0x01, 0x00, 0x01, 0x00, 0x01, 0x02, 0x02, 0xFD, 0x01, 12]
    );
}

#[test]
fn digital_read_replies_the_level() {
    let db = board();
    db.ports().set_level(pin(s(1), false), true);
    assert_eq!(
        exchange(&db, &[0x10, 0x09, 0x80, 0x07]),
        [0x07, 0x00, 0x01, 0x01]
    );
    assert_eq!(
        exchange(&db, &[0x10, 0x09, 0x81, 0x08]),
        [0x08, 0x00, 0x01, 0x00]
    );
    assert_eq!(
        db.ports().take_log(),
        [
            PortOp::DigitalRead(pin(s(1), false)),
            PortOp::DigitalRead(pin(s(1), true))
        ]
    );
}

#[test]
fn analog_read_replies_u16_le() {
    let db = board();
    db.ports().analog.borrow_mut().insert(2, 0x0123);
    assert_eq!(
        exchange(&db, &[0x30, 0x09, 0x82, 0x08]),
        [0x08, 0x00, 0x02, 0x23, 0x01]
    );
    assert_eq!(db.ports().take_log(), [PortOp::AnalogRead(s(2))]);
}

#[test]
fn outputs_execute_and_hold_no_reply() {
    let db = board();
    write(&db, &[0x12, 0x09, 0x01, 0x02]); // digital HIGH, actuator 1 pin B
    write(&db, &[0x11, 0x09, 0x02, 0x03]); // digital LOW, actuator 2 pin A
    write(&db, &[0x20, 0x09, 0x02, 0x04, 200]); // PWM duty 200, actuator 2 pin A
    write(&db, &[0x21, 0x09, 0x00, 0x05, 0xE8, 0x03]); // PWM 1000 Hz, actuator 1
    write(&db, &[0x22, 0x09, 0x01, 0x06, 0xDC, 0x05]); // pulse width 1500 µs, actuator 1 pin B
    assert_eq!(
        db.ports().take_log(),
        [
            PortOp::DigitalWrite(pin(a(1), true), Level::High),
            PortOp::DigitalWrite(pin(a(2), false), Level::Low),
            PortOp::PwmDuty(pin(a(2), false), 200),
            PortOp::PwmFrequency(a(1), 1000),
            PortOp::PwmPulseWidth(pin(a(1), true), 1500),
        ]
    );
    // Nothing to read: the answer is no_request with sequence number 0.
    assert_eq!(read(&db), [0x00, 0x0D, 0x00]);
    let d = db.diagnostics();
    assert_eq!((d.frames_ok, d.no_request_reads), (5, 1));
    assert!(events(&db).is_empty());
}

#[test]
fn an_output_read_anyway_gets_a_status_reply() {
    let db = board();
    assert_eq!(exchange(&db, &[0x12, 0x09, 0x00, 0x21]), [0x21, 0x00, 0x00]);
}

#[test]
fn a_reply_is_held_until_read_and_given_once() {
    let db = board();
    write(&db, &[0x00, 0x09, 0x00, 0x31]); // ping as a plain write
    assert_eq!(read(&db), [0x31, 0x00, 0x00]);
    assert_eq!(read(&db), [0x00, 0x0D, 0x00]);
}

#[test]
fn system_functions_heartbeat_failsafe_events_diagnostics() {
    let db = board();
    write(&db, &[0x02, 0x09, 0x00, 0x01]); // heartbeat
    write(&db, &[0x03, 0x09, 0x00, 0x02, 0xF4, 0x01]); // failsafe 500 ms
    assert_eq!(db.failsafe_timeout_ms(), 500);
    write(&db, &[0x04, 0x09, 0x80, 0x03, 0x01, 0, 0, 0, 0]); // rising edges on S1.A
                                                             // read_diagnostics: the counters before this request (3 ok).
    let mut expect = vec![0x04, 0x00, Diagnostics::LEN as u8];
    let d = Diagnostics {
        frames_ok: 3,
        ..Diagnostics::default()
    };
    expect.extend_from_slice(&d.to_bytes());
    assert_eq!(exchange(&db, &[0x05, 0x09, 0x00, 0x04]), expect);
    // clear: everything zero, then the clear itself counts.
    write(&db, &[0x06, 0x09, 0x00, 0x05]);
    let d = Diagnostics {
        frames_ok: 1,
        ..Diagnostics::default()
    };
    assert_eq!(db.diagnostics(), d);
    assert!(events(&db).is_empty());
}

#[test]
fn pec_is_negotiated_and_then_checked_on_requests_and_added_to_replies() {
    let db = board();
    // set_pec(1): the request has no PEC (the old mode); its reply, when read, is sent in the
    // new mode, with PEC, so that the motherboard reading it knows PEC is on.
    assert_eq!(
        exchange(&db, &[0x07, 0x09, 0x00, 0x01, 0x01]),
        [0x01, 0x00, 0x00, pec::compute(0x13, &[0x01, 0x00, 0x00])]
    );
    assert!(db.pec_enabled());
    // Another set_pec(1) without PEC: refused with pec_mismatch, in the mode the board has.
    assert_eq!(
        exchange(&db, &[0x07, 0x09, 0x00, 0x07, 0x01]),
        [0x07, 0x08, 0x00, pec::compute(0x13, &[0x07, 0x08, 0x00])]
    );

    // ping with a correct PEC byte over (0x09 << 1, frame)
    let frame = [0x00, 0x09, 0x00, 0x02];
    let mut req = frame.to_vec();
    req.push(pec::compute(0x12, &frame));
    let reply = exchange(&db, &req);
    assert_eq!(reply[..3], [0x02, 0x00, 0x00]);
    assert_eq!(reply[3], pec::compute(0x13, &[0x02, 0x00, 0x00]));
    assert_eq!(reply.len(), 4);

    // a wrong PEC byte: pec_mismatch (the reply itself carries a correct PEC)
    let reply = exchange(&db, &[0x00, 0x09, 0x00, 0x03, 0x00]);
    assert_eq!(
        reply,
        [0x03, 0x08, 0x00, pec::compute(0x13, &[0x03, 0x08, 0x00])]
    );
    // a frame without PEC byte: the last byte is taken as PEC and does not match
    let reply = exchange(&db, &[0x00, 0x09, 0x00, 0x04]);
    assert_eq!(reply[1], 0x08);
    assert_eq!(db.diagnostics().pec_errors, 3);

    // no_request also carries PEC
    assert_eq!(
        read(&db),
        [0x00, 0x0D, 0x00, pec::compute(0x13, &[0x00, 0x0D, 0x00])]
    );

    // set_pec(0) with PEC, then plain frames again
    let frame = [0x07, 0x09, 0x00, 0x05, 0x00];
    let mut req = frame.to_vec();
    req.push(pec::compute(0x12, &frame));
    write(&db, &req);
    assert!(!db.pec_enabled());
    assert_eq!(exchange(&db, &[0x00, 0x09, 0x00, 0x06]), [0x06, 0x00, 0x00]);
    // set_pec(1) refused (a board without the PEC capability): its reply stays in the old
    // mode, without PEC.
    let plain = Daughterboard::new(
        FakePorts::new(TestClock::new(), 3, 2),
        DbConfig {
            capabilities: Capabilities(firmware_db::ALL_CAPABILITIES.0 & !Capabilities::PEC),
            ..DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED)
        },
    );
    assert_eq!(
        exchange(&plain, &[0x07, 0x09, 0x00, 0x08, 0x01]),
        [0x08, 0x0a, 0x00]
    );
    assert!(!plain.pec_enabled());
}

#[test]
fn every_error_status_has_its_reply() {
    let db = board();
    let cases: &[(&[u8], [u8; 3])] = &[
        (&[0x00, 0x09, 0x00], [0x00, 0x02, 0x00]), // truncated
        (&[0x00, 0x09, 0x00, 0x04, 0xAA], [0x04, 0x02, 0x00]), // ping with data
        (&[0xF0, 0x09, 0x00, 0x05], [0x05, 0x03, 0x00]), // unknown function 15
        (&[0x0E, 0x09, 0x00, 0x06], [0x06, 0x04, 0x00]), // unknown system operand 14
        (&[0x10, 0x09, 0x84, 0x07], [0x07, 0x05, 0x00]), // sensor port 3 of 2
        (&[0x12, 0x09, 0x04, 0x07], [0x07, 0x05, 0x00]), // actuator port 3 of 2
        (&[0x30, 0x09, 0x00, 0x08], [0x08, 0x06, 0x00]), // analog on an actuator port
        (&[0x00, 0x0A, 0x00, 0x09], [0x09, 0x07, 0x00]), // addressed to board 10
        (&[0x00, 0x09, 0x01, 0x0B], [0x0B, 0x09, 0x00]), // ping with a port byte
        (&[0x41, 0x09, 0x80, 0x0C, 0x04], [0x0C, 0x0A, 0x00]), // serial read: unsupported
    ];
    for (req, reply) in cases {
        assert_eq!(exchange(&db, req), reply, "request {req:02x?}");
    }
    let d = db.diagnostics();
    assert_eq!(
        (
            d.bad_length,
            d.unknown_function,
            d.unknown_operand,
            d.port_errors
        ),
        (2, 1, 1, 3)
    );
    assert_eq!((d.wrong_address, d.other_errors, d.frames_ok), (1, 2, 0));
}

#[test]
fn port_errors_map_to_statuses() {
    use firmware_db::PortError;
    let db = board();
    let p = pin(s(2), true);
    for (err, status) in [
        (PortError::NoSuchPin, 0x05),
        (PortError::Unsupported, 0x0A),
        (PortError::Busy, 0x0B),
        (PortError::Timeout, 0x0C),
    ] {
        db.ports().failing.borrow_mut().insert(p.to_byte(), err);
        assert_eq!(
            exchange(&db, &[0x10, 0x09, 0x83, 0x01]),
            [0x01, status, 0x00]
        );
    }
}

#[test]
fn refused_outputs_are_reported_by_rejected_events() {
    let db = board();
    write(&db, &[0x12, 0x09, 0x06, 0x41]); // HIGH on actuator port 4 of 2
    write(&db, &[0xF0, 0x09, 0x00, 0x42]); // unknown function
    write(&db, &[0x20, 0x09, 0x80, 0x43, 0x10]); // PWM on a sensor port
    write(&db, &[0x12]); // too short to have a sequence number
    let evs = events(&db);
    let got: Vec<(EventKind, u8, u8, Status)> = evs
        .iter()
        .map(|e| (e.kind, e.pin.to_byte(), e.seq, e.status))
        .collect();
    assert_eq!(
        got,
        [
            (EventKind::Rejected, 0x06, 0x41, Status::PortOutOfRange),
            (EventKind::Rejected, 0x00, 0x42, Status::UnknownFunction),
            (EventKind::Rejected, 0x80, 0x43, Status::WrongPortKind),
            (EventKind::Rejected, 0x00, 0x00, Status::BadLength),
        ]
    );
    // On the wire, from board 9 to the MB at 0x08:
    let mut buf = [0u8; 40];
    let n = db.encode_event(&evs[0], Address::external(8).unwrap(), &mut buf);
    assert_eq!(buf[..n], [0x09, 0x05, 0x06, 0x41, 0x05, 0x00]);
    // Nothing was executed.
    assert!(db.ports().take_log().is_empty());
}

#[test]
fn batch_executes_items_in_order_one_result_each() {
    let db = board();
    db.ports().set_level(pin(s(1), false), true);
    db.ports().analog.borrow_mut().insert(2, 0x0456);
    #[rustfmt::skip]
    let req = [
        0x50, 0x09, 0x00, 0x0E,
        0x10, 0x80, 0,       // digital read S1.A
        0x12, 0x00, 0,       // HIGH A1.A
        0x30, 0x82, 0,       // analog S2
        0x10, 0x90, 0,       // digital read S9.A: out of range
        0x20, 0x02, 1, 77,   // PWM 77 on A2.A
    ];
    assert_eq!(
        exchange(&db, &req),
        [0x0E, 0x00, 13, 0x00, 1, 1, 0x00, 0, 0x00, 2, 0x56, 0x04, 0x05, 0, 0x00, 0]
    );
    assert_eq!(
        db.ports().take_log(),
        [
            PortOp::DigitalRead(pin(s(1), false)),
            PortOp::DigitalWrite(pin(a(1), false), Level::High),
            PortOp::AnalogRead(s(2)),
            PortOp::PwmDuty(pin(a(2), false), 77),
        ]
    );
    let d = db.diagnostics();
    assert_eq!((d.frames_ok, d.port_errors), (1, 1));
    // a pulse-in inside a batch is refused by the parser
    assert_eq!(
        exchange(&db, &[0x50, 0x09, 0x00, 0x0F, 0x13, 0x80, 0]),
        [0x0F, 0x09, 0x00]
    );
}

#[test]
fn scan_reads_every_sensor_port() {
    let db = board();
    db.ports().set_level(pin(s(1), false), true);
    db.ports().set_level(pin(s(2), true), true);
    db.ports().analog.borrow_mut().insert(1, 0x0100);
    db.ports().analog.borrow_mut().insert(2, 0x0123);
    assert_eq!(
        exchange(&db, &[0x60, 0x09, 0x00, 0x10]),
        [0x10, 0x00, 7, 2, 0x09, 0x00, 0x00, 0x01, 0x23, 0x01]
    );
    // one failing pin fails the scan with its status
    db.ports()
        .failing
        .borrow_mut()
        .insert(pin(s(2), false).to_byte(), firmware_db::PortError::Busy);
    assert_eq!(exchange(&db, &[0x60, 0x09, 0x00, 0x11]), [0x11, 0x0B, 0x00]);
}

#[test]
fn capabilities_switched_off_answer_unsupported() {
    let clock = TestClock::new();
    let mut cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    cfg.capabilities = x10_microcode::Capabilities(0);
    let db: Db = Daughterboard::new(FakePorts::new(clock, 2, 2), cfg);
    assert_eq!(exchange(&db, &[0x60, 0x09, 0x00, 0x01]), [0x01, 0x0A, 0x00]); // scan
    assert_eq!(exchange(&db, &[0x13, 0x09, 0x80, 0x02]), [0x02, 0x0A, 0x00]); // pulse-in
    assert_eq!(
        exchange(&db, &[0x07, 0x09, 0x00, 0x03, 0x01]),
        [0x03, 0x0A, 0x00]
    ); // PEC on
    assert_eq!(
        exchange(&db, &[0x07, 0x09, 0x00, 0x04, 0x00]),
        [0x04, 0x00, 0x00]
    ); // PEC off is fine
    assert_eq!(exchange(&db, &[0x00, 0x09, 0x00, 0x05]), [0x05, 0x00, 0x00]); // ping
}

/// Each operation is checked for its capability first, then for its port: a board without
/// the capability answers `unsupported` whatever the port, one with it `port_out_of_range`
/// for a port it does not have (2 sensor and 2 actuator ports here).
#[test]
fn capability_before_port_and_every_port_operation_checks_its_port() {
    let clock = TestClock::new();
    let mut cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    cfg.capabilities = x10_microcode::Capabilities(0);
    let bare: Db = Daughterboard::new(FakePorts::new(clock, 2, 2), cfg);
    let db = board();
    // pulse-in on S3.A, PWM frequency 10 kHz on A3 (byte 2: bit 7 sensor, bits 1-6 the
    // port's index, bit 0 pin B)
    let pulse = [0x13, 0x09, 0x84, 0x01];
    let freq = [0x21, 0x09, 0x04, 0x02, 0x10, 0x27];
    assert_eq!(exchange(&bare, &pulse), [0x01, 0x0A, 0x00]);
    assert_eq!(exchange(&db, &pulse), [0x01, 0x05, 0x00]);
    assert_eq!(exchange(&bare, &freq), [0x02, 0x0A, 0x00]);
    assert_eq!(exchange(&db, &freq), [0x02, 0x05, 0x00]);
    // high on A3.A, analog read of S3, duty on A4.A, input on S4.B
    assert_eq!(exchange(&db, &[0x12, 0x09, 0x04, 0x03]), [0x03, 0x05, 0x00]);
    assert_eq!(exchange(&db, &[0x30, 0x09, 0x84, 0x04]), [0x04, 0x05, 0x00]);
    assert_eq!(
        exchange(&db, &[0x20, 0x09, 0x06, 0x05, 9]),
        [0x05, 0x05, 0x00]
    );
    assert_eq!(exchange(&db, &[0x10, 0x09, 0x87, 0x06]), [0x06, 0x05, 0x00]);
    // serial: no such port first, then unsupported (no serial on these boards)
    assert_eq!(
        exchange(&db, &[0x40, 0x09, 0x84, 0x07, 0x41]),
        [0x07, 0x05, 0x00]
    );
    assert_eq!(
        exchange(&db, &[0x40, 0x09, 0x80, 0x08, 0x41]),
        [0x08, 0x0A, 0x00]
    );
    // the ports it has work
    assert_eq!(exchange(&db, &[0x12, 0x09, 0x01, 0x09]), [0x09, 0x00, 0x00]);
    assert_eq!(
        exchange(&db, &[0x30, 0x09, 0x82, 0x0A]),
        [0x0A, 0x00, 0x02, 0, 0]
    );
}

#[test]
fn event_enable_checks_kind_and_capacity() {
    let db = board();
    // analog window on an actuator pin: wrong_port_kind
    assert_eq!(
        exchange(&db, &[0x04, 0x09, 0x00, 0x01, 0x04, 0, 0, 0xFF, 0]),
        [0x01, 0x06, 0x00]
    );
    // low > high: bad_argument from the parser
    assert_eq!(
        exchange(&db, &[0x04, 0x09, 0x80, 0x02, 0x04, 9, 0, 1, 0]),
        [0x02, 0x09, 0x00]
    );
    // 16 pins can be watched, the 17th is busy (2 sensor + 2 actuator ports: use a bigger board)
    let clock = TestClock::new();
    let cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    let big: Db = Daughterboard::new(FakePorts::new(clock, 9, 0), cfg);
    for i in 0..17u8 {
        let p = PinRef::from_byte(0x80 | i);
        let mut req = vec![0x04, 0x09, p.to_byte(), i];
        req.extend_from_slice(
            &EventConfig {
                rising: true,
                ..EventConfig::OFF
            }
            .to_bytes(),
        );
        let status = if i < 16 { 0x00 } else { 0x0B };
        assert_eq!(exchange(&big, &req), [i, status, 0x00]);
    }
    // switching one off makes room
    let mut req = vec![0x04, 0x09, 0x80, 0x20];
    req.extend_from_slice(&EventConfig::OFF.to_bytes());
    assert_eq!(exchange(&big, &req), [0x20, 0x00, 0x00]);
    let mut req = vec![0x04, 0x09, 0x90, 0x21];
    req.extend_from_slice(
        &EventConfig {
            falling: true,
            ..EventConfig::OFF
        }
        .to_bytes(),
    );
    assert_eq!(exchange(&big, &req), [0x21, 0x00, 0x00]);
}

#[test]
fn a_second_pulse_in_on_a_busy_pin_is_busy_and_the_queue_is_bounded() {
    let clock = TestClock::new();
    let cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    let db: Db = Daughterboard::new(FakePorts::new(clock, 9, 0), cfg);
    // nothing runs the workers here: the jobs stay queued
    assert_eq!(exchange(&db, &[0x13, 0x09, 0x80, 0x01]), [0x01, 0x01, 0x00]);
    assert_eq!(exchange(&db, &[0x14, 0x09, 0x80, 0x02]), [0x02, 0x0B, 0x00]);
    for (i, p) in [0x81u8, 0x82, 0x83].iter().enumerate() {
        let seq = 3 + i as u8;
        assert_eq!(exchange(&db, &[0x13, 0x09, *p, seq]), [seq, 0x01, 0x00]);
    }
    // 4 accepted: the fifth pin finds the queue full
    assert_eq!(exchange(&db, &[0x13, 0x09, 0x84, 0x09]), [0x09, 0x0B, 0x00]);
    let d = db.diagnostics();
    assert_eq!((d.frames_ok, d.other_errors), (4, 2));
}

#[test]
fn overflow_is_counted_and_reported_once_there_is_room() {
    let db = board();
    // fill the queue with rejected outputs (request seqs 0..), then two more are dropped
    for seq in 0..EVENT_QUEUE_LEN as u8 + 2 {
        write(&db, &[0x12, 0x09, 0x3E, seq]);
    }
    assert_eq!(db.events_queued(), EVENT_QUEUE_LEN);
    assert_eq!(db.diagnostics().events_dropped, 2);
    // taking one out makes room: the overflow report goes in behind the others
    let first = db.try_next_event().unwrap();
    assert_eq!((first.kind, first.seq), (EventKind::Rejected, 0));
    assert_eq!(db.events_queued(), EVENT_QUEUE_LEN);
    let rest = events(&db);
    assert_eq!(rest.len(), EVENT_QUEUE_LEN);
    let last = rest.last().unwrap();
    assert_eq!(last.kind, EventKind::Overflow);
    assert_eq!(
        last.seq, 0,
        "first event numbered by the board's own counter"
    );
    assert_eq!(
        last.payload[..],
        [2, 0, 2, 0, 0, 0],
        "2 since the last report, 2 since boot"
    );
    assert_eq!(rest[EVENT_QUEUE_LEN - 2].seq, EVENT_QUEUE_LEN as u8 - 1);
    assert_eq!(db.diagnostics().events_dropped, 2);
}

#[test]
fn drops_after_a_report_are_reported_again() {
    let db = board();
    for seq in 0..EVENT_QUEUE_LEN as u8 + 1 {
        write(&db, &[0x12, 0x09, 0x3E, seq]);
    }
    // taking one out queues the report of the first drop: the queue is full again
    let first = db.try_next_event().unwrap();
    assert_eq!(first.seq, 0);
    assert_eq!(db.events_queued(), EVENT_QUEUE_LEN);
    write(&db, &[0x12, 0x09, 0x3E, 0x80]); // no room: dropped and counted
    assert_eq!(db.diagnostics().events_dropped, 2);
    let rest = events(&db);
    let got: Vec<(EventKind, u8, Vec<u8>)> = rest
        .iter()
        .map(|e| (e.kind, e.seq, e.payload.to_vec()))
        .collect();
    let mut expect: Vec<(EventKind, u8, Vec<u8>)> = (1..EVENT_QUEUE_LEN as u8)
        .map(|s| (EventKind::Rejected, s, vec![]))
        .collect();
    expect.push((EventKind::Overflow, 0, vec![1, 0, 1, 0, 0, 0]));
    expect.push((EventKind::Overflow, 1, vec![1, 0, 2, 0, 0, 0]));
    assert_eq!(got, expect);
}
