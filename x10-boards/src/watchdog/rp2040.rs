//! RP2040: the WATCHDOG block, the crash plan on SIO, IO_BANK0 and PWM, the reason in
//! WATCHDOG.REASON, VREG_AND_CHIP_RESET.CHIP_RESET and WATCHDOG.SCRATCH0 (SCRATCH4-7 are the
//! bootrom's, datasheet §2.8.1.1).

use embassy_rp::pac;
use x10_hal::ports::SafeState;

use x10_microcode::ResetReason;

use crate::crash::{self, PicoPlan, WATCHDOG_MS};
use crate::pico::ACTUATORS;
use crate::pins::PICO;

/// The crash plan of the Pico's table: every actuator port's safe state is the runtime's
/// (`Ports::safe_state`, which `PicoPorts` leaves at its default, all low).
const PLAN: PicoPlan = match crash::pico_plan(&PICO, &[SafeState::ALL_LOW; ACTUATORS]) {
    Ok(p) => p,
    Err(_) => panic!("the Pico's actuator pins and safe states make no crash plan"),
};

/// `WATCHDOG.LOAD` for [`WATCHDOG_MS`].
const LOAD: u32 = match crash::rp2040_load(WATCHDOG_MS) {
    Some(l) => l,
    None => panic!("WATCHDOG_MS is beyond the RP2040 watchdog's counter"),
};

/// `PSM.WDSEL`: what the watchdog resets, everything but the two oscillators (ROSC, XOSC), as
/// embassy-rp's `Watchdog::start` (`watchdog.rs` 72-78) and the SDK's `_watchdog_enable`. The
/// RESETS block is among them: reset, it holds every peripheral (IO, pads, PWM) in reset.
const WDSEL: u32 = 0x0001_fffc;

/// `IO_BANK0.GPIOn_CTRL` with FUNCSEL = 5 (SIO) and no overrides (datasheet §2.19.2).
const FUNC_SIO: u32 = 5;

/// Starts the watchdog: told what to reset, loaded, enabled (embassy-rp's `Watchdog::start`
/// stops it first; not needed here: loading it restarts the count whether it runs or not). It
/// pauses while a debugger halts the core (`CTRL.PAUSE_DBG0`, set since reset and left).
pub fn start() {
    pac::PSM.wdsel().write_value(pac::psm::regs::Wdsel(WDSEL));
    feed();
    // PAUSE_DBG0/1, PAUSE_JTAG as since reset.
    pac::WATCHDOG.ctrl().write(|c| {
        c.set_enable(true);
        c.set_pause_dbg0(true);
        c.set_pause_dbg1(true);
        c.set_pause_jtag(true);
    });
}

/// Loads the counter with the full timeout.
pub fn feed() {
    pac::WATCHDOG
        .load()
        .write_value(pac::watchdog::regs::Load(LOAD));
}

/// Why the chip reset ([`crash::rp2040_reset_reason`]); clears the crash record.
pub fn reset_reason() -> ResetReason {
    let w = pac::WATCHDOG;
    let r = crash::rp2040_reset_reason(
        w.reason().read().0,
        pac::VREG_AND_CHIP_RESET.chip_reset().read().0,
        w.scratch0().read(),
    );
    record(0);
    r
}

pub(super) fn record(word: u32) {
    pac::WATCHDOG.scratch0().write_value(word);
}

#[cfg_attr(
    not(any(feature = "daughterboard", feature = "motherboard")),
    allow(dead_code)
)]
pub(super) fn recorded() -> u32 {
    pac::WATCHDOG.scratch0().read()
}

/// Drives every actuator pin to its safe level ([`PLAN`]): the SIO levels and output enables
/// first, then each pin's function to SIO (a PWM pin leaves its slice at once, driven at the
/// level just set; the slice runs on, disconnected: stopping it too cost 52 B db-pico has not
/// got). IO_BANK0 is written only once out of reset (`RESETS.RESET_DONE`, datasheet §2.14):
/// before the HAL brought it out, the pins are not driven at all.
pub fn safe_outputs() {
    let sio = pac::SIO;
    sio.gpio_out(0).value_clr().write_value(PLAN.low);
    if PLAN.high != 0 {
        sio.gpio_out(0).value_set().write_value(PLAN.high);
    }
    sio.gpio_oe(0).value_set().write_value(PLAN.pins());
    let done = pac::RESETS.reset_done().read();
    if done.io_bank0() {
        for gpio in 0..30 {
            if PLAN.pins() & (1 << gpio) != 0 {
                pac::IO_BANK0
                    .gpio(gpio)
                    .ctrl()
                    .write_value(pac::io::regs::GpioCtrl(FUNC_SIO));
            }
        }
    }
}

/// Resets the chip through the watchdog at once (`CTRL.TRIGGER`, REASON becomes FORCE),
/// resetting what [`start`] told it to ([`WDSEL`]). A crash before [`start`] (in the HAL's
/// start-up, with no pin driven yet) resets nothing: the core then waits here, outputs
/// undriven, until a power cycle.
pub fn reset() -> ! {
    pac::WATCHDOG.ctrl().write(|c| {
        c.set_enable(true);
        c.set_trigger(true);
    });
    #[allow(clippy::empty_loop)]
    loop {}
}
