//! Frames ⇄ JSON, and frames in words: the `x10 decode` / `x10 encode` commands.
//!
//! Everything here is a pure function from bytes to [`serde_json::Value`] and back, so it is
//! unit-testable without the binary. The JSON shape is specified in `docs/protocol.md`
//! ("The `x10` tool"); in short:
//!
//! * request: `kind`, `function`, `operation`, `db`, `port_kind`, `port`, `pin`, `seq`, `data`,
//!   plus the operation's own fields (`duty`, `timeout_ms`, `items`, …);
//! * reply: `kind`, `seq`, `status`, `payload`, plus, when it is known which request the reply
//!   answers (`answers`), the decoded value (`level`, `value`, `identity`, `results`, …);
//! * event: `kind`, `source`, `event`, `port_kind`, `port`, `pin`, `seq`, `status`, `payload`,
//!   plus the decoded value of the kind (`level`, `width_us`, `identity`, …);
//! * with PEC: `pec_addr` (the address the PEC covers) and `pec` (the PEC byte).
//!
//! [`encode`] is the exact inverse of [`decode`]: it accepts what `decode` prints (and fewer
//! keys: `data` and `payload` can be left out and are then built from the decoded fields), and
//! refuses unknown keys and keys that disagree with the bytes.

use std::fmt;

use serde_json::{json, Map, Value};
use x10_microcode::{
    pec, Address, BatchResults, BoardKind, Capabilities, Diagnostics, Event, EventConfig,
    EventKind, Identity, Op, PinRef, PortKind, Reply, Request, ScanResult, Status,
    DIAGNOSTIC_NAMES, MAX_FRAME_LEN, MAX_PAYLOAD, MAX_REQUEST_DATA,
};

/// Why a frame or a JSON object could not be decoded or encoded: one line for people.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CodecError(String);

impl CodecError {
    fn new(msg: impl Into<String>) -> CodecError {
        CodecError(msg.into())
    }

    fn frame(kind: FrameKind, e: x10_microcode::Error) -> CodecError {
        CodecError(format!(
            "invalid {}: {e} (a board answers status {})",
            kind.name(),
            e.status().name()
        ))
    }
}

impl fmt::Display for CodecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CodecError {}

/// Result of this module.
pub type Result<T> = std::result::Result<T, CodecError>;

/// The three frame kinds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameKind {
    /// MB → DB.
    Request,
    /// DB → MB, the read half of a transaction.
    Reply,
    /// DB → MB, written by a DB acting as master.
    Event,
}

impl FrameKind {
    /// `request`, `reply` or `event`, as in the JSON `kind` key.
    pub const fn name(self) -> &'static str {
        match self {
            FrameKind::Request => "request",
            FrameKind::Reply => "reply",
            FrameKind::Event => "event",
        }
    }

    /// Inverse of [`FrameKind::name`].
    pub fn from_name(name: &str) -> Option<FrameKind> {
        [FrameKind::Request, FrameKind::Reply, FrameKind::Event]
            .into_iter()
            .find(|k| k.name() == name)
    }
}

// ---------------------------------------------------------------------------------------------
// Hex
// ---------------------------------------------------------------------------------------------

/// Splits an optional `request:`, `reply:` or `event:` prefix off a frame argument.
pub fn split_prefix(arg: &str) -> (Option<FrameKind>, &str) {
    let arg = arg.trim();
    if let Some((head, rest)) = arg.split_once(':') {
        if let Some(kind) = FrameKind::from_name(head.trim()) {
            return (Some(kind), rest);
        }
    }
    (None, arg)
}

/// Parses hex bytes: pairs of hex digits, optionally separated by spaces, `:`, `,`, `-` or
/// `_`, each group optionally prefixed `0x`. `12090102`, `12 09 01 02`, `12:09:01:02` and
/// `0x12,0x09,0x01,0x02` are the same frame.
///
/// # Errors
/// A character that is not a hex digit, a group with an odd number of digits, no bytes at all.
pub fn parse_hex(text: &str) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for group in text
        .split(|c: char| c.is_whitespace() || matches!(c, ':' | ',' | '-' | '_'))
        .filter(|g| !g.is_empty())
    {
        let digits = group
            .strip_prefix("0x")
            .or_else(|| group.strip_prefix("0X"))
            .unwrap_or(group);
        if let Some(bad) = digits.chars().find(|c| !c.is_ascii_hexdigit()) {
            return Err(CodecError::new(format!(
                "`{bad}` is not a hex digit (in `{group}`)"
            )));
        }
        if digits.is_empty() || digits.len() % 2 != 0 {
            return Err(CodecError::new(format!(
                "`{group}` has an odd number of hex digits"
            )));
        }
        for pair in digits.as_bytes().chunks(2) {
            let s = std::str::from_utf8(pair).map_err(|_| CodecError::new("bad hex"))?;
            let b = u8::from_str_radix(s, 16)
                .map_err(|_| CodecError::new(format!("`{s}` is not a hex byte")))?;
            out.push(b);
        }
    }
    if out.is_empty() {
        return Err(CodecError::new("no bytes given"));
    }
    Ok(out)
}

/// Lowercase hex, one space between bytes: the format [`parse_hex`] reads.
pub fn to_hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The frames given as command-line arguments. One argument is one frame, in any form
/// [`parse_hex`] reads, except when there are two or more arguments and every one is a single
/// byte — one or two hex digits, optionally prefixed `0x` — as logic analyzers print them: then
/// they are the bytes of one frame, and the first may carry a `request:`, `reply:` or `event:`
/// prefix. `12 09 01 02` (four arguments) is the frame `12 09 01 02`; `12090102 30098004` are
/// two frames. A frame of one byte is too short for every kind, so this does not change what
/// any valid input means.
pub fn frames_of_args(args: Vec<String>) -> Vec<String> {
    fn byte(arg: &str) -> Option<u8> {
        let arg = arg.trim();
        let digits = arg
            .strip_prefix("0x")
            .or_else(|| arg.strip_prefix("0X"))
            .unwrap_or(arg);
        if (1..=2).contains(&digits.len()) && digits.chars().all(|c| c.is_ascii_hexdigit()) {
            u8::from_str_radix(digits, 16).ok()
        } else {
            None
        }
    }
    let Some((first, rest)) = args.split_first() else {
        return args;
    };
    if rest.is_empty() {
        return args;
    }
    let (prefix, first) = split_prefix(first);
    let bytes: Option<Vec<u8>> = std::iter::once(first)
        .chain(rest.iter().map(String::as_str))
        .map(byte)
        .collect();
    match bytes {
        Some(bytes) => {
            let prefix = prefix.map_or(String::new(), |k| format!("{}:", k.name()));
            vec![format!("{prefix}{}", to_hex(&bytes))]
        }
        None => args,
    }
}

/// Parses an address given on the command line: decimal, or hex with `0x`.
///
/// # Errors
/// Not a number, or not a valid address (0 or `0x08..=0x77`).
pub fn parse_address(text: &str) -> Result<Address> {
    let t = text.trim();
    let n = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => u8::from_str_radix(h, 16),
        None => t.parse::<u8>(),
    }
    .map_err(|_| CodecError::new(format!("`{text}` is not an address (0..=0x77)")))?;
    Address::new(n).map_err(|e| CodecError::new(e.to_string()))
}

// ---------------------------------------------------------------------------------------------
// The operation table
// ---------------------------------------------------------------------------------------------

/// What byte 2 of an operation names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PortUse {
    /// The whole board: byte 2 is 0, the JSON port keys are null.
    Board,
    /// A pin of a port.
    Pin,
    /// A port; the pin bit is 0 (pin "A" in JSON).
    Port,
}

/// One operation as the tool names it.
struct OpInfo {
    function: &'static str,
    operation: &'static str,
    fn_op: u8,
    port: PortUse,
    /// Keys of the operation's own fields.
    fields: &'static [&'static str],
    /// True when the MB reads a reply.
    reply: bool,
}

const fn op(
    function: &'static str,
    operation: &'static str,
    fn_op: u8,
    port: PortUse,
    fields: &'static [&'static str],
    reply: bool,
) -> OpInfo {
    OpInfo {
        function,
        operation,
        fn_op,
        port,
        fields,
        reply,
    }
}

const EVENT_ENABLE_FIELDS: &[&str] = &["rising", "falling", "analog_window", "low", "high"];

/// Every operation (docs/protocol.md, "Functions and operands").
const OPS: &[OpInfo] = &[
    op("system", "ping", 0x00, PortUse::Board, &[], true),
    op("system", "identify", 0x01, PortUse::Board, &[], true),
    op("system", "heartbeat", 0x02, PortUse::Board, &[], false),
    op(
        "system",
        "set_failsafe",
        0x03,
        PortUse::Board,
        &["timeout_ms"],
        false,
    ),
    op(
        "system",
        "event_enable",
        0x04,
        PortUse::Pin,
        EVENT_ENABLE_FIELDS,
        false,
    ),
    op(
        "system",
        "read_diagnostics",
        0x05,
        PortUse::Board,
        &[],
        true,
    ),
    op(
        "system",
        "clear_diagnostics",
        0x06,
        PortUse::Board,
        &[],
        false,
    ),
    op("system", "set_pec", 0x07, PortUse::Board, &["on"], false),
    op("io", "input", 0x10, PortUse::Pin, &[], true),
    op("io", "low", 0x11, PortUse::Pin, &[], false),
    op("io", "high", 0x12, PortUse::Pin, &[], false),
    op(
        "io",
        "pulse_in_rising",
        0x13,
        PortUse::Pin,
        &["timeout_ms"],
        true,
    ),
    op(
        "io",
        "pulse_in_falling",
        0x14,
        PortUse::Pin,
        &["timeout_ms"],
        true,
    ),
    op("pwm", "duty", 0x20, PortUse::Pin, &["duty"], false),
    op("pwm", "frequency", 0x21, PortUse::Port, &["hz"], false),
    op("pwm", "pulse_width", 0x22, PortUse::Pin, &["us"], false),
    op("analog", "read", 0x30, PortUse::Port, &[], true),
    op("serial", "write", 0x40, PortUse::Port, &[], false),
    op("serial", "read", 0x41, PortUse::Port, &["count"], true),
    op("serial", "config", 0x42, PortUse::Port, &["baud"], false),
    op("batch", "batch", 0x50, PortUse::Board, &["items"], true),
    op("scan", "scan", 0x60, PortUse::Board, &[], true),
];

fn op_info(function: &str, operation: &str) -> Option<&'static OpInfo> {
    OPS.iter()
        .find(|o| o.function == function && o.operation == operation)
}

/// Keys every request (and batch item) may carry besides its operation's fields.
const REQUEST_KEYS: &[&str] = &[
    "kind",
    "function",
    "operation",
    "db",
    "port_kind",
    "port",
    "pin",
    "seq",
    "data",
    "pec_addr",
    "pec",
];
const ITEM_KEYS: &[&str] = &["function", "operation", "port_kind", "port", "pin", "data"];
const REPLY_KEYS: &[&str] = &[
    "kind",
    "seq",
    "status",
    "payload",
    "answers",
    "level",
    "value",
    "identity",
    "diagnostics",
    "scan",
    "results",
    "pec_addr",
    "pec",
];
const EVENT_KEYS: &[&str] = &[
    "kind",
    "source",
    "event",
    "port_kind",
    "port",
    "pin",
    "seq",
    "status",
    "payload",
    "level",
    "value",
    "inside",
    "width_us",
    "timeout_ms",
    "dropped",
    "identity",
    "rising_edges",
    "falling_edges",
    "dropped_total",
    "pec_addr",
    "pec",
];

// ---------------------------------------------------------------------------------------------
// What a reply answers
// ---------------------------------------------------------------------------------------------

/// Which request a reply answers, so that its payload can be decoded: an operation name
/// `function.operation` (`io.input`, `analog.read`, `system.identify`, …) and, for a batch, the
/// names of its items in order (`None` for an item whose operation is unknown).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Answers {
    /// `function.operation` of the request.
    pub name: String,
    /// For a batch: `function.operation` of each item, in order.
    pub items: Vec<Option<String>>,
}

impl Answers {
    /// Checks an operation name given by a user.
    ///
    /// # Errors
    /// Unknown operation, or one that has no reply.
    pub fn parse(name: &str) -> Result<Answers> {
        let (function, operation) = name.split_once('.').ok_or_else(|| {
            CodecError::new(format!(
                "`{name}` is not function.operation (e.g. io.input, analog.read)"
            ))
        })?;
        let info = op_info(function, operation)
            .ok_or_else(|| CodecError::new(format!("unknown operation `{name}`")))?;
        if !info.reply {
            return Err(CodecError::new(format!("{name} has no reply")));
        }
        Ok(Answers {
            name: name.to_string(),
            items: Vec::new(),
        })
    }

    /// What a reply to `op` answers, or `None` when `op` has no reply.
    pub fn of(op: &Op<'_>) -> Option<Answers> {
        if !op.expects_reply() {
            return None;
        }
        let items = match op {
            Op::Batch(b) => b.iter().map(|i| Some(full_name(&i))).collect(),
            _ => Vec::new(),
        };
        Some(Answers {
            name: full_name(op),
            items,
        })
    }

    /// What a reply to the decoded request `request` answers (see [`decode`]).
    pub fn of_request(request: &Value) -> Option<Answers> {
        let o = request.as_object()?;
        if o.get("kind").and_then(Value::as_str) != Some("request") {
            return None;
        }
        let name = op_name_of(o)?;
        let info = name
            .split_once('.')
            .and_then(|(f, op)| op_info(f, op))
            .filter(|i| i.reply)?;
        let items = if info.function == "batch" {
            o.get("items")?
                .as_array()?
                .iter()
                .map(|i| i.as_object().and_then(op_name_of))
                .collect()
        } else {
            Vec::new()
        };
        Some(Answers { name, items })
    }
}

fn op_name_of(o: &Map<String, Value>) -> Option<String> {
    Some(format!(
        "{}.{}",
        o.get("function")?.as_str()?,
        o.get("operation")?.as_str()?
    ))
}

fn full_name(op: &Op<'_>) -> String {
    format!("{}.{}", op.function().name(), op.name())
}

// ---------------------------------------------------------------------------------------------
// Decoding
// ---------------------------------------------------------------------------------------------

/// How to read one frame.
#[derive(Clone, Debug)]
pub struct DecodeOptions {
    /// The frame kind.
    pub kind: FrameKind,
    /// With PEC: the address it covers (the DB for requests and replies, the MB for events).
    pub pec: Option<Address>,
    /// For replies: what the reply answers.
    pub answers: Option<Answers>,
}

impl DecodeOptions {
    /// A frame of `kind` without PEC.
    pub fn new(kind: FrameKind) -> DecodeOptions {
        DecodeOptions {
            kind,
            pec: None,
            answers: None,
        }
    }
}

/// Decodes one frame into its JSON object.
///
/// # Errors
/// The frame does not parse (the message names the error and the status a board would
/// answer), or its PEC does not match.
pub fn decode(bytes: &[u8], opts: &DecodeOptions) -> Result<Value> {
    let (frame, pec_byte) = match opts.pec {
        Some(addr) => {
            let read = opts.kind == FrameKind::Reply;
            let frame = pec::strip(addr.addr_byte(read), bytes)
                .map_err(|e| CodecError::frame(opts.kind, e))?;
            (frame, bytes.last().copied())
        }
        None => (bytes, None),
    };
    let mut v = match opts.kind {
        FrameKind::Request => {
            let r = Request::parse(frame).map_err(|e| CodecError::frame(opts.kind, e))?;
            request_value(&r)
        }
        FrameKind::Reply => {
            let r = Reply::parse(frame).map_err(|e| CodecError::frame(opts.kind, e))?;
            reply_value(&r, opts.answers.as_ref())
        }
        FrameKind::Event => {
            let e = Event::parse(frame).map_err(|e| CodecError::frame(opts.kind, e))?;
            event_value(&e)
        }
    };
    if let (Some(addr), Some(p)) = (opts.pec, pec_byte) {
        v.insert("pec_addr".into(), json!(addr.get()));
        v.insert("pec".into(), json!(p));
    }
    Ok(Value::Object(v))
}

fn port_keys(m: &mut Map<String, Value>, pin: Option<PinRef>) {
    match pin {
        Some(p) => {
            let kind = match p.port.kind() {
                PortKind::Sensor => "sensor",
                PortKind::Actuator => "actuator",
            };
            let pin = match p.pin {
                x10_microcode::Pin::A => "A",
                x10_microcode::Pin::B => "B",
            };
            m.insert("port_kind".into(), json!(kind));
            m.insert("port".into(), json!(p.port.number()));
            m.insert("pin".into(), json!(pin));
        }
        None => {
            for k in ["port_kind", "port", "pin"] {
                m.insert(k.into(), Value::Null);
            }
        }
    }
}

fn op_value(op: &Op<'_>) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("function".into(), json!(op.function().name()));
    m.insert("operation".into(), json!(op.name()));
    port_keys(&mut m, op.pin_ref());
    let mut data = [0u8; MAX_REQUEST_DATA];
    let n = op.emit_data(&mut data).unwrap_or(0);
    m.insert("data".into(), json!(data.get(..n).unwrap_or(&[])));
    match *op {
        Op::SetFailsafe { timeout_ms } => {
            m.insert("timeout_ms".into(), json!(timeout_ms));
        }
        Op::EventEnable(_, cfg) => {
            m.insert("rising".into(), json!(cfg.rising));
            m.insert("falling".into(), json!(cfg.falling));
            m.insert("analog_window".into(), json!(cfg.analog_window));
            m.insert("low".into(), json!(cfg.low));
            m.insert("high".into(), json!(cfg.high));
        }
        Op::SetPec(on) => {
            m.insert("on".into(), json!(on));
        }
        Op::PulseIn { timeout_ms, .. } => {
            m.insert("timeout_ms".into(), json!(timeout_ms));
        }
        Op::PwmDuty(_, duty) => {
            m.insert("duty".into(), json!(duty));
        }
        Op::PwmFrequency(_, hz) => {
            m.insert("hz".into(), json!(hz));
        }
        Op::PwmPulseWidth(_, us) => {
            m.insert("us".into(), json!(us));
        }
        Op::SerialRead(_, count) => {
            m.insert("count".into(), json!(count));
        }
        Op::SerialConfig(_, baud) => {
            m.insert("baud".into(), json!(baud));
        }
        Op::Batch(b) => {
            let items: Vec<Value> = b.iter().map(|i| Value::Object(op_value(&i))).collect();
            m.insert("items".into(), Value::Array(items));
        }
        Op::Ping
        | Op::Identify
        | Op::Heartbeat
        | Op::ReadDiagnostics
        | Op::ClearDiagnostics
        | Op::DigitalRead(_)
        | Op::DigitalWrite(..)
        | Op::AnalogRead(_)
        | Op::SerialWrite(..)
        | Op::Scan => {}
    }
    m
}

fn request_value(r: &Request<'_>) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("kind".into(), json!("request"));
    m.insert("db".into(), json!(r.db.get()));
    m.insert("seq".into(), json!(r.seq));
    m.extend(op_value(&r.op));
    m
}

fn status_value(s: Status) -> Value {
    match s {
        Status::Unknown(x) => json!(x),
        s => json!(s.name()),
    }
}

fn identity_value(id: &Identity) -> Value {
    let board = match id.board.name() {
        "unknown" if id.board != BoardKind::UNKNOWN => json!(id.board.0),
        name => json!(name),
    };
    json!({
        "protocol_version": id.protocol_version,
        "firmware": id.firmware,
        "board": board,
        "sensor_ports": id.sensor_ports,
        "actuator_ports": id.actuator_ports,
        "capabilities": id.capabilities.0,
        "adc_bits": id.adc_bits,
    })
}

fn diagnostics_value(d: &Diagnostics) -> Value {
    let m: Map<String, Value> = DIAGNOSTIC_NAMES
        .iter()
        .zip(d.values())
        .map(|(k, v)| ((*k).to_string(), json!(v)))
        .collect();
    Value::Object(m)
}

fn scan_value(s: &ScanResult) -> Value {
    let analog = s.analog.get(..s.ports as usize).unwrap_or(&[]);
    json!({"ports": s.ports, "digital": s.digital, "analog": analog})
}

/// The decoded value of a reply payload that answers `name` (empty when the payload does not
/// have the shape that answer has).
fn interpret(name: &str, items: &[Option<String>], payload: &[u8]) -> Map<String, Value> {
    let mut m = Map::new();
    match name {
        "io.input" => {
            if let [level] = *payload {
                m.insert("level".into(), json!(level));
            }
        }
        "analog.read" => {
            if let [a, b] = *payload {
                m.insert("value".into(), json!(u16::from_le_bytes([a, b])));
            }
        }
        "system.identify" => {
            if let Ok(id) = Identity::parse(payload) {
                m.insert("identity".into(), identity_value(&id));
            }
        }
        "system.read_diagnostics" => {
            if let Ok(d) = Diagnostics::parse(payload) {
                m.insert("diagnostics".into(), diagnostics_value(&d));
            }
        }
        "scan.scan" => {
            if let Ok(s) = ScanResult::parse(payload) {
                m.insert("scan".into(), scan_value(&s));
            }
        }
        "batch.batch" => {
            let results: std::result::Result<Vec<_>, _> = BatchResults::new(payload).collect();
            if let Ok(results) = results {
                let list = results
                    .iter()
                    .enumerate()
                    .map(|(i, r)| {
                        let mut o = Map::new();
                        o.insert("status".into(), status_value(r.status));
                        o.insert("payload".into(), json!(r.value));
                        if let Some(Some(item)) = items.get(i) {
                            o.insert("answers".into(), json!(item));
                            if r.status.is_ok() {
                                o.extend(interpret(item, &[], r.value));
                            }
                        }
                        Value::Object(o)
                    })
                    .collect();
                m.insert("results".into(), Value::Array(list));
            }
        }
        _ => {}
    }
    m
}

fn reply_value(r: &Reply<'_>, answers: Option<&Answers>) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("kind".into(), json!("reply"));
    m.insert("seq".into(), json!(r.seq));
    m.insert("status".into(), status_value(r.status));
    m.insert("payload".into(), json!(r.payload));
    if let Some(a) = answers {
        m.insert("answers".into(), json!(a.name));
        if r.status.is_ok() {
            m.extend(interpret(&a.name, &a.items, r.payload));
        }
    }
    m
}

/// Event kinds that concern the whole board: byte 2 is 0 and the JSON port keys are null.
fn board_event(kind: EventKind) -> bool {
    matches!(
        kind,
        EventKind::FailsafeTripped | EventKind::Overflow | EventKind::Boot
    )
}

fn event_value(e: &Event<'_>) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("kind".into(), json!("event"));
    m.insert("source".into(), json!(e.source.get()));
    let kind = match e.kind {
        EventKind::Unknown(x) => json!(x),
        k => json!(k.name()),
    };
    m.insert("event".into(), kind);
    let pin = if board_event(e.kind) && e.pin.to_byte() == 0 {
        None
    } else {
        Some(e.pin)
    };
    port_keys(&mut m, pin);
    m.insert("seq".into(), json!(e.seq));
    m.insert("status".into(), status_value(e.status));
    m.insert("payload".into(), json!(e.payload));
    let p = e.payload;
    match (e.kind, p) {
        (EventKind::PinChange, &[level]) => {
            m.insert("level".into(), json!(level));
        }
        (EventKind::PinChange, &[level, r0, r1, f0, f1]) => {
            m.insert("level".into(), json!(level));
            m.insert("rising_edges".into(), json!(u16::from_le_bytes([r0, r1])));
            m.insert("falling_edges".into(), json!(u16::from_le_bytes([f0, f1])));
        }
        (EventKind::AnalogThreshold, &[a, b, inside]) if inside <= 1 => {
            m.insert("value".into(), json!(u16::from_le_bytes([a, b])));
            m.insert("inside".into(), json!(inside == 1));
        }
        (EventKind::DeferredReply, &[a, b, c, d]) => {
            m.insert("width_us".into(), json!(u32::from_le_bytes([a, b, c, d])));
        }
        (EventKind::FailsafeTripped, &[a, b]) => {
            m.insert("timeout_ms".into(), json!(u16::from_le_bytes([a, b])));
        }
        (EventKind::Overflow, &[a, b]) => {
            m.insert("dropped".into(), json!(u16::from_le_bytes([a, b])));
        }
        (EventKind::Overflow, &[a, b, c, d, e, f]) => {
            m.insert("dropped".into(), json!(u16::from_le_bytes([a, b])));
            m.insert(
                "dropped_total".into(),
                json!(u32::from_le_bytes([c, d, e, f])),
            );
        }
        (EventKind::Boot, p) => {
            if let Ok(id) = Identity::parse(p) {
                m.insert("identity".into(), identity_value(&id));
            }
        }
        _ => {}
    }
    m
}

// ---------------------------------------------------------------------------------------------
// Encoding
// ---------------------------------------------------------------------------------------------

/// Reads an integer: a JSON number, or a string `0x…` in hex.
fn int_of(v: &Value) -> Option<u64> {
    match v {
        Value::Number(n) => n.as_u64(),
        Value::String(s) => {
            let h = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X"))?;
            u64::from_str_radix(h, 16).ok()
        }
        _ => None,
    }
}

fn int_in(v: &Value, key: &str, max: u64) -> Result<u64> {
    int_of(v)
        .filter(|n| *n <= max)
        .ok_or_else(|| CodecError::new(format!("`{key}` must be an integer 0..={max}, got {v}")))
}

fn get_int(o: &Map<String, Value>, key: &str, max: u64) -> Result<Option<u64>> {
    match o.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => int_in(v, key, max).map(Some),
    }
}

fn need_int(o: &Map<String, Value>, key: &str, max: u64, what: &str) -> Result<u64> {
    get_int(o, key, max)?.ok_or_else(|| CodecError::new(format!("`{key}` is required for {what}")))
}

fn u8_of(n: u64) -> u8 {
    u8::try_from(n).unwrap_or(u8::MAX)
}

fn get_bool(o: &Map<String, Value>, key: &str) -> Result<Option<bool>> {
    match o.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::Bool(b)) => Ok(Some(*b)),
        Some(v) => Err(CodecError::new(format!(
            "`{key}` must be true or false, got {v}"
        ))),
    }
}

fn get_str<'v>(o: &'v Map<String, Value>, key: &str) -> Result<Option<&'v str>> {
    match o.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(s)) => Ok(Some(s)),
        Some(v) => Err(CodecError::new(format!(
            "`{key}` must be a string, got {v}"
        ))),
    }
}

fn get_bytes(o: &Map<String, Value>, key: &str) -> Result<Option<Vec<u8>>> {
    match o.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::Array(a)) => {
            a.iter()
                .map(|v| {
                    int_of(v).filter(|n| *n <= 255).map(u8_of).ok_or_else(|| {
                        CodecError::new(format!("`{key}` holds bytes 0..=255, got {v}"))
                    })
                })
                .collect::<Result<Vec<u8>>>()
                .map(Some)
        }
        Some(v) => Err(CodecError::new(format!(
            "`{key}` must be an array of bytes, got {v}"
        ))),
    }
}

fn check_keys(o: &Map<String, Value>, allowed: &[&str], extra: &[&str], what: &str) -> Result<()> {
    match o
        .keys()
        .find(|k| !allowed.contains(&k.as_str()) && !extra.contains(&k.as_str()))
    {
        Some(k) => Err(CodecError::new(format!("unknown key `{k}` for {what}"))),
        None => Ok(()),
    }
}

/// Byte 2 from `port_kind`, `port`, `pin`.
fn port_byte(o: &Map<String, Value>, info: &OpInfo, what: &str) -> Result<u8> {
    let kind = get_str(o, "port_kind")?;
    let number = get_int(o, "port", 255)?;
    let pin = get_str(o, "pin")?;
    if info.port == PortUse::Board {
        if kind.is_some() || number.is_some() || pin.is_some() {
            return Err(CodecError::new(format!(
                "{what} is addressed to the whole board: `port_kind`, `port` and `pin` must be null or absent"
            )));
        }
        return Ok(0);
    }
    let kind = match kind {
        Some("sensor") => PortKind::Sensor,
        Some("actuator") => PortKind::Actuator,
        Some(k) => {
            return Err(CodecError::new(format!(
                "`port_kind` must be \"sensor\" or \"actuator\", got \"{k}\""
            )))
        }
        None => {
            return Err(CodecError::new(format!(
                "`port_kind` is required for {what}"
            )))
        }
    };
    let number = number.ok_or_else(|| CodecError::new(format!("`port` is required for {what}")))?;
    let port = x10_microcode::Port::new(kind, u8_of(number))
        .map_err(|_| CodecError::new(format!("`port` must be 1..=64, got {number}")))?;
    let pin = match pin {
        None | Some("A") => x10_microcode::Pin::A,
        Some("B") => x10_microcode::Pin::B,
        Some(p) => {
            return Err(CodecError::new(format!(
                "`pin` must be \"A\" or \"B\", got \"{p}\""
            )))
        }
    };
    Ok(port.pin(pin).to_byte())
}

/// Data bytes of an operation from its own fields, when `data` is not given.
fn data_from_fields(o: &Map<String, Value>, info: &OpInfo, what: &str) -> Result<Vec<u8>> {
    let le16 = |key: &str| -> Result<Vec<u8>> {
        let v = need_int(o, key, u16::MAX.into(), what)?;
        Ok(u16::try_from(v).unwrap_or(0).to_le_bytes().to_vec())
    };
    Ok(match (info.function, info.operation) {
        ("system", "set_failsafe") => le16("timeout_ms")?,
        ("system", "event_enable") => {
            let cfg = EventConfig {
                rising: get_bool(o, "rising")?.unwrap_or(false),
                falling: get_bool(o, "falling")?.unwrap_or(false),
                analog_window: get_bool(o, "analog_window")?.unwrap_or(false),
                low: u16::try_from(get_int(o, "low", u16::MAX.into())?.unwrap_or(0)).unwrap_or(0),
                high: u16::try_from(get_int(o, "high", u16::MAX.into())?.unwrap_or(0)).unwrap_or(0),
            };
            cfg.to_bytes().to_vec()
        }
        ("system", "set_pec") => {
            let on = get_bool(o, "on")?
                .ok_or_else(|| CodecError::new(format!("`on` is required for {what}")))?;
            vec![u8::from(on)]
        }
        ("io", "pulse_in_rising" | "pulse_in_falling") => match get_int(o, "timeout_ms", 0xffff)? {
            None => Vec::new(),
            Some(v) => u16::try_from(v).unwrap_or(0).to_le_bytes().to_vec(),
        },
        ("pwm", "duty") => vec![u8_of(need_int(o, "duty", 255, what)?)],
        ("pwm", "frequency") => le16("hz")?,
        ("pwm", "pulse_width") => le16("us")?,
        ("serial", "write") => {
            return Err(CodecError::new(format!(
                "`data` (the bytes to send) is required for {what}"
            )))
        }
        ("serial", "read") => vec![u8_of(need_int(o, "count", 255, what)?)],
        ("serial", "config") => {
            let v = need_int(o, "baud", u32::MAX.into(), what)?;
            u32::try_from(v).unwrap_or(0).to_le_bytes().to_vec()
        }
        ("batch", "batch") => {
            let items = match o.get("items") {
                Some(Value::Array(items)) => items,
                _ => {
                    return Err(CodecError::new(
                        "`items` (an array of operations) is required for batch",
                    ))
                }
            };
            let mut out = Vec::new();
            for (i, item) in items.iter().enumerate() {
                let io = item
                    .as_object()
                    .ok_or_else(|| CodecError::new(format!("`items[{i}]` must be an object")))?;
                let (fn_op, port, data) =
                    op_bytes(io, true).map_err(|e| CodecError::new(format!("items[{i}]: {e}")))?;
                let len = u8::try_from(data.len())
                    .map_err(|_| CodecError::new(format!("items[{i}]: data too long")))?;
                out.extend_from_slice(&[fn_op, port, len]);
                out.extend_from_slice(&data);
            }
            out
        }
        _ => Vec::new(),
    })
}

/// Bytes 0 and 2 and the data of a request or batch item object.
fn op_bytes(o: &Map<String, Value>, item: bool) -> Result<(u8, u8, Vec<u8>)> {
    let function =
        get_str(o, "function")?.ok_or_else(|| CodecError::new("`function` is required"))?;
    let operation =
        get_str(o, "operation")?.ok_or_else(|| CodecError::new("`operation` is required"))?;
    let info = op_info(function, operation).ok_or_else(|| {
        let known: Vec<&str> = OPS
            .iter()
            .filter(|i| i.function == function)
            .map(|i| i.operation)
            .collect();
        if known.is_empty() {
            CodecError::new(format!("unknown function `{function}`"))
        } else {
            CodecError::new(format!(
                "unknown operation `{operation}` of {function} (known: {})",
                known.join(", ")
            ))
        }
    })?;
    let what = format!("{function} {operation}");
    let base = if item { ITEM_KEYS } else { REQUEST_KEYS };
    check_keys(o, base, info.fields, &what)?;
    let port = port_byte(o, info, &what)?;
    let data = match get_bytes(o, "data")? {
        Some(d) => d,
        None => data_from_fields(o, info, &what)?,
    };
    Ok((info.fn_op, port, data))
}

/// True when every key of `given` is in `decoded` with the same value (numbers compared as
/// integers, so `"0x09"` equals `9`); otherwise the path and both values.
fn mismatch(given: &Value, decoded: &Value, path: &str) -> Option<String> {
    match (given, decoded) {
        (Value::Object(g), Value::Object(d)) => g.iter().find_map(|(k, gv)| {
            let p = if path.is_empty() {
                k.clone()
            } else {
                format!("{path}.{k}")
            };
            match d.get(k) {
                Some(dv) => mismatch(gv, dv, &p),
                None => Some(format!("unknown key `{p}`")),
            }
        }),
        (Value::Array(g), Value::Array(d)) => {
            if g.len() != d.len() {
                return Some(format!(
                    "`{path}` has {} entries but the frame has {}",
                    g.len(),
                    d.len()
                ));
            }
            g.iter()
                .zip(d)
                .enumerate()
                .find_map(|(i, (gv, dv))| mismatch(gv, dv, &format!("{path}[{i}]")))
        }
        (g, d) if g == d => None,
        (g, Value::Number(n)) if int_of(g).is_some() && int_of(g) == n.as_u64() => None,
        (g, d) => Some(format!("`{path}` is {g} but the frame says {d}")),
    }
}

/// Appends the PEC when `pec_addr` is given, and checks a given `pec`.
fn finish(
    o: &Map<String, Value>,
    kind: FrameKind,
    mut bytes: Vec<u8>,
    answers: Option<Answers>,
) -> Result<Vec<u8>> {
    let mut opts = DecodeOptions::new(kind);
    opts.answers = answers;
    if let Some(addr) = get_int(o, "pec_addr", 255)? {
        let addr = Address::new(u8_of(addr)).map_err(|e| CodecError::new(e.to_string()))?;
        let read = kind == FrameKind::Reply;
        bytes.push(pec::compute(addr.addr_byte(read), &bytes));
        opts.pec = Some(addr);
    } else if o.get("pec").is_some_and(|v| !v.is_null()) {
        return Err(CodecError::new(
            "`pec` needs `pec_addr` (the address it covers)",
        ));
    }
    // Decode what was built and check every given key against it: this catches keys that
    // contradict `data`/`payload` and misplaced keys, and proves the inverse.
    let decoded = decode(&bytes, &opts)?;
    if let Some(m) = mismatch(&Value::Object(o.clone()), &decoded, "") {
        return Err(CodecError::new(m));
    }
    Ok(bytes)
}

fn encode_request(o: &Map<String, Value>) -> Result<Vec<u8>> {
    let (fn_op, port, data) = op_bytes(o, false)?;
    let db = u8_of(need_int(o, "db", 255, "a request")?);
    let seq = u8_of(need_int(o, "seq", 255, "a request")?);
    let mut bytes = vec![fn_op, db, port, seq];
    bytes.extend_from_slice(&data);
    Request::parse(&bytes).map_err(|e| CodecError::frame(FrameKind::Request, e))?;
    finish(o, FrameKind::Request, bytes, None)
}

fn status_of(o: &Map<String, Value>) -> Result<Status> {
    match o.get("status") {
        None | Some(Value::Null) => Ok(Status::Ok),
        Some(Value::String(s)) => match int_of(&Value::String(s.clone())) {
            Some(n) => Ok(Status::from_byte(u8_of(n.min(255)))),
            None => {
                Status::from_name(s).ok_or_else(|| CodecError::new(format!("unknown status `{s}`")))
            }
        },
        Some(v) => int_in(v, "status", 255).map(|n| Status::from_byte(u8_of(n))),
    }
}

/// Payload of a reply from its decoded value, when `payload` is not given.
fn payload_from_fields(o: &Map<String, Value>, answers: &str, what: &str) -> Result<Vec<u8>> {
    let obj = |key: &str| -> Result<&Map<String, Value>> {
        o.get(key)
            .and_then(Value::as_object)
            .ok_or_else(|| CodecError::new(format!("`{key}` must be an object")))
    };
    Ok(match answers {
        "io.input" if o.contains_key("level") => vec![u8_of(need_int(o, "level", 255, what)?)],
        "analog.read" if o.contains_key("value") => {
            let v = need_int(o, "value", u16::MAX.into(), what)?;
            u16::try_from(v).unwrap_or(0).to_le_bytes().to_vec()
        }
        "system.identify" if o.contains_key("identity") => identity_bytes(obj("identity")?)?,
        "system.read_diagnostics" if o.contains_key("diagnostics") => {
            let d = obj("diagnostics")?;
            check_keys(d, DIAGNOSTIC_NAMES, &[], "diagnostics")?;
            let mut values = [0u16; DIAGNOSTIC_NAMES.len()];
            for (slot, name) in values.iter_mut().zip(DIAGNOSTIC_NAMES) {
                let v = get_int(d, name, u16::MAX.into())?.unwrap_or(0);
                *slot = u16::try_from(v).unwrap_or(0);
            }
            Diagnostics::from_values(values).to_bytes().to_vec()
        }
        "scan.scan" if o.contains_key("scan") => {
            let s = obj("scan")?;
            check_keys(s, &["ports", "digital", "analog"], &[], "scan")?;
            let analog: Vec<u64> = match s.get("analog") {
                Some(Value::Array(a)) => a
                    .iter()
                    .map(|v| int_in(v, "scan.analog", u16::MAX.into()))
                    .collect::<Result<_>>()?,
                None | Some(Value::Null) => Vec::new(),
                Some(v) => {
                    return Err(CodecError::new(format!(
                        "`scan.analog` must be an array, got {v}"
                    )))
                }
            };
            let ports =
                get_int(s, "ports", ScanResult::MAX_PORTS as u64)?.unwrap_or(analog.len() as u64);
            if analog.len() as u64 != ports {
                return Err(CodecError::new(format!(
                    "`scan.analog` has {} values for {ports} ports",
                    analog.len()
                )));
            }
            let mut scan = ScanResult {
                ports: u8_of(ports),
                digital: u16::try_from(get_int(s, "digital", u16::MAX.into())?.unwrap_or(0))
                    .unwrap_or(0),
                ..ScanResult::default()
            };
            for (slot, v) in scan.analog.iter_mut().zip(&analog) {
                *slot = u16::try_from(*v).unwrap_or(0);
            }
            let mut buf = [0u8; MAX_PAYLOAD];
            let n = scan
                .emit(&mut buf)
                .map_err(|e| CodecError::new(format!("scan: {e}")))?;
            buf.get(..n).unwrap_or(&[]).to_vec()
        }
        "batch.batch" if o.contains_key("results") => {
            let results = match o.get("results") {
                Some(Value::Array(r)) => r,
                _ => return Err(CodecError::new("`results` must be an array")),
            };
            let mut out = Vec::new();
            for (i, r) in results.iter().enumerate() {
                let ro = r
                    .as_object()
                    .ok_or_else(|| CodecError::new(format!("`results[{i}]` must be an object")))?;
                let status = status_of(ro)?;
                let value = match get_bytes(ro, "payload")? {
                    Some(v) => v,
                    None => match get_str(ro, "answers")? {
                        Some(a) => payload_from_fields(ro, a, what)?,
                        None => Vec::new(),
                    },
                };
                let len = u8::try_from(value.len())
                    .map_err(|_| CodecError::new(format!("results[{i}]: value too long")))?;
                out.push(status.to_byte());
                out.push(len);
                out.extend_from_slice(&value);
            }
            out
        }
        _ => Vec::new(),
    })
}

fn identity_bytes(o: &Map<String, Value>) -> Result<Vec<u8>> {
    check_keys(
        o,
        &[
            "protocol_version",
            "firmware",
            "board",
            "sensor_ports",
            "actuator_ports",
            "capabilities",
            "adc_bits",
        ],
        &[],
        "identity",
    )?;
    let byte = |k: &str| -> Result<u8> { Ok(u8_of(get_int(o, k, 255)?.unwrap_or(0))) };
    let firmware = get_bytes(o, "firmware")?.unwrap_or_else(|| vec![0, 0, 0]);
    let [a, b, c] = firmware[..] else {
        return Err(CodecError::new("`identity.firmware` must be 3 bytes"));
    };
    let board = match o.get("board") {
        None | Some(Value::Null) => BoardKind::UNKNOWN,
        Some(Value::String(s)) if int_of(&Value::String(s.clone())).is_none() => (0..=255u8)
            .map(BoardKind)
            .find(|k| k.name() == s)
            .ok_or_else(|| CodecError::new(format!("unknown board kind `{s}`")))?,
        Some(v) => BoardKind(u8_of(int_in(v, "identity.board", 255)?)),
    };
    let id = Identity {
        protocol_version: byte("protocol_version")?,
        firmware: [a, b, c],
        board,
        sensor_ports: byte("sensor_ports")?,
        actuator_ports: byte("actuator_ports")?,
        capabilities: Capabilities(
            u16::try_from(get_int(o, "capabilities", u16::MAX.into())?.unwrap_or(0)).unwrap_or(0),
        ),
        adc_bits: byte("adc_bits")?,
    };
    Ok(id.to_bytes().to_vec())
}

fn encode_reply(o: &Map<String, Value>) -> Result<Vec<u8>> {
    check_keys(o, REPLY_KEYS, &[], "a reply")?;
    let seq = u8_of(need_int(o, "seq", 255, "a reply")?);
    let status = status_of(o)?;
    let answers = match get_str(o, "answers")? {
        Some(name) => {
            let mut a = Answers::parse(name)?;
            if let Some(Value::Array(results)) = o.get("results") {
                a.items = results
                    .iter()
                    .map(|r| r.get("answers")?.as_str().map(str::to_string))
                    .collect();
            }
            Some(a)
        }
        None => None,
    };
    let payload = match get_bytes(o, "payload")? {
        Some(p) => p,
        None => match &answers {
            Some(a) => payload_from_fields(o, &a.name, &a.name)?,
            None => Vec::new(),
        },
    };
    let r = Reply {
        seq,
        status,
        payload: &payload,
    };
    let mut buf = [0u8; MAX_FRAME_LEN + 256];
    let n = r
        .emit(&mut buf)
        .map_err(|e| CodecError::frame(FrameKind::Reply, e))?;
    finish(
        o,
        FrameKind::Reply,
        buf.get(..n).unwrap_or(&[]).to_vec(),
        answers,
    )
}

fn encode_event(o: &Map<String, Value>) -> Result<Vec<u8>> {
    check_keys(o, EVENT_KEYS, &[], "an event")?;
    let source = u8_of(need_int(o, "source", 255, "an event")?);
    let source = Address::new(source).map_err(|e| CodecError::new(e.to_string()))?;
    let kind = match o.get("event") {
        Some(Value::String(s)) => EventKind::from_name(s)
            .ok_or_else(|| CodecError::new(format!("unknown event kind `{s}`")))?,
        Some(v) if !v.is_null() => EventKind::from_byte(u8_of(int_in(v, "event", 255)?)),
        _ => return Err(CodecError::new("`event` is required for an event")),
    };
    // Events name a pin like a request does, or nothing (byte 2 = 0).
    let any_port = ["port_kind", "port", "pin"]
        .iter()
        .any(|k| o.get(*k).is_some_and(|v| !v.is_null()));
    let use_ = if any_port {
        PortUse::Pin
    } else {
        PortUse::Board
    };
    let info = op("", "", 0, use_, &[], false);
    let port = port_byte(o, &info, "an event")?;
    let seq = u8_of(need_int(o, "seq", 255, "an event")?);
    let status = status_of(o)?;
    let payload = match get_bytes(o, "payload")? {
        Some(p) => p,
        None => event_payload_from_fields(o, kind)?,
    };
    let e = Event {
        source,
        kind,
        pin: PinRef::from_byte(port),
        seq,
        status,
        payload: &payload,
    };
    let mut buf = [0u8; MAX_FRAME_LEN + 256];
    let n = e
        .emit(&mut buf)
        .map_err(|e| CodecError::frame(FrameKind::Event, e))?;
    finish(
        o,
        FrameKind::Event,
        buf.get(..n).unwrap_or(&[]).to_vec(),
        None,
    )
}

fn event_payload_from_fields(o: &Map<String, Value>, kind: EventKind) -> Result<Vec<u8>> {
    let what = kind.name();
    let le16 = |key: &str| -> Result<Vec<u8>> {
        let v = need_int(o, key, u16::MAX.into(), what)?;
        Ok(u16::try_from(v).unwrap_or(0).to_le_bytes().to_vec())
    };
    Ok(match kind {
        EventKind::PinChange if o.contains_key("level") => {
            let mut p = vec![u8_of(need_int(o, "level", 255, what)?)];
            if o.contains_key("rising_edges") || o.contains_key("falling_edges") {
                p.extend(le16("rising_edges")?);
                p.extend(le16("falling_edges")?);
            }
            p
        }
        EventKind::AnalogThreshold if o.contains_key("value") => {
            let mut p = le16("value")?;
            p.push(u8::from(get_bool(o, "inside")?.unwrap_or(false)));
            p
        }
        EventKind::DeferredReply if o.contains_key("width_us") => {
            let v = need_int(o, "width_us", u32::MAX.into(), what)?;
            u32::try_from(v).unwrap_or(0).to_le_bytes().to_vec()
        }
        EventKind::FailsafeTripped if o.contains_key("timeout_ms") => le16("timeout_ms")?,
        EventKind::Overflow if o.contains_key("dropped") => {
            let mut p = le16("dropped")?;
            if o.contains_key("dropped_total") {
                let v = need_int(o, "dropped_total", u32::MAX.into(), what)?;
                p.extend(u32::try_from(v).unwrap_or(0).to_le_bytes());
            }
            p
        }
        EventKind::Boot if o.contains_key("identity") => {
            let id = o
                .get("identity")
                .and_then(Value::as_object)
                .ok_or_else(|| CodecError::new("`identity` must be an object"))?;
            identity_bytes(id)?
        }
        _ => Vec::new(),
    })
}

/// Encodes one JSON object (as [`decode`] prints it) into frame bytes, PEC included when the
/// object has `pec_addr`.
///
/// # Errors
/// Not an object, unknown `kind`, unknown or contradictory keys, values out of range, or bytes
/// that do not make a valid frame.
pub fn encode(v: &Value) -> Result<Vec<u8>> {
    let o = v
        .as_object()
        .ok_or_else(|| CodecError::new(format!("expected a JSON object, got {v}")))?;
    let kind = match get_str(o, "kind")? {
        None => FrameKind::Request,
        Some(k) => FrameKind::from_name(k).ok_or_else(|| {
            CodecError::new(format!("unknown kind `{k}` (request, reply or event)"))
        })?,
    };
    match kind {
        FrameKind::Request => encode_request(o),
        FrameKind::Reply => encode_reply(o),
        FrameKind::Event => encode_event(o),
    }
}

// ---------------------------------------------------------------------------------------------
// Words
// ---------------------------------------------------------------------------------------------

fn port_words(o: &Map<String, Value>, with_pin: bool) -> Option<String> {
    let kind = o.get("port_kind")?.as_str()?;
    let port = o.get("port")?.as_u64()?;
    let pin = o.get("pin")?.as_str()?;
    Some(if with_pin {
        format!("{kind} port {port} pin {pin}")
    } else {
        format!("{kind} port {port}")
    })
}

/// Raw bytes (`data`, `payload`) in words: hex.
fn bytes_words(v: &Value) -> String {
    match v {
        Value::Array(a) => {
            let bytes: Vec<u8> = a.iter().filter_map(Value::as_u64).map(u8_of).collect();
            format!("[{}]", to_hex(&bytes))
        }
        v => v.to_string(),
    }
}

fn scalar_words(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Object(m) => m
            .iter()
            .map(|(k, v)| format!("{k}={}", scalar_words(v)))
            .collect::<Vec<_>>()
            .join(" "),
        v => v.to_string(),
    }
}

fn op_words(o: &Map<String, Value>) -> String {
    let function = o.get("function").and_then(Value::as_str).unwrap_or("?");
    let operation = o.get("operation").and_then(Value::as_str).unwrap_or("?");
    let info = op_info(function, operation);
    let mut s = if function == operation {
        function.to_string()
    } else {
        format!("{function} {operation}")
    };
    let with_pin = info.is_none_or(|i| i.port == PortUse::Pin);
    if let Some(p) = port_words(o, with_pin) {
        s.push_str(&format!(" on {p}"));
    }
    for f in info.map_or(&[][..], |i| i.fields) {
        if let Some(v) = o.get(*f).filter(|_| *f != "items") {
            s.push_str(&format!(", {f} {}", scalar_words(v)));
        }
    }
    if (function, operation) == ("serial", "write") {
        if let Some(d) = o.get("data") {
            s.push_str(&format!(", data {}", bytes_words(d)));
        }
    }
    if let Some(Value::Array(items)) = o.get("items") {
        let list: Vec<String> = items
            .iter()
            .filter_map(Value::as_object)
            .map(op_words)
            .collect();
        s.push_str(&format!(" of {}: {}", list.len(), list.join("; ")));
    }
    s
}

/// Decoded value keys of replies and batch results, in the order words print them.
const REPLY_VALUE_KEYS: &[&str] = &["level", "value", "identity", "diagnostics", "scan"];
/// Decoded value keys of events.
const EVENT_VALUE_KEYS: &[&str] = &[
    "level",
    "value",
    "inside",
    "width_us",
    "timeout_ms",
    "rising_edges",
    "falling_edges",
    "dropped",
    "dropped_total",
    "identity",
];

/// `key value, …` for the decoded keys present, else the raw bytes of `raw` if any.
fn value_words(o: &Map<String, Value>, keys: &[&str], raw: &str) -> Option<String> {
    let decoded: Vec<String> = keys
        .iter()
        .filter_map(|k| Some(format!("{k} {}", scalar_words(o.get(*k)?))))
        .collect();
    if !decoded.is_empty() {
        return Some(decoded.join(", "));
    }
    match o.get(raw) {
        Some(Value::Array(p)) if !p.is_empty() => {
            Some(format!("{raw} {}", bytes_words(&Value::Array(p.clone()))))
        }
        _ => None,
    }
}

fn addr_words(v: Option<&Value>) -> String {
    match v.and_then(Value::as_u64) {
        Some(0) => "SELF (internal DB)".to_string(),
        Some(a) => format!("DB {a:#04x}"),
        None => "?".to_string(),
    }
}

/// One line in words for a decoded frame (what `x10 decode` prints without `--json`).
pub fn describe(v: &Value) -> String {
    let Some(o) = v.as_object() else {
        return v.to_string();
    };
    let seq = o.get("seq").map_or_else(String::new, Value::to_string);
    let status = o.get("status").map(scalar_words).unwrap_or_default();
    let mut s = match o.get("kind").and_then(Value::as_str) {
        Some("request") => format!(
            "request to {} seq {seq}: {}",
            addr_words(o.get("db")),
            op_words(o)
        ),
        Some("reply") => {
            let mut s = format!("reply seq {seq}");
            if let Some(a) = o.get("answers").and_then(Value::as_str) {
                s.push_str(&format!(" to {a}"));
            }
            s.push_str(&format!(": {status}"));
            if let Some(w) = value_words(o, REPLY_VALUE_KEYS, "payload") {
                if !o.contains_key("results") {
                    s.push_str(&format!(", {w}"));
                }
            }
            if let Some(Value::Array(results)) = o.get("results") {
                let list: Vec<String> = results
                    .iter()
                    .filter_map(Value::as_object)
                    .map(|r| {
                        let st = r.get("status").map(scalar_words).unwrap_or_default();
                        match value_words(r, REPLY_VALUE_KEYS, "payload") {
                            Some(w) => format!("{st} {w}"),
                            None => st,
                        }
                    })
                    .collect();
                s.push_str(&format!(", results: {}", list.join("; ")));
            }
            s
        }
        Some("event") => {
            let mut s = format!(
                "event from {} seq {seq}: {}",
                addr_words(o.get("source")),
                o.get("event").map(scalar_words).unwrap_or_default()
            );
            if let Some(p) = port_words(o, true) {
                s.push_str(&format!(" on {p}"));
            }
            s.push_str(&format!(", status {status}"));
            if let Some(w) = value_words(o, EVENT_VALUE_KEYS, "payload") {
                s.push_str(&format!(", {w}"));
            }
            s
        }
        _ => v.to_string(),
    };
    if let (Some(p), Some(a)) = (
        o.get("pec").and_then(Value::as_u64),
        o.get("pec_addr").and_then(Value::as_u64),
    ) {
        s.push_str(&format!(" [PEC {p:#04x} ok, address {a:#04x}]"));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use x10_microcode::{Edge, Level, Pin, Port};

    fn op_info_of(op: &Op<'_>) -> Option<&'static OpInfo> {
        op_info(op.function().name(), op.name())
    }

    fn req_json(hex: &str) -> Value {
        decode(
            &parse_hex(hex).unwrap(),
            &DecodeOptions::new(FrameKind::Request),
        )
        .unwrap()
    }

    #[test]
    fn op_table_agrees_with_the_protocol_crate() {
        let s1 = Port::sensor(1).unwrap();
        let a1 = Port::actuator(1).unwrap();
        let ops = [
            Op::Ping,
            Op::Identify,
            Op::Heartbeat,
            Op::SetFailsafe { timeout_ms: 1 },
            Op::EventEnable(s1.pin(Pin::A), EventConfig::OFF),
            Op::ReadDiagnostics,
            Op::ClearDiagnostics,
            Op::SetPec(true),
            Op::DigitalRead(s1.pin(Pin::A)),
            Op::DigitalWrite(a1.pin(Pin::A), Level::Low),
            Op::DigitalWrite(a1.pin(Pin::A), Level::High),
            Op::PulseIn {
                pin: s1.pin(Pin::A),
                edge: Edge::Rising,
                timeout_ms: None,
            },
            Op::PulseIn {
                pin: s1.pin(Pin::A),
                edge: Edge::Falling,
                timeout_ms: None,
            },
            Op::PwmDuty(a1.pin(Pin::A), 1),
            Op::PwmFrequency(a1, 1),
            Op::PwmPulseWidth(a1.pin(Pin::A), 1),
            Op::AnalogRead(s1),
            Op::SerialWrite(s1, b"x"),
            Op::SerialRead(s1, 1),
            Op::SerialConfig(s1, 1),
            Op::Scan,
        ];
        assert_eq!(ops.len() + 1, OPS.len()); // + batch, checked below
        for op in ops {
            let info = op_info_of(&op).unwrap();
            assert_eq!(info.fn_op, op.fn_op_byte(), "{}", info.operation);
            assert_eq!(info.reply, op.expects_reply(), "{}", info.operation);
            let port = match op.pin_ref() {
                None => PortUse::Board,
                Some(_)
                    if matches!(
                        op,
                        Op::PwmFrequency(..)
                            | Op::AnalogRead(_)
                            | Op::SerialWrite(..)
                            | Op::SerialRead(..)
                            | Op::SerialConfig(..)
                    ) =>
                {
                    PortUse::Port
                }
                Some(_) => PortUse::Pin,
            };
            assert_eq!(info.port, port, "{}", info.operation);
            // Every field the table names is in the decoded object.
            let m = op_value(&op);
            for f in info.fields {
                assert!(m.contains_key(*f), "{} lacks {f}", info.operation);
            }
        }
        let batch = op_info("batch", "batch").unwrap();
        assert_eq!(batch.fn_op, 0x50);
    }

    #[test]
    fn hex_forms() {
        let want = vec![0x12, 0x09, 0x01, 0x02];
        for s in [
            "12090102",
            "12 09 01 02",
            "12:09:01:02",
            "0x12,0x09,0x01,0x02",
            " 1209 0102 ",
            "12-09-01-02",
            "12_09_01_02",
            "0X12 0X09 01 02",
        ] {
            assert_eq!(parse_hex(s), Ok(want.clone()), "{s}");
        }
        assert_eq!(to_hex(&want), "12 09 01 02");
        assert_eq!(
            parse_hex("12 9 01 02").unwrap_err().to_string(),
            "`9` has an odd number of hex digits"
        );
        assert_eq!(
            parse_hex("12 0g").unwrap_err().to_string(),
            "`g` is not a hex digit (in `0g`)"
        );
        assert_eq!(parse_hex("").unwrap_err().to_string(), "no bytes given");
        assert_eq!(
            parse_hex("0x").unwrap_err().to_string(),
            "`0x` has an odd number of hex digits"
        );
        assert_eq!(
            split_prefix("reply:01 00 00"),
            (Some(FrameKind::Reply), "01 00 00")
        );
        assert_eq!(split_prefix("event: 09"), (Some(FrameKind::Event), " 09"));
        assert_eq!(split_prefix("12:09"), (None, "12:09"));
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        // Single bytes are one frame; anything else is one frame per argument.
        assert_eq!(
            frames_of_args(args(&["12", "09", "0x1", "0X02"])),
            ["12 09 01 02"]
        );
        assert_eq!(
            frames_of_args(args(&["reply:04", "00", "02", "00", "02"])),
            ["reply:04 00 02 00 02"]
        );
        for unchanged in [
            &["12"][..],
            &["12090102", "30098004"],
            &["12", "09", "01", "0102"],
            &["12", "09", "01", "zz"],
            &["12", "reply:09"],
            &["12", "0x"],
        ] {
            assert_eq!(frames_of_args(args(unchanged)), args(unchanged));
        }
        assert!(frames_of_args(Vec::new()).is_empty());
        assert_eq!(parse_address("0x09").unwrap().get(), 9);
        assert_eq!(parse_address("16").unwrap().get(), 16);
        assert!(parse_address("0x78").is_err());
        assert!(parse_address("x").is_err());
    }

    #[test]
    fn decode_issue_example() {
        let v = req_json("12 09 01 02");
        assert_eq!(
            v,
            json!({"kind": "request", "function": "io", "operation": "high", "db": 9,
                   "port_kind": "actuator", "port": 1, "pin": "B", "seq": 2, "data": []})
        );
        assert_eq!(
            describe(&v),
            "request to DB 0x09 seq 2: io high on actuator port 1 pin B"
        );
        assert_eq!(encode(&v), Ok(vec![0x12, 0x09, 0x01, 0x02]));
    }

    #[test]
    fn encode_from_fields_without_data() {
        let v = json!({"kind": "request", "function": "pwm", "operation": "duty", "db": "0x09",
                       "port_kind": "actuator", "port": 1, "pin": "B", "seq": 3, "duty": 128});
        assert_eq!(encode(&v), Ok(vec![0x20, 0x09, 0x01, 0x03, 0x80]));
        // `kind` defaults to request, `pin` to A.
        let v = json!({"function": "analog", "operation": "read", "db": 9,
                       "port_kind": "sensor", "port": 1, "seq": 4});
        assert_eq!(encode(&v), Ok(vec![0x30, 0x09, 0x80, 0x04]));
        let v = json!({"function": "batch", "operation": "batch", "db": 9, "seq": 0x12,
        "items": [
            {"function": "io", "operation": "high", "port_kind": "actuator", "port": 1, "pin": "B"},
            {"function": "pwm", "operation": "duty", "port_kind": "actuator", "port": 1, "duty": 200},
            {"function": "analog", "operation": "read", "port_kind": "sensor", "port": 1}
        ]});
        assert_eq!(
            encode(&v).map(|b| to_hex(&b)),
            Ok("50 09 00 12 12 01 00 20 00 01 c8 30 80 00".to_string())
        );
    }

    #[test]
    fn encode_errors() {
        let cases = [
            (json!([1]), "expected a JSON object, got [1]"),
            (json!({"kind": "frame"}), "unknown kind `frame` (request, reply or event)"),
            (json!({"function": "io"}), "`operation` is required"),
            (
                json!({"function": "io", "operation": "toggle"}),
                "unknown operation `toggle` of io (known: input, low, high, pulse_in_rising, pulse_in_falling)",
            ),
            (json!({"function": "gpio", "operation": "x"}), "unknown function `gpio`"),
            (
                json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                       "port_kind": "actuator", "port": 1, "colour": "red"}),
                "unknown key `colour` for io high",
            ),
            (
                json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                       "port_kind": "actuator", "port": 1, "duty": 3}),
                "unknown key `duty` for io high",
            ),
            (
                json!({"function": "io", "operation": "high", "db": 300, "seq": 1,
                       "port_kind": "actuator", "port": 1}),
                "`db` must be an integer 0..=255, got 300",
            ),
            (
                json!({"function": "io", "operation": "high", "db": 5, "seq": 1,
                       "port_kind": "actuator", "port": 1}),
                "invalid request: bad daughterboard address 0x05 (a board answers status wrong_address)",
            ),
            (
                json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                       "port_kind": "actuator", "port": 65}),
                "`port` must be 1..=64, got 65",
            ),
            (
                json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                       "port_kind": "motor", "port": 1}),
                "`port_kind` must be \"sensor\" or \"actuator\", got \"motor\"",
            ),
            (
                json!({"function": "io", "operation": "high", "db": 9, "seq": -1,
                       "port_kind": "actuator", "port": 1}),
                "`seq` must be an integer 0..=255, got -1",
            ),
            (
                json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                       "port_kind": "actuator", "port": 1, "duty": 256}),
                "`duty` must be an integer 0..=255, got 256",
            ),
            (
                json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                       "port_kind": "actuator", "port": 1}),
                "`duty` is required for pwm duty",
            ),
            (
                json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                       "port_kind": "sensor", "port": 1, "duty": 3}),
                "invalid request: operation not available on this kind of port (a board answers status wrong_port_kind)",
            ),
            (
                json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                       "port_kind": "actuator", "port": 1, "duty": 3, "data": [4]}),
                "`duty` is 3 but the frame says 4",
            ),
            (
                json!({"function": "system", "operation": "ping", "db": 9, "seq": 1, "port": 2}),
                "system ping is addressed to the whole board: `port_kind`, `port` and `pin` must be null or absent",
            ),
            (
                json!({"kind": "reply", "seq": 1, "status": "fine"}),
                "unknown status `fine`",
            ),
            (
                json!({"kind": "reply", "seq": 1, "payload": vec![0u8; 29]}),
                "invalid reply: data or payload too long (a board answers status bad_length)",
            ),
            (
                json!({"kind": "reply", "seq": 1, "answers": "io.high"}),
                "io.high has no reply",
            ),
            (
                json!({"kind": "reply", "seq": 1, "answers": "io.input", "payload": [1, 2], "level": 1}),
                "unknown key `level`",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "pin_change", "seq": 1, "pec": 3}),
                "`pec` needs `pec_addr` (the address it covers)",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "boom", "seq": 1}),
                "unknown event kind `boom`",
            ),
            (
                json!({"kind": "event", "source": 3, "event": "boot", "seq": 0}),
                "bad daughterboard address 0x03",
            ),
            (
                json!({"kind": "request", "function": "io", "operation": "high", "db": 9, "seq": 2,
                       "port_kind": "actuator", "port": 1, "pin": "B", "pec_addr": 9, "pec": 1}),
                "`pec` is 1 but the frame says 156",
            ),
        ];
        for (v, msg) in cases {
            assert_eq!(encode(&v).unwrap_err().to_string(), msg, "{v}");
        }
    }

    #[test]
    fn reply_context_and_pec() {
        let mut opts = DecodeOptions::new(FrameKind::Reply);
        opts.answers = Some(Answers::parse("analog.read").unwrap());
        opts.pec = Some(Address::new(9).unwrap());
        let bytes = parse_hex("04 00 02 00 02").unwrap();
        let mut framed = bytes.clone();
        framed.push(pec::compute(0x13, &bytes));
        let v = decode(&framed, &opts).unwrap();
        assert_eq!(v["value"], json!(512));
        assert_eq!(v["pec_addr"], json!(9));
        assert_eq!(encode(&v), Ok(framed.clone()));
        assert_eq!(
            describe(&v),
            format!(
                "reply seq 4 to analog.read: ok, value 512 [PEC {:#04x} ok, address 0x09]",
                framed[5]
            )
        );
        // The context of a decoded batch request carries its items.
        let req = req_json("50 09 00 12 12 01 00 20 00 01 c8 30 80 00");
        let a = Answers::of_request(&req).unwrap();
        assert_eq!(a.name, "batch.batch");
        assert_eq!(
            a.items,
            ["io.high", "pwm.duty", "analog.read"].map(|s| Some(s.to_string()))
        );
        let mut opts = DecodeOptions::new(FrameKind::Reply);
        opts.answers = Some(a);
        let v = decode(
            &parse_hex("12 00 08 00 00 00 00 00 02 00 02").unwrap(),
            &opts,
        )
        .unwrap();
        assert_eq!(v["results"][2]["value"], json!(512));
        assert_eq!(v["results"][2]["answers"], json!("analog.read"));
        assert_eq!(
            encode(&v).map(|b| to_hex(&b)),
            Ok("12 00 08 00 00 00 00 00 02 00 02".into())
        );
        // Requests without a reply give no context.
        assert_eq!(Answers::of_request(&req_json("12 09 01 02")), None);
        // A wrong PEC is refused.
        let mut bad = framed;
        bad[5] ^= 1;
        let mut opts = DecodeOptions::new(FrameKind::Reply);
        opts.pec = Some(Address::new(9).unwrap());
        assert!(decode(&bad, &opts)
            .unwrap_err()
            .to_string()
            .starts_with("invalid reply: PEC mismatch"));
    }

    /// Removes `data` / `payload` wherever the decoded fields say the same, so that `encode`
    /// has to rebuild them.
    fn strip_raw(v: &mut Value) {
        let Some(o) = v.as_object_mut() else { return };
        let is_serial_write = o.get("function") == Some(&json!("serial"))
            && o.get("operation") == Some(&json!("write"));
        if o.contains_key("function") && !is_serial_write {
            o.remove("data");
        }
        if let Some(Value::Array(items)) = o.get_mut("items") {
            items.iter_mut().for_each(strip_raw);
        }
        if let Some(Value::Array(results)) = o.get_mut("results") {
            for r in results.iter_mut() {
                let decoded = REPLY_VALUE_KEYS.iter().any(|k| r.get(*k).is_some());
                if let Some(ro) = r.as_object_mut() {
                    if decoded || ro.get("payload") == Some(&json!([])) {
                        ro.remove("payload");
                    }
                }
            }
        }
        let decoded = REPLY_VALUE_KEYS
            .iter()
            .chain(EVENT_VALUE_KEYS)
            .chain(&["results"])
            .any(|k| o.contains_key(*k));
        if decoded || o.get("payload") == Some(&json!([])) {
            o.remove("payload");
        }
    }

    fn frame_strategy(
    ) -> impl proptest::strategy::Strategy<Value = (FrameKind, Vec<u8>, Option<String>)> {
        use proptest::prelude::*;
        let request = (
            proptest::sample::select(OPS.iter().map(|o| o.fn_op).collect::<Vec<_>>()),
            prop_oneof![Just(9u8), Just(0u8), any::<u8>()],
            prop_oneof![Just(0u8), any::<u8>()],
            any::<u8>(),
            proptest::collection::vec(any::<u8>(), 0..8),
        )
            .prop_map(|(f, db, port, seq, data)| {
                let mut v = vec![f, db, port, seq];
                v.extend(data);
                (FrameKind::Request, v, None)
            });
        let names: Vec<String> = OPS
            .iter()
            .filter(|o| o.reply)
            .map(|o| format!("{}.{}", o.function, o.operation))
            .collect();
        let reply = (
            any::<u8>(),
            prop_oneof![4 => Just(0u8), 1 => any::<u8>()],
            prop_oneof![
                Just(vec![1u8]),
                Just(vec![0u8, 2]),
                proptest::collection::vec(any::<u8>(), 10..=10),
                proptest::collection::vec(any::<u8>(), 28..=28),
                proptest::collection::vec(any::<u8>(), 0..=28),
                Just(vec![0u8, 0, 0, 0, 0, 2, 7, 1]),
                Just(vec![4u8, 0x96, 0, 1, 0, 2, 0, 3, 0, 4, 0]),
            ],
            proptest::option::of(proptest::sample::select(names)),
        )
            .prop_map(|(seq, status, payload, answers)| {
                let mut v = vec![seq, status, payload.len() as u8];
                v.extend(payload);
                (FrameKind::Reply, v, answers)
            });
        let event = (
            prop_oneof![Just(9u8), Just(0u8), any::<u8>()],
            prop_oneof![4 => 1u8..=7, 1 => any::<u8>()],
            prop_oneof![Just(0u8), any::<u8>()],
            any::<u8>(),
            prop_oneof![4 => Just(0u8), 1 => any::<u8>()],
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 0..=4),
                Just(vec![0x89u8, 3, 1]),
                proptest::collection::vec(any::<u8>(), 10..=10),
            ],
        )
            .prop_map(|(src, kind, port, seq, status, payload)| {
                let mut v = vec![src, kind, port, seq, status, payload.len() as u8];
                v.extend(payload);
                (FrameKind::Event, v, None)
            });
        prop_oneof![request, reply, event]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(3000))]

        /// decode → encode gives the same bytes, with and without PEC, and so does encoding
        /// from the decoded fields alone (raw `data`/`payload` removed).
        #[test]
        fn decode_encode_roundtrip((kind, bytes, answers) in frame_strategy(),
                                   with_pec in proptest::prelude::any::<bool>()) {
            let mut opts = DecodeOptions::new(kind);
            opts.answers = answers.map(|a| Answers::parse(&a).unwrap());
            let mut framed = bytes.clone();
            if with_pec {
                let addr = Address::new(0x09).unwrap();
                framed.push(pec::compute(addr.addr_byte(kind == FrameKind::Reply), &bytes));
                opts.pec = Some(addr);
            }
            if let Ok(v) = decode(&framed, &opts) {
                proptest::prop_assert_eq!(encode(&v), Ok(framed.clone()), "{}", v);
                let mut stripped = v.clone();
                strip_raw(&mut stripped);
                proptest::prop_assert_eq!(encode(&stripped), Ok(framed.clone()), "{}", stripped);
                // Words never fail.
                proptest::prop_assert!(!describe(&v).is_empty());
            }
        }

        /// Arbitrary JSON-ish objects never panic the encoder.
        #[test]
        fn encode_arbitrary_objects(keys in proptest::collection::vec(
            (proptest::sample::select(vec!["kind", "function", "operation", "db", "port_kind",
                "port", "pin", "seq", "data", "payload", "status", "answers", "results", "items",
                "event", "source", "identity", "scan", "pec_addr", "pec", "duty", "level"]),
             0u8..8), 0..10)) {
            let samples = [json!(null), json!(9), json!("io"), json!([1, 2]), json!({}),
                           json!(-1), json!("reply"), json!([{"function": "io"}])];
            let mut o = Map::new();
            for (k, i) in keys {
                o.insert(k.to_string(), samples[i as usize].clone());
            }
            let _ = encode(&Value::Object(o));
        }
    }

    #[test]
    fn encode_replies_and_events_from_fields() {
        let cases = [
            (
                json!({"kind": "reply", "seq": 18, "answers": "batch.batch", "results": [
                    {"status": "ok"}, {"status": "ok"},
                    {"status": "ok", "answers": "analog.read", "value": 512}]}),
                "12 00 08 00 00 00 00 00 02 00 02",
            ),
            (
                json!({"kind": "reply", "seq": 2, "answers": "system.identify", "identity": {
                    "protocol_version": 1, "firmware": [0, 1, 0], "board": "pico",
                    "sensor_ports": 4, "actuator_ports": 4, "capabilities": 511, "adc_bits": 12}}),
                "02 00 0a 01 00 01 00 03 04 04 ff 01 0c",
            ),
            (
                json!({"kind": "reply", "seq": 19, "answers": "scan.scan",
                       "scan": {"ports": 2, "digital": 6, "analog": [100, 200]}}),
                "13 00 07 02 06 00 64 00 c8 00",
            ),
            (
                json!({"kind": "reply", "seq": 6, "answers": "system.read_diagnostics",
                       "diagnostics": {"frames_ok": 1000, "pec_errors": 5}}),
                "06 00 1c e8 03 00 00 00 00 00 00 00 00 00 00 05 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00",
            ),
            (json!({"kind": "reply", "seq": 11, "status": "pending"}), "0b 01 00"),
            (json!({"kind": "reply", "seq": 7, "status": 66}), "07 42 00"),
            (
                json!({"kind": "event", "source": 9, "event": "pin_change", "port_kind": "sensor",
                       "port": 1, "pin": "A", "seq": 7, "level": 1}),
                "09 01 80 07 00 01 01",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "analog_threshold",
                       "port_kind": "sensor", "port": 2, "seq": 8, "value": 905, "inside": false}),
                "09 02 82 08 00 03 89 03 00",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "deferred_reply",
                       "port_kind": "sensor", "port": 3, "pin": "B", "seq": 11, "width_us": 1520}),
                "09 03 85 0b 00 04 f0 05 00 00",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "failsafe_tripped", "seq": 9,
                       "timeout_ms": 500}),
                "09 04 00 09 00 02 f4 01",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "overflow", "seq": 10, "dropped": 3}),
                "09 06 00 0a 00 02 03 00",
            ),
            (
                json!({"kind": "event", "source": 0, "event": 32, "seq": 11}),
                "00 20 00 0b 00 00",
            ),
            (
                json!({"kind": "event", "source": 9, "event": "pin_change", "port_kind": "sensor",
                       "port": 1, "seq": 7, "level": 1, "pec_addr": 16}),
                "09 01 80 07 00 01 01 95",
            ),
        ];
        for (v, hex) in cases {
            assert_eq!(encode(&v).map(|b| to_hex(&b)), Ok(hex.to_string()), "{v}");
        }
    }
}
