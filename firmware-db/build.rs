//! Link arguments of the daughterboard images, only when building for a board (host builds
//! get nothing):
//!
//! * `link.x` (cortex-m-rt), which includes the workspace root's `memory.x` (the linker runs
//!   there and looks in its working directory first); for the STM32G431 the symbol
//!   `__x10_stm32g431` selects that chip's values in it;
//! * `link-rp.x` (embassy-rp: the boot2 section) for the Pico;
//! * `defmt.x` (defmt).
//!
//! firmware-mb's build script does the same for the motherboard images.

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    if let Some(dir) = env::var_os("CARGO_MANIFEST_DIR") {
        let memory_x = std::path::Path::new(&dir).join("../memory.x");
        println!("cargo:rerun-if-changed={}", memory_x.display());
    }
    println!("cargo:rustc-link-arg-bins=--nmagic");
    // link.x includes memory.x, which defines the regions link-rp.x places sections in.
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_RP2040").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tlink-rp.x");
    }
    if env::var_os("CARGO_FEATURE_STM32G431").is_some() {
        println!("cargo:rustc-link-arg-bins=--defsym=__x10_stm32g431=1");
    }
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
