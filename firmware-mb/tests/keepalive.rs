//! The failsafe keepalive: a board whose failsafe a program set hears a heartbeat whenever
//! nothing was sent to it for a third of the timeout; a stopped motherboard lets it trip.

mod common;

use common::{sim, Node, PortOp, Seen, World};
use embassy_futures::join::join;
use embassy_futures::select::select;
use firmware_db::SafeState;
use x10_hal::time::{Clock, Instant};
use x10_microcode::test_support::db9;
use x10_microcode::{Address, Level, Op, Pin, Port};

impl World {
    /// The writes to DB 9 (start time, bytes).
    fn writes_to_9(&self) -> Vec<(u64, Vec<u8>)> {
        self.bus
            .seen()
            .into_iter()
            .filter_map(|(t, s)| match s {
                Seen::Write(9, b) | Seen::WriteRead(9, b, _) => Some((t, b)),
                _ => None,
            })
            .collect()
    }
}

/// `set_failsafe` to DB 9 with sequence number `seq`.
fn set_failsafe(seq: u8, ms: u16) -> Vec<u8> {
    let [lo, hi] = ms.to_le_bytes();
    vec![0x03, 0x09, 0x00, seq, lo, hi]
}

/// `heartbeat` to DB 9 with sequence number `seq`.
fn heartbeat(seq: u8) -> Vec<u8> {
    vec![0x02, 0x09, 0x00, seq]
}

/// One transfer on the loopback bus takes 100 µs; the board hears it at its end.
const T: u64 = common::TRANSFER_US;

#[test]
fn a_failsafe_set_by_a_program_is_kept_alive_while_the_program_sends_nothing() {
    let w = World::new();
    w.sim(async {
        w.at(1_000).await;
        w.mb.call(db9(), Op::SetFailsafe { timeout_ms: 300 })
            .await
            .unwrap();
        // the program falls silent for a second
        w.at(1_001_000).await;
    });
    // A heartbeat whenever nothing was sent for 100 ms (a third of 300 ms), measured from
    // the end of the last transfer: at 1 000 + k · 100 100 µs.
    let mut expected = vec![(1_000, set_failsafe(0, 300))];
    for k in 1..=9u8 {
        expected.push((1_000 + u64::from(k) * (100_000 + T), heartbeat(k)));
    }
    assert_eq!(w.writes_to_9(), expected);
    assert_eq!(w.mb.keepalive_ms(db9()), 300);
    // Heartbeats are the dispatcher's own: they take no pending slot and are not requests.
    let d = w.mb.diagnostics();
    assert_eq!((d.keepalives, d.keepalive_failures, d.completed), (9, 0, 1));
    let dd = w.db9.diagnostics();
    assert_eq!((dd.failsafe_trips, dd.frames_ok), (0, 10));
    assert_eq!(w.db9.failsafe_timeout_ms(), 300);
}

#[test]
fn the_programs_own_traffic_postpones_the_heartbeat() {
    let w = World::new();
    let a1a = Port::actuator(1).unwrap().pin(Pin::A);
    w.sim(async {
        w.at(1_000).await;
        w.mb.call(db9(), Op::SetFailsafe { timeout_ms: 300 })
            .await
            .unwrap();
        w.at(150_000).await;
        w.mb.call(db9(), Op::DigitalWrite(a1a, Level::High))
            .await
            .unwrap();
        w.at(400_000).await;
    });
    assert_eq!(
        w.writes_to_9(),
        [
            (1_000, set_failsafe(0, 300)),
            (101_100, heartbeat(1)),
            // the program's write at 150 000 µs ends at 150 100 µs: the next heartbeat is
            // 100 ms after that, not 100 ms after the previous heartbeat
            (150_000, vec![0x12, 0x09, 0x00, 0x02]),
            (250_100, heartbeat(3)),
            (350_200, heartbeat(4)),
        ]
    );
}

#[test]
fn set_failsafe_zero_stops_the_keepalive() {
    let w = World::new();
    w.sim(async {
        w.at(1_000).await;
        w.mb.call(db9(), Op::SetFailsafe { timeout_ms: 300 })
            .await
            .unwrap();
        w.at(250_000).await;
        w.mb.call(db9(), Op::SetFailsafe { timeout_ms: 0 })
            .await
            .unwrap();
        w.at(1_000_000).await;
    });
    assert_eq!(
        w.writes_to_9(),
        [
            (1_000, set_failsafe(0, 300)),
            (101_100, heartbeat(1)),
            (201_200, heartbeat(2)),
            (250_000, set_failsafe(3, 0)),
        ]
    );
    assert_eq!(w.mb.keepalive_ms(db9()), 0);
    assert_eq!(w.db9.diagnostics().failsafe_trips, 0);
}

#[test]
fn a_board_that_rebooted_gets_its_failsafe_set_again() {
    let w = World::new();
    w.sim(async {
        w.at(1_000).await;
        w.mb.call(db9(), Op::SetFailsafe { timeout_ms: 300 })
            .await
            .unwrap();
        // DB 9 restarts (its failsafe is off again) and says so with a boot event
        w.at(50_000).await;
        let boot = common::boot_event(9, &w.db9.identity());
        w.bus.to_mb(boot);
        w.at(200_000).await;
    });
    assert_eq!(
        w.writes_to_9(),
        [
            (1_000, set_failsafe(0, 300)),
            // at once, the same timeout
            (50_000, set_failsafe(1, 300)),
            (150_100, heartbeat(2)),
        ]
    );
    let d = w.mb.diagnostics();
    assert_eq!((d.failsafe_resends, d.keepalives, d.boots), (1, 1, 3));
}

#[test]
fn a_stopped_motherboard_leaves_the_board_to_trip_at_exactly_its_timeout() {
    let w = World::new();
    let stop_at = 500_000;
    let mb = async {
        // the motherboard runs until `stop_at`, then stops (crashed, unpowered)
        select(
            w.mb.run(w.bus.clone()),
            w.clock.sleep_until(Instant(stop_at)),
        )
        .await;
    };
    sim(&w.clock, join(mb, w.bus.run_dbs()), async {
        w.at(1_000).await;
        w.mb.call(db9(), Op::SetFailsafe { timeout_ms: 300 })
            .await
            .unwrap();
        w.at(900_000).await;
    });
    // The last heartbeat before the stop started at 401 400 µs; DB 9 heard it at its end,
    // 401 500 µs, and trips exactly 300 ms later.
    let writes = w.writes_to_9();
    assert_eq!(writes.last(), Some(&(401_400, heartbeat(4))));
    let trip = 401_400 + T + 300_000;
    let events: Vec<_> = w
        .bus
        .to_mb_log()
        .into_iter()
        .filter(|(t, _)| *t > 1_000)
        .collect();
    // failsafe_tripped (kind 4), DB 9's second event (its boot was the first), payload the
    // timeout in ms
    assert_eq!(
        events,
        [(trip, vec![0x09, 0x04, 0x00, 0x01, 0x00, 0x02, 0x2C, 0x01])]
    );
    assert_eq!(w.db9.diagnostics().failsafe_trips, 1);
    // every actuator went to its safe state (port 2 of the test board has a special one)
    let log = w.db9.ports().take_log();
    let tail = &log[log.len() - 8..];
    let safe2 = SafeState {
        pwm: [10, 20],
        digital: [Level::High, Level::Low],
    };
    let mut expected = Vec::new();
    for (n, safe) in [(1, SafeState::ALL_LOW), (2, safe2)] {
        let p = Port::actuator(n).unwrap();
        expected.push(PortOp::PwmDuty(p.pin(Pin::A), safe.pwm[0]));
        expected.push(PortOp::PwmDuty(p.pin(Pin::B), safe.pwm[1]));
        expected.push(PortOp::DigitalWrite(p.pin(Pin::A), safe.digital[0]));
        expected.push(PortOp::DigitalWrite(p.pin(Pin::B), safe.digital[1]));
    }
    assert_eq!(tail, &expected[..]);
}

/// The keepalive state is one entry per 7-bit address: no cap below the bus's 111 boards
/// (the old limit of 16 refused a 17th `SetFailsafe` with `Busy`). A failsafe stopped with
/// 0 is no longer kept alive.
#[test]
fn a_failsafe_on_any_number_of_boards_is_kept_alive() {
    let w = World::new();
    let boards: Vec<u8> = (0x30..0x30 + 40).collect();
    for &b in &boards {
        w.bus.attach(
            b,
            Node::Script(Box::new(|req| (0, vec![req[3], 0x00, 0x00]))),
        );
    }
    let addr = |b: u8| Address::external(b).unwrap();
    let results = w.sim(async {
        let mut r = Vec::new();
        for &b in &boards {
            r.push(
                w.mb.call(addr(b), Op::SetFailsafe { timeout_ms: 1_000 })
                    .await,
            );
        }
        w.mb.call(addr(boards[0]), Op::SetFailsafe { timeout_ms: 0 })
            .await
            .unwrap();
        w.at(1_000_000).await;
        r
    });
    assert!(results.iter().all(Result::is_ok), "{results:?}");
    assert_eq!(w.mb.keepalive_ms(addr(boards[0])), 0);
    for &b in &boards[1..] {
        assert_eq!(w.mb.keepalive_ms(addr(b)), 1_000);
        let heartbeats = w
            .bus
            .seen()
            .iter()
            .filter(|(_, s)| matches!(s, Seen::Write(a, f) if *a == b && f[0] == 0x02))
            .count();
        assert_eq!(heartbeats, 2, "board {b:#x}");
    }
    assert_eq!(w.mb.diagnostics().busy, 0);
}
