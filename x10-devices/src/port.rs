//! The generic port drivers, the thesis's `Sensor` and `Actuator` classes: one method per
//! microcode operation of a port. Every device driver is built from these two.

use x10_microcode::{Address, Edge, EventConfig, Level, Op, Payload, Pin, PinRef, Port, PortKind};

use crate::error::{Error, Quantity, RangeError};
use crate::units::Duty;
use crate::{Link, LinkError, PinEvent, Result};

/// A port of one kind on one board, and the link to reach it: what `Sensor` and `Actuator`
/// share.
#[derive(Clone, Debug)]
struct PortLink<L> {
    link: L,
    db: Address,
    port: Port,
}

fn level_of(payload: &[u8]) -> Result<Level> {
    match *payload {
        [0] => Ok(Level::Low),
        [1] => Ok(Level::High),
        _ => Err(Error::Link(LinkError::BadReply)),
    }
}

impl<L: Link> PortLink<L> {
    fn new(link: L, db: Address, kind: PortKind, number: u8) -> Result<Self> {
        let port = Port::new(kind, number).map_err(|_| Error::BadPort(number))?;
        Ok(PortLink { link, db, port })
    }

    fn at(link: L, db: Address, kind: PortKind, port: Port) -> Result<Self> {
        if port.kind() != kind {
            return Err(Error::WrongPortKind);
        }
        Ok(PortLink { link, db, port })
    }

    async fn call(&self, op: Op<'_>) -> Result<Payload> {
        Ok(self.link.call(self.db, op).await?)
    }

    async fn read_digital(&self, pin: Pin) -> Result<Level> {
        let reply = self.call(Op::DigitalRead(self.port.pin(pin))).await?;
        level_of(&reply)
    }

    async fn write_digital(&self, pin: Pin, level: Level) -> Result<()> {
        self.call(Op::DigitalWrite(self.port.pin(pin), level))
            .await?;
        Ok(())
    }

    async fn pulse_in(&self, pin: Pin, edge: Edge, timeout_ms: Option<u16>) -> Result<u32> {
        let op = Op::PulseIn {
            pin: self.port.pin(pin),
            edge,
            timeout_ms,
        };
        match *self.call(op).await? {
            [a, b, c, d] => Ok(u32::from_le_bytes([a, b, c, d])),
            _ => Err(Error::Link(LinkError::BadReply)),
        }
    }

    async fn enable_events(&self, pin: Pin, config: EventConfig) -> Result<()> {
        self.call(Op::EventEnable(self.port.pin(pin), config))
            .await?;
        Ok(())
    }

    async fn wait_event(&self, pin: Pin) -> Result<PinEvent> {
        Ok(self.link.wait_event(self.db, self.port.pin(pin)).await?)
    }
}

macro_rules! common_accessors {
    () => {
        /// The board.
        pub fn db(&self) -> Address {
            self.inner.db
        }

        /// The port.
        pub fn port(&self) -> Port {
            self.inner.port
        }

        /// Pin `pin` of the port.
        pub fn pin(&self, pin: Pin) -> PinRef {
            self.inner.port.pin(pin)
        }

        /// The link.
        pub fn link(&self) -> &L {
            &self.inner.link
        }

        /// Reads digital pin `pin` (`IO INPUT`, `0x10`).
        ///
        /// # Errors
        /// [`Error::Link`]; `Link(BadReply)` for a payload other than one byte 0 or 1.
        pub async fn read_digital(&self, pin: Pin) -> Result<Level> {
            self.inner.read_digital(pin).await
        }

        /// Drives digital pin `pin` (`IO LOW` `0x11` / `IO HIGH` `0x12`).
        ///
        /// # Errors
        /// [`Error::Link`].
        pub async fn write_digital(&self, pin: Pin, level: Level) -> Result<()> {
            self.inner.write_digital(pin, level).await
        }

        /// Measures one pulse on digital pin `pin`, in µs (`IO PULSE-IN` `0x13` rising /
        /// `0x14` falling; `timeout_ms` `None` uses the board's default). The board answers
        /// `pending` at once and the width later; the link resolves with the width.
        ///
        /// # Errors
        /// [`Error::Link`]; `Link(Status(Timeout))` when no pulse came before the timeout;
        /// `Link(BadReply)` for a payload other than 4 bytes.
        pub async fn pulse_in(&self, pin: Pin, edge: Edge, timeout_ms: Option<u16>) -> Result<u32> {
            self.inner.pulse_in(pin, edge, timeout_ms).await
        }

        /// Asks the board to report changes of pin `pin` (`SYSTEM EVENT-ENABLE`, `0x04`);
        /// [`EventConfig::OFF`] turns them off.
        ///
        /// # Errors
        /// [`Error::Link`].
        pub async fn enable_events(&self, pin: Pin, config: EventConfig) -> Result<()> {
            self.inner.enable_events(pin, config).await
        }

        /// Waits for the next event of pin `pin` (enable it first).
        ///
        /// # Errors
        /// [`Error::Link`]; `Link(Unsupported)` when the link delivers no events.
        pub async fn wait_event(&self, pin: Pin) -> Result<PinEvent> {
            self.inner.wait_event(pin).await
        }
    };
}

/// A sensor port: two digital I/O pins (A, B) and one analog input. Thesis class `Sensor`.
///
/// ```
/// # use x10_devices::{Sensor, SELF};
/// # fn f<L: x10_devices::Link>(link: L) -> x10_devices::Result<()> {
/// let force = Sensor::new(link, SELF, 1)?; // sensor port 1 of the internal board
/// # Ok(()) }
/// ```
#[derive(Clone, Debug)]
pub struct Sensor<L> {
    inner: PortLink<L>,
}

impl<L: Link> Sensor<L> {
    /// Sensor port `number` (counted from 1) of board `db`.
    ///
    /// # Errors
    /// [`Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Ok(Sensor {
            inner: PortLink::new(link, db, PortKind::Sensor, number)?,
        })
    }

    /// Sensor port `port` of board `db`.
    ///
    /// # Errors
    /// [`Error::WrongPortKind`] for an actuator port.
    pub fn at(link: L, db: Address, port: Port) -> Result<Self> {
        Ok(Sensor {
            inner: PortLink::at(link, db, PortKind::Sensor, port)?,
        })
    }

    common_accessors!();

    /// Reads the analog input (`ANALOG READ`, `0x30`): raw ADC counts.
    ///
    /// # Errors
    /// [`Error::Link`]; `Link(BadReply)` for a payload other than 2 bytes.
    pub async fn read_analog(&self) -> Result<u16> {
        match *self.inner.call(Op::AnalogRead(self.inner.port)).await? {
            [a, b] => Ok(u16::from_le_bytes([a, b])),
            _ => Err(Error::Link(LinkError::BadReply)),
        }
    }
}

/// An actuator port: two PWM pins (A, B) and two digital I/O pins (A, B). Thesis class
/// `Actuator`.
#[derive(Clone, Debug)]
pub struct Actuator<L> {
    inner: PortLink<L>,
}

impl<L: Link> Actuator<L> {
    /// Actuator port `number` (counted from 1) of board `db`.
    ///
    /// # Errors
    /// [`Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8) -> Result<Self> {
        Ok(Actuator {
            inner: PortLink::new(link, db, PortKind::Actuator, number)?,
        })
    }

    /// Actuator port `port` of board `db`.
    ///
    /// # Errors
    /// [`Error::WrongPortKind`] for a sensor port.
    pub fn at(link: L, db: Address, port: Port) -> Result<Self> {
        Ok(Actuator {
            inner: PortLink::at(link, db, PortKind::Actuator, port)?,
        })
    }

    common_accessors!();

    /// Drives digital pin A, then pin B (thesis `setDigital(a, b)`).
    ///
    /// # Errors
    /// [`Error::Link`]; when the first write fails the second is not sent.
    pub async fn set_digital(&self, a: Level, b: Level) -> Result<()> {
        self.write_digital(Pin::A, a).await?;
        self.write_digital(Pin::B, b).await
    }

    /// Sets the duty of PWM pin `pin` (`PWM DUTY`, `0x20`; thesis `pwm_a`/`pwm_b`).
    ///
    /// # Errors
    /// [`Error::Link`].
    pub async fn pwm(&self, pin: Pin, duty: Duty) -> Result<()> {
        self.inner
            .call(Op::PwmDuty(self.inner.port.pin(pin), duty.get()))
            .await?;
        Ok(())
    }

    /// Sets the PWM frequency of both PWM pins (`PWM FREQUENCY`, `0x21`).
    ///
    /// # Errors
    /// [`Error::Range`] ([`Quantity::PwmFrequency`]) for 0 Hz, before anything is sent;
    /// [`Error::Link`].
    pub async fn pwm_frequency(&self, hz: u16) -> Result<()> {
        RangeError::check(Quantity::PwmFrequency, hz as i32, 1, u16::MAX as i32)?;
        self.inner
            .call(Op::PwmFrequency(self.inner.port, hz))
            .await?;
        Ok(())
    }

    /// Sets the high time of each period of PWM pin `pin`, in µs (`PWM PULSE-WIDTH`,
    /// `0x22`); 0 stops the pulses.
    ///
    /// # Errors
    /// [`Error::Link`]; `Link(Status(Unsupported))` when the board cannot make it (longer
    /// than the period).
    pub async fn pulse_width(&self, pin: Pin, us: u16) -> Result<()> {
        self.inner
            .call(Op::PwmPulseWidth(self.inner.port.pin(pin), us))
            .await?;
        Ok(())
    }
}
