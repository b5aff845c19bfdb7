//! My robot: a heartbeat LED, and a motor that drives for two seconds whenever the button
//! is pressed. Each task is a plain `async fn` that takes the `X10` handle; the same code runs
//! in the simulator (`cargo sim`, `cargo test`) and on a board (`cargo mb-pico`).
//!
//! Wiring, all on the motherboard's own ports (`SELF`):
//!
//! | device | port | pin |
//! |---|---|---|
//! | DC motor on an H-bridge | actuator port 1 | A/B = IN1/IN2, PWM A = EN |
//! | LED | actuator port 2 | digital A |
//! | push button (HIGH when pressed) | sensor port 2 | digital B |
#![no_std]

use embassy_time::{Duration, Ticker, Timer};
use x10::{Button, ButtonState, DcMotor, DigitalOutput, Error, Pin, Speed, SELF, X10};

/// How long the motor runs after a press.
pub const DRIVE_TIME: Duration = Duration::from_secs(2);

/// Blinks the LED on actuator port 2, pin A: on for 500 ms, off for 500 ms.
pub async fn blink(x10: X10) -> Result<(), Error> {
    let mut led = DigitalOutput::new(x10, SELF, 2, Pin::A)?;
    let mut ticker = Ticker::every(Duration::from_millis(500));
    loop {
        led.toggle().await?;
        ticker.next().await;
    }
}

/// Waits for the button (sensor port 2, pin B); on each press, drives forward at 60 % for
/// two seconds, then stops.
pub async fn drive(x10: X10) -> Result<(), Error> {
    let mut motor = DcMotor::new(x10, SELF, 1)?;
    let mut button = Button::new(x10, SELF, 2, Pin::B)?;
    motor.stop().await?;
    button.enable_events().await?;
    loop {
        if button.wait_change().await? == ButtonState::Pressed {
            motor.set_speed(Speed::new(60)?).await?;
            Timer::after(DRIVE_TIME).await;
            motor.stop().await?;
        }
    }
}

x10::robot! {
    /// The robot: its tasks, listed here once. `cargo sim`, `cargo test` and both board images
    /// (`src/bin/`) run exactly these.
    pub struct Robot { blink, drive }
}
