//! [`x10_hal::time::Clock`] on SysTick: a 1 ms interrupt counts milliseconds, the counter
//! gives the microseconds in between. Sleeping yields until the time has come (the suites'
//! executor polls in a loop). QEMU's SysTick runs at the machine's CPU clock; with
//! `-icount shift=0` virtual time advances 1 ns per instruction, so runs are repeatable.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;
use x10_hal::time::{Clock, Instant};

/// CPU clock of the QEMU machine: the micro:bit's nRF51 runs at 16 MHz.
#[cfg(qemu_microbit)]
pub const CORE_HZ: u32 = 16_000_000;
/// CPU clock of the QEMU machine: the MPS2 FPGA images run at 25 MHz.
#[cfg(not(qemu_microbit))]
pub const CORE_HZ: u32 = 25_000_000;

const TICKS_PER_MS: u32 = CORE_HZ / 1_000;

static MS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    // The only writer: a load and a store (thumbv6m has no atomic add).
    MS.store(
        MS.load(Ordering::Relaxed).wrapping_add(1),
        Ordering::Relaxed,
    );
}

/// The SysTick clock; [`QemuClock::start`] it once per suite.
#[derive(Clone, Copy, Debug, Default)]
pub struct QemuClock;

impl QemuClock {
    /// Starts SysTick (a second call does nothing).
    pub fn start() -> QemuClock {
        if let Some(mut p) = cortex_m::Peripherals::take() {
            p.SYST.set_clock_source(SystClkSource::Core);
            p.SYST.set_reload(TICKS_PER_MS - 1);
            p.SYST.clear_current();
            p.SYST.enable_interrupt();
            p.SYST.enable_counter();
            // SysTick's current value reads 0 until the counter first reloads: wait for that,
            // or the first `now()` would read as (almost) a whole millisecond and the clock
            // would go backwards once.
            while cortex_m::peripheral::SYST::get_current() == 0 {}
        }
        QemuClock
    }
}

impl Clock for QemuClock {
    fn now(&self) -> Instant {
        loop {
            let ms = MS.load(Ordering::Relaxed);
            let left = cortex_m::peripheral::SYST::get_current();
            if MS.load(Ordering::Relaxed) == ms {
                let us = (TICKS_PER_MS - 1 - left.min(TICKS_PER_MS - 1)) / (CORE_HZ / 1_000_000);
                return Instant(u64::from(ms) * 1_000 + u64::from(us));
            }
        }
    }

    async fn sleep_until(&self, at: Instant) {
        while self.now() < at {
            embassy_futures::yield_now().await;
        }
    }
}
