//! Thesis Figure 4.6: a temperature alarm. A thermistor in a freezer (daughterboard 17) and
//! one in an oven (daughterboard 108) are watched; the alarm on daughterboard 10 sounds when
//! the freezer is warmer than 1 °C or the oven cooler than 200 °F.
//!
//! Wiring:
//!
//! | device | board | port | pin |
//! |---|---|---|---|
//! | thermistor "cold" (freezer) | 17 ([`FREEZER`]) | sensor port 1 | analog, thesis divider |
//! | thermistor "hot" (oven) | 108 ([`OVEN`]) | sensor port 6 | analog, thesis divider |
//! | alarm (HIGH = sounding) | 10 ([`CONTROL_BOARD`]) | actuator port 3 | digital A |
//!
//! ## The condition, as in the thesis
//! `cold.celsius() > 1 || hot.fahrenheit() < 200`, with the C `||`: the oven is read only when
//! the freezer is fine. Mixed units on purpose, as the thesis uses both of its thermistor
//! library's functions. Note what it means: an oven at room temperature (about 77 °F) raises
//! the alarm; the oven must be hot for the alarm to stay quiet.
//!
//! The alarm **latches**, as in the thesis: its `loop()` turns the alarm on (`alarm.on_a()`)
//! and has no branch that turns it off, so once raised it stays on until the program restarts
//! (`setup` drives it LOW). The latch holds the decision, not the write: a condition seen once
//! keeps the alarm wanted even if writing it failed and the temperature is back to normal.
//!
//! The alarm is a [`Kept`] [`DigitalOutput`]: its level is written when it changes, every
//! [`crate::REFRESH_STEPS`] steps without a change (LOW as well as HIGH: board 10 may have
//! reset and dropped a raised alarm to its safe LOW state), and at the next step after a failed
//! write; not on every pass as in the thesis. A failed thermistor read does not count: it is
//! another board (so the program calls [`Kept::keep`], not [`Kept::keep_or_forget`]).
//!
//! ## Differences from the thesis's code
//! * `readThermistorFarenheit(<200` does not compile; the intent is `readThermistorFahrenheit()
//!   < 200`.
//! * A thermistor that cannot be read (board absent, an open or shorted thermistor reading on an
//!   ADC rail) raises the alarm too, and `step` then returns the error so the runner logs it: a
//!   monitoring system that cannot see a temperature must not stay silent. The thesis would
//!   compute `log` of a negative number or divide by zero and compare a NaN (never true: no
//!   alarm).
//! * `setup` puts the alarm in a known state (LOW); the thesis's `setup()` is empty.

use x10_devices::{
    Address, DigitalOutput, Error, Kept, Level, Link, LinkError, Pin, Robot, Thermistor,
};

const fn addr(n: u8) -> Address {
    match Address::new(n) {
        Ok(a) => a,
        // Only used in constants, so evaluated at compile time: a bad address fails the build.
        Err(_) => panic!("invalid daughterboard address"),
    }
}

/// Daughterboard with the freezer's thermistor.
pub const FREEZER: Address = addr(17);
/// Daughterboard with the oven's thermistor (108 = 0x6c).
pub const OVEN: Address = addr(108);
/// Daughterboard with the alarm.
pub const CONTROL_BOARD: Address = addr(10);
/// Sensor port of the freezer's thermistor.
pub const COLD_PORT: u8 = 1;
/// Sensor port of the oven's thermistor.
pub const HOT_PORT: u8 = 6;
/// Actuator port of the alarm.
pub const ALARM_PORT: u8 = 3;
/// Pin of the alarm.
pub const ALARM_PIN: Pin = Pin::A;
/// Alarm when the freezer is warmer than this, °C.
pub const COLD_LIMIT_C: f32 = 1.0;
/// Alarm when the oven is cooler than this, °F.
pub const HOT_LIMIT_F: f32 = 200.0;

/// The Figure 4.6 program.
#[derive(Clone, Debug)]
pub struct TemperatureAlarm<L> {
    cold: Thermistor<L>,
    hot: Thermistor<L>,
    alarm: Kept<DigitalOutput<L>>,
    /// The latch: the condition has been seen since `setup`.
    raised: bool,
}

impl<L: Link + Clone> TemperatureAlarm<L> {
    /// The program on `link`.
    ///
    /// # Errors
    /// None with these constants; the drivers' constructors check port numbers.
    pub fn new(link: L) -> Result<Self, Error> {
        let alarm = DigitalOutput::new(link.clone(), CONTROL_BOARD, ALARM_PORT, ALARM_PIN)?;
        Ok(TemperatureAlarm {
            cold: Thermistor::new(link.clone(), FREEZER, COLD_PORT)?,
            hot: Thermistor::new(link, OVEN, HOT_PORT)?,
            alarm: Kept::new(alarm, crate::REFRESH),
            raised: false,
        })
    }
}

impl<L: Link> TemperatureAlarm<L> {
    /// True once the alarm has been raised (it latches), whether or not writing it succeeded.
    pub fn alarm_raised(&self) -> bool {
        self.raised
    }

    /// True while the alarm is known to sound: the last write (HIGH) succeeded.
    pub fn alarm_on(&self) -> bool {
        self.alarm.state() == Some(Level::High)
    }

    /// The thesis's condition; an unreadable thermistor counts as "alarm" and is reported.
    async fn alarm_wanted(&self) -> (bool, Option<Error>) {
        match self.cold.celsius().await {
            Ok(c) if c.0 > COLD_LIMIT_C => (true, None),
            Ok(_) => match self.hot.fahrenheit().await {
                Ok(f) => (f.0 < HOT_LIMIT_F, None),
                Err(e) => (true, Some(e)),
            },
            Err(e) => (true, Some(e)),
        }
    }
}

impl<L: Link> Robot for TemperatureAlarm<L> {
    async fn setup(&mut self) -> Result<(), LinkError> {
        self.raised = false;
        Ok(self.alarm.set(Level::Low).await?)
    }

    async fn step(&mut self) -> Result<(), LinkError> {
        let (wanted, fault) = self.alarm_wanted().await;
        self.raised |= wanted;
        let level = if self.raised { Level::High } else { Level::Low };
        self.alarm.keep(level).await?;
        match fault {
            Some(e) => Err(e.into()),
            None => Ok(()),
        }
    }
}
