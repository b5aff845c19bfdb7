//! The decisions of the STM32 adapter's edge latches ([`Ports::latch_edges`]), as pure
//! functions: tested on the host, no HAL.
//!
//! A latched pin has its EXTI line set to trigger on both edges with its interrupt unmasked
//! (`EXTI_IMR1`), so every edge sets the line's pending bits: one bit for both edges on the G4
//! (`EXTI_PR1`), one per direction on the C0 (`EXTI_RPR1`, `EXTI_FPR1`); they stay set until
//! the adapter clears them. With the line masked (before issue 21 item 4) the pending bits do
//! not latch, and the latches were 200 µs level polls that missed short pulses.
//!
//! Unmasking alone would hang the chip: embassy-stm32 0.6 enables every EXTI vector in the
//! NVIC at start-up (`exti/mod.rs` 547-558, from `init`, `lib.rs` 717-718), and the images
//! bind no EXTI handler, so the first edge would enter cortex-m-rt 0.7's `DefaultHandler_` (an
//! endless loop). So `latch_edges` first masks, in the NVIC, the vector that serves the line
//! ([`exti_vector`]), then unmasks the line in the EXTI: the pending bits latch and no
//! interrupt is taken (a pending but masked NVIC interrupt does not wake `WFE` either, as
//! `SEVONPEND` is off). The adapter also compares the pin's level with the level at the
//! previous take: a change counts as an edge even when no pending bit says so.
//!
//! [`Ports::latch_edges`]: x10_hal::ports::Ports::latch_edges

use x10_hal::ports::{EdgeCount, PortError};

/// What a line's pending bits said at one look.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pending {
    /// One bit per direction (C0: `EXTI_RPR1`, `EXTI_FPR1`).
    Split {
        /// A rising edge since the bits were last cleared.
        rising: bool,
        /// A falling edge since the bits were last cleared.
        falling: bool,
    },
    /// One bit for both (G4: `EXTI_PR1`).
    Either(bool),
}

/// The edges of a pin whose level was `before` at the previous take and is `now`, with its
/// pending bits `p` (read and cleared just before `now` was read). At least one edge per
/// direction the bits or the levels show; several edges of one direction between two takes
/// count as one.
#[must_use]
pub fn edges(p: Pending, before: bool, now: bool) -> EdgeCount {
    let rose = !before && now;
    let fell = before && !now;
    let (rising, falling) = match p {
        Pending::Split { rising, falling } => (rising || rose, falling || fell),
        // One bit: the levels give the direction; a bit with equal levels is a whole pulse
        // (an even number of edges, at least one of each).
        Pending::Either(p) => (rose || (p && before == now), fell || (p && before == now)),
    };
    EdgeCount {
        rising: u16::from(rising),
        falling: u16::from(falling),
    }
}

/// True when the pending bits or the levels show an edge not taken yet (what `wait_edge`
/// looks for).
#[must_use]
pub fn waiting(p: Pending, before: bool, now: bool) -> bool {
    !edges(p, before, now).is_none()
}

/// Whether a pin of GPIO port `port` may latch on its EXTI line, which the pin of port
/// `holder` holds (`None`: free). The 16 lines are shared by pin number across ports: PA4
/// and PB4 are both line 4.
///
/// # Errors
/// [`PortError::Unsupported`] when another port's pin holds the line (that pin is then
/// sampled by the runtime instead).
pub fn claim(holder: Option<u8>, port: u8) -> Result<(), PortError> {
    match holder {
        Some(h) if h != port => Err(PortError::Unsupported),
        _ => Ok(()),
    }
}

/// The first EXTI line of each EXTI interrupt vector of the G4, in the order of the
/// vectors EXTI0, EXTI1, EXTI2, EXTI3, EXTI4, EXTI9_5, EXTI15_10 (stm32-metapac 21,
/// `stm32g431cb`: interrupts 6 to 10, 23, 40).
pub const G4_VECTOR_LINES: [u8; 7] = [0, 1, 2, 3, 4, 5, 10];

/// The first EXTI line of each EXTI interrupt vector of the C0: EXTI0_1, EXTI2_3, EXTI4_15
/// (stm32-metapac 21, `stm32c011f6`: interrupts 5 to 7).
pub const C0_VECTOR_LINES: [u8; 3] = [0, 2, 4];

/// The index, in a chip's list of EXTI vectors whose first lines are `first_lines`
/// (ascending), of the vector that serves EXTI line `line` (0 to 15): the one the adapter
/// masks in the NVIC before it unmasks the line.
#[must_use]
pub fn exti_vector(first_lines: &[u8], line: usize) -> Option<usize> {
    if line > 15 {
        return None;
    }
    first_lines.iter().rposition(|&f| usize::from(f) <= line)
}

/// The bits a latched line sets in `EXTI_IMR1` (interrupt unmasked, so the pending bits
/// latch), `EXTI_RTSR1` and `EXTI_FTSR1` (both edges): its own bit in all three.
#[must_use]
pub fn exti_line_bits(line: usize) -> Option<[u32; 3]> {
    let bit = 1u32
        .checked_shl(u32::try_from(line).ok()?)
        .filter(|_| line < 16)?;
    Some([bit; 3])
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    const fn n(rising: u16, falling: u16) -> EdgeCount {
        EdgeCount { rising, falling }
    }

    #[test]
    fn split_bits_count_each_direction() {
        let split = |rising, falling| Pending::Split { rising, falling };
        assert_eq!(edges(split(false, false), false, false), n(0, 0));
        assert_eq!(edges(split(true, false), false, true), n(1, 0));
        assert_eq!(edges(split(false, true), true, false), n(0, 1));
        // A pulse between two looks: both bits, the level back where it was.
        assert_eq!(edges(split(true, true), false, false), n(1, 1));
        // The bits did not latch (masked line), the level changed: still one edge.
        assert_eq!(edges(split(false, false), false, true), n(1, 0));
        assert_eq!(edges(split(false, false), true, false), n(0, 1));
    }

    #[test]
    fn one_bit_takes_the_direction_from_the_levels() {
        use Pending::Either;
        assert_eq!(edges(Either(false), true, true), n(0, 0));
        assert_eq!(edges(Either(true), false, true), n(1, 0));
        assert_eq!(edges(Either(true), true, false), n(0, 1));
        // Equal levels with the bit set: a whole pulse (or several).
        assert_eq!(edges(Either(true), false, false), n(1, 1));
        assert_eq!(edges(Either(true), true, true), n(1, 1));
        // No bit but a level change: one edge.
        assert_eq!(edges(Either(false), false, true), n(1, 0));
        assert!(!waiting(Either(false), true, true));
        assert!(waiting(Either(false), true, false));
        assert!(waiting(Either(true), true, true));
    }

    /// Issue 21 item 4: a latched line is unmasked in the EXTI (before, `IMR1` was cleared and
    /// the pending bits never latched) once its NVIC vector is masked.
    #[test]
    fn a_latched_line_is_unmasked_after_its_vector_is_masked() {
        let imr = |line| exti_line_bits(line).map(|b| b[0]);
        assert_eq!(imr(0), Some(1));
        assert_eq!(imr(7), Some(1 << 7));
        assert_eq!(exti_line_bits(15), Some([1 << 15; 3]));
        assert_eq!(exti_line_bits(16), None);
        // G4: EXTI0..EXTI4 one line each, EXTI9_5, EXTI15_10.
        let g4: std::vec::Vec<_> = (0..16).map(|l| exti_vector(&G4_VECTOR_LINES, l)).collect();
        assert_eq!(
            g4,
            [0, 1, 2, 3, 4, 5, 5, 5, 5, 5, 6, 6, 6, 6, 6, 6].map(Some)
        );
        // C0: EXTI0_1, EXTI2_3, EXTI4_15.
        let c0: std::vec::Vec<_> = (0..16).map(|l| exti_vector(&C0_VECTOR_LINES, l)).collect();
        assert_eq!(
            c0,
            [0, 0, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2].map(Some)
        );
        assert_eq!(exti_vector(&C0_VECTOR_LINES, 16), None);
    }

    #[test]
    fn a_line_belongs_to_one_port() {
        assert_eq!(claim(None, 1), Ok(()));
        assert_eq!(claim(Some(1), 1), Ok(()));
        assert_eq!(claim(Some(0), 1), Err(PortError::Unsupported));
    }

    #[test]
    fn no_two_latchable_pins_of_a_map_share_a_line_unless_refused() {
        // The G431's sensor pins are on eight different lines; the C011's sensor pins too
        // (PC14, PC15, PA3, PA4, PA11, PA12).
        for map in [crate::pins::G431, crate::pins::C011] {
            let mut lines = 0u32;
            for s in map.sensors {
                for name in [s.a, s.b] {
                    let line: u32 = name.get(2..).and_then(|d| d.parse().ok()).expect(name);
                    assert_eq!(lines & (1 << line), 0, "{} line {line} twice", map.board);
                    lines |= 1 << line;
                }
            }
        }
    }
}
