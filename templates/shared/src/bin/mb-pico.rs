//! The motherboard image for a Raspberry Pi Pico: `cargo mb-pico` builds it, flashes it with
//! probe-rs and prints its defmt log.
#![no_std]
#![no_main]

use defmt::{unwrap, warn};
use embassy_executor::Spawner;
use x10::{MbConfig, X10};
use x10_boards::pico::{init, start_motherboard};
use x10_boards::start::MB_ADDRESS;
// The panic and HardFault handlers and the watchdog come with x10-boards (`x10_boards::watchdog`).
use defmt_rtt as _;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = init();
    let x10 = unwrap!(start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
    spawner.spawn(unwrap!(bumper(x10)));
    spawner.spawn(unwrap!(drive(x10)));
}

#[embassy_executor::task]
async fn bumper(x10: X10) {
    if let Err(e) = robot::bumper(x10).await {
        warn!("bumper ended: {}", e);
    }
}

#[embassy_executor::task]
async fn drive(x10: X10) {
    if let Err(e) = robot::drive(x10).await {
        warn!("drive ended: {}", e);
    }
}
