//! What a driver method can fail with.

use core::fmt;

use crate::LinkError;

/// The quantity a [`RangeError`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Quantity {
    /// A signed motor speed in percent ([`crate::Speed`]).
    Speed,
    /// A percentage ([`crate::Percent`]).
    Percent,
    /// A PWM frequency in Hz.
    PwmFrequency,
    /// A servo angle in degrees.
    Angle,
    /// A servo pulse width in µs.
    PulseWidth,
    /// A servo configuration's largest angle.
    MaxAngle,
    /// The step of a motor ramp in percent.
    RampStep,
    /// An ADC resolution in bits.
    AdcBits,
    /// A divider's fixed resistor in ohms.
    SeriesResistor,
    /// The number of agreeing samples a button debounce needs.
    DebounceSamples,
    /// The distance in raw counts between the two points of a calibration.
    CalibrationSpan,
    /// The speed of sound in m/s.
    SpeedOfSound,
    /// The interval of a [`crate::Refresh`] in steps.
    RefreshSteps,
}

/// A value outside the range its type allows. Nothing was sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RangeError {
    /// What the value is.
    pub quantity: Quantity,
    /// The value given.
    pub value: i32,
    /// Smallest allowed value.
    pub min: i32,
    /// Largest allowed value.
    pub max: i32,
}

impl RangeError {
    /// Checks `min <= value <= max`.
    ///
    /// # Errors
    /// A [`RangeError`] naming `quantity` when the value is outside.
    pub const fn check(
        quantity: Quantity,
        value: i32,
        min: i32,
        max: i32,
    ) -> Result<(), RangeError> {
        if value < min || value > max {
            Err(RangeError {
                quantity,
                value,
                min,
                max,
            })
        } else {
            Ok(())
        }
    }
}

impl fmt::Display for RangeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:?} {} out of range {}..={}",
            self.quantity, self.value, self.min, self.max
        )
    }
}

impl core::error::Error for RangeError {}

/// Why a driver method failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error {
    /// The link failed (NACK, timeout, arbitration, bus fault, malformed reply) or the board
    /// answered with a non-`ok` status. A read reply of the wrong length or value (a digital
    /// level other than 0 or 1) is `Link(LinkError::BadReply)`.
    Link(LinkError),
    /// A port number of 0 or above 64 (ports count from 1, as in the thesis). Nothing was sent.
    BadPort(u8),
    /// A port of the wrong kind (an actuator port given to a sensor driver, or the other way
    /// round). Nothing was sent.
    WrongPortKind,
    /// An argument or configuration value out of its range. Nothing was sent.
    Range(RangeError),
    /// The board answered, but the value is outside what the device can give a meaning to:
    /// a thermistor reading on either rail of the ADC (0: open circuit; full scale: short
    /// circuit or saturated), or a value above the ADC's full scale.
    ReadingOutOfRange {
        /// The raw value read.
        raw: u16,
        /// Smallest usable value.
        min: u16,
        /// Largest usable value.
        max: u16,
    },
}

impl From<LinkError> for Error {
    fn from(e: LinkError) -> Self {
        Error::Link(e)
    }
}

impl From<RangeError> for Error {
    fn from(e: RangeError) -> Self {
        Error::Range(e)
    }
}

impl From<Error> for LinkError {
    /// Lets code whose functions return [`LinkError`] use `?` on driver results.
    ///
    /// `Link(e)` becomes `e`; `BadPort(n)` becomes `Invalid(BadPort(n))`; `WrongPortKind`
    /// becomes `Invalid(WrongPortKind)`; `Range` becomes `Invalid(BadArgument)`; and
    /// `ReadingOutOfRange` becomes `BadReply` (a reply arrived, but its value is unusable).
    /// The conversion loses detail: a program that wants it handles [`Error`] itself.
    fn from(e: Error) -> Self {
        match e {
            Error::Link(l) => l,
            Error::BadPort(n) => LinkError::Invalid(x10_microcode::Error::BadPort(n)),
            Error::WrongPortKind => LinkError::Invalid(x10_microcode::Error::WrongPortKind),
            Error::Range(_) => LinkError::Invalid(x10_microcode::Error::BadArgument),
            Error::ReadingOutOfRange { .. } => LinkError::BadReply,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Link(e) => write!(f, "link: {e}"),
            Error::BadPort(n) => write!(f, "bad port number {n} (ports count from 1)"),
            Error::WrongPortKind => f.write_str("wrong kind of port for this driver"),
            Error::Range(e) => write!(f, "{e}"),
            Error::ReadingOutOfRange { raw, min, max } => {
                write!(f, "reading {raw} outside the usable range {min}..={max}")
            }
        }
    }
}

impl core::error::Error for Error {}
