//! Bus addresses: the motherboard's, and a daughterboard's build-time base plus
//! address-select jumpers read at boot.
//!
//! * The MB listens at [`MB_DEFAULT`] (0x08), or at `X10_MB_ADDR` when set at build time;
//!   a DB image must be built with the same value, since its events go there.
//! * A DB image built without `X10_DB_ADDR` is plug and play: its address is given over the
//!   bus and kept (`db_image.rs`, `docs/protocol.md`, "Addresses over the bus"). With it
//!   (`X10_DB_ADDR=0x12 cargo db-pico`, decimal or `0x` hex) the base is an override;
//!   [`build_base`] falls back to [`DEFAULT_BASE`] only for callers that want a base anyway.
//!   [`parse`] runs in a `const`, so a bad value stops the build instead of the board.
//! * Each jumper input has its internal pull-up on; a jumper fitted to GND reads low and sets
//!   its bit. Jumper *k* adds 2^k: with three jumpers one image serves eight boards
//!   (`base ..= base + 7`).
//! * [`check_base`] makes sure every jumper setting gives an address in `0x08..=0x76` other
//!   than the MB's, again at build time. `0x77` is where unaddressed boards listen (plug and
//!   play: `docs/protocol.md`, "Addresses over the bus"), never a board's or the MB's address.
//!
//! [`DEFAULT_BASE`] is 9, the light-sensor board of the thesis's Figure 4.4 program.

use x10_microcode::Address;

/// The base address when `X10_DB_ADDR` is not set.
pub const DEFAULT_BASE: u8 = 9;

/// The motherboard's address when `X10_MB_ADDR` is not set.
pub const MB_DEFAULT: u8 = 0x08;

/// Why a build-time address is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AddressError {
    /// Not a decimal or `0x` hexadecimal number below 256.
    NotANumber,
    /// Outside `0x08..=0x76` (or would be with some jumper setting).
    OutOfRange,
    /// Equal to the motherboard's address (or would be with some jumper setting).
    TakenByMotherboard,
}

/// Parses a decimal (`16`) or hexadecimal (`0x10`) byte; `const` so it can run on
/// `option_env!("X10_DB_ADDR")` at build time.
///
/// # Errors
/// [`AddressError::NotANumber`] for anything else.
pub const fn parse(s: &str) -> Result<u8, AddressError> {
    let b = s.as_bytes();
    let (radix, mut i) = if b.len() > 2 && b[0] == b'0' && (b[1] == b'x' || b[1] == b'X') {
        (16u32, 2)
    } else {
        (10u32, 0)
    };
    if i >= b.len() {
        return Err(AddressError::NotANumber);
    }
    let mut value: u32 = 0;
    while i < b.len() {
        let d = match b[i] {
            c @ b'0'..=b'9' => (c - b'0') as u32,
            c @ b'a'..=b'f' if radix == 16 => (c - b'a' + 10) as u32,
            c @ b'A'..=b'F' if radix == 16 => (c - b'A' + 10) as u32,
            _ => return Err(AddressError::NotANumber),
        };
        value = value * radix + d;
        if value > 0xff {
            return Err(AddressError::NotANumber);
        }
        i += 1;
    }
    Ok(value as u8)
}

/// Checks that `base` plus every value of `jumpers` jumpers is an external address other
/// than `mb` (the motherboard's).
///
/// # Errors
/// [`AddressError::OutOfRange`], [`AddressError::TakenByMotherboard`].
pub const fn check_base(base: u8, jumpers: u32, mb: u8) -> Result<u8, AddressError> {
    if jumpers > 6 {
        return Err(AddressError::OutOfRange);
    }
    let top = base as u32 + (1u32 << jumpers) - 1;
    if base < Address::MIN_EXTERNAL || top >= Address::UNADDRESSED.get() as u32 {
        return Err(AddressError::OutOfRange);
    }
    if base <= mb && mb as u32 <= top {
        return Err(AddressError::TakenByMotherboard);
    }
    Ok(base)
}

/// The motherboard's address for a build: `X10_MB_ADDR` as given by `env` (the caller passes
/// `option_env!("X10_MB_ADDR")`), or [`MB_DEFAULT`].
///
/// # Errors
/// As [`parse`]; [`AddressError::OutOfRange`] outside `0x08..=0x76`.
pub const fn build_mb(env: Option<&str>) -> Result<u8, AddressError> {
    let mb = match env {
        Some(s) => match parse(s) {
            Ok(b) => b,
            Err(e) => return Err(e),
        },
        None => MB_DEFAULT,
    };
    if mb < Address::MIN_EXTERNAL || mb >= Address::UNADDRESSED.get() {
        return Err(AddressError::OutOfRange);
    }
    Ok(mb)
}

/// The base address for a build: `X10_DB_ADDR` as given by `env` (the caller passes
/// `option_env!("X10_DB_ADDR")`), checked for `jumpers` jumpers and the MB address `mb`.
///
/// # Errors
/// As [`parse`] and [`check_base`].
pub const fn build_base(env: Option<&str>, jumpers: u32, mb: u8) -> Result<u8, AddressError> {
    let base = match env {
        Some(s) => match parse(s) {
            Ok(b) => b,
            Err(e) => return Err(e),
        },
        None => DEFAULT_BASE,
    };
    check_base(base, jumpers, mb)
}

/// The jumper value from the levels read at boot, bit 0 first: a low input (jumper to GND)
/// is a 1.
pub fn jumper_value(levels_high: impl IntoIterator<Item = bool>) -> u8 {
    levels_high
        .into_iter()
        .take(7)
        .enumerate()
        .fold(0, |v, (k, high)| if high { v } else { v | (1 << k) })
}

/// The board's address: `base` (from [`build_base`]) plus the jumper value.
///
/// # Errors
/// [`AddressError::OutOfRange`] when the sum is not an address a board may have, `0x08..=0x76`
/// (impossible for a
/// base accepted by [`check_base`] with as many jumpers as were read).
pub fn address(base: u8, jumper_value: u8) -> Result<Address, AddressError> {
    base.checked_add(jumper_value)
        .and_then(|a| Address::assignable(a).ok())
        .ok_or(AddressError::OutOfRange)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_decimal_and_hex() {
        assert_eq!(parse("16"), Ok(16));
        assert_eq!(parse("0x10"), Ok(16));
        assert_eq!(parse("0X7f"), Ok(0x7f));
        assert_eq!(parse("255"), Ok(255));
        assert_eq!(parse("256"), Err(AddressError::NotANumber));
        assert_eq!(parse(""), Err(AddressError::NotANumber));
        assert_eq!(parse("0x"), Err(AddressError::NotANumber));
        assert_eq!(parse("1f"), Err(AddressError::NotANumber));
        assert_eq!(parse(" 16"), Err(AddressError::NotANumber));
    }

    #[test]
    fn base_must_leave_room_for_every_jumper_setting() {
        assert_eq!(check_base(0x08, 3, 0x30), Ok(0x08));
        assert_eq!(check_base(0x6f, 3, 0x08), Ok(0x6f));
        assert_eq!(check_base(0x70, 3, 0x08), Err(AddressError::OutOfRange));
        assert_eq!(check_base(0x76, 0, 0x08), Ok(0x76));
        // 0x77 is where unaddressed boards listen.
        assert_eq!(check_base(0x77, 0, 0x08), Err(AddressError::OutOfRange));
        assert_eq!(check_base(0x07, 0, 0x30), Err(AddressError::OutOfRange));
        assert_eq!(check_base(0x09, 7, 0x08), Err(AddressError::OutOfRange));
    }

    #[test]
    fn base_must_not_reach_the_motherboard() {
        assert_eq!(
            check_base(0x08, 0, 0x08),
            Err(AddressError::TakenByMotherboard)
        );
        assert_eq!(
            check_base(0x05 + 3, 3, 0x0f),
            Err(AddressError::TakenByMotherboard)
        );
        assert_eq!(check_base(0x09, 3, 0x08), Ok(0x09));
        assert_eq!(check_base(0x09, 3, 0x11), Ok(0x09));
    }

    #[test]
    fn build_base_defaults_and_checks() {
        assert_eq!(build_base(None, 3, MB_DEFAULT), Ok(DEFAULT_BASE));
        assert_eq!(build_base(Some("0x20"), 3, MB_DEFAULT), Ok(0x20));
        assert_eq!(
            build_base(Some("0x75"), 3, MB_DEFAULT),
            Err(AddressError::OutOfRange)
        );
        assert_eq!(
            build_base(Some("x"), 0, MB_DEFAULT),
            Err(AddressError::NotANumber)
        );
        assert_eq!(
            build_base(Some("8"), 0, MB_DEFAULT),
            Err(AddressError::TakenByMotherboard)
        );
    }

    #[test]
    fn build_mb_defaults_and_checks() {
        assert_eq!(build_mb(None), Ok(0x08));
        assert_eq!(build_mb(Some("0x30")), Ok(0x30));
        assert_eq!(build_mb(Some("0x78")), Err(AddressError::OutOfRange));
        assert_eq!(build_mb(Some("0x77")), Err(AddressError::OutOfRange));
        assert_eq!(build_mb(Some("0x76")), Ok(0x76));
        assert_eq!(build_mb(Some("")), Err(AddressError::NotANumber));
    }

    #[test]
    fn fitted_jumpers_read_low_and_set_bits() {
        assert_eq!(jumper_value([true, true, true]), 0);
        assert_eq!(jumper_value([false, true, true]), 1);
        assert_eq!(jumper_value([true, false, false]), 6);
        assert_eq!(jumper_value([false, false, false]), 7);
        assert_eq!(jumper_value([]), 0);
    }

    #[test]
    fn address_adds_jumpers() {
        assert_eq!(address(0x10, 5), Ok(Address::external(0x15).unwrap()));
        assert_eq!(address(0x76, 1), Err(AddressError::OutOfRange));
        assert_eq!(address(0x76, 0), Ok(Address::external(0x76).unwrap()));
        assert_eq!(address(0xff, 1), Err(AddressError::OutOfRange));
    }
}
