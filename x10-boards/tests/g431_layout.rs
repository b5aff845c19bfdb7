//! The build script's G431 memory maps (`link_args.rs`) against `x10_boards::g431_boot`.

/// `link_args.rs`, compiled here as a module, with the test inside it (its items are private).
#[allow(dead_code)]
mod build {
    include!("../link_args.rs");

    use x10_boards::g431_boot::{check, ACTIVE, BOOT, DFU, LAYOUT, RECORD};

    #[test]
    fn the_layout_holds_and_the_memory_maps_carry_it() {
        assert_eq!(check(&LAYOUT), Ok(()));
        assert_eq!(
            (G431_BOOT_LEN, G431_ACTIVE_START, G431_ACTIVE_LEN),
            (BOOT.len, ACTIVE.start, ACTIVE.len)
        );
        assert_eq!(ACTIVE.start, 0x6800);
        assert_eq!(DFU.end(), 0x1B000);
        assert_eq!(RECORD.start, 0x1F000);
        assert_eq!(
            g431_memory(G431Image::Bootloader),
            "MEMORY {\n    FLASH : ORIGIN = 0x08000000, LENGTH = 24K\n    RAM   : ORIGIN = 0x20000000, LENGTH = 32K\n}\n"
        );
        assert_eq!(
            g431_memory(G431Image::Daughterboard),
            "MEMORY {\n    FLASH : ORIGIN = 0x08006800, LENGTH = 40K\n    RAM   : ORIGIN = 0x20000000, LENGTH = 32K\n}\n"
        );
        assert_eq!(g431_memory(G431Image::Motherboard), G431_MEMORY);
    }
}
