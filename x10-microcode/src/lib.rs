//! # x10-microcode: the X10 wire protocol
//!
//! Everything that crosses the X10 peripheral bus is defined here, and nothing else: no I/O, no
//! timing, no allocation. The motherboard (MB) runtime, the daughterboard (DB) runtime, the
//! device drivers, the simulator and the `x10` command-line tool all speak through these types.
//!
//! Three frame kinds exist (byte tables in `docs/protocol.md`):
//!
//! * [`Request`] (MB → DB, an I2C write to the DB): thesis Table 3.2 byte for byte.
//!   `function|operand, db, kind|port|pin, seq, data…`. Example: digital HIGH to DB 9, actuator
//!   port 1, pin B, sequence 2 is `12 09 01 02`.
//! * [`Reply`] (DB → MB, the read half of a write-then-read): `seq, status, len, payload…`.
//! * [`Event`] (DB → MB, written by a DB that briefly holds the master role to the MB's own
//!   address): `source, kind, port, seq, status, len, payload…`.
//!
//! With SMBus PEC negotiated ([`pec`]), every frame carries one more trailing byte.
//!
//! ## Layout, after smoltcp's `wire`
//! Each frame kind has a zero-copy *view* ([`RequestFrame`], [`ReplyFrame`], [`EventFrame`]) over
//! any `AsRef<[u8]>` buffer, with `new_checked`, getters and (for `AsMut` buffers) setters, and a
//! plain *representation* ([`Request`], [`Reply`], [`Event`]) with `parse`, `buffer_len` and
//! `emit`.
//!
//! ## Contract
//! * Parsing never panics, on any input. Unknown function, operand, status and event codes are
//!   reported as values ([`Error::UnknownFunction`], [`Status::Unknown`], …), never a panic.
//! * After `new_checked` succeeds no getter of a view panics.
//! * `emit` never panics given a buffer of at least `buffer_len()` bytes; given a shorter one it
//!   returns [`Error::BufferTooShort`].
//!
//! The crate is `no_std` and never allocates. With the `defmt` feature every public type
//! implements `defmt::Format`. With the `serde` feature the frames and their values implement
//! `serde::Serialize`, and the values `serde::Deserialize`, in the JSON shape of the `x10`
//! tool (`docs/protocol.md`, "The `x10` tool"); see the `serde_repr` module's source.
#![no_std]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

mod batch;
mod error;
mod event;
mod op;
pub mod pec;
mod reply;
mod request;
#[cfg(feature = "serde")]
mod serde_repr;
mod status;
pub mod sweep;
mod system;
#[cfg(feature = "test-support")]
#[doc(hidden)]
pub mod test_support;
mod types;
mod update;

pub use batch::{Batch, BatchItem, BatchItems, BatchResults, BatchWriter};
pub use error::Error;
pub use event::{Event, EventFrame, EventKind};
pub use op::{Function, Op, Operand, ReplyLen};
pub use reply::{Payload, Reply, ReplyFrame};
pub use request::{Request, RequestFrame};
pub use status::Status;
pub use system::{
    BoardKind, BootInfo, Capabilities, Diagnostics, EventConfig, Identity, ResetReason, ScanResult,
    DIAGNOSTIC_NAMES,
};
pub use types::{Address, Edge, Level, Pin, PinRef, Port, PortKind, Uid};
pub use update::{
    image_crc32, ImageInfo, UpdateFrame, UpdateOp, UpdateReport, UpdateState, Version, CHUNK_MAX,
    IMAGE_CRC,
};

/// Result type of this crate.
pub type Result<T> = core::result::Result<T, Error>;

/// Version of the wire protocol described in `docs/protocol.md`, reported by `identify`.
pub const PROTOCOL_VERSION: u8 = 1;

/// Length of the request header (function/operand, DB, port/pin, sequence number).
pub const REQUEST_HEADER_LEN: usize = 4;
/// Length of the reply header (sequence number, status, payload length).
pub const REPLY_HEADER_LEN: usize = 3;
/// Length of the event header (source, kind, port/pin, sequence number, status, payload length).
pub const EVENT_HEADER_LEN: usize = 6;

/// Largest request frame, PEC byte excluded. Boards size their receive buffers from it.
pub const MAX_REQUEST_LEN: usize = 32;
/// Largest data part of a request.
pub const MAX_REQUEST_DATA: usize = MAX_REQUEST_LEN - REQUEST_HEADER_LEN;
/// Largest payload of a reply or event.
pub const MAX_PAYLOAD: usize = 28;
/// Largest reply frame, PEC byte excluded.
pub const MAX_REPLY_LEN: usize = REPLY_HEADER_LEN + MAX_PAYLOAD;
/// Largest event frame, PEC byte excluded.
pub const MAX_EVENT_LEN: usize = EVENT_HEADER_LEN + MAX_PAYLOAD;
/// Largest frame of any kind with its check (a CRC-16 on every frame over 13 bytes,
/// [`pec::check_len`]): the size of every transfer buffer.
pub const MAX_FRAME_LEN: usize = MAX_EVENT_LEN + pec::MAX_CHECK_LEN;
