//! PWM arithmetic shared by the chip modules: which counter setup gives a frequency, and which
//! compare value gives a duty cycle or a pulse width. Pure integer math, tested on the host;
//! the chip modules only write the results into registers.

/// Frequency of every PWM port after boot, in Hz (until `pwm_frequency` changes it).
pub const DEFAULT_HZ: u16 = 1_000;

/// Fewest counter steps per period accepted: below this an 8-bit duty loses resolution, so
/// such frequencies are answered `unsupported`.
pub const MIN_COUNTS: u32 = 256;

/// What a PWM pin was last told, kept so that a frequency change can recompute its compare
/// value and the pin keeps its duty cycle or its pulse width.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Output {
    /// A duty cycle, 0 (always low) to 255 (always high).
    Duty(u8),
    /// A high time per period, in µs.
    PulseUs(u16),
}

impl Output {
    /// Off.
    pub const OFF: Output = Output::Duty(0);
}

/// The counter setup of an RP2040 PWM slice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SliceTiming {
    /// Clock divider in 1/16 steps (16 = divide by 1, the largest is 4095 = 255 15/16).
    pub div16: u16,
    /// TOP: the counter counts 0..=top, so a period is `top + 1` counts.
    pub top: u16,
}

/// The counter setup that makes an RP2040 PWM slice (clocked at `sys_hz`) run at `hz`, with
/// the smallest divider (hence the finest duty resolution). `None` when `hz` is 0, below what
/// the largest divider reaches, or so high that a period has fewer than [`MIN_COUNTS`] steps.
pub fn rp2040_slice(sys_hz: u32, hz: u16) -> Option<SliceTiming> {
    if hz == 0 {
        return None;
    }
    // Period in 1/16 clock cycles, floor(sys_hz · 16 / hz), in 32 bits (no 64-bit division
    // on the Cortex-M0+: issue 12). None above a 268 MHz clock.
    let hz = u32::from(hz);
    let period16 = (sys_hz / hz)
        .checked_mul(16)?
        .checked_add((sys_hz % hz) * 16 / hz)?;
    let div16 = period16.div_ceil(65_536).max(16);
    if div16 > 4_095 {
        return None;
    }
    let counts = period16.checked_add(div16 / 2)? / div16;
    if !(MIN_COUNTS..=65_536).contains(&counts) {
        return None;
    }
    Some(SliceTiming {
        div16: div16 as u16,
        top: (counts - 1) as u16,
    })
}

/// `round(n / d)` (halves up) by shift and subtract: the images need it only when a PWM
/// setting changes, and it spares them compiler-builtins' 64-bit division (0.9 KiB of flash on
/// the Cortex-M0+, issue 12). `d` must not be 0 (0 gives `u64::MAX`).
pub fn div_round(n: u64, d: u32) -> u64 {
    if d == 0 {
        return u64::MAX;
    }
    let d = u64::from(d);
    let mut q = 0u64;
    let mut r = 0u64;
    let mut bit = 64;
    while bit > 0 {
        bit -= 1;
        // r < d <= 2^32, so the shift cannot overflow.
        r = (r << 1) | ((n >> bit) & 1);
        q <<= 1;
        if r >= d {
            r -= d;
            q |= 1;
        }
    }
    // Halves up: the remainder is at least half the divisor.
    if r >= d - r {
        q + 1
    } else {
        q
    }
}

/// Whether an STM32 timer clocked at `timer_hz` can run at `hz` with at least [`MIN_COUNTS`]
/// steps per period (the prescaler reaches the low end of `u16` frequencies on every timer
/// clock up to 170 MHz).
pub fn stm32_frequency_ok(timer_hz: u32, hz: u16) -> bool {
    hz != 0 && timer_hz / u32::from(hz) >= MIN_COUNTS
}

/// The largest compare value embassy-stm32's `SimplePwm` accepts on any timer. Its
/// `set_frequency` sets ARR with 16 bits even on 32-bit timers (`timer/simple_pwm.rs` 369-370),
/// `max_duty_cycle` is ARR + 1 (446-448), and `set_duty_cycle` converts the compare value to
/// the timer's word with `unwrap!` (116-118): when ARR is 0xFFFF (at 1 Hz, 2 Hz or 1 297 Hz on
/// a 170 MHz timer clock) a compare value of ARR + 1 would panic on a 16-bit timer.
pub const STM32_MAX_COMPARE: u32 = 0xFFFF;

/// The compare value written to an STM32 timer channel: `c` clamped to the timer's maximum
/// duty (`max_duty`, ARR + 1) and to [`STM32_MAX_COMPARE`]. Where ARR is 0xFFFF, "always high"
/// becomes high for 65 535 of 65 536 counts.
pub fn stm32_compare(c: u32, max_duty: u32) -> u32 {
    c.min(max_duty).min(STM32_MAX_COMPARE)
}

/// The prescaler (PSC) and auto-reload value (ARR) of an STM32 timer clocked at `timer_hz`
/// running its PWM at `hz`: the values embassy-stm32 0.6's `SimplePwm::set_frequency`
/// programs (`timer/simple_pwm.rs` 361-371: edge-aligned, 16 ARR bits, rounded to the slower
/// frequency by `calculate_psc_arr`, `timer/low_level.rs` 309-364), computed in 32 bits. The
/// adapter programs the timers with it instead of calling the HAL, whose 64-bit arithmetic
/// links compiler-builtins' 64-bit division (0.9 KiB of flash; issue 12). The tests compare it
/// with the HAL's 64-bit formula at every `u16` frequency. Both values are at most 0xFFFF
/// (with 32-bit clock counts the prescaler always fits 16 bits); `None` for 0 Hz.
pub fn stm32_psc_arr(timer_hz: u32, hz: u32) -> Option<(u32, u32)> {
    if hz == 0 {
        return None;
    }
    let clocks = timer_hz / hz;
    // The smallest prescaler that brings ARR + 1 within 2^16 (at most 0xFFFF: clocks < 2^32).
    let psc = clocks.saturating_sub(1) >> 16;
    let arr = clocks.div_ceil(psc + 1).saturating_sub(1).clamp(1, 0xFFFF);
    Some((psc, arr))
}

/// A PWM unit's time base: how many counts a period has, and how fast the counter ticks
/// (`tick_num / tick_den` counts per second).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Timebase {
    /// Counts per period; a compare value of `counts` is always high.
    pub counts: u32,
    /// Tick rate numerator (counts per second × `tick_den`).
    pub tick_num: u64,
    /// Tick rate denominator (not 0; at most 4 294, so that `tick_den · 10^6` fits 32 bits).
    pub tick_den: u32,
}

impl Timebase {
    /// The time base of an RP2040 slice clocked at `sys_hz`.
    pub fn rp2040(sys_hz: u32, t: SliceTiming) -> Timebase {
        Timebase {
            counts: u32::from(t.top) + 1,
            tick_num: u64::from(sys_hz) * 16,
            tick_den: u32::from(t.div16.max(1)),
        }
    }

    /// The time base of a timer that runs at `hz` with `counts` counts per period (what
    /// embassy-stm32's `SimplePwm` reports as frequency and maximum duty).
    pub fn from_frequency(hz: u32, counts: u32) -> Timebase {
        Timebase {
            counts,
            tick_num: u64::from(hz) * u64::from(counts),
            tick_den: 1,
        }
    }

    /// The compare value for `out`: duty `d` gives `round(d · counts / 255)`; a pulse of
    /// `us` µs gives `round(us · tick rate / 10^6)`. `None` when the pulse is longer than a
    /// period (or the time base is out of its documented range).
    pub fn compare(&self, out: Output) -> Option<u32> {
        match out {
            Output::Duty(d) => {
                let c = div_round(u64::from(d) * u64::from(self.counts), 255);
                u32::try_from(c).ok()
            }
            Output::PulseUs(us) => {
                let den = self.tick_den.max(1).checked_mul(1_000_000)?;
                let c = div_round(u64::from(us).checked_mul(self.tick_num)?, den);
                u32::try_from(c).ok().filter(|&c| c <= self.counts)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SYS: u32 = 125_000_000;

    #[test]
    fn rp2040_default_frequency() {
        // 125 MHz / 1 kHz = 125 000 cycles = 2 000 000 sixteenths: divider
        // ceil(2 000 000 / 65 536) = 31/16, round(2 000 000 / 31) = 64 516 counts.
        let t = rp2040_slice(SYS, 1_000).unwrap();
        assert_eq!(
            t,
            SliceTiming {
                div16: 31,
                top: 64_515
            }
        );
        let tb = Timebase::rp2040(SYS, t);
        assert_eq!(tb.counts, 64_516);
        assert_eq!(tb.compare(Output::Duty(0)), Some(0));
        assert_eq!(tb.compare(Output::Duty(255)), Some(64_516));
        assert_eq!(tb.compare(Output::Duty(128)), Some(32_385));
        // 1.5 ms = 1.5 periods at 1 kHz: too long.
        assert_eq!(tb.compare(Output::PulseUs(1_500)), None);
        assert_eq!(tb.compare(Output::PulseUs(1_000)), Some(64_516));
        assert_eq!(tb.compare(Output::PulseUs(250)), Some(16_129));
    }

    #[test]
    fn rp2040_servo_frequency() {
        // 50 Hz: 2 500 000 cycles, divider ceil(40 000 000 / 65 536) = 611/16 = 38.1875.
        let t = rp2040_slice(SYS, 50).unwrap();
        assert_eq!(t.div16, 611);
        assert_eq!(t.top, 65_465); // round(40 000 000 / 611) - 1
        let tb = Timebase::rp2040(SYS, t);
        // 1.5 ms at 125 MHz / 38.1875 = 3 273 322 ticks/s → 4 910 counts.
        assert_eq!(tb.compare(Output::PulseUs(1_500)), Some(4_910));
        assert_eq!(tb.compare(Output::PulseUs(20_000)), Some(65_466));
        assert_eq!(tb.compare(Output::PulseUs(20_001)), None);
    }

    #[test]
    fn rp2040_limits() {
        assert_eq!(rp2040_slice(SYS, 0), None);
        // Lowest: 125 MHz / (255.9375 · 65 536) = 7.45 Hz.
        assert_eq!(rp2040_slice(SYS, 7), None);
        assert!(rp2040_slice(SYS, 8).is_some());
        // Highest with 256 counts: 488 281 Hz, above u16; 65 535 Hz gives 1 907 counts.
        assert_eq!(rp2040_slice(SYS, 65_535).unwrap().top, 1_906);
        // A 10 MHz clock gives only 153 counts at 65 535 Hz.
        assert_eq!(rp2040_slice(10_000_000, 65_535), None);
        assert_eq!(rp2040_slice(10_000_000, 39_062).unwrap().top, 255);
    }

    #[test]
    fn stm32_limits() {
        assert!(stm32_frequency_ok(170_000_000, 65_535));
        assert!(stm32_frequency_ok(16_000_000, 62_500));
        assert!(!stm32_frequency_ok(16_000_000, 62_501));
        assert!(!stm32_frequency_ok(16_000_000, 0));
        assert!(stm32_frequency_ok(16_000_000, 1));
    }

    #[test]
    fn from_frequency_pulse() {
        // 50 Hz, 64 000 counts (16 MHz / 5 / 64 000): 20 ms per period.
        let tb = Timebase::from_frequency(50, 64_000);
        assert_eq!(tb.compare(Output::PulseUs(1_000)), Some(3_200));
        assert_eq!(tb.compare(Output::PulseUs(20_000)), Some(64_000));
        assert_eq!(tb.compare(Output::PulseUs(20_001)), None);
        assert_eq!(tb.compare(Output::Duty(255)), Some(64_000));
    }

    #[test]
    fn stm32_full_duty_at_the_frequencies_where_arr_is_ffff() {
        // The three frequencies on a 170 MHz timer clock: ARR = 0xFFFF, so the HAL's
        // maximum duty is 65 536, one more than a 16-bit compare register holds.
        for hz in [1u16, 2, 1_297] {
            let (_, arr) = stm32_psc_arr(170_000_000, u32::from(hz)).unwrap();
            assert_eq!(arr, 0xFFFF, "{hz} Hz");
            let tb = Timebase::from_frequency(u32::from(hz), arr + 1);
            let c = tb.compare(Output::Duty(255)).unwrap();
            assert_eq!(c, 65_536);
            assert_eq!(stm32_compare(c, arr + 1), 0xFFFF);
        }
    }

    /// embassy-stm32 0.6's own arithmetic, in 64 bits: `SimplePwm::set_frequency` (edge-aligned)
    /// and `calculate_psc_arr` with 16 ARR bits, rounding to the slower frequency.
    fn hal_psc_arr(timer_hz: u32, hz: u32) -> Option<(u32, u32)> {
        let clocks = u64::from(timer_hz) / u64::from(hz);
        let max_arr: u64 = (1 << 16) - 1;
        let psc = u16::try_from(clocks.saturating_sub(1) / (max_arr + 1)).ok()?;
        let psc1 = u64::from(psc) + 1;
        let arr = clocks.div_ceil(psc1).saturating_sub(1).clamp(1, max_arr);
        Some((u32::from(psc), u32::try_from(arr).unwrap()))
    }

    /// The 32-bit prescaler and ARR equal the HAL's at every u16 frequency, on the timer clocks
    /// of the G431 (170 MHz) and the C011 (48 MHz) and a few others, and at the frequencies
    /// above u16 that a failed change restores (what the timer reported before).
    #[test]
    fn stm32_psc_arr_is_the_hals() {
        for timer_hz in [
            170_000_000,
            48_000_000,
            16_000_000,
            150_000_000,
            1_000_000,
            u32::MAX,
        ] {
            for hz in (1..=u32::from(u16::MAX)).chain([65_536, 100_000, 1_000_000, timer_hz]) {
                assert_eq!(
                    stm32_psc_arr(timer_hz, hz),
                    hal_psc_arr(timer_hz, hz),
                    "{timer_hz} Hz timer, {hz} Hz"
                );
            }
        }
        assert_eq!(stm32_psc_arr(170_000_000, 0), None);
        // 1 Hz on a 170 MHz timer: PSC 2593, ARR 65 535 (2594 · 65 536 ≥ 170 000 000).
        assert_eq!(stm32_psc_arr(170_000_000, 1), Some((2_593, 0xFFFF)));
        // The default 1 kHz: 170 000 clocks, PSC 2, ARR 56 666.
        assert_eq!(stm32_psc_arr(170_000_000, 1_000), Some((2, 56_666)));
        // 32-bit clock counts always fit: u32::MAX clocks take PSC 65 535, ARR 65 535.
        assert_eq!(stm32_psc_arr(u32::MAX, 1), Some((0xFFFF, 0xFFFF)));
    }

    /// Every frequency the protocol can ask for (u16) that the adapter accepts, on the timer
    /// clocks of the G431 (170 MHz) and the C011 (48 MHz), with every duty: the compare value
    /// written is never above the HAL's maximum nor 0xFFFF, and full duty stays full but for
    /// at most one count.
    #[test]
    fn stm32_every_frequency_and_duty_gives_a_compare_the_hal_accepts() {
        for timer_hz in [170_000_000, 48_000_000] {
            for hz in 1..=u16::MAX {
                if !stm32_frequency_ok(timer_hz, hz) {
                    continue;
                }
                let (psc, arr) = stm32_psc_arr(timer_hz, u32::from(hz)).unwrap();
                let max_duty = arr + 1;
                // What SimplePwm::get_frequency reports (timer/low_level.rs 577-588).
                let reported = timer_hz / arr / (psc + 1);
                let tb = Timebase::from_frequency(reported, max_duty);
                for d in 0..=255u8 {
                    let c = stm32_compare(tb.compare(Output::Duty(d)).unwrap(), max_duty);
                    assert!(
                        c <= max_duty && c <= STM32_MAX_COMPARE,
                        "{timer_hz} {hz} {d}"
                    );
                    if d == 255 {
                        assert!(c + 1 >= max_duty, "{timer_hz} {hz}");
                    }
                    if d == 0 {
                        assert_eq!(c, 0);
                    }
                }
            }
        }
    }

    /// The 64-bit arithmetic the functions above had before they avoided 64-bit division.
    fn reference_slice(sys_hz: u32, hz: u16) -> Option<SliceTiming> {
        if hz == 0 {
            return None;
        }
        let period16 = u64::from(sys_hz) * 16 / u64::from(hz);
        let div16 = period16.div_ceil(65_536).max(16);
        if div16 > 4_095 {
            return None;
        }
        let counts = (period16 + div16 / 2) / div16;
        if counts < u64::from(MIN_COUNTS) || counts > 65_536 {
            return None;
        }
        Some(SliceTiming {
            div16: div16 as u16,
            top: (counts - 1) as u16,
        })
    }

    fn reference_compare(tb: &Timebase, out: Output) -> Option<u32> {
        match out {
            Output::Duty(d) => Some(((u64::from(d) * u64::from(tb.counts) + 127) / 255) as u32),
            Output::PulseUs(us) => {
                let den = u64::from(tb.tick_den.max(1)) * 1_000_000;
                let c = (u64::from(us) * tb.tick_num + den / 2) / den;
                u32::try_from(c).ok().filter(|&c| c <= tb.counts)
            }
        }
    }

    #[test]
    fn div_round_edges() {
        assert_eq!(div_round(0, 7), 0);
        assert_eq!(div_round(7, 2), 4);
        assert_eq!(div_round(5, 2), 3);
        assert_eq!(div_round(4, 3), 1);
        assert_eq!(div_round(5, 3), 2);
        assert_eq!(div_round(u64::MAX, 1), u64::MAX);
        assert_eq!(div_round(u64::MAX, u32::MAX), 4_294_967_297);
        assert_eq!(div_round(1, 0), u64::MAX);
    }

    /// Every frequency on the RP2040's clocks: the same slice setup as 64-bit division gives.
    #[test]
    fn rp2040_slice_matches_64_bit_division_at_every_frequency() {
        for sys_hz in [125_000_000, 133_000_000, 48_000_000, 10_000_000] {
            for hz in 0..=u16::MAX {
                assert_eq!(
                    rp2040_slice(sys_hz, hz),
                    reference_slice(sys_hz, hz),
                    "{sys_hz} {hz}"
                );
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn div_round_is_rounded_division(n in proptest::num::u64::ANY, d in 1..=u32::MAX) {
            let d64 = u64::from(d);
            let (q, r) = (n / d64, n % d64);
            let expected = if r >= d64 - r { q + 1 } else { q };
            proptest::prop_assert_eq!(div_round(n, d), expected);
        }

        /// Duties and pulse widths on RP2040 slices at any frequency: as 64-bit division.
        #[test]
        fn rp2040_compares_match_64_bit_division(hz in 8..=u16::MAX, us in 0..=u16::MAX, d in 0..=255u8) {
            let t = rp2040_slice(125_000_000, hz).unwrap();
            let tb = Timebase::rp2040(125_000_000, t);
            proptest::prop_assert_eq!(tb.compare(Output::Duty(d)), reference_compare(&tb, Output::Duty(d)));
            proptest::prop_assert_eq!(tb.compare(Output::PulseUs(us)), reference_compare(&tb, Output::PulseUs(us)));
        }

        /// The same on STM32 timers (170 and 48 MHz).
        #[test]
        fn stm32_compares_match_64_bit_division(hz in 1..=u16::MAX, us in 0..=u16::MAX, d in 0..=255u8, fast in proptest::bool::ANY) {
            let timer_hz = if fast { 170_000_000 } else { 48_000_000 };
            proptest::prop_assume!(stm32_frequency_ok(timer_hz, hz));
            let (psc, arr) = stm32_psc_arr(timer_hz, u32::from(hz)).unwrap();
            let tb = Timebase::from_frequency(timer_hz / arr / (psc + 1), arr + 1);
            proptest::prop_assert_eq!(tb.compare(Output::Duty(d)), reference_compare(&tb, Output::Duty(d)));
            proptest::prop_assert_eq!(tb.compare(Output::PulseUs(us)), reference_compare(&tb, Output::PulseUs(us)));
        }

        /// Pulse widths, at any accepted frequency: a pulse that fits gives a compare value the
        /// HAL accepts.
        #[test]
        fn stm32_pulse_widths_give_compares_the_hal_accepts(
            hz in 1..=u16::MAX,
            us in 0..=u16::MAX,
            fast in proptest::bool::ANY,
        ) {
            let timer_hz = if fast { 170_000_000 } else { 48_000_000 };
            proptest::prop_assume!(stm32_frequency_ok(timer_hz, hz));
            let (psc, arr) = stm32_psc_arr(timer_hz, u32::from(hz)).unwrap();
            let tb = Timebase::from_frequency(timer_hz / arr / (psc + 1), arr + 1);
            if let Some(c) = tb.compare(Output::PulseUs(us)) {
                let c = stm32_compare(c, arr + 1);
                proptest::prop_assert!(c <= arr + 1 && c <= STM32_MAX_COMPARE);
            }
        }
    }
}
