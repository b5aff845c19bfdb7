//! What each device of a [`World`] did over a run, in device words: a motor's direction and
//! duty, an LED's level or brightness, a servo's angle, and the inputs as scripted.
//!
//! Outputs are decoded from the run's [`crate::ports::ActuatorLog`] (every change the
//! runtimes drove on a pin) and the board resets in its trace (a reset leaves every output
//! of the board undriven); inputs come from the world's scripts.
//!
//! ```
//! use x10_sim::sim::SimConfig;
//! use x10_sim::timeline::{MotorState, Timeline};
//! use x10_sim::world::{Device, World, SELF};
//!
//! let world = World::new().device(Device::dc_motor("drive", SELF, 1));
//! let outcome = world.sim(SimConfig::default()).unwrap().run().unwrap();
//! let tl = Timeline::new(&world, &outcome);
//! // Nothing drove it: stopped all along.
//! assert_eq!(tl.motor("drive").unwrap().at_ms(1_500), MotorState::STOPPED);
//! ```
//!
//! [`summary`] is the short end-of-run text, [`timeline_svg`] and [`timeline_html`] the plot.

mod plot;

use std::fmt::{self, Write as _};
use std::rc::Rc;

use x10_microcode::{Level, Port, PortKind};

use crate::exec::Nanos;
use crate::ports::{Change, OutputChange};
use crate::sim::{Keep, SimOutcome};
use crate::trace::Severity;
use crate::world::{seconds, Device, DeviceKind, Signal, World};

pub use plot::{timeline_html, timeline_html_of, timeline_svg, write_timeline, LABEL_ROWS};

/// How long a motor state must last to count as a state of its own, in ns: an H-bridge
/// command is three writes (two direction pins, then the duty), which go out as three
/// requests, so the bridge passes through in-between states for a fraction of a millisecond
/// (a few ms at 100 kHz). Shorter states are merged into the next one.
pub const MOTOR_SETTLE_NS: Nanos = 5_000_000;

/// Lines per device in [`summary`] before `… N more`.
pub const SUMMARY_CHANGES_PER_DEVICE: usize = 8;

/// Warnings and errors [`summary`] shows.
pub const SUMMARY_WARNINGS: usize = 5;

/// Which way an H-bridge drives its motor ([`x10_devices::HBridge`]'s table: IN1 = digital
/// A, IN2 = digital B).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MotorDirection {
    /// IN1 HIGH, IN2 LOW.
    Forward,
    /// IN1 LOW, IN2 HIGH.
    Reverse,
    /// Both HIGH: the terminals shorted.
    Brake,
    /// Both LOW (or undriven): the stopped state.
    Coast,
}

/// An H-bridge's state: its direction pins and its enable duty.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MotorState {
    /// Direction, from the two direction pins.
    pub direction: MotorDirection,
    /// The enable pin's duty in percent, as the driver's `Speed` gives it: the smallest
    /// percentage whose duty (`255 · % / 100`, rounded down) is at least [`MotorState::duty`],
    /// so a motor set to 50 % reads 50 %.
    pub duty_percent: u8,
    /// The enable pin's raw duty (0–255).
    pub duty: u8,
}

impl MotorState {
    /// The stopped state: coast, no enable.
    pub const STOPPED: MotorState = MotorState {
        direction: MotorDirection::Coast,
        duty_percent: 0,
        duty: 0,
    };

    /// Braking as the driver brakes: both inputs HIGH, enable full.
    pub const BRAKE: MotorState = MotorState {
        direction: MotorDirection::Brake,
        duty_percent: 100,
        duty: 255,
    };

    /// Forward at `percent` (0–100), as `DcMotor::set_percent(percent)` drives it.
    pub fn forward(percent: u8) -> MotorState {
        MotorState::driven(MotorDirection::Forward, percent)
    }

    /// Reverse at `percent` (0–100), as `DcMotor::set_percent(-percent)` drives it.
    pub fn reverse(percent: u8) -> MotorState {
        MotorState::driven(MotorDirection::Reverse, percent)
    }

    fn driven(direction: MotorDirection, percent: u8) -> MotorState {
        let percent = percent.min(100);
        let duty = u8::try_from(u16::from(percent) * 255 / 100).unwrap_or(u8::MAX);
        MotorState {
            direction,
            duty_percent: percent,
            duty,
        }
    }

    /// The state of pins IN1 (`a`), IN2 (`b`) and enable duty `duty`.
    pub fn decode(a: Option<Level>, b: Option<Level>, duty: u8) -> MotorState {
        let high = |l: Option<Level>| l.is_some_and(|l| l.is_high());
        let direction = match (high(a), high(b)) {
            (true, false) => MotorDirection::Forward,
            (false, true) => MotorDirection::Reverse,
            (true, true) => MotorDirection::Brake,
            (false, false) => MotorDirection::Coast,
        };
        MotorState {
            direction,
            duty_percent: duty_percent(duty),
            duty,
        }
    }

    /// Signed speed in percent: + forward, − reverse, 0 braking or coasting.
    pub fn signed_percent(&self) -> i16 {
        match self.direction {
            MotorDirection::Forward => i16::from(self.duty_percent),
            MotorDirection::Reverse => -i16::from(self.duty_percent),
            MotorDirection::Brake | MotorDirection::Coast => 0,
        }
    }

    /// True when driven forward or in reverse with a duty above 0.
    pub fn is_running(&self) -> bool {
        self.signed_percent() != 0
    }
}

/// The percentage of a duty byte, inverse of the driver's `255 · % / 100` rounded down.
pub fn duty_percent(duty: u8) -> u8 {
    u8::try_from((u16::from(duty) * 100).div_ceil(255)).unwrap_or(100)
}

impl fmt::Display for MotorState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.direction {
            MotorDirection::Forward => write!(f, "forward {} %", self.duty_percent),
            MotorDirection::Reverse => write!(f, "reverse {} %", self.duty_percent),
            MotorDirection::Brake if self.duty == 255 => f.write_str("brake"),
            MotorDirection::Brake => write!(f, "brake (enable {} %)", self.duty_percent),
            MotorDirection::Coast if self.duty == 0 => f.write_str("stopped"),
            MotorDirection::Coast => write!(f, "coast (enable {} %)", self.duty_percent),
        }
    }
}

/// A device's state at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeviceState {
    /// A DC motor.
    Motor(MotorState),
    /// A digital output (LED, digital output: driven HIGH) or input (button pressed, switch
    /// on, input high).
    Level(bool),
    /// A PWM output (dimmable LED, PWM output): its duty.
    Duty {
        /// Percent (as [`duty_percent`]).
        percent: u8,
        /// Raw 0–255.
        duty: u8,
    },
    /// A servo: its angle in degrees (from the pulse width and the servo's range); `None`
    /// before the first pulse width and after a release (width 0).
    Servo(Option<u16>),
    /// An analog input's reading in ADC counts.
    Counts(u16),
    /// A thermistor's temperature in °C.
    Celsius(f32),
    /// An ultrasonic ranger's distance to the obstacle in mm.
    Distance(f64),
}

/// A device's states over a run: a starting state and each change.
#[derive(Clone)]
pub struct Track<T> {
    initial: T,
    changes: Vec<(Nanos, T)>,
    exact: Option<Rc<dyn Fn(Nanos) -> T>>,
}

impl<T: fmt::Debug> fmt::Debug for Track<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Track")
            .field("initial", &self.initial)
            .field("changes", &self.changes)
            .finish()
    }
}

impl<T: Clone + PartialEq + 'static> Track<T> {
    pub(crate) fn new(initial: T, changes: Vec<(Nanos, T)>) -> Track<T> {
        let mut t = Track {
            initial,
            changes: Vec::new(),
            exact: None,
        };
        for (at, s) in changes {
            if *t.last() != s {
                t.changes.push((at, s));
            }
        }
        t
    }

    fn last(&self) -> &T {
        self.changes.last().map_or(&self.initial, |(_, s)| s)
    }

    /// The state at `t_ns`.
    pub fn at_ns(&self, t_ns: Nanos) -> T {
        if let Some(f) = &self.exact {
            return f(t_ns);
        }
        self.changes
            .iter()
            .take_while(|(at, _)| *at <= t_ns)
            .last()
            .map_or_else(|| self.initial.clone(), |(_, s)| s.clone())
    }

    /// The state at `t_ms`.
    pub fn at_ms(&self, t_ms: u64) -> T {
        self.at_ns(t_ms.saturating_mul(1_000_000))
    }

    /// The state before the first change.
    pub fn initial(&self) -> T {
        self.initial.clone()
    }

    /// The state at the end of the run.
    pub fn last_state(&self) -> T {
        self.last().clone()
    }

    /// Each change: when (ns) and the new state. For an analog input: its script's
    /// breakpoints.
    pub fn changes(&self) -> &[(Nanos, T)] {
        &self.changes
    }

    /// The states in order: the initial one, then each change's.
    pub fn states(&self) -> Vec<T> {
        std::iter::once(self.initial.clone())
            .chain(self.changes.iter().map(|(_, s)| s.clone()))
            .collect()
    }

    /// When (ns) the state first satisfied `pred` (0 when the initial state does).
    pub fn first_ns(&self, pred: impl Fn(&T) -> bool) -> Option<Nanos> {
        if pred(&self.initial) {
            return Some(0);
        }
        self.changes.iter().find(|(_, s)| pred(s)).map(|(t, _)| *t)
    }

    /// The same track through `f` (equal neighbours merged).
    pub fn map<U: Clone + PartialEq + 'static>(&self, f: impl Fn(&T) -> U + 'static) -> Track<U>
    where
        T: 'static,
    {
        let f = Rc::new(f);
        let mut t = Track::new(
            f(&self.initial),
            self.changes.iter().map(|(at, s)| (*at, f(s))).collect(),
        );
        if let Some(exact) = self.exact.clone() {
            let f = f.clone();
            t.exact = Some(Rc::new(move |ns| f(&exact(ns))));
        }
        t
    }
}

/// A device the timeline does not have, or not of the kind asked for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TimelineError {
    /// No device of that name.
    NoSuchDevice {
        /// The name asked for.
        name: String,
        /// The devices there are.
        known: Vec<String>,
    },
    /// A device of another kind.
    WrongKind {
        /// The device.
        name: String,
        /// Its kind.
        kind: &'static str,
        /// What was asked for.
        wanted: &'static str,
    },
}

impl fmt::Display for TimelineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TimelineError::NoSuchDevice { name, known } => write!(
                f,
                "no device called `{name}` (devices: {})",
                known.join(", ")
            ),
            TimelineError::WrongKind { name, kind, wanted } => {
                write!(f, "`{name}` is a {kind}, not a {wanted}")
            }
        }
    }
}

impl std::error::Error for TimelineError {}

/// One device's timeline.
#[derive(Clone, Debug)]
pub struct DeviceTimeline {
    /// The device.
    pub device: Device,
    /// Its board's log name (`mb`, `db09`).
    pub board: String,
    /// Its states.
    pub track: Track<DeviceState>,
    /// The model its value comes from (`ranger`, `bumper`, …; `None`: its script or an
    /// output).
    pub model: Option<&'static str>,
}

impl DeviceTimeline {
    /// `dc motor on mb A1`.
    pub fn description(&self) -> String {
        format!(
            "{} on {}",
            self.device.kind().name().replace('_', " "),
            self.device.place(&self.board)
        )
    }

    /// A state in the device's words: `forward 50 %`, `on`, `pressed`, `90°`, `512 counts`.
    pub fn words(&self, s: &DeviceState) -> String {
        match (s, self.device.kind()) {
            (DeviceState::Motor(m), _) => m.to_string(),
            (DeviceState::Level(v), DeviceKind::Led { .. }) => on_off(*v, "on", "off"),
            (DeviceState::Level(v), DeviceKind::Button { .. }) => on_off(*v, "pressed", "released"),
            (DeviceState::Level(v), DeviceKind::Switch { .. }) => on_off(*v, "on", "off"),
            (DeviceState::Level(v), _) => on_off(*v, "high", "low"),
            (DeviceState::Duty { percent, .. }, DeviceKind::Led { .. }) => {
                if *percent == 0 {
                    "off".to_string()
                } else {
                    format!("brightness {percent} %")
                }
            }
            (DeviceState::Duty { percent, .. }, _) => format!("duty {percent} %"),
            (DeviceState::Servo(Some(a)), _) => format!("{a}°"),
            (DeviceState::Servo(None), _) => "released".to_string(),
            (DeviceState::Counts(c), _) => format!("{c} counts"),
            (DeviceState::Celsius(c), _) => format!("{c:.1} °C"),
            (DeviceState::Distance(mm), _) if !mm.is_finite() => "nothing in range".to_string(),
            (DeviceState::Distance(mm), _) => format!("{mm:.0} mm"),
        }
    }

    /// The input's script in words (`None` for outputs and for inputs that read a model).
    pub fn script(&self) -> Option<String> {
        if self.model.is_some() {
            return None;
        }
        Some(match self.device.kind() {
            DeviceKind::Button { pressed, .. } => pressed.describe("pressed", "released"),
            DeviceKind::Switch { on, .. } => on.describe("on", "off"),
            DeviceKind::DigitalInput { level, .. } => level.describe("high", "low"),
            DeviceKind::LightSensor { counts }
            | DeviceKind::ForceSensor { counts }
            | DeviceKind::AnalogInput { counts } => counts.describe("counts"),
            DeviceKind::Thermistor { celsius, .. } => celsius.describe("°C"),
            DeviceKind::Ultrasonic { distance_mm, .. } => distance_mm.describe("mm"),
            _ => return None,
        })
    }
}

fn on_off(v: bool, on: &str, off: &str) -> String {
    if v { on } else { off }.to_string()
}

/// Every device's timeline over one run.
#[derive(Clone, Debug)]
pub struct Timeline {
    /// End of the run (ns).
    pub end_ns: Nanos,
    /// One per device, in the world's order.
    pub devices: Vec<DeviceTimeline>,
    /// The physical models replayed over the run (`None`: the world has none).
    motion: Option<crate::physics::Motion>,
}

/// What changed on outputs, in time order, with the instants at which boards were reset.
struct Events<'a> {
    changes: &'a [OutputChange],
    resets: &'a [(Nanos, String)],
}

impl Timeline {
    /// The timeline of `world`'s devices over the run `outcome` (a run of a simulation that
    /// [`World::sim`] built).
    pub fn new(world: &World, outcome: &SimOutcome) -> Timeline {
        let resets: Vec<(Nanos, String)> = outcome
            .trace
            .lines()
            .iter()
            .filter(|l| l.severity >= Severity::Warn && l.text.starts_with("reset:"))
            .map(|l| (l.t_ns, l.source.clone()))
            .collect();
        Timeline::from_changes(world, &outcome.log.changes(), &resets, outcome.end_ns)
    }

    /// The timeline from output changes, board resets (time, board log name) and the end of
    /// the run.
    pub fn from_changes(
        world: &World,
        changes: &[OutputChange],
        resets: &[(Nanos, String)],
        end_ns: Nanos,
    ) -> Timeline {
        let events = Events { changes, resets };
        let motion = world
            .physics_spec()
            .map(|spec| crate::physics::Motion::replay(spec, changes, end_ns));
        let devices = world
            .devices()
            .iter()
            .map(|d| {
                let board = world
                    .board_of(d)
                    .map_or_else(|| d.board().to_string(), |b| b.log_name());
                let adc_max = world.board_of(d).map_or(1_023, |b| b.adc_max());
                let model = motion.as_ref().and_then(|m| m.track_of(d, adc_max));
                let (track, model) = match model {
                    Some((name, track)) => (track, Some(name)),
                    None => {
                        let track = track_of(d, &board, &events, end_ns);
                        match motion.as_ref().and_then(|m| m.slew_of(d.name())) {
                            Some(speed) => (
                                crate::physics::slewed(&track, speed, end_ns),
                                Some("servo travel"),
                            ),
                            None => (track, None),
                        }
                    }
                };
                DeviceTimeline {
                    device: d.clone(),
                    board,
                    track,
                    model,
                }
            })
            .collect();
        Timeline {
            end_ns,
            devices,
            motion,
        }
    }

    /// The physical models over the run: the chassis's path and contacts, the ranger's
    /// readings, the thermal bodies ([`crate::physics::Motion`]); `None` when the world has
    /// no model.
    pub fn motion(&self) -> Option<&crate::physics::Motion> {
        self.motion.as_ref()
    }

    /// The chassis's pose at `t_ms`; `None` without a chassis.
    pub fn pose_at_ms(&self, t_ms: u64) -> Option<crate::physics::Pose> {
        self.motion
            .as_ref()
            .filter(|m| m.physics().chassis.is_some())
            .map(|m| m.pose_at_ms(t_ms))
    }

    /// The closest the chassis's outline came to a wall or box: when (ns) and the gap (mm).
    pub fn closest_to_wall(&self) -> Option<(Nanos, f64)> {
        self.motion.as_ref()?.closest_to_wall()
    }

    /// How long (ns) line sensor `name` (a device with `source = "line"`) was over a floor
    /// line; `None` when there is no such sensor.
    pub fn time_on_line_ns(&self, name: &str) -> Option<Nanos> {
        let m = self.motion.as_ref()?;
        match m.physics().source_of(name)? {
            crate::physics::Source::Line { at } => Some(m.time_on_line_ns(*at)),
            _ => None,
        }
    }

    /// Every contact of the chassis with a wall or box (empty without a chassis).
    pub fn contacts(&self) -> &[crate::physics::Contact] {
        self.motion.as_ref().map_or(&[], |m| m.contacts())
    }

    /// The timeline of device `name`.
    ///
    /// # Errors
    /// [`TimelineError::NoSuchDevice`].
    pub fn get(&self, name: &str) -> Result<&DeviceTimeline, TimelineError> {
        self.devices
            .iter()
            .find(|d| d.device.name() == name)
            .ok_or_else(|| TimelineError::NoSuchDevice {
                name: name.to_string(),
                known: self
                    .devices
                    .iter()
                    .map(|d| d.device.name().to_string())
                    .collect(),
            })
    }

    /// Any device's states.
    ///
    /// # Errors
    /// [`TimelineError::NoSuchDevice`].
    pub fn device(&self, name: &str) -> Result<Track<DeviceState>, TimelineError> {
        Ok(self.get(name)?.track.clone())
    }

    /// Every change of device `name`: when (ns) and the new state.
    ///
    /// # Errors
    /// [`TimelineError::NoSuchDevice`].
    pub fn changes(&self, name: &str) -> Result<Vec<(Nanos, DeviceState)>, TimelineError> {
        Ok(self.get(name)?.track.changes().to_vec())
    }

    fn typed<T: Clone + PartialEq + 'static>(
        &self,
        name: &str,
        wanted: &'static str,
        ok: impl Fn(&DeviceKind) -> bool,
        f: impl Fn(&DeviceState) -> T + 'static,
    ) -> Result<Track<T>, TimelineError> {
        let d = self.get(name)?;
        if !ok(d.device.kind()) {
            return Err(TimelineError::WrongKind {
                name: name.to_string(),
                kind: d.device.kind().name(),
                wanted,
            });
        }
        Ok(d.track.map(f))
    }

    /// A DC motor's states.
    ///
    /// # Errors
    /// [`TimelineError`] when there is no motor called `name`.
    pub fn motor(&self, name: &str) -> Result<Track<MotorState>, TimelineError> {
        self.typed(
            name,
            "dc_motor",
            |k| matches!(k, DeviceKind::DcMotor),
            |s| match s {
                DeviceState::Motor(m) => *m,
                _ => MotorState::STOPPED,
            },
        )
    }

    /// An LED: on (a dimmable one: duty above 0) or off.
    ///
    /// # Errors
    /// [`TimelineError`] when there is no LED called `name`.
    pub fn led(&self, name: &str) -> Result<Track<bool>, TimelineError> {
        self.typed(name, "led", |k| matches!(k, DeviceKind::Led { .. }), is_on)
    }

    /// A dimmable LED's or PWM output's duty in percent (a digital LED: 0 or 100).
    ///
    /// # Errors
    /// [`TimelineError`] when there is no LED or PWM output called `name`.
    pub fn brightness(&self, name: &str) -> Result<Track<u8>, TimelineError> {
        self.typed(
            name,
            "led or pwm_output",
            |k| matches!(k, DeviceKind::Led { .. } | DeviceKind::PwmOutput { .. }),
            |s| match s {
                DeviceState::Duty { percent, .. } => *percent,
                DeviceState::Level(true) => 100,
                _ => 0,
            },
        )
    }

    /// A servo's angle (`None`: no pulses).
    ///
    /// # Errors
    /// [`TimelineError`] when there is no servo called `name`.
    pub fn servo(&self, name: &str) -> Result<Track<Option<u16>>, TimelineError> {
        self.typed(
            name,
            "servo",
            |k| matches!(k, DeviceKind::Servo { .. }),
            |s| match s {
                DeviceState::Servo(a) => *a,
                _ => None,
            },
        )
    }

    /// Any on/off device's level: an LED or digital output driven HIGH, a button pressed, a
    /// switch on, a digital input high; a PWM output or dimmable LED with a duty above 0.
    ///
    /// # Errors
    /// [`TimelineError`] when there is no such device called `name`.
    pub fn level(&self, name: &str) -> Result<Track<bool>, TimelineError> {
        self.typed(
            name,
            "digital device",
            |k| {
                matches!(
                    k,
                    DeviceKind::Led { .. }
                        | DeviceKind::DigitalOutput { .. }
                        | DeviceKind::PwmOutput { .. }
                        | DeviceKind::Button { .. }
                        | DeviceKind::Switch { .. }
                        | DeviceKind::DigitalInput { .. }
                )
            },
            is_on,
        )
    }
}

fn is_on(s: &DeviceState) -> bool {
    match s {
        DeviceState::Level(v) => *v,
        DeviceState::Duty { duty, .. } => *duty > 0,
        _ => false,
    }
}

/// The instantaneous pin state of one actuator port, as the log tells it.
#[derive(Clone, Copy, Default)]
struct PortPins {
    level: [Option<Level>; 2],
    duty: [u8; 2],
    width: [Option<u16>; 2],
}

/// The port's states over the run, one per event (changes of its pins and resets of its
/// board), starting from power-up.
fn port_history(board: &str, port: Port, events: &Events<'_>) -> Vec<(Nanos, PortPins)> {
    let mut out = Vec::new();
    let mut pins = PortPins::default();
    let mut changes = events
        .changes
        .iter()
        .filter(|c| c.board == board && c.pin.port == port)
        .peekable();
    let mut resets = events
        .resets
        .iter()
        .filter(|(_, b)| b == board)
        .map(|(t, _)| *t)
        .peekable();
    loop {
        let next_change = changes.peek().map(|c| c.t_ns);
        let next_reset = resets.peek().copied();
        match (next_change, next_reset) {
            (None, None) => break,
            // A reset at the same instant as a change comes first (the change is the new
            // boot's).
            (c, Some(r)) if c.is_none_or(|c| r <= c) => {
                resets.next();
                pins = PortPins::default();
                out.push((r, pins));
            }
            _ => {
                let Some(c) = changes.next() else { break };
                let i = c.pin.pin.index();
                match c.change {
                    Change::Digital(l) => {
                        if let Some(s) = pins.level.get_mut(i) {
                            *s = Some(l);
                        }
                    }
                    Change::Duty(d) => {
                        if let Some(s) = pins.duty.get_mut(i) {
                            *s = d;
                        }
                    }
                    Change::PulseWidth(us) => {
                        if let Some(s) = pins.width.get_mut(i) {
                            *s = Some(us);
                        }
                    }
                    Change::Frequency(_) => {}
                }
                out.push((c.t_ns, pins));
            }
        }
    }
    out
}

/// Drops states that last less than `settle_ns` (merging them into the next one); the last
/// state always stays.
fn settle<T: Clone>(states: Vec<(Nanos, T)>, settle_ns: Nanos) -> Vec<(Nanos, T)> {
    let mut out: Vec<(Nanos, T)> = Vec::new();
    let mut i = 0;
    while i < states.len() {
        // The start of this group is the first state's time; its state is the first one that
        // lasts, or the last one.
        let start = states[i].0;
        let mut j = i;
        while j + 1 < states.len() && states[j + 1].0 - states[j].0 < settle_ns {
            j += 1;
        }
        out.push((start, states[j].1.clone()));
        i = j + 1;
    }
    out
}

fn servo_angle(us: Option<u16>, config: &x10_devices::ServoConfig) -> Option<u16> {
    let us = us.filter(|u| *u > 0)?;
    let (min, max, angle) = (
        u32::from(config.min_us()),
        u32::from(config.max_us()),
        u32::from(config.max_angle()),
    );
    let span = max.saturating_sub(min).max(1);
    let us = u32::from(us).clamp(min, max);
    // Nearest angle: the driver rounds the pulse to the nearest µs.
    let a = ((us - min) * angle + span / 2) / span;
    u16::try_from(a).ok()
}

/// A device state from a script at a time in µs.
type StateOf = Rc<dyn Fn(&Signal, u64) -> DeviceState>;

fn track_of(d: &Device, board: &str, events: &Events<'_>, end_ns: Nanos) -> Track<DeviceState> {
    // Every output is on an actuator port.
    let actuator = Port::new(PortKind::Actuator, d.port_number()).ok();
    let history =
        |port: Option<Port>| port.map_or_else(Vec::new, |p| port_history(board, p, events));
    let from_pins = |port: Option<Port>, f: &dyn Fn(&PortPins) -> DeviceState| {
        let initial = f(&PortPins::default());
        let states = history(port).iter().map(|(t, p)| (*t, f(p))).collect();
        (initial, states)
    };
    let digital_in = |s: &crate::world::DigitalSignal| {
        let script = s.to_digital(false);
        let mut changes = Vec::new();
        let mut t = 0;
        while let Some(at) = script.next_change_after(t).filter(|at| *at <= end_ns) {
            changes.push((at, DeviceState::Level(script.level_at(at))));
            t = at;
        }
        Track::new(DeviceState::Level(script.level_at(0)), changes)
    };
    let analog_in = |s: &Signal, f: StateOf| {
        let at = |t_us: u64| f(s, t_us);
        let changes = s
            .breakpoints_us()
            .into_iter()
            .map(|t| (t * 1_000, at(t)))
            .collect();
        let mut t = Track::new(at(0), changes);
        let s = s.clone();
        t.exact = Some(Rc::new(move |ns| f(&s, ns / 1_000)));
        t
    };
    match d.kind() {
        DeviceKind::DcMotor => {
            let (initial, states) = from_pins(actuator, &|p| {
                DeviceState::Motor(MotorState::decode(p.level[0], p.level[1], p.duty[0]))
            });
            Track::new(initial, settle(states, MOTOR_SETTLE_NS))
        }
        DeviceKind::Led {
            pin,
            dimmable: false,
        }
        | DeviceKind::DigitalOutput { pin } => {
            let i = pin.index();
            let port = actuator;
            let (initial, states) = from_pins(port, &|p| {
                DeviceState::Level(
                    p.level
                        .get(i)
                        .copied()
                        .flatten()
                        .is_some_and(|l| l.is_high()),
                )
            });
            Track::new(initial, states)
        }
        DeviceKind::Led { pin, .. } | DeviceKind::PwmOutput { pin } => {
            let i = pin.index();
            let (initial, states) = from_pins(actuator, &|p| {
                let duty = p.duty.get(i).copied().unwrap_or(0);
                DeviceState::Duty {
                    percent: duty_percent(duty),
                    duty,
                }
            });
            Track::new(initial, states)
        }
        DeviceKind::Servo { pin, config } => {
            let i = pin.index();
            let config = *config;
            let (initial, states) = from_pins(actuator, &|p| {
                DeviceState::Servo(servo_angle(p.width.get(i).copied().flatten(), &config))
            });
            Track::new(initial, states)
        }
        DeviceKind::Button { pressed: s, .. }
        | DeviceKind::Switch { on: s, .. }
        | DeviceKind::DigitalInput { level: s, .. } => digital_in(s),
        DeviceKind::LightSensor { counts }
        | DeviceKind::ForceSensor { counts }
        | DeviceKind::AnalogInput { counts } => analog_in(
            counts,
            Rc::new(|s: &Signal, t| DeviceState::Counts(s.counts_at_us(t))),
        ),
        DeviceKind::Thermistor { celsius, .. } => analog_in(
            celsius,
            Rc::new(|s: &Signal, t| DeviceState::Celsius(s.value_at_us_f32(t))),
        ),
        DeviceKind::Ultrasonic { distance_mm, .. } => analog_in(
            distance_mm,
            Rc::new(|s: &Signal, t| DeviceState::Distance(s.value_at_us(t))),
        ),
    }
}

/// The device lines of [`summary`] for the timeline `tl`: per device what changed (the first
/// [`SUMMARY_CHANGES_PER_DEVICE`] changes, then how many more), its script (inputs) or that it
/// did not change. `x10 monitor` prints them for a real robot too.
pub fn device_summary(tl: &Timeline) -> String {
    let mut s = String::new();
    let width = tl
        .devices
        .iter()
        .map(|d| d.device.name().chars().count())
        .max()
        .unwrap_or(0);
    for d in &tl.devices {
        let name = d.device.name();
        let pad = |n: &str| format!("{n:<width$}");
        if let Some(script) = d.script() {
            let _ = writeln!(
                s,
                "  {:>9}  {}  {}: {script}",
                "script",
                pad(name),
                d.description()
            );
            continue;
        }
        let changes = d.track.changes();
        if changes.is_empty() {
            let _ = writeln!(
                s,
                "  {:>9}  {}  no change: {}",
                "-",
                pad(name),
                d.words(&d.track.initial())
            );
            continue;
        }
        for (t, state) in changes.iter().take(SUMMARY_CHANGES_PER_DEVICE) {
            let _ = writeln!(s, "  {:>9}  {}  {}", seconds(*t), pad(name), d.words(state));
        }
        if changes.len() > SUMMARY_CHANGES_PER_DEVICE {
            let more = changes.len() - SUMMARY_CHANGES_PER_DEVICE;
            if let Some((t, last)) = changes.last() {
                let _ = writeln!(
                    s,
                    "  {:>9}  {}  … {more} more, the last at {}: {}",
                    "",
                    pad(name),
                    seconds(*t),
                    d.words(last)
                );
            }
        }
    }
    s
}

/// The short end-of-run text: per device what changed (outputs) or what was scripted
/// (inputs), the bus load, and the warnings and errors of the trace.
///
/// ```text
/// devices, 5.000 s at 400k:
///    1.012 s  drive      forward 50 %
///    1.520 s  drive      stopped
///          -  heartbeat  never driven
///     script  bumper     button on mb S2.B: pressed at 1.000 s for 50 ms, at 3.000 s for 50 ms
/// bus: 510 transactions, busy 61.2 ms = 1.22 % of the run; 0 NACK, 0 arbitration lost, 0 timeouts, 0 bus faults, 0 resets
/// warnings and errors: none
/// ```
pub fn summary(world: &World, outcome: &SimOutcome) -> String {
    let tl = Timeline::new(world, outcome);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "devices, {} at {}:",
        seconds(outcome.end_ns),
        outcome.speed
    );
    s.push_str(&device_summary(&tl));
    if let Some(line) = tl.motion().and_then(crate::physics::Motion::summary_line) {
        let _ = writeln!(s, "{line}");
    }
    let b = &outcome.bus;
    let busy_ns: Nanos = match outcome.kept.keep {
        Keep::All => outcome.records.iter().map(|r| r.duration_ns()).sum(),
        // The records are not all kept: the bus counted its busy time as it went.
        Keep::Summary => b.busy_ns,
    };
    let basis_points = busy_ns
        .saturating_mul(10_000)
        .checked_div(outcome.end_ns)
        .unwrap_or(0);
    let _ = writeln!(
        s,
        "bus: {} transactions, busy {}.{} ms = {}.{:02} % of the run; {} NACK, {} arbitration lost, {} timeouts, {} bus faults, {} resets",
        b.transactions,
        busy_ns / 1_000_000,
        busy_ns % 1_000_000 / 100_000,
        basis_points / 100,
        basis_points % 100,
        b.nacks,
        b.arbitration_lost,
        b.timeouts,
        b.bus_faults,
        b.resets
    );
    let warnings: Vec<_> = outcome
        .trace
        .lines()
        .iter()
        .filter(|l| l.severity >= Severity::Warn)
        .collect();
    // Past a bounded run's caps, warnings were counted, not kept.
    let total = warnings.len() as u64 + outcome.kept.warnings_dropped();
    if total == 0 {
        s.push_str("warnings and errors: none\n");
    } else {
        let _ = writeln!(s, "warnings and errors: {total}");
        for l in warnings.iter().take(SUMMARY_WARNINGS) {
            let _ = writeln!(s, "  {l}");
        }
        if total > SUMMARY_WARNINGS as u64 {
            let _ = writeln!(s, "  … {} more", total - SUMMARY_WARNINGS as u64);
        }
    }
    if let Some(line) = outcome.kept.summary_line() {
        let _ = writeln!(s, "{line}");
    }
    s
}

#[cfg(test)]
mod tests;
