//! The robot runner: `setup` once, then `step` at a fixed period, forever.

use embassy_futures::yield_now;
use x10_devices::{LinkError, Robot};
use x10_hal::time::Clock;

/// Which part of a robot program returned an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RobotPhase {
    /// [`Robot::setup`].
    Setup,
    /// [`Robot::step`].
    Step,
}

/// Runs `robot`: `setup` once, then `step` every `period_us` (on a fixed grid; a step that
/// overruns its period is followed at once by the next). An error is logged and the program
/// goes on: a board that NACKs once should not stop the robot. Never returns.
pub async fn run_robot<R: Robot, C: Clock>(robot: R, clock: C, period_us: u64) -> ! {
    run_robot_with(robot, clock, period_us, |phase, e| {
        error!("robot {}: {}", phase, e);
    })
    .await
}

/// [`run_robot`], calling `on_error` for every error (the simulator traces them).
pub async fn run_robot_with<R, C, F>(mut robot: R, clock: C, period_us: u64, mut on_error: F) -> !
where
    R: Robot,
    C: Clock,
    F: FnMut(RobotPhase, LinkError),
{
    if let Err(e) = robot.setup().await {
        on_error(RobotPhase::Setup, e);
    }
    let mut next = clock.now();
    loop {
        if let Err(e) = robot.step().await {
            on_error(RobotPhase::Step, e);
        }
        next = next.plus_us(period_us);
        let now = clock.now();
        if next < now {
            next = now;
        }
        clock.sleep_until(next).await;
        // A zero period, or a step that never awaits, must still let other tasks run.
        yield_now().await;
    }
}
