//! Plug and play on the daughterboard (issue 24): the unaddressed state takes nothing but an
//! `assign` with a valid check and the board's own ID, drives nothing, announces itself with
//! ID-seeded delays; `set_address` keeps the new address before answering and moves once the
//! reply has been read; `who_is_there` queues an `announce`; `blink` without an LED is
//! `unsupported`; the start address follows override, record, unaddressed.

mod common;

use std::cell::RefCell;
use std::future::Future;
use std::rc::Rc;

use common::{run, BusOp, FakeBus, FakePorts, TestClock, Txn};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{
    start_address, AddressRecord, Daughterboard, DbConfig, NoRecord, StoreError, TargetConfig,
    ANNOUNCE_MIN_US, ANNOUNCE_WINDOW_US,
};
use x10_hal::time::Clock;
use x10_microcode::{pec, Address, BoardKind, EventKind, Op, Request, Status, Uid};

const UID: Uid = Uid([0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a]);
const OTHER: Uid = Uid([0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2b]);

/// A record that remembers every store (shared, so the test sees it after the board has it).
#[derive(Clone, Default)]
struct TestRecord {
    stores: Rc<RefCell<Vec<Address>>>,
    fail: bool,
}

impl AddressRecord for TestRecord {
    fn load(&mut self) -> Option<Address> {
        self.stores.borrow().last().copied()
    }

    fn store(&mut self, address: Address) -> Result<(), StoreError> {
        if self.fail {
            return Err(StoreError::Failed);
        }
        self.stores.borrow_mut().push(address);
        Ok(())
    }
}

type Db = Daughterboard<NoopRawMutex, FakePorts, TestRecord>;

fn board(address: Address, uid: Uid, record: TestRecord) -> (TestClock, Db) {
    let clock = TestClock::new();
    let mut cfg = DbConfig::new(address, BoardKind::SIMULATED);
    cfg.uid = uid;
    let db = Daughterboard::with_record(FakePorts::new(clock.clone(), 2, 2), cfg, record);
    (clock, db)
}

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

/// The `assign` frame for `uid` → `to`, with its check (as the MB sends it).
fn assign(uid: Uid, to: u8) -> Vec<u8> {
    let r = Request {
        db: Address::UNADDRESSED,
        seq: 1,
        op: Op::Assign {
            uid,
            address: addr(to),
        },
    };
    let mut buf = [0u8; 40];
    let n = r.emit_with_pec(&mut buf).unwrap();
    buf[..n].to_vec()
}

fn read(db: &Db) -> Vec<u8> {
    let mut buf = [0u8; 40];
    let n = db.take_reply(&mut buf);
    buf[..n].to_vec()
}

/// True when the board has decided to move (its `moved()` future is ready): the address.
fn moved(db: &Db) -> Option<Address> {
    let mut f = core::pin::pin!(db.moved());
    let waker = std::task::Waker::noop();
    match f.as_mut().poll(&mut std::task::Context::from_waker(waker)) {
        std::task::Poll::Ready(a) => Some(a),
        std::task::Poll::Pending => None,
    }
}

#[test]
fn the_exact_assign_frame_of_the_protocol_doc() {
    assert_eq!(
        assign(UID, 0x2a),
        [0x08, 0x77, 0x00, 0x01, 0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a, 0x2a, 0x4f]
    );
}

#[test]
fn an_unaddressed_board_takes_only_a_checked_assign_with_its_own_id() {
    let record = TestRecord::default();
    let (_clock, db) = board(Address::UNADDRESSED, UID, record.clone());
    assert!(db.is_unaddressed());
    // Another board's assign: ignored, no error.
    db.handle_write(&assign(OTHER, 0x20), false);
    // Its own, with a wrong check, or without one: refused.
    let mut bad = assign(UID, 0x20);
    *bad.last_mut().unwrap() ^= 0x01;
    db.handle_write(&bad, false);
    let unchecked = &assign(UID, 0x20)[..13];
    db.handle_write(unchecked, false);
    // An address it may not take: refused.
    let mut reserved = assign(UID, 0x20)[..13].to_vec();
    reserved[12] = 0x77;
    let n = reserved.len();
    reserved.push(0);
    pec::append(0x77 << 1, &mut reserved, n).unwrap();
    db.handle_write(&reserved, false);
    // Anything else to 0x77, checked: refused, and nothing is driven.
    for op in [
        Op::Ping,
        Op::DigitalWrite(
            x10_microcode::Port::actuator(1)
                .unwrap()
                .pin(x10_microcode::Pin::A),
            x10_microcode::Level::High,
        ),
    ] {
        let r = Request {
            db: Address::UNADDRESSED,
            seq: 2,
            op,
        };
        let mut buf = [0u8; 40];
        let n = r.emit_with_pec(&mut buf).unwrap();
        db.handle_write(&buf[..n], true);
    }
    db.served();
    assert!(record.stores.borrow().is_empty());
    assert_eq!(moved(&db), None);
    assert!(db.ports().take_log().is_empty());
    // No reply is held at 0x77 and nothing is reported from there.
    assert_eq!(db.events_queued(), 0);
    let d = db.diagnostics();
    assert_eq!((d.pec_errors, d.other_errors, d.bad_length), (2, 3, 0));
    // Its own, checked: kept, then it moves.
    db.handle_write(&assign(UID, 0x20), false);
    assert_eq!(*record.stores.borrow(), vec![addr(0x20)]);
    db.served();
    assert_eq!(moved(&db), Some(addr(0x20)));
    assert_eq!(db.events_queued(), 0);
}

#[test]
fn set_address_keeps_then_answers_then_moves() {
    let record = TestRecord::default();
    let (_clock, db) = board(addr(9), UID, record.clone());
    db.handle_write(&[0x09, 0x09, 0x00, 0x05, 0x20], true);
    // Kept before the answer; no move while the reply is held.
    assert_eq!(*record.stores.borrow(), vec![addr(0x20)]);
    db.served();
    assert_eq!(moved(&db), None);
    assert_eq!(read(&db), [0x05, 0x00, 0x00]);
    db.served();
    assert_eq!(moved(&db), Some(addr(0x20)));
    // Out of range: refused, nothing kept.
    let (_c, db) = board(addr(9), UID, record.clone());
    db.handle_write(&[0x09, 0x09, 0x00, 0x06, 0x77], true);
    assert_eq!(read(&db), [0x06, 0x09, 0x00]);
    assert_eq!(record.stores.borrow().len(), 1);
    // A record that cannot be written: busy, and the board stays.
    let failing = TestRecord {
        fail: true,
        ..TestRecord::default()
    };
    let (_c, db) = board(addr(9), UID, failing);
    db.handle_write(&[0x09, 0x09, 0x00, 0x07, 0x20], true);
    assert_eq!(read(&db), [0x07, 0x0b, 0x00]);
    db.served();
    assert_eq!(moved(&db), None);
}

#[test]
fn a_board_without_a_record_refuses_set_address_and_blink_without_an_led() {
    let clock = TestClock::new();
    let db: Daughterboard<NoopRawMutex, FakePorts> = Daughterboard::new(
        FakePorts::new(clock, 2, 2),
        DbConfig::new(addr(9), BoardKind::SIMULATED),
    );
    db.handle_write(&[0x09, 0x09, 0x00, 0x05, 0x20], true);
    let mut buf = [0u8; 40];
    let n = db.take_reply(&mut buf);
    assert_eq!(buf[..n], [0x05, 0x0a, 0x00]);
    db.handle_write(&[0x0a, 0x09, 0x00, 0x06, 0x03], true);
    let n = db.take_reply(&mut buf);
    assert_eq!(buf[..n], [0x06, 0x0a, 0x00]);
    // As an output (no read): a `rejected` event says so.
    db.handle_write(&[0x0a, 0x09, 0x00, 0x07, 0x03], false);
    let ev = db.try_next_event().unwrap();
    assert_eq!(
        (ev.kind, ev.seq, ev.status),
        (EventKind::Rejected, 7, Status::Unsupported)
    );
}

#[test]
fn who_is_there_queues_an_announce_from_the_board_s_address_with_or_without_pec() {
    let (_clock, db) = board(addr(9), UID, TestRecord::default());
    db.handle_write(&[0x0b, 0x09, 0x00, 0x03], false);
    let ev = db.try_next_event().unwrap();
    let mut buf = [0u8; 40];
    let n = db.encode_event(&ev, addr(8), &mut buf);
    // The doc's example: from 9, event counter 0 here, with the ID and a CRC-16.
    let mut want = vec![0x09, 0x08, 0x00, 0x00, 0x00, 0x13];
    want.extend_from_slice(&db.identity().to_bytes());
    want.push(0);
    want.extend_from_slice(&UID.0);
    let len = want.len();
    want.resize(len + 2, 0);
    pec::append(8 << 1, &mut want, len).unwrap();
    assert_eq!(buf[..n], want[..]);
    // With PEC on, it is taken without its check too (the sweep cannot know), and with it.
    db.handle_write(&[0x07, 0x09, 0x00, 0x04, 0x01], true);
    assert!(db.pec_enabled());
    read(&db);
    db.handle_write(&[0x0b, 0x09, 0x00, 0x05], false);
    let mut checked = vec![0x0b, 0x09, 0x00, 0x06, 0];
    pec::append(9 << 1, &mut checked, 4).unwrap();
    db.handle_write(&checked, false);
    let kinds: Vec<EventKind> = std::iter::from_fn(|| db.try_next_event())
        .map(|e| e.kind)
        .collect();
    assert_eq!(kinds, vec![EventKind::Announce, EventKind::Announce]);
}

#[test]
fn start_address_is_the_override_else_the_record_else_unaddressed() {
    let kept = TestRecord::default();
    kept.stores.borrow_mut().push(addr(0x30));
    assert_eq!(
        start_address(Some(addr(0x11)), &mut kept.clone()),
        addr(0x11)
    );
    assert_eq!(start_address(None, &mut kept.clone()), addr(0x30));
    assert_eq!(
        start_address(None, &mut TestRecord::default()),
        Address::UNADDRESSED
    );
    assert_eq!(start_address(None, &mut NoRecord), Address::UNADDRESSED);
    // A kept value that is no address a board may have is ignored.
    let odd = TestRecord::default();
    odd.stores.borrow_mut().push(Address::UNADDRESSED);
    assert_eq!(start_address(None, &mut odd.clone()), Address::UNADDRESSED);
    assert_eq!(NoRecord.store(addr(0x20)), Err(StoreError::NoRecord));
}

/// When an unaddressed board with ID `uid`, run on the bus ([`firmware_db::run`]), writes its
/// announces to the MB (µs), until `assign_at_us`, when the MB's `assign` for it arrives; and
/// the address it then moves to.
fn announces_then_assign(uid: Uid, assign_at_us: u64) -> (Vec<u64>, Address) {
    let (clock, db) = board(Address::UNADDRESSED, uid, TestRecord::default());
    let bus = FakeBus::new(clock.clone());
    let mb = addr(8);
    let b = bus.clone();
    let c = clock.clone();
    let mb_side = async move {
        c.sleep_until(x10_hal::time::Instant(assign_at_us)).await;
        b.push(Txn::Write(assign(uid, 0x20)));
        core::future::pending::<()>().await
    };
    let moved_to = run(
        &clock,
        embassy_futures::select::select3(
            firmware_db::run(&db, bus.clone(), &clock, TargetConfig::new(mb)),
            db.moved(),
            mb_side,
        ),
    );
    let to = match moved_to {
        embassy_futures::select::Either3::Second(a) => a,
        _ => panic!("the board did not move"),
    };
    assert_eq!(clock.now_us(), assign_at_us);
    let mut times = Vec::new();
    for (t, op) in bus.ops() {
        let BusOp::Write(8, bytes) = op else {
            panic!("{op:?}")
        };
        // An announce from 0x77 with the ID, checked.
        assert_eq!(&bytes[..3], &[0x77, 0x08, 0x00]);
        assert_eq!(&bytes[17..25], &uid.0);
        assert_eq!(bytes.len(), 27);
        times.push(t);
    }
    // It drove nothing but the safe state of its ports at boot.
    assert_eq!(db.ports().take_log().len(), 8);
    (times, to)
}

#[test]
fn announces_repeat_after_id_seeded_delays_until_assigned() {
    let (a, to) = announces_then_assign(UID, 2_000_000);
    assert_eq!(to, addr(0x20));
    let (b, _) = announces_then_assign(OTHER, 2_000_000);
    // The first at boot, then one every ANNOUNCE_MIN + a random part below ANNOUNCE_WINDOW.
    assert_eq!(a[0], 0);
    assert_eq!(b[0], 0);
    for t in [&a, &b] {
        for w in t.windows(2) {
            let gap = w[1] - w[0];
            assert!(
                (ANNOUNCE_MIN_US..ANNOUNCE_MIN_US + u64::from(ANNOUNCE_WINDOW_US)).contains(&gap),
                "{gap}"
            );
        }
        assert!(t.len() >= 5 && t.len() <= 11, "{t:?}");
    }
    // The same board waits the same way every time; two boards differently.
    assert_eq!(a, announces_then_assign(UID, 2_000_000).0);
    assert_ne!(a[1..], b[1..]);
}
