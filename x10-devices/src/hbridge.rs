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
/// Each command is three writes: the direction pin that goes LOW first, then the one that goes
/// HIGH, then the PWM duty. So a direction change passes through coast (both LOW), never through
/// brake, and the new duty is applied only once the direction is right. If a write fails, the
/// later ones are not sent and the error is returned.
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
        self.port.write_digital(second.0, second.1).await?;
        self.port.pwm(Pin::A, duty).await
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
        self.apply((Pin::A, Level::High), (Pin::B, Level::High), Duty::FULL)
            .await
    }

    /// Coast, the stopped state: A LOW, B LOW, PWM A 0.
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn coast(&self) -> Result<()> {
        self.apply((Pin::A, Level::Low), (Pin::B, Level::Low), Duty::OFF)
            .await
    }

    /// Stops: the same as [`HBridge::coast`].
    ///
    /// # Errors
    /// [`crate::Error::Link`] of the first write that failed.
    pub async fn stop(&self) -> Result<()> {
        self.coast().await
    }
}
