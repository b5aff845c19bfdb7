//! Three tasks at once, which a periodic `setup`/`step` program cannot express: a heartbeat LED
//! blinks on its own timer, a lamp follows the light level in a sensor loop, and a bumper task
//! sleeps until the bumper is hit, then runs a timed back-off manoeuvre, while the other two
//! carry on. Each task is a plain `async fn`; the image (or the simulator) runs them side by
//! side with copies of one [`X10`].
//!
//! Wiring:
//!
//! | device | board | port | pin |
//! |---|---|---|---|
//! | light sensor | SELF | sensor port 1 | analog |
//! | bumper switch (HIGH when hit) | SELF | sensor port 2 | digital B |
//! | drive motor on an H-bridge | SELF | actuator port 1 | A/B = IN1/IN2, PWM A = EN |
//! | lamp (dimmable LED) | SELF | actuator port 2 | PWM A |
//! | heartbeat LED | 9 | actuator port 1 | digital A |

use embassy_time::{Duration, Ticker, Timer};
use x10::{
    Actuator, Address, AnalogSensor, Button, ButtonState, DcMotor, DigitalOutput, Duty, Error, Pin,
    Speed, SELF, X10,
};

/// The board with the heartbeat LED.
pub const LED_BOARD: Address = match Address::new(9) {
    Ok(a) => a,
    // Evaluated at compile time.
    Err(_) => panic!("9 is a valid daughterboard address"),
};
/// The heartbeat LED toggles this often.
pub const BLINK: Duration = Duration::from_millis(250);
/// The lamp follows the light this often.
pub const LAMP_PERIOD: Duration = Duration::from_millis(100);
/// Cruising speed (forward).
pub const CRUISE: Speed = speed(40);
/// Speed of the back-off (reverse).
pub const BACK_OFF: Speed = speed(-60);
/// How long the robot backs off after a hit.
pub const BACK_OFF_TIME: Duration = Duration::from_millis(800);
/// The pause between stopping and reversing (and back), so the H-bridge never reverses at
/// speed.
pub const SETTLE: Duration = Duration::from_millis(100);

const fn speed(percent: i8) -> Speed {
    match Speed::new(percent) {
        Ok(s) => s,
        // Evaluated at compile time.
        Err(_) => panic!("a speed is -100..=100 %"),
    }
}

/// Blinks the heartbeat LED (board 9, actuator port 1, pin A) for ever.
///
/// # Errors
/// The first failed write (the LED's board is gone).
pub async fn heartbeat(x10: X10) -> Result<(), Error> {
    let mut led = DigitalOutput::new(x10, LED_BOARD, 1, Pin::A)?;
    let mut ticker = Ticker::every(BLINK);
    loop {
        led.toggle().await?;
        ticker.next().await;
    }
}

/// The lamp (SELF actuator port 2, PWM A) glows brighter the darker it is: duty = 255 − light/4,
/// every 100 ms. A failed read or write is tried again at the next period.
///
/// # Errors
/// Only if a driver cannot be built.
pub async fn lamp(x10: X10) -> Result<(), Error> {
    let light = AnalogSensor::new(x10, SELF, 1)?;
    let lamp = Actuator::new(x10, SELF, 2)?;
    let mut ticker = Ticker::every(LAMP_PERIOD);
    let mut shown = None;
    loop {
        if let Ok(raw) = light.read_raw().await {
            let duty = Duty(255 - (raw.min(1023) / 4) as u8);
            if shown != Some(duty) && lamp.pwm(Pin::A, duty).await.is_ok() {
                shown = Some(duty);
            }
        }
        ticker.next().await;
    }
}

/// Cruises forward; whenever the bumper (SELF sensor port 2, pin B) is hit, stops, backs off
/// for [`BACK_OFF_TIME`], stops again and cruises on. Waits for the bumper's pin-change
/// events: no polling loop.
///
/// # Errors
/// The first failed call (a real robot would rather stop: see `docs/your-first-robot.md`).
pub async fn bumper(x10: X10) -> Result<(), Error> {
    let mut motor = DcMotor::new(x10, SELF, 1)?;
    let mut bumper = Button::new(x10, SELF, 2, Pin::B)?;
    bumper.enable_events().await?;
    motor.set_speed(CRUISE).await?;
    loop {
        if bumper.wait_change().await? == ButtonState::Pressed {
            motor.stop().await?;
            Timer::after(SETTLE).await;
            motor.set_speed(BACK_OFF).await?;
            Timer::after(BACK_OFF_TIME).await;
            motor.stop().await?;
            Timer::after(SETTLE).await;
            motor.set_speed(CRUISE).await?;
        }
    }
}
