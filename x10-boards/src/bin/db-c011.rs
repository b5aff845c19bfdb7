//! Daughterboard image for the STM32C011F6 (TSSOP-20): `cargo db-c011` flashes it and streams
//! its defmt log. The image itself (task, start-up) is `../db_image.rs`, shared with the other
//! boards.
//!
//! Address: `X10_DB_ADDR` at build time (default 9); every free pin is a port pin, so it has
//! no address-select jumpers. Events go to the motherboard at `X10_MB_ADDR` (default 0x08).
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    pub use x10_boards::c011::{init, Board, C011Bus as Bus, C011Ports as Ports, JUMPERS};
    use x10_microcode::BoardKind;

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::C011;
    /// The board's name in the log.
    pub const NAME: &str = "C011";
}

#[path = "../db_image.rs"]
mod image;
