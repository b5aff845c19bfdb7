//! Retry with bounded exponential backoff and deterministic jitter.
//!
//! Used by the MB dispatcher (arbitration lost, NACK from a DB that is briefly a master) and by
//! DBs delivering events (NACK from an RP2040 MB in its controller window, arbitration lost).
//! Jitter comes from a small xorshift generator seeded per node, so two boards that collide
//! back off differently, and a simulation replays exactly.

/// Retry policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RetryPolicy {
    /// Attempts in all, the first included (at least 1).
    pub attempts: u8,
    /// Backoff before the second attempt, in µs.
    pub base_us: u32,
    /// Largest backoff, in µs.
    pub max_us: u32,
}

impl RetryPolicy {
    /// The default: 5 attempts, 100 µs doubling to at most 3.2 ms.
    pub const DEFAULT: RetryPolicy = RetryPolicy {
        attempts: 5,
        base_us: 100,
        max_us: 3_200,
    };
}

impl Default for RetryPolicy {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Backoff state for one operation being retried.
#[derive(Clone, Debug)]
pub struct Backoff {
    policy: RetryPolicy,
    attempt: u8,
    rng: u32,
}

impl Backoff {
    /// A fresh backoff; `seed` should differ per node (its address works) and per operation.
    pub fn new(policy: RetryPolicy, seed: u32) -> Backoff {
        Backoff {
            policy,
            attempt: 0,
            // xorshift must not start at 0
            rng: seed.wrapping_mul(0x9E37_79B9) | 1,
        }
    }

    /// Attempts made so far.
    pub fn attempts(&self) -> u8 {
        self.attempt
    }

    /// Records a failed attempt; returns the delay in µs before the next one, or `None` when
    /// the attempts are used up. The delay is `base · 2^(n-1)` capped at `max`, plus up to half
    /// of that again as jitter.
    pub fn next_delay_us(&mut self) -> Option<u32> {
        self.attempt = self.attempt.saturating_add(1);
        if self.attempt >= self.policy.attempts.max(1) {
            return None;
        }
        let shift = u32::from(self.attempt - 1).min(16);
        let delay = self
            .policy
            .base_us
            .saturating_mul(1u32 << shift)
            .min(self.policy.max_us);
        // xorshift32
        let mut x = self.rng;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.rng = x;
        let jitter = if delay >= 2 { x % (delay / 2) } else { 0 };
        Some(delay + jitter)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doubles_caps_and_ends() {
        let p = RetryPolicy {
            attempts: 4,
            base_us: 100,
            max_us: 250,
        };
        let mut b = Backoff::new(p, 0x42);
        let d1 = b.next_delay_us().unwrap();
        let d2 = b.next_delay_us().unwrap();
        let d3 = b.next_delay_us().unwrap();
        assert!((100..150).contains(&d1), "{d1}");
        assert!((200..300).contains(&d2), "{d2}");
        assert!((250..375).contains(&d3), "{d3}");
        assert_eq!(b.next_delay_us(), None);
        assert_eq!(b.attempts(), 4);
    }

    #[test]
    fn same_seed_same_delays_other_seed_differs() {
        let run = |seed| {
            let mut b = Backoff::new(RetryPolicy::DEFAULT, seed);
            core::array::from_fn::<_, 4, _>(|_| b.next_delay_us())
        };
        assert_eq!(run(9), run(9));
        assert_ne!(run(9), run(10));
    }

    #[test]
    fn single_attempt_never_retries() {
        let mut b = Backoff::new(
            RetryPolicy {
                attempts: 1,
                base_us: 1,
                max_us: 1,
            },
            1,
        );
        assert_eq!(b.next_delay_us(), None);
    }
}
