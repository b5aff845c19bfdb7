//! The STM32G431 daughterboard's bootloader (issue 25): embassy-boot's A/B swap over the
//! chip's flash, the update mode (x10-boot's session of function 7 on the bus), then the jump
//! to the image in ACTIVE (`db-g431`). The layout is `x10_boards::g431_boot`'s;
//! `docs/boards.md` ("Updating the boards") says how it is flashed once and what in it is
//! verified by reading only.
//!
//! At every reset: `prepare_boot` reads STATE. A new image that the update mode wrote to DFU
//! and committed is swapped into ACTIVE, page by page, with its progress in STATE so that a
//! power cut during the swap resumes it; an image that was swapped in but never confirmed
//! (System 13, `mark_booted`) is swapped back (the rollback). When the image asked for the
//! update mode (System 12: embassy-boot's DFU-detach magic, `x10_boot::start_mode`), the
//! bootloader serves the bus at the board's address (its record) with `x10_boot::Session`
//! (its flash work done after each reply has been read) until `commit` or `leave`, then
//! resets; else it jumps to ACTIVE.
//!
//! Outside the update mode the HAL is not started (no clock change, no time driver, no
//! interrupt): the flash driver works on the reset clock (HSI16, zero wait states), and the
//! image starts from the chip's reset state but for VTOR and the stack pointer.
#![no_std]
#![no_main]

use core::cell::RefCell;

use cortex_m_rt::entry;
use defmt_rtt as _;
use embassy_boot_stm32::{BlockingFirmwareState, BootLoader, BootLoaderConfig, State};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::i2c::{self, I2c, SlaveAddrConfig, SlaveCommandKind};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use x10_boards::g431_boot::{ACTIVE, DFU, FLASH_BASE, PAGE, STATE};
use x10_boards::record::{G431_RECORD_OFFSET, RECORD_PAGES};
use x10_boot::{BootConfig, Exit, Session, StartMode};
use x10_microcode::{Address, BoardKind, MAX_REPLY_LEN};

/// embassy-boot's swap buffer: one erase page.
const BUFFER: usize = PAGE as usize;

/// The session's write buffer: 256 bytes (a multiple of the double word, divides the page).
const WRITE: usize = 256;

type G4Flash = Mutex<NoopRawMutex, RefCell<Flash<'static, Blocking>>>;

#[entry]
fn main() -> ! {
    // SAFETY: the only user of the flash controller in this image.
    #[allow(unsafe_code)]
    let flash = unsafe { embassy_stm32::peripherals::FLASH::steal() };
    let flash: G4Flash = Mutex::new(RefCell::new(Flash::new_blocking(flash)));
    let config = BootLoaderConfig {
        active: BlockingPartition::new(&flash, ACTIVE.start, ACTIVE.len),
        dfu: BlockingPartition::new(&flash, DFU.start, DFU.len),
        state: BlockingPartition::new(&flash, STATE.start, STATE.len),
    };
    // A flash error while swapping leaves STATE saying so: the next reset resumes. The image
    // in ACTIVE is started either way (a swap cut short is resumed before any jump).
    let state = BootLoader::try_prepare::<_, _, _, BUFFER>(config)
        .map(|l| l.state)
        .unwrap_or(State::Boot);
    if x10_boot::start_mode(&state) == StartMode::Update {
        update_mode(&flash);
    }
    start()
}

/// Serves x10-boot's session at the board's address until it says to reset. Without an
/// address in the record (a board never given one cannot have been sent System 12) the image
/// is started: its STATE still says update, so it is asked again at the next reset only if
/// the image does not clear it (`x10_boot::confirm_firmware` and `enter_update` rewrite it).
fn update_mode(flash: &G4Flash) {
    let record = x10_store::Record::new(
        BlockingPartition::new(flash, 0, x10_boards::g431_boot::FLASH_SIZE),
        G431_RECORD_OFFSET,
        RECORD_PAGES,
    );
    let Some(address) = record
        .ok()
        .and_then(|mut r| r.read().ok().flatten())
        .and_then(|a| Address::new(a).ok())
    else {
        return;
    };
    // The I2C block's interrupts are bound by the library (`x10_boards::g431::Irqs`); the
    // blocking driver polls, the handlers only clear the enables it sets.
    let p = embassy_stm32::init(Default::default());
    let mut bus = I2c::new_blocking(p.I2C1, p.PA15, p.PB7, i2c::Config::default())
        .into_slave_multimaster(SlaveAddrConfig::basic(address.get()));
    let mut aligned = [0u8; 8];
    let config = BootConfig {
        board: BoardKind::G431,
        floor: firmware_db::FIRMWARE_VERSION,
        address,
    };
    let mut session = Session::<_, _, WRITE>::new(
        config,
        BlockingPartition::new(flash, DFU.start, DFU.len),
        BlockingFirmwareState::new(
            BlockingPartition::new(flash, STATE.start, STATE.len),
            &mut aligned,
        ),
    );
    let mut frame = [0u8; 300];
    let mut reply = [0u8; MAX_REPLY_LEN + 1];
    loop {
        // A timeout (no master for a while) or a bus error: listen again.
        let Ok(command) = bus.blocking_listen() else {
            continue;
        };
        match command.kind {
            SlaveCommandKind::Write => {
                if let Ok(n) = bus.blocking_respond_to_write(&mut frame) {
                    session.handle_write(&frame[..n.min(frame.len())]);
                }
            }
            SlaveCommandKind::Read => {
                let n = session.take_reply(&mut reply);
                if bus
                    .blocking_respond_to_read(&reply[..n.min(reply.len())])
                    .is_ok()
                {
                    // The flash work the request left (an erase, a buffer's write, the swap
                    // mark), now that its reply has been read: never inside a transaction.
                    session.work();
                    if session.exit() != Exit::Stay {
                        cortex_m::peripheral::SCB::sys_reset();
                    }
                }
            }
        }
    }
}

/// Jumps to the image in ACTIVE.
#[allow(unsafe_code)]
fn start() -> ! {
    // SAFETY: ACTIVE holds an image linked for it (its vector table at its start).
    unsafe { BootLoader { state: State::Boot }.load(FLASH_BASE + ACTIVE.start) }
}

/// A panic (none is expected: the partitions are checked at compile time) starts the image
/// in ACTIVE as it is, the board's best chance of answering the motherboard.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    start()
}
