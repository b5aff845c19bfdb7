//! Starting the motherboard runtime on a board: `start_motherboard` of each chip module
//! ([`crate::pico`], [`crate::g431`]) builds the board's bus and ports, puts the
//! [`firmware_mb::Motherboard`] in a `static`, spawns its task and returns the [`X10`] handle
//! for the robot tasks. An image's `main`:
//!
//! ```ignore
//! #[embassy_executor::main]
//! async fn main(spawner: Spawner) {
//!     let p = x10_boards::pico::init();
//!     let x10 = unwrap!(x10_boards::pico::start_motherboard(spawner, p, MbConfig::new(MB_ADDRESS)));
//!     spawner.spawn(unwrap!(blink(x10)));
//! }
//! ```

use x10_microcode::Address;

/// Firmware over the bus (issue 25): what a motherboard image that carries daughterboard
/// images names (`x10-boards/carry.rs` generates its `CARRIED`; docs/boards.md "Updating the
/// boards"). An image that carries none does not name [`run_updates`], and does not link it;
/// one that carries no C011 image names `run_updates::<NoRom>`, and does not link the method
/// through ST's ROM bootloader ([`WithRom`]: `mb_image!`, the cfg `x10_carry_rom`).
pub use firmware_mb::update::{run_updates, DbImage, NoRom, UpdateConfig, UpdatePolicy, WithRom};
pub use firmware_mb::{MbConfig, X10};

/// How many boards the motherboard images know by their unique ID at once (plug and play's
/// directory: 16 B of RAM each).
pub const KNOWN_BOARDS: usize = 32;

/// Why `start_motherboard` failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartError {
    /// The motherboard was already started (it runs once per image).
    AlreadyStarted,
    /// The executor could not take the runtime's task.
    Spawn,
}

/// The motherboard's address: `X10_MB_ADDR` at build time, 0x08 by default. A bad value is a
/// compile error (the `panic!` runs in a `const`, never on the board).
pub const MB_ADDRESS: Address = match crate::address::build_mb(option_env!("X10_MB_ADDR")) {
    Ok(a) => match Address::external(a) {
        Ok(a) => a,
        Err(_) => panic!("X10_MB_ADDR must be a number in 0x08..=0x76"),
    },
    Err(_) => panic!("X10_MB_ADDR must be a number in 0x08..=0x76"),
};

static ROBOT: embassy_sync::blocking_mutex::Mutex<
    embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex,
    core::cell::Cell<&'static str>,
> = embassy_sync::blocking_mutex::Mutex::new(core::cell::Cell::new(""));

/// Names the robot program (the images' `main` calls it with the robot's `NAME`): the USB
/// link's hello carries it (docs/usb-link.md).
pub fn name_robot(name: &'static str) {
    ROBOT.lock(|r| r.set(name));
}

/// The name given to [`name_robot`] (empty before).
pub fn robot_name() -> &'static str {
    ROBOT.lock(core::cell::Cell::get)
}

/// Defines `start_motherboard` for one board: the `static` motherboard, its task, and the
/// function (tasks cannot be generic, so each board names its types).
macro_rules! motherboard_starter {
    (ports: $ports:ty, bus: $bus:ty, kind: $kind:expr, name: $name:literal $(,)?) => {
        type StartedMb = firmware_mb::Motherboard<$ports>;

        static MOTHERBOARD: static_cell::StaticCell<StartedMb> = static_cell::StaticCell::new();

        /// The boards the motherboard knows by their unique ID (plug and play: it addresses
        /// new boards, sweeps the bus at start, reports lost boards and collisions): 16 B each.
        static DIRECTORY: static_cell::StaticCell<
            [firmware_mb::KnownBoard; crate::start::KNOWN_BOARDS],
        > = static_cell::StaticCell::new();

        #[embassy_executor::task]
        async fn motherboard_task(mb: &'static StartedMb, bus: $bus) -> ! {
            use embassy_futures::select::{select, Either};
            // The watchdog is fed while the executor polls this task
            // (`crate::watchdog::keep_fed`): a robot task that never yields resets the board.
            match select(mb.run(bus), crate::watchdog::keep_fed()).await {
                Either::First(never) | Either::Second(never) => never,
            }
        }

        /// Starts the X10 motherboard runtime on this board: starts the hardware watchdog
        /// ([`crate::watchdog`], fed by the runtime's task), builds the bus (listening at
        /// `config.address`) and the ports of the internal daughterboard from `p`, spawns the
        /// runtime's task (dispatcher, DB-interrupt listener, internal daughterboard,
        /// keepalive) and, with the feature `usb-link`, the USB link's task
        /// ([`crate::usb_link`]), and returns the handle robot tasks take.
        ///
        /// # Errors
        /// [`crate::start::StartError::AlreadyStarted`] on a second call;
        /// [`crate::start::StartError::Spawn`] if the executor has no room for the task.
        pub fn start_motherboard(
            spawner: embassy_executor::Spawner,
            p: Peripherals,
            mut config: firmware_mb::MbConfig,
        ) -> Result<firmware_mb::X10, crate::start::StartError> {
            let address = config.address.get();
            config.internal.reset_reason = crate::watchdog::reset_reason();
            crate::watchdog::start();
            let board = Board::new(p, |_jumpers, _flash| crate::BusConfig::for_build(address));
            config.internal.board = $kind;
            let directory = DIRECTORY
                .try_init([firmware_mb::KnownBoard::EMPTY; crate::start::KNOWN_BOARDS])
                .ok_or(crate::start::StartError::AlreadyStarted)?;
            let started =
                firmware_mb::Motherboard::new(config, board.ports).with_directory(directory);
            // The USB link records calls and events (`crate::usb_link`).
            #[cfg(feature = "usb-link")]
            let started = started.with_observer(&crate::usb_link::RECORDER);
            let mb: &'static StartedMb = MOTHERBOARD
                .try_init(started)
                .ok_or(crate::start::StartError::AlreadyStarted)?;
            // Robot calls to the board's own ports run in the calling task (issue 27).
            mb.serve_internal_directly();
            let task =
                motherboard_task(mb, board.bus).map_err(|_| crate::start::StartError::Spawn)?;
            spawner.spawn(task);
            #[cfg(feature = "usb-link")]
            spawn_usb(spawner, board.usb, mb.handle())?;
            defmt::info!("X10 motherboard on a {=str} at {=u8:#04x}", $name, address);
            Ok(mb.handle())
        }
    };
}
