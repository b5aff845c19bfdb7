//! The motherboard image for an STM32G431 (WeAct board or Nucleo): `cargo mb-g431` builds it,
//! flashes it with probe-rs and prints its defmt log. Its 128 KiB of flash hold no
//! daughterboard image next to its own: it updates no board (the Pico's does).
#![no_std]
#![no_main]

// `main`: starts the X10 motherboard runtime and one embassy task per task of the robot
// (`src/lib.rs`), each logging the error that ends it. The panic and HardFault handlers and the
// watchdog come with x10-boards (`x10_boards::watchdog`), and so does the defmt logger
// (`x10_boards::usb_log`: RTT, and the USB link for `x10 monitor`).
x10_boards::mb_image!(x10_boards::g431, robot::Robot);
