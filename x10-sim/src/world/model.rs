//! The device models' arithmetic: scripted signals evaluated over virtual time, a thermistor's
//! ADC reading at a temperature, an ultrasonic echo's width at a distance.

use x10_devices::math::usable_raw_range;
use x10_devices::{Divider, ThermistorConfig};

use super::{DigitalSignal, Signal};
use crate::ports::Digital;

/// A point of a signal: (t_us, value).
type Point = (u64, f64);

/// The segment of a time-ordered point list around `t_us`: the last point at or before
/// `t_us`, and the next one when it lies strictly after `t_us`.
fn around(points: &[Point], t_us: u64) -> Option<(Point, Option<Point>)> {
    let i = points.iter().rposition(|(t, _)| *t <= t_us);
    match i {
        // Before the first point: its value.
        None => points.first().map(|p| (*p, None)),
        Some(i) => {
            let p = points.get(i).copied()?;
            Some((p, points.get(i + 1).copied().filter(|n| n.0 > t_us)))
        }
    }
}

impl Signal {
    /// The value at `t_us` in floating point (`f64`): what plots and summaries show.
    pub fn value_at_us(&self, t_us: u64) -> f64 {
        match self {
            Signal::Const(v) => *v,
            Signal::Steps(points) => around(points, t_us).map_or(0.0, |(p, _)| p.1),
            Signal::Linear(points) => match around(points, t_us) {
                None => 0.0,
                Some((p, None)) => p.1,
                Some(((t0, v0), Some((t1, v1)))) => {
                    v0 + (v1 - v0) * ((t_us - t0) as f64 / (t1 - t0) as f64)
                }
            },
        }
    }

    /// The value at `t_us` as ADC counts: whole numbers (the world checks that every value
    /// is), a linear segment interpolated in integers and rounded towards its start value,
    /// so `200 → 900` over 2 s is `200 + 700·dt/2 s` rounded down.
    pub fn counts_at_us(&self, t_us: u64) -> u16 {
        let whole = |v: f64| v.round().clamp(0.0, f64::from(u16::MAX)) as i128;
        let v = match self {
            Signal::Const(v) => whole(*v),
            Signal::Steps(points) => around(points, t_us).map_or(0, |(p, _)| whole(p.1)),
            Signal::Linear(points) => match around(points, t_us) {
                None => 0,
                Some((p, None)) => whole(p.1),
                Some(((t0, v0), Some((t1, v1)))) => {
                    let (v0, v1) = (whole(v0), whole(v1));
                    let span = i128::from(t1 - t0);
                    v0 + (v1 - v0) * i128::from(t_us - t0) / span
                }
            },
        };
        u16::try_from(v.clamp(0, i128::from(u16::MAX))).unwrap_or(u16::MAX)
    }

    /// The value at `t_us` in `f32` (temperatures): a linear segment is
    /// `v0 + (v1 − v0) · ((t − t0) / (t1 − t0))`, every step in `f32`, as the thermistor
    /// driver computes.
    pub fn value_at_us_f32(&self, t_us: u64) -> f32 {
        match self {
            Signal::Const(v) => *v as f32,
            Signal::Steps(points) => around(points, t_us).map_or(0.0, |(p, _)| p.1 as f32),
            Signal::Linear(points) => match around(points, t_us) {
                None => 0.0,
                Some((p, None)) => p.1 as f32,
                Some(((t0, v0), Some((t1, v1)))) => {
                    let (v0, v1) = (v0 as f32, v1 as f32);
                    v0 + (v1 - v0) * ((t_us - t0) as f32 / (t1 - t0) as f32)
                }
            },
        }
    }

    /// The instants (µs) where the signal has a breakpoint, in order.
    pub fn breakpoints_us(&self) -> Vec<u64> {
        match self {
            Signal::Const(_) => Vec::new(),
            Signal::Steps(p) | Signal::Linear(p) => p.iter().map(|(t, _)| *t).collect(),
        }
    }

    /// The smallest and largest value the signal takes.
    pub fn range(&self) -> (f64, f64) {
        match self {
            Signal::Const(v) => (*v, *v),
            Signal::Steps(p) | Signal::Linear(p) => p
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, v)| {
                    (lo.min(*v), hi.max(*v))
                }),
        }
    }
}

impl DigitalSignal {
    /// The script of the pin: `active_low` inverts every level (a button pulled up, pressed
    /// to ground).
    pub fn to_digital(&self, active_low: bool) -> Digital {
        match self {
            DigitalSignal::Const(v) => Digital::Const(*v ^ active_low),
            DigitalSignal::Toggles { initial, at_ms } => Digital::Toggles {
                initial: *initial ^ active_low,
                toggles_ms: at_ms.clone(),
            },
            DigitalSignal::Presses(presses) => Digital::Toggles {
                initial: active_low,
                toggles_ms: presses
                    .iter()
                    .flat_map(|(at, d)| [*at, at.saturating_add(*d)])
                    .collect(),
            },
            DigitalSignal::Pulses {
                first_us,
                period_us,
                width_us,
            } => Digital::Train {
                // `active_low` pulse trains are refused by the world's checks: a train of low
                // pulses is not a `Digital` script.
                first_us: *first_us,
                period_us: *period_us,
                width_us: *width_us,
            },
        }
    }

    /// The logical level (pressed, high) at `t_ns`, before any inversion.
    pub fn level_at_ns(&self, t_ns: u64) -> bool {
        self.to_digital(false).level_at(t_ns)
    }
}

/// The raw ADC reading of a thermistor wired as `config` at `celsius`: of the usable
/// readings, the one whose temperature (converted by the driver's own arithmetic,
/// [`ThermistorConfig::kelvin`]) is closest; on a tie, the warmer one for
/// [`Divider::ThermistorHigh`]. Below or above what the divider can show it is the end of
/// the usable range.
///
/// For [`ThermistorConfig::THESIS`] it is the reference of the thesis scenarios exactly
/// (`x10-sim/tests/scenario`, checked in `tests/world.rs`).
pub fn thermistor_raw(config: &ThermistorConfig, celsius: f32) -> u16 {
    let (min, max) = usable_raw_range(config.adc_bits());
    // A key that rises with the raw value, and the target on the same scale.
    let rising = config.divider() == Divider::ThermistorHigh;
    let key = |raw: u16| {
        config
            .kelvin(raw)
            .ok()
            .map(|k| k.0 - 273.15)
            .map(|t| if rising { t } else { -t })
    };
    let target = if rising { celsius } else { -celsius };
    let (mut lo, mut hi) = (min, max);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        match key(mid) {
            Some(t) if t < target => lo = mid + 1,
            _ => hi = mid,
        }
    }
    // lo is the first raw at or above the target; take the closer neighbour.
    let above = key(lo).unwrap_or(f32::MAX);
    let below = lo
        .checked_sub(1)
        .filter(|r| *r >= min)
        .and_then(key)
        .unwrap_or(f32::MIN);
    if (above - target).abs() <= (target - below).abs() {
        lo
    } else {
        lo - 1
    }
}

/// The width in µs of the echo from an obstacle `mm` away, sound at `speed_m_s`: the time
/// there and back, `2·mm / speed`, rounded up so that the driver's conversion
/// (`µs · speed / 2000`, rounded down, [`x10_devices::math::echo_to_distance`]) gives back
/// the whole millimetres of `mm`. At least 1 µs; at most `u16::MAX` µs (65 ms, far beyond
/// any sensor's timeout).
pub fn echo_width_us(mm: f64, speed_m_s: u16) -> u16 {
    let speed = f64::from(speed_m_s.max(1));
    // µs = mm · 2000 / speed. Rounding up on the exact value: the product of whole
    // millimetres and 2000 is exact in f64, so is its ceiling quotient.
    let us = (mm.max(0.0).floor() * 2000.0 / speed).ceil();
    us.clamp(1.0, f64::from(u16::MAX)) as u16
}

#[cfg(test)]
mod tests {
    use super::*;
    use x10_devices::math::echo_to_distance;
    use x10_devices::SteinhartHart;

    #[test]
    fn a_low_side_thermistor_reads_back_its_temperature() {
        let cfg = ThermistorConfig::new(SteinhartHart::THESIS, 10_000, 12, Divider::ThermistorLow)
            .unwrap();
        for c in [-20.0f32, 0.0, 25.0, 60.0, 100.0] {
            let raw = thermistor_raw(&cfg, c);
            let back = cfg.kelvin(raw).unwrap().0 - 273.15;
            assert!((back - c).abs() < 0.2, "{c} -> {raw} -> {back}");
        }
        assert!(thermistor_raw(&cfg, 0.0) > thermistor_raw(&cfg, 50.0));
    }

    #[test]
    fn echo_widths_give_back_the_distance() {
        for mm in 0..5_000u32 {
            let us = echo_width_us(f64::from(mm), 343);
            assert_eq!(echo_to_distance(u32::from(us), 343).0, mm, "{mm}");
        }
        assert_eq!(echo_width_us(171.0, 343), 998);
        assert_eq!(echo_width_us(1e9, 343), u16::MAX);
    }

    #[test]
    fn signals_step_and_interpolate() {
        let s = Signal::Steps(vec![(0, 40.0), (3_600_000, 350.0), (4_200_000, 40.0)]);
        assert_eq!(
            [0, 3_599_999, 3_600_000, 4_199_999, 4_200_000].map(|t| s.counts_at_us(t)),
            [40, 40, 350, 350, 40]
        );
        let l = Signal::Linear(vec![(1_000, 100.0), (3_000, 300.0), (3_000, 50.0)]);
        assert_eq!(
            [0, 1_000, 2_000, 2_999, 3_000, 9_000].map(|t| l.counts_at_us(t)),
            [100, 100, 200, 299, 50, 50]
        );
        assert_eq!(l.value_at_us(1_500), 150.0);
        let down = Signal::Linear(vec![(0, 10.0), (3, 0.0)]);
        assert_eq!([0, 1, 2, 3].map(|t| down.counts_at_us(t)), [10, 7, 4, 0]);
        assert_eq!(l.range(), (50.0, 300.0));
    }
}
