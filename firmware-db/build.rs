//! Build script of the daughterboard images: their link arguments, only when building for a
//! board (host builds get nothing). They are the motherboard images' too, so they live in one
//! file, `x10-boards/link_args.rs`, which firmware-mb's build script includes as well.

include!("../x10-boards/link_args.rs");

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    link_args();
}
