//! The record against power cuts at every step, wear, garbage and wrong geometry.

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use x10_store::mem::MemFlash;
use x10_store::{encode, Record, StoreError, SLOT};

/// Two pages of 8 slots, written 8 bytes at a time (as the STM32 chips do).
type Small8 = MemFlash<128, 8, 64>;
/// Two pages of 8 slots, written a byte at a time (as the RP2040 does).
type Small1 = MemFlash<128, 1, 64>;
/// The RP2040's record: two 4 KiB sectors, byte writes.
type Rp2040 = MemFlash<8192, 1, 4096>;
/// The STM32G431's and C011's record: two 2 KiB pages, double-word writes.
type Stm32 = MemFlash<4096, 8, 2048>;

/// The address changes of the sequence (each differs from the one before): 20 writes, so
/// two pages of 8 slots are each erased and filled more than once.
const CHANGES: [u8; 20] = [
    0x09, 0x10, 0x11, 0x12, 0x09, 0x77, 0x08, 0x30, 0x31, 0x32, 0x33, 0x34, 0x35, 0x36, 0x37, 0x38,
    0x39, 0x3A, 0x3B, 0x09,
];

/// Partial states of the byte being changed when the power goes: none of its bits changed,
/// one, the low half, the high half, every other one, all but one, all.
const MASKS: [u8; 7] = [0x00, 0x01, 0x0F, 0xF0, 0x55, 0xFE, 0xFF];

/// The flash's step count before and after each write of [`CHANGES`], without a cut.
fn steps_of_each_write<const S: usize, const W: usize, const E: usize>() -> Vec<(u64, u64)> {
    let mut rec = Record::new(MemFlash::<S, W, E>::new(), 0, 2).unwrap();
    CHANGES
        .iter()
        .map(|&v| {
            let before = rec.flash().steps();
            rec.write(v).unwrap();
            (before, rec.flash().steps())
        })
        .collect()
}

/// Cuts the power at every step of every write of [`CHANGES`], with each of [`MASKS`]; after
/// each cut: power on, a new `Record` (a reset), and the value must be exactly the new one if
/// the slot's bytes all reached their goal, else exactly the old one; then the write is done again and the sequence finished. Returns
/// (cuts, cuts that left the old value, cuts that left the new one).
fn cut_everywhere<const S: usize, const W: usize, const E: usize>() -> (u32, u32, u32) {
    let writes = steps_of_each_write::<S, W, E>();
    let total = writes.last().unwrap().1;
    let (mut cuts, mut old, mut new) = (0, 0, 0);
    for mask in MASKS {
        for cut in 0..total {
            let (i, &(_, end)) = writes
                .iter()
                .enumerate()
                .find(|(_, &(b, e))| b <= cut && cut < e)
                .unwrap();
            let before = i.checked_sub(1).map(|j| CHANGES[j]);
            // The slot is the last 8 steps of the write; it holds the new value once each
            // byte has reached its goal: those before the cut byte have, the cut byte has if
            // the bits it still needed are in the mask, those after it if they are 0xFF.
            let goal = encode(CHANGES[i], i as u16);
            let slot_start = end - SLOT as u64;
            let expect_new = cut >= slot_start && {
                let j = (cut - slot_start) as usize;
                goal[j] | mask == 0xFF && goal[j + 1..].iter().all(|&b| b == 0xFF)
            };
            let mut flash = MemFlash::<S, W, E>::new();
            flash.cut_at(cut, mask);
            let mut rec = Record::new(flash, 0, 2).unwrap();
            for &v in &CHANGES[..i] {
                rec.write(v).unwrap();
            }
            assert_eq!(
                rec.write(CHANGES[i]),
                Err(StoreError::Flash(NorFlashErrorKind::Other))
            );
            // The reset.
            let mut flash = rec.into_inner();
            assert!(flash.is_off());
            flash.power_on();
            let mut rec = Record::new(flash, 0, 2).unwrap();
            let got = rec.read().unwrap();
            let want = if expect_new { Some(CHANGES[i]) } else { before };
            assert_eq!(got, want, "cut at step {cut} (write {i}) mask {mask:#04x}");
            cuts += 1;
            if expect_new {
                new += 1;
            } else {
                old += 1;
            }
            // The caller writes again, and goes on; every value reads back, also after a
            // reset at the end.
            for &v in &CHANGES[i..] {
                rec.write(v).unwrap();
                assert_eq!(rec.read().unwrap(), Some(v));
            }
            let mut rec = Record::new(rec.into_inner(), 0, 2).unwrap();
            assert_eq!(rec.read().unwrap(), Some(0x09));
        }
    }
    (cuts, old, new)
}

#[test]
fn a_cut_at_any_step_leaves_the_old_value_or_the_new_one_double_word_writes() {
    let (cuts, old, new) = cut_everywhere::<128, 8, 64>();
    println!("8-byte writes, 64-byte pages: {cuts} cuts, {old} left the old value, {new} the new");
    // 20 slots of 8 steps; writes 8 and 16 erase a page (64 steps each), write 0 goes to
    // the erased flash's first slot.
    assert_eq!(cuts, 7 * (20 * 8 + 2 * 64));
    // Mask 0xFF: write 0 (sequence 0, bytes 6 and 7 are 0xFF) is complete from its byte 5 on,
    // the others from byte 6 on: 3 + 19 * 2. Mask 0x00: from byte 6 on, and byte 7: 2 + 19.
    // The masks in between cover the bits byte 5 (!value) or 6 (!sequence) still needs, or not.
    assert_eq!(new, 199);
    assert_eq!(old, cuts - new);
}

#[test]
fn a_cut_at_any_step_leaves_the_old_value_or_the_new_one_byte_writes() {
    let (cuts, old, new) = cut_everywhere::<128, 1, 64>();
    println!("1-byte writes, 64-byte pages: {cuts} cuts, {old} left the old value, {new} the new");
    assert_eq!((cuts, new), (7 * (20 * 8 + 2 * 64), 199));
}

/// The write that fills the last slot of a real page and the one that must erase the other
/// page, on the chips' geometries: a cut at each of their steps.
#[test]
fn cuts_on_the_chips_pages() {
    fn check<const S: usize, const W: usize, const E: usize>() {
        let slots = (E / SLOT) as u32;
        let mut base = Record::new(MemFlash::<S, W, E>::new(), 0, 2).unwrap();
        for n in 0..slots - 1 {
            base.write(if n % 2 == 0 { 0x20 } else { 0x21 }).unwrap();
        }
        // The value of the last of them, n = slots - 2.
        let last = if slots.is_multiple_of(2) { 0x20 } else { 0x21 };
        let flash = base.into_inner();
        let start = flash.steps();
        // Two writes: the page's last slot (8 steps), then an erase of the other page
        // (E steps) and its first slot (8 steps).
        for cut in start..start + 8 + E as u64 + 8 {
            for mask in [0x0F, 0xFF] {
                let mut f = flash.clone();
                f.cut_at(cut, mask);
                let mut rec = Record::new(f, 0, 2).unwrap();
                let r = rec.write(0x42).and_then(|()| rec.write(0x43));
                assert!(r.is_err());
                let mut f = rec.into_inner();
                f.power_on();
                let mut rec = Record::new(f, 0, 2).unwrap();
                let got = rec.read().unwrap();
                let first = cut < start + 8;
                let allowed: &[u8] = if first { &[last, 0x42] } else { &[0x42, 0x43] };
                assert!(allowed.contains(&got.unwrap()), "cut {cut}: {got:?}");
                rec.write(0x44).unwrap();
                assert_eq!(
                    Record::new(rec.into_inner(), 0, 2).unwrap().read().unwrap(),
                    Some(0x44)
                );
            }
        }
    }
    check::<8192, 1, 4096>();
    check::<4096, 8, 2048>();
}

#[test]
fn wear_per_address_change() {
    fn wear<const S: usize, const W: usize, const E: usize>(
        name: &str,
        changes: u32,
    ) -> (u32, u32) {
        let mut rec = Record::new(MemFlash::<S, W, E>::new(), 0, 2).unwrap();
        for n in 0..changes {
            rec.write(0x08 + (n % 2) as u8).unwrap();
        }
        let f = rec.flash();
        println!(
            "{name}: {changes} address changes: {} programs of {SLOT} bytes, {} page erases \
             (one every {} changes; each page erased {} times)",
            f.writes(),
            f.erases(),
            E / SLOT,
            f.erases() / 2
        );
        (f.writes(), f.erases())
    }
    // One erase per page filled (the first write goes to the erased flash's first slot).
    assert_eq!(
        wear::<8192, 1, 4096>("RP2040, two 4 KiB sectors", 10_000),
        (10_000, 19)
    );
    assert_eq!(
        wear::<4096, 8, 2048>("STM32, two 2 KiB pages", 10_000),
        (10_000, 39)
    );
}

#[test]
fn the_same_value_again_programs_nothing() {
    let mut rec = Record::new(Stm32::new(), 0, 2).unwrap();
    assert_eq!(rec.read().unwrap(), None);
    rec.write(0x11).unwrap();
    rec.write(0x11).unwrap();
    assert_eq!((rec.flash().writes(), rec.flash().erases()), (1, 0));
    // Exact bytes: page 0's first slot, the rest erased.
    let data = *rec.flash().data();
    assert_eq!(data[..8], [0x58, 0x11, 0x00, 0x00, 0xA7, 0xEE, 0xFF, 0xFF]);
    assert!(data[8..].iter().all(|&b| b == 0xFF));
    rec.write(0x12).unwrap();
    assert_eq!(
        rec.flash().data()[8..16],
        [0x58, 0x12, 0x01, 0x00, 0xA7, 0xED, 0xFE, 0xFF]
    );
    let mut again = Record::new(rec.into_inner(), 0, 2).unwrap();
    assert_eq!(again.read().unwrap(), Some(0x12));
}

#[test]
fn the_record_lives_where_it_is_told() {
    // Pages 1 and 2 of a four-page flash: pages 0 and 3 are never touched.
    let mut flash = MemFlash::<256, 8, 64>::new();
    flash.data_mut()[..64].fill(0x00);
    flash.data_mut()[192..].fill(0x00);
    let mut rec = Record::new(flash, 64, 2).unwrap();
    for v in 0..20 {
        rec.write(v).unwrap();
    }
    let data = *rec.flash().data();
    assert!(data[..64].iter().chain(&data[192..]).all(|&b| b == 0));
    assert_eq!(
        Record::new(rec.into_inner(), 64, 2)
            .unwrap()
            .read()
            .unwrap(),
        Some(19)
    );
}

#[test]
fn garbage_is_no_value_and_is_replaced() {
    // An old image where the record's pages now lie: pseudo-random bytes.
    let mut flash = Small8::new();
    let mut x = 0x1234_5678u32;
    for b in flash.data_mut().iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *b = x as u8;
    }
    let mut rec = Record::new(flash, 0, 2).unwrap();
    assert_eq!(rec.read().unwrap(), None);
    rec.write(0x33).unwrap();
    assert_eq!(rec.read().unwrap(), Some(0x33));
    assert_eq!(
        Record::new(rec.into_inner(), 0, 2).unwrap().read().unwrap(),
        Some(0x33)
    );
    // All zeros is no value either.
    let mut zeros = Small1::new();
    zeros.data_mut().fill(0);
    assert_eq!(Record::new(zeros, 0, 2).unwrap().read().unwrap(), None);
}

#[test]
fn a_slot_left_half_programmed_is_skipped() {
    let mut rec = Record::new(Small8::new(), 0, 2).unwrap();
    rec.write(0x10).unwrap();
    let mut flash = rec.into_inner();
    // Slot 1 of page 0: a program cut early (neither valid nor erased).
    flash.data_mut()[8..16].copy_from_slice(&[0x58, 0x11, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]);
    let mut rec = Record::new(flash, 0, 2).unwrap();
    assert_eq!(rec.read().unwrap(), Some(0x10));
    rec.write(0x11).unwrap();
    assert_eq!(rec.flash().data()[16..24], encode(0x11, 1));
}

#[test]
fn sequence_numbers_wrap_around() {
    let mut rec = Record::new(Small8::new(), 0, 2).unwrap();
    for n in 0..70_000u32 {
        rec.write((n % 200) as u8).unwrap();
    }
    assert_eq!(rec.read().unwrap(), Some((69_999 % 200) as u8));
    let mut again = Record::new(rec.into_inner(), 0, 2).unwrap();
    assert_eq!(again.read().unwrap(), Some((69_999 % 200) as u8));
}

#[test]
fn pages_that_do_not_suit_the_flash_are_refused() {
    let geometry = |r: Result<Record<Small8>, StoreError>| r.err();
    assert_eq!(
        geometry(Record::new(Small8::new(), 0, 1)),
        Some(StoreError::Geometry)
    );
    assert_eq!(
        geometry(Record::new(Small8::new(), 32, 2)),
        Some(StoreError::Geometry)
    );
    assert_eq!(
        geometry(Record::new(Small8::new(), 64, 2)),
        Some(StoreError::Geometry)
    );
    // Write size 16 does not divide a slot.
    assert_eq!(
        Record::new(MemFlash::<128, 16, 64>::new(), 0, 2).err(),
        Some(StoreError::Geometry)
    );
    // Pages of one slot.
    assert_eq!(
        Record::new(MemFlash::<16, 1, 8>::new(), 0, 2).err(),
        Some(StoreError::Geometry)
    );
    assert!(Record::new(Rp2040::new(), 0, 2).is_ok());
}

/// A flash whose programs lose bit 0 of their first byte (a worn-out cell).
struct Worn(Small8);

impl ErrorType for Worn {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for Worn {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl NorFlash for Worn {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = 64;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.0.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let mut b = [0u8; 8];
        b.copy_from_slice(bytes);
        if offset == 8 {
            b[0] |= 1;
        }
        self.0.write(offset, &b)
    }
}

#[test]
fn a_slot_that_does_not_read_back_is_an_error_and_is_skipped() {
    let mut rec = Record::new(Worn(Small8::new()), 0, 2).unwrap();
    rec.write(0x10).unwrap();
    assert_eq!(rec.write(0x11), Err(StoreError::Verify));
    assert_eq!(rec.read().unwrap(), Some(0x10));
    rec.write(0x11).unwrap();
    assert_eq!(rec.read().unwrap(), Some(0x11));
    assert_eq!(rec.flash().0.data()[16..24], encode(0x11, 1));
}

#[test]
fn flash_errors_are_typed() {
    let mut flash = Stm32::new();
    flash.cut_at(0, 0);
    let mut rec = Record::new(flash, 0, 2).unwrap();
    assert_eq!(
        rec.write(1),
        Err(StoreError::Flash(NorFlashErrorKind::Other))
    );
    assert_eq!(rec.read(), Err(StoreError::Flash(NorFlashErrorKind::Other)));
}

/// The C011's one-time-programmable area: 1 KiB, 128 slots, never erased.
#[test]
fn an_append_only_record_takes_one_slot_per_change_and_is_then_full() {
    type Otp = MemFlash<1024, 8, 1024>;
    let mut rec = Record::append_only(Otp::new(), 0, 1024).unwrap();
    assert_eq!(rec.read().unwrap(), None);
    for n in 0..128u32 {
        rec.write(0x08 + (n % 2) as u8).unwrap();
    }
    rec.write(0x09).unwrap(); // the value stored: nothing to do
    assert_eq!(rec.write(0x30), Err(StoreError::Full));
    assert_eq!(rec.read().unwrap(), Some(0x09));
    assert_eq!((rec.flash().writes(), rec.flash().erases()), (128, 0));
    let mut again = Record::append_only(rec.into_inner(), 0, 1024).unwrap();
    assert_eq!(again.read().unwrap(), Some(0x09));
    assert_eq!(again.write(0x30), Err(StoreError::Full));
    // Areas that are not whole slots, or beyond the flash.
    assert_eq!(
        Record::append_only(Otp::new(), 0, 12).err(),
        Some(StoreError::Geometry)
    );
    assert_eq!(
        Record::append_only(Otp::new(), 4, 16).err(),
        Some(StoreError::Geometry)
    );
    assert_eq!(
        Record::append_only(Otp::new(), 1016, 16).err(),
        Some(StoreError::Geometry)
    );
    assert_eq!(
        Record::append_only(Otp::new(), 0, 0).err(),
        Some(StoreError::Geometry)
    );
}

#[test]
fn an_append_only_record_cut_at_any_step_leaves_the_old_value_or_the_new_one() {
    type Otp = MemFlash<64, 8, 64>;
    let values = [0x10u8, 0x11, 0x12, 0x13, 0x14, 0x15, 0x16, 0x17];
    for mask in MASKS {
        for cut in 0..64u64 {
            let i = (cut / 8) as usize;
            let mut f = Otp::new();
            f.cut_at(cut, mask);
            let mut rec = Record::append_only(f, 0, 64).unwrap();
            for &v in &values[..i] {
                rec.write(v).unwrap();
            }
            assert!(rec.write(values[i]).is_err());
            let mut f = rec.into_inner();
            f.power_on();
            let mut rec = Record::append_only(f, 0, 64).unwrap();
            let got = rec.read().unwrap();
            let old = i.checked_sub(1).map(|j| values[j]);
            assert!(
                got == old || got == Some(values[i]),
                "cut {cut} mask {mask:#04x}: {got:?}"
            );
            // The cut slot is skipped: the rest of the area still takes changes.
            if got == old && i < 7 {
                rec.write(values[i]).unwrap();
                assert_eq!(rec.read().unwrap(), Some(values[i]));
            }
        }
    }
}
