//! # x10-robots: the thesis's robot programs
//!
//! Robot programs live here, in a plain `no_std` library generic over the link
//! (`L: Link + Clone`), so the same source compiles into the motherboard firmware (with the
//! motherboard runtime's handle as `L`) and runs in the simulator (with the simulated
//! motherboard's handle), and in tests against the recording double.
//!
//! | program | module(s) | boards | what it does |
//! |---|---|---|---|
//! | `fig4_2` | [`fig4_2`] | SELF | button or force sensor > 100 runs the motor at full speed |
//! | `fig4_4` | [`fig4_2`] + [`light_motor`] | SELF, 9 | the same, plus: light > 700 runs a second motor at 50 % |
//! | `fig4_6` | [`fig4_6`] | 17, 108, 10 | freezer > 1 °C or oven < 200 °F raises an alarm |
//!
//! ## Picking a program by name
//! [`names`] lists the programs; [`Program::from_name`] (or `str::parse`) picks one;
//! [`Program::build`] makes its robots, one [`AnyRobot`] per task (at most [`MAX_ROBOTS`]):
//!
//! ```
//! # use x10_robots::{Program, AnyRobot};
//! # use x10_devices::{testing::RecordingLink, Robot};
//! let link = RecordingLink::<8>::new();
//! let program = Program::from_name("fig4_4").unwrap();
//! let robots = program.build(&link).unwrap();
//! let names: Vec<&str> = robots.iter().map(AnyRobot::name).collect();
//! assert_eq!(names, ["single_board", "light_motor"]);
//! ```
//!
//! A firmware runs each robot in its own task (embassy tasks cannot be generic, hence the
//! [`AnyRobot`] enum over one concrete link type):
//!
//! ```text
//! #[embassy_executor::task(pool_size = x10_robots::MAX_ROBOTS)]
//! async fn robot_task(mut robot: AnyRobot<MbHandle>) {
//!     if let Err(e) = robot.setup().await { warn!("{}: setup: {}", robot.name(), e) }
//!     loop { if let Err(e) = robot.step().await { warn!("{}: {}", robot.name(), e) } }
//! }
//! for robot in Program::Fig4_4.build(handle)? { spawner.spawn(robot_task(robot).unwrap()) }
//! ```
//!
//! ## Keeping the actuators driven
//! The programs send an actuator command when the wanted state changes, and also every
//! [`REFRESH_STEPS`] steps without a change, and at the next step after a failed call to the
//! actuator's board. A daughterboard that resets comes back in its safe state without the
//! program noticing (its calls may not even fail); the periodic re-send restores the state
//! within [`REFRESH_STEPS`] steps, the re-send after a failure usually at once. Each robot
//! holds its actuator as an [`x10_devices::Kept`] output and calls its `keep` once per step.
//!
//! Adding a module the way Figure 4.4 does is adding a `Robot` type in its own module and
//! listing it in a program; no existing robot's code changes ([`light_motor`] explains).
#![no_std]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)
)]

use core::fmt;
use core::str::FromStr;

use x10_devices::{Address, Error, Link, LinkError, Refresh, Robot, SELF};

pub mod fig4_2;
pub mod fig4_6;
pub mod light_motor;

pub use fig4_2::SingleBoard;
pub use fig4_6::TemperatureAlarm;
pub use light_motor::LightMotor;

/// Most robots (tasks) one program has.
pub const MAX_ROBOTS: usize = 2;

/// Every robot re-sends its actuator state at least every this many steps, changed or not
/// (see [`x10_devices::Refresh`]), so a daughterboard that reset and fell back to its safe
/// state (motor coasting, alarm LOW) is driven again within 25 steps: 250 ms at the
/// simulator's 10 ms step period, 500 ms at the firmware's 20 ms. After a failed call the
/// state is sent again at the next step (each robot's documentation says which calls).
pub const REFRESH_STEPS: u16 = 25;

/// [`REFRESH_STEPS`] as a [`Refresh`].
const REFRESH: Refresh = match Refresh::every(REFRESH_STEPS) {
    Ok(r) => r,
    // Evaluated at compile time: a bad constant fails the build, never the robot.
    Err(_) => panic!("REFRESH_STEPS is at least 1"),
};

/// The robots of one program, one per task.
pub type Robots<L> = heapless::Vec<AnyRobot<L>, MAX_ROBOTS>;

/// The programs, by name.
pub fn names() -> &'static [&'static str] {
    &NAMES
}

const NAMES: [&str; 3] = [
    Program::Fig4_2.name(),
    Program::Fig4_4.name(),
    Program::Fig4_6.name(),
];

/// A robot program of the thesis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Program {
    /// Figure 4.2: one board, button or force sensor drives a motor.
    Fig4_2,
    /// Figure 4.4: Figure 4.2 plus the light-sensor module on board 9, as a second robot.
    Fig4_4,
    /// Figure 4.6: two thermistors raise an alarm.
    Fig4_6,
}

/// A name that is not one of [`names`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownProgram;

impl fmt::Display for UnknownProgram {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown program (known: fig4_2, fig4_4, fig4_6)")
    }
}

impl core::error::Error for UnknownProgram {}

impl Program {
    /// Every program.
    pub const ALL: [Program; 3] = [Program::Fig4_2, Program::Fig4_4, Program::Fig4_6];

    /// The name used on the command line and in the firmware's build configuration.
    pub const fn name(self) -> &'static str {
        match self {
            Program::Fig4_2 => "fig4_2",
            Program::Fig4_4 => "fig4_4",
            Program::Fig4_6 => "fig4_6",
        }
    }

    /// The program called `name` (exactly as [`Program::name`] spells it).
    pub fn from_name(name: &str) -> Option<Program> {
        Program::ALL.into_iter().find(|p| p.name() == name)
    }

    /// One line about the program.
    pub const fn description(self) -> &'static str {
        match self {
            Program::Fig4_2 => {
                "thesis Fig. 4.2: button (SELF S2.B) or force (SELF S1) > 100 runs the motor (SELF A1) at 100 %"
            }
            Program::Fig4_4 => {
                "thesis Fig. 4.4: Fig. 4.2 plus, as a second task, light (DB 9 S1) > 700 runs a motor (DB 9 A1) at 50 %"
            }
            Program::Fig4_6 => {
                "thesis Fig. 4.6: freezer (DB 17 S1) > 1 °C or oven (DB 108 S6) < 200 °F raises the alarm (DB 10 A3.A)"
            }
        }
    }

    /// The daughterboards the program talks to (SELF is the internal one).
    pub const fn boards(self) -> &'static [Address] {
        const FIG4_2: [Address; 1] = [SELF];
        const FIG4_4: [Address; 2] = [SELF, light_motor::BOARD];
        const FIG4_6: [Address; 3] = [fig4_6::FREEZER, fig4_6::OVEN, fig4_6::CONTROL_BOARD];
        match self {
            Program::Fig4_2 => &FIG4_2,
            Program::Fig4_4 => &FIG4_4,
            Program::Fig4_6 => &FIG4_6,
        }
    }

    /// Names of the program's robots, one per task, in [`Program::build`]'s order.
    pub const fn robot_names(self) -> &'static [&'static str] {
        match self {
            Program::Fig4_2 => &["single_board"],
            Program::Fig4_4 => &["single_board", "light_motor"],
            Program::Fig4_6 => &["temperature_alarm"],
        }
    }

    /// The program's robots on `link`, one per task.
    ///
    /// # Errors
    /// What the robots' constructors report (nothing with the thesis's constant wiring).
    pub fn build<L: Link + Clone>(self, link: L) -> Result<Robots<L>, Error> {
        Ok(match self {
            Program::Fig4_2 => Robots::from_array([AnyRobot::SingleBoard(SingleBoard::new(link)?)]),
            Program::Fig4_4 => Robots::from_array([
                AnyRobot::SingleBoard(SingleBoard::new(link.clone())?),
                AnyRobot::LightMotor(LightMotor::new(link)?),
            ]),
            Program::Fig4_6 => {
                Robots::from_array([AnyRobot::TemperatureAlarm(TemperatureAlarm::new(link)?)])
            }
        })
    }
}

impl FromStr for Program {
    type Err = UnknownProgram;

    fn from_str(s: &str) -> Result<Program, UnknownProgram> {
        Program::from_name(s).ok_or(UnknownProgram)
    }
}

impl fmt::Display for Program {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Any robot of this crate: one type for a firmware's task pool.
#[derive(Clone, Debug)]
pub enum AnyRobot<L> {
    /// Figure 4.2.
    SingleBoard(SingleBoard<L>),
    /// Figure 4.4's added module.
    LightMotor(LightMotor<L>),
    /// Figure 4.6.
    TemperatureAlarm(TemperatureAlarm<L>),
}

impl<L> AnyRobot<L> {
    /// The robot's name (as in [`Program::robot_names`]).
    pub fn name(&self) -> &'static str {
        match self {
            AnyRobot::SingleBoard(_) => "single_board",
            AnyRobot::LightMotor(_) => "light_motor",
            AnyRobot::TemperatureAlarm(_) => "temperature_alarm",
        }
    }
}

impl<L: Link> Robot for AnyRobot<L> {
    async fn setup(&mut self) -> Result<(), LinkError> {
        match self {
            AnyRobot::SingleBoard(r) => r.setup().await,
            AnyRobot::LightMotor(r) => r.setup().await,
            AnyRobot::TemperatureAlarm(r) => r.setup().await,
        }
    }

    async fn step(&mut self) -> Result<(), LinkError> {
        match self {
            AnyRobot::SingleBoard(r) => r.step().await,
            AnyRobot::LightMotor(r) => r.step().await,
            AnyRobot::TemperatureAlarm(r) => r.step().await,
        }
    }
}
