//! Requests (MB → DB): thesis Table 3.2.
//!
//! | byte | bits | field |
//! |---|---|---|
//! | 0 | 7..4 | function |
//! | 0 | 3..0 | operand |
//! | 1 | 7..0 | DB address (0 = internal) |
//! | 2 | 7 | port kind (1 = sensor) |
//! | 2 | 6..1 | port index (0-based) |
//! | 2 | 0 | pin (A = 0, B = 1) |
//! | 3 | 7..0 | sequence number |
//! | 4.. | | data |

use crate::op::Function;
use crate::types::{Address, PinRef};
use crate::{pec, Error, Op, Result, MAX_REQUEST_LEN, REQUEST_HEADER_LEN};

mod field {
    pub const FN_OP: usize = 0;
    pub const DB: usize = 1;
    pub const PORT: usize = 2;
    pub const SEQ: usize = 3;
    pub const DATA: usize = 4;
}

/// A zero-copy view of a request frame (PEC byte excluded).
#[derive(Debug, Clone)]
pub struct RequestFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> RequestFrame<T> {
    /// Wraps a buffer without checking it; getters may then return 0 for missing bytes.
    pub const fn new_unchecked(buffer: T) -> RequestFrame<T> {
        RequestFrame { buffer }
    }

    /// Wraps a buffer and checks its length.
    ///
    /// # Errors
    /// See [`RequestFrame::check_len`].
    pub fn new_checked(buffer: T) -> Result<RequestFrame<T>> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }

    /// Checks that the buffer holds a header and no more than [`MAX_REQUEST_LEN`] bytes.
    ///
    /// # Errors
    /// [`Error::Truncated`] below 4 bytes, [`Error::TooLong`] above [`MAX_REQUEST_LEN`].
    pub fn check_len(&self) -> Result<()> {
        let len = self.buffer.as_ref().len();
        if len < REQUEST_HEADER_LEN {
            Err(Error::Truncated)
        } else if len > MAX_REQUEST_LEN {
            Err(Error::TooLong)
        } else {
            Ok(())
        }
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }

    /// Byte 0.
    pub fn fn_op(&self) -> u8 {
        self.byte(field::FN_OP)
    }

    /// Function (high nibble of byte 0).
    pub fn function(&self) -> Function {
        Function::from_code(self.fn_op() >> 4)
    }

    /// Operand (low nibble of byte 0).
    pub fn operand(&self) -> u8 {
        self.fn_op() & 0x0f
    }

    /// Byte 1, the raw DB address.
    pub fn db(&self) -> u8 {
        self.byte(field::DB)
    }

    /// Byte 2, raw.
    pub fn port_byte(&self) -> u8 {
        self.byte(field::PORT)
    }

    /// Byte 2, decoded.
    pub fn pin_ref(&self) -> PinRef {
        PinRef::from_byte(self.port_byte())
    }

    /// Byte 3, the sequence number.
    pub fn seq(&self) -> u8 {
        self.byte(field::SEQ)
    }

    /// Bytes 4.., the data.
    pub fn data(&self) -> &[u8] {
        self.buffer.as_ref().get(field::DATA..).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> RequestFrame<T> {
    fn set_byte(&mut self, i: usize, v: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(i) {
            *b = v;
        }
    }

    /// Sets byte 0.
    pub fn set_fn_op(&mut self, v: u8) {
        self.set_byte(field::FN_OP, v)
    }

    /// Sets the function nibble.
    pub fn set_function(&mut self, f: Function) {
        let v = (f.code() << 4) | self.operand();
        self.set_fn_op(v)
    }

    /// Sets the operand nibble.
    pub fn set_operand(&mut self, op: u8) {
        let v = (self.fn_op() & 0xf0) | (op & 0x0f);
        self.set_fn_op(v)
    }

    /// Sets byte 1.
    pub fn set_db(&mut self, v: u8) {
        self.set_byte(field::DB, v)
    }

    /// Sets byte 2.
    pub fn set_port_byte(&mut self, v: u8) {
        self.set_byte(field::PORT, v)
    }

    /// Sets byte 3.
    pub fn set_seq(&mut self, v: u8) {
        self.set_byte(field::SEQ, v)
    }

    /// The data bytes, writable.
    pub fn data_mut(&mut self) -> &mut [u8] {
        self.buffer
            .as_mut()
            .get_mut(field::DATA..)
            .unwrap_or(&mut [])
    }
}

/// A request: the DB it goes to, its sequence number and its operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Request<'a> {
    /// Destination daughterboard (byte 1).
    pub db: Address,
    /// Sequence number (byte 3), echoed by the reply.
    pub seq: u8,
    /// The operation (bytes 0, 2 and the data).
    pub op: Op<'a>,
}

impl<'a> Request<'a> {
    /// Parses a request from a checked view.
    ///
    /// # Errors
    /// [`Error::BadAddress`] for byte 1, or the operation's parse error ([`Op::parse`]).
    pub fn parse_frame<T: AsRef<[u8]> + ?Sized>(
        frame: &RequestFrame<&'a T>,
    ) -> Result<Request<'a>> {
        frame.check_len()?;
        let bytes: &'a [u8] = frame.buffer.as_ref();
        let data = bytes.get(field::DATA..).unwrap_or(&[]);
        let db = Address::new(frame.db())?;
        let op = Op::parse(frame.fn_op(), frame.port_byte(), data)?;
        Ok(Request {
            db,
            seq: frame.seq(),
            op,
        })
    }

    /// Parses a request from the bytes of one transfer (PEC byte excluded).
    ///
    /// # Errors
    /// As [`RequestFrame::check_len`] and [`Request::parse_frame`].
    pub fn parse(bytes: &'a [u8]) -> Result<Request<'a>> {
        Self::parse_frame(&RequestFrame::new_checked(bytes)?)
    }

    /// Checks and strips the PEC byte (covering `db << 1`), then parses.
    ///
    /// # Errors
    /// [`Error::PecMismatch`] or as [`Request::parse`].
    pub fn parse_with_pec(db: Address, bytes: &'a [u8]) -> Result<Request<'a>> {
        Self::parse(pec::strip(db.addr_byte(false), bytes)?)
    }

    /// Encoded length, PEC excluded.
    pub fn buffer_len(&self) -> usize {
        REQUEST_HEADER_LEN + self.op.data_len()
    }

    /// Writes the request into a view over at least [`Request::buffer_len`] bytes.
    ///
    /// # Errors
    /// [`Error::TooLong`] when the data exceeds [`crate::MAX_REQUEST_DATA`] (no board would
    /// accept the frame), [`Error::BufferTooShort`].
    pub fn emit_frame<T: AsRef<[u8]> + AsMut<[u8]>>(
        &self,
        frame: &mut RequestFrame<T>,
    ) -> Result<()> {
        if self.buffer_len() > MAX_REQUEST_LEN {
            return Err(Error::TooLong);
        }
        if frame.buffer.as_ref().len() < self.buffer_len() {
            return Err(Error::BufferTooShort);
        }
        frame.set_fn_op(self.op.fn_op_byte());
        frame.set_db(self.db.get());
        frame.set_port_byte(self.op.port_byte());
        frame.set_seq(self.seq);
        self.op.emit_data(frame.data_mut())?;
        Ok(())
    }

    /// Writes the request at the start of `buf` and returns its length.
    ///
    /// # Errors
    /// As [`Request::emit_frame`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let len = self.buffer_len();
        if len > MAX_REQUEST_LEN {
            return Err(Error::TooLong);
        }
        let out = buf.get_mut(..len).ok_or(Error::BufferTooShort)?;
        self.emit_frame(&mut RequestFrame::new_unchecked(out))?;
        Ok(len)
    }

    /// Writes the request and its PEC byte; returns the total length.
    ///
    /// # Errors
    /// As [`Request::emit_frame`].
    pub fn emit_with_pec(&self, buf: &mut [u8]) -> Result<usize> {
        let len = self.emit(buf)?;
        pec::append(self.db.addr_byte(false), buf, len)
    }
}
