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
//!   then drains the transfer from the RX FIFO itself, ending it by the block's marks
//!   ([`pico_rules::heard`]), never by `STOP_DET` (never raced by the runtimes: the bytes it
//!   has drained are in the caller's buffer). Before the block is reset to become a
//!   controller, the bus lines must have stayed high for two SCL periods
//!   ([`pico_rules::LineWatch`]).
//! * [`PicoPorts`]: digital pins are `Flex` pins (input with pull-down, or output), PWM pins are
//!   channels A/B of one slice per actuator port, analog inputs are ADC0–ADC2, pulse-in uses the
//!   GPIO edge interrupts.

use core::cell::Cell;
use core::pin::pin;
/// The HAL, for the images' `main`.
pub use embassy_rp as hal;

use embassy_futures::poll_once;
use embassy_rp::gpio::{Flex, Input, Pull};
use embassy_rp::{adc, bind_interrupts, i2c, i2c_slave, pac, peripherals, pwm, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex as BlockingMutex;
use embassy_time::{block_for, with_deadline, with_timeout, Duration, Instant, Timer};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::ports::{EdgeCount, PortError, Ports};
use x10_microcode::{Edge, Level, PinRef, Port};

use crate::pico_rules::{
    self, Activity, Controller, ControllerEnd, Heard, LineWatch, Lines, Listen, Recovery, ReplyEnd,
    Switch, Target,
};
use crate::pins::PICO;
use crate::pwm::{rp2040_slice, Output, SliceTiming, Timebase, DEFAULT_HZ};
use crate::{address, port_lookup, pulse, BusConfig};

bind_interrupts!(
    /// The interrupts the Pico images use: the bus's I2C block (the ADC is read blocking).
    pub struct Irqs {
        I2C0_IRQ => i2c::InterruptHandler<peripherals::I2C0>;
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

use crate::port_lookup::Lock;
/// A digital pin, taken.
type PinGuard<'a> = port_lookup::Guard<'a, Flex<'static>>;

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
    /// The USB device block (the motherboard images' USB link).
    #[cfg(feature = "usb-link")]
    pub usb: Peri<'static, peripherals::USB>,
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
            /// `bus` gets the jumper value and the flash (for the address record and the
            /// unique ID, [`address_record`]) and returns the bus setup (the node's own
            /// address may depend on both).
            pub fn new(
                p: embassy_rp::Peripherals,
                bus: impl FnOnce(u8, Peri<'static, peripherals::FLASH>) -> BusConfig,
            ) -> Board {
                // Inputs only while they are read; dropped, the pins are disconnected again.
                let jumpers = {
                    let inputs: [Input<'static>; JUMPERS] = [ $( Input::new(p.$j, Pull::Up) ),* ];
                    // Let the pull-ups (about 50 kΩ against the pins' capacitance) settle: 10 µs.
                    cortex_m::asm::delay(embassy_rp::clocks::clk_sys_freq() / 100_000);
                    address::jumper_value(inputs.iter().map(|i| i.is_high()))
                };

                let bus = bus(jumpers, p.FLASH);
                let sys_hz = embassy_rp::clocks::clk_sys_freq();
                let adc = adc::Adc::new_blocking(p.ADC, adc::Config::default());
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
                    #[cfg(feature = "usb-link")]
                    usb: p.USB,
                    bus: PicoBus {
                        i2c: p.$i2c,
                        sda: p.$sda,
                        scl: p.$scl,
                        config: bus,
                        controller: None,
                        target: None,
                        controller_clean: true,
                        target_clean: true,
                        activity: Activity::default(),
                        kept: None,
                        sda_hold: pico_rules::sda_tx_hold(
                            embassy_rp::clocks::clk_peri_freq(),
                            bus.frequency_hz,
                        ),
                    },
                    ports: PicoPorts {
                        adc: Lock::new(adc),
                        sensors,
                        actuators,
                        latches: BlockingMutex::new(Cell::new(Latches {
                            pins: 0,
                            kept: [EdgeCount::NONE; 30],
                        })),
                    },
                    jumpers,
                }
            }
        }
    };
}

pico_table!(pico_build);

// ---------------------------------------------------------------------------------------
// Flash
// ---------------------------------------------------------------------------------------

/// The RP2040's flash (the Pico's 2 MiB), blocking, our own driver: each erase, program and
/// unique-ID read runs [`run_in_ram`], a routine in RAM that calls the boot ROM's flash
/// functions with interrupts off, then enters XIP again through a copy of the image's boot2,
/// the sequence of embassy-rp 0.10's `ram_helpers` (`src/flash.rs` 460-640), without its
/// `Flash` (the page padding in one path, no core 1 pause: no image of ours starts core 1;
/// no DMA wait: no DMA channel of ours reads flash). Its decisions (the ROM codes, bounds,
/// the pages a write programs, the unique-ID command) are `crate::rp_flash`'s, tested on the
/// host. Reads come from the XIP window.
pub struct PicoFlash {
    _flash: Peri<'static, peripherals::FLASH>,
}

/// The ROM's functions and the arguments of one flash operation, for [`run_in_ram`] (its
/// field offsets are the routine's: `repr(C)`, one word each).
#[repr(C)]
struct RamRun {
    connect: usize,
    exit_xip: usize,
    /// The operation: a ROM function or [`ssi_exchange`], called with `args`.
    op: usize,
    flush_cache: usize,
    /// The boot2 copy's address with the Thumb bit.
    enter_xip: usize,
    args: [usize; 4],
}

/// Calls, in order: `connect_internal_flash`, `flash_exit_xip`, the operation with its four
/// arguments, `flash_flush_cache` and the boot2 copy (which sets the SSI up for XIP again and
/// returns to its caller). It runs from RAM (`.data`, copied there by cortex-m-rt): nothing
/// in it may touch the flash while XIP is off, so it is written in assembly (no call the
/// compiler might add, no literal pool).
#[allow(unsafe_code)]
#[unsafe(naked)]
#[unsafe(link_section = ".data.ram_func")]
unsafe extern "C" fn run_in_ram(_run: *const RamRun) {
    core::arch::naked_asm!(
        "push {{r4, lr}}",
        "mov r4, r0",
        "ldr r0, [r4, #0]",
        "blx r0", // connect_internal_flash()
        "ldr r0, [r4, #4]",
        "blx r0", // flash_exit_xip()
        "ldr r0, [r4, #8]",
        "mov r12, r0",
        "ldr r0, [r4, #20]",
        "ldr r1, [r4, #24]",
        "ldr r2, [r4, #28]",
        "ldr r3, [r4, #32]",
        "blx r12", // the operation
        "ldr r0, [r4, #12]",
        "blx r0", // flash_flush_cache()
        "ldr r0, [r4, #16]",
        "blx r0", // boot2: XIP again
        "pop {{r4, pc}}",
    );
}

/// `ssi_exchange(buf, len, ssi, ss_ctrl)`: with the flash's chip select forced low
/// (`IO_QSPI` `GPIO_QSPI_SS_CTRL.OUTOVER`, at `ss_ctrl`), sends the `len` bytes of `buf`
/// through the SSI at `ssi` (`DR0`, 0x60; the ROM's `flash_exit_xip` left it in transfer
/// mode 0 with 8-bit frames, so it receives one byte for each byte sent) and puts the bytes
/// received in their place (waiting on `SR.RFNE`, 0x28 bit 3), then releases the chip
/// select. `len` is at most 16, the FIFOs' depth. From RAM, as [`run_in_ram`].
#[allow(unsafe_code)]
#[unsafe(naked)]
#[unsafe(link_section = ".data.ram_func")]
unsafe extern "C" fn ssi_exchange(_buf: *mut u8, _len: usize, _ssi: usize, _ss_ctrl: usize) {
    core::arch::naked_asm!(
        "push {{r4, r5, r6, lr}}",
        "movs r4, #2",
        "lsls r4, r4, #8",
        "str r4, [r3]", // OUTOVER = low
        "mov r5, r0",
        "mov r6, r1",
        "1:",
        "ldrb r4, [r5]",
        "str r4, [r2, #0x60]", // DR0
        "adds r5, #1",
        "subs r6, #1",
        "bne 1b",
        "mov r5, r0",
        "mov r6, r1",
        "2:",
        "ldr r4, [r2, #0x28]", // SR
        "lsls r4, r4, #28",    // RFNE (bit 3) to N
        "bpl 2b",
        "ldr r4, [r2, #0x60]",
        "strb r4, [r5]",
        "adds r5, #1",
        "subs r6, #1",
        "bne 2b",
        "movs r4, #3",
        "lsls r4, r4, #8",
        "str r4, [r3]", // OUTOVER = high
        "pop {{r4, r5, r6, pc}}",
    );
}

/// The SSI (`XIP_SSI`, datasheet §4.10.13).
const SSI_BASE: usize = 0x1800_0000;
/// `IO_QSPI`'s `GPIO_QSPI_SS_CTRL` (datasheet §2.19.6.2).
const QSPI_SS_CTRL: usize = 0x4001_800C;

/// The boot ROM's function `code` (datasheet §2.8.3: `rom_table_lookup`, its address in the
/// half-word at 0x18, with the function table's, the half-word at 0x14).
#[allow(unsafe_code)]
#[inline(never)]
fn rom_function(code: u16) -> usize {
    // SAFETY: the ROM is mapped at 0 and never changes; the two half-words and the lookup
    // routine are there on every RP2040 (datasheet §2.8.3), which takes the table and the
    // code and returns the function's address.
    unsafe {
        let lookup: unsafe extern "C" fn(*const u16, u32) -> usize =
            core::mem::transmute(usize::from(core::ptr::read_volatile(0x18 as *const u16)));
        let table = usize::from(core::ptr::read_volatile(0x14 as *const u16)) as *const u16;
        lookup(table, u32::from(code))
    }
}

impl PicoFlash {
    /// The driver, owning the flash.
    pub fn new(flash: Peri<'static, peripherals::FLASH>) -> Self {
        PicoFlash { _flash: flash }
    }

    /// Runs `op` (a ROM function or [`ssi_exchange`]) with `args` through [`run_in_ram`],
    /// interrupts off.
    #[allow(unsafe_code)]
    fn run(&mut self, op: usize, args: [usize; 4]) {
        use crate::rp_flash as f;
        // The image's boot2 (the first 256 bytes of flash), copied while XIP still works
        // (uninitialised before: no zeroing to pay for).
        let mut boot2 = core::mem::MaybeUninit::<[u32; 64]>::uninit();
        // SAFETY: the XIP window is mapped and readable, 256 bytes from its start; `boot2`
        // is 256 bytes of RAM.
        unsafe {
            core::ptr::copy_nonoverlapping(f::XIP_BASE as *const u32, boot2.as_mut_ptr().cast(), 64)
        };
        let run = RamRun {
            connect: rom_function(f::CONNECT_INTERNAL_FLASH),
            exit_xip: rom_function(f::FLASH_EXIT_XIP),
            op,
            flush_cache: rom_function(f::FLASH_FLUSH_CACHE),
            enter_xip: boot2.as_ptr() as usize | 1,
            args,
        };
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        // SAFETY: `&mut self` owns the flash; with interrupts off nothing else runs (core 1
        // is never started, no DMA channel reads flash), so nothing fetches from flash while
        // XIP is off; the routine, the boot2 copy and every buffer are in RAM.
        cortex_m::interrupt::free(|_| unsafe { run_in_ram(&run) });
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
    }

    /// The flash chip's 64-bit unique ID (command 0x4B).
    pub fn unique_id(&mut self) -> [u8; 8] {
        let mut buf = crate::rp_flash::UNIQUE_ID_COMMAND;
        let exchange: unsafe extern "C" fn(*mut u8, usize, usize, usize) = ssi_exchange;
        self.run(
            exchange as usize,
            [buf.as_mut_ptr() as usize, buf.len(), SSI_BASE, QSPI_SS_CTRL],
        );
        crate::rp_flash::unique_id(&buf)
    }
}

impl embedded_storage::nor_flash::ErrorType for PicoFlash {
    type Error = embedded_storage::nor_flash::NorFlashErrorKind;
}

impl embedded_storage::nor_flash::ReadNorFlash for PicoFlash {
    const READ_SIZE: usize = 1;

    #[allow(unsafe_code)]
    #[inline(never)]
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = crate::rp_flash::read_address(offset, bytes.len(), crate::record::PICO_FLASH)?;
        // SAFETY: the range lies within the XIP window of the flash (checked above).
        let flash = unsafe { core::slice::from_raw_parts(at as *const u8, bytes.len()) };
        bytes.copy_from_slice(flash);
        Ok(())
    }

    fn capacity(&self) -> usize {
        crate::record::PICO_FLASH as usize
    }
}

impl embedded_storage::nor_flash::NorFlash for PicoFlash {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = crate::rp_flash::SECTOR as usize;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let (at, len) = crate::rp_flash::erase_range(from, to, crate::record::PICO_FLASH)?;
        if len > 0 {
            let erase = rom_function(crate::rp_flash::FLASH_RANGE_ERASE);
            let block = crate::rp_flash::ERASE_BLOCK_SIZE as usize;
            self.run(erase, [at as usize, len as usize, block, 0]);
        }
        Ok(())
    }

    #[allow(unsafe_code)]
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        use crate::rp_flash::PAGE;
        let program = rom_function(crate::rp_flash::FLASH_RANGE_PROGRAM);
        for w in crate::rp_flash::pages(offset, bytes.len(), crate::record::PICO_FLASH)? {
            // The page, 0xFF (left as it is) but for the bytes written. Filled by volatile
            // stores: a fill LLVM sees as one brings `memset` into the image (54 B).
            let mut page = core::mem::MaybeUninit::<[u8; PAGE as usize]>::uninit();
            let p: *mut u8 = page.as_mut_ptr().cast();
            for i in 0..PAGE as usize {
                // SAFETY: `i` is within the page buffer.
                unsafe { core::ptr::write_volatile(p.add(i), 0xFF) };
            }
            // SAFETY: every byte was written above.
            let mut page = unsafe { page.assume_init() };
            page[w.at..w.at + w.len].copy_from_slice(&bytes[w.from..w.from + w.len]);
            self.run(
                program,
                [w.page as usize, page.as_ptr() as usize, PAGE as usize, 0],
            );
        }
        Ok(())
    }
}

/// The Pico's address record: the last two 4 KiB sectors of its flash
/// ([`crate::record::PICO_RECORD_OFFSET`], outside the image's `FLASH` region).
///
/// # Errors
/// `x10_store`'s: the flash's read errors.
pub fn address_record(
    flash: PicoFlash,
) -> Result<x10_store::Record<PicoFlash>, x10_store::StoreError> {
    x10_store::Record::new(
        flash,
        crate::record::PICO_RECORD_OFFSET,
        crate::record::RECORD_PAGES,
    )
}

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
    /// How long the target has been active with nothing for this node (a controller gone
    /// without a STOP).
    activity: Activity,
    /// The first byte of the next transfer, taken from the RX FIFO while `listen` drained the
    /// one before it (see [`pico_rules::heard`]); the next `listen` starts with it.
    kept: Option<u8>,
    /// `IC_SDA_HOLD.IC_SDA_TX_HOLD` for the target ([`pico_rules::sda_tx_hold`]).
    sda_hold: u16,
}

/// The fill byte sent when the controller reads more than the reply holds.
const FILL: u8 = 0xFF;

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

    /// The target side's state (see [`pico_rules::Target`]).
    fn target_state(&self) -> Target {
        let r = i2c_regs();
        let status = r.ic_status().read();
        let raw = r.ic_raw_intr_stat().read();
        Target {
            slv_activity: status.slv_activity(),
            rfne: status.rfne(),
            rd_req: raw.rd_req(),
            kept: self.kept.is_some(),
        }
    }

    /// The controller driver, built if needed, marked as in use until [`PicoBus::finish`].
    fn controller(&mut self) -> Result<&mut i2c::I2c<'static, I2cBlock, i2c::Async>, BusError> {
        if self.target.is_some() {
            let now = Instant::now().as_micros();
            let stale = pico_rules::stale_activity_us(self.config.frequency_hz);
            // Being addressed, holding bytes or a read request: switching would reset the
            // block and lose them. Activity alone for four byte times: abandoned (no STOP).
            match self.activity.switch(now, self.target_state(), stale) {
                Switch::Refuse => return Err(BusError::ArbitrationLost),
                Switch::Now | Switch::Stale => {}
            }
        }
        if !self.controller_clean {
            self.controller = None;
        }
        if self.controller.is_none() {
            // The block is about to be reset, or was: it would not see a transfer already
            // under way (issue 21 item 3).
            self.lines_free()?;
        }
        self.target = None;
        let (i2c, scl, sda) = self.parts();
        let mut cfg = i2c::Config::default();
        cfg.frequency = self.config.frequency_hz;
        self.controller_clean = false;
        // A STOP_DET left by an earlier transfer (anyone's) would end the next one at once
        // (see `pico_rules::controller_end`).
        i2c_regs().ic_clr_stop_det().read();
        Ok(self
            .controller
            .get_or_insert_with(|| i2c::I2c::new_async(i2c, scl, sda, Irqs, cfg)))
    }

    /// Samples SCL and SDA until [`pico_rules::LineWatch`] decides: both high for two SCL
    /// periods, or a line held for four byte times (a stuck bus: the transfer's own timeout and
    /// bus clear deal with it). [`BusError::ArbitrationLost`] when a line moved: another
    /// master's transfer is under way. A synchronous wait of 20 µs at 100 kHz (2 µs at
    /// 1 MHz), sampling as fast as the core goes so that no SCL pulse is missed.
    #[inline(never)]
    fn lines_free(&self) -> Result<(), BusError> {
        let hz = self.config.frequency_hz;
        let window = pico_rules::idle_window_us(hz);
        let stuck = u32::try_from(pico_rules::stale_activity_us(hz)).unwrap_or(u32::MAX);
        // The low 32 bits of the µs clock: the watch uses differences only.
        let now = || Instant::now().as_micros() as u32;
        let (scl, sda) = bus_lines();
        let mut w = LineWatch::new(now(), scl, sda);
        loop {
            let (scl, sda) = bus_lines();
            match w.sample(now(), scl, sda, window, stuck) {
                None => {}
                Some(Lines::Active) => return Err(BusError::ArbitrationLost),
                Some(Lines::Free | Lines::Stuck) => return Ok(()),
            }
        }
    }

    /// The target driver, built if needed (the controller is idle between calls).
    fn target(&mut self) -> &mut i2c_slave::I2cSlave<'static, I2cBlock> {
        self.controller = None;
        if !self.target_clean {
            self.target = None;
            self.target_clean = true;
        }
        if self.target.is_none() {
            // A new driver resets the block: nothing of an earlier transfer is left.
            self.kept = None;
        }
        let (i2c, scl, sda) = self.parts();
        let mut cfg = i2c_slave::Config::default();
        cfg.addr = u16::from(self.config.own_address);
        // With `together`, general calls (a sweep's `sample`, an `apply`) reach the listener
        // as writes: IC_ACK_GENERAL_CALL (embassy-rp `i2c_slave.rs` 150-153; docs/boards.md).
        cfg.general_call = cfg!(feature = "together");
        let hold = self.sda_hold;
        self.target.get_or_insert_with(|| {
            let t = i2c_slave::I2cSlave::new(i2c, scl, sda, Irqs, cfg);
            set_sda_hold(hold);
            t
        })
    }

    /// Finishes a controller transaction (issue 11 item 5, Pico part).
    ///
    /// * After an abort the block sends a STOP by itself, but embassy-rp returns as soon as it
    ///   reads the abort inside `wait_stop_det` (`i2c.rs` 306-307), before that STOP: wait for
    ///   the controller to go idle, so that a role switch (a block reset) does not cut it and
    ///   leave the other nodes' targets active.
    /// * After a timeout the transfer is aborted (`IC_ENABLE.ABORT`: flush, then STOP) and the
    ///   driver dropped, so the next one starts from a reset block.
    /// * When the controller does not go idle within a few byte times, a line is held: the
    ///   block is dropped and the bus cleared by [`PicoBus::recover`] (nine SCL pulses, a
    ///   STOP); `Bus` when SDA stays low.
    async fn finish(
        &mut self,
        r: Result<Result<(), i2c::Error>, embassy_time::TimeoutError>,
    ) -> Result<(), BusError> {
        self.controller_clean = true;
        let err = match r {
            Ok(Ok(())) => match self.wait_own_end().await {
                Ok(()) => return Ok(()),
                Err(e) => e,
            },
            Ok(Err(i2c::Error::Abort(reason))) => abort_error(reason),
            Ok(Err(_)) => return Err(BusError::Bus),
            Err(_) => {
                i2c_regs().ic_enable().modify(|w| w.set_abort(true));
                BusError::Timeout
            }
        };
        // The block is dropped (reset) only once its STOP is out.
        let idle = self.wait_controller_idle().await;
        if err == BusError::Timeout {
            self.controller = None;
        }
        if !idle {
            self.recover()?;
        }
        Err(err)
    }

    /// After embassy-rp reported a transfer done: waits until it really is (see
    /// [`pico_rules::controller_end`]: a STOP of another controller, or one left from the
    /// target side, ends embassy-rp's wait early), then clears `STOP_DET`. The abort it ended
    /// with, or [`BusError::Timeout`] (the transfer aborted) when it is not over in time.
    async fn wait_own_end(&self) -> Result<(), BusError> {
        let r = i2c_regs();
        let deadline = Instant::now() + self.timeout();
        loop {
            let status = r.ic_status().read();
            let now = Controller {
                mst_activity: status.mst_activity(),
                tfe: status.tfe(),
                tx_abrt: r.ic_raw_intr_stat().read().tx_abrt(),
            };
            match pico_rules::controller_end(now) {
                ControllerEnd::Done => {
                    r.ic_clr_stop_det().read();
                    return Ok(());
                }
                ControllerEnd::Aborted => {
                    let source = r.ic_tx_abrt_source().read().0;
                    r.ic_clr_tx_abrt().read();
                    return Err(pico_rules::abort_error(source));
                }
                ControllerEnd::Wait => {}
            }
            if Instant::now() >= deadline {
                r.ic_enable().modify(|w| w.set_abort(true));
                return Err(BusError::Timeout);
            }
            Timer::after_micros(STOP_POLL_US).await;
        }
    }

    /// Waits up to four byte times for the controller state machine to go idle (its STOP
    /// sent), then clears `STOP_DET`. False when it stays active.
    async fn wait_controller_idle(&self) -> bool {
        let deadline = Instant::now()
            + Duration::from_micros(pico_rules::stale_activity_us(self.config.frequency_hz));
        let r = i2c_regs();
        loop {
            if !r.ic_status().read().mst_activity() {
                r.ic_clr_stop_det().read();
                return true;
            }
            if Instant::now() >= deadline {
                return false;
            }
            Timer::after_micros(STOP_POLL_US).await;
        }
    }

    /// The bus-clear procedure (UM10204 §3.1.16): with the block dropped and both pins as
    /// open-drain GPIOs, up to nine SCL pulses until SDA is released, then a STOP. The next
    /// driver built takes the pins back. [`BusError::Bus`] when SDA stays low.
    ///
    /// Not exercised by the emulator rig (its bus model does not drive the pins' GPIO input
    /// levels): verified by reading only.
    fn recover(&mut self) -> Result<(), BusError> {
        self.controller = None;
        self.target = None;
        self.target_clean = true;
        let half = Duration::from_micros(500_000 / u64::from(self.config.frequency_hz.max(1)) + 1);
        let mut scl = Flex::new(self.scl.reborrow());
        let mut sda = Flex::new(self.sda.reborrow());
        for p in [&mut scl, &mut sda] {
            p.set_pull(Pull::Up);
            p.set_low();
            p.set_as_input(); // released: the pull-ups hold the line high
        }
        block_for(half);
        let mut clocks = 0;
        loop {
            match pico_rules::recovery(sda.is_high(), clocks) {
                Recovery::Clock => {
                    scl.set_as_output();
                    block_for(half);
                    scl.set_as_input();
                    block_for(half);
                    clocks += 1;
                }
                Recovery::Stop => {
                    scl.set_as_output();
                    sda.set_as_output();
                    block_for(half);
                    scl.set_as_input();
                    block_for(half);
                    sda.set_as_input();
                    block_for(half);
                    return Ok(());
                }
                Recovery::GiveUp => return Err(BusError::Bus),
            }
        }
    }

    /// Answers a read (see [`MultiMaster::respond`]): never more bytes than the TX FIFO can
    /// take, fill bytes one at a time, then waits for the read's STOP and checks the block.
    async fn reply(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let r = i2c_regs();
        // A TX_ABRT left by a flush keeps the TX FIFO flushed and makes embassy-rp return
        // `LeftoverBytes` at once (`i2c_slave.rs` 311-316); a stale RX_DONE would end the
        // answer before its first byte.
        if r.ic_raw_intr_stat().read().tx_abrt() {
            r.ic_clr_tx_abrt().read();
        }
        r.ic_clr_rx_done().read();
        let Some(t) = self.target.as_mut() else {
            return Err(BusError::Bus);
        };
        let mut rest = bytes;
        let mut failed = false;
        loop {
            let n = pico_rules::tx_chunk(rest.len(), r.ic_txflr().read().txflr());
            let chunk: &[u8] = if rest.is_empty() {
                // The controller reads on: one fill byte per request, so that none is left
                // in the FIFO when it stops (issue 11 item 1).
                &[FILL]
            } else if n == 0 {
                // The FIFO is full (cannot happen after `NeedMoreBytes`): let it drain.
                Timer::after_micros(STOP_POLL_US).await;
                continue;
            } else {
                let (c, more) = rest.split_at(n);
                rest = more;
                c
            };
            match t.respond_to_read(chunk).await {
                Ok(i2c_slave::ReadStatus::NeedMoreBytes) => {}
                Ok(i2c_slave::ReadStatus::Done) => break,
                Ok(i2c_slave::ReadStatus::LeftoverBytes(_)) | Err(_) => {
                    failed = true;
                    break;
                }
            }
        }
        // The read ends with its STOP (or the next transfer); `STOP_DET` is left alone (see
        // `pico_rules::read_over`).
        while !pico_rules::read_over(self.target_state()) {
            Timer::after_micros(STOP_POLL_US).await;
        }
        let Some(t) = self.target.as_mut() else {
            return Err(BusError::Bus);
        };
        let end = ReplyEnd {
            txflr: r.ic_txflr().read().txflr(),
            tx_abrt: r.ic_raw_intr_stat().read().tx_abrt(),
        };
        if pico_rules::reset_after_reply(end) {
            t.reset();
            set_sda_hold(self.sda_hold);
        }
        if failed {
            Err(BusError::Bus)
        } else {
            Ok(())
        }
    }

    /// Drains one transfer to this node from the RX FIFO into `buf` and reports it (see
    /// [`pico_rules::heard`]): the transfer's end is told by the next transfer's marked first
    /// byte (kept for the next call), a read request, or the state machine going idle, never
    /// by `STOP_DET`. Replaces embassy-rp's `I2cSlave::listen`, which ends a write on
    /// `STOP_DET` and loses the second of two writes received before it looks (issue 21 item
    /// 5).
    ///
    /// [`BusError::Overrun`] when a write does not fit `buf` (its remaining bytes are read
    /// as the next transfer, which the frame checks reject).
    async fn drain(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let r = i2c_regs();
        let mut len = 0;
        let mut byte = self.kept.take();
        loop {
            // The read request first: it follows every byte of the write before it.
            let raw = r.ic_raw_intr_stat().read();
            let mut next = false;
            let status = loop {
                if let Some(b) = byte.take() {
                    *buf.get_mut(len).ok_or(BusError::Overrun)? = b;
                    len += 1;
                }
                let s = r.ic_status().read();
                if !s.rfne() {
                    break s;
                }
                let d = r.ic_data_cmd().read();
                if len > 0 && d.first_data_byte() {
                    self.kept = Some(d.dat());
                    next = true;
                    break s;
                }
                byte = Some(d.dat());
            };
            let l = Listen {
                len,
                next,
                rd_req: raw.rd_req(),
                restart_det: raw.restart_det(),
                slv_activity: status.slv_activity(),
            };
            match pico_rules::heard(l) {
                Heard::Wait => Timer::after_micros(STOP_POLL_US).await,
                Heard::Write => return Ok(Incoming::Write(len)),
                Heard::WriteRead => {
                    r.ic_clr_restart_det().read();
                    return Ok(Incoming::WriteRead(len));
                }
                Heard::Read => {
                    r.ic_clr_restart_det().read();
                    return Ok(Incoming::Read);
                }
            }
        }
    }
}

/// Sets the target's SDA hold time ([`pico_rules::sda_tx_hold`]) after embassy-rp's
/// `I2cSlave` reset the block, which leaves it at one clock. The register takes writes only
/// while the block is disabled: it is disabled for the write, within a microsecond of
/// embassy-rp enabling it (an address phase begun in that microsecond is not acknowledged,
/// as while the block was in reset, and its controller retries).
#[inline(never)]
fn set_sda_hold(hold: u16) {
    let r = i2c_regs();
    r.ic_enable().write(|w| w.set_enable(false));
    r.ic_sda_hold().modify(|w| w.set_ic_sda_tx_hold(hold));
    r.ic_enable().write(|w| w.set_enable(true));
}

fn abort_error(reason: i2c::AbortReason) -> BusError {
    match reason {
        i2c::AbortReason::NoAcknowledge => BusError::Nack,
        i2c::AbortReason::ArbitrationLoss => BusError::ArbitrationLost,
        i2c::AbortReason::Other(source) => pico_rules::abort_error(source),
        _ => BusError::Bus,
    }
}

/// How often the adapter looks at the block while waiting for a STOP, in µs.
const STOP_POLL_US: u64 = 5;

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
        self.finish(r).await
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
        self.finish(r).await
    }

    async fn read(&mut self, addr: u8, read: &mut [u8]) -> Result<(), BusError> {
        if read.is_empty() {
            return Err(BusError::Bus);
        }
        let timeout = self.timeout();
        let c = self.controller()?;
        let r = with_timeout(timeout, c.read_async(addr, read)).await;
        self.finish(r).await
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        // Armed once; an armed target is not rebuilt, so nothing it received is reset.
        self.target();
        // Only this node's own address match counts (issue 11 item 6, issue 16 defect 2).
        while !pico_rules::addressed(self.target_state()) {
            Timer::after_micros(ADDRESSED_POLL_US).await;
        }
        Ok(())
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let timeout = self.timeout();
        self.target();
        // A transfer that never ends (its controller gone without a STOP) must not hold the
        // node for ever: reset the block after the timeout.
        let r = with_timeout(timeout, self.drain(buf)).await;
        r.unwrap_or_else(|_| {
            self.target_clean = false;
            Err(BusError::Timeout)
        })
    }

    /// # Errors
    /// [`BusError::Bus`] when no read is waiting (`listen` did not just report one) or the
    /// block aborted; [`BusError::Timeout`] when the controller stopped clocking.
    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let timeout = self.timeout();
        if self.target.is_none() {
            return Err(BusError::Bus);
        }
        // Set again when the answer completes; a dropped future or a timeout leaves it false,
        // and the block is reset before the next listen.
        self.target_clean = false;
        let r = with_timeout(timeout, self.reply(bytes)).await;
        match r {
            Ok(r) => {
                self.target_clean = true;
                r
            }
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
/// measurement, and any other operation on that pin meanwhile answers [`PortError::Busy`], but
/// `digital_read`, which answers its level.
pub struct PicoPorts {
    adc: Lock<adc::Adc<'static, adc::Blocking>>,
    sensors: [SensorPort; SENSORS],
    actuators: [ActuatorPort; ACTUATORS],
    latches: BlockingMutex<CriticalSectionRawMutex, Cell<Latches>>,
}

/// Which GPIOs latch their edges ([`Ports::latch_edges`]), and the edges taken off a latch
/// that a pulse-in was about to clear, kept for the next [`Ports::take_edges`].
#[derive(Clone, Copy)]
struct Latches {
    pins: u32,
    kept: [EdgeCount; 30],
}

/// The GPIO number of a pin of the table; a name that is not one fails the build.
const fn gpio_of(name: &str) -> u8 {
    match pico_rules::gpio_number(name) {
        Some(n) => n,
        None => panic!("the Pico's pin table names a pin that is not PIN_0..PIN_29"),
    }
}

/// GPIO numbers of the digital pins A and B of each sensor port ([`PICO`]).
const SENSOR_GPIOS: [[u8; 2]; SENSORS] = {
    let mut t = [[0; 2]; SENSORS];
    let mut i = 0;
    while i < SENSORS {
        t[i] = [gpio_of(PICO.sensors[i].a), gpio_of(PICO.sensors[i].b)];
        i += 1;
    }
    t
};

/// GPIO numbers of the digital pins A and B of each actuator port ([`PICO`]).
const ACTUATOR_GPIOS: [[u8; 2]; ACTUATORS] = {
    let mut t = [[0; 2]; ACTUATORS];
    let mut i = 0;
    while i < ACTUATORS {
        t[i] = [gpio_of(PICO.actuators[i].a), gpio_of(PICO.actuators[i].b)];
        i += 1;
    }
    t
};

/// How often [`PicoPorts`]'s `wait_edge` looks at the edge latches, in µs. embassy-rp owns
/// the GPIO interrupt (`IO_IRQ_BANK0`) and wakes only its own pin futures, so the latches are
/// polled; an edge is reported to the runtime within this time.
const EDGE_POLL_US: u64 = 200;

/// The raw interrupt register (`IO_BANK0.INTRn`) holding `gpio`'s edge latches.
fn intr(gpio: u8) -> pac::common::Reg<pac::io::regs::Int, pac::common::RW> {
    pac::IO_BANK0.intr(pico_rules::intr_slot(gpio).0)
}

/// Takes the edges latched in hardware on `gpio` and clears exactly those.
fn take_latched(gpio: u8) -> EdgeCount {
    let reg = intr(gpio);
    let (n, clear) = pico_rules::latched_edges(reg.read().0, gpio);
    if clear != 0 {
        reg.write_value(pac::io::regs::Int(clear));
    }
    n
}

impl PicoPorts {
    /// The GPIO number of a digital pin, from the pin table.
    fn gpio(pin: PinRef) -> Result<u8, PortError> {
        port_lookup::digital(&SENSOR_GPIOS, &ACTUATOR_GPIOS, pin, |s| s, |a| a).copied()
    }

    /// Moves the edges latched on `gpio` into the kept counts (before a pulse-in's edge
    /// future clears the latch, `gpio.rs` 296-299), plus `extra`.
    fn keep(&self, gpio: u8, extra: EdgeCount) {
        self.latches.lock(|l| {
            let mut v = l.get();
            if v.pins & (1 << gpio) != 0 {
                if let Some(k) = v.kept.get_mut(usize::from(gpio)) {
                    *k = k.plus(take_latched(gpio)).plus(extra);
                }
                l.set(v);
            }
        });
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

    /// A pin held by a pulse-in (an input while it measures) answers its level, read from
    /// `SIO.GPIO_IN`, not [`PortError::Busy`]: the daughterboard's event sampler reads the
    /// level of a pin with events right after taking its edges, and drops them when the read
    /// fails.
    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        let high = match self.digital(pin) {
            Ok(mut f) => {
                f.set_as_input();
                f.is_high()
            }
            Err(PortError::Busy) => gpio_level(Self::gpio(pin)?),
            Err(e) => return Err(e),
        };
        Ok(Level::from_bool(high))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        let mut f = self.digital(pin)?;
        f.set_level(level.is_high().into());
        f.set_as_output();
        Ok(())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        let mut u = port_lookup::take(self.pwm(pin.port)?)?;
        let mut out = u.out;
        out[pin.pin.index()] = Output::Duty(duty);
        let timing = u.timing;
        u.apply(timing, out)
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        let mut u = port_lookup::take(self.pwm(port)?)?;
        let timing = rp2040_slice(u.sys_hz, hz).ok_or(PortError::Unsupported)?;
        let out = u.out;
        u.apply(timing, out)
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        let mut u = port_lookup::take(self.pwm(pin.port)?)?;
        let mut out = u.out;
        out[pin.pin.index()] = Output::PulseUs(us);
        let timing = u.timing;
        u.apply(timing, out)
    }

    /// # Errors
    /// As the trait; a conversion the ADC flags as bad is answered [`PortError::Busy`] (worth
    /// a retry).
    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        let sensor = port_lookup::sensor(&self.sensors, port)?;
        let mut ch = port_lookup::take(&sensor.analog)?;
        let mut adc = port_lookup::take(&self.adc)?;
        // A blocking conversion: 96 cycles of the 48 MHz ADC clock, 2 µs.
        adc.blocking_read(&mut ch).map_err(|_| PortError::Busy)
    }

    /// # Errors
    /// As the trait.
    ///
    /// Each edge is awaited with embassy-rp's pin future, which clears the pin's edge latch
    /// when it arms (`gpio.rs` 296-299): the latched edges of a pin with events are kept
    /// before each arming. The end edge's future is armed only when the pulse is not over yet
    /// (the pin's level), so a pulse that ends before the task wakes from its start is
    /// measured (as at most the wake-up time) instead of missed (issue 11 item 9), and both
    /// its edges stay in the latch; an end edge between that look and the arming is wiped by
    /// the arming and given back ([`pulse::wiped_end_edge`], issue 21 item 6). Afterwards the
    /// pin's edge interrupt is disarmed: a future dropped at the timeout leaves it armed
    /// otherwise, and the next pulse-in would wake on the wrong edge.
    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        let gpio = Self::gpio(pin)?;
        let mut f = self.digital(pin)?;
        f.set_as_input();
        self.keep(gpio, EdgeCount::NONE);
        let deadline = Instant::now() + Duration::from_millis(u64::from(timeout_ms));
        let mut wiped = EdgeCount::NONE;
        let measure = async {
            // An edge, not a level: a pin already in the pulse waits for the next one.
            match edge {
                Edge::Rising => f.wait_for_rising_edge().await,
                Edge::Falling => f.wait_for_falling_edge().await,
            }
            let start = Instant::now();
            let high_at_end = matches!(edge, Edge::Falling);
            if gpio_level(gpio) != high_at_end {
                // The start edge, before the arming wipes it.
                self.keep(gpio, EdgeCount::NONE);
                let mut end = pin!(async {
                    match edge {
                        Edge::Rising => f.wait_for_falling_edge().await,
                        Edge::Falling => f.wait_for_rising_edge().await,
                    }
                });
                // The first poll arms the future; then the level, then the latch.
                if poll_once(end.as_mut()).is_pending() {
                    let over = gpio_level(gpio) == high_at_end;
                    let (latched, _) = pico_rules::latched_edges(intr(gpio).read().0, gpio);
                    wiped = pulse::wiped_end_edge(edge, over, latched);
                    if !over {
                        end.await;
                    }
                }
            }
            start.elapsed().as_micros()
        };
        let r = with_deadline(deadline, measure).await;
        disarm(gpio);
        self.keep(gpio, wiped);
        r.map(|us| u32::try_from(us).unwrap_or(u32::MAX))
            .map_err(|_| PortError::Timeout)
    }

    /// Latches with `IO_BANK0.INTRn`'s raw edge bits, which the RP2040 sets on every edge of
    /// every GPIO whether or not its interrupt is enabled (datasheet §2.19.6.2): no edge is
    /// missed, several edges of one direction between two takes count as one.
    fn latch_edges(&self, pin: PinRef) -> Result<(), PortError> {
        let gpio = Self::gpio(pin)?;
        self.latches.lock(|l| {
            let mut v = l.get();
            take_latched(gpio);
            v.pins |= 1 << gpio;
            if let Some(k) = v.kept.get_mut(usize::from(gpio)) {
                *k = EdgeCount::NONE;
            }
            l.set(v);
        });
        Ok(())
    }

    fn take_edges(&self, pin: PinRef) -> Result<EdgeCount, PortError> {
        let gpio = Self::gpio(pin)?;
        self.latches.lock(|l| {
            let mut v = l.get();
            if v.pins & (1 << gpio) == 0 {
                return Err(PortError::Unsupported);
            }
            let kept = v
                .kept
                .get_mut(usize::from(gpio))
                .map_or(EdgeCount::NONE, |k| core::mem::replace(k, EdgeCount::NONE));
            l.set(v);
            Ok(kept.plus(take_latched(gpio)))
        })
    }

    async fn wait_edge(&self) {
        loop {
            let waiting = self.latches.lock(|l| {
                let v = l.get();
                v.kept.iter().any(|k| !k.is_none())
                    || (0..4).any(|reg| {
                        pac::IO_BANK0.intr(reg).read().0 & pico_rules::edge_mask(v.pins, reg) != 0
                    })
            });
            if waiting {
                return;
            }
            Timer::after_micros(EDGE_POLL_US).await;
        }
    }
}

/// GPIO numbers of the bus lines ([`PICO`]).
const SCL_GPIO: u8 = gpio_of(PICO.i2c.scl);
const SDA_GPIO: u8 = gpio_of(PICO.i2c.sda);

/// The bus lines' levels (SCL, SDA), from `SIO.GPIO_IN`: the pads' inputs stay enabled in
/// the I2C function (embassy-rp `i2c.rs` 380-389).
fn bus_lines() -> (bool, bool) {
    let v = pac::SIO.gpio_in(0).read();
    (v & (1 << SCL_GPIO) != 0, v & (1 << SDA_GPIO) != 0)
}

/// The input level of `gpio` (`SIO.GPIO_IN`), read without its pin driver.
fn gpio_level(gpio: u8) -> bool {
    pac::SIO.gpio_in(0).read() & (1 << gpio) != 0
}

/// Disarms `gpio`'s edge and level interrupts for core 0 (what embassy-rp's interrupt handler
/// does when one fires), in a critical section against that handler.
fn disarm(gpio: u8) {
    let (n, shift) = pico_rules::intr_slot(gpio);
    cortex_m::interrupt::free(|_| {
        pac::IO_BANK0
            .int_proc(0)
            .inte(n)
            .modify(|w| w.0 &= !(0xf << shift));
    });
}

#[cfg(feature = "motherboard")]
use embassy_rp::Peripherals;

#[cfg(feature = "motherboard")]
motherboard_starter!(ports: PicoPorts, bus: PicoBus, kind: x10_microcode::BoardKind::PICO, name: "Pico");

#[cfg(feature = "usb-link")]
bind_interrupts!(
    /// The USB device's interrupt (the motherboard images' USB link).
    struct UsbIrqs {
        USBCTRL_IRQ => embassy_rp::usb::InterruptHandler<peripherals::USB>;
    }
);

/// The USB link's task (`crate::usb_link`), spawned by `start_motherboard`.
#[cfg(feature = "usb-link")]
#[embassy_executor::task]
async fn usb_task(usb: Peri<'static, peripherals::USB>, x10: firmware_mb::X10) -> ! {
    crate::usb_link::run(embassy_rp::usb::Driver::new(usb, UsbIrqs), x10, "Pico").await
}

#[cfg(feature = "usb-link")]
fn spawn_usb(
    spawner: embassy_executor::Spawner,
    usb: Peri<'static, peripherals::USB>,
    x10: firmware_mb::X10,
) -> Result<(), crate::start::StartError> {
    spawner.spawn(usb_task(usb, x10).map_err(|_| crate::start::StartError::Spawn)?);
    Ok(())
}
