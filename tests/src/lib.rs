//! # x10-tests: the host integration suite
//!
//! Every test in `tests/` runs the real motherboard runtime (`firmware-mb`), real
//! daughterboards (`firmware-db`) and the thesis's robot programs (`x10-robots`) on the
//! deterministic bus simulator of `x10-sim`, in virtual time, and asserts exact outcomes:
//! actuator states over time, bus transactions, counters, trace bytes.
//!
//! | file | what it shows |
//! |---|---|
//! | `thesis_programs.rs` | Figures 4.2, 4.4, 4.6 drive their actuators as scripted, at every bus clock |
//! | `arbitration.rs` | a DB pushing events while the MB dispatches: arbitration, nothing lost |
//! | `many_tasks.rs` | many robot tasks share the bus; every reply reaches its caller |
//! | `sequence.rs` | sequence numbers wrap with a request outstanding, never reused |
//! | `failures.rs` | a DB that never answers, answers late, is absent, resets mid-run (and its motor is driven again) |
//! | `failsafe.rs` | a stopped MB trips the DB failsafe; a talking one does not |
//! | `keepalive.rs` | the MB feeds a board's failsafe with heartbeats while its program is quiet |
//! | `determinism.rs` | same seed, same trace and waveform, byte for byte |
//! | `waveform.rs` | the VCD encodes every START, repeated START and STOP |
//! | `faults.rs` | the robot keeps working through injected NACKs and corrupted bytes |
//! | `faults_together.rs` | a sweep and outputs set together on a faulty bus, against the world and the ports |
//! | `faults_update.rs` | two boards updated through a faulty bus: each flash holds the image sent, byte for byte |
//! | `faults_pnp.rs` | ten unaddressed boards on a faulty bus: distinct addresses, the directory right, writes reach the right board |
//! | `latency.rs` | the latency table's figures against the wire-time minimum |
//!
//! This library only holds small helpers the tests share.

use x10_microcode::{Pin, PinRef, Port};
use x10_sim::exec::Nanos;
use x10_sim::ports::{ActuatorLog, Change};
use x10_sim::sim::SimConfig;

/// Settings for a test of a mechanism on the thesis's exact frames, `duration_ms` long: the
/// motherboard sets no PEC and no failsafe by itself (the safe defaults have their own
/// tests); the rest as [`SimConfig::default`].
pub fn thesis_frames(duration_ms: u64) -> SimConfig {
    SimConfig {
        mb_safe_defaults: false,
        duration_ms,
        ..SimConfig::default()
    }
}

/// `ms` milliseconds in ns.
pub const fn ms(ms: u64) -> Nanos {
    ms * 1_000_000
}

/// `us` microseconds in ns.
pub const fn us(us: u64) -> Nanos {
    us * 1_000
}

/// Actuator port `port` (from 1), pin `pin`. Panics on a port outside 1..=64 (test constants).
pub fn act(port: u8, pin: Pin) -> PinRef {
    match Port::actuator(port) {
        Ok(p) => p.pin(pin),
        Err(e) => panic!("bad actuator port {port}: {e}"),
    }
}

/// Sensor port `port` (from 1), pin `pin`. Panics on a port outside 1..=64 (test constants).
pub fn sens(port: u8, pin: Pin) -> PinRef {
    match Port::sensor(port) {
        Ok(p) => p.pin(pin),
        Err(e) => panic!("bad sensor port {port}: {e}"),
    }
}

/// The digital changes of one pin as `(time ns, high)`.
pub fn levels(log: &ActuatorLog, board: &str, pin: PinRef) -> Vec<(Nanos, bool)> {
    log.of(board, pin)
        .into_iter()
        .filter_map(|c| match c.change {
            Change::Digital(l) => Some((c.t_ns, l.is_high())),
            _ => None,
        })
        .collect()
}

/// The PWM duty changes of one pin as `(time ns, duty)`.
pub fn duties(log: &ActuatorLog, board: &str, pin: PinRef) -> Vec<(Nanos, u8)> {
    log.of(board, pin)
        .into_iter()
        .filter_map(|c| match c.change {
            Change::Duty(d) => Some((c.t_ns, d)),
            _ => None,
        })
        .collect()
}
