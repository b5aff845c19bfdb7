//! Decoding outputs from recorded pin changes.

use super::*;
use crate::world::{Board, Device, Pin, World, SELF};
use x10_devices::ServoConfig;

const MS: Nanos = 1_000_000;

fn change(t_ns: Nanos, board: &str, port: u8, pin: Pin, change: Change) -> OutputChange {
    OutputChange {
        t_ns,
        board: board.to_string(),
        pin: Port::new(PortKind::Actuator, port)
            .map(|p| p.pin(pin))
            .unwrap_or_else(|_| unreachable!()),
        change,
    }
}

fn high(t: Nanos, port: u8, pin: Pin) -> OutputChange {
    change(t, "mb", port, pin, Change::Digital(Level::High))
}

fn low(t: Nanos, port: u8, pin: Pin) -> OutputChange {
    change(t, "mb", port, pin, Change::Digital(Level::Low))
}

fn duty(t: Nanos, port: u8, pin: Pin, d: u8) -> OutputChange {
    change(t, "mb", port, pin, Change::Duty(d))
}

#[test]
fn duty_percent_inverts_the_drivers_rounding() {
    for p in 0..=100u16 {
        let d = u8::try_from(p * 255 / 100).unwrap();
        assert_eq!(u16::from(duty_percent(d)), p);
        assert_eq!(MotorState::forward(p as u8).duty, d);
    }
    assert_eq!(duty_percent(1), 1);
}

#[test]
fn a_bridge_decodes_as_the_hbridge_table_says() {
    use MotorDirection::*;
    let h = Some(Level::High);
    let l = Some(Level::Low);
    assert_eq!(MotorState::decode(h, l, 127), MotorState::forward(50));
    assert_eq!(MotorState::decode(l, h, 255), MotorState::reverse(100));
    assert_eq!(MotorState::decode(h, h, 255), MotorState::BRAKE);
    assert_eq!(MotorState::decode(l, l, 0), MotorState::STOPPED);
    assert_eq!(MotorState::decode(None, None, 0), MotorState::STOPPED);
    assert_eq!(MotorState::decode(l, l, 64).direction, Coast);
    assert_eq!(MotorState::forward(50).to_string(), "forward 50 %");
    assert_eq!(MotorState::reverse(30).signed_percent(), -30);
    assert_eq!(MotorState::BRAKE.to_string(), "brake");
    assert_eq!(MotorState::STOPPED.to_string(), "stopped");
    assert_eq!(
        MotorState::decode(l, l, 64).to_string(),
        "coast (enable 26 %)"
    );
}

#[test]
fn a_motor_command_is_one_change_and_a_reset_stops_the_motor() {
    let world = World::new()
        .board(Board::new(9, 1, 1))
        .device(Device::dc_motor("drive", SELF, 1))
        .device(Device::dc_motor("far", 9, 1));
    let t = 100 * MS;
    let changes = vec![
        // forward(50): B low (no change), A high, duty 127 — 0.3 ms apart.
        high(t, 1, Pin::A),
        duty(t + 300_000, 1, Pin::A, 127),
        // reverse(100) at 1 s: A low, B high, duty 255.
        low(1_000 * MS, 1, Pin::A),
        high(1_000 * MS + 300_000, 1, Pin::B),
        duty(1_000 * MS + 600_000, 1, Pin::A, 255),
        // brake at 2 s: A high (B is high), duty already 255.
        high(2_000 * MS, 1, Pin::A),
        // db09's motor forward at 1 s, reset at 1.5 s.
        change(1_000 * MS, "db09", 1, Pin::A, Change::Digital(Level::High)),
        change(1_000 * MS, "db09", 1, Pin::A, Change::Duty(255)),
    ];
    let resets = vec![(1_500 * MS, "db09".to_string())];
    let tl = Timeline::from_changes(&world, &changes, &resets, 3_000 * MS);
    let m = tl.motor("drive").unwrap();
    assert_eq!(
        m.changes(),
        &[
            (t, MotorState::forward(50)),
            (1_000 * MS, MotorState::reverse(100)),
            (2_000 * MS, MotorState::BRAKE),
        ]
    );
    assert_eq!(m.at_ms(0), MotorState::STOPPED);
    assert_eq!(m.at_ms(500), MotorState::forward(50));
    assert_eq!(m.at_ms(2_500), MotorState::BRAKE);
    assert_eq!(m.first_ns(|s| s.signed_percent() < 0), Some(1_000 * MS));
    let far = tl.motor("far").unwrap();
    assert_eq!(
        far.states(),
        vec![
            MotorState::STOPPED,
            MotorState::forward(100),
            MotorState::STOPPED
        ]
    );
    assert_eq!(far.changes()[1].0, 1_500 * MS);
    assert_eq!(
        tl.changes("far").unwrap(),
        vec![
            (1_000 * MS, DeviceState::Motor(MotorState::forward(100))),
            (1_500 * MS, DeviceState::Motor(MotorState::STOPPED))
        ]
    );
    assert_eq!(
        tl.led("drive").unwrap_err().to_string(),
        "`drive` is a dc_motor, not a led"
    );
    assert_eq!(
        tl.motor("walk").unwrap_err().to_string(),
        "no device called `walk` (devices: drive, far)"
    );
}

#[test]
fn leds_servos_and_pwm_outputs() {
    let world = World::new()
        .board(Board::internal(1, 3))
        .device(Device::led("heartbeat", SELF, 1, Pin::A))
        .device(Device::dimmable_led("lamp", SELF, 1, Pin::B))
        .device(Device::servo("arm", SELF, 2, Pin::A))
        .device(
            Device::servo("wrist", SELF, 2, Pin::B)
                .servo_config(ServoConfig::new(500, 2500, 270).unwrap()),
        )
        .device(Device::digital_output("relay", SELF, 3, Pin::B));
    let changes = vec![
        high(10 * MS, 1, Pin::A),
        low(20 * MS, 1, Pin::A),
        // A 1 ms blink is two changes: no settling for single pins.
        high(30 * MS, 1, Pin::A),
        low(31 * MS, 1, Pin::A),
        duty(10 * MS, 1, Pin::B, 102),
        duty(40 * MS, 1, Pin::B, 0),
        change(5 * MS, "mb", 2, Pin::A, Change::Frequency(50)),
        change(10 * MS, "mb", 2, Pin::A, Change::PulseWidth(1_500)),
        change(20 * MS, "mb", 2, Pin::A, Change::PulseWidth(2_000)),
        change(30 * MS, "mb", 2, Pin::A, Change::PulseWidth(0)),
        change(10 * MS, "mb", 2, Pin::B, Change::PulseWidth(1_500)),
        high(50 * MS, 3, Pin::B),
    ];
    let tl = Timeline::from_changes(&world, &changes, &[], 100 * MS);
    let hb = tl.led("heartbeat").unwrap();
    assert_eq!(
        hb.changes(),
        &[
            (10 * MS, true),
            (20 * MS, false),
            (30 * MS, true),
            (31 * MS, false)
        ]
    );
    assert_eq!(tl.brightness("lamp").unwrap().at_ms(15), 40);
    assert!(tl.led("lamp").unwrap().at_ms(15));
    assert!(!tl.led("lamp").unwrap().at_ms(45));
    assert_eq!(tl.brightness("heartbeat").unwrap().at_ms(15), 100);
    let arm = tl.servo("arm").unwrap();
    assert_eq!(arm.states(), vec![None, Some(90), Some(180), None]);
    assert_eq!(tl.servo("wrist").unwrap().at_ms(50), Some(135));
    assert!(tl.level("relay").unwrap().at_ms(60));
    assert!(!tl.level("relay").unwrap().at_ms(40));
}

#[test]
fn states_shorter_than_the_settle_time_merge_into_the_next() {
    let s = vec![
        (0, 'a'),
        (1, 'b'),
        (2, 'c'),
        (10, 'd'),
        (30, 'e'),
        (31, 'f'),
    ];
    assert_eq!(settle(s, 5), vec![(0, 'c'), (10, 'd'), (30, 'f')]);
    assert_eq!(settle(Vec::<(Nanos, char)>::new(), 5), vec![]);
}

#[test]
fn inputs_follow_their_scripts() {
    use crate::world::Signal;
    let world = World::new()
        .device(Device::button("bumper", SELF, 1, Pin::B).pressed_at_ms(1_000, 50))
        .device(
            Device::light_sensor("light", SELF, 1)
                .counts(Signal::linear([(0, 100.0), (4_000, 800.0)])),
        )
        .device(
            Device::thermistor("freezer", SELF, 2)
                .celsius(Signal::linear([(0, -18.0), (4_000, 6.0)])),
        );
    let tl = Timeline::from_changes(&world, &[], &[], 5_000 * MS);
    let b = tl.level("bumper").unwrap();
    assert_eq!(b.changes(), &[(1_000 * MS, true), (1_050 * MS, false)]);
    let light = tl.device("light").unwrap();
    assert_eq!(light.at_ms(2_000), DeviceState::Counts(450));
    // 100 + 700 · 2005/4000 = 450.875, rounded down.
    assert_eq!(light.at_ms(2_005), DeviceState::Counts(450));
    assert_eq!(light.at_ms(2_006), DeviceState::Counts(451));
    assert_eq!(light.changes().len(), 1);
    assert_eq!(
        tl.device("freezer").unwrap().at_ms(1_000),
        DeviceState::Celsius(-12.0)
    );
    let d = tl.get("freezer").unwrap();
    assert_eq!(d.words(&DeviceState::Celsius(-12.0)), "-12.0 °C");
    assert_eq!(d.description(), "thermistor on mb S2");
}
