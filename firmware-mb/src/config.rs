//! Configuration of the motherboard runtime.

use firmware_db::DbConfig;
use x10_hal::retry::RetryPolicy;
use x10_microcode::{Address, BoardKind, Uid};

/// How the motherboard runtime behaves. Build it with [`MbConfig::new`] and change fields as
/// needed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MbConfig {
    /// The motherboard's own 7-bit address: it listens there for events and deferred replies
    /// when the dispatcher is idle.
    pub address: Address,
    /// Time a request may take in all (queueing, bus retries, reply), in µs.
    pub request_timeout_us: u64,
    /// Pulse-in timeout assumed for a request that gives none, in ms (added to
    /// `request_timeout_us` for deferred operations). Keep it equal to the boards'
    /// `DbConfig::default_pulse_timeout_ms`.
    pub default_pulse_timeout_ms: u16,
    /// Retries of one bus transaction after NACK or arbitration loss.
    pub retry: RetryPolicy,
    /// After losing arbitration the dispatcher listens at least this long (µs) before it
    /// retries, unless a write to the motherboard (the event that won) arrives first: then it
    /// retries at once. Keep it longer than a daughterboard's first event retry after a
    /// NACK (`RetryPolicy::DEFAULT`: under 150 µs) plus that NACKed write (up to 100 µs at
    /// 100 kHz), so that the event that beat an MB whose role switch is too slow to ACK it
    /// finds the MB listening on its first retry, instead of colliding with the MB's retry.
    pub arbitration_wait_us: u32,
    /// Seed of the backoff jitter (differs per node so that colliding masters back off
    /// differently; the simulator sets it for reproducible runs).
    pub seed: u32,
    /// The internal daughterboard (address 0) on the motherboard's own ports.
    pub internal: DbConfig,
    /// PEC on every external board (default `true`). Before anything else reaches a board
    /// (first contact, and again after its `boot` event or any sign that it lost PEC), the
    /// dispatcher switches PEC on and waits for the board to confirm it with a reply checked
    /// in the new mode; requests carry their PEC byte as the board's state is when they go
    /// on the bus, never as it was when they were queued. A board that refuses PEC cannot
    /// be reached: its requests end in `LinkError::Status(unsupported)`. `false` is the
    /// thesis's bytes, unchecked: **unsafe on a noisy bus** (issue 10 measured 300 wrong
    /// values returned as `Ok` and 105 uncommanded actuator changes in 2.1 M operations at
    /// 0.1 % bit flips). The internal board (address 0) is reached without the bus and never
    /// gets PEC.
    pub pec: bool,
    /// Failsafe timeout set on every external board at first contact and after its `boot`
    /// event, in ms (default [`MbConfig::DEFAULT_FAILSAFE_MS`]; 0: none). The motherboard
    /// keeps it alive: a board that heard nothing for a third of it gets a heartbeat. A
    /// program's own `SetFailsafe` replaces it for that board. 0 with `pec: false` is the
    /// thesis's behaviour: actuators keep their last command when the motherboard stops.
    pub failsafe_ms: u16,
    /// Outputs to external boards are read back (default `true`): each is one write-then-read
    /// whose status reply ends the call, so an output the board refuses (a corrupted frame,
    /// a board that lost its set-up) ends in its status or `BadReply`, never in `Ok` with the
    /// refusal arriving later as a `rejected` event. It costs the read of a 3-byte reply and
    /// its check per output (about 45 bit times, 113 µs at 400 kHz). `false` is the thesis's
    /// single write: `Ok` once the board acknowledged the bytes. The internal board is
    /// always read back (it costs no bus).
    pub confirm_outputs: bool,
    /// Addresses a person chose (plug and play): an unaddressed board named here (by its ID,
    /// or as the only board of its kind) is given this address; no other board is ever given
    /// one of them. Default: none.
    pub pinned: &'static [PinnedAddress],
}

impl MbConfig {
    /// The default failsafe: 300 ms, kept alive by a heartbeat to a quiet board every 100 ms
    /// (a third of it), LEGO's keep-alive period. A lost heartbeat is tried again half an
    /// interval after it was due, so a live board is tried at 100, 150, 200 and 250 ms of
    /// silence (each try given up after 25 ms): four in a row must be lost before it trips,
    /// and a board whose motherboard stopped puts its actuators in their safe state within
    /// 300 ms. The cost on the bus: one heartbeat with PEC is 6
    /// bytes (address + 4 + PEC), about 56 bit times, 140 µs at 400 kHz, so 0.14 % of the
    /// bus per quiet board (0.56 % at 100 kHz); a board that hears a request in that time
    /// costs nothing.
    pub const DEFAULT_FAILSAFE_MS: u16 = 300;

    /// The safe defaults: PEC on every external board, a failsafe of
    /// [`MbConfig::DEFAULT_FAILSAFE_MS`] kept alive on every board, outputs read back, 100 ms per request, 1 s
    /// default pulse-in timeout, [`RetryPolicy::DEFAULT`], 400 µs of listening after a lost
    /// arbitration, and an internal daughterboard with every capability.
    pub const fn new(address: Address) -> MbConfig {
        MbConfig {
            address,
            request_timeout_us: 100_000,
            default_pulse_timeout_ms: 1_000,
            retry: RetryPolicy::DEFAULT,
            arbitration_wait_us: 400,
            seed: address.get() as u32,
            internal: DbConfig::new(Address::INTERNAL, BoardKind::INTERNAL),
            pec: true,
            failsafe_ms: Self::DEFAULT_FAILSAFE_MS,
            confirm_outputs: true,
            pinned: &[],
        }
    }

    /// The thesis's exact behaviour: requests are the thesis's bytes (no PEC) and no failsafe
    /// is set (PEC and failsafes only if a program asks for them). **Unsafe on a noisy bus**:
    /// a flipped bit can return a wrong value as `Ok` or change an actuator nobody commanded
    /// (see [`MbConfig::pec`]), and actuators keep running when the motherboard stops.
    pub const fn thesis_compatible(address: Address) -> MbConfig {
        let mut c = Self::new(address);
        c.pec = false;
        c.failsafe_ms = 0;
        c.confirm_outputs = false;
        c
    }

    /// True when the motherboard prepares each external board before its first request
    /// (PEC, failsafe).
    pub(crate) const fn manages_boards(&self) -> bool {
        self.pec || self.failsafe_ms > 0
    }
}

/// Which boards a pinned address is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PinBy {
    /// The board with this ID.
    Uid(Uid),
    /// The only board of this kind (while there is one; a second of the kind gets an address
    /// of its own, and neither takes this one).
    Kind(BoardKind),
}

/// An address a person chose (`MbConfig::pinned`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PinnedAddress {
    /// The board meant.
    pub by: PinBy,
    /// Its address (`0x08..=0x76`, not the motherboard's own).
    pub address: Address,
}
