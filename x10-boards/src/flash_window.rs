//! A part of a NOR flash seen as a flash of its own: offsets from the part's start, accesses
//! past its end refused. The G431 daughterboard image reaches embassy-boot's STATE partition
//! through it (`db-g431`'s System 12 and 13, issue 25) with the flash driver its address
//! record already owns. Portable, host-tested.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// `len` bytes of `flash` from `start`.
pub struct Window<'a, F> {
    flash: &'a mut F,
    start: u32,
    len: u32,
}

impl<'a, F> Window<'a, F> {
    /// The part of `flash` from `start`, `len` bytes long.
    pub fn new(flash: &'a mut F, start: u32, len: u32) -> Self {
        Window { flash, start, len }
    }

    /// The flash offset of `offset`, when `offset..offset + n` lies inside the window.
    fn at(&self, offset: u32, n: usize) -> Result<u32, NorFlashErrorKind> {
        let n = u32::try_from(n).map_err(|_| NorFlashErrorKind::OutOfBounds)?;
        match offset.checked_add(n) {
            Some(end) if end <= self.len => Ok(self.start + offset),
            _ => Err(NorFlashErrorKind::OutOfBounds),
        }
    }
}

impl<F: ErrorType> ErrorType for Window<'_, F> {
    type Error = NorFlashErrorKind;
}

impl<F: ReadNorFlash> ReadNorFlash for Window<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = self.at(offset, bytes.len())?;
        self.flash.read(at, bytes).map_err(|e| e.kind())
    }

    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl<F: NorFlash> NorFlash for Window<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let n = to.checked_sub(from).ok_or(NorFlashErrorKind::OutOfBounds)?;
        let at = self.at(from, n as usize)?;
        self.flash.erase(at, at + n).map_err(|e| e.kind())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = self.at(offset, bytes.len())?;
        self.flash.write(at, bytes).map_err(|e| e.kind())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 4 pages of 16 bytes, written 4 bytes at a time; every call logged as (op, offset, len).
    struct Flash {
        bytes: [u8; 64],
        log: [(u8, u32, u32); 4],
        n: usize,
    }

    impl ErrorType for Flash {
        type Error = NorFlashErrorKind;
    }

    impl ReadNorFlash for Flash {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            let o = offset as usize;
            bytes.copy_from_slice(&self.bytes[o..o + bytes.len()]);
            Ok(())
        }
        fn capacity(&self) -> usize {
            64
        }
    }

    impl NorFlash for Flash {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = 16;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            self.log[self.n] = (b'e', from, to);
            self.n += 1;
            self.bytes[from as usize..to as usize].fill(0xFF);
            Ok(())
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            self.log[self.n] = (b'w', offset, bytes.len() as u32);
            self.n += 1;
            let o = offset as usize;
            self.bytes[o..o + bytes.len()].copy_from_slice(bytes);
            Ok(())
        }
    }

    #[test]
    fn a_window_moves_offsets_and_refuses_what_lies_outside() {
        let mut f = Flash {
            bytes: [0; 64],
            log: [(0, 0, 0); 4],
            n: 0,
        };
        {
            let mut w = Window::new(&mut f, 32, 16);
            assert_eq!(w.capacity(), 16);
            assert_eq!(w.erase(0, 16), Ok(()));
            assert_eq!(w.write(4, &[1, 2, 3, 4]), Ok(()));
            let mut b = [0u8; 6];
            assert_eq!(w.read(2, &mut b), Ok(()));
            assert_eq!(b, [0xFF, 0xFF, 1, 2, 3, 4]);
            assert_eq!(w.write(16, &[0; 4]), Err(NorFlashErrorKind::OutOfBounds));
            assert_eq!(w.read(12, &mut [0; 5]), Err(NorFlashErrorKind::OutOfBounds));
            assert_eq!(w.erase(0, 32), Err(NorFlashErrorKind::OutOfBounds));
            assert_eq!(w.erase(16, 0), Err(NorFlashErrorKind::OutOfBounds));
            assert_eq!(
                w.read(u32::MAX, &mut [0; 1]),
                Err(NorFlashErrorKind::OutOfBounds)
            );
        }
        assert_eq!(f.log[..f.n], [(b'e', 32, 48), (b'w', 36, 4)]);
        assert_eq!(&f.bytes[32..40], &[0xFF, 0xFF, 0xFF, 0xFF, 1, 2, 3, 4]);
        assert_eq!(&f.bytes[..32], &[0; 32]);
    }
}
