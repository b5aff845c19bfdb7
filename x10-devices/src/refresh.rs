//! When to re-assert an actuator's state that did not change.

use crate::error::{Quantity, RangeError};

/// Counts the steps of a control loop and says when an actuator's state is due to be sent
/// again although it did not change.
///
/// A program that sends an actuator command only when the wanted state changes leaves the
/// bus to its sensor reads, but trusts that the board still holds what it was told. A board
/// that resets (brown-out, watchdog, a technician's reset button) comes back in its safe state
/// (motor coasting, outputs LOW) and nobody tells the program; a glitch on an output driver
/// goes unnoticed the same way. The embedded answer is to re-assert outputs periodically:
/// send the state at least every `steps` steps, changed or not, so that a lost state is
/// restored within `steps` × the step period. A forgotten state (after a failed command, see
/// [`crate::DcMotor::invalidate`]) is re-sent at the next step anyway; this bounds the case
/// where no call failed.
///
/// The count is of steps, not time, so a program stays deterministic and needs no clock; the
/// bound in time is `steps` × the runner's step period.
///
/// ```
/// # use x10_devices::Refresh;
/// let mut refresh = Refresh::every(3).unwrap();
/// refresh.restart(); // the state was just sent
/// assert_eq!([refresh.tick(), refresh.tick(), refresh.tick()], [false, false, true]);
/// assert!(refresh.tick()); // still due: nothing was sent
/// refresh.restart();
/// assert!(!refresh.tick());
/// ```
///
/// [`crate::Kept`] pairs it with an output and does this once per step: tick; if due or the
/// wanted state differs from the last one sent, send it and restart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Refresh {
    steps: u16,
    age: u16,
}

impl Refresh {
    /// Due on every `steps`-th [`Refresh::tick`] after the last [`Refresh::restart`] (or after
    /// it was made); 1 means every step.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::RefreshSteps`]) for 0.
    pub const fn every(steps: u16) -> Result<Refresh, RangeError> {
        match RangeError::check(Quantity::RefreshSteps, steps as i32, 1, u16::MAX as i32) {
            Ok(()) => Ok(Refresh { steps, age: 0 }),
            Err(e) => Err(e),
        }
    }

    /// The interval in steps.
    pub const fn steps(&self) -> u16 {
        self.steps
    }

    /// Counts one step; true when `steps` steps have passed since the last
    /// [`Refresh::restart`]: the state is due to be sent. It stays due until `restart`.
    pub fn tick(&mut self) -> bool {
        self.age = self.age.saturating_add(1);
        self.age >= self.steps
    }

    /// The state has just been sent successfully: the count starts again.
    pub fn restart(&mut self) {
        self.age = 0;
    }
}
