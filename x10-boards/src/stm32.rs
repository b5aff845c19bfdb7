//! STM32 chips with the I2C v2 block (embassy-stm32 0.6): the bus adapter, the ports and the
//! start-up shared by every STM32 board ([`crate::g431`], [`crate::c011`]). A chip module
//! gives only what differs: its clocks, its interrupt bindings, its ADC set-up and its pin
//! table, which it expands with `stm32_build!`.
//!
//! * [`Stm32Bus`]: one I2C v2 block is controller and target at once. embassy-stm32's
//!   `MultiMaster` driver sets the block up and waits for an address match (`listen`);
//!   everything else is the adapter's own, on the registers, polling ISR with a yield between
//!   polls (the driver's controller calls spin synchronously on BUSY and TC, issue 11 item 8;
//!   its target calls stall the bus on over-long transfers, issue 21 item 6). Decisions in
//!   [`crate::i2c_v2`], tested on the host: the adapter clears the flags earlier transfers left
//!   set before each call; refuses to start while this node is addressed or another
//!   controller's transfer is under way ([`BusError::ArbitrationLost`], the runtime retries);
//!   treats BUSY with both lines quiet for two byte times as stale (block reset), and after
//!   every block reset waits for quiet lines before its first START (issue 21 items 1 and 3);
//!   ends each transfer on its own STOP (AUTOEND); after a timeout sends STOP, resets the block
//!   (PE off and on) and clocks a stuck SDA free (UM10204 §3.1.16) before giving up with
//!   [`BusError::Bus`]. Target side: `addressed` is the driver's `listen` (ADDR seen, left
//!   set, SCL stretched, cancel-safe), kept for the adapter's `listen`, which receives the
//!   write (NACKing a byte past the longest frame); `respond` pads the reply with 0xFF for as
//!   long as the controller reads.
//! * [`Stm32Ports`]: digital pins are `Flex` pins (input with pull-down, or push-pull output),
//!   PWM pins are channels 1 and 2 of one timer per actuator port, analog inputs are on ADC1
//!   (12 bits), pulse-in samples its pin (see [`crate::pulse`] and `docs/boards.md` for its
//!   resolution).

use core::cell::Cell;

use embassy_stm32::adc::{self, AnyAdcChannel};
use embassy_stm32::gpio::{Flex, Pull, Speed};
use embassy_stm32::i2c::{self, I2c, SlaveCommandKind};
use embassy_stm32::mode::Async;
use embassy_stm32::{pac, peripherals, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex as BlockingMutex;
use embassy_time::{Duration, Instant};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::ports::{EdgeCount, PortError, Ports};
use x10_microcode::{Edge, Level, Pin, PinRef, Port};

use crate::i2c_v2::{self, After, Lines, Outcome, Progress, RxStep, Step, TxStep};
use crate::pulse::PulseIn;
use crate::pwm::{stm32_compare, stm32_frequency_ok, Output, Timebase, DEFAULT_HZ};
use crate::stm32_latch::{self, Pending};
use crate::{port_lookup, RX_LEN};

pub use crate::port_lookup::Lock;
/// A digital pin, taken.
type PinGuard<'a> = port_lookup::Guard<'a, Flex<'static>>;

/// What the chip module does with one actuator port's timer (its `PwmUnit` enum, one variant
/// per timer of the table).
pub trait PwmTimer {
    /// The timer's input clock in Hz.
    fn timer_hz(&self) -> u32;
    /// Sets the PWM frequency (both channels).
    fn set_frequency(&mut self, hz: u32);
    /// The frequency the timer reports and its maximum duty (ARR + 1).
    fn frequency_and_max(&self) -> (u32, u32);
    /// Writes a compare value (already clamped) to channel 1 (`Pin::A`) or 2 (`Pin::B`).
    fn set_compare(&mut self, pin: Pin, c: u32);
}

/// Everything a chip's table names, taken from the HAL.
pub struct Board<U, const S: usize, const A: usize> {
    /// The bus (controller and target at once).
    pub bus: Stm32Bus,
    /// The ports (actuators in their safe state: digital low, PWM off).
    pub ports: Stm32Ports<U, S, A>,
    /// The value of the address-select jumpers read at start-up (fitted = 1, bit 0 first; 0
    /// when the table has none).
    pub jumpers: u8,
    /// The USB device block and its pins (the G431 motherboard image's USB link).
    #[cfg(all(feature = "usb-link", feature = "stm32g431"))]
    pub usb: crate::g431::UsbParts,
}

/// The chip's 8-byte unique ID: its 96-bit UID (the `UID` registers, 0x1FFF7590 on the G431,
/// 0x1FFF7550 on the C011, stm32-metapac 21's `pac.rs` of each chip) folded by
/// [`crate::record::fold_uid96`]. Verified by reading: `embassy_stm32::uid::uid` (0.6.0,
/// `src/uid.rs` line 4) copies those 12 bytes.
#[must_use]
pub fn unique_id() -> [u8; 8] {
    crate::record::fold_uid96(&embassy_stm32::uid::uid())
}

/// Expands a pin table into a chip module's `Board::new` and `PwmUnit`. The chip module
/// provides `Irqs`, `new_adc` and `JUMPERS`, and names its two DMA channels.
macro_rules! stm32_build {
    (
        dma: ($tx:ident, $rx:ident),
        board: $board:literal,
        i2c: $i2c:ident { sda: $sda:ident, scl: $scl:ident },
        sensors: [ $( ($sa:ident, $sb:ident, $san:ident) ),* $(,)? ],
        actuators: [ $( ($tim:ident, $pa:ident, $pb:ident, $da:ident, $db:ident) ),* $(,)? ],
        jumpers: [ $( $j:ident ),* $(,)? ] $(,)?
    ) => {
        /// The chip's board: bus, ports and jumpers.
        pub type Board = $crate::stm32::Board<PwmUnit, SENSORS, ACTUATORS>;

        impl $crate::stm32::Board<PwmUnit, SENSORS, ACTUATORS> {
            /// Takes the table's peripherals: builds the ports in their safe state and the
            /// bus adapter. `p` comes from this module's `init()`.
            ///
            /// `bus` gets the jumper value and returns the bus setup (the node's own address
            /// may depend on the jumpers).
            pub fn new(
                p: embassy_stm32::Peripherals,
                bus: impl FnOnce(
                    u8,
                    embassy_stm32::Peri<'static, embassy_stm32::peripherals::FLASH>,
                ) -> $crate::BusConfig,
            ) -> Board {
                use embassy_stm32::gpio::{Input, OutputType, Pin as _};
                use embassy_stm32::i2c::{self, I2c, SlaveAddrConfig};
                use embassy_stm32::timer::simple_pwm::PwmPin;
                use $crate::stm32::{input, output_low, ActuatorPort, Lock, SensorPort};
                // Inputs only while they are read; dropped, the pins are disconnected again.
                let jumpers = {
                    let inputs: [Input<'static>; JUMPERS] = [ $( Input::new(p.$j, embassy_stm32::gpio::Pull::Up) ),* ];
                    if JUMPERS > 0 {
                        // Let the pull-ups (about 40 kΩ against the pins' capacitance) settle.
                        embassy_time::block_for(embassy_time::Duration::from_micros(10));
                    }
                    $crate::address::jumper_value(inputs.iter().map(|i| i.is_high()))
                };
                let bus = bus(jumpers, p.FLASH);
                let mut cfg = i2c::Config::default();
                cfg.frequency = embassy_stm32::time::Hertz(bus.frequency_hz);
                cfg.timeout = embassy_time::Duration::from_micros(u64::from(bus.timeout_us));
                let lines = [
                    (p.$scl.port(), p.$scl.pin()),
                    (p.$sda.port(), p.$sda.pin()),
                ];
                let i2c = I2c::new(p.$i2c, p.$scl, p.$sda, p.$tx, p.$rx, Irqs, cfg)
                    .into_slave_multimaster(SlaveAddrConfig {
                        // With `together` a daughterboard takes general calls (`sample`,
                        // `apply`): CR1.GCEN (embassy-stm32 `i2c/v2.rs` 1554, RM0440
                        // §37.4.8); they reach its listener as writes (ADDCODE 0).
                        general_call: cfg!(feature = "together"),
                        ..SlaveAddrConfig::basic(bus.own_address)
                    });
                let sensors = [ $( SensorPort {
                    gpio: [(p.$sa.port(), p.$sa.pin()), (p.$sb.port(), p.$sb.pin())],
                    pins: [Lock::new(input(p.$sa.into())), Lock::new(input(p.$sb.into()))],
                    analog: Lock::new(embassy_stm32::adc::AdcChannel::degrade_adc(p.$san)),
                } ),* ];
                let actuators = [ $( ActuatorPort {
                    gpio: [(p.$da.port(), p.$da.pin()), (p.$db.port(), p.$db.pin())],
                    pins: [Lock::new(output_low(p.$da.into())), Lock::new(output_low(p.$db.into()))],
                    pwm: Lock::new((PwmUnit::$tim(
                        embassy_stm32::timer::low_level::Timer::new(p.$tim),
                        PwmPin::new(p.$pa, OutputType::PushPull),
                        PwmPin::new(p.$pb, OutputType::PushPull),
                    ).started(), [$crate::pwm::Output::OFF; 2])),
                } ),* ];
                $crate::stm32::Board {
                    #[cfg(all(feature = "usb-link", feature = "stm32g431"))]
                    usb: (p.USB, p.PA12, p.PA11),
                    bus: $crate::stm32::Stm32Bus::new(i2c, embassy_stm32::pac::$i2c, lines, bus.frequency_hz, bus.timeout_us),
                    ports: $crate::stm32::Stm32Ports::new(new_adc(p.ADC1), ADC_BITS, sensors, actuators),
                    jumpers,
                }
            }
        }

        /// The timer of one actuator port (the table gives each port its own timer) and its
        /// two output pins (channel 1 is pin A, channel 2 pin B), kept so that they stay in
        /// their timer function.
        ///
        /// Set up as embassy-stm32's `SimplePwm::new` does it (`timer/simple_pwm.rs` 243-276:
        /// edge-aligned up-counting, PWM mode 1 with preloaded compare and auto-reload
        /// values, outputs enabled, an update event, started), but on the HAL's low-level
        /// timer: the prescaler and ARR come from [`$crate::pwm::stm32_psc_arr`] (32-bit
        /// arithmetic) instead of `SimplePwm::set_frequency`'s 64-bit division (issue 12).
        #[allow(non_camel_case_types, clippy::upper_case_acronyms)]
        pub enum PwmUnit {
            $(
                #[doc = stringify!($tim)]
                $tim(
                    embassy_stm32::timer::low_level::Timer<'static, embassy_stm32::peripherals::$tim>,
                    embassy_stm32::timer::simple_pwm::PwmPin<'static, embassy_stm32::peripherals::$tim, embassy_stm32::timer::Ch1>,
                    embassy_stm32::timer::simple_pwm::PwmPin<'static, embassy_stm32::peripherals::$tim, embassy_stm32::timer::Ch2>,
                ),
            )*
        }

        impl PwmUnit {
            /// The timer's registers that set its period.
            fn core(&self) -> embassy_stm32::pac::timer::TimCore {
                match self {
                    $( PwmUnit::$tim(t, ..) => t.regs_core(), )*
                }
            }

            /// Running at the default frequency, both channels on at 0 % duty.
            fn started(mut self) -> PwmUnit {
                use $crate::stm32::PwmTimer as _;
                self.set_frequency(u32::from($crate::pwm::DEFAULT_HZ));
                match &mut self {
                    $( PwmUnit::$tim(t, ..) => {
                        // Required for advanced timers (their main output enable).
                        t.enable_outputs();
                        $crate::stm32::start_pwm(t.regs_core());
                    } )*
                }
                self
            }
        }

        impl $crate::stm32::PwmTimer for PwmUnit {
            fn timer_hz(&self) -> u32 {
                match self {
                    $( PwmUnit::$tim(t, ..) => t.get_clock_frequency().0, )*
                }
            }

            fn set_frequency(&mut self, hz: u32) {
                // `None` only for 0 Hz, which the adapter never asks for.
                if let Some((psc, arr)) = $crate::pwm::stm32_psc_arr(self.timer_hz(), hz) {
                    let core = self.core();
                    // Both at most 0xFFFF. Applied at the next update event (ARR preloaded).
                    core.psc().write_value(psc as u16);
                    core.arr().write(|w| w.set_arr(arr as u16));
                }
            }

            fn frequency_and_max(&self) -> (u32, u32) {
                let core = self.core();
                let psc = u32::from(core.psc().read());
                let arr = u32::from(core.arr().read().arr());
                // What the HAL's `get_frequency` reports (`timer/low_level.rs` 577-588: the
                // timer clock / ARR / (PSC + 1)) and its maximum duty, ARR + 1.
                (self.timer_hz() / arr.max(1) / (psc + 1), arr + 1)
            }

            fn set_compare(&mut self, pin: x10_microcode::Pin, c: u32) {
                // `c` is at most 0xFFFF (`stm32_compare`): it fits every timer's word.
                $crate::stm32::set_compare(self.core(), pin, c);
            }
        }
    };
}

/// The rest of what `started` does for one timer: what the HAL's low-level `Timer` calls did
/// (`timer/low_level.rs`: `set_counting_mode(EdgeAlignedUp)` 702-712,
/// `set_output_compare_mode(PwmMode1)` 778-783 and `set_output_compare_preload` 1014-1019 on
/// channels 1 and 2, `set_autoreload_preload` 572-574, `generate_update_event` 428-432,
/// `start` 419-421, then `set_compare_value(0)` 803-812 and `enable_channel` 793-795 on both),
/// written once on the general-purpose register block instead of once per timer type (issue
/// 21: 0.5 KiB less on db-g431, whose four timers each had their own copy). The HAL's calls go
/// through `TimGp16::from_ptr(T::regs())` for every timer of the tables too (`regs_gp16`,
/// 692-694; TIM15 and TIM1 implement `GeneralInstance4Channel`, `timer/mod.rs` 326-381), and
/// TIM2's 32-bit CCRx take the same 0. The timer is fresh from `Timer::new` (enabled and
/// reset, so stopped, as the HAL's `set_counting_mode` asserts).
#[allow(unsafe_code)]
pub fn start_pwm(core: pac::timer::TimCore) {
    use embassy_stm32::timer::low_level::{CountingMode, OutputCompareMode};
    use pac::timer::vals::Urs;
    // SAFETY: the register block of a timer the caller owns, as the HAL's `regs_gp16`.
    let t = unsafe { pac::timer::TimGp16::from_ptr(core.as_ptr()) };
    let (cms, dir) = CountingMode::EdgeAlignedUp.into();
    t.cr1().modify(|w| {
        w.set_dir(dir);
        w.set_cms(cms);
    });
    t.ccmr_output(0).modify(|w| {
        for ch in 0..2 {
            w.set_ocm(ch, OutputCompareMode::PwmMode1.into());
            w.set_ocpe(ch, true);
        }
    });
    t.cr1().modify(|w| w.set_arpe(true));
    // Loads the preloaded registers.
    t.cr1().modify(|w| w.set_urs(Urs::COUNTER_ONLY));
    t.egr().write(|w| w.set_ug(true));
    t.cr1().modify(|w| w.set_urs(Urs::ANY_EVENT));
    t.cr1().modify(|w| w.set_cen(true));
    for ch in 0..2 {
        t.ccr(ch).write_value(pac::timer::regs::Ccr1ch(0));
    }
    t.ccer().modify(|w| {
        w.set_cce(0, true);
        w.set_cce(1, true);
    });
}

/// Writes compare value `c` of channel 1 (`Pin::A`) or 2 (`Pin::B`): the HAL's
/// `set_compare_value` (`timer/low_level.rs` 803-812, a 32-bit write of CCRx through the
/// general-purpose register block), once for every timer type.
#[allow(unsafe_code)]
pub fn set_compare(core: pac::timer::TimCore, pin: Pin, c: u32) {
    // SAFETY: the register block of a timer the caller owns, as the HAL's `regs_gp16`.
    let t = unsafe { pac::timer::TimGp16::from_ptr(core.as_ptr()) };
    t.ccr(pin.index()).write_value(pac::timer::regs::Ccr1ch(c));
}

/// A digital pin as an input with pull-down.
pub fn input(pin: Peri<'static, embassy_stm32::gpio::AnyPin>) -> Flex<'static> {
    let mut f = Flex::new(pin);
    f.set_as_input(Pull::Down);
    f
}

/// A digital pin as a push-pull output, low.
pub fn output_low(pin: Peri<'static, embassy_stm32::gpio::AnyPin>) -> Flex<'static> {
    let mut f = Flex::new(pin);
    f.set_low();
    f.set_as_output(Speed::Low);
    f
}

// ---------------------------------------------------------------------------------------
// Bus
// ---------------------------------------------------------------------------------------

// Fast-mode plus (1 MHz) needs the pins' Fm+ drive (SYSCFG_CFGR1 I2Cx_FMP), which this
// adapter does not set: an STM32 image is built for 100 or 400 kHz only.
const _: () = assert!(
    crate::BUS_HZ <= 400_000,
    "X10_BUS_HZ=1000000 is for the Pico only: the STM32 adapter does not enable Fm+ drive"
);

/// [`MultiMaster`] on an STM32 I2C v2 block (see the module doc).
pub struct Stm32Bus {
    i2c: I2c<'static, Async, i2c::MultiMaster>,
    regs: pac::i2c::I2c,
    /// SCL and SDA as (GPIO port, pin number), for the bus recovery.
    lines: [(u8, u8); 2],
    frequency_hz: u32,
    /// Longest controller transfer, clock stretching included (`BusConfig::timeout_us`).
    timeout_us: u32,
    /// The address match [`MultiMaster::addressed`] saw (ADDR still set, SCL stretched),
    /// for the following `listen`.
    matched: Option<SlaveCommandKind>,
    /// The block was reset (or just set up) and has not started a transfer since: its BUSY
    /// may miss a transfer already on the wire ([`i2c_v2::before_controller`]).
    fresh: Cell<bool>,
}

fn outcome(r: Result<(), i2c::Error>) -> Outcome {
    match r {
        Ok(()) => Outcome::Ok,
        Err(i2c::Error::Nack) => Outcome::Nack,
        Err(i2c::Error::Arbitration) => Outcome::Arbitration,
        Err(i2c::Error::Bus) => Outcome::Bus,
        Err(i2c::Error::Timeout) => Outcome::Timeout,
        Err(i2c::Error::Overrun | i2c::Error::Crc | i2c::Error::ZeroLengthTransfer) => {
            Outcome::Other
        }
    }
}

fn gpio(port: u8) -> Option<pac::gpio::Gpio> {
    match port {
        0 => Some(pac::GPIOA),
        1 => Some(pac::GPIOB),
        2 => Some(pac::GPIOC),
        _ => None,
    }
}

/// The bus lines as open-drain GPIO outputs, for [`i2c_v2::recover_bus`]: the pins keep their
/// open-drain output type from the I2C set-up; their mode goes from alternate function to
/// output for the recovery and back after it.
struct GpioLines {
    scl: (pac::gpio::Gpio, usize),
    sda: (pac::gpio::Gpio, usize),
    half_period: Duration,
}

impl GpioLines {
    fn set(line: (pac::gpio::Gpio, usize), release: bool) {
        let (g, n) = line;
        g.bsrr().write(|w| {
            if release {
                w.set_bs(n, true)
            } else {
                w.set_br(n, true)
            }
        });
    }

    fn mode(line: (pac::gpio::Gpio, usize), m: pac::gpio::vals::Moder) {
        line.0.moder().modify(|w| w.set_moder(line.1, m));
    }
}

impl Lines for GpioLines {
    fn scl(&mut self, release: bool) {
        Self::set(self.scl, release);
    }
    fn sda(&mut self, release: bool) {
        Self::set(self.sda, release);
    }
    fn sda_high(&mut self) -> bool {
        self.sda.0.idr().read().idr(self.sda.1) == pac::gpio::vals::Idr::HIGH
    }
    fn half_period(&mut self) {
        embassy_time::block_for(self.half_period);
    }
}

impl Stm32Bus {
    /// The adapter on a `MultiMaster` handle of block `regs`, whose SCL and SDA are
    /// `lines` (GPIO port, pin number), running at `frequency_hz`; a controller transfer
    /// gives up after `timeout_us`.
    pub fn new(
        i2c: I2c<'static, Async, i2c::MultiMaster>,
        regs: pac::i2c::I2c,
        lines: [(u8, u8); 2],
        frequency_hz: u32,
        timeout_us: u32,
    ) -> Stm32Bus {
        Stm32Bus {
            i2c,
            regs,
            lines,
            frequency_hz,
            timeout_us,
            matched: None,
            fresh: Cell::new(true),
        }
    }

    /// The levels of SCL and SDA now (`GPIOx_IDR` reads the pad in the alternate function
    /// mode too, RM0440 §9.3.11).
    fn levels(&self) -> (bool, bool) {
        let [scl, sda] = self.lines.map(|(port, pin)| {
            gpio(port)
                .is_some_and(|g| g.idr().read().idr(usize::from(pin)) == pac::gpio::vals::Idr::HIGH)
        });
        (scl, sda)
    }

    /// Whether SCL and SDA hold `scl` and `sda` without a break for `need_us`, sampled in a
    /// tight loop ([`i2c_v2::Hold`]; synchronous: it ends at the first other level, within an
    /// SCL period on a live bus, and lasts the whole window only when the lines are still).
    fn held(&self, scl: bool, sda: bool, need_us: u32) -> bool {
        let now = || Instant::now().as_micros();
        let gap = i2c_v2::max_gap_us(self.frequency_hz);
        let mut h = i2c_v2::Hold::new(scl, sda, need_us, gap, now());
        loop {
            let (c, d) = self.levels();
            match h.sample(now(), c, d) {
                i2c_v2::Held::Yes => return true,
                i2c_v2::Held::No => return false,
                i2c_v2::Held::Wait => {}
            }
        }
    }

    fn isr(&self) -> u32 {
        self.regs.isr().read().0
    }

    fn clear(&self, icr: u32) {
        if icr != 0 {
            self.regs.icr().write_value(pac::i2c::regs::Icr(icr));
        }
    }

    /// Before a controller call: clears what earlier transfers left, after a block reset
    /// waits for quiet lines, resets a block whose BUSY is stale, clears a bus whose SDA a
    /// target holds, or refuses to start ([`i2c_v2::before_controller`]).
    ///
    /// # Errors
    /// [`BusError::ArbitrationLost`] (retry) or, when a stuck SDA stays low after the bus
    /// clear, [`BusError::Bus`].
    fn start_controller(&self) -> Result<(), BusError> {
        let b = i2c_v2::before_controller(self.isr(), self.fresh.get(), self.frequency_hz)?;
        if b.quiet_us > 0 && !self.held(true, true, b.quiet_us) {
            // BUSY and SDA held low under a high SCL as long: a target stuck in a byte whose
            // controller is gone; nobody else would clock it free. Cleared, then retried.
            if b.reset && self.held(true, false, b.quiet_us) {
                self.reset_and_clear_bus()?;
            }
            return Err(BusError::ArbitrationLost);
        }
        if b.reset {
            defmt::warn!("I2C: BUSY with both lines high: stale, block reset");
            self.reset_block();
        }
        self.clear(b.icr);
        self.fresh.set(false);
        Ok(())
    }

    /// Before answering an address match: clears what earlier transfers left.
    fn start_target(&self) {
        self.clear(i2c_v2::before_target(self.isr()));
    }

    /// PE off and on: the block's state machines and flags back to reset, SCL and SDA
    /// released; the configuration (timing, own address) stays (RM0440 §37.4.6).
    fn reset_block(&self) {
        self.regs.cr1().modify(|w| w.set_pe(false));
        // PE reads back low after three APB clock cycles.
        while self.regs.cr1().read().pe() {}
        self.regs.cr1().modify(|w| w.set_pe(true));
        self.fresh.set(true);
    }

    /// Waits (polling, yielding between polls) up to [`i2c_v2::stop_wait_us`] for the STOP
    /// that ends this node's transfer, and clears STOPF. False when the bus stays busy.
    async fn wait_stop(&self) -> bool {
        let deadline = Instant::now()
            + Duration::from_micros(u64::from(i2c_v2::stop_wait_us(self.frequency_hz)));
        loop {
            let isr = self.isr();
            if isr & (i2c_v2::isr::STOPF | i2c_v2::isr::BUSY) != i2c_v2::isr::BUSY {
                self.clear(isr & i2c_v2::isr::STOPF);
                return true;
            }
            if Instant::now() >= deadline {
                return false;
            }
            embassy_futures::yield_now().await;
        }
    }

    /// The bus did not come free after this node's transfer: STOP, then PE reset, then the
    /// nine-clock recovery of a stuck SDA.
    ///
    /// # Errors
    /// [`BusError::Bus`] when SDA stays low after the recovery.
    async fn recover(&self) -> Result<(), BusError> {
        self.regs.cr2().modify(|w| w.set_stop(true));
        if self.wait_stop().await {
            return Ok(());
        }
        self.reset_and_clear_bus()
    }

    /// PE reset, then the nine-clock recovery when SDA is held low under a high SCL for two
    /// byte times (synchronous: that window, then at most [`i2c_v2::CLEAR_HALF_PERIODS`]
    /// half periods of [`i2c_v2::clear_half_period_us`], 138 µs at 100 kHz; kept out of line,
    /// it is rare). A line that moves in the window is a transfer under way (or SCL held low
    /// by a stretching target), which nine clocks of ours would corrupt: nothing is clocked.
    ///
    /// # Errors
    /// [`BusError::Bus`] when SDA stays low.
    #[inline(never)]
    fn reset_and_clear_bus(&self) -> Result<(), BusError> {
        self.reset_block();
        let [scl, sda] = self.lines;
        let (Some(gs), Some(gd)) = (gpio(scl.0), gpio(sda.0)) else {
            return Err(BusError::Bus);
        };
        if !self.held(true, false, i2c_v2::stale_us(self.frequency_hz)) {
            return Ok(());
        }
        let mut lines = GpioLines {
            scl: (gs, usize::from(scl.1)),
            sda: (gd, usize::from(sda.1)),
            half_period: Duration::from_micros(u64::from(i2c_v2::clear_half_period_us(
                self.frequency_hz,
            ))),
        };
        defmt::warn!("I2C: SDA held low, clocking it free");
        lines.scl(true);
        lines.sda(true);
        GpioLines::mode(lines.scl, pac::gpio::vals::Moder::OUTPUT);
        GpioLines::mode(lines.sda, pac::gpio::vals::Moder::OUTPUT);
        let free = i2c_v2::recover_bus(&mut lines);
        GpioLines::mode(lines.scl, pac::gpio::vals::Moder::ALTERNATE);
        GpioLines::mode(lines.sda, pac::gpio::vals::Moder::ALTERNATE);
        self.reset_block();
        if free {
            Ok(())
        } else {
            Err(BusError::Bus)
        }
    }

    /// One controller transfer: `write` out, then, when `read` is not empty, a repeated START
    /// and `read` in. Ends on its own STOP; after a failure does what
    /// [`i2c_v2::after_controller`] says and maps the outcome.
    ///
    /// # Errors
    /// [`BusError::ArbitrationLost`] when the bus is taken or arbitration was lost; `Nack`,
    /// `Timeout`; [`BusError::Bus`] for a bus error or when SDA stays stuck after a recovery.
    async fn transfer(&mut self, addr: u8, write: &[u8], read: &mut [u8]) -> Result<(), BusError> {
        let phases = i2c_v2::cr2_phases(addr, write.len(), read.len()).ok_or(BusError::Overrun)?;
        self.start_controller()?;
        let mut p = Progress::new(write.len(), read.len());
        let o = self.run_transfer(phases, write, read, &mut p).await;
        let (icr, after) = i2c_v2::after_controller(o);
        self.clear(icr);
        if o != Outcome::Ok {
            // A byte left in TXDR would go out in this node's next answer as a target.
            self.regs.isr().write(|w| w.set_txe(true));
        }
        let free = match after {
            After::Done => true,
            After::WaitStop => self.wait_stop().await,
            After::Reset => {
                self.reset_block();
                true
            }
            After::Abort => false,
        };
        if !free {
            self.recover().await?;
        }
        i2c_v2::transfer_error(o, &p)
    }

    /// The register sequence of a transfer (RM0440 §37.4.9; embassy-stm32's blocking
    /// `write_internal`/`read_internal` without their spins): CR2 starts the write phase
    /// (AUTOEND when no read follows), each TXIS takes a byte, TC starts the read phase with
    /// a repeated START and AUTOEND, each RXNE gives a byte, STOPF ends it. Between polls the
    /// task yields; no wait is synchronous.
    async fn run_transfer(
        &mut self,
        phases: (u32, u32),
        write: &[u8],
        read: &mut [u8],
        p: &mut Progress,
    ) -> Outcome {
        let (first, second) = phases;
        self.regs.cr2().write_value(pac::i2c::regs::Cr2(first));
        let deadline = self.deadline();
        loop {
            let step = i2c_v2::controller_step(self.isr(), p);
            match step {
                Step::Send => {
                    let byte = write.get(p.sent).copied().unwrap_or(0);
                    self.regs.txdr().write(|w| w.set_txdata(byte));
                }
                Step::Receive => {
                    let byte = self.regs.rxdr().read().rxdata();
                    if let Some(slot) = read.get_mut(p.received) {
                        *slot = byte;
                    }
                }
                Step::Restart => {
                    self.regs.cr2().write_value(pac::i2c::regs::Cr2(second));
                }
                Step::Finished => {
                    self.clear(i2c_v2::icr::STOPCF);
                    return Outcome::Ok;
                }
                Step::Failed(o) => return o,
                Step::Wait => {
                    if Instant::now() >= deadline {
                        return Outcome::Timeout;
                    }
                    embassy_futures::yield_now().await;
                    continue;
                }
            }
            // A move was made: count it and look again at once.
            p.advance(step);
        }
    }

    /// After the driver's `listen` failed: see [`Stm32Bus::target_failed`].
    fn target_error(&self, e: i2c::Error) -> BusError {
        self.target_failed(outcome(Err(e)))
    }

    /// After a target-side transfer failed: a timeout may have left SCL stretched in the
    /// middle of it, and errors leave the state machine where they struck, so the block is
    /// reset ([`i2c_v2::target_needs_reset`]).
    #[inline(never)]
    fn target_failed(&self, o: Outcome) -> BusError {
        if i2c_v2::target_needs_reset(o) {
            self.reset_block();
        }
        i2c_v2::controller_error(o).err().unwrap_or(BusError::Bus)
    }

    /// Arms the target side for `nbytes` bytes (RELOAD; `nack`: NACK the byte received last),
    /// which also ends a TCR stretch ([`i2c_v2::target_cr2`]).
    fn arm_target(&self, nbytes: u8, nack: bool) {
        let v = i2c_v2::target_cr2(self.regs.cr2().read().0, nbytes, nack);
        self.regs.cr2().write_value(pac::i2c::regs::Cr2(v));
    }

    /// The deadline of a transfer starting now.
    fn deadline(&self) -> Instant {
        Instant::now() + Duration::from_micros(u64::from(self.timeout_us))
    }

    /// Receives the write whose address match is pending (ADDR set, SCL stretched) into `buf`,
    /// polling ISR with a yield between polls ([`i2c_v2::receive_step`]). NBYTES is
    /// [`RX_LEN`], one byte more than the longest frame, with RELOAD: a byte past the longest
    /// frame raises TCR and is NACKed, so an over-long write ends at once with
    /// [`BusError::Overrun`] (the driver's `respond_to_write` let the block stretch SCL until
    /// its timeout after its DMA buffer was full: issue 21 item 6).
    ///
    /// A write ended by a repeated START that reads is a write-read (the read's ADDR is left
    /// set for [`Stm32Bus::transmit`]).
    async fn receive(&self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        self.start_target();
        self.arm_target(RX_LEN as u8, false);
        self.clear(i2c_v2::icr::ADDRCF);
        let deadline = self.deadline();
        let cap = RX_LEN.min(buf.len() + 1);
        let mut n = 0;
        loop {
            let isr = self.isr();
            match i2c_v2::receive_step(isr) {
                RxStep::Take => {
                    let byte = self.regs.rxdr().read().rxdata();
                    if let Some(slot) = buf.get_mut(n) {
                        *slot = byte;
                    }
                    n += 1;
                }
                RxStep::Refuse => {
                    // NACK chosen first, then NBYTES written, which ends the stretch.
                    self.regs.cr2().modify(|w| w.set_nack(true));
                    self.arm_target(1, true);
                }
                RxStep::Stop | RxStep::Restart => {
                    let restart = isr & i2c_v2::isr::STOPF == 0;
                    self.clear(isr & i2c_v2::isr::STOPF);
                    return match i2c_v2::received(n, cap, isr, restart) {
                        Some(true) => Ok(Incoming::WriteRead(n)),
                        Some(false) => Ok(Incoming::Write(n)),
                        None => Err(BusError::Overrun),
                    };
                }
                RxStep::Failed => return Err(self.target_failed(Outcome::Bus)),
                RxStep::Wait => {
                    if Instant::now() >= deadline {
                        return Err(self.target_failed(Outcome::Timeout));
                    }
                    embassy_futures::yield_now().await;
                }
            }
        }
    }

    /// Answers the read whose address match is pending: the reply, then 0xFF for as long as
    /// the controller reads (NBYTES 255 with RELOAD, armed again at each TCR), until its NACK
    /// and STOP ([`i2c_v2::transmit_step`]). The driver's `respond_to_read` sent only its
    /// buffer and then let the block stretch SCL until its timeout (issue 21 item 6).
    async fn transmit(&self, reply: &[u8]) -> Result<(), BusError> {
        self.start_target();
        // A byte left in TXDR would go out first.
        self.regs.isr().write(|w| w.set_txe(true));
        self.arm_target(255, false);
        self.clear(i2c_v2::icr::ADDRCF);
        let deadline = self.deadline();
        let mut i = 0;
        let mut nacked = false;
        loop {
            let isr = self.isr();
            match i2c_v2::transmit_step(isr, nacked) {
                TxStep::Send => {
                    let byte = i2c_v2::reply_byte(reply, i);
                    self.regs.txdr().write(|w| w.set_txdata(byte));
                    i += 1;
                }
                TxStep::Reload => self.arm_target(255, false),
                TxStep::Nacked => {
                    self.clear(i2c_v2::icr::NACKCF);
                    self.regs.isr().write(|w| w.set_txe(true));
                    nacked = true;
                }
                TxStep::Done => {
                    self.clear(isr & i2c_v2::isr::STOPF);
                    return Ok(());
                }
                TxStep::Failed => return Err(self.target_failed(Outcome::Bus)),
                TxStep::Wait => {
                    if Instant::now() >= deadline {
                        return Err(self.target_failed(Outcome::Timeout));
                    }
                    embassy_futures::yield_now().await;
                }
            }
        }
    }
}

impl MultiMaster for Stm32Bus {
    /// # Errors
    /// As the trait; [`BusError::ArbitrationLost`] at once when the bus is taken (see the
    /// module doc) or when arbitration is lost; [`BusError::Bus`] when SDA stays stuck after
    /// a recovery.
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        self.transfer(addr, bytes, &mut []).await
    }

    /// # Errors
    /// As [`Stm32Bus::write`].
    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        self.transfer(addr, bytes, read).await
    }

    /// embassy-stm32's `listen`: waits for ADDR and leaves it set (SCL stays stretched), so
    /// dropping it loses nothing. The match is kept for [`Stm32Bus::listen`].
    async fn addressed(&mut self) -> Result<(), BusError> {
        if self.matched.is_none() {
            let cmd = self.i2c.listen().await.map_err(|e| self.target_error(e))?;
            self.matched = Some(cmd.kind);
        }
        Ok(())
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let kind = match self.matched.take() {
            Some(kind) => kind,
            None => {
                self.i2c
                    .listen()
                    .await
                    .map_err(|e| self.target_error(e))?
                    .kind
            }
        };
        if kind == SlaveCommandKind::Read {
            return Ok(Incoming::Read);
        }
        self.receive(buf).await
    }

    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        self.transmit(bytes).await
    }
}

// ---------------------------------------------------------------------------------------
// Ports
// ---------------------------------------------------------------------------------------

/// One sensor port's pins.
pub struct SensorPort {
    /// Digital pins A and B: (GPIO port, pin number), A = 0, for the edge latches.
    pub gpio: [(u8, u8); 2],
    /// Digital pins A and B.
    pub pins: [Lock<Flex<'static>>; 2],
    /// The analog input.
    pub analog: Lock<AnyAdcChannel<'static, peripherals::ADC1>>,
}

/// One actuator port's pins and timer.
pub struct ActuatorPort<U> {
    /// Digital pins A and B: (GPIO port, pin number), A = 0, for the edge latches.
    pub gpio: [(u8, u8); 2],
    /// Digital pins A and B.
    pub pins: [Lock<Flex<'static>>; 2],
    /// The timer, and what each PWM pin was last told.
    pub pwm: Lock<(U, [Output; 2])>,
}

/// [`Ports`] on an STM32's pins: `S` sensor ports, `A` actuator ports whose timers are `U`.
///
/// Each pin is behind its own async mutex: a pulse-in holds its pin for the whole
/// measurement, and any other operation on that pin meanwhile answers [`PortError::Busy`].
pub struct Stm32Ports<U, const S: usize, const A: usize> {
    adc: Lock<adc::Adc<'static, peripherals::ADC1>>,
    adc_bits: u8,
    sensors: [SensorPort; S],
    actuators: [ActuatorPort<U>; A],
    latches: BlockingMutex<CriticalSectionRawMutex, Cell<Latches>>,
}

/// Per EXTI line: the GPIO port of the pin latching on it and that pin's level at its last
/// take ([`crate::stm32_latch`]).
type Latches = [Option<(u8, bool)>; 16];

/// How often `wait_edge` looks at the latched lines, in µs.
const EDGE_POLL_US: u64 = 200;

/// The level of pin `line` of GPIO port `port` (`GPIOx_IDR`), read without its pin driver.
fn gpio_level(port: u8, line: usize) -> bool {
    let gpio = match port {
        0 => pac::GPIOA,
        1 => pac::GPIOB,
        2 => pac::GPIOC,
        #[cfg(feature = "stm32c011")]
        5 => pac::GPIOF,
        _ => return false,
    };
    gpio.idr().read().idr(line) == pac::gpio::vals::Idr::HIGH
}

/// Routes EXTI line `line` to GPIO port `port`, both edges, pending cleared, and unmasks it so
/// that its pending bits latch, after masking its vector in the NVIC
/// ([`crate::stm32_latch`]: embassy-stm32 enabled them all and no EXTI handler is bound).
fn exti_latch(port: u8, line: usize) {
    #[cfg(feature = "stm32c011")]
    use crate::c011::{EXTI_VECTORS, EXTI_VECTOR_LINES};
    #[cfg(feature = "stm32g431")]
    use crate::g431::{EXTI_VECTORS, EXTI_VECTOR_LINES};
    use embassy_stm32::interrupt::InterruptExt as _;
    let (Some(v), Some([imr, rtsr, ftsr])) = (
        stm32_latch::exti_vector(&EXTI_VECTOR_LINES, line).and_then(|v| EXTI_VECTORS.get(v)),
        stm32_latch::exti_line_bits(line),
    ) else {
        return;
    };
    v.disable();
    // The mask takes effect before the line can raise the interrupt.
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    cortex_m::interrupt::free(|_| {
        #[cfg(feature = "stm32g431")]
        pac::SYSCFG
            .exticr(line / 4)
            .modify(|w| w.set_exti(line % 4, port));
        #[cfg(feature = "stm32c011")]
        pac::EXTI
            .exticr(line / 4)
            .modify(|w| w.set_exti(line % 4, port));
        pac::EXTI.rtsr(0).modify(|w| w.0 |= rtsr);
        pac::EXTI.ftsr(0).modify(|w| w.0 |= ftsr);
        exti_pending(line, true);
        pac::EXTI.imr(0).modify(|w| w.0 |= imr);
    });
}

/// The pending bits of EXTI line `line`, cleared with `clear`.
fn exti_pending(line: usize, clear: bool) -> Pending {
    #[cfg(feature = "stm32g431")]
    {
        let p = pac::EXTI.pr(0).read().line(line);
        if clear && p {
            pac::EXTI.pr(0).write(|w| w.set_line(line, true));
        }
        Pending::Either(p)
    }
    #[cfg(not(feature = "stm32g431"))]
    {
        let rising = pac::EXTI.rpr(0).read().line(line);
        let falling = pac::EXTI.fpr(0).read().line(line);
        if clear && rising {
            pac::EXTI.rpr(0).write(|w| w.set_line(line, true));
        }
        if clear && falling {
            pac::EXTI.fpr(0).write(|w| w.set_line(line, true));
        }
        Pending::Split { rising, falling }
    }
}

fn compare<U: PwmTimer>(unit: &U, out: Output) -> Option<u32> {
    let (hz, max) = unit.frequency_and_max();
    let c = Timebase::from_frequency(hz, max).compare(out)?;
    Some(stm32_compare(c, max))
}

impl<U: PwmTimer, const S: usize, const A: usize> Stm32Ports<U, S, A> {
    /// The ports of a board.
    pub fn new(
        adc: adc::Adc<'static, peripherals::ADC1>,
        adc_bits: u8,
        sensors: [SensorPort; S],
        actuators: [ActuatorPort<U>; A],
    ) -> Self {
        Stm32Ports {
            adc: Lock::new(adc),
            adc_bits,
            sensors,
            actuators,
            latches: BlockingMutex::new(Cell::new([None; 16])),
        }
    }

    /// The (GPIO port, pin number) of a digital pin.
    fn gpio(&self, pin: PinRef) -> Result<(u8, u8), PortError> {
        port_lookup::digital(
            &self.sensors,
            &self.actuators,
            pin,
            |s| &s.gpio,
            |a| &a.gpio,
        )
        .copied()
    }

    /// The digital pin `pin`, unless a pulse-in holds it ([`PortError::Busy`]).
    fn digital(&self, pin: PinRef) -> Result<PinGuard<'_>, PortError> {
        let lock = port_lookup::digital(
            &self.sensors,
            &self.actuators,
            pin,
            |s| &s.pins,
            |a| &a.pins,
        )?;
        port_lookup::take(lock)
    }

    fn pwm(&self, port: Port) -> Result<&Lock<(U, [Output; 2])>, PortError> {
        port_lookup::actuator(&self.actuators, port).map(|a| &a.pwm)
    }

    /// Sets one output of a port, or changes nothing when it does not fit the period.
    fn set_output(&self, pin: PinRef, out: Output) -> Result<(), PortError> {
        let mut guard = port_lookup::take(self.pwm(pin.port)?)?;
        let (unit, outs) = &mut *guard;
        let c = compare(unit, out).ok_or(PortError::Unsupported)?;
        unit.set_compare(pin.pin, c);
        if let Some(o) = outs.get_mut(pin.pin.index()) {
            *o = out;
        }
        Ok(())
    }
}

impl<U: PwmTimer, const S: usize, const A: usize> Ports for Stm32Ports<U, S, A> {
    fn sensor_ports(&self) -> u8 {
        S as u8
    }

    fn actuator_ports(&self) -> u8 {
        A as u8
    }

    fn adc_bits(&self) -> u8 {
        self.adc_bits
    }

    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        let mut f = self.digital(pin)?;
        f.set_as_input(Pull::Down);
        Ok(Level::from_bool(f.is_high()))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        let mut f = self.digital(pin)?;
        f.set_level(level.is_high().into());
        f.set_as_output(Speed::Low);
        Ok(())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        self.set_output(pin, Output::Duty(duty))
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        let mut guard = port_lookup::take(self.pwm(port)?)?;
        let (unit, outs) = &mut *guard;
        if !stm32_frequency_ok(unit.timer_hz(), hz) {
            return Err(PortError::Unsupported);
        }
        let (old_hz, _) = unit.frequency_and_max();
        unit.set_frequency(u32::from(hz));
        // Keep each pin's duty cycle or pulse width; undo when a pulse no longer fits.
        let [Some(a), Some(b)] = [compare(unit, outs[0]), compare(unit, outs[1])] else {
            unit.set_frequency(if old_hz == 0 {
                u32::from(DEFAULT_HZ)
            } else {
                old_hz
            });
            return Err(PortError::Unsupported);
        };
        unit.set_compare(Pin::A, a);
        unit.set_compare(Pin::B, b);
        Ok(())
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        self.set_output(pin, Output::PulseUs(us))
    }

    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        let sensor = port_lookup::sensor(&self.sensors, port)?;
        let mut ch = port_lookup::take(&sensor.analog)?;
        let mut adc = port_lookup::take(&self.adc)?;
        // A blocking conversion: 47.5 + 12.5 ADC cycles, under 2 µs at the G431's 42.5 MHz
        // ADC clock (170 MHz / 4), under 2 µs at the C011's (at most 35 MHz).
        Ok(adc.blocking_read(&mut *ch, adc::SampleTime::CYCLES47_5))
    }

    /// Samples the pin in a loop, yielding to the other tasks between samples, and lets
    /// [`PulseIn`] decide. The resolution is the time between two samples: the longest the
    /// other code runs without yielding (see `docs/boards.md`).
    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        let mut f = self.digital(pin)?;
        f.set_as_input(Pull::Down);
        let mut m = PulseIn::new(edge, Instant::now().as_micros(), timeout_ms);
        loop {
            let high = f.is_high();
            if let Some(r) = m.sample(high, Instant::now().as_micros()) {
                return r;
            }
            embassy_futures::yield_now().await;
        }
    }

    /// Latches on the pin's EXTI line (both edges; the line unmasked in the EXTI, its vector
    /// masked in the NVIC) when no pin of another GPIO port holds that line; see
    /// [`crate::stm32_latch`] for what is and is not known.
    ///
    /// # Errors
    /// [`PortError::NoSuchPin`]; [`PortError::Unsupported`] when the line is taken (the
    /// runtime samples the pin instead).
    fn latch_edges(&self, pin: PinRef) -> Result<(), PortError> {
        let (port, line) = self.gpio(pin)?;
        let l = usize::from(line);
        self.latches.lock(|c| {
            let mut v = c.get();
            let slot = v.get_mut(l).ok_or(PortError::NoSuchPin)?;
            stm32_latch::claim(slot.map(|(p, _)| p), port)?;
            exti_latch(port, l);
            *slot = Some((port, gpio_level(port, l)));
            c.set(v);
            Ok(())
        })
    }

    fn take_edges(&self, pin: PinRef) -> Result<EdgeCount, PortError> {
        let (port, line) = self.gpio(pin)?;
        let l = usize::from(line);
        self.latches.lock(|c| {
            let mut v = c.get();
            let slot = v.get_mut(l).ok_or(PortError::Unsupported)?;
            let Some((holder, before)) = *slot else {
                return Err(PortError::Unsupported);
            };
            if holder != port {
                return Err(PortError::Unsupported);
            }
            // The bits first, then the level: an edge between the two is in the level now
            // and in the bits next time (counted twice at worst, never lost).
            let pending = exti_pending(l, true);
            let now = gpio_level(port, l);
            *slot = Some((port, now));
            c.set(v);
            Ok(stm32_latch::edges(pending, before, now))
        })
    }

    async fn wait_edge(&self) {
        loop {
            let waiting = self.latches.lock(|c| {
                c.get().iter().enumerate().any(|(l, slot)| {
                    slot.is_some_and(|(port, before)| {
                        stm32_latch::waiting(exti_pending(l, false), before, gpio_level(port, l))
                    })
                })
            });
            if waiting {
                return;
            }
            embassy_time::Timer::after_micros(EDGE_POLL_US).await;
        }
    }
}
