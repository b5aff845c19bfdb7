//! A daughterboard on a scripted bus: the listener and the event sender with retry/backoff.

mod common;

use common::{run_until, BusOp, FakeBus, FakePorts, TestClock, Txn};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{run, Daughterboard, DbConfig, TargetConfig, MB_GONE_RETRY_US};
use x10_hal::bus::BusError;
use x10_hal::retry::RetryPolicy;
use x10_microcode::{pec, Address, BoardKind, Diagnostics};

type Db = Daughterboard<NoopRawMutex, FakePorts>;

const MB: u8 = 0x08;

fn setup() -> (TestClock, Db, FakeBus, TargetConfig) {
    let clock = TestClock::new();
    let cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    let db = Daughterboard::new(FakePorts::new(clock.clone(), 2, 2), cfg);
    let bus = FakeBus::new(clock.clone());
    let mut tcfg = TargetConfig::new(Address::external(MB).unwrap());
    tcfg.retry = RetryPolicy {
        attempts: 3,
        base_us: 100,
        max_us: 1_000,
    };
    (clock, db, bus, tcfg)
}

fn boot_frame(db: &Db) -> Vec<u8> {
    let mut f = vec![0x09, 0x07, 0x00, 0x00, 0x00, 0x0A];
    f.extend_from_slice(&db.identity().to_bytes());
    f
}

#[test]
fn boot_event_is_written_to_the_mb_then_requests_are_served() {
    let (clock, db, bus, tcfg) = setup();
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 10, fut.as_mut());
    assert_eq!(bus.take_ops(), [(0, BusOp::Write(MB, boot_frame(&db)))]);
    bus.push(Txn::WriteRead(vec![0x00, 0x09, 0x00, 0x05]));
    bus.push(Txn::Write(vec![0x12, 0x09, 0x00, 0x06]));
    bus.push(Txn::Write(vec![0x10, 0x09, 0x80, 0x07]));
    bus.push(Txn::Read);
    bus.push(Txn::Read);
    run_until(&clock, 20, fut.as_mut());
    assert_eq!(
        bus.take_ops(),
        [
            (10, BusOp::Respond(vec![0x05, 0x00, 0x00])),
            (10, BusOp::Respond(vec![0x07, 0x00, 0x01, 0x00])),
            (10, BusOp::Respond(vec![0x00, 0x0D, 0x00])),
        ]
    );
    let d = db.diagnostics();
    assert_eq!((d.frames_ok, d.events_sent, d.no_request_reads), (3, 1, 1));
}

#[test]
fn events_are_retried_with_backoff_while_listening() {
    let (clock, db, bus, tcfg) = setup();
    // boot event: bus timeout, arbitration lost (nobody addresses us), then delivered
    bus.script_writes(&[Err(BusError::Timeout), Err(BusError::ArbitrationLost)]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 50, fut.as_mut());
    // during the first backoff the MB talks to us: we answer, and keep waiting
    bus.push(Txn::WriteRead(vec![0x00, 0x09, 0x00, 0x01]));
    run_until(&clock, 10_000, fut.as_mut());
    let ops = bus.take_ops();
    let frame = boot_frame(&db);
    assert_eq!(ops.len(), 4, "{ops:?}");
    assert_eq!(ops[0], (0, BusOp::Write(MB, frame.clone())));
    assert_eq!(ops[1], (50, BusOp::Respond(vec![0x01, 0x00, 0x00])));
    assert_eq!(ops[2].1, BusOp::Write(MB, frame.clone()));
    assert_eq!(ops[3].1, BusOp::Write(MB, frame));
    // backoff: first delay in 100..150 µs, second in 200..300 µs after the first retry
    let (t1, t2) = (ops[2].0, ops[3].0);
    assert!((100..150).contains(&t1), "{t1}");
    assert!((200..300).contains(&(t2 - t1)), "{}", t2 - t1);
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.arbitration_lost),
        (1, 2, 1)
    );
    assert_eq!(d.events_dropped, 0);
}

#[test]
fn an_attempt_lost_to_a_transaction_addressed_to_us_is_retried_at_once_and_not_counted() {
    let (clock, db, bus, tcfg) = setup();
    // The MB polls us back to back: each time the event is about to go out, the MB's next
    // request to us has the bus (the port gives up its waiting write: arbitration lost, or
    // a single-role MB NACKs). 3 attempts are allowed; 5 such failures must not drop it.
    let ping = |seq| Txn::WriteRead(vec![0x00, 0x09, 0x00, seq]);
    for seq in 1..=5 {
        let e = if seq == 3 {
            BusError::Nack
        } else {
            BusError::ArbitrationLost
        };
        bus.script_addressed(e, ping(seq));
    }
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 10_000, fut.as_mut());
    let frame = boot_frame(&db);
    let mut expected = Vec::new();
    for seq in 1..=5u8 {
        expected.push((0, BusOp::Write(MB, frame.clone())));
        expected.push((0, BusOp::Respond(vec![seq, 0x00, 0x00])));
    }
    // each retry right after serving the request, at the same instant: no backoff
    expected.push((0, BusOp::Write(MB, frame)));
    assert_eq!(bus.take_ops(), expected);
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.arbitration_lost),
        (1, 5, 4)
    );
    assert_eq!((d.events_dropped, d.frames_ok), (0, 5));
}

#[test]
fn forgiven_attempts_are_bounded_and_a_dropped_event_is_still_reported() {
    let (clock, db, bus, tcfg) = setup();
    // An MB that wins every arbitration while polling us: 16 forgiven attempts, then the
    // 3 attempts of the policy, then the event is dropped and reported.
    let n = usize::from(firmware_db::MAX_EVENT_YIELDS) + 3;
    for i in 0..n {
        bus.script_addressed(
            BusError::ArbitrationLost,
            Txn::WriteRead(vec![0x00, 0x09, 0x00, i as u8]),
        );
    }
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 10_000, fut.as_mut());
    let ops = bus.take_ops();
    let writes: Vec<u64> = ops
        .iter()
        .filter(|(_, op)| matches!(op, BusOp::Write(..)))
        .map(|(t, _)| *t)
        .collect();
    // n attempts at the boot event, then the overflow report
    assert_eq!(writes.len(), n + 1, "{ops:?}");
    assert!(writes[..=16].iter().all(|&t| t == 0), "{writes:?}");
    // counted attempts wait out their backoff although we were addressed at once
    assert!((100..150).contains(&writes[17]), "{writes:?}");
    assert!(
        (200..300).contains(&(writes[18] - writes[17])),
        "{writes:?}"
    );
    assert_eq!(
        ops.last().unwrap().1,
        BusOp::Write(
            MB,
            vec![0x09, 0x06, 0x00, 0x01, 0x00, 0x06, 0x01, 0x00, 0x01, 0x00, 0x00, 0x00]
        )
    );
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (1, n as u16 - 1, 1)
    );
}

#[test]
fn an_undeliverable_event_is_dropped_counted_and_reported() {
    let (clock, db, bus, tcfg) = setup();
    // Three failed attempts at the boot event, then four failed slow retries.
    bus.script_writes(&[Err(BusError::Nack); 7]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 10_000, fut.as_mut());
    let ops = bus.take_ops();
    // three attempts at the boot event; then the MB is taken to be gone
    assert_eq!(ops.len(), 3, "{ops:?}");
    // the last attempt is followed by a listening wait of `base_us` (100 µs), then the drop
    let gone_at = ops[2].0 + 100;
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (0, 2, 1)
    );
    // A dead MB gets one write of the head event (the overflow report: counter 1, one
    // dropped) every MB_GONE_RETRY_US, no more.
    let report = BusOp::Write(
        MB,
        vec![
            0x09, 0x06, 0x00, 0x01, 0x00, 0x06, 0x01, 0x00, 0x01, 0x00, 0x00, 0x00,
        ],
    );
    run_until(&clock, gone_at + 450_000, fut.as_mut());
    let expect: Vec<_> = (1..=4)
        .map(|k| (gone_at + k * MB_GONE_RETRY_US, report.clone()))
        .collect();
    assert_eq!(bus.take_ops(), expect);
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (0, 6, 1)
    );
    // The MB is back without ever addressing the board: the fifth slow try is delivered and
    // the board is back to normal delivery (a new event goes at once).
    run_until(&clock, gone_at + 550_000, fut.as_mut());
    assert_eq!(
        bus.take_ops(),
        vec![(gone_at + 5 * MB_GONE_RETRY_US, report.clone())]
    );
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (1, 7, 1)
    );
    // a refused output (actuator port 5 of 2) gives a rejected event, sent at once
    bus.push(Txn::Write(vec![0x12, 0x09, 0x08, 0x02]));
    run_until(&clock, gone_at + 560_000, fut.as_mut());
    let ops = bus.take_ops();
    assert_eq!(ops.len(), 1, "{ops:?}");
    assert_eq!(ops[0].0, gone_at + 550_000);
}

#[test]
fn a_board_that_took_the_mb_for_gone_delivers_as_soon_as_it_is_addressed() {
    let (clock, db, bus, tcfg) = setup();
    bus.script_writes(&[Err(BusError::Nack); 4]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 150_000, fut.as_mut());
    let ops = bus.take_ops();
    // three attempts at the boot event, one failed slow retry of the overflow report
    assert_eq!(ops.len(), 4, "{ops:?}");
    assert_eq!(ops[3].0, ops[2].0 + 100 + MB_GONE_RETRY_US);
    // The MB is back (it sends a heartbeat): the report goes right after it.
    bus.push(Txn::Write(vec![0x02, 0x09, 0x00, 0x05]));
    run_until(&clock, 160_000, fut.as_mut());
    assert_eq!(
        bus.take_ops(),
        vec![(
            150_000,
            BusOp::Write(
                MB,
                vec![0x09, 0x06, 0x00, 0x01, 0x00, 0x06, 0x01, 0x00, 0x01, 0x00, 0x00, 0x00]
            )
        )]
    );
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (1, 3, 1)
    );
}

#[test]
fn events_carry_pec_when_negotiated_and_overruns_count_as_bad_length() {
    let (clock, db, bus, tcfg) = setup();
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 0, fut.as_mut());
    bus.take_ops();
    bus.push(Txn::Write(vec![0x07, 0x09, 0x00, 0x01, 0x01])); // PEC on
                                                              // a refused output (actuator port 5 of 2), with PEC: a rejected event goes out with PEC
    let frame = [0x12, 0x09, 0x08, 0x02];
    let mut req = frame.to_vec();
    req.push(pec::compute(0x12, &frame));
    bus.push(Txn::Write(req));
    bus.push(Txn::Overrun);
    run_until(&clock, 100, fut.as_mut());
    let ev = [0x09, 0x05, 0x08, 0x02, 0x05, 0x00];
    let mut with_pec = ev.to_vec();
    with_pec.push(pec::compute(MB << 1, &ev));
    assert_eq!(bus.take_ops(), [(0, BusOp::Write(MB, with_pec))]);
    let d = db.diagnostics();
    let expect = Diagnostics {
        frames_ok: 1,
        port_errors: 1,
        bad_length: 1,
        events_sent: 2,
        ..Diagnostics::default()
    };
    assert_eq!(d, expect);
}

#[test]
fn an_event_retried_after_the_mb_turned_pec_on_goes_out_with_pec() {
    let (clock, db, bus, tcfg) = setup();
    // The boot event's first attempt is NACKed; while the board waits to retry, the MB turns
    // PEC on. The retry must carry the PEC byte the MB now expects.
    bus.script_writes(&[Err(BusError::Nack)]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 0, fut.as_mut());
    bus.push(Txn::Write(vec![0x07, 0x09, 0x00, 0x01, 0x01])); // set_pec(1)
    run_until(&clock, 10_000, fut.as_mut());
    let plain = boot_frame(&db);
    let mut with_pec = plain.clone();
    with_pec.push(pec::compute(MB << 1, &plain));
    let writes: Vec<Vec<u8>> = bus
        .take_ops()
        .into_iter()
        .filter_map(|(_, op)| match op {
            BusOp::Write(MB, bytes) => Some(bytes),
            _ => None,
        })
        .collect();
    assert_eq!(writes, vec![plain, with_pec]);
    assert!(db.pec_enabled());
    assert_eq!(db.diagnostics().events_sent, 1);
}
