//! A hobby servo on a PWM pin of an actuator port.

use x10_microcode::{Address, Pin};

use crate::error::{Quantity, RangeError};
use crate::math::servo_pulse_us;
use crate::port::Actuator;
use crate::units::Degrees;
use crate::{Link, Result};

/// A servo's pulse range: `min_us` at 0°, `max_us` at `max_angle`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ServoConfig {
    min_us: u16,
    max_us: u16,
    max_angle: u16,
}

impl ServoConfig {
    /// The servo frame rate: 50 Hz, one pulse every 20 ms.
    pub const FRAME_HZ: u16 = 50;
    /// The longest pulse that fits a 50 Hz period.
    pub const PERIOD_US: u16 = 20_000;
    /// The common range: 1000 µs at 0°, 2000 µs at 180°.
    pub const STANDARD: ServoConfig = ServoConfig {
        min_us: 1000,
        max_us: 2000,
        max_angle: 180,
    };

    /// A range.
    ///
    /// # Errors
    /// [`RangeError`]: [`Quantity::PulseWidth`] unless `0 < min_us < max_us <= 20000`;
    /// [`Quantity::MaxAngle`] for a `max_angle` of 0 or above 360.
    pub const fn new(
        min_us: u16,
        max_us: u16,
        max_angle: u16,
    ) -> core::result::Result<ServoConfig, RangeError> {
        if let Err(e) = RangeError::check(Quantity::PulseWidth, min_us as i32, 1, max_us as i32 - 1)
        {
            return Err(e);
        }
        if let Err(e) = RangeError::check(
            Quantity::PulseWidth,
            max_us as i32,
            2,
            Self::PERIOD_US as i32,
        ) {
            return Err(e);
        }
        if let Err(e) = RangeError::check(Quantity::MaxAngle, max_angle as i32, 1, 360) {
            return Err(e);
        }
        Ok(ServoConfig {
            min_us,
            max_us,
            max_angle,
        })
    }

    /// Pulse at 0°.
    pub const fn min_us(&self) -> u16 {
        self.min_us
    }

    /// Pulse at the largest angle.
    pub const fn max_us(&self) -> u16 {
        self.max_us
    }

    /// The largest angle.
    pub const fn max_angle(&self) -> u16 {
        self.max_angle
    }

    /// The pulse for `angle`.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::Angle`]) above the largest angle.
    pub fn pulse_us(&self, angle: Degrees) -> core::result::Result<u16, RangeError> {
        RangeError::check(Quantity::Angle, angle.0 as i32, 0, self.max_angle as i32)?;
        Ok(servo_pulse_us(
            angle.0,
            self.min_us,
            self.max_us,
            self.max_angle,
        ))
    }
}

/// A servo on PWM pin `pin` of an actuator port: [`Servo::init`] sets the port's PWM to 50 Hz
/// (`PWM FREQUENCY`; it applies to both PWM pins of the port), [`Servo::set_angle`] sends the
/// pulse width (`PWM PULSE-WIDTH`).
#[derive(Clone, Debug)]
pub struct Servo<L> {
    port: Actuator<L>,
    pin: Pin,
    config: ServoConfig,
}

impl<L: Link> Servo<L> {
    /// A [`ServoConfig::STANDARD`] servo on PWM pin `pin` of actuator port `number` (from 1) of
    /// board `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8, pin: Pin) -> Result<Self> {
        Self::with_config(link, db, number, pin, ServoConfig::STANDARD)
    }

    /// A servo with its own pulse range.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn with_config(
        link: L,
        db: Address,
        number: u8,
        pin: Pin,
        config: ServoConfig,
    ) -> Result<Self> {
        Ok(Servo {
            port: Actuator::new(link, db, number)?,
            pin,
            config,
        })
    }

    /// The actuator port.
    pub fn actuator(&self) -> &Actuator<L> {
        &self.port
    }

    /// The pulse range.
    pub fn config(&self) -> &ServoConfig {
        &self.config
    }

    /// Sets the port's PWM frequency to 50 Hz. Call once before the first angle.
    ///
    /// # Errors
    /// [`crate::Error::Link`].
    pub async fn init(&self) -> Result<()> {
        self.port.pwm_frequency(ServoConfig::FRAME_HZ).await
    }

    /// Turns to `angle`.
    ///
    /// # Errors
    /// [`crate::Error::Range`] ([`Quantity::Angle`]) above the largest angle, before anything
    /// is sent; [`crate::Error::Link`].
    pub async fn set_angle(&self, angle: Degrees) -> Result<()> {
        let us = self.config.pulse_us(angle)?;
        self.port.pulse_width(self.pin, us).await
    }

    /// Sends a pulse width directly.
    ///
    /// # Errors
    /// [`crate::Error::Range`] ([`Quantity::PulseWidth`]) outside the configured range;
    /// [`crate::Error::Link`].
    pub async fn set_pulse_us(&self, us: u16) -> Result<()> {
        RangeError::check(
            Quantity::PulseWidth,
            us as i32,
            self.config.min_us as i32,
            self.config.max_us as i32,
        )?;
        self.port.pulse_width(self.pin, us).await
    }

    /// Stops the pulses (pulse width 0): the servo no longer holds its position.
    ///
    /// # Errors
    /// [`crate::Error::Link`].
    pub async fn release(&self) -> Result<()> {
        self.port.pulse_width(self.pin, 0).await
    }
}
