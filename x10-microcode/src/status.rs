//! Reply status codes.

use core::fmt;

/// Status byte of a reply or a deferred-reply event. One code for every way a request can fail.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status {
    /// 0x00: done; the payload holds the value.
    Ok,
    /// 0x01: accepted, the value comes later in a deferred-reply event with the same sequence
    /// number (pulse-in and other long operations).
    Pending,
    /// 0x02: the frame or its data has the wrong length.
    BadLength,
    /// 0x03: unknown function code.
    UnknownFunction,
    /// 0x04: unknown operand for this function.
    UnknownOperand,
    /// 0x05: the board has no such port.
    PortOutOfRange,
    /// 0x06: the operation does not exist on this kind of port.
    WrongPortKind,
    /// 0x07: byte 1 is not this board's address.
    WrongAddress,
    /// 0x08: the PEC byte does not match.
    PecMismatch,
    /// 0x09: a reserved bit is set or a data value is out of range.
    BadArgument,
    /// 0x0A: valid request, but this board does not implement it (e.g. serial).
    Unsupported,
    /// 0x0B: the board cannot take it now (e.g. a pulse-in already running on that pin).
    Busy,
    /// 0x0C: the operation ran out of time (e.g. no pulse before the pulse-in timeout).
    Timeout,
    /// 0x0D: the MB read a reply, but no request is waiting for one.
    NoRequest,
    /// 0x10 (update): the image is built for another board kind.
    WrongKind,
    /// 0x11 (update): the image is longer than the board's update slot.
    TooLarge,
    /// 0x12 (update): the CRC-32 over the received image is not the one `begin` announced.
    BadCrc,
    /// 0x13 (update): a chunk at an offset other than the next expected one (or the last
    /// one again).
    OutOfOrder,
    /// 0x14 (update): the image's version is below the floor compiled into the bootloader.
    TooOld,
    /// 0x15 (update): the flash refused an erase or a write.
    FlashError,
    /// 0x16 (update): a chunk or commit with no transfer begun.
    NoSession,
    /// 0x17 (update): commit before every byte of the image was received.
    Incomplete,
    /// A code this version does not know.
    Unknown(u8),
}

impl Status {
    /// Decodes a status byte; unknown codes become [`Status::Unknown`].
    pub const fn from_byte(b: u8) -> Status {
        match b {
            0x00 => Status::Ok,
            0x01 => Status::Pending,
            0x02 => Status::BadLength,
            0x03 => Status::UnknownFunction,
            0x04 => Status::UnknownOperand,
            0x05 => Status::PortOutOfRange,
            0x06 => Status::WrongPortKind,
            0x07 => Status::WrongAddress,
            0x08 => Status::PecMismatch,
            0x09 => Status::BadArgument,
            0x0A => Status::Unsupported,
            0x0B => Status::Busy,
            0x0C => Status::Timeout,
            0x0D => Status::NoRequest,
            0x10 => Status::WrongKind,
            0x11 => Status::TooLarge,
            0x12 => Status::BadCrc,
            0x13 => Status::OutOfOrder,
            0x14 => Status::TooOld,
            0x15 => Status::FlashError,
            0x16 => Status::NoSession,
            0x17 => Status::Incomplete,
            x => Status::Unknown(x),
        }
    }

    /// Encodes the status byte.
    pub const fn to_byte(self) -> u8 {
        match self {
            Status::Ok => 0x00,
            Status::Pending => 0x01,
            Status::BadLength => 0x02,
            Status::UnknownFunction => 0x03,
            Status::UnknownOperand => 0x04,
            Status::PortOutOfRange => 0x05,
            Status::WrongPortKind => 0x06,
            Status::WrongAddress => 0x07,
            Status::PecMismatch => 0x08,
            Status::BadArgument => 0x09,
            Status::Unsupported => 0x0A,
            Status::Busy => 0x0B,
            Status::Timeout => 0x0C,
            Status::NoRequest => 0x0D,
            Status::WrongKind => 0x10,
            Status::TooLarge => 0x11,
            Status::BadCrc => 0x12,
            Status::OutOfOrder => 0x13,
            Status::TooOld => 0x14,
            Status::FlashError => 0x15,
            Status::NoSession => 0x16,
            Status::Incomplete => 0x17,
            Status::Unknown(x) => x,
        }
    }

    /// True for [`Status::Ok`].
    pub const fn is_ok(self) -> bool {
        matches!(self, Status::Ok)
    }

    /// Lower-case name used by the `x10` tool and the docs (`ok`, `pending`, `bad_length`, …).
    pub const fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Pending => "pending",
            Status::BadLength => "bad_length",
            Status::UnknownFunction => "unknown_function",
            Status::UnknownOperand => "unknown_operand",
            Status::PortOutOfRange => "port_out_of_range",
            Status::WrongPortKind => "wrong_port_kind",
            Status::WrongAddress => "wrong_address",
            Status::PecMismatch => "pec_mismatch",
            Status::BadArgument => "bad_argument",
            Status::Unsupported => "unsupported",
            Status::Busy => "busy",
            Status::Timeout => "timeout",
            Status::NoRequest => "no_request",
            Status::WrongKind => "wrong_kind",
            Status::TooLarge => "too_large",
            Status::BadCrc => "bad_crc",
            Status::OutOfOrder => "out_of_order",
            Status::TooOld => "too_old",
            Status::FlashError => "flash_error",
            Status::NoSession => "no_session",
            Status::Incomplete => "incomplete",
            Status::Unknown(_) => "unknown",
        }
    }

    /// Inverse of [`Status::name`] for the known codes.
    pub fn from_name(name: &str) -> Option<Status> {
        (0u8..=0x17)
            .map(Status::from_byte)
            .find(|s| !matches!(s, Status::Unknown(_)) && s.name() == name)
    }
}

impl From<u8> for Status {
    fn from(b: u8) -> Status {
        Status::from_byte(b)
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Status::Unknown(x) => write!(f, "unknown({x:#04x})"),
            s => f.write_str(s.name()),
        }
    }
}
