//! The latency table (`x10 report`, `x10 sim --report`) and the end-of-run summary.
//!
//! For digitalOut, digitalIn, pwm and analog, to an external daughterboard (db09) and to the
//! internal one (SELF), at 100 kHz, 400 kHz and 1 MHz, the table gives:
//!
//! * **sim**: the simulated end-to-end time of one `call` through the real motherboard runtime
//!   (robot task → request channel → dispatcher → bus → real daughterboard runtime → reply →
//!   pending table → robot task), the mean of N back-to-back calls, as the thesis measured
//!   (Tables 4.2 and 4.3: 20 consecutive calls). Virtual time only advances on the bus and in
//!   the scripted signals (port calls take no virtual time, as on the boards, where they are
//!   synchronous; the boards' 2 µs ADC conversion is not modelled); CPU time is not modelled,
//!   so the internal board's figures are 0.
//! * **wire**: the wire-time minimum of the same bytes ([`x10_sim::timing`]): START, 9 bits per
//!   byte, repeated START for reads, STOP; no `t_BUF`, no stretching.
//! * **thesis**: the means the thesis measured on an Arduino Mega (bus at 230–300 kHz).

use std::cell::RefCell;
use std::fmt::Write as _;
use std::rc::Rc;

use x10_devices::SELF;
use x10_microcode::{Address, Level, Op, Pin, Port, DIAGNOSTIC_NAMES};

use x10_sim::bus::Outcome;
use x10_sim::exec::Nanos;
use x10_sim::sim::{task, Sim, SimConfig, SimError, SimOutcome};
use x10_sim::timing::Speed;
use x10_sim::trace::micros;

/// The thesis's means, µs: (operation, internal (Table 4.2), external (Table 4.3)).
pub const THESIS_MEANS: [(&str, f64, f64); 4] = [
    ("digitalOut", 39.4, 261.4),
    ("digitalIn", 83.58, 554.8),
    ("pwm", 57.8, 319.0),
    ("analog", 215.58, 685.2),
];

/// The external board of the measurement.
const DB: u8 = 0x09;

fn op_of(index: usize) -> Option<Op<'static>> {
    let a1 = Port::actuator(1).ok()?;
    let s1 = Port::sensor(1).ok()?;
    match index {
        0 => Some(Op::DigitalWrite(a1.pin(Pin::A), Level::High)),
        1 => Some(Op::DigitalRead(s1.pin(Pin::A))),
        2 => Some(Op::PwmDuty(a1.pin(Pin::A), 128)),
        3 => Some(Op::AnalogRead(s1)),
        _ => None,
    }
}

/// One measured row.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// Operation name (thesis naming).
    pub op: &'static str,
    /// True for the internal board.
    pub internal: bool,
    /// Bus clock.
    pub speed: Speed,
    /// Mean simulated end-to-end time (ns).
    pub mean_ns: Nanos,
    /// Shortest (ns).
    pub min_ns: Nanos,
    /// Longest (ns).
    pub max_ns: Nanos,
    /// Wire-time minimum of the same bytes (ns; `None` for the internal board).
    pub wire_ns: Option<Nanos>,
    /// Calls that failed (should be 0).
    pub failures: usize,
}

/// Measures every operation at `speed`, `samples` back-to-back calls each.
///
/// # Errors
/// [`SimError`] when the simulation cannot run.
pub fn measure(speed: Speed, samples: u32) -> Result<Vec<Measurement>, SimError> {
    type Samples = Vec<(usize, bool, Vec<Nanos>, usize)>;
    let results: Rc<RefCell<Samples>> = Rc::new(RefCell::new(Vec::new()));
    let r = results.clone();
    let config = SimConfig {
        // The mechanism under test, on the thesis's exact frames (no PEC, no failsafe the
        // motherboard sets by itself); the safe defaults have their own tests.
        mb_safe_defaults: false,
        speed,
        duration_ms: 50 + u64::from(samples) * 8 * 20,
        trace_calls: false,
        stop_when_tasks_done: true,
        record_wire: false,
        ..SimConfig::default()
    };
    let sim = Sim::new(config);
    let ports = sim.ports("db09", 2, 2);
    let db = Address::external(DB).map_err(|e| SimError::Config(e.to_string()))?;
    let sim = sim.with_board(db, ports).with_task(
        "measure",
        task(move |ctx| {
            Box::pin(async move {
                // Let the boards boot and their boot events go out first.
                ctx.clock.sleep_ns(20_000_000).await;
                let handle = ctx.handle();
                for i in 0..4 {
                    let Some(op) = op_of(i) else { continue };
                    for (internal, target) in [(false, db), (true, SELF)] {
                        let mut times = Vec::new();
                        let mut failures = 0;
                        for _ in 0..samples {
                            let t0 = ctx.clock.now_ns();
                            if handle.call(target, op).await.is_err() {
                                failures += 1;
                            }
                            times.push(ctx.clock.now_ns() - t0);
                        }
                        r.borrow_mut().push((i, internal, times, failures));
                    }
                }
            })
        }),
    );
    let outcome = sim.run()?;
    // The wire minimum from the frames actually sent to db09 (first of each kind).
    let t = speed.timing();
    let wire_of = |fn_op: u8| -> Option<Nanos> {
        outcome
            .records
            .iter()
            .find(|r| r.addr == DB && r.outcome == Outcome::Ok && r.written.first() == Some(&fn_op))
            .map(|r| {
                if r.is_read {
                    t.write_read_ns(r.written.len(), r.read.len())
                } else {
                    t.write_ns(r.written.len())
                }
            })
    };
    let mut rows = Vec::new();
    for (i, internal, times, failures) in results.borrow().iter() {
        let (Some(op), Some((name, _, _))) = (op_of(*i), THESIS_MEANS.get(*i)) else {
            continue;
        };
        let n = times.len().max(1) as Nanos;
        rows.push(Measurement {
            op: name,
            internal: *internal,
            speed,
            mean_ns: times.iter().sum::<Nanos>() / n,
            min_ns: times.iter().copied().min().unwrap_or(0),
            max_ns: times.iter().copied().max().unwrap_or(0),
            wire_ns: if *internal {
                None
            } else {
                wire_of(op.fn_op_byte())
            },
            failures: *failures,
        });
    }
    Ok(rows)
}

fn us(ns: Nanos) -> String {
    micros(ns).trim_end_matches("us").to_string()
}

/// The whole table as printed by `x10 report`.
///
/// # Errors
/// [`SimError`] when a simulation cannot run.
pub fn latency_table(samples: u32) -> Result<String, SimError> {
    let mut by_speed = Vec::new();
    for speed in Speed::ALL {
        by_speed.push(measure(speed, samples)?);
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "X10 latency per call, µs: simulated end-to-end (mean of {samples} back-to-back calls through the\n\
         real MB and DB runtimes), wire-time minimum of the same bytes, and the thesis's measured mean\n\
         (Arduino Mega, bus at 230-300 kHz; Table 4.3 external, Table 4.2 internal)."
    );
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "| operation  | board         | 100k sim | 100k wire | 400k sim | 400k wire | 1M sim | 1M wire | thesis |"
    );
    let _ = writeln!(
        s,
        "|------------|---------------|---------:|----------:|---------:|----------:|-------:|--------:|-------:|"
    );
    let mut failures = 0;
    for (i, (name, thesis_int, thesis_ext)) in THESIS_MEANS.iter().enumerate() {
        for internal in [false, true] {
            let mut cells = Vec::new();
            for rows in &by_speed {
                let row = rows.iter().filter(|r| r.internal == internal).nth(i);
                match row {
                    Some(r) => {
                        failures += r.failures;
                        cells.push(us(r.mean_ns));
                        cells.push(r.wire_ns.map_or_else(|| "-".to_string(), us));
                    }
                    None => {
                        cells.push("?".to_string());
                        cells.push("?".to_string());
                    }
                }
            }
            let board = if internal {
                "internal SELF"
            } else {
                "external db09"
            };
            let thesis = if internal { thesis_int } else { thesis_ext };
            let _ = writeln!(
                s,
                "| {name:<10} | {board:<13} | {:>8} | {:>9} | {:>8} | {:>9} | {:>6} | {:>7} | {thesis:>6} |",
                cells.first().map_or("", String::as_str),
                cells.get(1).map_or("", String::as_str),
                cells.get(2).map_or("", String::as_str),
                cells.get(3).map_or("", String::as_str),
                cells.get(4).map_or("", String::as_str),
                cells.get(5).map_or("", String::as_str),
            );
        }
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "Frames: digitalOut and pwm are one write (4 and 5 bytes); digitalIn and analog are one\n\
         write-then-read (4 bytes, repeated START, 4 and 5 reply bytes). Back-to-back calls include\n\
         the bus free time t_BUF between transactions. CPU time is not simulated, nor the boards'\n\
         2 us ADC conversion (port calls are synchronous and take no virtual time), so internal\n\
         calls take none; the thesis's internal figures are Arduino CPU time."
    );
    if failures > 0 {
        let _ = writeln!(
            s,
            "WARNING: {failures} calls failed during the measurement."
        );
    }
    Ok(s)
}

/// The end-of-run summary lines (`# …`) printed after a trace.
pub fn summary(o: &SimOutcome) -> String {
    let mut s = String::new();
    let b = &o.bus;
    let _ = writeln!(
        s,
        "# end {}: bus at {}: {} transactions, {} arbitration lost, {} NACK, {} timeouts, {} bus faults, {} faults injected, {} resets",
        x10_sim::trace::timestamp(o.end_ns),
        o.speed,
        b.transactions,
        b.arbitration_lost,
        b.nacks,
        b.timeouts,
        b.bus_faults,
        b.injected,
        b.resets
    );
    if b.yielded > 0 || o.spins > 0 {
        let _ = writeln!(
            s,
            "# {} controller calls given up because their node was being addressed; {} instants with tasks busy-looping",
            b.yielded, o.spins
        );
    }
    let m = &o.mb;
    let _ = writeln!(
        s,
        "# mb: {} requests, {} completed, {} timeouts, {} nacks, {} bad replies, {} status errors, {} retries, {} late, {} duplicate, {} unknown replies, {} events, {} boots, {} failsafe trips",
        m.requests,
        m.completed,
        m.timeouts,
        m.nacks,
        m.bad_replies,
        m.status_errors,
        m.retries,
        m.late_replies,
        m.duplicate_replies,
        m.unknown_replies,
        m.events,
        m.boots,
        m.failsafe_trips
    );
    let boards = std::iter::once(("mb (internal)", &o.internal))
        .chain(o.boards.iter().map(|(n, d)| (n.as_str(), d)));
    for (name, d) in boards {
        let counters: Vec<String> = DIAGNOSTIC_NAMES
            .iter()
            .zip(d.values())
            .filter(|(_, v)| *v > 0)
            .map(|(n, v)| format!("{n} {v}"))
            .collect();
        let _ = writeln!(
            s,
            "# {name}: {}",
            if counters.is_empty() {
                "no counters".to_string()
            } else {
                counters.join(", ")
            }
        );
    }
    s
}
