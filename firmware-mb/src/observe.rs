//! Watching the calls robot tasks make (the simulator traces them; boards set no observer).

use x10_devices::LinkError;
use x10_hal::time::Instant;
use x10_microcode::{Address, Op, Payload};

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
}
