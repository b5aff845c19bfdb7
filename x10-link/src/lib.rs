//! # x10-link: the USB link between the motherboard and a laptop
//!
//! The messages both ways ([`ToHost`], [`ToDevice`]), their framing ([`encode`],
//! [`FrameReader`]: postcard, a CRC-16, COBS, a zero byte) and, with the feature `mb`, the
//! motherboard's side: the bounded [`recorder::Recorder`] (a `firmware_mb::CallObserver`)
//! and [`recorder::serve`], which answers the laptop's requests through `X10::call`. The
//! laptop's side is `x10 monitor` (x10-cli). Every frame is documented, with example bytes,
//! in docs/usb-link.md. no_std, no allocation; decoding never panics, whatever the bytes.
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

mod frame;
mod msg;
#[cfg(feature = "mb")]
pub mod recorder;
mod wire;

pub use frame::{
    decode, encode, encode_host, unframe, Feed, FrameError, FrameReader, MAX_FRAME, MAX_LOG_CHUNK,
    MAX_MESSAGE,
};
pub use msg::{
    AssignStatus, BoardEntry, BoardState, CallError, CallRec, DiagCounters, Dropped, EventRec,
    Hello, Outcome, OutputRec, OutputValue, ToDevice, ToHost, UpdateFailure, UpdatePhase,
    UpdateRec, UpdateStatus, WireOp, BOARDS_PER_LIST, DIAG_NAMES, LINK_VERSION,
};
pub use wire::{read_to_device, write_to_host};
