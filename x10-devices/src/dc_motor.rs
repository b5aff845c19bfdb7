//! A DC motor on an H-bridge, with a signed speed and an optional ramp.

use embedded_hal_async::delay::DelayNs;
use x10_microcode::Address;

use crate::error::{Quantity, RangeError};
use crate::hbridge::HBridge;
use crate::kept::Output;
use crate::math::ramp_next;
use crate::units::{Direction, Percent, Speed};
use crate::{Link, Result};

/// How a ramp moves: at most `step` percent per command, `interval_ms` apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ramp {
    step: Percent,
    interval_ms: u32,
}

impl Ramp {
    /// A ramp of `step` percent (1 to 100) every `interval_ms`.
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::RampStep`]) for a step of 0 (it would never arrive) or
    /// above 100.
    pub const fn new(step: u8, interval_ms: u32) -> core::result::Result<Ramp, RangeError> {
        match RangeError::check(Quantity::RampStep, step as i32, 1, 100) {
            Ok(()) => Ok(Ramp {
                step: Percent(step),
                interval_ms,
            }),
            Err(e) => Err(e),
        }
    }

    /// Percent per step.
    pub const fn step(&self) -> Percent {
        self.step
    }

    /// Milliseconds between steps.
    pub const fn interval_ms(&self) -> u32 {
        self.interval_ms
    }
}

/// A DC motor on an [`HBridge`]: speed `-100..=100` % as a [`Speed`]. Positive is the bridge's
/// forward, negative its reverse (really reverse: the direction pins swap), 0 is the bridge's
/// stopped state (coast).
#[derive(Clone, Debug)]
pub struct DcMotor<L> {
    bridge: HBridge<L>,
    speed: Option<Speed>,
    /// The last command was a brake that succeeded: both inputs HIGH at full enable.
    braking: bool,
}

impl<L: Link> DcMotor<L> {
    /// The motor on the H-bridge of actuator port `number` (from 1) of board `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Ok(Self::from_bridge(HBridge::new(link, db, number)?))
    }

    /// The motor on `bridge`.
    pub fn from_bridge(bridge: HBridge<L>) -> Self {
        DcMotor {
            bridge,
            speed: None,
            braking: false,
        }
    }

    /// The bridge.
    pub fn bridge(&self) -> &HBridge<L> {
        &self.bridge
    }

    /// The speed last set successfully; `None` before the first, after a failed command (the
    /// bridge may be half-way), after [`DcMotor::brake`] and after [`DcMotor::invalidate`].
    pub fn speed(&self) -> Option<Speed> {
        self.speed
    }

    /// Forgets the speed (sends nothing): [`DcMotor::speed`] is `None` until the next
    /// successful [`DcMotor::set_speed`], so a program that compares it with the speed it
    /// wants (as [`crate::Kept::keep`] does) sends the command again, and [`DcMotor::ramp_to`] starts from 0.
    ///
    /// Call it when the board may have lost the state without a failed motor command: after
    /// any failed call to the motor's board (a NACK or timeout may be the board resetting,
    /// and a reset leaves the bridge coasting), or when the board reports a boot.
    pub fn invalidate(&mut self) {
        self.speed = None;
    }

    /// Sets the speed at once (three writes, see [`HBridge`]).
    ///
    /// # Errors
    /// [`crate::Error::Link`]; the speed is then unknown (`None`).
    pub async fn set_speed(&mut self, speed: Speed) -> Result<()> {
        self.speed = None;
        // Leaving a brake (both inputs HIGH, enable 255): the first write of a drive command
        // (the pin going LOW) would drive the new direction at full duty for one frame, so
        // the bridge coasts first.
        if core::mem::take(&mut self.braking) && speed.direction().is_some() {
            self.bridge.coast().await?;
        }
        let duty = speed.magnitude().to_duty();
        match speed.direction() {
            Some(Direction::Forward) => self.bridge.forward(duty).await?,
            Some(Direction::Reverse) => self.bridge.reverse(duty).await?,
            None => self.bridge.coast().await?,
        }
        self.speed = Some(speed);
        Ok(())
    }

    /// Sets the speed from a plain percentage.
    ///
    /// # Errors
    /// [`crate::Error::Range`] ([`Quantity::Speed`]) outside `-100..=100`, before anything is
    /// sent; otherwise as [`DcMotor::set_speed`].
    pub async fn set_percent(&mut self, percent: i8) -> Result<()> {
        self.set_speed(Speed::new(percent)?).await
    }

    /// Stops (coast: both bridge inputs LOW, no enable).
    ///
    /// # Errors
    /// As [`DcMotor::set_speed`].
    pub async fn stop(&mut self) -> Result<()> {
        self.set_speed(Speed::STOP).await
    }

    /// Brakes (both bridge inputs HIGH, enable full). The speed is then `None`: braking is
    /// not a speed.
    ///
    /// # Errors
    /// [`crate::Error::Link`].
    pub async fn brake(&mut self) -> Result<()> {
        self.speed = None;
        self.braking = false;
        self.bridge.brake().await?;
        self.braking = true;
        Ok(())
    }

    /// Ramps from the current speed (0 when unknown) to `target`, one [`DcMotor::set_speed`]
    /// per step of `ramp`, waiting `ramp.interval_ms()` on `delay` between steps (not after
    /// the last). A direction change stops at 0 on the way. Already at `target`: sends
    /// nothing.
    ///
    /// Any [`DelayNs`] works: `embassy_time::Delay`, on a board and in the simulator (whose
    /// embassy-time runs in virtual time).
    ///
    /// # Errors
    /// As [`DcMotor::set_speed`]; the ramp stops at the failed step.
    pub async fn ramp_to<D: DelayNs>(
        &mut self,
        target: Speed,
        ramp: Ramp,
        delay: &mut D,
    ) -> Result<()> {
        let mut current = self.speed.unwrap_or(Speed::STOP);
        if self.speed == Some(target) {
            return Ok(());
        }
        loop {
            let next = ramp_next(current, target, ramp.step);
            self.set_speed(next).await?;
            if next == target {
                return Ok(());
            }
            current = next;
            delay.delay_ms(ramp.interval_ms).await;
        }
    }
}

impl<L: Link> Output for DcMotor<L> {
    type State = Speed;

    fn state(&self) -> Option<Speed> {
        self.speed
    }

    fn invalidate(&mut self) {
        self.speed = None;
    }

    async fn set(&mut self, speed: Speed) -> Result<()> {
        self.set_speed(speed).await
    }
}
