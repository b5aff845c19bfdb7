//! The soak's ledger of event-pin edges: every edge of an event pin's script, from the
//! instant its board started latching it, accounted for against what the board wrote on the
//! bus and what the waiting task got, with the reason of every loss.
//!
//! Ground truth only: the pin's script, the instants at which the board's ports were told to
//! latch the pin ([`x10_sim::ports::ActuatorLog::latches`]), the bus's record of every event
//! frame the board wrote (as written and as received) and the resets. The runtimes' counters
//! are not used here.

use x10_sim::exec::Nanos;
use x10_sim::ports::Digital;

/// One `pin_change` event: when (first written, or returned by `wait_event`), the level it
/// reports and the edges it carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PinEv {
    /// Instant (ns).
    pub t: Nanos,
    /// The level it reports.
    pub level: bool,
    /// Rising edges it carries.
    pub rising: u16,
    /// Falling edges it carries.
    pub falling: u16,
}

impl PinEv {
    /// The payload `[level, rising u16 LE, falling u16 LE]`, if it is one.
    pub fn parse(t: Nanos, payload: &[u8]) -> Option<PinEv> {
        match *payload {
            [l @ (0 | 1), r0, r1, f0, f1] => Some(PinEv {
                t,
                level: l == 1,
                rising: u16::from_le_bytes([r0, r1]),
                falling: u16::from_le_bytes([f0, f1]),
            }),
            _ => None,
        }
    }

    fn same_payload(&self, other: &PinEv) -> bool {
        (self.level, self.rising, self.falling) == (other.level, other.rising, other.falling)
    }

    fn edges(&self) -> usize {
        usize::from(self.rising) + usize::from(self.falling)
    }
}

/// An event a board wrote to the motherboard (all attempts of one event number).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SentEv {
    /// The event, at its first attempt.
    pub ev: PinEv,
    /// When an attempt reached the motherboard as written, if one did.
    pub intact_at: Option<Nanos>,
    /// When it did not: true if the motherboard counts the loss (an attempt reached it
    /// corrupted, so it is refused as a bad event, or a later event of the board reached it
    /// intact in the same boot, so it sees the gap in the board's event counter).
    pub counted: bool,
}

/// One boot of a board: from `start` to `end` (its reset, or the end of the run).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Epoch {
    /// Boot (ns).
    pub start: Nanos,
    /// Reset or end of the run (ns).
    pub end: Nanos,
    /// Instants the board started latching the pin (each enable), in time order.
    pub latches: Vec<Nanos>,
    /// The pin's events the board wrote, in order.
    pub sent: Vec<SentEv>,
}

/// Edges (and events) by outcome.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeCounts {
    /// Script edges after the first latch of each boot.
    pub edges: u64,
    /// Carried by an event that `wait_event` returned.
    pub delivered: u64,
    /// Carried by an event lost on the bus, a loss the motherboard counts.
    pub lost_bus_counted: u64,
    /// Carried by an event lost on the bus that the motherboard cannot count (no corrupted
    /// attempt reached it, no later event of that boot did).
    pub lost_bus_silent: u64,
    /// Carried by an event that reached the motherboard intact but no `wait_event` returned.
    pub lost_mb: u64,
    /// Such events.
    pub lost_mb_events: u64,
    /// Not written by the board before it reset or the run ended, within the guard of it.
    pub excused_end: u64,
    /// Not written by the board before an enable restarted its counts, within the guard of
    /// that enable.
    pub excused_reenable: u64,
    /// Never written by the board, not excused: lost silently in the board.
    pub unsent: u64,
    /// Events the board wrote that the script does not explain (counts or level).
    pub wrong_sent: u64,
    /// Events `wait_event` returned that the board never wrote intact (nor as a retry).
    pub wrong_delivered: u64,
}

impl EdgeCounts {
    /// Adds `o`.
    pub fn add(&mut self, o: &EdgeCounts) {
        self.edges += o.edges;
        self.delivered += o.delivered;
        self.lost_bus_counted += o.lost_bus_counted;
        self.lost_bus_silent += o.lost_bus_silent;
        self.lost_mb += o.lost_mb;
        self.lost_mb_events += o.lost_mb_events;
        self.excused_end += o.excused_end;
        self.excused_reenable += o.excused_reenable;
        self.unsent += o.unsent;
        self.wrong_sent += o.wrong_sent;
        self.wrong_delivered += o.wrong_delivered;
    }
}

/// Every edge of `script` in `(from, to]`: instant and new level.
pub fn script_edges(script: &Digital, from: Nanos, to: Nanos) -> Vec<(Nanos, bool)> {
    let mut v = Vec::new();
    let mut t = from;
    while let Some(e) = script.next_change_after(t).filter(|&e| e <= to) {
        v.push((e, script.level_at(e)));
        t = e;
    }
    v
}

/// The ledger of one board's event pin: its boots (with what it wrote) and what
/// `wait_event` returned for it, in order. Edges within `guard` ns before a reset, the end of
/// the run (`run_end`) or a later enable may be missing without blame, and so may events
/// that reached the motherboard within `guard` of the end of the run.
///
/// The board's events must carry the script's edges in order: after a latch at `l`, the
/// `n`-th edge counted is the `n`-th edge of the script after `l`; each event carries the
/// next edges (as many rising and falling as it says, all before it was written) and
/// reports the level they leave. An event that fits only from a later latch restarts
/// there (the edges skipped were discarded by that enable). `wait_event` must return the
/// events that reached the motherboard intact, in order, each once.
pub fn ledger(
    script: &Digital,
    epochs: &[Epoch],
    got: &[PinEv],
    guard: Nanos,
    run_end: Nanos,
) -> EdgeCounts {
    let mut c = EdgeCounts::default();
    // Which sent events wait_event returned: (epoch, index) in arrival order.
    let mut arrived: Vec<(Nanos, usize, usize)> = epochs
        .iter()
        .enumerate()
        .flat_map(|(k, ep)| {
            ep.sent
                .iter()
                .enumerate()
                .filter_map(move |(i, s)| s.intact_at.map(|t| (t, k, i)))
        })
        .collect();
    arrived.sort_unstable();
    let mut delivered: Vec<Vec<bool>> = epochs.iter().map(|e| vec![false; e.sent.len()]).collect();
    let mut next = 0usize;
    for g in got {
        let found = arrived
            .iter()
            .enumerate()
            .skip(next)
            .take_while(|(_, &(t, _, _))| t <= g.t)
            .find(|(_, &(_, k, i))| epochs[k].sent[i].ev.same_payload(g));
        match found {
            Some((j, &(_, k, i))) => {
                delivered[k][i] = true;
                next = j + 1;
            }
            None => c.wrong_delivered += 1,
        }
    }
    for (ep, delivered) in epochs.iter().zip(&delivered) {
        c.add(&epoch_ledger(script, ep, delivered, guard, run_end));
    }
    c
}

/// One boot's events laid over the script's edges.
struct Walk<'a> {
    ep: &'a Epoch,
    edges: Vec<(Nanos, bool)>,
    /// The level at the first latch.
    start_level: bool,
    guard: Nanos,
}

/// Where the events of a boot have been laid so far.
#[derive(Clone)]
struct Laid {
    /// Per edge: the event that carries it.
    owner: Vec<Option<usize>>,
    /// Events the script does not explain.
    wrong: u64,
    /// The next edge to carry, and the latch counted from.
    pos: usize,
    latch: usize,
    /// The last event was laid after the one before although it fitted from a later enable
    /// too (it was queued before that enable): the next one restarts if it can (a pin has
    /// one event in the queue at a time).
    crossed: bool,
}

impl Walk<'_> {
    /// Does `ev` carry the edges from index `p` on (all before it was written, as many
    /// rising and falling, leaving the level it reports)?
    fn fits(&self, p: usize, ev: &PinEv) -> bool {
        let Some(span) = self.edges.get(p..p + ev.edges()) else {
            return false;
        };
        let before = p
            .checked_sub(1)
            .map_or(self.start_level, |i| self.edges[i].1);
        let rising = span.iter().filter(|e| e.1).count();
        let level = span.last().map_or(before, |e| e.1);
        rising == usize::from(ev.rising) && span.iter().all(|e| e.0 <= ev.t) && level == ev.level
    }

    fn first_after(&self, t: Nanos) -> usize {
        self.edges.partition_point(|e| e.0 <= t)
    }

    /// Edges before `until` a laying leaves unexplained (not carried, not excused), and its
    /// wrong events: the lower the better.
    fn score(&self, l: &Laid, until: Nanos) -> u64 {
        let unexplained = (0..self.edges.len())
            .take_while(|&j| self.edges[j].0 < until)
            .filter(|&j| l.owner[j].is_none() && !self.excused(j))
            .count() as u64;
        l.wrong * 1_000 + unexplained
    }

    fn excused(&self, j: usize) -> bool {
        self.excused_by_enable(j) || self.edges[j].0 + self.guard > self.ep.end
    }

    /// An edge not carried within `guard` before an enable: the enable restarted the counts
    /// (edges latched but not yet reported are not reported, by the protocol).
    fn excused_by_enable(&self, j: usize) -> bool {
        let t = self.edges[j].0;
        let next = self.ep.latches.partition_point(|&at| at < t);
        self.ep
            .latches
            .get(next)
            .is_some_and(|&at| t + self.guard > at)
    }

    /// Lays events `from..` in order (those written before `until`). An event that fits
    /// both after the previous one and from a later enable is either the one event of the
    /// pin queued before that enable and written after it, or the first counted from it:
    /// with `choose`, the events up to the next enable are laid each way and the way that
    /// explains more edges before it is kept.
    fn lay(&self, l: &mut Laid, from: usize, until: Nanos, choose: bool) {
        for i in from..self.ep.sent.len() {
            let ev = &self.ep.sent[i].ev;
            if ev.t >= until {
                return;
            }
            // The latest later enable the event fits from, if any.
            let restart = (l.latch + 1..self.ep.latches.len())
                .rev()
                .filter(|&k| self.ep.latches[k] <= ev.t)
                .map(|k| (k, self.first_after(self.ep.latches[k])))
                .find(|&(_, p)| p >= l.pos && self.fits(p, ev));
            let mut go_on = self.fits(l.pos, ev) && !(l.crossed && restart.is_some());
            if let (true, Some((k, _)), true) = (go_on, restart, choose) {
                let next = self.ep.latches.get(k + 1).copied().unwrap_or(self.ep.end);
                let mut a = l.clone();
                self.step(&mut a, i, None);
                a.crossed = true;
                self.lay(&mut a, i + 1, next, false);
                let mut b = l.clone();
                self.step(&mut b, i, restart);
                self.lay(&mut b, i + 1, next, false);
                go_on = self.score(&a, next) < self.score(&b, next);
            }
            match (go_on, restart) {
                (true, r) => {
                    self.step(l, i, None);
                    l.crossed = r.is_some();
                }
                (false, Some(r)) => {
                    self.step(l, i, Some(r));
                    l.crossed = false;
                }
                (false, None) => l.wrong += 1,
            }
        }
    }

    /// Lays event `i` after the previous one, or from enable `k` at edge `p`.
    fn step(&self, l: &mut Laid, i: usize, restart: Option<(usize, usize)>) {
        if let Some((k, p)) = restart {
            l.latch = k;
            l.pos = p;
        }
        let n = self.ep.sent[i].ev.edges();
        for slot in l.owner.iter_mut().skip(l.pos).take(n) {
            *slot = Some(i);
        }
        l.pos += n;
    }
}

fn epoch_ledger(
    script: &Digital,
    ep: &Epoch,
    delivered: &[bool],
    guard: Nanos,
    run_end: Nanos,
) -> EdgeCounts {
    let mut c = EdgeCounts::default();
    let Some(&first) = ep.latches.first() else {
        c.wrong_sent += ep.sent.len() as u64;
        return c;
    };
    let walk = Walk {
        ep,
        edges: script_edges(script, first, ep.end),
        start_level: script.level_at(first),
        guard,
    };
    let n = walk.edges.len();
    c.edges = n as u64;
    let mut l = Laid {
        owner: vec![None; n],
        wrong: 0,
        pos: 0,
        latch: 0,
        crossed: false,
    };
    walk.lay(&mut l, 0, Nanos::MAX, true);
    c.wrong_sent = l.wrong;
    let mut mb_events = vec![false; ep.sent.len()];
    for (j, &(t, _)) in walk.edges.iter().enumerate() {
        let near_end = t + guard > ep.end;
        match l.owner[j] {
            Some(i) if delivered[i] => c.delivered += 1,
            // Reached the motherboard when the run was ending: no time to deliver it.
            Some(i) if ep.sent[i].intact_at.is_some_and(|a| a + guard > run_end) => {
                c.excused_end += 1;
            }
            Some(i) if ep.sent[i].intact_at.is_some() => {
                c.lost_mb += 1;
                mb_events[i] = true;
            }
            Some(i) if ep.sent[i].counted => c.lost_bus_counted += 1,
            Some(_) if near_end => c.excused_end += 1,
            Some(_) => c.lost_bus_silent += 1,
            None if walk.excused_by_enable(j) => c.excused_reenable += 1,
            None if near_end => c.excused_end += 1,
            None => c.unsent += 1,
        }
    }
    c.lost_mb_events = mb_events.iter().filter(|&&m| m).count() as u64;
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Nanos = 1_000_000;

    /// Toggles at 10, 20, …, 100 ms (low before).
    fn script() -> Digital {
        Digital::Toggles {
            initial: false,
            toggles_ms: (1..=10).map(|k| 10 * k).collect(),
        }
    }

    fn ev(t_ms: u64, level: bool, rising: u16, falling: u16) -> PinEv {
        PinEv {
            t: t_ms * MS,
            level,
            rising,
            falling,
        }
    }

    fn sent(e: PinEv, delay_ms: Option<u64>) -> SentEv {
        SentEv {
            ev: e,
            intact_at: delay_ms.map(|d| e.t + d * MS),
            counted: false,
        }
    }

    fn at(mut e: PinEv, delay_ms: u64) -> PinEv {
        e.t += delay_ms * MS;
        e
    }

    #[test]
    fn every_edge_delivered_in_order_is_clean() {
        let evs = [
            ev(11, true, 1, 0),
            ev(45, false, 1, 2),
            ev(101, false, 3, 3),
        ];
        let ep = Epoch {
            start: 0,
            end: 200 * MS,
            latches: vec![5 * MS],
            sent: evs.iter().map(|&e| sent(e, Some(1))).collect(),
        };
        let got: Vec<PinEv> = evs.iter().map(|&e| at(e, 2)).collect();
        let c = ledger(&script(), &[ep], &got, 20 * MS, 1_000 * MS);
        assert_eq!(
            c,
            EdgeCounts {
                edges: 10,
                delivered: 10,
                ..EdgeCounts::default()
            }
        );
    }

    #[test]
    fn losses_get_their_reason() {
        // Latched at 25 ms: edges at 30 .. 100 ms (8). The board sends 30 (counted bus
        // loss), 40+50 (intact, not delivered), 60 (delivered); never 70 and 80 (unsent);
        // 90 and 100 lie within the guard of the reset at 105 ms.
        let ep = Epoch {
            start: 0,
            end: 105 * MS,
            latches: vec![25 * MS],
            sent: vec![
                SentEv {
                    counted: true,
                    ..sent(ev(31, true, 1, 0), None)
                },
                sent(ev(51, true, 1, 1), Some(1)),
                sent(ev(61, false, 0, 1), Some(1)),
            ],
        };
        let got = [ev(63, false, 0, 1)];
        let c = ledger(&script(), &[ep], &got, 20 * MS, 1_000 * MS);
        assert_eq!(
            c,
            EdgeCounts {
                edges: 8,
                delivered: 1,
                lost_bus_counted: 1,
                lost_mb: 2,
                lost_mb_events: 1,
                unsent: 2,
                excused_end: 2,
                ..EdgeCounts::default()
            }
        );
    }

    #[test]
    fn a_wrong_count_a_wrong_level_and_an_unknown_delivery_are_wrong() {
        let ep = Epoch {
            start: 0,
            end: 200 * MS,
            latches: vec![5 * MS],
            sent: vec![
                // Two edges by 21 ms, but it says three.
                sent(ev(21, false, 2, 1), Some(1)),
                // One edge by 11 ms, but the level it reports is low.
                sent(ev(11, false, 1, 0), Some(1)),
            ],
        };
        let got = [ev(30, true, 5, 5)];
        let c = ledger(&script(), &[ep], &got, 20 * MS, 1_000 * MS);
        assert_eq!((c.wrong_sent, c.wrong_delivered, c.unsent), (2, 1, 10));
    }

    #[test]
    fn an_event_queued_before_an_enable_and_written_after_it_is_told_apart() {
        // Latched at 5 ms and again at 62 ms (50 and 60 ms are discarded). Events: 10+20,
        // then 30+40 (queued before the second enable, written at 85 ms), then 70+80 and
        // 90+100: each of the last three fits after the one before as well as from the
        // enable (one rising and one falling edge, low after), but only one way explains
        // every edge.
        let evs = [
            ev(21, false, 1, 1),
            ev(85, false, 1, 1),
            ev(86, false, 1, 1),
            ev(101, false, 1, 1),
        ];
        let ep = Epoch {
            start: 0,
            end: 200 * MS,
            latches: vec![5 * MS, 62 * MS],
            sent: evs.iter().map(|&e| sent(e, Some(1))).collect(),
        };
        let got: Vec<PinEv> = evs.iter().map(|&e| at(e, 2)).collect();
        let c = ledger(&script(), &[ep], &got, 20 * MS, 1_000 * MS);
        assert_eq!(
            (
                c.edges,
                c.delivered,
                c.excused_reenable,
                c.unsent,
                c.wrong_sent
            ),
            (10, 8, 2, 0, 0)
        );
    }

    #[test]
    fn edges_an_enable_discarded_are_excused_without_a_later_event() {
        // Latched at 5 ms and again at 45 ms; the board sends 10+20, then nothing: 30 and
        // 40 ms lie within 20 ms before the second enable (excused), 50 .. 100 ms were never
        // sent (unsent).
        let ep = Epoch {
            start: 0,
            end: 200 * MS,
            latches: vec![5 * MS, 45 * MS],
            sent: vec![sent(ev(21, false, 1, 1), Some(1))],
        };
        let got = [ev(23, false, 1, 1)];
        let c = ledger(&script(), &[ep], &got, 20 * MS, 1_000 * MS);
        assert_eq!(
            (c.edges, c.delivered, c.excused_reenable, c.unsent),
            (10, 2, 2, 6)
        );
    }

    #[test]
    fn a_second_enable_restarts_the_count() {
        // Latched at 5 ms, then again at 33 ms (the edge at 30 ms is discarded, within the
        // guard of that enable); events from each latch.
        let ep = Epoch {
            start: 0,
            end: 200 * MS,
            latches: vec![5 * MS, 33 * MS],
            sent: vec![
                sent(ev(21, false, 1, 1), Some(1)),
                sent(ev(55, true, 1, 1), Some(1)),
            ],
        };
        let got = [ev(23, false, 1, 1), ev(57, true, 1, 1)];
        let c = ledger(&script(), &[ep], &got, 20 * MS, 1_000 * MS);
        assert_eq!(
            (c.edges, c.delivered, c.excused_reenable, c.unsent),
            (10, 4, 1, 5)
        );
    }
}
