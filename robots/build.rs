//! Build script of the motherboard images (bins `mb-pico`, `mb-g431`): their link arguments,
//! only when building for a board (host builds get nothing). The same file serves the
//! daughterboard images: `x10-boards/link_args.rs`.

include!("../x10-boards/link_args.rs");

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    link_args();
}
