//! The `x10 sim` and `x10 report` subcommands (wired into `src/bin/x10.rs`).

use std::io::{self, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use crate::examples;
use crate::report;
use crate::sim::SimConfig;
use crate::timing::Speed;

const SIM_HELP: &str = "\
PROGRAMS
  fig4_2  thesis Fig. 4.2: button (SELF S2.B) or force (SELF S1) > 100 runs the motor (SELF A1)
  fig4_4  Fig. 4.2 plus a second task: light on DB 9 S1 > 700 runs a motor on DB 9 A1 at 50 %
  fig4_6  thesis Fig. 4.6: freezer (DB 17 S1) > 1 °C or oven (DB 108 S6) < 200 °F: alarm (DB 10 A3.A)

SIGNALS (virtual time)
  button pressed at 2.0 s and released at 3.0 s; force 350 from 3.6 s to 4.2 s; light rising
  from 0.5 s to 900 at 2.5 s, 300 from 4.0 s; freezer warming from -18 °C to +6 °C over 4 s;
  oven at 250 °F.

OUTPUT
  One line per bus transaction (microcode, bytes, bus time), reply, event, robot call and
  output change: `seconds LEVEL source: what`. The same seed gives the same trace, byte for
  byte. --vcd writes SDA/SCL for GTKWave or Surfer.

EXAMPLES
  x10 sim fig4_4
  x10 sim fig4_6 --clock 100k --duration-ms 4000 --vcd fig4_6.vcd
  x10 sim --report";

/// Arguments of `x10 sim`.
#[derive(Args, Debug)]
#[command(after_help = SIM_HELP)]
pub struct SimArgs {
    /// Example robot: fig4_2, fig4_4 or fig4_6.
    #[arg(required_unless_present = "report", value_parser = example)]
    pub program: Option<&'static examples::Example>,
    /// Seed of the simulation's randomness (backoff jitter, injected faults).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Bus clock: 100k, 400k or 1M.
    #[arg(long, default_value = "400k", value_parser = speed)]
    pub clock: Speed,
    /// Virtual time to simulate, in ms.
    #[arg(long, default_value_t = 5_000, value_parser = clap::value_parser!(u64).range(1..=3_600_000))]
    pub duration_ms: u64,
    /// Write the SDA/SCL waveform to FILE as VCD.
    #[arg(long, value_name = "FILE")]
    pub vcd: Option<PathBuf>,
    /// Leave out the robots' per-call lines (bus, events, outputs and warnings stay).
    #[arg(long)]
    pub quiet: bool,
    /// Print the latency table instead (as `x10 report`).
    #[arg(long)]
    pub report: bool,
}

/// Arguments of `x10 report`.
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Calls measured per operation and clock.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub samples: u32,
}

fn example(s: &str) -> Result<&'static examples::Example, String> {
    examples::find(s).ok_or_else(|| format!("unknown example (known: {})", examples::names()))
}

fn speed(s: &str) -> Result<Speed, String> {
    s.parse::<Speed>().map_err(|e| e.to_string())
}

fn write_out(text: &str) -> ExitCode {
    let mut out = io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Ok(()) => ExitCode::SUCCESS,
        // `x10 sim … | head`: the reader went away.
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("x10: cannot write: {e}");
            ExitCode::FAILURE
        }
    }
}

/// `x10 sim PROGRAM [--seed N] [--clock 100k|400k|1M] [--duration-ms N] [--vcd FILE]`.
pub fn sim_main(args: SimArgs) -> ExitCode {
    if args.report {
        return report_main(ReportArgs { samples: 20 });
    }
    let Some(program) = args.program else {
        eprintln!("x10 sim: name a program (fig4_2, fig4_4, fig4_6) or give --report");
        return ExitCode::from(2);
    };
    let config = SimConfig {
        speed: args.clock,
        seed: args.seed,
        duration_ms: args.duration_ms,
        trace_calls: !args.quiet,
        record_wire: args.vcd.is_some(),
        ..SimConfig::default()
    };
    let Some(sim) = examples::sim(program.name, config) else {
        eprintln!("x10 sim: unknown example {}", program.name);
        return ExitCode::from(2);
    };
    let outcome = match sim.run() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("x10 sim: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some(path) = &args.vcd {
        if let Err(e) = std::fs::write(path, outcome.vcd()) {
            eprintln!("x10 sim: cannot write {}: {e}", path.display());
            return ExitCode::FAILURE;
        }
    }
    let mut text = format!(
        "# x10 sim {} --seed {} --clock {} --duration-ms {}: {}\n",
        program.name, args.seed, args.clock, args.duration_ms, program.description
    );
    text.push_str(&outcome.trace.render());
    text.push_str(&report::summary(&outcome));
    write_out(&text)
}

/// `x10 report [--samples N]`: the latency table.
pub fn report_main(args: ReportArgs) -> ExitCode {
    match report::latency_table(args.samples) {
        Ok(table) => write_out(&table),
        Err(e) => {
            eprintln!("x10 report: {e}");
            ExitCode::FAILURE
        }
    }
}
