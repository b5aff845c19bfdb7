//! The decisions of the motherboard images' defmt logger ([`crate::usb_log`]), pure and tested
//! on the host: where bytes go in the RTT up-channel's ring, how much room the host left, and
//! how a defmt frame is cut into the USB link's `Log` messages.
//!
//! The ring is SEGGER RTT's, as defmt-rtt 1.x fills it (its `channel.rs`, read for this):
//! `write` is the target's cursor, `read` the host's; the ring is empty when they are equal
//! and full when `write + 1 == read` (one byte always stays free). Without a host (mode
//! "no block, trim", 1, the mode the image starts in) the target writes on and old bytes are
//! overwritten; with one (mode "block if full", 2, which `probe-rs run` sets) it waits for
//! room. The logger writes every encoded byte (defmt's rzCOBS frames, each ended by `0x00`)
//! to the ring exactly as defmt-rtt does, so `probe-rs run`, `defmt-print` and the emulator
//! rig read the same log.

/// Mode bits of the up-channel's flags.
pub const MODE_MASK: u32 = 0b11;
/// The host reads and wants no byte lost: wait for room.
pub const MODE_BLOCK_IF_FULL: u32 = 2;
/// No host (yet): write on, overwrite what was not read.
pub const MODE_NON_BLOCKING_TRIM: u32 = 1;

/// Free bytes in a ring of `size` bytes between the target's `write` and the host's `read`
/// cursors (one byte always stays free, so a full ring is not read as an empty one).
pub const fn room(read: usize, write: usize, size: usize) -> usize {
    if read > write {
        read - write - 1
    } else {
        size - write - 1 + read
    }
}

/// True when the flags say a host reads the channel and wants no byte lost.
pub const fn host_waits(flags: u32) -> bool {
    flags & MODE_MASK == MODE_BLOCK_IF_FULL
}

/// Copies as much of `bytes` as `limit` allows into `ring` from cursor `write`, wrapping at
/// the end; returns how many bytes were copied and the new cursor. `limit` is [`room`] when
/// the host waits, the ring's size when it does not (at most one lap per call, as defmt-rtt).
/// A cursor outside the ring (a host that wrote garbage) copies nothing.
pub fn put(ring: &mut [u8], write: usize, bytes: &[u8], limit: usize) -> (usize, usize) {
    let size = ring.len();
    if write >= size {
        return (0, 0);
    }
    let n = bytes.len().min(limit).min(size);
    let mut at = write;
    for &b in bytes.iter().take(n) {
        if let Some(slot) = ring.get_mut(at) {
            *slot = b;
        }
        at += 1;
        if at == size {
            at = 0;
        }
    }
    (n, at)
}

/// Collects the bytes of one defmt frame for the USB link: they leave in pieces of at most
/// `N` bytes (a long frame in several), the rest when the frame ends.
pub struct Chunker<const N: usize> {
    buf: [u8; N],
    len: usize,
}

impl<const N: usize> Default for Chunker<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Chunker<N> {
    /// Empty.
    pub const fn new() -> Self {
        Chunker {
            buf: [0; N],
            len: 0,
        }
    }

    /// Takes encoded bytes; hands each full piece to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut impl FnMut(&[u8])) {
        for &b in bytes {
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            }
            if self.len == N {
                self.end(out);
            }
        }
    }

    /// Hands what is left to `out` (nothing when empty).
    pub fn end(&mut self, out: &mut impl FnMut(&[u8])) {
        let n = core::mem::take(&mut self.len);
        if let Some(piece) = self.buf.get(..n).filter(|p| !p.is_empty()) {
            out(piece);
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;
    use std::vec::Vec;

    #[test]
    fn room_leaves_one_byte_free() {
        assert_eq!(room(0, 0, 16), 15); // empty
        assert_eq!(room(5, 5, 16), 15);
        assert_eq!(room(0, 15, 16), 0); // full
        assert_eq!(room(5, 4, 16), 0);
        assert_eq!(room(10, 5, 16), 4);
        assert_eq!(room(5, 10, 16), 10);
        // Against the invariant room = size - 1 - bytes waiting, everywhere.
        for read in 0..16 {
            for write in 0..16 {
                assert_eq!(room(read, write, 16), 15 - (write + 16 - read) % 16);
            }
        }
    }

    #[test]
    fn put_wraps_at_the_end_of_the_ring() {
        let mut ring = [0u8; 8];
        assert_eq!(put(&mut ring, 6, &[1, 2, 3, 4], 8), (4, 2));
        assert_eq!(ring, [3, 4, 0, 0, 0, 0, 1, 2]);
        // Limited by the host's room: only what fits.
        assert_eq!(put(&mut ring, 2, &[9, 9, 9], 2), (2, 4));
        assert_eq!(ring, [3, 4, 9, 9, 0, 0, 1, 2]);
        // One lap at most per call; the cursor comes back where it started.
        let mut ring = [0u8; 4];
        assert_eq!(put(&mut ring, 1, &[1, 2, 3, 4, 5, 6], 4), (4, 1));
        assert_eq!(ring, [4, 1, 2, 3]);
        // A cursor the host broke: nothing.
        assert_eq!(put(&mut ring, 4, &[7], 4), (0, 0));
        assert_eq!(ring, [4, 1, 2, 3]);
    }

    #[test]
    fn the_host_waits_only_in_blocking_mode() {
        assert!(host_waits(2));
        assert!(host_waits(0x102));
        assert!(!host_waits(MODE_NON_BLOCKING_TRIM));
        assert!(!host_waits(0));
        assert!(!host_waits(3));
    }

    #[test]
    fn a_frame_leaves_in_pieces_of_at_most_n_bytes() {
        let mut c: Chunker<4> = Chunker::new();
        let mut got: Vec<Vec<u8>> = Vec::new();
        let mut out = |p: &[u8]| got.push(p.to_vec());
        c.push(&[1, 2], &mut out);
        c.push(&[3, 4, 5, 6, 7, 8, 9], &mut out);
        c.end(&mut out);
        c.end(&mut out); // nothing left: no empty piece
        c.push(&[0], &mut out);
        c.end(&mut out);
        assert_eq!(got, [vec![1, 2, 3, 4], vec![5, 6, 7, 8], vec![9], vec![0]]);
    }
}
