//! What the crash paths and the watchdog of the images write and read, decided here as pure
//! functions of the pin tables and of register values, tested on the host. The chip code
//! (`watchdog.rs` with `watchdog/rp2040.rs` or `watchdog/stm32.rs`) only reads and writes the
//! registers.
//!
//! * **Safe outputs through raw registers** ([`pico_plan`], [`stm32_plan`]): the panic and
//!   HardFault handlers drive every actuator pin (PWM A and B, digital A and B of every port) to
//!   its port's safe level, [`SafeState::ALL_LOW`] unless a board says otherwise, without the
//!   HAL or the runtime. A PWM pin is taken off its PWM unit and driven as a plain GPIO output
//!   at the level of its safe duty (0: low, 255: high): whatever the PWM unit does afterwards
//!   no longer reaches the pin.
//! * **Why the board reset** ([`rp2040_reset_reason`], [`stm32_reset_reason`]): from what the
//!   chip recorded (RP2040 `WATCHDOG.REASON` and `VREG_AND_CHIP_RESET.CHIP_RESET`, STM32
//!   `RCC_CSR` reset flags) and the crash marker ([`marker`]) the crash paths leave where a
//!   reset keeps it (RP2040 `WATCHDOG.SCRATCH0`, STM32 a RAM word the start-up does not
//!   initialise).
//! * **The watchdog's timeout** ([`WATCHDOG_MS`], [`FEED_MS`], [`rp2040_load`], [`iwdg`]).

use x10_hal::ports::SafeState;
use x10_microcode::{Level, ResetReason};

use crate::pins::BoardMap;

/// The watchdog's timeout in ms: a board whose executor stops polling its tasks for this long
/// is reset. A healthy runtime feeds it every [`FEED_MS`]; the longest stretch an image's
/// executor runs one task without yielding is far shorter (the STM32 bus clear's blocking
/// wait, 23 half SCL periods, 115 µs at 100 kHz; the C011's ADC conversion; a DB batch of five
/// operations, under 0.1 ms in the QEMU counts of docs/performance.md), so it is missed only
/// when the executor is stuck for at least `WATCHDOG_MS - FEED_MS` = 150 ms. It is under the
/// motherboard's default failsafe (300 ms): a hung board's outputs are released no later than
/// a board whose motherboard went silent.
pub const WATCHDOG_MS: u32 = 200;

/// How often the executor feeds the watchdog, in ms.
pub const FEED_MS: u64 = 50;

/// Why a crash path ran, as its [`marker`] records it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Crash {
    /// A panic (`core::panic!`, `defmt::panic!`, an `unwrap!`).
    Panic,
    /// A HardFault that no panic led to (a bad memory access, an undefined instruction).
    Fault,
}

/// The crash marker's upper 24 bits ("X10"): a word that does not carry them is no marker
/// (the STM32 keeps it in RAM, whose content after a power cut is anything).
pub const MARKER_TAG: u32 = 0x5831_3000;

/// The word a crash path records: [`MARKER_TAG`] and the byte of the [`ResetReason`] it
/// stands for.
#[must_use]
pub const fn marker(crash: Crash) -> u32 {
    MARKER_TAG
        | match crash {
            Crash::Panic => 2,
            Crash::Fault => 3,
        }
}

/// The crash a recorded word stands for, if it is a marker.
#[must_use]
pub const fn crash_of(word: u32) -> Option<Crash> {
    if word == marker(Crash::Panic) {
        Some(Crash::Panic)
    } else if word == marker(Crash::Fault) {
        Some(Crash::Fault)
    } else {
        None
    }
}

/// The marker a HardFault handler leaves: a panic's marker stays (the panic handlers end in
/// `udf`, a HardFault, so that a debugger shows the panic's backtrace); anything else becomes
/// [`Crash::Fault`]'s.
#[must_use]
pub const fn after_fault(word: u32) -> u32 {
    match crash_of(word) {
        Some(Crash::Panic) => word,
        _ => marker(Crash::Fault),
    }
}

const fn of_crash(crash: Crash) -> ResetReason {
    match crash {
        Crash::Panic => ResetReason::Panic,
        Crash::Fault => ResetReason::Fault,
    }
}

/// Why a table cannot be turned into a crash plan (a build error: the plans are `const`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanError {
    /// A pin name that is not one of the chip's GPIOs.
    NotAPin,
    /// A safe PWM duty other than 0 or 255: a level is all a crash path can hold on a pin.
    DutyNotALevel,
    /// Fewer safe states than actuator ports.
    MissingSafeState,
}

/// The level of a PWM pin whose safe duty is `duty`.
const fn duty_level(duty: u8) -> Result<bool, PlanError> {
    match duty {
        0 => Ok(false),
        255 => Ok(true),
        _ => Err(PlanError::DutyNotALevel),
    }
}

/// The actuator pins of `map` with their safe levels (high = true), in table order (PWM A, PWM
/// B, digital A, digital B of each port), each pin as a number: the GPIO number of an RP2040
/// (`rp2040`), `16 × port + pin` of an STM32.
const fn actuator_levels(
    map: &BoardMap,
    safe: &[SafeState],
    rp2040: bool,
    out: &mut [(u8, bool); 32],
) -> Result<usize, PlanError> {
    let mut n = 0;
    let mut i = 0;
    while i < map.actuators.len() {
        if i >= safe.len() {
            return Err(PlanError::MissingSafeState);
        }
        let a = &map.actuators[i];
        let s = &safe[i];
        let names = [a.pwm_a, a.pwm_b, a.a, a.b];
        let levels = [
            match duty_level(s.pwm[0]) {
                Ok(l) => l,
                Err(e) => return Err(e),
            },
            match duty_level(s.pwm[1]) {
                Ok(l) => l,
                Err(e) => return Err(e),
            },
            matches!(s.digital[0], Level::High),
            matches!(s.digital[1], Level::High),
        ];
        let mut k = 0;
        while k < 4 {
            let pin = if rp2040 {
                pico_gpio(names[k])
            } else {
                stm32_pin(names[k])
            };
            let Some(p) = pin else {
                return Err(PlanError::NotAPin);
            };
            out[n] = (p, levels[k]);
            n += 1;
            k += 1;
        }
        i += 1;
    }
    Ok(n)
}

// ---------------------------------------------------------------------------------------
// RP2040
// ---------------------------------------------------------------------------------------

/// What an RP2040 crash path writes: SIO output levels and output enables, and the GPIOs whose
/// function becomes SIO (a PWM pin leaves its slice, which runs on, disconnected).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PicoPlan {
    /// GPIOs driven low (`SIO.GPIO_OUT_CLR`).
    pub low: u32,
    /// GPIOs driven high (`SIO.GPIO_OUT_SET`).
    pub high: u32,
}

impl PicoPlan {
    /// Every GPIO of the plan: output enabled (`SIO.GPIO_OE_SET`), function SIO
    /// (`IO_BANK0.GPIOn_CTRL` = 5, no overrides).
    #[must_use]
    pub const fn pins(&self) -> u32 {
        self.low | self.high
    }
}

const fn pico_gpio(name: &str) -> Option<u8> {
    crate::pico_rules::gpio_number(name)
}

/// The RP2040 crash plan of `map` (the Pico's table) with each actuator port's safe state.
///
/// # Errors
/// [`PlanError`] when a pin is not a GPIO, a safe duty is not 0 or 255, or `safe` is short.
pub const fn pico_plan(map: &BoardMap, safe: &[SafeState]) -> Result<PicoPlan, PlanError> {
    let mut pins = [(0u8, false); 32];
    let n = match actuator_levels(map, safe, true, &mut pins) {
        Ok(n) => n,
        Err(e) => return Err(e),
    };
    let mut plan = PicoPlan { low: 0, high: 0 };
    let mut i = 0;
    while i < n {
        let (gpio, high) = pins[i];
        if high {
            plan.high |= 1 << gpio;
        } else {
            plan.low |= 1 << gpio;
        }
        i += 1;
    }
    Ok(plan)
}

/// `WATCHDOG.LOAD` for a timeout of `ms`: the RP2040's watchdog counts down twice per 1 µs
/// tick (erratum RP2040-E1, as embassy-rp's `Watchdog::feed` compensates), so twice the
/// microseconds. `None` above the 24-bit counter (8.3 s).
#[must_use]
pub const fn rp2040_load(ms: u32) -> Option<u32> {
    match ms.checked_mul(2_000) {
        Some(v) if v <= 0x00ff_ffff => Some(v),
        _ => None,
    }
}

/// `WATCHDOG.REASON` bits (RP2040 datasheet §4.7.6): the watchdog's timer ran out.
pub const RP2040_REASON_TIMER: u32 = 1 << 0;
/// `WATCHDOG.REASON`: the reset was forced (`CTRL.TRIGGER`).
pub const RP2040_REASON_FORCE: u32 = 1 << 1;
/// `VREG_AND_CHIP_RESET.CHIP_RESET` (datasheet §2.10.7): the last reset was power-on or
/// brown-out.
pub const RP2040_HAD_POR: u32 = 1 << 8;
/// `CHIP_RESET`: the last reset was the RUN pin.
pub const RP2040_HAD_RUN: u32 = 1 << 16;
/// `CHIP_RESET`: the last reset came from the debug port.
pub const RP2040_HAD_PSM_RESTART: u32 = 1 << 20;

/// Why an RP2040 reset, from `WATCHDOG.REASON`, `VREG_AND_CHIP_RESET.CHIP_RESET` and
/// `WATCHDOG.SCRATCH0` read at boot.
///
/// The watchdog block (REASON and the SCRATCH registers) is reset only by a chip-level reset
/// (power-on, brown-out, the RUN pin, the debug port), which clears both; a watchdog reset
/// keeps them (datasheet §4.7.1, §4.7.4). So REASON not 0 means the watchdog reset the chip: a
/// crash marker in SCRATCH0 names the crash (the crash paths trigger the watchdog, or it ran
/// out while they were stuck), else a timeout is a hang ([`ResetReason::Watchdog`]) and a
/// forced reset one that software asked for ([`ResetReason::Software`]: picotool, the
/// bootrom's reboot; the images force one only in their crash paths). REASON 0 is a
/// chip-level reset, told apart by CHIP_RESET: HAD_POR (power-on or brown-out) is
/// [`ResetReason::PowerOn`], anything else (HAD_RUN, the RUN pin; HAD_PSM_RESTART, the debug
/// port) [`ResetReason::ResetPin`].
#[must_use]
pub const fn rp2040_reset_reason(reason: u32, chip_reset: u32, scratch: u32) -> ResetReason {
    let reason = reason & (RP2040_REASON_TIMER | RP2040_REASON_FORCE);
    if reason != 0 {
        if let Some(c) = crash_of(scratch) {
            return of_crash(c);
        }
        return if reason & RP2040_REASON_TIMER != 0 {
            ResetReason::Watchdog
        } else {
            ResetReason::Software
        };
    }
    if chip_reset & RP2040_HAD_POR != 0 {
        ResetReason::PowerOn
    } else {
        ResetReason::ResetPin
    }
}

// ---------------------------------------------------------------------------------------
// STM32
// ---------------------------------------------------------------------------------------

/// An STM32 pin name (`PA0` … `PF15`) as `16 × port + pin` (port A = 0).
#[must_use]
pub const fn stm32_pin(name: &str) -> Option<u8> {
    let b = name.as_bytes();
    if b.len() < 3 || b.len() > 4 || b[0] != b'P' || b[1] < b'A' || b[1] > b'F' {
        return None;
    }
    let mut n: u8 = 0;
    let mut i = 2;
    while i < b.len() {
        if !b[i].is_ascii_digit() {
            return None;
        }
        n = n * 10 + (b[i] - b'0');
        i += 1;
    }
    if n < 16 {
        Some((b[1] - b'A') * 16 + n)
    } else {
        None
    }
}

/// What an STM32 crash path writes to one GPIO port: `BSRR` (the safe levels, set and reset
/// bits), then `MODER` with the pins' two bits replaced by 01, general-purpose output (RM0440
/// §9.4.1, RM0490 §6.4.1): the pin leaves its alternate function (a timer channel) or input
/// mode and is driven from `ODR`. The pins are push-pull already (`OTYPER` 0: the reset value,
/// and what every actuator pin is set up as: `Flex::set_as_output`, `PwmPin::new(..,
/// OutputType::PushPull)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpioWrite {
    /// The GPIO port: 0 = GPIOA, 1 = GPIOB, … (each 0x400 bytes after the one before).
    pub port: u8,
    /// `BSRR`: bit n drives pin n high, bit n + 16 drives it low.
    pub bsrr: u32,
    /// The `MODER` bits replaced: 0b11 at each pin's pair.
    pub moder_mask: u32,
    /// Their new value: 0b01 (output) at each pin's pair.
    pub moder: u32,
}

/// How many GPIO ports `map`'s actuator pins use (the length of its [`stm32_plan`]); 0 when a
/// name is not a pin.
#[must_use]
pub const fn stm32_ports_used(map: &BoardMap) -> usize {
    let mut used = 0u32;
    let mut i = 0;
    while i < map.actuators.len() {
        let a = &map.actuators[i];
        let names = [a.pwm_a, a.pwm_b, a.a, a.b];
        let mut k = 0;
        while k < 4 {
            match stm32_pin(names[k]) {
                Some(p) => used |= 1 << (p / 16),
                None => return 0,
            }
            k += 1;
        }
        i += 1;
    }
    used.count_ones() as usize
}

/// The STM32 crash plan of `map` with each actuator port's safe state: one [`GpioWrite`] per
/// GPIO port its actuator pins use, port A first. `N` is [`stm32_ports_used`].
///
/// # Errors
/// [`PlanError`] when a pin is not an STM32 pin name, a safe duty is not 0 or 255, `safe` is
/// short, or `N` is not the number of ports used.
pub const fn stm32_plan<const N: usize>(
    map: &BoardMap,
    safe: &[SafeState],
) -> Result<[GpioWrite; N], PlanError> {
    let mut pins = [(0u8, false); 32];
    let n = match actuator_levels(map, safe, false, &mut pins) {
        Ok(n) => n,
        Err(e) => return Err(e),
    };
    let empty = GpioWrite {
        port: 0,
        bsrr: 0,
        moder_mask: 0,
        moder: 0,
    };
    let mut by_port = [empty; 6];
    let mut i = 0;
    while i < n {
        let (p, high) = pins[i];
        let (port, pin) = ((p / 16) as usize, (p % 16) as u32);
        let w = &mut by_port[port];
        w.port = port as u8;
        w.bsrr |= if high { 1 << pin } else { 1 << (pin + 16) };
        w.moder_mask |= 0b11 << (2 * pin);
        w.moder |= 0b01 << (2 * pin);
        i += 1;
    }
    let mut out = [empty; N];
    let mut k = 0;
    let mut port = 0;
    while port < 6 {
        if by_port[port].moder_mask != 0 {
            if k >= N {
                return Err(PlanError::MissingSafeState);
            }
            out[k] = by_port[port];
            k += 1;
        }
        port += 1;
    }
    if k != N {
        return Err(PlanError::MissingSafeState);
    }
    Ok(out)
}

/// The IWDG's setting for a timeout: `PR` (the prescaler is 4 << PR) and `RLR` (12 bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Iwdg {
    /// `IWDG_PR`.
    pub pr: u8,
    /// `IWDG_RLR`.
    pub rlr: u16,
}

/// The IWDG setting for a timeout of at least `ms` on an LSI of `lsi_hz`: the smallest
/// prescaler whose 12-bit reload reaches it (the finest steps), the reload rounded up. The
/// timeout is `(RLR + 1) × 4 × 2^PR / f_LSI` (RM0440 §42.3.3, RM0490 §24.3.3). `None` when
/// even the largest prescaler (256) does not reach it.
#[must_use]
pub const fn iwdg(ms: u32, lsi_hz: u32) -> Option<Iwdg> {
    let mut pr = 0u8;
    while pr <= 6 {
        let div = 4u64 << pr;
        // ticks = ceil(ms · lsi_hz / (1000 · div))
        let num = ms as u64 * lsi_hz as u64;
        let den = 1000 * div;
        let ticks = num.div_ceil(den);
        if ticks >= 1 && ticks <= 4096 {
            return Some(Iwdg {
                pr,
                rlr: (ticks - 1) as u16,
            });
        }
        pr += 1;
    }
    None
}

/// `RCC_CSR` (G4) and `RCC_CSR2` (C0) reset flags, the same bits on both (RM0440 §7.4.29,
/// RM0490 §5.4.27).
pub const STM32_OBLRSTF: u32 = 1 << 25;
/// The NRST pin was low. Every internal reset drives NRST low too, so it comes with the
/// others: it stands alone only for the pin itself.
pub const STM32_PINRSTF: u32 = 1 << 26;
/// Power-on, power-down or brown-out (`BORRSTF` on the G4, `PWRRSTF` on the C0).
pub const STM32_BORRSTF: u32 = 1 << 27;
/// A software reset (`SYSRESETREQ`).
pub const STM32_SFTRSTF: u32 = 1 << 28;
/// The independent watchdog.
pub const STM32_IWDGRSTF: u32 = 1 << 29;
/// The window watchdog.
pub const STM32_WWDGRSTF: u32 = 1 << 30;
/// An illegal low-power mode entry.
pub const STM32_LPWRRSTF: u32 = 1 << 31;

/// Why an STM32 reset, from its reset flags (read at boot, then cleared with `RMVF`) and the
/// crash marker's RAM word.
///
/// A power-on or brown-out wins: the RAM word is whatever the SRAM woke up as. Otherwise a
/// marker names the crash whose path reset the board (`SYSRESETREQ`) or hung until the
/// watchdog did; without one, the watchdog is [`ResetReason::Watchdog`], and a software reset
/// or the NRST pin [`ResetReason::ResetPin`]: the images request a software reset only in
/// their crash paths (with a marker), so one without a marker is a debug probe's
/// (`SYSRESETREQ` is how probe-rs resets a Cortex-M). Every internal reset also drives NRST,
/// so PINRSTF comes last. Anything else (option-byte loading, an illegal low-power entry, no
/// flag) is [`ResetReason::PowerOn`], what a board reports that cannot tell.
#[must_use]
pub const fn stm32_reset_reason(csr: u32, word: u32) -> ResetReason {
    if csr & STM32_BORRSTF != 0 {
        return ResetReason::PowerOn;
    }
    if csr & (STM32_SFTRSTF | STM32_IWDGRSTF | STM32_WWDGRSTF) != 0 {
        if let Some(c) = crash_of(word) {
            return of_crash(c);
        }
    }
    if csr & (STM32_IWDGRSTF | STM32_WWDGRSTF) != 0 {
        ResetReason::Watchdog
    } else if csr & (STM32_SFTRSTF | STM32_PINRSTF) != 0 {
        ResetReason::ResetPin
    } else {
        ResetReason::PowerOn
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pins::{C011, G431, PICO};

    const LOW3: [SafeState; 3] = [SafeState::ALL_LOW; 3];
    const LOW4: [SafeState; 4] = [SafeState::ALL_LOW; 4];

    #[test]
    fn the_pico_plan_drives_its_twelve_actuator_pins_low() {
        let plan = pico_plan(&PICO, &LOW3).unwrap();
        // Ports 1..3: PWM GP2/GP3 (slice 1), GP6/GP7 (slice 3), GP10/GP11 (slice 5), digital
        // GP4/GP5, GP8/GP9, GP12/GP13: GP2..=GP13.
        assert_eq!(plan.low, 0b11_1111_1111_1100);
        assert_eq!(plan.high, 0);
        assert_eq!(plan.pins(), 0x3ffc);
        // No bus pin, sensor pin or jumper is touched.
        for p in [0, 1, 14, 15, 16, 17, 18, 19, 20, 21, 22, 26, 27, 28] {
            assert_eq!(plan.pins() & (1 << p), 0, "GP{p}");
        }
    }

    #[test]
    fn a_board_that_says_otherwise_gets_its_levels() {
        // Port 2: PWM B full on and digital A high (say an active-low brake input).
        let mut safe = LOW3;
        safe[1] = SafeState {
            pwm: [0, 255],
            digital: [Level::High, Level::Low],
        };
        let plan = pico_plan(&PICO, &safe).unwrap();
        assert_eq!(plan.high, (1 << 7) | (1 << 8));
        assert_eq!(plan.low, 0x3ffc & !((1 << 7) | (1 << 8)));
        let g = stm32_plan::<3>(&G431, &[safe[0], safe[1], safe[2], safe[0]]).unwrap();
        // G431 port 2: TIM2 PA5 (CH1), PB3 (CH2), digital PA6, PA7: PB3 and PA6 high.
        assert_eq!(g[0].bsrr & 0xffff, 1 << 6);
        assert_eq!(g[1].bsrr & 0xffff, 1 << 3);
        assert_eq!(g[1].bsrr & (1 << (3 + 16)), 0);
    }

    #[test]
    fn a_safe_duty_between_off_and_full_or_a_short_list_is_refused() {
        let mut safe = LOW3;
        safe[2].pwm[0] = 128;
        assert_eq!(pico_plan(&PICO, &safe), Err(PlanError::DutyNotALevel));
        assert_eq!(
            pico_plan(&PICO, &LOW3[..2]),
            Err(PlanError::MissingSafeState)
        );
        assert_eq!(
            stm32_plan::<3>(&G431, &LOW3),
            Err(PlanError::MissingSafeState)
        );
        // A plan of the wrong length is refused, not cut.
        assert_eq!(
            stm32_plan::<2>(&G431, &LOW4),
            Err(PlanError::MissingSafeState)
        );
        assert_eq!(
            stm32_plan::<4>(&G431, &LOW4),
            Err(PlanError::MissingSafeState)
        );
        // The Pico's names are not STM32 pins, and the other way round.
        assert_eq!(stm32_ports_used(&PICO), 0);
        assert_eq!(pico_plan(&G431, &LOW4), Err(PlanError::NotAPin));
    }

    #[test]
    fn stm32_pin_names() {
        assert_eq!(stm32_pin("PA0"), Some(0));
        assert_eq!(stm32_pin("PB9"), Some(16 + 9));
        assert_eq!(stm32_pin("PC15"), Some(32 + 15));
        assert_eq!(stm32_pin("PF2"), Some(80 + 2));
        for bad in ["PA16", "PG1", "P", "PA", "PIN_4", "pa1", "PA1x"] {
            assert_eq!(stm32_pin(bad), None, "{bad}");
        }
    }

    #[test]
    fn the_g431_plan_writes_ports_a_b_c() {
        // Actuator pins (table): TIM1 PA8 PA9 PA10 PB9; TIM2 PA5 PB3 PA6 PA7; TIM3 PB4 PB5
        // PB6 PC4; TIM15 PB14 PB15 PC10 PC11.
        assert_eq!(stm32_ports_used(&G431), 3);
        let plan = stm32_plan::<3>(&G431, &LOW4).unwrap();
        let a: u32 = [8, 9, 10, 5, 6, 7].iter().map(|p| 1 << p).sum();
        let b: u32 = [9, 3, 4, 5, 6, 14, 15].iter().map(|p| 1 << p).sum();
        let c: u32 = [4, 10, 11].iter().map(|p| 1 << p).sum();
        for (w, (port, pins)) in plan.iter().zip([(0, a), (1, b), (2, c)]) {
            assert_eq!(w.port, port);
            // All low: reset bits only.
            assert_eq!(w.bsrr, pins << 16);
            let mut mask = 0u32;
            let mut out = 0u32;
            for p in 0..16 {
                if pins & (1 << p) != 0 {
                    mask |= 0b11 << (2 * p);
                    out |= 0b01 << (2 * p);
                }
            }
            assert_eq!((w.moder_mask, w.moder), (mask, out), "port {port}");
        }
        // The bus (PB7, PA15), SWD (PA13, PA14) and the sensors stay as they are.
        assert_eq!(plan[0].moder_mask & (0b1111 << 26), 0);
        assert_eq!(plan[0].moder_mask & (0b11 << 30), 0);
        assert_eq!(plan[1].moder_mask & (0b11 << 14), 0);
    }

    #[test]
    fn the_c011_plan_writes_port_a_only() {
        assert_eq!(stm32_ports_used(&C011), 1);
        let plan = stm32_plan::<1>(&C011, &[SafeState::ALL_LOW]).unwrap();
        // TIM1 CH1 PA0, CH2 PA1, digital PA6, PA7.
        assert_eq!(
            plan[0],
            GpioWrite {
                port: 0,
                bsrr: 0b1100_0011 << 16,
                moder_mask: 0b1111_0000_0000_1111,
                moder: 0b0101_0000_0000_0101,
            }
        );
    }

    #[test]
    fn markers() {
        assert_eq!(marker(Crash::Panic), 0x5831_3002);
        assert_eq!(marker(Crash::Fault), 0x5831_3003);
        assert_eq!(crash_of(0x5831_3002), Some(Crash::Panic));
        assert_eq!(crash_of(0x5831_3003), Some(Crash::Fault));
        for w in [
            0,
            0xffff_ffff,
            0x5831_3000,
            0x5831_3004,
            0x5931_3002,
            0x0000_0002,
        ] {
            assert_eq!(crash_of(w), None, "{w:#x}");
        }
        // A HardFault keeps a panic's marker, and marks anything else as a fault.
        assert_eq!(after_fault(marker(Crash::Panic)), marker(Crash::Panic));
        assert_eq!(after_fault(marker(Crash::Fault)), marker(Crash::Fault));
        assert_eq!(after_fault(0), marker(Crash::Fault));
        assert_eq!(after_fault(0x1234_5678), marker(Crash::Fault));
        // The marker's low byte is the reason's wire byte.
        assert_eq!(of_crash(Crash::Panic).to_byte(), marker(Crash::Panic) as u8);
        assert_eq!(of_crash(Crash::Fault).to_byte(), marker(Crash::Fault) as u8);
    }

    #[test]
    fn rp2040_reasons() {
        use ResetReason::*;
        let panic = marker(Crash::Panic);
        let fault = marker(Crash::Fault);
        // Chip-level resets clear SCRATCH and REASON: CHIP_RESET tells them apart.
        assert_eq!(rp2040_reset_reason(0, RP2040_HAD_POR, 0), PowerOn);
        assert_eq!(rp2040_reset_reason(0, RP2040_HAD_RUN, 0), ResetPin);
        assert_eq!(rp2040_reset_reason(0, RP2040_HAD_PSM_RESTART, 0), ResetPin);
        // No HAD_POR: not a power-on (the flags say which of the others; both are the pin or a
        // probe). HAD_POR with the others (0xffffffff: rp2040js without the block) is power-on.
        assert_eq!(rp2040_reset_reason(0, 0, 0), ResetPin);
        assert_eq!(rp2040_reset_reason(0, 0xffff_ffff, 0), PowerOn);
        // A marker without a watchdog reset is not believed (REASON 0: chip-level reset).
        assert_eq!(rp2040_reset_reason(0, RP2040_HAD_POR, panic), PowerOn);
        // The crash paths force a watchdog reset after leaving their marker.
        assert_eq!(rp2040_reset_reason(RP2040_REASON_FORCE, 0, panic), Panic);
        assert_eq!(rp2040_reset_reason(RP2040_REASON_FORCE, 0, fault), Fault);
        // A crash path stuck before its reset: the watchdog ran out, the marker names it.
        assert_eq!(rp2040_reset_reason(RP2040_REASON_TIMER, 0, panic), Panic);
        // A hang: the timer ran out, no marker.
        assert_eq!(rp2040_reset_reason(RP2040_REASON_TIMER, 0, 0), Watchdog);
        assert_eq!(
            rp2040_reset_reason(RP2040_REASON_TIMER, RP2040_HAD_POR, 7),
            Watchdog
        );
        // Someone else forced it (picotool, the bootrom's reboot).
        assert_eq!(rp2040_reset_reason(RP2040_REASON_FORCE, 0, 0), Software);
        // Reserved REASON bits are not a watchdog reset.
        assert_eq!(
            rp2040_reset_reason(0xffff_fffc, RP2040_HAD_RUN, 0),
            ResetPin
        );
    }

    #[test]
    fn stm32_reasons() {
        use ResetReason::*;
        let panic = marker(Crash::Panic);
        let fault = marker(Crash::Fault);
        // Every internal reset comes with PINRSTF (it drives NRST).
        let pin = STM32_PINRSTF;
        assert_eq!(stm32_reset_reason(STM32_BORRSTF | pin, 0), PowerOn);
        // After a power cut the RAM word is anything, even a marker.
        assert_eq!(stm32_reset_reason(STM32_BORRSTF | pin, panic), PowerOn);
        assert_eq!(stm32_reset_reason(pin, 0), ResetPin);
        // The NRST pin alone does not make a stale marker a crash.
        assert_eq!(stm32_reset_reason(pin, panic), ResetPin);
        assert_eq!(stm32_reset_reason(STM32_SFTRSTF | pin, panic), Panic);
        assert_eq!(stm32_reset_reason(STM32_SFTRSTF | pin, fault), Fault);
        // A software reset without a marker: a debug probe's SYSRESETREQ.
        assert_eq!(stm32_reset_reason(STM32_SFTRSTF | pin, 0), ResetPin);
        assert_eq!(stm32_reset_reason(STM32_SFTRSTF, 0x5831_3001), ResetPin);
        assert_eq!(
            stm32_reset_reason(STM32_IWDGRSTF | pin, 0x5831_3001),
            Watchdog
        );
        assert_eq!(stm32_reset_reason(STM32_IWDGRSTF | pin, panic), Panic);
        assert_eq!(stm32_reset_reason(STM32_WWDGRSTF | pin, 0), Watchdog);
        assert_eq!(stm32_reset_reason(STM32_OBLRSTF | pin, 0), ResetPin);
        // Nothing else to tell by: power-on.
        assert_eq!(stm32_reset_reason(STM32_LPWRRSTF, panic), PowerOn);
        assert_eq!(stm32_reset_reason(STM32_OBLRSTF, 0), PowerOn);
        assert_eq!(stm32_reset_reason(0, panic), PowerOn);
    }

    #[test]
    fn watchdog_settings() {
        // RP2040: 200 ms = 400 000 half-µs counts, well inside the 24-bit counter.
        assert_eq!(rp2040_load(WATCHDOG_MS), Some(400_000));
        assert_eq!(rp2040_load(8_388), Some(16_776_000));
        assert_eq!(rp2040_load(8_389), None);
        assert_eq!(rp2040_load(u32::MAX), None);
        // IWDG on the nominal 32 kHz LSI: 200 ms = 6400 LSI periods, /4 reaches 4096 × 4 =
        // 16 384 periods: 1600 ticks.
        assert_eq!(iwdg(WATCHDOG_MS, 32_000), Some(Iwdg { pr: 0, rlr: 1599 }));
        assert_eq!(iwdg(512, 32_000), Some(Iwdg { pr: 0, rlr: 4095 }));
        assert_eq!(iwdg(513, 32_000), Some(Iwdg { pr: 1, rlr: 2051 }));
        assert_eq!(iwdg(32_768, 32_000), Some(Iwdg { pr: 6, rlr: 4095 }));
        assert_eq!(iwdg(32_769, 32_000), None);
        assert_eq!(iwdg(0, 32_000), None);
        // The timeout it gives is at least the one asked for, and under one tick more.
        for ms in [1, 7, 50, 200, 999, 5_000, 30_000] {
            let w = iwdg(ms, 32_000).unwrap();
            let lsi_periods = (u64::from(w.rlr) + 1) * (4 << w.pr);
            assert!(lsi_periods * 1000 >= u64::from(ms) * 32_000, "{ms}");
            assert!(
                (lsi_periods - (4 << w.pr)) * 1000 < u64::from(ms) * 32_000,
                "{ms}"
            );
        }
        // The feeder feeds four times per timeout.
        assert_eq!(u64::from(WATCHDOG_MS) / FEED_MS, 4);
    }
}
