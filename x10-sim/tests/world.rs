//! World files and device timelines: against the thesis scenarios, the real drivers and the
//! boards crate; the summary and the plot.

use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

use x10_devices::{
    Actuator, AnalogSensor, Button, DcMotor, Degrees, DigitalOutput, Duty, Level, Output, Servo,
    Thermistor, Ultrasonic,
};
use x10_microcode::{Address, Pin, PortKind};
use x10_sim::ports::Change;
use x10_sim::sim::{task, SimConfig, SimOutcome};

mod scenario;
use x10_sim::timeline::{
    summary, timeline_html, timeline_svg, write_timeline, MotorState, Timeline,
};
use x10_sim::timing::Speed;
use x10_sim::world::{Board, BoardKind, Device, Signal, World, SELF};

const MS: u64 = 1_000_000;

fn repo_file(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path)
}

fn load(name: &str) -> World {
    match World::load(repo_file(&format!("robots/worlds/{name}"))) {
        Ok(w) => w,
        Err(e) => panic!("{name}: {e}"),
    }
}

fn db(n: u8) -> Address {
    Address::external(n).unwrap()
}

/// Sample instants (ns): a regular grid that is not aligned to ms, and each boundary of the
/// scenarios ±1 ns.
fn sample_times() -> Vec<u64> {
    let mut v: Vec<u64> = (0..5_600).map(|i| i * 999_983).collect();
    for ms in [500, 1_930, 2_000, 2_500, 3_000, 3_600, 4_000, 4_200] {
        let t = ms * MS;
        v.extend([t - 1, t, t + 1, t - 1_000, t + 1_000]);
    }
    v
}

#[test]
fn world_files_give_exactly_the_scenario_signals() {
    let times = sample_times();
    for file in ["fig4_2.toml", "fig4_4.toml"] {
        let w = load(file);
        let s1 = w.sensor_script(SELF, 1).unwrap();
        let s2 = w.sensor_script(SELF, 2).unwrap();
        for &t in &times {
            let ms = t / MS;
            let force = if (scenario::FORCE_FROM_MS..scenario::FORCE_UNTIL_MS).contains(&ms) {
                350
            } else {
                40
            };
            assert_eq!(s1.analog.value_at(t), force, "{file} force at {t} ns");
            let pressed = (scenario::BUTTON_PRESS_MS..scenario::BUTTON_RELEASE_MS).contains(&ms);
            assert_eq!(s2.b.level_at(t), pressed, "{file} button at {t} ns");
            assert!(!s1.a.level_at(t) && !s1.b.level_at(t) && !s2.a.level_at(t));
            assert_eq!(s2.analog.value_at(t), 0);
        }
    }
    let w = load("fig4_4.toml");
    let light = w.sensor_script(9, 1).unwrap();
    for &t in &times {
        assert_eq!(
            light.analog.value_at(t),
            scenario::light_level(t / 1_000),
            "light at {t} ns"
        );
    }
    let w = load("fig4_6.toml");
    let freezer = w.sensor_script(17, 1).unwrap();
    let oven = w.sensor_script(108, 6).unwrap();
    for &t in &times {
        let want = scenario::thermistor_raw(scenario::freezer_celsius(t / 1_000));
        assert_eq!(freezer.analog.value_at(t), want, "freezer at {t} ns");
        assert_eq!(
            oven.analog.value_at(t),
            scenario::thermistor_raw(scenario::OVEN_CELSIUS)
        );
    }
    for port in 1..=5 {
        assert_eq!(w.sensor_script(108, port).unwrap().analog.value_at(0), 0);
    }
    // The boards, with the scenario's port counts.
    let counts = |w: &World| -> Vec<(String, u8, u8)> {
        w.boards()
            .iter()
            .map(|b| {
                (
                    b.log_name(),
                    b.kind().sensor_ports(),
                    b.kind().actuator_ports(),
                )
            })
            .collect()
    };
    let s = |n: &str, a, b| (n.to_string(), a, b);
    assert_eq!(counts(&load("fig4_2.toml")), vec![s("mb", 2, 2)]);
    assert_eq!(
        counts(&load("fig4_4.toml")),
        vec![s("mb", 2, 2), s("db09", 2, 2)]
    );
    assert_eq!(
        counts(&w),
        vec![
            s("mb", 2, 2),
            s("db11", 2, 2),
            s("db6c", 6, 2),
            s("db0a", 2, 3)
        ]
    );
}

#[test]
fn world_files_run_the_thesis_programs_exactly_as_the_scenarios_do() {
    for (file, program) in [
        ("fig4_2.toml", "fig4_2"),
        ("fig4_4.toml", "fig4_4"),
        ("fig4_6.toml", "fig4_6"),
    ] {
        let world = load(file);
        let config = SimConfig::default();
        let from_world = x10_sim::examples::with_tasks(program, world.sim(config).unwrap())
            .unwrap()
            .run()
            .unwrap();
        let from_scenario =
            x10_sim::examples::with_tasks(program, scenario::build(program, config).unwrap())
                .unwrap()
                .run()
                .unwrap();
        assert_eq!(
            from_world.trace.render(),
            from_scenario.trace.render(),
            "{file}"
        );
    }
}

#[test]
fn the_thesis_timelines_say_what_the_scenario_docs_say() {
    // tests/scenario: "fig4_2's motor runs from about 2.0 s to 3.0 s (button) and from 3.6 s to
    // 4.2 s (force); fig4_4's second motor runs from about 1.93 s to 4.0 s; fig4_6's alarm
    // goes on when the freezer passes 1 °C, at about 3.17 s, and stays on."
    let run = |file: &str, p: &str| {
        let w = load(file);
        let o = w
            .sim(SimConfig::default())
            .map(|sim| x10_sim::examples::with_tasks(p, sim).unwrap())
            .unwrap()
            .run()
            .unwrap();
        (Timeline::new(&w, &o), o)
    };
    let (tl, _) = run("fig4_4.toml", "fig4_4");
    let m = tl.motor("motor").unwrap();
    let on: Vec<(u64, MotorState)> = m.changes().iter().map(|(t, s)| (t / MS, *s)).collect();
    assert_eq!(
        on,
        vec![
            (2_020, MotorState::forward(100)),
            (3_020, MotorState::STOPPED),
            (3_600, MotorState::forward(100)),
            (4_200, MotorState::STOPPED),
        ]
    );
    let lm = tl.motor("light_motor").unwrap();
    assert_eq!(lm.at_ms(1_900), MotorState::STOPPED);
    assert_eq!(lm.at_ms(2_000), MotorState::forward(50));
    assert_eq!(lm.at_ms(4_100), MotorState::STOPPED);
    let (tl, _) = run("fig4_6.toml", "fig4_6");
    let alarm = tl.led("alarm").unwrap();
    // The program reads every 20 ms (x10_robots::PERIOD): the first read above 1 °C (each
    // frame with its PEC byte, the safe default).
    assert_eq!(alarm.first_ns(|on| *on).map(|t| t / MS), Some(3_183));
    assert!(alarm.last_state());
}

#[test]
fn the_bumper_file_is_the_builder_world() {
    let built = World::new()
        .board(Board::internal(2, 2))
        .board(Board::new(9, 2, 2))
        .device(
            Device::light_sensor("light", SELF, 1)
                .counts(Signal::linear([(0, 100.0), (4_000, 800.0)])),
        )
        .device(
            Device::button("bumper", SELF, 2, Pin::B)
                .pressed_at_ms(1_000, 50)
                .pressed_at_ms(3_000, 50),
        )
        .device(Device::dc_motor("drive", SELF, 1))
        .device(Device::dimmable_led("lamp", SELF, 2, Pin::A))
        .device(Device::led("heartbeat", 9, 1, Pin::A));
    assert_eq!(load("bumper.toml"), built);
}

#[test]
fn board_kinds_have_the_port_counts_of_the_pin_maps() {
    use x10_boards::pins::{G431, PICO};
    assert_eq!(
        BoardKind::PICO_PORTS,
        (PICO.sensor_ports(), PICO.actuator_ports())
    );
    assert_eq!(
        BoardKind::G431_PORTS,
        (G431.sensor_ports(), G431.actuator_ports())
    );
}

/// Runs `world` with one task `f` for `ms`; returns the outcome.
fn run_with<F>(world: &World, speed: Speed, ms: u64, f: F) -> SimOutcome
where
    F: FnOnce(x10_sim::sim::Ctx) -> x10_sim::sim::LocalFuture + 'static,
{
    let config = SimConfig {
        speed,
        duration_ms: ms,
        ..SimConfig::default()
    };
    world
        .sim(config)
        .unwrap()
        .with_task("robot", task(f))
        .run()
        .unwrap()
}

#[test]
fn the_ranger_driver_reads_the_scripted_distance() {
    // 2 m closing in to 0.2 m over 4 s.
    let profile = Signal::linear([(0, 2_000.0), (4_000, 200.0)]);
    for (speed, board) in [
        (Speed::Fast, 0u8),
        (Speed::Fast, 9),
        (Speed::FastPlus, 9),
        (Speed::Standard, 0),
    ] {
        let world = World::new()
            .board(Board::new(9, 2, 2))
            .device(Device::ultrasonic("sonar", board, 1).distance_mm(profile.clone()));
        let got = Rc::new(RefCell::new(Vec::new()));
        let g = got.clone();
        let target = if board == 0 { SELF } else { db(9) };
        let o = run_with(&world, speed, 4_500, move |ctx| {
            Box::pin(async move {
                let sonar = Ultrasonic::new(ctx.handle(), target, 1).unwrap();
                for _ in 0..40 {
                    ctx.clock.sleep_ns(100 * MS).await;
                    let d = sonar.distance().await;
                    g.borrow_mut().push(d.map(|d| d.map(|mm| mm.0)));
                }
            })
        });
        // Each echo starts 500 µs after the end of its trigger pulse (S1.A falling); the
        // driver must read the scripted distance at that instant, in whole millimetres.
        let name = if board == 0 { "mb" } else { "db09" };
        let trigger = x10_microcode::Port::new(PortKind::Sensor, 1)
            .unwrap()
            .pin(Pin::A);
        let falls: Vec<u64> = o
            .log
            .of(name, trigger)
            .iter()
            .filter(|c| c.change == Change::Digital(Level::Low))
            .map(|c| c.t_ns)
            .collect();
        let want: Vec<_> = falls
            .iter()
            .map(|t| Ok(Some(profile.value_at_us(t / 1_000 + 500).floor() as u32)))
            .collect();
        assert_eq!(falls.len(), 40, "{speed:?} {name}");
        assert_eq!(*got.borrow(), want, "{speed:?} {name}");
    }
    // At 100 kHz the pulse-in request to an external board takes longer than the HC-SR04's
    // 0.5 ms before its echo: the echo has already risen, the driver reads "nothing in
    // range", as the driver's documentation warns.
    let world = World::new()
        .board(Board::new(9, 2, 2))
        .device(Device::ultrasonic("sonar", 9, 1));
    let got = Rc::new(RefCell::new(Vec::new()));
    let g = got.clone();
    run_with(&world, Speed::Standard, 200, move |ctx| {
        Box::pin(async move {
            let sonar = Ultrasonic::new(ctx.handle(), db(9), 1).unwrap();
            ctx.clock.sleep_ns(20 * MS).await;
            let d = sonar.distance().await;
            g.borrow_mut().push(d.map(|d| d.map(|mm| mm.0)));
        })
    });
    assert_eq!(*got.borrow(), vec![Ok(None)]);
}

/// Reads the ranger on DB 9 every 100 ms with an embassy `Ticker`, 12 times; with `pause`,
/// the task is held up for 1 s first (a slow call, a long computation), and the ticker fires
/// the ticks it missed back to back: a burst of reads.
async fn sonar_ticker(x10: x10_sim::sim::X10, pause: bool) -> Result<(), x10_devices::Error> {
    let sonar = Ultrasonic::new(x10, db(9), 1)?;
    let mut ticker = embassy_time::Ticker::every(embassy_time::Duration::from_millis(100));
    if pause {
        embassy_time::Timer::after_millis(1_000).await;
    }
    for _ in 0..12 {
        ticker.next().await;
        sonar.distance().await?;
    }
    Ok(())
}

#[test]
fn a_ticker_burst_of_ultrasonic_reads_gets_no_echo_and_a_warning() {
    let world = World::new()
        .board(Board::new(9, 2, 2))
        .device(Device::ultrasonic("sonar", 9, 1).distance_mm(Signal::constant(500.0)));
    let run = |pause: bool| {
        world
            .sim(SimConfig {
                duration_ms: 2_500,
                ..SimConfig::default()
            })
            .unwrap()
            .with_robot("sonar", move |x10| sonar_ticker(x10, pause))
            .run()
            .unwrap()
    };
    // Paced at 100 ms: every read is answered, nothing to warn about.
    let paced = run(false);
    assert_eq!(paced.device_warnings, Vec::<String>::new());
    assert!(summary(&world, &paced).ends_with("warnings and errors: none\n"));
    // After the pause, the ticker's catch-up fires reads back to back: the HC-SR04 ignores
    // the triggers closer than 60 ms to its last measurement (no echo), and the run warns.
    let burst = run(true);
    // The burst: a read answered, the next 4.104 ms later ignored (it waits out its 30 ms
    // pulse-in timeout), the next 35.001 ms after the answered one ignored too, the next
    // answered; four times over, then the ticks are caught up.
    let ignored = |ms: &str| {
        format!("ultrasonic on S1.B: measurement {ms} ms after the last one, under the part's 60 ms minimum: no echo")
    };
    let want: Vec<String> = (0..4)
        .flat_map(|_| [ignored("4.104"), ignored("35.001")])
        .collect();
    assert_eq!(burst.device_warnings, want);
    let first = &want[0];
    let text = summary(&world, &burst);
    assert!(
        text.contains(&format!("WARN  db09: {first}")),
        "the summary lists the warning:\n{text}"
    );
}

#[test]
fn the_thermistor_driver_reads_the_scripted_temperature() {
    let profile = Signal::linear([(0, -20.0), (2_000, 100.0)]);
    let world = World::new()
        .board(Board::pico(9))
        .device(Device::thermistor("thesis", SELF, 1).celsius(profile.clone()))
        .device(
            Device::thermistor("fine", 9, 3)
                .celsius(profile.clone())
                .thermistor_config(
                    x10_devices::ThermistorConfig::new(
                        x10_devices::SteinhartHart::THESIS,
                        10_000,
                        12,
                        x10_devices::Divider::ThermistorLow,
                    )
                    .unwrap(),
                ),
        );
    let got = Rc::new(RefCell::new(Vec::new()));
    let g = got.clone();
    run_with(&world, Speed::Fast, 2_100, move |ctx| {
        Box::pin(async move {
            let thesis = Thermistor::new(ctx.handle(), SELF, 1).unwrap();
            let cfg = x10_devices::ThermistorConfig::new(
                x10_devices::SteinhartHart::THESIS,
                10_000,
                12,
                x10_devices::Divider::ThermistorLow,
            )
            .unwrap();
            let fine = Thermistor::with_config(ctx.handle(), db(9), 3, cfg).unwrap();
            for _ in 0..20 {
                ctx.clock.sleep_ns(100 * MS).await;
                let t = ctx.clock.now_ns();
                let a = thesis.celsius().await.unwrap().0;
                let b = fine.celsius().await.unwrap().0;
                g.borrow_mut().push((t, a, b));
            }
        })
    });
    let got = got.borrow();
    assert_eq!(got.len(), 20);
    for &(t, a, b) in got.iter() {
        let want = profile.value_at_us(t / 1_000) as f32;
        // The 10-bit thesis divider is within half a count (< 0.5 °C here), the 12-bit one
        // within 0.1 °C; the reading is taken up to 0.3 ms after `t`.
        assert!((a - want).abs() < 0.5, "{t}: {a} vs {want}");
        assert!((b - want).abs() < 0.1, "{t}: {b} vs {want}");
    }
}

#[test]
fn the_timeline_of_a_run_reads_in_device_words() {
    let world = World::new()
        .board(Board::new(9, 2, 3))
        .device(Device::dc_motor("left", SELF, 1))
        .device(Device::dc_motor("right", 9, 1))
        .device(Device::servo("arm", 9, 2, Pin::A))
        .device(Device::led("heartbeat", 9, 3, Pin::A))
        .device(Device::dimmable_led("lamp", SELF, 2, Pin::A));
    for speed in [Speed::Standard, Speed::Fast, Speed::FastPlus] {
        let o = run_with(&world, speed, 5_000, |ctx| {
            Box::pin(async move {
                let link = ctx.handle();
                let mut left = DcMotor::new(link, SELF, 1).unwrap();
                let mut right = DcMotor::new(link, db(9), 1).unwrap();
                let arm = Servo::new(link, db(9), 2, Pin::A).unwrap();
                let mut heartbeat = DigitalOutput::new(link, db(9), 3, Pin::A).unwrap();
                let lamp = Actuator::new(link, SELF, 2).unwrap();
                let at = |ms: u64| ctx.clock.sleep_until_ns(ms * MS);
                at(100).await;
                arm.init().await.unwrap();
                arm.set_angle(Degrees(90)).await.unwrap();
                at(1_000).await;
                left.set_percent(50).await.unwrap();
                right.set_percent(50).await.unwrap();
                heartbeat.set(Level::High).await.unwrap();
                lamp.pwm(Pin::A, Duty(102)).await.unwrap();
                at(2_000).await;
                left.set_percent(-30).await.unwrap();
                right.set_percent(-30).await.unwrap();
                arm.set_angle(Degrees(180)).await.unwrap();
                heartbeat.set(Level::Low).await.unwrap();
                at(3_000).await;
                left.brake().await.unwrap();
                right.brake().await.unwrap();
                arm.release().await.unwrap();
                at(4_000).await;
                left.stop().await.unwrap();
                right.stop().await.unwrap();
                lamp.pwm(Pin::A, Duty(0)).await.unwrap();
            })
        });
        let tl = Timeline::new(&world, &o);
        for motor in ["left", "right"] {
            let m = tl.motor(motor).unwrap();
            assert_eq!(
                m.states(),
                vec![
                    MotorState::STOPPED,
                    MotorState::forward(50),
                    MotorState::reverse(30),
                    MotorState::BRAKE,
                    MotorState::STOPPED
                ],
                "{speed:?} {motor}"
            );
            // Each change is dated by the first write of its command. The first command to a
            // daughterboard waits for the motherboard to prepare it (PEC on, failsafe set,
            // each read back): up to 1 ms more at 100 kHz.
            let times: Vec<u64> = m.changes().iter().map(|(t, _)| t / MS).collect();
            assert_eq!(
                times.get(1..),
                Some(&[2_000, 3_000, 4_000][..]),
                "{speed:?} {motor}"
            );
            assert!(
                (1_000..=1_001).contains(&times[0]),
                "{speed:?} {motor} {times:?}"
            );
            assert_eq!(m.at_ms(1_500), MotorState::forward(50));
            assert_eq!(m.at_ms(2_500).signed_percent(), -30);
        }
        let arm = tl.servo("arm").unwrap();
        assert_eq!(arm.states(), vec![None, Some(90), Some(180), None]);
        let hb = tl.led("heartbeat").unwrap();
        assert!(!hb.at_ms(900) && hb.at_ms(1_500) && !hb.at_ms(2_500));
        let lamp = tl.brightness("lamp").unwrap();
        assert_eq!(lamp.states(), vec![0, 40, 0]);
    }
}

#[test]
fn a_reset_board_stops_its_outputs_in_the_timeline() {
    let world = World::new()
        .board(Board::new(9, 2, 2))
        .device(Device::dc_motor("right", 9, 1));
    let config = SimConfig {
        duration_ms: 1_000,
        ..SimConfig::default()
    };
    let o = world
        .sim(config)
        .unwrap()
        .reset_at("db09", 500, 10)
        .with_task(
            "robot",
            task(|ctx| {
                Box::pin(async move {
                    ctx.clock.sleep_ns(100 * MS).await;
                    let mut right = DcMotor::new(ctx.handle(), db(9), 1).unwrap();
                    right.set_percent(80).await.unwrap();
                })
            }),
        )
        .run()
        .unwrap();
    let tl = Timeline::new(&world, &o);
    let m = tl.motor("right").unwrap();
    assert_eq!(
        m.changes()
            .iter()
            .map(|(t, s)| (t / MS, *s))
            .collect::<Vec<_>>(),
        vec![(100, MotorState::forward(80)), (500, MotorState::STOPPED)]
    );
}

/// The bumper robot of `robots/worlds/bumper.toml`, as a test task: drive forward at 50 %;
/// on a bump, back off for 300 ms at 30 %; the lamp's brightness follows the light (brighter
/// when darker); the heartbeat on db09 blinks every 250 ms.
fn bumper_robot(ctx: x10_sim::sim::Ctx) -> x10_sim::sim::LocalFuture {
    Box::pin(async move {
        let link = ctx.handle();
        let mut drive = DcMotor::new(link, SELF, 1).unwrap();
        let mut bumper = Button::new(link, SELF, 2, Pin::B).unwrap();
        let light = AnalogSensor::new(link, SELF, 1).unwrap();
        let lamp = Actuator::new(link, SELF, 2).unwrap();
        let mut heartbeat = DigitalOutput::new(link, db(9), 1, Pin::A).unwrap();
        let mut backing_until = None;
        let mut lamp_duty = None;
        let mut step = 0u64;
        loop {
            ctx.clock.sleep_until_ns(step * 10 * MS).await;
            let now = ctx.clock.now_ns();
            if step.is_multiple_of(25) {
                let on = (step / 25).is_multiple_of(2);
                let _ = heartbeat.set(Level::from_bool(on)).await;
            }
            if bumper.is_pressed().await.unwrap_or(false) && backing_until.is_none() {
                backing_until = Some(now + 300 * MS);
                let _ = drive.set_percent(-30).await;
            }
            match backing_until {
                Some(t) if now < t => {}
                _ => {
                    backing_until = None;
                    if drive.speed() != Some(x10_devices::Speed::new(50).unwrap()) {
                        let _ = drive.set_percent(50).await;
                    }
                }
            }
            if let Ok(raw) = light.read_raw().await {
                // Darker, brighter: 4 levels of 25 %.
                let level = 3 - (raw / 256).min(3);
                let duty = Duty(u8::try_from(level * 85).unwrap_or(255));
                if lamp_duty != Some(duty) && lamp.pwm(Pin::A, duty).await.is_ok() {
                    lamp_duty = Some(duty);
                }
            }
            step += 1;
        }
    })
}

#[test]
fn the_summary_of_a_run_is_short_and_exact() {
    let world = load("bumper.toml");
    let config = SimConfig {
        duration_ms: 5_000,
        ..SimConfig::default()
    };
    let o = world
        .sim(config)
        .unwrap()
        .reset_at("db09", 4_000, 5)
        .with_task("bumper_bot", task(bumper_robot))
        .run()
        .unwrap();
    let text = summary(&world, &o);
    assert_eq!(
        text,
        "\
devices, 5.000 s at 400k:
     script  light      light sensor on mb S1: 100 counts at 0 s, 800 at 4 s, linear in between
     script  bumper     button on mb S2.B: pressed at 1 s for 50 ms, at 3 s for 50 ms
    0.000 s  drive      forward 50 %
    1.010 s  drive      reverse 30 %
    1.310 s  drive      forward 50 %
    3.010 s  drive      reverse 30 %
    3.310 s  drive      forward 50 %
    0.001 s  lamp       brightness 100 %
    0.900 s  lamp       brightness 67 %
    2.360 s  lamp       brightness 34 %
    3.820 s  lamp       off
    0.001 s  heartbeat  on
    0.250 s  heartbeat  off
    0.500 s  heartbeat  on
    0.750 s  heartbeat  off
    1.000 s  heartbeat  on
    1.250 s  heartbeat  off
    1.500 s  heartbeat  on
    1.750 s  heartbeat  off
             heartbeat  … 10 more, the last at 4.750 s: off
bus: 70 transactions, busy 12.7 ms = 0.25 % of the run; 5 NACK, 0 arbitration lost, 0 timeouts, 0 bus faults, 1 resets
warnings and errors: 7
  4.000000 WARN  mb: -> db09 io high A1.A seq 50 +pec [12 09 00 32 19] bus 25us NACK (address)
  4.000000 WARN  db09: reset: firmware restarts at 4.005000
  4.000144 WARN  mb: -> db09 io high A1.A seq 50 +pec [12 09 00 32 19] bus 25us NACK (address)
  4.000413 WARN  mb: -> db09 io high A1.A seq 50 +pec [12 09 00 32 19] bus 25us NACK (address)
  4.000840 WARN  mb: -> db09 io high A1.A seq 50 +pec [12 09 00 32 19] bus 25us NACK (address)
  … 2 more
"
    );
}

#[test]
fn the_timeline_plot_is_well_formed_and_labelled() {
    let world = load("bumper.toml");
    let config = SimConfig {
        duration_ms: 5_000,
        ..SimConfig::default()
    };
    let o = world
        .sim(config)
        .unwrap()
        .with_task("bumper_bot", task(bumper_robot))
        .run()
        .unwrap();
    let svg = timeline_svg(&world, &o);
    let doc = match roxmltree::Document::parse(&svg) {
        Ok(d) => d,
        Err(e) => panic!("{e}\n{svg}"),
    };
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert_eq!(root.attribute("width"), Some("1000"));
    // Title, then per device its name, description and scale.
    let texts: Vec<&str> = root
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| n.text())
        .collect();
    assert_eq!(
        texts[..4],
        [
            "X10 timeline: 5.000 s of virtual time, bus at 400k",
            "light",
            "light sensor on mb S1",
            "scripted · 100 … 800 counts"
        ]
    );
    for name in [
        "bumper",
        "drive",
        "lamp",
        "heartbeat",
        "0 s",
        "2.5 s",
        "5 s",
    ] {
        assert!(texts.contains(&name), "{name} in {texts:?}");
    }
    assert!(texts.contains(&"rev 30 %"), "{texts:?}");
    let html = timeline_html(&world, &o, "Bumper <robot>");
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.contains("<title>Bumper &lt;robot&gt;</title>"));
    // The page holds the picture inline, without the namespace URL of a file.
    assert!(html.contains(&svg.replace(r#" xmlns="http://www.w3.org/2000/svg""#, "")));
    assert!(html.contains("devices, 5.000 s at 400k:"));
    // Written by extension (set X10_WORLD_PLOT_DIR to keep them and look at them).
    let dir = std::env::var("X10_WORLD_PLOT_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| std::env::temp_dir());
    let id = std::process::id();
    for (name, want) in [("svg", &svg), ("html", &html)] {
        let path = dir.join(format!("bumper-{id}.{name}"));
        write_timeline(&path, &world, &o, "Bumper <robot>").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), *want);
        if std::env::var("X10_WORLD_PLOT_DIR").is_err() {
            std::fs::remove_file(&path).unwrap();
        }
    }
}

#[test]
fn every_toml_example_of_the_world_doc_parses() {
    let doc = std::fs::read_to_string(repo_file("docs/world.md")).unwrap();
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in doc.lines() {
        match (&mut current, line.trim_start()) {
            (None, "```toml") => current = Some(String::new()),
            (Some(block), "```") => {
                blocks.push(std::mem::take(block));
                current = None;
            }
            (Some(block), _) => {
                block.push_str(line);
                block.push('\n');
            }
            _ => {}
        }
    }
    assert!(current.is_none(), "an unclosed ```toml block");
    assert!(blocks.len() >= 5, "{} blocks", blocks.len());
    for b in &blocks {
        if let Err(e) = World::from_toml(b) {
            panic!("{e}\n{b}");
        }
    }
}

#[test]
fn the_thesis_thermistor_model_matches_the_scenario() {
    let cfg = x10_devices::ThermistorConfig::THESIS;
    let mut c = -40.0f32;
    while c < 150.0 {
        assert_eq!(
            x10_sim::world::thermistor_raw(&cfg, c),
            scenario::thermistor_raw(c),
            "{c}"
        );
        c += 0.37;
    }
}

/// Issue 22 item 11 and issue 23 item 4: the trace decodes what the safe defaults send.
/// Every request, reply and event of the Figure 4.4 run (PEC on every board, the boot
/// events always checked) reads in words, with `+pec` when it carries its check.
#[test]
fn the_trace_decodes_every_frame_the_defaults_send() {
    let config = SimConfig {
        duration_ms: 3_000,
        ..SimConfig::default()
    };
    let outcome = x10_sim::examples::sim("fig4_4", config)
        .unwrap()
        .run()
        .unwrap();
    let trace = outcome.trace.render();
    assert!(!trace.contains("unparsed"), "{trace}");
    assert!(trace.contains("event boot seq 0 ok"), "{trace}");
    assert!(trace.contains("+pec"), "{trace}");
    assert!(trace.contains("<- db09 reply seq"), "{trace}");
}
