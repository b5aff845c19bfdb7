//! Link arguments of the motherboard images, only when building for a board: the same file as
//! the X10 repository's own images use (memory maps of the Pico and the STM32G431,
//! cortex-m-rt's `link.x`, embassy-rp's `link-rp.x`, defmt's `defmt.x`), taken from the X10
//! checkout this crate depends on. And the daughterboard images the Pico's image carries: the
//! checkout builds them (`cargo xtask carry`, db-pico by default, `X10_CARRY_KINDS=pico,g431,c011`
//! for more, `X10_CARRY_KINDS=` for none) and `carry.rs` embeds them (docs/boards.md, "The
//! motherboard carries the images").

include!("{{x10}}/x10-boards/link_args.rs");
include!("{{x10}}/x10-boards/carry.rs");
include!("{{x10}}/x10-boards/carry_checkout.rs");

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    link_args();
    carry_from_checkout("{{x10}}");
}
