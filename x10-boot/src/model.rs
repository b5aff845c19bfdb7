//! A daughterboard's flash in memory, for host tests and the simulator (feature `model`):
//! the state, active and DFU partitions of the Pico's layout in one byte array, erased to 0xFF,
//! written as NOR flash is (a write only clears bits), with the time each erase and program
//! would take on the Pico's W25Q16JV (datasheet, typical: 45 ms per 4 KiB sector erase,
//! 0.4 ms per 256-byte page program) added to a counter the caller turns into deaf time.
//!
//! Cloning a [`Flash`] shares it, so a board's flash outlives the board's resets (a power cut
//! keeps what was written). Its partitions are what [`crate::Session`], embassy-boot's
//! `BootLoader` and `BlockingFirmwareState` are given.

// Every index below is inside the array by construction (the partitions' constants) or checked
// first (`Part::span`); a test model, never in an image.
#![allow(clippy::indexing_slicing)]

extern crate std;

use core::cell::{Cell, RefCell};
use std::rc::Rc;
use std::vec;
use std::vec::Vec;

use embassy_boot::{BootLoader, BootLoaderConfig, State};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Sector erase size (the Pico's flash).
pub const SECTOR: usize = 4096;
/// The active slot: a DB image's 32 KiB.
pub const ACTIVE: usize = 32 * 1024;
/// The DFU slot: one sector more than the active one (embassy-boot's swap needs it).
pub const DFU: usize = ACTIVE + SECTOR;
/// The state partition.
pub const STATE: usize = SECTOR;
/// Time of a sector erase (ns, typical).
pub const ERASE_NS: u64 = 45_000_000;
/// Time of a 256-byte page program (ns, typical).
pub const PROGRAM_NS: u64 = 400_000;

/// A partition of [`Flash`]: [`Flash::STATE_PART`], [`Flash::ACTIVE_PART`] or
/// [`Flash::DFU_PART`].
pub type Which = usize;

/// The model's flash error. A read, erase or write outside the partition, or not on the
/// flash's alignment, is refused with it (embassy-boot never asks for one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutOfBounds;

impl NorFlashError for OutOfBounds {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::OutOfBounds
    }
}

/// The board's flash: all three partitions, and the flash time spent so far.
#[derive(Clone, Debug)]
pub struct Flash {
    mem: Rc<RefCell<Vec<u8>>>,
    busy_ns: Rc<Cell<u64>>,
}

/// One partition of a [`Flash`]: `embedded_storage`'s `NorFlash`.
#[derive(Debug)]
pub struct Part {
    flash: Flash,
    base: usize,
    len: usize,
}

impl Flash {
    /// The state partition.
    pub const STATE_PART: Which = 0;
    /// The active slot.
    pub const ACTIVE_PART: Which = 1;
    /// The DFU slot.
    pub const DFU_PART: Which = 2;

    /// A board flashed (by a probe) with `image` at the start of its active slot, the rest
    /// erased. An image longer than the slot is cut to it.
    pub fn with_active(image: &[u8]) -> Flash {
        let mut mem = vec![0xffu8; STATE + ACTIVE + DFU];
        let n = image.len().min(ACTIVE);
        mem[STATE..STATE + n].copy_from_slice(&image[..n]);
        Flash {
            mem: Rc::new(RefCell::new(mem)),
            busy_ns: Rc::new(Cell::new(0)),
        }
    }

    /// A partition: [`Flash::STATE_PART`], [`Flash::ACTIVE_PART`] or [`Flash::DFU_PART`] (any
    /// other number is the DFU slot).
    pub fn part(&self, which: Which) -> Part {
        let (base, len) = match which {
            Self::STATE_PART => (0, STATE),
            Self::ACTIVE_PART => (STATE, ACTIVE),
            _ => (STATE + ACTIVE, DFU),
        };
        Part {
            flash: self.clone(),
            base,
            len,
        }
    }

    /// The byte at `offset` in the active slot (0xFF past it).
    pub fn active_byte(&self, offset: usize) -> u8 {
        if offset >= ACTIVE {
            return 0xff;
        }
        self.mem.borrow()[STATE + offset]
    }

    /// The first `len` bytes of the active slot (at most the slot).
    pub fn active(&self, len: usize) -> Vec<u8> {
        self.mem.borrow()[STATE..STATE + len.min(ACTIVE)].to_vec()
    }

    /// The state partition's mark, as embassy-boot reads it.
    pub fn state(&self) -> State {
        State::from(&self.mem.borrow()[0..1])
    }

    /// Flash time spent so far (ns): every erase and program adds its typical time.
    pub fn busy_ns(&self) -> u64 {
        self.busy_ns.get()
    }

    /// embassy-boot's bootloader over the three partitions (its `prepare_boot` is the start).
    pub fn bootloader(&self) -> BootLoader<Part, Part, Part> {
        BootLoader::new(BootLoaderConfig {
            active: self.part(Self::ACTIVE_PART),
            dfu: self.part(Self::DFU_PART),
            state: self.part(Self::STATE_PART),
        })
    }
}

impl Part {
    /// `offset..offset + n` of the partition as indices into the whole flash, when inside.
    fn span(&self, offset: u32, n: usize) -> Result<core::ops::Range<usize>, OutOfBounds> {
        let from = offset as usize;
        match from.checked_add(n) {
            Some(to) if to <= self.len => Ok(self.base + from..self.base + to),
            _ => Err(OutOfBounds),
        }
    }
}

impl ErrorType for Part {
    type Error = OutOfBounds;
}

impl ReadNorFlash for Part {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), OutOfBounds> {
        let r = self.span(offset, bytes.len())?;
        bytes.copy_from_slice(&self.flash.mem.borrow()[r]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.len
    }
}

impl NorFlash for Part {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = SECTOR;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), OutOfBounds> {
        if to < from
            || !(from as usize).is_multiple_of(SECTOR)
            || !(to as usize).is_multiple_of(SECTOR)
        {
            return Err(OutOfBounds);
        }
        let r = self.span(from, (to - from) as usize)?;
        let sectors = (r.len() / SECTOR) as u64;
        self.flash.mem.borrow_mut()[r].fill(0xff);
        self.flash
            .busy_ns
            .set(self.flash.busy_ns.get() + ERASE_NS * sectors);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), OutOfBounds> {
        let r = self.span(offset, bytes.len())?;
        for (m, b) in self.flash.mem.borrow_mut()[r].iter_mut().zip(bytes) {
            *m &= *b;
        }
        self.flash
            .busy_ns
            .set(self.flash.busy_ns.get() + PROGRAM_NS * bytes.len().div_ceil(256) as u64);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_only_clear_bits_and_erases_cost_their_time() {
        let f = Flash::with_active(&[0x0f, 0xf0]);
        let mut a = f.part(Flash::ACTIVE_PART);
        a.write(0, &[0xff, 0x3c]).unwrap();
        assert_eq!(f.active(3), vec![0x0f, 0x30, 0xff]);
        assert_eq!(f.busy_ns(), PROGRAM_NS);
        a.erase(0, SECTOR as u32).unwrap();
        assert_eq!(f.active(2), vec![0xff, 0xff]);
        assert_eq!(f.busy_ns(), PROGRAM_NS + ERASE_NS);
    }

    #[test]
    fn outside_the_partition_is_refused() {
        let f = Flash::with_active(&[]);
        let mut s = f.part(Flash::STATE_PART);
        let mut b = [0u8; 2];
        assert_eq!(s.read(STATE as u32 - 1, &mut b), Err(OutOfBounds));
        assert_eq!(s.write(u32::MAX, &[0]), Err(OutOfBounds));
        assert_eq!(s.erase(0, 100), Err(OutOfBounds));
        assert_eq!(s.erase(SECTOR as u32, 0), Err(OutOfBounds));
        assert_eq!(f.busy_ns(), 0);
        assert_eq!(f.state(), State::Boot);
    }
}
