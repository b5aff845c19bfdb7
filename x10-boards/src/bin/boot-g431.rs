//! The STM32G431 daughterboard's bootloader (issue 25): embassy-boot's A/B swap over the
//! chip's flash, then the jump to the image in ACTIVE (`db-g431`). The layout is
//! `x10_boards::g431_boot`'s; `docs/boards.md` ("Updating the boards") says how it is
//! flashed once and what in it is verified by reading only.
//!
//! At every reset: `prepare_boot` reads STATE. A new image the running one wrote to DFU and
//! marked (`mark_updated`) is swapped into ACTIVE, page by page, with its progress in STATE so
//! that a power cut during the swap resumes it; an image that was swapped in but never
//! confirmed (`mark_booted`) is swapped back (the rollback). Then the jump.
//!
//! The HAL is not started (no clock change, no time driver, no interrupt): the flash driver
//! works on the reset clock (HSI16, zero wait states), and the image starts from the chip's
//! reset state but for VTOR and the stack pointer.
#![no_std]
#![no_main]

use core::cell::RefCell;

use cortex_m_rt::entry;
use defmt_rtt as _;
use embassy_boot_stm32::{BootLoader, BootLoaderConfig, State};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_stm32::flash::{Blocking, Flash};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use x10_boards::g431_boot::{ACTIVE, DFU, FLASH_BASE, PAGE, STATE};

/// embassy-boot's swap buffer: one erase page.
const BUFFER: usize = PAGE as usize;

#[entry]
fn main() -> ! {
    // SAFETY: the only user of the flash controller in this image.
    #[allow(unsafe_code)]
    let flash = unsafe { embassy_stm32::peripherals::FLASH::steal() };
    let flash: Mutex<NoopRawMutex, RefCell<Flash<'_, Blocking>>> =
        Mutex::new(RefCell::new(Flash::new_blocking(flash)));
    let config = BootLoaderConfig {
        active: BlockingPartition::new(&flash, ACTIVE.start, ACTIVE.len),
        dfu: BlockingPartition::new(&flash, DFU.start, DFU.len),
        state: BlockingPartition::new(&flash, STATE.start, STATE.len),
    };
    // A flash error while swapping leaves STATE saying so: the next reset resumes. The image
    // in ACTIVE is started either way (a swap cut short is resumed before any jump).
    let loader = BootLoader::try_prepare::<_, _, _, BUFFER>(config)
        .unwrap_or(BootLoader { state: State::Boot });
    start(loader)
}

/// Jumps to the image in ACTIVE.
#[allow(unsafe_code)]
fn start(loader: BootLoader) -> ! {
    // SAFETY: ACTIVE holds an image linked for it (its vector table at its start).
    unsafe { loader.load(FLASH_BASE + ACTIVE.start) }
}

/// A panic (none is expected: the partitions are checked at compile time) starts the image
/// in ACTIVE as it is, the board's best chance of answering the motherboard.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    start(BootLoader { state: State::Boot })
}
