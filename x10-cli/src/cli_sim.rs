//! The `x10 sim` and `x10 report` subcommands (wired into `src/bin/x10.rs`).

use std::process::ExitCode;

use clap::Args;

use crate::app::{self, RunArgs};
use crate::report;
use x10_sim::examples::{self, Example};
use x10_sim::world::World;

const SIM_HELP: &str = "\
EXAMPLES (robots/src, their worlds in robots/worlds)
  fig4_2  thesis Fig. 4.2: button (SELF S2.B) or force (SELF S1) > 100 runs the motor (SELF A1)
  fig4_4  Fig. 4.2 plus a second task: light on DB 9 S1 > 700 runs a motor on DB 9 A1 at 50 %
  fig4_6  thesis Fig. 4.6: freezer (DB 17 S1) > 1 °C or oven (DB 108 S6) < 200 °F: alarm (DB 10 A3.A)
  bumper  three tasks: heartbeat LED, a lamp following the light, a timed back-off on a bump
  doorbell  a button on DB 9 S1.A rings a chime on SELF A1.A: its events wake the task
  explorer  a chassis in a walled arena: drives; on each bump (from its contacts) backs off, turns
  wall_follower  a chassis keeps the wall on its left at 300 mm along its ranger's beam
  line_follower  a chassis follows the edge of a dark floor line with one line sensor
  freezer  Fig. 4.6's alarm against a freezer model whose door opens at 2 s: it warms, the alarm sounds
  full_bus  110 boards (0x09 to 0x76), 8 sensor ports each, every board scanned every 100 ms

OUTPUT
  A summary: what each device did and when, the bus load, warnings. --trace prints instead one
  line per bus transaction (microcode, bytes, bus time), reply, event, robot call and output
  change: `seconds LEVEL source: what`. The same seed gives the same output, byte for byte.
  --svg/--html draw the devices, the bus and each task's calls over time (hover for details; the
  page zooms and lists every change); --vcd writes SDA/SCL for GTKWave or Surfer; --mcap writes
  the run for Foxglove (plot /x10/outputs/BOARD/PIN/KIND .value: docs/usb-link.md); built with
  the feature foxglove-live, --foxglove-ws plays it to Foxglove's Open connection.

LONG RUNS
  A run longer than a virtual minute keeps a summary, built as it goes (--keep summary): the
  counts and the bus load of the whole run, the first 10 000 failures, warnings and output
  changes; its memory does not grow with the run. --trace, --svg, --html, --vcd and --mcap need
  the full record (--keep all, about 6 MB per virtual minute of a lightly loaded bus): with them
  the run keeps everything, and warns past 10 virtual minutes. --record FILE streams the
  bus's lines of --trace to FILE as each transaction ends, in any run: the whole bus record of
  a long one without holding it. --stats prints the speed and the peak memory; --bench runs
  the benchmark of docs/performance.md.

YOUR OWN ROBOT
  `x10 new PATH` makes a crate of your own; its `cargo sim` takes the same options.

EXAMPLES
  x10 sim fig4_4
  x10 sim bumper --html bumper.html
  x10 sim fig4_4 --mcap fig4_4.mcap                            # open it in Foxglove
  x10 sim explorer --duration-ms 20000 --html explorer.html    # the arena seen from above
  x10 sim fig4_6 --clock 100k --duration-ms 4000 --trace --vcd fig4_6.vcd
  x10 sim fig4_4 --duration-ms 36000000 --stats                # 10 virtual hours
  x10 sim full_bus --clock 1M --duration-ms 60000
  x10 sim --report";

/// Arguments of `x10 sim`.
#[derive(Args, Debug)]
#[command(after_help = SIM_HELP)]
pub struct SimArgs {
    /// Example robot: fig4_2, fig4_4, fig4_6, bumper, doorbell, explorer, wall_follower,
    /// line_follower, freezer or full_bus.
    #[arg(required_unless_present_any = ["report", "bench"], value_parser = example)]
    pub program: Option<&'static Example>,
    /// How to run, what to print.
    #[command(flatten)]
    pub run: RunArgs,
    /// Print the latency table instead (as `x10 report`).
    #[arg(long)]
    pub report: bool,
    /// Run the simulator's benchmark instead: fig4_4 for 10 virtual hours at 400k and
    /// full_bus for one at 1M, each in a process of its own (`x10 sim NAME --keep summary
    /// --stats`), printing its speed and peak memory (docs/performance.md; its figures are
    /// from a build with `--profile sim`).
    #[arg(long)]
    pub bench: bool,
}

/// The benchmark's runs ([`SimArgs::bench`]): example, bus clock, virtual time (ms).
pub const BENCH_RUNS: [(&str, &str, u64); 2] = [
    // Figure 4.4 for 10 virtual hours: a lightly loaded bus, two tasks on two boards.
    ("fig4_4", "400k", 36_000_000),
    // A full bus for a virtual hour: 110 boards scanned every 100 ms at 1 MHz.
    ("full_bus", "1M", 3_600_000),
];

/// Arguments of `x10 report`.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Calls measured per operation and clock.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub samples: u32,
}

fn example(s: &str) -> Result<&'static Example, String> {
    examples::find(s).ok_or_else(|| format!("unknown example (known: {})", examples::names()))
}

/// `x10 sim EXAMPLE [--world FILE] [--duration-ms N] [--trace] [--svg FILE] …`.
pub fn sim_main(args: SimArgs) -> ExitCode {
    if args.report {
        return report_main(ReportArgs { samples: 20 });
    }
    if args.bench {
        return bench_main();
    }
    let Some(example) = args.program else {
        eprintln!(
            "x10 sim: name an example ({}) or give --report",
            examples::names()
        );
        return ExitCode::from(2);
    };
    let Some((world, source)) = load_world("sim", args.run.world.as_deref(), Some(example)) else {
        return ExitCode::FAILURE;
    };
    let title = format!(
        "x10 sim {} against {source}: {}",
        example.name, example.description
    );
    app::run(&args.run, &world, example.add_tasks, &title, &source)
}

/// `x10 sim --bench`: runs each of [`BENCH_RUNS`] in a process of its own (so each peak
/// memory is its own) and prints its `stats:` line.
fn bench_main() -> ExitCode {
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => {
            eprintln!("x10 sim --bench: cannot find this program: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut text = String::new();
    for (name, clock, ms) in BENCH_RUNS {
        let args = [
            "sim".to_string(),
            name.to_string(),
            "--clock".to_string(),
            clock.to_string(),
            "--duration-ms".to_string(),
            ms.to_string(),
            "--keep".to_string(),
            "summary".to_string(),
            "--stats".to_string(),
        ];
        let out = match std::process::Command::new(&exe).args(&args).output() {
            Ok(o) => o,
            Err(e) => {
                eprintln!("x10 sim --bench: cannot run {}: {e}", exe.display());
                return ExitCode::FAILURE;
            }
        };
        let stdout = String::from_utf8_lossy(&out.stdout);
        let Some(stats) = stdout.lines().find(|l| l.starts_with("stats: ")) else {
            eprintln!(
                "x10 sim --bench: `x10 {}` printed no stats ({}): {}",
                args.join(" "),
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
            return ExitCode::FAILURE;
        };
        let bus = stdout
            .lines()
            .find(|l| l.starts_with("bus: "))
            .unwrap_or("bus: ?");
        text.push_str(&format!("x10 {}\n  {bus}\n  {stats}\n", args.join(" ")));
    }
    app::write_out(&text)
}

/// `x10 report [--samples N]`: the latency table.
pub fn report_main(args: ReportArgs) -> ExitCode {
    match report::latency_table(args.samples) {
        Ok(table) => app::write_out(&table),
        Err(e) => {
            eprintln!("x10 report: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The world at `path`, else `example`'s, with the name to show for it; `None` (said on
/// standard error, as `x10 COMMAND: FILE: error`) when there is neither or it cannot be read.
fn load_world(
    command: &str,
    path: Option<&std::path::Path>,
    example: Option<&Example>,
) -> Option<(World, String)> {
    let (world, source) = match (path, example) {
        (Some(path), _) => (World::load(path), path.display().to_string()),
        (None, Some(e)) => (e.world(), format!("robots/worlds/{}.toml", e.name)),
        (None, None) => {
            eprintln!("x10 {command}: name an example or give --world");
            return None;
        }
    };
    match world {
        Ok(w) => Some((w, source)),
        Err(e) => {
            eprintln!("x10 {command}: {source}: {e}");
            None
        }
    }
}

/// Arguments of `x10 plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Example robot whose world to read (fig4_2, fig4_4, fig4_6, bumper, doorbell).
    #[arg(value_parser = example, required_unless_present = "world")]
    pub program: Option<&'static Example>,
    /// A world file instead of an example's.
    #[arg(long)]
    pub world: Option<std::path::PathBuf>,
}

/// `x10 plan`: what the motherboard would update in a world, before any run: the images it
/// carries (`[[image]]`), then one line per daughterboard, its version (`firmware = …`) and
/// what happens to it (`x10_sim::firmware::update_plan`, the decision of the motherboard's
/// updater).
pub fn plan_main(args: PlanArgs) -> ExitCode {
    let Some((world, source)) = load_world("plan", args.world.as_deref(), args.program) else {
        return ExitCode::FAILURE;
    };
    println!("# x10 plan {source}");
    for line in x10_sim::firmware::update_plan(&world) {
        println!("{line}");
    }
    ExitCode::SUCCESS
}

/// Arguments of `x10 signals`.
#[derive(Args, Debug)]
pub struct SignalsArgs {
    /// Example robot whose world to read (fig4_2, fig4_4, fig4_6, bumper, doorbell).
    #[arg(value_parser = example, required_unless_present = "world")]
    pub program: Option<&'static Example>,
    /// A world file instead of an example's.
    #[arg(long)]
    pub world: Option<std::path::PathBuf>,
    /// How much virtual time, in ms.
    #[arg(long, default_value_t = 5_000)]
    pub duration_ms: u64,
    /// Sampling step, in ms.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    pub step_ms: u64,
}

/// `x10 signals`: what a world gives the boards, as JSON lines, for a rig that drives real
/// boards from the same description as the simulator (the emulated Picos, `emu/`). First one
/// line per device (`{"device", "kind", "board", "port", "output"}`), then, for every sensor
/// port of every board, its two pins and its analog input at 0 ms and at every step where one
/// of them changes (`{"t_ms", "board", "port", "a", "b", "analog"}`, in time order). The
/// values are the simulator's own (`World::sensor_script`): what its ports read.
pub fn signals_main(args: SignalsArgs) -> ExitCode {
    let Some((world, _)) = load_world("signals", args.world.as_deref(), args.program) else {
        return ExitCode::FAILURE;
    };
    let mut out = Vec::new();
    for d in world.devices() {
        let board = world.board_of(d).map(|b| b.address());
        out.push(serde_json::json!({
            "device": d.name(),
            "kind": d.kind().name(),
            "board": board,
            "port": d.port_number(),
            "output": d.kind().is_output(),
        }));
    }
    let mut ports = Vec::new();
    for b in world.boards() {
        for port in 1..=b.kind().sensor_ports() {
            if let Some(script) = world.sensor_script(b.address(), port) {
                ports.push((b.address(), port, script, None));
            }
        }
    }
    let mut t_ms = 0;
    while t_ms <= args.duration_ms {
        let t_ns = t_ms * 1_000_000;
        for (board, port, script, last) in &mut ports {
            let now = (
                script.a.level_at(t_ns),
                script.b.level_at(t_ns),
                script.analog.value_at(t_ns),
            );
            if *last != Some(now) {
                *last = Some(now);
                out.push(serde_json::json!({
                    "t_ms": t_ms, "board": board, "port": port,
                    "a": now.0, "b": now.1, "analog": now.2,
                }));
            }
        }
        t_ms += args.step_ms;
    }
    let mut text = String::new();
    for line in out {
        text.push_str(&line.to_string());
        text.push('\n');
    }
    match std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("x10 signals: cannot write: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_help_names_every_example() {
        for e in x10_sim::examples::EXAMPLES {
            assert!(
                super::SIM_HELP.contains(&format!("  {} ", e.name)),
                "{} missing from the help",
                e.name
            );
        }
    }
}
