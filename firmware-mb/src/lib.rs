//! # firmware-mb: the motherboard runtime
//!
//! Portable (no chip code, `no_std`, no allocation). The motherboard owns the bus controller
//! role and serves any number of robot tasks:
//!
//! * [`X10`] is what robot programs take: one concrete, `Copy` handle, the same on every board
//!   and in the simulator. It implements [`x10_devices::Link`], so every driver works
//!   through it; a pending table keyed by (board, sequence number) makes every request end
//!   exactly once, with its value or a typed [`x10_devices::LinkError`];
//! * [`Motherboard::run`], in a task of its own, serves them: the dispatcher with its
//!   DB-interrupt listener ([`MbCore::run_dispatcher`]), the internal daughterboard (address
//!   0: the `firmware-db` core on the board's own [`firmware_db::Ports`], its requests queued
//!   like bus requests and its events routed like bus events); the failsafe keepalive is
//!   sent by the dispatcher itself between jobs (and by the internal worker for the
//!   internal board): a board with a failsafe hears a heartbeat whenever nothing was sent
//!   to it for a third of the timeout, with no pending slot needed.
//!
//! Time is embassy-time's (on boards its chip driver; in the simulator a virtual-time
//! driver). Nothing here is an `#[embassy_executor::task]`: a board crate wraps
//! [`Motherboard::run`] in a task with its concrete types (`x10_boards::*::start_motherboard`),
//! the simulator polls it on its own deterministic executor. See `docs/architecture.md`.
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

#[macro_use]
mod fmt;

// The modules in layers, bottom up; a module uses only modules of the layers before its own
// (docs/architecture.md, "Modules of firmware-mb"). 1. Leaves: the bitmap over the boards,
// configuration, counters, the call observer.
mod board_set;
mod config;
mod diag;
mod observe;
// 2. Bookkeeping, one thing each (pure: no waiting, no I/O): the events received per board,
// the keepalive schedule, the pending requests, the event waiters.
mod directory;
mod events_in;
mod keepalive;
mod requests;
mod waiters;
// 3. Built on 2: the per-board state (with the keepalive), the job queue (slots' tickets).
mod boards;
mod jobs;
// 4. The table: all of 2 and 3 under one lock.
mod table;
// 5. The shared core (the table, the signals, the call path).
mod mb_core;
// 6. On the core: what a finished transfer means, where events go.
mod routing;
mod together;
mod transfer;
// 7. The dispatcher (transfers, events) and the programs' handle (calls, events).
mod dispatch;
mod handle;
pub mod update;
// 8. The top: the motherboard and its tasks.
mod motherboard;

pub use config::{MbConfig, PinBy, PinnedAddress};
pub use diag::MbDiagnostics;
pub use directory::{choose_address, AssignError, BoardQuery, KnownBoard, COLLISION_WINDOW_US};
pub use handle::{ASSIGN_WAIT_US, WAIT_FOR_BOARD_POLL_US, X10};
pub use jobs::REQUEST_QUEUE_LEN;
pub use keepalive::KEEPALIVE_RAM_BYTES;
pub use mb_core::{InternalBoard, MbCore};
pub use motherboard::Motherboard;
pub use observe::{CallObserver, CallRecord};
pub use requests::{MAX_PENDING, RECENT_LEN};
pub use together::{NotTogether, SweepResult, SweepSummary, Together, MAX_TOGETHER};
pub use waiters::{MAX_EVENT_WAITERS, UNCLAIMED_EVENTS};
