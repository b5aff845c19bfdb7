//! Frames ⇄ JSON, and frames in words: the `x10 decode` / `x10 encode` commands.
//!
//! Everything here is a pure function from bytes to [`serde_json::Value`] and back, so it is
//! unit-testable without the binary. The JSON shape is specified in `docs/protocol.md`
//! ("The `x10` tool"). A frame's own keys are `x10-microcode`'s serde representation (its
//! `serde` feature): a request is [`Request`] (`db`, `seq`, `function`, `operation`,
//! `port_kind`, `port`, `pin`, `data` and the operation's fields), a reply [`Reply`] (`seq`,
//! `status`, `payload`), an event [`Event`] (`source`, `event`, the port keys, `seq`,
//! `status`, `payload`), with [`Identity`], [`Diagnostics`], [`ScanResult`] and
//! [`EventConfig`] as they derive. What the tool adds, here:
//!
//! * `kind`, and with PEC `pec_addr` (the address the check covers), `pec` (the check: the PEC
//!   byte, or the CRC-16 of a frame over 13 bytes) and, for a CRC-16, `"check": "crc16"`;
//! * the decoded value of a reply, when it is known which request the reply answers
//!   (`answers`: [`Answers`]; `ReplyValue`), and of an event's payload (`EventValue`);
//! * encoding: [`encode`] is the exact inverse of [`decode`]. It accepts what `decode` prints,
//!   and fewer keys: `data` and `payload` can be left out and are then built from the decoded
//!   fields. Integers may be `"0x…"` strings. The frame built is decoded again and every key
//!   given must be in it with the same value, so unknown keys and keys that disagree with the
//!   bytes are refused; errors name the key.
//! * frames in hex ([`parse_hex`], [`frames_of_args`]) and in words ([`describe`]).

use std::fmt;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use x10_microcode::{
    pec, Address, BatchResults, BootInfo, Diagnostics, Edge, Event, EventConfig, EventKind,
    Identity, Op, Pin, PinRef, Port, PortKind, Reply, Request, ResetReason, ScanResult, Status,
    Uid, MAX_FRAME_LEN, MAX_REQUEST_DATA,
};

mod hex;
mod words;

pub use hex::{frames_of_args, parse_address, parse_hex, split_prefix, to_hex};
pub use words::describe;

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
// The operations, by name
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
    /// Byte 0.
    fn_op: u8,
    port: PortUse,
    /// Keys of the operation's own fields, in the order words print them.
    fields: &'static [&'static str],
    /// True when the MB reads a reply.
    reply: bool,
}

macro_rules! ops {
    ($($function:ident $operation:ident $fn_op:literal $port:ident
       [$($field:ident)*] $reply:literal;)*) => {
        &[$(OpInfo {
            function: stringify!($function),
            operation: stringify!($operation),
            fn_op: $fn_op,
            port: PortUse::$port,
            fields: &[$(stringify!($field)),*],
            reply: $reply,
        }),*]
    };
}

/// Every operation (docs/protocol.md, "Functions and operands").
const OPS: &[OpInfo] = ops! {
    system ping              0x00 Board []                  true;
    system identify          0x01 Board []                  true;
    system heartbeat         0x02 Board []                  false;
    system set_failsafe      0x03 Board [timeout_ms]        false;
    system event_enable      0x04 Pin   [rising falling analog_window low high] false;
    system read_diagnostics  0x05 Board []                  true;
    system clear_diagnostics 0x06 Board []                  false;
    system set_pec           0x07 Board [on]                false;
    system assign            0x08 Board [uid address]       false;
    system set_address       0x09 Board [address]           true;
    system blink             0x0a Board [secs]              false;
    system who_is_there      0x0b Board []                  false;
    system enter_update      0x0c Board []                  true;
    system confirm_firmware  0x0d Board []                  true;
    io     input             0x10 Pin   []                  true;
    io     low               0x11 Pin   []                  false;
    io     high              0x12 Pin   []                  false;
    io     pulse_in_rising   0x13 Pin   [timeout_ms]        true;
    io     pulse_in_falling  0x14 Pin   [timeout_ms]        true;
    pwm    duty              0x20 Pin   [duty]              false;
    pwm    frequency         0x21 Port  [hz]                false;
    pwm    pulse_width       0x22 Pin   [us]                false;
    analog read              0x30 Port  []                  true;
    serial write             0x40 Port  []                  false;
    serial read              0x41 Port  [count]             true;
    serial config            0x42 Port  [baud]              false;
    batch  batch             0x50 Board [items]             true;
    scan   scan              0x60 Board []                  true;
    update begin             0x70 Board [image_len crc32 board version] true;
    update chunk             0x71 Board [offset bytes]      true;
    update commit            0x72 Board []                  true;
    update status            0x73 Board []                  true;
    update leave             0x74 Board []                  true;
    sweep  sample            0x80 Board []                  true;
    sweep  apply             0x81 Board []                  true;
    stage  stage             0x90 Board [items]             false;
};

fn op_info(function: &str, operation: &str) -> Option<&'static OpInfo> {
    OPS.iter()
        .find(|o| o.function == function && o.operation == operation)
}

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
    /// True when the reply's length varies with its content (scan, serial read, batch): with
    /// PEC on it always ends in a CRC-16 (`pec::append16`).
    fn crc16_reply(&self) -> bool {
        matches!(
            self.name.as_str(),
            "scan.scan" | "serial.read" | "batch.batch" | "sweep.sample"
        )
    }

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

// ---------------------------------------------------------------------------------------------
// The decoded values of payloads
// ---------------------------------------------------------------------------------------------

/// The decoded value of a reply payload (or of one batch result), by what it answers: keys
/// `level` (io.input), `value` (analog.read), `identity`, `diagnostics`, `scan`, `results`
/// (batch.batch: one object per item, `status`, `payload` and, for a known item, `answers`
/// and the item's value).
#[derive(Serialize, Deserialize, Default)]
struct ReplyValue {
    level: Option<u8>,
    value: Option<u16>,
    identity: Option<Identity>,
    diagnostics: Option<Diagnostics>,
    scan: Option<ScanResult>,
    results: Option<Vec<Value>>,
}

/// The keys of one batch result besides its value.
#[derive(Serialize, Deserialize)]
struct BatchResult<'a> {
    status: Option<Status>,
    payload: Option<Vec<u8>>,
    answers: Option<&'a str>,
}

impl ReplyValue {
    /// The value of `payload` answering `name` (empty when the payload does not have the shape
    /// of that answer); `items` names a batch's items.
    fn of(name: &str, items: &[Option<String>], payload: &[u8]) -> ReplyValue {
        let mut v = ReplyValue::default();
        match (name, payload) {
            ("io.input", &[level]) => v.level = Some(level),
            ("analog.read", &[a, b]) => v.value = Some(u16::from_le_bytes([a, b])),
            ("system.identify", p) => v.identity = Identity::parse(p).ok(),
            ("system.read_diagnostics", p) => v.diagnostics = Diagnostics::parse(p).ok(),
            ("scan.scan", p) => v.scan = ScanResult::parse(p).ok(),
            ("batch.batch", p) => {
                let results: std::result::Result<Vec<_>, _> = BatchResults::new(p).collect();
                let result = |(i, r): (usize, &x10_microcode::BatchItem<'_>)| {
                    let item = items.get(i).and_then(Option::as_deref);
                    let mut o = present(BatchResult {
                        status: Some(r.status),
                        payload: Some(r.value.to_vec()),
                        answers: item,
                    });
                    if let (Some(name), true) = (item, r.status.is_ok()) {
                        o.extend(present(ReplyValue::of(name, &[], r.value)));
                    }
                    Value::Object(o)
                };
                v.results = results
                    .ok()
                    .map(|r| r.iter().enumerate().map(result).collect());
            }
            _ => {}
        }
        v
    }

    /// The payload these fields of `o` make for a reply answering `name` (empty without
    /// them).
    fn payload(&self, name: &str, o: Input<'_>) -> Result<Vec<u8>> {
        let bytes = match name {
            "io.input" => self.level.map(|level| vec![level]),
            "analog.read" => self.value.map(|v| v.to_le_bytes().to_vec()),
            "system.identify" => self.identity.map(|id| id.to_bytes().to_vec()),
            "system.read_diagnostics" => self.diagnostics.map(|d| d.to_bytes().to_vec()),
            "scan.scan" => match self.scan {
                Some(scan) => {
                    let mut buf = [0u8; ScanResult::MAX_LEN];
                    let n = scan
                        .emit(&mut buf)
                        .map_err(|e| CodecError::new(format!("scan: {e}")))?;
                    Some(buf.get(..n).unwrap_or(&[]).to_vec())
                }
                None => None,
            },
            "batch.batch" => match (&self.results, o.get("results")) {
                (Some(_), Some(results)) => Some(batch_results(results)?),
                _ => None,
            },
            _ => None,
        };
        Ok(bytes.unwrap_or_default())
    }
}

/// The payload of a batch reply from its `results`.
fn batch_results(results: Input<'_>) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for i in 0.. {
        let Some(r) = results.get(i) else { break };
        if !r.given.is_object() {
            return Err(CodecError::new(format!("`results[{i}]` must be an object")));
        }
        let head: BatchResult = r.parse()?;
        let value = match (head.payload, head.answers) {
            (Some(v), _) => v,
            (None, Some(name)) => r.parse::<ReplyValue>()?.payload(name, r)?,
            (None, None) => Vec::new(),
        };
        let len = u8::try_from(value.len())
            .map_err(|_| CodecError::new(format!("results[{i}]: value too long")))?;
        out.push(head.status.unwrap_or(Status::Ok).to_byte());
        out.push(len);
        out.extend_from_slice(&value);
    }
    Ok(out)
}

/// The decoded value of an event payload, by kind: `level` (and `rising_edges`,
/// `falling_edges` from a 5-byte `pin_change`), `value` and `inside`, `width_us`,
/// `timeout_ms`, `dropped` (and `dropped_total` from a 6-byte `overflow`), `identity`,
/// `reset_reason` and `uid` (`boot`, `announce`).
#[derive(Serialize, Deserialize, Default)]
struct EventValue {
    level: Option<u8>,
    rising_edges: Option<u16>,
    falling_edges: Option<u16>,
    value: Option<u16>,
    inside: Option<bool>,
    width_us: Option<u32>,
    timeout_ms: Option<u16>,
    dropped: Option<u16>,
    dropped_total: Option<u32>,
    identity: Option<Identity>,
    reset_reason: Option<ResetReason>,
    uid: Option<Uid>,
}

impl EventValue {
    /// The value of `payload` of an event of `kind` (empty when the payload does not have the
    /// kind's shape).
    fn of(kind: EventKind, payload: &[u8]) -> EventValue {
        let le16 = |a, b| Some(u16::from_le_bytes([a, b]));
        let mut v = EventValue::default();
        match (kind, payload) {
            (EventKind::PinChange, &[level]) => v.level = Some(level),
            (EventKind::PinChange, &[level, r0, r1, f0, f1]) => {
                v.level = Some(level);
                v.rising_edges = le16(r0, r1);
                v.falling_edges = le16(f0, f1);
            }
            (EventKind::AnalogThreshold, &[a, b, inside]) if inside <= 1 => {
                v.value = le16(a, b);
                v.inside = Some(inside == 1);
            }
            (EventKind::DeferredReply, &[a, b, c, d]) => {
                v.width_us = Some(u32::from_le_bytes([a, b, c, d]));
            }
            (EventKind::FailsafeTripped, &[a, b]) => v.timeout_ms = le16(a, b),
            (EventKind::Overflow, &[a, b]) => v.dropped = le16(a, b),
            (EventKind::Overflow, &[a, b, c, d, e, f]) => {
                v.dropped = le16(a, b);
                v.dropped_total = Some(u32::from_le_bytes([c, d, e, f]));
            }
            (EventKind::Boot | EventKind::Announce, p) => {
                if let Ok(b) = BootInfo::parse(p) {
                    v.identity = Some(b.identity);
                    v.reset_reason = Some(b.reset_reason);
                    v.uid = b.uid;
                } else {
                    // A board of an earlier version: the identity alone.
                    v.identity = Identity::parse(p).ok();
                }
            }
            _ => {}
        }
        v
    }

    /// The payload these fields make for an event of `kind` (empty without them).
    fn payload(&self, kind: EventKind) -> Result<Vec<u8>> {
        let what = kind.name();
        let bytes = match kind {
            EventKind::PinChange => match self.level {
                Some(level) => {
                    let mut p = vec![level];
                    if self.rising_edges.is_some() || self.falling_edges.is_some() {
                        p.extend(need(self.rising_edges, "rising_edges", what)?.to_le_bytes());
                        p.extend(need(self.falling_edges, "falling_edges", what)?.to_le_bytes());
                    }
                    Some(p)
                }
                None => None,
            },
            EventKind::AnalogThreshold => self.value.map(|v| {
                let mut p = v.to_le_bytes().to_vec();
                p.push(u8::from(self.inside.unwrap_or(false)));
                p
            }),
            EventKind::DeferredReply => self.width_us.map(|w| w.to_le_bytes().to_vec()),
            EventKind::FailsafeTripped => self.timeout_ms.map(|t| t.to_le_bytes().to_vec()),
            EventKind::Overflow => self.dropped.map(|d| {
                let mut p = d.to_le_bytes().to_vec();
                if let Some(total) = self.dropped_total {
                    p.extend(total.to_le_bytes());
                }
                p
            }),
            // Without a reset reason: the identity alone, as a board of an earlier version.
            EventKind::Boot | EventKind::Announce => {
                self.identity.map(|identity| match self.reset_reason {
                    Some(reset_reason) => {
                        let (b, n) = BootInfo {
                            identity,
                            reset_reason,
                            uid: self.uid,
                        }
                        .to_bytes();
                        b.get(..n).unwrap_or(&[]).to_vec()
                    }
                    None => identity.to_bytes().to_vec(),
                })
            }
            EventKind::Rejected | EventKind::Unknown(_) => None,
        };
        Ok(bytes.unwrap_or_default())
    }
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

/// `value` as a JSON object (every representation here serializes to one).
fn object(value: impl Serialize) -> Map<String, Value> {
    match serde_json::to_value(value) {
        Ok(Value::Object(m)) => m,
        _ => Map::new(),
    }
}

/// The keys of `value` that have one (a decoded value names only what the payload holds).
fn present(value: impl Serialize) -> Map<String, Value> {
    let mut m = object(value);
    m.retain(|_, v| !v.is_null());
    m
}

/// Decodes one frame into its JSON object.
///
/// # Errors
/// The frame does not parse (the message names the error and the status a board would
/// answer), or its PEC does not match.
pub fn decode(bytes: &[u8], opts: &DecodeOptions) -> Result<Value> {
    let invalid = |e| CodecError::frame(opts.kind, e);
    let (frame, pec_byte) = match opts.pec {
        Some(addr) => {
            let read = opts.kind == FrameKind::Reply;
            let crc16 = read && opts.answers.as_ref().is_some_and(Answers::crc16_reply);
            let frame = if crc16 {
                pec::strip16(addr.addr_byte(read), bytes).map_err(invalid)?
            } else {
                pec::strip(addr.addr_byte(read), bytes).map_err(invalid)?
            };
            // The check after the frame: one PEC byte, or a CRC-16 (little-endian).
            let check = match bytes.get(frame.len()..) {
                Some(&[b]) => Some((u16::from(b), false)),
                Some(&[lo, hi]) => Some((u16::from_le_bytes([lo, hi]), true)),
                _ => None,
            };
            (frame, check)
        }
        None => (bytes, None),
    };
    let mut m = match opts.kind {
        FrameKind::Request => object(Request::parse(frame).map_err(invalid)?),
        FrameKind::Reply => {
            let r = Reply::parse(frame).map_err(invalid)?;
            let mut m = object(r);
            if let Some(a) = &opts.answers {
                m.insert("answers".into(), a.name.clone().into());
                if r.status.is_ok() {
                    m.extend(present(ReplyValue::of(&a.name, &a.items, r.payload)));
                }
            }
            m
        }
        FrameKind::Event => {
            let e = Event::parse(frame).map_err(invalid)?;
            let mut m = object(e);
            m.extend(present(EventValue::of(e.kind, e.payload)));
            m
        }
    };
    m.insert("kind".into(), opts.kind.name().into());
    if let (Some(addr), Some((p, crc16))) = (opts.pec, pec_byte) {
        m.insert("pec_addr".into(), addr.get().into());
        m.insert("pec".into(), p.into());
        if crc16 {
            m.insert("check".into(), "crc16".into());
        }
    }
    Ok(Value::Object(m))
}

// ---------------------------------------------------------------------------------------------
// Encoding
// ---------------------------------------------------------------------------------------------

/// The keys of a representation: its fields.
fn keys_of<T: Serialize + Default>() -> Vec<String> {
    object(T::default()).keys().cloned().collect()
}

/// Refuses a key of `o` that none of `keys` names: "unknown key `colour` for io high".
fn check_keys(o: &Value, keys: &[Vec<String>], what: &str) -> Result<()> {
    let known = |k: &String| keys.iter().flatten().any(|known| known == k);
    match o.as_object().and_then(|o| o.keys().find(|k| !known(k))) {
        Some(k) => Err(CodecError::new(format!("unknown key `{k}` for {what}"))),
        None => Ok(()),
    }
}

/// Refuses unknown keys inside the decoded values `identity`, `diagnostics` and `scan` of
/// `o`, before the payload is made from them.
fn check_value_keys(o: &Value) -> Result<()> {
    let values = [
        ("identity", keys_of::<Identity>()),
        ("diagnostics", keys_of::<Diagnostics>()),
        ("scan", keys_of::<ScanResult>()),
    ];
    for (key, keys) in values {
        if let Some(v) = o.get(key) {
            check_keys(v, &[keys], key)?;
        }
    }
    Ok(())
}

/// The port keys of a request, batch item or event.
#[derive(Serialize, Deserialize, Default)]
struct PortJson {
    port_kind: Option<PortKind>,
    port: Option<u8>,
    pin: Option<Pin>,
}

impl PortJson {
    /// The pin the port keys of `o` name for an operation (or event) `what` that names
    /// `port`.
    fn pin_ref(o: Input<'_>, port: PortUse, what: &str) -> Result<Option<PinRef>> {
        if port == PortUse::Board {
            let keys = keys_of::<PortJson>();
            if keys
                .iter()
                .any(|k| o.ints.get(k).is_some_and(|v| !v.is_null()))
            {
                return Err(CodecError::new(format!(
                    "{what} is addressed to the whole board: `port_kind`, `port` and `pin` must be null or absent"
                )));
            }
            return Ok(None);
        }
        let p: PortJson = o.parse()?;
        let kind = need(p.port_kind, "port_kind", what)?;
        let number = need(p.port, "port", what)?;
        let port = Port::new(kind, number)
            .map_err(|_| CodecError::new(format!("`port` must be 1..=64, got {number}")))?;
        Ok(Some(port.pin(p.pin.unwrap_or(Pin::A))))
    }
}

/// The keys every request and batch item has besides its port: `data` may be left out, and
/// is then made from the operation's fields ([`OpFields`]).
#[derive(Serialize, Deserialize, Default)]
struct OpHead {
    function: Option<String>,
    operation: Option<String>,
    data: Option<Vec<u8>>,
}

/// The operations' own fields (each operation has those [`OPS`] names).
#[derive(Deserialize)]
struct OpFields {
    timeout_ms: Option<u16>,
    on: Option<bool>,
    uid: Option<Uid>,
    address: Option<u8>,
    secs: Option<u8>,
    duty: Option<u8>,
    hz: Option<u16>,
    us: Option<u16>,
    count: Option<u8>,
    baud: Option<u32>,
    items: Option<Vec<Value>>,
    image_len: Option<u32>,
    crc32: Option<u32>,
    board: Option<x10_microcode::BoardKind>,
    version: Option<[u8; 3]>,
    offset: Option<u32>,
    bytes: Option<Vec<u8>>,
}

/// The data bytes of operation `info` on `pin` from its fields in `o`, when `data` is not
/// given.
fn data_from_fields(o: Input<'_>, info: &OpInfo, pin: Option<PinRef>) -> Result<Vec<u8>> {
    let what = format!("{} {}", info.function, info.operation);
    let f: OpFields = o.parse()?;
    // Operations on the whole board have no pin, and none of them reads one.
    let pin = pin.unwrap_or(PinRef::from_byte(0));
    let op = match (info.function, info.operation) {
        ("system", "set_failsafe") => Op::SetFailsafe {
            timeout_ms: need(f.timeout_ms, "timeout_ms", &what)?,
        },
        ("system", "event_enable") => Op::EventEnable(pin, o.parse::<EventConfig>()?),
        ("system", "set_pec") => Op::SetPec(need(f.on, "on", &what)?),
        ("system", "assign") => Op::Assign {
            uid: need(f.uid, "uid", &what)?,
            address: assignable(need(f.address, "address", &what)?)?,
        },
        ("system", "set_address") => {
            Op::SetAddress(assignable(need(f.address, "address", &what)?)?)
        }
        ("system", "blink") => Op::Blink(need(f.secs, "secs", &what)?),
        ("io", "pulse_in_rising" | "pulse_in_falling") => Op::PulseIn {
            pin,
            edge: if info.operation == "pulse_in_rising" {
                Edge::Rising
            } else {
                Edge::Falling
            },
            timeout_ms: f.timeout_ms,
        },
        ("pwm", "duty") => Op::PwmDuty(pin, need(f.duty, "duty", &what)?),
        ("pwm", "frequency") => Op::PwmFrequency(pin.port, need(f.hz, "hz", &what)?),
        ("pwm", "pulse_width") => Op::PwmPulseWidth(pin, need(f.us, "us", &what)?),
        ("serial", "write") => {
            return Err(CodecError::new(format!(
                "`data` (the bytes to send) is required for {what}"
            )))
        }
        ("serial", "read") => Op::SerialRead(pin.port, need(f.count, "count", &what)?),
        ("serial", "config") => Op::SerialConfig(pin.port, need(f.baud, "baud", &what)?),
        ("batch", "batch") | ("stage", "stage") => {
            let items = f.items.and(o.get("items")).ok_or_else(|| {
                CodecError::new(format!(
                    "`items` (an array of operations) is required for {}",
                    info.function
                ))
            })?;
            return batch_data(items);
        }
        ("update", "begin") => {
            let info = x10_microcode::ImageInfo {
                len: need(f.image_len, "image_len", &what)?,
                crc32: need(f.crc32, "crc32", &what)?,
                board: need(f.board, "board", &what)?,
                version: need(f.version, "version", &what)?,
            };
            return Ok(info.to_bytes().to_vec());
        }
        ("update", "chunk") => {
            let offset = need(f.offset, "offset", &what)?;
            let bytes = need(f.bytes, "bytes", &what)?;
            let mut data = offset.to_le_bytes().to_vec();
            data.extend_from_slice(&bytes);
            return Ok(data);
        }
        // The others carry no data.
        _ => return Ok(Vec::new()),
    };
    let mut data = [0u8; MAX_REQUEST_DATA];
    let n = op
        .emit_data(&mut data)
        .map_err(|e| CodecError::new(format!("{what}: {e}")))?;
    Ok(data.get(..n).unwrap_or(&[]).to_vec())
}

/// An address a board may be given (`0x08..=0x76`).
fn assignable(raw: u8) -> Result<Address> {
    Address::assignable(raw)
        .map_err(|_| CodecError::new(format!("`address` must be 0x08..=0x76, got {raw:#04x}")))
}

/// The data of a batch: its items, each `fn_op, port, len, data`.
fn batch_data(items: Input<'_>) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for i in 0.. {
        let Some(item) = items.get(i) else { break };
        if !item.given.is_object() {
            return Err(CodecError::new(format!("`items[{i}]` must be an object")));
        }
        let (fn_op, port, data) =
            op_bytes(item, &[]).map_err(|e| CodecError::new(format!("items[{i}]: {e}")))?;
        let len = u8::try_from(data.len())
            .map_err(|_| CodecError::new(format!("items[{i}]: data too long")))?;
        out.extend_from_slice(&[fn_op, port, len]);
        out.extend_from_slice(&data);
    }
    Ok(out)
}

/// Bytes 0 and 2 and the data of a request or batch item object, which may also have the keys
/// `more` names.
fn op_bytes(o: Input<'_>, more: &[Vec<String>]) -> Result<(u8, u8, Vec<u8>)> {
    let head: OpHead = o.parse()?;
    let function = head
        .function
        .as_deref()
        .ok_or_else(|| CodecError::new("`function` is required"))?;
    let operation = head
        .operation
        .as_deref()
        .ok_or_else(|| CodecError::new("`operation` is required"))?;
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
    let fields = info.fields.iter().map(|f| (*f).to_string()).collect();
    let keys = [keys_of::<OpHead>(), keys_of::<PortJson>(), fields];
    check_keys(o.ints, &[&keys[..], more].concat(), &what)?;
    let pin = PortJson::pin_ref(o, info.port, &what)?;
    let data = match head.data {
        Some(d) => d,
        None => data_from_fields(o, info, pin)?,
    };
    Ok((info.fn_op, pin.map_or(0, PinRef::to_byte), data))
}

/// The keys a frame of any kind may have besides its own.
fn frame_keys() -> Vec<Vec<String>> {
    vec![vec!["kind".to_string()], keys_of::<PecJson>()]
}

#[derive(Serialize, Deserialize, Default)]
struct RequestJson {
    db: Option<u8>,
    seq: Option<u8>,
}

fn encode_request(o: Input<'_>) -> Result<Vec<u8>> {
    let more = [frame_keys(), vec![keys_of::<RequestJson>()]].concat();
    let (fn_op, port, data) = op_bytes(o, &more)?;
    let j: RequestJson = o.parse()?;
    let db = need(j.db, "db", "a request")?;
    let seq = need(j.seq, "seq", "a request")?;
    let mut bytes = vec![fn_op, db, port, seq];
    bytes.extend_from_slice(&data);
    Request::parse(&bytes).map_err(|e| CodecError::frame(FrameKind::Request, e))?;
    finish(o, FrameKind::Request, bytes, None)
}

#[derive(Serialize, Deserialize, Default)]
struct ReplyJson {
    seq: Option<u8>,
    status: Option<Status>,
    payload: Option<Vec<u8>>,
    answers: Option<String>,
}

fn encode_reply(o: Input<'_>) -> Result<Vec<u8>> {
    let keys = [keys_of::<ReplyJson>(), keys_of::<ReplyValue>()];
    check_keys(o.ints, &[&frame_keys()[..], &keys].concat(), "a reply")?;
    let j: ReplyJson = o.parse()?;
    let seq = need(j.seq, "seq", "a reply")?;
    let answers = match &j.answers {
        Some(name) => {
            let mut a = Answers::parse(name)?;
            if let Some(Value::Array(results)) = o.ints.get("results") {
                a.items = results
                    .iter()
                    .map(|r| r.get("answers")?.as_str().map(str::to_string))
                    .collect();
            }
            Some(a)
        }
        None => None,
    };
    let payload = match (j.payload, &answers) {
        (Some(p), _) => p,
        (None, Some(a)) => {
            check_value_keys(o.ints)?;
            o.parse::<ReplyValue>()?.payload(&a.name, o)?
        }
        (None, None) => Vec::new(),
    };
    let r = Reply {
        seq,
        status: j.status.unwrap_or(Status::Ok),
        payload: &payload,
    };
    let bytes = emitted(FrameKind::Reply, |buf| r.emit(buf))?;
    finish(o, FrameKind::Reply, bytes, answers)
}

#[derive(Serialize, Deserialize, Default)]
struct EventJson {
    source: Option<Address>,
    event: Option<EventKind>,
    seq: Option<u8>,
    status: Option<Status>,
    payload: Option<Vec<u8>>,
}

fn encode_event(o: Input<'_>) -> Result<Vec<u8>> {
    let keys = [
        keys_of::<EventJson>(),
        keys_of::<PortJson>(),
        keys_of::<EventValue>(),
    ];
    check_keys(o.ints, &[&frame_keys()[..], &keys].concat(), "an event")?;
    let j: EventJson = o.parse()?;
    let source = need(j.source, "source", "an event")?;
    let kind = need(j.event, "event", "an event")?;
    // Events name a pin like a request does, or nothing (byte 2 = 0).
    let port: PortJson = o.parse()?;
    let given = port.port_kind.is_some() || port.port.is_some() || port.pin.is_some();
    let port_use = if given { PortUse::Pin } else { PortUse::Board };
    let pin = PortJson::pin_ref(o, port_use, "an event")?;
    let seq = need(j.seq, "seq", "an event")?;
    let payload = match j.payload {
        Some(p) => p,
        None => {
            check_value_keys(o.ints)?;
            o.parse::<EventValue>()?.payload(kind)?
        }
    };
    let e = Event {
        source,
        kind,
        pin: pin.unwrap_or(PinRef::from_byte(0)),
        seq,
        status: j.status.unwrap_or(Status::Ok),
        payload: &payload,
    };
    let bytes = emitted(FrameKind::Event, |buf| e.emit(buf))?;
    finish(o, FrameKind::Event, bytes, None)
}

/// The bytes a frame's `emit` writes.
fn emitted(
    kind: FrameKind,
    emit: impl FnOnce(&mut [u8]) -> x10_microcode::Result<usize>,
) -> Result<Vec<u8>> {
    let mut buf = [0u8; MAX_FRAME_LEN + 256];
    let n = emit(&mut buf).map_err(|e| CodecError::frame(kind, e))?;
    Ok(buf.get(..n).unwrap_or(&[]).to_vec())
}

/// `pec_addr`, the address the check covers, `pec`, the check (a PEC byte, or a CRC-16 on a
/// frame over 13 bytes), and `check` (`crc16` for a CRC-16); the last two are checked against
/// the frame.
#[derive(Serialize, Deserialize, Default)]
struct PecJson {
    pec_addr: Option<Address>,
    pec: Option<Value>,
    check: Option<Value>,
}

/// Appends the PEC when `pec_addr` is given, then decodes what was built and checks every
/// key `given` against it: this catches keys that contradict `data` or `payload` and
/// misplaced keys, and proves the inverse.
fn finish(
    o: Input<'_>,
    kind: FrameKind,
    mut bytes: Vec<u8>,
    answers: Option<Answers>,
) -> Result<Vec<u8>> {
    let mut opts = DecodeOptions::new(kind);
    opts.answers = answers;
    let p: PecJson = o.parse()?;
    if let Some(addr) = p.pec_addr {
        let read = kind == FrameKind::Reply;
        let n = bytes.len();
        let crc16 = read && opts.answers.as_ref().is_some_and(Answers::crc16_reply);
        if crc16 {
            bytes.resize(n + 2, 0);
            pec::append16(addr.addr_byte(read), &mut bytes, n)
        } else {
            bytes.resize(n + pec::check_len(n), 0);
            pec::append(addr.addr_byte(read), &mut bytes, n)
        }
        .map_err(|e| CodecError::frame(kind, e))?;
        opts.pec = Some(addr);
    } else if p.pec.is_some() {
        return Err(CodecError::new(
            "`pec` needs `pec_addr` (the address it covers)",
        ));
    }
    let decoded = decode(&bytes, &opts)?;
    match mismatch(o.given, &decoded, "") {
        Some(m) => Err(CodecError::new(m)),
        None => Ok(bytes),
    }
}

/// `None` when every key of `given` is in `decoded` with the same value (numbers compared as
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
        (Value::String(g), Value::Number(n))
            if hex_integer(g).is_some_and(|g| Some(g) == n.as_u64()) =>
        {
            None
        }
        (g, d) => Some(format!("`{path}` is {g} but the frame says {d}")),
    }
}

/// Encodes one JSON object (as [`decode`] prints it) into frame bytes, PEC included when the
/// object has `pec_addr`.
///
/// # Errors
/// Not an object, unknown `kind`, unknown or contradictory keys, values out of range, or bytes
/// that do not make a valid frame.
pub fn encode(v: &Value) -> Result<Vec<u8>> {
    #[derive(Deserialize)]
    struct KindJson {
        kind: Option<String>,
    }
    if !v.is_object() {
        return Err(CodecError::new(format!("expected a JSON object, got {v}")));
    }
    let mut ints = v.clone();
    hex_integers(&mut ints);
    let o = Input {
        given: v,
        ints: &ints,
    };
    let kind = match o.parse::<KindJson>()?.kind {
        None => FrameKind::Request,
        Some(k) => FrameKind::from_name(&k).ok_or_else(|| {
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
// Reading JSON input: hex integers, errors that name the key
// ---------------------------------------------------------------------------------------------

/// `"0x…"` as a number.
fn hex_integer(s: &str) -> Option<u64> {
    let hex = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X"))?;
    u64::from_str_radix(hex, 16).ok()
}

/// Keys whose values are names, never numbers.
const NAME_KEYS: &[&str] = &[
    "kind",
    "function",
    "operation",
    "port_kind",
    "pin",
    "answers",
    "check",
];

/// Integers may be written as `"0x…"` strings (docs/protocol.md): they become numbers, except
/// under keys that take names.
fn hex_integers(v: &mut Value) {
    match v {
        Value::String(s) => {
            if let Some(n) = hex_integer(s) {
                *v = n.into();
            }
        }
        Value::Array(a) => a.iter_mut().for_each(hex_integers),
        Value::Object(o) => o
            .iter_mut()
            .filter(|(k, _)| !NAME_KEYS.contains(&k.as_str()))
            .for_each(|(_, v)| hex_integers(v)),
        _ => {}
    }
}

/// A value that must be given.
fn need<T>(v: Option<T>, key: &str, what: &str) -> Result<T> {
    v.ok_or_else(|| CodecError::new(format!("`{key}` is required for {what}")))
}

/// A JSON object (or array) of the input: as given, for messages and the final check, and
/// with its `"0x…"` integers as numbers, to read.
#[derive(Clone, Copy)]
struct Input<'v> {
    given: &'v Value,
    ints: &'v Value,
}

impl<'v> Input<'v> {
    /// Reads `T` from the keys it has (the other keys are other parts' business, and every
    /// key is checked against the frame in the end).
    fn parse<T: Deserialize<'v>>(self) -> Result<T> {
        serde_path_to_error::deserialize(self.ints).map_err(|e| explain(&e, self.given))
    }

    /// The value of a key, or an entry of an array.
    fn get<I: serde_json::value::Index + Copy>(self, i: I) -> Option<Input<'v>> {
        Some(Input {
            given: self.given.get(i)?,
            ints: self.ints.get(i)?,
        })
    }
}

/// A serde error as one line that names the key and the value given.
fn explain(e: &serde_path_to_error::Error<serde_json::Error>, root: &Value) -> CodecError {
    use serde_path_to_error::Segment;
    let msg = e.inner().to_string();
    let segments: Vec<&Segment> = e.path().iter().collect();
    let given = segments.iter().try_fold(root, |v, s| match s {
        Segment::Seq { index } => v.get(index),
        Segment::Map { key } => v.get(key),
        _ => None,
    });
    // `invalid type: …, expected E`, `invalid value: …, expected E`, `invalid length …,
    // expected E`, `unknown variant …, expected E`; anything else is the representation's own
    // message (an unknown status name, a bad address, …).
    let shape = msg.starts_with("invalid ") || msg.starts_with("unknown variant ");
    let (Some(given), Some((_, expected)), true, false) = (
        given,
        msg.rsplit_once(", expected "),
        shape,
        segments.is_empty(),
    ) else {
        return CodecError::new(msg);
    };
    let path = e.path().to_string();
    let key = match segments.last() {
        Some(Segment::Map { key }) => key.as_str(),
        _ => "",
    };
    let must = match expected {
        "u8" | "u16" | "u32" => {
            let max = match expected {
                "u8" => u64::from(u8::MAX),
                "u16" => u64::from(u16::MAX),
                _ => u64::from(u32::MAX),
            };
            // A byte of a byte array: name the array.
            if let (Some(Segment::Seq { .. }), 255) = (segments.last(), max) {
                let array = path.rsplit_once('[').map_or(path.as_str(), |(a, _)| a);
                return CodecError::new(format!("`{array}` holds bytes 0..=255, got {given}"));
            }
            format!("an integer 0..={max}")
        }
        "a boolean" => "true or false".to_string(),
        "a string" | "string or map" | "map with a single key" => "a string".to_string(),
        "a sequence" if key == "data" || key == "payload" => "an array of bytes".to_string(),
        "a sequence" => "an array".to_string(),
        e if e.starts_with("struct ") || e == "a map" => "an object".to_string(),
        e => e.replace('`', "\""),
    };
    CodecError::new(format!("`{path}` must be {must}, got {given}"))
}

#[cfg(test)]
mod tests;
