//! The hardware watchdog, the crash paths and the reset reason of every image (DB and MB), on
//! both chips: the chip part (`watchdog/rp2040.rs`, `watchdog/stm32.rs`) reads and writes the
//! registers, the decisions are [`crate::crash`]'s (host-tested). `docs/boards.md` ("After a
//! crash, a hang, a glitch, a power cut") says what each claim rests on.
//!
//! * [`start`] starts the watchdog with a [`WATCHDOG_MS`] timeout; [`keep_fed`], raced
//!   against the runtime in the runtime's own task, feeds it every [`FEED_MS`] from the
//!   executor. An executor that stops polling (a task that never yields, an interrupt handler
//!   that never returns) stops feeding it, and the chip resets.
//! * [`crashed`] (the panic handlers, before they log and stop the core with `udf`) and the
//!   HardFault handler put every actuator pin in its safe state through raw registers and
//!   record why (panic, fault) where the reset keeps it; the HardFault handler then resets the
//!   chip ([`reset`]).
//! * [`reset_reason`], read once at boot, says why the chip reset and clears what it read.
//!
//! With the `motherboard` feature this module also brings the image's `#[panic_handler]`
//! (the daughterboard image has its own, in `db_image.rs`).

use embassy_time::Timer;

pub use crate::crash::{Crash, FEED_MS, WATCHDOG_MS};

#[cfg_attr(feature = "rp2040", path = "watchdog/rp2040.rs")]
#[cfg_attr(not(feature = "rp2040"), path = "watchdog/stm32.rs")]
mod chip;

pub use chip::{feed, reset, reset_reason, safe_outputs, start};

/// Feeds the watchdog every [`FEED_MS`], for ever: race it against the runtime in one task
/// (`embassy_futures::select`), so that the watchdog is fed only while the executor polls.
pub async fn keep_fed() -> ! {
    loop {
        feed();
        Timer::after_millis(FEED_MS).await;
    }
}

/// What a panic handler does first: every actuator pin in its safe state, the crash recorded
/// for [`reset_reason`] after the reset. (Interrupts may go on: no interrupt handler of the
/// images drives an output, and the executor that would is the one stuck in the panic.)
pub fn crashed(crash: Crash) {
    safe_outputs();
    chip::record(crate::crash::marker(crash));
}

/// [`crashed`] for a panic, then `udf`: the daughterboard image's panic handlers.
pub fn panicked() -> ! {
    crashed(Crash::Panic);
    cortex_m::asm::udf()
}

/// The HardFault handler: every actuator pin in its safe state, the crash recorded (a panic's
/// record stays: the panic handlers end here through `udf`), then the chip reset. Without a
/// trampoline (no exception frame is read): the smallest handler.
#[cfg(any(feature = "daughterboard", feature = "motherboard"))]
#[allow(unsafe_code)]
#[cortex_m_rt::exception(trampoline = false)]
unsafe fn HardFault() -> ! {
    safe_outputs();
    chip::record(crate::crash::after_fault(chip::recorded()));
    reset()
}

/// The motherboard images' panic handler: outputs safe and the panic recorded first, then the
/// panic's message logged, then `udf`: a HardFault, which `probe-rs run` turns into a
/// backtrace (every frame's file and line) and which otherwise resets the chip. The message
/// only, not the location (panic-probe printed both): the backtrace has it, and without it
/// link-time optimisation drops every panic site's file path.
#[cfg(feature = "motherboard")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    crashed(Crash::Panic);
    match info.message().as_str() {
        Some(m) => defmt::error!("panic: {=str}", m),
        None => defmt::error!("panic (formatted message not kept: see the backtrace)"),
    }
    cortex_m::asm::udf()
}
