//! The STM32G431 daughterboard's flash with its A/B bootloader (issue 25): where the
//! bootloader (`boot-g431`), embassy-boot's state, the running image (ACTIVE, where
//! `db-g431` is linked) and the download slot (DFU) lie, as offsets from the start of
//! flash. No chip code: the layout's rules are checked at compile time ([`check`]) and by the
//! host tests, and the build script's memory maps (`link_args.rs`) carry the same numbers
//! (`tests/g431_layout.rs` compares them).
//!
//! | region | offset | size |
//! |---|---|---|
//! | bootloader (`boot-g431`) | 0x00000 | 24 KiB |
//! | STATE (embassy-boot's swap progress and magic) | 0x06000 | 2 KiB |
//! | ACTIVE (`db-g431`) | 0x06800 | 40 KiB |
//! | DFU (the new image, one page more than ACTIVE for the swap) | 0x10800 | 42 KiB |
//! | free | 0x1B000 | 16 KiB |
//! | address record (`record`) | 0x1F000 | 4 KiB |
//!
//! ACTIVE is larger than a daughterboard image's 32 KiB budget (which `cargo xtask size`
//! holds it to): the layout is in every board's bootloader, flashed once, and should outlive
//! an image that grows.

/// Where flash starts.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// The G431CB's flash.
pub const FLASH_SIZE: u32 = 128 * 1024;
/// One erase page (embassy-stm32 0.6's generated `BANK1_REGION.erase_size` for the chip).
pub const PAGE: u32 = 2048;
/// One program unit (a double word).
pub const WRITE: u32 = 8;

/// A part of flash: `start` and `len` in bytes from [`FLASH_BASE`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// Offset of its first byte.
    pub start: u32,
    /// Its size.
    pub len: u32,
}

impl Region {
    /// The offset just past it.
    pub const fn end(&self) -> u32 {
        self.start + self.len
    }
}

/// The bootloader.
pub const BOOT: Region = Region {
    start: 0,
    len: 24 * 1024,
};
/// embassy-boot's state partition.
pub const STATE: Region = Region {
    start: BOOT.end(),
    len: PAGE,
};
/// The image that runs.
pub const ACTIVE: Region = Region {
    start: STATE.end(),
    len: 40 * 1024,
};
/// The new image, written while the old one runs; one page more than [`ACTIVE`].
pub const DFU: Region = Region {
    start: ACTIVE.end(),
    len: 40 * 1024 + PAGE,
};
/// The address record (`x10_boards::record`): the last two pages, as without a bootloader.
pub const RECORD: Region = Region {
    start: FLASH_SIZE - 2 * PAGE,
    len: 2 * PAGE,
};

/// A rule of the layout that does not hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutError {
    /// A region does not start and end on a page.
    NotPageAligned(Region),
    /// Two regions overlap, or one runs past the end of flash.
    Overlap(Region, Region),
    /// DFU is not at least one page larger than ACTIVE (embassy-boot's swap needs the page).
    DfuTooSmall,
    /// STATE cannot hold embassy-boot's progress: `2 + 4 × (ACTIVE / PAGE)` program units
    /// (embassy-boot 0.7 `boot_loader.rs`, `assert_partitions`).
    StateTooSmall,
}

/// Checks the rules: DFU a page larger than ACTIVE, STATE large enough, every region on
/// pages, in order without overlap inside flash.
///
/// # Errors
/// The first rule that fails.
pub const fn check(regions: &[Region; 5]) -> Result<(), LayoutError> {
    let [_, state, active, dfu, _] = *regions;
    if dfu.len < active.len + PAGE {
        return Err(LayoutError::DfuTooSmall);
    }
    if 2 + 4 * (active.len / PAGE) > state.len / WRITE {
        return Err(LayoutError::StateTooSmall);
    }
    let mut i = 0;
    while i < regions.len() {
        let r = regions[i];
        if !r.start.is_multiple_of(PAGE) || !r.len.is_multiple_of(PAGE) || r.len == 0 {
            return Err(LayoutError::NotPageAligned(r));
        }
        let next_start = if i + 1 < regions.len() {
            regions[i + 1].start
        } else {
            FLASH_SIZE
        };
        if r.end() > next_start {
            let next = if i + 1 < regions.len() {
                regions[i + 1]
            } else {
                Region {
                    start: FLASH_SIZE,
                    len: 0,
                }
            };
            return Err(LayoutError::Overlap(r, next));
        }
        i += 1;
    }
    Ok(())
}

/// The layout, in flash order.
pub const LAYOUT: [Region; 5] = [BOOT, STATE, ACTIVE, DFU, RECORD];

const _: () = assert!(check(&LAYOUT).is_ok());

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_rule_catches_its_layout() {
        let mut l = LAYOUT;
        l[1].len = 1000;
        assert_eq!(check(&l), Err(LayoutError::NotPageAligned(l[1])));
        let mut l = LAYOUT;
        l[3].len = ACTIVE.len;
        assert_eq!(check(&l), Err(LayoutError::DfuTooSmall));
        let mut l = LAYOUT;
        l[2].len = 64 * 1024;
        l[3].start = l[2].end();
        l[3].len = 66 * 1024;
        assert_eq!(check(&l), Err(LayoutError::Overlap(l[3], RECORD)));
        let mut l = LAYOUT;
        l[2].len = 126 * 1024;
        l[3].len = 128 * 1024;
        assert!(matches!(check(&l), Err(LayoutError::Overlap(_, _))));
        // STATE of one page holds 256 program units: ACTIVE of 64 pages needs 258.
        assert_eq!(2 + 4 * (ACTIVE.len / PAGE), 82);
        let mut l = LAYOUT;
        l[2].len = 64 * PAGE;
        l[3].len = 65 * PAGE;
        assert_eq!(check(&l), Err(LayoutError::StateTooSmall));
    }
}
