//! Boards: the internal one and daughterboards, their kinds and port counts, and how devices name them.

use std::fmt;

use x10_microcode::{Address, Uid};

#[cfg(doc)]
use super::SELF;

/// The name of the motherboard's internal daughterboard (address 0) in the simulator's log and
/// trace.
pub const INTERNAL_NAME: &str = "mb";

/// What a board is: one of the two supported chips (with their fixed port counts and 12-bit
/// ADC), or a simulated board with any number of ports and a 10-bit ADC (the thesis's Arduino
/// figures).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardKind {
    /// A Raspberry Pi Pico (RP2040): [`BoardKind::PICO_PORTS`], 12-bit ADC.
    Pico,
    /// An STM32G431CB: [`BoardKind::G431_PORTS`], 12-bit ADC.
    G431,
    /// Any number of ports (0–64 of each), a 10-bit ADC unless the board says otherwise.
    Simulated {
        /// Sensor ports.
        sensor_ports: u8,
        /// Actuator ports.
        actuator_ports: u8,
    },
}

impl BoardKind {
    /// (sensor ports, actuator ports) of a Pico, as `x10_boards::pins::PICO` has them.
    pub const PICO_PORTS: (u8, u8) = (3, 3);
    /// (sensor ports, actuator ports) of a G431, as `x10_boards::pins::G431` has them.
    pub const G431_PORTS: (u8, u8) = (4, 4);
    /// ADC resolution of both chips' images.
    pub const CHIP_ADC_BITS: u8 = 12;
    /// ADC resolution of a simulated board unless it says otherwise.
    pub const SIMULATED_ADC_BITS: u8 = 10;

    /// Number of sensor ports.
    pub const fn sensor_ports(self) -> u8 {
        match self {
            BoardKind::Pico => Self::PICO_PORTS.0,
            BoardKind::G431 => Self::G431_PORTS.0,
            BoardKind::Simulated { sensor_ports, .. } => sensor_ports,
        }
    }

    /// Number of actuator ports.
    pub const fn actuator_ports(self) -> u8 {
        match self {
            BoardKind::Pico => Self::PICO_PORTS.1,
            BoardKind::G431 => Self::G431_PORTS.1,
            BoardKind::Simulated { actuator_ports, .. } => actuator_ports,
        }
    }

    /// The ADC resolution the board has unless it says otherwise.
    pub const fn default_adc_bits(self) -> u8 {
        match self {
            BoardKind::Pico | BoardKind::G431 => Self::CHIP_ADC_BITS,
            BoardKind::Simulated { .. } => Self::SIMULATED_ADC_BITS,
        }
    }

    /// The board kind the chip reports on the bus (`identify`, `boot`).
    pub const fn wire_kind(self) -> x10_microcode::BoardKind {
        match self {
            BoardKind::Pico => x10_microcode::BoardKind::PICO,
            BoardKind::G431 => x10_microcode::BoardKind::G431,
            BoardKind::Simulated { .. } => x10_microcode::BoardKind::SIMULATED,
        }
    }

    /// `pico`, `g431` or `simulated`, as a world file spells it.
    pub const fn label(self) -> &'static str {
        match self {
            BoardKind::Pico => "pico",
            BoardKind::G431 => "g431",
            BoardKind::Simulated { .. } => "simulated",
        }
    }
}

/// A board of the world: the internal daughterboard (address 0), a daughterboard on the
/// bus (0x08–0x76), or one without an address (plug and play: it boots unaddressed and the
/// motherboard gives it one; [`Board::without_address`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Board {
    /// Its address; for a board without one, a key of the world's own (0x80 and up, never on
    /// the bus), set when the board is added.
    pub(super) address: u8,
    pub(super) alias: Option<String>,
    pub(super) kind: BoardKind,
    pub(super) adc_bits: Option<u8>,
    /// No build-time address: plug and play.
    pub(super) unaddressed: bool,
    /// Its unique ID, when the world gives one (otherwise made from its name).
    pub(super) uid: Option<Uid>,
    /// The firmware version it runs, when the world gives one (`firmware = "0.1.0"`;
    /// otherwise the simulator's own, `firmware_db::FIRMWARE_VERSION`).
    pub(super) firmware: Option<x10_microcode::Version>,
    /// Pinned to the firmware it runs: the motherboard does not update it (`update = false`).
    pub(super) pinned: bool,
}

/// The first key [`Board::address`] holds for boards without an address.
pub(super) const UNADDRESSED_KEY: u8 = 0x80;

impl Board {
    /// The motherboard's internal daughterboard ([`SELF`], named `mb`) with simulated ports.
    /// A world that declares no internal board has one with 2 sensor and 2 actuator ports.
    pub fn internal(sensor_ports: u8, actuator_ports: u8) -> Board {
        Board::new(0, sensor_ports, actuator_ports)
    }

    /// A simulated daughterboard at `address` (`0` is the internal one), named after it
    /// (`db09` for 9).
    pub fn new(address: u8, sensor_ports: u8, actuator_ports: u8) -> Board {
        Board::of_kind(
            address,
            BoardKind::Simulated {
                sensor_ports,
                actuator_ports,
            },
        )
    }

    /// A board of `kind` at `address`.
    pub fn of_kind(address: u8, kind: BoardKind) -> Board {
        Board {
            address,
            alias: None,
            kind,
            adc_bits: None,
            unaddressed: false,
            uid: None,
            firmware: None,
            pinned: false,
        }
    }

    /// A simulated daughterboard called `name` without an address (plug and play): it boots
    /// unaddressed, announces itself and takes the address the motherboard gives it, kept in
    /// its simulated record. Devices name it by `name`.
    pub fn without_address(name: &str, sensor_ports: u8, actuator_ports: u8) -> Board {
        let mut b = Board::new(UNADDRESSED_KEY, sensor_ports, actuator_ports).named(name);
        b.unaddressed = true;
        b
    }

    /// Its unique ID (default: one made from its name, `x10_sim::board::uid_of_name`).
    pub fn uid(mut self, uid: Uid) -> Board {
        self.uid = Some(uid);
        self
    }

    /// The firmware version it runs (see [`Board::firmware_version`]).
    pub fn firmware(mut self, version: x10_microcode::Version) -> Board {
        self.firmware = Some(version);
        self
    }

    /// Pins it to the firmware it runs: the motherboard does not update it.
    pub fn pinned(mut self) -> Board {
        self.pinned = true;
        self
    }

    /// The firmware version it runs: the world's, else the simulator's own.
    pub fn firmware_version(&self) -> x10_microcode::Version {
        self.firmware.unwrap_or(firmware_db::FIRMWARE_VERSION)
    }

    /// True when the world gives its firmware version.
    pub fn has_firmware(&self) -> bool {
        self.firmware.is_some()
    }

    /// True when it is pinned to the firmware it runs.
    pub fn is_pinned(&self) -> bool {
        self.pinned
    }

    /// Its unique ID: the world's, else the one made from its log name (as the simulator's
    /// board reports it).
    pub fn unique_id(&self) -> Uid {
        self.uid
            .unwrap_or_else(|| crate::board::uid_of_name(&self.log_name()))
    }

    /// The board kind it reports on the bus as the chip it stands for: `pico` 3, `g431` 4,
    /// `simulated` 1 (`x10_microcode::BoardKind`).
    pub fn wire_kind(&self) -> x10_microcode::BoardKind {
        self.kind.wire_kind()
    }

    /// True for a board without an address.
    pub fn is_unaddressed(&self) -> bool {
        self.unaddressed
    }

    /// The board's own name for devices: its address, or its name when it has no address.
    pub(super) fn self_ref(&self) -> BoardRef {
        match (&self.alias, self.unaddressed) {
            (Some(n), true) => BoardRef::Name(n.clone()),
            _ => BoardRef::Address(self.address),
        }
    }

    /// A Raspberry Pi Pico at `address`.
    pub fn pico(address: u8) -> Board {
        Board::of_kind(address, BoardKind::Pico)
    }

    /// An STM32G431 at `address`.
    pub fn g431(address: u8) -> Board {
        Board::of_kind(address, BoardKind::G431)
    }

    /// Another name to refer to the board by (its log name stays `db09` / `mb`).
    pub fn named(mut self, name: &str) -> Board {
        self.alias = Some(name.to_string());
        self
    }

    /// The ADC resolution (1–16 bits).
    pub fn adc_bits(mut self, bits: u8) -> Board {
        self.adc_bits = Some(bits);
        self
    }

    /// The address (0 for the internal board; for a board without one, a key of the world's
    /// own, 0x80 and up, never on the bus).
    pub fn address(&self) -> u8 {
        self.address
    }

    /// True for the internal board.
    pub fn is_internal(&self) -> bool {
        self.address == 0
    }

    /// The kind.
    pub fn kind(&self) -> BoardKind {
        self.kind
    }

    /// The name the simulator's log and trace use: `mb` for the internal board, `db09` for
    /// address 9, its name for a board without an address.
    pub fn log_name(&self) -> String {
        if let (true, Some(n)) = (self.unaddressed, &self.alias) {
            n.clone()
        } else if self.is_internal() {
            INTERNAL_NAME.to_string()
        } else {
            format!("db{:02x}", self.address)
        }
    }

    /// The name given with [`Board::named`], if any.
    pub fn alias(&self) -> Option<&str> {
        self.alias.as_deref()
    }

    /// The ADC resolution.
    pub fn adc_resolution(&self) -> u8 {
        self.adc_bits.unwrap_or(self.kind.default_adc_bits())
    }

    /// The largest ADC reading.
    pub fn adc_max(&self) -> u16 {
        let bits = self.adc_resolution().clamp(1, 16);
        u16::try_from((1u32 << bits) - 1).unwrap_or(u16::MAX)
    }

    pub(super) fn answers_to(&self, r: &BoardRef) -> bool {
        match r {
            BoardRef::Address(a) => !self.unaddressed && *a == self.address,
            BoardRef::Name(n) => {
                *n == self.log_name()
                    || self.alias.as_deref() == Some(n.as_str())
                    || (self.is_internal() && n == "SELF")
            }
        }
    }

    pub(super) fn ports(&self) -> (u8, u8) {
        (self.kind.sensor_ports(), self.kind.actuator_ports())
    }
}

/// Which board a device is on: an address (0 = [`SELF`]) or a name (`mb`, `SELF`, `db09`,
/// or a board's own name).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BoardRef {
    /// By address.
    Address(u8),
    /// By name.
    Name(String),
}

impl From<u8> for BoardRef {
    fn from(a: u8) -> Self {
        BoardRef::Address(a)
    }
}

impl From<Address> for BoardRef {
    fn from(a: Address) -> Self {
        BoardRef::Address(a.get())
    }
}

impl From<&str> for BoardRef {
    fn from(n: &str) -> Self {
        BoardRef::Name(n.to_string())
    }
}

impl From<String> for BoardRef {
    fn from(n: String) -> Self {
        BoardRef::Name(n)
    }
}

impl fmt::Display for BoardRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardRef::Address(0) => f.write_str("SELF"),
            BoardRef::Address(a) => write!(f, "{a:#04x}"),
            BoardRef::Name(n) => f.write_str(n),
        }
    }
}
