//! Motherboard image for the Raspberry Pi Pico running the thesis's Figure 4.4: `cargo mb-pico` builds
//! it, flashes it with probe-rs and streams its defmt log. The image itself is
//! `../mb_image.rs`, shared with the other board and the other examples.
#![no_std]
#![no_main]

use x10_boards::pico as board;

#[path = "../mb_image.rs"]
#[macro_use]
mod image;

mb_image!(x10_robots::Fig4_4);
