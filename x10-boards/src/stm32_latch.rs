//! The decisions of the STM32 adapter's edge latches ([`Ports::latch_edges`]), as pure
//! functions: tested on the host, no HAL.
//!
//! A latched pin has its EXTI line set to trigger on both edges with its interrupt masked
//! (`EXTI_IMR1` bit 0: embassy-stm32's EXTI handler never runs for it and so never clears it),
//! and the adapter reads the line's pending bits: one bit for both edges on the G4
//! (`EXTI_PR1`), one per direction on the C0 (`EXTI_RPR1`, `EXTI_FPR1`). The reference
//! manuals are not at hand here to say whether a masked line still sets its pending bit, so
//! the adapter also compares the pin's level with the level at the previous take: a change
//! counts as an edge even when no pending bit says so. Either way no level change is missed
//! (the runtime no longer samples a latched pin), and, when the pending bits do latch, a
//! pulse shorter than the 200 µs between two looks is counted too.
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

#[cfg(test)]
mod tests {
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
