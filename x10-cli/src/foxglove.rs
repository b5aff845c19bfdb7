//! A run for Foxglove: the live robot's (`x10 monitor`), a recorded one's (`x10 monitor
//! --replay FILE`) or the simulator's (`x10 sim`, `cargo sim`) calls, events, output changes
//! and trace lines as JSON messages on topics, written to an MCAP file (`--mcap FILE`) that
//! Foxglove opens for plotting (docs/usb-link.md, "Plotting in Foxglove").
//!
//! The topics:
//!
//! | topic | schema | one message per |
//! | --- | --- | --- |
//! | `/x10/outputs/<board>/<pin>/<kind>` | `x10.Output` | output change: `value` is the series to plot (`/x10/outputs/db09/A1_A/pwm`: a motor's duty 0-255; `.../level`: 0 or 1; `.../A1/frequency_hz`; `.../pulse_us`) |
//! | `/x10/calls` | `x10.Call` | call of a robot task (or the laptop's): board, operation, result, start, end, `duration_us` |
//! | `/x10/events` | `x10.Event` | event routed to the motherboard: board, kind, pin, seq, status, payload |
//! | `/x10/log` | `foxglove.Log` | trace line (Foxglove's Log panel) |
//!
//! Log times are the motherboard's clock (the simulator's virtual time) in ns.

use std::collections::HashMap;
use std::io::{Seek, Write};

use crate::monitor::LinkRun;
use serde_json::{json, Value};
use x10_link::EventRec;
use x10_microcode::{Address, Event, EventKind, PinRef, Status};
use x10_sim::bus::{BusRecord, Outcome as BusOutcome};
use x10_sim::ports::{Change, OutputChange};
use x10_sim::sim::{CallSpan, SimOutcome};
use x10_sim::trace::{Severity, TraceLine};
use x10_sim::world::World;

/// A message's JSON schema: its name and text.
#[derive(Debug, PartialEq, Eq)]
pub struct Schema {
    /// Its name (`x10.Output`, `foxglove.Log`).
    pub name: &'static str,
    /// The JSON schema.
    pub json: &'static str,
}

/// An output change.
pub const OUTPUT: Schema = Schema {
    name: "x10.Output",
    json: r#"{"title":"x10.Output","description":"An output change: what a robot set on a board's pin","type":"object","properties":{"board":{"type":"string","description":"mb for the motherboard's own ports, db09 for board 9"},"pin":{"type":"string","description":"A1.A; the port (A1) for a frequency"},"device":{"type":"string","description":"the world's device on that port, when the world is known"},"kind":{"type":"string","enum":["level","pwm","frequency_hz","pulse_us"]},"value":{"type":"integer","description":"level 0 or 1, pwm 0-255, Hz, or us"},"text":{"type":"string"}}}"#,
};

/// A call.
pub const CALL: Schema = Schema {
    name: "x10.Call",
    json: r#"{"title":"x10.Call","description":"A finished call of a robot task (or of the laptop)","type":"object","properties":{"task":{"type":"string"},"board":{"type":"string","description":"SELF for the motherboard's own ports, db09 for board 9"},"op":{"type":"string"},"result":{"type":"string"},"ok":{"type":"boolean"},"start_ns":{"type":"integer"},"end_ns":{"type":"integer"},"duration_us":{"type":"number"},"text":{"type":"string"}}}"#,
};

/// An event.
pub const EVENT: Schema = Schema {
    name: "x10.Event",
    json: r#"{"title":"x10.Event","description":"An event a board sent the motherboard","type":"object","properties":{"board":{"type":"string"},"kind":{"type":"string"},"pin":{"type":"string"},"seq":{"type":"integer"},"status":{"type":"string"},"payload":{"type":"array","items":{"type":"integer"}}}}"#,
};

/// A trace line, as Foxglove's own `foxglove.Log` (its Log panel shows it).
pub const LOG: Schema = Schema {
    name: "foxglove.Log",
    json: r#"{"title":"foxglove.Log","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0}}},"level":{"type":"integer","description":"1 debug, 2 info, 3 warning, 4 error, 5 fatal"},"message":{"type":"string"},"name":{"type":"string"},"file":{"type":"string"},"line":{"type":"integer","minimum":0}}}"#,
};

/// The topic of calls.
pub const CALLS_TOPIC: &str = "/x10/calls";
/// The topic of events.
pub const EVENTS_TOPIC: &str = "/x10/events";
/// The topic of trace lines.
pub const LOG_TOPIC: &str = "/x10/log";

/// One message: its topic, schema, log time (ns) and JSON.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    /// The topic.
    pub topic: String,
    /// Its schema.
    pub schema: &'static Schema,
    /// When, ns of the motherboard's clock.
    pub log_time_ns: u64,
    /// The message.
    pub data: Value,
}

/// The kind and value of an output change, as its topic and message name them.
pub fn output_value(c: &Change) -> (&'static str, u32) {
    match c {
        Change::Digital(l) => ("level", u32::from(l.is_high())),
        Change::Duty(d) => ("pwm", u32::from(*d)),
        Change::Frequency(hz) => ("frequency_hz", u32::from(*hz)),
        Change::PulseWidth(us) => ("pulse_us", u32::from(*us)),
    }
}

/// The pin an output change names: `A1.A`, or the port (`A1`) for a port-wide frequency.
fn output_pin(c: &OutputChange) -> String {
    match c.change {
        Change::Frequency(_) => c.pin.port.to_string(),
        _ => c.pin.to_string(),
    }
}

/// The topic of an output change: `/x10/outputs/db09/A1_A/pwm` (no dot in a topic: Foxglove's
/// message paths would need it quoted).
pub fn output_topic(c: &OutputChange) -> String {
    let (kind, _) = output_value(&c.change);
    format!(
        "/x10/outputs/{}/{}/{kind}",
        c.board,
        output_pin(c).replace('.', "_")
    )
}

/// The output device of `world` on the change's board and port.
pub fn device_of(world: &World, c: &OutputChange) -> Option<String> {
    world
        .devices()
        .iter()
        .find(|d| {
            d.kind().is_output()
                && d.port_number() == c.pin.port.number()
                && world.board_of(d).map(|b| b.log_name()).as_deref() == Some(c.board.as_str())
        })
        .map(|d| d.name().to_string())
}

/// The message of an output change (`device`: the world's device on its port, when known).
pub fn output_message(c: &OutputChange, device: Option<&str>) -> Message {
    let (kind, value) = output_value(&c.change);
    let mut data = json!({
        "board": c.board,
        "pin": output_pin(c),
        "kind": kind,
        "value": value,
        "text": c.to_string(),
    });
    if let (Some(d), Some(obj)) = (device, data.as_object_mut()) {
        obj.insert("device".into(), Value::String(d.to_string()));
    }
    Message {
        topic: output_topic(c),
        schema: &OUTPUT,
        log_time_ns: c.t_ns,
        data,
    }
}

/// A call's text (`db09 io high A1.B -> ok in 450us`) split into board, operation and
/// result.
fn split_call(text: &str) -> (&str, &str, &str) {
    let (board, rest) = text.split_once(' ').unwrap_or((text, ""));
    let (op, rest) = rest.split_once(" -> ").unwrap_or((rest, ""));
    let result = rest.rsplit_once(" in ").map_or(rest, |(r, _)| r);
    (board, op, result)
}

/// The message of a call, at the time it ended.
pub fn call_message(c: &CallSpan) -> Message {
    let (board, op, result) = split_call(&c.text);
    Message {
        topic: CALLS_TOPIC.to_string(),
        schema: &CALL,
        log_time_ns: c.end_ns,
        data: json!({
            "task": c.task,
            "board": board,
            "op": op,
            "result": result,
            "ok": c.ok,
            "start_ns": c.start_ns,
            "end_ns": c.end_ns,
            "duration_us": c.end_ns.saturating_sub(c.start_ns) as f64 / 1_000.0,
            "text": c.text,
        }),
    }
}

/// An event the motherboard routed, owned.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EventRecord {
    /// When (ns).
    pub t_ns: u64,
    /// The board it came from.
    pub db: u8,
    /// Its kind.
    pub kind: EventKind,
    /// Its port and pin.
    pub pin: PinRef,
    /// Its sequence number or counter.
    pub seq: u8,
    /// Its status byte.
    pub status: u8,
    /// Its value bytes.
    pub payload: Vec<u8>,
}

impl EventRecord {
    /// The event of a link record.
    pub fn from_link(e: &EventRec<'_>) -> EventRecord {
        EventRecord {
            t_ns: e.at_us.saturating_mul(1_000),
            db: e.db,
            kind: EventKind::from_byte(e.kind),
            pin: PinRef::from_byte(e.port),
            seq: e.seq,
            status: e.status,
            payload: e.payload.to_vec(),
        }
    }

    /// The event a bus transaction carried to the motherboard at `mb` (a write to it that
    /// ended well and parses as an event, with or without its check), at the end of the
    /// transaction.
    pub fn from_bus(rec: &BusRecord, mb: Address) -> Option<EventRecord> {
        if rec.is_read || rec.addr != mb.get() || rec.outcome != BusOutcome::Ok {
            return None;
        }
        let ev = Event::parse(&rec.written)
            .or_else(|_| Event::parse_with_pec(mb, &rec.written))
            .ok()?;
        Some(EventRecord {
            t_ns: rec.end_ns,
            db: ev.source.get(),
            kind: ev.kind,
            pin: ev.pin,
            seq: ev.seq,
            status: ev.status.to_byte(),
            payload: ev.payload.to_vec(),
        })
    }
}

/// The message of an event.
pub fn event_message(e: &EventRecord) -> Message {
    Message {
        topic: EVENTS_TOPIC.to_string(),
        schema: &EVENT,
        log_time_ns: e.t_ns,
        data: json!({
            "board": crate::monitor::board_name(e.db),
            "kind": e.kind.name(),
            "pin": e.pin.to_string(),
            "seq": e.seq,
            "status": Status::from_byte(e.status).name(),
            "payload": e.payload,
        }),
    }
}

/// The message of a trace line (`foxglove.Log`: level 1 debug, 2 info, 3 warning, 4 error).
pub fn log_message(l: &TraceLine) -> Message {
    let level = match l.severity {
        Severity::Debug => 1,
        Severity::Info => 2,
        Severity::Warn => 3,
        Severity::Error => 4,
    };
    Message {
        topic: LOG_TOPIC.to_string(),
        schema: &LOG,
        log_time_ns: l.t_ns,
        data: json!({
            "timestamp": {"sec": l.t_ns / 1_000_000_000, "nsec": l.t_ns % 1_000_000_000},
            "level": level,
            "message": l.text,
            "name": l.source,
            "file": "",
            "line": 0,
        }),
    }
}

/// Every message of a simulator run, in time order (at one time: outputs, calls, events,
/// then trace lines): the robot's output changes (`outcome.log`), calls, the events its bus
/// carried to the motherboard at `mb` and its trace.
pub fn sim_messages(world: &World, outcome: &SimOutcome, mb: Address) -> Vec<Message> {
    let mut out: Vec<Message> = outcome
        .log
        .changes()
        .iter()
        .map(|c| output_message(c, device_of(world, c).as_deref()))
        .collect();
    out.extend(outcome.calls.iter().map(call_message));
    out.extend(
        outcome
            .records
            .iter()
            .filter_map(|r| EventRecord::from_bus(r, mb))
            .map(|e| event_message(&e)),
    );
    out.extend(outcome.trace.lines().iter().map(log_message));
    out.sort_by_key(|m| m.log_time_ns);
    out
}

/// Why an MCAP file could not be written.
#[derive(Debug)]
pub struct McapError(pub String);

impl std::fmt::Display for McapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for McapError {}

impl From<mcap::McapError> for McapError {
    fn from(e: mcap::McapError) -> McapError {
        McapError(e.to_string())
    }
}

/// An MCAP file being written: a channel per topic (JSON messages, `jsonschema` schemas),
/// added as its first message comes.
pub struct McapOut<W: Write + Seek> {
    writer: mcap::Writer<W>,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, u16>,
    sequence: u32,
}

impl<W: Write + Seek> std::fmt::Debug for McapOut<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapOut")
            .field("channels", &self.channels)
            .field("sequence", &self.sequence)
            .finish_non_exhaustive()
    }
}

impl McapOut<std::io::BufWriter<std::fs::File>> {
    /// Creates the file at `path`.
    ///
    /// # Errors
    /// The file cannot be created or written.
    pub fn create(path: &std::path::Path) -> Result<Self, McapError> {
        let file = std::fs::File::create(path).map_err(|e| McapError(e.to_string()))?;
        McapOut::new(std::io::BufWriter::new(file))
    }
}

impl<W: Write + Seek> McapOut<W> {
    /// An MCAP file written to `w` (profile `x10`, uncompressed).
    ///
    /// # Errors
    /// The header cannot be written.
    pub fn new(w: W) -> Result<Self, McapError> {
        let writer = mcap::WriteOptions::new()
            .profile("x10")
            .compression(None)
            .create(w)?;
        Ok(McapOut {
            writer,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            sequence: 0,
        })
    }

    fn channel(&mut self, m: &Message) -> Result<u16, McapError> {
        if let Some(id) = self.channels.get(&m.topic) {
            return Ok(*id);
        }
        let schema = match self.schemas.get(m.schema.name) {
            Some(id) => *id,
            None => {
                let id = self.writer.add_schema(
                    m.schema.name,
                    "jsonschema",
                    m.schema.json.as_bytes(),
                )?;
                self.schemas.insert(m.schema.name, id);
                id
            }
        };
        let id = self
            .writer
            .add_channel(schema, &m.topic, "json", &Default::default())?;
        self.channels.insert(m.topic.clone(), id);
        Ok(id)
    }

    /// Writes `m` (its channel first, the first time its topic comes).
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write(&mut self, m: &Message) -> Result<(), McapError> {
        let channel_id = self.channel(m)?;
        self.writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id,
                sequence: self.sequence,
                log_time: m.log_time_ns,
                publish_time: m.log_time_ns,
            },
            m.data.to_string().as_bytes(),
        )?;
        self.sequence = self.sequence.wrapping_add(1);
        Ok(())
    }

    /// Writes the index and the footer; returns the writer.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn finish(mut self) -> Result<W, McapError> {
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
}

/// Writes `messages` as an MCAP file at `path`.
///
/// # Errors
/// The file cannot be created or written.
pub fn write_file(path: &std::path::Path, messages: &[Message]) -> Result<(), McapError> {
    let mut out = McapOut::create(path)?;
    for m in messages {
        out.write(m)?;
    }
    let mut w = out.finish()?;
    w.flush().map_err(|e| McapError(e.to_string()))
}

/// What of a [`LinkRun`] was already turned into messages: each call from `x10 monitor`'s
/// loop takes the records that came since.
#[derive(Debug, Default)]
pub struct LinkCursor {
    calls: usize,
    outputs: usize,
    events: usize,
}

impl LinkCursor {
    /// A cursor at the start of a run.
    pub fn new() -> LinkCursor {
        LinkCursor::default()
    }

    /// The messages of the records `run` got since the last call, and of the trace `lines`
    /// they printed, in time order (`world`: the devices' names, when known).
    pub fn take(
        &mut self,
        run: &LinkRun,
        lines: &[TraceLine],
        world: Option<&World>,
    ) -> Vec<Message> {
        let outputs = run.outputs.get(self.outputs..).unwrap_or(&[]);
        let calls = run.calls.get(self.calls..).unwrap_or(&[]);
        let events = run.event_records.get(self.events..).unwrap_or(&[]);
        let mut out: Vec<Message> = outputs
            .iter()
            .map(|c| output_message(c, world.and_then(|w| device_of(w, c)).as_deref()))
            .collect();
        out.extend(calls.iter().map(call_message));
        out.extend(events.iter().map(event_message));
        out.extend(lines.iter().map(log_message));
        out.sort_by_key(|m| m.log_time_ns);
        self.outputs = run.outputs.len();
        self.calls = run.calls.len();
        self.events = run.event_records.len();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use x10_microcode::{Level, Port};

    #[test]
    fn calls_are_split_into_board_operation_and_result() {
        assert_eq!(
            split_call("db09 io high A1.B -> ok in 450us"),
            ("db09", "io high A1.B", "ok")
        );
        assert_eq!(
            split_call("SELF analog S1 -> error: no reply in time in 2.5ms"),
            ("SELF", "analog S1", "error: no reply in time")
        );
        assert_eq!(split_call("odd"), ("odd", "", ""));
    }

    #[test]
    fn output_changes_become_plottable_topics() {
        let a1 = Port::actuator(1).unwrap();
        let change = |c| OutputChange {
            t_ns: 2_000_463_000,
            board: "db09".into(),
            pin: a1.pin(x10_microcode::Pin::A),
            change: c,
        };
        let m = output_message(&change(Change::Duty(127)), Some("motor2"));
        assert_eq!(m.topic, "/x10/outputs/db09/A1_A/pwm");
        assert_eq!(m.log_time_ns, 2_000_463_000);
        assert_eq!(
            m.data.to_string(),
            r#"{"board":"db09","device":"motor2","kind":"pwm","pin":"A1.A","text":"db09 A1.A pwm 127","value":127}"#
        );
        let m = output_message(&change(Change::Digital(Level::High)), None);
        assert_eq!(m.topic, "/x10/outputs/db09/A1_A/level");
        assert_eq!(m.data["value"], 1);
        let m = output_message(&change(Change::Frequency(20_000)), None);
        assert_eq!(m.topic, "/x10/outputs/db09/A1/frequency_hz");
        assert_eq!(m.data["pin"], "A1");
        assert_eq!(m.data["value"], 20_000);
        let m = output_message(&change(Change::PulseWidth(1_500)), None);
        assert_eq!(m.topic, "/x10/outputs/db09/A1_A/pulse_us");
    }

    #[test]
    fn trace_lines_are_foxglove_logs() {
        let l = TraceLine::new(3_000_000_123, Severity::Warn, "robot", "SELF x -> error");
        let m = log_message(&l);
        assert_eq!(m.topic, "/x10/log");
        assert_eq!(
            m.data.to_string(),
            r#"{"file":"","level":3,"line":0,"message":"SELF x -> error","name":"robot","timestamp":{"nsec":123,"sec":3}}"#
        );
    }

    #[test]
    fn link_events_become_event_messages() {
        let rec = EventRec {
            db: 9,
            kind: 1,
            port: 0x80,
            seq: 4,
            status: 0,
            payload: &[1],
            at_us: 1_500,
        };
        let m = event_message(&EventRecord::from_link(&rec));
        assert_eq!(m.log_time_ns, 1_500_000);
        assert_eq!(
            m.data.to_string(),
            r#"{"board":"db09","kind":"pin_change","payload":[1],"pin":"S1.A","seq":4,"status":"ok"}"#
        );
    }
}
