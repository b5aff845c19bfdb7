//! The messages both ways: [`ToHost`] (motherboard to laptop) and [`ToDevice`] (laptop to
//! motherboard). postcard encodes an enum as its variant's index (a varint) followed by its
//! fields, so a new message is a new variant at the end: older decoders refuse it as an
//! unknown variant (a counted, typed error), and [`LINK_VERSION`] in [`Hello`] says which
//! variants a side knows. docs/usb-link.md lists every variant with example bytes.

use serde::{Deserialize, Serialize};

/// The version of this message set. 1: [`ToDevice`] 0-4, [`ToHost`] 0-9. 2 (issue 26's
/// plug-and-play and update requests): [`ToDevice::Boards`], [`ToDevice::Assign`],
/// [`ToDevice::Update`]; [`ToHost::BoardList`], [`ToHost::Assigned`],
/// [`ToHost::UpdateAnswer`], [`ToHost::Update`].
pub const LINK_VERSION: u16 = 2;

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

/// What the motherboard knows of a board's state ([`BoardEntry`]).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardState {
    /// 0: it answers.
    Present,
    /// 1: it stopped answering, or it is unaddressed and its `assign` not yet answered.
    Lost,
    /// 2: its firmware is being updated.
    Updating,
    /// 3: another board answers at its address (a collision).
    Collided,
}

/// One board plug and play knows (`firmware_mb::KnownBoard`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardEntry {
    /// Its address.
    pub address: u8,
    /// Its unique ID.
    pub uid: [u8; 8],
    /// Its board kind (`x10_microcode::BoardKind`'s byte).
    pub kind: u8,
    /// Its firmware version: major, minor, patch.
    pub firmware: [u8; 3],
    /// Its state.
    pub state: BoardState,
}

/// Boards per [`ToHost::BoardList`] (a message stays within `MAX_MESSAGE`).
pub const BOARDS_PER_LIST: usize = 8;

/// How the laptop's [`ToDevice::Assign`] ended (`firmware_mb::AssignError`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AssignStatus {
    /// 0: the board confirmed its `set_address` (or, unaddressed, its `assign` was sent): it
    /// starts again at the new address; [`ToDevice::Boards`] lists it there, present, once its
    /// `boot` came from there.
    Done,
    /// 1: no board with that unique ID is known.
    UnknownUid,
    /// 2: not an address a board may take (outside `0x08..=0x76`, the motherboard's, `0x64`).
    Reserved,
    /// 3: another board is there, or it is pinned to another board.
    Taken,
    /// 4: the board shares its address with another (a collision): it cannot be moved alone.
    Collided,
    /// 5: the board did not confirm: its `set_address` failed with this error.
    NotConfirmed(CallError),
}

/// The answer to the laptop's [`ToDevice::Update`] (`firmware_mb::update::UpdateRefusal`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpdateStatus {
    /// 0: started: this many boards will be updated ([`ToHost::Update`] records follow).
    Started(u8),
    /// 1: this motherboard image carries no daughterboard images.
    NoImages,
    /// 2: no board with that unique ID is known.
    UnknownUid,
    /// 3: the board does not answer.
    NotPresent,
    /// 4: no image of the board's kind is carried.
    NoImage,
    /// 5: already up to date (every board, for an update of all).
    UpToDate,
    /// 6: busy: an update is under way, of the board at this address (0: one is about to
    /// start).
    Busy(u8),
}

/// Why an update failed (`firmware_mb::update::UpdateError`, without its details: the
/// motherboard's log has them).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpdateFailure {
    /// 0: no update method for the board's kind.
    NoMethod,
    /// 1: `enter_update` refused or failed.
    Enter,
    /// 2: the bootloader did not answer in time.
    NoBootloader,
    /// 3: the bootloader refused `begin`, a chunk or `commit`.
    Refused,
    /// 4: a transfer failed on the bus after every retry.
    Link,
    /// 5: the board did not come back in time.
    NotBack,
    /// 6: it came back with its old version (rolled back).
    RolledBack,
    /// 7: the ROM bootloader (STM32C011) refused, or the update through it failed.
    Rom,
}

/// Where an update is.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpdatePhase {
    /// 0: it starts.
    Started,
    /// 1: the board runs the new version (confirmed).
    Done,
    /// 2: it failed.
    Failed(UpdateFailure),
}

/// An update of a board's firmware by the motherboard (its own or the laptop's request).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct UpdateRec {
    /// The board.
    pub db: u8,
    /// The version it ran.
    pub from: [u8; 3],
    /// The version carried.
    pub to: [u8; 3],
    /// Where the update is.
    pub phase: UpdatePhase,
    /// When, µs since the motherboard booted.
    pub at_us: u64,
}

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
    /// 10 (version 2): the answer to [`ToDevice::Boards`] `id`: the known boards from index
    /// `first` on, at most [`BOARDS_PER_LIST`], in the order they were first heard.
    BoardList {
        /// The request's id.
        id: u16,
        /// How many boards the motherboard knows.
        total: u8,
        /// The index of `boards[0]`.
        first: u8,
        /// The boards.
        boards: heapless::Vec<BoardEntry, BOARDS_PER_LIST>,
    },
    /// 11 (version 2): the answer to [`ToDevice::Assign`] `id`.
    Assigned {
        /// The request's id.
        id: u16,
        /// How it ended.
        status: AssignStatus,
    },
    /// 12 (version 2): the answer to [`ToDevice::Update`] `id`.
    UpdateAnswer {
        /// The request's id.
        id: u16,
        /// Started, or why not.
        status: UpdateStatus,
    },
    /// 13 (version 2): an update starts or ended.
    Update(UpdateRec),
}

/// Laptop to motherboard. New requests come as new variants at the end, with a new
/// [`LINK_VERSION`] (version 2 added 5-7).
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
    /// 5 (version 2): the boards plug and play knows, in full, from index `first`; answered
    /// with [`ToHost::BoardList`] (ask again from `first + boards.len()` until `total`).
    Boards {
        /// Chosen by the laptop.
        id: u16,
        /// The index of the first board wanted.
        first: u8,
    },
    /// 6 (version 2): give the board with unique ID `uid` the address `address`; answered
    /// with [`ToHost::Assigned`] once it confirmed (or why not).
    Assign {
        /// Chosen by the laptop.
        id: u16,
        /// The board's unique ID.
        uid: [u8; 8],
        /// Its new address.
        address: u8,
    },
    /// 7 (version 2): update the board `uid` now (whatever the image's policy), or every
    /// board out of date (`None`: a `Never` policy overridden), with the images the
    /// motherboard carries; answered with [`ToHost::UpdateAnswer`], then [`ToHost::Update`]
    /// records.
    Update {
        /// Chosen by the laptop.
        id: u16,
        /// The board, or `None` for every board.
        uid: Option<[u8; 8]>,
    },
}
