//! Scripted signals over virtual time: numbers (counts, °C, mm) and digital levels.

/// A scripted number over virtual time (ADC counts, °C, mm). Times are µs from the start of
/// the run; the constructors take ms.
#[derive(Clone, Debug, PartialEq)]
pub enum Signal {
    /// Always this value.
    Const(f64),
    /// Piecewise constant: `(t_us, value)` in time order, each value from its time on; the
    /// first value also holds before its time.
    Steps(Vec<(u64, f64)>),
    /// Piecewise linear through `(t_us, value)` points in time order, constant before the
    /// first and after the last. Two points at the same time make a jump (the second value
    /// holds from that instant).
    Linear(Vec<(u64, f64)>),
}

impl Signal {
    /// Always `value`.
    pub fn constant(value: f64) -> Signal {
        Signal::Const(value)
    }

    /// Piecewise constant, from `(t_ms, value)` pairs.
    pub fn steps(points_ms: impl IntoIterator<Item = (u64, f64)>) -> Signal {
        Signal::Steps(ms_to_us(points_ms))
    }

    /// Piecewise linear, through `(t_ms, value)` points.
    pub fn linear(points_ms: impl IntoIterator<Item = (u64, f64)>) -> Signal {
        Signal::Linear(ms_to_us(points_ms))
    }

    /// A linear ramp from `from` at `start_ms` to `to` at `end_ms`, constant outside.
    pub fn ramp(from: f64, start_ms: u64, to: f64, end_ms: u64) -> Signal {
        Signal::linear([(start_ms, from), (end_ms, to)])
    }

    pub(super) fn points(&self) -> &[(u64, f64)] {
        match self {
            Signal::Const(_) => &[],
            Signal::Steps(p) | Signal::Linear(p) => p,
        }
    }

    /// The script in words: `40 counts, 350 from 3.6 s, 40 from 4.2 s`; `200 counts at 0 s,
    /// 900 at 2.5 s, linear in between`.
    pub fn describe(&self, unit: &str) -> String {
        let with_unit = |x: f64| format!("{} {unit}", format_number(x));
        match self {
            Signal::Const(x) => with_unit(*x),
            Signal::Steps(p) => {
                let parts: Vec<String> = p
                    .iter()
                    .enumerate()
                    .map(|(i, (t, x))| match i {
                        0 if *t == 0 => with_unit(*x),
                        0 => format!("{} (also before {})", with_unit(*x), short_seconds(*t)),
                        _ => format!("{} from {}", format_number(*x), short_seconds(*t)),
                    })
                    .collect();
                parts.join(", ")
            }
            Signal::Linear(p) => {
                let parts: Vec<String> = p
                    .iter()
                    .enumerate()
                    .map(|(i, (t, x))| {
                        let v = if i == 0 {
                            with_unit(*x)
                        } else {
                            format_number(*x)
                        };
                        format!("{v} at {}", short_seconds(*t))
                    })
                    .collect();
                format!("{}, linear in between", parts.join(", "))
            }
        }
    }
}

/// `0 s`, `0.5 s`, `1.234567 s` from µs.
pub(crate) fn short_seconds(t_us: u64) -> String {
    let whole = t_us / 1_000_000;
    let frac = t_us % 1_000_000;
    if frac == 0 {
        format!("{whole} s")
    } else {
        let digits = format!("{frac:06}");
        format!("{whole}.{} s", digits.trim_end_matches('0'))
    }
}

/// `40`, `-18`, `121.1`, `0.25`: whole numbers without decimals, others as short as they
/// round-trip.
fn format_number(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else {
        format!("{x}")
    }
}

fn ms_to_us(points_ms: impl IntoIterator<Item = (u64, f64)>) -> Vec<(u64, f64)> {
    points_ms
        .into_iter()
        .map(|(t, v)| (t.saturating_mul(1_000), v))
        .collect()
}

/// `1.234 s` from ns (ms resolution, rounded down).
pub(crate) fn seconds(t_ns: u64) -> String {
    let ms = t_ns / 1_000_000;
    format!("{}.{:03} s", ms / 1_000, ms % 1_000)
}

/// A scripted digital input over virtual time (the logical level: pressed, on, high).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DigitalSignal {
    /// Always this level.
    Const(bool),
    /// `initial`, then toggled at each time (ms, strictly increasing).
    Toggles {
        /// Level before the first toggle.
        initial: bool,
        /// Toggle times in ms.
        at_ms: Vec<u64>,
    },
    /// Low except during each `(at_ms, for_ms)` press (in time order, not overlapping, not
    /// touching).
    Presses(Vec<(u64, u64)>),
    /// High pulses `width_us` wide every `period_us` from `first_us` on.
    Pulses {
        /// Start of the first pulse (µs).
        first_us: u64,
        /// Period (µs).
        period_us: u64,
        /// Width (µs, less than the period).
        width_us: u64,
    },
}

impl DigitalSignal {
    /// The script in words: `pressed at 1 s for 50 ms, at 3 s for 50 ms`.
    pub fn describe(&self, on: &str, off: &str) -> String {
        let level = |v: bool| if v { on } else { off };
        match self {
            DigitalSignal::Const(v) => format!("always {}", level(*v)),
            DigitalSignal::Toggles { initial, at_ms } => {
                let times: Vec<String> = at_ms.iter().map(|t| short_seconds(t * 1_000)).collect();
                format!("{}, toggled at {}", level(*initial), times.join(", "))
            }
            DigitalSignal::Presses(p) => {
                let parts: Vec<String> = p
                    .iter()
                    .map(|(at, d)| format!("at {} for {d} ms", short_seconds(at * 1_000)))
                    .collect();
                format!("{on} {}", parts.join(", "))
            }
            DigitalSignal::Pulses {
                first_us,
                period_us,
                width_us,
            } => format!(
                "{on} for {} every {} from {}",
                short_seconds(*width_us),
                short_seconds(*period_us),
                short_seconds(*first_us)
            ),
        }
    }
}
