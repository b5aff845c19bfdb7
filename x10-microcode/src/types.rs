//! Addresses, ports and pins.
//!
//! On the wire ports are counted from 0 (byte 2, bits 6..1); every constructor and accessor
//! meant for people counts them from 1, as the thesis does.

use core::fmt;

use crate::{Error, Result};

/// A daughterboard address: 0 for the internal DB on the MB itself, or a 7-bit I2C address in
/// `0x08..=0x77` (the range I2C leaves to ordinary devices).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(try_from = "u8", into = "u8")
)]
pub struct Address(u8);

impl Address {
    /// The internal daughterboard, reached without the bus (thesis `SELF`).
    pub const INTERNAL: Address = Address(0);
    /// Lowest external address.
    pub const MIN_EXTERNAL: u8 = 0x08;
    /// Highest external address.
    pub const MAX_EXTERNAL: u8 = 0x77;
    /// The address every *unaddressed* daughterboard listens at (plug and play,
    /// `docs/protocol.md`, "Addresses over the bus"): the top of the external range, so the
    /// addresses a motherboard gives out (`0x08..=0x76`) stay one block. Only ever written to
    /// (`assign`), never read from: several unaddressed boards may acknowledge one write
    /// together, none of them ever drives data onto the bus here.
    pub const UNADDRESSED: Address = Address(0x77);
    /// Where an STM32 daughterboard's ROM bootloader answers while it is being updated
    /// (ST's I2C bootloader, AN4221: the STM32C011's, as Arduino's Modulino uses it). A
    /// motherboard never gives it out and never probes it: an empty probe there restarts the
    /// ROM bootloader's wait (docs/boards.md, "Updating the boards").
    pub const STM32_BOOTLOADER: u8 = 0x64;

    /// Checks an address a board may be given over the bus (`assign`, `set_address`): an
    /// external address other than [`Address::UNADDRESSED`].
    ///
    /// # Errors
    /// [`Error::BadArgument`] unless `raw` is in `0x08..=0x76`.
    pub const fn assignable(raw: u8) -> Result<Address> {
        if raw >= Self::MIN_EXTERNAL && raw < Self::UNADDRESSED.0 {
            Ok(Address(raw))
        } else {
            Err(Error::BadArgument)
        }
    }

    /// True for [`Address::UNADDRESSED`].
    pub const fn is_unaddressed(self) -> bool {
        self.0 == Self::UNADDRESSED.0
    }

    /// Checks an address.
    ///
    /// # Errors
    /// [`Error::BadAddress`] unless `raw` is 0 or in `0x08..=0x77`.
    pub const fn new(raw: u8) -> Result<Address> {
        if raw == 0 || (raw >= Self::MIN_EXTERNAL && raw <= Self::MAX_EXTERNAL) {
            Ok(Address(raw))
        } else {
            Err(Error::BadAddress(raw))
        }
    }

    /// Checks an address that must be on the bus (not the internal board).
    ///
    /// # Errors
    /// [`Error::BadAddress`] unless `raw` is in `0x08..=0x77`.
    pub const fn external(raw: u8) -> Result<Address> {
        if raw >= Self::MIN_EXTERNAL && raw <= Self::MAX_EXTERNAL {
            Ok(Address(raw))
        } else {
            Err(Error::BadAddress(raw))
        }
    }

    /// The raw 7-bit value.
    pub const fn get(self) -> u8 {
        self.0
    }

    /// True for the internal daughterboard (address 0).
    pub const fn is_internal(self) -> bool {
        self.0 == 0
    }

    /// The I2C address byte (address and R/W bit) that SMBus PEC covers.
    pub const fn addr_byte(self, read: bool) -> u8 {
        (self.0 << 1) | read as u8
    }
}

impl TryFrom<u8> for Address {
    type Error = Error;

    /// As [`Address::new`].
    fn try_from(raw: u8) -> Result<Address> {
        Address::new(raw)
    }
}

impl From<Address> for u8 {
    fn from(a: Address) -> u8 {
        a.0
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_internal() {
            f.write_str("SELF")
        } else {
            write!(f, "{:#04x}", self.0)
        }
    }
}

/// A board's unique ID: 8 bytes, sent as they are (no byte order to choose). An RP2040 board
/// reports its flash chip's 64-bit unique ID as read; an STM32 board its 96-bit UID folded to
/// 64 bits (the fold lives with the chip code, in `x10-boards`). The motherboard keys
/// addresses by it and the unaddressed state's random delays are seeded from it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(transparent)
)]
pub struct Uid(pub [u8; 8]);

impl Uid {
    /// Encoded length.
    pub const LEN: usize = 8;

    /// The first [`Uid::LEN`] bytes of `bytes`.
    ///
    /// # Errors
    /// [`Error::BadLength`] when there are fewer.
    pub fn parse(bytes: &[u8]) -> Result<Uid> {
        let b = bytes.get(..Self::LEN).ok_or(Error::BadLength)?;
        let mut u = [0u8; Self::LEN];
        u.copy_from_slice(b);
        Ok(Uid(u))
    }

    /// A 32-bit mix of the ID (FNV-1a, then a multiply-xorshift finaliser): the seed of a
    /// board's delays and the start of the motherboard's search for a free address. Two IDs
    /// that differ in one bit give unrelated values.
    pub fn hash32(self) -> u32 {
        let mut h = self.0.iter().fold(0x811c_9dc5u32, |h, b| {
            (h ^ u32::from(*b)).wrapping_mul(0x0100_0193)
        });
        h ^= h >> 16;
        h = h.wrapping_mul(0x7feb_352d);
        h ^= h >> 15;
        h
    }
}

impl fmt::Display for Uid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in self.0 {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

/// Kind of port: byte 2, bit 7 (1 = sensor).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "lowercase")
)]
pub enum PortKind {
    /// Actuator port: 2 PWM pins and 2 digital I/O pins.
    Actuator,
    /// Sensor port: 2 digital I/O pins and 1 analog input.
    Sensor,
}

/// One of the two pins of a port: byte 2, bit 0 (A = 0, B = 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Pin {
    /// Pin A (bit 0 clear).
    A,
    /// Pin B (bit 0 set).
    B,
}

impl Pin {
    /// 0 for A, 1 for B.
    pub const fn index(self) -> usize {
        match self {
            Pin::A => 0,
            Pin::B => 1,
        }
    }
}

/// A sensor or actuator port of a daughterboard.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Port {
    kind: PortKind,
    /// 0-based, as on the wire.
    index: u8,
}

impl Port {
    /// Number of ports of each kind the wire can name (6 bits).
    pub const MAX_PORTS: u8 = 64;

    /// A port by its kind and 1-based number, as the thesis numbers them.
    ///
    /// # Errors
    /// [`Error::BadPort`] when `number` is 0 or above 64.
    pub const fn new(kind: PortKind, number: u8) -> Result<Port> {
        if number == 0 || number > Self::MAX_PORTS {
            Err(Error::BadPort(number))
        } else {
            Ok(Port {
                kind,
                index: number - 1,
            })
        }
    }

    /// Sensor port `number` (1-based).
    ///
    /// # Errors
    /// [`Error::BadPort`] when `number` is 0 or above 64.
    pub const fn sensor(number: u8) -> Result<Port> {
        Self::new(PortKind::Sensor, number)
    }

    /// Actuator port `number` (1-based).
    ///
    /// # Errors
    /// [`Error::BadPort`] when `number` is 0 or above 64.
    pub const fn actuator(number: u8) -> Result<Port> {
        Self::new(PortKind::Actuator, number)
    }

    /// Port kind.
    pub const fn kind(self) -> PortKind {
        self.kind
    }

    /// 1-based port number.
    pub const fn number(self) -> u8 {
        self.index + 1
    }

    /// 0-based port index, as on the wire.
    pub const fn index(self) -> u8 {
        self.index
    }

    /// This port with pin `pin`.
    pub const fn pin(self, pin: Pin) -> PinRef {
        PinRef { port: self, pin }
    }

    /// Decodes byte 2 of a request, ignoring the pin bit.
    pub const fn from_byte(byte: u8) -> Port {
        PinRef::from_byte(byte).port
    }
}

impl fmt::Display for Port {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let k = match self.kind {
            PortKind::Sensor => 'S',
            PortKind::Actuator => 'A',
        };
        write!(f, "{}{}", k, self.number())
    }
}

/// A pin of a port: the whole of request byte 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PinRef {
    /// The port.
    pub port: Port,
    /// The pin of that port.
    pub pin: Pin,
}

impl PinRef {
    /// Decodes request byte 2. Every byte value is a valid pin reference.
    pub const fn from_byte(byte: u8) -> PinRef {
        let kind = if byte & 0x80 != 0 {
            PortKind::Sensor
        } else {
            PortKind::Actuator
        };
        let pin = if byte & 1 != 0 { Pin::B } else { Pin::A };
        PinRef {
            port: Port {
                kind,
                index: (byte >> 1) & 0x3f,
            },
            pin,
        }
    }

    /// Encodes request byte 2.
    pub const fn to_byte(self) -> u8 {
        let kind = match self.port.kind {
            PortKind::Sensor => 0x80,
            PortKind::Actuator => 0,
        };
        kind | ((self.port.index & 0x3f) << 1) | self.pin.index() as u8
    }
}

impl From<Port> for PinRef {
    /// The port with pin A (bit 0 clear), as operations that take no pin encode it.
    fn from(port: Port) -> PinRef {
        PinRef { port, pin: Pin::A }
    }
}

impl fmt::Display for PinRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = match self.pin {
            Pin::A => 'A',
            Pin::B => 'B',
        };
        write!(f, "{}.{}", self.port, p)
    }
}

/// Digital level written by IO LOW / IO HIGH.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Level {
    /// Low (thesis `LO`, operand 1).
    Low,
    /// High (thesis `HI`, operand 2).
    High,
}

impl Level {
    /// High for `true`.
    pub const fn from_bool(high: bool) -> Level {
        if high {
            Level::High
        } else {
            Level::Low
        }
    }

    /// True for high.
    pub const fn is_high(self) -> bool {
        matches!(self, Level::High)
    }
}

/// Which edge starts a pulse-in measurement.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Edge {
    /// Measure a high pulse: from a rising edge to the next falling edge (operand 3).
    Rising,
    /// Measure a low pulse: from a falling edge to the next rising edge (operand 4).
    Falling,
}
