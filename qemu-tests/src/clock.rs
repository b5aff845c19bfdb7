//! [`x10_hal::time::Clock`] on SysTick: a 1 ms interrupt counts milliseconds, the counter
//! gives the microseconds in between. Sleeping yields until the time has come (the suites'
//! executor polls in a loop). QEMU's SysTick runs at the machine's CPU clock; with
//! `-icount shift=0` virtual time advances 1 ns per instruction, so runs are repeatable.
//!
//! The same clock is embassy-time's driver ([`QemuTimeDriver`], 1 MHz ticks: a tick is one
//! µs of [`QemuClock::now`]), which the motherboard runtime reads and sleeps on.

use core::sync::atomic::{AtomicU32, Ordering};
use core::task::Waker;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use cortex_m_rt::exception;
use x10_hal::time::{Clock, Instant};

/// CPU clock of the QEMU machine: the micro:bit's nRF51 runs at 16 MHz.
#[cfg(qemu_microbit)]
pub const CORE_HZ: u32 = 16_000_000;
/// CPU clock of the QEMU machine: the MPS2 FPGA images run at 25 MHz.
#[cfg(not(qemu_microbit))]
pub const CORE_HZ: u32 = 25_000_000;

/// SysTick ticks per millisecond (its reload value + 1).
pub const TICKS_PER_MS: u32 = CORE_HZ / 1_000;

/// Milliseconds: one per SysTick exception (one per reload of the counter).
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
            while SYST::get_current() == 0 {}
        }
        QemuClock
    }
}

/// The milliseconds since [`QemuClock::start`] and the SysTick ticks into the current one
/// (`0..CORE_HZ / 1000`), read consistently.
///
/// Near a reload QEMU's SysTick is not a chip's: the counter shows the reload late (it reads
/// 0, then jumps to some ticks below the reload value), and the exception that counts the
/// millisecond may run while it still reads 0; on any target the exception waits while
/// interrupts are masked. So a reading of 0 is taken again (0 lasts one tick on a chip, a few
/// instructions here), and a pending SysTick with the counter in the first half of its period
/// counts as the millisecond it is about to add. Without both, a reading near a millisecond
/// boundary could be a millisecond ahead or behind, and the clock went back (embassy-time's
/// timers then ran out up to a millisecond early). Assumes interrupts are never masked for
/// half a millisecond.
pub fn ms_and_ticks() -> (u64, u32) {
    loop {
        let ms = MS.load(Ordering::Relaxed);
        let left = SYST::get_current();
        // After the counter: if it reloads in between, `left` is the old period's end.
        let pending = SCB::is_pendst_pending();
        if left != 0 && MS.load(Ordering::Relaxed) == ms {
            let reloaded = pending && left >= TICKS_PER_MS / 2;
            let ticks = TICKS_PER_MS - 1 - left.min(TICKS_PER_MS - 1);
            return (u64::from(ms) + u64::from(reloaded), ticks);
        }
    }
}

impl Clock for QemuClock {
    /// Monotonic (see [`ms_and_ticks`]).
    fn now(&self) -> Instant {
        let (ms, ticks) = ms_and_ticks();
        Instant(ms * 1_000 + u64::from(ticks / (CORE_HZ / 1_000_000)))
    }

    async fn sleep_until(&self, at: Instant) {
        while self.now() < at {
            embassy_futures::yield_now().await;
        }
    }
}

/// embassy-time's driver on [`QemuClock`]: `now` is [`QemuClock::now`] in µs, which are
/// embassy-time's ticks (`embassy-time-driver` at its default 1 MHz: no `tick-hz-*` feature
/// is enabled in this build).
///
/// No timer queue: [`QemuTimeDriver::schedule_wake`] wakes the waker at once. The suites'
/// executor is `embassy_futures::block_on`, which polls its future in a busy loop and ignores
/// the waker (its wake is a no-op), and `select`/`join` poll every unfinished branch on every
/// poll, so a task sleeping on an `embassy_time::Timer` is polled again at once anyway and
/// sees the time when it comes. Waking at once keeps that true under an executor that does
/// honour wakers (the task is polled again right away, a busy wait rather than a missed
/// deadline); storing the waker would need a queue and an alarm on SysTick for no gain here.
#[derive(Clone, Copy, Debug, Default)]
pub struct QemuTimeDriver;

impl embassy_time_driver::Driver for QemuTimeDriver {
    fn now(&self) -> u64 {
        QemuClock.now().0
    }

    fn schedule_wake(&self, _at: u64, waker: &Waker) {
        waker.wake_by_ref();
    }
}

// A tick must be a µs of `QemuClock::now`.
const _: () = assert!(embassy_time_driver::TICK_HZ == 1_000_000);

embassy_time_driver::time_driver_impl!(static DRIVER: QemuTimeDriver = QemuTimeDriver);
