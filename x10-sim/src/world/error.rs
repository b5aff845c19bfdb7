//! What can be wrong with a world, and where.

use std::fmt;

use super::DeviceKind;

/// Why a world is not right: what and where (the line of the world file, when it came from
/// one).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorldError {
    /// Line of the world file (from 1), when known.
    pub line: Option<usize>,
    /// What is wrong.
    pub kind: WorldErrorKind,
}

/// What is wrong with a world.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum WorldErrorKind {
    /// The file could not be read.
    Io {
        /// The file.
        path: String,
        /// Why.
        message: String,
    },
    /// Not TOML, or a value of the wrong type or an unknown field (the TOML reader's
    /// message).
    Syntax(String),
    /// A device kind this crate does not know.
    UnknownDeviceKind {
        /// The device.
        device: String,
        /// The kind it names.
        kind: String,
    },
    /// A board kind this crate does not know.
    UnknownBoardKind {
        /// The board.
        board: String,
        /// The kind it names.
        kind: String,
    },
    /// A device on a board the world does not have.
    UnknownBoard {
        /// The device.
        device: String,
        /// The board it names.
        board: String,
    },
    /// An address that is neither 0 (internal) nor 0x08–0x76 (0x77 is where unaddressed
    /// boards listen).
    BadAddress {
        /// The address.
        address: i64,
    },
    /// Two boards at one address.
    DuplicateAddress {
        /// The address.
        address: u8,
    },
    /// Two boards that answer to one name.
    DuplicateBoardName {
        /// The name.
        name: String,
    },
    /// Two devices with one name.
    DuplicateDeviceName {
        /// The name.
        name: String,
    },
    /// A board whose port counts are missing, too large, or given for a chip whose counts are
    /// fixed.
    BoardPorts {
        /// The board.
        board: String,
        /// What is wrong.
        reason: String,
    },
    /// A port written wrongly (not `S1`, `A2`, …).
    BadPort {
        /// The device.
        device: String,
        /// What was written.
        port: String,
    },
    /// A port the board does not have.
    PortOutOfRange {
        /// The device.
        device: String,
        /// The port (`A3`).
        port: String,
        /// The board's log name.
        board: String,
        /// Ports of that kind the board has.
        available: u8,
    },
    /// A device on the wrong kind of port (a motor on a sensor port).
    WrongPortKind {
        /// The device.
        device: String,
        /// Its kind.
        kind: &'static str,
        /// The port written.
        port: String,
    },
    /// A pin two devices use.
    PinTaken {
        /// The device.
        device: String,
        /// The pin (`mb A1 PWM A`).
        pin: String,
        /// The device that has it.
        by: String,
    },
    /// A servo sharing its port's PWM frequency (50 Hz) with another PWM device.
    SharedPwmFrequency {
        /// The servo.
        device: String,
        /// The other device.
        other: String,
    },
    /// A field the device needs.
    MissingField {
        /// The device.
        device: String,
        /// The field.
        field: &'static str,
    },
    /// A field or builder setting that does not apply to the device's kind.
    NotApplicable {
        /// The device.
        device: String,
        /// The field or setting.
        field: String,
        /// The device's kind.
        kind: &'static str,
    },
    /// A value out of range or malformed (a signal, a pin, a configuration).
    BadValue {
        /// The device or board.
        item: String,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A board at the motherboard's own bus address.
    MotherboardAddress {
        /// The address.
        address: u8,
    },
}

impl fmt::Display for WorldErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use WorldErrorKind as K;
        match self {
            K::Io { path, message } => write!(f, "cannot read {path}: {message}"),
            K::Syntax(m) => f.write_str(m),
            K::UnknownDeviceKind { device, kind } => write!(
                f,
                "device `{device}`: unknown kind `{kind}` (kinds: {})",
                DeviceKind::NAMES.join(", ")
            ),
            K::UnknownBoardKind { board, kind } => write!(
                f,
                "board {board}: unknown kind `{kind}` (kinds: pico, g431, simulated)"
            ),
            K::UnknownBoard { device, board } => {
                write!(f, "device `{device}`: no board `{board}` in the world")
            }
            K::BadAddress { address } => write!(
                f,
                "board address {address}: not 0 (the internal board) nor 8 to 118 (0x08 to 0x76; 0x77 is where boards without an address listen)"
            ),
            K::DuplicateAddress { address } => {
                write!(f, "two boards at address {address} ({address:#04x})")
            }
            K::DuplicateBoardName { name } => write!(f, "two boards are called `{name}`"),
            K::DuplicateDeviceName { name } => write!(f, "two devices are called `{name}`"),
            K::BoardPorts { board, reason } => write!(f, "board {board}: {reason}"),
            K::BadPort { device, port } => write!(
                f,
                "device `{device}`: port `{port}` is not a port (S1, S2, … for sensor ports, A1, A2, … for actuator ports)"
            ),
            K::PortOutOfRange {
                device,
                port,
                board,
                available,
            } => {
                let kind = if port.starts_with('S') {
                    "sensor"
                } else {
                    "actuator"
                };
                write!(
                    f,
                    "device `{device}`: port {port} is out of range: board {board} has {available} {kind} port{}",
                    if *available == 1 { "" } else { "s" }
                )
            }
            K::WrongPortKind { device, kind, port } => {
                let needs = if port.starts_with('S') {
                    "an actuator port (A1, A2, …)"
                } else {
                    "a sensor port (S1, S2, …)"
                };
                write!(f, "device `{device}`: a {kind} goes on {needs}, not on {port}")
            }
            K::PinTaken { device, pin, by } => {
                write!(f, "device `{device}`: {pin} is already used by `{by}`")
            }
            K::SharedPwmFrequency { device, other } => write!(
                f,
                "device `{device}`: a servo sets its port's PWM frequency to 50 Hz, which `{other}` on the same port also uses"
            ),
            K::MissingField { device, field } => {
                write!(f, "device `{device}`: `{field}` is missing")
            }
            K::NotApplicable {
                device,
                field,
                kind,
            } => write!(f, "device `{device}`: `{field}` does not apply to a {kind}"),
            K::BadValue {
                item,
                field,
                reason,
            } => write!(f, "{item}: `{field}` {reason}"),
            K::MotherboardAddress { address } => write!(
                f,
                "board at address {address:#04x}: that is the motherboard's own bus address"
            ),
        }
    }
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "line {l}: {}", self.kind),
            None => write!(f, "{}", self.kind),
        }
    }
}

impl std::error::Error for WorldError {}

impl WorldError {
    /// An error without a place.
    pub fn new(kind: WorldErrorKind) -> WorldError {
        WorldError { line: None, kind }
    }
}

pub(super) fn bad(item: String, field: &str, reason: impl Into<String>) -> WorldErrorKind {
    WorldErrorKind::BadValue {
        item,
        field: field.to_string(),
        reason: reason.into(),
    }
}
