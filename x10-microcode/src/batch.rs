//! Batches: several operations in one request (function 5), one result each in the reply.
//!
//! Request data is a sequence of items `fn_op, port, len, data[len]` (the bytes an ordinary
//! request has at offsets 0, 2 and 4.., plus a length). The reply payload has one result per
//! item, in order: `status, len, value[len]`. Batches cannot nest and cannot hold deferred
//! operations (pulse-in): every item's result is in the one reply.

use crate::{Error, Function, Op, Result, Status, MAX_PAYLOAD, MAX_REQUEST_DATA};

/// Item header: `fn_op`, `port`, `len`.
const ITEM_HEADER: usize = 3;
/// Result header: `status`, `len`.
const RESULT_HEADER: usize = 2;

/// A checked sequence of batch items (the data bytes of a batch request).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Batch<'a> {
    bytes: &'a [u8],
}

/// One raw item: `fn_op`, `port`, data.
type RawItem<'a> = (u8, u8, &'a [u8]);

/// Splits one `head(3) + data(len)` record off `bytes`.
fn split_record(bytes: &[u8]) -> Result<(RawItem<'_>, &[u8])> {
    let (head, rest) = bytes
        .split_at_checked(ITEM_HEADER)
        .ok_or(Error::Truncated)?;
    let [a, b, len] = *head else {
        return Err(Error::Truncated);
    };
    let (data, rest) = rest
        .split_at_checked(len as usize)
        .ok_or(Error::Truncated)?;
    Ok(((a, b, data), rest))
}

impl<'a> Batch<'a> {
    /// Checks the items of a batch.
    ///
    /// # Errors
    /// [`Error::BadLength`] for an empty batch, [`Error::Truncated`] for a cut item,
    /// [`Error::NestedBatch`], [`Error::BadArgument`] for a deferred item, [`Error::TooLong`]
    /// when the results would not fit one reply, or the item's own parse error.
    pub fn new_checked(bytes: &'a [u8]) -> Result<Batch<'a>> {
        Self::checked(bytes, false)
    }

    /// As [`Batch::new_checked`]; with `stage`, every item must be an output a `stage` may
    /// hold ([`Op::is_stageable`], [`Error::BadArgument`] otherwise), checked in the same pass.
    pub(crate) fn checked(bytes: &'a [u8], stage: bool) -> Result<Batch<'a>> {
        if bytes.is_empty() {
            return Err(Error::BadLength);
        }
        let mut rest = bytes;
        let mut reply = 0usize;
        while !rest.is_empty() {
            let ((fn_op, port, data), tail) = split_record(rest)?;
            // Checked on the function code before parsing the item, so that a nested batch is
            // reported as such whatever its own contents (an empty one would otherwise be
            // `BadLength`).
            if Function::from_code(fn_op >> 4) == Function::Batch {
                return Err(Error::NestedBatch);
            }
            let op = Op::parse(fn_op, port, data)?;
            if op.is_deferred()
                || op.moves_board()
                || op.is_together()
                || (stage && !op.is_stageable())
            {
                return Err(Error::BadArgument);
            }
            reply += RESULT_HEADER + op.reply_capacity();
            rest = tail;
        }
        if reply > MAX_PAYLOAD {
            return Err(Error::TooLong);
        }
        Ok(Batch { bytes })
    }

    /// The encoded items.
    pub const fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The items, in order.
    pub fn iter(&self) -> BatchItems<'a> {
        BatchItems { rest: self.bytes }
    }

    /// Number of items.
    pub fn len(&self) -> usize {
        self.iter().count()
    }

    /// Never true for a checked batch; here for completeness.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Largest reply payload for this batch.
    pub fn reply_capacity(&self) -> usize {
        self.iter()
            .map(|op| RESULT_HEADER + op.reply_capacity())
            .sum()
    }
}

impl<'a> BatchItems<'a> {
    /// The items of `bytes` that were checked as a [`Batch`] before (a board's held
    /// `stage`), parsed again one by one without checking the whole first: a malformed item
    /// ends the iteration.
    pub const fn of_checked(bytes: &'a [u8]) -> BatchItems<'a> {
        BatchItems { rest: bytes }
    }
}

/// Iterator over the operations of a [`Batch`].
#[derive(Clone, Debug)]
pub struct BatchItems<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for BatchItems<'a> {
    type Item = Op<'a>;

    fn next(&mut self) -> Option<Op<'a>> {
        let ((fn_op, port, data), tail) = split_record(self.rest).ok()?;
        self.rest = tail;
        // Items were checked by `Batch::new_checked`; an error cannot occur here, and if it did
        // the iteration would simply end.
        Op::parse(fn_op, port, data).ok()
    }
}

/// Encodes batch items into a caller's buffer.
#[derive(Debug)]
pub struct BatchWriter<'b> {
    buf: &'b mut [u8],
    len: usize,
}

impl<'b> BatchWriter<'b> {
    /// A writer over `buf` (at most [`MAX_REQUEST_DATA`] bytes of it are used).
    pub fn new(buf: &'b mut [u8]) -> BatchWriter<'b> {
        BatchWriter { buf, len: 0 }
    }

    /// Appends one operation.
    ///
    /// # Errors
    /// [`Error::NestedBatch`], [`Error::BadArgument`] for a deferred operation,
    /// [`Error::TooLong`] when the batch would exceed [`MAX_REQUEST_DATA`] bytes, or
    /// [`Error::BufferTooShort`].
    pub fn push(&mut self, op: &Op<'_>) -> Result<()> {
        if matches!(op, Op::Batch(_)) {
            return Err(Error::NestedBatch);
        }
        if op.is_deferred() || op.moves_board() || op.is_together() {
            return Err(Error::BadArgument);
        }
        op.validate()?;
        let data_len = op.data_len();
        let end = self.len + ITEM_HEADER + data_len;
        if end > MAX_REQUEST_DATA {
            return Err(Error::TooLong);
        }
        let item = self
            .buf
            .get_mut(self.len..end)
            .ok_or(Error::BufferTooShort)?;
        let (head, data) = item.split_at_mut(ITEM_HEADER);
        head.copy_from_slice(&[op.fn_op_byte(), op.port_byte(), data_len as u8]);
        op.emit_data(data)?;
        self.len = end;
        Ok(())
    }

    /// The finished batch.
    ///
    /// # Errors
    /// What [`Batch::new_checked`] reports (an empty batch, results too long for one reply).
    pub fn finish(self) -> Result<Batch<'b>> {
        let bytes: &'b [u8] = self.buf;
        Batch::new_checked(bytes.get(..self.len).ok_or(Error::BufferTooShort)?)
    }
}

/// The result of one batch item in a batch reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BatchItem<'a> {
    /// Status of the item.
    pub status: Status,
    /// Value bytes of the item (empty for outputs).
    pub value: &'a [u8],
}

/// Iterator over the results in the payload of a batch reply.
#[derive(Clone, Debug)]
pub struct BatchResults<'a> {
    rest: &'a [u8],
}

impl<'a> BatchResults<'a> {
    /// Results in `payload`; an incomplete trailing result ends the iteration with an `Err`.
    pub const fn new(payload: &'a [u8]) -> BatchResults<'a> {
        BatchResults { rest: payload }
    }

    /// Writes one result (`status, len, value`) at the start of `buf`; returns its length.
    ///
    /// # Errors
    /// [`Error::TooLong`] for a value over 255 bytes, [`Error::BufferTooShort`].
    pub fn emit(buf: &mut [u8], status: Status, value: &[u8]) -> Result<usize> {
        let len = u8::try_from(value.len()).map_err(|_| Error::TooLong)?;
        let total = RESULT_HEADER + value.len();
        let out = buf.get_mut(..total).ok_or(Error::BufferTooShort)?;
        let (head, v) = out.split_at_mut(RESULT_HEADER);
        head.copy_from_slice(&[status.to_byte(), len]);
        v.copy_from_slice(value);
        Ok(total)
    }
}

impl<'a> Iterator for BatchResults<'a> {
    type Item = Result<BatchItem<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        let parsed = match *self.rest {
            [status, len, ref tail @ ..] => tail
                .split_at_checked(len as usize)
                .map(|(value, rest)| (Status::from_byte(status), value, rest)),
            _ => None,
        };
        match parsed {
            Some((status, value, rest)) => {
                self.rest = rest;
                Some(Ok(BatchItem { status, value }))
            }
            None => {
                self.rest = &[];
                Some(Err(Error::Truncated))
            }
        }
    }
}
