//! Motherboard image for the STM32G431 (WeAct core board): `X10_ROBOT=fig4_4 cargo mb-g431`
//! builds it with that robot program, flashes it and streams its defmt log. The image itself
//! (tasks, start-up) is `../image.rs`, shared with the other boards.
#![no_std]
#![no_main]

/// What the shared image needs of this board.
mod board {
    pub use x10_boards::g431::{init, Board, G431Bus as Bus, G431Ports as Ports};
    use x10_microcode::BoardKind;

    /// What the internal daughterboard reports as its board.
    pub const KIND: BoardKind = BoardKind::G431;
    /// The board's name in the log.
    pub const NAME: &str = "G431";
}

#[path = "../image.rs"]
mod image;
