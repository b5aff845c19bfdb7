//! The Pico's bootloader (issue 25): boot2, then this image at 0x10000100, embassy-boot's
//! STATE sector, the ACTIVE slot (db-pico built with the feature `active-slot`) and the DFU
//! slot (`x10_boards::rp_flash::layout`). At every reset it runs embassy-boot's
//! `prepare_boot` over our flash driver (`pico::PicoFlash`): an update marked in STATE is
//! swapped into ACTIVE (the old image kept in DFU), and an update that was swapped in but never
//! confirmed by the new image (`mark_booted`) is swapped back. Then it starts the watchdog
//! (`watchdog::start`, 200 ms) and jumps to ACTIVE: a new image that hangs before it feeds the
//! watchdog resets the chip, and, not confirmed, is rolled back.
#![no_std]
#![no_main]

use core::cell::RefCell;

use defmt_rtt as _;
use embassy_boot::{BootLoader, BootLoaderConfig};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use x10_boards::pico::PicoFlash;
use x10_boards::rp_flash::{layout, XIP_BASE};
use x10_boards::watchdog;

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

#[cortex_m_rt::entry]
fn main() -> ! {
    let p = embassy_rp::init(Default::default());
    let flash = Mutex::<NoopRawMutex, _>::new(RefCell::new(PicoFlash::new(p.FLASH)));
    let mut boot = BootLoader::new(BootLoaderConfig {
        active: BlockingPartition::new(&flash, layout::ACTIVE, layout::ACTIVE_LEN),
        dfu: BlockingPartition::new(&flash, layout::DFU, layout::DFU_LEN),
        state: BlockingPartition::new(&flash, layout::STATE, layout::STATE_LEN),
    });
    // The swap copies a sector in pieces of this buffer (it divides the 4 KiB sector).
    let mut buf = [0u8; 256];
    // A flash error leaves the slots as they were: boot what ACTIVE holds.
    let _ = boot.prepare_boot(&mut buf);
    watchdog::start();
    // SAFETY: ACTIVE holds an image linked there (its vector table first); nothing of this
    // image is used after the jump.
    #[allow(unsafe_code)]
    unsafe {
        jump(XIP_BASE + layout::ACTIVE)
    }
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
