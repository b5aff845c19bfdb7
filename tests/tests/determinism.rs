//! Same seed, same run: the trace and the waveform are identical byte for byte, even with
//! injected faults; another seed gives another run.

use x10_sim::bus::FaultConfig;
use x10_sim::sim::{SimConfig, SimOutcome};
use x10_sim::timing::Speed;

fn run(seed: u64) -> SimOutcome {
    let config = SimConfig {
        seed,
        speed: Speed::Standard,
        duration_ms: 3_000,
        faults: FaultConfig {
            nack_ppm: 20_000,
            corrupt_ppm: 10_000,
            ..FaultConfig::NONE
        },
        ..SimConfig::default()
    };
    x10_sim::examples::sim("fig4_4", config)
        .expect("an example")
        .run()
        .unwrap()
}

#[test]
fn same_seed_same_trace_and_waveform_byte_for_byte() {
    let a = run(7);
    let b = run(7);
    let (ta, tb) = (a.trace.render(), b.trace.render());
    assert!(ta.len() > 10_000);
    assert!(ta.contains("fault injected"), "the run exercises faults");
    assert_eq!(ta, tb);
    assert_eq!(a.vcd(), b.vcd());
    assert_eq!(a.records, b.records);
    assert_eq!(a.log.changes(), b.log.changes());
    assert_eq!(a.mb, b.mb);
}

#[test]
fn another_seed_gives_another_run() {
    let a = run(7);
    let c = run(8);
    assert_ne!(a.trace.render(), c.trace.render());
    // The robot still does its job either way.
    for o in [&a, &c] {
        assert!(o.bus.injected > 0);
        assert!(o.mb.retries > 0);
    }
}

#[test]
fn simulations_on_parallel_threads_are_isolated() {
    // embassy-time reads the virtual time of the simulation on the calling thread: four runs
    // at once, with different seeds and examples, each equal to the same run made alone.
    let alone: Vec<String> = [7, 8].iter().map(|&s| run(s).trace.render()).collect();
    let bumper = |seed: u64| {
        let config = SimConfig {
            seed,
            duration_ms: 3_000,
            ..SimConfig::default()
        };
        x10_sim::examples::sim("bumper", config)
            .expect("an example")
            .run()
            .unwrap()
            .trace
            .render()
    };
    let bumper_alone = bumper(3);
    let handles: Vec<std::thread::JoinHandle<String>> = (0..4u64)
        .map(|i| {
            std::thread::spawn(move || match i {
                0 => run(7).trace.render(),
                1 => run(8).trace.render(),
                _ => bumper(3),
            })
        })
        .collect();
    let together: Vec<String> = handles.into_iter().map(|h| h.join().unwrap()).collect();
    assert_eq!(together[0], alone[0]);
    assert_eq!(together[1], alone[1]);
    assert_eq!(together[2], bumper_alone);
    assert_eq!(together[3], bumper_alone);
}
