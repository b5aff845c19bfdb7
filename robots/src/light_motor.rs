//! Thesis Figure 4.4: the module added beside Figure 4.2 without touching it. Daughterboard 9
//! carries a light sensor and a second motor; the motor runs forward at 50 % while the light
//! reading is above 700 and stops otherwise.
//!
//! Wiring (daughterboard 9, [`BOARD`]):
//!
//! | device | port | pin |
//! |---|---|---|
//! | DC motor on an H-bridge | actuator port 1 | digital A/B = IN1/IN2, PWM A = EN |
//! | light sensor | sensor port 1 | analog input |
//!
//! ## How it runs beside Figure 4.2 without touching its code
//! This module is a separate [`Robot`] value, [`LightMotor`]; [`crate::fig4_2`] is not changed
//! or even imported. The program "Figure 4.4" ([`crate::Program::Fig4_4`]) is the two robots
//! together: [`crate::Program::build`] returns a [`crate::fig4_2::SingleBoard`] and a
//! [`LightMotor`], each holding a clone of the same link, and the motherboard firmware (or the
//! simulator) runs each in its own task, `setup` once then `step` forever. The motherboard
//! runtime's dispatcher serialises their requests on the bus; neither waits for the other.
//!
//! In the thesis, Figure 4.4's new code sits inside the same `loop()` as the old one, after
//! it (declarations included), so "adding a module" meant editing the existing program.
//!
//! ## Differences from the thesis's code
//! * Its "off" is `setDigital(LO, HI)` with the PWM left at 50 %: reverse at half power. Here
//!   off is the H-bridge's stopped state (coast).
//! * The light sensor is commented "force sensor"; it is an [`AnalogSensor`] here.
//! * The motor is a [`Kept`] [`DcMotor`], as in [`crate::fig4_2`]: its command is sent when
//!   the wanted speed changes, every [`crate::REFRESH_STEPS`] steps without a change, and at
//!   the next step after any failed call to board 9 (it may be resetting), not on every pass;
//!   `setup` stops the motor.

use x10_devices::{Address, AnalogSensor, DcMotor, Error, Kept, Link, LinkError, Robot, Speed};

/// Daughterboard 9 (the thesis's `BOARD2`).
pub const BOARD: Address = match Address::new(9) {
    Ok(a) => a,
    // Evaluated at compile time: a bad constant fails the build, never the robot.
    Err(_) => panic!("9 is a valid daughterboard address"),
};
/// Actuator port of the motor's H-bridge.
pub const MOTOR_PORT: u8 = 1;
/// Sensor port of the light sensor.
pub const LIGHT_PORT: u8 = 1;
/// The motor runs while the light reading (raw ADC counts) is above this.
pub const LIGHT_THRESHOLD: u16 = 700;
/// The motor's speed when it runs: half power forward.
pub const RUN_SPEED: Speed = match Speed::new(50) {
    Ok(s) => s,
    // Evaluated at compile time.
    Err(_) => panic!("50 % is a valid speed"),
};

/// The Figure 4.4 module.
#[derive(Clone, Debug)]
pub struct LightMotor<L> {
    motor: Kept<DcMotor<L>>,
    light: AnalogSensor<L>,
}

impl<L: Link + Clone> LightMotor<L> {
    /// The module on `link`.
    ///
    /// # Errors
    /// None with these constants; the drivers' constructors check port numbers.
    pub fn new(link: L) -> Result<Self, Error> {
        let motor = DcMotor::new(link.clone(), BOARD, MOTOR_PORT)?;
        Ok(LightMotor {
            motor: Kept::new(motor, crate::REFRESH),
            light: AnalogSensor::new(link, BOARD, LIGHT_PORT)?,
        })
    }
}

impl<L: Link> LightMotor<L> {
    /// The motor's last commanded speed; `None` when unknown (before `setup`, after a failed
    /// call).
    pub fn motor_speed(&self) -> Option<Speed> {
        self.motor.state()
    }
}

impl<L: Link> Robot for LightMotor<L> {
    async fn setup(&mut self) -> Result<(), LinkError> {
        Ok(self.motor.set(Speed::STOP).await?)
    }

    async fn step(&mut self) -> Result<(), LinkError> {
        // Half power while bright, stopped otherwise.
        let wanted = self.light.read_raw().await.map(|light| {
            if light > LIGHT_THRESHOLD {
                RUN_SPEED
            } else {
                Speed::STOP
            }
        });
        Ok(self.motor.keep_or_forget(wanted).await?)
    }
}
