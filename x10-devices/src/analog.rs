//! An analog sensor (light, force, potentiometer, …) with a linear calibration.

use x10_microcode::{Address, EventConfig, EventKind, Pin};

use crate::math::Calibration;
use crate::port::Sensor;
use crate::{Error, Link, Result};

/// An analog value crossing the window of [`AnalogSensor::watch_window`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Crossing {
    /// The raw value the board read when it saw the crossing.
    pub value: u16,
    /// True when the value is now inside the window, false when it left it.
    pub inside: bool,
}

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

    /// Asks the board to report whenever the value enters or leaves `low..=high` (an analog
    /// window event, `SYSTEM EVENT-ENABLE` on the port's pin A: a button's pin-change events
    /// on pin A of the same port would share that pin's setting). The board samples the input
    /// itself; [`AnalogSensor::wait_crossing`] then awaits the crossings without polling.
    ///
    /// # Errors
    /// [`Error::Link`] (`Status(bad_argument)` for `low > high`).
    pub async fn watch_window(&self, low: u16, high: u16) -> Result<()> {
        let config = EventConfig {
            analog_window: true,
            low,
            high,
            ..EventConfig::OFF
        };
        self.sensor.enable_events(Pin::A, config).await
    }

    /// Stops the window events.
    ///
    /// # Errors
    /// [`Error::Link`].
    pub async fn unwatch(&self) -> Result<()> {
        self.sensor.enable_events(Pin::A, EventConfig::OFF).await
    }

    /// Waits for the next crossing of the window set with [`AnalogSensor::watch_window`].
    ///
    /// # Errors
    /// [`Error::Link`]; `Link(BadReply)` for an event whose payload is not a window
    /// event's.
    pub async fn wait_crossing(&self) -> Result<Crossing> {
        loop {
            let ev = self.sensor.wait_event(Pin::A).await?;
            if ev.kind != EventKind::AnalogThreshold {
                continue;
            }
            return match ev.value.as_slice() {
                [a, b, inside] => Ok(Crossing {
                    value: u16::from_le_bytes([*a, *b]),
                    inside: *inside != 0,
                }),
                _ => Err(Error::Link(crate::LinkError::BadReply)),
            };
        }
    }
}
