//! Link arguments of the motherboard images, only when building for a board (target OS
//! `none`): cortex-m-rt's `link.x` (which includes `memory.x` from this folder), embassy-rp's
//! `link-rp.x` for the Pico, defmt's `defmt.x`.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    if let Some(dir) = std::env::var_os("CARGO_MANIFEST_DIR") {
        println!("cargo:rustc-link-search={}", std::path::Path::new(&dir).display());
    }
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if std::env::var_os("CARGO_FEATURE_PICO").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tlink-rp.x");
    }
    if std::env::var_os("CARGO_FEATURE_G431").is_some() {
        println!("cargo:rustc-link-arg-bins=--defsym=__x10_stm32g431=1");
    }
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
