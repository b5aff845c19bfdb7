//! # x10-robots: example robot programs
//!
//! Each example is one or more plain `async fn`s that take an [`x10::X10`] handle: the same
//! functions run in a motherboard image (`src/bin/mb-*.rs`, each an embassy task) and in the
//! simulator (`cargo x10 sim NAME`, against the world in `worlds/NAME.toml`). Nothing here is
//! a registry: your own robot lives in a crate of its own (`cargo x10 new PATH`, see
//! `docs/your-first-robot.md`), written the same way.
//!
//! Each example is declared once as a robot ([`x10::robot!`]): the simulator
//! (`sim.robot(x10_robots::Fig4_4)`) and the images (`Fig4_4.spawn(spawner, x10)`) take its
//! tasks from there.
//!
//! | robot | tasks | boards | what it does |
//! |---|---|---|---|
//! | [`Fig4_2`] | [`fig4_2::single_board`] | SELF | thesis Fig. 4.2: button or force > 100 runs the motor at full speed |
//! | [`Fig4_4`] | [`fig4_2::single_board`], [`fig4_4::light_motor`] | SELF, 9 | Fig. 4.4: Fig. 4.2 unchanged, plus light > 700 runs a second motor at 50 % |
//! | [`Fig4_6`] | [`fig4_6::temperature_alarm`] | 17, 108, 10 | Fig. 4.6: freezer > 1 °C or oven < 200 °F raises the alarm |
//! | [`Bumper`] | [`bumper::heartbeat`], [`bumper::lamp`], [`bumper::bumper`] | SELF, 9 | three concurrent tasks: a blinking LED, a light-following lamp, and a timed back-off when the bumper is hit |
//! | [`Explorer`] | [`arena::explorer`] | SELF | a chassis in a walled arena: drives, and on each bump backs off, turns and goes on |
//! | [`WallFollower`] | [`arena::wall_follower`] | SELF | a chassis keeps the wall on its left at 300 mm along its ranger's beam |
//! | [`LineFollower`] | [`arena::line_follower`] | SELF | a chassis follows the edge of a dark floor line with one line sensor |
//! | [`Doorbell`] | [`doorbell::doorbell`] | 9, SELF | a button's events from board 9 wake the task, which mirrors the button on a chime |
//! | [`FullBus`] | [`full_bus::scan_all`] | 0x09 to 0x76 | a full bus: 110 boards, each scanned once every 100 ms (the load test of the bus and the simulator) |
//!
//! ## Keeping the actuators driven
//! The thesis programs send an actuator command when the wanted state changes, and also every
//! [`REFRESH_STEPS`] steps without a change, and at the next step after a failed call to the
//! actuator's board ([`x10::Kept`]): a daughterboard that resets comes back in its safe state
//! (motor coasting, alarm LOW) without the program noticing, and the periodic re-send drives
//! it again. A call that fails is not the end of the program: the loop goes on, and the next
//! step re-sends.
#![no_std]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)
)]

use embassy_time::Duration;
use x10::Refresh;

pub mod arena;
pub mod bumper;
pub mod doorbell;
pub mod fig4_2;
pub mod fig4_4;
pub mod fig4_6;
pub mod full_bus;
pub mod pnp;

x10::robot! {
    /// Thesis Figure 4.2: one task on the motherboard's own ports.
    pub struct Fig4_2 { single_board: fig4_2::single_board }
}

x10::robot! {
    /// Thesis Figure 4.4: Figure 4.2 unchanged, plus the light-sensor motor on board 9.
    pub struct Fig4_4 { single_board: fig4_2::single_board, light_motor: fig4_4::light_motor }
}

x10::robot! {
    /// Thesis Figure 4.6: the temperature alarm on boards 17, 108 and 10.
    pub struct Fig4_6 { temperature_alarm: fig4_6::temperature_alarm }
}

x10::robot! {
    /// Three concurrent tasks: a heartbeat LED, a lamp following the light, a bumper back-off.
    pub struct Bumper { heartbeat: bumper::heartbeat, lamp: bumper::lamp, bumper: bumper::bumper }
}

x10::robot! {
    /// A chassis in a walled arena: drives, and on each bump backs off, turns and goes on.
    pub struct Explorer { explorer: arena::explorer }
}

x10::robot! {
    /// A chassis following the wall on its left with an ultrasonic ranger.
    pub struct WallFollower { wall_follower: arena::wall_follower }
}

x10::robot! {
    /// A chassis following a dark line on the floor with one line sensor.
    pub struct LineFollower { line_follower: arena::line_follower }
}

x10::robot! {
    /// Plug and play: two daughterboards from one image, addressed over the bus, both driven.
    pub struct TwoBoards { two_boards: pnp::two_boards }
}

x10::robot! {
    /// A full bus: 110 daughterboards, each scanned once every 100 ms.
    pub struct FullBus { scan_all: full_bus::scan_all }
}

x10::robot! {
    /// A button on board 9 rings a chime on the motherboard while held.
    pub struct Doorbell { doorbell: doorbell::doorbell }
}

/// The thesis programs' loop period: each pass of their `loop()` runs every 20 ms.
pub const PERIOD: Duration = Duration::from_millis(20);

/// Every thesis program re-sends its actuator state at least every this many steps, changed or
/// not (see [`x10::Refresh`]): within 500 ms at the 20 ms [`PERIOD`].
pub const REFRESH_STEPS: u16 = 25;

/// [`REFRESH_STEPS`] as a [`Refresh`].
pub(crate) const REFRESH: Refresh = match Refresh::every(REFRESH_STEPS) {
    Ok(r) => r,
    // Evaluated at compile time: a bad constant fails the build, never the robot.
    Err(_) => panic!("REFRESH_STEPS is at least 1"),
};
