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
pub const MAX_FRAME: usize = cobs_max(MAX_MESSAGE + 2) + 1;

/// The most bytes COBS makes of `len` bytes: one code byte ahead of the first block, and one
/// more for every full block of 254 non-zero bytes (exact below 254 bytes: every frame here).
pub(crate) const fn cobs_max(len: usize) -> usize {
    len + 1 + len / 254
}

/// COBS-encodes `body` byte by byte through `put`, then the frame's final zero: blocks of at
/// most 254 non-zero bytes, each led by its length plus one; a block ends at a zero of `body`
/// (which the next block's code stands for) or when full (code 0xFF); a block, empty if need
/// be, follows every zero and every full block but a last one. The same bytes as the `cobs`
/// crate's `encode` (the tests below compare them) for any body but the empty one (`[1]`
/// here, nothing there; a body here holds at least its CRC); written straight into the
/// recorder's ring, with no frame buffer between.
pub(crate) fn cobs_each(body: &[u8], put: &mut dyn FnMut(u8)) {
    let mut rest = body;
    loop {
        let head = rest.get(..254).unwrap_or(rest);
        let (n, zero) = match head.iter().position(|&b| b == 0) {
            Some(i) => (i, true),
            None => (head.len(), false),
        };
        // n <= 254: the code fits a byte.
        put(n as u8 + 1);
        for &b in head.get(..n).unwrap_or(&[]) {
            put(b);
        }
        rest = rest.get(n + usize::from(zero)..).unwrap_or(&[]);
        if !zero && (n < 254 || rest.is_empty()) {
            break;
        }
    }
    put(0);
}

/// Decodes COBS in place (`buf` without its final zero); returns the decoded length, or
/// `None` when a block's code points past the end (the `cobs` crate's `decode_in_place`'s
/// refusal; a zero byte cannot occur, the frame ends at the first).
fn cobs_decode(buf: &mut [u8]) -> Option<usize> {
    let end = buf.len();
    let (mut r, mut w) = (0, 0);
    while let Some(&code) = buf.get(r) {
        let n = usize::from(code).checked_sub(1)?;
        r += 1;
        if r + n > end {
            return None;
        }
        for _ in 0..n {
            // w <= r < end: both in range (checked forms, no panic path).
            let b = *buf.get(r)?;
            *buf.get_mut(w)? = b;
            r += 1;
            w += 1;
        }
        if code != 0xFF && r < end {
            *buf.get_mut(w)? = 0;
            w += 1;
        }
    }
    Some(w)
}

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
    let n = host_body(msg, &mut raw)?;
    cobs_into(raw.get(..n).ok_or(FrameError::TooLong)?, out)
}

/// A [`ToHost`]'s postcard bytes (`crate::wire`) followed by their CRC, written into `raw`;
/// returns their length (the frame before COBS).
///
/// # Errors
/// [`FrameError::TooLong`] when the message is over [`MAX_MESSAGE`] bytes.
pub(crate) fn host_body(
    msg: &ToHost<'_>,
    raw: &mut [u8; MAX_MESSAGE + 2],
) -> Result<usize, FrameError> {
    let n = crate::wire::write_to_host(msg, raw.get_mut(..MAX_MESSAGE).unwrap_or(&mut []))
        .ok_or(FrameError::TooLong)?;
    add_crc(raw, n)
}

/// Appends the CRC of `raw[..n]`; returns the length with it.
fn add_crc(raw: &mut [u8; MAX_MESSAGE + 2], n: usize) -> Result<usize, FrameError> {
    let crc = CRC16.checksum(raw.get(..n).ok_or(FrameError::TooLong)?);
    raw.get_mut(n..n + 2)
        .ok_or(FrameError::TooLong)?
        .copy_from_slice(&crc.to_le_bytes());
    Ok(n + 2)
}

/// Appends the CRC of `raw[..n]`, COBS-encodes the lot into `out` and ends it with a zero.
fn seal(raw: &mut [u8; MAX_MESSAGE + 2], n: usize, out: &mut [u8]) -> Result<usize, FrameError> {
    let len = add_crc(raw, n)?;
    cobs_into(raw.get(..len).ok_or(FrameError::TooLong)?, out)
}

/// COBS-encodes `body` into `out` and ends it with a zero; returns the frame's length.
fn cobs_into(body: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
    if cobs_max(body.len()) >= out.len() {
        return Err(FrameError::TooLong);
    }
    let mut len = 0;
    cobs_each(body, &mut |b| {
        if let Some(slot) = out.get_mut(len) {
            *slot = b;
        }
        len += 1;
    });
    Ok(len)
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
    let n = cobs_decode(body).ok_or(FrameError::Cobs)?;
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

#[cfg(test)]
mod tests {
    extern crate std;
    use std::{vec, vec::Vec};

    use super::{cobs_decode, cobs_each, cobs_max};
    use proptest::prelude::*;

    fn ours(body: &[u8]) -> Vec<u8> {
        let mut v = Vec::new();
        cobs_each(body, &mut |b| v.push(b));
        v
    }

    /// The `cobs` crate's frame: its encoding and the final zero.
    fn theirs(body: &[u8]) -> Vec<u8> {
        let mut v = vec![0u8; cobs::max_encoding_length(body.len()) + 2];
        let n = cobs::encode(body, &mut v);
        v.truncate(n);
        v.push(0);
        v
    }

    #[test]
    fn cobs_examples() {
        assert_eq!(ours(&[]), [1, 0]);
        assert_eq!(ours(&[0]), [1, 1, 0]);
        assert_eq!(ours(&[0x11, 0, 0x22, 0x33]), [2, 0x11, 3, 0x22, 0x33, 0]);
        // 254 non-zero bytes: one full block, nothing after it; one more byte: a second block.
        let full = [7u8; 254];
        let mut want = vec![0xFF];
        want.extend_from_slice(&full);
        want.push(0);
        assert_eq!(ours(&full), want);
        assert_eq!(ours(&full), theirs(&full));
        let mut longer = full.to_vec();
        longer.push(9);
        want.pop();
        want.extend_from_slice(&[2, 9, 0]);
        assert_eq!(ours(&longer), want);
        assert_eq!(ours(&longer), theirs(&longer));
        // Every frame length the link writes has the bound exactly.
        for len in 0..254 {
            assert_eq!(ours(&vec![5u8; len]).len(), cobs_max(len) + 1);
        }
    }

    #[test]
    fn a_code_past_the_end_is_refused() {
        assert_eq!(cobs_decode(&mut [3, 1]), None);
        assert_eq!(cobs_decode(&mut [2, 9, 1]), Some(2));
        assert_eq!(cobs_decode(&mut []), Some(0));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]

        #[test]
        fn cobs_writes_what_the_cobs_crate_writes(
            body in proptest::collection::vec(prop_oneof![Just(0u8), any::<u8>(), 1u8..=255], 1..600)
        ) {
            let enc = ours(&body);
            prop_assert_eq!(&enc, &theirs(&body));
            prop_assert!(enc.len() <= cobs_max(body.len()) + 1);
            let mut dec = enc.clone();
            dec.pop();
            let n = cobs_decode(&mut dec);
            prop_assert_eq!(n, Some(body.len()));
            prop_assert_eq!(&dec[..body.len()], &body[..]);
        }

        #[test]
        fn cobs_decodes_any_bytes_as_the_cobs_crate_does(
            bytes in proptest::collection::vec(1u8..=255, 1..300)
        ) {
            let mut a = bytes.clone();
            let mut b = bytes;
            let ours = cobs_decode(&mut a);
            let theirs = cobs::decode_in_place(&mut b).ok();
            prop_assert_eq!(ours, theirs);
            if let Some(n) = ours {
                prop_assert_eq!(&a[..n], &b[..n]);
            }
        }
    }
}
