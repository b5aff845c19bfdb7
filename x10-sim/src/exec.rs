//! A deterministic, single-threaded executor with virtual time.
//!
//! Any number of `!Send` futures (MB tasks, DB tasks, robot programs, the bus engine) run on
//! one thread. The executor polls every ready task in spawn order until none is ready, then
//! moves virtual time to the earliest sleeper's deadline and wakes every sleeper due by then.
//! Nothing reads the wall clock and nothing sleeps: a simulated minute takes as long as the
//! work done in it, and the same inputs give the same order of polls, byte for byte.
//!
//! Time is kept in nanoseconds so that bus bit times at 1 MHz (and the I2C spec's sub-µs setup
//! and hold times) are exact; [`SimClock`] exposes it to the runtimes as the microsecond
//! [`x10_hal::time::Clock`].
//!
//! ## embassy-time in virtual time
//! This module is also embassy-time's driver (`embassy-time-driver`, 1 MHz ticks) for any
//! program linked with the simulator: `embassy_time::Instant::now()` reads, and
//! `Timer::after` sleeps in, the virtual time of the simulation running on the calling
//! thread. A running [`Executor`] makes its clock the thread's current one, so simulations on
//! different threads (`cargo test` runs tests in parallel) are isolated from each other, and
//! robot programs, the motherboard runtime and the daughterboards all see one virtual time.
//! Outside a run, `Instant::now()` reads the clock of the last executor created or run on the
//! thread (0 before any).

use std::cell::{Cell, RefCell};
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::future::Future;
use std::pin::Pin;
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};

use x10_hal::time::{Clock, Instant};

/// Nanoseconds of virtual time.
pub type Nanos = u64;

/// How many polls one virtual instant may take before the executor reports a livelock (tasks
/// that wake each other forever while no timer is left to move time on).
pub const MAX_POLLS_PER_INSTANT: u64 = 2_000_000;

/// Polls after which an instant counts as *spinning*: tasks keep waking each other (as
/// embassy-sync's single-waker `Channel` senders do when several wait on a full channel).
/// On a chip that is a busy loop while time passes, so the executor moves time on to the next
/// timer with the spinning tasks still ready, and counts it in [`RunStats::spins`].
pub const SPIN_POLLS: u64 = 2_000;

/// A sleeper's timer: its deadline, its sequence number (timers due at one instant wake in the
/// order they were made) and its slot in [`TimeState::slots`].
type TimerKey = (Nanos, u64, usize);

/// The waker of one timer, or none once the timer was cancelled; `seq` tells whose it is (a
/// slot is reused once its timer has left the heap).
struct Slot {
    seq: u64,
    waker: Option<Waker>,
}

#[derive(Default)]
struct TimeState {
    now: Nanos,
    /// The sleepers' deadlines, earliest first (a binary heap: no allocation per timer once
    /// it has grown). A cancelled timer stays in the heap until it comes first, then is
    /// dropped without waking anything.
    timers: BinaryHeap<Reverse<TimerKey>>,
    /// The wakers, by slot; `free` lists the slots no timer in the heap uses.
    slots: Vec<Slot>,
    free: Vec<usize>,
    next_timer: u64,
    /// embassy-time's wake-ups: one entry per waker (the earliest asked for), as embassy's
    /// own timer queues keep them. A task whose timer was dropped is woken once more for
    /// nothing, which a future must tolerate anyway.
    embassy: Vec<(Nanos, Waker)>,
}

impl TimeState {
    /// A timer waking `waker` at `at`; its key.
    fn add_timer(&mut self, at: Nanos, waker: Waker) -> TimerKey {
        let seq = self.next_timer;
        self.next_timer += 1;
        let slot = match self.free.pop() {
            Some(i) => {
                if let Some(s) = self.slots.get_mut(i) {
                    *s = Slot {
                        seq,
                        waker: Some(waker),
                    };
                }
                i
            }
            None => {
                self.slots.push(Slot {
                    seq,
                    waker: Some(waker),
                });
                self.slots.len() - 1
            }
        };
        let key = (at, seq, slot);
        self.timers.push(Reverse(key));
        key
    }

    /// The waker slot of the live timer `key` (none once it has fired).
    fn timer_slot(&mut self, key: TimerKey) -> Option<&mut Option<Waker>> {
        self.slots
            .get_mut(key.2)
            .filter(|s| s.seq == key.1 && s.waker.is_some())
            .map(|s| &mut s.waker)
    }

    /// Cancels the timer `key` (nothing if it has fired).
    fn cancel_timer(&mut self, key: TimerKey) {
        if let Some(w) = self.timer_slot(key) {
            *w = None;
        }
    }

    /// Drops the cancelled timers at the head of the heap, so that the head is a live one.
    fn skip_cancelled(&mut self) {
        while let Some(&Reverse((_, seq, slot))) = self.timers.peek() {
            let live = self
                .slots
                .get(slot)
                .is_some_and(|s| s.seq == seq && s.waker.is_some());
            if live {
                return;
            }
            self.timers.pop();
            self.free.push(slot);
        }
    }

    /// The earliest deadline of any sleeper.
    fn next_deadline(&mut self) -> Option<Nanos> {
        self.skip_cancelled();
        let sleep = self.timers.peek().map(|&Reverse((at, _, _))| at);
        let embassy = self.embassy.iter().map(|&(at, _)| at).min();
        match (sleep, embassy) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Moves every waker due by `now` into `due`: sleepers in deadline order, then
    /// embassy-time's in the order they were scheduled.
    fn take_due(&mut self, now: Nanos, due: &mut Vec<Waker>) {
        while let Some(&Reverse((at, seq, slot))) = self.timers.peek() {
            if at > now {
                break;
            }
            self.timers.pop();
            if let Some(s) = self.slots.get_mut(slot).filter(|s| s.seq == seq) {
                if let Some(w) = s.waker.take() {
                    due.push(w);
                }
            }
            self.free.push(slot);
        }
        if self.embassy.iter().any(|&(at, _)| at <= now) {
            let mut keep = Vec::with_capacity(self.embassy.len());
            for (at, w) in self.embassy.drain(..) {
                if at <= now {
                    due.push(w);
                } else {
                    keep.push((at, w));
                }
            }
            self.embassy = keep;
        }
    }

    fn schedule_embassy(&mut self, at: Nanos, waker: &Waker) {
        if at <= self.now {
            waker.wake_by_ref();
            return;
        }
        match self.embassy.iter_mut().find(|(_, w)| w.will_wake(waker)) {
            Some(entry) => entry.0 = entry.0.min(at),
            None => self.embassy.push((at, waker.clone())),
        }
    }
}

thread_local! {
    /// The virtual time embassy-time reads on this thread (see the module docs).
    static CURRENT_TIME: RefCell<Option<Rc<TimeCore>>> = const { RefCell::new(None) };
    /// The name of the task being polled on this thread.
    static CURRENT_TASK: RefCell<Option<Rc<str>>> = const { RefCell::new(None) };
}

fn set_current_time(core: Option<Rc<TimeCore>>) -> Option<Rc<TimeCore>> {
    CURRENT_TIME.with(|c| std::mem::replace(&mut *c.borrow_mut(), core))
}

/// The name of the task the executor is polling on this thread (`None` outside a poll).
pub fn current_task() -> Option<Rc<str>> {
    CURRENT_TASK.with(|c| c.borrow().clone())
}

/// embassy-time's driver: the virtual time of the simulation running on this thread.
struct VirtualTimeDriver;

impl embassy_time_driver::Driver for VirtualTimeDriver {
    fn now(&self) -> u64 {
        CURRENT_TIME.with(|c| {
            c.borrow()
                .as_ref()
                .map_or(0, |core| core.now() / NANOS_PER_TICK)
        })
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        let handled = CURRENT_TIME.with(|c| match c.borrow().as_ref() {
            Some(core) => {
                let at_ns = at.saturating_mul(NANOS_PER_TICK);
                match core.state.try_borrow_mut() {
                    Ok(mut st) => st.schedule_embassy(at_ns, waker),
                    // Only while the executor itself holds the state: never from a task.
                    Err(_) => waker.wake_by_ref(),
                }
                true
            }
            None => false,
        });
        if !handled {
            // No simulation on this thread: wake at once rather than never.
            waker.wake_by_ref();
        }
    }
}

embassy_time_driver::time_driver_impl!(static DRIVER: VirtualTimeDriver = VirtualTimeDriver);

/// Nanoseconds per embassy-time tick.
const NANOS_PER_TICK: u64 = 1_000_000_000 / embassy_time_driver::TICK_HZ;

/// Virtual time and the sleepers' queue, shared by the executor and every [`SimClock`].
#[derive(Default)]
struct TimeCore {
    state: RefCell<TimeState>,
}

impl TimeCore {
    fn now(&self) -> Nanos {
        self.state.borrow().now
    }
}

/// The clock of one simulation: virtual time that advances only when every task waits.
///
/// Cloning is cheap; every clone reads the same time.
#[derive(Clone)]
pub struct SimClock {
    core: Rc<TimeCore>,
}

impl Default for SimClock {
    fn default() -> Self {
        Self::new()
    }
}

impl SimClock {
    /// A clock at virtual time 0. Give it to [`Executor::with_clock`] to run tasks on it.
    pub fn new() -> SimClock {
        SimClock {
            core: Rc::new(TimeCore::default()),
        }
    }

    /// Now, in nanoseconds.
    pub fn now_ns(&self) -> Nanos {
        self.core.now()
    }

    /// Sleeps until `at` nanoseconds (returns at once if that has passed).
    pub fn sleep_until_ns(&self, at: Nanos) -> Sleep {
        Sleep {
            core: self.core.clone(),
            at,
            key: None,
        }
    }

    /// Wakes `waker` at `at` nanoseconds (at once if that has passed): a timer that nothing
    /// cancels. The simulated bus hands a result that a task would only sleep on until `at`
    /// this way, so the task is polled once, at `at`, instead of once now to start its sleep
    /// and once at `at`.
    pub fn wake_at(&self, at: Nanos, waker: Waker) {
        let mut st = self.core.state.borrow_mut();
        if at <= st.now {
            drop(st);
            waker.wake();
            return;
        }
        st.add_timer(at, waker);
    }

    /// Sleeps for `ns` nanoseconds.
    pub fn sleep_ns(&self, ns: Nanos) -> Sleep {
        self.sleep_until_ns(self.now_ns().saturating_add(ns))
    }
}

impl Clock for SimClock {
    fn now(&self) -> Instant {
        Instant(self.now_ns() / 1_000)
    }

    async fn sleep_until(&self, at: Instant) {
        self.sleep_until_ns(at.0.saturating_mul(1_000)).await
    }
}

/// The future of [`SimClock::sleep_until_ns`]. Dropping it removes its timer.
pub struct Sleep {
    core: Rc<TimeCore>,
    at: Nanos,
    key: Option<TimerKey>,
}

impl Future for Sleep {
    type Output = ();

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let this = &mut *self;
        let mut st = this.core.state.borrow_mut();
        if st.now >= this.at {
            if let Some(key) = this.key.take() {
                st.cancel_timer(key);
            }
            return Poll::Ready(());
        }
        if let Some(key) = this.key {
            if let Some(w) = st.timer_slot(key) {
                if !w.as_ref().is_some_and(|w| w.will_wake(cx.waker())) {
                    *w = Some(cx.waker().clone());
                }
                return Poll::Pending;
            }
        }
        // First poll, or polled again after its timer fired early (never: it fires at `at`).
        this.key = Some(st.add_timer(this.at, cx.waker().clone()));
        Poll::Pending
    }
}

impl Drop for Sleep {
    fn drop(&mut self) {
        if let Some(key) = self.key.take() {
            if let Ok(mut st) = self.core.state.try_borrow_mut() {
                st.cancel_timer(key);
            }
        }
    }
}

/// The tasks woken since they were last polled, one bit per task (by index): the executor
/// finds the next woken task without looking at every task, so a simulation of many boards
/// (each a task, most of them idle at any instant) costs what its woken tasks cost. The first
/// [`FAST_TASKS`] tasks have atomic bits (a wake is one `fetch_or`); any task past them, a
/// bit behind a lock.
struct WakeSet {
    fast: Box<[AtomicU64]>,
    slow: Mutex<Vec<u64>>,
}

/// Tasks whose wakes take no lock ([`WakeSet`]).
pub const FAST_TASKS: usize = 4096;

impl Default for WakeSet {
    fn default() -> Self {
        WakeSet {
            fast: (0..FAST_TASKS / 64).map(|_| AtomicU64::new(0)).collect(),
            slow: Mutex::new(Vec::new()),
        }
    }
}

impl WakeSet {
    fn mark(&self, index: usize) {
        let bit = 1u64 << (index % 64);
        if let Some(word) = self.fast.get(index / 64) {
            word.fetch_or(bit, Ordering::Relaxed);
            return;
        }
        if let Ok(mut words) = self.slow.lock() {
            let w = (index - FAST_TASKS) / 64;
            if words.len() <= w {
                words.resize(w + 1, 0);
            }
            if let Some(word) = words.get_mut(w) {
                *word |= bit;
            }
        }
    }

    fn is_marked(&self, index: usize) -> bool {
        let bit = 1u64 << (index % 64);
        match self.fast.get(index / 64) {
            Some(word) => word.load(Ordering::Relaxed) & bit != 0,
            None => self.slow.lock().is_ok_and(|words| {
                words
                    .get((index - FAST_TASKS) / 64)
                    .is_some_and(|w| w & bit != 0)
            }),
        }
    }

    /// Clears and returns the lowest marked index at or above `from`, below `tasks`.
    fn take_next(&self, from: usize, tasks: usize) -> Option<usize> {
        let first = from / 64;
        let fast_words = tasks.min(FAST_TASKS).div_ceil(64);
        for w in first..fast_words {
            let Some(word) = self.fast.get(w) else { break };
            let mask = if w == first {
                u64::MAX << (from % 64)
            } else {
                u64::MAX
            };
            let hits = word.load(Ordering::Relaxed) & mask;
            if hits != 0 {
                let bit = hits.trailing_zeros() as usize;
                word.fetch_and(!(1u64 << bit), Ordering::Relaxed);
                return Some(w * 64 + bit);
            }
        }
        if tasks <= FAST_TASKS {
            return None;
        }
        let from = from.max(FAST_TASKS) - FAST_TASKS;
        let mut words = self.slow.lock().ok()?;
        let first = from / 64;
        for (w, word) in words.iter_mut().enumerate().skip(first) {
            let mask = if w == first {
                u64::MAX << (from % 64)
            } else {
                u64::MAX
            };
            let hits = *word & mask;
            if hits != 0 {
                let bit = hits.trailing_zeros() as usize;
                *word &= !(1u64 << bit);
                return Some(FAST_TASKS + w * 64 + bit);
            }
        }
        None
    }
}

struct TaskFlag {
    set: Arc<WakeSet>,
    index: usize,
}

impl Wake for TaskFlag {
    fn wake(self: Arc<Self>) {
        self.set.mark(self.index);
    }

    fn wake_by_ref(self: &Arc<Self>) {
        self.set.mark(self.index);
    }
}

type BoxFuture<'a> = Pin<Box<dyn Future<Output = ()> + 'a>>;

struct Task<'a> {
    name: Rc<str>,
    future: BoxFuture<'a>,
    waker: Waker,
}

/// Identifies a spawned task.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TaskId(pub usize);

/// Spawns tasks into a running [`Executor`] (from inside other tasks).
#[derive(Clone)]
pub struct Spawner<'a> {
    queue: Rc<RefCell<Vec<(String, BoxFuture<'a>)>>>,
}

impl<'a> Spawner<'a> {
    /// Queues `future` as a new task; it is first polled in the same virtual instant.
    pub fn spawn(&self, name: impl Into<String>, future: impl Future<Output = ()> + 'a) {
        self.queue
            .borrow_mut()
            .push((name.into(), Box::pin(future)));
    }
}

/// Why [`Executor::run_until_ns`] stopped early.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunError {
    /// Some task kept waking itself at one instant without ever sleeping.
    Livelock {
        /// The instant, in ns.
        at: Nanos,
        /// The tasks that were still being woken.
        tasks: Vec<String>,
    },
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Livelock { at, tasks } => write!(
                f,
                "livelock at t = {at} ns: tasks {tasks:?} never stop waking themselves"
            ),
        }
    }
}

impl std::error::Error for RunError {}

/// What a run did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunStats {
    /// Virtual time at the end, in ns.
    pub end_ns: Nanos,
    /// Task polls in all.
    pub polls: u64,
    /// Tasks that ran to completion.
    pub finished: usize,
    /// Tasks still alive.
    pub alive: usize,
    /// Instants left while tasks were still spinning (see [`SPIN_POLLS`]).
    pub spins: u64,
}

/// The deterministic executor. `'a` lets tasks borrow anything that outlives the executor.
pub struct Executor<'a> {
    time: Rc<TimeCore>,
    tasks: Vec<Option<Task<'a>>>,
    woken: Arc<WakeSet>,
    spawn_queue: Rc<RefCell<Vec<(String, BoxFuture<'a>)>>>,
    polls: Cell<u64>,
    finished: usize,
    spins: u64,
}

impl Default for Executor<'_> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'a> Executor<'a> {
    /// An executor at virtual time 0 with no tasks, on a clock of its own.
    pub fn new() -> Self {
        Self::with_clock(&SimClock::new())
    }

    /// An executor with no tasks on `clock` (made before the things the tasks borrow).
    pub fn with_clock(clock: &SimClock) -> Self {
        set_current_time(Some(clock.core.clone()));
        Executor {
            time: clock.core.clone(),
            tasks: Vec::new(),
            woken: Arc::new(WakeSet::default()),
            spawn_queue: Rc::new(RefCell::new(Vec::new())),
            polls: Cell::new(0),
            finished: 0,
            spins: 0,
        }
    }

    /// The clock of this executor's virtual time.
    pub fn clock(&self) -> SimClock {
        SimClock {
            core: self.time.clone(),
        }
    }

    /// A handle to spawn tasks from inside tasks.
    pub fn spawner(&self) -> Spawner<'a> {
        Spawner {
            queue: self.spawn_queue.clone(),
        }
    }

    /// Adds a task; tasks are polled in the order they were spawned.
    pub fn spawn(
        &mut self,
        name: impl Into<String>,
        future: impl Future<Output = ()> + 'a,
    ) -> TaskId {
        self.push_task(name.into(), Box::pin(future))
    }

    fn push_task(&mut self, name: String, future: BoxFuture<'a>) -> TaskId {
        let index = self.tasks.len();
        let waker = Waker::from(Arc::new(TaskFlag {
            set: self.woken.clone(),
            index,
        }));
        // Polled first in the pass that comes next.
        self.woken.mark(index);
        self.tasks.push(Some(Task {
            name: name.into(),
            future,
            waker,
        }));
        TaskId(self.tasks.len() - 1)
    }

    fn drain_spawns(&mut self) -> bool {
        let queued: Vec<_> = self.spawn_queue.borrow_mut().drain(..).collect();
        let any = !queued.is_empty();
        for (name, fut) in queued {
            self.push_task(name, fut);
        }
        any
    }

    /// Virtual time now, in ns.
    pub fn now_ns(&self) -> Nanos {
        self.time.now()
    }

    /// True while the task has not finished.
    pub fn is_alive(&self, id: TaskId) -> bool {
        self.tasks.get(id.0).is_some_and(Option::is_some)
    }

    /// Polls every ready task until none is ready, or until the instant spins
    /// ([`SPIN_POLLS`]) while a timer could move time on; returns the polls made and whether
    /// it spun.
    fn run_instant(&mut self) -> Result<(u64, bool), RunError> {
        let mut polls_here = 0u64;
        loop {
            let mut progressed = self.drain_spawns();
            // One pass in index order: a task woken during the pass is polled in it when its
            // index is above the one being polled, in the next pass otherwise.
            let mut from = 0;
            while let Some(i) = self.woken.take_next(from, self.tasks.len()) {
                from = i + 1;
                let Some(task) = self.tasks.get_mut(i).and_then(Option::as_mut) else {
                    continue;
                };
                progressed = true;
                polls_here += 1;
                let mut cx = Context::from_waker(&task.waker);
                let previous = CURRENT_TASK.with(|c| c.replace(Some(task.name.clone())));
                let ready = task.future.as_mut().poll(&mut cx).is_ready();
                CURRENT_TASK.with(|c| c.replace(previous));
                if ready {
                    if let Some(slot) = self.tasks.get_mut(i) {
                        *slot = None;
                    }
                    self.finished += 1;
                }
            }
            if !progressed {
                return Ok((polls_here, false));
            }
            if polls_here > SPIN_POLLS && self.time.state.borrow_mut().next_deadline().is_some() {
                return Ok((polls_here, true));
            }
            if polls_here > MAX_POLLS_PER_INSTANT {
                let tasks = self
                    .tasks
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| self.woken.is_marked(*i))
                    .filter_map(|(_, t)| t.as_ref().map(|t| t.name.to_string()))
                    .collect();
                return Err(RunError::Livelock {
                    at: self.time.now(),
                    tasks,
                });
            }
        }
    }

    /// Runs until virtual time `end` (ns) or until no task can ever wake again, whichever is
    /// first. Time ends at `end` in the first case and at the last wake-up in the second.
    ///
    /// # Errors
    /// [`RunError::Livelock`] when some task keeps waking itself at one instant.
    pub fn run_until_ns(&mut self, end: Nanos) -> Result<RunStats, RunError> {
        self.run_while(end, &|| true)
    }

    /// As [`Executor::run_until_ns`], but also stops after the first instant at which
    /// `keep_going` returns false.
    ///
    /// # Errors
    /// [`RunError::Livelock`] when some task keeps waking itself at one instant.
    pub fn run_while(
        &mut self,
        end: Nanos,
        keep_going: &dyn Fn() -> bool,
    ) -> Result<RunStats, RunError> {
        set_current_time(Some(self.time.clone()));
        // The wakers due at each instant, in a vector kept across instants.
        let mut due: Vec<Waker> = Vec::new();
        loop {
            let (polls, spun) = self.run_instant()?;
            self.polls.set(self.polls.get() + polls);
            if spun {
                self.spins += 1;
            }
            if !keep_going() {
                break;
            }
            {
                let mut st = self.time.state.borrow_mut();
                let Some(deadline) = st.next_deadline() else {
                    break;
                };
                if deadline > end {
                    st.now = st.now.max(end);
                    break;
                }
                st.now = st.now.max(deadline);
                let now = st.now;
                st.take_due(now, &mut due);
            }
            for w in due.drain(..) {
                w.wake();
            }
        }
        Ok(self.stats())
    }

    /// Statistics so far.
    pub fn stats(&self) -> RunStats {
        RunStats {
            end_ns: self.time.now(),
            polls: self.polls.get(),
            finished: self.finished,
            alive: self.tasks.iter().flatten().count(),
            spins: self.spins,
        }
    }
}

/// A small seeded generator (SplitMix64): fault injection and scripted noise. Same seed, same
/// numbers, on every machine.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next_u64() % n
        }
    }

    /// True with probability `ppm` parts per million.
    pub fn chance_ppm(&mut self, ppm: u32) -> bool {
        ppm > 0 && self.below(1_000_000) < u64::from(ppm)
    }

    /// An independent generator derived from this one (for another component).
    pub fn fork(&mut self) -> Rng {
        Rng::new(self.next_u64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    #[test]
    fn tasks_past_the_lock_free_ones_are_polled_in_order_too() {
        let n = FAST_TASKS + 70;
        let log = RefCell::new(Vec::new());
        let mut ex = Executor::new();
        let clock = ex.clock();
        for i in 0..n {
            let (log, clock) = (&log, clock.clone());
            ex.spawn(format!("t{i}"), async move {
                log.borrow_mut().push(i);
                // The last ones sleep first, so they wake first in deadline order.
                clock.sleep_ns((n - i) as u64).await;
                log.borrow_mut().push(i);
            });
        }
        let stats = ex.run_until_ns(1_000_000).unwrap();
        let log = log.borrow().clone();
        assert_eq!(log.len(), 2 * n);
        assert!(log[..n].iter().copied().eq(0..n));
        assert!(log[n..].iter().copied().eq((0..n).rev()));
        assert_eq!((stats.finished, stats.alive), (n, 0));
    }

    #[test]
    fn sleepers_wake_in_deadline_order_and_time_jumps() {
        let log = RefCell::new(Vec::new());
        let mut ex = Executor::new();
        let clock = ex.clock();
        for (name, at) in [("c", 30u64), ("a", 10), ("b", 20), ("a2", 10)] {
            let clock = clock.clone();
            let log = &log;
            ex.spawn(name, async move {
                clock.sleep_until(Instant(at)).await;
                log.borrow_mut().push((name, clock.now().0));
            });
        }
        let stats = ex.run_until_ns(1_000_000).unwrap();
        assert_eq!(
            *log.borrow(),
            vec![("a", 10), ("a2", 10), ("b", 20), ("c", 30)]
        );
        assert_eq!(stats.end_ns, 30_000);
        assert_eq!(stats.finished, 4);
        assert_eq!(stats.alive, 0);
    }

    #[test]
    fn run_stops_at_end_and_resumes() {
        let count = Cell::new(0u32);
        let mut ex = Executor::new();
        let clock = ex.clock();
        let c = &count;
        ex.spawn("ticker", async move {
            loop {
                clock.sleep_us(100).await;
                c.set(c.get() + 1);
            }
        });
        let s = ex.run_until_ns(1_050_000).unwrap();
        assert_eq!(count.get(), 10);
        assert_eq!(s.end_ns, 1_050_000);
        ex.run_until_ns(2_000_000).unwrap();
        assert_eq!(count.get(), 20);
    }

    #[test]
    fn channel_wakeups_run_in_the_same_instant() {
        use embassy_sync::blocking_mutex::raw::NoopRawMutex;
        use embassy_sync::channel::Channel;
        let ch: Channel<NoopRawMutex, u32, 4> = Channel::new();
        let got = RefCell::new(Vec::new());
        let mut ex = Executor::new();
        let clock = ex.clock();
        let (chr, gotr) = (&ch, &got);
        let c2 = clock.clone();
        ex.spawn("rx", async move {
            for _ in 0..3 {
                let v = chr.receive().await;
                gotr.borrow_mut().push((v, c2.now_ns()));
            }
        });
        ex.spawn("tx", async move {
            for v in 0..3 {
                clock.sleep_ns(500).await;
                chr.send(v).await;
            }
        });
        ex.run_until_ns(10_000).unwrap();
        assert_eq!(*got.borrow(), vec![(0, 500), (1, 1000), (2, 1500)]);
    }

    #[test]
    fn dropped_sleep_leaves_no_timer() {
        let mut ex = Executor::new();
        let clock = ex.clock();
        let c = clock.clone();
        ex.spawn("select", async move {
            let long = c.sleep_ns(1_000_000);
            let short = c.sleep_ns(10);
            embassy_futures::select::select(long, short).await;
        });
        let s = ex.run_until_ns(u64::MAX).unwrap();
        // The long sleep was dropped: time stops at the short one.
        assert_eq!(s.end_ns, 10);
    }

    #[test]
    fn cancelled_timers_neither_wake_nor_hold_time_and_their_slots_are_reused() {
        let log = RefCell::new(Vec::new());
        let mut ex = Executor::new();
        let clock = ex.clock();
        let (c1, c2) = (clock.clone(), clock.clone());
        let l = &log;
        ex.spawn("x", async move {
            // The 1 ms sleep is dropped when the 10 ns one ends: cancelled in the heap.
            embassy_futures::select::select(c1.sleep_ns(10), c1.sleep_ns(1_000_000)).await;
            l.borrow_mut().push(("x", c1.now_ns()));
        });
        ex.spawn("y", async move {
            // Made after the first timers fired: they take their slots again.
            for _ in 0..3 {
                c2.sleep_ns(15).await;
                l.borrow_mut().push(("y", c2.now_ns()));
            }
        });
        let s = ex.run_until_ns(u64::MAX).unwrap();
        assert_eq!(
            *log.borrow(),
            vec![("x", 10), ("y", 15), ("y", 30), ("y", 45)]
        );
        // Time stops at the last live timer, not at the cancelled 1 ms one.
        assert_eq!((s.end_ns, s.polls, s.finished), (45, 6, 2));
    }

    #[test]
    fn wake_at_polls_the_task_once_at_that_instant() {
        let seen = RefCell::new(Vec::new());
        let again = Cell::new(0u32);
        let mut ex = Executor::new();
        let clock = ex.clock();
        let c = clock.clone();
        let s = &seen;
        let mut armed = false;
        ex.spawn(
            "waiter",
            std::future::poll_fn(move |cx: &mut Context<'_>| {
                s.borrow_mut().push(c.now_ns());
                if armed {
                    return Poll::Ready(());
                }
                armed = true;
                c.wake_at(700, cx.waker().clone());
                Poll::Pending
            }),
        );
        let stats = ex.run_until_ns(10_000).unwrap();
        assert_eq!(*seen.borrow(), vec![0, 700]);
        assert_eq!((stats.polls, stats.end_ns), (2, 700));
        // A time already passed wakes at once.
        let a = &again;
        let c = clock.clone();
        ex.spawn(
            "late",
            std::future::poll_fn(move |cx: &mut Context<'_>| {
                a.set(a.get() + 1);
                if a.get() > 1 {
                    return Poll::Ready(());
                }
                c.wake_at(5, cx.waker().clone());
                Poll::Pending
            }),
        );
        let stats = ex.run_until_ns(20_000).unwrap();
        // No timer is left: time stays at the last wake-up.
        assert_eq!((again.get(), stats.end_ns), (2, 700));
    }

    #[test]
    fn livelock_is_reported() {
        let mut ex = Executor::new();
        ex.spawn(
            "spinner",
            std::future::poll_fn(|cx: &mut Context<'_>| {
                cx.waker().wake_by_ref();
                Poll::<()>::Pending
            }),
        );
        match ex.run_until_ns(10) {
            Err(RunError::Livelock { at, tasks }) => {
                assert_eq!(at, 0);
                assert_eq!(tasks, vec!["spinner".to_string()]);
            }
            other => panic!("expected livelock, got {other:?}"),
        }
    }

    #[test]
    fn spinning_tasks_do_not_stop_time() {
        // Two tasks that wake each other forever, and a sleeper: time still reaches the
        // sleeper's deadline, and the spin is counted.
        let woke = Cell::new(false);
        let mut ex = Executor::new();
        let clock = ex.clock();
        for name in ["a", "b"] {
            ex.spawn(
                name,
                std::future::poll_fn(|cx: &mut Context<'_>| {
                    cx.waker().wake_by_ref();
                    Poll::<()>::Pending
                }),
            );
        }
        let w = &woke;
        let c2 = clock.clone();
        ex.spawn("sleeper", async move {
            clock.sleep_ns(1_000).await;
            w.set(true);
        });
        ex.spawn("late sleeper", async move {
            c2.sleep_ns(1_000_000).await;
        });
        let s = ex.run_until_ns(500).unwrap();
        assert!(!woke.get());
        assert_eq!(s.end_ns, 500);
        let s = ex.run_until_ns(2_000).unwrap();
        assert!(woke.get());
        assert!(s.spins >= 2, "{s:?}");
    }

    #[test]
    fn spawner_adds_tasks_at_the_current_instant() {
        let seen = RefCell::new(Vec::new());
        let mut ex = Executor::new();
        let sp = ex.spawner();
        let clock = ex.clock();
        let s = &seen;
        ex.spawn("parent", async move {
            clock.sleep_ns(7).await;
            let c = clock.clone();
            sp.spawn("child", async move {
                s.borrow_mut().push(c.now_ns());
            });
        });
        ex.run_until_ns(100).unwrap();
        assert_eq!(*seen.borrow(), vec![7]);
    }

    #[test]
    fn rng_is_deterministic() {
        let mut a = Rng::new(42);
        let mut b = Rng::new(42);
        let xs: Vec<u64> = (0..5).map(|_| a.next_u64()).collect();
        let ys: Vec<u64> = (0..5).map(|_| b.next_u64()).collect();
        assert_eq!(xs, ys);
        assert_ne!(Rng::new(43).next_u64(), xs[0]);
        assert!((0..1000).all(|_| a.below(7) < 7));
        assert!(!a.chance_ppm(0));
        assert!(a.chance_ppm(1_000_000));
    }
}
