//! An NTC thermistor in a voltage divider on a sensor port's analog input.

use x10_microcode::Address;

use crate::error::{Quantity, RangeError};
use crate::math::{check_adc_bits, divider_resistance, Divider, SteinhartHart};
use crate::port::Sensor;
use crate::units::{Celsius, Fahrenheit, Kelvin};
use crate::{Link, Result};

/// How a thermistor is wired and what it is made of.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThermistorConfig {
    coefficients: SteinhartHart,
    fixed_ohms: u32,
    adc_bits: u8,
    divider: Divider,
}

impl ThermistorConfig {
    /// The thesis's setup (Figures 3.11, 4.5): a 10 kΩ NTC thermistor with
    /// [`SteinhartHart::THESIS`], from the supply to the input, a 10 kΩ fixed resistor to
    /// ground ([`Divider::ThermistorHigh`]), read by a 10-bit ADC (full scale 1024).
    pub const THESIS: ThermistorConfig = ThermistorConfig {
        coefficients: SteinhartHart::THESIS,
        fixed_ohms: 10_000,
        adc_bits: 10,
        divider: Divider::ThermistorHigh,
    };

    /// A configuration.
    ///
    /// # Errors
    /// [`RangeError`] for a fixed resistor of 0 Ω ([`Quantity::SeriesResistor`]) or an ADC
    /// resolution outside 2–16 bits ([`Quantity::AdcBits`]).
    pub const fn new(
        coefficients: SteinhartHart,
        fixed_ohms: u32,
        adc_bits: u8,
        divider: Divider,
    ) -> core::result::Result<ThermistorConfig, RangeError> {
        if fixed_ohms == 0 {
            return Err(RangeError {
                quantity: Quantity::SeriesResistor,
                value: 0,
                min: 1,
                max: i32::MAX,
            });
        }
        if let Err(e) = check_adc_bits(adc_bits) {
            return Err(e);
        }
        Ok(ThermistorConfig {
            coefficients,
            fixed_ohms,
            adc_bits,
            divider,
        })
    }

    /// The Steinhart–Hart coefficients.
    pub const fn coefficients(&self) -> SteinhartHart {
        self.coefficients
    }

    /// The divider's fixed resistor in ohms.
    pub const fn fixed_ohms(&self) -> u32 {
        self.fixed_ohms
    }

    /// The ADC resolution in bits.
    pub const fn adc_bits(&self) -> u8 {
        self.adc_bits
    }

    /// The divider wiring.
    pub const fn divider(&self) -> Divider {
        self.divider
    }

    /// Raw ADC value → thermistor resistance in ohms.
    ///
    /// # Errors
    /// [`crate::Error::ReadingOutOfRange`] for 0, full scale (`2^bits − 1`) and above.
    pub fn resistance(&self, raw: u16) -> Result<f32> {
        divider_resistance(raw, self.adc_bits, self.fixed_ohms, self.divider)
    }

    /// Raw ADC value → temperature.
    ///
    /// # Errors
    /// As [`ThermistorConfig::resistance`].
    pub fn kelvin(&self, raw: u16) -> Result<Kelvin> {
        Ok(self.coefficients.kelvin(self.resistance(raw)?))
    }
}

/// A thermistor on the analog input of a sensor port (thesis `Thermistor`, Figure 4.5): one
/// `ANALOG READ` per reading, the rest is [`ThermistorConfig`] arithmetic.
#[derive(Clone, Debug)]
pub struct Thermistor<L> {
    sensor: Sensor<L>,
    config: ThermistorConfig,
}

impl<L: Link> Thermistor<L> {
    /// A thermistor wired as the thesis's ([`ThermistorConfig::THESIS`]) on sensor port
    /// `number` (from 1) of board `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Self::with_config(link, db, number, ThermistorConfig::THESIS)
    }

    /// A thermistor with its own configuration.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn with_config(link: L, db: Address, number: u8, config: ThermistorConfig) -> Result<Self> {
        Ok(Thermistor {
            sensor: Sensor::new(link, db, number)?,
            config,
        })
    }

    /// The sensor port.
    pub fn sensor(&self) -> &Sensor<L> {
        &self.sensor
    }

    /// The configuration.
    pub fn config(&self) -> &ThermistorConfig {
        &self.config
    }

    /// One raw ADC reading.
    ///
    /// # Errors
    /// [`crate::Error::Link`].
    pub async fn read_raw(&self) -> Result<u16> {
        self.sensor.read_analog().await
    }

    /// The temperature in kelvin.
    ///
    /// # Errors
    /// [`crate::Error::Link`]; [`crate::Error::ReadingOutOfRange`] for a reading on a rail
    /// (0: thermistor open or unplugged; full scale: shorted) or above full scale.
    pub async fn kelvin(&self) -> Result<Kelvin> {
        self.config.kelvin(self.read_raw().await?)
    }

    /// The temperature in degrees Celsius (thesis `readThermistorCelsius`).
    ///
    /// # Errors
    /// As [`Thermistor::kelvin`].
    pub async fn celsius(&self) -> Result<Celsius> {
        Ok(self.kelvin().await?.to_celsius())
    }

    /// The temperature in degrees Fahrenheit (thesis `readThermistorFahrenheit`).
    ///
    /// # Errors
    /// As [`Thermistor::kelvin`].
    pub async fn fahrenheit(&self) -> Result<Fahrenheit> {
        Ok(self.celsius().await?.to_fahrenheit())
    }
}
