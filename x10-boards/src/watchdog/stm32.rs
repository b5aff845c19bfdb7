//! STM32 (G431, C011): the IWDG, the crash plan on the GPIO ports' `BSRR` and `MODER`, the
//! reason in the RCC reset flags (`RCC_CSR` on the G4, `RCC_CSR2` on the C0) and a RAM word
//! that the start-up does not initialise.

use core::mem::MaybeUninit;

use embassy_stm32::pac;
use pac::iwdg::vals::{Key, Pr};
use x10_hal::ports::SafeState;

use x10_microcode::ResetReason;

use crate::crash::{self, GpioWrite, Iwdg, WATCHDOG_MS};
#[cfg(feature = "stm32c011")]
use crate::pins::C011 as MAP;
#[cfg(feature = "stm32g431")]
use crate::pins::G431 as MAP;

/// Actuator ports of the board.
const ACTUATORS: usize = MAP.actuators.len();

/// The crash plan of the board's table: every actuator port's safe state is the runtime's
/// (`Ports::safe_state`, which `Stm32Ports` leaves at its default, all low).
const PLAN: [GpioWrite; crash::stm32_ports_used(&MAP)] =
    match crash::stm32_plan(&MAP, &[SafeState::ALL_LOW; ACTUATORS]) {
        Ok(p) => p,
        Err(_) => panic!("the board's actuator pins and safe states make no crash plan"),
    };

/// The IWDG setting for [`WATCHDOG_MS`] on the nominal 32 kHz LSI (embassy-stm32's
/// `rcc::LSI_FREQ`). The LSI of the G4 runs at 29.5 to 34 kHz (DS12589 table "LSI oscillator
/// characteristics"), so 188 to 217 ms; the C0's is within a few percent of 32 kHz too.
const IWDG: Iwdg = match crash::iwdg(WATCHDOG_MS, 32_000) {
    Some(w) => w,
    None => panic!("WATCHDOG_MS is beyond the IWDG"),
};

/// Starts the IWDG as RM0440 §42.3.2 and RM0490 §24.3.2 say: start (0xCCCC, which also starts
/// the LSI), unlock (0x5555), prescaler and reload, wait until both reached the LSI domain
/// (`SR` 0), reload (0xAAAA, which locks them again). It cannot be stopped but by a reset.
pub fn start() {
    let w = pac::IWDG;
    w.kr().write(|k| k.set_key(Key::START));
    w.kr().write(|k| k.set_key(Key::ENABLE));
    w.pr().write(|p| p.set_pr(Pr::from_bits(IWDG.pr)));
    w.rlr().write(|r| r.set_rl(IWDG.rlr));
    while w.sr().read().0 != 0 {}
    feed();
}

/// Reloads the counter.
pub fn feed() {
    pac::IWDG.kr().write(|k| k.set_key(Key::RESET));
}

/// The crash record: a RAM word in `.uninit`, which cortex-m-rt's start-up neither zeroes nor
/// initialises, and which a system reset keeps (SRAM is not erased by a reset: RM0440 §7.1.2,
/// RM0490 §6.1.2).
#[allow(unsafe_code)]
#[link_section = ".uninit.x10_crash"]
static mut RECORD: MaybeUninit<u32> = MaybeUninit::uninit();

#[allow(unsafe_code)]
pub(super) fn record(word: u32) {
    // SAFETY: a plain aligned word written with a volatile store; read only by `recorded`.
    unsafe { core::ptr::write_volatile(core::ptr::addr_of_mut!(RECORD).cast::<u32>(), word) }
}

#[allow(unsafe_code)]
pub(super) fn recorded() -> u32 {
    // SAFETY: as above; any bit pattern is a valid u32 (after a power cut it is noise, which
    // `crash::stm32_reset_reason` ignores).
    unsafe { core::ptr::read_volatile(core::ptr::addr_of!(RECORD).cast::<u32>()) }
}

/// Why the chip reset ([`crash::stm32_reset_reason`]); clears the reset flags (`RMVF`) and
/// the crash record.
pub fn reset_reason() -> ResetReason {
    #[cfg(feature = "stm32g431")]
    let csr = pac::RCC.csr();
    #[cfg(feature = "stm32c011")]
    let csr = pac::RCC.csr2();
    let r = crash::stm32_reset_reason(csr.read().0, recorded());
    csr.modify(|w| w.set_rmvf(true));
    record(0);
    r
}

/// Drives every actuator pin to its safe level ([`PLAN`]): per GPIO port, `BSRR` (the level)
/// then `MODER` (general-purpose output). A PWM pin leaves its timer's alternate function at
/// once; the timer runs on, disconnected. Before the HAL enabled the GPIO clocks the writes
/// do nothing, and the pins are still in their reset state (analog, not driven).
#[allow(unsafe_code)]
pub fn safe_outputs() {
    let base = pac::GPIOA.as_ptr() as usize;
    for w in PLAN {
        // SAFETY: GPIOA + 0x400 × port is that port's register block (RM0440 §2.2.2, RM0490
        // §2.2.2); the plan names only ports the table's pins are on.
        let g = unsafe { pac::gpio::Gpio::from_ptr((base + 0x400 * w.port as usize) as *mut ()) };
        g.bsrr().write_value(pac::gpio::regs::Bsrr(w.bsrr));
        g.moder().modify(|m| m.0 = (m.0 & !w.moder_mask) | w.moder);
    }
}

/// Resets the chip at once with `SYSRESETREQ`: the same system reset as the IWDG's (RM0440
/// §7.1.2, RM0490 §6.1.2), sooner than the IWDG would (it cannot be forced, only shortened
/// through its reload register).
pub fn reset() -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}
