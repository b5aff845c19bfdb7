//! The STM32C011's way into ST's ROM bootloader (issue 25), the decisions without the chip:
//! what `c011::enter_rom_bootloader` checks before it jumps. The MB's side of the update is
//! `x10-stmboot`; `docs/boards.md` ("Updating the boards") says what each claim rests on.
//!
//! System 12 does not jump from the running image: it leaves [`REQUEST`] in a RAM word a
//! reset keeps and resets the chip once its reply has been read (firmware-db's `moving`);
//! the next start finds the word before the HAL starts and jumps from there, with the chip in
//! its reset state and the watchdog not started.
//!
//! The jump, from that reset state: the ROM's stack pointer and reset vector from its vector
//! table at [`SYSTEM_MEMORY`], the reset vector checked first ([`rom_entry`]), so that a chip
//! whose ROM is not where the manual says is never jumped into. Arduino's Modulino firmware
//! (the same chip) jumps from its running image instead, after `HAL_RCC_DeInit` and clearing
//! the NVIC; starting from a reset needs neither.

/// The C011's system memory, where the ROM bootloader's vector table is (RM0490 §2.2,
/// "Memory map"; AN2606's STM32C011xx section).
pub const SYSTEM_MEMORY: u32 = 0x1FFF_0000;
/// Where the one-time-programmable area starts, past the system memory (`record`'s
/// `C011_OTP_BASE`).
pub const SYSTEM_MEMORY_END: u32 = 0x1FFF_7000;

/// The word System 12 leaves in RAM (`.uninit`, kept by the system reset that follows) to
/// ask the next start for the ROM bootloader: "XROM".
pub const REQUEST: u32 = u32::from_be_bytes(*b"XROM");

/// Whether the word read at start asks for the ROM bootloader. After a power cut the word is
/// noise: one chance in 2^32 to start the ROM bootloader, which the motherboard then finds at
/// 0x64 and sends back (Go) or updates.
pub const fn requested(word: u32) -> bool {
    word == REQUEST
}

/// Whether `reset`, the second word of the ROM's vector table, is a Thumb address (bit 0
/// set) inside the system memory: the one check before the jump. (A stack pointer that is not
/// one would fault at once; the fault goes to the image's own HardFault handler, since VTOR
/// still points at it, which resets the chip into the image: the request word is spent.)
pub const fn rom_entry(reset: u32) -> bool {
    reset & 1 == 1 && (reset & !1).wrapping_sub(SYSTEM_MEMORY) < SYSTEM_MEMORY_END - SYSTEM_MEMORY
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_request_word_asks_for_the_rom_bootloader() {
        assert_eq!(REQUEST, 0x5852_4F4D);
        assert!(requested(0x5852_4F4D));
        assert!(!requested(0));
        assert!(!requested(!0));
        assert!(!requested(0x4D4F_5258));
    }

    #[test]
    fn the_rom_entry_is_a_thumb_address_in_system_memory() {
        assert!(rom_entry(0x1FFF_0A2D));
        assert!(rom_entry(0x1FFF_0001));
        assert!(rom_entry(0x1FFF_6FFF));
        // Erased or unreadable, ARM state, main flash, SRAM, past the system memory (the OTP),
        // just below it.
        assert!(!rom_entry(0xFFFF_FFFF));
        assert!(!rom_entry(0x1FFF_0A2C));
        assert!(!rom_entry(0x0800_00C1));
        assert!(!rom_entry(0x2000_0101));
        assert!(!rom_entry(0x1FFF_7001));
        assert!(!rom_entry(0x1FFE_FFFF));
    }
}
