//! Sequence numbers wrap around (they are one byte) while a request is still outstanding: the
//! outstanding one's number is never reused, and its deferred reply reaches it.

use std::cell::RefCell;
use std::rc::Rc;

use x10_microcode::{Address, Edge, Op, Pin, Request};
use x10_sim::ports::{Analog, Digital, SensorScript};
use x10_sim::sim::{task, Sim, SimConfig};
use x10_tests::{ms, sens, thesis_frames};

#[test]
fn sequence_numbers_wrap_twice_around_a_pending_pulse_in() {
    let pulse = Rc::new(RefCell::new(None));
    let reads = Rc::new(RefCell::new(Vec::new()));
    let config = SimConfig {
        stop_when_tasks_done: true,
        ..thesis_frames(1_000)
    };
    let sim = Sim::new(config);
    // S1.A: an ultrasonic echo, first pulse at 150 ms, 1160 µs wide (20 cm).
    // S1.B: high.
    let ports = sim.ports("db09", 1, 1).with_sensor(
        1,
        SensorScript {
            a: Digital::Pulses {
                first_us: 150_000,
                period_us: 60_000,
                width_us: Analog::Const(1_160),
            },
            b: Digital::Const(true),
            ..SensorScript::default()
        },
    );
    let db = Address::external(9).unwrap();
    let (p, r) = (pulse.clone(), reads.clone());
    let o = sim
        .with_board(db, ports)
        .with_task(
            "ultrasonic",
            task(move |ctx| {
                Box::pin(async move {
                    ctx.clock.sleep_ns(ms(1)).await;
                    let op = Op::PulseIn {
                        pin: sens(1, Pin::A),
                        edge: Edge::Rising,
                        timeout_ms: Some(400),
                    };
                    let v = ctx.handle().call(db, op).await;
                    *p.borrow_mut() = Some((ctx.clock.now_ns(), v));
                })
            }),
        )
        .with_task(
            "reader",
            task(move |ctx| {
                Box::pin(async move {
                    ctx.clock.sleep_ns(ms(2)).await;
                    // ~230 µs each at 400 kHz: 600 reads take ~140 ms, past the echo.
                    for _ in 0..600 {
                        let v = ctx
                            .handle()
                            .call(db, Op::DigitalRead(sens(1, Pin::B)))
                            .await;
                        r.borrow_mut().push(v);
                    }
                })
            }),
        )
        .run()
        .unwrap();

    // The pulse-in answered `pending`, then its deferred reply came after the echo ended.
    let (t, v) = pulse.borrow_mut().take().unwrap();
    assert_eq!(v.unwrap().as_slice(), 1_160u32.to_le_bytes());
    assert!((ms(151)..ms(152)).contains(&t), "{t}");
    let reads = reads.borrow();
    assert_eq!(reads.len(), 600);
    assert!(reads
        .iter()
        .all(|r| r.as_ref().map(|p| p.as_slice()) == Ok(&[1][..])));

    // On the wire: the pulse-in's sequence number, then the reads' numbers wrapping past 255
    // twice without ever taking it while it was pending.
    let requests: Vec<(u64, Request<'_>)> = o
        .records
        .iter()
        .filter(|rec| rec.addr == 0x09)
        .filter_map(|rec| Request::parse(&rec.written).ok().map(|r| (rec.start_ns, r)))
        .collect();
    let (pulse_at, pulse_seq) = requests
        .iter()
        .find(|(_, r)| matches!(r.op, Op::PulseIn { .. }))
        .map(|(t, r)| (*t, r.seq))
        .unwrap();
    let during: Vec<u8> = requests
        .iter()
        .filter(|(at, r)| *at > pulse_at && *at < t && matches!(r.op, Op::DigitalRead(_)))
        .map(|(_, r)| r.seq)
        .collect();
    assert!(during.len() > 512, "{} reads while pending", during.len());
    assert!(!during.contains(&pulse_seq));
    let wraps = during.windows(2).filter(|w| w[1] < w[0]).count();
    assert!(wraps >= 2, "{wraps} wraps");
    // Every other number was used, in order, skipping only the pending one (and recently
    // ended ones, which the runtime also keeps out of reuse).
    assert!(during.windows(2).all(|w| w[1] != w[0]));
    assert_eq!(
        o.mb.late_replies + o.mb.duplicate_replies + o.mb.unknown_replies + o.mb.bad_replies,
        0
    );
    assert_eq!(o.mb.completed, 601);
}
