//! The daughterboard image, shared by every board: each bin (`src/bin/db-*.rs`) names its board
//! in a `mod board` and includes this file as `#[path = "../image.rs"] mod image;`. It is not a
//! module of the library, which stays free of chip code.
//!
//! What a bin's `board` module provides:
//! * `init()`, the HAL start-up, and `Board`, whose `new` takes its parts (bus, ports) and
//!   reads the address-select jumpers;
//! * `Bus` and `Ports`, the board's bus adapter and ports;
//! * `JUMPERS`, how many address-select jumpers the board has;
//! * `KIND`, the `x10_microcode::BoardKind` the daughterboard reports;
//! * `name()`, the board's name in the log (an interned string: 2 bytes on the wire, no
//!   length and text to send);
//! * `Record`, `record(flash)` and `uid(&mut record)`: the address record in the chip's flash
//!   (opened while the board is built, before its bus: the bus needs the address) and the
//!   chip's unique ID.
//!
//! Address (plug and play, `docs/protocol.md`, "Addresses over the bus"): one image serves
//! every board of a chip. A board starts at the address its record keeps; a new board starts
//! unaddressed (0x77), announces itself and takes the address the motherboard gives it, keeps
//! it and restarts there. `X10_DB_ADDR` at build time (plus the jumpers read at boot) is an
//! override: such a board never takes an address over the bus. Events go to the motherboard
//! at `X10_MB_ADDR` (default 0x08).

use defmt::{info, unwrap};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_futures::select::{select3, Either3};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, TargetConfig};
use static_cell::StaticCell;
use x10_boards::watchdog;
use x10_boards::{address, BusConfig, EmbassyClock};
use x10_microcode::Address;

use crate::board::{init, record, uid, Board, Bus, Ports, Record, JUMPERS, KIND};

/// The motherboard's address, checked at build time.
/// (A `panic!` in a `const` is a compile error naming the variable: it never runs on the board.)
const MB: u8 = match address::build_mb(option_env!("X10_MB_ADDR")) {
    Ok(a) => a,
    Err(_) => panic!("X10_MB_ADDR must be a number in 0x08..=0x76"),
};

/// [`MB`] as an address (checked at build time: a `panic!` in a `const` never runs on the
/// board).
const MB_ADDRESS: Address = match Address::external(MB) {
    Ok(a) => a,
    Err(_) => panic!("X10_MB_ADDR must be a number in 0x08..=0x76"),
};

/// The build-time override: `X10_DB_ADDR`, checked at build time for every jumper setting;
/// `None` without it (plug and play).
/// (A `panic!` in a `const` is a compile error naming the variable: it never runs on the board.)
const BASE: Option<u8> = match option_env!("X10_DB_ADDR") {
    None => None,
    Some(_) => match address::build_base(option_env!("X10_DB_ADDR"), JUMPERS as u32, MB) {
        Ok(b) => Some(b),
        Err(_) if JUMPERS == 0 => {
            panic!("X10_DB_ADDR must be in 0x08..=0x76 and differ from X10_MB_ADDR")
        }
        Err(_) => panic!(
            "X10_DB_ADDR plus every jumper setting (0..2^jumpers) must stay in 0x08..=0x76 and miss X10_MB_ADDR"
        ),
    },
};

/// A panic first puts every actuator pin in its safe state and records the panic for the next
/// boot's reset reason ([`watchdog::crashed`]), then stops the core with a HardFault (`udf`):
/// `probe-rs run` turns it into a backtrace (the file and line of every frame, the panicking
/// one first, `rust_begin_unwind` at the top, from the debug info on the host); without a
/// debugger the HardFault handler (`x10_boards::watchdog`) resets the chip. It logs nothing
/// (the backtrace says it is a panic; `defmt::panic!` and `unwrap!` log their message first). Nothing of the `PanicInfo` is
/// read, not even its location: with the handler ignoring it, link-time optimisation drops
/// what every panic site builds for it (its message, its file name and line, and the
/// `core::fmt` code that would format them). Reading the location alone kept all of that:
/// 6.5 KiB of flash on db-pico, 6.6 KiB on db-g431 (issue 12).
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    watchdog::panicked()
}

/// `defmt::panic!` and `unwrap!` (their message is logged by defmt before this is called).
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    watchdog::panicked()
}

type Db = Daughterboard<NoopRawMutex, Ports, Record>;

static DB: StaticCell<Db> = StaticCell::new();

#[embassy_executor::task]
async fn daughterboard(db: &'static Db, bus: Bus, target: TargetConfig) -> ! {
    // The watchdog is fed while the executor polls this task (see `watchdog::keep_fed`).
    match select3(
        firmware_db::run(db, bus, EmbassyClock, target),
        watchdog::keep_fed(),
        db.moved(),
    )
    .await
    {
        Either3::First(never) | Either3::Second(never) => never,
        // Given an address over the bus and kept: restart there (its outputs were safe for
        // an unaddressed board; a `set_address` restarts a board like a reset would).
        Either3::Third(to) => {
            info!("moving to {=u8:#04x}: restarting", to.get());
            cortex_m::peripheral::SCB::sys_reset()
        }
    }
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let mut own = Address::UNADDRESSED;
    // Before anything else: the record of a crash and the chip's reset flags.
    let reset_reason = watchdog::reset_reason();
    let p = init();
    watchdog::start();
    let mut kept: Option<Record> = None;
    let board = Board::new(p, |jumpers, flash| {
        let mut k = record(flash);
        own = match BASE {
            // BASE + 0..2^JUMPERS was checked at build time, so this cannot fail.
            Some(base) => unwrap!(address::address(base, jumpers).ok()),
            None => firmware_db::start_address(None, &mut k),
        };
        kept = Some(k);
        BusConfig::for_build(own.get())
    });
    let mb = MB_ADDRESS;
    info!(
        "X10 daughterboard on a {=istr} at {=u8:#04x} (jumpers {=u8}), motherboard at {=u8:#04x}",
        crate::board::name(),
        own.get(),
        board.jumpers,
        mb.get()
    );
    // `Board::new` called the setup above: the record is there.
    let Some(mut kept) = kept else {
        watchdog::panicked()
    };
    // An override always wins: `set_address` is answered `unsupported`.
    kept.overridden = BASE.is_some();
    let mut config = DbConfig::new(own, KIND);
    config.reset_reason = reset_reason;
    config.uid = uid(&mut kept);
    let db = DB.init(Daughterboard::with_record(board.ports, config, kept));
    // One task, spawned once: the pool (size 1) cannot be exhausted.
    // (A plain panic if it could: `unwrap!` would bring the error's `Format` code, 20 B.)
    match daughterboard(db, board.bus, TargetConfig::new(mb)) {
        Ok(task) => spawner.spawn(task),
        Err(_) => watchdog::panicked(),
    }
}
