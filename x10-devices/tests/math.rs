//! The drivers' arithmetic, from raw numbers.

use x10_devices::math::{
    divider_resistance, echo_to_distance, ramp_next, servo_pulse_us, usable_raw_range, Debouncer,
};
use x10_devices::{
    Calibration, Celsius, Divider, Duty, Error, Fahrenheit, Kelvin, Millimetres, Percent, Quantity,
    RangeError, Speed, SteinhartHart, ThermistorConfig,
};

/// Reference values computed independently with CPython 3.11.7's `math` module (double
/// precision), by this script (run here with `python3 therm.py`):
///
/// ```python
/// import math
/// A,B,C=0.001129148,0.000234125,0.0000000876741
/// def high(raw,bits=10,rf=10000): fs=2**bits; return rf*(fs-raw)/raw
/// def low(raw,bits=10,rf=10000): fs=2**bits; return rf*raw/(fs-raw)
/// def sh(r): L=math.log(r); return 1/(A+B*L+C*L**3)
/// for raw in [1,100,256,512,700,1000,1022]:
///     r=high(raw); k=sh(r); c=k-273.15; f=c*9/5+32
///     print(f"high raw={raw} R={r:.6f} K={k:.6f} C={c:.6f} F={f:.6f}")
/// for raw in [300,512]:
///     r=low(raw); k=sh(r); c=k-273.15
///     print(f"low raw={raw} R={r:.6f} C={c:.6f}")
/// raw=2048; r=high(raw,12,4700); print(f"high12 raw={raw} rf=4700 R={r:.6f} C={sh(r)-273.15:.6f}")
/// ```
///
/// Output (raw, R in Ω, K, °C, °F):
const THESIS_TABLE: [(u16, f64, f64, f64, f64); 7] = [
    (1, 10230000.0, 189.508764, -83.641236, -118.554224),
    (100, 92400.0, 253.990164, -19.159836, -2.487705),
    (256, 30000.0, 274.816974, 1.666974, 35.000553),
    (512, 10000.0, 298.149668, 24.999668, 76.999403),
    (700, 4628.571429, 316.668688, 43.518688, 110.333638),
    (1000, 240.0, 412.076162, 138.926162, 282.067091),
    (1022, 19.569472, 547.125259, 273.975259, 525.155466),
];

fn close(got: f32, want: f64, tol: f64) {
    assert!(
        (got as f64 - want).abs() <= tol,
        "got {got}, want {want} ± {tol}"
    );
}

#[test]
fn thermistor_thesis_setup_matches_python() {
    let cfg = ThermistorConfig::THESIS;
    for (raw, ohms, k, c, f) in THESIS_TABLE {
        close(cfg.resistance(raw).unwrap(), ohms, ohms * 1e-6);
        let kelvin = cfg.kelvin(raw).unwrap();
        // f32 arithmetic: a few millikelvin at most.
        close(kelvin.0, k, 0.005);
        close(kelvin.to_celsius().0, c, 0.005);
        close(kelvin.to_celsius().to_fahrenheit().0, f, 0.01);
    }
}

#[test]
fn thermistor_low_side_and_other_resolutions() {
    let low =
        ThermistorConfig::new(SteinhartHart::THESIS, 10_000, 10, Divider::ThermistorLow).unwrap();
    close(low.resistance(300).unwrap(), 4143.646409, 0.01);
    close(low.kelvin(300).unwrap().to_celsius().0, 46.347291, 0.005);
    close(low.kelvin(512).unwrap().to_celsius().0, 24.999668, 0.005);
    let twelve =
        ThermistorConfig::new(SteinhartHart::THESIS, 4_700, 12, Divider::ThermistorHigh).unwrap();
    close(twelve.resistance(2048).unwrap(), 4700.0, 1e-3);
    close(
        twelve.kelvin(2048).unwrap().to_celsius().0,
        43.130793,
        0.005,
    );
}

#[test]
fn thermistor_rails_are_errors_not_infinities() {
    // 0 would divide by zero (open thermistor); 1023 is the 10-bit full-scale code
    // (saturated or shorted); anything above cannot come from a 10-bit ADC.
    for raw in [0u16, 1023, 1024, 65535] {
        assert_eq!(
            divider_resistance(raw, 10, 10_000, Divider::ThermistorHigh),
            Err(Error::ReadingOutOfRange {
                raw,
                min: 1,
                max: 1022
            })
        );
        assert_eq!(
            ThermistorConfig::THESIS.kelvin(raw),
            Err(Error::ReadingOutOfRange {
                raw,
                min: 1,
                max: 1022
            })
        );
    }
    assert_eq!(usable_raw_range(10), (1, 1022));
    assert_eq!(usable_raw_range(12), (1, 4094));
    assert_eq!(usable_raw_range(16), (1, 65534));
}

#[test]
fn thesis_figure_3_11_divider_is_off_by_ten() {
    // Figure 3.11 writes R = 1024000/raw − 10000, Figure 4.5 and the appendix 10240000/raw −
    // 10000. For the thesis's circuit R = 10 kΩ · (1024 − raw) / raw = 10240000/raw − 10000:
    // at mid scale (512) the thermistor equals the fixed resistor. Figure 3.11's version
    // gives −8000 Ω there (the logarithm of a negative number).
    let r = ThermistorConfig::THESIS.resistance(512).unwrap();
    assert_eq!(r, 10_000.0);
    assert_eq!(10_240_000 / 512 - 10_000, 10_000);
    assert_eq!(1_024_000 / 512 - 10_000, -8_000);
}

#[test]
fn thermistor_config_rejects_nonsense() {
    let e = ThermistorConfig::new(SteinhartHart::THESIS, 0, 10, Divider::ThermistorHigh);
    assert_eq!(
        e,
        Err(RangeError {
            quantity: Quantity::SeriesResistor,
            value: 0,
            min: 1,
            max: i32::MAX
        })
    );
    for bits in [0u8, 1, 17] {
        let e = ThermistorConfig::new(SteinhartHart::THESIS, 10_000, bits, Divider::ThermistorHigh);
        assert_eq!(
            e,
            Err(RangeError {
                quantity: Quantity::AdcBits,
                value: bits as i32,
                min: 2,
                max: 16
            })
        );
    }
}

#[test]
fn temperature_units() {
    assert_eq!(Kelvin(273.15).to_celsius(), Celsius(0.0));
    assert_eq!(Celsius(100.0).to_fahrenheit(), Fahrenheit(212.0));
    assert_eq!(Celsius(-40.0).to_fahrenheit(), Fahrenheit(-40.0));
    assert_eq!(Fahrenheit(212.0).to_celsius(), Celsius(100.0));
}

#[test]
fn speed_percent_duty() {
    assert_eq!(Speed::new(100).unwrap(), Speed::FULL_FORWARD);
    assert_eq!(Speed::new(-100).unwrap(), Speed::FULL_REVERSE);
    for bad in [101i8, 127, -101, -128] {
        assert_eq!(
            Speed::new(bad),
            Err(RangeError {
                quantity: Quantity::Speed,
                value: bad as i32,
                min: -100,
                max: 100
            })
        );
    }
    assert_eq!(
        Speed::new(-37).unwrap().magnitude(),
        Percent::new(37).unwrap()
    );
    assert_eq!(Speed::reverse(Percent::new(37).unwrap()).percent(), -37);
    assert_eq!(Speed::forward(Percent::FULL), Speed::FULL_FORWARD);
    assert_eq!(
        Percent::new(101),
        Err(RangeError {
            quantity: Quantity::Percent,
            value: 101,
            min: 0,
            max: 100
        })
    );
    // The thesis's 255 * power / 100, rounded down.
    let duty = |p: u8| Duty::from_percent(Percent::new(p).unwrap()).get();
    assert_eq!(
        (duty(0), duty(1), duty(50), duty(99), duty(100)),
        (0, 2, 127, 252, 255)
    );
}

#[test]
fn ramp_steps_and_stops_at_zero_when_reversing() {
    let s = |p: i8| Speed::new(p).unwrap();
    let step = |p: u8| Percent::new(p).unwrap();
    assert_eq!(ramp_next(s(0), s(100), step(30)), s(30));
    assert_eq!(ramp_next(s(90), s(100), step(30)), s(100));
    assert_eq!(ramp_next(s(100), s(10), step(30)), s(70));
    assert_eq!(ramp_next(s(20), s(-50), step(30)), s(0));
    assert_eq!(ramp_next(s(0), s(-50), step(30)), s(-30));
    assert_eq!(ramp_next(s(-30), s(-50), step(30)), s(-50));
    assert_eq!(ramp_next(s(-100), s(100), step(100)), s(0));
    assert_eq!(ramp_next(s(42), s(42), step(5)), s(42));
}

#[test]
fn servo_pulse() {
    assert_eq!(servo_pulse_us(0, 1000, 2000, 180), 1000);
    assert_eq!(servo_pulse_us(90, 1000, 2000, 180), 1500);
    assert_eq!(servo_pulse_us(180, 1000, 2000, 180), 2000);
    // 1000 · 1 / 180 = 5.56 → 6 (nearest).
    assert_eq!(servo_pulse_us(1, 1000, 2000, 180), 1006);
    assert_eq!(servo_pulse_us(45, 500, 2500, 270), 833);
}

#[test]
fn echo_distance() {
    // 343 m/s: 1000 µs there and back is 171.5 mm → 171.
    assert_eq!(echo_to_distance(1000, 343), Millimetres(171));
    assert_eq!(echo_to_distance(0, 343), Millimetres(0));
    assert_eq!(echo_to_distance(23_324, 343), Millimetres(4000));
    assert_eq!(echo_to_distance(u32::MAX, 343), Millimetres(736_586_891));
}

#[test]
fn calibration() {
    assert_eq!(Calibration::RAW.apply(700), 700.0);
    // A force sensor: 100 counts at 0 N, 900 counts at 20 N.
    let c = Calibration::two_point((100, 0.0), (900, 20.0)).unwrap();
    assert_eq!(c.scale, 0.025);
    assert_eq!(c.offset, -2.5);
    assert_eq!(c.apply(500), 10.0);
    assert_eq!(
        Calibration::two_point((5, 1.0), (5, 2.0)),
        Err(RangeError {
            quantity: Quantity::CalibrationSpan,
            value: 0,
            min: 1,
            max: 65535
        })
    );
    assert_eq!(Calibration::linear(2.0, 1.0).apply(3), 7.0);
}

#[test]
fn debouncer_needs_consecutive_agreeing_samples() {
    let mut d = Debouncer::new(3, false).unwrap();
    let seq = [
        true, true, false, true, true, true, false, true, false, false, false,
    ];
    let want = [
        false, false, false, false, false, true, true, true, true, true, false,
    ];
    for (i, (s, w)) in seq.iter().zip(want).enumerate() {
        assert_eq!(d.update(*s), w, "sample {i}");
    }
    let mut one = Debouncer::new(1, false).unwrap();
    assert!(one.update(true));
    assert!(!one.update(false));
    assert_eq!(
        Debouncer::new(0, false),
        Err(RangeError {
            quantity: Quantity::DebounceSamples,
            value: 0,
            min: 1,
            max: 32
        })
    );
    assert!(Debouncer::new(33, false).is_err());
}
