// Link arguments of the firmware images: one file for the build scripts of x10-boards (the
// daughterboard images) and x10-robots (the motherboard images), which take it in with
// `include!`.
// It is no module of x10-boards (a build script runs on the host, before any chip code).
// rustc lists an included file among the build script's sources, so changing this file
// rebuilds and reruns both scripts.

/// The memory map of the Raspberry Pi Pico (RP2040): the first 256 bytes of the 2 MiB flash
/// hold the second-stage bootloader (boot2 for the Pico's W25Q080-compatible flash, placed by
/// embassy-rp's link-rp.x), the image follows; the last 8 KiB (two 4 KiB sectors from
/// 0x101FE000) are the address record's (`x10_boards::record`), outside the image; 256 KiB
/// of striped SRAM (SRAM0-3).
const PICO_MEMORY: &str = "MEMORY {
    BOOT2 : ORIGIN = 0x10000000, LENGTH = 0x100
    FLASH : ORIGIN = 0x10000100, LENGTH = 2048K - 0x100 - 8K
    RAM   : ORIGIN = 0x20000000, LENGTH = 256K
}
";

/// The Pico's bootloader, `boot-pico` (feature `pico-bootloader`, issue 25): boot2, then the bootloader up to embassy-boot's
/// STATE sector at 0x10008000 (`x10_boards::rp_flash::layout`).
const PICO_BOOT_MEMORY: &str = "MEMORY {
    BOOT2 : ORIGIN = 0x10000000, LENGTH = 0x100
    FLASH : ORIGIN = 0x10000100, LENGTH = 0x8000 - 0x100
    RAM   : ORIGIN = 0x20000000, LENGTH = 256K
}
";

/// db-pico under the bootloader (feature `active-slot`): the ACTIVE slot, 32 KiB from
/// 0x10009000; no boot2 (the bootloader's is the chip's).
const PICO_ACTIVE_MEMORY: &str = "MEMORY {
    FLASH : ORIGIN = 0x10009000, LENGTH = 32K
    RAM   : ORIGIN = 0x20000000, LENGTH = 256K
}
";

/// The memory map of the STM32G431CB: 128 KiB flash, of which the last 4 KiB (two 2 KiB
/// pages from 0x0801F000) are the address record's (`x10_boards::record`), outside the
/// image; SRAM1 (16 KiB), SRAM2 (6 KiB) and CCM SRAM (10 KiB, aliased there) are contiguous
/// from 0x20000000.
const G431_MEMORY: &str = "MEMORY {
    FLASH : ORIGIN = 0x08000000, LENGTH = 128K - 4K
    RAM   : ORIGIN = 0x20000000, LENGTH = 32K
}
";

/// The G431 daughterboard's flash with its bootloader (issue 25; `x10_boards::g431_boot`
/// holds the same numbers, with the layout's rules, and a test compares them): the bootloader
/// `boot-g431` in the first 24 KiB, embassy-boot's STATE page, then ACTIVE, the 40 KiB
/// `db-g431` is linked into (DFU and the address record follow).
const G431_BOOT_LEN: u32 = 24 * 1024;
/// Where ACTIVE starts (after the bootloader and the STATE page), from 0x08000000.
const G431_ACTIVE_START: u32 = G431_BOOT_LEN + 2 * 1024;
/// ACTIVE's size: more than a daughterboard image's 32 KiB budget, which `cargo xtask size`
/// holds it to.
const G431_ACTIVE_LEN: u32 = 40 * 1024;

/// Which G431 image a memory map is for.
#[derive(Clone, Copy)]
enum G431Image {
    /// `mb-g431`: the whole flash but the address record.
    Motherboard,
    /// `boot-g431`: the bootloader's part.
    Bootloader,
    /// `db-g431`: ACTIVE, started by `boot-g431`.
    Daughterboard,
}

/// The G431's memory map for one image (the RAM is the same for all: SRAM1, SRAM2 and CCM
/// SRAM, contiguous from 0x20000000).
fn g431_memory(image: G431Image) -> String {
    let (origin, len) = match image {
        G431Image::Motherboard => return G431_MEMORY.to_string(),
        G431Image::Bootloader => (0, G431_BOOT_LEN),
        G431Image::Daughterboard => (G431_ACTIVE_START, G431_ACTIVE_LEN),
    };
    format!(
        "MEMORY {{\n    FLASH : ORIGIN = 0x{:08X}, LENGTH = {}K\n    RAM   : ORIGIN = 0x20000000, LENGTH = 32K\n}}\n",
        0x0800_0000 + origin,
        len / 1024
    )
}

/// Prints the link arguments of the package's bins, only when building for a board (target OS
/// `none`; host builds get nothing):
///
/// * `link.x` (cortex-m-rt), which includes `memory.x`. Each image finds exactly one: the Pico
///   and the G431 the one this function writes to the build script's `OUT_DIR` (and puts on
///   the search path), the C011 the one embassy-stm32's `memory-x` feature writes from the
///   chip's metadata. No `memory.x` may lie in the workspace root: the linker runs there and
///   would take it before any on the search path;
/// * `link-rp.x` (embassy-rp: the boot2 section) for the Pico, but for the ACTIVE slot's image;
/// * `defmt.x` (defmt).
fn link_args() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let feature = |f: &str| std::env::var_os(format!("CARGO_FEATURE_{f}")).is_some();
    let memory = if feature("PICO_BOOTLOADER") {
        Some(PICO_BOOT_MEMORY.to_string())
    } else if feature("ACTIVE_SLOT") {
        Some(PICO_ACTIVE_MEMORY.to_string())
    } else if feature("RP2040") {
        Some(PICO_MEMORY.to_string())
    } else if feature("STM32G431") {
        // x10-boards' `bootloader` and `daughterboard` features; x10-robots has neither.
        Some(g431_memory(if feature("BOOTLOADER") {
            G431Image::Bootloader
        } else if feature("DAUGHTERBOARD") {
            G431Image::Daughterboard
        } else {
            G431Image::Motherboard
        }))
    } else {
        None
    };
    if let (Some(memory), Some(out)) = (memory, std::env::var_os("OUT_DIR")) {
        let out = std::path::PathBuf::from(out);
        if let Err(e) = std::fs::write(out.join("memory.x"), memory) {
            println!("cargo:warning=cannot write memory.x: {e}");
        }
        println!("cargo:rustc-link-search={}", out.display());
    }
    println!("cargo:rustc-link-arg-bins=--nmagic");
    // link.x includes memory.x, which defines the regions link-rp.x places sections in.
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // The ACTIVE slot's image has no boot2 (embassy-rp's `boot2-none`).
    if std::env::var_os("CARGO_FEATURE_RP2040").is_some() && !feature("ACTIVE_SLOT") {
        println!("cargo:rustc-link-arg-bins=-Tlink-rp.x");
    }
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
