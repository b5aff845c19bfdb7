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

use x10_sim::sim::{Keep, Sim, SimConfig, SimOutcome};
use x10_sim::timeline;
use x10_sim::timing::Speed;
use x10_sim::world::World;

/// How to run and what to print: the options of `cargo sim` and `x10 sim`.
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// The world to run against (default: the crate's world file).
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Virtual time to simulate, in ms (up to 10 days). Runs longer than a virtual minute
    /// keep a summary only (see --keep).
    #[arg(long, default_value_t = 5_000, value_parser = clap::value_parser!(u64).range(1..=MAX_DURATION_MS))]
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
    /// Write the run to FILE as MCAP for Foxglove: output changes on
    /// /x10/outputs/BOARD/PIN/KIND (plot `.value`), calls, events and the trace
    /// (docs/usb-link.md, "Plotting in Foxglove").
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// After the run, serve it to Foxglove's Open connection (the Foxglove WebSocket
    /// protocol) at ADDR (default 127.0.0.1:8765: ws://localhost:8765), played at the pace of
    /// its virtual time once a panel subscribes.
    #[cfg(feature = "foxglove-live")]
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove_ws::DEFAULT_ADDR)]
    pub foxglove_ws: Option<String>,
    /// How fast --foxglove-ws plays the run: 1 is the virtual time's own pace, 10 ten times
    /// faster.
    #[cfg(feature = "foxglove-live")]
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        requires = "foxglove_ws"
    )]
    pub foxglove_speed: f64,
    /// What the run keeps: `all` (every transaction and call: what --trace, --svg, --html
    /// and --vcd need; memory grows with the run, about 6 MB per virtual minute of a lightly
    /// loaded bus) or `summary` (counts, the bus load and the first 10 000 failures, output
    /// changes and warnings, built as the run goes: memory independent of the run's length).
    /// Default: `summary` for runs longer than a virtual minute (60 000 ms) without those
    /// four options, `all` otherwise.
    #[arg(long, value_parser = keep)]
    pub keep: Option<Keep>,
    /// Stream the bus's record to FILE as the run goes: the lines --trace prints for each
    /// transaction (frames, replies, events, faults, lost arbitrations), written as each
    /// ends, whatever the run keeps: the whole bus record of a long run, in bounded memory.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// After the summary, print how fast the run went and its peak memory: bus
    /// transactions and virtual seconds per wall second and per CPU second of the process,
    /// and its VmHWM.
    #[arg(long)]
    pub stats: bool,
}

/// The longest run `--duration-ms` takes: 10 virtual days.
pub const MAX_DURATION_MS: u64 = 864_000_000;

/// Runs longer than this (ms) keep a summary only unless an option needs the full record.
pub const AUTO_SUMMARY_MS: u64 = 60_000;

/// Runs longer than this (ms) with the full record get a warning (their memory).
pub const WARN_FULL_MS: u64 = 600_000;

fn keep(s: &str) -> Result<Keep, String> {
    match s {
        "all" => Ok(Keep::All),
        "summary" => Ok(Keep::Summary),
        _ => Err("`all` or `summary`".to_string()),
    }
}

impl RunArgs {
    /// The options that need every transaction and call (the trace, the pages, the VCD, the
    /// MCAP file).
    fn needs_full_record(&self) -> Option<&'static str> {
        [
            (self.trace, "--trace"),
            (self.svg.is_some(), "--svg"),
            (self.html.is_some(), "--html"),
            (self.vcd.is_some(), "--vcd"),
            (self.mcap.is_some(), "--mcap"),
            (self.foxglove_live(), "--foxglove-ws"),
        ]
        .into_iter()
        .find_map(|(on, name)| on.then_some(name))
    }

    /// True with `--foxglove-ws` (in a build with the feature `foxglove-live`).
    fn foxglove_live(&self) -> bool {
        #[cfg(feature = "foxglove-live")]
        return self.foxglove_ws.is_some();
        #[cfg(not(feature = "foxglove-live"))]
        false
    }

    /// What the run keeps: `--keep`, else a summary for runs longer than
    /// [`AUTO_SUMMARY_MS`] that no option needs the full record of.
    pub fn keep(&self) -> Keep {
        match self.keep {
            Some(k) => k,
            None if self.duration_ms > AUTO_SUMMARY_MS && self.needs_full_record().is_none() => {
                Keep::Summary
            }
            None => Keep::All,
        }
    }
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
    let args = without_separator(std::env::args_os());
    if args.get(1).is_some_and(|a| *a == "plan") {
        return plan_main(world_file, args.into_iter().skip(1));
    }
    let cli = Cli::parse_from(args);
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

#[derive(Parser, Debug)]
#[command(
    name = "plan",
    about = "Prints what the robot's motherboard image (`cargo mb-pico`) would update in its world: \
             the daughterboard images it carries (X10_CARRY_KINDS, default pico, at X10_FW_VERSION \
             or the X10 checkout's version), then each daughterboard and what happens to it"
)]
struct PlanCli {
    /// The world to read (default: the crate's world file).
    #[arg(long, value_name = "FILE")]
    world: Option<PathBuf>,
}

/// The images a robot crate's `cargo mb-pico` carries, as its build script builds them
/// (`x10-boards/carry_checkout.rs`): the kinds of `kinds` (`X10_CARRY_KINDS`; `None`: `pico`),
/// each at `version` (`X10_FW_VERSION`; `None`: the X10 checkout's, this crate's own). The
/// simulator's worlds have no C011 board: a `c011` is left out and said in the second value.
///
/// # Errors
/// An unknown kind or a version that is not major.minor.patch, in words.
pub fn crate_carried_images(
    kinds: Option<&str>,
    version: Option<&str>,
) -> Result<(Vec<x10_sim::world::CarriedImage>, bool), String> {
    use x10_sim::world::{BoardKind, CarriedImage};
    let version = version.unwrap_or(env!("CARGO_PKG_VERSION"));
    let parts: Vec<Option<u8>> = version.split('.').map(|p| p.parse().ok()).collect();
    let version = match parts.as_slice() {
        [Some(a), Some(b), Some(c)] => [*a, *b, *c],
        _ => {
            return Err(format!(
                "X10_FW_VERSION `{version}` is not major.minor.patch (numbers up to 255)"
            ))
        }
    };
    let mut images = Vec::new();
    let mut c011 = false;
    for k in kinds.unwrap_or("pico").split(',').map(str::trim) {
        let kind = match k {
            "" => continue,
            "pico" => BoardKind::Pico,
            "g431" => BoardKind::G431,
            "c011" => {
                c011 = true;
                continue;
            }
            other => {
                return Err(format!(
                    "X10_CARRY_KINDS: unknown board kind `{other}` (pico, g431 or c011)"
                ))
            }
        };
        images.push(CarriedImage { kind, version });
    }
    Ok((images, c011))
}

/// `cargo plan` in a robot crate (`cargo sim -- plan`): `x10 plan` for the crate's world with
/// the images its `cargo mb-pico` carries ([`crate_carried_images`]), unless the world names
/// its own (`[[image]]`). Exit code 1 when the world or the variables are wrong.
fn plan_main(world_file: &str, args: impl IntoIterator<Item = std::ffi::OsString>) -> ExitCode {
    let cli = PlanCli::parse_from(args);
    let path = cli.world.unwrap_or_else(|| PathBuf::from(world_file));
    let mut world = match World::load(&path) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("plan: {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
    };
    let kinds = std::env::var("X10_CARRY_KINDS").ok();
    let version = std::env::var("X10_FW_VERSION").ok();
    println!("# cargo plan {}", path.display());
    if world.images().is_empty() {
        let (images, c011) = match crate_carried_images(kinds.as_deref(), version.as_deref()) {
            Ok(i) => i,
            Err(e) => {
                eprintln!("plan: {e}");
                return ExitCode::FAILURE;
            }
        };
        println!("# the images cargo mb-pico carries (X10_CARRY_KINDS, X10_FW_VERSION)");
        if c011 {
            println!("# and c011's: a world file has no C011 board");
        }
        for i in images {
            world = world.carries(i);
        }
    } else {
        println!("# the images the world names ([[image]])");
    }
    for line in x10_sim::firmware::update_plan(&world) {
        println!("{line}");
    }
    ExitCode::SUCCESS
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
        keep: args.keep(),
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
    if let Some(option) = args.needs_full_record() {
        if args.keep() == Keep::Summary {
            eprintln!("sim: {option} needs the full record: leave out --keep summary");
            return ExitCode::from(2);
        }
        if args.duration_ms > WARN_FULL_MS {
            eprintln!(
                "sim: warning: {option} keeps every transaction and call in memory, about 6 MB per virtual minute of a lightly loaded bus: a run this long may need GBs"
            );
        }
    }
    let sim = match world.sim(config(args)) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    let sim = match &args.record {
        None => sim,
        Some(path) => match std::fs::File::create(path) {
            Ok(f) => robots_sim_record(sim, f),
            Err(e) => {
                eprintln!("sim: cannot write {}: {e}", path.display());
                return ExitCode::FAILURE;
            }
        },
    };
    let started = std::time::Instant::now();
    let cpu_before = cpu_seconds();
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
    if outcome.record_errors > 0 {
        if let Some(path) = &args.record {
            eprintln!(
                "sim: {} writes to {} failed",
                outcome.record_errors,
                path.display()
            );
            return ExitCode::FAILURE;
        }
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
    if args.stats {
        text.push_str(&stats_line(&outcome, started.elapsed(), cpu_before));
    }
    let printed = write_out(&text);
    #[cfg(feature = "foxglove-live")]
    if let Some(addr) = &args.foxglove_ws {
        let Err(code) = serve_live(args, world, &outcome, addr);
        return code;
    }
    if problems.is_empty() {
        printed
    } else {
        ExitCode::FAILURE
    }
}

/// `--foxglove-ws ADDR`: the run served to Foxglove, played once a panel subscribes.
#[cfg(feature = "foxglove-live")]
fn serve_live(
    args: &RunArgs,
    world: &World,
    outcome: &SimOutcome,
    addr: &str,
) -> Result<std::convert::Infallible, ExitCode> {
    let server = crate::foxglove_ws::LiveServer::start(addr, "x10 sim").map_err(|e| {
        eprintln!("sim: --foxglove-ws {addr}: {e}");
        ExitCode::FAILURE
    })?;
    let messages = crate::foxglove::sim_messages(world, outcome, config(args).mb_address);
    // Every topic first: a client that connects sees them all.
    server.advertise(&messages);
    println!(
        "sim: Foxglove's Open connection: ws://{} (the run plays once a panel subscribes; Ctrl-C ends)",
        server.addr()
    );
    let _ = io::stdout().flush();
    server.play(&messages, args.foxglove_speed);
    println!(
        "sim: played {} messages; Foxglove keeps them while connected (Ctrl-C ends)",
        messages.len()
    );
    let _ = io::stdout().flush();
    // Connected panels keep what they got while the server lives: until Ctrl-C.
    loop {
        std::thread::park();
    }
}

/// `sim` streaming its bus record to `file` (buffered).
fn robots_sim_record(sim: Sim, file: std::fs::File) -> Sim {
    sim.record_to(Box::new(io::BufWriter::new(file)))
}

/// How fast a run went and its peak memory, one line: `stats: N bus transactions in S s
/// wall (C s CPU): T transactions per wall s (U per CPU s), V virtual s per wall s (W per CPU
/// s); P task polls (Q per transaction); peak memory M MB (VmHWM)`. The CPU time is the process's own (/proc/self/stat), what
/// the run costs on a core of its own when the machine is shared; `cpu_before` is its value
/// before the run.
pub fn stats_line(
    outcome: &SimOutcome,
    wall: std::time::Duration,
    cpu_before: Option<f64>,
) -> String {
    let wall_s = wall.as_secs_f64().max(1e-9);
    let cpu_s = cpu_seconds()
        .zip(cpu_before)
        .map(|(after, before)| (after - before).max(1e-9));
    let virtual_s = outcome.end_ns as f64 / 1e9;
    let txns = outcome.bus.transactions as f64;
    let peak = peak_memory_kb().map_or_else(
        || "unknown".to_string(),
        |kb| format!("{:.1} MB", kb as f64 / 1024.0),
    );
    match cpu_s {
        Some(cpu) => format!(
            "stats: {} bus transactions in {wall_s:.2} s wall ({cpu:.2} s CPU): {:.0} transactions per wall s ({:.0} per CPU s), {:.0} virtual s per wall s ({:.0} per CPU s); {} task polls ({:.1} per transaction); peak memory {peak} (VmHWM)\n",
            outcome.bus.transactions,
            txns / wall_s,
            txns / cpu,
            virtual_s / wall_s,
            virtual_s / cpu,
            outcome.polls,
            outcome.polls as f64 / txns.max(1.0),
        ),
        None => format!(
            "stats: {} bus transactions in {wall_s:.2} s wall: {:.0} transactions per wall s, {:.0} virtual s per wall s; peak memory {peak} (VmHWM)\n",
            outcome.bus.transactions,
            txns / wall_s,
            virtual_s / wall_s,
        ),
    }
}

/// The CPU time this process has used, user and system, in seconds (from /proc/self/stat;
/// `None` where there is no such file). Linux counts it in ticks of 1/100 s.
pub fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The fields after the command's name (which may hold spaces), from field 3 on.
    let rest = stat.rsplit_once(") ")?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// The process's peak resident memory in KiB (`VmHWM` of /proc/self/status; `None` where
/// there is no such file).
pub fn peak_memory_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
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
    if let Some(path) = &args.mcap {
        let messages = crate::foxglove::sim_messages(world, outcome, config(args).mb_address);
        if let Err(e) = crate::foxglove::write_file(path, &messages) {
            eprintln!("sim: cannot write {}: {e}", path.display());
            return Err(ExitCode::FAILURE);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cargo_plan_knows_what_cargo_mb_pico_carries() {
        use x10_sim::world::{BoardKind, CarriedImage};
        let ours: [u8; 3] = {
            let v: Vec<u8> = env!("CARGO_PKG_VERSION")
                .split('.')
                .map(|p| p.parse().unwrap())
                .collect();
            [v[0], v[1], v[2]]
        };
        // Unset: db-pico at the checkout's version, as the crate's build script carries it.
        assert_eq!(
            crate_carried_images(None, None),
            Ok((
                vec![CarriedImage {
                    kind: BoardKind::Pico,
                    version: ours
                }],
                false
            ))
        );
        assert_eq!(
            crate_carried_images(Some("c011, g431,pico"), Some("2.0.1")),
            Ok((
                vec![
                    CarriedImage {
                        kind: BoardKind::G431,
                        version: [2, 0, 1]
                    },
                    CarriedImage {
                        kind: BoardKind::Pico,
                        version: [2, 0, 1]
                    }
                ],
                true
            ))
        );
        assert_eq!(crate_carried_images(Some(""), None), Ok((vec![], false)));
        assert_eq!(
            crate_carried_images(Some("pico,uno"), None),
            Err("X10_CARRY_KINDS: unknown board kind `uno` (pico, g431 or c011)".into())
        );
        assert_eq!(
            crate_carried_images(None, Some("2.0")),
            Err("X10_FW_VERSION `2.0` is not major.minor.patch (numbers up to 255)".into())
        );
        assert!(crate_carried_images(None, Some("1.2.256")).is_err());
    }

    fn args(v: &[&str]) -> RunArgs {
        let mut all = vec!["sim"];
        all.extend_from_slice(v);
        Cli::parse_from(all).run
    }

    #[test]
    fn long_runs_keep_a_summary_unless_an_option_needs_everything() {
        assert_eq!(args(&[]).keep(), Keep::All);
        assert_eq!(args(&["--duration-ms", "60000"]).keep(), Keep::All);
        assert_eq!(args(&["--duration-ms", "60001"]).keep(), Keep::Summary);
        assert_eq!(args(&["--duration-ms", "864000000"]).keep(), Keep::Summary);
        for option in [
            &["--trace"][..],
            &["--svg", "a.svg"],
            &["--html", "a.html"],
            &["--vcd", "a.vcd"],
            &["--mcap", "a.mcap"],
        ] {
            let mut v = vec!["--duration-ms", "3600000"];
            v.extend_from_slice(option);
            assert_eq!(args(&v).keep(), Keep::All, "{option:?}");
            assert_eq!(args(&v).needs_full_record(), Some(option[0]));
        }
        assert_eq!(args(&["--keep", "summary"]).keep(), Keep::Summary);
        assert_eq!(
            args(&["--keep", "all", "--duration-ms", "3600000"]).keep(),
            Keep::All
        );
        assert!(Cli::try_parse_from(["sim", "--keep", "some"]).is_err());
        assert!(Cli::try_parse_from(["sim", "--duration-ms", "864000001"]).is_err());
        assert_eq!(
            config(&args(&["--duration-ms", "70000"])).keep,
            Keep::Summary
        );
    }

    #[test]
    fn record_streams_the_bus_lines_of_the_trace_to_a_file() {
        x10_sim::isolated(|| {
            let Some(example) = x10_sim::examples::find("fig4_4") else {
                panic!("fig4_4")
            };
            let Ok(world) = example.world() else {
                panic!("its world")
            };
            let path = std::env::temp_dir().join(format!("x10-record-{}.txt", std::process::id()));
            let p = path.display().to_string();
            let a = args(&["--duration-ms", "300", "--keep", "summary", "--record", &p]);
            assert_eq!(
                run(&a, &world, example.add_tasks, "t", "w.toml"),
                ExitCode::SUCCESS
            );
            let record = std::fs::read_to_string(&path).unwrap_or_default();
            let _ = std::fs::remove_file(&path);
            // Figure 4.4's first transaction: board 9's boot event to the motherboard.
            let first = record.lines().next().unwrap_or_default();
            assert!(
                first.starts_with("0.000000 INFO  db09: -> mb event boot seq 0 ok "),
                "{first}"
            );
            assert!(record.lines().count() > 10);
            // The same lines as the trace of the same run.
            let sim = world
                .sim(config(&args(&["--duration-ms", "300"])))
                .map(example.add_tasks);
            let Ok(Ok(full)) = sim.map(Sim::run) else {
                panic!("the run")
            };
            let trace = full.trace.render();
            assert!(record.lines().all(|l| trace.lines().any(|t| t == l)));
        });
    }

    #[test]
    fn a_summary_with_an_option_that_needs_everything_is_refused() {
        let world = World::new();
        let a = args(&["--keep", "summary", "--trace"]);
        assert_eq!(run(&a, &world, |s| s, "t", "w.toml"), ExitCode::from(2));
    }
}
