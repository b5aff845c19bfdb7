//! Helpers the tests of several crates share (feature `test-support`, which only tests turn
//! on: firmware images never have it). They panic on a bad argument, as a test should.
#![allow(clippy::unwrap_used)]

use crate::{Address, Port};

/// Sensor port `n` (1-based).
pub fn s(n: u8) -> Port {
    Port::sensor(n).unwrap()
}

/// Actuator port `n` (1-based).
pub fn a(n: u8) -> Port {
    Port::actuator(n).unwrap()
}

/// Daughterboard 9, the tests' usual board.
pub fn db9() -> Address {
    Address::external(9).unwrap()
}
