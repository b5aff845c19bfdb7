//! # firmware-db: the daughterboard runtime
//!
//! Portable (no chip code, `no_std`, no allocation): validates and executes microcode on a
//! board's [`Ports`], holds a reply for every read, pushes events to the motherboard as a brief
//! master, and trips a failsafe when the MB falls silent. The board binaries supply the
//! [`Ports`], the bus ([`x10_hal::bus::MultiMaster`]) and the clock ([`x10_hal::time::Clock`]);
//! the motherboard runtime reuses the same core for its internal daughterboard (address 0),
//! and the simulator runs it on virtual time.
//!
//! * [`Daughterboard`]: the core. [`Daughterboard::handle_write`] / [`Daughterboard::take_reply`]
//!   for transactions, [`Daughterboard::run_background`] for pulse-in, event sampling and the
//!   failsafe, [`Daughterboard::next_event`] for the event queue.
//! * [`run_target`]: a daughterboard on the bus (listener and event sender); [`run`] joins it
//!   with the background work.
//!
//! Nothing in this crate is an `#[embassy_executor::task]`: firmware wraps these `async fn`s in
//! tasks, the simulator polls them on its own executor.
#![no_std]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

mod background;
mod config;
mod daughterboard;
mod event;
mod record;
mod target;

pub use config::{DbConfig, TargetConfig, ALL_CAPABILITIES, FIRMWARE_VERSION};
pub use daughterboard::{
    Daughterboard, DEFERRED_QUEUE_LEN, DEFERRED_WORKERS, EVENT_QUEUE_LEN, MAX_EVENT_PINS,
    REPLY_BUF_LEN,
};
pub use event::{OutEvent, EVENT_PAYLOAD_LEN};
pub use record::{start_address, AddressRecord, NoRecord, StoreError};
pub use target::{
    run, run_target, ANNOUNCE_MIN_US, ANNOUNCE_WINDOW_US, MAX_EVENT_YIELDS, MB_GONE_RETRY_US,
};
/// The board's ports (defined in `x10-hal`, so that board crates need not depend on this one).
pub use x10_hal::ports::{self, EdgeCount, PortError, Ports, SafeState};
