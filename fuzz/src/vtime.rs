//! Virtual time and a deterministic single-threaded executor for one fuzz case.
//!
//! This module is embassy-time's driver for the fuzz binaries: `Instant::now()` reads the
//! virtual time of the case running on this thread, and a timer registers its waker here. The
//! executor polls every ready task in spawn order until none is ready, then moves time to the
//! earliest timer. Nothing reads the wall clock: the same input gives the same polls.

use std::cell::{Cell, RefCell};
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll, Wake, Waker};

thread_local! {
    static NOW_US: Cell<u64> = const { Cell::new(0) };
    static TIMERS: RefCell<Vec<(u64, Waker)>> = const { RefCell::new(Vec::new()) };
}

/// Virtual time now, in µs.
pub fn now_us() -> u64 {
    NOW_US.with(Cell::get)
}

fn ticks_to_us_ceil(t: u64) -> u64 {
    let hz = embassy_time_driver::TICK_HZ;
    if hz == 1_000_000 {
        t
    } else {
        ((u128::from(t) * 1_000_000).div_ceil(u128::from(hz))) as u64
    }
}

fn us_to_ticks(us: u64) -> u64 {
    let hz = embassy_time_driver::TICK_HZ;
    if hz == 1_000_000 {
        us
    } else {
        (u128::from(us) * u128::from(hz) / 1_000_000) as u64
    }
}

/// Registers `waker` to be woken at `at_us` (one entry per waker, the earliest asked for, as
/// embassy's timer queues keep them).
pub fn wake_at(at_us: u64, waker: &Waker) {
    if at_us <= now_us() {
        waker.wake_by_ref();
        return;
    }
    TIMERS.with(|t| {
        let mut t = t.borrow_mut();
        match t.iter_mut().find(|(_, w)| w.will_wake(waker)) {
            Some(e) => e.0 = e.0.min(at_us),
            None => t.push((at_us, waker.clone())),
        }
    });
}

struct VirtualDriver;

impl embassy_time_driver::Driver for VirtualDriver {
    fn now(&self) -> u64 {
        us_to_ticks(now_us())
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        wake_at(ticks_to_us_ceil(at), waker);
    }
}

embassy_time_driver::time_driver_impl!(static DRIVER: VirtualDriver = VirtualDriver);

/// Sleeps until `at_us` of virtual time.
pub async fn sleep_until(at_us: u64) {
    std::future::poll_fn(|cx| {
        if now_us() >= at_us {
            Poll::Ready(())
        } else {
            wake_at(at_us, cx.waker());
            Poll::Pending
        }
    })
    .await
}

struct Flag(AtomicBool);

impl Wake for Flag {
    fn wake(self: Arc<Self>) {
        self.0.store(true, Ordering::Relaxed);
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.0.store(true, Ordering::Relaxed);
    }
}

struct Task<'a> {
    fut: Pin<Box<dyn Future<Output = ()> + 'a>>,
    flag: Arc<Flag>,
    waker: Waker,
    done: bool,
}

/// Why [`Executor::run`] stopped.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Stop {
    /// `until` returned true.
    Done,
    /// Some task kept waking itself at one instant (µs) without time moving on.
    Livelock(u64),
    /// Nothing can wake any more (no ready task, no timer), at this instant.
    Stalled(u64),
    /// Time would pass the limit.
    Limit(u64),
}

/// The executor of one case. Creating one resets the thread's virtual time to 0.
pub struct Executor<'a> {
    tasks: Vec<Task<'a>>,
}

/// Polls at one instant after which the case counts as a livelock.
pub const MAX_POLLS_PER_INSTANT: u64 = 50_000;

impl<'a> Executor<'a> {
    /// A new executor; virtual time starts at 0.
    pub fn new() -> Self {
        NOW_US.with(|n| n.set(0));
        TIMERS.with(|t| t.borrow_mut().clear());
        Executor { tasks: Vec::new() }
    }

    /// Adds a task (polled in spawn order).
    pub fn spawn(&mut self, fut: impl Future<Output = ()> + 'a) {
        let flag = Arc::new(Flag(AtomicBool::new(true)));
        let waker = Waker::from(flag.clone());
        self.tasks.push(Task {
            fut: Box::pin(fut),
            flag,
            waker,
            done: false,
        });
    }

    /// Runs until `until()` holds after an instant, or time would pass `limit_us`.
    pub fn run(&mut self, limit_us: u64, until: &dyn Fn() -> bool) -> Stop {
        loop {
            let mut polls = 0u64;
            loop {
                let mut progressed = false;
                for task in self.tasks.iter_mut() {
                    if task.done || !task.flag.0.swap(false, Ordering::Relaxed) {
                        continue;
                    }
                    progressed = true;
                    polls += 1;
                    let mut cx = Context::from_waker(&task.waker);
                    if task.fut.as_mut().poll(&mut cx).is_ready() {
                        task.done = true;
                    }
                }
                if !progressed {
                    break;
                }
                if polls > MAX_POLLS_PER_INSTANT {
                    return Stop::Livelock(now_us());
                }
            }
            if until() {
                return Stop::Done;
            }
            let next = TIMERS.with(|t| t.borrow().iter().map(|(at, _)| *at).min());
            let Some(next) = next else {
                return Stop::Stalled(now_us());
            };
            if next > limit_us {
                return Stop::Limit(now_us());
            }
            NOW_US.with(|n| n.set(n.get().max(next)));
            let now = now_us();
            let due: Vec<Waker> = TIMERS.with(|t| {
                let mut t = t.borrow_mut();
                let mut due = Vec::new();
                t.retain(|(at, w)| {
                    if *at <= now {
                        due.push(w.clone());
                        false
                    } else {
                        true
                    }
                });
                due
            });
            for w in due {
                w.wake();
            }
        }
    }
}

impl Default for Executor<'_> {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Executor<'_> {
    fn drop(&mut self) {
        // Drop the tasks (they may touch the timers) before clearing the timers.
        self.tasks.clear();
        TIMERS.with(|t| t.borrow_mut().clear());
    }
}
