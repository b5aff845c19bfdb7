//! serde representations of the wire types (feature `serde`): the JSON of `x10 decode --json`
//! and `x10 encode --json`, specified in `docs/protocol.md` ("The `x10` tool"). no_std, no
//! allocation.
//!
//! Derived, with attributes, where the Rust fields are the JSON keys: [`crate::Identity`],
//! [`crate::Diagnostics`], [`crate::EventConfig`], [`crate::Capabilities`] (a number),
//! [`crate::PortKind`] (`sensor`, `actuator`), [`crate::Pin`] (`A`, `B`), [`crate::Address`]
//! (a number, checked), [`ScanResult`] (through [`ScanRepr`]: `analog` has `ports` values)
//! and [`crate::Reply`] (`seq`, `status`, `payload`).
//!
//! Written here, where the JSON is not the Rust shape:
//! * [`Status`], [`EventKind`], [`BoardKind`]: the name of a known code, the number of an
//!   unknown one (`"pending"`, `66`); either is read back.
//! * [`Op`]: `function` and `operation` by name (one Rust variant can be two operations: `io
//!   low` and `io high`), the port as `port_kind`, `port` (from 1), `pin` (all null for the
//!   operations addressed to the whole board), the raw `data`, and the operation's own fields
//!   (`duty`, `timeout_ms`, the event enables, `items` of a batch, …).
//! * [`Request`]: `db`, `seq` and the operation's keys in one object.
//! * [`Event`]: `source`, `event`, the port keys (null for board events with byte 2 = 0),
//!   `seq`, `status`, `payload`.
//!
//! Frames borrow their data from the bytes they were parsed from, so they serialize only; a
//! tool builds frames from JSON through the values above and [`Op`]'s constructors.

use core::fmt;

use serde::de::{self, Deserializer, Unexpected, Visitor};
use serde::ser::{SerializeMap, Serializer};
use serde::{Deserialize, Serialize};

use crate::{
    BoardKind, Event, EventKind, Op, PinRef, Request, ResetReason, ScanResult, Status,
    MAX_REQUEST_DATA,
};

// -------------------------------------------------------------------------------------------
// Codes: a name, or the number of an unknown code
// -------------------------------------------------------------------------------------------

/// Reads a code given by name or number.
struct NameOrCode<T> {
    /// What the code is, for "unknown status `fine`".
    what: &'static str,
    /// What is expected, for "expected a status name or code 0..=255".
    expecting: &'static str,
    of_name: fn(&str) -> Option<T>,
    of_code: fn(u8) -> T,
}

impl<T> Visitor<'_> for NameOrCode<T> {
    type Value = T;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.expecting)
    }

    fn visit_str<E: de::Error>(self, s: &str) -> Result<T, E> {
        (self.of_name)(s).ok_or_else(|| E::custom(format_args!("unknown {} `{s}`", self.what)))
    }

    fn visit_u64<E: de::Error>(self, n: u64) -> Result<T, E> {
        u8::try_from(n)
            .map(self.of_code)
            .map_err(|_| E::invalid_value(Unexpected::Unsigned(n), &self))
    }
}

impl Serialize for Status {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match *self {
            Status::Unknown(code) => s.serialize_u8(code),
            known => s.serialize_str(known.name()),
        }
    }
}

impl<'de> Deserialize<'de> for Status {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Status, D::Error> {
        d.deserialize_any(NameOrCode {
            what: "status",
            expecting: "a status name or code 0..=255",
            of_name: Status::from_name,
            of_code: Status::from_byte,
        })
    }
}

impl Serialize for EventKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match *self {
            EventKind::Unknown(code) => s.serialize_u8(code),
            known => s.serialize_str(known.name()),
        }
    }
}

impl<'de> Deserialize<'de> for EventKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<EventKind, D::Error> {
        d.deserialize_any(NameOrCode {
            what: "event kind",
            expecting: "an event kind name or code 0..=255",
            of_name: EventKind::from_name,
            of_code: EventKind::from_byte,
        })
    }
}

impl Serialize for ResetReason {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            ResetReason::Unknown(code) => s.serialize_u8(*code),
            known => s.serialize_str(known.name()),
        }
    }
}

impl<'de> Deserialize<'de> for ResetReason {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<ResetReason, D::Error> {
        d.deserialize_any(NameOrCode {
            what: "reset reason",
            expecting: "a reset reason name or code 0..=255",
            of_name: |name| {
                (0..=255)
                    .map(ResetReason::from_byte)
                    .find(|r| !matches!(r, ResetReason::Unknown(_)) && r.name() == name)
            },
            of_code: ResetReason::from_byte,
        })
    }
}

impl Serialize for BoardKind {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.name() {
            "unknown" if *self != BoardKind::UNKNOWN => s.serialize_u8(self.0),
            name => s.serialize_str(name),
        }
    }
}

impl<'de> Deserialize<'de> for BoardKind {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<BoardKind, D::Error> {
        d.deserialize_any(NameOrCode {
            what: "board kind",
            expecting: "a board kind name or code 0..=255",
            of_name: |name| (0..=255).map(BoardKind).find(|k| k.name() == name),
            of_code: BoardKind,
        })
    }
}

// -------------------------------------------------------------------------------------------
// Scan results: `analog` holds `ports` values
// -------------------------------------------------------------------------------------------

/// [`ScanResult`] as JSON: `ports` (default: the number of `analog` values), `digital`,
/// `analog` (one value per port).
#[derive(Serialize, Deserialize)]
pub(crate) struct ScanRepr {
    #[serde(default)]
    ports: Option<u8>,
    #[serde(default)]
    digital: u16,
    #[serde(default)]
    analog: heapless::Vec<u16, { ScanResult::MAX_PORTS }>,
}

impl From<ScanResult> for ScanRepr {
    fn from(s: ScanResult) -> ScanRepr {
        ScanRepr {
            ports: Some(s.ports),
            digital: s.digital,
            analog: s.analog.iter().copied().take(s.ports.into()).collect(),
        }
    }
}

/// `analog` does not have one value per port.
pub(crate) struct ScanPortsError {
    ports: u8,
    values: usize,
}

impl fmt::Display for ScanPortsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "`scan.analog` has {} values for {} ports",
            self.values, self.ports
        )
    }
}

impl TryFrom<ScanRepr> for ScanResult {
    type Error = ScanPortsError;

    fn try_from(r: ScanRepr) -> Result<ScanResult, ScanPortsError> {
        let values = r.analog.len();
        let ports = r.ports.unwrap_or(values as u8);
        if usize::from(ports) != values {
            return Err(ScanPortsError { ports, values });
        }
        let mut scan = ScanResult {
            ports,
            digital: r.digital,
            ..ScanResult::default()
        };
        for (slot, v) in scan.analog.iter_mut().zip(r.analog) {
            *slot = v;
        }
        Ok(scan)
    }
}

// -------------------------------------------------------------------------------------------
// Frames
// -------------------------------------------------------------------------------------------

/// `port_kind`, `port` (from 1) and `pin` of `pin`, or three nulls.
fn port_entries<M: SerializeMap>(m: &mut M, pin: Option<PinRef>) -> Result<(), M::Error> {
    m.serialize_entry("port_kind", &pin.map(|p| p.port.kind()))?;
    m.serialize_entry("port", &pin.map(|p| p.port.number()))?;
    m.serialize_entry("pin", &pin.map(|p| p.pin))
}

/// The items of a batch, each an operation object.
struct Items<'a>(crate::Batch<'a>);

impl Serialize for Items<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.0.iter())
    }
}

/// The keys of an operation: names, port, raw data, its own fields.
fn op_entries<M: SerializeMap>(m: &mut M, op: &Op<'_>) -> Result<(), M::Error> {
    m.serialize_entry("function", op.function().name())?;
    m.serialize_entry("operation", op.name())?;
    port_entries(m, op.pin_ref())?;
    let mut data = [0u8; MAX_REQUEST_DATA];
    let n = op.emit_data(&mut data).unwrap_or(0);
    m.serialize_entry("data", data.get(..n).unwrap_or(&[]))?;
    match *op {
        Op::SetFailsafe { timeout_ms } => m.serialize_entry("timeout_ms", &timeout_ms),
        Op::PulseIn { timeout_ms, .. } => m.serialize_entry("timeout_ms", &timeout_ms),
        Op::EventEnable(_, cfg) => {
            m.serialize_entry("rising", &cfg.rising)?;
            m.serialize_entry("falling", &cfg.falling)?;
            m.serialize_entry("analog_window", &cfg.analog_window)?;
            m.serialize_entry("low", &cfg.low)?;
            m.serialize_entry("high", &cfg.high)
        }
        Op::SetPec(on) => m.serialize_entry("on", &on),
        Op::Assign { uid, address } => {
            m.serialize_entry("uid", &uid)?;
            m.serialize_entry("address", &address)
        }
        Op::SetAddress(address) => m.serialize_entry("address", &address),
        Op::Blink(secs) => m.serialize_entry("secs", &secs),
        Op::PwmDuty(_, duty) => m.serialize_entry("duty", &duty),
        Op::PwmFrequency(_, hz) => m.serialize_entry("hz", &hz),
        Op::PwmPulseWidth(_, us) => m.serialize_entry("us", &us),
        Op::SerialRead(_, count) => m.serialize_entry("count", &count),
        Op::SerialConfig(_, baud) => m.serialize_entry("baud", &baud),
        Op::Batch(b) | Op::Stage(b) => m.serialize_entry("items", &Items(b)),
        Op::Update(f) => match f.op() {
            crate::UpdateOp::Begin(info) => {
                m.serialize_entry("image_len", &info.len)?;
                m.serialize_entry("crc32", &info.crc32)?;
                m.serialize_entry("board", &info.board)?;
                m.serialize_entry("version", &info.version)
            }
            crate::UpdateOp::Chunk { offset, data } => {
                m.serialize_entry("offset", &offset)?;
                m.serialize_entry("bytes", data)
            }
            _ => Ok(()),
        },
        Op::EnterUpdate | Op::ConfirmFirmware => Ok(()),
        Op::Ping
        | Op::Identify
        | Op::Heartbeat
        | Op::ReadDiagnostics
        | Op::ClearDiagnostics
        | Op::DigitalRead(_)
        | Op::DigitalWrite(..)
        | Op::AnalogRead(_)
        | Op::SerialWrite(..)
        | Op::WhoIsThere
        | Op::Scan
        | Op::Sample
        | Op::Apply => Ok(()),
    }
}

impl Serialize for Op<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        op_entries(&mut m, self)?;
        m.end()
    }
}

impl Serialize for Request<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("db", &self.db)?;
        m.serialize_entry("seq", &self.seq)?;
        op_entries(&mut m, &self.op)?;
        m.end()
    }
}

impl Serialize for Event<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // Events about the whole board name no pin (byte 2 = 0).
        let board = matches!(
            self.kind,
            EventKind::FailsafeTripped
                | EventKind::Overflow
                | EventKind::Boot
                | EventKind::Announce
        ) && self.pin.to_byte() == 0;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("source", &self.source)?;
        m.serialize_entry("event", &self.kind)?;
        port_entries(&mut m, (!board).then_some(self.pin))?;
        m.serialize_entry("seq", &self.seq)?;
        m.serialize_entry("status", &self.status)?;
        m.serialize_entry("payload", self.payload)?;
        m.end()
    }
}
