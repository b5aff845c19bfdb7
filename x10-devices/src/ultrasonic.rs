//! An ultrasonic range finder (HC-SR04, Parallax PING))) and alike) timed by pulse-in.

use x10_microcode::{Address, Edge, Level, Pin, Status};

use crate::error::{Error, Quantity, RangeError};
use crate::math::echo_to_distance;
use crate::port::Sensor;
use crate::units::Millimetres;
use crate::{Link, LinkError, Result};

/// Wiring and limits of an ultrasonic sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UltrasonicConfig {
    trigger: Option<Pin>,
    echo: Pin,
    timeout_ms: u16,
    max_range: Millimetres,
    speed_of_sound_m_s: u16,
}

impl UltrasonicConfig {
    /// An HC-SR04 on a sensor port: trigger on pin A, echo on pin B, 4 m range, echo timeout
    /// 30 ms (a 4 m echo is 23.3 ms; without an obstacle the HC-SR04 answers after ~38 ms),
    /// sound at 343 m/s (dry air at 20 °C).
    pub const HC_SR04: UltrasonicConfig = UltrasonicConfig {
        trigger: Some(Pin::A),
        echo: Pin::B,
        timeout_ms: 30,
        max_range: Millimetres(4000),
        speed_of_sound_m_s: 343,
    };

    /// A configuration. `trigger` `None` is a free-running sensor (it pulses by itself);
    /// `trigger == Some(echo)` a one-pin sensor such as the PING))).
    ///
    /// # Errors
    /// [`RangeError`] ([`Quantity::SpeedOfSound`]) for a speed of sound of 0.
    pub const fn new(
        trigger: Option<Pin>,
        echo: Pin,
        timeout_ms: u16,
        max_range: Millimetres,
        speed_of_sound_m_s: u16,
    ) -> core::result::Result<UltrasonicConfig, RangeError> {
        if let Err(e) = RangeError::check(
            Quantity::SpeedOfSound,
            speed_of_sound_m_s as i32,
            1,
            u16::MAX as i32,
        ) {
            return Err(e);
        }
        Ok(UltrasonicConfig {
            trigger,
            echo,
            timeout_ms,
            max_range,
            speed_of_sound_m_s,
        })
    }

    /// The distance an echo of `echo_us` means, or `None` beyond the range.
    pub fn distance(&self, echo_us: u32) -> Option<Millimetres> {
        let d = echo_to_distance(echo_us, self.speed_of_sound_m_s);
        (d <= self.max_range).then_some(d)
    }
}

/// An ultrasonic range finder on a sensor port: trigger pulse (HIGH then LOW on the trigger
/// pin: the write latency makes the pulse far longer than the 10 µs the HC-SR04 needs), then
/// a pulse-in on the echo pin, which the board times.
///
/// The echo must start after the pulse-in request reaches the board; an HC-SR04 starts its
/// echo about 0.5 ms after the trigger, longer than a pulse-in request takes at 400 kHz and
/// above. A missed echo reads as "nothing in range".
#[derive(Clone, Debug)]
pub struct Ultrasonic<L> {
    sensor: Sensor<L>,
    config: UltrasonicConfig,
}

impl<L: Link> Ultrasonic<L> {
    /// An [`UltrasonicConfig::HC_SR04`] on sensor port `number` (from 1) of board `db`.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Self::with_config(link, db, number, UltrasonicConfig::HC_SR04)
    }

    /// A sensor with its own wiring and limits.
    ///
    /// # Errors
    /// [`crate::Error::BadPort`] for 0 or above 64.
    pub fn with_config(link: L, db: Address, number: u8, config: UltrasonicConfig) -> Result<Self> {
        Ok(Ultrasonic {
            sensor: Sensor::new(link, db, number)?,
            config,
        })
    }

    /// The sensor port.
    pub fn sensor(&self) -> &Sensor<L> {
        &self.sensor
    }

    /// The configuration.
    pub fn config(&self) -> &UltrasonicConfig {
        &self.config
    }

    /// Triggers (if there is a trigger pin) and times one echo, in µs; `None` when no echo
    /// came before the timeout (the board's `timeout` status).
    ///
    /// # Errors
    /// [`crate::Error::Link`] for everything else.
    pub async fn echo_us(&self) -> Result<Option<u32>> {
        if let Some(t) = self.config.trigger {
            self.sensor.write_digital(t, Level::High).await?;
            self.sensor.write_digital(t, Level::Low).await?;
        }
        let echo = self
            .sensor
            .pulse_in(self.config.echo, Edge::Rising, Some(self.config.timeout_ms))
            .await;
        match echo {
            Ok(us) => Ok(Some(us)),
            Err(Error::Link(LinkError::Status(Status::Timeout))) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// The distance to the nearest obstacle; `None` when nothing is in range (no echo, or one
    /// beyond the configured range).
    ///
    /// # Errors
    /// As [`Ultrasonic::echo_us`].
    pub async fn distance(&self) -> Result<Option<Millimetres>> {
        Ok(self
            .echo_us()
            .await?
            .and_then(|us| self.config.distance(us)))
    }
}
