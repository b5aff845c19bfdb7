//! One digital pin of an actuator port driven as an output (an alarm, a relay, a lamp).

use x10_microcode::{Address, Level, Pin};

use crate::kept::Output;
use crate::port::Actuator;
use crate::{Link, Result};

/// Digital pin `pin` of an actuator port, driven HIGH or LOW (`IO HIGH` `0x12` / `IO LOW`
/// `0x11`) through its [`Output`] methods, which remember the level last written successfully
/// so that a [`crate::Kept`] can keep it asserted. A board's safe state (after a reset or its
/// failsafe) is LOW.
#[derive(Clone, Debug)]
pub struct DigitalOutput<L> {
    port: Actuator<L>,
    pin: Pin,
    level: Option<Level>,
}

impl<L: Link> DigitalOutput<L> {
    /// Pin `pin` of actuator port `number` (from 1) of board `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8, pin: Pin) -> Result<Self> {
        Ok(Self::from_actuator(Actuator::new(link, db, number)?, pin))
    }

    /// Pin `pin` of an actuator port.
    pub fn from_actuator(port: Actuator<L>, pin: Pin) -> Self {
        DigitalOutput {
            port,
            pin,
            level: None,
        }
    }

    /// The actuator port.
    pub fn actuator(&self) -> &Actuator<L> {
        &self.port
    }

    /// The pin.
    pub fn pin(&self) -> Pin {
        self.pin
    }

    /// The level last written successfully (`None` before the first, after a failure).
    pub fn level(&self) -> Option<Level> {
        self.level
    }

    /// Drives the pin HIGH (one write).
    ///
    /// # Errors
    /// [`crate::Error::Link`]; the level is then unknown.
    pub async fn high(&mut self) -> Result<()> {
        Output::set(self, Level::High).await
    }

    /// Drives the pin LOW (one write).
    ///
    /// # Errors
    /// [`crate::Error::Link`]; the level is then unknown.
    pub async fn low(&mut self) -> Result<()> {
        Output::set(self, Level::Low).await
    }

    /// Drives the pin to the other level (HIGH when the level is unknown); returns the level
    /// written.
    ///
    /// # Errors
    /// [`crate::Error::Link`]; the level is then unknown.
    pub async fn toggle(&mut self) -> Result<Level> {
        let next = match self.level {
            Some(Level::High) => Level::Low,
            _ => Level::High,
        };
        Output::set(self, next).await?;
        Ok(next)
    }
}

/// The level: `state()` is the level last written successfully (`None` before the first,
/// after a failed write, after `invalidate()`); `set(level)` is one write.
impl<L: Link> Output for DigitalOutput<L> {
    type State = Level;

    fn state(&self) -> Option<Level> {
        self.level
    }

    fn invalidate(&mut self) {
        self.level = None;
    }

    /// Drives the pin to `level` (one write).
    ///
    /// # Errors
    /// [`crate::Error::Link`]; the level is then unknown (`None`).
    async fn set(&mut self, level: Level) -> Result<()> {
        self.level = None;
        self.port.write_digital(self.pin, level).await?;
        self.level = Some(level);
        Ok(())
    }
}
