//! The Pico's bootloader (issue 25): boot2, then this image at 0x10000100, embassy-boot's
//! STATE sector, the ACTIVE slot (db-pico built with the feature `active-slot`) and the DFU
//! slot (`x10_boards::rp_flash::layout`). At every reset it runs embassy-boot's
//! `prepare_boot` over our flash driver (`pico::PicoFlash`): an update marked in STATE is
//! swapped into ACTIVE (the old image kept in DFU), and an update that was swapped in but never
//! confirmed by the new image (`mark_booted`) is swapped back. Then it starts the watchdog
//! (`watchdog::start`, 200 ms) and jumps to ACTIVE: a new image that hangs before it feeds the
//! watchdog resets the chip, and, not confirmed, is rolled back.
//!
//! Update mode: when the application asked for it (System 12 `enter_update`, which leaves
//! embassy-boot's DFU-detach magic in STATE: `x10_boot::start_mode`), the bootloader serves
//! `x10_boot::Session` as an I2C target at the board's address (read from its address record),
//! every frame checked (PEC or CRC-16), until `commit` (the update marked: reset, and the
//! swap) or `leave` (reset into ACTIVE), or [`UPDATE_IDLE_S`] without a frame (left as by
//! `leave`). The watchdog is not started in update mode.
#![no_std]
#![no_main]

use core::cell::RefCell;

use defmt_rtt as _;
use embassy_boot::BlockingFirmwareState;
use embassy_boot::{BootLoader, BootLoaderConfig};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_executor::Executor;
use embassy_rp::i2c_slave::{self, Command, I2cSlave};
use embassy_rp::peripherals::I2C0;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::{with_timeout, Duration};
use static_cell::StaticCell;
use x10_boards::pico::PicoFlash;
use x10_boards::record::{PICO_PAGE, PICO_RECORD_OFFSET, RECORD_PAGES};
use x10_boards::rp_flash::{layout, XIP_BASE};
use x10_boards::watchdog;
use x10_boot::{BootConfig, Exit, Session, StartMode};
use x10_microcode::{Address, BoardKind, UpdateOp};

/// Update mode ends by itself after this long without a frame for the board (as `leave`).
const UPDATE_IDLE_S: u64 = 30;

/// The oldest firmware version update mode installs (`too_old` below it).
const FLOOR: x10_microcode::Version = [0, 1, 0];

/// The flash, shared by the partitions.
type Flash = Mutex<NoopRawMutex, RefCell<PicoFlash>>;

/// Nothing to report a panic to: the watchdog (when it runs) or the HardFault resets.
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    cortex_m::asm::udf()
}

/// `defmt`'s (embassy-rp's own checks).
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    cortex_m::asm::udf()
}

/// A fault (before the watchdog runs, nothing else would end it): reset.
#[allow(unsafe_code)]
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}

/// The flash, shared by the partitions (static: the update task borrows it).
static FLASH: StaticCell<Flash> = StaticCell::new();
/// embassy-boot's state word for the session (the flash's write size: one byte).
static ALIGNED: StaticCell<[u8; 1]> = StaticCell::new();
/// The executor of update mode.
static EXECUTOR: StaticCell<Executor> = StaticCell::new();

/// A partition of the flash.
type Part = BlockingPartition<'static, NoopRawMutex, PicoFlash>;

#[cortex_m_rt::entry]
fn main() -> ! {
    let p = embassy_rp::init(Default::default());
    let flash: &'static Flash = FLASH.init(Mutex::new(RefCell::new(PicoFlash::new(p.FLASH))));
    let mut boot = BootLoader::new(BootLoaderConfig {
        active: BlockingPartition::new(flash, layout::ACTIVE, layout::ACTIVE_LEN),
        dfu: BlockingPartition::new(flash, layout::DFU, layout::DFU_LEN),
        state: BlockingPartition::new(flash, layout::STATE, layout::STATE_LEN),
    });
    // The swap copies a sector in pieces of this buffer (it divides the 4 KiB sector).
    let mut buf = [0u8; 256];
    // A flash error leaves the slots as they were: boot what ACTIVE holds.
    if let Ok(state) = boot.prepare_boot(&mut buf) {
        if x10_boot::start_mode(&state) == StartMode::Update {
            update_mode(flash, p.I2C0, p.PIN_1, p.PIN_0)
        }
    }
    watchdog::start();
    // SAFETY: ACTIVE holds an image linked there (its vector table first); nothing of this
    // image is used after the jump.
    #[allow(unsafe_code)]
    unsafe {
        jump(XIP_BASE + layout::ACTIVE)
    }
}

/// Sets up the update session at the board's address and serves it ([`serve`]).
fn update_mode(
    flash: &'static Flash,
    i2c: embassy_rp::Peri<'static, embassy_rp::peripherals::I2C0>,
    scl: embassy_rp::Peri<'static, embassy_rp::peripherals::PIN_1>,
    sda: embassy_rp::Peri<'static, embassy_rp::peripherals::PIN_0>,
) -> ! {
    // The board's address: the one its record keeps (unaddressed without one).
    let record = BlockingPartition::new(flash, PICO_RECORD_OFFSET, RECORD_PAGES * PICO_PAGE);
    let address = x10_store::Record::new(record, 0, RECORD_PAGES)
        .and_then(|mut r| r.read())
        .ok()
        .flatten()
        .and_then(|a| Address::assignable(a).ok())
        .unwrap_or(Address::UNADDRESSED);
    let state = BlockingFirmwareState::new(
        BlockingPartition::new(flash, layout::STATE, layout::STATE_LEN),
        ALIGNED.init([0u8; 1]),
    );
    let config = BootConfig {
        board: BoardKind::PICO,
        floor: FLOOR,
        address,
    };
    let dfu = BlockingPartition::new(flash, layout::DFU, layout::DFU_LEN);
    let session = Session::new(config, dfu, state);
    let mut cfg = i2c_slave::Config::default();
    cfg.addr = u16::from(address.get());
    let bus = I2cSlave::new(i2c, scl, sda, x10_boards::pico::Irqs, cfg);
    set_sda_hold(x10_boards::pico_rules::bootloader_sda_tx_hold(
        embassy_rp::clocks::clk_peri_freq(),
    ));
    EXECUTOR.init(Executor::new()).run(|spawner| {
        // One task, spawned once: its pool (size 1) cannot be exhausted.
        if let Ok(task) = serve(session, bus) {
            spawner.spawn(task);
        }
    })
}

/// Sets the target's SDA hold time (`IC_SDA_HOLD.IC_SDA_TX_HOLD`, [`x10_boards::pico_rules::
/// bootloader_sda_tx_hold`]): `I2cSlave::new` resets the block, which leaves it at the slave
/// minimum. The register takes writes only while the block is disabled; the block is enabled
/// again at once, before the executor starts (db-pico's target does the same after each
/// reset of its block).
fn set_sda_hold(hold: u16) {
    let r = embassy_rp::pac::I2C0;
    r.ic_enable().write(|w| w.set_enable(false));
    r.ic_sda_hold().modify(|w| w.set_ic_sda_tx_hold(hold));
    r.ic_enable().write(|w| w.set_enable(true));
}

/// The update session on the bus: each write handed to the session, each read answered with
/// its reply, until the session ends (`commit`, `leave`) or [`UPDATE_IDLE_S`] pass without a
/// transfer (then as `leave`); then the chip resets.
#[embassy_executor::task]
async fn serve(mut session: Session<'static, Part, Part, 256>, mut bus: I2cSlave<'static, I2C0>) {
    let mut rx = [0u8; 64];
    let mut tx = [0u8; 64];
    loop {
        let heard = with_timeout(Duration::from_secs(UPDATE_IDLE_S), bus.listen(&mut rx)).await;
        let read = match heard {
            // Nobody for a while: leave (STATE back to boot), then reset.
            Err(_) => {
                session.update(UpdateOp::Leave);
                break;
            }
            Ok(Ok(Command::Write(n))) => {
                session.handle_write(rx.get(..n).unwrap_or(&[]));
                false
            }
            Ok(Ok(Command::WriteRead(n))) => {
                session.handle_write(rx.get(..n).unwrap_or(&[]));
                true
            }
            Ok(Ok(Command::Read)) => true,
            Ok(Ok(Command::GeneralCall(_)) | Err(_)) => false,
        };
        if read {
            let n = session.take_reply(&mut tx);
            let _ = bus.respond_and_fill(tx.get(..n).unwrap_or(&[]), 0xFF).await;
        }
        // The flash work the request left (an erase, a buffer's write, the swap mark), once
        // its reply has gone: the motherboard's next request meanwhile finds the board deaf
        // and is tried again.
        session.work();
        if session.exit() != Exit::Stay {
            break;
        }
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// Starts the image whose vector table is at `vtor`: every interrupt this image enabled
/// disabled and unpended (the image's own start-up enables its own), `VTOR` set, then its
/// stack pointer and reset vector taken (`cortex_m::asm::bootload`).
///
/// # Safety
/// `vtor` must hold a valid vector table.
#[allow(unsafe_code)]
unsafe fn jump(vtor: u32) -> ! {
    let cp = cortex_m::Peripherals::steal();
    cp.NVIC.icer[0].write(u32::MAX);
    cp.NVIC.icpr[0].write(u32::MAX);
    cp.SCB.vtor.write(vtor);
    cortex_m::asm::bootload(vtor as *const u32)
}
