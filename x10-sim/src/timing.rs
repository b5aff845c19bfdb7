//! I2C bus timing per the I2C-bus specification (NXP UM10204, rev. 7, Table 10).
//!
//! The simulator accounts every transaction with these figures:
//!
//! | symbol | duration |
//! |---|---|
//! | START | `t_HD;STA` (SDA falls, then SCL falls) |
//! | each bit | one SCL period `T` (low 53 %, high 47 %, which meets `t_LOW`/`t_HIGH` in every mode) |
//! | each byte | 9 bits: 8 data bits and the ACK/NACK bit |
//! | repeated START | `T_low + t_SU;STA + t_HD;STA` |
//! | STOP | `T_low + t_SU;STO` |
//! | bus free before the next START | `t_BUF` |
//!
//! plus any time a target stretches SCL.

use std::fmt;
use std::str::FromStr;

use crate::exec::Nanos;

/// Bus clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Speed {
    /// Standard mode, 100 kHz.
    Standard,
    /// Fast mode, 400 kHz.
    Fast,
    /// Fast-mode Plus, 1 MHz.
    FastPlus,
}

impl Speed {
    /// Every speed, slowest first.
    pub const ALL: [Speed; 3] = [Speed::Standard, Speed::Fast, Speed::FastPlus];

    /// Clock in Hz.
    pub const fn hz(self) -> u32 {
        match self {
            Speed::Standard => 100_000,
            Speed::Fast => 400_000,
            Speed::FastPlus => 1_000_000,
        }
    }

    /// The name the command line takes and prints (`100k`, `400k`, `1M`).
    pub const fn label(self) -> &'static str {
        match self {
            Speed::Standard => "100k",
            Speed::Fast => "400k",
            Speed::FastPlus => "1M",
        }
    }

    /// The timing figures of this mode.
    pub const fn timing(self) -> Timing {
        match self {
            Speed::Standard => Timing {
                bit_ns: 10_000,
                hd_sta_ns: 4_000,
                su_sta_ns: 4_700,
                su_sto_ns: 4_000,
                buf_ns: 4_700,
            },
            Speed::Fast => Timing {
                bit_ns: 2_500,
                hd_sta_ns: 600,
                su_sta_ns: 600,
                su_sto_ns: 600,
                buf_ns: 1_300,
            },
            Speed::FastPlus => Timing {
                bit_ns: 1_000,
                hd_sta_ns: 260,
                su_sta_ns: 260,
                su_sto_ns: 260,
                buf_ns: 500,
            },
        }
    }
}

impl fmt::Display for Speed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.label())
    }
}

/// A `--clock` value that is not `100k`, `400k` or `1M`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BadSpeed(pub String);

impl fmt::Display for BadSpeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown bus clock {:?}: use 100k, 400k or 1M", self.0)
    }
}

impl std::error::Error for BadSpeed {}

impl FromStr for Speed {
    type Err = BadSpeed;

    fn from_str(s: &str) -> Result<Speed, BadSpeed> {
        match s.trim().to_ascii_lowercase().as_str() {
            "100k" | "100khz" | "100000" | "standard" => Ok(Speed::Standard),
            "400k" | "400khz" | "400000" | "fast" => Ok(Speed::Fast),
            "1m" | "1mhz" | "1000k" | "1000000" | "fast-plus" | "fastplus" => Ok(Speed::FastPlus),
            _ => Err(BadSpeed(s.to_string())),
        }
    }
}

/// Timing figures of one bus mode, in ns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    /// SCL period `T`.
    pub bit_ns: Nanos,
    /// Hold time of a (repeated) START, `t_HD;STA`.
    pub hd_sta_ns: Nanos,
    /// Set-up time of a repeated START, `t_SU;STA`.
    pub su_sta_ns: Nanos,
    /// Set-up time of STOP, `t_SU;STO`.
    pub su_sto_ns: Nanos,
    /// Bus free time between STOP and START, `t_BUF`.
    pub buf_ns: Nanos,
}

impl Timing {
    /// SCL low part of a bit.
    pub const fn low_ns(&self) -> Nanos {
        self.bit_ns * 53 / 100
    }

    /// SCL high part of a bit.
    pub const fn high_ns(&self) -> Nanos {
        self.bit_ns - self.low_ns()
    }

    /// START condition.
    pub const fn start_ns(&self) -> Nanos {
        self.hd_sta_ns
    }

    /// One byte and its ACK bit.
    pub const fn byte_ns(&self) -> Nanos {
        9 * self.bit_ns
    }

    /// Repeated START.
    pub const fn repeated_start_ns(&self) -> Nanos {
        self.low_ns() + self.su_sta_ns + self.hd_sta_ns
    }

    /// STOP condition.
    pub const fn stop_ns(&self) -> Nanos {
        self.low_ns() + self.su_sto_ns
    }

    /// Wire time of a write of `n` data bytes, START to STOP, without stretching.
    pub const fn write_ns(&self, n: usize) -> Nanos {
        self.start_ns() + (1 + n as Nanos) * self.byte_ns() + self.stop_ns()
    }

    /// Wire time of a write of `w` bytes, repeated START and read of `r` bytes, START to
    /// STOP, without stretching.
    pub const fn write_read_ns(&self, w: usize, r: usize) -> Nanos {
        self.start_ns()
            + (1 + w as Nanos) * self.byte_ns()
            + self.repeated_start_ns()
            + (1 + r as Nanos) * self.byte_ns()
            + self.stop_ns()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_byte_write_at_each_speed() {
        // START + 5 bytes * 9 bits + STOP
        assert_eq!(
            Speed::Standard.timing().write_ns(4),
            4_000 + 450_000 + 5_300 + 4_000
        );
        assert_eq!(
            Speed::Fast.timing().write_ns(4),
            600 + 112_500 + 1_325 + 600
        );
        assert_eq!(
            Speed::FastPlus.timing().write_ns(4),
            260 + 45_000 + 530 + 260
        );
    }

    #[test]
    fn write_read_adds_repeated_start_and_read_bytes() {
        let t = Speed::Fast.timing();
        assert_eq!(
            t.write_read_ns(4, 4),
            600 + 5 * 22_500 + (1_325 + 600 + 600) + 5 * 22_500 + 1_325 + 600
        );
    }

    #[test]
    fn low_and_high_meet_the_spec_minimums() {
        // (t_LOW min, t_HIGH min) per UM10204 Table 10
        for (speed, low_min, high_min) in [
            (Speed::Standard, 4_700, 4_000),
            (Speed::Fast, 1_300, 600),
            (Speed::FastPlus, 500, 260),
        ] {
            let t = speed.timing();
            assert!(t.low_ns() >= low_min, "{speed}");
            assert!(t.high_ns() >= high_min, "{speed}");
        }
    }

    #[test]
    fn speeds_parse() {
        assert_eq!("100k".parse(), Ok(Speed::Standard));
        assert_eq!("400K".parse(), Ok(Speed::Fast));
        assert_eq!("1M".parse(), Ok(Speed::FastPlus));
        assert!("2M".parse::<Speed>().is_err());
        assert_eq!(Speed::FastPlus.to_string(), "1M");
    }
}
