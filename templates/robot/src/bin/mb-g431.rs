//! The motherboard image for an STM32G431 (WeAct board or Nucleo): `cargo mb-g431` builds it, flashes it with
//! probe-rs and prints its defmt log.
#![no_std]
#![no_main]

use defmt::unwrap;
use embassy_executor::Spawner;
use x10::MbConfig;
use x10_boards::g431::{init, start_motherboard};
use x10_boards::start::MB_ADDRESS;
// The panic and HardFault handlers and the watchdog come with x10-boards (`x10_boards::watchdog`),
// and so does the defmt logger (`x10_boards::usb_log`: RTT, and the USB link for `x10 monitor`).

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // The USB link's hello names the robot (`x10 monitor`, docs/usb-link.md).
    x10_boards::start::name_robot(<robot::Robot as x10::Robot>::NAME);
    let p = init();
    let x10 = unwrap!(start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
    // One embassy task per task of the robot (`src/lib.rs`), each logging the error that ends it.
    unwrap!(robot::Robot.spawn(spawner, x10));
}
