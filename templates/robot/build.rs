//! Link arguments of the motherboard images, only when building for a board: the same file as
//! the X10 repository's own images use (memory maps of the Pico and the STM32G431,
//! cortex-m-rt's `link.x`, embassy-rp's `link-rp.x`, defmt's `defmt.x`), taken from the X10
//! checkout this crate depends on.

include!("{{x10}}/x10-boards/link_args.rs");

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    link_args();
}
