//! `cargo sim`: the two tasks that share the motor, against `world.toml`.

fn main() -> std::process::ExitCode {
    x10_cli::app::main("world.toml", |sim| {
        sim.with_robot("drive", robot::drive)
            .with_robot("bumper", robot::bumper)
    })
}
