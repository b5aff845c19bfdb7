//! Daughterboard image for the STM32G431 (WeAct core board): `cargo db-g431` flashes it and
//! streams its defmt log. The image itself (task, start-up) is `../image.rs`, shared with the
//! other boards.
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
    pub use x10_boards::g431::{init, Board, G431Bus as Bus, G431Ports as Ports, JUMPERS};
    use x10_boards::kept;
    #[cfg(feature = "g431-update")]
    use x10_boards::{boot_state, flash_window::Window, g431_boot::STATE};
    use x10_microcode::{Address, BoardKind, Uid};

    /// Where the board keeps the address it is given over the bus, and, with the feature
    /// `g431-update`, System 12 and 13 on embassy-boot's STATE partition, which `boot-g431`
    /// reads at every reset (issue 25; +340 B, which the image does not have yet: without the
    /// feature both are answered `unsupported` / `ok` as on a board without a bootloader).
    pub struct Record(kept::Kept<x10_boards::g431::G431Flash>);

    impl core::ops::Deref for Record {
        type Target = kept::Kept<x10_boards::g431::G431Flash>;
        fn deref(&self) -> &Self::Target {
            &self.0
        }
    }

    impl core::ops::DerefMut for Record {
        fn deref_mut(&mut self) -> &mut Self::Target {
            &mut self.0
        }
    }

    #[cfg(feature = "g431-update")]
    impl Record {
        /// embassy-boot's STATE partition, through the record's flash driver.
        fn state(&mut self) -> Window<'_, x10_boards::g431::G431Flash> {
            Window::new(self.0.record.flash(), STATE.start, STATE.len)
        }
    }

    impl AddressRecord for Record {
        fn load(&mut self) -> Option<Address> {
            self.0.load()
        }

        fn store(&mut self, address: Address) -> Result<(), StoreError> {
            self.0.store(address)
        }

        /// STATE's DFU-detach magic: `boot-g431` stays in update mode at the next start.
        #[cfg(feature = "g431-update")]
        fn enter_update(&mut self) -> Result<(), StoreError> {
            boot_state::enter_update(&mut self.state()).map_err(|_| StoreError::Failed)
        }

        /// STATE's boot magic after a swap: `boot-g431` keeps this image.
        #[cfg(feature = "g431-update")]
        fn confirm_firmware(&mut self) -> Result<(), StoreError> {
            boot_state::confirm_firmware(&mut self.state()).map_err(|_| StoreError::Failed)
        }
    }

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::G431;
    /// The board's name in the log.
    pub fn name() -> defmt::Str {
        defmt::intern!("G431")
    }

    /// The record, for `assign` and `set_address` (the flash driver).
    pub fn record(flash: Peri<'static, FLASH>) -> Record {
        // Its geometry is fixed at build time and mapped reads cannot fail.
        Record(kept::Kept::new(unwrap!(x10_boards::g431::address_record(
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
