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

/// The boot event as it goes on the bus: identity, reset reason (power-on), the board's ID
/// (all zero here), and always its check (a CRC-16: the frame is 25 bytes), whatever the
/// board's PEC setting.
fn boot_frame(db: &Db) -> Vec<u8> {
    let mut f = vec![0x09, 0x07, 0x00, 0x00, 0x00, 0x13];
    f.extend_from_slice(&db.identity().to_bytes());
    f.push(0x00);
    f.extend_from_slice(&[0; 8]);
    let n = f.len();
    f.resize(n + pec::check_len(n), 0);
    pec::append(MB << 1, &mut f, n).unwrap();
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
    // backoff after the timeout (counted): 100..150 µs; after the arbitration loss (never
    // counted): a random delay in [base/2, base/2 + base) = 50..150 µs
    let (t1, t2) = (ops[2].0, ops[3].0);
    assert!((100..150).contains(&t1), "{t1}");
    assert!((50..150).contains(&(t2 - t1)), "{}", t2 - t1);
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
fn forgiven_nacks_are_bounded_then_the_event_is_kept_not_dropped() {
    let (clock, db, bus, tcfg) = setup();
    // A single-role MB that NACKs every event while it polls us back to back: 16 forgiven
    // NACKs, then the 3 attempts of the policy, and the MB is taken for gone. The boot event
    // is kept, not dropped: the MB's next request (scripted with the last NACK) shows it is
    // back, and the event goes out right after it.
    let n = usize::from(firmware_db::MAX_EVENT_YIELDS) + 3;
    for i in 0..n {
        bus.script_addressed(
            BusError::Nack,
            Txn::WriteRead(vec![0x00, 0x09, 0x00, i as u8]),
        );
    }
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 10_000, fut.as_mut());
    let ops = bus.take_ops();
    let writes: Vec<(u64, &BusOp)> = ops
        .iter()
        .filter(|(_, op)| matches!(op, BusOp::Write(..)))
        .map(|(t, op)| (*t, op))
        .collect();
    // n failed attempts at the boot event, then its delivery; no other event (no overflow)
    let boot = BusOp::Write(MB, boot_frame(&db));
    assert_eq!(writes.len(), n + 1, "{ops:?}");
    assert!(writes.iter().all(|(_, op)| **op == boot), "{ops:?}");
    let t: Vec<u64> = writes.iter().map(|(t, _)| *t).collect();
    assert!(t[..=16].iter().all(|&t| t == 0), "{t:?}");
    // counted attempts wait out their backoff although we were addressed at once
    assert!((100..150).contains(&t[17]), "{t:?}");
    assert!((200..300).contains(&(t[18] - t[17])), "{t:?}");
    // the third counted NACK uses the attempts up; the request already waiting shows the MB
    // is there, and the kept event goes right after it is served
    assert_eq!(t[19], t[18], "{t:?}");
    assert_eq!(ops.last().unwrap(), &(t[19], boot));
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (1, n as u16, 0),
        "every write after the first is a retry; nothing dropped"
    );
    assert_eq!((d.arbitration_lost, d.frames_ok), (0, n as u16));
}

#[test]
fn arbitration_losses_never_use_up_attempts() {
    let (clock, db, bus, tcfg) = setup();
    // 40 arbitration losses in a row, nobody addressing us (another master floods the bus):
    // the policy allows 3 attempts, yet the event is never given up. Each retry waits a random
    // delay in [base/2, base/2 + window), the window doubling from base (100 µs) up to max
    // (1 ms).
    bus.script_writes(&[Err(BusError::ArbitrationLost); 40]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 100_000, fut.as_mut());
    let ops = bus.take_ops();
    let boot = BusOp::Write(MB, boot_frame(&db));
    assert_eq!(ops.len(), 41, "{ops:?}");
    assert!(ops.iter().all(|(_, op)| *op == boot), "{ops:?}");
    for (k, w) in ops.windows(2).enumerate() {
        let window = (100u64 << k.min(16)).min(1_000);
        let wait = w[1].0 - w[0].0;
        assert!(
            (50..50 + window).contains(&wait),
            "wait {wait} after loss {}",
            k + 1
        );
    }
    let d = db.diagnostics();
    assert_eq!(
        (
            d.events_sent,
            d.event_retries,
            d.arbitration_lost,
            d.events_dropped
        ),
        (1, 40, 40, 0)
    );
}

#[test]
fn an_undeliverable_event_is_kept_and_tried_every_100_ms_until_the_mb_is_back() {
    let (clock, db, bus, tcfg) = setup();
    // Three failed attempts at the boot event, then four failed slow retries.
    bus.script_writes(&[Err(BusError::Nack); 7]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 10_000, fut.as_mut());
    let ops = bus.take_ops();
    // three attempts at the boot event; then the MB is taken to be gone
    assert_eq!(ops.len(), 3, "{ops:?}");
    // the last attempt is followed by a listening wait of `base_us` (100 µs)
    let gone_at = ops[2].0 + 100;
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (0, 2, 0),
        "the event is kept: nothing dropped, no overflow report"
    );
    // A dead MB gets one write of the kept event (the boot event itself) every
    // MB_GONE_RETRY_US, no more.
    let boot = BusOp::Write(MB, boot_frame(&db));
    run_until(&clock, gone_at + 450_000, fut.as_mut());
    let expect: Vec<_> = (1..=4)
        .map(|k| (gone_at + k * MB_GONE_RETRY_US, boot.clone()))
        .collect();
    assert_eq!(bus.take_ops(), expect);
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (0, 6, 0)
    );
    // The MB is back without ever addressing the board: the fifth slow try is delivered, so
    // the MB learns of the boot after all, and the board is back to normal delivery.
    run_until(&clock, gone_at + 550_000, fut.as_mut());
    assert_eq!(
        bus.take_ops(),
        vec![(gone_at + 5 * MB_GONE_RETRY_US, boot.clone())]
    );
    let d = db.diagnostics();
    assert_eq!(
        (d.events_sent, d.event_retries, d.events_dropped),
        (1, 7, 0)
    );
    // a refused output (actuator port 5 of 2) gives a rejected event, sent at once (the pause
    // that paces events, 0.5..1.5 ms after the last delivery, is long over)
    bus.push(Txn::Write(vec![0x12, 0x09, 0x08, 0x02]));
    run_until(&clock, gone_at + 560_000, fut.as_mut());
    let ops = bus.take_ops();
    assert_eq!(ops.len(), 1, "{ops:?}");
    assert_eq!(ops[0].0, gone_at + 550_000);
    assert_eq!(
        ops[0].1,
        BusOp::Write(MB, vec![0x09, 0x05, 0x08, 0x02, 0x05, 0x00])
    );
    let d = db.diagnostics();
    assert_eq!((d.events_sent, d.events_dropped), (2, 0));
}

#[test]
fn a_board_that_took_the_mb_for_gone_delivers_as_soon_as_it_is_addressed() {
    let (clock, db, bus, tcfg) = setup();
    bus.script_writes(&[Err(BusError::Nack); 4]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 150_000, fut.as_mut());
    let ops = bus.take_ops();
    // three attempts at the boot event, one failed slow retry of it
    let boot = BusOp::Write(MB, boot_frame(&db));
    assert_eq!(ops.len(), 4, "{ops:?}");
    assert!(ops.iter().all(|(_, op)| *op == boot), "{ops:?}");
    assert_eq!(ops[3].0, ops[2].0 + 100 + MB_GONE_RETRY_US);
    // The MB is back (it sends a heartbeat): the kept boot event goes right after it.
    bus.push(Txn::Write(vec![0x02, 0x09, 0x00, 0x05]));
    run_until(&clock, 160_000, fut.as_mut());
    assert_eq!(bus.take_ops(), vec![(150_000, boot)]);
    let d = db.diagnostics();
    assert_eq!(
        (
            d.events_sent,
            d.event_retries,
            d.events_dropped,
            d.frames_ok
        ),
        (1, 4, 0, 1),
        "5 writes of one event: 4 retries; nothing dropped"
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
    run_until(&clock, 2_000, fut.as_mut());
    let ev = [0x09, 0x05, 0x08, 0x02, 0x05, 0x00];
    let mut with_pec = ev.to_vec();
    with_pec.push(pec::compute(MB << 1, &ev));
    let ops = bus.take_ops();
    assert_eq!(ops.len(), 1, "{ops:?}");
    assert_eq!(ops[0].1, BusOp::Write(MB, with_pec));
    // paced: 0.5..1.5 ms after the boot event (event_gap_us = 1 ms, randomized)
    assert!((500..1_500).contains(&ops[0].0), "{ops:?}");
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
fn the_boot_event_is_checked_before_and_after_the_mb_turned_pec_on() {
    let (clock, db, bus, tcfg) = setup();
    // The boot event's first attempt is NACKed; while the board waits to retry, the MB turns
    // PEC on. Both attempts carry the check (a CRC-16: the boot event is 25 bytes).
    bus.script_writes(&[Err(BusError::Nack)]);
    let fut = run(&db, bus.clone(), &clock, tcfg);
    let mut fut = core::pin::pin!(fut);
    run_until(&clock, 0, fut.as_mut());
    bus.push(Txn::Write(vec![0x07, 0x09, 0x00, 0x01, 0x01])); // set_pec(1)
    run_until(&clock, 10_000, fut.as_mut());
    let checked = boot_frame(&db);
    assert_eq!(checked.len(), 6 + 19 + 2);
    let writes: Vec<Vec<u8>> = bus
        .take_ops()
        .into_iter()
        .filter_map(|(_, op)| match op {
            BusOp::Write(MB, bytes) => Some(bytes),
            _ => None,
        })
        .collect();
    assert_eq!(writes, vec![checked.clone(), checked]);
    assert!(db.pec_enabled());
    assert_eq!(db.diagnostics().events_sent, 1);
}
