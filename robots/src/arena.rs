//! Robots that drive: a differential-drive chassis (left motor on SELF actuator port 1, right
//! on port 2, each on an H-bridge) in an arena. In the simulator their worlds
//! (`worlds/explorer.toml`, `wall_follower.toml`, `line_follower.toml`) give the chassis,
//! the arena and the sensors that read the chassis's pose, so the program's own movement
//! decides what its sensors see (`docs/world.md`, "Physics").
//!
//! Wiring:
//!
//! | device | board | port | pin |
//! |---|---|---|---|
//! | left motor on an H-bridge | SELF | actuator port 1 | A/B = IN1/IN2, PWM A = EN |
//! | right motor on an H-bridge | SELF | actuator port 2 | A/B = IN1/IN2, PWM A = EN |
//! | bumper switch (HIGH when hit; [`explorer`]) | SELF | sensor port 2 | digital B |
//! | ultrasonic ranger ([`wall_follower`]) | SELF | sensor port 1 | trigger A, echo B |
//! | line sensor, reflectance ([`line_follower`]) | SELF | sensor port 1 | analog |

use embassy_time::{Duration, Ticker, Timer};
use x10::{AnalogSensor, Button, ButtonState, DcMotor, Error, Pin, Speed, Ultrasonic, SELF, X10};

/// The explorer's cruising speed.
pub const CRUISE: Speed = speed(60);
/// The explorer's back-off speed.
pub const BACK: Speed = speed(-50);
/// How long the explorer backs off after a hit.
pub const BACK_TIME: Duration = Duration::from_millis(600);
/// How long it spins (left wheel forward, right wheel back) before cruising on.
pub const TURN_TIME: Duration = Duration::from_millis(450);
/// The pause after stopping, so an H-bridge never reverses at speed.
pub const SETTLE: Duration = Duration::from_millis(100);

/// The wall-follower's distance to keep along its beam, mm.
pub const WALL_MM: i32 = 300;
/// The wall-follower's measurement period (the HC-SR04 answers at most every 60 ms).
pub const RANGE_PERIOD: Duration = Duration::from_millis(70);
/// The followers' base speed, percent.
pub const BASE: i32 = 40;

/// The line sensor reads below this on the (dark) line.
pub const DARK: u16 = 460;
/// The line-follower's reading period.
pub const LINE_PERIOD: Duration = Duration::from_millis(20);

const fn speed(percent: i8) -> Speed {
    match Speed::new(percent) {
        Ok(s) => s,
        // Evaluated at compile time.
        Err(_) => panic!("a speed is -100..=100 %"),
    }
}

/// Both wheels at once.
struct Drive {
    left: DcMotor<X10>,
    right: DcMotor<X10>,
}

impl Drive {
    fn new(x10: X10) -> Result<Drive, Error> {
        Ok(Drive {
            left: DcMotor::new(x10, SELF, 1)?,
            right: DcMotor::new(x10, SELF, 2)?,
        })
    }

    async fn set(&mut self, left: Speed, right: Speed) -> Result<(), Error> {
        self.left.set_speed(left).await?;
        self.right.set_speed(right).await
    }

    /// Percentages, clamped to ±100; a speed already set is not sent again.
    async fn percent(&mut self, left: i32, right: i32) -> Result<(), Error> {
        let s = |p: i32| Speed::new(p.clamp(-100, 100) as i8).unwrap_or(Speed::STOP);
        let (l, r) = (s(left), s(right));
        if self.left.speed() != Some(l) {
            self.left.set_speed(l).await?;
        }
        if self.right.speed() != Some(r) {
            self.right.set_speed(r).await?;
        }
        Ok(())
    }

    async fn stop(&mut self) -> Result<(), Error> {
        self.set(Speed::STOP, Speed::STOP).await
    }
}

/// Drives ahead; when the bumper (SELF sensor port 2, pin B) is hit, stops, backs off for
/// [`BACK_TIME`], spins right for [`TURN_TIME`] and drives on. Waits for the bumper's events.
///
/// # Errors
/// The first failed call.
pub async fn explorer(x10: X10) -> Result<(), Error> {
    let mut drive = Drive::new(x10)?;
    let mut bumper = Button::new(x10, SELF, 2, Pin::B)?;
    bumper.enable_events().await?;
    drive.set(CRUISE, CRUISE).await?;
    loop {
        if bumper.wait_change().await? == ButtonState::Pressed {
            drive.stop().await?;
            Timer::after(SETTLE).await;
            drive.set(BACK, BACK).await?;
            Timer::after(BACK_TIME).await;
            drive.stop().await?;
            Timer::after(SETTLE).await;
            drive.set(CRUISE, BACK).await?;
            Timer::after(TURN_TIME).await;
            drive.stop().await?;
            Timer::after(SETTLE).await;
            drive.set(CRUISE, CRUISE).await?;
        }
    }
}

/// Follows the wall on its left: the ranger (SELF sensor port 1) looks ahead and to the left;
/// every [`RANGE_PERIOD`] the difference from [`WALL_MM`] steers (proportional, ±25 %), and
/// nothing in range turns left to find the wall again. A failed measurement is skipped.
///
/// # Errors
/// Only if a driver cannot be built, or a motor command fails.
pub async fn wall_follower(x10: X10) -> Result<(), Error> {
    let mut drive = Drive::new(x10)?;
    let ranger = Ultrasonic::new(x10, SELF, 1)?;
    let mut ticker = Ticker::every(RANGE_PERIOD);
    loop {
        let steer = match ranger.distance().await {
            Ok(Some(d)) => {
                let error = i32::try_from(d.0).unwrap_or(i32::MAX) - WALL_MM;
                (error / 6).clamp(-25, 25)
            }
            Ok(None) => 25,
            Err(_) => 0,
        };
        drive.percent(BASE - steer, BASE + steer).await?;
        ticker.next().await;
    }
}

/// Follows the left edge of a dark line: on the line (a reading below [`DARK`]) it veers
/// right, off it veers left, every [`LINE_PERIOD`].
///
/// # Errors
/// Only if a driver cannot be built, or a motor command fails.
pub async fn line_follower(x10: X10) -> Result<(), Error> {
    let mut drive = Drive::new(x10)?;
    let sensor = AnalogSensor::new(x10, SELF, 1)?;
    let mut ticker = Ticker::every(LINE_PERIOD);
    loop {
        if let Ok(raw) = sensor.read_raw().await {
            if raw < DARK {
                drive.percent(BASE, BASE / 4).await?;
            } else {
                drive.percent(BASE / 4, BASE).await?;
            }
        }
        ticker.next().await;
    }
}
