//! The builder, the file reader and the checks.

use super::*;
use x10_devices::ServoConfig;

fn err(text: &str) -> String {
    match World::from_toml(text) {
        Ok(_) => "no error".to_string(),
        Err(e) => e.to_string(),
    }
}

const TWO_BOARDS: &str = r#"
[[board]]
address = 0
sensor_ports = 2
actuator_ports = 2

[[board]]
address = 9
name = "front"
sensor_ports = 1
actuator_ports = 2
"#;

fn with_boards(devices: &str) -> String {
    format!("{TWO_BOARDS}{devices}")
}

#[test]
fn a_file_and_the_builder_make_the_same_world() {
    let text = with_boards(
        r#"
[[device]]
name = "left"
kind = "dc_motor"
port = "A1"

[[device]]
name = "bumper"
kind = "button"
board = "SELF"
port = "S2"
pin = "B"
active_low = true
presses = [[1000, 50], [3000, 50]]

[[device]]
name = "light"
kind = "light_sensor"
board = "front"
port = "S1"
counts = { linear = [[0, 100], [4000, 800.0]] }

[[device]]
name = "arm"
kind = "servo"
board = 9
port = "A2"
pwm = "B"
max_angle = 90

[[device]]
name = "oven"
kind = "thermistor"
board = "mb"
port = "S1"
celsius = { steps = [[0, 20], [1500.5, 180]] }

[[device]]
name = "sonar"
kind = "ultrasonic"
board = "db09"
port = "S1"
trigger = "none"
echo = "A"
distance_mm = 250
"#,
    );
    let from_file = World::from_toml(&text).unwrap();
    let built = World::new()
        .board(Board::internal(2, 2))
        .board(Board::new(9, 1, 2).named("front"))
        .device(Device::dc_motor("left", SELF, 1))
        .device(
            Device::button("bumper", "SELF", 2, Pin::B)
                .active_low()
                .pressed_at_ms(1_000, 50)
                .pressed_at_ms(3_000, 50),
        )
        .device(
            Device::light_sensor("light", "front", 1)
                .counts(Signal::linear([(0, 100.0), (4_000, 800.0)])),
        )
        .device(
            Device::servo("arm", 9, 2, Pin::B)
                .servo_config(ServoConfig::new(1000, 2000, 90).unwrap()),
        )
        .device(
            Device::thermistor("oven", "mb", 1)
                .celsius(Signal::Steps(vec![(0, 20.0), (1_500_500, 180.0)])),
        )
        .device(
            Device::ultrasonic("sonar", "db09", 1)
                .distance_mm(Signal::constant(250.0))
                .ranger(Ranger {
                    trigger: None,
                    echo: Pin::A,
                    ..Ranger::HC_SR04
                }),
        );
    assert_eq!(built.check(), Ok(()));
    assert_eq!(from_file, built);
    assert_eq!(
        built.device_named("sonar").map(|d| d.place("db09")),
        Some("db09 S1 (echo A)".to_string())
    );
    assert_eq!(
        built.device_named("arm").map(|d| d.place("db09")),
        Some("db09 A2 PWM B".to_string())
    );
}

#[test]
fn board_kinds_have_their_chips_port_counts() {
    let w = World::from_toml(
        "[[board]]\naddress = 0\nkind = \"g431\"\n[[board]]\naddress = 0x20\nkind = \"pico\"\n",
    )
    .unwrap();
    let boards = w.boards();
    assert_eq!(boards.len(), 2);
    assert_eq!(boards[0].log_name(), "mb");
    assert_eq!(
        (
            boards[0].kind().sensor_ports(),
            boards[0].kind().actuator_ports()
        ),
        (4, 4)
    );
    assert_eq!(boards[1].log_name(), "db20");
    assert_eq!(boards[1].kind(), BoardKind::Pico);
    assert_eq!(boards[1].adc_resolution(), 12);
    assert_eq!(boards[1].adc_max(), 4095);
    // No internal board declared: the default one.
    assert_eq!(World::new().boards(), vec![Board::internal(2, 2)]);
    assert_eq!(World::new(), World::new().board(Board::internal(2, 2)));
    assert_ne!(World::new(), World::new().board(Board::internal(2, 3)));
}

#[test]
fn errors_name_the_line_and_the_field() {
    let cases: &[(&str, &str)] = &[
        (
            "[[device]]\nname = \"m\"\nkind = \"motor\"\nport = \"A1\"\n",
            "line 3: device `m`: unknown kind `motor` (kinds: dc_motor, led, digital_output, pwm_output, servo, button, switch, digital_input, light_sensor, force_sensor, analog_input, thermistor, ultrasonic)",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A3\"\n",
            "line 4: device `m`: port A3 is out of range: board mb has 2 actuator ports",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"S1\"\n",
            "line 4: device `m`: a dc_motor goes on an actuator port (A1, A2, …), not on S1",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"s1\"\n",
            "line 4: device `m`: a dc_motor goes on an actuator port (A1, A2, …), not on S1",
        ),
        (
            "[[device]]\nname = \"b\"\nkind = \"button\"\nport = \"A1\"\npin = \"A\"\n",
            "line 4: device `b`: a button goes on a sensor port (S1, S2, …), not on A1",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A1\"\n[[device]]\nname = \"l\"\nkind = \"led\"\nport = \"A1\"\npwm = \"A\"\n",
            "line 8: device `l`: mb A1 PWM A is already used by `m`",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A1\"\n[[device]]\nname = \"l\"\nkind = \"led\"\nport = \"A1\"\npwm = \"B\"\n",
            "no error",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nboard = \"db42\"\nport = \"A1\"\n",
            "line 4: device `m`: no board `db42` in the world",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nboard = 9\nport = \"A1\"\n",
            "line 4: device `m`: no board `0x09` in the world",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A1\"\n[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A2\"\n",
            "line 6: two devices are called `m`",
        ),
        (
            "[[board]]\naddress = 9\nsensor_ports = 1\nactuator_ports = 1\n[[board]]\naddress = 9\nsensor_ports = 1\nactuator_ports = 1\n",
            "line 6: two boards at address 9 (0x09)",
        ),
        (
            "[[board]]\naddress = 9\nname = \"x\"\nsensor_ports = 1\nactuator_ports = 1\n[[board]]\naddress = 10\nname = \"x\"\nsensor_ports = 1\nactuator_ports = 1\n",
            "line 8: two boards are called `x`",
        ),
        (
            "[[board]]\naddress = 9\nname = \"db0a\"\nsensor_ports = 1\nactuator_ports = 1\n[[board]]\naddress = 10\nsensor_ports = 1\nactuator_ports = 1\n",
            "line 7: two boards are called `db0a`",
        ),
        (
            "[[board]]\naddress = 3\nsensor_ports = 1\nactuator_ports = 1\n",
            "line 2: board address 3: not 0 (the internal board) nor 8 to 118 (0x08 to 0x76; 0x77 is where boards without an address listen)",
        ),
        (
            "[[board]]\naddress = 9\n",
            "line 2: board db09: needs `sensor_ports` and `actuator_ports` (or `kind = \"pico\"` or `\"g431\"`)",
        ),
        (
            "[[board]]\naddress = 9\nkind = \"pico\"\nsensor_ports = 2\n",
            "line 4: board db09: a pico has 3 sensor and 3 actuator ports: leave out `sensor_ports` and `actuator_ports`, or make it `kind = \"simulated\"`",
        ),
        (
            "[[board]]\naddress = 9\nkind = \"arduino\"\n",
            "line 3: board db09: unknown kind `arduino` (kinds: pico, g431, simulated)",
        ),
        (
            "[[board]]\naddress = 9\nsensor_ports = 65\nactuator_ports = 1\n",
            "line 3: board db09: `sensor_ports` is 65: 0 to 64",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"B1\"\n",
            "line 4: device `m`: port `B1` is not a port (S1, S2, … for sensor ports, A1, A2, … for actuator ports)",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\n",
            "line 1: device `m`: `port` is missing",
        ),
        (
            "[[device]]\nname = \"l\"\nkind = \"led\"\nport = \"A1\"\n",
            "line 1: device `l`: `pin` is missing",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A1\"\ncounts = 3\n",
            "line 5: device `m`: `counts` does not apply to a dc_motor",
        ),
        (
            "[[device]]\nname = \"l\"\nkind = \"light_sensor\"\nport = \"S1\"\ncounts = 1024\n",
            "line 5: device `l`: `counts` has 1024, outside 0 to 1023",
        ),
        (
            "[[device]]\nname = \"l\"\nkind = \"light_sensor\"\nport = \"S1\"\ncounts = 10.5\n",
            "line 5: device `l`: `counts` has 10.5: ADC counts are whole numbers",
        ),
        (
            "[[device]]\nname = \"l\"\nkind = \"light_sensor\"\nport = \"S1\"\ncounts = { linear = [[10, 1], [5, 2]] }\n",
            "line 5: device `l`: `counts` has times that go backwards",
        ),
        (
            "[[device]]\nname = \"l\"\nkind = \"light_sensor\"\nport = \"S1\"\ncounts = { ramp = [] }\n",
            "line 5: device `l`: `counts` must be a number, `{ steps = [[t_ms, value], …] }` or `{ linear = [[t_ms, value], …] }`",
        ),
        (
            "[[device]]\nname = \"l\"\nkind = \"light_sensor\"\nport = \"S1\"\ncounts = { steps = [[-1, 2]] }\n",
            "line 5: device `l`: `counts` has `[-1, 2]` in `steps`: each point is [t_ms, value] with t_ms not negative",
        ),
        (
            "[[device]]\nname = \"b\"\nkind = \"button\"\nport = \"S1\"\npin = \"A\"\npresses = [[100, 50], [120, 10]]\n",
            "line 6: device `b`: `presses` has presses out of time order, overlapping or touching",
        ),
        (
            "[[device]]\nname = \"b\"\nkind = \"button\"\nport = \"S1\"\npin = \"C\"\n",
            "line 5: device `b`: `pin` is \"C\": \"A\" or \"B\"",
        ),
        (
            "[[device]]\nname = \"b\"\nkind = \"button\"\nport = \"S1\"\npin = \"A\"\nlevel = true\npresses = [[1, 1]]\n",
            "line 7: device `b`: `presses` cannot be combined with `level`, `toggles` or `pulses`",
        ),
        (
            "[[device]]\nname = \"t\"\nkind = \"thermistor\"\nport = \"S1\"\nadc_bits = 12\n",
            "line 5: device `t`: `adc_bits` is 12 but board mb has a 10-bit ADC",
        ),
        (
            "[[device]]\nname = \"s\"\nkind = \"servo\"\nport = \"A1\"\npwm = \"A\"\n[[device]]\nname = \"l\"\nkind = \"led\"\nport = \"A1\"\npwm = \"B\"\n",
            "line 9: device `s`: a servo sets its port's PWM frequency to 50 Hz, which `l` on the same port also uses",
        ),
        (
            "[[device]]\nname = \"s\"\nkind = \"servo\"\nport = \"A1\"\npwm = \"A\"\n[[device]]\nname = \"s2\"\nkind = \"servo\"\nport = \"A1\"\npwm = \"B\"\n",
            "no error",
        ),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"A1\"\ncolour = \"red\"\n",
            "line 5: unknown field `colour`, expected one of `name`, `kind`, `board`, `port`, `pin`, `pwm`, `active_low`, `level`, `toggles`, `presses`, `pulses`, `counts`, `celsius`, `distance_mm`, `fixed_ohms`, `adc_bits`, `divider`, `steinhart_hart`, `trigger`, `echo`, `speed_of_sound`, `echo_delay_us`, `min_interval_ms`, `min_us`, `max_us`, `max_angle`",
        ),
        ("[[device]\nname = 1", "line 1: unclosed array table, expected `]`"),
        (
            "[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = 1\n",
            "line 4: invalid type: integer `1`, expected a string",
        ),
    ];
    for (text, want) in cases {
        assert_eq!(err(text), *want, "{text}");
    }
}

#[test]
fn errors_are_typed() {
    let e = World::from_toml("[[device]]\nname = \"m\"\nkind = \"dc_motor\"\nport = \"S1\"\n")
        .unwrap_err();
    assert_eq!(e.line, Some(4));
    assert_eq!(
        e.kind,
        WorldErrorKind::WrongPortKind {
            device: "m".to_string(),
            kind: "dc_motor",
            port: "S1".to_string()
        }
    );
    let e = World::load("/nonexistent/world.toml").unwrap_err();
    assert!(matches!(e.kind, WorldErrorKind::Io { .. }), "{e:?}");
}

#[test]
fn builder_mistakes_are_errors_too() {
    let w = World::new().device(Device::dc_motor("m", SELF, 1).pressed_at_ms(10, 10));
    assert_eq!(
        w.check().unwrap_err().to_string(),
        "device `m`: `pressed_at_ms` does not apply to a dc_motor"
    );
    let w = World::new().device(Device::dc_motor("m", SELF, 0));
    assert_eq!(
        w.check().unwrap_err().to_string(),
        "device `m`: port A0 is out of range: board mb has 2 actuator ports"
    );
    let w = World::new().board(Board::new(8, 1, 1));
    let e = w.sim(SimConfig::default()).err().map(|e| e.to_string());
    assert_eq!(
        e.as_deref(),
        Some("board at address 0x08: that is the motherboard's own bus address")
    );
}

#[test]
fn sensor_scripts_put_each_device_on_its_pin() {
    let w = World::new()
        .device(Device::button("b", SELF, 1, Pin::B).pressed_at_ms(100, 50))
        .device(Device::switch("s", SELF, 1, Pin::A).active_low())
        .device(Device::force_sensor("f", SELF, 1).counts(Signal::steps([(0, 7.0), (10, 9.0)])))
        .device(
            Device::digital_input("p", SELF, 2, Pin::A).level(DigitalSignal::Pulses {
                first_us: 1_000,
                period_us: 10_000,
                width_us: 2_000,
            }),
        );
    let s1 = w.sensor_script(SELF, 1).unwrap();
    let ms = |t: u64| t * 1_000_000;
    assert_eq!(
        [0, 99, 100, 149, 150].map(|t| s1.b.level_at(ms(t))),
        [false, false, true, true, false]
    );
    // Active low and never on: always HIGH.
    assert!(s1.a.level_at(0) && s1.a.level_at(ms(1_000)));
    assert_eq!([0, 9, 10].map(|t| s1.analog.value_at(ms(t))), [7, 7, 9]);
    let s2 = w.sensor_script(SELF, 2).unwrap();
    assert_eq!(
        [0, 1, 2, 3, 11, 13].map(|t| s2.a.level_at(ms(t))),
        [false, true, true, false, true, false]
    );
    assert_eq!(s2.analog.value_at(0), 0);
    assert!(w.sensor_script(SELF, 3).is_none());
    assert!(w.sensor_script(9, 1).is_none());
}

#[test]
fn scripts_read_in_words() {
    assert_eq!(
        Signal::steps([(0, 40.0), (3_600, 350.0), (4_200, 40.0)]).describe("counts"),
        "40 counts, 350 from 3.6 s, 40 from 4.2 s"
    );
    assert_eq!(
        Signal::linear([(0, -18.0), (4_000, 6.5)]).describe("°C"),
        "-18 °C at 0 s, 6.5 at 4 s, linear in between"
    );
    assert_eq!(Signal::constant(121.1).describe("°C"), "121.1 °C");
    assert_eq!(
        DigitalSignal::Presses(vec![(1_000, 50), (3_000, 50)]).describe("pressed", "released"),
        "pressed at 1 s for 50 ms, at 3 s for 50 ms"
    );
    assert_eq!(
        DigitalSignal::Toggles {
            initial: true,
            at_ms: vec![1_500]
        }
        .describe("on", "off"),
        "on, toggled at 1.5 s"
    );
    assert_eq!(
        DigitalSignal::Pulses {
            first_us: 100_000,
            period_us: 500_000,
            width_us: 20_000
        }
        .describe("high", "low"),
        "high for 0.02 s every 0.5 s from 0.1 s"
    );
}
