//! Build script of the daughterboard images (bins `db-pico`, `db-g431`, `db-c011`): their link
//! arguments, only when building for a board (host builds get nothing). They are the
//! motherboard images' too, so they live in one file, `link_args.rs`, which x10-robots' build
//! script includes as well.

include!("link_args.rs");

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    link_args();
}
