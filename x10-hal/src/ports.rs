//! What a board supplies to the daughterboard runtime (and to the MB's internal daughterboard):
//! its sensor and actuator ports.
//!
//! Port numbers here are the wire's 0-based indices inside [`PinRef`]/[`Port`]; the runtime has
//! already checked them against [`Ports::sensor_ports`] and [`Ports::actuator_ports`] and the
//! port kind against the operation, so an implementation may treat an out-of-range port as a
//! bug of its own and return [`PortError::NoSuchPin`].

use x10_microcode::{Edge, Level, PinRef, Port};

/// Why a port operation failed on the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PortError {
    /// The board has no such pin (its pin map has a hole there).
    NoSuchPin,
    /// The board cannot do this on that pin (no PWM, no ADC, value out of range for the
    /// hardware): answered `unsupported`.
    Unsupported,
    /// The pin is in use by a running operation (a pulse-in): answered `busy`.
    Busy,
    /// A pulse-in saw no pulse before its timeout: answered `timeout`.
    Timeout,
}

/// The safe state of one actuator port, applied by the failsafe and at boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafeState {
    /// PWM duty of pins A and B (0 = off).
    pub pwm: [u8; 2],
    /// Levels of the digital pins A and B.
    pub digital: [Level; 2],
}

impl SafeState {
    /// Everything off and low: an H-bridge with both inputs low coasts.
    pub const ALL_LOW: SafeState = SafeState {
        pwm: [0, 0],
        digital: [Level::Low, Level::Low],
    };
}

/// Edges counted on one pin by [`Ports::take_edges`], each saturating at `u16::MAX`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EdgeCount {
    /// Low-to-high transitions.
    pub rising: u16,
    /// High-to-low transitions.
    pub falling: u16,
}

impl EdgeCount {
    /// No edge.
    pub const NONE: EdgeCount = EdgeCount {
        rising: 0,
        falling: 0,
    };

    /// True when no edge was counted.
    pub const fn is_none(&self) -> bool {
        self.rising == 0 && self.falling == 0
    }

    /// Both counts added, saturating.
    pub const fn plus(self, other: EdgeCount) -> EdgeCount {
        EdgeCount {
            rising: self.rising.saturating_add(other.rising),
            falling: self.falling.saturating_add(other.falling),
        }
    }
}

/// A board's sensor ports (2 digital I/O + 1 analog each) and actuator ports (2 PWM + 2
/// digital I/O each).
///
/// Every method takes `&self`: the runtime keeps a pulse-in measurement running while it
/// serves other requests, so implementations keep their pins behind interior mutability
/// (a `RefCell` or a blocking mutex per pin) and answer [`PortError::Busy`] for a pin that is
/// in use.
///
/// Reads and settings (GPIO, PWM, ADC) are synchronous: on every board they complete at once
/// (a register write; an ADC conversion of about 2 µs waited for), and an `async fn` here
/// costs the state machine of an `await` in every caller: making them synchronous saved
/// 0.9 KiB of flash on db-pico (docs/boards.md "Sizes"). Only [`Ports::pulse_in`] and
/// [`Ports::wait_edge`], which wait for the outside world, are `async`.
#[allow(async_fn_in_trait)]
pub trait Ports {
    /// Number of sensor ports (at most 64; a scan reports at most 8).
    fn sensor_ports(&self) -> u8;

    /// Number of actuator ports (at most 64).
    fn actuator_ports(&self) -> u8;

    /// ADC resolution in bits (reported by identify; analog values are in `0..2^bits`).
    fn adc_bits(&self) -> u8;

    /// Reads a digital pin (making it an input first if it was an output).
    ///
    /// # Errors
    /// [`PortError::NoSuchPin`], [`PortError::Busy`].
    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError>;

    /// Drives a digital pin (making it an output first).
    ///
    /// # Errors
    /// [`PortError::NoSuchPin`], [`PortError::Busy`].
    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError>;

    /// Sets the duty cycle (0–255) of PWM pin A or B of an actuator port.
    ///
    /// # Errors
    /// [`PortError::NoSuchPin`], [`PortError::Unsupported`].
    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError>;

    /// Sets the PWM frequency of both PWM pins of an actuator port.
    ///
    /// # Errors
    /// [`PortError::Unsupported`] when the hardware cannot produce `hz`.
    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError>;

    /// Sets the high time of each PWM period in µs (servo pulses).
    ///
    /// # Errors
    /// [`PortError::Unsupported`] when longer than the period or not supported.
    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError>;

    /// Reads the analog input of a sensor port, in `0..2^adc_bits`.
    ///
    /// # Errors
    /// [`PortError::NoSuchPin`], [`PortError::Unsupported`].
    fn analog_read(&self, port: Port) -> Result<u16, PortError>;

    /// Measures one pulse on a digital pin: waits for `edge`, then for the opposite edge, and
    /// returns the time between them in µs. Gives up after `timeout_ms` in all.
    ///
    /// # Errors
    /// [`PortError::Timeout`], [`PortError::NoSuchPin`], [`PortError::Unsupported`].
    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError>;

    /// Starts latching the edges of a digital input `pin` in hardware (an edge interrupt that
    /// counts, a timer in counter mode, a latched interrupt flag), from now on, with its
    /// counts at zero. Edges are counted until the board resets; calling it again restarts the
    /// counts. The daughterboard calls it when events are enabled on the pin.
    ///
    /// A board that cannot latch edges on `pin` answers [`PortError::Unsupported`] (the
    /// default); the runtime then samples the pin and counts the level changes it sees, which
    /// misses pulses shorter than the sample interval.
    ///
    /// # Errors
    /// [`PortError::Unsupported`], [`PortError::NoSuchPin`].
    fn latch_edges(&self, pin: PinRef) -> Result<(), PortError> {
        let _ = pin;
        Err(PortError::Unsupported)
    }

    /// The edges latched on `pin` since [`Ports::latch_edges`] or the previous call, and
    /// starts counting again from zero. Every edge is counted exactly once: none is lost
    /// between two calls (a count that would pass `u16::MAX` stays there).
    ///
    /// # Errors
    /// [`PortError::Unsupported`] when the pin is not latched.
    fn take_edges(&self, pin: PinRef) -> Result<EdgeCount, PortError> {
        let _ = pin;
        Err(PortError::Unsupported)
    }

    /// Returns once an edge has been latched on some latched pin and not yet taken (at once if
    /// one is waiting). Without edge latching (the default) it never returns; the runtime
    /// races it against its sampling timer.
    async fn wait_edge(&self) {
        core::future::pending::<()>().await
    }

    /// Blinks the board's status LED for `secs` seconds (0 stops it), so that a person can
    /// find the board (`blink`, plug and play). The board times the blinking itself. A board
    /// without a status LED answers [`PortError::Unsupported`] (the default).
    ///
    /// # Errors
    /// [`PortError::Unsupported`].
    fn blink(&self, secs: u8) -> Result<(), PortError> {
        let _ = secs;
        Err(PortError::Unsupported)
    }

    /// The safe state of an actuator port (default: all low).
    fn safe_state(&self, port: Port) -> SafeState {
        let _ = port;
        SafeState::ALL_LOW
    }
}
