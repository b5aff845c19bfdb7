//! The messages both ways: [`ToHost`] (motherboard to laptop) and [`ToDevice`] (laptop to
//! motherboard). postcard encodes an enum as its variant's index (a varint) followed by its
//! fields, so a new message is a new variant at the end: older decoders refuse it as an
//! unknown variant (a counted, typed error), and [`LINK_VERSION`] in [`Hello`] says which
//! variants a side knows. docs/usb-link.md lists every variant with example bytes.

use serde::{Deserialize, Serialize};

/// The version of this message set. 1: the variants below.
pub const LINK_VERSION: u16 = 1;

/// An operation as the bus carries it: byte 0 of a request (function and operand), byte 2
/// (the port field) and the data bytes. `x10_microcode::Op::parse(fn_op, port, data)` reads it.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct WireOp<'a> {
    /// Function (high nibble) and operand (low nibble).
    pub fn_op: u8,
    /// The port field: port number and pin bits.
    pub port: u8,
    /// The data bytes.
    #[serde(borrow)]
    pub data: &'a [u8],
}

/// Why a call failed, as `x10_devices::LinkError` says it (plus the link's own refusals).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CallError {
    /// 0: the board did not acknowledge after every retry.
    Nack,
    /// 1: no reply in time.
    Timeout,
    /// 2: arbitration lost on every retry.
    ArbitrationLost,
    /// 3: a bus fault.
    Bus,
    /// 4: a malformed reply.
    BadReply,
    /// 5: the board answered with this status byte.
    Status(u8),
    /// 6: the operation could not be encoded or parsed (nothing was sent).
    Invalid,
    /// 7: no free request slot.
    Busy,
    /// 8: not offered by this link.
    Unsupported,
    /// 9: the board address is not a valid address.
    BadAddress,
    /// 10: the board's firmware is being updated.
    Updating,
}

/// How a call ended: its reply payload, or why not.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome<'a> {
    /// 0: the reply's payload.
    Ok(#[serde(borrow)] &'a [u8]),
    /// 1: the error.
    Err(CallError),
}

/// One finished call (a robot task's or the laptop's), on the motherboard's clock.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct CallRec<'a> {
    /// The board called (0 = the motherboard's own ports).
    pub db: u8,
    /// The operation.
    #[serde(borrow)]
    pub op: WireOp<'a>,
    /// How it ended.
    #[serde(borrow)]
    pub outcome: Outcome<'a>,
    /// When it started, µs since the motherboard booted.
    pub start_us: u64,
    /// When it ended.
    pub end_us: u64,
}

/// One event the motherboard routed (pin change, analog threshold, deferred reply, boot,
/// rejected...): the fields of `x10_microcode::Event`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct EventRec<'a> {
    /// The board it came from.
    pub db: u8,
    /// `x10_microcode::EventKind` as its byte.
    pub kind: u8,
    /// The port field (port and pin).
    pub port: u8,
    /// Sequence number (deferred reply, rejected) or the board's event counter.
    pub seq: u8,
    /// Status byte.
    pub status: u8,
    /// Value bytes.
    #[serde(borrow)]
    pub payload: &'a [u8],
    /// When the motherboard routed it, µs since boot.
    pub at_us: u64,
}

/// What an output change set.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputValue {
    /// 0: a digital pin's level (true = high).
    Level(bool),
    /// 1: a PWM duty, 0-255.
    Duty(u8),
    /// 2: a PWM frequency in Hz.
    FrequencyHz(u32),
    /// 3: a servo pulse width in µs.
    PulseWidthUs(u16),
}

/// An actuator change the motherboard commanded: an output operation that ended `ok`.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutputRec {
    /// The board.
    pub db: u8,
    /// The port field (port number and pin bits, as in the request).
    pub port: u8,
    /// The value set.
    pub value: OutputValue,
    /// When the call that set it ended, µs since boot.
    pub at_us: u64,
}

/// What the motherboard could not send, counted since the laptop said hello.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dropped {
    /// Call records that did not fit the buffer.
    pub calls: u32,
    /// Event records that did not fit.
    pub events: u32,
    /// Output records that did not fit.
    pub outputs: u32,
    /// Log bytes that did not fit.
    pub log_bytes: u32,
    /// Frames from the laptop that did not decode (COBS, CRC, postcard).
    pub bad_frames: u32,
}

/// The first message each way: who speaks and which version of the messages it knows.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hello<'a> {
    /// [`LINK_VERSION`] of the sender.
    pub version: u16,
    /// The motherboard's bus address (0 from the laptop).
    pub address: u8,
    /// The board (`"Pico"`, `"STM32G431"`; the laptop's program name).
    #[serde(borrow)]
    pub board: &'a str,
    /// The robot program's name (empty from the laptop).
    #[serde(borrow)]
    pub robot: &'a str,
}

/// The motherboard's counters (`firmware_mb::MbDiagnostics`) in the order of
/// [`DIAG_NAMES`].
pub type DiagCounters = heapless::Vec<u32, 48>;

/// The names of [`DiagCounters`], in order (the fields of `firmware_mb::MbDiagnostics`).
pub const DIAG_NAMES: [&str; 42] = [
    "requests",
    "completed",
    "timeouts",
    "nacks",
    "arbitration_failures",
    "bus_errors",
    "bad_replies",
    "status_errors",
    "busy",
    "arbitration_lost",
    "nacked",
    "keepalives",
    "failsafe_resends",
    "keepalive_failures",
    "retries",
    "yields",
    "cancelled",
    "abandoned",
    "late_replies",
    "duplicate_replies",
    "unknown_replies",
    "events",
    "bad_events",
    "events_dropped",
    "rejected",
    "failsafe_trips",
    "boots",
    "watchdog_resets",
    "panic_resets",
    "fault_resets",
    "overflows",
    "event_gaps",
    "events_lost",
    "pec_resyncs",
    "unexpected_reads",
    "listener_errors",
    "announces",
    "assigns",
    "unassigned",
    "boards_found",
    "boards_lost",
    "collisions",
];

/// Motherboard to laptop.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub enum ToHost<'a> {
    /// 0: the answer to the laptop's hello; records flow from now on.
    Hello(#[serde(borrow)] Hello<'a>),
    /// 1: defmt log bytes (rzcobs frames as defmt's encoder wrote them).
    Log(#[serde(borrow)] &'a [u8]),
    /// 2: a finished call.
    Call(#[serde(borrow)] CallRec<'a>),
    /// 3: an event.
    Event(#[serde(borrow)] EventRec<'a>),
    /// 4: an output change.
    Output(OutputRec),
    /// 5: what was dropped so far (sent when it changed and there is room again).
    Dropped(Dropped),
    /// 6: the answer to [`ToDevice::Call`] `id`.
    Reply {
        /// The request's id.
        id: u16,
        /// How the call ended.
        #[serde(borrow)]
        outcome: Outcome<'a>,
    },
    /// 7: the answer to [`ToDevice::Diagnostics`] `id`.
    Diagnostics {
        /// The request's id.
        id: u16,
        /// The counters, in the order of [`DIAG_NAMES`].
        counters: DiagCounters,
    },
    /// 8: the answer to [`ToDevice::ListBoards`] `id`: the addresses of the boards the
    /// motherboard knows of (0 = its own ports).
    Boards {
        /// The request's id.
        id: u16,
        /// Addresses, ascending.
        addresses: heapless::Vec<u8, 16>,
    },
    /// 9: a request the motherboard could not take (unknown variant of a newer laptop, or
    /// the link's request queue full): its id, or 0 when it did not decode.
    Refused {
        /// The request's id (0 when unknown).
        id: u16,
    },
}

/// Laptop to motherboard. New requests (plug and play's assign, firmware update) come as new
/// variants at the end, with a new [`LINK_VERSION`].
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq, Eq)]
pub enum ToDevice<'a> {
    /// 0: start listening: the motherboard answers with its own hello and keeps records
    /// from now on (until the port closes or [`ToDevice::Bye`]).
    Hello(#[serde(borrow)] Hello<'a>),
    /// 1: stop listening: no records are kept, counters only.
    Bye,
    /// 2: call `op` on board `db` as a robot task would; answered with [`ToHost::Reply`].
    Call {
        /// Chosen by the laptop, copied into the reply.
        id: u16,
        /// The board (0 = the motherboard's own ports).
        db: u8,
        /// The operation.
        #[serde(borrow)]
        op: WireOp<'a>,
    },
    /// 3: read the motherboard's counters; answered with [`ToHost::Diagnostics`].
    Diagnostics {
        /// Chosen by the laptop.
        id: u16,
    },
    /// 4: list the boards; answered with [`ToHost::Boards`].
    ListBoards {
        /// Chosen by the laptop.
        id: u16,
    },
}
