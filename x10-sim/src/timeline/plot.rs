//! The timeline as a picture: one lane per device, time in seconds across, step plots for
//! levels, duties, angles and motor speeds, lines for scripted analog inputs. Plain SVG text,
//! and an HTML page around it.

use std::fmt::Write as _;
use std::path::Path;

use super::{summary, DeviceState, DeviceTimeline, MotorDirection, Timeline};
use crate::exec::Nanos;
use crate::sim::SimOutcome;
use crate::world::{seconds, DeviceKind, World};

const WIDTH: f64 = 1000.0;
const LABEL: f64 = 230.0;
const RIGHT: f64 = 24.0;
const TOP: f64 = 40.0;
const LANE: f64 = 62.0;
const PLOT_PAD: f64 = 18.0;
const PLOT_H: f64 = 34.0;
const AXIS: f64 = 44.0;
const LABEL_GAP: f64 = 64.0;

const OUTPUT: &str = "#1f6feb";
const INPUT: &str = "#1a7f37";
const BRAKE: &str = "#cf222e";

/// `&`, `<`, `>`, `"` and `'` escaped for XML text and attributes.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// A tick interval (s) that gives at most 10 intervals over `end_s`.
fn tick_step(end_s: f64) -> f64 {
    let mut step = 0.001;
    for _ in 0..30 {
        for m in [1.0, 2.0, 5.0] {
            if end_s / (step * m) <= 10.0 {
                return step * m;
            }
        }
        step *= 10.0;
    }
    step
}

fn tick_label(t: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else if step >= 0.1 {
        1
    } else if step >= 0.01 {
        2
    } else {
        3
    };
    let text = format!("{t:.decimals$}");
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        &text
    };
    format!("{text} s")
}

/// How a lane scales its values: `lo..hi` over the plot height.
struct Scale {
    lo: f64,
    hi: f64,
    /// Shown in the label column.
    text: String,
}

fn number(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.1}")
    }
}

/// A state as a plotted value (`None`: nothing to draw).
fn value(s: &DeviceState) -> Option<f64> {
    match s {
        DeviceState::Motor(m) => Some(f64::from(m.signed_percent())),
        DeviceState::Level(v) => Some(if *v { 1.0 } else { 0.0 }),
        DeviceState::Duty { percent, .. } => Some(f64::from(*percent)),
        DeviceState::Servo(a) => a.map(f64::from),
        DeviceState::Counts(c) => Some(f64::from(*c)),
        DeviceState::Celsius(c) => Some(f64::from(*c)),
        DeviceState::Distance(mm) => Some(*mm),
    }
}

/// A short label for a change.
fn short(d: &DeviceTimeline, s: &DeviceState) -> String {
    match s {
        DeviceState::Motor(m) => match m.direction {
            MotorDirection::Forward => format!("fwd {} %", m.duty_percent),
            MotorDirection::Reverse => format!("rev {} %", m.duty_percent),
            MotorDirection::Brake => "brake".to_string(),
            MotorDirection::Coast => "stop".to_string(),
        },
        DeviceState::Duty { percent, .. } => format!("{percent} %"),
        _ => d.words(s),
    }
}

fn scale_of(d: &DeviceTimeline) -> Scale {
    let kind = d.device.kind();
    let level = |on: &str, off: &str| Scale {
        lo: 0.0,
        hi: 1.0,
        text: format!("{off} / {on}"),
    };
    let analog = |signal: &crate::world::Signal, unit: &str| {
        let (lo, hi) = signal.range();
        if hi > lo {
            Scale {
                lo,
                hi,
                text: format!("{} … {} {unit}", number(lo), number(hi)),
            }
        } else {
            // A constant: drawn across the middle.
            Scale {
                lo: lo - 1.0,
                hi: hi + 1.0,
                text: format!("constant {} {unit}", number(lo)),
            }
        }
    };
    match kind {
        DeviceKind::DcMotor => Scale {
            lo: -100.0,
            hi: 100.0,
            text: "reverse 100 % … forward 100 %".to_string(),
        },
        DeviceKind::Led {
            dimmable: false, ..
        }
        | DeviceKind::Switch { .. } => level("on", "off"),
        DeviceKind::Button { .. } => level("pressed", "released"),
        DeviceKind::DigitalOutput { .. } | DeviceKind::DigitalInput { .. } => level("high", "low"),
        DeviceKind::Led { .. } | DeviceKind::PwmOutput { .. } => Scale {
            lo: 0.0,
            hi: 100.0,
            text: "duty 0 … 100 %".to_string(),
        },
        DeviceKind::Servo { config, .. } => Scale {
            lo: 0.0,
            hi: f64::from(config.max_angle()),
            text: format!("0 … {}°", config.max_angle()),
        },
        DeviceKind::LightSensor { counts }
        | DeviceKind::ForceSensor { counts }
        | DeviceKind::AnalogInput { counts } => analog(counts, "counts"),
        DeviceKind::Thermistor { celsius, .. } => analog(celsius, "°C"),
        DeviceKind::Ultrasonic { distance_mm, .. } => analog(distance_mm, "mm"),
    }
}

impl Timeline {
    fn x(&self, t_ns: Nanos) -> f64 {
        let end = self.end_ns.max(1) as f64;
        LABEL + (WIDTH - LABEL - RIGHT) * (t_ns.min(self.end_ns) as f64 / end)
    }

    /// The timeline as an SVG picture titled `title`.
    pub fn svg(&self, title: &str) -> String {
        let n = self.devices.len() as f64;
        let height = TOP + LANE * n + AXIS;
        let plot_right = WIDTH - RIGHT;
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH:.0}" height="{height:.0}" viewBox="0 0 {WIDTH:.0} {height:.0}" font-family="DejaVu Sans, Verdana, sans-serif">"#
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="12" y="24" font-size="15" font-weight="bold">{}</text>"#,
            escape(title)
        );
        // Lanes.
        for (i, d) in self.devices.iter().enumerate() {
            let y0 = TOP + LANE * i as f64;
            let fill = if i % 2 == 0 { "#f6f8fa" } else { "#ffffff" };
            let _ = writeln!(
                s,
                r#"<rect x="0" y="{y0:.1}" width="{WIDTH:.0}" height="{LANE:.0}" fill="{fill}"/>"#
            );
            self.lane(&mut s, d, y0);
        }
        // Time axis and grid.
        let axis_y = TOP + LANE * n + 6.0;
        let end_s = self.end_ns as f64 / 1e9;
        let step = tick_step(end_s);
        let _ = writeln!(
            s,
            r##"<line x1="{LABEL:.1}" y1="{axis_y:.1}" x2="{plot_right:.1}" y2="{axis_y:.1}" stroke="#57606a"/>"##
        );
        let mut k = 0u32;
        loop {
            let t = step * f64::from(k);
            if t > end_s + step * 1e-6 {
                break;
            }
            let x = self.x((t * 1e9).round() as Nanos);
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{TOP:.1}" x2="{x:.1}" y2="{axis_y:.1}" stroke="#d0d7de" stroke-dasharray="2,3"/>"##
            );
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{axis_y:.1}" x2="{x:.1}" y2="{:.1}" stroke="#57606a"/>"##,
                axis_y + 5.0
            );
            let _ = writeln!(
                s,
                r##"<text x="{x:.1}" y="{:.1}" font-size="11" text-anchor="middle" fill="#24292f">{}</text>"##,
                axis_y + 18.0,
                tick_label(t, step)
            );
            k += 1;
        }
        let _ = writeln!(
            s,
            r##"<text x="{plot_right:.1}" y="{:.1}" font-size="11" text-anchor="end" fill="#57606a">virtual time</text>"##,
            axis_y + 34.0
        );
        s.push_str("</svg>\n");
        s
    }

    fn lane(&self, s: &mut String, d: &DeviceTimeline, y0: f64) {
        let scale = scale_of(d);
        let top = y0 + PLOT_PAD;
        let bottom = top + PLOT_H;
        let y = |v: f64| {
            let span = (scale.hi - scale.lo).max(f64::MIN_POSITIVE);
            bottom - (v.clamp(scale.lo, scale.hi) - scale.lo) / span * PLOT_H
        };
        let is_input = d.script().is_some();
        let colour = if is_input { INPUT } else { OUTPUT };
        let _ = writeln!(
            s,
            r##"<text x="12" y="{:.1}" font-size="13" font-weight="bold" fill="#24292f">{}</text>"##,
            y0 + 19.0,
            escape(d.device.name())
        );
        let _ = writeln!(
            s,
            r##"<text x="12" y="{:.1}" font-size="10" fill="#57606a">{}</text>"##,
            y0 + 34.0,
            escape(&d.description())
        );
        let _ = writeln!(
            s,
            r##"<text x="12" y="{:.1}" font-size="10" fill="#57606a">{}{}</text>"##,
            y0 + 48.0,
            if is_input { "scripted · " } else { "" },
            escape(&scale.text)
        );
        // Zero line of a motor, base line of the rest.
        let base = if matches!(d.device.kind(), DeviceKind::DcMotor) {
            y(0.0)
        } else {
            bottom
        };
        let _ = writeln!(
            s,
            r##"<line x1="{LABEL:.1}" y1="{base:.1}" x2="{:.1}" y2="{base:.1}" stroke="#8c959f" stroke-width="0.6"/>"##,
            WIDTH - RIGHT
        );
        let analog = matches!(
            d.device.kind(),
            DeviceKind::LightSensor { .. }
                | DeviceKind::ForceSensor { .. }
                | DeviceKind::AnalogInput { .. }
                | DeviceKind::Thermistor { .. }
                | DeviceKind::Ultrasonic { .. }
        );
        if analog {
            // One sample per pixel column of the script.
            let columns = (WIDTH - LABEL - RIGHT) as u64;
            let mut path = String::new();
            for c in 0..=columns {
                let t = self.end_ns.saturating_mul(c) / columns.max(1);
                if let Some(v) = value(&d.track.at_ns(t)) {
                    let cmd = if path.is_empty() { 'M' } else { 'L' };
                    let _ = write!(path, "{cmd}{:.1},{:.1} ", self.x(t), y(v));
                }
            }
            let _ = writeln!(
                s,
                r#"<path d="{}" fill="none" stroke="{colour}" stroke-width="1.6"/>"#,
                path.trim_end()
            );
            return;
        }
        // Step plot: segments of constant state.
        let mut segments: Vec<(Nanos, Nanos, DeviceState)> = Vec::new();
        let mut start = 0;
        let mut state = d.track.initial();
        for (t, next) in d.track.changes() {
            let t = (*t).min(self.end_ns);
            segments.push((start, t, state));
            start = t;
            state = *next;
        }
        segments.push((start, self.end_ns, state));
        let mut line = String::new();
        let mut area = String::new();
        let mut last_y: Option<f64> = None;
        for (a, b, st) in &segments {
            let (xa, xb) = (self.x(*a), self.x(*b));
            if let DeviceState::Motor(m) = st {
                if m.direction == MotorDirection::Brake && xb > xa {
                    let _ = writeln!(
                        s,
                        r#"<rect x="{xa:.1}" y="{top:.1}" width="{:.1}" height="{PLOT_H:.1}" fill="{BRAKE}" fill-opacity="0.25"/>"#,
                        xb - xa
                    );
                }
            }
            match value(st) {
                Some(v) => {
                    let yv = y(v);
                    if last_y.is_some() {
                        let _ = write!(line, "L{xa:.1},{yv:.1} ");
                    } else {
                        let _ = write!(line, "M{xa:.1},{yv:.1} ");
                    }
                    let _ = write!(line, "L{xb:.1},{yv:.1} ");
                    if xb > xa {
                        let _ = write!(
                            area,
                            "M{xa:.1},{base:.1} L{xa:.1},{yv:.1} L{xb:.1},{yv:.1} L{xb:.1},{base:.1} Z "
                        );
                    }
                    last_y = Some(yv);
                }
                None => last_y = None,
            }
        }
        if !area.is_empty() {
            let _ = writeln!(
                s,
                r#"<path d="{}" fill="{colour}" fill-opacity="0.15" stroke="none"/>"#,
                area.trim_end()
            );
        }
        if !line.is_empty() {
            let _ = writeln!(
                s,
                r#"<path d="{}" fill="none" stroke="{colour}" stroke-width="1.8"/>"#,
                line.trim_end()
            );
        }
        // Labels of the changes where there is room for them (on/off lanes speak for
        // themselves).
        let mut last_label = f64::NEG_INFINITY;
        let labelled = d
            .track
            .changes()
            .iter()
            .filter(|(_, st)| !matches!(st, DeviceState::Level(_)));
        for (t, st) in labelled {
            if *t > self.end_ns {
                break;
            }
            let x = self.x(*t);
            if x - last_label < LABEL_GAP {
                continue;
            }
            last_label = x;
            let text = short(d, st);
            // Near the right edge the label ends at the change instead of starting there.
            let room = (WIDTH - RIGHT - x) / 6.0;
            let (x, anchor) = if (text.chars().count() as f64) < room {
                (x + 2.0, "start")
            } else {
                (x - 2.0, "end")
            };
            let _ = writeln!(
                s,
                r##"<text x="{x:.1}" y="{:.1}" font-size="10" text-anchor="{anchor}" fill="#24292f">{}</text>"##,
                y0 + 13.0,
                escape(&text)
            );
        }
    }
}

/// The timeline of `world`'s devices over `outcome` as an SVG picture.
pub fn timeline_svg(world: &World, outcome: &SimOutcome) -> String {
    let title = format!(
        "X10 timeline: {} of virtual time, bus at {}",
        seconds(outcome.end_ns),
        outcome.speed
    );
    Timeline::new(world, outcome).svg(&title)
}

/// Writes the timeline of `world`'s devices over `outcome` to `path`: an HTML page titled
/// `title` ([`timeline_html`]) when the name ends in `.html` or `.htm`, otherwise an SVG
/// picture ([`timeline_svg`]).
///
/// # Errors
/// The file system's.
pub fn write_timeline(
    path: &Path,
    world: &World,
    outcome: &SimOutcome,
    title: &str,
) -> std::io::Result<()> {
    let html = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("html") || e.eq_ignore_ascii_case("htm"));
    let text = if html {
        timeline_html(world, outcome, title)
    } else {
        timeline_svg(world, outcome)
    };
    std::fs::write(path, text)
}

/// An HTML page titled `title` with the timeline picture and the [`summary`].
pub fn timeline_html(world: &World, outcome: &SimOutcome, title: &str) -> String {
    let svg = timeline_svg(world, outcome);
    let text = summary(world, outcome);
    format!(
        r#"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{t}</title>
<style>
body {{ font-family: DejaVu Sans, Verdana, sans-serif; margin: 24px; color: #24292f; }}
pre {{ background: #f6f8fa; padding: 12px; overflow-x: auto; }}
</style>
</head>
<body>
<h1>{t}</h1>
{svg}<h2>Summary</h2>
<pre>{summary}</pre>
</body>
</html>
"#,
        t = escape(title),
        summary = escape(&text)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round() {
        assert_eq!(tick_step(5.0), 0.5);
        assert_eq!(tick_step(10.0), 1.0);
        assert_eq!(tick_step(0.3), 0.05);
        assert_eq!(tick_label(1.5, 0.5), "1.5 s");
        assert_eq!(tick_label(2.0, 1.0), "2 s");
        assert_eq!(tick_label(2.0, 0.5), "2 s");
        assert_eq!(tick_label(0.0, 0.5), "0 s");
        assert_eq!(tick_label(0.15, 0.05), "0.15 s");
        assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }
}
