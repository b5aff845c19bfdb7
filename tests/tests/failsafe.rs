//! A motherboard that falls silent (it stops: a crash, a power loss) trips the daughterboard's
//! failsafe: every actuator goes to its declared safe state and the board tries to report it.
//! One that keeps talking never trips it. (A live MB whose program merely stops sending keeps
//! the failsafe fed with heartbeats: see keepalive.rs.)

use x10_microcode::{Address, Level, Op, Pin};
use x10_sim::bus::Outcome;
use x10_sim::sim::{task, Sim, SimOutcome};
use x10_sim::timing::Speed;
use x10_tests::{act, duties, levels, ms, thesis_frames};

/// When the MB stops in the silent case.
const MB_STOP_MS: u64 = 300;

/// Sets a 200 ms failsafe on db09, drives its motor (A1.A high, PWM 200), then, when
/// `heartbeat` is set, sends a heartbeat every 100 ms; otherwise the MB stops at 300 ms.
fn run(heartbeat: bool) -> SimOutcome {
    let config = thesis_frames(1_000);
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 1, 1);
    let db = Address::external(9).unwrap();
    let a1a = act(1, Pin::A);
    let sim = if heartbeat {
        sim
    } else {
        sim.stop_mb_at(MB_STOP_MS)
    };
    sim.with_board(db, ports)
        .with_task(
            "driver",
            task(move |ctx| {
                Box::pin(async move {
                    let link = ctx.handle();
                    ctx.clock.sleep_ns(ms(10)).await;
                    link.call(db, Op::SetFailsafe { timeout_ms: 200 })
                        .await
                        .unwrap();
                    link.call(db, Op::DigitalWrite(a1a, Level::High))
                        .await
                        .unwrap();
                    link.call(db, Op::PwmDuty(a1a, 200)).await.unwrap();
                    if heartbeat {
                        loop {
                            ctx.clock.sleep_ns(ms(100)).await;
                            link.call(db, Op::Heartbeat).await.unwrap();
                        }
                    }
                })
            }),
        )
        .run()
        .unwrap()
}

#[test]
fn a_silent_mb_trips_the_failsafe_once() {
    let o = run(false);
    let a1a = act(1, Pin::A);
    let t = Speed::Fast.timing();
    // The last transaction addressed to db09 (the PWM write) ended at `last`; the runtimes'
    // clock counts whole µs.
    let last = o
        .records
        .iter()
        .filter(|r| r.addr == 0x09)
        .map(|r| r.end_ns)
        .max()
        .unwrap();
    let trip = last / 1_000 * 1_000 + ms(200);
    // Driven at 10 ms (set_failsafe, read back for its 3-byte reply, then io high), safe
    // (all low, PWM 0) 200 ms after the MB fell silent.
    let high_at = ms(10) + t.write_read_ns(6, 3) + t.buf_ns + t.write_ns(4);
    assert_eq!(
        levels(&o.log, "db09", a1a),
        vec![(0, false), (high_at, true), (trip, false)]
    );
    // The PWM write (function 2) set the duty when it ended.
    let pwm_end = o
        .records
        .iter()
        .find(|r| r.addr == 0x09 && r.written.first() == Some(&0x20))
        .map(|r| r.end_ns)
        .unwrap();
    assert_eq!(duties(&o.log, "db09", a1a), vec![(pwm_end, 200), (trip, 0)]);
    // The MB kept db09's failsafe fed (a heartbeat whenever nothing was sent for 200/3 ms)
    // until it stopped: the last frame db09 heard came shortly before the stop.
    assert!(
        last < ms(MB_STOP_MS) && last > ms(MB_STOP_MS) - ms(67),
        "{last}"
    );
    // The board tried to tell the MB (a failsafe_tripped event, payload 200 ms): the stopped MB
    // NACKs its address, so the board made its 5 attempts (RetryPolicy::DEFAULT), then took
    // the MB for gone and kept the event (never dropped): no burst of retries, the kept event
    // tried once every 100 ms (MB_GONE_RETRY_US), counted from the end of the previous try
    // (the last attempt's 100 µs wait, then each NACKed address: 25 µs at 400 kHz), five
    // times until the run ends at 1 s.
    let tripped: Vec<_> = o
        .records
        .iter()
        .filter(|r| r.addr == 0x08 && r.written.get(1) == Some(&4))
        .collect();
    assert_eq!(tripped.len(), 10);
    for r in &tripped {
        assert_eq!(r.written[6..8], 200u16.to_le_bytes());
        assert_eq!(r.outcome, Outcome::Nack { byte: 0 });
    }
    assert!(tripped[0].start_ns >= trip);
    // Nothing else went to the MB after the first attempt (no overflow report: nothing was
    // dropped).
    let to_mb = o
        .records
        .iter()
        .filter(|r| r.addr == 0x08 && r.start_ns >= tripped[0].start_ns)
        .count();
    assert_eq!(to_mb, 10);
    let slow = &tripped[5..];
    assert_eq!(slow[0].start_ns - tripped[4].start_ns, ms(100) + 125_000);
    for w in slow.windows(2) {
        assert_eq!(w[1].start_ns - w[0].start_ns, ms(100) + 25_000);
    }
    let db09 = o.board("db09").unwrap();
    assert_eq!(db09.failsafe_trips, 1);
    // 9 retries of the tripped event (4 fast, 5 slow); the boot event sent, nothing dropped.
    assert_eq!(db09.event_retries, 9);
    assert_eq!((db09.events_sent, db09.events_dropped), (1, 0));
    // The stopped MB saw nothing of it.
    assert_eq!(o.mb.failsafe_trips, 0);
}

#[test]
fn a_talking_mb_keeps_the_actuators_on() {
    let o = run(true);
    let a1a = act(1, Pin::A);
    assert_eq!(levels(&o.log, "db09", a1a).len(), 2);
    assert_eq!(o.log.level_at("db09", a1a, ms(999)), Some(Level::High));
    assert_eq!(o.log.duty_at("db09", a1a, ms(999)), 200);
    assert_eq!(o.mb.failsafe_trips, 0);
    assert_eq!(o.board("db09").unwrap().failsafe_trips, 0);
}
