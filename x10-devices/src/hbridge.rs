//! An H-bridge (L293D, L298N, TB6612 and alike) on one actuator port.

use x10_microcode::{Address, Level, Pin};

use crate::port::Actuator;
use crate::units::{Direction, Duty};
use crate::{Link, Result};

/// An H-bridge on an actuator port, wired as the thesis's shield does:
///
/// | port pin | bridge input | role |
/// |---|---|---|
/// | digital A | IN1 | direction |
/// | digital B | IN2 | direction |
/// | PWM A | EN (enable) | speed: duty 0–255 |
/// | PWM B | — | not used, free for something else |
///
/// | state | IN1 (digital A) | IN2 (digital B) | EN (PWM A) |
/// |---|---|---|---|
/// | forward | HIGH | LOW | duty |
/// | reverse | LOW | HIGH | duty |
/// | brake (motor terminals shorted) | HIGH | HIGH | 255 |
/// | coast = **stopped** | LOW | LOW | 0 |
///
/// "Stopped" is coast: both inputs LOW and no enable, the state the daughterboard's failsafe
/// (`SafeState::ALL_LOW`) and a board reset also leave, so every way of stopping agrees.
///
/// Each command is three writes, ordered so that no frame in between drives the motor in a
/// direction or at a duty nobody asked for:
/// * forward / reverse: the direction pin that goes LOW first, then the PWM duty, then the pin
///   that goes HIGH. A direction change passes through coast (both LOW), never through brake,
///   and the new direction is driven only once its duty is set: a reversal never drives the
///   new direction at the old duty (it did when the duty came last). From a brake (both
///   HIGH, enable 255) the first write would drive the new direction at full enable: coast
///   first ([`crate::DcMotor`] does).
/// * coast / stop: the enable 0 first, then both pins LOW.
/// * brake: both pins HIGH, then the enable 255.
///
/// If a write fails, the later ones are not sent and the error is returned.
#[derive(Clone, Debug)]
pub struct HBridge<L> {
    port: Actuator<L>,
}

impl<L: Link> HBridge<L> {
    /// The bridge on actuator port `number` (from 1) of board `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Ok(Self::from_actuator(Actuator::new(link, db, number)?))
    }

    /// The bridge on an actuator port.
    pub fn from_actuator(port: Actuator<L>) -> Self {
        HBridge { port }
    }

    /// The actuator port.
    pub fn actuator(&self) -> &Actuator<L> {
        &self.port
    }

    async fn apply(&self, first: (Pin, Level), second: (Pin, Level), duty: Duty) -> Result<()> {
        self.port.write_digital(first.0, first.1).await?;
        self.port.pwm(Pin::A, duty).await?;
        self.port.write_digital(second.0, second.1).await
    }

    /// Forward at `duty`: B LOW, A HIGH, PWM A `duty`.
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn forward(&self, duty: Duty) -> Result<()> {
        self.apply((Pin::B, Level::Low), (Pin::A, Level::High), duty)
            .await
    }

    /// Reverse at `duty`: A LOW, B HIGH, PWM A `duty`.
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn reverse(&self, duty: Duty) -> Result<()> {
        self.apply((Pin::A, Level::Low), (Pin::B, Level::High), duty)
            .await
    }

    /// [`HBridge::forward`] or [`HBridge::reverse`].
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn drive(&self, direction: Direction, duty: Duty) -> Result<()> {
        match direction {
            Direction::Forward => self.forward(duty).await,
            Direction::Reverse => self.reverse(duty).await,
        }
    }

    /// Brake (short the motor): A HIGH, B HIGH, PWM A 255.
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn brake(&self) -> Result<()> {
        // Both pins before the enable: from forward or reverse the first write already brakes,
        // from coast it drives nothing (enable 0); raising the enable before both pins were
        // HIGH would drive one direction at full power for a frame.
        self.port.write_digital(Pin::A, Level::High).await?;
        self.port.write_digital(Pin::B, Level::High).await?;
        self.port.pwm(Pin::A, Duty::FULL).await
    }

    /// Coast, the stopped state: A LOW, B LOW, PWM A 0.
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn coast(&self) -> Result<()> {
        // The enable first: from any state (a brake included, where lowering one pin would
        // drive the other direction at full power) nothing is driven after the first write.
        self.port.pwm(Pin::A, Duty::OFF).await?;
        self.port.write_digital(Pin::A, Level::Low).await?;
        self.port.write_digital(Pin::B, Level::Low).await
    }

    /// Stops: the same as [`HBridge::coast`].
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn stop(&self) -> Result<()> {
        self.coast().await
    }
}
