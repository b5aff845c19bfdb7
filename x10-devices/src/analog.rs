//! An analog sensor (light, force, potentiometer, …) with a linear calibration.

use x10_microcode::Address;

use crate::math::Calibration;
use crate::port::Sensor;
use crate::{Link, Result};

/// An analog sensor on a sensor port's analog input: [`AnalogSensor::read_raw`] gives ADC
/// counts (what the thesis's programs compare: `force1.readAnalog() > 100`),
/// [`AnalogSensor::read`] applies a [`Calibration`].
#[derive(Clone, Debug)]
pub struct AnalogSensor<L> {
    sensor: Sensor<L>,
    calibration: Calibration,
}

impl<L: Link> AnalogSensor<L> {
    /// An uncalibrated ([`Calibration::RAW`]) sensor on sensor port `number` (from 1) of board
    /// `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Self::with_calibration(link, db, number, Calibration::RAW)
    }

    /// A calibrated sensor.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn with_calibration(
        link: L,
        db: Address,
        number: u8,
        calibration: Calibration,
    ) -> Result<Self> {
        Ok(AnalogSensor {
            sensor: Sensor::new(link, db, number)?,
            calibration,
        })
    }

    /// The sensor port.
    pub fn sensor(&self) -> &Sensor<L> {
        &self.sensor
    }

    /// The calibration.
    pub fn calibration(&self) -> Calibration {
        self.calibration
    }

    /// One raw reading in ADC counts.
    ///
    /// # Errors
    /// [`crate::Error::Link`].
    pub async fn read_raw(&self) -> Result<u16> {
        self.sensor.read_analog().await
    }

    /// One calibrated reading.
    ///
    /// # Errors
    /// [`crate::Error::Link`].
    pub async fn read(&self) -> Result<f32> {
        Ok(self.calibration.apply(self.read_raw().await?))
    }
}
