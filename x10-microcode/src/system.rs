//! Payloads of the system functions and of scan: identity, diagnostics, event configuration,
//! scan results.

use crate::{Error, Result, Uid};

/// Board kind codes reported by `identify`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardKind(pub u8);

impl BoardKind {
    /// Not reported.
    pub const UNKNOWN: BoardKind = BoardKind(0);
    /// A daughterboard in the host simulator.
    pub const SIMULATED: BoardKind = BoardKind(1);
    /// The internal daughterboard of a motherboard (address 0).
    pub const INTERNAL: BoardKind = BoardKind(2);
    /// Raspberry Pi Pico (RP2040).
    pub const PICO: BoardKind = BoardKind(3);
    /// STM32G431 core board or Nucleo.
    pub const G431: BoardKind = BoardKind(4);
    /// STM32C011F6 daughterboard (TSSOP-20).
    pub const C011: BoardKind = BoardKind(5);

    /// Name for people.
    pub const fn name(self) -> &'static str {
        match self.0 {
            1 => "simulated",
            2 => "internal",
            3 => "pico",
            4 => "g431",
            5 => "c011",
            _ => "unknown",
        }
    }
}

/// Why a board last started, reported by its `boot` event after its identity (byte 10 of the
/// payload). A board reads it from its chip at start-up (reset-cause flags, and a mark its
/// panic or fault handler left in memory that survives the reset).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetReason {
    /// Power applied (or brown-out): code 0. Also what a board reports that cannot tell.
    PowerOn,
    /// The hardware watchdog fired: the executor hung (code 1).
    Watchdog,
    /// The firmware panicked; its handler put the outputs in their safe state and reset the
    /// chip (code 2).
    Panic,
    /// A processor fault (HardFault); its handler put the outputs in their safe state and
    /// reset the chip (code 3).
    Fault,
    /// The reset pin, or a debug probe (code 4).
    ResetPin,
    /// A reset the firmware asked for (code 5), e.g. after an update.
    Software,
    /// A code this version does not know.
    Unknown(u8),
}

impl ResetReason {
    /// The reason of wire code `b`.
    pub const fn from_byte(b: u8) -> ResetReason {
        match b {
            0 => ResetReason::PowerOn,
            1 => ResetReason::Watchdog,
            2 => ResetReason::Panic,
            3 => ResetReason::Fault,
            4 => ResetReason::ResetPin,
            5 => ResetReason::Software,
            other => ResetReason::Unknown(other),
        }
    }

    /// The wire code.
    pub const fn to_byte(self) -> u8 {
        match self {
            ResetReason::PowerOn => 0,
            ResetReason::Watchdog => 1,
            ResetReason::Panic => 2,
            ResetReason::Fault => 3,
            ResetReason::ResetPin => 4,
            ResetReason::Software => 5,
            ResetReason::Unknown(b) => b,
        }
    }

    /// Name for people (`unknown` for codes this version does not know).
    pub const fn name(self) -> &'static str {
        match self {
            ResetReason::PowerOn => "power_on",
            ResetReason::Watchdog => "watchdog",
            ResetReason::Panic => "panic",
            ResetReason::Fault => "fault",
            ResetReason::ResetPin => "reset_pin",
            ResetReason::Software => "software",
            ResetReason::Unknown(_) => "unknown",
        }
    }

    /// True for a reset caused by the firmware failing (watchdog, panic, fault).
    pub const fn is_crash(self) -> bool {
        matches!(
            self,
            ResetReason::Watchdog | ResetReason::Panic | ResetReason::Fault
        )
    }
}

/// Payload of the `boot` and `announce` events: the board's [`Identity`] (10 bytes), why it
/// started (1 byte), then its unique ID (8 bytes, [`Uid`]). A receiver reads the identity from
/// the first 10 bytes and ignores bytes it does not know after the ID. A board of an earlier
/// version sent 11 bytes (no ID): that parses with `uid: None`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BootInfo {
    /// What `identify` answers.
    pub identity: Identity,
    /// Why the board started.
    pub reset_reason: ResetReason,
    /// The board's unique ID (`None` from a board of an earlier version).
    pub uid: Option<Uid>,
}

impl BootInfo {
    /// Encoded length without the ID (a board of an earlier version).
    pub const LEN_NO_UID: usize = Identity::LEN + 1;
    /// Encoded length with the ID, as this version sends it.
    pub const LEN: usize = Self::LEN_NO_UID + Uid::LEN;

    /// Parses a `boot` or `announce` event's payload.
    ///
    /// # Errors
    /// [`Error::BadLength`] when it is shorter than [`BootInfo::LEN_NO_UID`], or longer but
    /// shorter than [`BootInfo::LEN`] (a cut ID).
    pub fn parse(payload: &[u8]) -> Result<BootInfo> {
        let id = payload.get(..Identity::LEN).ok_or(Error::BadLength)?;
        let reason = *payload.get(Identity::LEN).ok_or(Error::BadLength)?;
        let uid = match payload.get(Self::LEN_NO_UID..) {
            Some([]) | None => None,
            Some(rest) => Some(Uid::parse(rest)?),
        };
        Ok(BootInfo {
            identity: Identity::parse(id)?,
            reset_reason: ResetReason::from_byte(reason),
            uid,
        })
    }

    /// Encodes the payload: [`BootInfo::LEN`] bytes with an ID, [`BootInfo::LEN_NO_UID`]
    /// without (the rest of the array is then zero). Returns the array and the length used.
    pub fn to_bytes(&self) -> ([u8; Self::LEN], usize) {
        let mut b = [0u8; Self::LEN];
        let (id, rest) = b.split_at_mut(Identity::LEN);
        id.copy_from_slice(&self.identity.to_bytes());
        let (reason, uid) = rest.split_at_mut(1);
        if let Some(r) = reason.first_mut() {
            *r = self.reset_reason.to_byte();
        }
        match self.uid {
            Some(u) => {
                uid.copy_from_slice(&u.0);
                (b, Self::LEN)
            }
            None => (b, Self::LEN_NO_UID),
        }
    }
}

/// Capability bits reported by `identify`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(transparent)
)]
pub struct Capabilities(pub u16);

impl Capabilities {
    /// Pulse-in measurements (deferred replies).
    pub const PULSE_IN: u16 = 1 << 0;
    /// Serial function.
    pub const SERIAL: u16 = 1 << 1;
    /// Events pushed to the MB as a brief master.
    pub const EVENTS: u16 = 1 << 2;
    /// SMBus PEC.
    pub const PEC: u16 = 1 << 3;
    /// Failsafe timeout.
    pub const FAILSAFE: u16 = 1 << 4;
    /// Batches.
    pub const BATCH: u16 = 1 << 5;
    /// Scan of all sensor ports.
    pub const SCAN: u16 = 1 << 6;
    /// PWM frequency setting.
    pub const PWM_FREQUENCY: u16 = 1 << 7;
    /// PWM pulse width in µs (servos).
    pub const PWM_PULSE_WIDTH: u16 = 1 << 8;

    /// True when every bit of `bits` is set.
    pub const fn has(self, bits: u16) -> bool {
        self.0 & bits == bits
    }
}

/// Reply payload of `identify` (10 bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct Identity {
    /// [`crate::PROTOCOL_VERSION`] of the board.
    pub protocol_version: u8,
    /// Firmware version, major.minor.patch.
    pub firmware: [u8; 3],
    /// Board kind.
    pub board: BoardKind,
    /// Number of sensor ports.
    pub sensor_ports: u8,
    /// Number of actuator ports.
    pub actuator_ports: u8,
    /// Capability bits.
    pub capabilities: Capabilities,
    /// ADC resolution in bits (10 on the thesis's Arduino, 12 on RP2040 and STM32G4).
    pub adc_bits: u8,
}

impl Identity {
    /// Encoded length.
    pub const LEN: usize = 10;

    /// Parses an identify payload.
    ///
    /// # Errors
    /// [`Error::BadLength`] unless the payload is exactly [`Identity::LEN`] bytes.
    pub fn parse(payload: &[u8]) -> Result<Identity> {
        match *payload {
            [protocol_version, a, b, c, board, sensor_ports, actuator_ports, c0, c1, adc_bits] => {
                Ok(Identity {
                    protocol_version,
                    firmware: [a, b, c],
                    board: BoardKind(board),
                    sensor_ports,
                    actuator_ports,
                    capabilities: Capabilities(u16::from_le_bytes([c0, c1])),
                    adc_bits,
                })
            }
            _ => Err(Error::BadLength),
        }
    }

    /// Encodes the payload.
    pub fn to_bytes(&self) -> [u8; Self::LEN] {
        let [c0, c1] = self.capabilities.0.to_le_bytes();
        let [a, b, c] = self.firmware;
        [
            self.protocol_version,
            a,
            b,
            c,
            self.board.0,
            self.sensor_ports,
            self.actuator_ports,
            c0,
            c1,
            self.adc_bits,
        ]
    }
}

macro_rules! diagnostics {
    ($($(#[$doc:meta])* $name:ident),* $(,)?) => {
        /// Diagnostics counters of a board (reply payload of `read_diagnostics`): 14 counters,
        /// u16 LE each, in this order, saturating at 65535.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[cfg_attr(
            feature = "serde",
            derive(serde::Serialize, serde::Deserialize),
            serde(default)
        )]
        pub struct Diagnostics {
            $($(#[$doc])* pub $name: u16,)*
        }

        /// Names of the diagnostics counters, in wire order.
        pub const DIAGNOSTIC_NAMES: &[&str] = &[$(stringify!($name)),*];

        impl Diagnostics {
            /// Encoded length.
            pub const LEN: usize = 2 * DIAGNOSTIC_NAMES.len();

            /// The counters in wire order.
            pub fn values(&self) -> [u16; DIAGNOSTIC_NAMES.len()] {
                [$(self.$name),*]
            }

            /// Builds the counters from values in wire order.
            pub fn from_values(v: [u16; DIAGNOSTIC_NAMES.len()]) -> Diagnostics {
                let [$($name),*] = v;
                Diagnostics { $($name),* }
            }
        }
    };
}

diagnostics! {
    /// Requests executed with status `ok` or `pending`.
    frames_ok,
    /// Requests refused with `bad_length`.
    bad_length,
    /// Requests refused with `unknown_function`.
    unknown_function,
    /// Requests refused with `unknown_operand`.
    unknown_operand,
    /// Requests refused with `port_out_of_range` or `wrong_port_kind`.
    port_errors,
    /// Requests refused with `wrong_address`.
    wrong_address,
    /// Frames whose PEC did not match.
    pec_errors,
    /// Requests refused with `bad_argument`, `unsupported` or `busy`.
    other_errors,
    /// Events delivered to the MB.
    events_sent,
    /// Event deliveries retried (NACK or arbitration lost).
    event_retries,
    /// Events dropped because the queue was full (also reported in an overflow event).
    events_dropped,
    /// Arbitration lost while this board was a master.
    arbitration_lost,
    /// Times the failsafe put the actuators in their safe state.
    failsafe_trips,
    /// Reads with no reply waiting (answered with `no_request`).
    no_request_reads,
}

impl Diagnostics {
    /// Parses a `read_diagnostics` payload.
    ///
    /// # Errors
    /// [`Error::BadLength`] unless the payload is exactly [`Diagnostics::LEN`] bytes.
    pub fn parse(payload: &[u8]) -> Result<Diagnostics> {
        if payload.len() != Self::LEN {
            return Err(Error::BadLength);
        }
        let mut v = [0u16; DIAGNOSTIC_NAMES.len()];
        for (slot, pair) in v.iter_mut().zip(payload.chunks_exact(2)) {
            if let [a, b] = *pair {
                *slot = u16::from_le_bytes([a, b]);
            }
        }
        Ok(Diagnostics::from_values(v))
    }

    /// Encodes the payload.
    pub fn to_bytes(&self) -> [u8; Self::LEN] {
        let mut out = [0u8; Self::LEN];
        for (pair, v) in out.chunks_exact_mut(2).zip(self.values()) {
            pair.copy_from_slice(&v.to_le_bytes());
        }
        out
    }
}

/// Event enables for one pin (data of `event_enable`, 5 bytes):
/// `flags, low u16 LE, high u16 LE`. Flags: bit 0 rising edge, bit 1 falling edge, bit 2 analog
/// window (sensor ports: an event whenever the analog value crosses into or out of
/// `low..=high`); other bits must be zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default)
)]
pub struct EventConfig {
    /// Event on a rising edge of the digital pin.
    pub rising: bool,
    /// Event on a falling edge of the digital pin.
    pub falling: bool,
    /// Event when the analog value enters or leaves `low..=high`.
    pub analog_window: bool,
    /// Lower bound of the analog window.
    pub low: u16,
    /// Upper bound of the analog window.
    pub high: u16,
}

impl EventConfig {
    /// Encoded length.
    pub const LEN: usize = 5;

    /// All events off.
    pub const OFF: EventConfig = EventConfig {
        rising: false,
        falling: false,
        analog_window: false,
        low: 0,
        high: 0,
    };

    /// Parses the data of an `event_enable` request.
    ///
    /// # Errors
    /// [`Error::BadLength`] unless exactly 5 bytes; [`Error::BadArgument`] for reserved flag
    /// bits or an analog window with `low > high`.
    pub fn parse(data: &[u8]) -> Result<EventConfig> {
        let [flags, l0, l1, h0, h1] = *data else {
            return Err(Error::BadLength);
        };
        if flags & !0b111 != 0 {
            return Err(Error::BadArgument);
        }
        let cfg = EventConfig {
            rising: flags & 1 != 0,
            falling: flags & 2 != 0,
            analog_window: flags & 4 != 0,
            low: u16::from_le_bytes([l0, l1]),
            high: u16::from_le_bytes([h0, h1]),
        };
        if cfg.analog_window && cfg.low > cfg.high {
            return Err(Error::BadArgument);
        }
        Ok(cfg)
    }

    /// Encodes the data.
    pub fn to_bytes(&self) -> [u8; Self::LEN] {
        let flags = self.rising as u8 | (self.falling as u8) << 1 | (self.analog_window as u8) << 2;
        let [l0, l1] = self.low.to_le_bytes();
        let [h0, h1] = self.high.to_le_bytes();
        [flags, l0, l1, h0, h1]
    }
}

/// Reply payload of `scan`: `n, digital u16 LE, analog u16 LE × n`. Digital bit `2i` is pin A
/// of sensor port `i + 1`, bit `2i + 1` its pin B.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(
        into = "crate::serde_repr::ScanRepr",
        try_from = "crate::serde_repr::ScanRepr"
    )
)]
pub struct ScanResult {
    /// Number of sensor ports reported (at most [`ScanResult::MAX_PORTS`]).
    pub ports: u8,
    /// Digital pin levels, two bits per port.
    pub digital: u16,
    /// Analog values; entries at and after `ports` are zero.
    pub analog: [u16; ScanResult::MAX_PORTS],
}

impl ScanResult {
    /// Most sensor ports one scan reports.
    pub const MAX_PORTS: usize = 8;
    /// Longest scan payload: 3 + 2 × [`ScanResult::MAX_PORTS`] = 19 bytes.
    pub const MAX_LEN: usize = 3 + 2 * Self::MAX_PORTS;

    /// Encoded length for this number of ports.
    pub const fn len(&self) -> usize {
        3 + 2 * self.ports as usize
    }

    /// True when no port is reported.
    pub const fn is_empty(&self) -> bool {
        self.ports == 0
    }

    /// Level of pin `pin` (0 = A, 1 = B) of 1-based sensor port `port`.
    pub fn digital(&self, port: u8, pin: usize) -> Option<bool> {
        if port == 0 || port > self.ports || pin > 1 {
            return None;
        }
        Some(self.digital >> (2 * (port as usize - 1) + pin) & 1 != 0)
    }

    /// Analog value of 1-based sensor port `port`.
    pub fn analog(&self, port: u8) -> Option<u16> {
        if port == 0 || port > self.ports {
            return None;
        }
        self.analog.get(port as usize - 1).copied()
    }

    /// Parses a scan payload.
    ///
    /// # Errors
    /// [`Error::BadLength`] when the length does not match the port count,
    /// [`Error::TooLong`] for more than [`ScanResult::MAX_PORTS`] ports.
    pub fn parse(payload: &[u8]) -> Result<ScanResult> {
        let [n, d0, d1, ref rest @ ..] = *payload else {
            return Err(Error::BadLength);
        };
        if n as usize > Self::MAX_PORTS {
            return Err(Error::TooLong);
        }
        if rest.len() != 2 * n as usize {
            return Err(Error::BadLength);
        }
        let mut analog = [0u16; Self::MAX_PORTS];
        for (slot, pair) in analog.iter_mut().zip(rest.chunks_exact(2)) {
            if let [a, b] = *pair {
                *slot = u16::from_le_bytes([a, b]);
            }
        }
        Ok(ScanResult {
            ports: n,
            digital: u16::from_le_bytes([d0, d1]),
            analog,
        })
    }

    /// Encodes the payload into `buf`; returns its length.
    ///
    /// # Errors
    /// [`Error::TooLong`] for more than [`ScanResult::MAX_PORTS`] ports,
    /// [`Error::BufferTooShort`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        if self.ports as usize > Self::MAX_PORTS {
            return Err(Error::TooLong);
        }
        let out = buf.get_mut(..self.len()).ok_or(Error::BufferTooShort)?;
        let (head, rest) = out.split_at_mut(3);
        let [d0, d1] = self.digital.to_le_bytes();
        head.copy_from_slice(&[self.ports, d0, d1]);
        for (pair, v) in rest.chunks_exact_mut(2).zip(self.analog) {
            pair.copy_from_slice(&v.to_le_bytes());
        }
        Ok(self.len())
    }
}
