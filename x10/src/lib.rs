//! # x10: write your own robot
//!
//! A robot program is one or more plain `async fn`s that take an [`X10`], the handle on the
//! motherboard runtime, and run for ever or return. They use `embassy_time` (`Timer`,
//! `Ticker`, `Instant`, `Duration`, `with_timeout`) and `embassy_futures` (`select`, `join`)
//! directly, build drivers on the handle and await them, events included:
//!
//! ```
//! use embassy_time::Timer;
//! use x10::{Button, ButtonState, DcMotor, Error, Pin, Speed, SELF, X10};
//!
//! /// Backs off for 800 ms whenever the bumper (sensor port 2, pin B) is pressed.
//! pub async fn bumper(x10: X10) -> Result<(), Error> {
//!     let mut motor = DcMotor::new(x10, SELF, 1)?; // H-bridge on actuator port 1
//!     let mut bumper = Button::new(x10, SELF, 2, Pin::B)?;
//!     bumper.enable_events().await?;
//!     loop {
//!         if bumper.wait_change().await? == ButtonState::Pressed {
//!             motor.set_speed(Speed::new(-60)?).await?;
//!             Timer::after_millis(800).await;
//!             motor.stop().await?;
//!         }
//!     }
//! }
//! ```
//!
//! The same function runs
//! * on a board: the image's `main` starts the motherboard runtime
//!   (`x10_boards::pico::start_motherboard`) and spawns an embassy task that awaits it;
//! * in the simulator: `x10_sim::Sim::with_robot("bumper", bumper)` (or a world file and the
//!   `x10_cli::app` command line), in virtual time, against simulated daughterboards.
//!
//! A robot with several tasks is declared once with [`robot!`]: `x10::robot! { pub struct
//! Robot { heartbeat, bumper } }`; the simulator runs `sim.robot(Robot)` and the image's
//! `main` calls `Robot.spawn(spawner, x10)` (see [`Robot`]).
//!
//! [`X10`] is `Copy`: give it to as many tasks as the robot has. Every driver method returns
//! a [`Result`]; nothing panics. Boards are addressed by number, [`SELF`] (0) being the
//! motherboard's own ports; ports count from 1, as in the thesis.
//!
//! Boards flashed with one image for all find their addresses themselves (plug and play,
//! `docs/protocol.md`, "Addresses over the bus"): `x10.boards(&mut list)` says which boards the
//! motherboard knows (address, unique ID, kind, ports, firmware), `x10.wait_for_board(query,
//! timeout_us)` waits for one by address, kind or ID, `x10.set_address(old, new)` moves a board
//! (it keeps the new address), `x10.blink(address, seconds)` makes it show itself; addresses a
//! person chooses go in `MbConfig::pinned`.
//!
//! This crate re-exports `firmware_mb::X10` and the drivers, units and types of
//! `x10_devices`; [`every`] runs loop()-style code on a fixed period.
#![no_std]

use core::convert::Infallible;

pub use embassy_time::Duration;
pub use firmware_mb::{BoardQuery, KnownBoard, MbConfig, MbDiagnostics, PinBy, PinnedAddress, X10};
pub use x10_devices::*;
pub use x10_microcode::{Address, BoardKind, Op, Uid};

mod robot;
pub use robot::{task_ended, Robot, TaskEnd, Tasks};

/// Runs `step` every `period` on a fixed grid (an embassy `Ticker`), for ever: the Arduino
/// `loop()` of the thesis, for code written that way. A step that overruns its period is
/// followed at once by the next one. Returns the first error `step` returns (handle the
/// errors you want to ride out inside `step`).
///
/// ```
/// # use x10::{every, AnalogSensor, Duration, Error, SELF, X10};
/// async fn log_light(x10: X10) -> Result<(), Error> {
///     let light = AnalogSensor::new(x10, SELF, 1)?;
///     let mut brightest = 0;
///     every(Duration::from_millis(100), async || {
///         brightest = brightest.max(light.read_raw().await?);
///         Ok::<(), Error>(())
///     })
///     .await?;
///     Ok(())
/// }
/// ```
///
/// # Errors
/// The first error of `step`.
pub async fn every<E>(
    period: Duration,
    mut step: impl AsyncFnMut() -> core::result::Result<(), E>,
) -> core::result::Result<Infallible, E> {
    let mut ticker = embassy_time::Ticker::every(period);
    loop {
        step().await?;
        ticker.next().await;
    }
}
