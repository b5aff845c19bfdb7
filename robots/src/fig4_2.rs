//! Thesis Figure 4.2 (and Figure 1.1): a single-board robot. A push button and a force sensor
//! on the internal daughterboard drive a DC motor: full speed forward while the button is
//! pressed or the force reading is above 100, stopped otherwise.
//!
//! Wiring (all on the internal daughterboard, [`SELF`]):
//!
//! | device | port | pin |
//! |---|---|---|
//! | DC motor on an H-bridge | actuator port 1 | digital A/B = IN1/IN2, PWM A = EN |
//! | force sensor | sensor port 1 | analog input |
//! | push button (HIGH when pressed) | sensor port 2 | digital B |
//!
//! ## Differences from the thesis's code, and why
//! * The thesis declares `Sensor pushbutton(SELF,1)` under a comment saying port 2 (and
//!   "force sensor"), so button and force sensor would share port 1. Port 2, as the comment
//!   and the hardware description say, is used here.
//! * `pushbutton.readDigitalB()` is declared `void` and has an empty body in the appendix, so
//!   the `if` could not compile. Here the button is a debounced [`Button`] on pin B (two
//!   agreeing reads, i.e. two steps, make a press).
//! * Figure 4.2 turns the motor "on" with `setDigital(LO, HI)`, Figure 4.4's copy of the same
//!   program with `setDigital(HI, LO)`, and Figure 4.4's "off" (`setDigital(LO, HI)` with the
//!   PWM left at 100 %) actually drives the motor in reverse at full power. Here forward is the
//!   [`x10_devices::HBridge`] convention (A HIGH, B LOW) and off is the bridge's stopped state
//!   (coast: A LOW, B LOW, PWM 0), so the PWM does not stay at 100 %.
//! * The C `||` skips the force reading while the button is pressed; so does this program.
//! * The thesis re-sends the motor command on every pass of `loop()`. Here the motor is a
//!   [`Kept`] [`DcMotor`]: its command is sent when the wanted speed changes, and also every
//!   [`crate::REFRESH_STEPS`] steps without a change, and at the next step after any failed
//!   call ([`Kept::keep_or_forget`]: every call goes to the motor's board, and a NACK or
//!   timeout may be that board resetting, which leaves the motor coasting): the motor is
//!   driven again within [`crate::REFRESH_STEPS`] steps after a reset nobody reported, while
//!   the bus stays free for the sensor reads in between. `setup` puts the motor in the stopped
//!   state first (the thesis's `setup()` is empty, so the motor starts in whatever state the
//!   pins had).

use x10_devices::{
    AnalogSensor, Button, DcMotor, Error, Kept, Link, LinkError, Pin, Robot, Speed, SELF,
};

/// The board everything is on.
pub const BOARD: x10_devices::Address = SELF;
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

/// The Figure 4.2 program.
#[derive(Clone, Debug)]
pub struct SingleBoard<L> {
    motor: Kept<DcMotor<L>>,
    force: AnalogSensor<L>,
    button: Button<L>,
}

impl<L: Link + Clone> SingleBoard<L> {
    /// The program on `link`.
    ///
    /// # Errors
    /// None with these constants; the drivers' constructors check port numbers.
    pub fn new(link: L) -> Result<Self, Error> {
        let motor = DcMotor::new(link.clone(), BOARD, MOTOR_PORT)?;
        Ok(SingleBoard {
            motor: Kept::new(motor, crate::REFRESH),
            force: AnalogSensor::new(link.clone(), BOARD, FORCE_PORT)?,
            button: Button::new(link, BOARD, BUTTON_PORT, BUTTON_PIN)?,
        })
    }
}

impl<L: Link> SingleBoard<L> {
    /// The motor's last commanded speed; `None` when unknown (before `setup`, after a failed
    /// call).
    pub fn motor_speed(&self) -> Option<Speed> {
        self.motor.state()
    }

    /// Full speed while the button is pressed or the force is above the threshold (the force
    /// is not read while the button is pressed).
    async fn wanted(&mut self) -> Result<Speed, Error> {
        let run = self.button.is_pressed().await? || self.force.read_raw().await? > FORCE_THRESHOLD;
        Ok(if run {
            Speed::FULL_FORWARD
        } else {
            Speed::STOP
        })
    }
}

impl<L: Link> Robot for SingleBoard<L> {
    async fn setup(&mut self) -> Result<(), LinkError> {
        Ok(self.motor.set(Speed::STOP).await?)
    }

    async fn step(&mut self) -> Result<(), LinkError> {
        let wanted = self.wanted().await;
        Ok(self.motor.keep_or_forget(wanted).await?)
    }
}
