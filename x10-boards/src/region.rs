//! A region of a NOR flash as a flash of its own: what the daughterboard image under a
//! bootloader hands embassy-boot for the STATE partition (System 12 `enter_update`, System 13
//! `confirm_firmware`, through `x10_boot`), over the flash its address record already owns.
//! Offsets are the region's; anything outside it is `OutOfBounds`.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// `len` bytes of `flash` from `offset`.
pub struct Region<'a, F> {
    flash: &'a mut F,
    offset: u32,
    len: u32,
}

impl<'a, F> Region<'a, F> {
    /// The region; `offset` and `len` are taken as they are (the flash itself checks its end).
    pub fn new(flash: &'a mut F, offset: u32, len: u32) -> Self {
        Region { flash, offset, len }
    }

    /// The flash offset of `len` bytes at region offset `at`.
    fn at(&self, at: u32, len: usize) -> Result<u32, NorFlashErrorKind> {
        let end = u32::try_from(len)
            .ok()
            .and_then(|l| at.checked_add(l))
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        if end > self.len {
            return Err(NorFlashErrorKind::OutOfBounds);
        }
        self.offset
            .checked_add(at)
            .ok_or(NorFlashErrorKind::OutOfBounds)
    }
}

impl<F: ErrorType> ErrorType for Region<'_, F> {
    type Error = NorFlashErrorKind;
}

impl<F: ReadNorFlash> ReadNorFlash for Region<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = self.at(offset, bytes.len())?;
        self.flash.read(at, bytes).map_err(|e| e.kind())
    }

    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl<F: NorFlash> NorFlash for Region<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if from > to {
            return Err(NorFlashErrorKind::OutOfBounds);
        }
        let at = self.at(from, (to - from) as usize)?;
        self.flash.erase(at, at + (to - from)).map_err(|e| e.kind())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = self.at(offset, bytes.len())?;
        self.flash.write(at, bytes).map_err(|e| e.kind())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use x10_store::mem::MemFlash;

    #[test]
    fn a_region_reads_writes_and_erases_at_its_offset_only() {
        let mut flash = MemFlash::<{ 3 * 4096 }, 1, 4096>::new();
        let mut r = Region::new(&mut flash, 4096, 4096);
        assert_eq!(r.capacity(), 4096);
        r.write(0, &[0xF0]).unwrap();
        r.write(4095, &[0x12]).unwrap();
        let mut b = [0u8; 1];
        r.read(0, &mut b).unwrap();
        assert_eq!(b, [0xF0]);
        assert_eq!(r.write(4096, &[0]), Err(NorFlashErrorKind::OutOfBounds));
        assert_eq!(
            r.read(4095, &mut [0u8; 2]),
            Err(NorFlashErrorKind::OutOfBounds)
        );
        assert_eq!(r.erase(0, 8192), Err(NorFlashErrorKind::OutOfBounds));
        assert_eq!(r.erase(4096, 0), Err(NorFlashErrorKind::OutOfBounds));
        let mut all = [0u8; 3 * 4096];
        flash.read(0, &mut all).unwrap();
        assert_eq!(all[4096], 0xF0);
        assert_eq!(all[8191], 0x12);
        assert!(all[..4096].iter().all(|&x| x == 0xFF));
        assert!(all[8192..].iter().all(|&x| x == 0xFF));
        Region::new(&mut flash, 4096, 4096).erase(0, 4096).unwrap();
        flash.read(0, &mut all).unwrap();
        assert!(all.iter().all(|&x| x == 0xFF));
    }
}
