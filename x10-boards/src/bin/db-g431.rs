//! Daughterboard image for the STM32G431 (WeAct core board): `cargo db-g431` flashes it and
//! streams its defmt log. The image itself (task, start-up) is `../image.rs`, shared with the
//! other boards.
//!
//! Address: `X10_DB_ADDR` at build time (default 9); every pin of the board is a port pin, so
//! it has no address-select jumpers. Events go to the motherboard at `X10_MB_ADDR` (default
//! 0x08).
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    pub use x10_boards::g431::{init, Board, G431Bus as Bus, G431Ports as Ports, JUMPERS};
    use x10_microcode::BoardKind;

    /// What the daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::G431;
    /// The board's name in the log.
    pub const NAME: &str = "G431";
}

#[path = "../db_image.rs"]
mod image;
