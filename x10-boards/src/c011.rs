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

/// Starts the HAL with [`hal_config`].
pub fn init() -> embassy_stm32::Peripherals {
    embassy_stm32::init(hal_config())
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

/// System 12 on the C011 (issue 25): leaves the image for ST's ROM bootloader, which then
/// answers the motherboard at 0x64 on the same pins (I2C1, PB6/PB7) and takes the new image
/// (`x10-stmboot`). The steps are [`crate::c011_rom`]'s; every register named here was read
/// in stm32-metapac 21 (`rcc_c0.rs`, `syscfg_c0.rs`) and the steps against RM0490 and ST's
/// STM32C0 HAL, not run on a board: verified by reading only.
///
/// The independent watchdog keeps running (nothing stops it); AN2606's STM32C011xx section
/// says the bootloader refreshes it (and Arduino's Modulino firmware, whose watchdog runs with
/// a 0.5 s timeout, is updated this way). The actuator pins go to their reset state (inputs)
/// with the GPIO reset, as at any reset.
///
/// # Errors
/// [`c011_rom::RomEntryError`](crate::c011_rom::RomEntryError) when the system memory does
/// not hold a vector table (nothing has been changed then).
#[allow(unsafe_code)]
pub fn enter_rom_bootloader() -> Result<core::convert::Infallible, crate::c011_rom::RomEntryError> {
    use crate::c011_rom::{rom_vector, SYSTEM_MEMORY};
    use embassy_stm32::pac;
    // SAFETY: the system memory is readable ROM.
    let words = unsafe {
        [
            core::ptr::read_volatile(SYSTEM_MEMORY as *const u32),
            core::ptr::read_volatile((SYSTEM_MEMORY + 4) as *const u32),
        ]
    };
    rom_vector(words)?;
    cortex_m::interrupt::disable();
    // SAFETY: interrupts are off; what follows only stops and resets, and never returns.
    unsafe {
        let nvic = &*cortex_m::peripheral::NVIC::PTR;
        nvic.icer[0].write(!0);
        nvic.icpr[0].write(!0);
        (*cortex_m::peripheral::SYST::PTR).csr.write(0);
    }
    // The clock back to its reset value (HSISYS = HSI48 / 4, 12 MHz: the flash's wait state
    // stays, more than enough), then every peripheral reset and released.
    let rcc = pac::RCC;
    rcc.cr()
        .modify(|w| w.set_hsidiv(pac::rcc::vals::Hsidiv::DIV4));
    rcc.gpiorstr().write_value(pac::rcc::regs::Gpiorstr(!0));
    rcc.ahbrstr().write_value(pac::rcc::regs::Ahbrstr(!0));
    rcc.apbrstr1().write_value(pac::rcc::regs::Apbrstr1(!0));
    rcc.apbrstr2().write_value(pac::rcc::regs::Apbrstr2(!0));
    rcc.gpiorstr().write_value(pac::rcc::regs::Gpiorstr(0));
    rcc.ahbrstr().write_value(pac::rcc::regs::Ahbrstr(0));
    rcc.apbrstr1().write_value(pac::rcc::regs::Apbrstr1(0));
    rcc.apbrstr2().write_value(pac::rcc::regs::Apbrstr2(0));
    // The system memory at address 0, as when the chip boots into it.
    rcc.apbenr2().modify(|w| w.set_syscfgen(true));
    pac::SYSCFG
        .cfgr1()
        .modify(|w| w.set_mem_mode(pac::syscfg::vals::MemMode::SYSTEM_FLASH));
    // SAFETY: the vector table was checked above; the jump never returns.
    unsafe { cortex_m::asm::bootload(SYSTEM_MEMORY as *const u32) }
}
