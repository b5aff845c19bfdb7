//! Every edge of an event pin reaches the motherboard: the real runtimes on the simulated bus,
//! checked against the pin's script (issue 22 items 12 and 13).
//!
//! The check ([`check`]): the events of the pin, added up in the order `wait_event` returned
//! them, must carry exactly the script's edges after the enable, rising and falling; after
//! each event the counts so far must be those of a prefix of the script (the last of those
//! edges at or before the event's arrival) and its level the level that prefix leaves.

use std::cell::RefCell;
use std::rc::Rc;

use x10_microcode::{Address, Edge, EventConfig, Op, Pin, PinRef, Port};
use x10_sim::exec::Nanos;
use x10_sim::ports::{Digital, SensorScript};
use x10_sim::sim::{task, Sim, SimConfig};

const MS: Nanos = 1_000_000;

fn db() -> Address {
    Address::external(0x10).unwrap()
}

fn event_pin() -> PinRef {
    Port::sensor(2).unwrap().pin(Pin::A)
}

/// What the tasks saw.
#[derive(Default)]
struct Seen {
    /// The enable call's start and end.
    enable: Option<(Nanos, Nanos)>,
    /// Per event: arrival, level, rising and falling counts.
    events: Vec<(Nanos, bool, u16, u16)>,
    /// Per pulse-in: start, end, result (µs) or the error's text.
    pulses: Vec<(Nanos, Nanos, Result<u32, String>)>,
}

/// Pulse-ins a run makes.
#[derive(Clone, Copy)]
enum Pulses {
    None,
    /// Back to back, once the events are on.
    AfterEnable,
    /// This many, back to back from the start: the first holds the pin when the events are
    /// enabled (5 ms after the start).
    FromStart(usize),
}

/// One run: board 0x10 with `script` on S2.A sampled every `sample_us`, events on both edges
/// of S2.A (one task enables them, then waits for events for ever); with `pulses`, a
/// second task measures rising pulses of S2.A (timeout 50 ms).
fn run(script: &Digital, sample_us: u32, pulses: Pulses, duration_ms: u64) -> Seen {
    let config = SimConfig {
        duration_ms,
        trace_calls: false,
        record_wire: false,
        ..SimConfig::default()
    };
    let mut sim = Sim::new(config);
    let ports = sim.ports("db10", 2, 2).with_sensor(
        2,
        SensorScript {
            a: script.clone(),
            ..SensorScript::default()
        },
    );
    sim = sim.with_board(db(), ports);
    sim.board_mut("db10").unwrap().config.sample_interval_us = sample_us;
    let seen = Rc::new(RefCell::new(Seen::default()));
    let s = seen.clone();
    let sim = sim.with_task(
        "events",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                let cfg = EventConfig {
                    rising: true,
                    falling: true,
                    ..EventConfig::OFF
                };
                if let Pulses::FromStart(_) = pulses {
                    ctx.clock.sleep_ns(5 * MS).await;
                }
                loop {
                    let started = ctx.clock.now_ns();
                    if x10
                        .call(db(), Op::EventEnable(event_pin(), cfg))
                        .await
                        .is_ok()
                    {
                        s.borrow_mut().enable = Some((started, ctx.clock.now_ns()));
                        break;
                    }
                    ctx.clock.sleep_ns(MS).await;
                }
                loop {
                    match x10.wait_event(db(), event_pin()).await {
                        Ok(ev) => {
                            let (level, r, f) = match ev.value.as_slice() {
                                [l, r0, r1, f0, f1] => (
                                    *l == 1,
                                    u16::from_le_bytes([*r0, *r1]),
                                    u16::from_le_bytes([*f0, *f1]),
                                ),
                                other => panic!("pin_change payload {other:?}"),
                            };
                            s.borrow_mut()
                                .events
                                .push((ctx.clock.now_ns(), level, r, f));
                        }
                        Err(e) => panic!("wait_event: {e}"),
                    }
                }
            })
        }),
    );
    let s = seen.clone();
    let sim = if let Pulses::AfterEnable | Pulses::FromStart(_) = pulses {
        sim.with_task(
            "pulse",
            task(move |ctx| {
                Box::pin(async move {
                    let x10 = ctx.handle();
                    let mut left = match pulses {
                        Pulses::FromStart(n) => n,
                        _ => usize::MAX,
                    };
                    while left == usize::MAX && s.borrow().enable.is_none() {
                        ctx.clock.sleep_ns(MS).await;
                    }
                    while left > 0 {
                        left -= 1;
                        let started = ctx.clock.now_ns();
                        let op = Op::PulseIn {
                            pin: event_pin(),
                            edge: Edge::Rising,
                            timeout_ms: Some(50),
                        };
                        let r = match x10.call(db(), op).await {
                            Ok(p) => match p.as_slice() {
                                [a, b, c, d] => Ok(u32::from_le_bytes([*a, *b, *c, *d])),
                                other => Err(format!("payload {other:?}")),
                            },
                            Err(e) => Err(e.to_string()),
                        };
                        s.borrow_mut().pulses.push((started, ctx.clock.now_ns(), r));
                    }
                })
            }),
        )
    } else {
        sim
    };
    let outcome = sim.run().unwrap();
    assert_eq!(outcome.spins, 0);
    let seen = std::mem::take(&mut *seen.borrow_mut());
    seen
}

/// Every edge of `script` in `(from, to]`: instant and new level.
fn edges(script: &Digital, from: Nanos, to: Nanos) -> Vec<(Nanos, bool)> {
    let mut v = Vec::new();
    let mut t = from;
    while let Some(e) = script.next_change_after(t).filter(|&e| e <= to) {
        v.push((e, script.level_at(e)));
        t = e;
    }
    v
}

/// Checks the events against the script (see the module doc); the first disagreement.
fn check(script: &Digital, seen: &Seen, end: Nanos) -> Result<(), String> {
    let (_, enabled) = seen.enable.ok_or("events never enabled")?;
    let truth = edges(script, enabled, end);
    let start_level = script.level_at(enabled);
    let (mut rising, mut falling) = (0usize, 0usize);
    for &(at, level, r, f) in &seen.events {
        rising += usize::from(r);
        falling += usize::from(f);
        let n = rising + falling;
        let prefix = truth.get(..n).ok_or_else(|| {
            format!(
                "event at {at} ns: {n} edges so far, the script made {}",
                truth.len()
            )
        })?;
        let want_r = prefix.iter().filter(|e| e.1).count();
        if (rising, falling) != (want_r, n - want_r) {
            return Err(format!(
                "event at {at} ns: {rising} rising / {falling} falling so far, the script's first {n} edges are {want_r} / {}",
                n - want_r
            ));
        }
        let want_level = prefix.last().map_or(start_level, |e| e.1);
        if level != want_level {
            return Err(format!(
                "event at {at} ns: level {level}, the script is {want_level} after {n} edges"
            ));
        }
        if let Some(&(t, _)) = prefix.last() {
            if t > at {
                return Err(format!("event at {at} ns reports an edge at {t} ns"));
            }
        }
    }
    if rising + falling != truth.len() {
        return Err(format!(
            "{} of {} edges delivered; the last delivered event came at {:?} ns, the last edge at {:?} ns",
            rising + falling,
            truth.len(),
            seen.events.last().map(|e| e.0),
            truth.last().map(|e| e.0),
        ));
    }
    Ok(())
}

/// Issue 22 item 12: a pin that toggles every 1 ms and then stops. Its last edges are latched
/// while its previous event is still queued; they must go out once that event leaves the
/// queue (before the fix nothing woke the sampler and they waited for an edge that never
/// came). Twelve stop instants, 100 µs sampling, 400 kHz.
#[test]
fn the_last_edge_of_a_pin_that_stops_toggling_is_reported() {
    let mut failures = Vec::new();
    for toggles in 20..32u64 {
        let script = Digital::Toggles {
            initial: false,
            toggles_ms: (0..toggles).map(|k| 60 + k).collect(),
        };
        let duration_ms = 60 + toggles + 100;
        let seen = run(&script, 100, Pulses::None, duration_ms);
        let (_, enabled) = seen.enable.unwrap();
        assert!(enabled < 60 * MS, "enabled at {enabled} ns");
        if let Err(e) = check(&script, &seen, duration_ms * MS) {
            failures.push(format!("{toggles} toggles: {e}"));
        }
        // The last event reports the final level within 5 ms of the last edge: the event
        // queued before it goes out, then this one, each after the board's pacing gap
        // (0.5 to 1.5 ms, `TargetConfig::event_gap_us`) and its transfer.
        let last_edge = (60 + toggles - 1) * MS;
        let last = seen.events.last().copied();
        if !last.is_some_and(|(at, level, _, _)| {
            level == (toggles % 2 == 1) && at <= last_edge + 5 * MS
        }) {
            failures.push(format!(
                "{toggles} toggles: last event {last:?}, last edge at {last_edge} ns"
            ));
        }
    }
    assert_eq!(failures, Vec::<String>::new());
}

/// Issue 22 item 13: pulse-in on a pin with events. The sampler's read fails `Busy` while the
/// pulse-in holds the pin; the edges it had taken must not be lost, and the events must keep
/// matching the pin. Every pulse-in measures the script's width.
#[test]
fn pulse_in_on_an_event_pin_loses_no_edge() {
    // High 2 ms every 7 ms, from 50 ms to 500 ms.
    let toggles_ms: Vec<u64> = (0..65).flat_map(|k| [50 + 7 * k, 52 + 7 * k]).collect();
    let last_rise = toggles_ms[toggles_ms.len() - 2] * MS;
    let script = Digital::Toggles {
        initial: false,
        toggles_ms,
    };
    let duration_ms = 650;
    for sample_us in [10_000, 100] {
        let seen = run(&script, sample_us, Pulses::AfterEnable, duration_ms);
        assert_eq!(
            check(&script, &seen, duration_ms * MS),
            Ok(()),
            "sampling every {sample_us} us"
        );
        let (before, after): (Vec<_>, Vec<_>) = seen.pulses.iter().partition(|p| p.0 < last_rise);
        assert!(before.len() > 50, "{} pulse-ins", before.len());
        for (started, ended, r) in before {
            assert_eq!(r, &Ok(2_000), "pulse-in from {started} to {ended} ns");
        }
        for (started, ended, r) in after.iter().filter(|p| p.1 < duration_ms * MS) {
            assert_eq!(
                r,
                &Err("board answered timeout".to_string()),
                "pulse-in from {started} to {ended} ns"
            );
        }
    }
}

/// Issue 22 item 13, the first sample: a pulse-in holds the pin when the events are enabled
/// and through the first edges, so no level has been read yet. The edges are carried until
/// the pin is free again (the pulse-in's end wakes the sampler), none lost.
#[test]
fn edges_latched_before_the_first_level_read_are_carried() {
    let toggles_ms: Vec<u64> = (0..20).flat_map(|k| [30 + 7 * k, 32 + 7 * k]).collect();
    let script = Digital::Toggles {
        initial: false,
        toggles_ms,
    };
    let duration_ms = 400;
    for sample_us in [10_000, 100] {
        let seen = run(&script, sample_us, Pulses::FromStart(3), duration_ms);
        let (started, _) = seen.enable.unwrap();
        assert!(seen.pulses[0].0 < started, "{:?}", seen.pulses[0]);
        assert_eq!(
            check(&script, &seen, duration_ms * MS),
            Ok(()),
            "sampling every {sample_us} us"
        );
        let widths: Vec<_> = seen.pulses.iter().map(|p| p.2.clone()).collect();
        assert_eq!(widths, [Ok(2_000), Ok(2_000), Ok(2_000)]);
    }
}
