//! The motherboard images of the examples, shared by the boards: each bin (`src/bin/mb-*.rs`)
//! names its board module as `board`, includes this file as
//! `#[path = "../mb_image.rs"] #[macro_use] mod image;` and calls [`mb_image!`] with the
//! example's robot (`x10_robots::Fig4_4`, declared once with `x10::robot!`). `main` starts the
//! X10 motherboard runtime and spawns one embassy task per robot task. The panic and HardFault handlers and the watchdog come with x10-boards
//! (`x10_boards::watchdog`); your own robot's image looks the same (`cargo x10 new`,
//! `docs/your-first-robot.md`).
//!
//! The daughterboard images the image carries (issue 25): `cargo xtask` builds them first and
//! names them in `X10_CARRY`; the build script (`x10-boards/carry.rs`) makes `CARRIED` of
//! them. With images, `main` also spawns the updater (`x10_boards::start::run_updates`), which
//! brings every board of a carried kind to the carried version, as the image's policy says:
//! `mb_image!(Robot)` is `UpdatePolicy::Auto`; `mb_image!(Robot, updates: UpdatePolicy::Never)`
//! or `updates: UpdatePolicy::Except(&[Uid(…)])` says otherwise (docs/boards.md, "Updating the
//! boards"). Without images the updater is not compiled in.

/// `mb_image!(path::to::Robot)` or `mb_image!(path::to::Robot, updates: POLICY)`: the image's
/// `main`, which starts the motherboard runtime, spawns the updater when the image carries
/// daughterboard images (with `POLICY`, an `UpdatePolicy`; `Auto` when not given) and spawns
/// the robot's tasks (declared once with `x10::robot!`).
macro_rules! mb_image {
    ($robot:path) => {
        mb_image!($robot, updates: x10_boards::start::UpdatePolicy::Auto);
    };
    ($robot:path, updates: $policy:expr) => {
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

        // `CARRIED`: the daughterboard images of `X10_CARRY` (x10-boards/carry.rs).
        include!(concat!(env!("OUT_DIR"), "/carried.rs"));

        /// The updater: brings the boards of the carried kinds to the carried versions.
        #[cfg(x10_carry)]
        #[embassy_executor::task]
        async fn updater(x10: x10::X10, policy: x10_boards::start::UpdatePolicy) -> ! {
            // The gap between chunks scaled to this image's bus clock (at most half of
            // the bus for the update).
            x10_boards::start::run_updates(
                x10,
                x10_boards::start::UpdateConfig::for_bus_hz(x10_boards::BUS_HZ),
                CARRIED,
                policy,
            )
            .await
        }

        #[embassy_executor::main]
        async fn main(spawner: Spawner) {
            let policy: x10_boards::start::UpdatePolicy = $policy;
            // The USB link's hello names the robot (docs/usb-link.md).
            x10_boards::start::name_robot(<$robot>::NAME);
            let p = init();
            let x10 = unwrap!(start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
            info!(
                "robot program {=str}, tasks {}",
                <$robot>::NAME,
                <$robot>::TASKS
            );
            #[cfg(x10_carry)]
            {
                for image in CARRIED {
                    info!(
                        "carries board kind {} firmware {}.{}.{}, {} B",
                        image.kind.0,
                        image.version[0],
                        image.version[1],
                        image.version[2],
                        image.bytes.len()
                    );
                }
                spawner.spawn(unwrap!(updater(x10, policy)));
            }
            #[cfg(not(x10_carry))]
            let _ = policy;
            unwrap!($robot.spawn(spawner, x10));
        }
    };
}
