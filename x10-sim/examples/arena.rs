//! Runs an example robot in its arena and prints the simulator's speed; with a file name,
//! writes the arena's top view (SVG) there.
//!
//! ```sh
//! cargo run --release -p x10-sim --example arena -- explorer 60000
//! cargo run -p x10-sim --example arena -- explorer 20000 docs/arena-explorer.svg
//! ```
//!
//! With no argument, runs each arena example (explorer, wall_follower, line_follower) for
//! 60 s of virtual time, 5 times, and prints its best speed (the figures of
//! docs/performance.md).

use std::time::Instant;

use x10_sim::examples;
use x10_sim::physics::top_view_svg;
use x10_sim::sim::SimConfig;
use x10_sim::timeline::Timeline;

/// Runs per example; the fastest is printed.
const RUNS: usize = 5;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: Vec<(String, u64)> = match args.first() {
        Some(name) => {
            let ms = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(60_000);
            vec![(name.clone(), ms)]
        }
        None => ["explorer", "wall_follower", "line_follower"]
            .iter()
            .map(|n| (n.to_string(), 60_000))
            .collect(),
    };
    for (name, ms) in runs {
        let Some(example) = examples::find(&name) else {
            eprintln!("unknown example `{name}` (known: {})", examples::names());
            std::process::exit(2);
        };
        let world = match example.world() {
            Ok(w) => w,
            Err(e) => {
                eprintln!("{name}: {e}");
                std::process::exit(1);
            }
        };
        let config = SimConfig {
            duration_ms: ms,
            ..SimConfig::default()
        };
        // The best of RUNS (the machine may be busy with other work).
        let mut best: Option<(f64, x10_sim::sim::SimOutcome, Timeline)> = None;
        for _ in 0..RUNS {
            let Some(sim) = examples::sim(&name, config) else {
                eprintln!("{name}: no simulation");
                std::process::exit(1);
            };
            let start = Instant::now();
            let outcome = match sim.run() {
                Ok(o) => o,
                Err(e) => {
                    eprintln!("{name}: {e}");
                    std::process::exit(1);
                }
            };
            let tl = Timeline::new(&world, &outcome);
            let wall = start.elapsed().as_secs_f64();
            if best.as_ref().is_none_or(|(w, _, _)| wall < *w) {
                best = Some((wall, outcome, tl));
            }
        }
        let Some((wall, outcome, tl)) = best else {
            return;
        };
        let virt = outcome.end_ns as f64 / 1e9;
        println!(
            "{name}: {virt:.1} s of virtual time in {wall:.3} s of wall time (run and replay, best of {RUNS}): {:.0}x real time",
            virt / wall
        );
        if let (Some(path), Some(m)) = (args.get(2), tl.motion()) {
            if let Err(e) = std::fs::write(path, top_view_svg(m)) {
                eprintln!("{path}: {e}");
                std::process::exit(1);
            }
            println!("wrote {path}");
        }
    }
}
