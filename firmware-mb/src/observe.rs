//! Watching the calls robot tasks make and the events the motherboard routes (the simulator
//! traces calls; the USB link, `x10_link::recorder`, records both; other boards set no observer).

use x10_devices::LinkError;
use x10_hal::time::Instant;
use x10_microcode::{Address, Event, Op, Payload};

/// One finished call, as [`CallObserver::observe`] sees it.
#[derive(Debug)]
pub struct CallRecord<'a> {
    /// The board called.
    pub db: Address,
    /// The operation sent.
    pub op: &'a Op<'a>,
    /// How it ended.
    pub result: &'a Result<Payload, LinkError>,
    /// When the call started (µs since boot).
    pub started: Instant,
    /// When it ended.
    pub ended: Instant,
}

/// Told of every call that ends (set with `Motherboard::with_observer`). Called inside the
/// caller's task, right after the call ended; keep it short.
pub trait CallObserver: Sync {
    /// A call ended.
    fn observe(&self, call: &CallRecord<'_>);

    /// An event was routed (a bus board's or the internal board's), at `at`. Called inside the
    /// motherboard's task; keep it short. By default nothing (the USB link records them).
    fn event(&self, _event: &Event<'_>, _at: Instant) {}

    /// The updater (`update::run_updates`) starts updating the board at `db` from `from` to
    /// `to` (`end` is `None`), or that update ended, at `at`. Called inside the updater's task. By
    /// default nothing (the USB link records it).
    fn update(
        &self,
        _db: Address,
        _from: x10_microcode::Version,
        _to: x10_microcode::Version,
        _end: Option<&Result<(), crate::update::UpdateError>>,
        _at: Instant,
    ) {
    }
}
