//! The shape of a robot program.

use crate::LinkError;

/// A robot program: `setup` once, then `step` again and again, like an Arduino sketch's
/// `setup()` and `loop()`.
///
/// The same program value runs on the motherboard firmware and in the simulator; both call it
/// through the motherboard runtime's robot runner, which logs an `Err` from `step` and keeps
/// going (a board that NACKs once should not stop the robot). Several programs run side by side
/// as separate tasks, which is how a module is added without touching existing code.
#[allow(async_fn_in_trait)]
pub trait Robot {
    /// Runs once before the first step.
    ///
    /// # Errors
    /// Whatever the program's drivers report.
    async fn setup(&mut self) -> Result<(), LinkError> {
        Ok(())
    }

    /// One pass of the control loop.
    ///
    /// # Errors
    /// Whatever the program's drivers report.
    async fn step(&mut self) -> Result<(), LinkError>;
}
