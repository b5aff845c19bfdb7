//! SMBus Packet Error Code: CRC-8, polynomial 0x07, initial value 0, over the I2C address byte
//! (7-bit address shifted left, R/W bit in bit 0) followed by every byte of the frame.
//!
//! PEC is negotiated per board with the `set_pec` system request. With PEC off a request is
//! exactly the thesis bytes; with PEC on one byte is appended to every request, reply and event.
//! Which address byte is covered:
//! * request: the DB's address, write (`db << 1`);
//! * reply: the DB's address, read (`db << 1 | 1`);
//! * event: the MB's address, write (`mb << 1`).

use crc::{Crc, CRC_8_SMBUS};

use crate::{Error, Result};

const SMBUS: Crc<u8> = Crc::<u8>::new(&CRC_8_SMBUS);

/// PEC over `addr_byte` followed by `frame`.
pub fn compute(addr_byte: u8, frame: &[u8]) -> u8 {
    let mut d = SMBUS.digest();
    d.update(&[addr_byte]);
    d.update(frame);
    d.finalize()
}

/// Splits the trailing PEC byte off `frame_with_pec` and checks it.
///
/// # Errors
/// [`Error::Truncated`] for an empty input, [`Error::PecMismatch`] when the byte is wrong.
pub fn strip(addr_byte: u8, frame_with_pec: &[u8]) -> Result<&[u8]> {
    let (&received, frame) = frame_with_pec.split_last().ok_or(Error::Truncated)?;
    let computed = compute(addr_byte, frame);
    if received == computed {
        Ok(frame)
    } else {
        Err(Error::PecMismatch { received, computed })
    }
}

/// Writes the PEC of `buf[..len]` into `buf[len]` and returns `len + 1`.
///
/// # Errors
/// [`Error::BufferTooShort`] when `buf` has no room after `len` bytes.
pub fn append(addr_byte: u8, buf: &mut [u8], len: usize) -> Result<usize> {
    let (frame, rest) = buf.split_at_mut_checked(len).ok_or(Error::BufferTooShort)?;
    let slot = rest.first_mut().ok_or(Error::BufferTooShort)?;
    *slot = compute(addr_byte, frame);
    Ok(len + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_of_crc8_smbus() {
        // The catalogue check value of CRC-8/SMBUS over "123456789" is 0xF4.
        assert_eq!(SMBUS.checksum(b"123456789"), 0xF4);
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
