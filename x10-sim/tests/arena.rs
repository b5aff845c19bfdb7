//! Worlds that answer back (issue 28): the example robots in their arenas, checked on what the
//! robot did in the world, not only on the commands it sent.

use x10_sim::examples;
use x10_sim::sim::{SimConfig, SimOutcome};
use x10_sim::timeline::{summary, Timeline};
use x10_sim::world::World;

fn run(name: &str, ms: u64) -> (World, SimOutcome) {
    let e = examples::find(name).expect("an example");
    let world = e.world().expect("its world");
    let config = SimConfig {
        duration_ms: ms,
        ..SimConfig::default()
    };
    let outcome = examples::sim(name, config)
        .expect("its simulation")
        .run()
        .expect("the simulation runs");
    (world, outcome)
}

#[test]
fn explore() {
    let (world, outcome) = run("explorer", 20_000);
    let tl = Timeline::new(&world, &outcome);
    println!("{}", summary(&world, &outcome));
    let m = tl.motion().unwrap();
    for c in m.contacts() {
        println!("{c:?}");
    }
    println!("{:?}", tl.closest_to_wall());
    for t in (0..20).map(|s| s * 1000) {
        println!("{t} {:?}", tl.pose_at_ms(t));
    }
}

#[test]
fn others() {
    for (name, ms) in [("wall_follower", 30_000), ("line_follower", 30_000), ("freezer", 12_000)] {
        let (world, outcome) = run(name, ms);
        let tl = Timeline::new(&world, &outcome);
        println!("=== {name}\n{}", summary(&world, &outcome));
        println!("{:?} {:?}", tl.closest_to_wall(), tl.time_on_line_ns("eye"));
        for t in (0..ms / 1000).step_by(2).map(|s| s * 1000) { println!("{t} {:?}", tl.pose_at_ms(t)); }
        if name == "freezer" { println!("{:?}", tl.led("alarm").unwrap().first_ns(|on| *on)); }
    }
}
