//! Daughterboard image for the STM32C011F6 (TSSOP-20): `cargo db-c011` flashes it and streams
//! its defmt log. The image itself (task, start-up) is `../db_image.rs`, shared with the other
//! boards.
//!
//! Address: given over the bus and kept in the chip's flash (plug and play, one image for
//! every board of this chip); `X10_DB_ADDR` at build time is an override. Events go to the
//! motherboard at `X10_MB_ADDR` (default 0x08).
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    use defmt::unwrap;
    use embassy_stm32::peripherals::FLASH;
    use embassy_stm32::Peri;
    use firmware_db::{AddressRecord, StoreError};
    pub use x10_boards::c011::{init, Board, C011Bus as Bus, C011Ports as Ports, JUMPERS};
    use x10_boards::kept;
    use x10_microcode::{Address, BoardKind, Uid};

    /// Where the board keeps the address it is given over the bus, and System 12's way into
    /// ST's ROM bootloader (issue 25; the board has no bootloader of its own).
    pub struct Record(kept::Kept<x10_boards::c011::C011Otp>);

    impl core::ops::Deref for Record {
        type Target = kept::Kept<x10_boards::c011::C011Otp>;
        fn deref(&self) -> &Self::Target {
            &self.0
        }
    }

    impl core::ops::DerefMut for Record {
        fn deref_mut(&mut self) -> &mut Self::Target {
            &mut self.0
        }
    }

    impl AddressRecord for Record {
        fn load(&mut self) -> Option<Address> {
            self.0.load()
        }

        fn store(&mut self, address: Address) -> Result<(), StoreError> {
            self.0.store(address)
        }

        /// The next start jumps into the ROM bootloader (`c011::init`); the runtime resets
        /// the chip once the reply has been read. Nothing to write in flash: always `Ok`.
        fn enter_update(&mut self) -> Result<(), StoreError> {
            x10_boards::c011::request_rom_bootloader();
            Ok(())
        }
    }

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::C011;
    /// The board's name in the log.
    pub fn name() -> defmt::Str {
        defmt::intern!("C011")
    }

    /// The record, for `assign` and `set_address` (append-only in the OTP area).
    pub fn record(flash: Peri<'static, FLASH>) -> Record {
        // Its geometry is fixed at build time and OTP reads cannot fail.
        Record(kept::Kept::new(unwrap!(x10_boards::c011::address_record(
            flash
        )
        .ok())))
    }

    /// The board's unique ID: the 96-bit UID folded to 8 bytes.
    pub fn uid(_record: &mut Record) -> Uid {
        Uid(x10_boards::stm32::unique_id())
    }
}

#[path = "../db_image.rs"]
mod image;
