//! Thesis Figure 4.2 (and Figure 1.1): a single-board robot. A push button and a force sensor
//! on the internal daughterboard drive a DC motor: full speed forward while the button is
//! pressed or the force reading is above 100, stopped otherwise.
//!
//! Wiring (all on the internal daughterboard, `SELF`):
//!
//! | device | port | pin |
//! |---|---|---|
//! | DC motor on an H-bridge | actuator port 1 | digital A/B = IN1/IN2, PWM A = EN |
//! | force sensor | sensor port 1 | analog input |
//! | push button (HIGH when pressed) | sensor port 2 | digital B |
//!
//! ## Differences from the thesis's code, and why
//! * The thesis declares `Sensor pushbutton(SELF,1)` under a comment saying port 2, so button
//!   and force sensor would share port 1. Port 2, as the comment and the hardware description
//!   say, is used here.
//! * `pushbutton.readDigitalB()` is declared `void` in the appendix, so the `if` could not
//!   compile. Here the button is a debounced [`Button`] on pin B (two agreeing reads).
//! * Figure 4.2 turns the motor "on" with `setDigital(LO, HI)`, Figure 4.4's copy with
//!   `setDigital(HI, LO)`, and Figure 4.4's "off" leaves the PWM at 100 % with the bridge
//!   reversed. Here forward is the [`x10::HBridge`] convention (A HIGH, B LOW) and off is the
//!   bridge's stopped state (coast: A LOW, B LOW, PWM 0).
//! * The C `||` skips the force reading while the button is pressed; so does this program.
//! * The motor is a [`Kept`] [`DcMotor`]: its command is sent when the wanted speed changes,
//!   every [`crate::REFRESH_STEPS`] steps without a change, and at the next step after any
//!   failed call (a NACK may be the board resetting), not on every pass; before the loop the
//!   motor is stopped (the thesis's `setup()` is empty).

use embassy_time::Ticker;
use x10::{AnalogSensor, Button, DcMotor, Error, Kept, Pin, Speed, SELF, X10};

/// Actuator port of the motor's H-bridge.
pub const MOTOR_PORT: u8 = 1;
/// Sensor port of the force sensor.
pub const FORCE_PORT: u8 = 1;
/// Sensor port of the button.
pub const BUTTON_PORT: u8 = 2;
/// Pin of the button.
pub const BUTTON_PIN: Pin = Pin::B;
/// The motor runs while the force reading (raw ADC counts) is above this.
pub const FORCE_THRESHOLD: u16 = 100;

/// The Figure 4.2 program. Runs for ever; returns only if a driver cannot be built.
///
/// # Errors
/// [`Error::BadPort`] with bad port constants (never with these).
pub async fn single_board(x10: X10) -> Result<(), Error> {
    let mut motor = Kept::new(DcMotor::new(x10, SELF, MOTOR_PORT)?, crate::REFRESH);
    let force = AnalogSensor::new(x10, SELF, FORCE_PORT)?;
    let mut button = Button::new(x10, SELF, BUTTON_PORT, BUTTON_PIN)?;
    // A failed write is sent again at the next step (Kept).
    let _ = motor.set(Speed::STOP).await;
    let mut ticker = Ticker::every(crate::PERIOD);
    loop {
        // Button pressed, or else force above 100: full speed forward; otherwise stop.
        let run = match button.is_pressed().await {
            Ok(true) => Ok(true),
            Ok(false) => force.read_raw().await.map(|f| f > FORCE_THRESHOLD),
            Err(e) => Err(e),
        };
        let wanted = run.map(|run| {
            if run {
                Speed::FULL_FORWARD
            } else {
                Speed::STOP
            }
        });
        // A failed read forgets the motor's state, so the next step sends it again.
        let _ = motor.keep_or_forget(wanted).await;
        ticker.next().await;
    }
}
