//! The example robots of `x10-robots`, by name, for `x10 sim NAME`: each is its tasks (plain
//! `async fn`s taking an [`crate::sim::X10`]) and the world they run against
//! (`robots/worlds/NAME.toml`, compiled in). Your own robot does not go here: it lives in its
//! own crate with its own world file and `sim` command (`x10 new`,
//! `docs/your-first-robot.md`).

use x10_robots::{
    Bumper, Doorbell, Explorer, Fig4_2, Fig4_4, Fig4_6, FullBus, LineFollower, WallFollower,
};

use crate::sim::{Sim, SimConfig};
use crate::world::{World, WorldError};

/// One example robot.
#[derive(Clone, Copy, Debug)]
pub struct Example {
    /// Its name on the command line.
    pub name: &'static str,
    /// One line about it.
    pub description: &'static str,
    /// Adds its robot's tasks (`x10_robots::Fig4_4` and so on) to a simulation.
    pub add_tasks: fn(Sim) -> Sim,
    /// Its world file (`robots/worlds/NAME.toml`).
    pub world: &'static str,
}

/// Every example.
pub const EXAMPLES: [Example; 10] = [
    Example {
        name: "fig4_2",
        description: "thesis Fig. 4.2: button (SELF S2.B) or force (SELF S1) > 100 runs the motor (SELF A1) at 100 %",
        add_tasks: |sim| sim.robot(Fig4_2),
        world: include_str!("../../robots/worlds/fig4_2.toml"),
    },
    Example {
        name: "fig4_4",
        description: "thesis Fig. 4.4: Fig. 4.2 unchanged plus a second task: light (DB 9 S1) > 700 runs a motor (DB 9 A1) at 50 %",
        add_tasks: |sim| sim.robot(Fig4_4),
        world: include_str!("../../robots/worlds/fig4_4.toml"),
    },
    Example {
        name: "fig4_6",
        description: "thesis Fig. 4.6: freezer (DB 17 S1) > 1 °C or oven (DB 108 S6) < 200 °F raises the alarm (DB 10 A3.A)",
        add_tasks: |sim| sim.robot(Fig4_6),
        world: include_str!("../../robots/worlds/fig4_6.toml"),
    },
    Example {
        name: "bumper",
        description: "three tasks: a heartbeat LED (DB 9), a lamp following the light (SELF), a timed back-off when the bumper is hit (SELF)",
        add_tasks: |sim| sim.robot(Bumper),
        world: include_str!("../../robots/worlds/bumper.toml"),
    },
    Example {
        name: "doorbell",
        description: "a button on DB 9 (S1.A) rings a chime on the motherboard (SELF A1.A) while held: its events wake the task",
        add_tasks: |sim| sim.robot(Doorbell),
        world: include_str!("../../robots/worlds/doorbell.toml"),
    },
    Example {
        name: "explorer",
        description: "a chassis (SELF A1 left, A2 right) in a walled arena with a box: drives, and on each bump (SELF S2.B, from the chassis's contacts) backs off, turns and goes on",
        add_tasks: |sim| sim.robot(Explorer),
        world: include_str!("../../robots/worlds/explorer.toml"),
    },
    Example {
        name: "wall_follower",
        description: "a chassis keeps the wall on its left at 300 mm along its ranger's beam (SELF S1, echoes from the arena's walls)",
        add_tasks: |sim| sim.robot(WallFollower),
        world: include_str!("../../robots/worlds/wall_follower.toml"),
    },
    Example {
        name: "line_follower",
        description: "a chassis follows the edge of a dark circle on the floor with one line sensor (SELF S1, the floor's reflectance under it)",
        add_tasks: |sim| sim.robot(LineFollower),
        world: include_str!("../../robots/worlds/line_follower.toml"),
    },
    Example {
        name: "freezer",
        description: "thesis Fig. 4.6's alarm against a freezer model: its door (DB 17 S2.A) opens at 2 s and the cabinet warms towards 20 °C until the alarm (DB 10 A3.A) goes on",
        add_tasks: |sim| sim.robot(Fig4_6),
        world: include_str!("../../robots/worlds/freezer.toml"),
    },
    Example {
        name: "full_bus",
        description: "a full bus: 110 daughterboards (0x09 to 0x76) with 8 sensor ports each, every one scanned once every 100 ms (the load test of the bus and the simulator)",
        add_tasks: |sim| sim.robot(FullBus),
        world: include_str!("../../robots/worlds/full_bus.toml"),
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

impl Example {
    /// Its world.
    ///
    /// # Errors
    /// None for the examples' own files (a test loads each).
    pub fn world(&self) -> Result<World, WorldError> {
        World::from_toml(self.world)
    }
}

/// Adds example `name`'s robot tasks to `sim`; `None` for an unknown name.
pub fn with_tasks(name: &str, sim: Sim) -> Option<Sim> {
    find(name).map(|e| (e.add_tasks)(sim))
}

/// Example `name` against its world, ready to run; `None` for an unknown name (or a world
/// file that does not load, which a test rules out).
pub fn sim(name: &str, config: SimConfig) -> Option<Sim> {
    let example = find(name)?;
    let sim = example.world().ok()?.sim(config).ok()?;
    with_tasks(name, sim)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_example_has_a_valid_world_and_its_tasks() {
        for e in EXAMPLES {
            assert!(e.world().is_ok(), "{}", e.name);
            assert!(sim(e.name, SimConfig::default()).is_some(), "{}", e.name);
        }
        assert!(sim("fig9_9", SimConfig::default()).is_none());
    }
}
