//! Units and ranges as types. A value of one of these types is always in range: the checked
//! constructors return a [`RangeError`] otherwise.

use crate::error::{Quantity, RangeError};

/// Which way a motor turns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// Positive speeds.
    Forward,
    /// Negative speeds.
    Reverse,
}

/// A percentage, `0..=100`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Percent(pub(crate) u8);

impl Percent {
    /// 0 %.
    pub const ZERO: Percent = Percent(0);
    /// 100 %.
    pub const FULL: Percent = Percent(100);

    /// Checks `percent <= 100`.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::Percent`]) above 100.
    pub const fn new(percent: u8) -> Result<Percent, RangeError> {
        match RangeError::check(Quantity::Percent, percent as i32, 0, 100) {
            Ok(()) => Ok(Percent(percent)),
            Err(e) => Err(e),
        }
    }

    /// The value, `0..=100`.
    pub const fn get(self) -> u8 {
        self.0
    }

    /// The PWM duty for this share of full power ([`Duty::from_percent`]).
    pub const fn to_duty(self) -> Duty {
        Duty::from_percent(self)
    }
}

/// A PWM duty cycle as the wire carries it: `0` (always low) ..= `255` (always high).
/// Every `u8` is a valid duty.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Duty(pub u8);

impl Duty {
    /// Always low.
    pub const OFF: Duty = Duty(0);
    /// Always high.
    pub const FULL: Duty = Duty(255);

    /// `255 × percent / 100`, rounded down, exactly as the thesis's `pwm_a(power)` computes
    /// it: 100 % is 255, 50 % is 127, 1 % is 2. Frames therefore match captures from the
    /// original.
    pub const fn from_percent(p: Percent) -> Duty {
        // p <= 100, so the product fits in u16 and the quotient in u8.
        Duty(((p.0 as u16 * 255) / 100) as u8)
    }

    /// The raw duty byte.
    pub const fn get(self) -> u8 {
        self.0
    }
}

/// A signed motor speed in percent of full power: `-100` (full reverse) ..= `100` (full
/// forward); `0` is stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Speed(i8);

impl Speed {
    /// Stopped.
    pub const STOP: Speed = Speed(0);
    /// Full power forward.
    pub const FULL_FORWARD: Speed = Speed(100);
    /// Full power in reverse.
    pub const FULL_REVERSE: Speed = Speed(-100);

    /// Checks `-100 <= percent <= 100`.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::Speed`]) outside that range.
    pub const fn new(percent: i8) -> Result<Speed, RangeError> {
        match RangeError::check(Quantity::Speed, percent as i32, -100, 100) {
            Ok(()) => Ok(Speed(percent)),
            Err(e) => Err(e),
        }
    }

    /// `magnitude` forward.
    pub const fn forward(magnitude: Percent) -> Speed {
        Speed(magnitude.0 as i8)
    }

    /// `magnitude` in reverse.
    pub const fn reverse(magnitude: Percent) -> Speed {
        Speed(-(magnitude.0 as i8))
    }

    /// The value, `-100..=100`.
    pub const fn percent(self) -> i8 {
        self.0
    }

    /// The share of full power, without the direction.
    pub const fn magnitude(self) -> Percent {
        Percent(self.0.unsigned_abs())
    }

    /// The direction, or `None` when stopped.
    pub const fn direction(self) -> Option<Direction> {
        if self.0 > 0 {
            Some(Direction::Forward)
        } else if self.0 < 0 {
            Some(Direction::Reverse)
        } else {
            None
        }
    }
}

/// A temperature in kelvin.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Kelvin(pub f32);

/// A temperature in degrees Celsius.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Celsius(pub f32);

/// A temperature in degrees Fahrenheit.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fahrenheit(pub f32);

impl Kelvin {
    /// `K − 273.15`.
    pub fn to_celsius(self) -> Celsius {
        Celsius(self.0 - 273.15)
    }
}

impl Celsius {
    /// `°C × 9 / 5 + 32`.
    pub fn to_fahrenheit(self) -> Fahrenheit {
        Fahrenheit(self.0 * 9.0 / 5.0 + 32.0)
    }
}

impl Fahrenheit {
    /// `(°F − 32) × 5 / 9`.
    pub fn to_celsius(self) -> Celsius {
        Celsius((self.0 - 32.0) * 5.0 / 9.0)
    }
}

/// An angle in whole degrees (a servo checks it against its own range).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Degrees(pub u16);

/// A distance in millimetres.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Millimetres(pub u32);
