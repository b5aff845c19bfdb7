//! Motherboard image for the Raspberry Pi Pico running the plug-and-play example (two
//! daughterboards from one image, given their addresses over the bus, both driven): the image
//! the emulated-RP2040 scenario `plug-and-play` runs. `cargo run -p x10-robots --release
//! --target thumbv6m-none-eabi --features rp2040 --bin mb-pico-pnp` flashes it.
#![no_std]
#![no_main]

x10_boards::mb_image!(x10_boards::pico, x10_robots::TwoBoards);
