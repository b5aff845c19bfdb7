//! Boards that act together, on one daughterboard (issue 27 items 3 and 4): a general-call
//! `sample` held as a sweep frame for a plain read; `stage` held, executed by `apply`, dropped
//! after 100 ms or by the failsafe; a general call with one flipped bit does nothing.

mod common;

use common::{run_until, FakePorts, PortOp, TestClock};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, OutEvent};
use x10_microcode::{pec, Address, BoardKind, EventKind, Level, Op, Pin, Port, Status};

type Db = Daughterboard<NoopRawMutex, FakePorts>;

const DB: u8 = 9;

fn board(clock: &TestClock) -> Db {
    let cfg = DbConfig::new(Address::external(DB).unwrap(), BoardKind::SIMULATED);
    Daughterboard::new(FakePorts::new(clock.clone(), 2, 2), cfg)
}

fn events(db: &Db) -> Vec<OutEvent> {
    std::iter::from_fn(|| db.try_next_event()).collect()
}

fn take_reply(db: &Db) -> Vec<u8> {
    let mut buf = [0u8; 40];
    let n = db.take_reply(&mut buf);
    buf[..n].to_vec()
}

/// A general-call frame with its check over the address byte 0x00.
fn general(frame: &[u8]) -> Vec<u8> {
    let mut f = frame.to_vec();
    f.push(pec::compute(0x00, frame));
    f
}

/// A reply of board 9 with its PEC byte.
fn checked(frame: &[u8]) -> Vec<u8> {
    let mut f = frame.to_vec();
    f.push(pec::compute((DB << 1) | 1, frame));
    f
}

/// `stage` of duty 200 on A1.A and HIGH on A2.B.
const STAGE: [u8; 11] = [
    0x90, DB, 0x00, 0x07, 0x20, 0x00, 0x01, 200, 0x12, 0x03, 0x00,
];

fn a1a() -> x10_microcode::PinRef {
    Port::actuator(1).unwrap().pin(Pin::A)
}

fn a2b() -> x10_microcode::PinRef {
    Port::actuator(2).unwrap().pin(Pin::B)
}

#[test]
fn a_general_call_sample_is_held_for_a_plain_read() {
    let clock = TestClock::new();
    let db = board(&clock);
    let ports = db.ports();
    ports.analog.borrow_mut().insert(1, 0x123);
    ports.analog.borrow_mut().insert(2, 0xfed);
    ports.set_level(Port::sensor(2).unwrap().pin(Pin::A), true);
    db.handle_write(&general(&[0x80, 0x00, 0x00, 0x42]), false);
    assert!(events(&db).is_empty());
    // seq, ok, 5 bytes: levels 0b0100, 0x123 and 0xfed packed; a CRC-16 (PEC off).
    let read = take_reply(&db);
    assert_eq!(read.len(), x10_microcode::sweep::frame_len(2));
    assert_eq!(
        &read[..8],
        &[0x42, 0x00, 0x05, 0x04, 0x00, 0x23, 0xd1, 0xfe]
    );
    let db9 = Address::external(DB).unwrap();
    let r = x10_microcode::Reply::parse_read_for(db9, true, &read, &Op::Sample).unwrap();
    let v = x10_microcode::sweep::unpack(2, r.payload).unwrap();
    assert_eq!(v.digital, 0b0100);
    assert_eq!(&v.analog[..2], &[0x123, 0xfed]);
    // Given once: the next read finds nothing held.
    assert_eq!(take_reply(&db)[..3], [0, Status::NoRequest.to_byte(), 0]);
    // A value above 12 bits: `unsupported`, no values (the MB scans that board instead).
    ports.analog.borrow_mut().insert(1, 0x1000);
    db.handle_write(&general(&[0x80, 0x00, 0x00, 0x43]), false);
    let read = take_reply(&db);
    let r = x10_microcode::Reply::parse_read_for(db9, true, &read, &Op::Sample).unwrap();
    assert_eq!(
        (r.seq, r.status, r.payload),
        (0x43, Status::Unsupported, &[][..])
    );
}

#[test]
fn staged_outputs_change_only_at_the_apply_and_are_confirmed() {
    let clock = TestClock::new();
    let db = board(&clock);
    db.handle_write(&STAGE, true);
    // Read back like any output: ok, held; nothing driven.
    assert_eq!(take_reply(&db), [0x07, 0x00, 0x00]);
    assert!(db.ports().take_log().is_empty());
    db.handle_write(&general(&[0x81, 0x00, 0x00, 0x08]), false);
    assert_eq!(
        db.ports().take_log(),
        [
            PortOp::PwmDuty(a1a(), 200),
            PortOp::DigitalWrite(a2b(), Level::High)
        ]
    );
    // The confirmation for the MB's plain read: the apply's sequence number, ok, and (a
    // general call's reply) always its PEC byte.
    assert_eq!(take_reply(&db), checked(&[0x08, 0x00, 0x00]));
    // A second apply finds nothing held: it does nothing (and answers ok).
    db.handle_write(&general(&[0x81, 0x00, 0x00, 0x09]), false);
    assert!(db.ports().take_log().is_empty());
    assert_eq!(take_reply(&db), checked(&[0x09, 0x00, 0x00]));
    assert!(events(&db).is_empty());
}

#[test]
fn an_item_the_board_refuses_is_reported_by_the_apply_and_the_others_run() {
    let clock = TestClock::new();
    let db = board(&clock);
    // Duty on A3.A (the board has 2 actuator ports), then HIGH on A2.B.
    db.handle_write(
        &[
            0x90, DB, 0x00, 0x07, 0x20, 0x04, 0x01, 200, 0x12, 0x03, 0x00,
        ],
        true,
    );
    assert_eq!(take_reply(&db), [0x07, 0x00, 0x00]);
    db.handle_write(&general(&[0x81, 0x00, 0x00, 0x08]), false);
    assert_eq!(
        db.ports().take_log(),
        [PortOp::DigitalWrite(a2b(), Level::High)]
    );
    assert_eq!(
        take_reply(&db),
        checked(&[0x08, Status::PortOutOfRange.to_byte(), 0x00])
    );
}

#[test]
fn every_flipped_bit_of_an_apply_is_refused_and_moves_nothing() {
    let clock = TestClock::new();
    let db = board(&clock);
    let apply = general(&[0x81, 0x00, 0x00, 0x08]);
    let before = db.diagnostics();
    for bit in 0..apply.len() * 8 {
        db.handle_write(&STAGE, false);
        let mut f = apply.clone();
        f[bit / 8] ^= 1 << (bit % 8);
        db.handle_write(&f, false);
        assert!(db.ports().take_log().is_empty(), "bit {bit}");
    }
    // Each was refused: mostly its check; a flipped byte 1 makes it a frame for another
    // board (or this one, then with the wrong check): refused too, never executed.
    let d = db.diagnostics();
    assert_eq!(d.frames_ok - before.frames_ok, 40, "the 40 stages only");
    assert!(events(&db).iter().all(|e| e.kind == EventKind::Rejected));
}

#[test]
fn a_stage_without_apply_is_dropped_after_100_ms_counted_and_reported() {
    let clock = TestClock::new();
    let db = board(&clock);
    let bg = db.run_background(&clock);
    let mut bg = core::pin::pin!(bg);
    run_until(&clock, 1_000, bg.as_mut());
    let _ = events(&db);
    let _ = db.ports().take_log();
    db.handle_write(&STAGE, false);
    run_until(&clock, 100_999, bg.as_mut());
    assert!(events(&db).is_empty());
    run_until(&clock, 101_000, bg.as_mut());
    let evs = events(&db);
    assert_eq!(evs.len(), 1);
    assert_eq!(
        (evs[0].kind, evs[0].seq, evs[0].status),
        (EventKind::Rejected, 0x07, Status::Timeout)
    );
    assert_eq!(db.diagnostics().other_errors, 1);
    // Its apply, late, moves nothing.
    db.handle_write(&general(&[0x81, 0x00, 0x00, 0x08]), false);
    assert!(db.ports().take_log().is_empty());
}

#[test]
fn the_failsafe_drops_what_is_staged() {
    let clock = TestClock::new();
    let db = board(&clock);
    let bg = db.run_background(&clock);
    let mut bg = core::pin::pin!(bg);
    run_until(&clock, 1_000, bg.as_mut());
    // A 50 ms failsafe, then a stage; silence.
    db.handle_write(&[0x03, DB, 0x00, 0x01, 50, 0], false);
    db.handle_write(&STAGE, false);
    run_until(&clock, 51_000, bg.as_mut());
    assert_eq!(db.diagnostics().failsafe_trips, 1);
    let _ = db.ports().take_log();
    db.handle_write(&general(&[0x81, 0x00, 0x00, 0x08]), false);
    assert!(db.ports().take_log().is_empty());
    // Dropped by the failsafe, not counted as a timeout.
    run_until(&clock, 200_000, bg.as_mut());
    assert_eq!(db.diagnostics().other_errors, 0);
}

#[test]
fn an_unaddressed_board_ignores_general_calls() {
    let clock = TestClock::new();
    let cfg = DbConfig::new(Address::UNADDRESSED, BoardKind::SIMULATED);
    let db: Db = Daughterboard::new(FakePorts::new(clock.clone(), 2, 2), cfg);
    db.handle_write(&general(&[0x80, 0x00, 0x00, 0x01]), false);
    db.handle_write(&general(&[0x81, 0x00, 0x00, 0x02]), false);
    assert_eq!(db.diagnostics(), Default::default());
    assert!(db.ports().take_log().is_empty());
}
