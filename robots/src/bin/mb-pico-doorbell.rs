//! Motherboard image for the Raspberry Pi Pico running the doorbell example (a button on
//! daughterboard 9 rings a chime on the motherboard): the image the emulated-RP2040 scenario
//! `doorbell` runs, so that a daughterboard's event waking a motherboard task is measured on
//! the real chip code. `cargo run -p x10-robots --release --target thumbv6m-none-eabi
//! --features rp2040 --bin mb-pico-doorbell` flashes it.
#![no_std]
#![no_main]

x10_boards::mb_image!(x10_boards::pico, x10_robots::Doorbell);
