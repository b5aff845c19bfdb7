//! Motherboard image for the STM32G431 running the thesis's Figure 4.4: `cargo mb-g431` builds
//! it, flashes it with probe-rs and streams its defmt log. The image itself is
//! `x10_boards::mb_image!`, shared with the other board, the other examples and your own
//! robot's images (`cargo x10 new`).
#![no_std]
#![no_main]

x10_boards::mb_image!(x10_boards::g431, x10_robots::Fig4_4);
