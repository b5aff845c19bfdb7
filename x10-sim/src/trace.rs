//! The readable trace: defmt-like lines, one per microcode, reply, event, actuator change and
//! notable happening, in virtual-time order.
//!
//! ```text
//! 0.000463 INFO  mb: -> db09 io high A1.B seq 2 [12 09 01 02] bus 463.3us
//! 0.001620 INFO  mb: <- db09 reply seq 3 ok [01] [03 00 01 01] bus 1151.6us
//! 0.002000 INFO  db09: A1.A high
//! ```
//!
//! The time is virtual seconds with µs resolution. Lines are sorted by time; lines at the same
//! time keep the order they were produced in, so the same run gives the same text byte for
//! byte.

use std::fmt;

use x10_microcode::{Address, Event, EventConfig, EventKind, Op, Reply, Request};

use crate::bus::{BusRecord, Outcome};
use crate::exec::Nanos;
use crate::ports::OutputChange;

/// Severity of a trace line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Detail.
    Debug,
    /// Normal operation.
    Info,
    /// Something went wrong and was handled (retry, NACK, timeout, fault).
    Warn,
    /// Something went wrong and was not handled.
    Error,
}

impl Severity {
    /// `DEBUG`, `INFO`, `WARN`, `ERROR`.
    pub const fn label(self) -> &'static str {
        match self {
            Severity::Debug => "DEBUG",
            Severity::Info => "INFO",
            Severity::Warn => "WARN",
            Severity::Error => "ERROR",
        }
    }
}

/// One line of the trace.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TraceLine {
    /// Virtual time (ns).
    pub t_ns: Nanos,
    /// Severity.
    pub severity: Severity,
    /// Who speaks (`mb`, `db09`, `bus`, `sim`, …).
    pub source: String,
    /// What happened.
    pub text: String,
}

impl TraceLine {
    /// A line.
    pub fn new(
        t_ns: Nanos,
        severity: Severity,
        source: impl Into<String>,
        text: impl Into<String>,
    ) -> TraceLine {
        TraceLine {
            t_ns,
            severity,
            source: source.into(),
            text: text.into(),
        }
    }
}

/// `seconds.micros`, e.g. `2.000463`.
pub fn timestamp(t_ns: Nanos) -> String {
    let us = t_ns / 1_000;
    format!("{}.{:06}", us / 1_000_000, us % 1_000_000)
}

/// A duration in µs with one decimal when not whole (`463.3us`, `45us`).
pub fn micros(ns: Nanos) -> String {
    let tenths = (ns + 50) / 100;
    if tenths.is_multiple_of(10) {
        format!("{}us", tenths / 10)
    } else {
        format!("{}.{}us", tenths / 10, tenths % 10)
    }
}

impl fmt::Display for TraceLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {:<5} {}: {}",
            timestamp(self.t_ns),
            self.severity.label(),
            self.source,
            self.text
        )
    }
}

/// Bytes as `[12 09 01 02]`.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::from("[");
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        s.push_str(&format!("{b:02x}"));
    }
    s.push(']');
    s
}

fn event_config(cfg: &EventConfig) -> String {
    let mut parts = Vec::new();
    if cfg.rising {
        parts.push("rising".to_string());
    }
    if cfg.falling {
        parts.push("falling".to_string());
    }
    if cfg.analog_window {
        parts.push(format!("window {}..={}", cfg.low, cfg.high));
    }
    if parts.is_empty() {
        "off".to_string()
    } else {
        parts.join(" ")
    }
}

/// An operation in words: `io high A1.B`, `pwm duty A1.A 255`, `analog read S1`.
pub fn describe_op(op: &Op<'_>) -> String {
    let f = op.function().name();
    let n = op.name();
    match op {
        Op::DigitalRead(p) | Op::DigitalWrite(p, _) => format!("{f} {n} {p}"),
        Op::PulseIn {
            pin, timeout_ms, ..
        } => match timeout_ms {
            Some(ms) => format!("{f} {n} {pin} timeout {ms}ms"),
            None => format!("{f} {n} {pin}"),
        },
        Op::PwmDuty(p, d) => format!("{f} {n} {p} {d}"),
        Op::PwmFrequency(p, hz) => format!("{f} {n} {p} {hz}Hz"),
        Op::PwmPulseWidth(p, us) => format!("{f} {n} {p} {us}us"),
        Op::AnalogRead(p) => format!("{f} {n} {p}"),
        Op::SetFailsafe { timeout_ms } => format!("{f} {n} {timeout_ms}ms"),
        Op::EventEnable(p, cfg) => format!("{f} {n} {p} {}", event_config(cfg)),
        Op::SetPec(on) => format!("{f} {n} {}", if *on { "on" } else { "off" }),
        Op::SerialWrite(p, data) => format!("{f} {n} {p} {}", hex(data)),
        Op::SerialRead(p, len) => format!("{f} {n} {p} {len}"),
        Op::SerialConfig(p, baud) => format!("{f} {n} {p} {baud}baud"),
        Op::Batch(b) => format!("{f} {} items", b.len()),
        _ => format!("{f} {n}"),
    }
}

/// A request frame to board `db` in words (`io high A1.B seq 2`; `+pec` when it carries its
/// check, a PEC byte or a CRC-16), or why it does not parse.
pub fn describe_request(db: u8, bytes: &[u8]) -> String {
    match Request::parse(bytes) {
        Ok(r) => format!("{} seq {}", describe_op(&r.op), r.seq),
        Err(e) => match Address::new(db).and_then(|a| Request::parse_with_pec(a, bytes)) {
            Ok(r) => format!("{} seq {} +pec", describe_op(&r.op), r.seq),
            Err(_) => format!("unparsed ({e})"),
        },
    }
}

/// A reply read from board `db` in words (`reply seq 3 ok [01]`; `+pec` when it carries its
/// check). The bytes are what the motherboard read: the frame, its check, then padding.
pub fn describe_reply(db: u8, bytes: &[u8]) -> String {
    let Ok(a) = Address::new(db) else {
        return "unparsed reply (address)".to_string();
    };
    match Reply::parse_read(a, false, bytes) {
        Ok(r) => format!("reply seq {} {} {}", r.seq, r.status.name(), hex(r.payload)),
        Err(e) => match Reply::parse_read(a, true, bytes) {
            Ok(r) => format!(
                "reply seq {} {} {} +pec",
                r.seq,
                r.status.name(),
                hex(r.payload)
            ),
            Err(_) => format!("unparsed reply ({e})"),
        },
    }
}

/// An event written to the motherboard at `mb` in words (`event pin_change S1.A seq 4 ok
/// [01]`; `+pec` when it carries its check; a `rejected` event names the status it reports).
pub fn describe_event(mb: u8, bytes: &[u8]) -> String {
    let (parsed, checked) = match Event::parse(bytes) {
        Ok(ev) => (Ok(ev), false),
        Err(e) => match Address::new(mb).and_then(|a| Event::parse_with_pec(a, bytes)) {
            Ok(ev) => (Ok(ev), true),
            Err(_) => (Err(e), false),
        },
    };
    match parsed {
        Ok(ev) => {
            let pin = match ev.kind {
                EventKind::PinChange
                | EventKind::AnalogThreshold
                | EventKind::DeferredReply
                | EventKind::Rejected => format!(" {}", ev.pin),
                _ => String::new(),
            };
            format!(
                "event {}{pin} seq {} {} {}{}",
                ev.kind,
                ev.seq,
                ev.status.name(),
                hex(ev.payload),
                if checked { " +pec" } else { "" }
            )
        }
        Err(e) => format!("unparsed event ({e})"),
    }
}

/// Names bus nodes and tells events from requests.
pub struct BusNames<'a> {
    /// Node names by node id.
    pub names: &'a [String],
    /// The motherboard's address: writes to it are events.
    pub mb_address: Option<u8>,
}

impl BusNames<'_> {
    fn name(&self, node: usize) -> String {
        self.names
            .get(node)
            .cloned()
            .unwrap_or_else(|| format!("node{node}"))
    }

    fn target(&self, rec: &BusRecord) -> String {
        rec.target
            .map_or_else(|| format!("{:#04x}", rec.addr), |n| self.name(n))
    }
}

/// The trace lines of one bus transaction.
pub fn bus_lines(rec: &BusRecord, names: &BusNames<'_>) -> Vec<TraceLine> {
    let mut lines = Vec::new();
    let master = names.name(rec.master);
    let target = names.target(rec);
    for f in &rec.faults {
        lines.push(TraceLine::new(
            rec.start_ns,
            Severity::Warn,
            "bus",
            format!("fault injected: {f}"),
        ));
    }
    for l in &rec.losers {
        // Losing arbitration is the multi-master bus working (the loser retries): not a
        // warning.
        lines.push(TraceLine::new(
            rec.start_ns,
            Severity::Info,
            names.name(l.node),
            format!(
                "lost arbitration to {master} at bit {} (wanted {:#04x} {})",
                l.bit,
                l.addr,
                hex(&l.write)
            ),
        ));
    }
    let is_event = names.mb_address == Some(rec.addr) && !rec.is_read;
    let what = if is_event {
        describe_event(rec.addr, &rec.written)
    } else {
        describe_request(rec.addr, &rec.written)
    };
    let stretch = if rec.stretch_ns > 0 {
        format!(" stretch {}", micros(rec.stretch_ns))
    } else {
        String::new()
    };
    let base = format!(
        "-> {target} {what} {} bus {}{stretch}",
        hex(&rec.written),
        micros(rec.duration_ns())
    );
    match rec.outcome {
        Outcome::Ok => {
            lines.push(TraceLine::new(
                rec.start_ns,
                Severity::Info,
                master.clone(),
                base,
            ));
            if rec.is_read {
                lines.push(TraceLine::new(
                    rec.end_ns,
                    Severity::Info,
                    master,
                    format!(
                        "<- {target} {} {}",
                        describe_reply(rec.addr, &rec.read),
                        hex(&rec.read)
                    ),
                ));
            }
        }
        Outcome::Nack { byte } => {
            let which = if byte == 0 {
                "address".to_string()
            } else {
                format!("byte {byte}")
            };
            lines.push(TraceLine::new(
                rec.start_ns,
                Severity::Warn,
                master,
                format!("{base} NACK ({which})"),
            ));
        }
        Outcome::Timeout => lines.push(TraceLine::new(
            rec.start_ns,
            Severity::Warn,
            master,
            format!("{base} TIMEOUT (target held SCL)"),
        )),
        Outcome::Bus => lines.push(TraceLine::new(
            rec.start_ns,
            Severity::Warn,
            master,
            format!("{base} BUS FAULT"),
        )),
    }
    lines
}

/// The trace line of an output change.
pub fn change_line(c: &OutputChange) -> TraceLine {
    let text = c.to_string();
    let text = text
        .strip_prefix(&format!("{} ", c.board))
        .unwrap_or(&text)
        .to_string();
    TraceLine::new(c.t_ns, Severity::Info, c.board.clone(), text)
}

/// A whole trace.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Trace {
    lines: Vec<TraceLine>,
}

impl Trace {
    /// An empty trace.
    pub fn new() -> Trace {
        Trace::default()
    }

    /// Adds lines (kept in time order, stable).
    pub fn extend(&mut self, lines: impl IntoIterator<Item = TraceLine>) {
        self.lines.extend(lines);
        self.lines.sort_by_key(|l| l.t_ns);
    }

    /// The lines.
    pub fn lines(&self) -> &[TraceLine] {
        &self.lines
    }

    /// The whole trace as text, one line each.
    pub fn render(&self) -> String {
        let mut s = String::new();
        for l in &self.lines {
            s.push_str(&l.to_string());
            s.push('\n');
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::{Loser, WireSym};

    fn rec(written: Vec<u8>, read: Vec<u8>, outcome: Outcome) -> BusRecord {
        BusRecord {
            txn: 0,
            start_ns: 2_345_000,
            end_ns: 2_345_000 + 463_300,
            master: 0,
            addr: 0x09,
            target: Some(1),
            is_read: !read.is_empty(),
            received: written.clone(),
            written,
            read,
            outcome,
            losers: vec![],
            stretch_ns: 0,
            faults: vec![],
            wire: vec![(0, WireSym::Start)],
        }
    }

    #[test]
    fn request_reply_and_event_lines() {
        let names = ["mb".to_string(), "db09".to_string()];
        let n = BusNames {
            names: &names,
            mb_address: Some(0x08),
        };
        let lines = bus_lines(&rec(vec![0x12, 0x09, 0x01, 0x02], vec![], Outcome::Ok), &n);
        assert_eq!(
            lines[0].to_string(),
            "0.002345 INFO  mb: -> db09 io high A1.B seq 2 [12 09 01 02] bus 463.3us"
        );
        let lines = bus_lines(
            &rec(
                vec![0x10, 0x09, 0x80, 0x03],
                vec![0x03, 0x00, 0x01, 0x01],
                Outcome::Ok,
            ),
            &n,
        );
        assert_eq!(lines.len(), 2);
        assert_eq!(
            lines[1].to_string(),
            "0.002808 INFO  mb: <- db09 reply seq 3 ok [01] [03 00 01 01]"
        );
        let mut ev = rec(
            vec![0x09, 0x01, 0x80, 0x04, 0x00, 0x01, 0x01],
            vec![],
            Outcome::Ok,
        );
        ev.addr = 0x08;
        ev.master = 1;
        ev.target = Some(0);
        ev.losers = vec![Loser {
            node: 0,
            addr: 0x09,
            write: vec![0x12],
            bit: 4,
        }];
        let lines = bus_lines(&ev, &n);
        assert_eq!(
            lines[0].to_string(),
            "0.002345 INFO  mb: lost arbitration to db09 at bit 4 (wanted 0x09 [12])"
        );
        assert_eq!(
            lines[1].to_string(),
            "0.002345 INFO  db09: -> mb event pin_change S1.A seq 4 ok [01] [09 01 80 04 00 01 01] bus 463.3us"
        );
        let lines = bus_lines(
            &rec(
                vec![0x20, 0x09, 0x00, 0x05, 0xff],
                vec![],
                Outcome::Nack { byte: 0 },
            ),
            &n,
        );
        assert_eq!(
            lines[0].to_string(),
            "0.002345 WARN  mb: -> db09 pwm duty A1.A 255 seq 5 [20 09 00 05 ff] bus 463.3us NACK (address)"
        );
    }

    #[test]
    fn micros_and_timestamps() {
        assert_eq!(micros(463_300), "463.3us");
        assert_eq!(micros(45_000), "45us");
        assert_eq!(micros(45_049), "45us");
        assert_eq!(timestamp(2_000_463_999), "2.000463");
    }

    #[test]
    fn trace_sorts_stably_by_time() {
        let mut t = Trace::new();
        t.extend([
            TraceLine::new(5, Severity::Info, "a", "second"),
            TraceLine::new(1, Severity::Info, "b", "first"),
            TraceLine::new(5, Severity::Info, "c", "third"),
        ]);
        let texts: Vec<_> = t.lines().iter().map(|l| l.text.as_str()).collect();
        assert_eq!(texts, ["first", "second", "third"]);
        assert!(t.render().ends_with("c: third\n"));
    }
}
