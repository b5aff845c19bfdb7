//! Boards that misbehave: one that never answers, one that is absent, one that answers late,
//! one that resets mid-run. Every request ends once, with a typed error, and is counted.

use std::cell::RefCell;
use std::rc::Rc;

use x10_devices::LinkError;
use x10_hal::bus::MultiMaster;
use x10_microcode::{Address, Edge, Level, Op, Pin, Port};
use x10_sim::bus::{NodeConfig, Outcome};
use x10_sim::ports::{Analog, Digital, SensorScript};
use x10_sim::sim::{task, Sim, SimConfig};
use x10_sim::timing::Speed;
use x10_tests::{act, levels, ms, sens, thesis_frames};

type Results = Rc<RefCell<Vec<(u64, u64, Result<Vec<u8>, LinkError>)>>>;

#[test]
fn a_board_that_never_answers_times_out_and_an_absent_one_is_nacked() {
    let results: Results = Rc::new(RefCell::new(Vec::new()));
    let r = results.clone();
    let config = SimConfig {
        stop_when_tasks_done: true,
        ..thesis_frames(1_000)
    };
    let o = Sim::new(config)
        // 0x20 acknowledges its address and takes writes, but never answers a read.
        .with_raw_node(NodeConfig::new("mute", Some(0x20)))
        .with_task(
            "mute",
            task(|ctx| {
                Box::pin(async move {
                    let mut port = ctx.bus.port(ctx.node("mute").unwrap());
                    let mut buf = [0u8; 40];
                    loop {
                        let _ = port.listen(&mut buf).await;
                    }
                })
            }),
        )
        .with_task(
            "caller",
            task(move |ctx| {
                Box::pin(async move {
                    let mute = Address::external(0x20).unwrap();
                    let absent = Address::external(0x30).unwrap();
                    let s1 = Port::sensor(1).unwrap();
                    for (db, op) in [
                        (mute, Op::AnalogRead(s1)),
                        (absent, Op::AnalogRead(s1)),
                        (mute, Op::DigitalWrite(act(1, Pin::A), Level::High)),
                    ] {
                        let t0 = ctx.clock.now_ns();
                        let v = ctx.handle().call(db, op).await.map(|p| p.to_vec());
                        r.borrow_mut().push((t0, ctx.clock.now_ns(), v));
                    }
                })
            }),
        )
        .run()
        .unwrap();
    let res = results.borrow();
    let t = Speed::Fast.timing();
    // 1. The read: the target stretches SCL waiting for a reply that never comes; after the
    //    25 ms stretch timeout the bus gives up and so does the request, once.
    let (t0, t1, v) = &res[0];
    assert_eq!(*v, Err(LinkError::Timeout));
    let ar_end = t.start_ns() + 5 * t.byte_ns() + t.repeated_start_ns() + t.byte_ns();
    assert_eq!(t1 - t0, ar_end + ms(25) + t.stop_ns());
    // 2. Nobody at 0x30: NACK on the address, retried with backoff, 5 attempts in all.
    assert_eq!(res[1].2, Err(LinkError::Nack));
    let nacked: Vec<_> = o
        .records
        .iter()
        .filter(|rec| rec.addr == 0x30)
        .map(|rec| rec.outcome)
        .collect();
    assert_eq!(nacked, vec![Outcome::Nack { byte: 0 }; 5]);
    // 3. A write to the mute board is fine: it acknowledges.
    assert_eq!(res[2].2, Ok(vec![]));
    assert_eq!(o.mb.timeouts, 1);
    assert_eq!(o.mb.nacks, 1);
    assert_eq!(o.mb.nacked, 5);
    assert_eq!(o.mb.retries, 4);
    assert_eq!(o.mb.completed, 1);
}

#[test]
fn a_reply_that_comes_after_the_caller_gave_up_is_dropped_and_counted() {
    let results: Results = Rc::new(RefCell::new(Vec::new()));
    let r = results.clone();
    let config = SimConfig {
        stop_when_tasks_done: true,
        ..thesis_frames(1_000)
    };
    let sim = Sim::new(config);
    // The echo comes at 50 ms: the pulse-in's deferred reply leaves the DB at about 51 ms.
    let ports = sim.ports("db09", 1, 1).with_sensor(
        1,
        SensorScript {
            a: Digital::Pulses {
                first_us: 50_000,
                period_us: 60_000,
                width_us: Analog::Const(580),
            },
            b: Digital::Const(true),
            ..SensorScript::default()
        },
    );
    let db = Address::external(9).unwrap();
    let o = sim
        .with_board(db, ports)
        .with_task(
            "impatient",
            task(move |ctx| {
                Box::pin(async move {
                    let op = Op::PulseIn {
                        pin: sens(1, Pin::A),
                        edge: Edge::Rising,
                        timeout_ms: Some(200),
                    };
                    let t0 = ctx.clock.now_ns();
                    // The caller gives up after 20 ms.
                    let v = ctx.handle().call_with_timeout(db, op, 20_000).await;
                    r.borrow_mut()
                        .push((t0, ctx.clock.now_ns(), v.map(|p| p.to_vec())));
                    // Later, the same board still answers the next request correctly.
                    ctx.clock.sleep_ns(ms(100)).await;
                    let t0 = ctx.clock.now_ns();
                    let v = ctx
                        .handle()
                        .call(db, Op::DigitalRead(sens(1, Pin::B)))
                        .await;
                    r.borrow_mut()
                        .push((t0, ctx.clock.now_ns(), v.map(|p| p.to_vec())));
                })
            }),
        )
        .run()
        .unwrap();
    let res = results.borrow();
    assert_eq!(res[0].2, Err(LinkError::Timeout));
    assert_eq!(res[0].1 - res[0].0, ms(20));
    assert_eq!(res[1].2, Ok(vec![1]));
    // The deferred reply did arrive (an event from db09 at about 50.6 ms) and was dropped.
    let deferred: Vec<_> = o
        .records
        .iter()
        .filter(|rec| rec.addr == 0x08 && rec.written.get(1) == Some(&3))
        .collect();
    assert_eq!(deferred.len(), 1);
    assert!((ms(50)..ms(52)).contains(&deferred[0].start_ns));
    assert_eq!(o.mb.late_replies, 1);
    assert_eq!(o.mb.timeouts, 1);
    assert_eq!(o.mb.completed, 1);
    assert_eq!(o.mb.unknown_replies + o.mb.duplicate_replies, 0);
}

#[test]
fn a_board_that_resets_mid_run_fails_calls_while_down_then_serves_again() {
    let results: Results = Rc::new(RefCell::new(Vec::new()));
    let r = results.clone();
    let config = thesis_frames(1_000);
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 1, 1).with_sensor(
        1,
        SensorScript {
            analog: Analog::Const(512),
            ..SensorScript::default()
        },
    );
    let db = Address::external(9).unwrap();
    let a1a = act(1, Pin::A);
    let o = sim
        .with_board(db, ports)
        .reset_at("db09", 300, 50)
        .with_task(
            "poller",
            task(move |ctx| {
                Box::pin(async move {
                    let link = ctx.handle();
                    ctx.clock.sleep_ns(ms(5)).await;
                    link.call(db, Op::DigitalWrite(a1a, Level::High))
                        .await
                        .unwrap();
                    loop {
                        let t0 = ctx.clock.now_ns();
                        let v = link
                            .call(db, Op::AnalogRead(Port::sensor(1).unwrap()))
                            .await;
                        r.borrow_mut()
                            .push((t0, ctx.clock.now_ns(), v.map(|p| p.to_vec())));
                        ctx.clock.sleep_ns(ms(5)).await;
                    }
                })
            }),
        )
        .run()
        .unwrap();
    let res = results.borrow();
    let ok = Ok(512u16.to_le_bytes().to_vec());
    for (t0, t1, v) in res.iter() {
        if *t1 < ms(300) || *t0 > ms(352) {
            assert_eq!(*v, ok, "call at {t0}");
        } else {
            // Down: the board NACKs its address on every attempt.
            assert!(
                *v == ok || *v == Err(LinkError::Nack),
                "call at {t0}: {v:?}"
            );
        }
    }
    let failed = res.iter().filter(|(_, _, v)| v.is_err()).count();
    assert!((5..=11).contains(&failed), "{failed} failed");
    // The board came back: boot event again (the internal board's and two of db09's).
    assert_eq!(o.mb.boots, 3);
    let after = res
        .iter()
        .filter(|(_, t1, v)| *t1 > ms(350) && v.is_ok())
        .count();
    assert_eq!(o.board("db09").unwrap().frames_ok as usize, after);
    // Its actuator went back to the safe state at the reboot; the program did not drive it
    // again (it wrote it once), so it stays low.
    assert_eq!(
        levels(&o.log, "db09", a1a),
        vec![
            (0, false),
            (ms(5) + Speed::Fast.timing().write_ns(4), true),
            (ms(350), false)
        ]
    );
    assert!(o
        .trace
        .render()
        .contains("db09: reset: firmware restarts at 0.350000"));
}

/// Figure 4.4's second module drives db09's motor; db09 resets for 2 ms between two steps, so
/// no call fails, and comes back with its outputs in the safe state. The program re-asserts
/// its motor at the next periodic refresh (every 25 steps), so the motor runs again without the
/// program having noticed anything.
#[test]
fn a_motor_on_a_board_that_reset_is_driven_again() {
    use x10_robots::{PERIOD, REFRESH_STEPS};
    let config = thesis_frames(5_000);
    let o = x10_sim::examples::sim("fig4_4", config)
        .expect("an example")
        .reset_at("db09", 2_503, 2)
        .run()
        .unwrap();
    let a1a = act(1, Pin::A);
    let changes = levels(&o.log, "db09", a1a);
    // low at boot; high when the light rises; low when the reset ends (safe state); high again;
    // low when the light falls at 4 s.
    let ends: Vec<bool> = changes.iter().map(|&(_, high)| high).collect();
    assert_eq!(ends, vec![false, true, false, true, false], "{changes:?}");
    let reset_end = changes[2].0;
    assert_eq!(reset_end, ms(2_505));
    // Driven again within one refresh period of 20 ms steps.
    let again = changes[3].0;
    assert!(
        again > reset_end && again - reset_end <= ms(PERIOD.as_millis() * u64::from(REFRESH_STEPS)),
        "{changes:?}"
    );
    assert_eq!(o.log.level_at("db09", a1a, ms(3_000)), Some(Level::High));
}
