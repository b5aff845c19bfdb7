//! Build script of the motherboard images (nothing happens for host builds):
//!
//! * the robot program: `X10_ROBOT` names one of `x10_robots::names()` (default `fig4_2`);
//!   it becomes `$OUT_DIR/robot.rs`, which the images include, so the image runs exactly the
//!   program the simulator runs under that name. An unknown name stops the build and lists
//!   the programs.
//! * link arguments, the same as firmware-db's (one file, `x10-boards/link_args.rs`): `link.x`
//!   (with the workspace root's `memory.x`; `__x10_stm32g431` selects the STM32G431 values in
//!   it), `link-rp.x` for the Pico, `defmt.x`.

include!("../x10-boards/link_args.rs");

/// Program run when `X10_ROBOT` is not set: the one that needs no daughterboard.
#[cfg(feature = "_chip")]
const DEFAULT_ROBOT: &str = "fig4_2";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    #[cfg(feature = "_chip")]
    robot();
    link_args();
}

/// Writes `$OUT_DIR/robot.rs` for the program named by `X10_ROBOT`.
#[cfg(feature = "_chip")]
fn robot() {
    use std::env;
    use std::path::PathBuf;
    use std::process::exit;

    println!("cargo:rerun-if-env-changed=X10_ROBOT");
    let name = env::var("X10_ROBOT").unwrap_or_else(|_| DEFAULT_ROBOT.to_owned());
    let Some(program) = x10_robots::Program::from_name(&name) else {
        eprintln!(
            "X10_ROBOT={name:?} is not a robot program; the programs are: {}",
            x10_robots::names().join(", ")
        );
        exit(1);
    };
    let code = format!(
        "/// The robot program of this image (`X10_ROBOT={name}`): {desc}\n\
         const PROGRAM: x10_robots::Program = x10_robots::Program::{program:?};\n",
        desc = program.description(),
    );
    let Some(out) = env::var_os("OUT_DIR").map(PathBuf::from) else {
        eprintln!("OUT_DIR is not set: not run by cargo?");
        exit(1);
    };
    if let Err(e) = std::fs::write(out.join("robot.rs"), code) {
        eprintln!("cannot write {}: {e}", out.join("robot.rs").display());
        exit(1);
    }
}
