//! [`Clock`] on embassy-time: the clock of every board image (and of the QEMU suites).

use x10_hal::time::{Clock, Instant};

/// The embassy-time clock. Its instants are microseconds since boot; sleeping is an
/// embassy-time timer, so the executor sleeps too.
#[derive(Clone, Copy, Debug, Default)]
pub struct EmbassyClock;

impl Clock for EmbassyClock {
    fn now(&self) -> Instant {
        Instant(embassy_time::Instant::now().as_micros())
    }

    async fn sleep_until(&self, at: Instant) {
        embassy_time::Timer::at(embassy_time::Instant::from_micros(at.as_micros())).await
    }
}
