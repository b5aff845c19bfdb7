//! A robot declared once: [`robot!`](crate::robot) names its tasks, and the simulator, the
//! tests and the board images all take them from there.
//!
//! ```
//! use x10::{DigitalOutput, Error, Pin, SELF, X10};
//!
//! pub async fn blink(x10: X10) -> Result<(), Error> {
//!     let mut led = DigitalOutput::new(x10, SELF, 2, Pin::A)?;
//!     loop {
//!         led.toggle().await?;
//!         embassy_time::Timer::after_millis(500).await;
//!     }
//! }
//!
//! pub async fn drive(x10: X10) -> Result<(), Error> {
//!     # let _ = x10;
//!     Ok(())
//! }
//!
//! x10::robot! {
//!     /// My robot: a heartbeat and a drive loop.
//!     pub struct Robot { blink, drive }
//! }
//!
//! use x10::Robot as _;
//! assert_eq!(Robot::TASKS, ["blink", "drive"]);
//! ```
//!
//! * In the simulator: `sim.robot(robot::Robot)` (x10-sim), or in a robot crate's `sim.rs`,
//!   `x10_cli::app::main("world.toml", |sim| sim.robot(robot::Robot))`.
//! * On a board: the image's `main` calls `robot::Robot.spawn(spawner, x10)`, which spawns one
//!   embassy task per robot task (each logs, over defmt, the error that ends it). This part is
//!   compiled for the boards only (`target_os = "none"`), and needs `embassy-executor` among
//!   the robot crate's dependencies for those targets, as `x10 new` writes it.
//!
//! A task that lives in another module is named with its path: `pub struct Fig4_4 {
//! single_board: crate::fig4_2::single_board, light_motor }`.

use core::convert::Infallible;
use core::future::Future;

use crate::{Error, X10};

/// How a robot task ended: `()`, never ([`Infallible`]), or a `Result` whose error is an
/// [`Error`].
pub trait TaskEnd {
    /// The error the task ended with, if it ended with one.
    fn into_error(self) -> Option<Error>;
}

impl TaskEnd for () {
    fn into_error(self) -> Option<Error> {
        None
    }
}

impl TaskEnd for Infallible {
    fn into_error(self) -> Option<Error> {
        match self {}
    }
}

impl<T> TaskEnd for Result<T, Error> {
    fn into_error(self) -> Option<Error> {
        self.err()
    }
}

/// Somewhere a robot's tasks run: the simulator implements it (`x10_sim::sim::Sim`); on a
/// board, [`robot!`](crate::robot) spawns embassy tasks instead.
pub trait Tasks {
    /// Runs `task(x10)` as a task called `name`.
    fn task<F, Fut>(&mut self, name: &'static str, task: F)
    where
        F: FnOnce(X10) -> Fut + 'static,
        Fut: Future + 'static,
        Fut::Output: TaskEnd;
}

/// A robot: its name and its tasks, declared once with [`robot!`](crate::robot).
pub trait Robot {
    /// The robot's name (the name of the type [`robot!`](crate::robot) declared).
    const NAME: &'static str;
    /// Its tasks' names, in the order they start.
    const TASKS: &'static [&'static str];
    /// Hands every task to `tasks`, in the order of [`Robot::TASKS`].
    fn tasks<T: Tasks>(tasks: &mut T);
}

/// Logs how a task ended (over defmt, with the `defmt` feature): what a board image's task
/// wrapper does with the value its robot task returned. Used by [`robot!`](crate::robot).
pub fn task_ended(name: &str, end: impl TaskEnd) {
    let error = end.into_error();
    #[cfg(feature = "defmt")]
    match error {
        Some(e) => defmt::warn!("{=str} ended: {}", name, e),
        None => defmt::info!("{=str} ended", name),
    }
    #[cfg(not(feature = "defmt"))]
    let _ = (name, error);
}

/// Declares a robot once: a unit struct that implements [`Robot`], naming its tasks (plain
/// `async fn(X10)`s), and, on the boards, `Robot.spawn(spawner, x10)`.
///
/// ```
/// # use x10::{Error, X10};
/// # pub async fn heartbeat(_: X10) -> Result<(), Error> { Ok(()) }
/// # pub mod drive { pub async fn run(_: x10::X10) -> Result<(), x10::Error> { Ok(()) } }
/// x10::robot! {
///     /// Two tasks: `heartbeat` here, and `drive` from another module.
///     pub struct Rover { heartbeat, drive: drive::run }
/// }
/// # use x10::Robot as _;
/// # assert_eq!(Rover::NAME, "Rover");
/// ```
///
/// On a board (`target_os = "none"`) it also generates one `#[embassy_executor::task]` per
/// task and
///
/// ```ignore
/// impl Rover {
///     pub fn spawn(self, spawner: embassy_executor::Spawner, x10: x10::X10)
///         -> Result<(), embassy_executor::SpawnError>;
/// }
/// ```
///
/// which the image's `main` calls once: `unwrap!(robot::Rover.spawn(spawner, x10));`.
#[macro_export]
macro_rules! robot {
    (
        $(#[$attr:meta])*
        $vis:vis struct $robot:ident { $( $task:ident $(: $path:path)? ),+ $(,)? }
    ) => {
        $(#[$attr])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        $vis struct $robot;

        impl $crate::Robot for $robot {
            const NAME: &'static str = stringify!($robot);
            const TASKS: &'static [&'static str] = &[$(stringify!($task)),+];
            fn tasks<T: $crate::Tasks>(tasks: &mut T) {
                $( tasks.task(stringify!($task), $crate::__robot_task!(here $task $(, $path)?)); )+
            }
        }

        #[cfg(target_os = "none")]
        const _: () = {
            $(
                #[embassy_executor::task]
                async fn $task(x10: $crate::X10) {
                    $crate::task_ended(
                        stringify!($task),
                        $crate::__robot_task!(module $task $(, $path)?)(x10).await,
                    );
                }
            )+

            impl $robot {
                /// Spawns one embassy task per robot task, in the order they were declared.
                ///
                /// # Errors
                /// `SpawnError` when called a second time (each task exists once).
                pub fn spawn(
                    self,
                    spawner: embassy_executor::Spawner,
                    x10: $crate::X10,
                ) -> Result<(), embassy_executor::SpawnError> {
                    $( spawner.spawn($task(x10)?); )+
                    Ok(())
                }
            }
        };
    };
}

/// The function of a task in [`robot!`](crate::robot): its path when one is given, else the
/// function of that name where the robot is declared (`here`), or in its module (`module`:
/// inside the block of the board's task wrappers, whose names hide the functions').
#[doc(hidden)]
#[macro_export]
macro_rules! __robot_task {
    (here $task:ident) => {
        $task
    };
    (module $task:ident) => {
        self::$task
    };
    ($where:ident $task:ident, $path:path) => {
        $path
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    extern crate std;
    use std::vec::Vec;

    async fn first(_x10: X10) -> Result<(), Error> {
        Ok(())
    }

    async fn second(_x10: X10) -> Result<core::convert::Infallible, Error> {
        Err(Error::WrongPortKind)
    }

    mod elsewhere {
        pub async fn third(_x10: crate::X10) {}
    }

    crate::robot! {
        /// Three tasks, one of them from another module.
        struct Three { first, second, third: elsewhere::third }
    }

    /// Records the names it is handed (x10-sim's tests run such robots for real).
    struct Names(Vec<&'static str>);

    impl Tasks for Names {
        fn task<F, Fut>(&mut self, name: &'static str, _task: F)
        where
            F: FnOnce(X10) -> Fut + 'static,
            Fut: Future + 'static,
            Fut::Output: TaskEnd,
        {
            self.0.push(name);
        }
    }

    #[test]
    fn every_task_is_handed_over_once_in_order() {
        assert_eq!(Three::NAME, "Three");
        assert_eq!(Three::TASKS, ["first", "second", "third"]);
        let mut names = Names(Vec::new());
        Three::tasks(&mut names);
        assert_eq!(names.0, Three::TASKS);
    }

    #[test]
    fn a_task_end_gives_its_error_or_none() {
        assert_eq!(().into_error(), None);
        assert_eq!(Ok::<u8, Error>(3).into_error(), None);
        assert_eq!(
            Err::<(), Error>(Error::WrongPortKind).into_error(),
            Some(Error::WrongPortKind)
        );
    }
}
