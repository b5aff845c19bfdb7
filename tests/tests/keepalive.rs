//! The failsafe keepalive: a robot program that sets a board's failsafe and then sends only
//! on change (here: nothing at all) does not trip it, because the motherboard sends the board
//! a heartbeat whenever nothing was sent to it for a third of the timeout; it stops when the
//! program sets the failsafe to 0, and a board that restarted gets its failsafe set again.
//!
//! That a motherboard that stops running lets the board trip at exactly its timeout is shown
//! at the firmware level (`firmware-mb/tests/keepalive.rs`): the simulator has no way to stop
//! its motherboard mid-run.

use x10_microcode::{Address, Level, Op, Pin};
use x10_sim::bus::{BusRecord, Outcome};
use x10_sim::sim::{task, Sim, SimOutcome};
use x10_sim::timing::Speed;
use x10_tests::{act, duties, levels, ms, thesis_frames};

/// The failsafe timeout the program sets, and the keepalive interval (a third of it, in ns,
/// on the runtimes' whole-µs clock).
const TIMEOUT_MS: u16 = 200;
const INTERVAL_NS: u64 = 66_666_000;

/// Sets a 200 ms failsafe on db09 at 10 ms and drives its motor (A1.A high, PWM 200), then
/// sends nothing, except the failsafe set to 0 at `stop_ms` if given. db09 restarts at
/// `reset_ms` if given. Runs 2.1 s.
fn run(stop_ms: Option<u64>, reset_ms: Option<u64>) -> SimOutcome {
    let config = thesis_frames(2_100);
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 1, 1);
    let db = Address::external(9).unwrap();
    let a1a = act(1, Pin::A);
    let mut sim = sim.with_board(db, ports).with_task(
        "program",
        task(move |ctx| {
            Box::pin(async move {
                let link = ctx.handle();
                ctx.clock.sleep_ns(ms(10)).await;
                let fs = Op::SetFailsafe {
                    timeout_ms: TIMEOUT_MS,
                };
                link.call(db, fs).await.unwrap();
                link.call(db, Op::DigitalWrite(a1a, Level::High))
                    .await
                    .unwrap();
                link.call(db, Op::PwmDuty(a1a, 200)).await.unwrap();
                if let Some(stop) = stop_ms {
                    ctx.clock.sleep_until_ns(ms(stop)).await;
                    link.call(db, Op::SetFailsafe { timeout_ms: 0 })
                        .await
                        .unwrap();
                }
            })
        }),
    );
    if let Some(at) = reset_ms {
        sim = sim.reset_at("db09", at, 5);
    }
    sim.run().unwrap()
}

/// Transactions the MB made to db09, in order.
fn to_db09(o: &SimOutcome) -> Vec<&BusRecord> {
    o.records
        .iter()
        .filter(|r| r.addr == 0x09 && r.master == 0)
        .collect()
}

fn is_heartbeat(r: &BusRecord) -> bool {
    r.written.len() == 4 && r.written[..3] == [0x02, 0x09, 0x00]
}

/// Each heartbeat starts exactly one interval after the end of the MB's previous transaction
/// to the board (in whole µs, the runtimes' clock). Returns how many there were.
fn check_heartbeats(txns: &[&BusRecord]) -> usize {
    let mut n = 0;
    for pair in txns.windows(2) {
        if is_heartbeat(pair[1]) {
            let due = pair[0].end_ns / 1_000 * 1_000 + INTERVAL_NS;
            assert_eq!(pair[1].start_ns, due, "{:?}", pair[1]);
            assert_eq!(pair[1].outcome, Outcome::Ok);
            n += 1;
        }
    }
    n
}

#[test]
fn a_program_that_sends_nothing_does_not_trip_the_failsafe() {
    let o = run(None, None);
    let a1a = act(1, Pin::A);
    let txns = to_db09(&o);
    // set_failsafe, io high, pwm, then only heartbeats, each one interval after the
    // previous transaction, up to the end of the run
    assert_eq!(txns[0].written, [0x03, 0x09, 0x00, 0x00, 0xC8, 0x00]);
    assert!(txns[3..].iter().all(|r| is_heartbeat(r)));
    let beats = check_heartbeats(&txns);
    assert_eq!(beats, txns.len() - 3);
    // (2 100 ms - 10 ms) / 66.7 ms
    assert_eq!(beats, 31);
    let last = txns.last().unwrap();
    assert!(last.end_ns + INTERVAL_NS > ms(2_100));
    assert_eq!(o.mb.keepalives, beats as u32);
    // The motor stayed on for the whole run; nobody tripped.
    assert_eq!(levels(&o.log, "db09", a1a).len(), 2);
    assert_eq!(o.log.level_at("db09", a1a, ms(2_099)), Some(Level::High));
    assert_eq!(duties(&o.log, "db09", a1a).len(), 1);
    assert_eq!(o.log.duty_at("db09", a1a, ms(2_099)), 200);
    assert_eq!(o.board("db09").unwrap().failsafe_trips, 0);
    assert_eq!(o.mb.failsafe_trips, 0);
    assert_eq!(o.mb.keepalive_failures, 0);
}

#[test]
fn setting_the_failsafe_to_zero_stops_the_heartbeats() {
    let o = run(Some(500), None);
    let txns = to_db09(&o);
    let last = txns.last().unwrap();
    // the last transaction to db09 is the program's set_failsafe 0, at 500 ms
    assert_eq!(last.written[..3], [0x03, 0x09, 0x00]);
    assert_eq!(last.written[4..], [0x00, 0x00]);
    assert_eq!(last.start_ns, ms(500));
    let beats = check_heartbeats(&txns);
    // (500 ms - 10 ms) / 66.7 ms
    assert_eq!(beats, 7);
    assert_eq!(o.mb.keepalives, 7);
    assert_eq!(o.board("db09").unwrap().failsafe_trips, 0);
}

#[test]
fn a_board_that_restarts_gets_its_failsafe_set_again() {
    let o = run(None, Some(1_000));
    let txns = to_db09(&o);
    // db09 restarts at 1 000 ms (down 5 ms) and reports it with a boot event; the MB sets its
    // failsafe again right after routing it, and heartbeats go on from there.
    let boot = o
        .records
        .iter()
        .find(|r| r.addr == 0x08 && r.start_ns > ms(1_000) && r.written.get(1) == Some(&7))
        .unwrap();
    assert!(boot.start_ns >= ms(1_005));
    let resend = txns.iter().find(|r| r.start_ns > boot.start_ns).unwrap();
    assert_eq!(resend.written[..3], [0x03, 0x09, 0x00]);
    assert_eq!(resend.written[4..], [0xC8, 0x00]);
    assert_eq!(resend.outcome, Outcome::Ok);
    // as soon as the bus is free again after the boot event
    assert_eq!(resend.start_ns, boot.end_ns + Speed::Fast.timing().buf_ns);
    let after: Vec<_> = txns
        .iter()
        .copied()
        .filter(|r| r.start_ns >= resend.start_ns)
        .collect();
    assert!(after[1..].iter().all(|r| is_heartbeat(r)));
    assert_eq!(check_heartbeats(&after), after.len() - 1);
    assert_eq!(o.mb.failsafe_resends, 1);
    // The restarted board (its counters are of the current boot) armed the failsafe again
    // and never tripped.
    let d = o.board("db09").unwrap();
    assert_eq!(d.failsafe_trips, 0);
    assert_eq!(o.mb.failsafe_trips, 0);
}
