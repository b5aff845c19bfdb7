//! [`mb_image!`](crate::mb_image): the `main` of a motherboard image, shared by the X10
//! repository's example images (`robots/src/bin/mb-*.rs`) and a robot crate's own
//! (`cargo x10 new`: `src/bin/mb-pico.rs`, `src/bin/mb-g431.rs`).
//!
//! The daughterboard images the image carries (issue 25): the build script (`carry.rs`, and
//! in a robot crate `carry_checkout.rs`, which builds them in the X10 checkout) writes
//! `$OUT_DIR/carried.rs` with `CARRIED`, and with images sets the cfg `x10_carry`; then
//! `main` also spawns the updater ([`run_updates`](crate::start::run_updates)), which brings
//! every board of a carried kind to the carried version as the image's policy says (docs/boards.md,
//! "The motherboard carries the images"). Without images the updater is not compiled in;
//! without a C011 image its method through ST's ROM bootloader is not (the build script sets
//! the cfg `x10_carry_rom` only with one: `run_updates::<NoRom>` otherwise, which refuses a
//! C011 board).
//!
//! The logger: with x10-boards' `usb-log` feature its own (RTT and the USB link), else the
//! calling crate's `defmt-rtt` (a dependency it must have then).

/// `x10_boards::mb_image!(x10_boards::pico, path::to::Robot)`, or with
/// `, updates: POLICY` after the robot: the image's `main`, which starts the motherboard
/// runtime of the board module (`x10_boards::pico` or `x10_boards::g431`: its `init` and
/// `start_motherboard`), spawns the updater when the image carries daughterboard images (with
/// `POLICY`, an [`UpdatePolicy`](crate::start::UpdatePolicy); `UpdatePolicy::Auto` when not
/// given: every board of a carried kind that runs another version; `UpdatePolicy::Never`:
/// none; `UpdatePolicy::Except(&[Uid(…)])`: all but those boards) and spawns the robot's tasks
/// (declared once with `x10::robot!`). The calling crate depends on `x10`, `defmt` and
/// `embassy-executor`, and its build script writes `$OUT_DIR/carried.rs` (`carry.rs`).
#[macro_export]
macro_rules! mb_image {
    ($($board:ident)::+, $robot:path) => {
        $crate::mb_image!($($board)::+, $robot, updates: $crate::start::UpdatePolicy::Auto);
    };
    ($($board:ident)::+, $robot:path, updates: $policy:expr) => {
        $crate::__mb_logger!();

        // `CARRIED`: the daughterboard images of `X10_CARRY` (x10-boards/carry.rs).
        include!(concat!(env!("OUT_DIR"), "/carried.rs"));

        /// How the updater treats a board updated through ST's ROM bootloader (a C011's):
        /// updated when the image carries a C011 image (the cfg `x10_carry_rom` of
        /// x10-boards/carry.rs), else refused, and that method not linked (11.2 KiB on the
        /// Pico).
        #[cfg(all(x10_carry, x10_carry_rom))]
        type CarriedRom = $crate::start::WithRom;
        #[cfg(all(x10_carry, not(x10_carry_rom)))]
        type CarriedRom = $crate::start::NoRom;

        /// The updater: brings the boards of the carried kinds to the carried versions.
        #[cfg(x10_carry)]
        #[embassy_executor::task]
        async fn updater(x10: ::x10::X10, policy: $crate::start::UpdatePolicy) -> ! {
            // The gap between chunks scaled to this image's bus clock (at most half of
            // the bus for the update).
            $crate::start::run_updates::<CarriedRom>(
                x10,
                $crate::start::UpdateConfig::for_bus_hz($crate::BUS_HZ),
                CARRIED,
                policy,
            )
            .await
        }

        #[embassy_executor::main]
        async fn main(spawner: embassy_executor::Spawner) {
            let policy: $crate::start::UpdatePolicy = $policy;
            // The USB link's hello names the robot (docs/usb-link.md).
            $crate::start::name_robot(<$robot as ::x10::Robot>::NAME);
            let p = $($board)::+::init();
            let x10 = ::defmt::unwrap!($($board)::+::start_motherboard(
                spawner,
                p,
                $crate::start::MbConfig::new($crate::start::MB_ADDRESS)
            ));
            ::defmt::info!(
                "robot program {=str}, tasks {}",
                <$robot as ::x10::Robot>::NAME,
                <$robot as ::x10::Robot>::TASKS
            );
            #[cfg(x10_carry)]
            {
                for image in CARRIED {
                    ::defmt::info!(
                        "carries board kind {} firmware {}.{}.{}, {} B",
                        image.kind.0,
                        image.version[0],
                        image.version[1],
                        image.version[2],
                        image.bytes.len()
                    );
                }
                spawner.spawn(::defmt::unwrap!(updater(x10, policy)));
            }
            #[cfg(not(x10_carry))]
            let _ = policy;
            ::defmt::unwrap!($robot.spawn(spawner, x10));
        }
    };
}

/// The defmt logger of [`mb_image!`](crate::mb_image): x10-boards' own with `usb-log`.
#[cfg(feature = "usb-log")]
#[doc(hidden)]
#[macro_export]
macro_rules! __mb_logger {
    () => {};
}

/// The defmt logger of [`mb_image!`](crate::mb_image): the calling crate's `defmt-rtt`
/// without `usb-log`.
#[cfg(not(feature = "usb-log"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __mb_logger {
    () => {
        use defmt_rtt as _;
    };
}
