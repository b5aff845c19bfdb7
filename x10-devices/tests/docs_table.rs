//! `docs/drivers.md` has a table of the exact microcode each driver method sends. This test
//! parses that table, runs every row's call against the recording double (scripted with the
//! row's reply payloads) and checks the frames; and it checks that the table and the list of
//! calls here have the same rows. A driver change that alters a frame fails here until the
//! table is updated.

use std::collections::BTreeSet;
use x10_microcode::test_support::db9;

use embassy_futures::block_on;
use x10_devices::testing::RecordingLink;
use x10_devices::{
    Actuator, AnalogSensor, Button, DcMotor, Degrees, DigitalOutput, Duty, Edge, EventConfig,
    EventKind, HBridge, Kept, Level, Output, Pin, PinEvent, Ramp, Refresh, Sensor, Servo, Speed,
    Thermistor, Ultrasonic,
};

type Link = RecordingLink<32>;

/// Every row of the table: the call as written there, and how to run it (DB 9, port 1).
const ROWS: &[&str] = &[
    "Sensor::read_analog()",
    "Sensor::read_digital(Pin::B)",
    "Sensor::write_digital(Pin::A, Level::High)",
    "Sensor::pulse_in(Pin::B, Edge::Rising, Some(30))",
    "Sensor::pulse_in(Pin::A, Edge::Falling, None)",
    "Sensor::enable_events(Pin::B, rising + falling)",
    "Actuator::write_digital(Pin::B, Level::Low)",
    "Actuator::set_digital(Level::Low, Level::High)",
    "Actuator::read_digital(Pin::A)",
    "Actuator::pwm(Pin::A, Duty(128))",
    "Actuator::pwm_frequency(50)",
    "Actuator::pulse_width(Pin::B, 1500)",
    "HBridge::forward(Duty(200))",
    "HBridge::reverse(Duty(200))",
    "HBridge::brake()",
    "HBridge::coast()",
    "HBridge::stop()",
    "DcMotor::set_speed(Speed::FULL_FORWARD)",
    "DcMotor::set_percent(-50)",
    "DcMotor::stop()",
    "DcMotor::brake()",
    "DcMotor::ramp_to(Speed::FULL_FORWARD, Ramp::new(50, 10))",
    "DigitalOutput::set(Level::High)",
    "Kept::keep(Speed::FULL_FORWARD)",
    "Thermistor::celsius()",
    "Thermistor::fahrenheit()",
    "Thermistor::kelvin()",
    "Servo::init()",
    "Servo::set_angle(Degrees(90))",
    "Servo::set_pulse_us(1250)",
    "Servo::release()",
    "Button::is_pressed()",
    "Button::enable_events()",
    "Button::disable_events()",
    "Button::wait_change()",
    "AnalogSensor::read_raw()",
    "AnalogSensor::read()",
    "Ultrasonic::distance()",
];

struct NoDelay;

impl embedded_hal_async::delay::DelayNs for NoDelay {
    async fn delay_ns(&mut self, _ns: u32) {}
}

/// Runs one row's call and returns its result, `{:?}`-formatted.
fn run(call: &str, link: &Link) -> String {
    let sensor = || Sensor::new(link, db9(), 1).unwrap();
    let actuator = || Actuator::new(link, db9(), 1).unwrap();
    let bridge = || HBridge::new(link, db9(), 1).unwrap();
    let mut motor = DcMotor::new(link, db9(), 1).unwrap();
    let thermistor = || Thermistor::new(link, db9(), 1).unwrap();
    let servo = || Servo::new(link, db9(), 1, Pin::A).unwrap();
    let mut button = Button::new(link, db9(), 1, Pin::B).unwrap();
    let analog = || AnalogSensor::new(link, db9(), 1).unwrap();
    let both = EventConfig {
        rising: true,
        falling: true,
        ..EventConfig::OFF
    };
    macro_rules! show {
        ($e:expr) => {
            format!("{:?}", $e.await)
        };
    }
    block_on(async {
        match call {
            "Sensor::read_analog()" => show!(sensor().read_analog()),
            "Sensor::read_digital(Pin::B)" => show!(sensor().read_digital(Pin::B)),
            "Sensor::write_digital(Pin::A, Level::High)" => {
                show!(sensor().write_digital(Pin::A, Level::High))
            }
            "Sensor::pulse_in(Pin::B, Edge::Rising, Some(30))" => {
                show!(sensor().pulse_in(Pin::B, Edge::Rising, Some(30)))
            }
            "Sensor::pulse_in(Pin::A, Edge::Falling, None)" => {
                show!(sensor().pulse_in(Pin::A, Edge::Falling, None))
            }
            "Sensor::enable_events(Pin::B, rising + falling)" => {
                show!(sensor().enable_events(Pin::B, both))
            }
            "Actuator::write_digital(Pin::B, Level::Low)" => {
                show!(actuator().write_digital(Pin::B, Level::Low))
            }
            "Actuator::set_digital(Level::Low, Level::High)" => {
                show!(actuator().set_digital(Level::Low, Level::High))
            }
            "Actuator::read_digital(Pin::A)" => show!(actuator().read_digital(Pin::A)),
            "Actuator::pwm(Pin::A, Duty(128))" => show!(actuator().pwm(Pin::A, Duty(128))),
            "Actuator::pwm_frequency(50)" => show!(actuator().pwm_frequency(50)),
            "Actuator::pulse_width(Pin::B, 1500)" => show!(actuator().pulse_width(Pin::B, 1500)),
            "HBridge::forward(Duty(200))" => show!(bridge().forward(Duty(200))),
            "HBridge::reverse(Duty(200))" => show!(bridge().reverse(Duty(200))),
            "HBridge::brake()" => show!(bridge().brake()),
            "HBridge::coast()" => show!(bridge().coast()),
            "HBridge::stop()" => show!(bridge().stop()),
            "DcMotor::set_speed(Speed::FULL_FORWARD)" => {
                show!(motor.set_speed(Speed::FULL_FORWARD))
            }
            "DcMotor::set_percent(-50)" => show!(motor.set_percent(-50)),
            "DcMotor::stop()" => show!(motor.stop()),
            "DcMotor::brake()" => show!(motor.brake()),
            "DcMotor::ramp_to(Speed::FULL_FORWARD, Ramp::new(50, 10))" => {
                let ramp = Ramp::new(50, 10).unwrap();
                show!(motor.ramp_to(Speed::FULL_FORWARD, ramp, &mut NoDelay))
            }
            "DigitalOutput::set(Level::High)" => {
                let mut output = DigitalOutput::new(link, db9(), 1, Pin::A).unwrap();
                show!(output.set(Level::High))
            }
            "Kept::keep(Speed::FULL_FORWARD)" => {
                // A fresh kept motor: its speed is unknown, so the first keep sends it.
                let mut kept = Kept::new(motor, Refresh::every(25).unwrap());
                show!(kept.keep(Speed::FULL_FORWARD))
            }
            "Thermistor::celsius()" => show!(thermistor().celsius()),
            "Thermistor::fahrenheit()" => show!(thermistor().fahrenheit()),
            "Thermistor::kelvin()" => show!(thermistor().kelvin()),
            "Servo::init()" => show!(servo().init()),
            "Servo::set_angle(Degrees(90))" => show!(servo().set_angle(Degrees(90))),
            "Servo::set_pulse_us(1250)" => show!(servo().set_pulse_us(1250)),
            "Servo::release()" => show!(servo().release()),
            "Button::is_pressed()" => show!(button.is_pressed()),
            "Button::enable_events()" => show!(button.enable_events()),
            "Button::disable_events()" => show!(button.disable_events()),
            "Button::wait_change()" => {
                // The board reports pin B of sensor port 1 going HIGH; one read confirms it.
                link.event(PinEvent {
                    source: db9(),
                    kind: EventKind::PinChange,
                    pin: button.sensor().pin(Pin::B),
                    value: heapless::Vec::from_slice(&[1]).unwrap(),
                });
                show!(button.wait_change())
            }
            "AnalogSensor::read_raw()" => show!(analog().read_raw()),
            "AnalogSensor::read()" => show!(analog().read()),
            "Ultrasonic::distance()" => show!(Ultrasonic::new(link, db9(), 1).unwrap().distance()),
            other => panic!("no scenario for table row `{other}`"),
        }
    })
}

fn hex_bytes(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap_or_else(|_| panic!("bad hex byte `{b}`")))
        .collect()
}

struct Row {
    call: String,
    frames: Vec<Vec<u8>>,
    replies: Vec<Vec<u8>>,
    returns: String,
}

fn table() -> Vec<Row> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/drivers.md");
    let doc = std::fs::read_to_string(path).expect("docs/drivers.md");
    let start = doc
        .find("<!-- microcode-table:begin -->")
        .expect("table begin marker");
    let end = doc
        .find("<!-- microcode-table:end -->")
        .expect("table end marker");
    let mut rows = Vec::new();
    for line in doc[start..end]
        .lines()
        .filter(|l| l.starts_with('|'))
        .skip(2)
    {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        // "", driver, call, sends, replies, returns, ""
        assert_eq!(cells.len(), 7, "row `{line}`");
        let cell = |s: &str| -> Vec<String> {
            s.split("<br>")
                .map(|x| x.trim().trim_matches('`').trim().to_string())
                .collect()
        };
        let call = cells[2].trim_matches('`').to_string();
        let frames: Vec<Vec<u8>> = cell(cells[3]).iter().map(|f| hex_bytes(f)).collect();
        let replies: Vec<Vec<u8>> = cell(cells[4])
            .iter()
            .map(|r| if r == "·" { Vec::new() } else { hex_bytes(r) })
            .collect();
        assert_eq!(
            frames.len(),
            replies.len(),
            "one reply per frame in `{call}`"
        );
        assert!(call.starts_with(cells[1]), "driver column of `{call}`");
        let returns = cells[5].trim_matches('`').to_string();
        rows.push(Row {
            call,
            frames,
            replies,
            returns,
        });
    }
    rows
}

#[test]
fn the_table_in_docs_matches_the_drivers() {
    let rows = table();
    let in_doc: BTreeSet<&str> = rows.iter().map(|r| r.call.as_str()).collect();
    let here: BTreeSet<&str> = ROWS.iter().copied().collect();
    assert_eq!(in_doc.len(), rows.len(), "a row appears twice in the table");
    assert_eq!(in_doc, here, "rows in docs/drivers.md vs this test");
    for row in &rows {
        let link = Link::new();
        for r in &row.replies {
            link.reply(r);
        }
        let returned = run(&row.call, &link);
        assert_eq!(returned, row.returns, "value returned by `{}`", row.call);
        let want: Vec<&[u8]> = row.frames.iter().map(Vec::as_slice).collect();
        link.assert_sent(&want);
        link.finish();
    }
}
