//! My robot in its arena (`cargo test`): what it did in the world, not only what it sent.

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
fn it_backs_off_from_every_wall_it_hits_and_never_goes_through() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(20_000);
        let timeline = Timeline::new(&world, &outcome);
        let hits = timeline.contacts();
        assert!(hits.len() >= 3, "{hits:?}");
        let left = timeline.motor("left").expect("a motor called left");
        for hit in hits {
            let ms = hit.t_ns / 1_000_000;
            assert_eq!(left.at_ms(ms + 100), MotorState::reverse(50), "{hit:?}");
        }
        // Against the walls, never through one.
        let (_, gap) = timeline.closest_to_wall().expect("an arena");
        assert!(gap >= 0.0, "{gap}");
    });
}

#[test]
fn it_keeps_clear_of_the_walls_until_its_first_hit() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(20_000);
        let timeline = Timeline::new(&world, &outcome);
        let first = timeline.contacts().first().expect("a contact").clone();
        assert_eq!(first.obstacle, "wall 2");
        let before = timeline.pose_at_ms(first.t_ns / 1_000_000 - 500).expect("a chassis");
        assert!(before.x_mm < 1_300.0, "{before:?}");
    });
}
