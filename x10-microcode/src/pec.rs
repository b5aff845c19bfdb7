//! The frame check: SMBus Packet Error Code (CRC-8, polynomial 0x07, initial value 0) on frames
//! of up to [`CRC8_MAX_FRAME`] (13) bytes, CRC-16 (CRC-16/IBM-3740, polynomial 0x1021, initial value
//! 0xFFFF, little-endian on the wire) on longer ones; both over the I2C address byte (7-bit
//! address shifted left, R/W bit in bit 0) followed by every byte of the frame.
//!
//! CRC-8/SMBUS detects every error of up to 3 bits in a codeword (address byte, frame, check)
//! of up to 127 bits, so with a frame of up to 13 bytes, not beyond (two bits 127 apart pass);
//! CRC-16/IBM-3740 does so up to 32 767 bits, so on every frame of the protocol
//! (docs/protocol.md, "The check: CRC-8 on short frames, CRC-16 on long ones").
//!
//! The check is negotiated per board with the `set_pec` system request. With it off a request is
//! exactly the thesis bytes; with it on every request, reply and event carries its check: one
//! byte when the frame has up to 13 bytes, two when it is longer. A receiver tells which from
//! the length alone ([`check_len`]): a frame with its check of up to 14 bytes ends in a CRC-8,
//! one of 16 or more in a CRC-16, and 15 bytes is never a valid length.
//! Which address byte is covered:
//! * request: the DB's address, write (`db << 1`);
//! * reply: the DB's address, read (`db << 1 | 1`);
//! * event: the MB's address, write (`mb << 1`).

use crc::{Crc, NoTable, CRC_16_IBM_3740};

use crate::{Error, Result};

/// CRC-8/SMBUS (polynomial 0x07) of each 4-bit value: the check computed a nibble at a time,
/// two table steps a byte. The `crc` crate's CRC-8 has either a 256-byte table (0.2 KiB of the
/// DB images' flash, which they have not got) or none (8 steps a byte: the PEC of a 5-byte
/// frame took 342 Cortex-M0 instructions, against 54 with the table); this 16-byte one is in
/// between. Checked against the crate's CRC-8/SMBUS by the tests.
// Evaluated at compile time: an index out of range would fail the build, never the board.
#[allow(clippy::indexing_slicing)]
const NIBBLE: [u8; 16] = {
    let mut t = [0u8; 16];
    let mut n = 0;
    while n < 16 {
        let mut c = (n as u8) << 4;
        let mut k = 0;
        while k < 4 {
            c = if c & 0x80 != 0 {
                (c << 1) ^ 0x07
            } else {
                c << 1
            };
            k += 1;
        }
        t[n] = c;
        n += 1;
    }
    t
};

/// One byte into a CRC-8/SMBUS.
fn crc8_step(crc: u8, byte: u8) -> u8 {
    let c = crc ^ byte;
    // Indices are 4-bit values: always inside the 16-entry table (the `get` is optimised out).
    let t = |c: u8| NIBBLE.get(usize::from(c >> 4)).copied().unwrap_or(0);
    let c = (c << 4) ^ t(c);
    (c << 4) ^ t(c)
}
/// Bitwise, without the 512-byte table: long frames are rare and at most 37 bytes, and the
/// daughterboard images count every byte of flash.
const CRC16: Crc<u16, NoTable> = Crc::<u16, NoTable>::new(&CRC_16_IBM_3740);

/// The longest frame that carries a one-byte CRC-8; longer frames carry a CRC-16.
pub const CRC8_MAX_FRAME: usize = 13;
/// The most bytes a check adds to a frame.
pub const MAX_CHECK_LEN: usize = 2;

/// How many check bytes follow a frame of `frame_len` bytes: 1 up to [`CRC8_MAX_FRAME`], else 2.
pub const fn check_len(frame_len: usize) -> usize {
    if frame_len <= CRC8_MAX_FRAME {
        1
    } else {
        2
    }
}

/// The SMBus PEC (CRC-8) over `addr_byte` followed by `frame`.
pub fn compute(addr_byte: u8, frame: &[u8]) -> u8 {
    frame
        .iter()
        .fold(crc8_step(0, addr_byte), |c, &b| crc8_step(c, b))
}

/// The CRC-16/IBM-3740 over `addr_byte` followed by `frame`.
pub fn compute16(addr_byte: u8, frame: &[u8]) -> u16 {
    let mut d = CRC16.digest();
    d.update(&[addr_byte]);
    d.update(frame);
    d.finalize()
}

/// The check of `frame` as sent: its CRC-8, or its CRC-16 for a frame longer than
/// [`CRC8_MAX_FRAME`], as a number.
pub fn check(addr_byte: u8, frame: &[u8]) -> u16 {
    if check_len(frame.len()) == 1 {
        u16::from(compute(addr_byte, frame))
    } else {
        compute16(addr_byte, frame)
    }
}

/// Splits the trailing check off `frame_with_check` and verifies it: one CRC-8 byte when the
/// input has up to `CRC8_MAX_FRAME + 1` bytes, two CRC-16 bytes (little-endian) when it has
/// `CRC8_MAX_FRAME + 3` or more.
///
/// # Errors
/// [`Error::Truncated`] for an empty input, [`Error::BadLength`] for `CRC8_MAX_FRAME + 2`
/// bytes (no frame has that length with its check), [`Error::PecMismatch`] for a wrong PEC
/// byte, [`Error::CrcMismatch`] for a wrong CRC-16.
pub fn strip(addr_byte: u8, frame_with_check: &[u8]) -> Result<&[u8]> {
    let n = frame_with_check.len();
    if n == 0 {
        return Err(Error::Truncated);
    }
    let frame_len = if n <= CRC8_MAX_FRAME + 1 {
        n - 1
    } else if n >= CRC8_MAX_FRAME + 3 {
        n - 2
    } else {
        return Err(Error::BadLength);
    };
    let (frame, tail) = frame_with_check.split_at(frame_len);
    match *tail {
        [received] => {
            let computed = compute(addr_byte, frame);
            if received == computed {
                Ok(frame)
            } else {
                Err(Error::PecMismatch { received, computed })
            }
        }
        [lo, hi] if u16::from_le_bytes([lo, hi]) == compute16(addr_byte, frame) => Ok(frame),
        [_, _] => Err(Error::CrcMismatch),
        _ => Err(Error::BadLength),
    }
}

/// Writes the check of `buf[..len]` after it ([`check_len`]`(len)` bytes) and returns the
/// total length.
///
/// # Errors
/// [`Error::BufferTooShort`] when `buf` has no room for the check after `len` bytes.
pub fn append(addr_byte: u8, buf: &mut [u8], len: usize) -> Result<usize> {
    let (frame, rest) = buf.split_at_mut_checked(len).ok_or(Error::BufferTooShort)?;
    let n = check_len(len);
    let slot = rest.get_mut(..n).ok_or(Error::BufferTooShort)?;
    let c = check(addr_byte, frame).to_le_bytes();
    for (s, b) in slot.iter_mut().zip(c) {
        *s = b;
    }
    Ok(len + n)
}

/// Appends a CRC-16 (low byte first) to the `len`-byte frame in `buf`, whatever its length:
/// the check of a reply to an operation whose reply length varies ([`crate::Op::reply_len`]
/// other than `Exact`). Returns the new length.
///
/// # Errors
/// [`Error::BufferTooShort`] when `buf` has no room for the frame and two bytes.
pub fn append16(addr_byte: u8, buf: &mut [u8], len: usize) -> Result<usize> {
    let (frame, rest) = buf.split_at_mut_checked(len).ok_or(Error::BufferTooShort)?;
    let slot = rest.get_mut(..2).ok_or(Error::BufferTooShort)?;
    slot.copy_from_slice(&compute16(addr_byte, frame).to_le_bytes());
    Ok(len + 2)
}

/// Checks the CRC-16 that ends `frame_with_check` (whatever its length, as [`append16`] adds
/// it) and returns the frame without it.
///
/// # Errors
/// [`Error::Truncated`] for fewer than two bytes, [`Error::CrcMismatch`].
pub fn strip16(addr_byte: u8, frame_with_check: &[u8]) -> Result<&[u8]> {
    let n = frame_with_check
        .len()
        .checked_sub(2)
        .ok_or(Error::Truncated)?;
    let (frame, tail) = frame_with_check.split_at(n);
    match *tail {
        [lo, hi] if u16::from_le_bytes([lo, hi]) == compute16(addr_byte, frame) => Ok(frame),
        _ => Err(Error::CrcMismatch),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_of_crc8_smbus() {
        // The catalogue check value of CRC-8/SMBUS over "123456789" is 0xF4.
        assert_eq!(compute(b'1', b"23456789"), 0xF4);
    }

    #[test]
    fn the_nibble_table_crc8_is_the_crates_crc8_smbus() {
        const SMBUS: Crc<u8, NoTable> = Crc::<u8, NoTable>::new(&crc::CRC_8_SMBUS);
        for a in 0..=255u8 {
            for b in [0u8, 1, 0x7f, 0x80, 0xa5, 0xff, a] {
                let frame = [b, a ^ 0x5a, b.wrapping_mul(3), a];
                let mut d = SMBUS.digest();
                d.update(&[a]);
                d.update(&frame);
                assert_eq!(compute(a, &frame), d.finalize(), "{a:#04x} {frame:02x?}");
            }
        }
    }

    #[test]
    fn check_value_of_crc16_ibm_3740() {
        // The catalogue check value of CRC-16/IBM-3740 over "123456789" is 0x29B1.
        assert_eq!(CRC16.checksum(b"123456789"), 0x29B1);
    }

    #[test]
    fn frames_up_to_14_bytes_get_crc8_longer_ones_crc16() {
        assert_eq!(check_len(0), 1);
        assert_eq!(check_len(13), 1);
        assert_eq!(check_len(14), 2);
        assert_eq!(check_len(36), 2);
        for len in 1..=40usize {
            let mut buf = [0u8; 48];
            for (i, b) in buf.iter_mut().take(len).enumerate() {
                *b = (i as u8).wrapping_mul(37).wrapping_add(5);
            }
            let n = append(0x13, &mut buf, len).unwrap();
            assert_eq!(n, len + check_len(len));
            assert_ne!(n, CRC8_MAX_FRAME + 2, "no frame is 15 bytes with its check");
            assert_eq!(strip(0x13, &buf[..n]), Ok(&buf[..len]));
            if len > CRC8_MAX_FRAME {
                assert_eq!(
                    u16::from_le_bytes([buf[len], buf[len + 1]]),
                    compute16(0x13, &buf[..len])
                );
            }
        }
        assert_eq!(strip(0x13, &[0u8; 15]), Err(Error::BadLength));
    }

    #[test]
    fn two_bit_errors_127_bits_apart_pass_crc8_but_not_crc16() {
        // CRC-8/SMBUS's polynomial divides x^127 + 1: flipping bits 127 apart is invisible to
        // it. A 20-byte frame (with its address byte 168 covered bits) has such pairs.
        let frame: [u8; 20] = core::array::from_fn(|i| (i as u8) ^ 0x5A);
        let flip = |f: &mut [u8; 20], bit: usize| f[bit / 8] ^= 0x80 >> (bit % 8);
        let mut bad = frame;
        flip(&mut bad, 8);
        flip(&mut bad, 8 + 127);
        assert_eq!(compute(0x13, &frame), compute(0x13, &bad));
        assert_ne!(compute16(0x13, &frame), compute16(0x13, &bad));
        let mut buf = [0u8; 22];
        buf[..20].copy_from_slice(&bad);
        let good = compute16(0x13, &frame).to_le_bytes();
        buf[20..].copy_from_slice(&good);
        assert_eq!(strip(0x13, &buf), Err(Error::CrcMismatch));
    }

    #[test]
    fn append_then_strip() {
        let mut buf = [0x12, 0x09, 0x01, 0x02, 0xAA];
        assert_eq!(append(0x12, &mut buf, 4), Ok(5));
        assert_eq!(buf[4], compute(0x12, &[0x12, 0x09, 0x01, 0x02]));
        assert_eq!(strip(0x12, &buf), Ok(&buf[..4]));
        buf[1] ^= 1;
        assert!(matches!(strip(0x12, &buf), Err(Error::PecMismatch { .. })));
        assert_eq!(strip(0x12, &[]), Err(Error::Truncated));
        assert_eq!(append(0, &mut [0u8; 4], 4), Err(Error::BufferTooShort));
    }
}
