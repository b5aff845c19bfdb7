//! Events (DB → MB): written by a daughterboard that briefly holds the master role, to the MB's
//! own address. `source, kind, port, seq, status, len, payload[len]`.
//!
//! An I2C target cannot see who wrote to it, so the sender puts its own address in byte 0, as
//! SMBus Host Notify does. `seq` is the request's sequence number for a deferred reply or a
//! rejected request, and the board's own event counter otherwise (gaps reveal lost events).

use core::fmt;

use crate::reply::layout;
use crate::types::{Address, PinRef};
use crate::{pec, Error, ReplyFrame, Result, Status, EVENT_HEADER_LEN, MAX_PAYLOAD};

mod field {
    pub const SOURCE: usize = 0;
    pub const KIND: usize = 1;
    pub const PORT: usize = 2;
    /// From here on (`seq, status, len, payload[len]`), the frame is laid out as a reply
    /// ([`crate::reply::layout`]).
    pub const REPLY: usize = 3;
    pub const PAYLOAD: usize = 6;
}

/// What an event reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EventKind {
    /// 0x01: a digital pin changed; payload: the new level (1 byte).
    PinChange,
    /// 0x02: an analog value crossed its window; payload: value u16 LE, then 1 if now inside
    /// the window, 0 if outside.
    AnalogThreshold,
    /// 0x03: the reply to a request answered `pending`; `seq` and `status` are the request's,
    /// payload its value (pulse width in µs, u32 LE).
    DeferredReply,
    /// 0x04: the MB was silent past the failsafe timeout; every actuator is in its safe state.
    /// Payload: the timeout in ms (u16 LE).
    FailsafeTripped,
    /// 0x05: a request that has no reply (an output) was refused; `seq` is the request's,
    /// `status` says why. Nothing is refused silently.
    Rejected,
    /// 0x06: the event queue overflowed; payload: number of events dropped (u16 LE).
    Overflow,
    /// 0x07: the board (re)started; payload: a [`crate::BootInfo`] (identity, reset reason,
    /// unique ID). Always sent with its check.
    Boot,
    /// 0x08: a board says who it is (plug and play): an unaddressed board, from
    /// [`Address::UNADDRESSED`], until the MB assigns it an address; or any board asked by
    /// `who_is_there`, from its own address. Payload: a [`crate::BootInfo`] with the unique ID.
    /// Always sent with its check.
    Announce,
    /// Any other code.
    Unknown(u8),
}

impl EventKind {
    /// Decodes an event kind byte.
    pub const fn from_byte(b: u8) -> EventKind {
        match b {
            1 => EventKind::PinChange,
            2 => EventKind::AnalogThreshold,
            3 => EventKind::DeferredReply,
            4 => EventKind::FailsafeTripped,
            5 => EventKind::Rejected,
            6 => EventKind::Overflow,
            7 => EventKind::Boot,
            8 => EventKind::Announce,
            x => EventKind::Unknown(x),
        }
    }

    /// Encodes the event kind byte.
    pub const fn to_byte(self) -> u8 {
        match self {
            EventKind::PinChange => 1,
            EventKind::AnalogThreshold => 2,
            EventKind::DeferredReply => 3,
            EventKind::FailsafeTripped => 4,
            EventKind::Rejected => 5,
            EventKind::Overflow => 6,
            EventKind::Boot => 7,
            EventKind::Announce => 8,
            EventKind::Unknown(x) => x,
        }
    }

    /// Name used by the `x10` tool and the docs.
    pub const fn name(self) -> &'static str {
        match self {
            EventKind::PinChange => "pin_change",
            EventKind::AnalogThreshold => "analog_threshold",
            EventKind::DeferredReply => "deferred_reply",
            EventKind::FailsafeTripped => "failsafe_tripped",
            EventKind::Rejected => "rejected",
            EventKind::Overflow => "overflow",
            EventKind::Boot => "boot",
            EventKind::Announce => "announce",
            EventKind::Unknown(_) => "unknown",
        }
    }

    /// Inverse of [`EventKind::name`] for the known kinds.
    pub fn from_name(name: &str) -> Option<EventKind> {
        (1u8..=8)
            .map(EventKind::from_byte)
            .find(|k| k.name() == name)
    }
}

impl fmt::Display for EventKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EventKind::Unknown(x) => write!(f, "unknown({x:#04x})"),
            k => f.write_str(k.name()),
        }
    }
}

/// A zero-copy view of an event frame (PEC byte excluded).
#[derive(Debug, Clone)]
pub struct EventFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EventFrame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> EventFrame<T> {
        EventFrame { buffer }
    }

    /// Wraps a buffer and checks its length.
    ///
    /// # Errors
    /// See [`EventFrame::check_len`].
    pub fn new_checked(buffer: T) -> Result<EventFrame<T>> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// Checks that the header and the declared payload are in the buffer.
    ///
    /// # Errors
    /// [`Error::Truncated`], or [`Error::TooLong`] for a declared payload over
    /// [`MAX_PAYLOAD`].
    pub fn check_len(&self) -> Result<()> {
        layout::check_len(self.reply_part())
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }

    /// Bytes 3.., laid out as a reply.
    fn reply_part(&self) -> &[u8] {
        self.buffer.as_ref().get(field::REPLY..).unwrap_or(&[])
    }

    /// Byte 0, the sender's address.
    pub fn source(&self) -> u8 {
        self.byte(field::SOURCE)
    }

    /// Byte 1, the event kind.
    pub fn kind(&self) -> EventKind {
        EventKind::from_byte(self.byte(field::KIND))
    }

    /// Byte 2, the port and pin concerned (0 when none).
    pub fn pin_ref(&self) -> PinRef {
        PinRef::from_byte(self.byte(field::PORT))
    }

    /// Byte 3, the sequence number.
    pub fn seq(&self) -> u8 {
        ReplyFrame::new_unchecked(self.reply_part()).seq()
    }

    /// Byte 4, the status.
    pub fn status(&self) -> Status {
        ReplyFrame::new_unchecked(self.reply_part()).status()
    }

    /// Byte 5, the payload length.
    pub fn payload_len(&self) -> u8 {
        ReplyFrame::new_unchecked(self.reply_part()).payload_len()
    }

    /// Header plus payload.
    pub fn frame_len(&self) -> usize {
        field::REPLY + layout::frame_len(self.reply_part())
    }

    /// The payload.
    pub fn payload(&self) -> &[u8] {
        layout::payload(self.reply_part())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EventFrame<T> {
    fn set_byte(&mut self, i: usize, v: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(i) {
            *b = v;
        }
    }

    /// Bytes 3.., laid out as a reply, writable.
    fn reply_part_mut(&mut self) -> ReplyFrame<&mut [u8]> {
        ReplyFrame::new_unchecked(
            self.buffer
                .as_mut()
                .get_mut(field::REPLY..)
                .unwrap_or(&mut []),
        )
    }

    /// Sets byte 0.
    pub fn set_source(&mut self, v: u8) {
        self.set_byte(field::SOURCE, v)
    }

    /// Sets byte 1.
    pub fn set_kind(&mut self, k: EventKind) {
        self.set_byte(field::KIND, k.to_byte())
    }

    /// Sets byte 2.
    pub fn set_pin_ref(&mut self, p: PinRef) {
        self.set_byte(field::PORT, p.to_byte())
    }

    /// Sets byte 3.
    pub fn set_seq(&mut self, v: u8) {
        self.reply_part_mut().set_seq(v)
    }

    /// Sets byte 4.
    pub fn set_status(&mut self, s: Status) {
        self.reply_part_mut().set_status(s)
    }

    /// Sets byte 5.
    pub fn set_payload_len(&mut self, v: u8) {
        self.reply_part_mut().set_payload_len(v)
    }

    /// The payload, writable (as long as byte 5 declares).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        layout::payload_mut(self.reply_part_mut().into_inner())
    }
}

/// An event from a daughterboard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Event<'a> {
    /// The sender (0 for the internal DB).
    pub source: Address,
    /// What happened.
    pub kind: EventKind,
    /// Port and pin concerned (byte 0 of the port field when none).
    pub pin: PinRef,
    /// Request sequence number (deferred reply, rejected) or the board's event counter.
    pub seq: u8,
    /// Status (deferred reply, rejected); `ok` otherwise.
    pub status: Status,
    /// Value bytes.
    pub payload: &'a [u8],
}

impl<'a> Event<'a> {
    /// Parses exactly one event frame.
    ///
    /// # Errors
    /// [`Error::Truncated`], [`Error::TooLong`], [`Error::BadLength`] for bytes after the
    /// payload, [`Error::BadAddress`] for a bad source address.
    pub fn parse(bytes: &'a [u8]) -> Result<Event<'a>> {
        let frame = EventFrame::new_checked(bytes)?;
        if frame.frame_len() != bytes.len() {
            return Err(Error::BadLength);
        }
        let payload = bytes
            .get(field::PAYLOAD..frame.frame_len())
            .ok_or(Error::Truncated)?;
        Ok(Event {
            source: Address::new(frame.source())?,
            kind: frame.kind(),
            pin: frame.pin_ref(),
            seq: frame.seq(),
            status: frame.status(),
            payload,
        })
    }

    /// Checks and strips the PEC byte (covering `mb << 1`), then parses.
    ///
    /// # Errors
    /// [`Error::PecMismatch`] or as [`Event::parse`].
    pub fn parse_with_pec(mb: Address, bytes: &'a [u8]) -> Result<Event<'a>> {
        Self::parse(pec::strip(mb.addr_byte(false), bytes)?)
    }

    /// True for the kinds that are always sent with their check, whatever the board's PEC
    /// setting (`boot`, `announce`): they are sent before the MB could switch PEC on.
    pub fn always_checked(&self) -> bool {
        matches!(self.kind, EventKind::Boot | EventKind::Announce)
    }

    /// Encoded length, PEC excluded.
    pub fn buffer_len(&self) -> usize {
        EVENT_HEADER_LEN + self.payload.len()
    }

    /// Writes the event at the start of `buf`; returns its length.
    ///
    /// # Errors
    /// [`Error::TooLong`] for a payload over [`MAX_PAYLOAD`], [`Error::BufferTooShort`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        if self.payload.len() > MAX_PAYLOAD {
            return Err(Error::TooLong);
        }
        let len = self.buffer_len();
        let out = buf.get_mut(..len).ok_or(Error::BufferTooShort)?;
        let mut frame = EventFrame::new_unchecked(out);
        frame.set_source(self.source.get());
        frame.set_kind(self.kind);
        frame.set_pin_ref(self.pin);
        frame.set_seq(self.seq);
        frame.set_status(self.status);
        frame.set_payload_len(self.payload.len() as u8);
        frame.payload_mut().copy_from_slice(self.payload);
        Ok(len)
    }

    /// Writes the event and its PEC byte (covering `mb << 1`); returns the total length.
    ///
    /// # Errors
    /// As [`Event::emit`].
    pub fn emit_with_pec(&self, mb: Address, buf: &mut [u8]) -> Result<usize> {
        let len = self.emit(buf)?;
        pec::append(mb.addr_byte(false), buf, len)
    }
}
