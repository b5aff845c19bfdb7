//! STM32C011F6 (TSSOP-20, Cortex-M0+, 32 KiB flash, 6 KiB RAM): what differs from the other
//! STM32 boards, the rest is [`crate::stm32`]. The pin map is
//! [`pins::C011`](crate::pins::C011)'s table: one actuator port and three sensor ports, SWD
//! (PA13, PA14) and NRST left free, no pin left for jumpers (the address is set at build time).
//!
//! Clocks: 48 MHz from the internal HSI48 (HSISYS, divider 1); no crystal.

/// The HAL, for the images' `main`.
pub use embassy_stm32 as hal;
use embassy_stm32::adc::{self, Resolution};
use embassy_stm32::{bind_interrupts, dma, i2c, peripherals, rcc, Peri};

use crate::pins::C011;
pub use crate::stm32::PwmTimer;

bind_interrupts!(
    /// The interrupts the C011 image uses: the bus's I2C block (one vector for events and
    /// errors) and its two DMA channels (channels 2 and 3 share a vector).
    pub struct Irqs {
        I2C1 => i2c::EventInterruptHandler<peripherals::I2C1>, i2c::ErrorInterruptHandler<peripherals::I2C1>;
        DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
        DMA1_CHANNEL2_3 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    }
);

/// The C0's EXTI interrupt vectors, in the order of
/// [`C0_VECTOR_LINES`](crate::stm32_latch::C0_VECTOR_LINES): masked in the NVIC before a line
/// they serve latches edges (the image binds no EXTI handler).
pub(crate) const EXTI_VECTORS: [embassy_stm32::interrupt::Interrupt; 3] = {
    use embassy_stm32::interrupt::Interrupt::*;
    [EXTI0_1, EXTI2_3, EXTI4_15]
};
/// The first EXTI line of each of [`EXTI_VECTORS`].
pub(crate) const EXTI_VECTOR_LINES: [u8; 3] = crate::stm32_latch::C0_VECTOR_LINES;

/// Number of sensor ports ([`C011`]).
pub const SENSORS: usize = C011.sensors.len();
/// Number of actuator ports ([`C011`]).
pub const ACTUATORS: usize = C011.actuators.len();
/// Number of address-select jumpers ([`C011`]): none.
pub const JUMPERS: usize = C011.jumpers.len();

/// ADC resolution of the STM32C011.
pub const ADC_BITS: u8 = 12;

/// The bus adapter of the C011 image.
pub type C011Bus = crate::stm32::Stm32Bus;
/// The ports of the C011 image.
pub type C011Ports = crate::stm32::Stm32Ports<PwmUnit, SENSORS, ACTUATORS>;

/// The HAL configuration of the C011 image: 48 MHz system clock straight from HSI48.
pub fn hal_config() -> embassy_stm32::Config {
    let mut c = embassy_stm32::Config::default();
    c.rcc.hsi = Some(rcc::Hsi {
        sys_div: rcc::HsiSysDiv::DIV1,
        ker_div: rcc::HsiKerDiv::DIV3,
    });
    c.rcc.sys = rcc::Sysclk::HSISYS;
    c
}

/// Starts the HAL with [`hal_config`]; first, when System 12 asked for it before the reset
/// ([`request_rom_bootloader`]), ST's ROM bootloader instead ([`enter_rom_bootloader`]).
pub fn init() -> embassy_stm32::Peripherals {
    if crate::c011_rom::requested(take_rom_request()) {
        // A ROM that does not look like one is not jumped into: the image starts.
        enter_rom_bootloader();
    }
    embassy_stm32::init(hal_config())
}

/// The RAM word System 12 leaves for the next start: in `.uninit`, which cortex-m-rt's
/// start-up neither zeroes nor initialises and a system reset keeps (RM0490 §6.1.2), like
/// the crash record (`watchdog`).
#[allow(unsafe_code)]
#[link_section = ".uninit.x10_rom"]
static mut ROM_REQUEST: core::mem::MaybeUninit<u32> = core::mem::MaybeUninit::uninit();

/// System 12 (`enter_update`) on the C011: asks the next start for ST's ROM bootloader; the
/// daughterboard runtime resets the chip once its reply has been read.
#[allow(unsafe_code)]
pub fn request_rom_bootloader() {
    // SAFETY: a plain aligned word written with a volatile store; read by `take_rom_request`.
    unsafe {
        core::ptr::write_volatile(
            core::ptr::addr_of_mut!(ROM_REQUEST).cast::<u32>(),
            crate::c011_rom::REQUEST,
        )
    }
}

/// Reads the request word and clears it (a failed jump or the next reset starts the image).
#[allow(unsafe_code)]
fn take_rom_request() -> u32 {
    let p = core::ptr::addr_of_mut!(ROM_REQUEST).cast::<u32>();
    // SAFETY: as above; any bit pattern is a valid u32 (after a power cut it is noise).
    unsafe {
        let w = core::ptr::read_volatile(p);
        core::ptr::write_volatile(p, 0);
        w
    }
}

fn new_adc(p: Peri<'static, peripherals::ADC1>) -> adc::Adc<'static, peripherals::ADC1> {
    adc::Adc::new(p, Resolution::BITS12)
}

macro_rules! c011_build {
    ($($table:tt)*) => { stm32_build! { dma: (DMA1_CH1, DMA1_CH2), $($table)* } };
}

c011_table!(c011_build);

/// The C011's 1 KiB one-time-programmable area (0x1FFF7000, 128 double words that are never
/// erased) as NOR flash, for its address record ([`address_record`]). Offsets are from the
/// area's start. `erase` always fails (nothing erases OTP; an append-only record never asks).
///
/// A double word is programmed as embassy-stm32 0.6.0 programs one of the main flash
/// (`src/flash/common.rs` 120-135 `write_chunk_unlocked`; `src/flash/c.rs` 13-51 `unlock`,
/// `enable_blocking_write`, `blocking_write`, 103-127 `wait_ready_blocking`,
/// `clear_all_err`): wait for `BSY` to clear, clear the error flags, unlock with the two
/// keys, set `PG`, write the two words, wait for `BSY`, read the error flags, clear `PG`, lock.
/// Verified by reading only (no C011 here), and that the same sequence programs the OTP area
/// is taken from ST's STM32G0 and STM32WB manuals (one-time-programmable 1 KiB at 0x1FFF7000,
/// double-word programming, a double word with any bit at 0 cannot be programmed again),
/// not from RM0490 itself: re-check on a board.
pub struct C011Otp {
    _flash: Peri<'static, peripherals::FLASH>,
}

impl C011Otp {
    /// Takes the flash controller.
    pub fn new(flash: Peri<'static, peripherals::FLASH>) -> Self {
        C011Otp { _flash: flash }
    }
}

impl embedded_storage::nor_flash::ErrorType for C011Otp {
    type Error = embedded_storage::nor_flash::NorFlashErrorKind;
}

impl embedded_storage::nor_flash::ReadNorFlash for C011Otp {
    const READ_SIZE: usize = 1;

    #[allow(unsafe_code)]
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let base = crate::record::c011_otp_address(offset, bytes.len(), 1)?;
        for (a, b) in (base..).zip(bytes.iter_mut()) {
            // SAFETY: `a` lies in the OTP area (checked above), readable memory.
            *b = unsafe { core::ptr::read_volatile(a as *const u8) };
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        crate::record::C011_OTP_LEN as usize
    }
}

impl embedded_storage::nor_flash::NorFlash for C011Otp {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = crate::record::C011_OTP_LEN as usize;

    fn erase(&mut self, _from: u32, _to: u32) -> Result<(), Self::Error> {
        Err(embedded_storage::nor_flash::NorFlashErrorKind::Other)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let base = crate::record::c011_otp_address(offset, bytes.len(), 8)?;
        for (a, w) in (base..).step_by(8).zip(bytes.chunks_exact(8)) {
            let lo = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
            let hi = u32::from_le_bytes([w[4], w[5], w[6], w[7]]);
            program_double_word(a, lo, hi)?;
        }
        Ok(())
    }
}

/// Programs one double word at `address` (see [`C011Otp`]).
#[allow(unsafe_code)]
fn program_double_word(
    address: u32,
    lo: u32,
    hi: u32,
) -> Result<(), embedded_storage::nor_flash::NorFlashErrorKind> {
    use core::sync::atomic::{fence, Ordering};
    let f = embassy_stm32::pac::FLASH;
    while f.sr().read().bsy() {}
    // The error flags are write-1-to-clear: writing back what was read clears them.
    f.sr().modify(|_| {});
    if f.cr().read().lock() {
        f.keyr().write_value(0x4567_0123);
        f.keyr().write_value(0xCDEF_89AB);
    }
    f.cr().write(|w| w.set_pg(true));
    fence(Ordering::SeqCst);
    // SAFETY: `address` is a double word of the OTP area (checked by the caller), which
    // takes two word writes while PG is set.
    unsafe {
        core::ptr::write_volatile(address as *mut u32, lo);
        fence(Ordering::SeqCst);
        core::ptr::write_volatile((address + 4) as *mut u32, hi);
    }
    fence(Ordering::SeqCst);
    while f.sr().read().bsy() {}
    let sr = f.sr().read();
    f.cr().write(|w| w.set_pg(false));
    f.cr().modify(|w| w.set_lock(true));
    crate::record::c011_program_outcome(sr.progerr(), sr.wrperr(), sr.pgaerr())
}

/// The C011's address record: append-only in its one-time-programmable area (128 changes in
/// the chip's life, then `StoreError::Full` with the last value kept). The unique ID is
/// [`crate::stm32::unique_id`].
///
/// # Errors
/// `x10_store`'s: the area's read errors.
pub fn address_record(
    flash: Peri<'static, peripherals::FLASH>,
) -> Result<x10_store::Record<C011Otp>, x10_store::StoreError> {
    x10_store::Record::append_only(C011Otp::new(flash), 0, crate::record::C011_OTP_LEN)
}

/// The C011's way into ST's ROM bootloader (issue 25), called by [`init`] at the start after
/// System 12 ([`request_rom_bootloader`]), before the HAL starts: the chip is in its reset
/// state (the system reset that followed System 12's reply reset every peripheral, the clock
/// is the reset one, HSI48 / 4, no interrupt is enabled, the watchdog is not started yet), so
/// what is left is the jump through the ROM's vector table (stack pointer, reset vector),
/// the reset vector checked first by [`c011_rom::rom_entry`](crate::c011_rom::rom_entry). The ROM
/// bootloader then answers the motherboard at 0x64 on the same pins (I2C1, PB6/PB7) and takes
/// the new image (`x10-stmboot`). Arduino's Modulino firmware (the same chip) jumps so too,
/// without remapping address 0 to the system memory; no more is done here (32 bytes of flash
/// the image does not have). Not run on a board: verified by reading only.
///
/// Returns only when the system memory does not hold a vector table (nothing has been changed
/// then).
#[allow(unsafe_code)]
pub fn enter_rom_bootloader() {
    use crate::c011_rom::{rom_entry, SYSTEM_MEMORY};
    // SAFETY: the system memory is readable ROM.
    let reset = unsafe { core::ptr::read_volatile((SYSTEM_MEMORY + 4) as *const u32) };
    if rom_entry(reset) {
        // SAFETY: the reset vector was checked; the jump never returns.
        unsafe { cortex_m::asm::bootload(SYSTEM_MEMORY as *const u32) }
    }
}
