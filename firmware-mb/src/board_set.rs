//! [`BoardSet`]: one bit per 7-bit address, the building block of the per-board state (PEC,
//! prepared boards, failsafes kept alive, event counters known). Owns nothing of the
//! motherboard's; a leaf the bookkeeping modules share.

use x10_microcode::Address;

/// Every 7-bit address: the boards the motherboard keeps state for.
pub(crate) const BOARDS: usize = 128;

/// The index of `board` in the per-board arrays (0..[`BOARDS`]).
pub(crate) fn board_index(board: Address) -> usize {
    usize::from(board.get()) % BOARDS
}

/// A set of boards, one bit per address (index 0..[`BOARDS`]) in 32-bit words: no 128-bit
/// shifts on the M0.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoardSet([u32; BOARDS / 32]);

impl BoardSet {
    /// The empty set.
    pub(crate) const fn new() -> BoardSet {
        BoardSet([0; BOARDS / 32])
    }

    /// True when the board at index `i` is in the set.
    pub(crate) fn contains(&self, i: usize) -> bool {
        self.0.get(i / 32).is_some_and(|w| w >> (i % 32) & 1 != 0)
    }

    /// Puts the board at index `i` in the set (`on`) or takes it out.
    pub(crate) fn set(&mut self, i: usize, on: bool) {
        if let Some(w) = self.0.get_mut(i / 32) {
            let bit = 1u32 << (i % 32);
            if on {
                *w |= bit;
            } else {
                *w &= !bit;
            }
        }
    }

    /// The words of the set: bit `i % 32` of word `i / 32` is the board at index `i`.
    pub(crate) fn words(&self) -> &[u32; BOARDS / 32] {
        &self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_bit_per_board() {
        let mut s = BoardSet::new();
        for i in [0, 8, 31, 32, 63, 64, 0x77] {
            s.set(i, true);
        }
        for i in 0..BOARDS {
            assert_eq!(
                s.contains(i),
                matches!(i, 0 | 8 | 31 | 32 | 63 | 64 | 0x77),
                "board {i}"
            );
        }
        s.set(32, false);
        assert!(!s.contains(32));
        assert!(s.contains(31) && s.contains(63));
        assert!(!s.contains(BOARDS));
    }
}
