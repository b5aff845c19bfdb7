//! The robot in the simulator, checked against what the devices really did over virtual
//! time (`cargo test`). Same seed, same run: no sleeps, no flakes. Each test runs in a
//! process of its own (`x10_sim::isolated`), so the statics of the robot program (an
//! embassy-sync `Mutex` two tasks share, a `StaticCell`) are its simulation's alone.

use x10_sim::sim::{Sim, SimConfig, SimOutcome};
use x10_sim::timeline::{MotorState, Timeline};
use x10_sim::world::World;

/// Runs both tasks against `world.toml` for `ms` of virtual time.
fn run(ms: u64) -> (World, SimOutcome) {
    let world = World::load("world.toml").expect("world.toml");
    let config = SimConfig {
        duration_ms: ms,
        ..SimConfig::default()
    };
    let sim: Sim = world.sim(config).expect("a valid world");
    let outcome = sim
        .robot(robot::Robot)
        .run()
        .expect("the simulation runs");
    (world, outcome)
}

#[test]
fn the_motor_drives_for_two_seconds_after_the_press() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(5_000);
        let timeline = Timeline::new(&world, &outcome);
        let motor = timeline.motor("motor").expect("a motor called motor");
        assert_eq!(motor.at_ms(900), MotorState::STOPPED);
        // The button is pressed at 1.0 s: the press event, one confirming read, then the motor.
        assert_eq!(motor.at_ms(1_050), MotorState::forward(60));
        assert_eq!(motor.at_ms(2_900), MotorState::forward(60));
        assert_eq!(motor.at_ms(3_100), MotorState::STOPPED);
        assert_eq!(motor.at_ms(4_999), MotorState::STOPPED);
    });
}

#[test]
fn the_led_blinks_every_half_second() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(2_100);
        let led = Timeline::new(&world, &outcome).led("led").expect("an LED called led");
        let on: Vec<bool> = [250, 750, 1_250, 1_750].map(|ms| led.at_ms(ms)).into();
        assert_eq!(on, [true, false, true, false]);
    });
}
