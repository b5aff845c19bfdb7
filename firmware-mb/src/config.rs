//! Configuration of the motherboard runtime.

use firmware_db::DbConfig;
use x10_hal::retry::RetryPolicy;
use x10_microcode::{Address, BoardKind};

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
}

impl MbConfig {
    /// 100 ms per request, 1 s default pulse-in timeout, [`RetryPolicy::DEFAULT`], 400 µs of
    /// listening after a lost arbitration, and an internal daughterboard with every
    /// capability.
    pub const fn new(address: Address) -> MbConfig {
        MbConfig {
            address,
            request_timeout_us: 100_000,
            default_pulse_timeout_ms: 1_000,
            retry: RetryPolicy::DEFAULT,
            arbitration_wait_us: 400,
            seed: address.get() as u32,
            internal: DbConfig::new(Address::INTERNAL, BoardKind::INTERNAL),
        }
    }
}
