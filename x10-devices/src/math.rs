//! The arithmetic of the drivers, apart from any I/O, so that it is tested from raw numbers.
//!
//! Floating point is `f32`: boards without an FPU (Cortex-M0) emulate it, and `f64` emulation
//! is larger and slower for no gain at 10–16 ADC bits (against CPython's double-precision
//! results the thermistor is within 0.005 K, `tests/math.rs`). The logarithm comes from the
//! [`libm`] crate, because `no_std` has no `f32::ln`.

use crate::error::{Error, Quantity, RangeError};
use crate::units::{Kelvin, Millimetres, Percent, Speed};

/// Steinhart–Hart coefficients: `1/T = A + B·ln R + C·(ln R)³`, `T` in kelvin, `R` in ohms.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SteinhartHart {
    /// A.
    pub a: f32,
    /// B.
    pub b: f32,
    /// C.
    pub c: f32,
}

impl SteinhartHart {
    /// The thesis's coefficients (Figures 3.11 and 4.5, from the Arduino Playground
    /// thermistor example): a common 10 kΩ NTC thermistor.
    pub const THESIS: SteinhartHart = SteinhartHart {
        a: 0.001129148,
        b: 0.000234125,
        c: 0.0000000876741,
    };

    /// The temperature at resistance `ohms` (which must be positive and finite; the thermistor
    /// driver guarantees it).
    pub fn kelvin(&self, ohms: f32) -> Kelvin {
        let l = libm::logf(ohms);
        Kelvin(1.0 / (self.a + self.b * l + self.c * l * l * l))
    }
}

/// How a thermistor and its fixed resistor form the voltage divider the ADC reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Divider {
    /// Thermistor from the supply to the ADC input, fixed resistor from the input to ground
    /// (the thesis's circuit). `raw/2^bits = R_fixed / (R_fixed + R_t)`, so
    /// `R_t = R_fixed · (2^bits − raw) / raw`: the reading rises as the thermistor warms.
    ThermistorHigh,
    /// Fixed resistor from the supply to the ADC input, thermistor from the input to ground.
    /// `raw/2^bits = R_t / (R_fixed + R_t)`, so `R_t = R_fixed · raw / (2^bits − raw)`.
    ThermistorLow,
}

/// The raw values from which a divider's resistance can be computed: `1 ..= 2^bits − 2`.
/// 0 and the full-scale code `2^bits − 1` are the rails (an open or shorted thermistor, or a
/// saturated ADC), where the formula divides by zero or takes the logarithm of zero or loses
/// all precision.
pub const fn usable_raw_range(adc_bits: u8) -> (u16, u16) {
    let full = 1u32 << adc_bits;
    (1, (full - 2) as u16)
}

/// Checks an ADC resolution for [`divider_resistance`]: 2 to 16 bits.
///
/// # Errors
/// [`RangeError`] ([`Quantity::AdcBits`]) outside `2..=16`.
pub const fn check_adc_bits(adc_bits: u8) -> Result<(), RangeError> {
    RangeError::check(Quantity::AdcBits, adc_bits as i32, 2, 16)
}

/// The resistance of a divider's thermistor, in ohms, from a raw ADC value.
///
/// `adc_bits` must have passed [`check_adc_bits`].
///
/// # Errors
/// [`Error::ReadingOutOfRange`] when `raw` is outside [`usable_raw_range`].
pub fn divider_resistance(
    raw: u16,
    adc_bits: u8,
    fixed_ohms: u32,
    divider: Divider,
) -> Result<f32, Error> {
    let (min, max) = usable_raw_range(adc_bits);
    if raw < min || raw > max {
        return Err(Error::ReadingOutOfRange { raw, min, max });
    }
    let full = (1u32 << adc_bits) as f32;
    let raw = raw as f32;
    let fixed = fixed_ohms as f32;
    Ok(match divider {
        Divider::ThermistorHigh => fixed * (full - raw) / raw,
        Divider::ThermistorLow => fixed * raw / (full - raw),
    })
}

/// The next speed of a ramp from `current` towards `target`, moving at most `step`; a ramp
/// that changes direction stops at 0 on the way (one step ends there), so the motor never
/// jumps from one direction to the other.
pub fn ramp_next(current: Speed, target: Speed, step: Percent) -> Speed {
    let cur = current.percent() as i16;
    let tgt = target.percent() as i16;
    let aim = if cur * tgt < 0 { 0 } else { tgt };
    let step = step.get() as i16;
    let next = if aim > cur {
        (cur + step).min(aim)
    } else {
        (cur - step).max(aim)
    };
    // `next` lies between `cur` and `aim`, both in -100..=100.
    Speed::new(next as i8).unwrap_or(target)
}

/// The pulse width for `angle` on a servo that takes `min_us` at 0° and `max_us` at
/// `max_angle`, rounded to the nearest µs. Needs `angle <= max_angle`, `max_angle > 0` and
/// `min_us <= max_us` (the servo driver checks them; otherwise the result is clamped to
/// `max_us`).
pub fn servo_pulse_us(angle: u16, min_us: u16, max_us: u16, max_angle: u16) -> u16 {
    let span = max_us.saturating_sub(min_us) as u32;
    let max_angle = max_angle.max(1) as u32;
    let add = (span * angle as u32 + max_angle / 2) / max_angle;
    (min_us as u32 + add).min(max_us as u32) as u16
}

/// The distance to an obstacle from the width of an ultrasonic echo pulse: the sound travels
/// there and back, so `mm = µs · (m/s) / 2000`, rounded down. At 343 m/s (dry air, 20 °C),
/// 1 000 µs is 171 mm.
pub fn echo_to_distance(echo_us: u32, speed_of_sound_m_s: u16) -> Millimetres {
    let mm = echo_us as u64 * speed_of_sound_m_s as u64 / 2000;
    Millimetres(mm.min(u32::MAX as u64) as u32)
}

/// A linear calibration from raw ADC counts to a physical value: `value = offset + scale · raw`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Calibration {
    /// Units per raw count.
    pub scale: f32,
    /// Value at raw 0.
    pub offset: f32,
}

impl Calibration {
    /// The raw value itself.
    pub const RAW: Calibration = Calibration {
        scale: 1.0,
        offset: 0.0,
    };

    /// A calibration from its slope and intercept.
    pub const fn linear(scale: f32, offset: f32) -> Calibration {
        Calibration { scale, offset }
    }

    /// The line through two measured points `(raw, value)`.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::CalibrationSpan`]) when both points have the same raw value.
    pub fn two_point(p0: (u16, f32), p1: (u16, f32)) -> Result<Calibration, RangeError> {
        let span = p1.0 as i32 - p0.0 as i32;
        if span == 0 {
            return Err(RangeError {
                quantity: Quantity::CalibrationSpan,
                value: 0,
                min: 1,
                max: u16::MAX as i32,
            });
        }
        let scale = (p1.1 - p0.1) / span as f32;
        Ok(Calibration {
            scale,
            offset: p0.1 - scale * p0.0 as f32,
        })
    }

    /// The value for a raw reading.
    pub fn apply(&self, raw: u16) -> f32 {
        self.offset + self.scale * raw as f32
    }
}

/// A counting debouncer: the debounced state takes a new level only after `samples`
/// consecutive samples agree on it. The debounce window is therefore `samples` times the
/// polling interval.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Debouncer {
    samples: u8,
    state: bool,
    count: u8,
}

impl Debouncer {
    /// Largest number of samples.
    pub const MAX_SAMPLES: u8 = 32;

    /// A debouncer starting in `initial`.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::DebounceSamples`]) unless `1 <= samples <= 32`.
    pub const fn new(samples: u8, initial: bool) -> Result<Debouncer, RangeError> {
        match RangeError::check(
            Quantity::DebounceSamples,
            samples as i32,
            1,
            Self::MAX_SAMPLES as i32,
        ) {
            Ok(()) => Ok(Debouncer {
                samples,
                state: initial,
                count: 0,
            }),
            Err(e) => Err(e),
        }
    }

    /// Feeds one sample; returns the debounced state.
    pub fn update(&mut self, sample: bool) -> bool {
        if sample == self.state {
            self.count = 0;
        } else {
            self.count += 1;
            if self.count >= self.samples {
                self.state = sample;
                self.count = 0;
            }
        }
        self.state
    }

    /// The debounced state.
    pub const fn state(&self) -> bool {
        self.state
    }

    /// Samples needed to change state.
    pub const fn samples(&self) -> u8 {
        self.samples
    }
}
