//! # x10-devices: drivers composed from microcode
//!
//! Every driver here is generic over one small async trait, [`Link`], through which it sends
//! microcode operations to a daughterboard and awaits their outcome. The motherboard runtime,
//! the internal daughterboard, the simulator and test doubles implement it; drivers never see
//! I2C.
//!
//! Two layers, as in the thesis (chapter 3.1.2.5, 4.2):
//!
//! * the generic port drivers [`Sensor`] and [`Actuator`]: one method per microcode operation
//!   of a port (analog read, digital read/write of each pin, PWM duty/frequency/pulse width,
//!   pulse-in, events), ports counted from 1, the internal board as [`SELF`] (address 0);
//! * device drivers built only from those: [`HBridge`], [`DcMotor`], [`DigitalOutput`],
//!   [`Thermistor`], [`Servo`], [`Button`], [`AnalogSensor`], [`Ultrasonic`]. Each is a few dozen lines; their arithmetic
//!   lives in [`math`], where it is tested from raw numbers.
//!
//! [`Refresh`] tells a control loop when to re-send an actuator state that did not change, so
//! a board that reset (and fell back to its safe state) is driven again within a bounded number
//! of steps; [`Kept`] wraps an [`Output`] ([`DcMotor`], [`DigitalOutput`]) and a `Refresh` into
//! one call per step, [`Kept::keep`].
//!
//! Units and ranges are types ([`Speed`], [`Percent`], [`Duty`], [`Celsius`], …): an
//! out-of-range value is a [`RangeError`] when the value is made, before anything is sent.
//! Every driver method returns [`Error`]; `docs/drivers.md` lists the exact microcode each
//! method sends.
//!
//! The crate is `no_std` and never allocates. With the `testing` feature it also provides
//! `testing::RecordingLink`, a recording test double for this and other crates' tests.
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

mod analog;
mod button;
mod dc_motor;
mod digital_output;
mod error;
mod hbridge;
mod kept;
mod link;
pub mod math;
mod port;
mod refresh;
mod servo;
#[cfg(feature = "testing")]
pub mod testing;
mod thermistor;
mod ultrasonic;
mod units;

pub use analog::{AnalogSensor, Crossing};
pub use button::{Button, ButtonState};
pub use dc_motor::{DcMotor, Ramp};
pub use digital_output::DigitalOutput;
pub use error::{Error, Quantity, RangeError};
pub use hbridge::HBridge;
pub use kept::{Kept, Output};
pub use link::{Link, LinkError, PinEvent};
pub use math::{Calibration, Divider, SteinhartHart};
pub use port::{Actuator, Sensor};
pub use refresh::Refresh;
pub use servo::{Servo, ServoConfig};
pub use thermistor::{Thermistor, ThermistorConfig};
pub use ultrasonic::{Ultrasonic, UltrasonicConfig};
pub use units::{
    Celsius, Degrees, Direction, Duty, Fahrenheit, Kelvin, Millimetres, Percent, Speed,
};
pub use x10_microcode::{
    Address, Edge, EventConfig, EventKind, Level, Payload, Pin, PinRef, Port, PortKind, Status,
};

/// The internal daughterboard on the motherboard itself (thesis `SELF`, address 0).
pub const SELF: Address = Address::INTERNAL;

/// `docs/drivers.md`: its complete Rust examples run as doctests; its excerpts (`rust,ignore`
/// under an `<!-- excerpt: FILE -->` line) are checked against their files by
/// `tests/docs_examples.rs`.
#[cfg(doctest)]
#[doc = include_str!("../../docs/drivers.md")]
pub struct DriversGuide;

/// Result of every driver method.
pub type Result<T> = core::result::Result<T, Error>;
