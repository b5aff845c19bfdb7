//! The timeline as a picture: one lane per device, time in seconds across, step plots for
//! levels, duties, angles and motor speeds, lines for scripted analog inputs; below them, on
//! the same time axis, the bus (each transaction and the load) and one lane per task (each
//! call from its start to its result). Every change, transaction and call is an SVG element
//! with a `<title>` (its tooltip); a change's label is placed in up to [`LABEL_ROWS`] rows
//! above its lane and, where none has room, the lane says how many labels wait for a zoom.
//! Plain SVG text, and an HTML page around it ([`timeline_html`]) that adds horizontal zoom
//! and pan (a small inline script, no external asset) and a table of every change.

use std::fmt::Write as _;
use std::path::Path;

use super::{summary, DeviceState, DeviceTimeline, MotorDirection, Timeline};
use crate::bus::{BusRecord, Outcome};
use crate::exec::Nanos;
use crate::sim::{CallSpan, SimOutcome};
use crate::trace::{self, timestamp};
use crate::world::{seconds, DeviceKind, World};

const WIDTH: f64 = 1000.0;
const LABEL: f64 = 230.0;
const RIGHT: f64 = 24.0;
const TOP: f64 = 40.0;
const LANE: f64 = 62.0;
const PLOT_H: f64 = 34.0;
const AXIS: f64 = 44.0;
/// Height of one row of change labels.
const ROW_H: f64 = 12.0;
/// Rows of change labels a lane may have.
pub const LABEL_ROWS: usize = 3;
/// Estimated width of one character of a label (font size 10), px.
const CHAR_W: f64 = 6.0;
/// Space between two labels in one row, px.
const LABEL_SPACE: f64 = 6.0;
/// Bins of the bus-load curve across the run.
const LOAD_BINS: u64 = 250;

const OUTPUT: &str = "#1f6feb";
const INPUT: &str = "#1a7f37";
const BRAKE: &str = "#cf222e";
const CALL: &str = "#8250df";

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
        // Nothing in range (a ranger reading a model): nothing to draw.
        DeviceState::Distance(mm) => mm.is_finite().then_some(*mm),
    }
}

/// A short label for a change.
pub(crate) fn short(d: &DeviceTimeline, s: &DeviceState) -> String {
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
    if d.model.is_some() && is_analog(kind) {
        // A sensor reading a model: the range of what it read.
        let read: Vec<(u64, f64)> = d
            .track
            .states()
            .iter()
            .filter_map(value)
            .map(|v| (0, v))
            .collect();
        let signal = if read.is_empty() {
            crate::world::Signal::Const(0.0)
        } else {
            crate::world::Signal::Steps(read)
        };
        let unit = match kind {
            DeviceKind::Thermistor { .. } => "°C",
            DeviceKind::Ultrasonic { .. } => "mm",
            _ => "counts",
        };
        return analog(&signal, unit);
    }
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

impl DeviceTimeline {
    /// Whether a change of this device gets a label in the plot: every change but an on/off
    /// level's (the step speaks for itself) and a scripted analog input's breakpoints (the
    /// line does). Every change has its tooltip ([`DeviceTimeline::change_text`]) either way.
    pub fn labels_changes(&self) -> bool {
        !is_analog(self.device.kind()) && !matches!(self.track.initial(), DeviceState::Level(_))
    }

    /// A change's label in the plot: `fwd 50 %`, `rev 30 %`, `brake`, `stop`, `40 %`, `90°`.
    pub fn label(&self, s: &DeviceState) -> String {
        short(self, s)
    }

    /// A change's tooltip in the plot and its line in the page's table of changes:
    /// `drive 2.020463 s: forward 50 %`.
    pub fn change_text(&self, t_ns: Nanos, s: &DeviceState) -> String {
        format!(
            "{} {} s: {}",
            self.device.name(),
            timestamp(t_ns),
            self.words(s)
        )
    }
}

fn is_analog(kind: &DeviceKind) -> bool {
    matches!(
        kind,
        DeviceKind::LightSensor { .. }
            | DeviceKind::ForceSensor { .. }
            | DeviceKind::AnalogInput { .. }
            | DeviceKind::Thermistor { .. }
            | DeviceKind::Ultrasonic { .. }
    )
}

/// A label put in a row (the same rule as the page's script, which places them again at each
/// zoom).
struct Placed {
    /// The change's x (base zoom).
    x: f64,
    text: String,
    /// `None`: no row had room.
    row: Option<usize>,
}

impl Placed {
    fn width(&self) -> f64 {
        self.text.chars().count() as f64 * CHAR_W
    }

    /// Start and end of the text, and its anchor: after the change, or before it when it
    /// would run past the plot's right end.
    fn extent(&self) -> (f64, f64, &'static str) {
        let w = self.width();
        if self.x + 2.0 + w <= WIDTH - RIGHT {
            (self.x + 2.0, self.x + 2.0 + w, "start")
        } else {
            (self.x - 2.0 - w, self.x - 2.0, "end")
        }
    }
}

/// Places labels (in time order) in the first of `rows` rows where they do not touch the
/// previous one.
fn place(labels: &mut [Placed], rows: usize) {
    let mut ends = vec![f64::NEG_INFINITY; rows];
    for l in labels {
        let (a, b, _) = l.extent();
        l.row = ends.iter().position(|e| e + LABEL_SPACE <= a);
        if let Some(r) = l.row {
            ends[r] = b;
        }
    }
}

/// What the plot draws besides the devices.
struct Extras<'a> {
    records: &'a [BusRecord],
    calls: &'a [CallSpan],
    /// The tasks in the order of their first call.
    tasks: Vec<&'a str>,
}

impl<'a> Extras<'a> {
    fn new(records: &'a [BusRecord], calls: &'a [CallSpan]) -> Extras<'a> {
        let mut tasks: Vec<&str> = Vec::new();
        for c in calls {
            if !tasks.contains(&c.task.as_str()) {
                tasks.push(&c.task);
            }
        }
        Extras {
            records,
            calls,
            tasks,
        }
    }
}

/// A bus transaction in words, for its tooltip.
fn transaction_text(r: &BusRecord) -> String {
    let mut what = trace::describe_request(r.addr, &r.written);
    if what.starts_with("unparsed") {
        let event = trace::describe_event(r.addr, &r.written);
        what = if event.starts_with("unparsed") {
            format!("bytes {}", trace::hex(&r.written))
        } else {
            event
        };
    }
    if r.is_read {
        what = format!("{what}, read {}", trace::describe_reply(r.addr, &r.read));
    }
    let outcome = match r.outcome {
        Outcome::Ok => String::new(),
        Outcome::Nack { byte: 0 } => ", NACK (address)".to_string(),
        Outcome::Nack { byte } => format!(", NACK (byte {byte})"),
        Outcome::Timeout => ", timeout".to_string(),
        Outcome::Bus => ", bus fault".to_string(),
    };
    format!(
        "bus {} s: to {:#04x} {what}, {}{outcome}",
        timestamp(r.start_ns),
        r.addr,
        trace::micros(r.duration_ns())
    )
}

/// A call in words, for its tooltip.
fn call_text(c: &CallSpan) -> String {
    format!("{} {} s: {}", c.task, timestamp(c.start_ns), c.text)
}

const STYLE: &str = "circle.change:hover { stroke: #24292f; stroke-width: 2; } \
rect.txn:hover, rect.call:hover { fill-opacity: 1; } line.call:hover { stroke-width: 4; } \
text.label { pointer-events: none; }";

impl Timeline {
    fn x(&self, t_ns: Nanos) -> f64 {
        let end = self.end_ns.max(1) as f64;
        LABEL + (WIDTH - LABEL - RIGHT) * (t_ns.min(self.end_ns) as f64 / end)
    }

    /// The timeline as an SVG picture titled `title`: the device lanes only.
    pub fn svg(&self, title: &str) -> String {
        self.render(title, &Extras::new(&[], &[]), true)
    }

    /// The labels of device `d`'s changes, placed; the rows used.
    fn labels(&self, d: &DeviceTimeline) -> (Vec<Placed>, usize) {
        if !d.labels_changes() {
            return (Vec::new(), 0);
        }
        let mut labels: Vec<Placed> = d
            .track
            .changes()
            .iter()
            .filter(|(t, _)| *t <= self.end_ns)
            .map(|(t, st)| Placed {
                x: self.x(*t),
                text: short(d, st),
                row: None,
            })
            .collect();
        place(&mut labels, LABEL_ROWS);
        let rows = labels
            .iter()
            .filter_map(|l| l.row)
            .max()
            .map_or(1, |r| r + 1);
        let rows = if labels.iter().any(|l| l.row.is_none()) {
            LABEL_ROWS
        } else {
            rows
        };
        (labels, rows)
    }

    /// The picture; `standalone`: an SVG file (with its namespace), else for inline use in
    /// HTML (no namespace URL).
    fn render(&self, title: &str, extras: &Extras<'_>, standalone: bool) -> String {
        let placed: Vec<(Vec<Placed>, usize)> =
            self.devices.iter().map(|d| self.labels(d)).collect();
        let lane_h = |rows: usize| (6.0 + ROW_H * rows.max(1) as f64 + PLOT_H + 10.0).max(LANE);
        let extra_lanes = if extras.records.is_empty() && extras.calls.is_empty() {
            0
        } else {
            1 + extras.tasks.len()
        };
        let lanes_h: f64 =
            placed.iter().map(|(_, r)| lane_h(*r)).sum::<f64>() + LANE * extra_lanes as f64;
        let height = TOP + lanes_h + AXIS;
        let plot_right = WIDTH - RIGHT;
        let mut s = String::new();
        let ns = if standalone {
            r#" xmlns="http://www.w3.org/2000/svg""#
        } else {
            ""
        };
        let _ = writeln!(
            s,
            r#"<svg{ns} id="x10-timeline" width="{WIDTH:.0}" height="{height:.0}" viewBox="0 0 {WIDTH:.0} {height:.0}" font-family="DejaVu Sans, Verdana, sans-serif" data-left="{LABEL:.1}" data-right="{plot_right:.1}" data-end-s="{}" data-row="{ROW_H:.1}" data-char="{CHAR_W:.1}" data-space="{LABEL_SPACE:.1}">"#,
            self.end_ns as f64 / 1e9
        );
        let _ = writeln!(s, "<style>{STYLE}</style>");
        let _ = writeln!(
            s,
            r#"<defs><clipPath id="x10-plot-area"><rect x="{LABEL:.1}" y="0" width="{:.1}" height="{height:.0}"/></clipPath></defs>"#,
            plot_right - LABEL
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="12" y="24" font-size="15" font-weight="bold">{}</text>"#,
            escape(title)
        );
        let mut y0 = TOP;
        let mut lane_no = 0usize;
        let mut band = |s: &mut String, y0: f64, h: f64| {
            let fill = if lane_no.is_multiple_of(2) {
                "#f6f8fa"
            } else {
                "#ffffff"
            };
            lane_no += 1;
            let _ = writeln!(
                s,
                r#"<rect x="0" y="{y0:.1}" width="{WIDTH:.0}" height="{h:.1}" fill="{fill}"/>"#
            );
        };
        for (i, (d, (labels, rows))) in self.devices.iter().zip(&placed).enumerate() {
            let h = lane_h(*rows);
            band(&mut s, y0, h);
            self.lane(&mut s, i, d, y0, labels, *rows);
            y0 += h;
        }
        if extra_lanes > 0 {
            band(&mut s, y0, LANE);
            self.bus_lane(&mut s, y0, extras.records);
            y0 += LANE;
            for task in &extras.tasks {
                band(&mut s, y0, LANE);
                self.task_lane(&mut s, y0, task, extras.calls);
                y0 += LANE;
            }
        }
        // Time axis and grid.
        let axis_y = y0 + 6.0;
        let _ = writeln!(
            s,
            r##"<line x1="{LABEL:.1}" y1="{axis_y:.1}" x2="{plot_right:.1}" y2="{axis_y:.1}" stroke="#57606a"/>"##
        );
        let _ = writeln!(
            s,
            r#"<g id="x10-ticks" clip-path="url(#x10-plot-area)" data-top="{TOP:.1}" data-axis="{axis_y:.1}">"#
        );
        let end_s = self.end_ns as f64 / 1e9;
        let step = tick_step(end_s);
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
            // The first and last ticks' labels stay inside the plot.
            let anchor = if k == 0 {
                "start"
            } else if t > end_s - step * 1e-6 {
                "end"
            } else {
                "middle"
            };
            let _ = writeln!(
                s,
                r##"<text x="{x:.1}" y="{:.1}" font-size="11" text-anchor="{anchor}" fill="#24292f">{}</text>"##,
                axis_y + 18.0,
                tick_label(t, step)
            );
            k += 1;
        }
        s.push_str("</g>\n");
        let _ = writeln!(
            s,
            r##"<text x="{plot_right:.1}" y="{:.1}" font-size="11" text-anchor="end" fill="#57606a">virtual time</text>"##,
            axis_y + 34.0
        );
        s.push_str("</svg>\n");
        s
    }

    /// The label column of a lane: a name, and up to three lines below it.
    fn lane_text(s: &mut String, y0: f64, name: &str, lines: &[&str]) {
        let _ = writeln!(
            s,
            r##"<text x="12" y="{:.1}" font-size="13" font-weight="bold" fill="#24292f">{}</text>"##,
            y0 + 19.0,
            escape(name)
        );
        for (i, l) in lines.iter().enumerate() {
            let _ = writeln!(
                s,
                r##"<text x="12" y="{:.1}" font-size="10" fill="#57606a">{}</text>"##,
                y0 + 34.0 + 14.0 * i as f64,
                escape(l)
            );
        }
    }

    fn bus_lane(&self, s: &mut String, y0: f64, records: &[BusRecord]) {
        let top = y0 + 18.0;
        let bottom = top + PLOT_H;
        let busy: Nanos = records.iter().map(BusRecord::duration_ns).sum();
        let basis_points = busy
            .saturating_mul(10_000)
            .checked_div(self.end_ns)
            .unwrap_or(0);
        let bin_ns = self.end_ns.div_ceil(LOAD_BINS).max(1);
        let first = format!(
            "{} transactions, busy {}.{:02} %",
            records.len(),
            basis_points / 100,
            basis_points % 100
        );
        let bin = if bin_ns.is_multiple_of(1_000_000) {
            format!("{} ms", bin_ns / 1_000_000)
        } else {
            format!("{} µs", bin_ns.div_ceil(1_000))
        };
        let second = format!("the line: load per {bin}, 0 … 100 %");
        Self::lane_text(s, y0, "bus", &[&first, &second]);
        let _ = writeln!(s, r#"<g clip-path="url(#x10-plot-area)"><g class="zoom">"#);
        for r in records {
            let xa = self.x(r.start_ns);
            let xb = self.x(r.end_ns);
            let colour = if r.outcome == Outcome::Ok {
                OUTPUT
            } else {
                BRAKE
            };
            let _ = writeln!(
                s,
                r#"<rect class="txn" x="{xa:.3}" y="{top:.1}" width="{:.3}" height="{PLOT_H:.1}" fill="{colour}" fill-opacity="0.35" stroke="{colour}" stroke-width="0.6" vector-effect="non-scaling-stroke"><title>{}</title></rect>"#,
                (xb - xa).max(0.0),
                escape(&transaction_text(r))
            );
        }
        // The load: the bus's busy fraction of each bin.
        let mut load = vec![0 as Nanos; LOAD_BINS as usize];
        for r in records {
            let mut t = r.start_ns.min(self.end_ns);
            let end = r.end_ns.min(self.end_ns);
            while t < end {
                let bin = t / bin_ns;
                let bin_end = ((bin + 1) * bin_ns).min(end);
                if let Some(l) = load.get_mut(bin as usize) {
                    *l += bin_end - t;
                }
                t = bin_end;
            }
        }
        let mut path = String::new();
        for (i, busy) in load.iter().enumerate() {
            let a = (i as u64 * bin_ns).min(self.end_ns);
            let b = ((i as u64 + 1) * bin_ns).min(self.end_ns);
            let v = *busy as f64 / bin_ns as f64;
            let y = bottom - v.min(1.0) * PLOT_H;
            let cmd = if path.is_empty() { 'M' } else { 'L' };
            let _ = write!(
                path,
                "{cmd}{:.1},{y:.1} L{:.1},{y:.1} ",
                self.x(a),
                self.x(b)
            );
        }
        let _ = writeln!(
            s,
            r##"<path d="{}" fill="none" stroke="#24292f" stroke-width="1" vector-effect="non-scaling-stroke"/>"##,
            path.trim_end()
        );
        s.push_str("</g></g>\n");
    }

    fn task_lane(&self, s: &mut String, y0: f64, task: &str, calls: &[CallSpan]) {
        let top = y0 + 18.0;
        let mine: Vec<&CallSpan> = calls.iter().filter(|c| c.task == task).collect();
        let failed = mine.iter().filter(|c| !c.ok).count();
        let first = format!("task: {} calls, {failed} failed", mine.len());
        Self::lane_text(
            s,
            y0,
            &format!("task {task}"),
            &[&first, "each call from its start to its result"],
        );
        let _ = writeln!(s, r#"<g clip-path="url(#x10-plot-area)"><g class="zoom">"#);
        for c in mine {
            let xa = self.x(c.start_ns);
            let xb = self.x(c.end_ns);
            let colour = if c.ok { CALL } else { BRAKE };
            let tip = escape(&call_text(c));
            if c.end_ns > c.start_ns {
                let _ = writeln!(
                    s,
                    r#"<rect class="call" x="{xa:.3}" y="{top:.1}" width="{:.3}" height="{PLOT_H:.1}" fill="{colour}" fill-opacity="0.35" stroke="{colour}" stroke-width="0.6" vector-effect="non-scaling-stroke"><title>{tip}</title></rect>"#,
                    (xb - xa).max(0.0)
                );
            } else {
                // A call that took no virtual time (the internal board): a line.
                let _ = writeln!(
                    s,
                    r#"<line class="call" x1="{xa:.3}" y1="{top:.1}" x2="{xa:.3}" y2="{:.1}" stroke="{colour}" stroke-width="2" vector-effect="non-scaling-stroke"><title>{tip}</title></line>"#,
                    top + PLOT_H
                );
            }
        }
        s.push_str("</g></g>\n");
    }

    fn lane(
        &self,
        s: &mut String,
        index: usize,
        d: &DeviceTimeline,
        y0: f64,
        labels: &[Placed],
        rows: usize,
    ) {
        let scale = scale_of(d);
        let top = y0 + 6.0 + ROW_H * rows.max(1) as f64;
        let bottom = top + PLOT_H;
        let y = |v: f64| {
            let span = (scale.hi - scale.lo).max(f64::MIN_POSITIVE);
            bottom - (v.clamp(scale.lo, scale.hi) - scale.lo) / span * PLOT_H
        };
        let is_input = d.script().is_some();
        let colour = if is_input { INPUT } else { OUTPUT };
        let kind_line = format!(
            "{}{}",
            if is_input { "scripted · " } else { "" },
            scale.text
        );
        Self::lane_text(s, y0, d.device.name(), &[&d.description(), &kind_line]);
        let hidden = labels.iter().filter(|l| l.row.is_none()).count();
        let note_id = format!("x10-note-{index}");
        let _ = writeln!(
            s,
            r##"<text id="{note_id}" x="12" y="{:.1}" font-size="10" fill="{BRAKE}">{}</text>"##,
            y0 + 62.0,
            hidden_note(hidden)
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
        let _ = writeln!(s, r#"<g clip-path="url(#x10-plot-area)"><g class="zoom">"#);
        if is_analog(d.device.kind()) {
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
                r#"<path d="{}" fill="none" stroke="{colour}" stroke-width="1.6" vector-effect="non-scaling-stroke"/>"#,
                path.trim_end()
            );
        } else {
            self.steps(s, d, top, base, colour, &y);
        }
        s.push_str("</g>\n");
        // A dot per change, with its tooltip.
        for (t, st) in d.track.changes() {
            if *t > self.end_ns {
                break;
            }
            let x = self.x(*t);
            let cy = value(st).map_or(base, &y);
            let _ = writeln!(
                s,
                r#"<circle class="change" data-x="{x:.3}" cx="{x:.1}" cy="{cy:.1}" r="3" fill="{colour}" stroke="white" stroke-width="1"><title>{}</title></circle>"#,
                escape(&d.change_text(*t, st))
            );
        }
        // The labels, in their rows (the page's script places them again at each zoom).
        let _ = writeln!(
            s,
            r#"<g class="labels" data-rows="{rows}" data-y="{:.1}" data-note="{note_id}">"#,
            y0 + 13.0
        );
        for l in labels {
            let (a, b, anchor) = l.extent();
            let x = if anchor == "start" { a } else { b };
            let (row, visible) = match l.row {
                Some(r) => (r, ""),
                None => (0, r#" visibility="hidden""#),
            };
            let _ = writeln!(
                s,
                r##"<text class="label" data-x="{:.3}" data-w="{:.1}" x="{x:.1}" y="{:.1}" font-size="10" text-anchor="{anchor}" fill="#24292f"{visible}>{}</text>"##,
                l.x,
                l.width(),
                y0 + 13.0 + ROW_H * row as f64,
                escape(&l.text)
            );
        }
        s.push_str("</g></g>\n");
    }

    /// A step plot of the segments of constant state.
    fn steps(
        &self,
        s: &mut String,
        d: &DeviceTimeline,
        top: f64,
        base: f64,
        colour: &str,
        y: &dyn Fn(f64) -> f64,
    ) {
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
                        r#"<rect x="{xa:.3}" y="{top:.1}" width="{:.3}" height="{PLOT_H:.1}" fill="{BRAKE}" fill-opacity="0.25"/>"#,
                        xb - xa
                    );
                }
            }
            match value(st) {
                Some(v) => {
                    let yv = y(v);
                    if last_y.is_some() {
                        let _ = write!(line, "L{xa:.3},{yv:.1} ");
                    } else {
                        let _ = write!(line, "M{xa:.3},{yv:.1} ");
                    }
                    let _ = write!(line, "L{xb:.3},{yv:.1} ");
                    if xb > xa {
                        let _ = write!(
                            area,
                            "M{xa:.3},{base:.1} L{xa:.3},{yv:.1} L{xb:.3},{yv:.1} L{xb:.3},{base:.1} Z "
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
                r#"<path d="{}" fill="none" stroke="{colour}" stroke-width="1.8" vector-effect="non-scaling-stroke"/>"#,
                line.trim_end()
            );
        }
    }
}

/// The note of a lane whose labels did not all fit.
fn hidden_note(hidden: usize) -> String {
    match hidden {
        0 => String::new(),
        1 => "1 label without room: zoom in or hover".to_string(),
        n => format!("{n} labels without room: zoom in or hover"),
    }
}

/// The timeline of `world`'s devices over `outcome` as an SVG picture: a lane per device,
/// then the bus and a lane per task that made calls, on one time axis.
pub fn timeline_svg(world: &World, outcome: &SimOutcome) -> String {
    render(world, outcome, true)
}

fn plot_title(outcome: &SimOutcome) -> String {
    format!(
        "X10 timeline: {} of virtual time, bus at {}",
        seconds(outcome.end_ns),
        outcome.speed
    )
}

fn render(world: &World, outcome: &SimOutcome, standalone: bool) -> String {
    Timeline::new(world, outcome).render(
        &plot_title(outcome),
        &Extras::new(&outcome.records, &outcome.calls),
        standalone,
    )
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

/// The page's script: horizontal zoom (wheel over the plot, the buttons, `+` and `-`) and pan
/// (drag, the arrow keys); labels placed again at each zoom, ticks redrawn.
const SCRIPT: &str = include_str!("zoom.js");

/// An HTML page titled `title`, self-contained (no external asset, no network): the timeline
/// picture with horizontal zoom and pan, every change in a table, and the [`summary`].
pub fn timeline_html(world: &World, outcome: &SimOutcome, title: &str) -> String {
    let tl = Timeline::new(world, outcome);
    page(
        &tl,
        &plot_title(outcome),
        &Extras::new(&outcome.records, &outcome.calls),
        &summary(world, outcome),
        title,
    )
}

/// The same page for a run that was not simulated (a real robot seen over the USB link,
/// `x10 monitor`): its device timeline `tl`, its calls (no bus transactions: the link does not
/// carry them), the plot's title, the summary text and the page's title.
pub fn timeline_html_of(
    tl: &Timeline,
    calls: &[crate::sim::CallSpan],
    plot_title: &str,
    summary: &str,
    title: &str,
) -> String {
    page(tl, plot_title, &Extras::new(&[], calls), summary, title)
}

fn page(tl: &Timeline, plot_title: &str, extras: &Extras<'_>, text: &str, title: &str) -> String {
    let svg = tl.render(plot_title, extras, false);
    let mut rows: Vec<(Nanos, usize, String, String)> = Vec::new();
    for (i, d) in tl.devices.iter().enumerate() {
        for (t, st) in d.track.changes() {
            if *t <= tl.end_ns {
                rows.push((*t, i, d.device.name().to_string(), d.words(st)));
            }
        }
    }
    rows.sort_by_key(|(t, i, _, _)| (*t, *i));
    let mut table = String::new();
    for (t, _, name, words) in &rows {
        let _ = writeln!(
            table,
            "<tr><td>{} s</td><td>{}</td><td>{}</td></tr>",
            timestamp(*t),
            escape(name),
            escape(words)
        );
    }
    format!(
        r#"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{t}</title>
<style>
body {{ font-family: DejaVu Sans, Verdana, sans-serif; margin: 24px; color: #24292f; }}
pre {{ background: #f6f8fa; padding: 12px; overflow-x: auto; }}
#x10-timeline {{ cursor: grab; user-select: none; touch-action: none; }}
.tools {{ margin: 8px 0; font-size: 14px; }}
.tools button {{ font-size: 14px; margin-right: 4px; }}
table {{ border-collapse: collapse; font-size: 13px; }}
td, th {{ border-bottom: 1px solid #d0d7de; padding: 2px 12px 2px 0; text-align: left; }}
td:first-child {{ font-variant-numeric: tabular-nums; }}
</style>
</head>
<body>
<h1>{t}</h1>
<div class="tools"><button id="x10-in" type="button">zoom in</button><button id="x10-out" type="button">zoom out</button><button id="x10-reset" type="button">whole run</button> <span id="x10-zoom">1×</span> · wheel over the plot zooms, drag pans; hover a dot, a transaction or a call for its details</div>
{svg}{arena}<h2>Changes ({n})</h2>
<table>
<tr><th>time</th><th>device</th><th>change</th></tr>
{table}</table>
<h2>Summary</h2>
<pre>{summary}</pre>
<script>
{SCRIPT}</script>
</body>
</html>
"#,
        t = escape(title),
        n = rows.len(),
        arena = tl
            .motion()
            .filter(|m| m.physics().chassis.is_some())
            .map(crate::physics::top_view_section)
            .unwrap_or_default(),
        summary = escape(text)
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
