//! Build script of the motherboard images (bins `mb-pico`, `mb-g431`): their link arguments,
//! only when building for a board (host builds get nothing), and the daughterboard images they
//! carry (`X10_CARRY`, set by `cargo xtask`: `x10-boards/carry.rs`). The same link arguments
//! serve the daughterboard images: `x10-boards/link_args.rs`.

include!("../x10-boards/link_args.rs");
include!("../x10-boards/carry.rs");

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    link_args();
    carried_images();
}
