//! Pulse-in on a pin that can only be sampled: the edge logic, fed with samples and times.
//!
//! The STM32 module samples a pin in a loop (its EXTI lines are too few for every digital pin
//! of the pin map, and an EXTI input cannot drive the pin as an output) and hands every sample
//! to a [`PulseIn`]; the decisions (what counts as an edge, when the measurement is over, the
//! timeout) are made here and tested on the host.

use x10_hal::ports::PortError;
use x10_microcode::Edge;

/// One pulse measurement: waits for the start edge (`Rising`: low → high), then for the
/// opposite edge, and reports the time between them; gives up at the deadline.
///
/// As with Arduino's `pulseIn`, a pin already at the pulse level when the measurement starts
/// has to return to the idle level first: only a real edge starts a pulse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PulseIn {
    active_high: bool,
    deadline_us: u64,
    state: State,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Waiting for the idle level (`seen_idle` false) or, once seen, for the start edge.
    Armed { seen_idle: bool },
    /// Inside the pulse since `start_us`.
    InPulse { start_us: u64 },
}

impl PulseIn {
    /// A measurement started at `now_us`, giving up `timeout_ms` later.
    pub fn new(edge: Edge, now_us: u64, timeout_ms: u16) -> PulseIn {
        PulseIn {
            active_high: matches!(edge, Edge::Rising),
            deadline_us: now_us.saturating_add(u64::from(timeout_ms) * 1_000),
            state: State::Armed { seen_idle: false },
        }
    }

    /// Feeds the pin level sampled at `now_us` (times never decrease). `None` while the
    /// measurement goes on; otherwise the pulse length in µs (saturated to `u32`).
    ///
    /// # Errors
    /// [`PortError::Timeout`] when the deadline passed before the pulse ended.
    pub fn sample(&mut self, high: bool, now_us: u64) -> Option<Result<u32, PortError>> {
        let active = high == self.active_high;
        match self.state {
            State::Armed { seen_idle: false } if !active => {
                self.state = State::Armed { seen_idle: true };
            }
            State::Armed { seen_idle: true } if active => {
                self.state = State::InPulse { start_us: now_us };
            }
            State::InPulse { start_us } if !active => {
                let us = now_us.saturating_sub(start_us);
                return Some(Ok(u32::try_from(us).unwrap_or(u32::MAX)));
            }
            _ => {}
        }
        if now_us >= self.deadline_us {
            return Some(Err(PortError::Timeout));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs a measurement over (time, level) samples.
    fn run(edge: Edge, timeout_ms: u16, samples: &[(u64, bool)]) -> Option<Result<u32, PortError>> {
        let mut p = PulseIn::new(edge, 0, timeout_ms);
        samples.iter().find_map(|&(t, high)| p.sample(high, t))
    }

    #[test]
    fn measures_a_high_pulse() {
        let s = [
            (0, false),
            (5, false),
            (10, true),
            (400, true),
            (1_510, false),
        ];
        assert_eq!(run(Edge::Rising, 10, &s), Some(Ok(1_500)));
    }

    #[test]
    fn measures_a_low_pulse() {
        let s = [(0, true), (7, false), (50, false), (107, true)];
        assert_eq!(run(Edge::Falling, 10, &s), Some(Ok(100)));
    }

    #[test]
    fn a_pin_already_in_the_pulse_waits_for_the_next_one() {
        // High at the start: that pulse is not measured, the next one is.
        let s = [(0, true), (20, false), (30, true), (90, false)];
        assert_eq!(run(Edge::Rising, 10, &s), Some(Ok(60)));
    }

    #[test]
    fn times_out_without_an_edge_or_inside_a_pulse() {
        assert_eq!(
            run(Edge::Rising, 1, &[(0, false), (999, false), (1_000, false)]),
            Some(Err(PortError::Timeout))
        );
        assert_eq!(
            run(Edge::Rising, 1, &[(0, false), (10, true), (1_000, true)]),
            Some(Err(PortError::Timeout))
        );
        assert_eq!(run(Edge::Rising, 1, &[(0, false), (999, true)]), None);
    }

    #[test]
    fn an_end_edge_seen_at_the_deadline_still_counts() {
        let s = [(0, false), (10, true), (1_000, false)];
        assert_eq!(run(Edge::Rising, 1, &s), Some(Ok(990)));
    }
}
