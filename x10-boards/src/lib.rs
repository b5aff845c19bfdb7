//! # x10-boards: the chip code of the X10 boards
//!
//! Everything that the motherboard (MB) and daughterboard (DB) images of one board share, and
//! nothing the portable runtimes decide:
//!
//! * the pin map, one table per board ([`pins::PICO`], [`pins::G431`]), also shown in
//!   `docs/boards.md` (a host test keeps the two equal);
//! * the bus: [`x10_hal::bus::MultiMaster`] for the RP2040 (`pico::PicoBus`, switching the I2C
//!   block between controller and target only while its own target side is idle: it cannot
//!   see another master's transfer to another node, see `docs/boards.md`) and for the STM32G431
//!   and STM32C011 (`stm32::Stm32Bus`, as `g431::G431Bus` and `c011::C011Bus`: one I2C v2
//!   block, embassy-stm32's `MultiMaster` driver waiting for the address match, the adapter's
//!   own register-level controller and target transfers);
//! * the ports: [`x10_hal::ports::Ports`] for each board (`pico::PicoPorts`,
//!   `g431::G431Ports`, `c011::C011Ports`), used by a DB image and by the internal
//!   daughterboard of an MB image;
//! * the clock: [`EmbassyClock`], [`x10_hal::time::Clock`] on embassy-time;
//! * the DB address: a build-time base plus jumpers read at boot ([`address`]).
//!
//! Retries, backoff, timeouts and the choice of when to be controller or target belong to the
//! runtimes and `x10-hal`; the adapters here only translate calls and errors, and refuse to
//! take the controller role while the bus is in use as far as the chip can tell (which the
//! runtimes see as arbitration lost, and retry).
//!
//! With the `motherboard` feature, each chip module also has `start_motherboard`
//! ([`start`]): the library call an image's `main` makes to start the X10 motherboard runtime
//! and get the robot programs' [`firmware_mb::X10`] handle. The images themselves (`main`,
//! robot tasks, defmt-rtt) are the bins of x10-robots (motherboard, the example programs),
//! x10-boards (daughterboard, `db_image.rs`) and of a user's own robot crate.
//!
//! Every image runs the chip's hardware watchdog and has panic and HardFault handlers that put
//! the actuator outputs in their safe state before the chip resets ([`watchdog`], with the
//! motherboard images' panic handler; the decisions in [`crash`], tested on the host).
//!
//! Features: `rp2040`, `stm32g431`, `stm32c011` (one per build: each brings its HAL and
//! critical section), `time` (only [`EmbassyClock`]), `small-mem` (the images' small
//! `memcpy`/`memset` and 64-bit division, [`mem`]; on with `motherboard` and `daughterboard`). Without any, only
//! the portable parts compile: the pin tables, PWM arithmetic ([`pwm`]), pulse-in edge logic
//! ([`pulse`]), where a request's port or pin leads ([`port_lookup`]), the STM32 and RP2040
//! bus decisions ([`i2c_v2`], [`pico_rules`]) and addresses, all tested on the host.
#![no_std]

#[macro_use]
pub mod pins;
pub mod address;
pub mod boot_state;
pub mod c011_rom;
pub mod crash;
pub mod flash_window;
pub mod g431_boot;
pub mod i2c_v2;
// Raw-pointer loops behind the images' memcpy/memset (see the module): the one place of
// this crate that needs `unsafe`.
#[allow(unsafe_code)]
pub mod mem;
pub mod pico_rules;
pub mod port_lookup;
pub mod pulse;
pub mod pwm;
pub mod record;
pub mod rp_flash;
pub mod rtt;
pub mod stm32_latch;

#[cfg(feature = "time")]
mod clock;
#[cfg(feature = "time")]
pub use clock::EmbassyClock;

#[cfg(any(
    all(feature = "rp2040", feature = "stm32g431"),
    all(feature = "rp2040", feature = "stm32c011"),
    all(feature = "stm32g431", feature = "stm32c011"),
))]
compile_error!(
    "features `rp2040`, `stm32g431` and `stm32c011` are exclusive: build one image per cargo call"
);

#[cfg(feature = "motherboard")]
#[macro_use]
pub mod start;
// `mb_image!`: a motherboard image's `main` (exported at the crate's root).
#[cfg(feature = "motherboard")]
mod mb_image;
#[cfg(feature = "usb-link")]
pub mod usb_link;
// The defmt global logger (RTT and the USB link): a `#[no_mangle]` control block the host
// reads behind the target's back, and the critical section defmt's logger API hands over.
#[cfg(feature = "usb-log")]
#[allow(unsafe_code)]
pub mod usb_log;

#[cfg(feature = "daughterboard")]
pub mod kept;

#[cfg(feature = "rp2040")]
pub mod pico;

#[cfg(any(feature = "stm32g431", feature = "stm32c011"))]
#[macro_use]
pub mod stm32;

#[cfg(feature = "stm32g431")]
pub mod g431;

#[cfg(feature = "stm32c011")]
pub mod c011;

#[cfg(any(feature = "rp2040", feature = "stm32g431", feature = "stm32c011"))]
pub mod watchdog;

/// How a board's bus adapter is set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BusConfig {
    /// This node's own 7-bit address (where it listens as a target).
    pub own_address: u8,
    /// SCL frequency in Hz (100 kHz, 400 kHz or 1 MHz).
    pub frequency_hz: u32,
    /// Longest one controller transaction or one answer to a read may take, clock stretching
    /// included, before it fails with `BusError::Timeout`.
    pub timeout_us: u32,
}

impl BusConfig {
    /// Standard-mode I2C (100 kHz, as the thesis's Arduino boards run) and a 20 ms timeout: the
    /// longest transfer (a 36-byte frame out and a 32-byte reply back) takes about 6.3 ms at
    /// 100 kHz.
    pub const fn standard(own_address: u8) -> BusConfig {
        BusConfig {
            own_address,
            frequency_hz: 100_000,
            timeout_us: 20_000,
        }
    }

    /// [`BusConfig::standard`] at the bus frequency this image was built for ([`BUS_HZ`]):
    /// what the images use.
    pub const fn for_build(own_address: u8) -> BusConfig {
        BusConfig {
            frequency_hz: BUS_HZ,
            ..BusConfig::standard(own_address)
        }
    }
}

/// The SCL frequencies an image may be built for: standard mode, fast mode, fast-mode plus.
pub const BUS_FREQUENCIES: [u32; 3] = [100_000, 400_000, 1_000_000];

/// Why `X10_BUS_HZ` was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusHzError {
    /// Not a decimal number.
    NotANumber,
    /// A number, but not one of [`BUS_FREQUENCIES`].
    Unsupported,
}

/// The bus frequency for a build: `X10_BUS_HZ` as given by `env` (the caller passes
/// `option_env!("X10_BUS_HZ")`), in Hz, decimal; 100 000 when it is not set. Every board on
/// one bus must be built with the same value.
///
/// # Errors
/// [`BusHzError`] for anything but `100000`, `400000` or `1000000`.
pub const fn bus_hz(env: Option<&str>) -> Result<u32, BusHzError> {
    let Some(s) = env else {
        return Ok(BUS_FREQUENCIES[0]);
    };
    let b = s.as_bytes();
    if b.is_empty() || b.len() > 9 {
        return Err(BusHzError::NotANumber);
    }
    let mut n: u32 = 0;
    let mut i = 0;
    while i < b.len() {
        if !b[i].is_ascii_digit() {
            return Err(BusHzError::NotANumber);
        }
        n = n * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    let mut k = 0;
    while k < BUS_FREQUENCIES.len() {
        if BUS_FREQUENCIES[k] == n {
            return Ok(n);
        }
        k += 1;
    }
    Err(BusHzError::Unsupported)
}

/// The bus frequency of this build: the environment variable `X10_BUS_HZ` when the image is
/// built (`X10_BUS_HZ=400000 cargo db-pico`), else 100 kHz. Anything but 100000, 400000 or
/// 1000000 fails the build.
pub const BUS_HZ: u32 = match bus_hz(option_env!("X10_BUS_HZ")) {
    Ok(hz) => hz,
    Err(_) => panic!("X10_BUS_HZ must be 100000, 400000 or 1000000 (Hz)"),
};

/// Receive buffer size of the adapters: the longest frame plus one byte, so that a longer
/// write is seen (and answered `BusError::Overrun`) instead of being cut silently.
pub const RX_LEN: usize = x10_microcode::MAX_FRAME_LEN + 1;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bus_frequency_is_one_of_three_or_the_build_fails() {
        assert_eq!(bus_hz(None), Ok(100_000));
        assert_eq!(bus_hz(Some("100000")), Ok(100_000));
        assert_eq!(bus_hz(Some("400000")), Ok(400_000));
        assert_eq!(bus_hz(Some("1000000")), Ok(1_000_000));
        assert_eq!(bus_hz(Some("200000")), Err(BusHzError::Unsupported));
        assert_eq!(bus_hz(Some("0")), Err(BusHzError::Unsupported));
        assert_eq!(bus_hz(Some("400k")), Err(BusHzError::NotANumber));
        assert_eq!(bus_hz(Some("")), Err(BusHzError::NotANumber));
        assert_eq!(bus_hz(Some("99999999999")), Err(BusHzError::NotANumber));
        let c = BusConfig::for_build(9);
        assert_eq!(c.frequency_hz, BUS_HZ);
        assert_eq!(c.own_address, 9);
        assert_eq!(c.timeout_us, BusConfig::standard(9).timeout_us);
    }
}
