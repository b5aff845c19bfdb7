//! Memory map and link arguments of the QEMU suites, by target:
//! thumbv6m → BBC micro:bit (nRF51, Cortex-M0: 256 KiB flash, 16 KiB RAM),
//! thumbv7em → MPS2 AN386 (Cortex-M4: 4 MiB flash/RAM at 0x0/0x20000000).
//! The memory.x goes to OUT_DIR (this directory has none, so the linker finds that one).

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo::rustc-check-cfg=cfg(qemu_microbit)");
    let target = env::var("TARGET").unwrap_or_default();
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let memory = if target.starts_with("thumbv6m") {
        println!("cargo:rustc-cfg=qemu_microbit");
        "MEMORY {\n  FLASH : ORIGIN = 0x00000000, LENGTH = 256K\n  RAM : ORIGIN = 0x20000000, LENGTH = 16K\n}\n"
    } else {
        "MEMORY {\n  FLASH : ORIGIN = 0x00000000, LENGTH = 4M\n  RAM : ORIGIN = 0x20000000, LENGTH = 4M\n}\n"
    };
    let out = PathBuf::from(env::var("OUT_DIR").unwrap_or_default());
    if let Err(e) = fs::write(out.join("memory.x"), memory) {
        eprintln!("cannot write memory.x: {e}");
        std::process::exit(1);
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg=-Tlink.x");
    println!("cargo:rustc-link-arg=-Tdefmt.x");
}
