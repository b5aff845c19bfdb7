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
//! This module is one more task, [`light_motor`]; [`crate::fig4_2`] is not changed or even
//! imported. The program "Figure 4.4" is the two tasks spawned side by side (the image's
//! `main` spawns both; `cargo x10 sim fig4_4` runs both), each with a copy of the same
//! [`X10`] handle. The motherboard runtime serialises their requests on the bus; neither
//! waits for the other. In the thesis, Figure 4.4's new code sits inside the same `loop()` as
//! the old one, so "adding a module" meant editing the existing program.
//!
//! ## Differences from the thesis's code
//! * Its "off" is `setDigital(LO, HI)` with the PWM left at 50 %: reverse at half power. Here
//!   off is the H-bridge's stopped state (coast).
//! * The light sensor is commented "force sensor"; it is an [`AnalogSensor`] here.
//! * The motor is a [`Kept`] [`DcMotor`], as in [`crate::fig4_2`].

use embassy_time::Ticker;
use x10::{Address, AnalogSensor, DcMotor, Error, Kept, Speed, X10};

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

/// The Figure 4.4 module. Runs for ever; returns only if a driver cannot be built.
///
/// # Errors
/// [`Error::BadPort`] with bad port constants (never with these).
pub async fn light_motor(x10: X10) -> Result<(), Error> {
    let mut motor = Kept::new(DcMotor::new(x10, BOARD, MOTOR_PORT)?, crate::REFRESH);
    let light = AnalogSensor::new(x10, BOARD, LIGHT_PORT)?;
    let _ = motor.set(Speed::STOP).await;
    let mut ticker = Ticker::every(crate::PERIOD);
    loop {
        // Half power while bright, stopped otherwise.
        let wanted = light.read_raw().await.map(|light| {
            if light > LIGHT_THRESHOLD {
                RUN_SPEED
            } else {
                Speed::STOP
            }
        });
        let _ = motor.keep_or_forget(wanted).await;
        ticker.next().await;
    }
}
