//! # firmware-mb: the motherboard runtime
//!
//! Portable (no chip code, `no_std`, no allocation). The motherboard owns the bus controller
//! role and serves any number of robot tasks:
//!
//! * [`Motherboard::run`] joins the four long-running parts: the dispatcher with its
//!   DB-interrupt listener ([`Motherboard::run_dispatcher`]), the internal daughterboard's
//!   background work, the routing of its events ([`Motherboard::run_internal_events`]), and
//!   the failsafe keepalive ([`Motherboard::run_keepalive`]: a board whose failsafe a
//!   program set hears a heartbeat whenever nothing was sent to it for a third of the
//!   timeout);
//! * [`Motherboard::call`] / [`MbHandle`] (an [`x10_devices::Link`]) is what robot programs
//!   use: a pending table keyed by (board, sequence number) makes every request end exactly
//!   once, with its value or a typed [`x10_devices::LinkError`];
//! * address 0 is the internal daughterboard: the `firmware-db` core on the motherboard's
//!   own [`firmware_db::Ports`], reached by direct calls, its events routed like bus events;
//! * [`run_robot`] runs a [`x10_devices::Robot`] program: `setup`, then `step` forever.
//!
//! Nothing here is an `#[embassy_executor::task]`: firmware wraps these `async fn`s in tasks,
//! the simulator polls them on its own deterministic executor. Generic over the raw mutex
//! (`embassy_sync::blocking_mutex::raw::RawMutex`), the bus ([`x10_hal::bus::MultiMaster`])
//! and the clock ([`x10_hal::time::Clock`]). See `docs/architecture.md`.
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

mod config;
mod diag;
mod dispatch;
mod handle;
mod keepalive;
mod motherboard;
mod robot;
mod table;

pub use config::MbConfig;
pub use diag::MbDiagnostics;
pub use handle::MbHandle;
pub use keepalive::{BUSY_RETRY_US, MAX_KEEPALIVES};
pub use motherboard::{Motherboard, REQUEST_QUEUE_LEN};
pub use robot::{run_robot, run_robot_with, RobotPhase};
pub use table::{MAX_EVENT_WAITERS, MAX_PENDING, RECENT_LEN, UNCLAIMED_EVENTS};
