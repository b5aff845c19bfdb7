//! The RP2040's flash driver of our own (`pico::PicoFlash`): its decisions, tested on the
//! host. The chip half (`pico.rs`, "Flash") calls the boot ROM's flash functions from a
//! routine in RAM with interrupts off, as embassy-rp 0.10 does (`src/flash.rs`,
//! `ram_helpers`), without embassy-rp's `Flash`; this module says which ROM functions, where
//! an offset is read, which 256-byte pages a write programs and what the unique-ID command
//! sends and returns.
//!
//! RP2040 datasheet §2.8.3 ("Bootrom Contents"): the ROM's function table is found through
//! the half-words at 0x14 (the table) and 0x18 (`rom_table_lookup`); each function is looked
//! up by a two-letter code. `flash_range_erase(addr, count, block_size, block_cmd)` erases
//! whole 4 KiB sectors; `flash_range_program(addr, data, count)` programs `count` bytes from
//! a 256-byte page boundary, `count` a multiple of 256 (§2.8.3, "Flash Access Functions"). Programming a byte with
//! 0xFF leaves it as it is (NOR flash only clears bits), so a write of fewer bytes programs
//! whole pages padded with 0xFF ([`pages`]).

use embedded_storage::nor_flash::NorFlashErrorKind;

/// Where the flash is mapped for execute-in-place reads (XIP, cached).
pub const XIP_BASE: u32 = 0x1000_0000;
/// The flash's page: what `flash_range_program` programs at once.
pub const PAGE: u32 = 256;
/// The flash's sector: what `flash_range_erase` erases at once (embassy-rp's `ERASE_SIZE`).
pub const SECTOR: u32 = 4096;

/// The ROM's code of a function: its two letters, the first in the low byte (the value
/// `rom_table_lookup` compares, datasheet §2.8.3).
#[must_use]
pub const fn rom_code(name: [u8; 2]) -> u16 {
    u16::from_le_bytes(name)
}

/// `connect_internal_flash`: the QSPI pins to the SSI.
pub const CONNECT_INTERNAL_FLASH: u16 = rom_code(*b"IF");
/// `flash_exit_xip`: the SSI to serial mode, the flash out of continuous reads.
pub const FLASH_EXIT_XIP: u16 = rom_code(*b"EX");
/// `flash_range_erase(addr, count, block_size, block_cmd)`.
pub const FLASH_RANGE_ERASE: u16 = rom_code(*b"RE");
/// `flash_range_program(addr, data, count)`.
pub const FLASH_RANGE_PROGRAM: u16 = rom_code(*b"RP");
/// `flash_flush_cache`: flushes the XIP cache, gives the chip select back to the SSI.
pub const FLASH_FLUSH_CACHE: u16 = rom_code(*b"FC");

/// `block_size` passed to `flash_range_erase`: larger than any range, so the ROM erases 4 KiB
/// sectors only (command 0x20), as embassy-rp does (`1 << 31`, `block_cmd` 0).
pub const ERASE_BLOCK_SIZE: u32 = 1 << 31;

/// The XIP address of `len` bytes at `offset` in a flash of `capacity` bytes.
///
/// # Errors
/// `OutOfBounds` when the range leaves the flash.
pub fn read_address(offset: u32, len: usize, capacity: u32) -> Result<u32, NorFlashErrorKind> {
    end(offset, len, capacity)?;
    Ok(XIP_BASE + offset)
}

/// `from..to` as the ROM's erase arguments: the offset and the length.
///
/// # Errors
/// `NotAligned` unless both are multiples of [`SECTOR`], `OutOfBounds` when `from > to` or
/// `to` is beyond the flash.
pub fn erase_range(from: u32, to: u32, capacity: u32) -> Result<(u32, u32), NorFlashErrorKind> {
    if from > to || to > capacity {
        return Err(NorFlashErrorKind::OutOfBounds);
    }
    if !from.is_multiple_of(SECTOR) || !to.is_multiple_of(SECTOR) {
        return Err(NorFlashErrorKind::NotAligned);
    }
    Ok((from, to - from))
}

/// The end of `len` bytes at `offset`, within `capacity`.
fn end(offset: u32, len: usize, capacity: u32) -> Result<u32, NorFlashErrorKind> {
    u32::try_from(len)
        .ok()
        .and_then(|l| offset.checked_add(l))
        .filter(|&e| e <= capacity)
        .ok_or(NorFlashErrorKind::OutOfBounds)
}

/// One page of a write: the page's offset in the flash, where the bytes go in it, and which
/// of the written bytes they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PageWrite {
    /// The page's offset from the start of flash (a multiple of [`PAGE`]).
    pub page: u32,
    /// Where the bytes start within the page.
    pub at: usize,
    /// The first of the written bytes in this page (an index into the caller's slice).
    pub from: usize,
    /// How many of them.
    pub len: usize,
}

/// The pages a write of `len` bytes at `offset` programs, in order; every byte of a page
/// outside its [`PageWrite`] is programmed with 0xFF (left as it is).
///
/// # Errors
/// `OutOfBounds` when the range leaves the flash.
pub fn pages(
    offset: u32,
    len: usize,
    capacity: u32,
) -> Result<impl Iterator<Item = PageWrite>, NorFlashErrorKind> {
    end(offset, len, capacity)?;
    let mut done = 0usize;
    Ok(core::iter::from_fn(move || {
        if done >= len {
            return None;
        }
        // `offset + done` stays within the flash (checked above), so it fits a u32.
        let here = offset + done as u32;
        let at = (here % PAGE) as usize;
        let n = (PAGE as usize - at).min(len - done);
        let w = PageWrite {
            page: here - at as u32,
            at,
            from: done,
            len: n,
        };
        done += n;
        Some(w)
    }))
}

/// The Pico's flash with the bootloader `boot-pico` (issue 25), as offsets from the start of
/// flash: boot2 (256 B), the bootloader, embassy-boot's STATE (one sector), ACTIVE (the
/// daughterboard image, its 32 KiB budget) and DFU (ACTIVE plus one sector, where an update
/// is written). The address record stays in the last two sectors (`record::PICO_RECORD_OFFSET`).
/// The link maps of both images (`link_args.rs`) follow these numbers (tested).
pub mod layout {
    use super::SECTOR;

    /// The bootloader's vector table, after boot2.
    pub const BOOTLOADER: u32 = 0x100;
    /// embassy-boot's state: one sector after the bootloader's 32 KiB (less boot2).
    pub const STATE: u32 = 0x8000;
    /// Its length.
    pub const STATE_LEN: u32 = SECTOR;
    /// The running daughterboard image (`db-pico` built with `active-slot`).
    pub const ACTIVE: u32 = STATE + STATE_LEN;
    /// Its length: the daughterboard images' 32 KiB budget.
    pub const ACTIVE_LEN: u32 = 32 * 1024;
    /// Where an update is written: ACTIVE plus the one sector embassy-boot's swap needs.
    pub const DFU: u32 = ACTIVE + ACTIVE_LEN;
    /// Its length.
    pub const DFU_LEN: u32 = ACTIVE_LEN + SECTOR;

    // embassy-boot 0.7's partition rules (`assert_partitions`, boot_loader.rs 425-436; its
    // page is one sector, the state written a byte at a time), and the slots clear of the
    // address record: a build-time error otherwise.
    const _: () = assert!(
        ACTIVE_LEN.is_multiple_of(SECTOR)
            && DFU_LEN.is_multiple_of(SECTOR)
            && DFU_LEN - ACTIVE_LEN >= SECTOR
            && 2 + 4 * (ACTIVE_LEN / SECTOR) <= STATE_LEN
            && STATE.is_multiple_of(SECTOR)
            && ACTIVE.is_multiple_of(SECTOR)
            && DFU + DFU_LEN <= crate::record::PICO_RECORD_OFFSET
    );
}

/// The flash command that reads its 64-bit unique ID (Winbond W25Q: 0x4B, four dummy bytes,
/// then the ID), as the bytes the SSI sends: the command, the dummies, and one byte clocked
/// out for each ID byte. The SSI receives as many bytes as it sends (transfer mode 0).
pub const UNIQUE_ID_COMMAND: [u8; 13] = [0x4B, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];

/// The unique ID in the bytes the SSI received for [`UNIQUE_ID_COMMAND`]: its last eight.
#[must_use]
pub fn unique_id(received: &[u8; 13]) -> [u8; 8] {
    let mut id = [0u8; 8];
    id.copy_from_slice(&received[5..]);
    id
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    const CAP: u32 = 2 * 1024 * 1024;

    #[test]
    fn rom_codes_are_the_two_letters_low_byte_first() {
        assert_eq!(CONNECT_INTERNAL_FLASH, 0x4649);
        assert_eq!(FLASH_EXIT_XIP, 0x5845);
        assert_eq!(FLASH_RANGE_ERASE, 0x4552);
        assert_eq!(FLASH_RANGE_PROGRAM, 0x5052);
        assert_eq!(FLASH_FLUSH_CACHE, 0x4346);
    }

    #[test]
    fn reads_map_offsets_to_xip_addresses_within_the_flash() {
        assert_eq!(read_address(0, 4, CAP), Ok(0x1000_0000));
        assert_eq!(read_address(0x1F_E000, 8, CAP), Ok(0x101F_E000));
        assert_eq!(read_address(CAP - 1, 1, CAP), Ok(0x101F_FFFF));
        assert_eq!(read_address(CAP, 0, CAP), Ok(0x1020_0000));
        assert_eq!(
            read_address(CAP - 1, 2, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(
            read_address(u32::MAX, 8, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(
            read_address(0, usize::MAX, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        );
    }

    #[test]
    fn erases_are_whole_sectors_inside_the_flash() {
        assert_eq!(
            erase_range(0x1F_E000, 0x20_0000, CAP),
            Ok((0x1F_E000, 8192))
        );
        assert_eq!(erase_range(4096, 4096, CAP), Ok((4096, 0)));
        assert_eq!(
            erase_range(0x1F_E000, 0x1F_E100, CAP),
            Err(NorFlashErrorKind::NotAligned)
        );
        assert_eq!(
            erase_range(0x100, 0x1000, CAP),
            Err(NorFlashErrorKind::NotAligned)
        );
        assert_eq!(
            erase_range(8192, 4096, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(
            erase_range(0, CAP + 4096, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        );
    }

    #[test]
    fn a_slot_write_programs_one_padded_page() {
        // x10-store's 8-byte slot at 0x1FE108: the page at 0x1FE100, bytes 8 to 15.
        let p: Vec<_> = pages(0x1F_E108, 8, CAP).unwrap().collect();
        assert_eq!(
            p,
            [PageWrite {
                page: 0x1F_E100,
                at: 8,
                from: 0,
                len: 8
            }]
        );
    }

    #[test]
    fn a_write_across_pages_is_cut_at_each_page_boundary() {
        let p: Vec<_> = pages(0x1F0, 0x220, CAP).unwrap().collect();
        assert_eq!(
            p,
            [
                PageWrite {
                    page: 0x100,
                    at: 0xF0,
                    from: 0,
                    len: 0x10
                },
                PageWrite {
                    page: 0x200,
                    at: 0,
                    from: 0x10,
                    len: 0x100
                },
                PageWrite {
                    page: 0x300,
                    at: 0,
                    from: 0x110,
                    len: 0x100
                },
                PageWrite {
                    page: 0x400,
                    at: 0,
                    from: 0x210,
                    len: 0x10
                },
            ]
        );
        // Aligned whole pages: one each, nothing padded.
        let p: Vec<_> = pages(0x1000, 512, CAP).unwrap().collect();
        assert_eq!(p.len(), 2);
        assert_eq!(
            (p[1].page, p[1].at, p[1].from, p[1].len),
            (0x1100, 0, 256, 256)
        );
        assert_eq!(pages(0, 0, CAP).unwrap().count(), 0);
    }

    #[test]
    fn writes_beyond_the_flash_are_refused() {
        assert!(matches!(
            pages(CAP - 4, 8, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        ));
        assert!(matches!(
            pages(u32::MAX - 2, 8, CAP),
            Err(NorFlashErrorKind::OutOfBounds)
        ));
        assert_eq!(pages(CAP - 8, 8, CAP).unwrap().count(), 1);
    }

    #[test]
    fn the_boot_layout_suits_embassy_boot_and_the_link_maps() {
        use layout::*;
        // In order, sector-aligned (embassy-boot's rules are checked at build time, in
        // `layout`).
        assert_eq!(
            (STATE, ACTIVE, DFU, DFU + DFU_LEN),
            (0x8000, 0x9000, 0x1_1000, 0x1_A000)
        );
        // The link maps (`link_args.rs`) say the same.
        assert!(link::BOOT.contains("FLASH : ORIGIN = 0x10000100, LENGTH = 0x8000 - 0x100\n"));
        assert!(link::ACTIVE.contains("FLASH : ORIGIN = 0x10009000, LENGTH = 32K\n"));
        assert!(!link::ACTIVE.contains("BOOT2"));
        assert_eq!(XIP_BASE + ACTIVE, 0x1000_9000);
    }

    /// The memory maps the build scripts write (`link_args.rs`), read as text.
    mod link {
        #![allow(dead_code)]
        extern crate std;
        use std::string::{String, ToString};
        use std::{format, println};
        include!("../link_args.rs");
        pub const BOOT: &str = PICO_BOOT_MEMORY;
        pub const ACTIVE: &str = PICO_ACTIVE_MEMORY;
    }

    #[test]
    fn the_unique_id_is_the_last_eight_bytes_received() {
        // What the flash shifts out: nothing driven during the command and the dummy bytes
        // (0xFF), then the ID.
        let rx = [
            0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xE6, 0x61, 0x38, 0x52, 0x83, 0x5C, 0x2A, 0x27,
        ];
        assert_eq!(
            unique_id(&rx),
            [0xE6, 0x61, 0x38, 0x52, 0x83, 0x5C, 0x2A, 0x27]
        );
        assert_eq!(UNIQUE_ID_COMMAND[0], 0x4B);
        assert!(UNIQUE_ID_COMMAND[1..].iter().all(|&b| b == 0));
    }
}
