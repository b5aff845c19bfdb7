//! A daughterboard pushes events while the motherboard keeps the bus busy dispatching: both
//! masters wait for the bus and start in the same instant, arbitration decides bit by bit, and
//! nothing is lost: every edge reaches the task waiting for it, every request its caller.

use std::cell::RefCell;
use std::rc::Rc;

use x10_microcode::{Address, EventConfig, EventKind, Op, Pin};
use x10_sim::bus::Role;
use x10_sim::ports::{Analog, Digital, SensorScript};
use x10_sim::sim::{task, Sim, SimConfig, SimOutcome};
use x10_tests::{ms, sens, thesis_frames};

/// Edges on db09 S1.A: high for 25 ms every 50 ms from 5 ms on.
fn square() -> Digital {
    Digital::Pulses {
        first_us: 5_000,
        period_us: 50_000,
        width_us: Analog::Const(25_000),
    }
}

struct Run {
    outcome: SimOutcome,
    events: Vec<(u64, u8)>,
    reads: Vec<Result<u16, String>>,
}

fn run(mb_role: Role) -> Run {
    let events = Rc::new(RefCell::new(Vec::new()));
    let reads = Rc::new(RefCell::new(Vec::new()));
    let config = SimConfig {
        mb_role,
        ..thesis_frames(1_000)
    };
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 2, 2).with_sensor(
        1,
        SensorScript {
            a: square(),
            ..SensorScript::default()
        },
    );
    let other = sim.ports("db0a", 2, 2).with_sensor(
        1,
        SensorScript {
            analog: Analog::Const(321),
            ..SensorScript::default()
        },
    );
    let db = Address::external(9).unwrap();
    let db0a = Address::external(0x0a).unwrap();
    let s1a = sens(1, Pin::A);
    let ev = events.clone();
    let rd = reads.clone();
    let outcome = sim
        .with_board(db, ports)
        .with_board(db0a, other)
        .with_task(
            "events",
            task(move |ctx| {
                Box::pin(async move {
                    let link = ctx.handle();
                    let cfg = EventConfig {
                        rising: true,
                        falling: true,
                        ..EventConfig::OFF
                    };
                    link.call(db, Op::EventEnable(s1a, cfg)).await.unwrap();
                    loop {
                        let e = link.wait_event(db, s1a).await.unwrap();
                        assert_eq!(e.kind, EventKind::PinChange);
                        ev.borrow_mut().push((ctx.clock.now_ns(), e.value[0]));
                    }
                })
            }),
        )
        .with_task(
            "load",
            task(move |ctx| {
                Box::pin(async move {
                    // Back-to-back reads of another board: the bus is busy nearly all the
                    // time, and the event sender must win it by arbitration.
                    let link = ctx.handle();
                    loop {
                        let r = link.call(db0a, Op::AnalogRead(s1a.port)).await;
                        rd.borrow_mut().push(
                            r.map(|p| u16::from_le_bytes([p[0], p[1]]))
                                .map_err(|e| e.to_string()),
                        );
                    }
                })
            }),
        )
        .run()
        .unwrap();
    Run {
        outcome,
        events: events.take(),
        reads: reads.take(),
    }
}

fn check(r: &Run, role: &str) {
    // Events were enabled at 0.4 ms and the simulated port latches edges from then on, so
    // the 40 edges from 5 ms to 980 ms (edge k at 5 ms + 25 ms·k) each become one event,
    // rising first, reported when latched and delivered within a few hundred µs more.
    let levels: Vec<u8> = r.events.iter().map(|(_, v)| *v).collect();
    let expected: Vec<u8> = (0..40).map(|i| u8::from(i % 2 == 0)).collect();
    assert_eq!(levels, expected, "{role}");
    for (i, (t, _)) in r.events.iter().enumerate() {
        let edge = ms(5) + ms(25) * i as u64;
        assert!(
            (edge..edge + ms(11)).contains(t),
            "{role}: event {i} at {t}"
        );
    }
    // Every read got the right value.
    assert!(r.reads.len() > 3_000, "{role}: {}", r.reads.len());
    assert!(r.reads.iter().all(|x| *x == Ok(321)), "{role}");
    let o = &r.outcome;
    // Nothing was dropped anywhere, and every event sent was routed.
    let db = o.board("db09").unwrap();
    assert_eq!(db.events_dropped, 0, "{role}");
    assert_eq!(
        o.mb.overflows + o.mb.events_dropped + o.mb.bad_events,
        0,
        "{role}"
    );
    // No node dropped a transfer it had started to receive (the simulator loses such a
    // transfer, as the boards' ports do).
    assert_eq!(o.bus.lost_transfers, 0, "{role}");
    let sent = u32::from(db.events_sent) + u32::from(o.board("db0a").unwrap().events_sent);
    assert_eq!(
        sent + 1,
        o.mb.events,
        "{role}: bus events and the internal board's boot"
    );
}

fn collisions(o: &SimOutcome) -> usize {
    // Transactions in which the MB (node 0) lost arbitration to an event: at bit 5 of the
    // address byte when it addressed db0a (0x08 = 0001000 against 0x0a = 0001010), bit 6
    // for db09 (0x09 = 0001001).
    let c: Vec<_> = o
        .records
        .iter()
        .filter(|rec| rec.addr == 0x08 && rec.losers.iter().any(|l| l.node == 0))
        .collect();
    for rec in &c {
        for l in rec.losers.iter().filter(|l| l.node == 0) {
            // The first bit where the MB's address differs from 0x08, where it sends a 1.
            let expected = match l.addr {
                0x0a => 5,
                0x09 => 6,
                other => panic!("MB lost while addressing {other:#04x}"),
            };
            assert_eq!(l.bit, expected, "{rec:?}");
        }
    }
    c.len()
}

#[test]
fn events_win_arbitration_against_requests_and_nothing_is_lost_dual_role_mb() {
    let r = run(Role::DualRole);
    check(&r, "dual-role");
    let o = &r.outcome;
    let n = collisions(o);
    assert!(n >= 30, "{n} collisions");
    // The MB counts every lost attempt: lost on the wire, or given up at once because it was
    // being addressed while it waited for the bus.
    assert_eq!(u64::from(o.mb.arbitration_lost), n as u64 + o.bus.yielded);
    // A dual-role MB takes the event at once: no NACK, no DB retry.
    assert_eq!(o.board("db09").unwrap().event_retries, 0);
    assert_eq!(o.mb.arbitration_failures + o.mb.nacks + o.mb.timeouts, 0);
}

#[test]
fn events_win_arbitration_and_nothing_is_lost_single_role_mb() {
    // An RP2040-like MB that re-arms its target within 2 µs of losing arbitration is ready
    // before the ACK bit of the winner's address (3 bit times later at 400 kHz).
    let r = run(Role::SingleRole { switch_ns: 2_000 });
    check(&r, "single-role");
    let o = &r.outcome;
    assert!(collisions(o) >= 30);
    assert_eq!(o.mb.arbitration_failures + o.mb.nacks + o.mb.timeouts, 0);
}

#[test]
fn events_survive_a_slow_single_role_mb() {
    // An MB whose role switch (20 µs) outlasts the 3 bit times between its loss and the ACK
    // bit NACKs the event that beat it. The policies are asymmetric: the DB retries after
    // 100..150 µs, the MB listens 400 µs after a lost arbitration before it retries, so the
    // DB's first retry finds it listening.
    let r = run(Role::SingleRole { switch_ns: 20_000 });
    check(&r, "slow single-role");
    let o = &r.outcome;
    assert!(collisions(o) >= 30);
    // Every pin event was NACKed once and delivered by its first retry.
    assert_eq!(o.board("db09").unwrap().event_retries, 40);
    assert_eq!(o.mb.arbitration_failures + o.mb.nacks + o.mb.timeouts, 0);
}

#[test]
fn events_survive_back_to_back_polling_of_the_same_board() {
    // The MB polls db09 back to back, so when db09 wants to send an event the bus usually
    // carries a request addressed to it: its write gives up (arbitration lost), it serves the
    // request and retries right after it, without counting that attempt, and its event to
    // the MB's lower address wins against the MB's next request.
    let events = Rc::new(RefCell::new(Vec::new()));
    let config = thesis_frames(1_000);
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 2, 2).with_sensor(
        1,
        SensorScript {
            a: square(),
            analog: Analog::Const(321),
            ..SensorScript::default()
        },
    );
    let db = Address::external(9).unwrap();
    let s1a = sens(1, Pin::A);
    let ev = events.clone();
    let reads = Rc::new(RefCell::new(0u32));
    let rd = reads.clone();
    let o = sim
        .with_board(db, ports)
        .with_task(
            "events",
            task(move |ctx| {
                Box::pin(async move {
                    let link = ctx.handle();
                    let cfg = EventConfig {
                        rising: true,
                        falling: true,
                        ..EventConfig::OFF
                    };
                    link.call(db, Op::EventEnable(s1a, cfg)).await.unwrap();
                    loop {
                        let e = link.wait_event(db, s1a).await.unwrap();
                        ev.borrow_mut().push((ctx.clock.now_ns(), e.value[0]));
                    }
                })
            }),
        )
        .with_task(
            "load",
            task(move |ctx| {
                Box::pin(async move {
                    let link = ctx.handle();
                    loop {
                        let p = link.call(db, Op::AnalogRead(s1a.port)).await.unwrap();
                        assert_eq!(u16::from_le_bytes([p[0], p[1]]), 321);
                        *rd.borrow_mut() += 1;
                    }
                })
            }),
        )
        .run()
        .unwrap();
    // The same 40 edges as above, each one event, in order, within a sample period.
    let events = events.take();
    let levels: Vec<u8> = events.iter().map(|(_, v)| *v).collect();
    let expected: Vec<u8> = (0..40).map(|i| u8::from(i % 2 == 0)).collect();
    assert_eq!(levels, expected);
    for (i, (t, _)) in events.iter().enumerate() {
        let edge = ms(5) + ms(25) * i as u64;
        assert!((edge..edge + ms(11)).contains(t), "event {i} at {t}");
    }
    assert!(*reads.borrow() > 3_000, "{}", reads.borrow());
    let d = o.board("db09").unwrap();
    assert_eq!(d.events_dropped, 0);
    // An event queued while a request to db09 is being received waits for the end of that
    // transaction (a transfer under way is never cut) and then goes out first. Only 4 times
    // (events go out when the edge is latched, not on the 10 ms grid; the event_enable is a
    // write-then-read, read back) did its write find the bus taken by a request addressed to
    // it (its address already matched); each such event went out on the one retry right
    // after serving the request.
    assert_eq!(d.arbitration_lost, 4);
    assert_eq!(d.event_retries, d.arbitration_lost);
    // No node dropped a transfer it had started to receive.
    assert_eq!(o.bus.lost_transfers, 0);
    // Boot and 40 pin events from db09, and the internal board's boot.
    assert_eq!((d.events_sent, o.mb.events), (41, 42));
    assert_eq!(o.mb.overflows + o.mb.events_dropped + o.mb.bad_events, 0);
    assert_eq!(o.mb.arbitration_failures + o.mb.nacks + o.mb.timeouts, 0);
}
