//! The world file: TOML read with serde into plain records (each field with its place in
//! the text), then turned into a [`World`] with every error naming its line.

use serde::Deserialize;
use toml::{Spanned, Value};
use x10_devices::{Divider, ServoConfig, SteinhartHart, ThermistorConfig};

use super::{
    Board, BoardKind, BoardRef, Device, DeviceKind, DigitalSignal, Item, Pin, Ranger, Signal,
    World, WorldError, WorldErrorKind,
};

/// A world file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorld {
    #[serde(default)]
    board: Vec<Spanned<RawBoard>>,
    #[serde(default)]
    device: Vec<Spanned<RawDevice>>,
    // The physical models (world/arena.rs).
    physics: Option<Spanned<super::arena::RawPhysics>>,
    chassis: Option<Spanned<super::arena::RawChassis>>,
    arena: Option<Spanned<super::arena::RawArena>>,
    #[serde(default)]
    sensor: Vec<Spanned<super::arena::RawSensor>>,
    #[serde(default)]
    thermal: Vec<Spanned<super::arena::RawThermal>>,
    #[serde(default)]
    servo: Vec<Spanned<super::arena::RawServo>>,
    // The daughterboard images the motherboard carries (issue 25).
    #[serde(default)]
    image: Vec<Spanned<RawImage>>,
}

/// One `[[image]]`: a daughterboard image the motherboard carries (`kind`, `version`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawImage {
    kind: Spanned<String>,
    version: Spanned<String>,
}

/// One `[[board]]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBoard {
    address: Option<Spanned<i64>>,
    uid: Option<Spanned<String>>,
    name: Option<Spanned<String>>,
    kind: Option<Spanned<String>>,
    sensor_ports: Option<Spanned<i64>>,
    actuator_ports: Option<Spanned<i64>>,
    adc_bits: Option<Spanned<i64>>,
    /// The firmware version it runs (`"0.1.0"`).
    firmware: Option<Spanned<String>>,
    /// `false`: pinned to the firmware it runs, never updated.
    update: Option<Spanned<bool>>,
}

/// One `[[device]]`: every field any kind takes; which apply is checked per kind.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDevice {
    name: Spanned<String>,
    kind: Spanned<String>,
    board: Option<Spanned<Value>>,
    port: Option<Spanned<String>>,
    pin: Option<Spanned<String>>,
    pwm: Option<Spanned<String>>,
    active_low: Option<Spanned<bool>>,
    // Digital inputs.
    level: Option<Spanned<bool>>,
    toggles: Option<Spanned<Vec<u64>>>,
    presses: Option<Spanned<Vec<(u64, u64)>>>,
    pulses: Option<Spanned<RawPulses>>,
    // Analog inputs.
    counts: Option<Spanned<Value>>,
    celsius: Option<Spanned<Value>>,
    distance_mm: Option<Spanned<Value>>,
    // Thermistor wiring (each field overrides the thesis's).
    fixed_ohms: Option<Spanned<u32>>,
    adc_bits: Option<Spanned<u8>>,
    divider: Option<Spanned<String>>,
    steinhart_hart: Option<Spanned<[f32; 3]>>,
    // Ultrasonic wiring (each field overrides the HC-SR04's).
    trigger: Option<Spanned<String>>,
    echo: Option<Spanned<String>>,
    speed_of_sound: Option<Spanned<u16>>,
    echo_delay_us: Option<Spanned<u32>>,
    min_interval_ms: Option<Spanned<u32>>,
    // Servo range (each field overrides the standard one).
    min_us: Option<Spanned<u16>>,
    max_us: Option<Spanned<u16>>,
    max_angle: Option<Spanned<u16>>,
}

/// `pulses = { first_ms = 100, period_ms = 500, width_ms = 20 }`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPulses {
    first_ms: f64,
    period_ms: f64,
    width_ms: f64,
}

/// Line numbers of byte offsets.
struct Lines {
    starts: Vec<usize>,
}

impl Lines {
    fn new(text: &str) -> Lines {
        let mut starts = vec![0];
        starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Lines { starts }
    }

    /// Line (from 1) of byte `offset`.
    fn of(&self, offset: usize) -> usize {
        self.starts.partition_point(|s| *s <= offset).max(1)
    }
}

/// Reads `text` into a world (not yet checked: [`World::check`] does that with the lines
/// recorded here).
pub(super) fn parse(text: &str) -> Result<World, WorldError> {
    let lines = Lines::new(text);
    let raw: RawWorld = toml::from_str(text).map_err(|e| WorldError {
        line: e.span().map(|s| lines.of(s.start)),
        kind: WorldErrorKind::Syntax(e.message().trim().to_string()),
    })?;
    let mut world = World::new();
    for (i, b) in raw.board.iter().enumerate() {
        let item = Item::Board(i);
        let line = |s: &std::ops::Range<usize>| lines.of(s.start);
        world.lines.insert((item, ""), line(&b.span()));
        let b = b.get_ref();
        for (field, v) in [
            ("address", b.address.as_ref().map(Spanned::span)),
            ("uid", b.uid.as_ref().map(Spanned::span)),
            ("name", b.name.as_ref().map(Spanned::span)),
            ("kind", b.kind.as_ref().map(Spanned::span)),
            ("sensor_ports", b.sensor_ports.as_ref().map(Spanned::span)),
            (
                "actuator_ports",
                b.actuator_ports.as_ref().map(Spanned::span),
            ),
            ("adc_bits", b.adc_bits.as_ref().map(Spanned::span)),
            ("firmware", b.firmware.as_ref().map(Spanned::span)),
            ("update", b.update.as_ref().map(Spanned::span)),
        ] {
            if let Some(s) = v {
                world.lines.insert((item, field), line(&s));
            }
        }
        let board = board(b).map_err(|(field, kind)| world.at(item, field, kind))?;
        world.push_board(board);
    }
    for (i, d) in raw.device.iter().enumerate() {
        let item = Item::Device(i);
        world.lines.insert((item, ""), lines.of(d.span().start));
        let d = d.get_ref();
        for (field, span) in d.spans() {
            world.lines.insert((item, field), lines.of(span.start));
        }
        let device = device(d).map_err(|(field, kind)| world.at(item, field, kind))?;
        world.devices.push(device);
    }
    for (i, m) in raw.image.iter().enumerate() {
        let item = Item::Image(i);
        world.lines.insert((item, ""), lines.of(m.span().start));
        let m = m.get_ref();
        world
            .lines
            .insert((item, "kind"), lines.of(m.kind.span().start));
        world
            .lines
            .insert((item, "version"), lines.of(m.version.span().start));
        let image = image(i, m).map_err(|(field, kind)| world.at(item, field, kind))?;
        world.images.push(image);
    }
    let models = super::arena::RawModels {
        physics: raw.physics.as_ref(),
        chassis: raw.chassis.as_ref(),
        arena: raw.arena.as_ref(),
        sensors: &raw.sensor,
        thermals: &raw.thermal,
        servos: &raw.servo,
    };
    super::arena::read(models, &mut world, &|offset| lines.of(offset))?;
    Ok(world)
}

type FieldError = (&'static str, WorldErrorKind);

/// A version written `major.minor.patch`, each 0 to 255.
pub(super) fn parse_version(text: &str) -> Option<x10_microcode::Version> {
    let mut parts = text.split('.').map(|p| p.parse::<u8>().ok());
    let v = [parts.next()??, parts.next()??, parts.next()??];
    parts.next().is_none().then_some(v)
}

fn version_field(
    label: &str,
    field: &'static str,
    text: &str,
) -> Result<x10_microcode::Version, FieldError> {
    parse_version(text).ok_or((
        field,
        super::bad(
            label.to_string(),
            field,
            format!("is \"{text}\": major.minor.patch, each 0 to 255 (\"0.1.0\")"),
        ),
    ))
}

fn image(i: usize, m: &RawImage) -> Result<super::CarriedImage, FieldError> {
    let label = format!("image {}", i + 1);
    let kind = match m.kind.get_ref().as_str() {
        "pico" => BoardKind::Pico,
        "g431" => BoardKind::G431,
        "simulated" => BoardKind::Simulated {
            sensor_ports: 0,
            actuator_ports: 0,
        },
        other => {
            return Err((
                "kind",
                super::bad(
                    label,
                    "kind",
                    format!("is \"{other}\": \"pico\", \"g431\" or \"simulated\""),
                ),
            ))
        }
    };
    let version = version_field(&label, "version", m.version.get_ref())?;
    Ok(super::CarriedImage { kind, version })
}

fn board(b: &RawBoard) -> Result<Board, FieldError> {
    // No address: plug and play (named by its `name`, checked with the other boards).
    let addr = match &b.address {
        None => None,
        Some(address) => {
            let address = *address.get_ref();
            Some(
                u8::try_from(address)
                    .ok()
                    .filter(|a| *a == 0 || (0x08..=0x76).contains(a))
                    .ok_or(("address", WorldErrorKind::BadAddress { address }))?,
            )
        }
    };
    let label = match (addr, &b.name) {
        (Some(0), _) => "mb".to_string(),
        (Some(a), _) => format!("db{a:02x}"),
        (None, Some(n)) => n.get_ref().clone(),
        (None, None) => "a board without an address".to_string(),
    };
    let uid = match &b.uid {
        None => None,
        Some(u) => Some(parse_uid(u.get_ref()).ok_or((
            "uid",
            super::bad(
                label.clone(),
                "uid",
                format!(
                    "is \"{}\": 16 hexadecimal digits, the ID's 8 bytes in order",
                    u.get_ref()
                ),
            ),
        ))?),
    };
    let ports = |field: &'static str, v: &Option<Spanned<i64>>| -> Result<Option<u8>, FieldError> {
        match v {
            None => Ok(None),
            Some(n) => u8::try_from(*n.get_ref())
                .ok()
                .filter(|n| *n <= x10_microcode::Port::MAX_PORTS)
                .map(Some)
                .ok_or((
                    field,
                    WorldErrorKind::BoardPorts {
                        board: label.clone(),
                        reason: format!("`{field}` is {}: 0 to 64", n.get_ref()),
                    },
                )),
        }
    };
    let sensors = ports("sensor_ports", &b.sensor_ports)?;
    let actuators = ports("actuator_ports", &b.actuator_ports)?;
    let kind_name = b.kind.as_ref().map(|k| k.get_ref().as_str());
    let kind = match kind_name {
        Some("pico" | "g431") => {
            if sensors.is_some() || actuators.is_some() {
                let field = if sensors.is_some() {
                    "sensor_ports"
                } else {
                    "actuator_ports"
                };
                let kind = if kind_name == Some("pico") {
                    BoardKind::Pico
                } else {
                    BoardKind::G431
                };
                return Err((
                    field,
                    WorldErrorKind::BoardPorts {
                        board: label,
                        reason: format!(
                            "a {} has {} sensor and {} actuator ports: leave out `sensor_ports` and `actuator_ports`, or make it `kind = \"simulated\"`",
                            kind.label(),
                            kind.sensor_ports(),
                            kind.actuator_ports()
                        ),
                    },
                ));
            }
            if kind_name == Some("pico") {
                BoardKind::Pico
            } else {
                BoardKind::G431
            }
        }
        None | Some("simulated") => match (sensors, actuators) {
            (Some(sensor_ports), Some(actuator_ports)) => BoardKind::Simulated {
                sensor_ports,
                actuator_ports,
            },
            _ => {
                return Err((
                    if kind_name.is_some() { "kind" } else { "address" },
                    WorldErrorKind::BoardPorts {
                        board: label,
                        reason: "needs `sensor_ports` and `actuator_ports` (or `kind = \"pico\"` or `\"g431\"`)".to_string(),
                    },
                ))
            }
        },
        Some(other) => {
            return Err((
                "kind",
                WorldErrorKind::UnknownBoardKind {
                    board: label,
                    kind: other.to_string(),
                },
            ))
        }
    };
    let mut board = Board::of_kind(addr.unwrap_or(super::board::UNADDRESSED_KEY), kind);
    board.unaddressed = addr.is_none();
    board.uid = uid;
    if let Some(n) = &b.name {
        board = board.named(n.get_ref());
    }
    if let Some(v) = &b.firmware {
        board = board.firmware(version_field(&label, "firmware", v.get_ref())?);
    }
    if b.update.as_ref().is_some_and(|u| !*u.get_ref()) {
        board = board.pinned();
    }
    if let Some(bits) = &b.adc_bits {
        let bits = u8::try_from(*bits.get_ref())
            .ok()
            .filter(|b| (1..=16).contains(b))
            .ok_or((
                "adc_bits",
                super::bad(
                    label.clone(),
                    "adc_bits",
                    format!("is {}: 1 to 16 bits", bits.get_ref()),
                ),
            ))?;
        board = board.adc_bits(bits);
    }
    Ok(board)
}

/// A unique ID written as 16 hexadecimal digits (`"e6613852833f5c2a"`).
fn parse_uid(s: &str) -> Option<x10_microcode::Uid> {
    if s.len() != 16 || !s.is_ascii() {
        return None;
    }
    let mut u = [0u8; 8];
    for (i, b) in u.iter_mut().enumerate() {
        *b = u8::from_str_radix(s.get(2 * i..2 * i + 2)?, 16).ok()?;
    }
    Some(x10_microcode::Uid(u))
}

impl RawDevice {
    /// The fields present, with their spans.
    fn spans(&self) -> Vec<(&'static str, std::ops::Range<usize>)> {
        fn s<T>(v: &Option<Spanned<T>>) -> Option<std::ops::Range<usize>> {
            v.as_ref().map(Spanned::span)
        }
        let all = [
            ("name", Some(self.name.span())),
            ("kind", Some(self.kind.span())),
            ("board", s(&self.board)),
            ("port", s(&self.port)),
            ("pin", s(&self.pin)),
            ("pwm", s(&self.pwm)),
            ("active_low", s(&self.active_low)),
            ("level", s(&self.level)),
            ("toggles", s(&self.toggles)),
            ("presses", s(&self.presses)),
            ("pulses", s(&self.pulses)),
            ("counts", s(&self.counts)),
            ("celsius", s(&self.celsius)),
            ("distance_mm", s(&self.distance_mm)),
            ("fixed_ohms", s(&self.fixed_ohms)),
            ("adc_bits", s(&self.adc_bits)),
            ("divider", s(&self.divider)),
            ("steinhart_hart", s(&self.steinhart_hart)),
            ("trigger", s(&self.trigger)),
            ("echo", s(&self.echo)),
            ("speed_of_sound", s(&self.speed_of_sound)),
            ("echo_delay_us", s(&self.echo_delay_us)),
            ("min_interval_ms", s(&self.min_interval_ms)),
            ("min_us", s(&self.min_us)),
            ("max_us", s(&self.max_us)),
            ("max_angle", s(&self.max_angle)),
        ];
        all.into_iter()
            .filter_map(|(f, s)| s.map(|s| (f, s)))
            .collect()
    }
}

/// The fields each kind takes besides `name`, `kind`, `board` and `port`.
fn fields_of(kind: &str) -> &'static [&'static str] {
    match kind {
        "dc_motor" => &[],
        "led" => &["pin", "pwm"],
        "digital_output" => &["pin"],
        "pwm_output" => &["pwm"],
        "servo" => &["pwm", "min_us", "max_us", "max_angle"],
        "button" | "switch" => &["pin", "active_low", "level", "toggles", "presses", "pulses"],
        "digital_input" => &["pin", "level", "toggles", "presses", "pulses"],
        "light_sensor" | "force_sensor" | "analog_input" => &["counts"],
        "thermistor" => &[
            "celsius",
            "fixed_ohms",
            "adc_bits",
            "divider",
            "steinhart_hart",
        ],
        "ultrasonic" => &[
            "distance_mm",
            "trigger",
            "echo",
            "speed_of_sound",
            "echo_delay_us",
            "min_interval_ms",
        ],
        _ => &[],
    }
}

fn device(d: &RawDevice) -> Result<Device, FieldError> {
    let name = d.name.get_ref().clone();
    let kind = d.kind.get_ref().as_str();
    let Some(kind_name) = super::DeviceKind::NAMES.iter().find(|k| **k == kind) else {
        return Err((
            "kind",
            WorldErrorKind::UnknownDeviceKind {
                device: name,
                kind: kind.to_string(),
            },
        ));
    };
    let allowed = fields_of(kind);
    for (field, _) in d.spans() {
        if !matches!(field, "name" | "kind" | "board" | "port") && !allowed.contains(&field) {
            return Err((
                field,
                WorldErrorKind::NotApplicable {
                    device: name,
                    field: field.to_string(),
                    kind: kind_name,
                },
            ));
        }
    }
    let who = format!("device `{name}`");
    let bad = |field: &'static str, reason: String| (field, super::bad(who.clone(), field, reason));
    let missing = |field: &'static str| {
        (
            field,
            WorldErrorKind::MissingField {
                device: name.clone(),
                field,
            },
        )
    };
    let board = match &d.board {
        None => BoardRef::Address(0),
        Some(v) => match v.get_ref() {
            Value::String(s) => BoardRef::Name(s.clone()),
            Value::Integer(n) => BoardRef::Address(u8::try_from(*n).map_err(|_| {
                (
                    "board",
                    WorldErrorKind::UnknownBoard {
                        device: name.clone(),
                        board: n.to_string(),
                    },
                )
            })?),
            _ => {
                return Err(bad(
                    "board",
                    "must be a board's name (\"mb\", \"db09\", …) or address (0, 9, …)".to_string(),
                ))
            }
        },
    };
    let port_text = d.port.as_ref().ok_or_else(|| missing("port"))?.get_ref();
    let (port_kind, port) = parse_port(port_text).ok_or((
        "port",
        WorldErrorKind::BadPort {
            device: name.clone(),
            port: port_text.clone(),
        },
    ))?;
    let pin_field =
        |field: &'static str, v: &Option<Spanned<String>>| -> Result<Option<Pin>, FieldError> {
            match v {
                None => Ok(None),
                Some(p) => match p.get_ref().as_str() {
                    "A" | "a" => Ok(Some(Pin::A)),
                    "B" | "b" => Ok(Some(Pin::B)),
                    other => Err(bad(field, format!("is \"{other}\": \"A\" or \"B\""))),
                },
            }
        };
    let pin = pin_field("pin", &d.pin)?;
    let pwm = pin_field("pwm", &d.pwm)?;
    let need = |p: Option<Pin>, field: &'static str| p.ok_or_else(|| missing(field));
    let digital = || digital_signal(d).map_err(|(f, r)| bad(f, r));
    let signal =
        |field: &'static str, v: &Option<Spanned<Value>>| -> Result<Option<Signal>, FieldError> {
            v.as_ref()
                .map(|v| numeric_signal(v.get_ref()).map_err(|r| bad(field, r)))
                .transpose()
        };
    let active_low = d.active_low.as_ref().is_some_and(|v| *v.get_ref());
    let kind = match kind {
        "dc_motor" => DeviceKind::DcMotor,
        "led" => match (pin, pwm) {
            (Some(pin), None) => DeviceKind::Led {
                pin,
                dimmable: false,
            },
            (None, Some(pin)) => DeviceKind::Led {
                pin,
                dimmable: true,
            },
            (None, None) => return Err(missing("pin")),
            (Some(_), Some(_)) => {
                return Err(bad(
                    "pwm",
                    "and `pin` both given: an LED is on a digital pin (`pin`) or, dimmable, on a PWM pin (`pwm`)".to_string(),
                ))
            }
        },
        "digital_output" => DeviceKind::DigitalOutput {
            pin: need(pin, "pin")?,
        },
        "pwm_output" => DeviceKind::PwmOutput {
            pin: need(pwm, "pwm")?,
        },
        "servo" => {
            let std = ServoConfig::STANDARD;
            let v = |f: &Option<Spanned<u16>>, default: u16| f.as_ref().map_or(default, |v| *v.get_ref());
            let config = ServoConfig::new(
                v(&d.min_us, std.min_us()),
                v(&d.max_us, std.max_us()),
                v(&d.max_angle, std.max_angle()),
            )
            .map_err(|e| {
                let field = if e.quantity == x10_devices::Quantity::MaxAngle {
                    "max_angle"
                } else if d.min_us.is_some() {
                    "min_us"
                } else {
                    "max_us"
                };
                bad(field, format!("out of range: {e:?}"))
            })?;
            DeviceKind::Servo {
                pin: need(pwm, "pwm")?,
                config,
            }
        }
        "button" => DeviceKind::Button {
            pin: need(pin, "pin")?,
            active_low,
            pressed: digital()?,
        },
        "switch" => DeviceKind::Switch {
            pin: need(pin, "pin")?,
            active_low,
            on: digital()?,
        },
        "digital_input" => DeviceKind::DigitalInput {
            pin: need(pin, "pin")?,
            level: digital()?,
        },
        "light_sensor" => DeviceKind::LightSensor {
            counts: signal("counts", &d.counts)?.unwrap_or(Signal::Const(0.0)),
        },
        "force_sensor" => DeviceKind::ForceSensor {
            counts: signal("counts", &d.counts)?.unwrap_or(Signal::Const(0.0)),
        },
        "analog_input" => DeviceKind::AnalogInput {
            counts: signal("counts", &d.counts)?.unwrap_or(Signal::Const(0.0)),
        },
        "thermistor" => {
            let t = ThermistorConfig::THESIS;
            let coefficients = d.steinhart_hart.as_ref().map_or(t.coefficients(), |c| {
                let [a, b, c] = *c.get_ref();
                SteinhartHart { a, b, c }
            });
            let divider = match d.divider.as_ref().map(|v| v.get_ref().as_str()) {
                None => t.divider(),
                Some("thermistor_high") => Divider::ThermistorHigh,
                Some("thermistor_low") => Divider::ThermistorLow,
                Some(other) => {
                    return Err(bad(
                        "divider",
                        format!("is \"{other}\": \"thermistor_high\" or \"thermistor_low\""),
                    ))
                }
            };
            let config = ThermistorConfig::new(
                coefficients,
                d.fixed_ohms.as_ref().map_or(t.fixed_ohms(), |v| *v.get_ref()),
                d.adc_bits.as_ref().map_or(t.adc_bits(), |v| *v.get_ref()),
                divider,
            )
            .map_err(|e| {
                let field = if e.quantity == x10_devices::Quantity::AdcBits {
                    "adc_bits"
                } else {
                    "fixed_ohms"
                };
                bad(field, format!("out of range: {e:?}"))
            })?;
            DeviceKind::Thermistor {
                config,
                celsius: signal("celsius", &d.celsius)?.unwrap_or(Signal::Const(20.0)),
            }
        }
        "ultrasonic" => {
            let h = Ranger::HC_SR04;
            let trigger = match d.trigger.as_ref().map(|v| v.get_ref().as_str()) {
                None => h.trigger,
                Some("none") => None,
                Some(_) => pin_field("trigger", &d.trigger)?,
            };
            DeviceKind::Ultrasonic {
                ranger: Ranger {
                    trigger,
                    echo: pin_field("echo", &d.echo)?.unwrap_or(h.echo),
                    speed_of_sound_m_s: d
                        .speed_of_sound
                        .as_ref()
                        .map_or(h.speed_of_sound_m_s, |v| *v.get_ref()),
                    echo_delay_us: d
                        .echo_delay_us
                        .as_ref()
                        .map_or(h.echo_delay_us, |v| *v.get_ref()),
                    min_interval_ms: d
                        .min_interval_ms
                        .as_ref()
                        .map_or(h.min_interval_ms, |v| *v.get_ref()),
                },
                distance_mm: signal("distance_mm", &d.distance_mm)?
                    .unwrap_or(Signal::Const(1_000.0)),
            }
        }
        _ => {
            return Err((
                "kind",
                WorldErrorKind::UnknownDeviceKind {
                    device: name,
                    kind: kind.to_string(),
                },
            ))
        }
    };
    if kind.port_kind() != port_kind {
        return Err((
            "port",
            WorldErrorKind::WrongPortKind {
                device: name,
                kind: kind_name,
                port: format!(
                    "{}{port}",
                    if port_kind == x10_microcode::PortKind::Sensor {
                        'S'
                    } else {
                        'A'
                    }
                ),
            },
        ));
    }
    Ok(Device::new(&name, board, port, kind))
}

/// `S1` → (sensor, 1), `A12` → (actuator, 12).
fn parse_port(text: &str) -> Option<(x10_microcode::PortKind, u8)> {
    let mut chars = text.chars();
    let kind = match chars.next()? {
        'S' | 's' => x10_microcode::PortKind::Sensor,
        'A' | 'a' => x10_microcode::PortKind::Actuator,
        _ => return None,
    };
    let rest = chars.as_str();
    if rest.is_empty() || !rest.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    Some((kind, rest.parse().ok()?))
}

/// A time in ms (integer or float, not negative) as µs.
fn ms_to_us(v: &Value) -> Option<u64> {
    let ms = match v {
        Value::Integer(n) => *n as f64,
        Value::Float(f) => *f,
        _ => return None,
    };
    ms_f64_to_us(ms)
}

/// A time in ms (finite, not negative, below 10¹² ms) as µs.
fn ms_f64_to_us(ms: f64) -> Option<u64> {
    (0.0..1e12)
        .contains(&ms)
        .then(|| (ms * 1_000.0).round() as u64)
}

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Integer(n) => Some(*n as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

const SIGNAL_FORMS: &str =
    "must be a number, `{ steps = [[t_ms, value], …] }` or `{ linear = [[t_ms, value], …] }`";

/// `40`, `{ steps = [[0, 40], [3600, 350]] }`, `{ linear = [[0, 100], [4000, 800]] }`.
fn numeric_signal(v: &Value) -> Result<Signal, String> {
    if let Some(x) = number(v) {
        return Ok(Signal::Const(x));
    }
    let Value::Table(t) = v else {
        return Err(SIGNAL_FORMS.to_string());
    };
    let mut keys = t.keys();
    let (Some(key), None) = (keys.next(), keys.next()) else {
        return Err(SIGNAL_FORMS.to_string());
    };
    let Some(Value::Array(points)) = t.get(key) else {
        return Err(SIGNAL_FORMS.to_string());
    };
    let mut out = Vec::new();
    for p in points {
        let pair = match p {
            Value::Array(a) if a.len() == 2 => {
                a.first().and_then(ms_to_us).zip(a.get(1).and_then(number))
            }
            _ => None,
        };
        let Some(pair) = pair else {
            return Err(format!(
                "has `{p}` in `{key}`: each point is [t_ms, value] with t_ms not negative"
            ));
        };
        out.push(pair);
    }
    match key.as_str() {
        "steps" => Ok(Signal::Steps(out)),
        "linear" => Ok(Signal::Linear(out)),
        _ => Err(SIGNAL_FORMS.to_string()),
    }
}

/// The digital script of a button, switch or digital input from `level`, `toggles`,
/// `presses` or `pulses`; on an error, the field and what is wrong.
fn digital_signal(d: &RawDevice) -> Result<DigitalSignal, (&'static str, String)> {
    let level = d.level.as_ref().map(|v| *v.get_ref());
    match (&d.toggles, &d.presses, &d.pulses) {
        (None, None, None) => Ok(DigitalSignal::Const(level.unwrap_or(false))),
        (Some(t), None, None) => Ok(DigitalSignal::Toggles {
            initial: level.unwrap_or(false),
            at_ms: t.get_ref().clone(),
        }),
        (None, Some(p), None) if level.is_none() => Ok(DigitalSignal::Presses(p.get_ref().clone())),
        (None, None, Some(p)) if level.is_none() => {
            let p = p.get_ref();
            let us = ms_f64_to_us;
            match (us(p.first_ms), us(p.period_ms), us(p.width_ms)) {
                (Some(first_us), Some(period_us), Some(width_us)) => Ok(DigitalSignal::Pulses {
                    first_us,
                    period_us,
                    width_us,
                }),
                _ => Err(("pulses", "needs times in ms, not negative".to_string())),
            }
        }
        (_, Some(_), _) => Err((
            "presses",
            "cannot be combined with `level`, `toggles` or `pulses`".to_string(),
        )),
        _ => Err((
            "pulses",
            "cannot be combined with `level`, `toggles` or `presses`".to_string(),
        )),
    }
}
