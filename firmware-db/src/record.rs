//! Where a daughterboard keeps the address it was given over the bus (plug and play,
//! `docs/protocol.md`, "Addresses over the bus").

use x10_microcode::Address;

/// Why an address could not be kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError {
    /// The board keeps no address (it has none of its own, or its address is a build-time
    /// override, which always wins): `set_address` is answered `unsupported`.
    NoRecord,
    /// The record could not be written (flash error): `set_address` is answered `busy` and the
    /// board stays where it is.
    Failed,
}

/// The board's address record, implemented by the image (a power-cut-safe record in the
/// chip's own flash) or by the simulator (in memory, kept across its board resets).
///
/// The runtime calls [`AddressRecord::store`] when it is given an address (`assign`, or
/// `set_address`), before it answers and moves; the image reads the record once at start-up
/// ([`start_address`]).
pub trait AddressRecord {
    /// The address kept, if any. A value that is not an address a board may be given
    /// ([`Address::assignable`]) is not one: [`start_address`] ignores it.
    fn load(&mut self) -> Option<Address>;

    /// Keeps `address` for every later start (a power cut during the write must leave the old
    /// address or the new one, never none).
    ///
    /// # Errors
    /// [`StoreError::NoRecord`], [`StoreError::Failed`].
    fn store(&mut self, address: Address) -> Result<(), StoreError>;

    /// System 12, `enter_update`: marks the board's boot state so that its bootloader stays in
    /// update mode at the next start (`x10_boot::enter_update` on a chip). On `Ok` the runtime
    /// answers `ok` and, once the reply has been read, restarts the board as after a move to
    /// the address it has ([`crate::Daughterboard::moved`]): the image resets the chip.
    ///
    /// # Errors
    /// [`StoreError::NoRecord`] without a bootloader (the default: answered `unsupported`),
    /// [`StoreError::Failed`] when the mark could not be written (`busy`).
    fn enter_update(&mut self) -> Result<(), StoreError> {
        Err(StoreError::NoRecord)
    }

    /// System 13, `confirm_firmware`: the running image marks itself good, so that the
    /// bootloader keeps it at the next reset (`x10_boot::confirm_firmware` on a chip). The
    /// default: nothing to confirm, `Ok`.
    ///
    /// # Errors
    /// [`StoreError::Failed`] when the mark could not be written (`busy`).
    fn confirm_firmware(&mut self) -> Result<(), StoreError> {
        Ok(())
    }
}

/// A board that keeps no address: with a build-time override, or without flash to spare.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoRecord;

impl AddressRecord for NoRecord {
    fn load(&mut self) -> Option<Address> {
        None
    }

    fn store(&mut self, _: Address) -> Result<(), StoreError> {
        Err(StoreError::NoRecord)
    }
}

impl<R: AddressRecord> AddressRecord for &mut R {
    fn load(&mut self) -> Option<Address> {
        (**self).load()
    }

    fn store(&mut self, address: Address) -> Result<(), StoreError> {
        (**self).store(address)
    }

    fn enter_update(&mut self) -> Result<(), StoreError> {
        (**self).enter_update()
    }

    fn confirm_firmware(&mut self) -> Result<(), StoreError> {
        (**self).confirm_firmware()
    }
}

/// The address a board starts at: the build-time `override_address` when there is one (such a
/// board is never unaddressed), else the address its record keeps (when it is one a board may
/// be given), else [`Address::UNADDRESSED`].
pub fn start_address(
    override_address: Option<Address>,
    record: &mut impl AddressRecord,
) -> Address {
    override_address
        .or_else(|| {
            record
                .load()
                .filter(|a| Address::assignable(a.get()).is_ok())
        })
        .unwrap_or(Address::UNADDRESSED)
}
