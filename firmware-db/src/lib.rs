//! # firmware-db: the daughterboard runtime
//!
//! Portable (no chip code): validates and executes microcode on a board's [`Ports`], answers
//! reads, pushes events to the motherboard as a brief master, and trips a failsafe when the MB
//! falls silent. The board binaries supply the [`Ports`] and the bus.
#![no_std]

pub mod ports;

pub use ports::{PortError, Ports, SafeState};
