//! Daughterboard image for the Raspberry Pi Pico: `cargo db-pico` flashes it and streams its
//! defmt log. The image itself (task, start-up) is `../db_image.rs`, shared with the other boards.
//!
//! Address: `X10_DB_ADDR` at build time (default 9) plus the three address-select jumpers
//! read at boot; events go to the motherboard at `X10_MB_ADDR` (default 0x08).
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    pub use x10_boards::pico::{init, Board, PicoBus as Bus, PicoPorts as Ports, JUMPERS};
    use x10_microcode::BoardKind;

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::PICO;
    /// The board's name in the log.
    pub const NAME: &str = "Pico";
}

#[path = "../db_image.rs"]
mod image;
