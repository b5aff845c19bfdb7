//! My robot in an arena: two wheels, each on a motor behind an H-bridge, and a bumper at the
//! front. It drives ahead; when the bumper is hit it backs off, turns right on the spot and
//! drives on.
//!
//! Wiring, all on the motherboard's own ports (`SELF`):
//!
//! | device | port | pin |
//! |---|---|---|
//! | left wheel's motor on an H-bridge | actuator port 1 | A/B = IN1/IN2, PWM A = EN |
//! | right wheel's motor on an H-bridge | actuator port 2 | A/B = IN1/IN2, PWM A = EN |
//! | bumper (HIGH when hit) | sensor port 2 | digital B |
#![no_std]

use embassy_time::{Duration, Timer};
use x10::{Button, ButtonState, DcMotor, Error, Pin, Speed, SELF, X10};

/// How long the robot backs off after a hit.
pub const BACK_OFF: Duration = Duration::from_millis(500);
/// How long it then turns on the spot.
pub const TURN: Duration = Duration::from_millis(400);

/// Drives ahead at 50 %; on each hit of the bumper (sensor port 2, pin B), backs off, turns
/// right and drives on.
pub async fn explore(x10: X10) -> Result<(), Error> {
    let mut left = DcMotor::new(x10, SELF, 1)?;
    let mut right = DcMotor::new(x10, SELF, 2)?;
    let mut bumper = Button::new(x10, SELF, 2, Pin::B)?;
    let (ahead, back) = (Speed::new(50)?, Speed::new(-50)?);
    bumper.enable_events().await?;
    left.set_speed(ahead).await?;
    right.set_speed(ahead).await?;
    loop {
        if bumper.wait_change().await? == ButtonState::Pressed {
            left.set_speed(back).await?;
            right.set_speed(back).await?;
            Timer::after(BACK_OFF).await;
            left.set_speed(ahead).await?;
            Timer::after(TURN).await;
            right.set_speed(ahead).await?;
        }
    }
}

x10::robot! {
    /// The robot: one task.
    pub struct Robot { explore }
}
