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
fn it_meets_the_walls_and_the_box_in_this_order() {
    x10_sim::isolated(|| {
        let (world, outcome) = run(20_000);
        let timeline = Timeline::new(&world, &outcome);
        let hits: Vec<(&str, u64)> = timeline
            .contacts()
            .iter()
            .map(|c| (c.obstacle.as_str(), c.t_ns / 1_000_000))
            .collect();
        // Walls are numbered in the order of `size_mm`'s sides: 1 bottom, 2 right, 3 top,
        // 4 left; boxes after them.
        assert_eq!(
            hits,
            [
                ("wall 2", 7_207),
                ("wall 2", 8_751),
                ("box 1", 13_442),
                ("box 1", 14_652),
                ("wall 3", 19_756),
            ]
        );
    });
}
