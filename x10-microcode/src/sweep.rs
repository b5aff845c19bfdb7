//! Boards that act together: a whole bus read in one sweep, outputs applied at once.
//!
//! * **Sweep.** The motherboard writes one `sample` request ([`crate::Op::Sample`]) to the
//!   I2C **general call** address (0x00; byte 1 of the frame is 0 too), always with its check
//!   (covering the address byte `0x00`). Every daughterboard samples its sensor ports at that
//!   moment and holds its reply (the levels and the analog values packed in 12 bits:
//!   [`pack`], always with a CRC-16); the motherboard then reads each board with a **plain
//!   read** (no write first): 19 bytes for 8 ports, so a 110-board bus is read in about 20 ms
//!   at 1 MHz instead of 31 ms with one `scan` per board.
//! * **Staged outputs.** A `stage` request ([`crate::Op::Stage`]) carries outputs that the
//!   board checks at once and holds; an `apply` ([`crate::Op::Apply`]) written to the general
//!   call address makes every board execute what it holds, all from the same bytes on the
//!   wire. What is held and never applied is dropped after [`STAGE_TIMEOUT_MS`].

use crate::{Error, Result, ScanResult};

/// Staged outputs that no `apply` reached within this many ms (100 ms) are dropped: the board
/// counts it (`other_errors`, as a `timeout`) and sends a `rejected` event with the `stage`
/// request's sequence number and status `timeout`.
pub const STAGE_TIMEOUT_MS: u16 = 100;

/// The general call address: every board that listens to it receives the write.
pub const GENERAL_CALL: u8 = 0x00;

/// The longest `sample` reply payload: the levels (2 bytes) and 8 values of 12 bits (12).
pub const MAX_PAYLOAD_LEN: usize = payload_len(ScanResult::MAX_PORTS as u8);

/// Bytes the analog values of `ports` sensor ports take, 12 bits each, packed.
pub const fn packed_len(ports: u8) -> usize {
    (ports as usize * 3).div_ceil(2)
}

/// Payload of an `ok` reply to `sample` from a board with `ports` sensor ports.
pub const fn payload_len(ports: u8) -> usize {
    2 + packed_len(ports)
}

/// Bytes the motherboard reads from a board with `ports` sensor ports after a `sample`: the
/// reply header, the payload and the CRC-16 (19 for 8 ports).
pub const fn frame_len(ports: u8) -> usize {
    crate::REPLY_HEADER_LEN + payload_len(ports) + 2
}

/// The payload of an `ok` reply to `sample` into `out`; its length.
///
/// | byte | field |
/// |---|---|
/// | 0..=1 | digital levels, u16, as in a `scan` (bit 2*i* pin A of port *i* + 1) |
/// | 2.. | analog values, 12 bits each, two in three bytes: value 2*k* in the low 12 bits of bytes 3*k*..3*k*+1 (LE), value 2*k*+1 in the high 12 bits of bytes 3*k*+1..3*k*+2; unused bits 0 |
///
/// # Errors
/// [`Error::BadArgument`] for an analog value above 12 bits, [`Error::BufferTooShort`]
/// (more than 8 ports, or `out` too short).
pub fn pack(values: &ScanResult, out: &mut [u8]) -> Result<usize> {
    let len = payload_len(values.ports);
    let out = out.get_mut(..len).ok_or(Error::BufferTooShort)?;
    out.fill(0);
    let [d0, d1] = values.digital.to_le_bytes();
    let mut bit = 16;
    for i in 0..usize::from(values.ports) {
        let v = *values.analog.get(i).ok_or(Error::BufferTooShort)?;
        if v > 0x0fff {
            return Err(Error::BadArgument);
        }
        let word = u32::from(v) << (bit % 8);
        for (k, b) in word.to_le_bytes().into_iter().take(3).enumerate() {
            if let Some(slot) = out.get_mut(bit / 8 + k) {
                *slot |= b;
            }
        }
        bit += 12;
    }
    if let [a, b, ..] = out {
        *a = d0;
        *b = d1;
    }
    Ok(len)
}

/// The values of a board with `ports` sensor ports from the payload of its `ok` reply to
/// `sample`.
///
/// # Errors
/// [`Error::BadLength`] when the payload is not [`payload_len`]`(ports)` bytes,
/// [`Error::TooLong`] for more than 8 ports, [`Error::BadArgument`] when an unused bit is set.
pub fn unpack(ports: u8, payload: &[u8]) -> Result<ScanResult> {
    if usize::from(ports) > ScanResult::MAX_PORTS {
        return Err(Error::TooLong);
    }
    let [d0, d1, ref packed @ ..] = *payload else {
        return Err(Error::BadLength);
    };
    if payload.len() != payload_len(ports) {
        return Err(Error::BadLength);
    }
    let mut values = ScanResult {
        ports,
        digital: u16::from_le_bytes([d0, d1]),
        ..ScanResult::default()
    };
    for (i, slot) in values
        .analog
        .iter_mut()
        .take(usize::from(ports))
        .enumerate()
    {
        let bit = 12 * i;
        let mut word = [0u8; 4];
        for (k, w) in word.iter_mut().take(3).enumerate() {
            *w = packed.get(bit / 8 + k).copied().unwrap_or(0);
        }
        *slot = ((u32::from_le_bytes(word) >> (bit % 8)) & 0x0fff) as u16;
    }
    // Unused bits (above 2 × ports in the levels, past the last value) are zero.
    let unused = values
        .digital
        .checked_shr(2 * u32::from(ports))
        .unwrap_or(0);
    let tail = (12 * usize::from(ports)) % 8;
    let last_pad = tail != 0 && packed.last().is_some_and(|b| b >> tail != 0);
    if unused != 0 || last_pad {
        return Err(Error::BadArgument);
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_ports_pack_into_fourteen_bytes_and_back() {
        let values = ScanResult {
            ports: 8,
            digital: 0x9a5c,
            analog: [0x000, 0xfff, 0x123, 0x456, 0x789, 0xabc, 0x001, 0x800],
        };
        let mut buf = [0u8; 32];
        let n = pack(&values, &mut buf).unwrap();
        assert_eq!(n, 14);
        assert_eq!(frame_len(8), 19);
        assert_eq!(
            &buf[..n],
            &[0x5c, 0x9a, 0x00, 0xf0, 0xff, 0x23, 0x61, 0x45, 0x89, 0xc7, 0xab, 0x01, 0x00, 0x80]
        );
        assert_eq!(unpack(8, &buf[..n]), Ok(values));
        assert_eq!(unpack(8, &buf[..n - 1]), Err(Error::BadLength));
        assert_eq!(unpack(7, &buf[..n]), Err(Error::BadLength));
    }

    #[test]
    fn odd_port_counts_leave_the_top_nibble_zero() {
        let values = ScanResult {
            ports: 3,
            digital: 0b10_0111,
            analog: [0xabc, 0x123, 0xfff, 0, 0, 0, 0, 0],
        };
        let mut buf = [0u8; 32];
        let n = pack(&values, &mut buf).unwrap();
        assert_eq!(n, 2 + 5);
        assert_eq!(&buf[2..n], &[0xbc, 0x3a, 0x12, 0xff, 0x0f]);
        assert_eq!(unpack(3, &buf[..n]), Ok(values));
        let mut bad = buf;
        bad[n - 1] |= 0x10;
        assert_eq!(unpack(3, &bad[..n]), Err(Error::BadArgument));
        let mut bad = buf;
        bad[1] |= 0x80;
        assert_eq!(unpack(3, &bad[..n]), Err(Error::BadArgument));
    }

    #[test]
    fn a_value_above_twelve_bits_is_not_packed() {
        let values = ScanResult {
            ports: 1,
            digital: 0,
            analog: [0x1000, 0, 0, 0, 0, 0, 0, 0],
        };
        assert_eq!(pack(&values, &mut [0u8; 32]), Err(Error::BadArgument));
    }
}
