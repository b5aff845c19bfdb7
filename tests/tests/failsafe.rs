//! A motherboard that falls silent trips the daughterboard's failsafe: every actuator goes to
//! its declared safe state and the board reports it. One that keeps talking never trips it.

use x10_devices::Link;
use x10_microcode::{Address, Level, Op, Pin};
use x10_sim::sim::{task, Sim, SimConfig, SimOutcome};
use x10_sim::timing::Speed;
use x10_tests::{act, duties, levels, ms};

/// Sets a 200 ms failsafe on db09, drives its motor (A1.A high, PWM 200), then, when
/// `heartbeat` is set, sends a heartbeat every 100 ms; otherwise falls silent.
fn run(heartbeat: bool) -> SimOutcome {
    let config = SimConfig {
        duration_ms: 1_000,
        ..SimConfig::default()
    };
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 1, 1);
    let db = Address::external(9).unwrap();
    let a1a = act(1, Pin::A);
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
    // Driven at 10 ms (set_failsafe, then io high), safe (all low, PWM 0) 200 ms after the MB
    // fell silent.
    let high_at = ms(10) + t.write_ns(6) + t.buf_ns + t.write_ns(4);
    assert_eq!(
        levels(&o.log, "db09", a1a),
        vec![(0, false), (high_at, true), (trip, false)]
    );
    assert_eq!(duties(&o.log, "db09", a1a), vec![(last, 200), (trip, 0)]);
    // The board told the MB (a failsafe_tripped event, payload 200 ms), once.
    let tripped: Vec<_> = o
        .records
        .iter()
        .filter(|r| r.addr == 0x08 && r.written.get(1) == Some(&4))
        .collect();
    assert_eq!(tripped.len(), 1);
    assert_eq!(tripped[0].written[6..8], 200u16.to_le_bytes());
    assert_eq!(o.mb.failsafe_trips, 1);
    assert_eq!(o.board("db09").unwrap().failsafe_trips, 1);
    assert!(o
        .trace
        .render()
        .contains("db09: -> mb event failsafe_tripped seq"));
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
