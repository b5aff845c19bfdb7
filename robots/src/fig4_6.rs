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
//! (the program drives it LOW before its loop). The latch holds the decision, not the write: a condition seen once
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
//!   ADC rail) raises the alarm too: a monitoring system that cannot see a temperature must not
//!   stay silent. The thesis would
//!   compute `log` of a negative number or divide by zero and compare a NaN (never true: no
//!   alarm).
//! * The alarm starts in a known state (LOW); the thesis's `setup()` is empty.

use embassy_time::Ticker;
use x10::{Address, DigitalOutput, Error, Kept, Level, Pin, Thermistor, X10};

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
/// The freezer is too warm above this (°C).
pub const COLD_LIMIT_C: f32 = 1.0;
/// The oven is too cool below this (°F).
pub const HOT_LIMIT_F: f32 = 200.0;

/// The Figure 4.6 program. Runs for ever; returns only if a driver cannot be built.
///
/// # Errors
/// [`Error::BadPort`] with bad port constants (never with these).
pub async fn temperature_alarm(x10: X10) -> Result<(), Error> {
    let cold = Thermistor::new(x10, FREEZER, COLD_PORT)?;
    let hot = Thermistor::new(x10, OVEN, HOT_PORT)?;
    let alarm = DigitalOutput::new(x10, CONTROL_BOARD, ALARM_PORT, ALARM_PIN)?;
    let mut alarm = Kept::new(alarm, crate::REFRESH);
    let _ = alarm.set(Level::Low).await;
    let mut raised = false;
    let mut ticker = Ticker::every(crate::PERIOD);
    loop {
        // Freezer above 1 °C, or else oven below 200 °F; a reading that fails counts as too.
        let wanted = match cold.celsius().await {
            Ok(c) if c.0 > COLD_LIMIT_C => true,
            Ok(_) => hot.fahrenheit().await.map_or(true, |f| f.0 < HOT_LIMIT_F),
            Err(_) => true,
        };
        // The alarm latches: once raised it stays on (the thesis never turns it off).
        raised |= wanted;
        let _ = alarm
            .keep(if raised { Level::High } else { Level::Low })
            .await;
        ticker.next().await;
    }
}
