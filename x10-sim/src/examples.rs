//! The example robots of `x10-robots`, by name, for `x10 sim NAME`: each is its tasks (plain
//! `async fn`s taking an [`crate::sim::X10`]) and the world they run against. Your own robot
//! does not go here: it lives in its own crate with its own world file and `sim` command
//! (`x10 new`, `docs/your-first-robot.md`).

use crate::scenario;
use crate::sim::{Sim, SimConfig};

/// One example robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Example {
    /// Its name on the command line.
    pub name: &'static str,
    /// One line about it.
    pub description: &'static str,
    /// Its robot tasks, by name, in the order they are spawned.
    pub tasks: &'static [&'static str],
}

/// Every example.
pub const EXAMPLES: [Example; 3] = [
    Example {
        name: "fig4_2",
        description: "thesis Fig. 4.2: button (SELF S2.B) or force (SELF S1) > 100 runs the motor (SELF A1) at 100 %",
        tasks: &["single_board"],
    },
    Example {
        name: "fig4_4",
        description: "thesis Fig. 4.4: Fig. 4.2 unchanged plus a second task: light (DB 9 S1) > 700 runs a motor (DB 9 A1) at 50 %",
        tasks: &["single_board", "light_motor"],
    },
    Example {
        name: "fig4_6",
        description: "thesis Fig. 4.6: freezer (DB 17 S1) > 1 °C or oven (DB 108 S6) < 200 °F raises the alarm (DB 10 A3.A)",
        tasks: &["temperature_alarm"],
    },
];

/// The example called `name`.
pub fn find(name: &str) -> Option<&'static Example> {
    EXAMPLES.iter().find(|e| e.name == name)
}

/// The names of the examples, comma-separated.
pub fn names() -> String {
    EXAMPLES
        .iter()
        .map(|e| e.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Adds example `name`'s robot tasks to `sim`; `None` for an unknown name.
pub fn with_tasks(name: &str, sim: Sim) -> Option<Sim> {
    use x10_robots::{fig4_2, fig4_4, fig4_6};
    Some(match name {
        "fig4_2" => sim.with_robot("single_board", fig4_2::single_board),
        "fig4_4" => sim
            .with_robot("single_board", fig4_2::single_board)
            .with_robot("light_motor", fig4_4::light_motor),
        "fig4_6" => sim.with_robot("temperature_alarm", fig4_6::temperature_alarm),
        _ => return None,
    })
}

/// Example `name` against its world, ready to run; `None` for an unknown name.
pub fn sim(name: &str, config: SimConfig) -> Option<Sim> {
    with_tasks(name, scenario::build(name, config)?)
}
