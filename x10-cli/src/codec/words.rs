//! Frames in words: the line `x10 decode` prints for each decoded frame (without `--json`),
//! made from the frame's JSON object.

use serde_json::{Map, Value};

use super::{op_info, to_hex, PortUse};

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
            let bytes: Vec<u8> = a
                .iter()
                .filter_map(Value::as_u64)
                .map(|n| u8::try_from(n).unwrap_or(u8::MAX))
                .collect();
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
pub(super) const REPLY_VALUE_KEYS: &[&str] = &["level", "value", "identity", "diagnostics", "scan"];
/// Decoded value keys of events.
pub(super) const EVENT_VALUE_KEYS: &[&str] = &[
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
        if o.get("check").and_then(Value::as_str) == Some("crc16") {
            s.push_str(&format!(" [CRC-16 {p:#06x} ok, address {a:#04x}]"));
        } else {
            s.push_str(&format!(" [PEC {p:#04x} ok, address {a:#04x}]"));
        }
    }
    s
}
