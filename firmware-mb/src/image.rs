//! The motherboard image, shared by every board: each bin (`src/bin/mb-*.rs`) names its board in
//! a `mod board` and includes this file as `#[path = "../image.rs"] mod image;`. It is not a
//! module of the library, which stays free of chip code.
//!
//! What a bin's `board` module provides:
//! * `init()`, the HAL start-up, and `Board`, whose `new` takes its parts (bus and ports);
//! * `Bus` and `Ports`, the board's bus adapter and ports;
//! * `KIND`, the `x10_microcode::BoardKind` the internal daughterboard reports;
//! * `NAME`, the board's name in the log.
//!
//! Tasks: the motherboard runtime (dispatcher, DB-interrupt listener, internal daughterboard on
//! the board's own ports) and one task per robot of the program chosen by `X10_ROBOT` at build
//! time. The MB listens at `X10_MB_ADDR` (default 0x08).

use defmt::{info, unwrap};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_mb::{run_robot, MbConfig, MbHandle, Motherboard};
use panic_probe as _;
use static_cell::StaticCell;
use x10_boards::{address, BusConfig, EmbassyClock};
use x10_microcode::Address;
use x10_robots::{AnyRobot, MAX_ROBOTS};

use crate::board::{init, Board, Bus, Ports, KIND, NAME};

include!(concat!(env!("OUT_DIR"), "/robot.rs"));

/// The motherboard's address, checked at build time.
/// (A `panic!` in a `const` is a compile error naming the variable: it never runs on the board.)
const MB: u8 = match address::build_mb(option_env!("X10_MB_ADDR")) {
    Ok(a) => a,
    Err(_) => panic!("X10_MB_ADDR must be a number in 0x08..=0x77"),
};

/// Period of a robot's `step`, in µs.
const STEP_US: u64 = 20_000;

type Mb = Motherboard<NoopRawMutex, Ports, EmbassyClock>;
type Handle = MbHandle<'static, NoopRawMutex, Ports, EmbassyClock>;

static MOTHERBOARD: StaticCell<Mb> = StaticCell::new();

#[embassy_executor::task]
async fn motherboard(mb: &'static Mb, bus: Bus) -> ! {
    mb.run(bus).await
}

#[embassy_executor::task(pool_size = MAX_ROBOTS)]
async fn robot(robot: AnyRobot<Handle>) -> ! {
    info!("robot {} starts", robot.name());
    run_robot(robot, EmbassyClock, STEP_US).await
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let board = Board::new(init(), |_jumpers| BusConfig::standard(MB));
    // MB was checked at build time.
    let own = unwrap!(Address::external(MB).ok());
    let mut config = MbConfig::new(own);
    config.internal.board = KIND;
    let mb = MOTHERBOARD.init(Motherboard::new(config, EmbassyClock, board.ports));
    info!(
        "X10 motherboard on a {=str} at {=u8:#04x}, robot program {=str}",
        NAME,
        own.get(),
        PROGRAM.name()
    );
    // One motherboard task and at most MAX_ROBOTS robots: the pools (sizes 1 and
    // MAX_ROBOTS) cannot be exhausted, and the program's constant wiring cannot fail.
    spawner.spawn(unwrap!(motherboard(mb, board.bus)));
    for r in unwrap!(PROGRAM.build(mb.handle()).ok()) {
        spawner.spawn(unwrap!(robot(r)));
    }
}
