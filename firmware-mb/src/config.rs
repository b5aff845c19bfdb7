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
    /// Seed of the backoff jitter (differs per node so that colliding masters back off
    /// differently; the simulator sets it for reproducible runs).
    pub seed: u32,
    /// The internal daughterboard (address 0) on the motherboard's own ports.
    pub internal: DbConfig,
}

impl MbConfig {
    /// 100 ms per request, 1 s default pulse-in timeout, [`RetryPolicy::DEFAULT`], and an
    /// internal daughterboard with every capability.
    pub const fn new(address: Address) -> MbConfig {
        MbConfig {
            address,
            request_timeout_us: 100_000,
            default_pulse_timeout_ms: 1_000,
            retry: RetryPolicy::DEFAULT,
            seed: address.get() as u32,
            internal: DbConfig::new(Address::INTERNAL, BoardKind::INTERNAL),
        }
    }
}
