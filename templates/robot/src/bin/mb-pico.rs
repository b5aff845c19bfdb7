//! The motherboard image for a Raspberry Pi Pico: `cargo mb-pico` builds it, flashes it with
//! probe-rs and prints its defmt log. It carries the X10 checkout's daughterboard images
//! (`build.rs`: db-pico by default, `X10_CARRY_KINDS=pico,g431,c011` for more) and brings
//! every daughterboard of those kinds to their version over the bus; `cargo plan` prints what
//! it would update in `world.toml`.
//!
//! Which boards it updates: every one by default. To update none, or to leave some boards on
//! the firmware they run (by unique ID: `x10 boards` prints them), end the line below with
//! `, updates: x10_boards::start::UpdatePolicy::Never)` or
//! `, updates: x10_boards::start::UpdatePolicy::Except(&[x10::Uid([0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08])]))`.
#![no_std]
#![no_main]

// `main`: starts the X10 motherboard runtime, the updater, and one embassy task per task of the
// robot (`src/lib.rs`), each logging the error that ends it. The panic and HardFault handlers
// and the watchdog come with x10-boards (`x10_boards::watchdog`), and so does the defmt logger
// (`x10_boards::usb_log`: RTT, and the USB link for `x10 monitor`).
x10_boards::mb_image!(x10_boards::pico, robot::Robot);
