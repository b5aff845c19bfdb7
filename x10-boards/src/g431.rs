//! STM32G431 (WeAct core board, NUCLEO-G431RB): what differs from the other STM32 boards, the
//! rest is [`crate::stm32`]. The pin map is [`pins::G431`](crate::pins::G431)'s table.
//!
//! Clocks: 170 MHz from the internal 16 MHz HSI through the PLL (no crystal assumed, so the
//! same image runs on the WeAct board and the NUCLEO-G431RB).

/// The HAL, for the images' `main`.
pub use embassy_stm32 as hal;
use embassy_stm32::adc;
use embassy_stm32::{bind_interrupts, dma, i2c, peripherals, rcc, Peri};

use crate::pins::G431;
pub use crate::stm32::PwmTimer;

bind_interrupts!(
    /// The interrupts the G431 images use: the bus's I2C block and its two DMA channels.
    pub struct Irqs {
        I2C1_EV => i2c::EventInterruptHandler<peripherals::I2C1>;
        I2C1_ER => i2c::ErrorInterruptHandler<peripherals::I2C1>;
        DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
        DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    }
);

/// The G4's EXTI interrupt vectors, in the order of
/// [`G4_VECTOR_LINES`](crate::stm32_latch::G4_VECTOR_LINES): masked in the NVIC before a line
/// they serve latches edges (the images bind no EXTI handler).
pub(crate) const EXTI_VECTORS: [embassy_stm32::interrupt::Interrupt; 7] = {
    use embassy_stm32::interrupt::Interrupt::*;
    [EXTI0, EXTI1, EXTI2, EXTI3, EXTI4, EXTI9_5, EXTI15_10]
};
/// The first EXTI line of each of [`EXTI_VECTORS`].
pub(crate) const EXTI_VECTOR_LINES: [u8; 7] = crate::stm32_latch::G4_VECTOR_LINES;

/// Number of sensor ports ([`G431`]).
pub const SENSORS: usize = G431.sensors.len();
/// Number of actuator ports ([`G431`]).
pub const ACTUATORS: usize = G431.actuators.len();
/// Number of address-select jumpers ([`G431`]): none, every pin is a port pin.
pub const JUMPERS: usize = G431.jumpers.len();

/// ADC resolution of the STM32G431.
pub const ADC_BITS: u8 = 12;

/// The bus adapter of the G431 images.
pub type G431Bus = crate::stm32::Stm32Bus;
/// The ports of the G431 images.
pub type G431Ports = crate::stm32::Stm32Ports<PwmUnit, SENSORS, ACTUATORS>;

/// The HAL configuration of every G431 image: 170 MHz system clock from HSI16 and the PLL
/// (16 MHz / 4 × 85 / 2), ADC clocked from the system clock.
pub fn hal_config() -> embassy_stm32::Config {
    let mut c = embassy_stm32::Config::default();
    c.rcc.pll = Some(rcc::Pll {
        source: rcc::PllSource::HSI,
        prediv: rcc::PllPreDiv::DIV4,
        mul: rcc::PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(rcc::PllRDiv::DIV2),
    });
    c.rcc.sys = rcc::Sysclk::PLL1_R;
    c.rcc.boost = true;
    c.rcc.mux.adc12sel = rcc::mux::Adcsel::SYS;
    // The USB link's 48 MHz: HSI48 trimmed by the CRS from the host's start-of-frame packets
    // (RM0440 7.2.5 and 8.4.6; USB full speed needs ±0.25 %, which HSI48 alone does not
    // meet), as CLK48 (RCC_CCIPR.CLK48SEL = 0, its reset value, selects HSI48).
    #[cfg(feature = "usb-link")]
    {
        c.rcc.hsi48 = Some(rcc::Hsi48Config {
            sync_from_usb: true,
        });
        c.rcc.mux.clk48sel = rcc::mux::Clk48sel::HSI48;
    }
    c
}

/// Starts the HAL with [`hal_config`].
pub fn init() -> embassy_stm32::Peripherals {
    embassy_stm32::init(hal_config())
}

fn new_adc(p: Peri<'static, peripherals::ADC1>) -> adc::Adc<'static, peripherals::ADC1> {
    adc::Adc::new(p, Default::default())
}

macro_rules! g431_build {
    ($($table:tt)*) => { stm32_build! { dma: (DMA1_CH1, DMA1_CH2), $($table)* } };
}

g431_table!(g431_build);

#[cfg(feature = "motherboard")]
use embassy_stm32::Peripherals;

#[cfg(feature = "motherboard")]
motherboard_starter!(ports: G431Ports, bus: G431Bus, kind: x10_microcode::BoardKind::G431, name: "STM32G431");

/// The G431's flash driver, blocking (offsets from 0x0800_0000).
pub type G431Flash = embassy_stm32::flash::Flash<'static, embassy_stm32::flash::Blocking>;

/// The G431's address record: the last two 2 KiB pages of its 128 KiB
/// ([`crate::record::G431_RECORD_OFFSET`], outside the image's `FLASH` region). The unique ID
/// is [`crate::stm32::unique_id`].
///
/// # Errors
/// `x10_store`'s: the flash's read errors.
pub fn address_record(
    flash: Peri<'static, peripherals::FLASH>,
) -> Result<x10_store::Record<G431Flash>, x10_store::StoreError> {
    x10_store::Record::new(
        G431Flash::new_blocking(flash),
        crate::record::G431_RECORD_OFFSET,
        crate::record::RECORD_PAGES,
    )
}

/// The USB block and its pins: PA12 is D+, PA11 D- (the core board's USB connector).
#[cfg(feature = "usb-link")]
pub type UsbParts = (
    Peri<'static, peripherals::USB>,
    Peri<'static, peripherals::PA12>,
    Peri<'static, peripherals::PA11>,
);

#[cfg(feature = "usb-link")]
bind_interrupts!(
    /// The USB device's interrupt (the motherboard image's USB link): the low-priority line,
    /// the one embassy-stm32's driver serves.
    struct UsbIrqs {
        USB_LP => embassy_stm32::usb::InterruptHandler<peripherals::USB>;
    }
);

/// The USB link's task (`crate::usb_link`), spawned by `start_motherboard`.
#[cfg(feature = "usb-link")]
#[embassy_executor::task]
async fn usb_task(usb: UsbParts, x10: firmware_mb::X10) -> ! {
    let (usb, dp, dm) = usb;
    let driver = embassy_stm32::usb::Driver::new(usb, UsbIrqs, dp, dm);
    crate::usb_link::run(driver, x10, "STM32G431").await
}

#[cfg(feature = "usb-link")]
fn spawn_usb(
    spawner: embassy_executor::Spawner,
    usb: UsbParts,
    x10: firmware_mb::X10,
) -> Result<(), crate::start::StartError> {
    spawner.spawn(usb_task(usb, x10).map_err(|_| crate::start::StartError::Spawn)?);
    Ok(())
}
