//! # x10-sim: X10 on a laptop
//!
//! A deterministic simulator that runs the real motherboard and daughterboard runtimes
//! (`firmware-mb`, `firmware-db`) against one simulated multi-master I2C bus and simulated
//! ports, in virtual time: a library for tests and tools. The `x10` command-line tool and the
//! `cargo sim` command of a robot crate are `x10-cli`'s.
//!
//! * [`exec`]: the single-threaded executor with virtual time, its [`exec::SimClock`] and a
//!   seeded generator.
//! * [`timing`]: I2C bit and condition times at 100 kHz, 400 kHz and 1 MHz.
//! * [`bus`]: the bus (arbitration, NACK, stretching, faults) and each node's
//!   [`x10_hal::bus::MultiMaster`] port.
//! * [`ports`]: simulated sensor and actuator ports with scripted signals, recording every
//!   actuator change.
//! * [`board`]: a daughterboard running the real `firmware-db`, restarted on reset.
//! * [`sim`]: the simulation builder ([`sim::Sim`]) running the real motherboard runtime,
//!   daughterboards, robot programs (`async fn`s taking an [`sim::X10`]) and test tasks; the
//!   executor is embassy-time's driver, so programs sleep in virtual time. Its outcome
//!   ([`sim::SimOutcome`]) holds the trace, the bus records, the actuator log and the
//!   counters.
//! * [`trace`] and [`vcd`]: the readable trace and the SDA/SCL waveform.
//! * [`world`]: the boards, devices and scripted signals a program runs against, from a
//!   builder or a TOML file; [`timeline`]: what each device did over a run, as a short
//!   summary, an SVG or an HTML page.
//! * [`physics`]: a world that answers back: a differential-drive chassis in an arena,
//!   sensors that read its pose, thermal bodies, integrated on a grid of virtual time.
//! * [`isolated`]: runs a test's simulation in a process of its own, so the statics a robot
//!   program shares between its tasks (embassy-sync `Mutex`, `Signal`, `StaticCell`, …) are
//!   that simulation's own.
//! * [`examples`]: the example robots of `x10-robots` by name, with their worlds.
pub mod board;
pub mod bus;
pub mod examples;
pub mod exec;
pub mod firmware;
pub mod isolate;
pub mod physics;
pub mod ports;

pub mod sim;
pub mod timeline;
pub mod timing;
pub mod trace;
pub mod vcd;
pub mod world;

pub use isolate::isolated;
