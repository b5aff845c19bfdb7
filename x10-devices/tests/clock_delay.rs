//! `ClockDelay`: `DelayNs` over an `x10_hal::time::Clock`, on a virtual clock.

use core::cell::{Cell, RefCell};

use embassy_futures::block_on;
use embedded_hal_async::delay::DelayNs;
use x10_devices::ClockDelay;
use x10_hal::time::{Clock, Instant};

#[derive(Default)]
struct VirtualClock {
    now: Cell<u64>,
    sleeps: RefCell<Vec<u64>>,
}

impl Clock for VirtualClock {
    fn now(&self) -> Instant {
        Instant(self.now.get())
    }

    async fn sleep_until(&self, at: Instant) {
        self.sleeps.borrow_mut().push(at.0);
        self.now.set(self.now.get().max(at.0));
    }
}

#[test]
fn delays_advance_the_clock_by_at_least_the_time_asked() {
    let clock = VirtualClock::default();
    clock.now.set(5);
    let mut d = ClockDelay::new(&clock);
    block_on(async {
        d.delay_ms(20).await; // 20 000 µs
        d.delay_us(7).await;
        d.delay_ns(1).await; // rounds up to 1 µs
        d.delay_ns(2_000).await;
        d.delay_ns(0).await;
        d.delay_ms(u32::MAX).await; // no overflow: 4 294 967 295 000 µs
    });
    assert_eq!(
        *clock.sleeps.borrow(),
        vec![
            20_005,
            20_012,
            20_013,
            20_015,
            20_015,
            20_015 + 4_294_967_295_000
        ]
    );
    assert_eq!(d.clock().now(), Instant(20_015 + 4_294_967_295_000));
}
