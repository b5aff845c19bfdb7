//! Devices: what each kind is, the pins it takes, and the builder's constructors and settings.

use x10_devices::{ServoConfig, ThermistorConfig};
use x10_microcode::{Pin, Port, PortKind};

use super::{BoardRef, DigitalSignal, Signal};

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
    /// The shortest time between two measurements the part answers, ms (from one trigger
    /// pulse's end to the next): a trigger sooner than that gets no echo, and the run warns.
    pub min_interval_ms: u32,
}

impl Ranger {
    /// An HC-SR04: trigger on pin A, echo on pin B, sound at 343 m/s, the echo starting
    /// 500 µs after the trigger pulse (the driver's "about 0.5 ms"), at most one measurement
    /// every 60 ms (its datasheet: "we suggest to use over 60ms measurement cycle, in order to
    /// prevent trigger signal to the echo signal").
    pub const HC_SR04: Ranger = Ranger {
        trigger: Some(Pin::A),
        echo: Pin::B,
        speed_of_sound_m_s: 343,
        echo_delay_us: 500,
        min_interval_ms: 60,
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
    pub(super) fn uses(&self) -> Vec<Use> {
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
pub(super) enum Use {
    Digital(Pin),
    Pwm(Pin),
    Analog,
}

pub(super) fn pin_letter(p: Pin) -> char {
    match p {
        Pin::A => 'A',
        Pin::B => 'B',
    }
}

/// A device on a port of a board.
#[derive(Clone, Debug, PartialEq)]
pub struct Device {
    pub(super) name: String,
    pub(super) board: BoardRef,
    pub(super) port: u8,
    pub(super) kind: DeviceKind,
    pub(super) misuse: Vec<String>,
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

    /// A button, switch or digital input: one more press (high) at `at_ms` for `for_ms`
    /// (presses in time order).
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

    pub(super) fn port_label(&self) -> String {
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
