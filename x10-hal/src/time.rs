//! A monotonic clock in microseconds: the runtimes' internal seam over time. Robot programs
//! never see it; they use `embassy_time` directly. With the `embassy-time` feature,
//! [`EmbassyClock`] is this clock on embassy-time (on boards, and in the simulator, whose
//! embassy-time driver runs in virtual time).

/// A point in time, in microseconds since the clock started.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Instant(pub u64);

impl Instant {
    /// Microseconds since the clock started.
    pub const fn as_micros(self) -> u64 {
        self.0
    }

    /// This instant plus `us` microseconds (saturating).
    pub const fn plus_us(self, us: u64) -> Instant {
        Instant(self.0.saturating_add(us))
    }

    /// This instant plus `ms` milliseconds (saturating).
    pub const fn plus_ms(self, ms: u64) -> Instant {
        Instant(self.0.saturating_add(ms.saturating_mul(1000)))
    }

    /// Microseconds from `earlier` to `self` (0 if `earlier` is later).
    pub const fn since(self, earlier: Instant) -> u64 {
        self.0.saturating_sub(earlier.0)
    }
}

/// A monotonic clock. On boards: embassy-time. In the simulator: virtual time that advances
/// only when every task is waiting.
#[allow(async_fn_in_trait)]
pub trait Clock {
    /// Now.
    fn now(&self) -> Instant;

    /// Sleeps until `at` (returns at once if it has passed).
    async fn sleep_until(&self, at: Instant);

    /// Sleeps for `us` microseconds.
    async fn sleep_us(&self, us: u64) {
        let at = self.now().plus_us(us);
        self.sleep_until(at).await
    }
}

impl<C: Clock + ?Sized> Clock for &C {
    fn now(&self) -> Instant {
        (**self).now()
    }

    async fn sleep_until(&self, at: Instant) {
        (**self).sleep_until(at).await
    }
}

/// [`Clock`] on embassy-time. Its instants are microseconds since boot; sleeping is an
/// embassy-time timer, so the executor sleeps too.
#[cfg(feature = "embassy-time")]
#[derive(Clone, Copy, Debug, Default)]
pub struct EmbassyClock;

#[cfg(feature = "embassy-time")]
impl Clock for EmbassyClock {
    fn now(&self) -> Instant {
        Instant(embassy_time::Instant::now().as_micros())
    }

    async fn sleep_until(&self, at: Instant) {
        embassy_time::Timer::at(embassy_time::Instant::from_micros(at.as_micros())).await
    }
}
