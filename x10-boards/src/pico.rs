//! Raspberry Pi Pico (RP2040, embassy-rp): bus, ports and start-up, built from
//! [`pins::PICO`](crate::pins::PICO)'s table.
//!
//! * [`PicoBus`]: the RP2040 I2C block is a controller or a target, never both. The adapter
//!   keeps the block and its pins and builds whichever driver the call needs: `write` and
//!   `write_read` run on an `i2c::I2c`, `listen` and `respond` on an `i2c_slave::I2cSlave`.
//!   Building a driver resets the block, so it switches only while the bus is idle for this
//!   node (no target activity, nothing received and unread, no read request pending);
//!   otherwise `write` fails at once with [`BusError::ArbitrationLost`] and the runtime
//!   listens, then retries with its backoff. While it is a controller the node NACKs its own
//!   address: the other side retries too. `addressed` arms the target and polls its state
//!   (address matched and active, bytes received, or a read request) every
//!   [`ADDRESSED_POLL_US`] without reading anything, so dropping it loses nothing; `listen`
//!   then drains the transfer with embassy-rp's `I2cSlave::listen` (never raced by the
//!   runtimes: the bytes it has drained live in its locals).
//! * [`PicoPorts`]: digital pins are `Flex` pins (input with pull-down, or output), PWM pins are
//!   channels A/B of one slice per actuator port, analog inputs are ADC0–ADC2, pulse-in uses the
//!   GPIO edge interrupts.

/// The HAL, for the images' `main`.
pub use embassy_rp as hal;
use embassy_rp::gpio::{Flex, Input, Pull};
use embassy_rp::{adc, bind_interrupts, i2c, i2c_slave, pac, peripherals, pwm, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::mutex::{Mutex, MutexGuard};
use embassy_time::{with_deadline, with_timeout, Duration, Instant, Timer};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::ports::{PortError, Ports};
use x10_microcode::{Edge, Level, PinRef, Port};

use crate::pins::PICO;
use crate::pwm::{rp2040_slice, Output, SliceTiming, Timebase, DEFAULT_HZ};
use crate::{address, port_lookup, BusConfig, RX_LEN};

bind_interrupts!(
    /// The interrupts the Pico images use: the bus's I2C block and the ADC.
    pub struct Irqs {
        I2C0_IRQ => i2c::InterruptHandler<peripherals::I2C0>;
        ADC_IRQ_FIFO => adc::InterruptHandler;
    }
);

/// Number of sensor ports ([`PICO`]).
pub const SENSORS: usize = PICO.sensors.len();
/// Number of actuator ports ([`PICO`]).
pub const ACTUATORS: usize = PICO.actuators.len();
/// Number of address-select jumpers ([`PICO`]).
pub const JUMPERS: usize = PICO.jumpers.len();

/// ADC resolution of the RP2040.
pub const ADC_BITS: u8 = 12;

type Lock<T> = Mutex<CriticalSectionRawMutex, T>;
/// A digital pin, taken.
type PinGuard<'a> = MutexGuard<'a, CriticalSectionRawMutex, Flex<'static>>;

/// Starts the HAL: clocks from the Pico's 12 MHz crystal (125 MHz system clock), time driver.
pub fn init() -> embassy_rp::Peripherals {
    embassy_rp::init(Default::default())
}

/// Everything the table names, taken from the HAL.
pub struct Board {
    /// The bus (not yet listening: it becomes a target on the first `listen`).
    pub bus: PicoBus,
    /// The ports (actuators in their safe state: digital low, PWM off).
    pub ports: PicoPorts,
    /// The value of the address-select jumpers read at start-up (fitted = 1, bit 0 first).
    pub jumpers: u8,
}

macro_rules! pico_build {
    (
        board: $board:literal,
        i2c: $i2c:ident { sda: $sda:ident, scl: $scl:ident },
        sensors: [ $( ($sa:ident, $sb:ident, $san:ident) ),* $(,)? ],
        actuators: [ $( ($slice:ident, $pa:ident, $pb:ident, $da:ident, $db:ident) ),* $(,)? ],
        jumpers: [ $( $j:ident ),* $(,)? ] $(,)?
    ) => {
        /// The I2C block of the bus.
        pub type I2cBlock = peripherals::$i2c;
        type SdaPin = peripherals::$sda;
        type SclPin = peripherals::$scl;

        fn i2c_regs() -> pac::i2c::I2c {
            pac::$i2c
        }

        impl Board {
            /// Takes the table's peripherals: reads the jumpers, builds the ports in their
            /// safe state and the bus adapter.
            ///
            /// `bus` gets the jumper value and returns the bus setup (the node's own address
            /// may depend on the jumpers).
            pub fn new(p: embassy_rp::Peripherals, bus: impl FnOnce(u8) -> BusConfig) -> Board {
                // Inputs only while they are read; dropped, the pins are disconnected again.
                let jumpers = {
                    let inputs: [Input<'static>; JUMPERS] = [ $( Input::new(p.$j, Pull::Up) ),* ];
                    // Let the pull-ups (about 50 kΩ against the pins' capacitance) settle: 10 µs.
                    cortex_m::asm::delay(embassy_rp::clocks::clk_sys_freq() / 100_000);
                    address::jumper_value(inputs.iter().map(|i| i.is_high()))
                };

                let bus = bus(jumpers);
                let sys_hz = embassy_rp::clocks::clk_sys_freq();
                let adc = adc::Adc::new(p.ADC, Irqs, adc::Config::default());
                let sensors = [ $( SensorPort {
                    pins: [Lock::new(input(p.$sa.into())), Lock::new(input(p.$sb.into()))],
                    analog: Lock::new(adc::Channel::new_pin(p.$san, Pull::None)),
                } ),* ];
                let actuators = [ $( ActuatorPort {
                    pins: [Lock::new(output_low(p.$da.into())), Lock::new(output_low(p.$db.into()))],
                    pwm: Lock::new(PwmUnit::new(sys_hz, |cfg| {
                        pwm::Pwm::new_output_ab(p.$slice, p.$pa, p.$pb, cfg)
                    })),
                } ),* ];
                Board {
                    bus: PicoBus {
                        i2c: p.$i2c,
                        sda: p.$sda,
                        scl: p.$scl,
                        config: bus,
                        controller: None,
                        target: None,
                        controller_clean: true,
                        target_clean: true,
                    },
                    ports: PicoPorts {
                        adc: Lock::new(adc),
                        sensors,
                        actuators,
                    },
                    jumpers,
                }
            }
        }
    };
}

pico_table!(pico_build);

fn input(pin: Peri<'static, embassy_rp::gpio::AnyPin>) -> Flex<'static> {
    let mut f = Flex::new(pin);
    f.set_pull(Pull::Down);
    f.set_as_input();
    f
}

fn output_low(pin: Peri<'static, embassy_rp::gpio::AnyPin>) -> Flex<'static> {
    let mut f = Flex::new(pin);
    f.set_low();
    f.set_as_output();
    f
}

// ---------------------------------------------------------------------------------------
// Bus
// ---------------------------------------------------------------------------------------

/// [`MultiMaster`] on the RP2040's I2C block, switching roles (see the module doc).
///
/// At most one of `controller` and `target` is `Some`: the driver of the current role.
pub struct PicoBus {
    i2c: Peri<'static, I2cBlock>,
    sda: Peri<'static, SdaPin>,
    scl: Peri<'static, SclPin>,
    config: BusConfig,
    controller: Option<i2c::I2c<'static, I2cBlock, i2c::Async>>,
    target: Option<i2c_slave::I2cSlave<'static, I2cBlock>>,
    /// False while a controller transaction is in flight: still false on the next call means
    /// its future was dropped half-way, and the block is rebuilt (reset) before use.
    controller_clean: bool,
    /// The same for an answer to a read.
    target_clean: bool,
}

impl PicoBus {
    /// The block and its pins, for the one driver about to be built.
    ///
    /// Sound because `self` owns the only handles to the three peripherals (moved in by
    /// [`Board::new`]), every caller drops the other role's driver first, and the copies are
    /// handed to at most one driver; the drivers hold no borrowed data (their lifetime is a
    /// marker), and an unused copy does nothing when dropped.
    #[allow(unsafe_code)]
    fn parts(
        &self,
    ) -> (
        Peri<'static, I2cBlock>,
        Peri<'static, SclPin>,
        Peri<'static, SdaPin>,
    ) {
        // SAFETY: see above; `Peri::clone_unchecked` only requires that one copy is in use.
        unsafe {
            (
                self.i2c.clone_unchecked(),
                self.scl.clone_unchecked(),
                self.sda.clone_unchecked(),
            )
        }
    }

    fn timeout(&self) -> Duration {
        Duration::from_micros(u64::from(self.config.timeout_us))
    }

    /// True when the target side is busy or holds something: being addressed right now,
    /// received bytes not yet read, or a read request waiting for an answer. Switching to
    /// controller would reset the block and lose them.
    fn target_busy() -> bool {
        let r = i2c_regs();
        let status = r.ic_status().read();
        let raw = r.ic_raw_intr_stat().read();
        status.slv_activity() || status.rfne() || raw.rd_req()
    }

    /// The controller driver, built if needed, marked as in use until [`PicoBus::finish`].
    fn controller(&mut self) -> Result<&mut i2c::I2c<'static, I2cBlock, i2c::Async>, BusError> {
        if self.target.is_some() {
            if Self::target_busy() {
                return Err(BusError::ArbitrationLost);
            }
            self.target = None;
        }
        if !self.controller_clean {
            self.controller = None;
        }
        let (i2c, scl, sda) = self.parts();
        let mut cfg = i2c::Config::default();
        cfg.frequency = self.config.frequency_hz;
        self.controller_clean = false;
        Ok(self
            .controller
            .get_or_insert_with(|| i2c::I2c::new_async(i2c, scl, sda, Irqs, cfg)))
    }

    /// The target driver, built if needed (the controller is idle between calls).
    fn target(&mut self) -> &mut i2c_slave::I2cSlave<'static, I2cBlock> {
        self.controller = None;
        if !self.target_clean {
            self.target = None;
            self.target_clean = true;
        }
        let (i2c, scl, sda) = self.parts();
        let mut cfg = i2c_slave::Config::default();
        cfg.addr = u16::from(self.config.own_address);
        cfg.general_call = false;
        self.target
            .get_or_insert_with(|| i2c_slave::I2cSlave::new(i2c, scl, sda, Irqs, cfg))
    }

    /// Finishes a controller transaction: on a timeout the driver is dropped, so the next
    /// one starts from a reset block.
    fn finish(
        &mut self,
        r: Result<Result<(), i2c::Error>, embassy_time::TimeoutError>,
    ) -> Result<(), BusError> {
        self.controller_clean = true;
        match r {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => Err(controller_error(e)),
            Err(_) => {
                self.controller = None;
                Err(BusError::Timeout)
            }
        }
    }
}

fn controller_error(e: i2c::Error) -> BusError {
    match e {
        i2c::Error::Abort(i2c::AbortReason::NoAcknowledge) => BusError::Nack,
        i2c::Error::Abort(i2c::AbortReason::ArbitrationLoss) => BusError::ArbitrationLost,
        _ => BusError::Bus,
    }
}

/// How often [`PicoBus`]'s `addressed` looks at the target side, in µs. The block ACKs its
/// address and fills its 16-byte receive FIFO by itself (then stretches SCL), so a match is
/// never missed; this only bounds the delay before the transfer is drained (16 bytes take
/// 1.4 ms at 100 kHz, 360 µs at 400 kHz).
pub const ADDRESSED_POLL_US: u64 = 20;

impl MultiMaster for PicoBus {
    /// # Errors
    /// As the trait; also [`BusError::ArbitrationLost`] when the target side is busy (see the
    /// module doc) and [`BusError::Bus`] for an empty write, which the block cannot send.
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        if bytes.is_empty() {
            return Err(BusError::Bus);
        }
        let timeout = self.timeout();
        let c = self.controller()?;
        let r = with_timeout(timeout, c.write_async(addr, bytes.iter().copied())).await;
        self.finish(r)
    }

    /// # Errors
    /// As [`PicoBus::write`]; an empty `read` is [`BusError::Bus`].
    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        if bytes.is_empty() || read.is_empty() {
            return Err(BusError::Bus);
        }
        let timeout = self.timeout();
        let c = self.controller()?;
        let r = with_timeout(
            timeout,
            c.write_read_async(addr, bytes.iter().copied(), read),
        )
        .await;
        self.finish(r)
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        // Armed once; an armed target is not rebuilt, so nothing it received is reset.
        self.target();
        while !Self::target_busy() {
            Timer::after_micros(ADDRESSED_POLL_US).await;
        }
        Ok(())
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let mut rx = [0u8; RX_LEN];
        let t = self.target();
        loop {
            let n = match t.listen(&mut rx).await {
                Ok(i2c_slave::Command::Read) => return Ok(Incoming::Read),
                Ok(i2c_slave::Command::Write(n)) => Incoming::Write(n),
                Ok(i2c_slave::Command::WriteRead(n)) => Incoming::WriteRead(n),
                // General calls are not enabled; should one be reported, it is not for us.
                Ok(i2c_slave::Command::GeneralCall(_)) => continue,
                Err(i2c_slave::Error::PartialWrite(_)) => return Err(BusError::Overrun),
                Err(i2c_slave::Error::PartialGeneralCall(_)) => continue,
                Err(_) => return Err(BusError::Bus),
            };
            let len = match n {
                Incoming::Write(n) | Incoming::WriteRead(n) => n,
                Incoming::Read => 0,
            };
            let (Some(dst), Some(src)) = (buf.get_mut(..len), rx.get(..len)) else {
                return Err(BusError::Overrun);
            };
            dst.copy_from_slice(src);
            return Ok(n);
        }
    }

    /// # Errors
    /// [`BusError::Bus`] when no read is waiting (`listen` did not just report one) or the
    /// block aborted; [`BusError::Timeout`] when the controller stopped clocking.
    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let timeout = self.timeout();
        // Set again when the answer completes; a dropped future or a failure leaves it false,
        // and the block is reset before the next listen.
        self.target_clean = false;
        let Some(t) = self.target.as_mut() else {
            return Err(BusError::Bus);
        };
        let fut = async {
            if bytes.is_empty() {
                t.respond_till_stop(0xFF).await
            } else {
                t.respond_and_fill(bytes, 0xFF).await.map(|_| ())
            }
        };
        let r = with_timeout(timeout, fut).await;
        match r {
            Ok(Ok(())) => {
                self.target_clean = true;
                Ok(())
            }
            Ok(Err(_)) => Err(BusError::Bus),
            Err(_) => Err(BusError::Timeout),
        }
    }
}

// ---------------------------------------------------------------------------------------
// Ports
// ---------------------------------------------------------------------------------------

struct SensorPort {
    pins: [Lock<Flex<'static>>; 2],
    analog: Lock<adc::Channel<'static>>,
}

struct ActuatorPort {
    pins: [Lock<Flex<'static>>; 2],
    pwm: Lock<PwmUnit>,
}

/// One PWM slice: its driver, its counter setup and what each channel was told.
struct PwmUnit {
    pwm: pwm::Pwm<'static>,
    sys_hz: u32,
    timing: SliceTiming,
    out: [Output; 2],
}

impl PwmUnit {
    fn new(sys_hz: u32, build: impl FnOnce(pwm::Config) -> pwm::Pwm<'static>) -> PwmUnit {
        // DEFAULT_HZ is reachable from any system clock between 2 MHz and 2 GHz.
        let timing = rp2040_slice(sys_hz, DEFAULT_HZ).unwrap_or(SliceTiming {
            div16: 16,
            top: 0xffff,
        });
        PwmUnit {
            pwm: build(slice_config(timing, 0, 0)),
            sys_hz,
            timing,
            out: [Output::OFF; 2],
        }
    }

    fn timebase(&self, timing: SliceTiming) -> Timebase {
        Timebase::rp2040(self.sys_hz, timing)
    }

    /// Writes `timing` and `out` to the slice, or changes nothing when an output does not
    /// fit the period.
    fn apply(&mut self, timing: SliceTiming, out: [Output; 2]) -> Result<(), PortError> {
        let tb = self.timebase(timing);
        let a = tb.compare(out[0]).ok_or(PortError::Unsupported)?;
        let b = tb.compare(out[1]).ok_or(PortError::Unsupported)?;
        let (a, b) = (
            u16::try_from(a).unwrap_or(u16::MAX),
            u16::try_from(b).unwrap_or(u16::MAX),
        );
        self.pwm.set_config(&slice_config(timing, a, b));
        self.timing = timing;
        self.out = out;
        Ok(())
    }
}

fn slice_config(t: SliceTiming, a: u16, b: u16) -> pwm::Config {
    let mut c = pwm::Config::default();
    c.divider = fixed::FixedU16::from_bits(t.div16);
    c.top = t.top;
    c.compare_a = a;
    c.compare_b = b;
    c.enable = true;
    c
}

/// [`Ports`] on the Pico's pins ([`PICO`]).
///
/// Each pin is behind its own async mutex: a pulse-in holds its pin for the whole
/// measurement, and any other operation on that pin meanwhile answers [`PortError::Busy`].
pub struct PicoPorts {
    adc: Lock<adc::Adc<'static, adc::Async>>,
    sensors: [SensorPort; SENSORS],
    actuators: [ActuatorPort; ACTUATORS],
}

impl PicoPorts {
    /// The digital pin `pin`, unless a pulse-in holds it ([`PortError::Busy`]).
    fn digital(&self, pin: PinRef) -> Result<PinGuard<'_>, PortError> {
        let lock = port_lookup::digital(
            &self.sensors,
            &self.actuators,
            pin,
            |s| &s.pins,
            |a| &a.pins,
        )?;
        lock.try_lock().map_err(|_| PortError::Busy)
    }

    fn pwm(&self, port: Port) -> Result<&Lock<PwmUnit>, PortError> {
        port_lookup::actuator(&self.actuators, port).map(|a| &a.pwm)
    }
}

impl Ports for PicoPorts {
    fn sensor_ports(&self) -> u8 {
        PICO.sensor_ports()
    }

    fn actuator_ports(&self) -> u8 {
        PICO.actuator_ports()
    }

    fn adc_bits(&self) -> u8 {
        ADC_BITS
    }

    async fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        let mut f = self.digital(pin)?;
        f.set_as_input();
        Ok(Level::from_bool(f.is_high()))
    }

    async fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        let mut f = self.digital(pin)?;
        f.set_level(level.is_high().into());
        f.set_as_output();
        Ok(())
    }

    async fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        let mut u = self.pwm(pin.port)?.lock().await;
        let mut out = u.out;
        out[pin.pin.index()] = Output::Duty(duty);
        let timing = u.timing;
        u.apply(timing, out)
    }

    async fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        let mut u = self.pwm(port)?.lock().await;
        let timing = rp2040_slice(u.sys_hz, hz).ok_or(PortError::Unsupported)?;
        let out = u.out;
        u.apply(timing, out)
    }

    async fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        let mut u = self.pwm(pin.port)?.lock().await;
        let mut out = u.out;
        out[pin.pin.index()] = Output::PulseUs(us);
        let timing = u.timing;
        u.apply(timing, out)
    }

    /// # Errors
    /// As the trait; a conversion the ADC flags as bad is answered [`PortError::Busy`] (worth
    /// a retry).
    async fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        let sensor = port_lookup::sensor(&self.sensors, port)?;
        let mut ch = sensor.analog.lock().await;
        let mut adc = self.adc.lock().await;
        adc.read(&mut ch).await.map_err(|_| PortError::Busy)
    }

    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        let mut f = self.digital(pin)?;
        f.set_as_input();
        let deadline = Instant::now() + Duration::from_millis(u64::from(timeout_ms));
        let measure = async {
            // An edge, not a level: a pin already in the pulse waits for the next one.
            match edge {
                Edge::Rising => f.wait_for_rising_edge().await,
                Edge::Falling => f.wait_for_falling_edge().await,
            }
            let start = Instant::now();
            match edge {
                Edge::Rising => f.wait_for_falling_edge().await,
                Edge::Falling => f.wait_for_rising_edge().await,
            }
            start.elapsed().as_micros()
        };
        with_deadline(deadline, measure)
            .await
            .map(|us| u32::try_from(us).unwrap_or(u32::MAX))
            .map_err(|_| PortError::Timeout)
    }
}

#[cfg(feature = "motherboard")]
use embassy_rp::Peripherals;

#[cfg(feature = "motherboard")]
motherboard_starter!(ports: PicoPorts, bus: PicoBus, kind: x10_microcode::BoardKind::PICO, name: "Pico");
