// Link arguments of the firmware images: one file for the build scripts of x10-boards (the
// daughterboard images) and x10-robots (the motherboard images), which take it in with
// `include!`.
// It is no module of x10-boards (a build script runs on the host, before any chip code).
// rustc lists an included file among the build script's sources, so changing this file
// rebuilds and reruns both scripts.

/// Prints the link arguments of the package's bins, only when building for a board (target OS
/// `none`; host builds get nothing):
///
/// * `link.x` (cortex-m-rt), which includes the workspace root's `memory.x` (the linker runs
///   there and looks in its working directory first); for the STM32G431 the symbol
///   `__x10_stm32g431` selects that chip's values in it;
/// * `link-rp.x` (embassy-rp: the boot2 section) for the Pico;
/// * `defmt.x` (defmt).
fn link_args() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    if let Some(dir) = std::env::var_os("CARGO_MANIFEST_DIR") {
        let memory_x = std::path::Path::new(&dir).join("../memory.x");
        println!("cargo:rerun-if-changed={}", memory_x.display());
    }
    println!("cargo:rustc-link-arg-bins=--nmagic");
    // link.x includes memory.x, which defines the regions link-rp.x places sections in.
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if std::env::var_os("CARGO_FEATURE_RP2040").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tlink-rp.x");
    }
    if std::env::var_os("CARGO_FEATURE_STM32G431").is_some() {
        println!("cargo:rustc-link-arg-bins=--defsym=__x10_stm32g431=1");
    }
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
