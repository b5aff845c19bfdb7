//! The address record's place on each chip and the chips' unique IDs: the portable half,
//! tested on the host. The chip halves open the record with `x10_store`
//! (`pico::address_record`, `g431::address_record`) and read the unique ID
//! (`pico::PicoFlash::unique_id`, `stm32::unique_id`); see `docs/boards.md` "Address record".
//!
//! * RP2040 (Pico, 2 MiB of QSPI flash, 4 KiB sectors): the last two sectors,
//!   [`PICO_RECORD_OFFSET`]; the image's `FLASH` region ends before them (`link_args.rs`).
//! * STM32G431CB (128 KiB, 2 KiB pages): the last two pages, [`G431_RECORD_OFFSET`].
//! * STM32C011F6 (32 KiB, 2 KiB pages): two pages would leave the image 28 KiB; the record's
//!   place there is the chip's 1 KiB one-time-programmable area ([`C011_OTP_ADDRESS`],
//!   `x10_store::Record::append_only`: 128 address changes in the chip's life), through
//!   `c011::C011Otp` (its address and outcome decisions here: [`c011_otp_address`],
//!   [`c011_program_outcome`]).

use embedded_storage::nor_flash::NorFlashErrorKind;

/// The Pico's flash: 2 MiB.
pub const PICO_FLASH: u32 = 2048 * 1024;
/// The RP2040's erase unit (a 4 KiB sector of the QSPI flash; embassy-rp's `ERASE_SIZE`).
pub const PICO_PAGE: u32 = 4096;
/// Where the Pico's record begins, from the start of flash: its last two sectors.
pub const PICO_RECORD_OFFSET: u32 = PICO_FLASH - RECORD_PAGES * PICO_PAGE;

/// The STM32G431CB's flash: 128 KiB.
pub const G431_FLASH: u32 = 128 * 1024;
/// The STM32G431's page (stm32-metapac's `erase_size` for the STM32G431CB: single bank).
pub const G431_PAGE: u32 = 2048;
/// Where the G431's record begins, from the start of flash (0x0800_0000): its last two pages.
pub const G431_RECORD_OFFSET: u32 = G431_FLASH - RECORD_PAGES * G431_PAGE;

/// The STM32C011's one-time-programmable area (1 KiB of double words, never erased).
pub const C011_OTP_ADDRESS: u32 = 0x1FFF_7000;
/// Its length: 128 slots of 8 bytes.
pub const C011_OTP_LEN: u32 = 1024;

/// The pages a record takes (they alternate).
pub const RECORD_PAGES: u32 = 2;

/// The address of `len` bytes at `offset` in the C011's one-time-programmable area, both
/// multiples of `align` (1 to read, 8, a double word, to program).
///
/// # Errors
/// `OutOfBounds` beyond the area's [`C011_OTP_LEN`] bytes, `NotAligned`.
pub fn c011_otp_address(offset: u32, len: usize, align: u32) -> Result<u32, NorFlashErrorKind> {
    let len = u32::try_from(len).map_err(|_| NorFlashErrorKind::OutOfBounds)?;
    match offset.checked_add(len) {
        Some(end) if end <= C011_OTP_LEN => {}
        _ => return Err(NorFlashErrorKind::OutOfBounds),
    }
    if !offset.is_multiple_of(align) || !len.is_multiple_of(align) {
        return Err(NorFlashErrorKind::NotAligned);
    }
    Ok(C011_OTP_ADDRESS + offset)
}

/// The outcome of a double-word program from the flash status register's error flags after
/// `BSY` cleared (`PROGERR`: the double word was not erased, e.g. an OTP word already
/// written; `WRPERR`: protected; `PGAERR`: misaligned), as embassy-stm32 0.6.0's
/// `wait_ready_blocking` tells them (`src/flash/c.rs` 103-120).
///
/// # Errors
/// `NotAligned` for `PGAERR`, `Other` for the others.
pub fn c011_program_outcome(
    progerr: bool,
    wrperr: bool,
    pgaerr: bool,
) -> Result<(), NorFlashErrorKind> {
    if pgaerr {
        Err(NorFlashErrorKind::NotAligned)
    } else if progerr || wrperr {
        Err(NorFlashErrorKind::Other)
    } else {
        Ok(())
    }
}

/// The 8-byte unique ID of an STM32 chip from its 96-bit UID (the 12 bytes at `UID_BASE`,
/// as `embassy_stm32::uid::uid()` reads them: bytes 0 to 3 the die's X and Y coordinates on
/// the wafer, byte 4 the wafer number, bytes 5 to 11 the lot number in ASCII): bytes 0 to 3
/// XORed with bytes 8 to 11, bytes 4 to 7 as they are.
///
/// Two chips of one lot (the last 7 bytes equal, as on one reel) always get different IDs:
/// for a fixed lot the fold is one-to-one on coordinates and wafer. Across lots two IDs are
/// equal only if wafer and the lot's first three characters are, and the coordinates XOR
/// the lot's last four characters match.
#[must_use]
pub fn fold_uid96(uid: &[u8; 12]) -> [u8; 8] {
    let mut id = [0u8; 8];
    for (i, b) in id.iter_mut().enumerate() {
        *b = uid[i] ^ if i < 4 { uid[i + 8] } else { 0 };
    }
    id
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// The memory maps the build scripts write (`link_args.rs`), read as text.
    mod link {
        #![allow(dead_code)]
        extern crate std;
        use std::string::{String, ToString};
        use std::{format, println};
        include!("../link_args.rs");
        pub const PICO: &str = PICO_MEMORY;
        pub const G431: &str = G431_MEMORY;
    }

    #[test]
    fn stm32_unique_ids_fold_to_these_bytes() {
        // X = 0x0012, Y = 0x0034, wafer 7, lot "ABC1234".
        let uid = [
            0x12, 0x00, 0x34, 0x00, 0x07, b'A', b'B', b'C', b'1', b'2', b'3', b'4',
        ];
        assert_eq!(
            fold_uid96(&uid),
            [0x23, 0x32, 0x07, 0x34, 0x07, b'A', b'B', b'C']
        );
        // The neighbouring die of the same lot and wafer.
        let mut next = uid;
        next[0] = 0x13;
        assert_eq!(
            fold_uid96(&next),
            [0x22, 0x32, 0x07, 0x34, 0x07, b'A', b'B', b'C']
        );
    }

    #[test]
    fn one_lot_never_folds_two_dies_to_one_id() {
        let lot = *b"XYZ9876";
        let mut seen = std::collections::HashSet::new();
        for x in 0..64u16 {
            for y in 0..64u16 {
                for wafer in 0..4u8 {
                    let mut uid = [0u8; 12];
                    uid[..2].copy_from_slice(&x.to_le_bytes());
                    uid[2..4].copy_from_slice(&y.to_le_bytes());
                    uid[4] = wafer;
                    uid[5..].copy_from_slice(&lot);
                    assert!(seen.insert(fold_uid96(&uid)));
                }
            }
        }
    }

    #[test]
    fn the_otp_area_is_addressed_within_its_1_kib() {
        assert_eq!(c011_otp_address(0, 8, 8), Ok(0x1FFF_7000));
        assert_eq!(c011_otp_address(1016, 8, 8), Ok(0x1FFF_73F8));
        assert_eq!(c011_otp_address(1017, 7, 1), Ok(0x1FFF_73F9));
        assert_eq!(c011_otp_address(0, 1024, 1), Ok(0x1FFF_7000));
        assert_eq!(
            c011_otp_address(1024, 8, 8),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(
            c011_otp_address(1020, 8, 1),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(
            c011_otp_address(u32::MAX, 8, 8),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(
            c011_otp_address(4, 8, 8),
            Err(NorFlashErrorKind::NotAligned)
        );
        assert_eq!(
            c011_otp_address(8, 4, 8),
            Err(NorFlashErrorKind::NotAligned)
        );
        assert_eq!(c011_otp_address(0, 0, 8), Ok(0x1FFF_7000));
    }

    #[test]
    fn program_flags_give_these_outcomes() {
        assert_eq!(c011_program_outcome(false, false, false), Ok(()));
        assert_eq!(
            c011_program_outcome(true, false, false),
            Err(NorFlashErrorKind::Other)
        );
        assert_eq!(
            c011_program_outcome(false, true, false),
            Err(NorFlashErrorKind::Other)
        );
        assert_eq!(
            c011_program_outcome(true, true, true),
            Err(NorFlashErrorKind::NotAligned)
        );
    }

    #[test]
    fn the_records_lie_after_the_images_flash() {
        assert_eq!(PICO_RECORD_OFFSET, 0x1F_E000);
        assert_eq!(G431_RECORD_OFFSET, 0x1_F000);
        // The images' FLASH regions end where the records begin.
        assert!(link::PICO.contains("FLASH : ORIGIN = 0x10000100, LENGTH = 2048K - 0x100 - 8K\n"));
        assert!(link::G431.contains("FLASH : ORIGIN = 0x08000000, LENGTH = 128K - 4K\n"));
        assert_eq!(
            0x1000_0000 + 2048 * 1024 - 8 * 1024,
            0x1000_0000 + PICO_RECORD_OFFSET
        );
        assert_eq!(
            0x0800_0000 + (128 - 4) * 1024,
            0x0800_0000 + G431_RECORD_OFFSET
        );
        assert_eq!(C011_OTP_LEN / x10_store::SLOT as u32, 128);
    }
}
