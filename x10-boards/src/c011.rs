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
