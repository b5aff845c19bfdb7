//! Configuration of a daughterboard: who it is and how its background work is timed.

use x10_hal::retry::RetryPolicy;
use x10_microcode::{Address, BoardKind, Capabilities, ResetReason, Uid};

/// Parses one decimal component of the crate version at compile time (0 if it does not fit).
const fn version_part(s: &str) -> u8 {
    match u8::from_str_radix(s, 10) {
        Ok(v) => v,
        Err(_) => 0,
    }
}

/// Firmware version reported by `identify` and the `boot` event: this crate's
/// `CARGO_PKG_VERSION`, major.minor.patch, unless the image was built with `X10_FW_VERSION`
/// set (`major.minor.patch`, each 0 to 255: an update's test image built from the same source
/// with another version, issue 25). A value that is not one is a compile error naming the
/// variable.
pub const FIRMWARE_VERSION: [u8; 3] = match option_env!("X10_FW_VERSION") {
    None => [
        version_part(env!("CARGO_PKG_VERSION_MAJOR")),
        version_part(env!("CARGO_PKG_VERSION_MINOR")),
        version_part(env!("CARGO_PKG_VERSION_PATCH")),
    ],
    Some(v) => match parse_version(v) {
        Some(v) => v,
        None => panic!("X10_FW_VERSION must be major.minor.patch, each 0 to 255"),
    },
};

/// `major.minor.patch` (decimal, each 0 to 255) as three bytes; `None` for anything else.
#[must_use]
pub const fn parse_version(s: &str) -> Option<[u8; 3]> {
    let mut rest = s.as_bytes();
    let mut parts = (0u8, 0u8, 0u8);
    let mut part = 0;
    let mut digits = 0;
    let mut value: u8 = 0;
    loop {
        let (c, next) = match rest {
            [c, next @ ..] => (Some(*c), next),
            [] => (None, rest),
        };
        match c {
            Some(d @ b'0'..=b'9') => {
                value = match value.checked_mul(10) {
                    Some(v) => match v.checked_add(d - b'0') {
                        Some(v) => v,
                        None => return None,
                    },
                    None => return None,
                };
                digits += 1;
            }
            Some(b'.') | None => {
                if digits == 0 || digits > 3 {
                    return None;
                }
                match part {
                    0 => parts.0 = value,
                    1 => parts.1 = value,
                    2 => parts.2 = value,
                    _ => return None,
                }
                part += 1;
                digits = 0;
                value = 0;
                if c.is_none() {
                    break;
                }
            }
            Some(_) => return None,
        }
        rest = next;
    }
    if part == 3 {
        Some([parts.0, parts.1, parts.2])
    } else {
        None
    }
}

/// Everything this runtime implements. `Capabilities::SERIAL` is absent: [`crate::Ports`] has
/// no serial methods, so serial requests are answered `unsupported`.
pub const ALL_CAPABILITIES: Capabilities = Capabilities(
    Capabilities::PULSE_IN
        | Capabilities::EVENTS
        | Capabilities::PEC
        | Capabilities::FAILSAFE
        | Capabilities::BATCH
        | Capabilities::SCAN
        | Capabilities::PWM_FREQUENCY
        | Capabilities::PWM_PULSE_WIDTH,
);

/// How one daughterboard behaves. Build it with [`DbConfig::new`] and change fields as needed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DbConfig {
    /// The board's own address: byte 1 of every request must equal it (0 for the internal
    /// daughterboard of a motherboard).
    pub address: Address,
    /// Board kind reported by `identify`.
    pub board: BoardKind,
    /// Capability bits reported by `identify`. A request whose capability bit is clear is
    /// answered `unsupported` (pulse-in, event enables, PEC on, failsafe, batch, scan, PWM
    /// frequency, PWM pulse width). `SERIAL` is never reported.
    pub capabilities: Capabilities,
    /// Interval between two samples of the pins that have events enabled, in µs (at least 1).
    pub sample_interval_us: u32,
    /// Pulse-in timeout when a request gives none, in ms.
    pub default_pulse_timeout_ms: u16,
    /// Failsafe timeout in effect at boot, in ms (0: off until the MB sets one).
    pub failsafe_timeout_ms: u16,
    /// Why the board started, reported by its `boot` event (the image reads it from the
    /// chip at start-up; [`ResetReason::PowerOn`] by default).
    pub reset_reason: ResetReason,
    /// The board's unique ID (the image reads it from the chip; all zero by default), sent in
    /// its `boot` and `announce` events and matched against every `assign`.
    pub uid: Uid,
    /// Firmware version reported by `identify` and the `boot` event ([`FIRMWARE_VERSION`];
    /// the simulator gives a board the version its simulated flash holds).
    pub firmware: [u8; 3],
}

impl DbConfig {
    /// A configuration with every capability, events sampled every 10 ms, a 1 s default
    /// pulse-in timeout, the failsafe off and a power-on start.
    pub const fn new(address: Address, board: BoardKind) -> DbConfig {
        DbConfig {
            address,
            board,
            capabilities: ALL_CAPABILITIES,
            sample_interval_us: 10_000,
            default_pulse_timeout_ms: 1_000,
            failsafe_timeout_ms: 0,
            reset_reason: ResetReason::PowerOn,
            uid: Uid([0; Uid::LEN]),
            firmware: FIRMWARE_VERSION,
        }
    }
}

/// How a daughterboard on the bus delivers its events (see [`crate::run_target`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TargetConfig {
    /// The motherboard's own 7-bit address: events are written there.
    pub mb_address: Address,
    /// Retry policy for one event: NACKs, bus timeouts and bus errors use up its attempts;
    /// arbitration losses never do (their random delay starts at `base_us` and doubles up to
    /// `max_us`). When the attempts are used up the MB is taken to be gone and the event is
    /// kept, tried again every [`crate::MB_GONE_RETRY_US`] (never dropped).
    pub retry: RetryPolicy,
    /// Mean pause between two events written by this board, in µs (each pause is random in
    /// `[g/2, 3g/2)`, `g` the larger of this and twice the last delivery's duration): bounds
    /// the board's share of the bus under an event flood (see [`crate::run_target`]).
    pub event_gap_us: u32,
}

impl TargetConfig {
    /// Events to `mb_address` with [`RetryPolicy::DEFAULT`], paced 1 ms apart on average.
    pub const fn new(mb_address: Address) -> TargetConfig {
        TargetConfig {
            mb_address,
            retry: RetryPolicy::DEFAULT,
            event_gap_us: 1_000,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::parse_version;

    #[test]
    fn versions_parse_as_three_bytes() {
        assert_eq!(parse_version("0.1.0"), Some([0, 1, 0]));
        assert_eq!(parse_version("2.0.255"), Some([2, 0, 255]));
        assert_eq!(parse_version("10.20.30"), Some([10, 20, 30]));
        assert_eq!(parse_version("2.0"), None);
        assert_eq!(parse_version("2.0.0.1"), None);
        assert_eq!(parse_version("2.0.256"), None);
        assert_eq!(parse_version("2..0"), None);
        assert_eq!(parse_version(""), None);
        assert_eq!(parse_version("v2.0.0"), None);
        assert_eq!(parse_version("2.0.0 "), None);
        assert_eq!(parse_version("1000.0.0"), None);
    }
}
