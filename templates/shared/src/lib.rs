//! Two tasks that share the motor: the drive loop keeps it going forward, the bumper
//! manoeuvre takes it over on a press (back off, pause) and gives it back. The motor sits in
//! a `static` embassy-sync `Mutex`, as in any embassy program: whoever holds the lock drives.
//! Same wiring and world as the template: motor on actuator port 1, bumper (a push button,
//! HIGH when pressed) on sensor port 2, pin B.
#![no_std]

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::{Duration, Ticker, Timer};
use x10::{Button, ButtonState, DcMotor, Error, Pin, Speed, SELF, X10};

/// The motor, shared by both tasks; `drive` puts it there when it starts.
static MOTOR: Mutex<CriticalSectionRawMutex, Option<DcMotor<X10>>> = Mutex::new(None);

/// How long the bumper manoeuvre backs off, then pauses, before the drive loop resumes.
pub const BACK_OFF: Duration = Duration::from_millis(500);
pub const PAUSE: Duration = Duration::from_millis(200);

/// Drives forward at 60 %, every 100 ms, whenever the bumper manoeuvre does not hold the
/// motor.
pub async fn drive(x10: X10) -> Result<(), Error> {
    *MOTOR.lock().await = Some(DcMotor::new(x10, SELF, 1)?);
    let mut ticker = Ticker::every(Duration::from_millis(100));
    loop {
        if let Some(motor) = MOTOR.lock().await.as_mut() {
            motor.set_speed(Speed::new(60)?).await?;
        }
        ticker.next().await;
    }
}

/// On each press of the bumper: takes the motor, backs off at 50 %, stops, pauses, and
/// gives the motor back.
pub async fn bumper(x10: X10) -> Result<(), Error> {
    let mut bumper = Button::new(x10, SELF, 2, Pin::B)?;
    bumper.enable_events().await?;
    loop {
        if bumper.wait_change().await? == ButtonState::Pressed {
            if let Some(motor) = MOTOR.lock().await.as_mut() {
                motor.set_speed(Speed::new(-50)?).await?;
                Timer::after(BACK_OFF).await;
                motor.stop().await?;
                Timer::after(PAUSE).await;
            }
        }
    }
}

x10::robot! {
    /// The robot: its tasks, listed here once. `cargo sim`, `cargo test` and both board images
    /// (`src/bin/`) run exactly these.
    pub struct Robot { drive, bumper }
}
