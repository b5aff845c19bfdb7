//! # x10-cli: the `x10` command-line tool
//!
//! The tool around the simulator library (`x10-sim`): everything here is a command or what
//! a command prints; the simulation itself (bus, executor, ports, boards, worlds, trace,
//! timeline, VCD) is `x10-sim`'s.
//!
//! * [`codec`]: frames ⇄ JSON and frames in words: `x10 decode`, `x10 encode`.
//! * [`app`]: the simulator command of a robot crate (`cargo sim` in a crate made by
//!   `x10 new`) and of `x10 sim`: options, summary or trace, SVG, HTML and VCD files.
//! * [`cli_sim`]: the `x10 sim` and `x10 report` subcommands.
//! * [`report`]: the latency table and the end-of-run summary printed after a trace.
//! * [`soak`]: `x10 soak`, many calls on a faulty bus checked against the simulator's ground
//!   truth.
//! * [`new`]: `x10 new`, a robot crate from the template.
//! * [`monitor`]: `x10 monitor`, the live robot over its USB link, and [`monitor::Robot`], the
//!   laptop program's API.
//! * [`foxglove`]: `--mcap FILE` of `x10 monitor`, `x10 sim` and `cargo sim`: the run as an
//!   MCAP file for plotting in Foxglove.
//! * `foxglove_ws` (cargo feature `foxglove-live`): `x10 monitor --foxglove-ws`, the live run
//!   served to Foxglove's *Open connection*.
//! * [`uf2`]: `x10 uf2`, a Pico image as a UF2 file for the boot ROM's drive (no probe).
pub mod app;
pub mod cli_sim;
pub mod codec;
pub mod foxglove;
#[cfg(feature = "foxglove-live")]
pub mod foxglove_ws;
pub mod link_requests;
pub mod monitor;
pub mod new;
pub mod report;
pub mod soak;
pub mod uf2;
