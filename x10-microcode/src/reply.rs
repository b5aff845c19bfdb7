//! Replies (DB → MB, the read half of a write-then-read): `seq, status, len, payload[len]`.

use crate::types::Address;
use crate::{pec, Error, Result, Status, MAX_PAYLOAD, REPLY_HEADER_LEN};

mod field {
    pub const SEQ: usize = 0;
    pub const STATUS: usize = 1;
    pub const LEN: usize = 2;
    pub const PAYLOAD: usize = 3;
}

/// An owned copy of a reply payload, as the MB hands it to a caller.
pub type Payload = heapless::Vec<u8, MAX_PAYLOAD>;

/// A zero-copy view of a reply frame (PEC byte excluded). The buffer may be longer than the
/// frame (a fixed-size read); [`ReplyFrame::frame_len`] says where the frame ends.
#[derive(Debug, Clone)]
pub struct ReplyFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> ReplyFrame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> ReplyFrame<T> {
        ReplyFrame { buffer }
    }

    /// Wraps a buffer and checks its length.
    ///
    /// # Errors
    /// See [`ReplyFrame::check_len`].
    pub fn new_checked(buffer: T) -> Result<ReplyFrame<T>> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// Checks that the header and the declared payload are in the buffer.
    ///
    /// # Errors
    /// [`Error::Truncated`] when they are not, [`Error::TooLong`] when the declared payload
    /// exceeds [`MAX_PAYLOAD`].
    pub fn check_len(&self) -> Result<()> {
        layout::check_len(self.buffer.as_ref())
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }

    /// Byte 0, the sequence number of the request answered.
    pub fn seq(&self) -> u8 {
        self.byte(field::SEQ)
    }

    /// Byte 1, the status.
    pub fn status(&self) -> Status {
        Status::from_byte(self.byte(field::STATUS))
    }

    /// Byte 2, the payload length.
    pub fn payload_len(&self) -> u8 {
        self.byte(field::LEN)
    }

    /// Length of the frame: header plus payload.
    pub fn frame_len(&self) -> usize {
        layout::frame_len(self.buffer.as_ref())
    }

    /// The payload.
    pub fn payload(&self) -> &[u8] {
        layout::payload(self.buffer.as_ref())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> ReplyFrame<T> {
    fn set_byte(&mut self, i: usize, v: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(i) {
            *b = v;
        }
    }

    /// Sets byte 0.
    pub fn set_seq(&mut self, v: u8) {
        self.set_byte(field::SEQ, v)
    }

    /// Sets byte 1.
    pub fn set_status(&mut self, s: Status) {
        self.set_byte(field::STATUS, s.to_byte())
    }

    /// Sets byte 2.
    pub fn set_payload_len(&mut self, v: u8) {
        self.set_byte(field::LEN, v)
    }

    /// The payload, writable (as long as byte 2 declares).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        layout::payload_mut(self.buffer.as_mut())
    }
}

/// The reply layout (`seq, status, len, payload[len]`) on a slice: what [`ReplyFrame`]
/// reads and writes, and the part of an event frame from its byte 3 on, laid out the same
/// ([`crate::EventFrame`]).
pub(crate) mod layout {
    use super::field;
    use crate::{Error, Result, MAX_PAYLOAD, REPLY_HEADER_LEN};

    /// The declared payload length (0 when `b` is too short to declare one).
    fn payload_len(b: &[u8]) -> usize {
        usize::from(b.get(field::LEN).copied().unwrap_or(0))
    }

    /// Checks that the header and the declared payload are in `b`.
    pub(crate) fn check_len(b: &[u8]) -> Result<()> {
        let len = usize::from(*b.get(field::LEN).ok_or(Error::Truncated)?);
        if len > MAX_PAYLOAD {
            return Err(Error::TooLong);
        }
        if b.len() < REPLY_HEADER_LEN + len {
            return Err(Error::Truncated);
        }
        Ok(())
    }

    /// Header plus declared payload.
    pub(crate) fn frame_len(b: &[u8]) -> usize {
        REPLY_HEADER_LEN + payload_len(b)
    }

    /// The declared payload, as far as `b` holds it.
    pub(crate) fn payload(b: &[u8]) -> &[u8] {
        b.get(field::PAYLOAD..frame_len(b)).unwrap_or(&[])
    }

    /// The declared payload, writable.
    pub(crate) fn payload_mut(b: &mut [u8]) -> &mut [u8] {
        let end = frame_len(b);
        b.get_mut(field::PAYLOAD..end).unwrap_or(&mut [])
    }
}

/// A reply: the sequence number it answers, a status, and the value bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Reply<'a> {
    /// Sequence number of the request answered.
    pub seq: u8,
    /// Outcome.
    pub status: Status,
    /// Value bytes; their meaning depends on the request (see `docs/protocol.md`).
    pub payload: &'a [u8],
}

impl<'a> Reply<'a> {
    /// Parses a reply from a checked view; bytes after the frame are ignored.
    ///
    /// # Errors
    /// As [`ReplyFrame::check_len`].
    pub fn parse_frame<T: AsRef<[u8]> + ?Sized>(frame: &ReplyFrame<&'a T>) -> Result<Reply<'a>> {
        frame.check_len()?;
        let bytes: &'a [u8] = frame.buffer.as_ref();
        let payload = bytes
            .get(field::PAYLOAD..frame.frame_len())
            .ok_or(Error::Truncated)?;
        Ok(Reply {
            seq: frame.seq(),
            status: frame.status(),
            payload,
        })
    }

    /// Parses exactly one reply frame.
    ///
    /// # Errors
    /// [`Error::Truncated`], [`Error::TooLong`], or [`Error::BadLength`] for bytes after the
    /// declared payload.
    pub fn parse(bytes: &'a [u8]) -> Result<Reply<'a>> {
        let frame = ReplyFrame::new_checked(bytes)?;
        if frame.frame_len() != bytes.len() {
            return Err(Error::BadLength);
        }
        Self::parse_frame(&frame)
    }

    /// Parses the reply at the start of a fixed-size read from `db`: with `pec`, the frame's
    /// check follows it (covering `db << 1 | 1`: one PEC byte, or a CRC-16 after a frame of
    /// more than 13 bytes, [`pec::check_len`]). Bytes after that are padding.
    ///
    /// # Errors
    /// As [`ReplyFrame::check_len`], [`Error::Truncated`] for a missing PEC byte,
    /// [`Error::PecMismatch`].
    pub fn parse_read(db: Address, pec_on: bool, read: &'a [u8]) -> Result<Reply<'a>> {
        let frame = ReplyFrame::new_checked(read)?;
        let len = frame.frame_len();
        let bytes = if pec_on {
            let with = read
                .get(..len + pec::check_len(len))
                .ok_or(Error::Truncated)?;
            pec::strip(db.addr_byte(true), with)?
        } else {
            read.get(..len).ok_or(Error::Truncated)?
        };
        Self::parse(bytes)
    }

    /// Parses the reply to `op` at the start of a fixed-size read from `db` (with `pec`, PEC
    /// byte after the frame, covering `db << 1 | 1`), and checks it against the operation
    /// ([`crate::Op::check_reply`]): an `ok` reply must have a length the operation allows,
    /// any other status an empty payload.
    ///
    /// Where the check is never depends on a byte the check has not covered: for an
    /// operation whose `ok` payload has one length *n* ([`crate::ReplyLen::Exact`]) the check
    /// is looked for after *n* payload bytes (an `ok` reply) and, if it does not match there,
    /// right after the header (a status-only reply); the received LEN byte must then agree.
    /// For the others (scan, serial read, batch) the LEN byte is checked against the lengths
    /// the operation allows and the reply always ends in a CRC-16 (the daughterboard appends
    /// it with [`pec::append16`] when the operation's [`crate::ReplyLen`] is not exact): a
    /// LEN byte misread as another allowed length moves the CRC-16 to bytes that match it by
    /// chance once in 65 536. A status-only reply with a PEC byte (from a board that could not
    /// parse the request) is accepted only with a status other than `ok`.
    ///
    /// # Errors
    /// [`Error::BadLength`] for a length the operation does not allow, [`Error::Truncated`],
    /// [`Error::TooLong`], [`Error::PecMismatch`].
    pub fn parse_read_for(
        db: Address,
        pec_on: bool,
        read: &'a [u8],
        op: &crate::Op<'_>,
    ) -> Result<Reply<'a>> {
        let ok_len = op.reply_len();
        let reply = match ok_len {
            crate::ReplyLen::Exact(n) if pec_on => {
                let at = |payload: usize| -> Result<Reply<'a>> {
                    let len = REPLY_HEADER_LEN + payload;
                    let with = read
                        .get(..len + pec::check_len(len))
                        .ok_or(Error::Truncated)?;
                    Self::parse(pec::strip(db.addr_byte(true), with)?)
                };
                match at(usize::from(n)) {
                    Ok(r) => r,
                    Err(e) if n > 0 => at(0).map_err(|_| e)?,
                    Err(e) => return Err(e),
                }
            }
            crate::ReplyLen::Exact(_) => Self::parse_read(db, pec_on, read)?,
            _ => {
                let len = *read.get(field::LEN).ok_or(Error::Truncated)?;
                if len != 0 && !ok_len.allows(len) {
                    return Err(Error::BadLength);
                }
                if pec_on {
                    // Always a CRC-16 (`pec::append16`): a misread LEN moves where it is
                    // looked for, and a CRC-16 matches there by chance once in 65 536.
                    let frame = REPLY_HEADER_LEN + usize::from(len);
                    let with = read.get(..frame + 2).ok_or(Error::Truncated)?;
                    match pec::strip16(db.addr_byte(true), with) {
                        Ok(bytes) => Self::parse(bytes)?,
                        // A board that could not tell the operation (a frame too broken to
                        // parse) answers a status alone, with a PEC byte: never `ok`.
                        Err(e) if len == 0 => {
                            let r = Self::parse_read(db, true, read).map_err(|_| e)?;
                            if r.status == Status::Ok {
                                return Err(e);
                            }
                            r
                        }
                        Err(e) => return Err(e),
                    }
                } else {
                    Self::parse_read(db, false, read)?
                }
            }
        };
        op.check_reply(reply.status, reply.payload)?;
        Ok(reply)
    }

    /// A reply with no payload.
    pub const fn status_only(seq: u8, status: Status) -> Reply<'static> {
        Reply {
            seq,
            status,
            payload: &[],
        }
    }

    /// Encoded length, PEC excluded.
    pub fn buffer_len(&self) -> usize {
        REPLY_HEADER_LEN + self.payload.len()
    }

    /// Writes the reply at the start of `buf`; returns its length.
    ///
    /// # Errors
    /// [`Error::TooLong`] for a payload over [`MAX_PAYLOAD`], [`Error::BufferTooShort`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        if self.payload.len() > MAX_PAYLOAD {
            return Err(Error::TooLong);
        }
        let len = self.buffer_len();
        let out = buf.get_mut(..len).ok_or(Error::BufferTooShort)?;
        let mut frame = ReplyFrame::new_unchecked(out);
        frame.set_seq(self.seq);
        frame.set_status(self.status);
        frame.set_payload_len(self.payload.len() as u8);
        // A level (1 byte) or an analog value (2 bytes), the usual payloads, by hand: LLVM
        // turns any copy loop into a `memcpy` call, which costs about 30 instructions on the
        // Cortex-M0 for those (issue 27).
        match (frame.payload_mut(), self.payload) {
            ([d], [b]) => *d = *b,
            ([d0, d1], [b0, b1]) => {
                *d0 = *b0;
                *d1 = *b1;
            }
            (dst, src) => dst.copy_from_slice(src),
        }
        Ok(len)
    }

    /// Writes the reply and its PEC byte (covering `db << 1 | 1`); returns the total length.
    ///
    /// # Errors
    /// As [`Reply::emit`].
    pub fn emit_with_pec(&self, db: Address, buf: &mut [u8]) -> Result<usize> {
        let len = self.emit(buf)?;
        pec::append(db.addr_byte(true), buf, len)
    }

    /// The payload as one byte (digital read).
    ///
    /// # Errors
    /// [`Error::BadLength`] unless the payload is 1 byte.
    pub fn value_u8(&self) -> Result<u8> {
        match *self.payload {
            [v] => Ok(v),
            _ => Err(Error::BadLength),
        }
    }

    /// The payload as u16 LE (analog read).
    ///
    /// # Errors
    /// [`Error::BadLength`] unless the payload is 2 bytes.
    pub fn value_u16(&self) -> Result<u16> {
        match *self.payload {
            [a, b] => Ok(u16::from_le_bytes([a, b])),
            _ => Err(Error::BadLength),
        }
    }

    /// The payload as u32 LE (pulse width in µs).
    ///
    /// # Errors
    /// [`Error::BadLength`] unless the payload is 4 bytes.
    pub fn value_u32(&self) -> Result<u32> {
        match *self.payload {
            [a, b, c, d] => Ok(u32::from_le_bytes([a, b, c, d])),
            _ => Err(Error::BadLength),
        }
    }
}
