//! The daughterboard images' address record (plug and play): `firmware_db::AddressRecord` over
//! an `x10_store::Record` in the chip's own flash. The image opens it while its board is built
//! (`Board::new` hands the flash to the bus setup), since the STM32 target address is set when
//! the I2C block is configured.

use embedded_storage::nor_flash::NorFlash;
use firmware_db::{AddressRecord, StoreError};
use x10_microcode::Address;

/// A board's address record: what `assign` and `set_address` store.
pub struct Kept<F: NorFlash> {
    /// The record in flash.
    pub record: x10_store::Record<F>,
    /// The board's address is a build-time override: nothing is stored (`set_address` is
    /// answered `unsupported`), the record keeps what it had.
    pub overridden: bool,
}

impl<F: NorFlash> Kept<F> {
    /// The record, not overridden.
    pub fn new(record: x10_store::Record<F>) -> Self {
        Kept {
            record,
            overridden: false,
        }
    }
}

impl<F: NorFlash> AddressRecord for Kept<F> {
    fn load(&mut self) -> Option<Address> {
        self.record
            .read()
            .ok()
            .flatten()
            .and_then(|a| Address::new(a).ok())
    }

    fn store(&mut self, address: Address) -> Result<(), StoreError> {
        if self.overridden {
            return Err(StoreError::NoRecord);
        }
        // `Record::write` programs nothing when the record already holds it (no wear).
        self.record
            .write(address.get())
            .map_err(|_| StoreError::Failed)
    }

    /// System 12 under the Pico's bootloader (`active-slot`): embassy-boot's DFU-detach mark
    /// in STATE (`boot_state::enter_update`, the bytes `x10_boot::enter_update` writes), through
    /// the flash the record owns.
    #[cfg(feature = "active-slot")]
    fn enter_update(&mut self) -> Result<(), StoreError> {
        crate::boot_state::enter_update(&mut pico_state(self.record.flash()))
            .map_err(|_| StoreError::Failed)
    }

    /// System 13 under the Pico's bootloader: embassy-boot's boot mark when the image was
    /// swapped in (`boot_state::confirm_firmware`).
    #[cfg(feature = "active-slot")]
    fn confirm_firmware(&mut self) -> Result<(), StoreError> {
        crate::boot_state::confirm_firmware(&mut pico_state(self.record.flash()))
            .map_err(|_| StoreError::Failed)
    }
}

/// embassy-boot's STATE partition of the Pico's layout (`rp_flash::layout`) over `flash`.
#[cfg(feature = "active-slot")]
fn pico_state<F: NorFlash>(flash: &mut F) -> crate::flash_window::Window<'_, F> {
    use crate::rp_flash::layout::{STATE, STATE_LEN};
    crate::flash_window::Window::new(flash, STATE, STATE_LEN)
}
