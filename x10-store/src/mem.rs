//! [`MemFlash`]: NOR flash in memory that can lose its power at any step.
//!
//! It behaves as NOR flash does: an erase sets every bit of its pages to 1, a write (program)
//! can only clear bits (the new contents are the old ANDed with the data written), and the
//! power can be cut in the middle of either.
//!
//! **Steps.** Every byte an erase or a program changes is one step, counted from 0 over the
//! flash's whole life ([`MemFlash::steps`]). [`MemFlash::cut_at`]`(k, mask)` cuts the power
//! during step `k`: the steps before it are done, the byte of step `k` is left half-way (the
//! bits of `mask` have reached their new value, the others not: a partly programmed or partly
//! erased byte), and nothing after it happens. The operation that was cut, and every one after
//! it, fails with `NorFlashErrorKind::Other` until [`MemFlash::power_on`]. An erase changes
//! its bytes in address order, a program its bytes in the order given.
//!
//! No allocation and no `std`: the contents are an array of `SIZE` bytes.

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};

/// NOR flash of `SIZE` bytes in memory, with write size `WRITE` and erase size `ERASE`, and
/// power cuts (see the module's documentation).
#[derive(Clone)]
pub struct MemFlash<const SIZE: usize, const WRITE: usize, const ERASE: usize> {
    data: [u8; SIZE],
    steps: u64,
    cut: Option<(u64, u8)>,
    off: bool,
    erases: u32,
    writes: u32,
}

impl<const SIZE: usize, const WRITE: usize, const ERASE: usize> Default
    for MemFlash<SIZE, WRITE, ERASE>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const SIZE: usize, const WRITE: usize, const ERASE: usize> MemFlash<SIZE, WRITE, ERASE> {
    /// Erased flash (every byte `0xFF`), powered, no cut planned.
    #[must_use]
    pub const fn new() -> Self {
        MemFlash {
            data: [0xFF; SIZE],
            steps: 0,
            cut: None,
            off: false,
            erases: 0,
            writes: 0,
        }
    }

    /// The contents.
    #[must_use]
    pub fn data(&self) -> &[u8; SIZE] {
        &self.data
    }

    /// The contents, to change behind the flash's back (a test's garbage, an image).
    pub fn data_mut(&mut self) -> &mut [u8; SIZE] {
        &mut self.data
    }

    /// Steps done so far (bytes erased or programmed, one each).
    #[must_use]
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Erase operations so far (each of one or more pages).
    #[must_use]
    pub fn erases(&self) -> u32 {
        self.erases
    }

    /// Program (write) operations so far.
    #[must_use]
    pub fn writes(&self) -> u32 {
        self.writes
    }

    /// Cuts the power during step `step` (see the module's documentation): the bits of
    /// `mask` of that step's byte reach their new value, the others keep the old one.
    pub fn cut_at(&mut self, step: u64, mask: u8) {
        self.cut = Some((step, mask));
    }

    /// Whether the power is off (a cut has happened).
    #[must_use]
    pub fn is_off(&self) -> bool {
        self.off
    }

    /// Powers the flash on again after a cut (the contents are kept); no cut is planned.
    pub fn power_on(&mut self) {
        self.off = false;
        self.cut = None;
    }

    /// One step: byte `i` becomes `new` (or half of it, if the power is cut now).
    fn step(&mut self, i: usize, new: u8) -> Result<(), NorFlashErrorKind> {
        if self.off {
            return Err(NorFlashErrorKind::Other);
        }
        let old = self
            .data
            .get(i)
            .copied()
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        match self.cut {
            Some((at, mask)) if at == self.steps => {
                if let Some(b) = self.data.get_mut(i) {
                    *b = (old & !mask) | (new & mask);
                }
                self.off = true;
                Err(NorFlashErrorKind::Other)
            }
            _ => {
                if let Some(b) = self.data.get_mut(i) {
                    *b = new;
                }
                self.steps += 1;
                Ok(())
            }
        }
    }

    fn check(&self, from: usize, to: usize, align: usize) -> Result<(), NorFlashErrorKind> {
        if self.off {
            Err(NorFlashErrorKind::Other)
        } else if from > to || to > SIZE {
            Err(NorFlashErrorKind::OutOfBounds)
        } else if !from.is_multiple_of(align) || !to.is_multiple_of(align) {
            Err(NorFlashErrorKind::NotAligned)
        } else {
            Ok(())
        }
    }
}

impl<const SIZE: usize, const WRITE: usize, const ERASE: usize> ErrorType
    for MemFlash<SIZE, WRITE, ERASE>
{
    type Error = NorFlashErrorKind;
}

impl<const SIZE: usize, const WRITE: usize, const ERASE: usize> ReadNorFlash
    for MemFlash<SIZE, WRITE, ERASE>
{
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let from = offset as usize;
        self.check(from, from.saturating_add(bytes.len()), 1)?;
        bytes.copy_from_slice(
            self.data
                .get(from..from + bytes.len())
                .ok_or(NorFlashErrorKind::OutOfBounds)?,
        );
        Ok(())
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize, const WRITE: usize, const ERASE: usize> NorFlash
    for MemFlash<SIZE, WRITE, ERASE>
{
    const WRITE_SIZE: usize = WRITE;
    const ERASE_SIZE: usize = ERASE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.check(from as usize, to as usize, ERASE)?;
        self.erases += 1;
        for i in from as usize..to as usize {
            self.step(i, 0xFF)?;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let from = offset as usize;
        self.check(from, from.saturating_add(bytes.len()), WRITE)?;
        self.writes += 1;
        for (i, &b) in (from..).zip(bytes) {
            let old = self.data.get(i).copied().unwrap_or(0xFF);
            self.step(i, old & b)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Flash = MemFlash<64, 4, 32>;

    #[test]
    fn program_clears_bits_and_erase_sets_them() {
        let mut f = Flash::new();
        f.write(4, &[0x0F, 0xF0, 0x55, 0xAA]).unwrap();
        f.write(4, &[0x3C, 0xFF, 0xFF, 0x00]).unwrap();
        assert_eq!(&f.data()[4..8], &[0x0C, 0xF0, 0x55, 0x00]);
        assert_eq!(f.steps(), 8);
        f.erase(0, 32).unwrap();
        assert_eq!(f.data()[..32], [0xFF; 32]);
        assert_eq!((f.steps(), f.erases(), f.writes()), (40, 1, 2));
        assert_eq!(f.write(2, &[0; 4]), Err(NorFlashErrorKind::NotAligned));
        assert_eq!(f.erase(0, 16), Err(NorFlashErrorKind::NotAligned));
        assert_eq!(f.erase(32, 96), Err(NorFlashErrorKind::OutOfBounds));
        let mut b = [0u8; 2];
        assert_eq!(f.read(63, &mut b), Err(NorFlashErrorKind::OutOfBounds));
    }

    #[test]
    fn a_cut_program_leaves_the_byte_half_way_and_the_power_off() {
        let mut f = Flash::new();
        f.cut_at(2, 0x0F);
        assert_eq!(
            f.write(8, &[0x00, 0x11, 0x22, 0x33]),
            Err(NorFlashErrorKind::Other)
        );
        assert_eq!(&f.data()[8..12], &[0x00, 0x11, 0xF2, 0xFF]);
        assert!(f.is_off());
        let mut b = [0u8; 1];
        assert_eq!(f.read(0, &mut b), Err(NorFlashErrorKind::Other));
        assert_eq!(f.erase(0, 32), Err(NorFlashErrorKind::Other));
        f.power_on();
        f.read(10, &mut b).unwrap();
        assert_eq!(b, [0xF2]);
        assert_eq!(f.steps(), 2);
    }

    #[test]
    fn a_cut_erase_leaves_the_bytes_before_it_erased_and_the_rest_as_they_were() {
        let mut f = Flash::new();
        f.data_mut()[..32].fill(0x00);
        f.cut_at(3, 0xF0);
        assert_eq!(f.erase(0, 32), Err(NorFlashErrorKind::Other));
        assert_eq!(&f.data()[..5], &[0xFF, 0xFF, 0xFF, 0xF0, 0x00]);
        assert_eq!(f.data()[5..32], [0; 27]);
    }
}
