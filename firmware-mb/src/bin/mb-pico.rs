//! Motherboard image for the Raspberry Pi Pico: `X10_ROBOT=fig4_4 cargo mb-pico` builds it
//! with that robot program, flashes it and streams its defmt log. The image itself (tasks,
//! start-up) is `../image.rs`, shared with the other boards.
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    pub use x10_boards::pico::{init, Board, PicoBus as Bus, PicoPorts as Ports};
    use x10_microcode::BoardKind;

    /// What the internal daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::PICO;
    /// The board's name in the log.
    pub const NAME: &str = "Pico";
}

#[path = "../image.rs"]
mod image;
