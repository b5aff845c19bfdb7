//! Daughterboard image for the Raspberry Pi Pico: `cargo db-pico` flashes it and streams its
//! defmt log. The image itself (task, start-up) is `../db_image.rs`, shared with the other boards.
//!
//! Address: given over the bus and kept in the chip's flash (plug and play, one image for
//! every board of this chip); `X10_DB_ADDR` at build time (plus the three address-select
//! jumpers) is an override. Events go to the motherboard at `X10_MB_ADDR` (default 0x08).
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    use embassy_rp::peripherals::FLASH;
    use embassy_rp::Peri;
    pub use x10_boards::pico::{init, Board, PicoBus as Bus, PicoPorts as Ports, JUMPERS};
    use x10_microcode::{BoardKind, Uid};

    /// Where the board keeps the address it is given over the bus: for now the watchdog's
    /// SCRATCH1 register, kept by resets, cleared by a power cut (`pico::ScratchKept`).
    pub type Record = x10_boards::pico::ScratchKept;

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::PICO;
    /// The board's name in the log.
    pub const NAME: &str = "Pico";

    /// The record, for `assign` and `set_address`.
    pub fn record(flash: Peri<'static, FLASH>) -> Record {
        x10_boards::pico::ScratchKept {
            flash: x10_boards::pico::PicoFlash::new_blocking(flash),
            overridden: false,
        }
    }

    /// The board's unique ID: its flash chip's (command 0x4B); zeros if it cannot be read.
    pub fn uid(record: &mut Record) -> Uid {
        Uid(x10_boards::pico::unique_id(&mut record.flash).unwrap_or([0; 8]))
    }
}

#[path = "../db_image.rs"]
mod image;
