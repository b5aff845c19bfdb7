//! # x10-sim: X10 on a laptop
//!
//! A deterministic simulator that runs the real motherboard and daughterboard runtimes
//! (`firmware-mb`, `firmware-db`) against one simulated multi-master I2C bus and simulated
//! ports, in virtual time, and the `x10` command-line tool.
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
//!   executor is embassy-time's driver, so programs sleep in virtual time.
//! * [`trace`] and [`vcd`]: the readable trace and the SDA/SCL waveform.
//! * [`soak`]: `x10 soak`, many calls on a faulty bus checked against the ground truth.
//! * [`report`]: the latency table and the end-of-run summary; [`cli_sim`]: the `x10 sim` and
//!   `x10 report` subcommands; [`app`]: the simulator command of a robot crate (`cargo sim`);
//!   [`examples`]: the example robots of `x10-robots` by name; [`new`]: `x10 new`, a robot
//!   crate from the template.
//! * [`world`]: the boards, devices and scripted signals a program runs against, from a
//!   builder or a TOML file; [`timeline`]: what each device did over a run, as a short
//!   summary, an SVG or an HTML page.
pub mod app;
pub mod board;
pub mod bus;
pub mod cli_sim;
pub mod codec;
pub mod examples;
pub mod exec;
pub mod new;
pub mod ports;
pub mod report;
pub mod soak;

pub mod sim;
pub mod timeline;
pub mod timing;
pub mod trace;
pub mod vcd;
pub mod world;
