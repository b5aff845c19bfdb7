//! Daughterboard image for the STM32G431 (WeAct core board): `cargo db-g431` flashes it and streams its
//! defmt log.
//!
//! Address: `X10_DB_ADDR` at build time (default 9); every pin of the board is a port pin, so
//! it has no address-select jumpers. Events go to the motherboard at `X10_MB_ADDR` (default
//! 0x08).
#![no_std]
#![no_main]

use defmt::{info, unwrap};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, TargetConfig};
use panic_probe as _;
use static_cell::StaticCell;
use x10_boards::g431::{Board, G431Bus, G431Ports, JUMPERS};
use x10_boards::{address, BusConfig, EmbassyClock};
use x10_microcode::{Address, BoardKind};

/// The motherboard's address, checked at build time.
const MB: u8 = match address::build_mb(option_env!("X10_MB_ADDR")) {
    Ok(a) => a,
    Err(_) => panic!("X10_MB_ADDR must be a number in 0x08..=0x77"),
};

/// The base address, checked at build time for every jumper setting.
const BASE: u8 = match address::build_base(option_env!("X10_DB_ADDR"), JUMPERS as u32, MB) {
    Ok(b) => b,
    Err(_) => panic!("X10_DB_ADDR must be in 0x08..=0x77 and differ from X10_MB_ADDR"),
};

type Db = Daughterboard<NoopRawMutex, G431Ports>;

static DB: StaticCell<Db> = StaticCell::new();

#[embassy_executor::task]
async fn daughterboard(db: &'static Db, bus: G431Bus, target: TargetConfig) -> ! {
    firmware_db::run(db, bus, EmbassyClock, target).await
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = x10_boards::g431::init();
    let mut own = Address::INTERNAL;
    let board = Board::new(p, |jumpers| {
        // BASE + 0..2^JUMPERS was checked at build time, so this cannot fail.
        own = unwrap!(address::address(BASE, jumpers).ok());
        BusConfig::standard(own.get())
    });
    // MB was checked at build time.
    let mb = unwrap!(Address::external(MB).ok());
    info!(
        "X10 daughterboard on a G431 at {=u8:#04x} (base {=u8:#04x} + jumpers {=u8}), motherboard at {=u8:#04x}",
        own.get(),
        BASE,
        board.jumpers,
        mb.get()
    );
    let db = DB.init(Daughterboard::new(
        board.ports,
        DbConfig::new(own, BoardKind::G431),
    ));
    // One task, spawned once: the pool (size 1) cannot be exhausted.
    spawner.spawn(unwrap!(daughterboard(db, board.bus, TargetConfig::new(mb))));
}
