//! # x10-devices: drivers composed from microcode
//!
//! Every driver here is generic over one small async trait, [`Link`], through which it sends
//! microcode operations to a daughterboard and awaits their outcome. The motherboard runtime,
//! the internal daughterboard, the simulator and test doubles implement it.
#![no_std]

mod link;
mod robot;

pub use link::{Link, LinkError, PinEvent};
pub use robot::Robot;
pub use x10_microcode::Address;

/// The internal daughterboard on the motherboard itself (thesis `SELF`, address 0).
pub const SELF: Address = Address::INTERNAL;
