//! [`DelayNs`] over the project's own clock.

use embedded_hal_async::delay::DelayNs;
use x10_hal::time::Clock;

/// Adapts an [`x10_hal::time::Clock`] (the motherboard runtime's clock, or the simulator's
/// virtual time) to [`embedded_hal_async::delay::DelayNs`], the delay trait drivers take.
///
/// Drivers take `DelayNs` because it is the ecosystem's standard (`embassy_time::Delay`
/// implements it, as do most HALs and mocks), so they work outside X10 too; this adapter lets
/// the X10 runtimes and the simulator pass their clock. Nanoseconds are rounded up to whole
/// microseconds, the clock's resolution, so a delay is never shorter than asked.
#[derive(Clone, Copy, Debug)]
pub struct ClockDelay<C> {
    clock: C,
}

impl<C: Clock> ClockDelay<C> {
    /// Delays on `clock`.
    pub const fn new(clock: C) -> Self {
        ClockDelay { clock }
    }

    /// The clock.
    pub fn clock(&self) -> &C {
        &self.clock
    }
}

impl<C: Clock> DelayNs for ClockDelay<C> {
    async fn delay_ns(&mut self, ns: u32) {
        self.clock.sleep_us(u64::from(ns.div_ceil(1000))).await
    }

    async fn delay_us(&mut self, us: u32) {
        self.clock.sleep_us(u64::from(us)).await
    }

    async fn delay_ms(&mut self, ms: u32) {
        self.clock.sleep_us(u64::from(ms) * 1000).await
    }
}
