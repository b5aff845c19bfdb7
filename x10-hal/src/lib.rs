//! # x10-hal: what the X10 runtimes need from a board, and nothing more
//!
//! * [`bus::MultiMaster`]: one multi-master I2C port, controller and target.
//! * [`ports::Ports`]: a board's sensor and actuator ports, on which a daughterboard executes
//!   microcode.
//! * [`time::Clock`]: a monotonic microsecond clock with async sleeps.
//! * [`retry::Backoff`]: the retry and backoff policy both runtimes use when the bus is busy.
//!
//! Boards implement these in their firmware crates (RP2040 by switching roles, STM32 I2C v2
//! with one `MultiMaster` handle, both on embassy-time); the simulator implements them with a
//! virtual bus and virtual time. Nothing here names a chip.
#![no_std]

pub mod bus;
pub mod ports;
pub mod retry;
pub mod time;
