//! The two tasks that share the motor, in the simulator. Each test runs in a process of its
//! own (`x10_sim::isolated`): the `static` the tasks share is that simulation's alone.

use x10_sim::sim::{SimConfig, SimOutcome};
use x10_sim::timeline::{MotorState, Timeline};
use x10_sim::world::World;

fn run(ms: u64) -> (World, SimOutcome) {
    let world = World::load("world.toml").expect("world.toml");
    let config = SimConfig {
        duration_ms: ms,
        ..SimConfig::default()
    };
    let outcome = world
        .sim(config)
        .expect("a valid world")
        .robot(robot::Robot)
        .run()
        .expect("the simulation runs");
    (world, outcome)
}

#[test]
fn the_bumper_takes_the_motor_and_gives_it_back() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(3_000);
        let timeline = Timeline::new(&world, &outcome);
        let motor = timeline.motor("motor").expect("a motor called motor");
        assert_eq!(motor.at_ms(900), MotorState::forward(60));
        // The bumper is pressed at 1.0 s: back off for 500 ms, stop for 200 ms, drive again.
        assert_eq!(motor.at_ms(1_100), MotorState::reverse(50));
        assert_eq!(motor.at_ms(1_600), MotorState::STOPPED);
        assert_eq!(motor.at_ms(1_800), MotorState::forward(60));
        assert_eq!(motor.at_ms(2_999), MotorState::forward(60));
    });
}

#[test]
fn the_drive_loop_runs_alone_until_the_press() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(900);
        let timeline = Timeline::new(&world, &outcome);
        let motor = timeline.motor("motor").expect("a motor called motor");
        assert_eq!(motor.at_ms(50), MotorState::forward(60));
        assert_eq!(motor.at_ms(899), MotorState::forward(60));
        assert!(outcome.task_errors.is_empty());
    });
}
