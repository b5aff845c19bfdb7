//! # x10-store: one byte kept in NOR flash, across power cuts
//!
//! A daughterboard keeps its bus address in its own flash ([`Record`]). A power cut at any
//! moment of a [`Record::write`] (during a program, during an erase, between the two) leaves
//! the old value or the new one: never none, never garbage. Writes are spread over the pages
//! (wear levelling): a change programs one 8-byte slot, and a page is erased only when the
//! active page is full, so with two 4 KiB pages (the RP2040) a page is erased once every 512
//! changes, with two 2 KiB pages (the STM32 chips) once every 256.
//!
//! The crate is generic over `embedded_storage::nor_flash::NorFlash` (blocking), which
//! embassy-rp's and embassy-stm32's `Flash` drivers implement. The feature `mem` adds
//! [`mem::MemFlash`], an in-memory NOR flash that cuts the power at a chosen step, leaving
//! the partly programmed or partly erased bytes real NOR flash can leave: the tests use it,
//! and so can a simulator.
//!
//! ## The slot: 8 bytes
//!
//! | byte | 0 | 1 | 2 | 3 | 4 | 5 | 6 | 7 |
//! |---|---|---|---|---|---|---|---|---|
//! | value | `0x58` (`X`, the format) | the value | sequence, low byte | sequence, high byte | `0xA7` (`!0x58`) | `!value` | `!seq_lo` | `!seq_hi` |
//!
//! Example: value `0x11` with sequence number 5 is `58 11 05 00 A7 EE FA FF`.
//!
//! Bytes 4 to 7 are the complement of bytes 0 to 3, so a valid slot has exactly 32 bits set.
//! NOR flash moves bits one way at a time: programming only clears bits (1 to 0), erasing
//! only sets them (0 to 1). A program or an erase cut short leaves each bit either where it
//! was or where the operation was taking it, so the cut slot differs from both its start and
//! its goal in one direction only, and its number of set bits changes: it is not a valid slot
//! (this is the complement code's detection of every unidirectional error). So:
//!
//! * a program cut short leaves no valid slot (an erased slot, all `0xFF`, is not valid
//!   either): the newest valid slot is still the old value;
//! * an erase cut short only turns valid slots invalid, and the page erased is never the one
//!   holding the newest record;
//! * the new value exists from the moment its slot's last bit is programmed.
//!
//! ## Where the slots go
//!
//! The record owns `page_count` (at least 2) whole erase pages from `first_page_offset`.
//! Every valid slot carries a 16-bit sequence number; the newest (in serial-number arithmetic,
//! so the number may wrap) is the value. A write programs the first erased slot after the
//! newest one in the same page (with no valid slot anywhere: the first erased slot of page
//! 0); when that page has none left, it erases the next page (in turn) and programs that
//! page's first slot. Slots that are neither valid nor erased (the leftovers of a cut program)
//! are skipped. A write of the value already stored programs nothing.
//!
//! [`Record::append_only`] keeps the record in memory that is never erased (one-time
//! programmable): the same slots, one area, and [`StoreError::Full`] when its last slot is
//! used.
//!
//! Not covered: bits left "weak" by a cut (reading sometimes 0, sometimes 1), and on the
//! STM32 chips an ECC double error in a double word whose programming was cut (the chip
//! raises an NMI when such a word is read): see `docs/boards.md`.
#![no_std]

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};

#[cfg(feature = "mem")]
pub mod mem;

/// The bytes of one slot.
pub const SLOT: usize = 8;

/// The first byte of every slot: the format (`X`).
pub const TAG: u8 = 0x58;

/// Why the record could not be read or written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError {
    /// The flash driver failed (a power cut in [`mem::MemFlash`] is `Other`).
    Flash(NorFlashErrorKind),
    /// The pages do not suit the flash: fewer than 2, not aligned to its erase size, beyond
    /// its capacity, an erase page smaller than two slots or with more than 16 383 slots in
    /// all, or a write or read size that does not divide [`SLOT`].
    Geometry,
    /// A programmed slot did not read back as written (the slot is skipped from then on).
    Verify,
    /// An append-only record ([`Record::append_only`], one-time-programmable memory) has no
    /// erased slot left: the value stored stays, a new one cannot be kept.
    Full,
}

impl<E: NorFlashError> From<E> for StoreError {
    fn from(e: E) -> Self {
        StoreError::Flash(e.kind())
    }
}

/// The 8 bytes of a slot holding `value` with sequence number `seq`.
#[must_use]
pub fn encode(value: u8, seq: u16) -> [u8; SLOT] {
    let [lo, hi] = seq.to_le_bytes();
    [TAG, value, lo, hi, !TAG, !value, !lo, !hi]
}

/// The value and sequence number of a valid slot; `None` for anything else (erased, cut
/// short, another format).
#[must_use]
pub fn decode(slot: &[u8; SLOT]) -> Option<(u8, u16)> {
    let ok = slot[0] == TAG && (0..4).all(|i| slot[i] == !slot[i + 4]);
    ok.then(|| (slot[1], u16::from_le_bytes([slot[2], slot[3]])))
}

/// Whether sequence number `a` is newer than `b` (serial-number arithmetic: valid slots are
/// never more than 16 383 numbers apart, see [`StoreError::Geometry`]).
#[must_use]
pub fn newer(a: u16, b: u16) -> bool {
    let d = a.wrapping_sub(b);
    d != 0 && d < 0x8000
}

/// Where a slot is: its page (0-based, within the record) and its index in the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct At {
    page: u32,
    slot: u32,
}

/// The newest valid slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Newest {
    at: At,
    value: u8,
    seq: u16,
}

/// One byte in flash that survives power cuts (see the crate's documentation).
pub struct Record<F> {
    flash: F,
    base: u32,
    pages: u32,
    /// Bytes per page: the erase size, or the whole area of an append-only record.
    page_size: u32,
    /// Whether pages may be erased (not in one-time-programmable memory).
    erasable: bool,
    /// The newest valid slot, after a scan.
    newest: Option<Newest>,
    /// The first erased slot after [`Record::newest`] in its page, after a scan.
    free: Option<At>,
    /// Whether `newest` and `free` are known (false after a flash error: the next call scans).
    scanned: bool,
}

impl<F: NorFlash> Record<F> {
    /// The record on `page_count` erase pages of `flash` from byte `first_page_offset`; scans
    /// them for the newest value.
    ///
    /// # Errors
    /// [`StoreError::Geometry`] for pages that do not suit the flash; the flash's read errors.
    pub fn new(flash: F, first_page_offset: u32, page_count: u32) -> Result<Self, StoreError> {
        let erase = F::ERASE_SIZE as u64;
        let end = u64::from(first_page_offset) + u64::from(page_count) * erase;
        let slots = u64::from(page_count) * erase / SLOT as u64;
        if page_count < 2
            || erase < 2 * SLOT as u64
            || !erase.is_multiple_of(SLOT as u64)
            || !u64::from(first_page_offset).is_multiple_of(erase)
            || end > flash.capacity() as u64
            || slots > 0x3FFF
            || !SLOT.is_multiple_of(F::WRITE_SIZE)
            || !SLOT.is_multiple_of(F::READ_SIZE)
        {
            return Err(StoreError::Geometry);
        }
        Self::open(flash, first_page_offset, page_count, erase as u32, true)
    }

    /// An append-only record on the `len` bytes of `flash` from `offset`, for memory that is
    /// never erased (the STM32C011's one-time-programmable area): each change takes the next
    /// slot, `len / 8` changes in the chip's life; then [`Record::write`] answers
    /// [`StoreError::Full`] and the value stored stays.
    ///
    /// # Errors
    /// [`StoreError::Geometry`] for an area not of whole slots, beyond the flash, or not
    /// aligned to its write size; the flash's read errors.
    pub fn append_only(flash: F, offset: u32, len: u32) -> Result<Self, StoreError> {
        if len < SLOT as u32
            || !len.is_multiple_of(SLOT as u32)
            || !offset.is_multiple_of(SLOT as u32)
            || u64::from(offset) + u64::from(len) > flash.capacity() as u64
            || len / SLOT as u32 > 0x3FFF
            || !SLOT.is_multiple_of(F::WRITE_SIZE)
            || !SLOT.is_multiple_of(F::READ_SIZE)
        {
            return Err(StoreError::Geometry);
        }
        Self::open(flash, offset, 1, len, false)
    }

    fn open(
        flash: F,
        base: u32,
        pages: u32,
        page_size: u32,
        erasable: bool,
    ) -> Result<Self, StoreError> {
        let mut r = Record {
            flash,
            base,
            pages,
            page_size,
            erasable,
            newest: None,
            free: None,
            scanned: false,
        };
        r.scan()?;
        Ok(r)
    }

    /// The value stored, `None` if there is none (a new chip, or flash never written by this
    /// format).
    ///
    /// # Errors
    /// The flash's read errors (only after an earlier error, when the pages are scanned again).
    pub fn read(&mut self) -> Result<Option<u8>, StoreError> {
        self.scan()?;
        Ok(self.newest.map(|n| n.value))
    }

    /// Stores `value`: afterwards [`Record::read`] gives it, now and after any reset. A value
    /// equal to the one stored programs nothing.
    ///
    /// # Errors
    /// The flash's errors; [`StoreError::Verify`] when the slot did not read back as written;
    /// [`StoreError::Full`] (append-only records). After an error (a power cut included) the record holds the old value or the new one.
    pub fn write(&mut self, value: u8) -> Result<(), StoreError> {
        self.scan()?;
        if self.newest.map(|n| n.value) == Some(value) {
            return Ok(());
        }
        let seq = self.newest.map_or(0, |n| n.seq.wrapping_add(1));
        // The next call scans again.
        self.scanned = false;
        let at = match self.free {
            Some(at) => at,
            None if !self.erasable => return Err(StoreError::Full),
            None => {
                let page = self.newest.map_or(0, |n| (n.at.page + 1) % self.pages);
                let from = self.base + page * self.page_size;
                self.flash.erase(from, from + self.page_size)?;
                At { page, slot: 0 }
            }
        };
        let bytes = encode(value, seq);
        let off = self.offset(at);
        self.flash.write(off, &bytes)?;
        let mut back = [0u8; SLOT];
        self.flash.read(off, &mut back)?;
        if back != bytes {
            return Err(StoreError::Verify);
        }
        // Written: the next call scans again (it finds this slot the newest, and the first
        // erased slot after it), which costs reads but no code of its own here.
        Ok(())
    }

    /// The flash, back (for a simulator that keeps it across a reset).
    pub fn into_inner(self) -> F {
        self.flash
    }

    /// The flash, to look at (its contents changed behind the record's back are seen only by
    /// a new [`Record`]).
    pub fn flash(&mut self) -> &mut F {
        &mut self.flash
    }

    fn slots_per_page(&self) -> u32 {
        self.page_size / SLOT as u32
    }

    fn offset(&self, at: At) -> u32 {
        self.base + at.page * self.page_size + at.slot * SLOT as u32
    }

    fn slot(&mut self, at: At) -> Result<[u8; SLOT], StoreError> {
        let mut b = [0u8; SLOT];
        self.flash.read(self.offset(at), &mut b)?;
        Ok(b)
    }

    /// Finds the newest valid slot and the first erased slot after it in its page (without a
    /// valid slot: the first erased slot of page 0), unless known.
    fn scan(&mut self) -> Result<(), StoreError> {
        if self.scanned {
            return Ok(());
        }
        let mut newest: Option<Newest> = None;
        let mut free = None;
        for page in 0..self.pages {
            for slot in 0..self.slots_per_page() {
                let at = At { page, slot };
                let b = self.slot(at)?;
                if let Some((value, seq)) = decode(&b) {
                    if newest.is_none_or(|n| newer(seq, n.seq)) {
                        newest = Some(Newest { at, value, seq });
                        free = None;
                    }
                } else if free.is_none()
                    && b == [0xFF; SLOT]
                    && newest.map_or(page == 0, |n| n.at.page == page)
                {
                    free = Some(at);
                }
            }
        }
        self.newest = newest;
        self.free = free;
        self.scanned = true;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slot_is_these_bytes() {
        assert_eq!(
            encode(0x11, 5),
            [0x58, 0x11, 0x05, 0x00, 0xA7, 0xEE, 0xFA, 0xFF]
        );
        assert_eq!(
            encode(0x77, 0x1234),
            [0x58, 0x77, 0x34, 0x12, 0xA7, 0x88, 0xCB, 0xED]
        );
        assert_eq!(decode(&encode(0x11, 5)), Some((0x11, 5)));
        assert_eq!(decode(&[0xFF; SLOT]), None);
        assert_eq!(decode(&[0; SLOT]), None);
        // Another tag, complemented properly: another format, not this record.
        assert_eq!(decode(&[0x59, 0x11, 5, 0, 0xA6, 0xEE, 0xFA, 0xFF]), None);
    }

    /// Every state a program or an erase of one slot can be cut in (each bit at its start or
    /// its goal) is invalid, except the goal.
    #[test]
    fn no_cut_short_slot_is_valid() {
        let goals = [
            encode(0x11, 5),
            encode(0x00, 0),
            encode(0xFF, 0xFFFF),
            encode(0x5A, 0x8001),
        ];
        for goal in goals {
            // Program from erased: each byte somewhere between 0xFF and its goal. Byte by
            // byte, with every subset of the bits of the byte being programmed.
            for cut in 0..SLOT {
                for mask in 0..=255u8 {
                    let mut b = [0xFF; SLOT];
                    b[..cut].copy_from_slice(&goal[..cut]);
                    b[cut] = goal[cut] | !mask;
                    assert_eq!(decode(&b).is_some(), b == goal, "{b:02x?}");
                    // Erase from the goal: the same bits set again.
                    let mut e = goal;
                    e[..cut].fill(0xFF);
                    e[cut] = goal[cut] | mask;
                    assert_eq!(decode(&e).is_some(), e == goal, "{e:02x?}");
                }
            }
        }
    }

    #[test]
    fn sequence_numbers_wrap() {
        assert!(newer(1, 0));
        assert!(!newer(0, 1));
        assert!(!newer(7, 7));
        assert!(newer(0, 0xFFFF));
        assert!(newer(0x3FFE, 0xFFFF));
        assert!(!newer(0xFFFF, 0));
    }
}
