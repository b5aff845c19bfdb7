//! A robot declared once with `x10::robot!` runs in the simulator through `Sim::robot`: the
//! same tasks, names and run as listing each function with `Sim::with_robot`, and a task's
//! error is reported under the name the declaration gives it.

use x10_devices::{DigitalOutput, Error, Pin, SELF};
use x10_robots::{bumper, Bumper};
use x10_sim::sim::{SimConfig, SimOutcome};
use x10_sim::world::World;

const WORLD: &str = include_str!("../../robots/worlds/bumper.toml");

fn config() -> SimConfig {
    SimConfig {
        duration_ms: 3_000,
        ..SimConfig::default()
    }
}

fn world() -> World {
    World::from_toml(WORLD).expect("the bumper world")
}

fn run(add: impl FnOnce(x10_sim::sim::Sim) -> x10_sim::sim::Sim) -> SimOutcome {
    add(world().sim(config()).expect("a valid world"))
        .run()
        .expect("the simulation runs")
}

#[test]
fn a_declared_robot_runs_exactly_its_tasks_in_order() {
    let declared = run(|sim| sim.robot(Bumper));
    let listed = run(|sim| {
        sim.with_robot("heartbeat", bumper::heartbeat)
            .with_robot("lamp", bumper::lamp)
            .with_robot("bumper", bumper::bumper)
    });
    assert!(!declared.calls.is_empty());
    let tasks = |o: &SimOutcome| {
        let mut t: Vec<String> = o.calls.iter().map(|c| c.task.clone()).collect();
        t.dedup();
        t.sort();
        t.dedup();
        t
    };
    assert_eq!(tasks(&declared), ["bumper", "heartbeat", "lamp"]);
    assert_eq!(declared.trace.render(), listed.trace.render());
    assert!(!declared.log.is_empty());
    assert_eq!(declared.log.changes(), listed.log.changes());
}

async fn on_a_missing_port(x10: x10::X10) -> Result<(), Error> {
    // The motherboard's own board has 4 actuator ports: port 9 is refused.
    DigitalOutput::new(x10, SELF, 9, Pin::A)?.toggle().await?;
    Ok(())
}

async fn quiet(_x10: x10::X10) {}

x10::robot! {
    /// A task that fails at once and one that ends quietly.
    struct Failing { quiet, broken: on_a_missing_port }
}

#[test]
fn a_declared_tasks_error_is_reported_under_its_declared_name() {
    let outcome = run(|sim| sim.robot(Failing));
    assert_eq!(outcome.task_errors.len(), 1);
    assert_eq!(outcome.task_errors[0].0, "broken");
    assert!(outcome
        .problems("world.toml")
        .iter()
        .any(|p| p.contains("broken")));
}
