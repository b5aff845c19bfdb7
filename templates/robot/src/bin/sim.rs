//! `cargo sim`: runs the robot (`robot::Robot`, its tasks declared once in `src/lib.rs`) in
//! the simulator against `world.toml` and prints what each device did (`cargo sim --help`
//! for the options: duration, full trace, SVG plot, …); exits 1 when the run went wrong, its
//! first line saying what.

fn main() -> std::process::ExitCode {
    x10_cli::app::main("world.toml", |sim| sim.robot(robot::Robot))
}
