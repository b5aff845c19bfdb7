//! Errors of parsing and emitting frames.

use core::fmt;

use crate::Status;

/// Why a frame could not be parsed or emitted.
///
/// Every parse error maps to the [`Status`] a daughterboard answers with ([`Error::status`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error {
    /// The frame is shorter than its header, or than the length its header declares.
    Truncated,
    /// The frame has bytes after its declared end, or an operation has the wrong data length.
    BadLength,
    /// The buffer handed to `emit` is shorter than `buffer_len()`.
    BufferTooShort,
    /// The function code (high nibble of byte 0) is not defined.
    UnknownFunction(u8),
    /// The operand (low nibble of byte 0) is not defined for this function.
    UnknownOperand {
        /// Function code.
        function: u8,
        /// Operand code.
        operand: u8,
    },
    /// A DB address that is neither 0 nor in `0x08..=0x77`.
    BadAddress(u8),
    /// A 1-based port number of 0 or above 64.
    BadPort(u8),
    /// The operation does not exist on this kind of port (PWM on a sensor port, analog on an
    /// actuator port, …).
    WrongPortKind,
    /// A field that must be zero is not, or a data value is out of its range.
    BadArgument,
    /// A batch inside a batch.
    NestedBatch,
    /// The payload is longer than [`crate::MAX_PAYLOAD`] or data longer than
    /// [`crate::MAX_REQUEST_DATA`].
    TooLong,
    /// The PEC byte (the check of a frame of up to 13 bytes) does not match the frame.
    PecMismatch {
        /// PEC byte received.
        received: u8,
        /// PEC computed over the frame.
        computed: u8,
    },
    /// The CRC-16 (the check of a frame of more than 13 bytes) does not match the frame. Its
    /// values are not kept, so that `Error` stays three bytes (every parse returns it).
    CrcMismatch,
}

impl Error {
    /// The status a daughterboard replies with when a request fails to parse with this error.
    pub const fn status(self) -> Status {
        match self {
            Error::Truncated | Error::BadLength | Error::BufferTooShort | Error::TooLong => {
                Status::BadLength
            }
            Error::UnknownFunction(_) => Status::UnknownFunction,
            Error::UnknownOperand { .. } => Status::UnknownOperand,
            Error::BadAddress(_) => Status::WrongAddress,
            Error::BadPort(_) => Status::PortOutOfRange,
            Error::WrongPortKind => Status::WrongPortKind,
            Error::BadArgument | Error::NestedBatch => Status::BadArgument,
            Error::PecMismatch { .. } | Error::CrcMismatch => Status::PecMismatch,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated => f.write_str("frame truncated"),
            Error::BadLength => f.write_str("bad frame or data length"),
            Error::BufferTooShort => f.write_str("buffer too short"),
            Error::UnknownFunction(x) => write!(f, "unknown function {x:#x}"),
            Error::UnknownOperand { function, operand } => {
                write!(f, "unknown operand {operand:#x} of function {function:#x}")
            }
            Error::BadAddress(a) => write!(f, "bad daughterboard address {a:#04x}"),
            Error::BadPort(p) => write!(f, "bad port number {p} (ports count from 1)"),
            Error::WrongPortKind => f.write_str("operation not available on this kind of port"),
            Error::BadArgument => f.write_str("bad argument"),
            Error::NestedBatch => f.write_str("batch inside a batch"),
            Error::TooLong => f.write_str("data or payload too long"),
            Error::PecMismatch { received, computed } => {
                write!(
                    f,
                    "PEC mismatch: received {received:#04x}, computed {computed:#04x}"
                )
            }
            Error::CrcMismatch => f.write_str("CRC-16 mismatch"),
        }
    }
}

impl core::error::Error for Error {}
