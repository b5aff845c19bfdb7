//! The models against their equations, on hand-written actuator logs.

use x10_microcode::{Level, Pin, Port};

use super::*;
use crate::ports::{ActuatorLog, Change, OutputChange};
use crate::world::{Device, World, SELF};

fn change(t_ms: u64, port: u8, pin: Pin, change: Change) -> OutputChange {
    OutputChange {
        t_ns: t_ms * 1_000_000,
        board: "mb".to_string(),
        pin: Port::actuator(port).unwrap().pin(pin),
        change,
    }
}

/// H-bridge writes for motor `port` at `t_ms`: + forward, − reverse, at `duty`.
fn drive(t_ms: u64, port: u8, forward: bool, duty: u8) -> Vec<OutputChange> {
    let (a, b) = if forward {
        (Level::High, Level::Low)
    } else {
        (Level::Low, Level::High)
    };
    vec![
        change(t_ms, port, Pin::A, Change::Digital(a)),
        change(t_ms, port, Pin::B, Change::Digital(b)),
        change(t_ms, port, Pin::A, Change::Duty(duty)),
    ]
}

fn robot(arena: Arena, start: (f64, f64, f64)) -> World {
    World::new()
        .board(crate::world::Board::internal(2, 2))
        .device(Device::dc_motor("left", SELF, 1))
        .device(Device::dc_motor("right", SELF, 2))
        .device(Device::button("bumper", SELF, 2, Pin::B))
        .device(Device::light_sensor("eye", SELF, 1))
        .chassis(Chassis::new("left", "right").start(start.0, start.1, start.2))
        .arena(arena)
        .model("bumper", Source::Bumper { arc_deg: 180.0 })
        .model("eye", Source::Line { at: (80.0, 0.0) })
}

fn engine(world: &World, log: Vec<OutputChange>) -> Engine {
    world.check().unwrap();
    Engine::new(
        world.physics_spec().unwrap(),
        ActuatorLog::from_changes(log),
        None,
    )
}

fn pose(e: &mut Engine, t_ms: u64) -> (f64, f64, f64) {
    e.pose_at(t_ms * 1_000_000)
}

#[test]
fn a_wheel_speed_follows_its_command_with_the_time_constant() {
    let world = robot(Arena::default(), (0.0, 0.0, 0.0));
    let mut log = drive(0, 1, true, 255);
    log.extend(drive(0, 2, true, 255));
    let mut e = engine(&world, log);
    let top = Chassis::new("l", "r").top_speed_mm_s();
    assert!((top - 376.991).abs() < 1e-3, "{top}");
    // Both wheels alike: straight along +x, y and heading exactly 0.
    for t in [100, 500, 1_000, 3_000] {
        let (x, y, h) = pose(&mut e, t);
        assert_eq!((y, h), (0.0, 0.0));
        // x(t) = top · (t − τ (1 − e^(−t/τ))); each 1 ms step moves at the speed reached at
        // its start, so the path leads it by less than top · dt.
        let s = t as f64 / 1_000.0;
        let exact = top * (s - 0.1 * (1.0 - (-s / 0.1).exp()));
        assert!(
            x >= exact && x - exact < top * 0.001,
            "{t} ms: {x} vs {exact}"
        );
    }
}

#[test]
fn opposite_wheels_turn_in_place_and_the_dead_band_holds() {
    let world = robot(Arena::default(), (500.0, 500.0, 0.0));
    let mut log = drive(0, 1, false, 255);
    log.extend(drive(0, 2, true, 255));
    let mut e = engine(&world, log);
    let (x, y, h) = pose(&mut e, 2_000);
    assert_eq!((x, y), (500.0, 500.0));
    // ω = 2v / base: after the speed settles, 2 · 377 / 120 rad/s.
    assert!(h > 10.0 && h < 12.57, "{h}");
    // 10 % (duty 25): within the 10 % dead band, nothing moves.
    let mut log = drive(0, 1, true, 25);
    log.extend(drive(0, 2, true, 25));
    let mut e = engine(&world, log);
    assert_eq!(pose(&mut e, 2_000), (500.0, 500.0, 0.0));
}

#[test]
fn the_chassis_stops_against_a_wall_and_the_bumper_follows_the_contact() {
    let world = robot(Arena::walled(1_000.0, 1_000.0), (500.0, 500.0, 0.0));
    let mut log = drive(0, 1, true, 255);
    log.extend(drive(0, 2, true, 255));
    log.extend(drive(3_000, 1, false, 255));
    log.extend(drive(3_000, 2, false, 255));
    let mut e = engine(&world, log);
    let (x, _, _) = pose(&mut e, 2_900);
    // Against wall 2 (x = 1000): the outline (radius 80) within 1 µm of it, never through.
    assert!(x <= 920.0 && x > 920.0 - 1e-3, "{x}");
    assert_eq!(e.contacts.len(), 1);
    assert_eq!(e.contacts[0].obstacle, "wall 2");
    let hit = e.contacts[0].t_ns;
    // 420 mm at up to 377 mm/s from rest: a little over 1.2 s.
    assert!((1_200_000_000..1_300_000_000).contains(&hit), "{hit}");
    assert!(!e.levels(PinModel::Bumper).at(hit - 1));
    assert!(e.levels(PinModel::Bumper).at(hit));
    let (x, _, _) = pose(&mut e, 4_000);
    assert!(x < 800.0, "{x}");
    let edges = &e.levels(PinModel::Bumper).edges;
    assert_eq!(edges.len(), 2);
    assert_eq!(edges[0], (hit, true));
    assert!(edges[1].0 > 3_000_000_000 && !edges[1].1);
}

#[test]
fn the_state_does_not_depend_on_when_or_how_often_it_is_read() {
    let arena =
        Arena::walled(2_000.0, 2_000.0).line(vec![(0.0, 500.0), (2_000.0, 700.0)], 40.0, 0.1);
    let world = robot(arena, (300.0, 300.0, 45.0));
    let mut log = drive(0, 1, true, 200);
    log.extend(drive(0, 2, true, 255));
    log.extend(drive(1_500, 1, false, 120));
    log.extend(drive(2_500, 2, false, 90));
    let mut every = engine(&world, log.clone());
    let mut counts = Vec::new();
    for t in 0..4_000u64 {
        counts.push(every.counts(1, t * 1_000_000 + 123_456, 1_023));
    }
    let mut once = engine(&world, log);
    let last = once.counts(1, 3_999_123_456, 1_023);
    assert_eq!(counts.last(), Some(&last));
    assert_eq!(every.path, once.path);
    // Read backwards after the fact: the same values.
    for t in (0..4_000u64).rev().step_by(97) {
        assert_eq!(
            once.counts(1, t * 1_000_000 + 123_456, 1_023),
            counts[t as usize]
        );
    }
    assert!(counts.contains(&102) && counts.contains(&818));
}

#[test]
fn a_ranger_sees_the_nearest_wall_along_its_beam() {
    let world = robot(Arena::walled(1_000.0, 1_000.0), (500.0, 500.0, 0.0))
        .device(
            Device::ultrasonic("sonar", SELF, 1).ranger(crate::world::Ranger {
                trigger: Some(Pin::A),
                echo: Pin::A,
                ..crate::world::Ranger::HC_SR04
            }),
        )
        .model("sonar", Source::front_ranger(80.0));
    let mut e = engine(&world, Vec::new());
    // 1000 − 500 − 80 mm ahead; the side rays (±3.75°, ±7.5°) are longer.
    let sensor = world
        .physics()
        .sensors
        .iter()
        .position(|s| s.device == "sonar")
        .unwrap();
    assert_eq!(e.range(sensor, 0).map(|r| r.0), Some(420.0));
    assert_eq!(
        e.echo_us(sensor, 500, 500, 343),
        crate::world::echo_width_us(420.0, 343)
    );
}

#[test]
fn a_freezer_warms_towards_the_kitchen_while_its_door_is_open() {
    let world = World::new()
        .device(Device::switch("door", SELF, 1, Pin::A).level(
            crate::world::DigitalSignal::Toggles {
                initial: false,
                at_ms: vec![1_000, 6_000],
            },
        ))
        .device(Device::thermistor("t", SELF, 2))
        .device(Device::led("heater", SELF, 1, Pin::A))
        .thermal(Thermal::new("cabinet", -18.0, -18.0, 10.0).door("door", 20.0))
        .thermal(Thermal::new("oven", 20.0, 20.0, 5.0).heater("heater", 200.0))
        .model(
            "t",
            Source::Thermal {
                body: "cabinet".to_string(),
            },
        );
    let log = vec![change(0, 1, Pin::A, Change::Digital(Level::High))];
    let mut e = engine(&world, log);
    let at = |e: &mut Engine, body: usize, ms: u64| e.celsius(body, ms * 1_000_000);
    assert_eq!(at(&mut e, 0, 1_000), -18.0);
    // T(t) = 20 − 38 e^(−t/τ) from the opening at 1 s, within the step's error.
    let open = at(&mut e, 0, 6_000);
    let exact = 20.0 - 38.0 * (-0.5f64).exp();
    assert!((open - exact).abs() < 0.01, "{open} vs {exact}");
    // Shut again at 6 s: back towards −18 °C.
    assert!(at(&mut e, 0, 8_000) < open);
    // The oven's heater is on from 0: 20 + 200 (1 − e^(−t/5 s)).
    let oven = at(&mut e, 1, 5_000);
    let exact = 20.0 + 200.0 * (1.0 - (-1.0f64).exp());
    assert!((oven - exact).abs() < 0.1, "{oven} vs {exact}");
}

#[test]
fn an_encoder_toggles_its_edges_per_revolution() {
    let world = robot(Arena::default(), (0.0, 0.0, 0.0))
        .device(Device::digital_input("tick", SELF, 1, Pin::A))
        .model("tick", Source::Encoder(Wheel::Left));
    let mut log = drive(0, 1, true, 255);
    log.extend(drive(0, 2, true, 255));
    let mut e = engine(&world, log);
    e.advance_to(3_000_000_000);
    let per_rev = f64::from(Chassis::new("l", "r").encoder_edges_per_rev);
    let turned = e.turned[0] / (std::f64::consts::TAU * 30.0);
    let edges = e.levels(PinModel::Encoder(Wheel::Left)).edges.len();
    assert_eq!(edges, (turned * per_rev).floor() as usize);
    assert!(edges > 200, "{edges}");
}

#[test]
fn a_light_sensor_reads_the_inverse_square_of_its_distance_to_the_lamp() {
    let world = robot(
        Arena::default().lamp(Lamp {
            at: (1_000.0, 0.0),
            counts_at_1m: 100.0,
            ambient_counts: 20.0,
        }),
        (0.0, 0.0, 0.0),
    )
    .device(Device::light_sensor("light", SELF, 2))
    .model("light", Source::Light { at: (0.0, 0.0) });
    let mut e = engine(&world, Vec::new());
    let i = world.physics().sensors.len() - 1;
    assert_eq!(e.counts(i, 0, 1_023), 120);
    let world2 = robot(
        Arena::default().lamp(Lamp {
            at: (500.0, 0.0),
            counts_at_1m: 100.0,
            ambient_counts: 20.0,
        }),
        (0.0, 0.0, 0.0),
    )
    .device(Device::light_sensor("light", SELF, 2))
    .model("light", Source::Light { at: (0.0, 0.0) });
    let mut e = engine(&world2, Vec::new());
    assert_eq!(e.counts(i, 0, 1_023), 420);
}

#[test]
fn a_servo_travels_at_its_rated_speed() {
    use crate::timeline::{DeviceState, Track};
    let commanded = Track::new(
        DeviceState::Servo(None),
        vec![
            (100_000_000, DeviceState::Servo(Some(0))),
            (1_000_000_000, DeviceState::Servo(Some(180))),
            (2_000_000_000, DeviceState::Servo(None)),
        ],
    );
    // 600°/s: 6° per 10 ms sample, from the command on; the first angle is where it starts.
    let t = slewed(&commanded, 600.0, 3_000_000_000);
    let at = |ms: u64| t.at_ms(ms);
    assert_eq!(at(50), DeviceState::Servo(None));
    assert_eq!(at(100), DeviceState::Servo(Some(0)));
    assert_eq!(at(999), DeviceState::Servo(Some(0)));
    assert_eq!(at(1_000), DeviceState::Servo(Some(6)));
    assert_eq!(at(1_150), DeviceState::Servo(Some(96)));
    assert_eq!(at(1_289), DeviceState::Servo(Some(174)));
    assert_eq!(at(1_290), DeviceState::Servo(Some(180)));
    assert_eq!(at(2_000), DeviceState::Servo(None));
    let world = World::new()
        .device(Device::servo("arm", SELF, 1, Pin::A))
        .servo_slew("arm", 600.0);
    assert!(world.check().is_ok());
    let wrong = World::from_toml(
        "[[device]]\nname = \"led\"\nkind = \"led\"\nport = \"A1\"\npin = \"A\"\n\n[[servo]]\ndevice = \"led\"\nspeed_deg_s = 600\n",
    )
    .expect_err("not a servo");
    assert_eq!(
        wrong.to_string(),
        "line 8: servo `led`: `device` names `led`, a led: not a servo"
    );
}

/// A model pin on a board's ports: `wait_edge` wakes at each edge the integration records and
/// `take_edges` counts them exactly, while the same ports drive the motors.
#[test]
fn a_board_waiting_for_encoder_edges_wakes_at_each_and_counts_them_all() {
    use std::cell::RefCell;

    use firmware_db::Ports;
    use x10_microcode::PortKind;

    use crate::exec::{Executor, SimClock};
    use crate::ports::{Digital, SensorScript, SimPorts};

    let world = robot(Arena::default(), (0.0, 0.0, 0.0))
        .device(Device::digital_input("tick", SELF, 1, Pin::A))
        .model("tick", Source::Encoder(Wheel::Left));
    let clock = SimClock::new();
    let log = ActuatorLog::new();
    let engine = Engine::new(
        world.physics_spec().unwrap(),
        log.clone(),
        Some(clock.clone()),
    )
    .into_shared();
    let pin = ModelPin::new(engine.clone(), PinModel::Encoder(Wheel::Left), false);
    let ports = SimPorts::new("mb", clock.clone(), log, 2, 2).with_sensor(
        1,
        SensorScript {
            a: Digital::Model(pin),
            ..SensorScript::default()
        },
    );
    let tick = Port::new(PortKind::Sensor, 1).unwrap().pin(Pin::A);
    let wakes = RefCell::new(Vec::new());
    let counted = RefCell::new(0u32);
    let mut ex = Executor::with_clock(&clock);
    let (p, w, n, c) = (&ports, &wakes, &counted, clock.clone());
    ex.spawn("board", async move {
        for port in [1, 2] {
            let a = Port::actuator(port).unwrap();
            p.digital_write(a.pin(Pin::A), Level::High).unwrap();
            p.digital_write(a.pin(Pin::B), Level::Low).unwrap();
            p.pwm_duty(a.pin(Pin::A), 255).unwrap();
        }
        p.latch_edges(tick).unwrap();
        while c.now_ns() < 1_000_000_000 {
            p.wait_edge().await;
            let e = p.take_edges(tick).unwrap();
            w.borrow_mut().push(c.now_ns());
            *n.borrow_mut() += u32::from(e.rising) + u32::from(e.falling);
        }
    });
    ex.run_until_ns(1_000_000_000).unwrap();
    let recorded: Vec<u64> = engine
        .borrow()
        .levels(PinModel::Encoder(Wheel::Left))
        .edges
        .iter()
        .map(|(t, _)| *t)
        .filter(|t| *t <= 1_000_000_000)
        .collect();
    assert!(recorded.len() > 40, "{}", recorded.len());
    // One wake per edge, at its instant (edges are on the 1 ms grid, at most one per step
    // at this speed), and every edge counted.
    assert_eq!(*wakes.borrow(), recorded);
    assert_eq!(*counted.borrow() as usize, recorded.len());
}
