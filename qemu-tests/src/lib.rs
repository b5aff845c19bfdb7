//! # x10-qemu-tests: the portable X10 cores on real Cortex-M instruction sets
//!
//! Support for the suites in `tests/` (defmt-test, one binary per suite): a clock on SysTick
//! (also embassy-time's driver, which the motherboard runtime uses), a recording fake
//! [`firmware_db::Ports`], and a two-node loopback bus. Each suite runs under QEMU
//! (`run.sh`): `microbit` (Cortex-M0, thumbv6m) and `mps2-an386` (Cortex-M4, thumbv7em).
//! Logs go out over semihosting as defmt frames (decoded by `defmt-print`); a failed test, a
//! panic or a HardFault ends QEMU with a non-zero exit code.
#![no_std]

pub mod clock;
pub mod ports;
pub mod stack;
pub mod wire;

use core::future::Future;

use cortex_m_rt::{exception, ExceptionFrame};
use defmt_semihosting as _;

pub use clock::{QemuClock, QemuTimeDriver};
pub use ports::{FakePorts, PortOp};
pub use wire::{End, Wire};

/// Runs a future to completion (the suites' executor: a poll loop that ignores wakers; the
/// clock moves on its own, driven by SysTick, and a future waiting on it or on an
/// `embassy_time::Timer` is simply polled again).
pub fn block_on<F: Future>(f: F) -> F::Output {
    embassy_futures::block_on(f)
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    defmt::error!("HardFault at pc {=u32:#x}", frame.pc());
    semihosting::process::exit(2)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    semihosting::process::exit(1)
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    semihosting::process::exit(1)
}
