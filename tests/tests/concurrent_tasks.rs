//! The fourth example (`robots/src/bumper.rs`): three tasks at once, checked against what the
//! simulated ports really held. The bumper task sleeps on the button's events and runs a timed
//! manoeuvre (`Timer::after`) while the lamp's sensor loop and the heartbeat keep their own
//! periods, undisturbed.

use x10_sim::sim::{SimConfig, SimOutcome};
use x10_sim::timeline::{MotorState, Timeline};
use x10_sim::world::World;

const MS: u64 = 1_000_000;

fn run() -> (World, SimOutcome) {
    let example = x10_sim::examples::find("bumper").expect("the bumper example");
    let world = example.world().expect("its world");
    let config = SimConfig {
        duration_ms: 5_000,
        ..SimConfig::default()
    };
    let sim = world.sim(config).expect("a valid world");
    let outcome = x10_sim::examples::with_tasks("bumper", sim)
        .expect("its tasks")
        .run()
        .expect("it runs");
    (world, outcome)
}

#[test]
fn the_bumper_backs_off_for_800_ms_after_each_hit_while_the_other_tasks_go_on() {
    let (world, outcome) = run();
    let tl = Timeline::new(&world, &outcome);
    let drive = tl.motor("drive").unwrap();
    let changes: Vec<(u64, MotorState)> =
        drive.changes().iter().map(|(t, s)| (t / MS, *s)).collect();
    // Bumps at 1.0 s and 3.0 s (50 ms each): stop, 100 ms, reverse 60 % for 800 ms, stop,
    // 100 ms, cruise at 40 % again.
    assert_eq!(
        changes,
        vec![
            (0, MotorState::forward(40)),
            (1_000, MotorState::STOPPED),
            (1_100, MotorState::reverse(60)),
            (1_900, MotorState::STOPPED),
            (2_000, MotorState::forward(40)),
            (3_000, MotorState::STOPPED),
            (3_100, MotorState::reverse(60)),
            (3_900, MotorState::STOPPED),
            (4_000, MotorState::forward(40)),
        ]
    );
    // The heartbeat on db09 toggled every 250 ms the whole time, manoeuvres or not. The first
    // write waits for the motherboard to prepare db09 (PEC on, failsafe set, each read back):
    // it lands at 1 ms.
    let heartbeat = tl.led("heartbeat").unwrap();
    let times: Vec<u64> = heartbeat.changes().iter().map(|(t, _)| t / MS).collect();
    let expected: Vec<u64> = (0..20).map(|i| (i * 250).max(1)).collect();
    assert_eq!(times, expected);
    // The lamp followed the light every 100 ms: duty = 255 − light/4, the light ramping from
    // 100 to 800 counts over 4 s.
    let lamp = tl.brightness("lamp").unwrap();
    assert_eq!(lamp.at_ms(50), 91);
    assert_eq!(lamp.at_ms(4_500), 22);
    assert!(lamp.changes().len() > 30, "{}", lamp.changes().len());
    assert_eq!(outcome.mb.timeouts, 0);
}
