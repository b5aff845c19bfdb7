//! STM32G431 (embassy-stm32, I2C v2): bus, ports and start-up, built from
//! [`pins::G431`](crate::pins::G431)'s table.
//!
//! * [`G431Bus`]: one I2C v2 handle in `MultiMaster` mode is controller and target at once, so
//!   the adapter forwards calls. Two checks keep it from blocking: embassy-stm32's `write`
//!   busy-waits (synchronously) while another master holds the bus, so a write while the bus
//!   is BUSY, or while this node is being addressed, fails at once with
//!   [`BusError::ArbitrationLost`] and the runtime retries with its backoff; and the driver's
//!   own timeout is the short one from [`BusConfig`] (a timeout of that wait while this node is
//!   addressed is reported as arbitration lost too). Target side: `addressed` is the driver's
//!   `listen` (ADDR seen, left set, SCL stretched, cancel-safe), kept for the adapter's
//!   `listen`, which receives the transfer (`respond_to_write`, never raced by the runtimes).
//! * [`G431Ports`]: digital pins are `Flex` pins (input with pull-down, or push-pull output),
//!   PWM pins are channels 1 and 2 of one timer per actuator port, analog inputs are on ADC1
//!   (12 bits), pulse-in samples its pin (see [`crate::pulse`]).
//!
//! Clocks: 170 MHz from the internal 16 MHz HSI through the PLL (no crystal assumed, so the
//! same image runs on the WeAct board and the NUCLEO-G431RB).

use core::task::Poll;

/// The HAL, for the images' `main`.
pub use embassy_stm32 as hal;
use embassy_stm32::adc::{self, AdcChannel, AnyAdcChannel, SampleTime};
use embassy_stm32::gpio::{Flex, Input, OutputType, Pull, Speed};
use embassy_stm32::i2c::{self, I2c, SlaveAddrConfig, SlaveCommandKind};
use embassy_stm32::mode::Async;
use embassy_stm32::rcc;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::{bind_interrupts, dma, pac, peripherals, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::Instant;
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::ports::{PortError, Ports};
use x10_microcode::{Edge, Level, Pin, PinRef, Port, PortKind, MAX_FRAME_LEN};

use crate::pins::G431;
use crate::pulse::PulseIn;
use crate::pwm::{stm32_frequency_ok, Output, Timebase, DEFAULT_HZ};
use crate::{BusConfig, RX_LEN};

bind_interrupts!(
    /// The interrupts the G431 images use: the bus's I2C block and its two DMA channels.
    pub struct Irqs {
        I2C1_EV => i2c::EventInterruptHandler<peripherals::I2C1>;
        I2C1_ER => i2c::ErrorInterruptHandler<peripherals::I2C1>;
        DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
        DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    }
);

/// Number of sensor ports ([`G431`]).
pub const SENSORS: usize = G431.sensors.len();
/// Number of actuator ports ([`G431`]).
pub const ACTUATORS: usize = G431.actuators.len();
/// Number of address-select jumpers ([`G431`]): none, every pin is a port pin.
pub const JUMPERS: usize = G431.jumpers.len();

/// ADC resolution of the STM32G431.
pub const ADC_BITS: u8 = 12;

type Lock<T> = Mutex<CriticalSectionRawMutex, T>;

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
    c
}

/// Starts the HAL with [`hal_config`].
pub fn init() -> embassy_stm32::Peripherals {
    embassy_stm32::init(hal_config())
}

/// Everything the table names, taken from the HAL.
pub struct Board {
    /// The bus (controller and target at once).
    pub bus: G431Bus,
    /// The ports (actuators in their safe state: digital low, PWM off).
    pub ports: G431Ports,
    /// The value of the address-select jumpers read at start-up (fitted = 1, bit 0 first; the
    /// table has none, so 0).
    pub jumpers: u8,
}

macro_rules! g431_build {
    (
        board: $board:literal,
        i2c: $i2c:ident { sda: $sda:ident, scl: $scl:ident },
        sensors: [ $( ($sa:ident, $sb:ident, $san:ident) ),* $(,)? ],
        actuators: [ $( ($tim:ident, $pa:ident, $pb:ident, $da:ident, $db:ident) ),* $(,)? ],
        jumpers: [ $( $j:ident ),* $(,)? ] $(,)?
    ) => {
        fn i2c_regs() -> pac::i2c::I2c {
            pac::$i2c
        }

        impl Board {
            /// Takes the table's peripherals: builds the ports in their safe state and the
            /// bus adapter. `p` comes from `embassy_stm32::init(hal_config())`.
            ///
            /// `bus` gets the jumper value and returns the bus setup (the node's own address
            /// may depend on the jumpers).
            pub fn new(p: embassy_stm32::Peripherals, bus: impl FnOnce(u8) -> BusConfig) -> Board {
                // Inputs only while they are read; dropped, the pins are disconnected again.
                let jumpers = {
                    let inputs: [Input<'static>; JUMPERS] = [ $( Input::new(p.$j, Pull::Up) ),* ];
                    if JUMPERS > 0 {
                        // Let the pull-ups (about 40 kΩ against the pins' capacitance) settle.
                        embassy_time::block_for(embassy_time::Duration::from_micros(10));
                    }
                    crate::address::jumper_value(inputs.iter().map(|i| i.is_high()))
                };
                let bus = bus(jumpers);
                let mut cfg = i2c::Config::default();
                cfg.frequency = Hertz(bus.frequency_hz);
                cfg.timeout = embassy_time::Duration::from_micros(u64::from(bus.timeout_us));
                let i2c = I2c::new(p.$i2c, p.$scl, p.$sda, p.DMA1_CH1, p.DMA1_CH2, Irqs, cfg)
                    .into_slave_multimaster(SlaveAddrConfig::basic(bus.own_address));
                let sensors = [ $( SensorPort {
                    pins: [Lock::new(input(p.$sa.into())), Lock::new(input(p.$sb.into()))],
                    analog: Lock::new(p.$san.degrade_adc()),
                } ),* ];
                let actuators = [ $( ActuatorPort {
                    pins: [Lock::new(output_low(p.$da.into())), Lock::new(output_low(p.$db.into()))],
                    pwm: Lock::new((PwmUnit::$tim(SimplePwm::new(
                        p.$tim,
                        Some(PwmPin::new(p.$pa, OutputType::PushPull)),
                        Some(PwmPin::new(p.$pb, OutputType::PushPull)),
                        None,
                        None,
                        Hertz(u32::from(DEFAULT_HZ)),
                        CountingMode::EdgeAlignedUp,
                    )).started(), [Output::OFF; 2])),
                } ),* ];
                Board {
                    bus: G431Bus { i2c, matched: None },
                    ports: G431Ports {
                        adc: Lock::new(adc::Adc::new(p.ADC1, Default::default())),
                        sensors,
                        actuators,
                    },
                    jumpers,
                }
            }
        }

        /// The timer of one actuator port (the table gives each port its own timer).
        #[allow(non_camel_case_types, clippy::upper_case_acronyms)]
        enum PwmUnit {
            $( $tim(SimplePwm<'static, peripherals::$tim>), )*
        }

        impl PwmUnit {
            /// Both channels on at 0 % duty.
            fn started(mut self) -> PwmUnit {
                match &mut self {
                    $( PwmUnit::$tim(p) => {
                        p.ch1().set_duty_cycle(0);
                        p.ch2().set_duty_cycle(0);
                        p.ch1().enable();
                        p.ch2().enable();
                    } )*
                }
                self
            }

            /// The timer's input clock.
            fn timer_hz(&self) -> u32 {
                match self {
                    $( PwmUnit::$tim(_) => rcc::frequency::<peripherals::$tim>().0, )*
                }
            }

            fn set_frequency(&mut self, hz: u32) {
                match self {
                    $( PwmUnit::$tim(p) => p.set_frequency(Hertz(hz)), )*
                }
            }

            fn timebase(&self) -> Timebase {
                match self {
                    $( PwmUnit::$tim(p) => Timebase::from_frequency(p.get_frequency().0, p.max_duty_cycle()), )*
                }
            }

            fn set_compare(&mut self, pin: Pin, c: u32) {
                match self {
                    $( PwmUnit::$tim(p) => match pin {
                        Pin::A => p.ch1().set_duty_cycle(c),
                        Pin::B => p.ch2().set_duty_cycle(c),
                    }, )*
                }
            }
        }
    };
}

g431_table!(g431_build);

fn input(pin: Peri<'static, embassy_stm32::gpio::AnyPin>) -> Flex<'static> {
    let mut f = Flex::new(pin);
    f.set_as_input(Pull::Down);
    f
}

fn output_low(pin: Peri<'static, embassy_stm32::gpio::AnyPin>) -> Flex<'static> {
    let mut f = Flex::new(pin);
    f.set_low();
    f.set_as_output(Speed::Low);
    f
}

// ---------------------------------------------------------------------------------------
// Bus
// ---------------------------------------------------------------------------------------

/// [`MultiMaster`] on the STM32G431's I2C v2 block (see the module doc).
pub struct G431Bus {
    i2c: I2c<'static, Async, i2c::MultiMaster>,
    /// The address match [`MultiMaster::addressed`] saw (ADDR still set, SCL stretched),
    /// for the following `listen`.
    matched: Option<SlaveCommandKind>,
}

/// Longest reply that gets padded: a controller reading past the reply gets 0xFF, as the
/// trait promises, for up to this many bytes in all.
const TX_LEN: usize = MAX_FRAME_LEN + 16;

fn bus_error(e: i2c::Error) -> BusError {
    match e {
        i2c::Error::Nack => BusError::Nack,
        i2c::Error::Arbitration => BusError::ArbitrationLost,
        i2c::Error::Timeout => BusError::Timeout,
        i2c::Error::Overrun => BusError::Overrun,
        i2c::Error::Bus | i2c::Error::Crc | i2c::Error::ZeroLengthTransfer => BusError::Bus,
    }
}

impl G431Bus {
    /// Fails when the bus is taken: another master holds it (BUSY), or it is addressing this
    /// node (ADDR, the clock is stretched until `listen` answers).
    fn bus_free() -> Result<(), BusError> {
        let isr = i2c_regs().isr().read();
        if isr.busy() || isr.addr() {
            Err(BusError::ArbitrationLost)
        } else {
            Ok(())
        }
    }

    /// A controller call's result. embassy-stm32 spins (synchronously) while BUSY before it
    /// starts; a master that began between [`G431Bus::bus_free`] and that spin and addresses
    /// this node keeps BUSY set (ADDR stretches SCL) until the spin times out: that is this
    /// node being addressed, not a dead bus, so it is reported as `ArbitrationLost` and the
    /// runtime serves the transaction and retries.
    fn controller_result(r: Result<(), i2c::Error>) -> Result<(), BusError> {
        match r {
            Err(i2c::Error::Timeout) if i2c_regs().isr().read().addr() => {
                Err(BusError::ArbitrationLost)
            }
            r => r.map_err(bus_error),
        }
    }
}

impl MultiMaster for G431Bus {
    /// # Errors
    /// As the trait; [`BusError::ArbitrationLost`] at once when the bus is taken (see the
    /// module doc), or when the driver's BUSY wait timed out while this node was being
    /// addressed; an empty write is [`BusError::Bus`].
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        Self::bus_free()?;
        Self::controller_result(self.i2c.write(addr, bytes).await)
    }

    /// # Errors
    /// As [`G431Bus::write`].
    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        Self::bus_free()?;
        Self::controller_result(self.i2c.write_read(addr, bytes, read).await)
    }

    /// embassy-stm32's `listen`: waits for ADDR and leaves it set (SCL stays stretched), so
    /// dropping it loses nothing. The match is kept for [`G431Bus::listen`].
    async fn addressed(&mut self) -> Result<(), BusError> {
        if self.matched.is_none() {
            let cmd = self.i2c.listen().await.map_err(bus_error)?;
            self.matched = Some(cmd.kind);
        }
        Ok(())
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let kind = match self.matched.take() {
            Some(kind) => kind,
            None => self.i2c.listen().await.map_err(bus_error)?.kind,
        };
        if kind == SlaveCommandKind::Read {
            return Ok(Incoming::Read);
        }
        // The driver acknowledges and drops bytes past its buffer: one byte more than the
        // longest frame shows an over-long write.
        let mut rx = [0u8; RX_LEN];
        let n = self
            .i2c
            .respond_to_write(&mut rx)
            .await
            .map_err(bus_error)?;
        let (Some(dst), Some(src)) = (buf.get_mut(..n), rx.get(..n)) else {
            return Err(BusError::Overrun);
        };
        if n >= RX_LEN {
            return Err(BusError::Overrun);
        }
        dst.copy_from_slice(src);
        // The write ended with STOP, or with a repeated START: then ADDR is already set again
        // with the read direction, and `listen` reports it without waiting.
        match embassy_futures::poll_once(self.i2c.listen()) {
            Poll::Ready(Ok(c)) if c.kind == SlaveCommandKind::Read => Ok(Incoming::WriteRead(n)),
            _ => Ok(Incoming::Write(n)),
        }
    }

    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let mut tx = [0xFFu8; TX_LEN];
        let reply: &[u8] = match tx.get_mut(..bytes.len()) {
            Some(head) => {
                head.copy_from_slice(bytes);
                &tx
            }
            None => bytes,
        };
        self.i2c
            .respond_to_read(reply)
            .await
            .map(|_| ())
            .map_err(bus_error)
    }
}

// ---------------------------------------------------------------------------------------
// Ports
// ---------------------------------------------------------------------------------------

struct SensorPort {
    pins: [Lock<Flex<'static>>; 2],
    analog: Lock<AnyAdcChannel<'static, peripherals::ADC1>>,
}

struct ActuatorPort {
    pins: [Lock<Flex<'static>>; 2],
    pwm: Lock<(PwmUnit, [Output; 2])>,
}

/// [`Ports`] on the STM32G431's pins ([`G431`]).
///
/// Each pin is behind its own async mutex: a pulse-in holds its pin for the whole
/// measurement, and any other operation on that pin meanwhile answers [`PortError::Busy`].
pub struct G431Ports {
    adc: Lock<adc::Adc<'static, peripherals::ADC1>>,
    sensors: [SensorPort; SENSORS],
    actuators: [ActuatorPort; ACTUATORS],
}

impl G431Ports {
    fn digital(&self, pin: PinRef) -> Result<&Lock<Flex<'static>>, PortError> {
        let i = usize::from(pin.port.index());
        let pins = match pin.port.kind() {
            PortKind::Sensor => &self.sensors.get(i).ok_or(PortError::NoSuchPin)?.pins,
            PortKind::Actuator => &self.actuators.get(i).ok_or(PortError::NoSuchPin)?.pins,
        };
        pins.get(pin.pin.index()).ok_or(PortError::NoSuchPin)
    }

    fn pwm(&self, port: Port) -> Result<&Lock<(PwmUnit, [Output; 2])>, PortError> {
        match port.kind() {
            PortKind::Actuator => self
                .actuators
                .get(usize::from(port.index()))
                .map(|a| &a.pwm)
                .ok_or(PortError::NoSuchPin),
            PortKind::Sensor => Err(PortError::Unsupported),
        }
    }

    /// Sets one output of a port, or changes nothing when it does not fit the period.
    async fn set_output(&self, pin: PinRef, out: Output) -> Result<(), PortError> {
        let mut guard = self.pwm(pin.port)?.lock().await;
        let (unit, outs) = &mut *guard;
        let c = unit.timebase().compare(out).ok_or(PortError::Unsupported)?;
        unit.set_compare(pin.pin, c);
        if let Some(o) = outs.get_mut(pin.pin.index()) {
            *o = out;
        }
        Ok(())
    }
}

impl Ports for G431Ports {
    fn sensor_ports(&self) -> u8 {
        G431.sensor_ports()
    }

    fn actuator_ports(&self) -> u8 {
        G431.actuator_ports()
    }

    fn adc_bits(&self) -> u8 {
        ADC_BITS
    }

    async fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        let mut f = self.digital(pin)?.try_lock().map_err(|_| PortError::Busy)?;
        f.set_as_input(Pull::Down);
        Ok(Level::from_bool(f.is_high()))
    }

    async fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        let mut f = self.digital(pin)?.try_lock().map_err(|_| PortError::Busy)?;
        f.set_level(if level.is_high() {
            embassy_stm32::gpio::Level::High
        } else {
            embassy_stm32::gpio::Level::Low
        });
        f.set_as_output(Speed::Low);
        Ok(())
    }

    async fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        self.set_output(pin, Output::Duty(duty)).await
    }

    async fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        let mut guard = self.pwm(port)?.lock().await;
        let (unit, outs) = &mut *guard;
        if !stm32_frequency_ok(unit.timer_hz(), hz) {
            return Err(PortError::Unsupported);
        }
        let before = unit.timebase();
        unit.set_frequency(u32::from(hz));
        let after = unit.timebase();
        // Keep each pin's duty cycle or pulse width; undo when a pulse no longer fits.
        let compares = [after.compare(outs[0]), after.compare(outs[1])];
        let [Some(a), Some(b)] = compares else {
            let old_hz = before.tick_num / u64::from(before.counts.max(1));
            unit.set_frequency(u32::try_from(old_hz).unwrap_or(u32::from(DEFAULT_HZ)));
            return Err(PortError::Unsupported);
        };
        unit.set_compare(Pin::A, a);
        unit.set_compare(Pin::B, b);
        Ok(())
    }

    async fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        self.set_output(pin, Output::PulseUs(us)).await
    }

    async fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        let sensor = match port.kind() {
            PortKind::Sensor => self
                .sensors
                .get(usize::from(port.index()))
                .ok_or(PortError::NoSuchPin)?,
            PortKind::Actuator => return Err(PortError::Unsupported),
        };
        let mut ch = sensor.analog.lock().await;
        let mut adc = self.adc.lock().await;
        // A blocking conversion: 47.5 + 12.5 ADC cycles at 170 MHz / 4 (the driver's
        // prescaler), under 2 µs.
        Ok(adc.blocking_read(&mut *ch, SampleTime::CYCLES47_5))
    }

    /// Samples the pin in a loop, yielding to the other tasks between samples, and lets
    /// [`PulseIn`] decide; the resolution is the loop's period (a few µs when the other tasks
    /// are idle).
    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        let mut f = self.digital(pin)?.try_lock().map_err(|_| PortError::Busy)?;
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
}

#[cfg(feature = "motherboard")]
use embassy_stm32::Peripherals;

#[cfg(feature = "motherboard")]
motherboard_starter!(ports: G431Ports, bus: G431Bus, kind: x10_microcode::BoardKind::G431, name: "STM32G431");
