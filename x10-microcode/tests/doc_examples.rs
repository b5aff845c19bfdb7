//! The example frames of `docs/protocol.md` ("## Example frames") are parsed here and must decode
//! to exactly the fields the document states, and re-emit to the same bytes; rows marked
//! `error=STATUS` must be refused with that status. So the specification cannot drift from the
//! code.
//!
//! Fields use the keys of `x10 decode --json` (flattened with `.`), computed here directly from
//! the representations of this crate, independently of the `x10` tool.

use std::collections::{BTreeMap, BTreeSet};

use x10_microcode::{
    Address, BatchResults, Diagnostics, Event, EventKind, Identity, Op, Pin, PinRef, PortKind,
    Reply, Request, ScanResult, Status, UpdateOp, DIAGNOSTIC_NAMES, MAX_FRAME_LEN,
    MAX_REQUEST_DATA,
};

#[derive(Clone, Debug, PartialEq, Eq)]
enum Val {
    Null,
    Bool(bool),
    Int(u64),
    Str(String),
    List(Vec<u64>),
}

fn int(s: &str) -> Option<u64> {
    match s.strip_prefix("0x") {
        Some(h) => u64::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

fn val(s: &str) -> Val {
    match s {
        "null" => Val::Null,
        "true" => Val::Bool(true),
        "false" => Val::Bool(false),
        _ => {
            if let Some(inner) = s.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
                Val::List(
                    inner
                        .split(',')
                        .filter(|x| !x.is_empty())
                        .map(|x| int(x).unwrap_or_else(|| panic!("bad list entry `{x}`")))
                        .collect(),
                )
            } else if let Some(n) = int(s) {
                Val::Int(n)
            } else {
                Val::Str(s.to_string())
            }
        }
    }
}

struct Example {
    line: usize,
    kind: String,
    pec: Option<Address>,
    bytes: Vec<u8>,
    fields: Vec<(String, Val)>,
}

impl Example {
    fn field(&self, key: &str) -> Option<&Val> {
        self.fields.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }
}

fn examples() -> Vec<Example> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    let text = std::fs::read_to_string(path).expect("docs/protocol.md");
    let start = text
        .find("\n## Example frames\n")
        .expect("a section `## Example frames`");
    let first_line = text[..start].lines().count() + 1;
    let mut out = Vec::new();
    for (i, line) in text[start..].lines().enumerate() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 6 || !["request", "reply", "event"].contains(&cells[1]) {
            continue;
        }
        let line_no = first_line + i;
        let unquote = |s: &str| s.trim_matches('`').trim().to_string();
        let pec = match cells[2] {
            "-" => None,
            a => Some(Address::new(int(&unquote(a)).unwrap() as u8).unwrap()),
        };
        let bytes = unquote(cells[3])
            .split_whitespace()
            .map(|b| u8::from_str_radix(b, 16).unwrap_or_else(|_| panic!("line {line_no}: `{b}`")))
            .collect();
        let fields = unquote(cells[4])
            .split_whitespace()
            .map(|kv| {
                let (k, v) = kv
                    .split_once('=')
                    .unwrap_or_else(|| panic!("line {line_no}: `{kv}` is not key=value"));
                (k.to_string(), val(v))
            })
            .collect();
        out.push(Example {
            line: line_no,
            kind: cells[1].to_string(),
            pec,
            bytes,
            fields,
        });
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Representations → flat key/value maps with the keys of `x10 decode --json`
// ---------------------------------------------------------------------------------------------

type Flat = BTreeMap<String, Val>;

fn put(m: &mut Flat, k: impl Into<String>, v: Val) {
    m.insert(k.into(), v);
}

fn list(b: &[u8]) -> Val {
    Val::List(b.iter().map(|&x| x.into()).collect())
}

fn status(s: Status) -> Val {
    match s {
        Status::Unknown(x) => Val::Int(x.into()),
        s => Val::Str(s.name().into()),
    }
}

fn port_keys(m: &mut Flat, prefix: &str, pin: Option<PinRef>) {
    match pin {
        Some(p) => {
            let kind = match p.port.kind() {
                PortKind::Sensor => "sensor",
                PortKind::Actuator => "actuator",
            };
            let pin = match p.pin {
                Pin::A => "A",
                Pin::B => "B",
            };
            put(m, format!("{prefix}port_kind"), Val::Str(kind.into()));
            put(m, format!("{prefix}port"), Val::Int(p.port.number().into()));
            put(m, format!("{prefix}pin"), Val::Str(pin.into()));
        }
        None => {
            for k in ["port_kind", "port", "pin"] {
                put(m, format!("{prefix}{k}"), Val::Null);
            }
        }
    }
}

fn op_fields(m: &mut Flat, prefix: &str, op: &Op<'_>) {
    let p = |k: &str| format!("{prefix}{k}");
    put(m, p("function"), Val::Str(op.function().name().into()));
    put(m, p("operation"), Val::Str(op.name().into()));
    port_keys(m, prefix, op.pin_ref());
    let mut data = [0u8; MAX_REQUEST_DATA];
    let n = op.emit_data(&mut data).unwrap();
    put(m, p("data"), list(&data[..n]));
    match *op {
        Op::SetFailsafe { timeout_ms } => put(m, p("timeout_ms"), Val::Int(timeout_ms.into())),
        Op::EventEnable(_, c) => {
            put(m, p("rising"), Val::Bool(c.rising));
            put(m, p("falling"), Val::Bool(c.falling));
            put(m, p("analog_window"), Val::Bool(c.analog_window));
            put(m, p("low"), Val::Int(c.low.into()));
            put(m, p("high"), Val::Int(c.high.into()));
        }
        Op::SetPec(on) => put(m, p("on"), Val::Bool(on)),
        Op::Assign { uid, address } => {
            put(m, p("uid"), list(&uid.0));
            put(m, p("address"), Val::Int(address.get().into()));
        }
        Op::SetAddress(address) => put(m, p("address"), Val::Int(address.get().into())),
        Op::Blink(secs) => put(m, p("secs"), Val::Int(secs.into())),
        Op::PulseIn { timeout_ms, .. } => put(
            m,
            p("timeout_ms"),
            timeout_ms.map_or(Val::Null, |t| Val::Int(t.into())),
        ),
        Op::PwmDuty(_, d) => put(m, p("duty"), Val::Int(d.into())),
        Op::PwmFrequency(_, hz) => put(m, p("hz"), Val::Int(hz.into())),
        Op::PwmPulseWidth(_, us) => put(m, p("us"), Val::Int(us.into())),
        Op::SerialRead(_, n) => put(m, p("count"), Val::Int(n.into())),
        Op::SerialConfig(_, baud) => put(m, p("baud"), Val::Int(baud.into())),
        Op::Update(f) if matches!(f.op(), UpdateOp::Begin(_)) => {
            let UpdateOp::Begin(info) = f.op() else {
                unreachable!()
            };
            put(m, p("image_len"), Val::Int(info.len.into()));
            put(m, p("crc32"), Val::Int(info.crc32.into()));
            put(m, p("board"), Val::Str(info.board.name().into()));
            put(m, p("version"), list(&info.version));
        }
        Op::Update(f) if matches!(f.op(), UpdateOp::Chunk { .. }) => {
            let UpdateOp::Chunk { offset, data } = f.op() else {
                unreachable!()
            };
            put(m, p("offset"), Val::Int(offset.into()));
            put(m, p("bytes"), list(data));
        }
        Op::Batch(b) | Op::Stage(b) => {
            for (i, item) in b.iter().enumerate() {
                op_fields(m, &format!("{prefix}items.{i}."), &item);
            }
        }
        _ => {}
    }
}

fn identity_fields(m: &mut Flat, id: &Identity) {
    put(
        m,
        "identity.protocol_version",
        Val::Int(id.protocol_version.into()),
    );
    put(m, "identity.firmware", list(&id.firmware));
    let board = match id.board.name() {
        "unknown" if id.board.0 != 0 => Val::Int(id.board.0.into()),
        name => Val::Str(name.into()),
    };
    put(m, "identity.board", board);
    put(m, "identity.sensor_ports", Val::Int(id.sensor_ports.into()));
    put(
        m,
        "identity.actuator_ports",
        Val::Int(id.actuator_ports.into()),
    );
    put(
        m,
        "identity.capabilities",
        Val::Int(id.capabilities.0.into()),
    );
    put(m, "identity.adc_bits", Val::Int(id.adc_bits.into()));
}

fn reply_fields(r: &Reply<'_>, answers: Option<&str>) -> Flat {
    let mut m = Flat::new();
    put(&mut m, "seq", Val::Int(r.seq.into()));
    put(&mut m, "status", status(r.status));
    put(&mut m, "payload", list(r.payload));
    let Some(answers) = answers else { return m };
    put(&mut m, "answers", Val::Str(answers.into()));
    if !r.status.is_ok() {
        return m;
    }
    match answers {
        "io.input" => {
            if let [l] = *r.payload {
                put(&mut m, "level", Val::Int(l.into()));
            }
        }
        "analog.read" => {
            if let Ok(v) = r.value_u16() {
                put(&mut m, "value", Val::Int(v.into()));
            }
        }
        "system.identify" => identity_fields(&mut m, &Identity::parse(r.payload).unwrap()),
        "system.read_diagnostics" => {
            let d = Diagnostics::parse(r.payload).unwrap();
            for (name, v) in DIAGNOSTIC_NAMES.iter().zip(d.values()) {
                put(&mut m, format!("diagnostics.{name}"), Val::Int(v.into()));
            }
        }
        "scan.scan" => {
            let s = ScanResult::parse(r.payload).unwrap();
            put(&mut m, "scan.ports", Val::Int(s.ports.into()));
            put(&mut m, "scan.digital", Val::Int(s.digital.into()));
            let analog = (1..=s.ports).map(|p| s.analog(p).unwrap().into()).collect();
            put(&mut m, "scan.analog", Val::List(analog));
        }
        "batch.batch" => {
            for (i, res) in BatchResults::new(r.payload).enumerate() {
                let res = res.unwrap();
                put(&mut m, format!("results.{i}.status"), status(res.status));
                put(&mut m, format!("results.{i}.payload"), list(res.value));
            }
        }
        _ => {}
    }
    m
}

fn event_fields(e: &Event<'_>) -> Flat {
    let mut m = Flat::new();
    put(&mut m, "source", Val::Int(e.source.get().into()));
    let kind = match e.kind {
        EventKind::Unknown(x) => Val::Int(x.into()),
        k => Val::Str(k.name().into()),
    };
    put(&mut m, "event", kind);
    let board_kind = matches!(
        e.kind,
        EventKind::FailsafeTripped | EventKind::Overflow | EventKind::Boot | EventKind::Announce
    );
    let pin = (!(board_kind && e.pin.to_byte() == 0)).then_some(e.pin);
    port_keys(&mut m, "", pin);
    put(&mut m, "seq", Val::Int(e.seq.into()));
    put(&mut m, "status", status(e.status));
    put(&mut m, "payload", list(e.payload));
    match (e.kind, e.payload) {
        (EventKind::PinChange, &[l]) => put(&mut m, "level", Val::Int(l.into())),
        (EventKind::PinChange, &[l, r0, r1, f0, f1]) => {
            put(&mut m, "level", Val::Int(l.into()));
            let rising = u16::from_le_bytes([r0, r1]);
            put(&mut m, "rising_edges", Val::Int(rising.into()));
            let falling = u16::from_le_bytes([f0, f1]);
            put(&mut m, "falling_edges", Val::Int(falling.into()));
        }
        (EventKind::AnalogThreshold, &[a, b, inside]) if inside <= 1 => {
            put(&mut m, "value", Val::Int(u16::from_le_bytes([a, b]).into()));
            put(&mut m, "inside", Val::Bool(inside == 1));
        }
        (EventKind::DeferredReply, &[a, b, c, d]) => put(
            &mut m,
            "width_us",
            Val::Int(u32::from_le_bytes([a, b, c, d]).into()),
        ),
        (EventKind::FailsafeTripped, &[a, b]) => put(
            &mut m,
            "timeout_ms",
            Val::Int(u16::from_le_bytes([a, b]).into()),
        ),
        (EventKind::Overflow, &[a, b]) => put(
            &mut m,
            "dropped",
            Val::Int(u16::from_le_bytes([a, b]).into()),
        ),
        (EventKind::Overflow, &[a, b, c, d, e, f]) => {
            put(
                &mut m,
                "dropped",
                Val::Int(u16::from_le_bytes([a, b]).into()),
            );
            put(
                &mut m,
                "dropped_total",
                Val::Int(u32::from_le_bytes([c, d, e, f]).into()),
            );
        }
        (EventKind::Boot | EventKind::Announce, p) => match x10_microcode::BootInfo::parse(p) {
            Ok(b) => {
                identity_fields(&mut m, &b.identity);
                put(
                    &mut m,
                    "reset_reason",
                    Val::Str(b.reset_reason.name().into()),
                );
                if let Some(uid) = b.uid {
                    put(&mut m, "uid", list(&uid.0));
                }
            }
            // A board of an earlier version: the identity alone.
            Err(_) => identity_fields(&mut m, &Identity::parse(p).unwrap()),
        },
        _ => {}
    }
    m
}

// ---------------------------------------------------------------------------------------------
// The test
// ---------------------------------------------------------------------------------------------

/// Parses one example; returns its fields, or the status name of the parse error.
fn decode(ex: &Example) -> Result<Flat, &'static str> {
    let answers = match ex.field("answers") {
        Some(Val::Str(a)) => Some(a.as_str()),
        _ => None,
    };
    let mut out = [0u8; MAX_FRAME_LEN];
    let mut m = match ex.kind.as_str() {
        "request" => {
            let r = match ex.pec {
                Some(db) => Request::parse_with_pec(db, &ex.bytes),
                None => Request::parse(&ex.bytes),
            }
            .map_err(|e| e.status().name())?;
            let n = match ex.pec {
                Some(_) => r.emit_with_pec(&mut out),
                None => r.emit(&mut out),
            }
            .unwrap();
            assert_eq!(&out[..n], ex.bytes, "line {}: re-emitted", ex.line);
            let mut m = Flat::new();
            put(&mut m, "db", Val::Int(r.db.get().into()));
            put(&mut m, "seq", Val::Int(r.seq.into()));
            op_fields(&mut m, "", &r.op);
            m
        }
        "reply" => {
            let db = ex.pec.unwrap_or(Address::INTERNAL);
            let r = Reply::parse_read(db, ex.pec.is_some(), &ex.bytes)
                .map_err(|e| e.status().name())?;
            // A reply example is exactly one frame: no padding after it.
            let check = if ex.pec.is_some() {
                x10_microcode::pec::check_len(r.buffer_len())
            } else {
                0
            };
            assert_eq!(r.buffer_len() + check, ex.bytes.len());
            let n = match ex.pec {
                Some(db) => r.emit_with_pec(db, &mut out),
                None => r.emit(&mut out),
            }
            .unwrap();
            assert_eq!(&out[..n], ex.bytes, "line {}: re-emitted", ex.line);
            reply_fields(&r, answers)
        }
        "event" => {
            let e = match ex.pec {
                Some(mb) => Event::parse_with_pec(mb, &ex.bytes),
                None => Event::parse(&ex.bytes),
            }
            .map_err(|e| e.status().name())?;
            let n = match ex.pec {
                Some(mb) => e.emit_with_pec(mb, &mut out),
                None => e.emit(&mut out),
            }
            .unwrap();
            assert_eq!(&out[..n], ex.bytes, "line {}: re-emitted", ex.line);
            event_fields(&e)
        }
        k => panic!("line {}: unknown kind {k}", ex.line),
    };
    if let Some(addr) = ex.pec {
        put(&mut m, "pec_addr", Val::Int(addr.get().into()));
        // The check after the frame: a PEC byte, or a CRC-16 (low byte first) after a frame
        // of more than 13 bytes.
        let n = ex.bytes.len();
        let check = if n <= x10_microcode::pec::CRC8_MAX_FRAME + 1 {
            u64::from(ex.bytes[n - 1])
        } else {
            put(&mut m, "check", Val::Str("crc16".into()));
            u64::from(u16::from_le_bytes([ex.bytes[n - 2], ex.bytes[n - 1]]))
        };
        put(&mut m, "pec", Val::Int(check));
    }
    Ok(m)
}

#[test]
fn every_example_frame_decodes_to_what_the_document_says() {
    let all = examples();
    assert!(all.len() >= 20, "only {} examples", all.len());
    let mut ops = BTreeSet::new();
    let mut event_kinds = BTreeSet::new();
    let mut ok_rows = BTreeMap::<&str, usize>::new();
    let mut pec_rows = BTreeMap::<&str, usize>::new();
    let mut error_rows = BTreeMap::<&str, usize>::new();
    for ex in &all {
        let result = decode(ex);
        if let Some(expected) = ex.field("error") {
            assert_eq!(
                ex.fields.len(),
                1,
                "line {}: an error row has only `error=`",
                ex.line
            );
            let Val::Str(expected) = expected else {
                panic!("line {}: error=NAME", ex.line)
            };
            assert_eq!(
                result.as_ref().err().copied(),
                Some(expected.as_str()),
                "line {}: expected refusal with {expected}, got {result:?}",
                ex.line
            );
            *error_rows.entry(kind_name(&ex.kind)).or_default() += 1;
            continue;
        }
        let got = result.unwrap_or_else(|s| panic!("line {}: refused with {s}", ex.line));
        for (k, v) in &ex.fields {
            match got.get(k) {
                Some(g) => assert_eq!(g, v, "line {}: `{k}`", ex.line),
                None => panic!(
                    "line {}: `{k}` is not a field of this frame: {got:?}",
                    ex.line
                ),
            }
        }
        // The identifying fields must be stated.
        let required: &[&str] = match ex.kind.as_str() {
            "request" => &["function", "operation", "seq"],
            "reply" => &["seq", "status"],
            _ => &["source", "event", "seq"],
        };
        for k in required {
            assert!(ex.field(k).is_some(), "line {}: states no `{k}`", ex.line);
        }
        if ex.kind == "request" {
            if let (Some(Val::Str(f)), Some(Val::Str(o))) =
                (got.get("function"), got.get("operation"))
            {
                ops.insert(format!("{f}.{o}"));
            }
        }
        if ex.kind == "event" {
            event_kinds.insert(format!("{:?}", got["event"]));
        }
        *ok_rows.entry(kind_name(&ex.kind)).or_default() += 1;
        if ex.pec.is_some() {
            *pec_rows.entry(kind_name(&ex.kind)).or_default() += 1;
        }
    }
    // Every operation and every event kind has an example; every kind has examples with PEC
    // and refused examples.
    assert_eq!(ops.len(), 36, "operations with an example: {ops:?}");
    assert_eq!(
        event_kinds.len(),
        9,
        "event kinds with an example: {event_kinds:?}"
    );
    for kind in ["request", "reply", "event"] {
        assert!(
            ok_rows.get(kind).copied().unwrap_or(0) >= 5,
            "{kind}: {ok_rows:?}"
        );
        assert!(
            pec_rows.get(kind).copied().unwrap_or(0) >= 1,
            "{kind}: {pec_rows:?}"
        );
        assert!(
            error_rows.get(kind).copied().unwrap_or(0) >= 1,
            "{kind}: {error_rows:?}"
        );
    }
}

fn kind_name(k: &str) -> &'static str {
    match k {
        "request" => "request",
        "reply" => "reply",
        _ => "event",
    }
}

#[test]
fn the_issue_example_is_documented() {
    let all = examples();
    let ex = all
        .iter()
        .find(|e| e.bytes == [0x12, 0x09, 0x01, 0x02] && e.pec.is_none())
        .expect("12 09 01 02 is an example");
    assert_eq!(ex.field("operation"), Some(&Val::Str("high".into())));
    assert_eq!(ex.field("pin"), Some(&Val::Str("B".into())));
}

#[test]
fn value_syntax() {
    assert_eq!(val("null"), Val::Null);
    assert_eq!(val("0x10"), Val::Int(16));
    assert_eq!(val("[]"), Val::List(vec![]));
    assert_eq!(val("[0x68,105]"), Val::List(vec![0x68, 105]));
    assert_eq!(val("io.input"), Val::Str("io.input".into()));
}
