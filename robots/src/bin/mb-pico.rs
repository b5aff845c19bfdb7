//! Motherboard image for the Raspberry Pi Pico running the thesis's Figure 4.4: `cargo mb-pico` builds
//! it, flashes it with probe-rs and streams its defmt log. The image itself is
//! `x10_boards::mb_image!`, shared with the other board, the other examples and your own
//! robot's images (`cargo x10 new`).
#![no_std]
#![no_main]

x10_boards::mb_image!(x10_boards::pico, x10_robots::Fig4_4);
