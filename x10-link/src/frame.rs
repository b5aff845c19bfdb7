//! Framing: a message is postcard-encoded, followed by its CRC-16 (CRC-16/IBM-3740, the
//! microcode's CRC, little-endian), COBS-encoded, and ended by one `0x00` byte. A frame
//! therefore holds no zero byte but its last; a reader that starts in the middle of a stream
//! (a laptop opening the port late) skips to the next zero and is in step again.
//!
//! ```
//! use x10_link::{encode, ToDevice, FrameReader, Feed};
//! let mut buf = [0u8; 64];
//! let n = encode(&ToDevice::ListBoards { id: 9 }, &mut buf).unwrap();
//! assert_eq!(&buf[..n], &[0x05, 0x04, 0x09, 0xe2, 0x40, 0x00]);
//! let mut r: FrameReader<64> = FrameReader::new();
//! let mut got = None;
//! for &b in &buf[..n] {
//!     if let Feed::Frame = r.feed(b) {
//!         got = Some(format!("{:?}", r.decode::<ToDevice>().unwrap()));
//!     }
//! }
//! assert_eq!(got.as_deref(), Some("ListBoards { id: 9 }"));
//! ```

use crc::{Crc, NoTable, CRC_16_IBM_3740};
use serde::{Deserialize, Serialize};

use crate::msg::{ToDevice, ToHost};

/// The frame check.
const CRC16: Crc<u16, NoTable> = Crc::<u16, NoTable>::new(&CRC_16_IBM_3740);

/// The largest message (postcard bytes, before the CRC) either side sends: a call record with
/// a full payload and data is under 100 bytes; a log chunk is at most [`MAX_LOG_CHUNK`].
pub const MAX_MESSAGE: usize = 200;

/// The longest frame on the wire: a [`MAX_MESSAGE`] message, its CRC, the COBS overhead and
/// the final zero.
pub const MAX_FRAME: usize = cobs::max_encoding_length(MAX_MESSAGE + 2) + 1;

/// The most log bytes one `Log` message carries.
pub const MAX_LOG_CHUNK: usize = 128;

/// Why a frame could not be written or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// The message or frame does not fit the buffer given (writing), or the frame was longer
    /// than the reader's buffer (reading; the reader skipped to the next zero).
    TooLong,
    /// Not valid COBS, or empty.
    Cobs,
    /// Shorter than its CRC, or the CRC does not match.
    Crc,
    /// postcard could not encode (writing) or decode (reading) the message: an unknown
    /// variant (a newer peer), a truncated field, bytes left over, bad UTF-8.
    Message,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FrameError::TooLong => "frame too long",
            FrameError::Cobs => "bad COBS",
            FrameError::Crc => "CRC mismatch",
            FrameError::Message => "message does not decode",
        })
    }
}

/// Writes `msg` as one frame (ending in its zero) into `out`; returns the frame's length.
///
/// # Errors
/// [`FrameError::TooLong`] when the message is over [`MAX_MESSAGE`] bytes or `out` is short;
/// [`FrameError::Message`] when postcard refuses it.
pub fn encode<T: Serialize>(msg: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_MESSAGE + 2];
    let n = match postcard::to_slice(msg, &mut raw[..MAX_MESSAGE]) {
        Ok(s) => s.len(),
        Err(postcard::Error::SerializeBufferFull) => return Err(FrameError::TooLong),
        Err(_) => return Err(FrameError::Message),
    };
    seal(&mut raw, n, out)
}

/// [`encode`] of a [`ToHost`] without serde: the same bytes (`crate::wire`), the
/// motherboard's encoder.
///
/// # Errors
/// [`FrameError::TooLong`] when the message is over [`MAX_MESSAGE`] bytes or `out` is short.
pub fn encode_host(msg: &ToHost<'_>, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_MESSAGE + 2];
    let n = crate::wire::write_to_host(msg, raw.get_mut(..MAX_MESSAGE).unwrap_or(&mut []))
        .ok_or(FrameError::TooLong)?;
    seal(&mut raw, n, out)
}

/// Appends the CRC of `raw[..n]`, COBS-encodes the lot into `out` and ends it with a zero.
fn seal(raw: &mut [u8; MAX_MESSAGE + 2], n: usize, out: &mut [u8]) -> Result<usize, FrameError> {
    let crc = CRC16.checksum(raw.get(..n).ok_or(FrameError::TooLong)?);
    raw.get_mut(n..n + 2)
        .ok_or(FrameError::TooLong)?
        .copy_from_slice(&crc.to_le_bytes());
    let body = raw.get(..n + 2).ok_or(FrameError::TooLong)?;
    let len = cobs::try_encode(body, out).map_err(|_| FrameError::TooLong)?;
    *out.get_mut(len).ok_or(FrameError::TooLong)? = 0;
    Ok(len + 1)
}

/// Decodes one frame's bytes (with or without its final zero) in place: COBS, then the CRC.
/// Returns the message bytes (postcard), a prefix of `frame`.
///
/// # Errors
/// [`FrameError::Cobs`], [`FrameError::Crc`].
pub fn unframe(frame: &mut [u8]) -> Result<&[u8], FrameError> {
    let end = frame.iter().position(|&b| b == 0).unwrap_or(frame.len());
    let body = frame.get_mut(..end).ok_or(FrameError::Cobs)?;
    if body.is_empty() {
        return Err(FrameError::Cobs);
    }
    let n = cobs::decode_in_place(body).map_err(|_| FrameError::Cobs)?;
    let msg_len = n.checked_sub(2).ok_or(FrameError::Crc)?;
    let msg = body.get(..msg_len).ok_or(FrameError::Crc)?;
    let crc = body.get(msg_len..n).ok_or(FrameError::Crc)?;
    if crc != CRC16.checksum(msg).to_le_bytes() {
        return Err(FrameError::Crc);
    }
    Ok(msg)
}

/// Decodes one frame's bytes in place into a message borrowing from them.
///
/// # Errors
/// As [`unframe`], and [`FrameError::Message`] when postcard cannot read the message (or
/// bytes are left after it).
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<T, FrameError> {
    let msg = unframe(frame)?;
    match postcard::take_from_bytes::<T>(msg) {
        Ok((m, [])) => Ok(m),
        _ => Err(FrameError::Message),
    }
}

/// What [`FrameReader::feed`] saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feed {
    /// Inside a frame (or between frames).
    Pending,
    /// A frame ended; [`FrameReader::decode`] reads it (until the next `feed`).
    Frame,
    /// A frame ended that is too long for the buffer (its bytes were skipped).
    TooLong,
}

/// Collects a byte stream into frames, `N` bytes at most each (longer ones are skipped to
/// the next zero and reported). Never panics, whatever the bytes.
#[derive(Debug)]
pub struct FrameReader<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
    done: usize,
}

impl<const N: usize> Default for FrameReader<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameReader<N> {
    /// An empty reader.
    pub const fn new() -> Self {
        FrameReader {
            buf: [0; N],
            len: 0,
            overflow: false,
            done: 0,
        }
    }

    /// Forgets a partial frame (the port was closed).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
        self.done = 0;
    }

    /// Takes one byte of the stream.
    pub fn feed(&mut self, byte: u8) -> Feed {
        if self.done > 0 {
            self.done = 0;
        }
        if byte == 0 {
            let n = self.len;
            self.len = 0;
            if core::mem::take(&mut self.overflow) {
                return Feed::TooLong;
            }
            if n == 0 {
                // Two zeros in a row (a keep-alive or a resync): no frame.
                return Feed::Pending;
            }
            self.done = n;
            return Feed::Frame;
        }
        match self.buf.get_mut(self.len) {
            Some(slot) if !self.overflow => {
                *slot = byte;
                self.len += 1;
            }
            _ => self.overflow = true,
        }
        Feed::Pending
    }

    /// The frame that just ended (after [`Feed::Frame`]), decoded as a `T`. A second call
    /// for the same frame gives [`FrameError::Cobs`] (the first decoded it in place).
    ///
    /// # Errors
    /// As [`decode`].
    pub fn decode<'a, T: Deserialize<'a>>(&'a mut self) -> Result<T, FrameError> {
        let n = core::mem::take(&mut self.done);
        let frame = self.buf.get_mut(..n).ok_or(FrameError::Cobs)?;
        decode(frame)
    }

    /// [`FrameReader::decode`] of a [`ToDevice`] without serde (`crate::wire`), the
    /// motherboard's decoder: the same messages and the same refusals.
    ///
    /// # Errors
    /// As [`decode`].
    pub fn decode_device(&mut self) -> Result<ToDevice<'_>, FrameError> {
        let n = core::mem::take(&mut self.done);
        let frame = self.buf.get_mut(..n).ok_or(FrameError::Cobs)?;
        let msg = unframe(frame)?;
        crate::wire::read_to_device(msg).ok_or(FrameError::Message)
    }
}
