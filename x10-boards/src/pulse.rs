//! Pulse-in on a pin that can only be sampled: the edge logic, fed with samples and times.
//!
//! The STM32 module samples a pin in a loop (its EXTI lines are too few for every digital pin
//! of the pin map, and an EXTI input cannot drive the pin as an output) and hands every sample
//! to a [`PulseIn`]; the decisions (what counts as an edge, when the measurement is over, the
//! timeout) are made here and tested on the host.

use x10_hal::ports::{EdgeCount, PortError};
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

/// The end edge of a pulse to give back to a pin's edge latch after a pulse-in armed its
/// end-edge wait: one edge when the pin was at the level after the pulse right after the
/// arming (`over`, read first) and the latch, read next, shows no edge in the end's direction
/// (`latched`).
///
/// On the Pico the latch is the pin's raw interrupt bits, and arming embassy-rp's edge future
/// clears them (`gpio.rs` 296-299). The adapter arms it only when the pulse is not over yet
/// (a pulse already over keeps both edges in the latch); an end edge that comes between that
/// look and the arming is latched, then wiped by the arming, and the pin's next event
/// reported a rising edge without its falling one (issue 21 item 6). An end edge after the
/// arming is in the latch and must not be counted twice; one before it is not, and the pin is
/// then already at its end level: so the level is read before the latch.
#[must_use]
pub fn wiped_end_edge(edge: Edge, over: bool, latched: EdgeCount) -> EdgeCount {
    let (end, seen) = match edge {
        Edge::Rising => (
            EdgeCount {
                rising: 0,
                falling: 1,
            },
            latched.falling,
        ),
        Edge::Falling => (
            EdgeCount {
                rising: 1,
                falling: 0,
            },
            latched.rising,
        ),
    };
    if over && seen == 0 {
        end
    } else {
        EdgeCount::NONE
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

    const RISE: EdgeCount = EdgeCount {
        rising: 1,
        falling: 0,
    };
    const FALL: EdgeCount = EdgeCount {
        rising: 0,
        falling: 1,
    };

    #[test]
    fn an_end_edge_wiped_by_the_arming_is_given_back() {
        // Over, nothing latched since the arming: the end edge came before it and was wiped.
        assert_eq!(wiped_end_edge(Edge::Rising, true, EdgeCount::NONE), FALL);
        assert_eq!(wiped_end_edge(Edge::Falling, true, EdgeCount::NONE), RISE);
        // An edge of the other direction since the arming does not stand for it.
        assert_eq!(wiped_end_edge(Edge::Rising, true, RISE), FALL);
        assert_eq!(wiped_end_edge(Edge::Falling, true, FALL), RISE);
    }

    #[test]
    fn an_end_edge_in_the_latch_is_not_counted_twice() {
        // Over, its end edge latched after the arming: it will be taken from the latch.
        assert_eq!(wiped_end_edge(Edge::Rising, true, FALL), EdgeCount::NONE);
        assert_eq!(wiped_end_edge(Edge::Falling, true, RISE), EdgeCount::NONE);
        // Not over: the end is awaited, nothing to give back.
        for latched in [EdgeCount::NONE, RISE, FALL] {
            for edge in [Edge::Rising, Edge::Falling] {
                assert_eq!(wiped_end_edge(edge, false, latched), EdgeCount::NONE);
            }
        }
    }
}
