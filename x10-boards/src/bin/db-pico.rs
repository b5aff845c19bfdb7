//! Daughterboard image for the Raspberry Pi Pico: `cargo db-pico` flashes it and streams its
//! defmt log. The image itself (task, start-up) is `../db_image.rs`, shared with the other boards.
//!
//! Address: given over the bus and kept in the chip's flash (plug and play, one image for
//! every board of this chip, the record through our own flash driver, `pico::PicoFlash`); `X10_DB_ADDR` at build time (plus the three address-select
//! jumpers) is an override. Events go to the motherboard at `X10_MB_ADDR` (default 0x08).
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    use embassy_rp::peripherals::FLASH;
    use embassy_rp::Peri;
    use x10_boards::kept;
    pub use x10_boards::pico::{init, Board, PicoBus as Bus, PicoPorts as Ports, JUMPERS};
    use x10_microcode::{BoardKind, Uid};

    /// Where the board keeps the address it is given over the bus: a record in the last two
    /// sectors of its flash (`pico::address_record`, our own flash driver `pico::PicoFlash`).
    pub type Record = kept::Kept<x10_boards::pico::PicoFlash>;

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::PICO;
    /// The board's name in the log.
    pub fn name() -> defmt::Str {
        defmt::intern!("Pico")
    }

    /// The record, for `assign` and `set_address` (the flash driver).
    pub fn record(flash: Peri<'static, FLASH>) -> Record {
        // Its geometry is fixed at build time and reads within the flash cannot fail (a
        // panic without a message: `unwrap!`'s costs 20 B more).
        let flash = x10_boards::pico::PicoFlash::new(flash);
        match x10_boards::pico::address_record(flash) {
            Ok(r) => kept::Kept::new(r),
            Err(_) => x10_boards::watchdog::panicked(),
        }
    }

    /// The board's unique ID: its flash chip's (command 0x4B).
    pub fn uid(record: &mut Record) -> Uid {
        Uid(record.record.flash().unique_id())
    }
}

#[path = "../db_image.rs"]
mod image;
