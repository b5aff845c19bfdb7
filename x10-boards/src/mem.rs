//! Small memory routines for the images: `memcpy`, `memmove`, `memset` and their ARM EABI
//! forms (`__aeabi_memcpy`, `__aeabi_memclr4`, …), byte at a time; and the 64-bit and
//! 32-bit unsigned divisions (`__udivmoddi4`, `__udivsi3`, `__udivmodsi4`), a bit at a time.
//!
//! Why: the images must fit the 32 KiB of an STM32C011 (issue 12), and the word-at-a-time
//! versions compiler-builtins links in take 2.3 KiB (Cortex-M0+) to 3.3 KiB (Cortex-M4) of
//! flash; these take about 100 bytes. They are slower on long copies (about 6 cycles a byte),
//! and the images copy little: frames of at most 36 bytes, reply buffers, and a task's state
//! once when it is spawned.
//!
//! compiler-builtins defines its versions as weak symbols; the strong ones exported here (with
//! the `small-mem` feature, on a bare-metal target only) win at link time. The loops use
//! volatile accesses so that LLVM cannot turn them back into a call to `memcpy` itself.
//!
//! 64-bit division: the images divide 64-bit numbers only at start-up (embassy-stm32's busy
//! wait while the C011's ADC regulator starts, `sys_hz * us / 1_000_000`); compiler-builtins'
//! fast version takes 0.9 KiB of flash, [`divmod_u64`] about 60 bytes and some 64 steps per
//! division. compiler-builtins' `__aeabi_uldivmod` (weak too) calls the `__udivmoddi4`
//! exported here.
//!
//! 32-bit division: the Cortex-M0+ has no divide instruction, and compiler-builtins'
//! `__aeabi_uidiv` / `__aeabi_uidivmod` (weak) end in a 398-byte division routine; the
//! strong `__udivsi3`, `__aeabi_uidiv`, `__umodsi3` and `__udivmodsi4` here take
//! [`divmod_u32`] (two steps per quotient bit; the images divide when they set up the
//! I2C block for a role switch, a PWM frequency or a timeout): -0.3 KiB on db-pico and db-c011 (issue 24). The Cortex-M4 divides
//! in hardware and never calls them.
//!
//! The loops themselves ([`copy_forward`], [`copy_backward`], [`fill`], [`divmod_u64`],
//! [`divmod_u32`]) are plain functions, tested on the host.

use core::ptr::{read_volatile, write_volatile};

/// Copies `n` bytes from `src` to `dst`, lowest address first (right for `dst <= src` even
/// when the two overlap).
///
/// # Safety
/// `src` must be valid for `n` reads and `dst` for `n` writes.
pub unsafe fn copy_forward(dst: *mut u8, src: *const u8, n: usize) {
    let mut i = 0;
    while i < n {
        // SAFETY: i < n, within both ranges (the caller's contract).
        unsafe { write_volatile(dst.add(i), read_volatile(src.add(i))) };
        i += 1;
    }
}

/// Copies `n` bytes from `src` to `dst`, highest address first (right for `dst > src` even
/// when the two overlap).
///
/// # Safety
/// As [`copy_forward`].
pub unsafe fn copy_backward(dst: *mut u8, src: *const u8, n: usize) {
    let mut i = n;
    while i > 0 {
        i -= 1;
        // SAFETY: i < n, within both ranges (the caller's contract).
        unsafe { write_volatile(dst.add(i), read_volatile(src.add(i))) };
    }
}

/// `memmove`: copies in the direction that is right for overlapping ranges.
///
/// # Safety
/// As [`copy_forward`].
pub unsafe fn copy(dst: *mut u8, src: *const u8, n: usize) {
    // SAFETY: passed on.
    unsafe {
        if (dst as usize) <= (src as usize) {
            copy_forward(dst, src, n);
        } else {
            copy_backward(dst, src, n);
        }
    }
}

/// Sets `n` bytes at `dst` to `byte`.
///
/// # Safety
/// `dst` must be valid for `n` writes.
pub unsafe fn fill(dst: *mut u8, n: usize, byte: u8) {
    let mut i = 0;
    while i < n {
        // SAFETY: i < n, within the range (the caller's contract).
        unsafe { write_volatile(dst.add(i), byte) };
        i += 1;
    }
}

/// The exported symbols. The ARM run-time ABI's `__aeabi_memset` takes the length before the
/// value (the C `memset` the other way round); the 4- and 8-suffixed forms only promise an
/// aligned destination, which a byte loop does not need.
/// `(n / d, n % d)` by shift and subtract, one quotient bit per step. Division by 0 gives
/// `(u64::MAX, n)` (Rust checks for it before it divides, so the images never ask).
pub fn divmod_u64(n: u64, d: u64) -> (u64, u64) {
    if d == 0 {
        return (u64::MAX, n);
    }
    let mut q = 0u64;
    let mut r = 0u64;
    let mut bit = 64;
    while bit > 0 {
        bit -= 1;
        // r < d, so r · 2 + 1 fits 65 bits: the bit shifted out is kept in `carry`.
        let carry = r >> 63;
        r = (r << 1) | ((n >> bit) & 1);
        q <<= 1;
        if carry != 0 || r >= d {
            r = r.wrapping_sub(d);
            q |= 1;
        }
    }
    (q, r)
}

/// `(n / d, n % d)` for 32-bit numbers by shift and subtract: the divisor is shifted up to
/// the dividend's size first, so a division takes two steps per bit of the quotient (22 for
/// the RP2040's 125 MHz over 100 kHz) instead of 32. Division by 0 gives `(u32::MAX, n)`.
pub fn divmod_u32(n: u32, d: u32) -> (u32, u32) {
    if d == 0 {
        return (u32::MAX, n);
    }
    let mut ds = d;
    let mut bit = 1u32;
    while ds < n && ds & 0x8000_0000 == 0 {
        ds <<= 1;
        bit <<= 1;
    }
    let mut q = 0u32;
    let mut r = n;
    while bit != 0 {
        if r >= ds {
            r -= ds;
            q |= bit;
        }
        ds >>= 1;
        bit >>= 1;
    }
    (q, r)
}

#[cfg(all(feature = "small-mem", target_os = "none"))]
#[allow(unsafe_code, missing_docs, clippy::missing_safety_doc)]
mod exported {
    use super::{copy, copy_forward, divmod_u32, divmod_u64, fill};

    /// 32-bit unsigned division on the Cortex-M0+ (no divide instruction): compiler-builtins'
    /// `__aeabi_uidiv` and `__aeabi_uidivmod` (weak) end in these.
    #[no_mangle]
    pub extern "C" fn __udivsi3(n: u32, d: u32) -> u32 {
        divmod_u32(n, d).0
    }

    #[no_mangle]
    pub extern "C" fn __aeabi_uidiv(n: u32, d: u32) -> u32 {
        divmod_u32(n, d).0
    }

    #[no_mangle]
    pub extern "C" fn __umodsi3(n: u32, d: u32) -> u32 {
        divmod_u32(n, d).1
    }

    #[no_mangle]
    pub unsafe extern "C" fn __udivmodsi4(n: u32, d: u32, rem: *mut u32) -> u32 {
        let (q, r) = divmod_u32(n, d);
        if !rem.is_null() {
            // SAFETY: a non-null `rem` points at a u32 (the caller's contract).
            unsafe { *rem = r };
        }
        q
    }

    /// `n / d`, and `n % d` into `*rem` when it is not null (the C signature compiler-builtins'
    /// `__aeabi_uldivmod` calls).
    #[no_mangle]
    pub unsafe extern "C" fn __udivmoddi4(n: u64, d: u64, rem: *mut u64) -> u64 {
        let (q, r) = divmod_u64(n, d);
        if !rem.is_null() {
            // SAFETY: a non-null `rem` points at a u64 (the caller's contract).
            unsafe { *rem = r };
        }
        q
    }

    // SAFETY (all): the compiler calls these with valid ranges, as for the C functions.
    #[no_mangle]
    pub unsafe extern "C" fn memcpy(dst: *mut u8, src: *const u8, n: usize) -> *mut u8 {
        unsafe { copy_forward(dst, src, n) };
        dst
    }
    #[no_mangle]
    pub unsafe extern "C" fn memmove(dst: *mut u8, src: *const u8, n: usize) -> *mut u8 {
        unsafe { copy(dst, src, n) };
        dst
    }
    #[no_mangle]
    pub unsafe extern "C" fn memset(dst: *mut u8, c: i32, n: usize) -> *mut u8 {
        unsafe { fill(dst, n, c as u8) };
        dst
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memcpy(dst: *mut u8, src: *const u8, n: usize) {
        unsafe { copy_forward(dst, src, n) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memcpy4(dst: *mut u8, src: *const u8, n: usize) {
        unsafe { copy_forward(dst, src, n) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memcpy8(dst: *mut u8, src: *const u8, n: usize) {
        unsafe { copy_forward(dst, src, n) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memmove(dst: *mut u8, src: *const u8, n: usize) {
        unsafe { copy(dst, src, n) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memmove4(dst: *mut u8, src: *const u8, n: usize) {
        unsafe { copy(dst, src, n) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memmove8(dst: *mut u8, src: *const u8, n: usize) {
        unsafe { copy(dst, src, n) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memset(dst: *mut u8, n: usize, c: i32) {
        unsafe { fill(dst, n, c as u8) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memset4(dst: *mut u8, n: usize, c: i32) {
        unsafe { fill(dst, n, c as u8) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memset8(dst: *mut u8, n: usize, c: i32) {
        unsafe { fill(dst, n, c as u8) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memclr(dst: *mut u8, n: usize) {
        unsafe { fill(dst, n, 0) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memclr4(dst: *mut u8, n: usize) {
        unsafe { fill(dst, n, 0) }
    }
    #[no_mangle]
    pub unsafe extern "C" fn __aeabi_memclr8(dst: *mut u8, n: usize) {
        unsafe { fill(dst, n, 0) }
    }
}

#[cfg(test)]
#[allow(unsafe_code)]
mod tests {
    use super::*;

    fn pattern() -> [u8; 40] {
        core::array::from_fn(|i| i as u8 + 1)
    }

    #[test]
    fn copies_disjoint_ranges() {
        let src = pattern();
        let mut dst = [0u8; 40];
        // SAFETY: both arrays hold 40 bytes.
        unsafe { copy(dst.as_mut_ptr(), src.as_ptr(), 40) };
        assert_eq!(dst, src);
        let mut dst = [0u8; 40];
        // SAFETY: within both arrays.
        unsafe { copy_forward(dst.as_mut_ptr().add(3), src.as_ptr(), 5) };
        assert_eq!(dst[..9], [0, 0, 0, 1, 2, 3, 4, 5, 0]);
    }

    #[test]
    fn moves_overlapping_ranges_both_ways() {
        for shift in 1..8usize {
            let mut up = pattern();
            let mut expected = pattern();
            expected.copy_within(0..30, shift);
            // SAFETY: 0..30 and shift..30+shift lie in the 40-byte array.
            unsafe { copy(up.as_mut_ptr().add(shift), up.as_ptr(), 30) };
            assert_eq!(up, expected, "up by {shift}");

            let mut down = pattern();
            let mut expected = pattern();
            expected.copy_within(shift..shift + 30, 0);
            // SAFETY: as above.
            unsafe { copy(down.as_mut_ptr(), down.as_ptr().add(shift), 30) };
            assert_eq!(down, expected, "down by {shift}");
        }
    }

    #[test]
    fn zero_length_touches_nothing() {
        let mut dst = pattern();
        // SAFETY: no byte is accessed.
        unsafe {
            copy(dst.as_mut_ptr(), [9u8; 1].as_ptr(), 0);
            fill(dst.as_mut_ptr(), 0, 0);
        }
        assert_eq!(dst, pattern());
    }

    #[test]
    fn fills() {
        let mut dst = pattern();
        // SAFETY: 2..12 lies in the array.
        unsafe { fill(dst.as_mut_ptr().add(2), 10, 0xA5) };
        let mut expected = pattern();
        expected[2..12].fill(0xA5);
        assert_eq!(dst, expected);
    }

    #[test]
    fn divides_as_the_hardware_does() {
        let samples = [
            0,
            1,
            2,
            3,
            7,
            1_000_000,
            48_000_000 * 21,
            u64::from(u32::MAX),
            u64::from(u32::MAX) + 1,
            1 << 63,
            (1 << 63) + 1,
            u64::MAX - 1,
            u64::MAX,
        ];
        for &n in &samples {
            for &d in &samples[1..] {
                assert_eq!(divmod_u64(n, d), (n / d, n % d), "{n} / {d}");
            }
        }
        // The one division the C011 image makes: 48 MHz · 21 µs / 1 000 000.
        assert_eq!(divmod_u64(48_000_000 * 21, 1_000_000), (1_008, 0));
        assert_eq!(divmod_u64(5, 0), (u64::MAX, 5));
    }

    #[test]
    fn divides_32_bit_numbers_as_the_hardware_does() {
        let samples = [
            0u32,
            1,
            2,
            3,
            7,
            1_000,
            125_000_000,
            0x7FFF_FFFF,
            0x8000_0000,
            0x8000_0001,
            u32::MAX - 1,
            u32::MAX,
        ];
        for &n in &samples {
            for &d in &samples[1..] {
                assert_eq!(divmod_u32(n, d), (n / d, n % d), "{n} / {d}");
            }
        }
        // The RP2040's PWM divider: 125 MHz over 1 kHz.
        assert_eq!(divmod_u32(125_000_000, 1_000), (125_000, 0));
        assert_eq!(divmod_u32(5, 0), (u32::MAX, 5));
    }

    proptest::proptest! {
        #[test]
        fn divides_any_pair(n in proptest::num::u64::ANY, d in 1..=u64::MAX, shift in 0..64u32) {
            // Divisors of every size, not only large ones.
            let d = (d >> shift).max(1);
            proptest::prop_assert_eq!(divmod_u64(n, d), (n / d, n % d));
        }

        #[test]
        fn divides_any_32_bit_pair(n in proptest::num::u32::ANY, d in 1..=u32::MAX, shift in 0..32u32) {
            let d = (d >> shift).max(1);
            proptest::prop_assert_eq!(divmod_u32(n, d), (n / d, n % d));
        }
    }
}
