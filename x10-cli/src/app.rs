//! The simulator command of a robot crate (`cargo sim` in a crate made by `x10 new`) and of
//! `x10 sim`: runs robot tasks against a world file and prints a short summary (what each
//! device did, bus load, errors), the full trace with `--trace`, and writes the timeline as
//! SVG or HTML, the bus as VCD.
//!
//! ```no_run
//! fn main() -> std::process::ExitCode {
//!     # async fn drive(_x10: x10_sim::sim::X10) {}
//!     x10_cli::app::main("world.toml", |sim| sim.with_robot("drive", drive))
//! }
//! ```

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser};

use x10_sim::sim::{Sim, SimConfig, SimOutcome};
use x10_sim::timeline;
use x10_sim::timing::Speed;
use x10_sim::world::World;

/// How to run and what to print: the options of `cargo sim` and `x10 sim`.
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// The world to run against (default: the crate's world file).
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Virtual time to simulate, in ms.
    #[arg(long, default_value_t = 5_000, value_parser = clap::value_parser!(u64).range(1..=3_600_000))]
    pub duration_ms: u64,
    /// Seed of the simulation's randomness (backoff jitter, injected faults).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Bus clock: 100k, 400k or 1M.
    #[arg(long, default_value = "400k", value_parser = speed)]
    pub clock: Speed,
    /// Print the full trace (every frame, reply, event, call and output change) instead of
    /// the summary.
    #[arg(long)]
    pub trace: bool,
    /// Leave the robots' per-call lines out of the trace.
    #[arg(long, requires = "trace")]
    pub quiet: bool,
    /// Write the devices' timeline as an SVG picture to FILE.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Write the devices' timeline as an HTML page to FILE.
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// Write the SDA/SCL waveform to FILE as VCD (GTKWave, Surfer).
    #[arg(long, value_name = "FILE")]
    pub vcd: Option<PathBuf>,
}

fn speed(s: &str) -> Result<Speed, String> {
    s.parse::<Speed>().map_err(|e| e.to_string())
}

#[derive(Parser, Debug)]
#[command(
    name = "sim",
    about = "Runs the robot against its world in the X10 simulator, in virtual time"
)]
struct Cli {
    #[command(flatten)]
    run: RunArgs,
}

/// The `main` of a robot crate's simulator command: parses the command line
/// ([`RunArgs`]), loads the world (`world_file`, relative to the crate, unless `--world`
/// names another), adds the robot tasks with `robots`, runs and prints. Exits non-zero when
/// the run went wrong ([`SimOutcome::problems`]).
pub fn main(world_file: &str, robots: impl FnOnce(Sim) -> Sim) -> ExitCode {
    let cli = Cli::parse_from(without_separator(std::env::args_os()));
    let default = Path::new(world_file);
    let path = cli
        .run
        .world
        .clone()
        .unwrap_or_else(|| default.to_path_buf());
    let world = match World::load(&path) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("sim: {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
    };
    let title = format!("the robot against {}", path.display());
    run(
        &cli.run,
        &world,
        robots,
        &title,
        &path.display().to_string(),
    )
}

/// The arguments without a `--` right after the program's name: `cargo sim -- --trace`
/// (cargo's own form, the `sim` alias already ends in `--`) means `cargo sim --trace`.
pub fn without_separator<T: PartialEq<&'static str>>(args: impl IntoIterator<Item = T>) -> Vec<T> {
    let mut args: Vec<T> = args.into_iter().collect();
    if args.len() > 1 && args[1] == "--" {
        args.remove(1);
    }
    args
}

/// The simulation configuration of `args`.
pub fn config(args: &RunArgs) -> SimConfig {
    SimConfig {
        speed: args.clock,
        seed: args.seed,
        duration_ms: args.duration_ms,
        trace_calls: !args.quiet,
        record_wire: args.vcd.is_some(),
        ..SimConfig::default()
    }
}

/// Runs `robots` against `world` as `args` say and prints a header line naming the run
/// (`title`), then the summary or the trace; writes the files asked for. When the run went
/// wrong ([`SimOutcome::problems`], `world_label` naming the world in them), the first lines
/// say what (`error: …`) and the exit code is 1.
pub fn run(
    args: &RunArgs,
    world: &World,
    robots: impl FnOnce(Sim) -> Sim,
    title: &str,
    world_label: &str,
) -> ExitCode {
    let sim = match world.sim(config(args)) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    let outcome = match robots(sim).run() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Err(code) = write_files(args, world, &outcome, title) {
        return code;
    }
    let problems = outcome.problems(world_label);
    let mut text: String = problems.iter().map(|p| format!("error: {p}\n")).collect();
    text.push_str(&format!(
        "# {title} (--seed {} --clock {} --duration-ms {})\n",
        args.seed, args.clock, args.duration_ms
    ));
    if args.trace {
        text.push_str(&outcome.trace.render());
        text.push_str(&crate::report::summary(&outcome));
    } else {
        text.push_str(&timeline::summary(world, &outcome));
    }
    let printed = write_out(&text);
    if problems.is_empty() {
        printed
    } else {
        ExitCode::FAILURE
    }
}

fn write_files(
    args: &RunArgs,
    world: &World,
    outcome: &SimOutcome,
    title: &str,
) -> Result<(), ExitCode> {
    let files: [(&Option<PathBuf>, &dyn Fn() -> String); 3] = [
        (&args.svg, &|| timeline::timeline_svg(world, outcome)),
        (&args.html, &|| {
            timeline::timeline_html(world, outcome, title)
        }),
        (&args.vcd, &|| outcome.vcd()),
    ];
    for (path, render) in files {
        if let Some(path) = path {
            if let Err(e) = std::fs::write(path, render()) {
                eprintln!("sim: cannot write {}: {e}", path.display());
                return Err(ExitCode::FAILURE);
            }
        }
    }
    Ok(())
}

/// Prints `text`; a reader that went away (`| head`) is not an error.
pub fn write_out(text: &str) -> ExitCode {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cannot write: {e}");
            ExitCode::FAILURE
        }
    }
}
