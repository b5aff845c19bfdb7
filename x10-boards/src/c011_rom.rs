//! The STM32C011's way into ST's ROM bootloader (issue 25), the decisions without the chip:
//! what `c011::enter_rom_bootloader` checks before it jumps. The MB's side of the update is
//! `x10-stmboot`; `docs/boards.md` ("Updating the boards") says what each claim rests on.
//!
//! The jump (as Arduino's Modulino firmware, the same chip, does it, and ST's knowledge-base
//! sequence for a jump to the system memory): interrupts off, every NVIC interrupt disabled
//! and its pending bit cleared, SysTick stopped, the system clock back to its reset value
//! (HSI48 / 4), every peripheral of the GPIO, AHB and APB buses reset (the STM32C0 HAL's
//! `__HAL_RCC_*_FORCE_RESET` macros write all ones to the reset registers, then release
//! them), the system memory mapped at address 0 (`SYSCFG_CFGR1.MEM_MODE`), then the ROM's
//! stack pointer and reset vector, read from its vector table at [`SYSTEM_MEMORY`] — which
//! this module checks first, so that a chip whose ROM is not where the manual says is never
//! jumped into.

/// The C011's system memory, where the ROM bootloader's vector table is (RM0490 §2.2,
/// "Memory map"; AN2606's STM32C011xx section).
pub const SYSTEM_MEMORY: u32 = 0x1FFF_0000;
/// Where the one-time-programmable area starts, past the system memory (`record`'s
/// `C011_OTP_BASE`).
pub const SYSTEM_MEMORY_END: u32 = 0x1FFF_7000;
/// The C011's SRAM: 6 KiB from 0x20000000.
pub const SRAM: core::ops::Range<u32> = 0x2000_0000..0x2000_1800;

/// The ROM bootloader's first two vectors, checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RomVector {
    /// Its initial stack pointer.
    pub sp: u32,
    /// Its reset handler (a Thumb address: bit 0 set).
    pub reset: u32,
}

/// Why the jump is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RomEntryError {
    /// The initial stack pointer is not a word-aligned address in SRAM (or its top).
    Stack(u32),
    /// The reset vector is not a Thumb address in the system memory.
    Reset(u32),
}

/// Checks the two words at [`SYSTEM_MEMORY`]: a stack pointer in SRAM (up to its top, word
/// aligned) and a Thumb reset vector inside the system memory.
///
/// # Errors
/// [`RomEntryError`] for the first word that is not so.
pub const fn rom_vector(words: [u32; 2]) -> Result<RomVector, RomEntryError> {
    let [sp, reset] = words;
    if sp < SRAM.start || sp > SRAM.end || sp % 4 != 0 {
        return Err(RomEntryError::Stack(sp));
    }
    let target = reset & !1;
    if reset & 1 == 0 || target < SYSTEM_MEMORY || target >= SYSTEM_MEMORY_END {
        return Err(RomEntryError::Reset(reset));
    }
    Ok(RomVector { sp, reset })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rom_vector_is_a_stack_in_sram_and_a_thumb_handler_in_system_memory() {
        assert_eq!(
            rom_vector([0x2000_1800, 0x1FFF_0A2D]),
            Ok(RomVector {
                sp: 0x2000_1800,
                reset: 0x1FFF_0A2D
            })
        );
        assert_eq!(
            rom_vector([0x2000_0400, 0x1FFF_0001]).map(|v| v.sp),
            Ok(0x2000_0400)
        );
        // An erased or unreadable ROM, a stack past the SRAM or unaligned.
        assert_eq!(
            rom_vector([0xFFFF_FFFF, 0xFFFF_FFFF]),
            Err(RomEntryError::Stack(0xFFFF_FFFF))
        );
        assert_eq!(
            rom_vector([0x2000_1804, 0x1FFF_0A2D]),
            Err(RomEntryError::Stack(0x2000_1804))
        );
        assert_eq!(
            rom_vector([0x2000_17FE, 0x1FFF_0A2D]),
            Err(RomEntryError::Stack(0x2000_17FE))
        );
        // An ARM-state address, one in main flash, one past the system memory.
        assert_eq!(
            rom_vector([0x2000_1800, 0x1FFF_0A2C]),
            Err(RomEntryError::Reset(0x1FFF_0A2C))
        );
        assert_eq!(
            rom_vector([0x2000_1800, 0x0800_00C1]),
            Err(RomEntryError::Reset(0x0800_00C1))
        );
        assert_eq!(
            rom_vector([0x2000_1800, 0x1FFF_7001]),
            Err(RomEntryError::Reset(0x1FFF_7001))
        );
    }
}
