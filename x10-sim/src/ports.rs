//! Simulated sensor and actuator ports: [`firmware_db::Ports`] on virtual time.
//!
//! Inputs follow scripts ([`Digital`], [`Analog`]) written as functions of virtual time: a
//! button pressed at t = 2 s, a thermistor warming up, a light level, an ultrasonic echo.
//! Outputs (digital levels and PWM settings, on actuator ports and on sensor pins driven as
//! outputs) are recorded in a shared [`ActuatorLog`] as timestamped changes, so tests can ask
//! what a pin was at any instant.
//!
//! Reads and settings take no virtual time: they are synchronous calls of
//! [`firmware_db::Ports`], as on the boards, where they complete at once (the boards' 2 µs
//! ADC conversion is not modelled, nor is CPU time). Pulse-in and edge waits take the time
//! of the scripted signals.

use std::cell::RefCell;
use std::fmt;
use std::rc::Rc;

use firmware_db::{EdgeCount, PortError, Ports, SafeState};
use x10_microcode::{Edge, Level, Pin, PinRef, Port, PortKind};

use crate::exec::{Nanos, SimClock};

/// A scripted analog input, in ADC counts, as a function of virtual time.
#[derive(Clone)]
pub enum Analog {
    /// Always this value.
    Const(u16),
    /// Linear from `from` at `start_ms` to `to` at `end_ms`, constant outside.
    Ramp {
        /// Value until `start_ms`.
        from: u16,
        /// Value from `end_ms` on.
        to: u16,
        /// Start of the ramp.
        start_ms: u64,
        /// End of the ramp.
        end_ms: u64,
    },
    /// Piecewise constant: `(from_ms, value)` pairs in time order; before the first, `initial`.
    Steps {
        /// Value before the first step.
        initial: u16,
        /// Steps.
        steps: Vec<(u64, u16)>,
    },
    /// Any function of the time in µs.
    Func(Rc<dyn Fn(u64) -> u16>),
}

impl fmt::Debug for Analog {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Analog::Const(v) => write!(f, "Const({v})"),
            Analog::Ramp {
                from,
                to,
                start_ms,
                end_ms,
            } => write!(f, "Ramp({from}@{start_ms}ms -> {to}@{end_ms}ms)"),
            Analog::Steps { initial, steps } => write!(f, "Steps({initial}, {steps:?})"),
            Analog::Func(_) => f.write_str("Func"),
        }
    }
}

impl Analog {
    /// The value at `t_ns`.
    pub fn value_at(&self, t_ns: Nanos) -> u16 {
        match self {
            Analog::Const(v) => *v,
            Analog::Ramp {
                from,
                to,
                start_ms,
                end_ms,
            } => {
                let (s, e) = (start_ms * 1_000_000, end_ms * 1_000_000);
                if t_ns <= s || e <= s {
                    if t_ns >= e {
                        *to
                    } else {
                        *from
                    }
                } else if t_ns >= e {
                    *to
                } else {
                    let span = (e - s) as i128;
                    let done = (t_ns - s) as i128;
                    let v = i128::from(*from) + (i128::from(*to) - i128::from(*from)) * done / span;
                    u16::try_from(v).unwrap_or(if to > from { *to } else { *from })
                }
            }
            Analog::Steps { initial, steps } => steps
                .iter()
                .take_while(|(ms, _)| ms * 1_000_000 <= t_ns)
                .last()
                .map_or(*initial, |(_, v)| *v),
            Analog::Func(f) => f(t_ns / 1_000),
        }
    }
}

/// A scripted digital input as a function of virtual time.
#[derive(Clone, Debug)]
pub enum Digital {
    /// Always this level.
    Const(bool),
    /// `initial`, then toggled at each of `toggles_ms` (in time order).
    Toggles {
        /// Level before the first toggle.
        initial: bool,
        /// Toggle times in ms.
        toggles_ms: Vec<u64>,
    },
    /// Periodic high pulses (an ultrasonic echo): from `first_us` on, every `period_us`, a
    /// pulse whose width in µs is `width_us` evaluated at the pulse's start.
    Pulses {
        /// Start of the first pulse.
        first_us: u64,
        /// Period.
        period_us: u64,
        /// Pulse width in µs, as a function of time.
        width_us: Analog,
    },
    /// A periodic pulse train of one width (a blinking or toggling input): high for
    /// `width_us` every `period_us` from `first_us` on. Unlike [`Digital::Pulses`], the width
    /// may be longer than 65 ms.
    Train {
        /// Start of the first pulse.
        first_us: u64,
        /// Period.
        period_us: u64,
        /// Pulse width (at most the period).
        width_us: u64,
    },
    /// An ultrasonic ranger's echo pin (HC-SR04 and alike), which answers its trigger: low,
    /// except for one high pulse `delay_us` after each falling edge of the `trigger` pin of
    /// the same port (the end of the trigger pulse, as the board's output log recorded it),
    /// `width_us` wide (evaluated at the start of the echo). With `trigger` `None` (a
    /// free-running sensor) the echo starts `delay_us` after each pulse-in on the pin begins.
    ///
    /// Only pulse-in sees the echo: a digital read of the pin reads low. A pulse-in that
    /// starts after the echo has risen (or with no trigger pulse before it) misses it and
    /// times out, as `pulseIn` does on a board. A measurement that starts less than
    /// `min_interval_us` after the last one the part answered gets no echo either (an HC-SR04
    /// ignores a trigger while its last ping may still echo), and the run warns
    /// ([`ActuatorLog::device_warnings`]).
    Echo {
        /// The trigger pin of the same port, if any.
        trigger: Option<Pin>,
        /// From the trigger's falling edge (or the start of the pulse-in) to the echo, in µs.
        delay_us: u64,
        /// The shortest time between two measurements the part answers, µs (0: any rate).
        min_interval_us: u64,
        /// Echo width in µs, as a function of the time the echo starts.
        width_us: Analog,
    },
    /// A level from a physical model (a bumper, a wheel encoder: [`crate::physics`]): read
    /// at any instant up to now; its edges are those the model's integration recorded, so
    /// [`Digital::next_change_after`] knows only those up to now (a pulse-in on it sees no
    /// future edge), and a task waiting for edges looks again at each step of the model's grid.
    Model(crate::physics::ModelPin),
}

impl Digital {
    /// Low until `at_ms`, then high: a button pressed once and held.
    pub fn pressed_at(at_ms: u64) -> Digital {
        Digital::Toggles {
            initial: false,
            toggles_ms: vec![at_ms],
        }
    }

    /// The level at `t_ns`.
    pub fn level_at(&self, t_ns: Nanos) -> bool {
        match self {
            Digital::Const(v) => *v,
            Digital::Toggles {
                initial,
                toggles_ms,
            } => {
                let n = toggles_ms
                    .iter()
                    .take_while(|ms| *ms * 1_000_000 <= t_ns)
                    .count();
                *initial ^ (n % 2 == 1)
            }
            Digital::Pulses {
                first_us,
                period_us,
                width_us,
            } => PulseTrain::new(*first_us, *period_us)
                .level_at(t_ns, &|start| u64::from(width_us.value_at(start)) * 1_000),
            Digital::Train {
                first_us,
                period_us,
                width_us,
            } => PulseTrain::new(*first_us, *period_us).level_at(t_ns, &|_| width_us * 1_000),
            Digital::Echo { .. } => false,
            Digital::Model(m) => m.level_at(t_ns),
        }
    }

    /// The first instant strictly after `t_ns` at which the level changes, if any.
    pub fn next_change_after(&self, t_ns: Nanos) -> Option<Nanos> {
        match self {
            Digital::Const(_) => None,
            Digital::Toggles { toggles_ms, .. } => toggles_ms
                .iter()
                .map(|ms| ms * 1_000_000)
                .find(|&at| at > t_ns),
            Digital::Pulses {
                first_us,
                period_us,
                width_us,
            } => PulseTrain::new(*first_us, *period_us)
                .next_change_after(t_ns, |start| u64::from(width_us.value_at(start)) * 1_000),
            Digital::Train {
                first_us,
                period_us,
                width_us,
            } => {
                PulseTrain::new(*first_us, *period_us).next_change_after(t_ns, |_| width_us * 1_000)
            }
            Digital::Echo { .. } => None,
            Digital::Model(m) => m.next_change_after(t_ns),
        }
    }
}

/// A train of pulses in ns: the first rises at `first`, one every `period`; the width of
/// each comes from a function of its start (capped at the period).
struct PulseTrain {
    first: Nanos,
    period: Nanos,
}

impl PulseTrain {
    /// Periods without a pulse [`PulseTrain::next_change_after`] looks through.
    const MAX_QUIET: usize = 10_000;

    fn new(first_us: u64, period_us: u64) -> PulseTrain {
        PulseTrain {
            first: first_us * 1_000,
            period: (period_us * 1_000).max(1),
        }
    }

    /// The start of the period `t_ns` is in (`t_ns` at or after `first`).
    fn start(&self, t_ns: Nanos) -> Nanos {
        self.first + (t_ns - self.first) / self.period * self.period
    }

    fn level_at(&self, t_ns: Nanos, width_ns: &impl Fn(Nanos) -> Nanos) -> bool {
        if t_ns < self.first {
            return false;
        }
        let start = self.start(t_ns);
        t_ns < start + width_ns(start).min(self.period)
    }

    /// The first instant after `t_ns` at which the level changes: a rise at the start of a
    /// period whose pulse has a width (unless the previous pulse filled its period), a fall
    /// at the end of a pulse narrower than its period (unless the next one starts at once).
    /// Periods with no pulse (width 0) are skipped, up to [`PulseTrain::MAX_QUIET`] of them
    /// in a row (then `None`: the train has stopped).
    fn next_change_after(&self, t_ns: Nanos, width_ns: impl Fn(Nanos) -> Nanos) -> Option<Nanos> {
        let level = |t: Nanos| self.level_at(t, &width_ns);
        let mut start = if t_ns < self.first {
            self.first
        } else {
            self.start(t_ns)
        };
        for _ in 0..Self::MAX_QUIET {
            let width = width_ns(start).min(self.period);
            for at in [start, start + width] {
                if at > t_ns && at > 0 && level(at) != level(at - 1) {
                    return Some(at);
                }
            }
            start += self.period;
        }
        None
    }
}

/// What a sensor port's inputs do.
#[derive(Clone, Debug)]
pub struct SensorScript {
    /// Digital pin A.
    pub a: Digital,
    /// Digital pin B.
    pub b: Digital,
    /// Analog input.
    pub analog: Analog,
}

impl Default for SensorScript {
    fn default() -> Self {
        SensorScript {
            a: Digital::Const(false),
            b: Digital::Const(false),
            analog: Analog::Const(0),
        }
    }
}

/// What changed on an output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Change {
    /// Digital level driven.
    Digital(Level),
    /// PWM duty (0–255).
    Duty(u8),
    /// PWM frequency of the port (Hz).
    Frequency(u16),
    /// PWM high time (µs).
    PulseWidth(u16),
}

/// One recorded output change.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputChange {
    /// When (ns).
    pub t_ns: Nanos,
    /// Board name (`mb`, `db09`, …).
    pub board: String,
    /// Which pin (pin A for port-wide settings).
    pub pin: PinRef,
    /// What it became.
    pub change: Change,
}

impl fmt::Display for OutputChange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.change {
            Change::Digital(l) => write!(
                f,
                "{} {} {}",
                self.board,
                self.pin,
                if l.is_high() { "high" } else { "low" }
            ),
            Change::Duty(d) => write!(f, "{} {} pwm {d}", self.board, self.pin),
            Change::Frequency(hz) => {
                write!(f, "{} {} pwm frequency {hz} Hz", self.board, self.pin.port)
            }
            Change::PulseWidth(us) => write!(f, "{} {} pulse width {us} us", self.board, self.pin),
        }
    }
}

/// The firmware put an actuator port in its safe state (it asked the port for it:
/// `firmware-db` does so only in `apply_safe_state`, at boot and when its failsafe trips).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SafeStateApplied {
    /// When (ns).
    pub t_ns: Nanos,
    /// Board name.
    pub board: String,
    /// The actuator port.
    pub port: Port,
    /// Its safe state.
    pub safe: SafeState,
}

/// Every output change of every simulated board, shared. Cloning shares the log.
#[derive(Clone, Default)]
pub struct ActuatorLog {
    changes: Rc<RefCell<Vec<OutputChange>>>,
    safe: Rc<RefCell<Vec<SafeStateApplied>>>,
    latches: Rc<RefCell<Vec<EdgeLatch>>>,
    warnings: Rc<RefCell<Vec<DeviceWarning>>>,
    blinks: Rc<RefCell<Vec<Blink>>>,
    bound: Rc<LogBound>,
}

/// How much an [`ActuatorLog`] keeps: everything unless [`ActuatorLog::bound_to`] set a cap.
#[derive(Debug, Default)]
struct LogBound {
    /// Entries kept per list (changes, safe states, latches, warnings, blinks); 0: no cap.
    cap: std::cell::Cell<usize>,
    /// A reader follows the changes as the run goes (the physics engine): they are all kept.
    followed: std::cell::Cell<bool>,
    /// Changes counted but not kept.
    changes_dropped: std::cell::Cell<u64>,
    /// Device warnings counted but not kept.
    warnings_dropped: std::cell::Cell<u64>,
    /// Safe states, latches and blinks counted but not kept.
    others_dropped: std::cell::Cell<u64>,
}

impl LogBound {
    /// True when a list of `len` entries is full.
    fn full(&self, len: usize) -> bool {
        let cap = self.cap.get();
        cap > 0 && len >= cap
    }

    /// Pushes `item` on `list` unless it is full; counts it in `dropped` otherwise.
    fn keep<T>(&self, list: &RefCell<Vec<T>>, item: T, dropped: &std::cell::Cell<u64>) {
        let mut list = list.borrow_mut();
        if self.full(list.len()) {
            dropped.set(dropped.get() + 1);
        } else {
            list.push(item);
        }
    }
}

/// A board was asked to blink its status LED (`blink`, to find it by eye): every simulated
/// board has one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Blink {
    /// When (ns).
    pub t_ns: Nanos,
    /// Board name.
    pub board: String,
    /// For how many seconds (0 stops it).
    pub secs: u8,
}

/// The firmware started latching a pin's edges ([`Ports::latch_edges`]: the counts start from
/// zero here, edges after `t_ns` are counted).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdgeLatch {
    /// When (ns).
    pub t_ns: Nanos,
    /// Board name.
    pub board: String,
    /// The pin.
    pub pin: PinRef,
}

/// A documented limit of a device model that the program broke (a measurement sooner than
/// the part allows): the run's summary lists it with the warnings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceWarning {
    /// When (ns).
    pub t_ns: Nanos,
    /// The board of the device's port.
    pub board: String,
    /// What happened and what the part did.
    pub text: String,
}

impl ActuatorLog {
    /// An empty log.
    pub fn new() -> ActuatorLog {
        ActuatorLog::default()
    }

    fn push(&self, c: OutputChange) {
        if self.bound.followed.get() {
            self.changes.borrow_mut().push(c);
        } else {
            self.bound
                .keep(&self.changes, c, &self.bound.changes_dropped);
        }
    }

    /// Keeps at most `cap` entries in each of its lists (changes, safe states, latches,
    /// device warnings, blinks) and counts the others ([`ActuatorLog::dropped`]); the changes
    /// are all kept when a reader follows them as the run goes (a world with physics, whose
    /// engine reads them). A bounded run ([`crate::sim::Keep::Summary`]) sets it.
    pub fn bound_to(&self, cap: usize) {
        self.bound.cap.set(cap);
    }

    /// Marks the changes as read while the run goes (they are never dropped).
    pub(crate) fn follow(&self) {
        self.bound.followed.set(true);
    }

    /// Entries counted but not kept at the cap of [`ActuatorLog::bound_to`]: (output changes,
    /// device warnings, the others).
    pub fn dropped(&self) -> (u64, u64, u64) {
        let b = &self.bound;
        (
            b.changes_dropped.get(),
            b.warnings_dropped.get(),
            b.others_dropped.get(),
        )
    }

    /// Every time a board's firmware put an actuator port in its safe state, in time order:
    /// the changes it made then are commanded by design (boot, failsafe), not by a caller.
    pub fn safe_states(&self) -> Vec<SafeStateApplied> {
        self.safe.borrow().clone()
    }

    /// Every `blink` a board's firmware carried out, in time order.
    pub fn blinks(&self) -> Vec<Blink> {
        self.blinks.borrow().clone()
    }

    /// Every time a board's firmware started latching a pin's edges (events enabled on it),
    /// in time order.
    pub fn latches(&self) -> Vec<EdgeLatch> {
        self.latches.borrow().clone()
    }

    /// Every device warning so far, in time order.
    pub fn device_warnings(&self) -> Vec<DeviceWarning> {
        self.warnings.borrow().clone()
    }

    /// All changes so far, in time order.
    pub fn changes(&self) -> Vec<OutputChange> {
        self.changes.borrow().clone()
    }

    /// A log holding `changes` (a finished run's, to replay the models over it).
    pub(crate) fn from_changes(changes: Vec<OutputChange>) -> ActuatorLog {
        let log = ActuatorLog::new();
        *log.changes.borrow_mut() = changes;
        log
    }

    /// Calls `f` with the changes so far, without copying them.
    pub(crate) fn with_changes<R>(&self, f: impl FnOnce(&[OutputChange]) -> R) -> R {
        f(&self.changes.borrow())
    }

    /// Number of changes so far.
    pub fn len(&self) -> usize {
        self.changes.borrow().len()
    }

    /// True when nothing changed yet.
    pub fn is_empty(&self) -> bool {
        self.changes.borrow().is_empty()
    }

    /// Changes of one board's pin, in time order.
    pub fn of(&self, board: &str, pin: PinRef) -> Vec<OutputChange> {
        self.changes
            .borrow()
            .iter()
            .filter(|c| c.board == board && c.pin == pin)
            .cloned()
            .collect()
    }

    /// The level a pin was driven to at `t_ns` (`None`: never driven by then).
    pub fn level_at(&self, board: &str, pin: PinRef, t_ns: Nanos) -> Option<Level> {
        self.last_at(board, pin, t_ns, |c| match c {
            Change::Digital(l) => Some(l),
            _ => None,
        })
    }

    /// The PWM duty of a pin at `t_ns` (0 if never set).
    pub fn duty_at(&self, board: &str, pin: PinRef, t_ns: Nanos) -> u8 {
        self.last_at(board, pin, t_ns, |c| match c {
            Change::Duty(d) => Some(d),
            _ => None,
        })
        .unwrap_or(0)
    }

    /// The value `pick` finds in the last change of a pin at or before `t_ns` in which it
    /// finds one.
    fn last_at<T>(
        &self,
        board: &str,
        pin: PinRef,
        t_ns: Nanos,
        pick: impl Fn(Change) -> Option<T>,
    ) -> Option<T> {
        self.changes
            .borrow()
            .iter()
            .rev()
            .filter(|c| c.board == board && c.pin == pin && c.t_ns <= t_ns)
            .find_map(|c| pick(c.change))
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct ActuatorState {
    out: [Option<Level>; 2],
    duty: [u8; 2],
    freq: Option<u16>,
    width: [Option<u16>; 2],
}

#[derive(Debug)]
struct State {
    sensor_out: Vec<[Option<Level>; 2]>,
    actuators: Vec<ActuatorState>,
    busy: Vec<PinRef>,
    /// Echo pins with the start of the last measurement their part answered.
    pings: Vec<(PinRef, Nanos)>,
    /// Pins whose edges are latched, with the instant of the last take (edges after it are
    /// counted by the next take).
    latched: Vec<(PinRef, Nanos)>,
}

impl State {
    /// `sensors` sensor and `actuators` actuator ports as after power-up: every output
    /// undriven, PWM off, nothing busy or latched.
    fn new(sensors: usize, actuators: usize) -> State {
        State {
            sensor_out: vec![[None, None]; sensors],
            actuators: vec![ActuatorState::default(); actuators],
            busy: Vec::new(),
            pings: Vec::new(),
            latched: Vec::new(),
        }
    }

    /// The driven level of `pin` (`None` undriven), or `None` when there is no such pin.
    fn out(&mut self, pin: PinRef) -> Option<&mut Option<Level>> {
        let i = usize::from(pin.port.index());
        let out = match pin.port.kind() {
            PortKind::Sensor => self.sensor_out.get_mut(i),
            PortKind::Actuator => self.actuators.get_mut(i).map(|a| &mut a.out),
        };
        out.and_then(|o| o.get_mut(pin.pin.index()))
    }
}

/// Sets `slot` to `value`; whether that changed it.
fn replace<T: PartialEq>(slot: &mut T, value: T) -> bool {
    let changed = *slot != value;
    *slot = value;
    changed
}

/// One board's simulated ports.
pub struct SimPorts {
    board: String,
    clock: SimClock,
    adc_bits: u8,
    sensors: Vec<SensorScript>,
    actuator_inputs: Vec<[Digital; 2]>,
    safe: Vec<SafeState>,
    state: RefCell<State>,
    log: ActuatorLog,
}

impl SimPorts {
    /// A board named `board` with `sensor_ports` idle sensor ports (inputs low, analog 0),
    /// `actuator_ports` actuator ports, a 10-bit ADC (the thesis's Arduino figures),
    /// recording into `log`.
    pub fn new(
        board: impl Into<String>,
        clock: SimClock,
        log: ActuatorLog,
        sensor_ports: u8,
        actuator_ports: u8,
    ) -> SimPorts {
        let s = usize::from(sensor_ports.min(Port::MAX_PORTS));
        let a = usize::from(actuator_ports.min(Port::MAX_PORTS));
        SimPorts {
            board: board.into(),
            clock,
            adc_bits: 10,
            sensors: vec![SensorScript::default(); s],
            actuator_inputs: vec![[Digital::Const(false), Digital::Const(false)]; a],
            safe: vec![SafeState::ALL_LOW; a],
            state: RefCell::new(State::new(s, a)),
            log,
        }
    }

    /// Scripts sensor port `number` (1-based); out-of-range numbers are ignored.
    pub fn with_sensor(mut self, number: u8, script: SensorScript) -> SimPorts {
        if let Some(s) = self.sensors.get_mut(usize::from(number.wrapping_sub(1))) {
            *s = script;
        }
        self
    }

    /// Sets the safe state of actuator port `number` (1-based).
    pub fn with_safe_state(mut self, number: u8, safe: SafeState) -> SimPorts {
        if let Some(s) = self.safe.get_mut(usize::from(number.wrapping_sub(1))) {
            *s = safe;
        }
        self
    }

    /// Sets the ADC resolution (1–16 bits).
    pub fn with_adc_bits(mut self, bits: u8) -> SimPorts {
        self.adc_bits = bits.clamp(1, 16);
        self
    }

    /// The same board (scripts, safe states, log) as it is after power-up: every
    /// output undriven, PWM off. The simulator builds one per (re)boot of a board.
    pub fn fresh(&self) -> SimPorts {
        SimPorts {
            board: self.board.clone(),
            clock: self.clock.clone(),
            adc_bits: self.adc_bits,
            sensors: self.sensors.clone(),
            actuator_inputs: self.actuator_inputs.clone(),
            safe: self.safe.clone(),
            state: RefCell::new(State::new(self.sensors.len(), self.actuator_inputs.len())),
            log: self.log.clone(),
        }
    }

    /// The board loses power (a reset): every PWM output stops at once. Records, at the
    /// current instant, the duty of each pin that had one falling to 0 and the pulse width of
    /// each servo pin falling to 0 (no more pulses). Digital outputs are released (no longer
    /// driven); the log keeps the level they were last driven to until the firmware drives
    /// them again, since it records driven levels only ([`ActuatorLog::level_at`]).
    pub fn power_off(&self) {
        let mut stopped = Vec::new();
        {
            let mut st = self.state.borrow_mut();
            for (i, a) in st.actuators.iter_mut().enumerate() {
                let Ok(port) = Port::actuator(u8::try_from(i + 1).unwrap_or(u8::MAX)) else {
                    continue;
                };
                for (pin, duty) in [Pin::A, Pin::B].into_iter().zip(a.duty.iter_mut()) {
                    if *duty != 0 {
                        *duty = 0;
                        stopped.push((port.pin(pin), Change::Duty(0)));
                    }
                }
                for (pin, width) in [Pin::A, Pin::B].into_iter().zip(a.width.iter_mut()) {
                    if width.is_some_and(|w| w != 0) {
                        *width = Some(0);
                        stopped.push((port.pin(pin), Change::PulseWidth(0)));
                    }
                }
                a.out = [None, None];
            }
            for s in &mut st.sensor_out {
                *s = [None, None];
            }
        }
        for (pin, change) in stopped {
            self.record(pin, change);
        }
    }

    /// The board name.
    pub fn board(&self) -> &str {
        &self.board
    }

    /// The shared log.
    pub fn log(&self) -> &ActuatorLog {
        &self.log
    }

    fn input(&self, pin: PinRef) -> Result<&Digital, PortError> {
        let i = usize::from(pin.port.index());
        match pin.port.kind() {
            PortKind::Sensor => self.sensors.get(i).map(|s| match pin.pin {
                Pin::A => &s.a,
                Pin::B => &s.b,
            }),
            PortKind::Actuator => self
                .actuator_inputs
                .get(i)
                .and_then(|p| p.get(pin.pin.index())),
        }
        .ok_or(PortError::NoSuchPin)
    }

    fn record(&self, pin: PinRef, change: Change) {
        self.log.push(OutputChange {
            t_ns: self.clock.now_ns(),
            board: self.board.clone(),
            pin,
            change,
        });
    }

    fn check_not_busy(&self, pin: PinRef) -> Result<(), PortError> {
        if self.state.borrow().busy.contains(&pin) {
            Err(PortError::Busy)
        } else {
            Ok(())
        }
    }

    /// The echo a [`Digital::Echo`] pin gives a pulse-in starting now: its start and end
    /// (ns), or `None` when there is none to see (no trigger pulse, the echo already rose, or
    /// a width of 0).
    fn echo(
        &self,
        pin: PinRef,
        trigger: Option<Pin>,
        delay_us: u64,
        min_interval_us: u64,
        width_us: &Analog,
    ) -> Option<(Nanos, Nanos)> {
        let now = self.clock.now_ns();
        let from = match trigger {
            None => now,
            Some(t) => {
                // The trigger's last falling edge: a LOW logged right after a HIGH, found from
                // the end of the log (no copy of it: a run measures thousands of times).
                let trigger = pin.port.pin(t);
                self.log.with_changes(|changes| {
                    let mut later: Option<(Nanos, Level)> = None;
                    for c in changes.iter().rev() {
                        if c.t_ns > now || c.pin != trigger || c.board != self.board {
                            continue;
                        }
                        if let Change::Digital(level) = c.change {
                            if later.is_some_and(|(_, l)| l == Level::Low) && level == Level::High {
                                return later.map(|(t, _)| t);
                            }
                            later = Some((c.t_ns, level));
                        }
                    }
                    None
                })?
            }
        };
        // A new measurement (not a second pulse-in on the last trigger) too soon after the
        // last one the part answered: no echo.
        let last = self
            .state
            .borrow()
            .pings
            .iter()
            .find(|(p, _)| *p == pin)
            .map(|(_, t)| *t);
        let min_ns = min_interval_us.saturating_mul(1_000);
        if let Some(last) = last.filter(|&l| from > l && from - l < min_ns) {
            let gap_us = (from - last) / 1_000;
            self.log.bound.keep(&self.log.warnings, DeviceWarning {
                t_ns: from,
                board: self.board.clone(),
                text: format!(
                    "ultrasonic on {pin}: measurement {}.{:03} ms after the last one, under the part's {} ms minimum: no echo",
                    gap_us / 1_000,
                    gap_us % 1_000,
                    min_interval_us / 1_000
                ),
            }, &self.log.bound.warnings_dropped);
            return None;
        }
        {
            let mut state = self.state.borrow_mut();
            state.pings.retain(|(p, _)| *p != pin);
            state.pings.push((pin, from));
        }
        let start = from.saturating_add(delay_us.saturating_mul(1_000));
        let width = u64::from(width_us.value_at(start)) * 1_000;
        (start >= now && width > 0).then(|| (start, start + width))
    }

    /// Edges of `signal` in `(from_ns, to_ns]`.
    fn edges_between(signal: &Digital, from_ns: Nanos, to_ns: Nanos) -> EdgeCount {
        if let Digital::Model(m) = signal {
            return m.edges_between(from_ns, to_ns);
        }
        let mut n = EdgeCount::NONE;
        let mut t = from_ns;
        while let Some(at) = signal.next_change_after(t).filter(|&at| at <= to_ns) {
            if signal.level_at(at) {
                n.rising = n.rising.saturating_add(1);
            } else {
                n.falling = n.falling.saturating_add(1);
            }
            t = at;
        }
        n
    }

    /// A PWM setting of actuator `pin`'s port: `set` changes its state (saying whether
    /// anything changed) or refuses; `change` is recorded for `pin` if anything changed.
    fn set_pwm(
        &self,
        pin: PinRef,
        change: Change,
        set: impl FnOnce(&mut ActuatorState) -> Result<bool, PortError>,
    ) -> Result<(), PortError> {
        if pin.port.kind() != PortKind::Actuator {
            return Err(PortError::Unsupported);
        }
        let changed = {
            let mut st = self.state.borrow_mut();
            let a = st
                .actuators
                .get_mut(usize::from(pin.port.index()))
                .ok_or(PortError::NoSuchPin)?;
            set(a)?
        };
        if changed {
            self.record(pin, change);
        }
        Ok(())
    }
}

impl Ports for SimPorts {
    fn sensor_ports(&self) -> u8 {
        u8::try_from(self.sensors.len()).unwrap_or(Port::MAX_PORTS)
    }

    fn actuator_ports(&self) -> u8 {
        u8::try_from(self.actuator_inputs.len()).unwrap_or(Port::MAX_PORTS)
    }

    fn adc_bits(&self) -> u8 {
        self.adc_bits
    }

    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        self.check_not_busy(pin)?;
        let level = self.input(pin)?.level_at(self.clock.now_ns());
        // Reading makes the pin an input.
        if let Some(slot) = self.state.borrow_mut().out(pin) {
            *slot = None;
        }
        Ok(Level::from_bool(level))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        self.check_not_busy(pin)?;
        let changed = {
            let mut st = self.state.borrow_mut();
            let slot = st.out(pin).ok_or(PortError::NoSuchPin)?;
            replace(slot, Some(level))
        };
        if changed {
            self.record(pin, Change::Digital(level));
        }
        Ok(())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        self.set_pwm(pin, Change::Duty(duty), |a| {
            let slot = a
                .duty
                .get_mut(pin.pin.index())
                .ok_or(PortError::NoSuchPin)?;
            Ok(replace(slot, duty))
        })
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        if hz == 0 {
            return Err(PortError::Unsupported);
        }
        self.set_pwm(port.into(), Change::Frequency(hz), |a| {
            Ok(replace(&mut a.freq, Some(hz)))
        })
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        self.set_pwm(pin, Change::PulseWidth(us), |a| {
            // The period of the current frequency (50 Hz servo default).
            let period_us = 1_000_000 / u32::from(a.freq.unwrap_or(50).max(1));
            if u32::from(us) > period_us {
                return Err(PortError::Unsupported);
            }
            let slot = a
                .width
                .get_mut(pin.pin.index())
                .ok_or(PortError::NoSuchPin)?;
            Ok(replace(slot, Some(us)))
        })
    }

    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        if port.kind() != PortKind::Sensor {
            return Err(PortError::Unsupported);
        }
        let script = self
            .sensors
            .get(usize::from(port.index()))
            .ok_or(PortError::NoSuchPin)?;
        let v = script.analog.value_at(self.clock.now_ns());
        let max = if self.adc_bits >= 16 {
            u16::MAX
        } else {
            (1u16 << self.adc_bits) - 1
        };
        Ok(v.min(max))
    }

    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        self.check_not_busy(pin)?;
        let signal = self.input(pin)?.clone();
        self.state.borrow_mut().busy.push(pin);
        let deadline = self
            .clock
            .now_ns()
            .saturating_add(u64::from(timeout_ms) * 1_000_000);
        let start_level = matches!(edge, Edge::Rising);
        if let Digital::Echo {
            trigger,
            delay_us,
            min_interval_us,
            width_us,
        } = &signal
        {
            let echo = self.echo(pin, *trigger, *delay_us, *min_interval_us, width_us);
            let result = match echo {
                // Only a rising-edge pulse-in that starts before the echo rises sees it whole.
                Some((start, end)) if start_level && end <= deadline => {
                    self.clock.sleep_until_ns(end).await;
                    Ok(u32::try_from((end - start) / 1_000).unwrap_or(u32::MAX))
                }
                _ => {
                    self.clock.sleep_until_ns(deadline).await;
                    Err(PortError::Timeout)
                }
            };
            self.state.borrow_mut().busy.retain(|p| *p != pin);
            return result;
        }
        let result = async {
            // Wait for the starting edge, then for the opposite one.
            let mut started = None;
            let mut t = self.clock.now_ns();
            loop {
                let Some(at) = signal.next_change_after(t).filter(|&at| at <= deadline) else {
                    self.clock.sleep_until_ns(deadline).await;
                    return Err(PortError::Timeout);
                };
                t = at;
                let level = signal.level_at(at);
                match started {
                    None if level == start_level => started = Some(at),
                    Some(s) if level != start_level => {
                        self.clock.sleep_until_ns(at).await;
                        let us = (at - s) / 1_000;
                        return Ok(u32::try_from(us).unwrap_or(u32::MAX));
                    }
                    _ => {}
                }
            }
        }
        .await;
        self.state.borrow_mut().busy.retain(|p| *p != pin);
        result
    }

    /// Latches every scripted edge of the pin's input from now on (exactly: see
    /// [`Ports::take_edges`]).
    fn blink(&self, secs: u8) -> Result<(), PortError> {
        self.log.bound.keep(
            &self.log.blinks,
            Blink {
                t_ns: self.clock.now_ns(),
                board: self.board.clone(),
                secs,
            },
            &self.log.bound.others_dropped,
        );
        Ok(())
    }

    fn latch_edges(&self, pin: PinRef) -> Result<(), PortError> {
        self.input(pin)?;
        let now = self.clock.now_ns();
        let mut st = self.state.borrow_mut();
        match st.latched.iter_mut().find(|(p, _)| *p == pin) {
            Some(l) => l.1 = now,
            None => st.latched.push((pin, now)),
        }
        self.log.bound.keep(
            &self.log.latches,
            EdgeLatch {
                t_ns: now,
                board: self.board.clone(),
                pin,
            },
            &self.log.bound.others_dropped,
        );
        Ok(())
    }

    /// Every scripted edge of the pin's input since the latch or the last take, counted
    /// exactly (an edge at the instant of a take belongs to that take).
    fn take_edges(&self, pin: PinRef) -> Result<EdgeCount, PortError> {
        let signal = self.input(pin)?;
        let now = self.clock.now_ns();
        let mut st = self.state.borrow_mut();
        let l = st
            .latched
            .iter_mut()
            .find(|(p, _)| *p == pin)
            .ok_or(PortError::Unsupported)?;
        let since = core::mem::replace(&mut l.1, now);
        Ok(Self::edges_between(signal, since, now))
    }

    /// Sleeps until the next scripted edge of a latched pin (returns at once when one is
    /// waiting to be taken); never returns while no pin is latched.
    async fn wait_edge(&self) {
        loop {
            let now = self.clock.now_ns();
            let next = {
                let st = self.state.borrow();
                st.latched
                    .iter()
                    .filter_map(|(p, since)| match self.input(*p).ok()? {
                        Digital::Model(m) => Some(m.wake_after(*since, now)),
                        d => d.next_change_after(*since),
                    })
                    .min()
            };
            match next {
                Some(at) if at <= now => return,
                Some(at) => self.clock.sleep_until_ns(at).await,
                None => core::future::pending::<()>().await,
            }
        }
    }

    fn safe_state(&self, port: Port) -> SafeState {
        let safe = self
            .safe
            .get(usize::from(port.index()))
            .copied()
            .unwrap_or(SafeState::ALL_LOW);
        self.log.bound.keep(
            &self.log.safe,
            SafeStateApplied {
                t_ns: self.clock.now_ns(),
                board: self.board.clone(),
                port,
                safe,
            },
            &self.log.bound.others_dropped,
        );
        safe
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exec::Executor;
    use x10_hal::time::Clock;

    fn pin(kind: PortKind, n: u8, p: Pin) -> PinRef {
        Port::new(kind, n).unwrap().pin(p)
    }

    #[test]
    fn signals_follow_their_scripts() {
        let b = Digital::pressed_at(2_000);
        assert!(!b.level_at(1_999_999_999));
        assert!(b.level_at(2_000_000_000));
        assert_eq!(b.next_change_after(0), Some(2_000_000_000));
        assert_eq!(b.next_change_after(2_000_000_000), None);
        let r = Analog::Ramp {
            from: 100,
            to: 300,
            start_ms: 1_000,
            end_ms: 3_000,
        };
        assert_eq!(r.value_at(0), 100);
        assert_eq!(r.value_at(2_000_000_000), 200);
        assert_eq!(r.value_at(9_000_000_000), 300);
        let s = Analog::Steps {
            initial: 5,
            steps: vec![(10, 6), (20, 7)],
        };
        assert_eq!(
            [0, 10, 15, 20, 99].map(|ms| s.value_at(ms * 1_000_000)),
            [5, 6, 6, 7, 7]
        );
        let echo = Digital::Pulses {
            first_us: 100,
            period_us: 1_000,
            width_us: Analog::Const(300),
        };
        assert!(!echo.level_at(99_999));
        assert!(echo.level_at(100_000));
        assert!(!echo.level_at(400_000));
        assert!(echo.level_at(1_100_000));
        assert_eq!(echo.next_change_after(100_000), Some(400_000));
        assert_eq!(echo.next_change_after(400_000), Some(1_100_000));
        let blink = Digital::Train {
            first_us: 100_000,
            period_us: 700_000,
            width_us: 200_000,
        };
        assert_eq!(
            [0, 100, 299, 300, 799, 800, 1_000].map(|ms| blink.level_at(ms * 1_000_000)),
            [false, true, true, false, false, true, false]
        );
        assert_eq!(blink.next_change_after(0), Some(100_000_000));
        assert_eq!(blink.next_change_after(100_000_000), Some(300_000_000));
        assert_eq!(blink.next_change_after(300_000_000), Some(800_000_000));
        // Periods without a pulse (width 0) and pulses that fill their period make no edge:
        // high 300 us from 1 ms, none at 2 and 3 ms, then the whole period at 4 and 5 ms.
        let bursts = Digital::Pulses {
            first_us: 1_000,
            period_us: 1_000,
            width_us: Analog::Steps {
                initial: 300,
                steps: vec![(2, 0), (4, 1_000), (6, 0)],
            },
        };
        let mut edges = Vec::new();
        let mut t = 0;
        while let Some(at) = bursts.next_change_after(t) {
            edges.push((at / 1_000, bursts.level_at(at)));
            t = at;
        }
        assert_eq!(
            edges,
            [(1_000, true), (1_300, false), (4_000, true), (6_000, false)]
        );
        let never = Digital::Train {
            first_us: 0,
            period_us: 10,
            width_us: 0,
        };
        assert_eq!(never.next_change_after(0), None);
    }

    #[test]
    fn outputs_are_logged_only_when_they_change_and_inputs_follow_time() {
        let log = ActuatorLog::new();
        let clock = SimClock::new();
        let ports = SimPorts::new("db09", clock.clone(), log.clone(), 2, 2).with_sensor(
            1,
            SensorScript {
                a: Digital::pressed_at(2),
                b: Digital::Const(true),
                analog: Analog::Ramp {
                    from: 0,
                    to: 2000,
                    start_ms: 0,
                    end_ms: 10,
                },
            },
        );
        let results = RefCell::new(Vec::new());
        let mut ex = Executor::with_clock(&clock);
        let (p, r) = (&ports, &results);
        let a1a = pin(PortKind::Actuator, 1, Pin::A);
        let s1a = pin(PortKind::Sensor, 1, Pin::A);
        ex.spawn("t", async move {
            let push = |v: String| r.borrow_mut().push(v);
            p.digital_write(a1a, Level::High).unwrap();
            p.digital_write(a1a, Level::High).unwrap();
            p.pwm_duty(a1a, 128).unwrap();
            let v = p.digital_read(s1a);
            push(format!("{v:?}"));
            clock.sleep_until(x10_hal::time::Instant(5_000)).await;
            let v = p.digital_read(s1a);
            push(format!("{v:?}"));
            let v = p.analog_read(s1a.port);
            push(format!("{v:?}"));
            let v = p.pwm_duty(s1a, 1);
            push(format!("{v:?}"));
            let v = p.digital_write(pin(PortKind::Actuator, 3, Pin::A), Level::Low);
            push(format!("{v:?}"));
            p.digital_write(a1a, Level::Low).unwrap();
        });
        ex.run_until_ns(1_000_000_000).unwrap();
        assert_eq!(
            *results.borrow(),
            vec![
                "Ok(Low)",
                "Ok(High)",
                "Ok(1000)",
                "Err(Unsupported)",
                "Err(NoSuchPin)"
            ]
        );
        let changes = log.changes();
        assert_eq!(changes.len(), 3);
        assert_eq!(changes[0].change, Change::Digital(Level::High));
        assert_eq!(changes[1].change, Change::Duty(128));
        // Port calls take no virtual time: the write after the analog read at 5 ms is at 5 ms.
        assert_eq!(changes[2].t_ns, 5_000_000);
        assert_eq!(log.level_at("db09", a1a, 4_999_999), Some(Level::High));
        assert_eq!(log.level_at("db09", a1a, 5_000_000), Some(Level::Low));
        assert_eq!(log.level_at("db09", a1a, 6_000_000), Some(Level::Low));
        assert_eq!(log.duty_at("db09", a1a, 0), 128);
        assert_eq!(changes[0].to_string(), "db09 A1.A high");
    }

    #[test]
    fn pulse_in_measures_the_echo_and_times_out() {
        let clock = SimClock::new();
        let ports = SimPorts::new("db", clock.clone(), ActuatorLog::new(), 1, 0).with_sensor(
            1,
            SensorScript {
                a: Digital::Pulses {
                    first_us: 500,
                    period_us: 60_000,
                    width_us: Analog::Const(1_160),
                },
                ..SensorScript::default()
            },
        );
        let out = RefCell::new(Vec::new());
        let mut ex = Executor::with_clock(&clock);
        let (p, o) = (&ports, &out);
        let s1a = pin(PortKind::Sensor, 1, Pin::A);
        let s1b = pin(PortKind::Sensor, 1, Pin::B);
        ex.spawn("t", async move {
            let r = p.pulse_in(s1a, Edge::Rising, 100).await;
            o.borrow_mut().push((clock.now_ns(), r));
            let r = p.pulse_in(s1a, Edge::Falling, 200).await;
            o.borrow_mut().push((clock.now_ns(), r));
            let r = p.pulse_in(s1b, Edge::Rising, 5).await;
            o.borrow_mut().push((clock.now_ns(), r));
        });
        ex.run_until_ns(10_000_000_000).unwrap();
        let o = out.borrow();
        assert_eq!(o[0], (1_660_000, Ok(1_160)));
        // Falling edge: called at the end of the first pulse, so it measures the low time from
        // the end of the second pulse to the start of the third.
        assert_eq!(o[1], (120_500_000, Ok(60_000 - 1_160)));
        assert_eq!(o[2], (125_500_000, Err(PortError::Timeout)));
    }

    #[test]
    fn an_echo_pin_ignores_a_trigger_sooner_than_its_minimum_interval_and_warns() {
        let clock = SimClock::new();
        let log = ActuatorLog::new();
        let ports = SimPorts::new("db09", clock.clone(), log.clone(), 1, 0).with_sensor(
            1,
            SensorScript {
                b: Digital::Echo {
                    trigger: Some(Pin::A),
                    delay_us: 500,
                    min_interval_us: 60_000,
                    width_us: Analog::Const(1_000),
                },
                ..SensorScript::default()
            },
        );
        let out = RefCell::new(Vec::new());
        let mut ex = Executor::with_clock(&clock);
        let (p, o) = (&ports, &out);
        let (trig, echo) = (
            pin(PortKind::Sensor, 1, Pin::A),
            pin(PortKind::Sensor, 1, Pin::B),
        );
        ex.spawn("t", async move {
            // Triggers ending at 10 ms (answered), 30 ms (20 ms later: ignored), 70 ms (60 ms
            // after the last answered one: answered).
            for at_ms in [10, 30, 70] {
                clock.sleep_until_ns(at_ms * 1_000_000).await;
                p.digital_write(trig, Level::High).unwrap();
                p.digital_write(trig, Level::Low).unwrap();
                let r = p.pulse_in(echo, Edge::Rising, 5).await;
                o.borrow_mut().push((clock.now_ns(), r));
            }
        });
        ex.run_until_ns(1_000_000_000).unwrap();
        assert_eq!(
            *out.borrow(),
            vec![
                (11_500_000, Ok(1_000)),
                (35_000_000, Err(PortError::Timeout)),
                (71_500_000, Ok(1_000)),
            ]
        );
        assert_eq!(
            log.device_warnings(),
            [DeviceWarning {
                t_ns: 30_000_000,
                board: "db09".to_string(),
                text: "ultrasonic on S1.B: measurement 20.000 ms after the last one, under the part's 60 ms minimum: no echo".to_string(),
            }]
        );
    }

    #[test]
    fn an_echo_pin_answers_its_trigger() {
        let clock = SimClock::new();
        let echo = |trigger| Digital::Echo {
            trigger,
            delay_us: 500,
            min_interval_us: 0,
            width_us: Analog::Const(1_000),
        };
        let ports = SimPorts::new("db", clock.clone(), ActuatorLog::new(), 2, 0)
            .with_sensor(
                1,
                SensorScript {
                    b: echo(Some(Pin::A)),
                    ..SensorScript::default()
                },
            )
            .with_sensor(
                2,
                SensorScript {
                    b: echo(None),
                    ..SensorScript::default()
                },
            );
        let out = RefCell::new(Vec::new());
        let mut ex = Executor::with_clock(&clock);
        let (p, o) = (&ports, &out);
        let (s1a, s1b) = (
            pin(PortKind::Sensor, 1, Pin::A),
            pin(PortKind::Sensor, 1, Pin::B),
        );
        let s2b = pin(PortKind::Sensor, 2, Pin::B);
        ex.spawn("t", async move {
            let push = |r| o.borrow_mut().push((clock.now_ns(), r));
            // No trigger pulse yet: nothing to see.
            push(p.pulse_in(s1b, Edge::Rising, 5).await);
            // A trigger pulse ending at 10 ms: the echo is 10.5 ms to 11.5 ms.
            clock.sleep_until_ns(10_000_000).await;
            p.digital_write(s1a, Level::High).unwrap();
            p.digital_write(s1a, Level::Low).unwrap();
            clock.sleep_until_ns(10_400_000).await;
            push(p.pulse_in(s1b, Edge::Rising, 30).await);
            // Too late for the same echo: it already rose.
            clock.sleep_until_ns(20_000_000).await;
            p.digital_write(s1a, Level::High).unwrap();
            p.digital_write(s1a, Level::Low).unwrap();
            clock.sleep_until_ns(20_600_000).await;
            push(p.pulse_in(s1b, Edge::Rising, 30).await);
            // Free-running: 0.5 ms after the pulse-in starts.
            push(p.pulse_in(s2b, Edge::Rising, 30).await);
            push(p.pulse_in(s2b, Edge::Falling, 3).await);
            // A digital read of an echo pin reads low.
            push(p.digital_read(s2b).map(|l| u32::from(l.is_high())));
        });
        ex.run_until_ns(1_000_000_000).unwrap();
        assert_eq!(
            *out.borrow(),
            vec![
                (5_000_000, Err(PortError::Timeout)),
                (11_500_000, Ok(1_000)),
                (50_600_000, Err(PortError::Timeout)),
                (52_100_000, Ok(1_000)),
                (55_100_000, Err(PortError::Timeout)),
                (55_100_000, Ok(0)),
            ]
        );
    }
}
