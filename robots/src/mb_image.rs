//! The motherboard image running the thesis's Figure 4.4, shared by the boards: each bin
//! (`src/bin/mb-*.rs`) names its board module as `board` and includes this file as
//! `#[path = "../mb_image.rs"] mod image;`. `main` starts the X10 motherboard runtime and
//! spawns the example's two robot tasks; your own robot's image looks the same
//! (`cargo x10 new`, `docs/your-first-robot.md`).

use defmt::{info, unwrap, warn};
use embassy_executor::Spawner;
use x10::{MbConfig, X10};
use x10_boards::start::MB_ADDRESS;
use {defmt_rtt as _, panic_probe as _};

use crate::board::{init, start_motherboard};

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = init();
    let x10 = unwrap!(start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
    info!("robot program: thesis Figure 4.4 (tasks single_board, light_motor)");
    spawner.spawn(unwrap!(single_board(x10)));
    spawner.spawn(unwrap!(light_motor(x10)));
}

#[embassy_executor::task]
async fn single_board(x10: X10) {
    if let Err(e) = x10_robots::fig4_2::single_board(x10).await {
        warn!("single_board ended: {}", e);
    }
}

#[embassy_executor::task]
async fn light_motor(x10: X10) {
    if let Err(e) = x10_robots::fig4_4::light_motor(x10).await {
        warn!("light_motor ended: {}", e);
    }
}
