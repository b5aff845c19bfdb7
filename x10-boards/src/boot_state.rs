//! embassy-boot 0.7's STATE magic as the G431 daughterboard image writes it for System 12
//! (`enter_update`: the DFU-detach magic, `boot-g431` then stays in update mode) and System 13
//! (`confirm_firmware`: the boot magic after a swap, `boot-g431` then keeps the image). These
//! are `x10_boot::enter_update` and `x10_boot::confirm_firmware` (issue 25) without
//! embassy-boot's `BlockingFirmwareState`, whose generic code and length assertion (with its
//! panic formatting) cost db-g431 about 450 bytes it does not have; the bytes written are
//! embassy-boot's own (`set_magic` in its `firmware_updater/blocking.rs`), which the tests
//! check against embassy-boot itself. Portable, host-tested.

use embedded_storage::nor_flash::NorFlash;

/// embassy-boot's magic bytes (its `lib.rs`): the image runs.
pub const BOOT: u8 = 0xD0;
/// A new image was swapped in and has not confirmed itself.
pub const SWAP: u8 = 0xF0;
/// The image asked for the update mode.
pub const DFU_DETACH: u8 = 0xE0;
/// Erased flash.
const ERASED: u8 = 0xFF;
/// The largest program unit handled (the STM32's double word).
const MAX_WRITE: usize = 8;

/// Writes `magic` in the first program unit of the state partition `state`, as embassy-boot's
/// `set_magic` does: when it is not there already, the swap progress is invalidated, the
/// partition erased and the magic written.
///
/// # Errors
/// The flash's.
pub fn set_magic<F: NorFlash>(state: &mut F, magic: u8) -> Result<(), F::Error> {
    const { assert!(F::WRITE_SIZE <= MAX_WRITE) };
    let mut buf = [0u8; MAX_WRITE];
    let w = &mut buf[..F::WRITE_SIZE];
    let unit = F::WRITE_SIZE as u32;
    state.read(0, w)?;
    if w.iter().any(|&b| b != magic) {
        state.read(unit, w)?;
        if w.iter().all(|&b| b == ERASED) {
            w.fill(!ERASED);
            state.write(unit, w)?;
        }
        state.erase(0, state.capacity() as u32)?;
        w.fill(magic);
        state.write(0, w)?;
    }
    Ok(())
}

/// System 12: the DFU-detach magic.
///
/// # Errors
/// The flash's.
pub fn enter_update<F: NorFlash>(state: &mut F) -> Result<(), F::Error> {
    set_magic(state, DFU_DETACH)
}

/// System 13: the boot magic when the state says a new image was swapped in; nothing
/// written otherwise.
///
/// # Errors
/// The flash's.
pub fn confirm_firmware<F: NorFlash>(state: &mut F) -> Result<(), F::Error> {
    const { assert!(F::WRITE_SIZE <= MAX_WRITE) };
    let mut buf = [0u8; MAX_WRITE];
    let w = &mut buf[..F::WRITE_SIZE];
    state.read(0, w)?;
    if w.iter().all(|&b| b == SWAP) {
        set_magic(state, BOOT)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use embassy_boot::{AlignedBuffer, BlockingFirmwareState, State};
    use embedded_storage::nor_flash::{ErrorType, NorFlashErrorKind, ReadNorFlash};
    use std::vec::Vec;

    /// One 2 KiB page, programmed by double word (bits only cleared), every call counted.
    struct Page {
        bytes: Vec<u8>,
        erases: u32,
        writes: u32,
    }

    impl Page {
        fn new() -> Self {
            Page {
                bytes: std::vec![0xFF; 2048],
                erases: 0,
                writes: 0,
            }
        }
    }

    impl ErrorType for Page {
        type Error = NorFlashErrorKind;
    }

    impl ReadNorFlash for Page {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            let o = offset as usize;
            bytes.copy_from_slice(&self.bytes[o..o + bytes.len()]);
            Ok(())
        }
        fn capacity(&self) -> usize {
            2048
        }
    }

    impl NorFlash for Page {
        const WRITE_SIZE: usize = 8;
        const ERASE_SIZE: usize = 2048;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            self.erases += 1;
            self.bytes[from as usize..to as usize].fill(0xFF);
            Ok(())
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            self.writes += 1;
            let o = offset as usize;
            for (d, s) in self.bytes[o..o + bytes.len()].iter_mut().zip(bytes) {
                *d &= s;
            }
            Ok(())
        }
    }

    fn embassy_state(page: &mut Page) -> State {
        let mut a = AlignedBuffer([0u8; 8]);
        BlockingFirmwareState::new(page, &mut a.0)
            .get_state()
            .unwrap()
    }

    #[test]
    fn the_bytes_are_embassy_boots_own() {
        // Ours, read by embassy-boot.
        let mut ours = Page::new();
        enter_update(&mut ours).unwrap();
        assert_eq!(embassy_state(&mut ours), State::DfuDetach);
        // embassy-boot's, byte for byte.
        let mut theirs = Page::new();
        {
            let mut a = AlignedBuffer([0u8; 8]);
            BlockingFirmwareState::new(&mut theirs, &mut a.0)
                .mark_dfu()
                .unwrap();
        }
        assert_eq!(ours.bytes, theirs.bytes);
        assert_eq!(
            &ours.bytes[..16],
            &[0xE0; 8]
                .iter()
                .chain(&[0xFF; 8])
                .copied()
                .collect::<Vec<_>>()[..]
        );
        // Already there: nothing written again.
        let (e, w) = (ours.erases, ours.writes);
        enter_update(&mut ours).unwrap();
        assert_eq!((ours.erases, ours.writes), (e, w));
    }

    #[test]
    fn confirm_turns_a_swap_into_boot_and_leaves_anything_else() {
        let mut page = Page::new();
        {
            let mut a = AlignedBuffer([0u8; 8]);
            BlockingFirmwareState::new(&mut page, &mut a.0)
                .mark_updated()
                .unwrap();
        }
        assert_eq!(embassy_state(&mut page), State::Swap);
        confirm_firmware(&mut page).unwrap();
        assert_eq!(embassy_state(&mut page), State::Boot);
        assert_eq!(&page.bytes[..8], &[BOOT; 8]);
        // Booted, detached, erased: confirm writes nothing.
        for start in [BOOT, DFU_DETACH, 0xFF] {
            let mut p = Page::new();
            if start != 0xFF {
                set_magic(&mut p, start).unwrap();
            }
            let before = p.bytes.clone();
            let (e, w) = (p.erases, p.writes);
            confirm_firmware(&mut p).unwrap();
            assert_eq!((p.bytes == before, p.erases, p.writes), (true, e, w));
        }
    }
}
