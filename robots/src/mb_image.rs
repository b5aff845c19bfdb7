//! The motherboard images of the examples, shared by the boards: each bin (`src/bin/mb-*.rs`)
//! names its board module as `board`, includes this file as
//! `#[path = "../mb_image.rs"] #[macro_use] mod image;` and calls [`mb_image!`] with the
//! example's robot (`x10_robots::Fig4_4`, declared once with `x10::robot!`). `main` starts the
//! X10 motherboard runtime and spawns one embassy task per robot task. The panic and HardFault handlers and the watchdog come with x10-boards
//! (`x10_boards::watchdog`); your own robot's image looks the same (`cargo x10 new`,
//! `docs/your-first-robot.md`).

/// `mb_image!(path::to::Robot)`: the image's `main`, which starts the motherboard runtime and
/// spawns the robot's tasks (declared once with `x10::robot!`).
macro_rules! mb_image {
    ($robot:path) => {
        use defmt::{info, unwrap};
        use embassy_executor::Spawner;
        use x10::{MbConfig, Robot};
        use x10_boards::start::MB_ADDRESS;
        // The panic handler comes with x10-boards (`x10_boards::watchdog`): safe outputs first.
        // The defmt logger: with the USB link x10-boards' (`x10_boards::usb_log`: RTT and the
        // link), without it defmt-rtt.
        #[cfg(not(feature = "usb-link"))]
        use defmt_rtt as _;

        use crate::board::{init, start_motherboard};

        #[embassy_executor::main]
        async fn main(spawner: Spawner) {
            // The USB link's hello names the robot (docs/usb-link.md).
            x10_boards::start::name_robot(<$robot>::NAME);
            let p = init();
            let x10 = unwrap!(start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
            info!(
                "robot program {=str}, tasks {}",
                <$robot>::NAME,
                <$robot>::TASKS
            );
            unwrap!($robot.spawn(spawner, x10));
        }
    };
}
