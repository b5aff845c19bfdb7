//! The world a robot program runs against: its boards, the devices on their ports and the
//! signals its sensors see over virtual time, described once in Rust ([`World`], a builder)
//! or in a small TOML file ([`World::from_toml`], [`World::load`]; the format is in
//! `docs/world.md`), then turned into a [`Sim`] ([`World::sim`]). After the run,
//! [`crate::timeline`] says per device what happened, in device words.
//!
//! ```
//! use x10_sim::sim::SimConfig;
//! use x10_sim::world::{Board, Device, Pin, Signal, World, SELF};
//!
//! let world = World::new()
//!     .board(Board::internal(2, 2))
//!     .board(Board::new(9, 2, 2))
//!     .device(Device::dc_motor("drive", SELF, 1))
//!     .device(Device::button("bumper", SELF, 2, Pin::B).pressed_at_ms(1_000, 50))
//!     .device(Device::light_sensor("light", SELF, 1).counts(Signal::linear([(0, 100.0), (4_000, 800.0)])))
//!     .device(Device::led("heartbeat", 9, 1, Pin::A));
//! let sim = world.sim(SimConfig::default()).unwrap();
//! // Add the robot program or test tasks to `sim`, then run it:
//! let outcome = sim.run().unwrap();
//! let timeline = x10_sim::timeline::Timeline::new(&world, &outcome);
//! assert!(!timeline.led("heartbeat").unwrap().last_state());
//! ```
//!
//! The device models:
//!
//! * **inputs** follow their scripts exactly: a button's pin is at its pressed level during
//!   each press; an analog sensor's ADC reading is its counts profile; a thermistor's reading
//!   is the raw value whose temperature, through the driver's own divider and Steinhart–Hart
//!   arithmetic, is closest to the scripted temperature ([`thermistor_raw`]); an ultrasonic
//!   ranger's echo pin answers a pulse-in after a trigger pulse with the echo width of the
//!   scripted distance ([`echo_width_us`], [`crate::ports::Digital::Echo`]);
//! * **outputs** are whatever the runtime drove, as the board's ports recorded it; the
//!   timeline decodes them (an H-bridge's direction and duty, an LED's level or brightness, a
//!   servo's angle).

mod file;
mod model;

use std::collections::HashMap;
use std::fmt;
use std::path::Path;
use std::rc::Rc;

use x10_devices::{ServoConfig, ThermistorConfig};
use x10_microcode::{Address, Port, PortKind};

pub use model::{echo_width_us, thermistor_raw};
pub use x10_devices::SELF;
pub use x10_microcode::Pin;

use crate::board::board_name;
use crate::ports::{Analog, Digital, SensorScript, SimPorts};
use crate::sim::{Sim, SimConfig};

/// The name of the motherboard's internal daughterboard (address 0) in the simulator's log and
/// trace.
pub const INTERNAL_NAME: &str = "mb";

/// What a board is: one of the two supported chips (with their fixed port counts and 12-bit
/// ADC), or a simulated board with any number of ports and a 10-bit ADC (the thesis's Arduino
/// figures).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardKind {
    /// A Raspberry Pi Pico (RP2040): [`BoardKind::PICO_PORTS`], 12-bit ADC.
    Pico,
    /// An STM32G431CB: [`BoardKind::G431_PORTS`], 12-bit ADC.
    G431,
    /// Any number of ports (0–64 of each), a 10-bit ADC unless the board says otherwise.
    Simulated {
        /// Sensor ports.
        sensor_ports: u8,
        /// Actuator ports.
        actuator_ports: u8,
    },
}

impl BoardKind {
    /// (sensor ports, actuator ports) of a Pico, as `x10_boards::pins::PICO` has them.
    pub const PICO_PORTS: (u8, u8) = (3, 3);
    /// (sensor ports, actuator ports) of a G431, as `x10_boards::pins::G431` has them.
    pub const G431_PORTS: (u8, u8) = (4, 4);
    /// ADC resolution of both chips' images.
    pub const CHIP_ADC_BITS: u8 = 12;
    /// ADC resolution of a simulated board unless it says otherwise.
    pub const SIMULATED_ADC_BITS: u8 = 10;

    /// Number of sensor ports.
    pub const fn sensor_ports(self) -> u8 {
        match self {
            BoardKind::Pico => Self::PICO_PORTS.0,
            BoardKind::G431 => Self::G431_PORTS.0,
            BoardKind::Simulated { sensor_ports, .. } => sensor_ports,
        }
    }

    /// Number of actuator ports.
    pub const fn actuator_ports(self) -> u8 {
        match self {
            BoardKind::Pico => Self::PICO_PORTS.1,
            BoardKind::G431 => Self::G431_PORTS.1,
            BoardKind::Simulated { actuator_ports, .. } => actuator_ports,
        }
    }

    /// The ADC resolution the board has unless it says otherwise.
    pub const fn default_adc_bits(self) -> u8 {
        match self {
            BoardKind::Pico | BoardKind::G431 => Self::CHIP_ADC_BITS,
            BoardKind::Simulated { .. } => Self::SIMULATED_ADC_BITS,
        }
    }

    /// `pico`, `g431` or `simulated`, as a world file spells it.
    pub const fn label(self) -> &'static str {
        match self {
            BoardKind::Pico => "pico",
            BoardKind::G431 => "g431",
            BoardKind::Simulated { .. } => "simulated",
        }
    }
}

/// A board of the world: the internal daughterboard (address 0) or a daughterboard on the
/// bus (0x08–0x77).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Board {
    address: u8,
    alias: Option<String>,
    kind: BoardKind,
    adc_bits: Option<u8>,
}

impl Board {
    /// The motherboard's internal daughterboard ([`SELF`], named `mb`) with simulated ports.
    /// A world that declares no internal board has one with 2 sensor and 2 actuator ports.
    pub fn internal(sensor_ports: u8, actuator_ports: u8) -> Board {
        Board::new(0, sensor_ports, actuator_ports)
    }

    /// A simulated daughterboard at `address` (`0` is the internal one), named after it
    /// (`db09` for 9).
    pub fn new(address: u8, sensor_ports: u8, actuator_ports: u8) -> Board {
        Board::of_kind(
            address,
            BoardKind::Simulated {
                sensor_ports,
                actuator_ports,
            },
        )
    }

    /// A board of `kind` at `address`.
    pub fn of_kind(address: u8, kind: BoardKind) -> Board {
        Board {
            address,
            alias: None,
            kind,
            adc_bits: None,
        }
    }

    /// A Raspberry Pi Pico at `address`.
    pub fn pico(address: u8) -> Board {
        Board::of_kind(address, BoardKind::Pico)
    }

    /// An STM32G431 at `address`.
    pub fn g431(address: u8) -> Board {
        Board::of_kind(address, BoardKind::G431)
    }

    /// Another name to refer to the board by (its log name stays `db09` / `mb`).
    pub fn named(mut self, name: &str) -> Board {
        self.alias = Some(name.to_string());
        self
    }

    /// The ADC resolution (1–16 bits).
    pub fn adc_bits(mut self, bits: u8) -> Board {
        self.adc_bits = Some(bits);
        self
    }

    /// The address (0 for the internal board).
    pub fn address(&self) -> u8 {
        self.address
    }

    /// True for the internal board.
    pub fn is_internal(&self) -> bool {
        self.address == 0
    }

    /// The kind.
    pub fn kind(&self) -> BoardKind {
        self.kind
    }

    /// The name the simulator's log and trace use: `mb` for the internal board, `db09` for
    /// address 9.
    pub fn log_name(&self) -> String {
        if self.is_internal() {
            INTERNAL_NAME.to_string()
        } else {
            format!("db{:02x}", self.address)
        }
    }

    /// The name given with [`Board::named`], if any.
    pub fn alias(&self) -> Option<&str> {
        self.alias.as_deref()
    }

    /// The ADC resolution.
    pub fn adc_resolution(&self) -> u8 {
        self.adc_bits.unwrap_or(self.kind.default_adc_bits())
    }

    /// The largest ADC reading.
    pub fn adc_max(&self) -> u16 {
        let bits = self.adc_resolution().clamp(1, 16);
        u16::try_from((1u32 << bits) - 1).unwrap_or(u16::MAX)
    }

    fn answers_to(&self, r: &BoardRef) -> bool {
        match r {
            BoardRef::Address(a) => *a == self.address,
            BoardRef::Name(n) => {
                *n == self.log_name()
                    || self.alias.as_deref() == Some(n.as_str())
                    || (self.is_internal() && n == "SELF")
            }
        }
    }

    fn ports(&self) -> (u8, u8) {
        (self.kind.sensor_ports(), self.kind.actuator_ports())
    }
}

/// Which board a device is on: an address (0 = [`SELF`]) or a name (`mb`, `SELF`, `db09`,
/// or a board's own name).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BoardRef {
    /// By address.
    Address(u8),
    /// By name.
    Name(String),
}

impl From<u8> for BoardRef {
    fn from(a: u8) -> Self {
        BoardRef::Address(a)
    }
}

impl From<Address> for BoardRef {
    fn from(a: Address) -> Self {
        BoardRef::Address(a.get())
    }
}

impl From<&str> for BoardRef {
    fn from(n: &str) -> Self {
        BoardRef::Name(n.to_string())
    }
}

impl From<String> for BoardRef {
    fn from(n: String) -> Self {
        BoardRef::Name(n)
    }
}

impl fmt::Display for BoardRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardRef::Address(0) => f.write_str("SELF"),
            BoardRef::Address(a) => write!(f, "{a:#04x}"),
            BoardRef::Name(n) => f.write_str(n),
        }
    }
}

/// A scripted number over virtual time (ADC counts, °C, mm). Times are µs from the start of
/// the run; the constructors take ms.
#[derive(Clone, Debug, PartialEq)]
pub enum Signal {
    /// Always this value.
    Const(f64),
    /// Piecewise constant: `(t_us, value)` in time order, each value from its time on; the
    /// first value also holds before its time.
    Steps(Vec<(u64, f64)>),
    /// Piecewise linear through `(t_us, value)` points in time order, constant before the
    /// first and after the last. Two points at the same time make a jump (the second value
    /// holds from that instant).
    Linear(Vec<(u64, f64)>),
}

impl Signal {
    /// Always `value`.
    pub fn constant(value: f64) -> Signal {
        Signal::Const(value)
    }

    /// Piecewise constant, from `(t_ms, value)` pairs.
    pub fn steps(points_ms: impl IntoIterator<Item = (u64, f64)>) -> Signal {
        Signal::Steps(ms_to_us(points_ms))
    }

    /// Piecewise linear, through `(t_ms, value)` points.
    pub fn linear(points_ms: impl IntoIterator<Item = (u64, f64)>) -> Signal {
        Signal::Linear(ms_to_us(points_ms))
    }

    /// A linear ramp from `from` at `start_ms` to `to` at `end_ms`, constant outside.
    pub fn ramp(from: f64, start_ms: u64, to: f64, end_ms: u64) -> Signal {
        Signal::linear([(start_ms, from), (end_ms, to)])
    }

    fn points(&self) -> &[(u64, f64)] {
        match self {
            Signal::Const(_) => &[],
            Signal::Steps(p) | Signal::Linear(p) => p,
        }
    }

    /// The script in words: `40 counts, 350 from 3.6 s, 40 from 4.2 s`; `200 counts at 0 s,
    /// 900 at 2.5 s, linear in between`.
    pub fn describe(&self, unit: &str) -> String {
        let with_unit = |x: f64| format!("{} {unit}", format_number(x));
        match self {
            Signal::Const(x) => with_unit(*x),
            Signal::Steps(p) => {
                let parts: Vec<String> = p
                    .iter()
                    .enumerate()
                    .map(|(i, (t, x))| match i {
                        0 if *t == 0 => with_unit(*x),
                        0 => format!("{} (also before {})", with_unit(*x), short_seconds(*t)),
                        _ => format!("{} from {}", format_number(*x), short_seconds(*t)),
                    })
                    .collect();
                parts.join(", ")
            }
            Signal::Linear(p) => {
                let parts: Vec<String> = p
                    .iter()
                    .enumerate()
                    .map(|(i, (t, x))| {
                        let v = if i == 0 {
                            with_unit(*x)
                        } else {
                            format_number(*x)
                        };
                        format!("{v} at {}", short_seconds(*t))
                    })
                    .collect();
                format!("{}, linear in between", parts.join(", "))
            }
        }
    }
}

/// `0 s`, `0.5 s`, `1.234567 s` from µs.
pub(crate) fn short_seconds(t_us: u64) -> String {
    let whole = t_us / 1_000_000;
    let frac = t_us % 1_000_000;
    if frac == 0 {
        format!("{whole} s")
    } else {
        let digits = format!("{frac:06}");
        format!("{whole}.{} s", digits.trim_end_matches('0'))
    }
}

/// `40`, `-18`, `121.1`, `0.25`: whole numbers without decimals, others as short as they
/// round-trip.
fn format_number(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else {
        format!("{x}")
    }
}

fn ms_to_us(points_ms: impl IntoIterator<Item = (u64, f64)>) -> Vec<(u64, f64)> {
    points_ms
        .into_iter()
        .map(|(t, v)| (t.saturating_mul(1_000), v))
        .collect()
}

/// `1.234 s` from ns (ms resolution, rounded down).
pub(crate) fn seconds(t_ns: u64) -> String {
    let ms = t_ns / 1_000_000;
    format!("{}.{:03} s", ms / 1_000, ms % 1_000)
}

/// A scripted digital input over virtual time (the logical level: pressed, on, high).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DigitalSignal {
    /// Always this level.
    Const(bool),
    /// `initial`, then toggled at each time (ms, strictly increasing).
    Toggles {
        /// Level before the first toggle.
        initial: bool,
        /// Toggle times in ms.
        at_ms: Vec<u64>,
    },
    /// Low except during each `(at_ms, for_ms)` press (in time order, not overlapping, not
    /// touching).
    Presses(Vec<(u64, u64)>),
    /// High pulses `width_us` wide every `period_us` from `first_us` on.
    Pulses {
        /// Start of the first pulse (µs).
        first_us: u64,
        /// Period (µs).
        period_us: u64,
        /// Width (µs, less than the period).
        width_us: u64,
    },
}

impl DigitalSignal {
    /// The script in words: `pressed at 1 s for 50 ms, at 3 s for 50 ms`.
    pub fn describe(&self, on: &str, off: &str) -> String {
        let level = |v: bool| if v { on } else { off };
        match self {
            DigitalSignal::Const(v) => format!("always {}", level(*v)),
            DigitalSignal::Toggles { initial, at_ms } => {
                let times: Vec<String> = at_ms.iter().map(|t| short_seconds(t * 1_000)).collect();
                format!("{}, toggled at {}", level(*initial), times.join(", "))
            }
            DigitalSignal::Presses(p) => {
                let parts: Vec<String> = p
                    .iter()
                    .map(|(at, d)| format!("at {} for {d} ms", short_seconds(at * 1_000)))
                    .collect();
                format!("{on} {}", parts.join(", "))
            }
            DigitalSignal::Pulses {
                first_us,
                period_us,
                width_us,
            } => format!(
                "{on} for {} every {} from {}",
                short_seconds(*width_us),
                short_seconds(*period_us),
                short_seconds(*first_us)
            ),
        }
    }
}

/// An ultrasonic ranger's wiring and timing (defaults: an HC-SR04 as
/// [`x10_devices::UltrasonicConfig::HC_SR04`] wires it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ranger {
    /// Trigger pin of the sensor port (`None`: free-running).
    pub trigger: Option<Pin>,
    /// Echo pin of the sensor port.
    pub echo: Pin,
    /// Speed of sound in m/s (the driver's, so distances convert back exactly).
    pub speed_of_sound_m_s: u16,
    /// From the end of the trigger pulse to the start of the echo, µs.
    pub echo_delay_us: u32,
}

impl Ranger {
    /// An HC-SR04: trigger on pin A, echo on pin B, sound at 343 m/s, the echo starting
    /// 500 µs after the trigger pulse (the driver's "about 0.5 ms").
    pub const HC_SR04: Ranger = Ranger {
        trigger: Some(Pin::A),
        echo: Pin::B,
        speed_of_sound_m_s: 343,
        echo_delay_us: 500,
    };
}

/// What a device is, with its pins and scripts.
#[derive(Clone, Debug, PartialEq)]
pub enum DeviceKind {
    /// A DC motor on an H-bridge on an actuator port (digital A/B = IN1/IN2, PWM A = EN;
    /// [`x10_devices::HBridge`]).
    DcMotor,
    /// An LED on a digital pin (on/off) or, `dimmable`, on a PWM pin (brightness).
    Led {
        /// Its pin.
        pin: Pin,
        /// On the PWM pin rather than the digital one.
        dimmable: bool,
    },
    /// Any output on a digital pin (a relay, an alarm).
    DigitalOutput {
        /// Its pin.
        pin: Pin,
    },
    /// Any output on a PWM pin of an actuator port.
    PwmOutput {
        /// Its PWM pin.
        pin: Pin,
    },
    /// A hobby servo on a PWM pin of an actuator port.
    Servo {
        /// Its PWM pin.
        pin: Pin,
        /// Its pulse range (the driver's).
        config: ServoConfig,
    },
    /// A push button on a digital pin of a sensor port.
    Button {
        /// Its pin.
        pin: Pin,
        /// Reads LOW when pressed.
        active_low: bool,
        /// When it is pressed.
        pressed: DigitalSignal,
    },
    /// A switch on a digital pin of a sensor port.
    Switch {
        /// Its pin.
        pin: Pin,
        /// Reads LOW when on.
        active_low: bool,
        /// When it is on.
        on: DigitalSignal,
    },
    /// Any digital input on a pin of a sensor port.
    DigitalInput {
        /// Its pin.
        pin: Pin,
        /// Its level.
        level: DigitalSignal,
    },
    /// A light sensor on a sensor port's analog input.
    LightSensor {
        /// Its reading.
        counts: Signal,
    },
    /// A force sensor on a sensor port's analog input.
    ForceSensor {
        /// Its reading.
        counts: Signal,
    },
    /// Any analog input.
    AnalogInput {
        /// Its reading.
        counts: Signal,
    },
    /// A thermistor in a divider on a sensor port's analog input.
    Thermistor {
        /// Its wiring (the driver's).
        config: ThermistorConfig,
        /// Its temperature.
        celsius: Signal,
    },
    /// An ultrasonic ranger on a sensor port's digital pins.
    Ultrasonic {
        /// Its wiring.
        ranger: Ranger,
        /// The distance to the obstacle.
        distance_mm: Signal,
    },
}

impl DeviceKind {
    /// The name a world file uses: `dc_motor`, `led`, …
    pub fn name(&self) -> &'static str {
        match self {
            DeviceKind::DcMotor => "dc_motor",
            DeviceKind::Led { .. } => "led",
            DeviceKind::DigitalOutput { .. } => "digital_output",
            DeviceKind::PwmOutput { .. } => "pwm_output",
            DeviceKind::Servo { .. } => "servo",
            DeviceKind::Button { .. } => "button",
            DeviceKind::Switch { .. } => "switch",
            DeviceKind::DigitalInput { .. } => "digital_input",
            DeviceKind::LightSensor { .. } => "light_sensor",
            DeviceKind::ForceSensor { .. } => "force_sensor",
            DeviceKind::AnalogInput { .. } => "analog_input",
            DeviceKind::Thermistor { .. } => "thermistor",
            DeviceKind::Ultrasonic { .. } => "ultrasonic",
        }
    }

    /// Every kind name, as [`DeviceKind::name`] spells them.
    pub const NAMES: [&'static str; 13] = [
        "dc_motor",
        "led",
        "digital_output",
        "pwm_output",
        "servo",
        "button",
        "switch",
        "digital_input",
        "light_sensor",
        "force_sensor",
        "analog_input",
        "thermistor",
        "ultrasonic",
    ];

    /// True for the devices whose state the runtime drives (the rest are scripted inputs).
    pub fn is_output(&self) -> bool {
        matches!(
            self,
            DeviceKind::DcMotor
                | DeviceKind::Led { .. }
                | DeviceKind::DigitalOutput { .. }
                | DeviceKind::PwmOutput { .. }
                | DeviceKind::Servo { .. }
        )
    }

    /// The kind of port it goes on.
    pub fn port_kind(&self) -> PortKind {
        if self.is_output() {
            PortKind::Actuator
        } else {
            PortKind::Sensor
        }
    }

    /// What it takes of its port.
    fn uses(&self) -> Vec<Use> {
        match self {
            DeviceKind::DcMotor => {
                vec![Use::Digital(Pin::A), Use::Digital(Pin::B), Use::Pwm(Pin::A)]
            }
            DeviceKind::Led {
                pin,
                dimmable: true,
            }
            | DeviceKind::PwmOutput { pin }
            | DeviceKind::Servo { pin, .. } => vec![Use::Pwm(*pin)],
            DeviceKind::Led { pin, .. }
            | DeviceKind::DigitalOutput { pin }
            | DeviceKind::Button { pin, .. }
            | DeviceKind::Switch { pin, .. }
            | DeviceKind::DigitalInput { pin, .. } => vec![Use::Digital(*pin)],
            DeviceKind::LightSensor { .. }
            | DeviceKind::ForceSensor { .. }
            | DeviceKind::AnalogInput { .. }
            | DeviceKind::Thermistor { .. } => vec![Use::Analog],
            DeviceKind::Ultrasonic { ranger, .. } => {
                let mut v = vec![Use::Digital(ranger.echo)];
                if let Some(t) = ranger.trigger.filter(|t| *t != ranger.echo) {
                    v.push(Use::Digital(t));
                }
                v
            }
        }
    }
}

/// What a device takes of its port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Use {
    Digital(Pin),
    Pwm(Pin),
    Analog,
}

fn pin_letter(p: Pin) -> char {
    match p {
        Pin::A => 'A',
        Pin::B => 'B',
    }
}

/// A device on a port of a board.
#[derive(Clone, Debug, PartialEq)]
pub struct Device {
    name: String,
    board: BoardRef,
    port: u8,
    kind: DeviceKind,
    misuse: Vec<String>,
}

impl Device {
    /// A device of `kind` on port `port` (from 1; a sensor or actuator port as the kind needs)
    /// of `board`.
    pub fn new(name: &str, board: impl Into<BoardRef>, port: u8, kind: DeviceKind) -> Device {
        Device {
            name: name.to_string(),
            board: board.into(),
            port,
            kind,
            misuse: Vec::new(),
        }
    }

    /// A DC motor on the H-bridge of actuator port `port`.
    pub fn dc_motor(name: &str, board: impl Into<BoardRef>, port: u8) -> Device {
        Device::new(name, board, port, DeviceKind::DcMotor)
    }

    /// An LED on digital pin `pin` of actuator port `port` (on while HIGH).
    pub fn led(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Led {
                pin,
                dimmable: false,
            },
        )
    }

    /// An LED on PWM pin `pin` of actuator port `port` (brightness = duty).
    pub fn dimmable_led(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Led {
                pin,
                dimmable: true,
            },
        )
    }

    /// Any output on digital pin `pin` of actuator port `port`.
    pub fn digital_output(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(name, board, port, DeviceKind::DigitalOutput { pin })
    }

    /// Any output on PWM pin `pin` of actuator port `port`.
    pub fn pwm_output(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(name, board, port, DeviceKind::PwmOutput { pin })
    }

    /// A [`ServoConfig::STANDARD`] servo on PWM pin `pin` of actuator port `port`.
    pub fn servo(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Servo {
                pin,
                config: ServoConfig::STANDARD,
            },
        )
    }

    /// A button (HIGH when pressed, never pressed until [`Device::pressed_at_ms`]) on digital
    /// pin `pin` of sensor port `port`.
    pub fn button(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Button {
                pin,
                active_low: false,
                pressed: DigitalSignal::Const(false),
            },
        )
    }

    /// A switch (HIGH when on, off until [`Device::level`] says otherwise) on digital pin
    /// `pin` of sensor port `port`.
    pub fn switch(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Switch {
                pin,
                active_low: false,
                on: DigitalSignal::Const(false),
            },
        )
    }

    /// Any digital input (low until [`Device::level`] says otherwise) on pin `pin` of sensor
    /// port `port`.
    pub fn digital_input(name: &str, board: impl Into<BoardRef>, port: u8, pin: Pin) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::DigitalInput {
                pin,
                level: DigitalSignal::Const(false),
            },
        )
    }

    /// A light sensor (0 counts until [`Device::counts`]) on sensor port `port`.
    pub fn light_sensor(name: &str, board: impl Into<BoardRef>, port: u8) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::LightSensor {
                counts: Signal::Const(0.0),
            },
        )
    }

    /// A force sensor (0 counts until [`Device::counts`]) on sensor port `port`.
    pub fn force_sensor(name: &str, board: impl Into<BoardRef>, port: u8) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::ForceSensor {
                counts: Signal::Const(0.0),
            },
        )
    }

    /// Any analog input (0 counts until [`Device::counts`]) on sensor port `port`.
    pub fn analog_input(name: &str, board: impl Into<BoardRef>, port: u8) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::AnalogInput {
                counts: Signal::Const(0.0),
            },
        )
    }

    /// A thermistor wired as [`ThermistorConfig::THESIS`], at 20 °C until
    /// [`Device::celsius`], on sensor port `port`.
    pub fn thermistor(name: &str, board: impl Into<BoardRef>, port: u8) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Thermistor {
                config: ThermistorConfig::THESIS,
                celsius: Signal::Const(20.0),
            },
        )
    }

    /// An HC-SR04 ([`Ranger::HC_SR04`]) 1 m from an obstacle until [`Device::distance_mm`],
    /// on sensor port `port`.
    pub fn ultrasonic(name: &str, board: impl Into<BoardRef>, port: u8) -> Device {
        Device::new(
            name,
            board,
            port,
            DeviceKind::Ultrasonic {
                ranger: Ranger::HC_SR04,
                distance_mm: Signal::Const(1_000.0),
            },
        )
    }

    fn misused(mut self, setting: &str) -> Device {
        self.misuse.push(setting.to_string());
        self
    }

    /// A button or switch: one more press at `at_ms` for `for_ms` (presses in time order).
    pub fn pressed_at_ms(mut self, at_ms: u64, for_ms: u64) -> Device {
        match &mut self.kind {
            DeviceKind::Button { pressed: s, .. }
            | DeviceKind::Switch { on: s, .. }
            | DeviceKind::DigitalInput { level: s, .. } => match s {
                DigitalSignal::Presses(p) => p.push((at_ms, for_ms)),
                DigitalSignal::Const(false) => *s = DigitalSignal::Presses(vec![(at_ms, for_ms)]),
                _ => return self.misused("pressed_at_ms (after another script)"),
            },
            _ => return self.misused("pressed_at_ms"),
        }
        self
    }

    /// A button, switch or digital input: its whole script.
    pub fn level(mut self, signal: DigitalSignal) -> Device {
        match &mut self.kind {
            DeviceKind::Button { pressed: s, .. }
            | DeviceKind::Switch { on: s, .. }
            | DeviceKind::DigitalInput { level: s, .. } => *s = signal,
            _ => return self.misused("level"),
        }
        self
    }

    /// A button or switch: reads LOW when pressed (a switch to ground with a pull-up).
    pub fn active_low(mut self) -> Device {
        match &mut self.kind {
            DeviceKind::Button { active_low, .. } | DeviceKind::Switch { active_low, .. } => {
                *active_low = true;
            }
            _ => return self.misused("active_low"),
        }
        self
    }

    /// A light, force or generic analog sensor: its reading in ADC counts.
    pub fn counts(mut self, signal: Signal) -> Device {
        match &mut self.kind {
            DeviceKind::LightSensor { counts }
            | DeviceKind::ForceSensor { counts }
            | DeviceKind::AnalogInput { counts } => *counts = signal,
            _ => return self.misused("counts"),
        }
        self
    }

    /// A thermistor: its temperature in °C.
    pub fn celsius(mut self, signal: Signal) -> Device {
        match &mut self.kind {
            DeviceKind::Thermistor { celsius, .. } => *celsius = signal,
            _ => return self.misused("celsius"),
        }
        self
    }

    /// A thermistor: its wiring.
    pub fn thermistor_config(mut self, config: ThermistorConfig) -> Device {
        match &mut self.kind {
            DeviceKind::Thermistor { config: c, .. } => *c = config,
            _ => return self.misused("thermistor_config"),
        }
        self
    }

    /// An ultrasonic ranger: the distance to the obstacle in mm.
    pub fn distance_mm(mut self, signal: Signal) -> Device {
        match &mut self.kind {
            DeviceKind::Ultrasonic { distance_mm, .. } => *distance_mm = signal,
            _ => return self.misused("distance_mm"),
        }
        self
    }

    /// An ultrasonic ranger: its wiring and timing.
    pub fn ranger(mut self, ranger: Ranger) -> Device {
        match &mut self.kind {
            DeviceKind::Ultrasonic { ranger: r, .. } => *r = ranger,
            _ => return self.misused("ranger"),
        }
        self
    }

    /// A servo: its pulse range.
    pub fn servo_config(mut self, config: ServoConfig) -> Device {
        match &mut self.kind {
            DeviceKind::Servo { config: c, .. } => *c = config,
            _ => return self.misused("servo_config"),
        }
        self
    }

    /// The name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The board it is on.
    pub fn board(&self) -> &BoardRef {
        &self.board
    }

    /// The port number (from 1).
    pub fn port_number(&self) -> u8 {
        self.port
    }

    /// What it is.
    pub fn kind(&self) -> &DeviceKind {
        &self.kind
    }

    /// Its port (`None` for a number outside 1–64).
    pub fn port(&self) -> Option<Port> {
        Port::new(self.kind.port_kind(), self.port).ok()
    }

    fn port_label(&self) -> String {
        let k = match self.kind.port_kind() {
            PortKind::Sensor => 'S',
            PortKind::Actuator => 'A',
        };
        format!("{k}{}", self.port)
    }

    /// Where it is, in words, with its board's log name: `mb A1`, `mb S2.B`, `db09 A2 PWM A`,
    /// `mb S3 (trigger A, echo B)`.
    pub fn place(&self, board_log_name: &str) -> String {
        let p = self.port_label();
        match &self.kind {
            DeviceKind::DcMotor
            | DeviceKind::LightSensor { .. }
            | DeviceKind::ForceSensor { .. }
            | DeviceKind::AnalogInput { .. }
            | DeviceKind::Thermistor { .. } => format!("{board_log_name} {p}"),
            DeviceKind::Led {
                pin,
                dimmable: true,
            }
            | DeviceKind::PwmOutput { pin }
            | DeviceKind::Servo { pin, .. } => {
                format!("{board_log_name} {p} PWM {}", pin_letter(*pin))
            }
            DeviceKind::Led { pin, .. }
            | DeviceKind::DigitalOutput { pin }
            | DeviceKind::Button { pin, .. }
            | DeviceKind::Switch { pin, .. }
            | DeviceKind::DigitalInput { pin, .. } => {
                format!("{board_log_name} {p}.{}", pin_letter(*pin))
            }
            DeviceKind::Ultrasonic { ranger, .. } => match ranger.trigger {
                Some(t) => format!(
                    "{board_log_name} {p} (trigger {}, echo {})",
                    pin_letter(t),
                    pin_letter(ranger.echo)
                ),
                None => format!("{board_log_name} {p} (echo {})", pin_letter(ranger.echo)),
            },
        }
    }
}

/// Where in a world file a thing was written (for error messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Item {
    Board(usize),
    Device(usize),
}

/// The boards and devices a robot program runs against.
#[derive(Clone, Debug, Default)]
pub struct World {
    boards: Vec<Board>,
    devices: Vec<Device>,
    /// Line of each (item, field) in the file the world came from.
    lines: HashMap<(Item, &'static str), usize>,
}

/// Two worlds are equal when they have the same boards and the same devices on the same
/// boards (named by address or by name alike), wherever they came from.
impl PartialEq for World {
    fn eq(&self, other: &Self) -> bool {
        let resolved = |w: &World| -> Vec<(Device, Option<u8>)> {
            w.devices
                .iter()
                .map(|d| {
                    let address = w.board_of(d).map(|b| b.address);
                    let mut d = d.clone();
                    if let Some(a) = address {
                        d.board = BoardRef::Address(a);
                    }
                    (d, address)
                })
                .collect()
        };
        self.boards == other.boards && resolved(self) == resolved(other)
    }
}

/// Why a world is not right: what and where (the line of the world file, when it came from
/// one).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorldError {
    /// Line of the world file (from 1), when known.
    pub line: Option<usize>,
    /// What is wrong.
    pub kind: WorldErrorKind,
}

/// What is wrong with a world.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WorldErrorKind {
    /// The file could not be read.
    Io {
        /// The file.
        path: String,
        /// Why.
        message: String,
    },
    /// Not TOML, or a value of the wrong type or an unknown field (the TOML reader's
    /// message).
    Syntax(String),
    /// A device kind this crate does not know.
    UnknownDeviceKind {
        /// The device.
        device: String,
        /// The kind it names.
        kind: String,
    },
    /// A board kind this crate does not know.
    UnknownBoardKind {
        /// The board.
        board: String,
        /// The kind it names.
        kind: String,
    },
    /// A device on a board the world does not have.
    UnknownBoard {
        /// The device.
        device: String,
        /// The board it names.
        board: String,
    },
    /// An address that is neither 0 (internal) nor 0x08–0x77.
    BadAddress {
        /// The address.
        address: i64,
    },
    /// Two boards at one address.
    DuplicateAddress {
        /// The address.
        address: u8,
    },
    /// Two boards that answer to one name.
    DuplicateBoardName {
        /// The name.
        name: String,
    },
    /// Two devices with one name.
    DuplicateDeviceName {
        /// The name.
        name: String,
    },
    /// A board whose port counts are missing, too large, or given for a chip whose counts are
    /// fixed.
    BoardPorts {
        /// The board.
        board: String,
        /// What is wrong.
        reason: String,
    },
    /// A port written wrongly (not `S1`, `A2`, …).
    BadPort {
        /// The device.
        device: String,
        /// What was written.
        port: String,
    },
    /// A port the board does not have.
    PortOutOfRange {
        /// The device.
        device: String,
        /// The port (`A3`).
        port: String,
        /// The board's log name.
        board: String,
        /// Ports of that kind the board has.
        available: u8,
    },
    /// A device on the wrong kind of port (a motor on a sensor port).
    WrongPortKind {
        /// The device.
        device: String,
        /// Its kind.
        kind: &'static str,
        /// The port written.
        port: String,
    },
    /// A pin two devices use.
    PinTaken {
        /// The device.
        device: String,
        /// The pin (`mb A1 PWM A`).
        pin: String,
        /// The device that has it.
        by: String,
    },
    /// A servo sharing its port's PWM frequency (50 Hz) with another PWM device.
    SharedPwmFrequency {
        /// The servo.
        device: String,
        /// The other device.
        other: String,
    },
    /// A field the device needs.
    MissingField {
        /// The device.
        device: String,
        /// The field.
        field: &'static str,
    },
    /// A field or builder setting that does not apply to the device's kind.
    NotApplicable {
        /// The device.
        device: String,
        /// The field or setting.
        field: String,
        /// The device's kind.
        kind: &'static str,
    },
    /// A value out of range or malformed (a signal, a pin, a configuration).
    BadValue {
        /// The device or board.
        item: String,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A board at the motherboard's own bus address.
    MotherboardAddress {
        /// The address.
        address: u8,
    },
}

impl fmt::Display for WorldErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use WorldErrorKind as K;
        match self {
            K::Io { path, message } => write!(f, "cannot read {path}: {message}"),
            K::Syntax(m) => f.write_str(m),
            K::UnknownDeviceKind { device, kind } => write!(
                f,
                "device `{device}`: unknown kind `{kind}` (kinds: {})",
                DeviceKind::NAMES.join(", ")
            ),
            K::UnknownBoardKind { board, kind } => write!(
                f,
                "board {board}: unknown kind `{kind}` (kinds: pico, g431, simulated)"
            ),
            K::UnknownBoard { device, board } => {
                write!(f, "device `{device}`: no board `{board}` in the world")
            }
            K::BadAddress { address } => write!(
                f,
                "board address {address}: not 0 (the internal board) nor 8 to 119 (0x08 to 0x77)"
            ),
            K::DuplicateAddress { address } => {
                write!(f, "two boards at address {address} ({address:#04x})")
            }
            K::DuplicateBoardName { name } => write!(f, "two boards are called `{name}`"),
            K::DuplicateDeviceName { name } => write!(f, "two devices are called `{name}`"),
            K::BoardPorts { board, reason } => write!(f, "board {board}: {reason}"),
            K::BadPort { device, port } => write!(
                f,
                "device `{device}`: port `{port}` is not a port (S1, S2, … for sensor ports, A1, A2, … for actuator ports)"
            ),
            K::PortOutOfRange {
                device,
                port,
                board,
                available,
            } => {
                let kind = if port.starts_with('S') {
                    "sensor"
                } else {
                    "actuator"
                };
                write!(
                    f,
                    "device `{device}`: port {port} is out of range: board {board} has {available} {kind} port{}",
                    if *available == 1 { "" } else { "s" }
                )
            }
            K::WrongPortKind { device, kind, port } => {
                let needs = if port.starts_with('S') {
                    "an actuator port (A1, A2, …)"
                } else {
                    "a sensor port (S1, S2, …)"
                };
                write!(f, "device `{device}`: a {kind} goes on {needs}, not on {port}")
            }
            K::PinTaken { device, pin, by } => {
                write!(f, "device `{device}`: {pin} is already used by `{by}`")
            }
            K::SharedPwmFrequency { device, other } => write!(
                f,
                "device `{device}`: a servo sets its port's PWM frequency to 50 Hz, which `{other}` on the same port also uses"
            ),
            K::MissingField { device, field } => {
                write!(f, "device `{device}`: `{field}` is missing")
            }
            K::NotApplicable {
                device,
                field,
                kind,
            } => write!(f, "device `{device}`: `{field}` does not apply to a {kind}"),
            K::BadValue {
                item,
                field,
                reason,
            } => write!(f, "{item}: `{field}` {reason}"),
            K::MotherboardAddress { address } => write!(
                f,
                "board at address {address:#04x}: that is the motherboard's own bus address"
            ),
        }
    }
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "line {l}: {}", self.kind),
            None => write!(f, "{}", self.kind),
        }
    }
}

impl std::error::Error for WorldError {}

impl WorldError {
    /// An error without a place.
    pub fn new(kind: WorldErrorKind) -> WorldError {
        WorldError { line: None, kind }
    }
}

fn bad(item: String, field: &str, reason: impl Into<String>) -> WorldErrorKind {
    WorldErrorKind::BadValue {
        item,
        field: field.to_string(),
        reason: reason.into(),
    }
}

impl World {
    /// An empty world: the internal board with 2 sensor and 2 actuator ports, no devices.
    pub fn new() -> World {
        World::default()
    }

    /// Adds a board (an internal one replaces the default).
    pub fn board(mut self, board: Board) -> World {
        self.boards.push(board);
        self
    }

    /// Adds a device.
    pub fn device(mut self, device: Device) -> World {
        self.devices.push(device);
        self
    }

    /// Reads a world file's text.
    ///
    /// # Errors
    /// [`WorldError`] with the line: TOML syntax, wrong types and unknown fields
    /// ([`WorldErrorKind::Syntax`]), then everything [`World::check`] finds.
    pub fn from_toml(text: &str) -> Result<World, WorldError> {
        let world = file::parse(text)?;
        world.check()?;
        Ok(world)
    }

    /// Reads a world file.
    ///
    /// # Errors
    /// [`WorldErrorKind::Io`] when it cannot be read; otherwise as [`World::from_toml`], the
    /// message prefixed by the path.
    pub fn load(path: impl AsRef<Path>) -> Result<World, WorldError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| {
            WorldError::new(WorldErrorKind::Io {
                path: path.display().to_string(),
                message: e.to_string(),
            })
        })?;
        World::from_toml(&text)
    }

    /// The boards, the internal one first (the default one when none was declared), then the
    /// others in the order given.
    pub fn boards(&self) -> Vec<Board> {
        let mut v = Vec::new();
        match self.boards.iter().find(|b| b.is_internal()) {
            Some(b) => v.push(b.clone()),
            None => v.push(Board::internal(2, 2)),
        }
        v.extend(self.boards.iter().filter(|b| !b.is_internal()).cloned());
        v
    }

    /// The devices in the order given.
    pub fn devices(&self) -> &[Device] {
        &self.devices
    }

    /// The device called `name`.
    pub fn device_named(&self, name: &str) -> Option<&Device> {
        self.devices.iter().find(|d| d.name == name)
    }

    /// The board `r` names.
    pub fn find_board(&self, r: &BoardRef) -> Option<Board> {
        self.boards().into_iter().find(|b| b.answers_to(r))
    }

    /// The board a device is on.
    pub fn board_of(&self, device: &Device) -> Option<Board> {
        self.find_board(&device.board)
    }

    fn at(&self, item: Item, field: &'static str, kind: WorldErrorKind) -> WorldError {
        let line = self
            .lines
            .get(&(item, field))
            .or_else(|| self.lines.get(&(item, "")))
            .copied();
        WorldError { line, kind }
    }

    /// Checks the world: boards (addresses, names, port counts), devices (names, boards,
    /// ports, pins, scripts).
    ///
    /// # Errors
    /// The first [`WorldError`] found, in file order.
    pub fn check(&self) -> Result<(), WorldError> {
        self.check_boards()?;
        self.check_devices()
    }

    fn check_boards(&self) -> Result<(), WorldError> {
        let mut addresses: Vec<u8> = Vec::new();
        let mut names: Vec<String> = Vec::new();
        for (i, b) in self.boards.iter().enumerate() {
            let item = Item::Board(i);
            if b.address != 0 && Address::external(b.address).is_err() {
                return Err(self.at(
                    item,
                    "address",
                    WorldErrorKind::BadAddress {
                        address: i64::from(b.address),
                    },
                ));
            }
            if addresses.contains(&b.address) {
                return Err(self.at(
                    item,
                    "address",
                    WorldErrorKind::DuplicateAddress { address: b.address },
                ));
            }
            addresses.push(b.address);
            let (s, a) = b.ports();
            if s > Port::MAX_PORTS || a > Port::MAX_PORTS {
                return Err(self.at(
                    item,
                    "sensor_ports",
                    WorldErrorKind::BoardPorts {
                        board: b.log_name(),
                        reason: format!(
                            "{s} sensor and {a} actuator ports: at most {} of each",
                            Port::MAX_PORTS
                        ),
                    },
                ));
            }
            if let Some(bits) = b.adc_bits.filter(|b| !(1..=16).contains(b)) {
                return Err(self.at(
                    item,
                    "adc_bits",
                    bad(b.log_name(), "adc_bits", format!("is {bits}: 1 to 16 bits")),
                ));
            }
            let mut own = vec![b.log_name()];
            if b.is_internal() {
                own.push("SELF".to_string());
            }
            if let Some(alias) = &b.alias {
                if alias.is_empty() {
                    return Err(self.at(item, "name", bad(b.log_name(), "name", "is empty")));
                }
                if !own.contains(alias) {
                    own.push(alias.clone());
                }
            }
            for n in own {
                if names.contains(&n) {
                    let field = if b.alias.as_ref() == Some(&n) {
                        "name"
                    } else {
                        "address"
                    };
                    return Err(self.at(
                        item,
                        field,
                        WorldErrorKind::DuplicateBoardName { name: n },
                    ));
                }
                names.push(n);
            }
        }
        Ok(())
    }

    fn check_devices(&self) -> Result<(), WorldError> {
        // (board address, port, use) → device name
        let mut taken: Vec<(u8, Port, Use, String)> = Vec::new();
        for (i, d) in self.devices.iter().enumerate() {
            let item = Item::Device(i);
            let at = |field, kind| self.at(item, field, kind);
            if d.name.is_empty() {
                return Err(at("name", bad("a device".to_string(), "name", "is empty")));
            }
            if self.devices[..i].iter().any(|o| o.name == d.name) {
                return Err(at(
                    "name",
                    WorldErrorKind::DuplicateDeviceName {
                        name: d.name.clone(),
                    },
                ));
            }
            if let Some(setting) = d.misuse.first() {
                return Err(at(
                    "",
                    WorldErrorKind::NotApplicable {
                        device: d.name.clone(),
                        field: setting.clone(),
                        kind: d.kind.name(),
                    },
                ));
            }
            let Some(board) = self.board_of(d) else {
                return Err(at(
                    "board",
                    WorldErrorKind::UnknownBoard {
                        device: d.name.clone(),
                        board: d.board.to_string(),
                    },
                ));
            };
            let (sensors, actuators) = board.ports();
            let available = match d.kind.port_kind() {
                PortKind::Sensor => sensors,
                PortKind::Actuator => actuators,
            };
            let Some(port) = d.port().filter(|_| d.port <= available) else {
                return Err(at(
                    "port",
                    WorldErrorKind::PortOutOfRange {
                        device: d.name.clone(),
                        port: d.port_label(),
                        board: board.log_name(),
                        available,
                    },
                ));
            };
            self.check_scripts(i, d, &board)?;
            for u in d.kind.uses() {
                if let Some((_, _, _, by)) = taken
                    .iter()
                    .find(|(a, p, used, _)| *a == board.address && *p == port && *used == u)
                {
                    let what = match u {
                        Use::Digital(p) => format!("{}.{}", d.port_label(), pin_letter(p)),
                        Use::Pwm(p) => format!("{} PWM {}", d.port_label(), pin_letter(p)),
                        Use::Analog => format!("{} analog input", d.port_label()),
                    };
                    return Err(at(
                        "port",
                        WorldErrorKind::PinTaken {
                            device: d.name.clone(),
                            pin: format!("{} {what}", board.log_name()),
                            by: by.clone(),
                        },
                    ));
                }
            }
            // A servo sets the port's PWM frequency: no other PWM user on that port but servos.
            let is_servo = matches!(d.kind, DeviceKind::Servo { .. });
            let uses_pwm = d.kind.uses().iter().any(|u| matches!(u, Use::Pwm(_)));
            if uses_pwm {
                for (a, p, u, by) in &taken {
                    if *a != board.address || *p != port || !matches!(u, Use::Pwm(_)) {
                        continue;
                    }
                    let other_is_servo = self
                        .device_named(by)
                        .is_some_and(|o| matches!(o.kind, DeviceKind::Servo { .. }));
                    if is_servo != other_is_servo {
                        let (servo, other) = if is_servo {
                            (d.name.clone(), by.clone())
                        } else {
                            (by.clone(), d.name.clone())
                        };
                        return Err(at(
                            "port",
                            WorldErrorKind::SharedPwmFrequency {
                                device: servo,
                                other,
                            },
                        ));
                    }
                }
            }
            for u in d.kind.uses() {
                taken.push((board.address, port, u, d.name.clone()));
            }
        }
        Ok(())
    }

    fn check_scripts(&self, i: usize, d: &Device, board: &Board) -> Result<(), WorldError> {
        let item = Item::Device(i);
        let who = format!("device `{}`", d.name);
        let err = |field: &'static str, reason: String| {
            Err(self.at(item, field, bad(who.clone(), field, reason)))
        };
        let check_signal = |field: &'static str, s: &Signal, min: f64, max: f64, whole: bool| {
            let pts = s.points();
            if matches!(s, Signal::Steps(_) | Signal::Linear(_)) && pts.is_empty() {
                return err(field, "has no points".to_string());
            }
            if pts.windows(2).any(|w| w[1].0 < w[0].0) {
                return err(field, "has times that go backwards".to_string());
            }
            let values: Vec<f64> = match s {
                Signal::Const(v) => vec![*v],
                _ => pts.iter().map(|p| p.1).collect(),
            };
            for v in values {
                if !v.is_finite() || v < min || v > max {
                    return err(field, format!("has {v}, outside {min} to {max}"));
                }
                if whole && v.fract() != 0.0 {
                    return err(field, format!("has {v}: ADC counts are whole numbers"));
                }
            }
            Ok(())
        };
        let check_digital = |field: &'static str, s: &DigitalSignal, active_low: bool| match s {
            DigitalSignal::Const(_) => Ok(()),
            DigitalSignal::Toggles { at_ms, .. } => {
                if at_ms.windows(2).any(|w| w[1] <= w[0]) {
                    err(field, "needs strictly increasing times".to_string())
                } else {
                    Ok(())
                }
            }
            DigitalSignal::Presses(p) => {
                if p.iter().any(|(_, d)| *d == 0) {
                    return err(field, "has a press of 0 ms".to_string());
                }
                if p.windows(2)
                    .any(|w| w[1].0 <= w[0].0.saturating_add(w[0].1))
                {
                    return err(
                        field,
                        "has presses out of time order, overlapping or touching".to_string(),
                    );
                }
                Ok(())
            }
            DigitalSignal::Pulses {
                period_us,
                width_us,
                ..
            } => {
                if active_low {
                    err(
                        field,
                        "cannot be a pulse train on an active-low input".to_string(),
                    )
                } else if *width_us == 0 || *width_us >= *period_us {
                    err(field, "needs 0 < width < period".to_string())
                } else {
                    Ok(())
                }
            }
        };
        let adc_max = f64::from(board.adc_max());
        match &d.kind {
            DeviceKind::LightSensor { counts }
            | DeviceKind::ForceSensor { counts }
            | DeviceKind::AnalogInput { counts } => {
                check_signal("counts", counts, 0.0, adc_max, true)
            }
            DeviceKind::Thermistor { config, celsius } => {
                if config.adc_bits() != board.adc_resolution() {
                    return err(
                        "adc_bits",
                        format!(
                            "is {} but board {} has a {}-bit ADC",
                            config.adc_bits(),
                            board.log_name(),
                            board.adc_resolution()
                        ),
                    );
                }
                check_signal("celsius", celsius, -273.15, 1_000.0, false)
            }
            DeviceKind::Ultrasonic {
                ranger,
                distance_mm,
            } => {
                if ranger.speed_of_sound_m_s == 0 {
                    return err("speed_of_sound", "is 0".to_string());
                }
                check_signal("distance_mm", distance_mm, 0.0, 100_000.0, false)
            }
            DeviceKind::Button {
                pressed: s,
                active_low,
                ..
            } => check_digital("presses", s, *active_low),
            DeviceKind::Switch {
                on: s, active_low, ..
            } => check_digital("level", s, *active_low),
            DeviceKind::DigitalInput { level, .. } => check_digital("level", level, false),
            _ => Ok(()),
        }
    }

    /// What sensor port `port` of `board` sees: the scripts of every device on it (pins and
    /// analog input nobody uses stay low and 0). `None` when the world has no such board or
    /// port.
    pub fn sensor_script(&self, board: impl Into<BoardRef>, port: u8) -> Option<SensorScript> {
        let board = self.find_board(&board.into())?;
        if port == 0 || port > board.kind.sensor_ports() {
            return None;
        }
        let mut script = SensorScript::default();
        for d in self
            .devices
            .iter()
            .filter(|d| d.port == port && board.answers_to(&d.board))
        {
            let pin_of = |script: &mut SensorScript, pin: Pin, s: Digital| match pin {
                Pin::A => script.a = s,
                Pin::B => script.b = s,
            };
            match &d.kind {
                DeviceKind::Button {
                    pin,
                    active_low,
                    pressed: s,
                }
                | DeviceKind::Switch {
                    pin,
                    active_low,
                    on: s,
                } => pin_of(&mut script, *pin, s.to_digital(*active_low)),
                DeviceKind::DigitalInput { pin, level } => {
                    pin_of(&mut script, *pin, level.to_digital(false));
                }
                DeviceKind::LightSensor { counts }
                | DeviceKind::ForceSensor { counts }
                | DeviceKind::AnalogInput { counts } => {
                    script.analog = match counts {
                        Signal::Const(_) => Analog::Const(counts.counts_at_us(0)),
                        _ => {
                            let c = counts.clone();
                            Analog::Func(Rc::new(move |t_us| c.counts_at_us(t_us)))
                        }
                    };
                }
                DeviceKind::Thermistor { config, celsius } => {
                    let config = *config;
                    script.analog = match celsius {
                        Signal::Const(c) => Analog::Const(thermistor_raw(&config, *c as f32)),
                        _ => {
                            let c = celsius.clone();
                            Analog::Func(Rc::new(move |t_us| {
                                thermistor_raw(&config, c.value_at_us_f32(t_us))
                            }))
                        }
                    };
                }
                DeviceKind::Ultrasonic {
                    ranger,
                    distance_mm,
                } => {
                    let speed = ranger.speed_of_sound_m_s;
                    let c = distance_mm.clone();
                    let echo = Digital::Echo {
                        trigger: ranger.trigger.filter(|t| *t != ranger.echo),
                        delay_us: u64::from(ranger.echo_delay_us),
                        width_us: Analog::Func(Rc::new(move |t_us| {
                            echo_width_us(c.value_at_us(t_us), speed)
                        })),
                    };
                    pin_of(&mut script, ranger.echo, echo);
                }
                DeviceKind::DcMotor
                | DeviceKind::Led { .. }
                | DeviceKind::DigitalOutput { .. }
                | DeviceKind::PwmOutput { .. }
                | DeviceKind::Servo { .. } => {}
            }
        }
        Some(script)
    }

    fn ports_for(&self, sim: &Sim, board: &Board) -> SimPorts {
        let (s, a) = board.ports();
        let mut ports = sim
            .ports(&board_name_of(board), s, a)
            .with_adc_bits(board.adc_resolution());
        for n in 1..=s {
            if let Some(script) = self.sensor_script(BoardRef::Address(board.address), n) {
                ports = ports.with_sensor(n, script);
            }
        }
        ports
    }

    /// A simulation of this world: the internal board's ports and every other board with its
    /// ports and scripts. No robot program: add it, or test tasks, to the returned [`Sim`].
    ///
    /// # Errors
    /// As [`World::check`]; [`WorldErrorKind::MotherboardAddress`] for a board at
    /// `config.mb_address`.
    pub fn sim(&self, config: SimConfig) -> Result<Sim, WorldError> {
        self.check()?;
        let mb = config.mb_address.get();
        if let Some(i) = self.boards.iter().position(|b| b.address == mb) {
            return Err(self.at(
                Item::Board(i),
                "address",
                WorldErrorKind::MotherboardAddress { address: mb },
            ));
        }
        let sim = Sim::new(config);
        let boards = self.boards();
        let mut sim = match boards.iter().find(|b| b.is_internal()) {
            Some(b) => {
                let ports = self.ports_for(&sim, b);
                sim.with_internal_ports(ports)
            }
            None => sim,
        };
        for b in boards.iter().filter(|b| !b.is_internal()) {
            let address = Address::external(b.address).map_err(|_| {
                WorldError::new(WorldErrorKind::BadAddress {
                    address: i64::from(b.address),
                })
            })?;
            let ports = self.ports_for(&sim, b);
            sim = sim.with_board(address, ports);
        }
        Ok(sim)
    }
}

/// The simulator's name of a board (`mb`, `db09`): the one its log and trace use.
fn board_name_of(board: &Board) -> String {
    match Address::external(board.address) {
        Ok(a) => board_name(a),
        Err(_) => INTERNAL_NAME.to_string(),
    }
}

/// `docs/world.md`: its Rust examples run as doctests (its TOML examples are read by
/// `tests/world.rs`).
#[cfg(doctest)]
#[doc = include_str!("../../docs/world.md")]
pub struct WorldGuide;

#[cfg(test)]
mod tests;
