//! The thesis's robot programs (Figures 4.2, 4.4, 4.6) in the simulator: the actuators follow
//! the scripted signals of their worlds (`robots/worlds/*.toml`), at every bus clock.

use x10_microcode::Pin;
use x10_sim::sim::{Sim, SimConfig, SimOutcome};
use x10_sim::timing::Speed;
use x10_tests::{act, duties, levels, ms};

fn run(program: &str, speed: Speed) -> SimOutcome {
    let config = SimConfig {
        speed,
        ..SimConfig::default()
    };
    match x10_sim::examples::sim(program, config).map(Sim::run) {
        Some(Ok(o)) => o,
        None => panic!("no example {program}"),
        Some(Err(e)) => panic!("{program} at {speed}: {e}"),
    }
}

/// Figure 4.2's motor on the internal board: IN1 (A1.A) and EN (PWM A1.A).
fn assert_fig4_2_motor(o: &SimOutcome) {
    let a1a = act(1, Pin::A);
    // Boot safe state at 0, then: button pressed at 2.0 s (debounced: two agreeing reads 20 ms
    // apart), released at 3.0 s (then the force sensor is read), force 350 from 3.6 s to 4.2 s
    // (port calls take no virtual time: the boards' 2 µs ADC conversion is not simulated).
    assert_eq!(
        levels(&o.log, "mb", a1a),
        vec![
            (0, false),
            (ms(2_020), true),
            (ms(3_020), false),
            (ms(3_600), true),
            (ms(4_200), false),
        ]
    );
    assert_eq!(
        duties(&o.log, "mb", a1a),
        vec![
            (ms(2_020), 255),
            (ms(3_020), 0),
            (ms(3_600), 255),
            (ms(4_200), 0),
        ]
    );
    // IN2 stays low: forward only, and off is coast (both low), never reverse.
    assert_eq!(levels(&o.log, "mb", act(1, Pin::B)), vec![(0, false)]);
    assert_eq!(
        o.log.level_at("mb", a1a, ms(2_500)).map(|l| l.is_high()),
        Some(true)
    );
    assert_eq!(
        o.log.level_at("mb", a1a, ms(3_300)).map(|l| l.is_high()),
        Some(false)
    );
}

#[test]
fn fig4_2_button_or_force_runs_the_motor_on_the_internal_board() {
    let o = run("fig4_2", Speed::Fast);
    assert_fig4_2_motor(&o);
    // Everything is on the internal board: nothing on the bus.
    assert!(o.records.is_empty());
    assert_eq!(
        o.mb.timeouts + o.mb.nacks + o.mb.bad_replies + o.mb.status_errors,
        0
    );
}

#[test]
fn fig4_4_adds_the_light_module_without_changing_fig4_2() {
    let o = run("fig4_4", Speed::Fast);
    // The first program behaves exactly as alone, to the nanosecond.
    assert_fig4_2_motor(&o);
    let alone = run("fig4_2", Speed::Fast);
    assert_eq!(
        o.log.changes().iter().filter(|c| c.board == "mb").count(),
        alone.log.len()
    );
    // DB 9's motor: on when the light passes 700 (1.93 s, seen at the next 10 ms step), half
    // power (duty 127), off when the light drops to 300 at 4.0 s.
    let a1a = act(1, Pin::A);
    let on = levels(&o.log, "db09", a1a);
    assert_eq!(on.len(), 3, "{on:?}");
    assert_eq!(on[0], (0, false));
    assert!(
        on[1].1 && (ms(1_931)..ms(1_945)).contains(&on[1].0),
        "{on:?}"
    );
    assert!(
        !on[2].1 && (ms(4_000)..ms(4_005)).contains(&on[2].0),
        "{on:?}"
    );
    let d = duties(&o.log, "db09", a1a);
    assert_eq!(d.iter().map(|(_, v)| *v).collect::<Vec<_>>(), vec![127, 0]);
    assert_eq!(levels(&o.log, "db09", act(1, Pin::B)), vec![(0, false)]);
    // Every request ended with a value (the run ends between two requests; while the ADC's
    // 2 µs were simulated, it ended with one in flight).
    assert_eq!(o.mb.requests, o.mb.completed, "{:?}", o.mb);
    assert_eq!(o.board("db09").map(|d| d.events_sent), Some(1));
}

#[test]
fn fig4_4_at_every_bus_clock() {
    for speed in Speed::ALL {
        let o = run("fig4_4", speed);
        assert_fig4_2_motor(&o);
        let on = levels(&o.log, "db09", act(1, Pin::A));
        assert_eq!(on.len(), 3, "{speed}: {on:?}");
        // Light above 700 from 1.930 s; the next 20 ms step reads it and drives the motor (at
        // 100 kHz, with PEC on every frame and each output read back, the three writes end
        // at about 1.951 s).
        assert!((ms(1_931)..ms(1_955)).contains(&on[1].0), "{speed}: {on:?}");
        assert!((ms(4_000)..ms(4_015)).contains(&on[2].0), "{speed}: {on:?}");
        assert_eq!(o.mb.timeouts + o.mb.nacks + o.mb.bad_replies, 0, "{speed}");
        // Slower clock, longer transactions: the bus time of the same analog read scales.
        let read = o
            .records
            .iter()
            .find(|r| r.is_read && r.written.first() == Some(&0x30))
            .map(|r| r.duration_ns());
        // The safe defaults put a PEC byte on both frames: 4 + 1 written, 5 + 1 read.
        let wire = speed.timing().write_read_ns(5, 6);
        assert_eq!(
            read,
            Some(wire),
            "{speed}: the analog read's wire time (the boards' 2 us ADC stretch is not simulated)"
        );
    }
}

#[test]
fn fig4_6_raises_the_alarm_when_the_freezer_passes_1_c_and_latches() {
    for speed in Speed::ALL {
        let o = run("fig4_6", speed);
        let alarm = act(3, Pin::A);
        let l = levels(&o.log, "db0a", alarm);
        // Low from setup (after the boot safe state), high once, never low again.
        assert_eq!(l.len(), 2, "{speed}: {l:?}");
        assert_eq!(l[0], (0, false));
        // The freezer passes 1 °C at about 3.17 s (raw 250 → 1.0x °C on the thesis divider).
        assert!(
            l[1].1 && (ms(3_150)..ms(3_200)).contains(&l[1].0),
            "{speed}: {l:?}"
        );
        assert_eq!(
            o.log
                .level_at("db0a", alarm, ms(5_000))
                .map(|l| l.is_high()),
            Some(true)
        );
        // Before the alarm the oven (hot, 250 °F) is read every step; after it, only the
        // freezer (the C `||` short-circuits). The oven's board then hears only the
        // motherboard's failsafe heartbeats (writes).
        let oven_reads_after = o
            .records
            .iter()
            .filter(|r| r.addr == 0x6c && r.is_read && r.start_ns > l[1].0)
            .count();
        assert_eq!(oven_reads_after, 0, "{speed}");
        assert!(o
            .records
            .iter()
            .any(|r| r.addr == 0x6c && r.start_ns < l[1].0));
    }
}
