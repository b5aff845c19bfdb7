//! The keepalive of one board does not wait for another's: with a board gone (every
//! transaction NACKed), the other board's heartbeat goes out as soon as the absent board's
//! heartbeat has used up its bus retries, ahead of anything queued after it was due, and its
//! failsafe never trips.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use common::{LoopBus, Node, Seen, World};
use embassy_futures::select::select;
use x10_devices::LinkError;
use x10_hal::time::{Clock, Instant};
use x10_microcode::{Address, Op, Port};

fn addr(b: u8) -> Address {
    Address::external(b).unwrap()
}

/// `heartbeat` to `board` with sequence number `seq`.
fn heartbeat(board: u8, seq: u8) -> Vec<u8> {
    vec![0x02, board, 0x00, seq]
}

/// The writes to `board` (start time, bytes).
fn writes_to(bus: &LoopBus, board: u8) -> Vec<(u64, Vec<u8>)> {
    bus.seen()
        .into_iter()
        .filter_map(|(t, s)| match s {
            Seen::Write(b, bytes) | Seen::WriteRead(b, bytes, _) if b == board => Some((t, bytes)),
            _ => None,
        })
        .collect()
}

/// DB 9 (present) and board 10, each with a 300 ms failsafe set by a program (board 10 first,
/// at 1 000 µs), after which board 10 goes away; `program` runs beside until 1 s.
fn run(program: impl Fn(&World) -> Box<dyn std::future::Future<Output = ()> + '_>) -> World {
    let w = World::new();
    w.bus.attach(
        10,
        Node::Script(Box::new(|req| (0, vec![req[3], 0x00, 0x00]))),
    );
    w.bus.attach(0x20, Node::Silent);
    w.sim(async {
        w.clock.sleep_until(Instant(1_000)).await;
        for b in [10, 9] {
            w.mb.call(addr(b), Op::SetFailsafe { timeout_ms: 300 })
                .await
                .unwrap();
        }
        // board 10 goes away: every transaction to it is NACKed from now on
        w.bus.attach(10, Node::Absent);
        select(
            Box::into_pin(program(&w)),
            w.clock.sleep_until(Instant(1_000_000)),
        )
        .await;
    });
    w
}

/// Checks the common outcome: board 10's heartbeats, lost, are tried again half an interval
/// (50 ms) after each was due, three times, then once per interval (100 ms): 11 tries in the
/// second, the first of five NACKed attempts, the others of one (board 10 is silent after
/// the first). Every heartbeat to DB 9 starts at most one NACKed try of board 10 (at most
/// five attempts and their backoff, under 3 ms) after it was due; DB 9 never trips. Returns
/// DB 9's heartbeat start times.
fn check(w: &World) -> Vec<u64> {
    let to9 = w.writes_to_9();
    let to10 = writes_to(&w.bus, 10);
    assert_eq!(to9.len(), 10);
    // Its first lost heartbeat is tried at all five attempts; from then on board 10 is
    // silent and each try is a single attempt (`retry_for`): 1 + 5 + 10 writes.
    assert_eq!(to10.len(), 1 + 5 + 10);
    // The first attempt of each of board 10's tries, in ms.
    let tries: Vec<u64> = to10
        .iter()
        .enumerate()
        .filter(|(i, _)| *i == 1 || *i >= 6)
        .map(|(_, (t, _))| *t / 1_000)
        .collect();
    assert_eq!(tries.len(), 11);
    assert_eq!(tries[..4], [101, 151, 201, 251]);
    for pair in tries[3..].windows(2) {
        assert!((100..=103).contains(&(pair[1] - pair[0])), "{tries:?}");
    }
    for (k, (at, bytes)) in to9.iter().enumerate().skip(1) {
        assert_eq!(bytes, &heartbeat(9, k as u8));
        let gap = at - to9[k - 1].0;
        assert!((100_000..=103_000).contains(&gap), "round {k}: {gap} µs");
    }
    // Keepalives are the dispatcher's own, not requests: their NACKed attempts are counted
    // (`nacked`), no request ended in `Nack`.
    let d = w.mb.diagnostics();
    assert_eq!(
        (d.keepalives, d.keepalive_failures, d.nacks, d.nacked),
        (9, 11, 0, 15)
    );
    let dd = w.db9.diagnostics();
    assert_eq!((dd.failsafe_trips, dd.frames_ok), (0, 10));
    to9.iter().map(|(t, _)| *t).collect()
}

impl World {
    fn writes_to_9(&self) -> Vec<(u64, Vec<u8>)> {
        writes_to(&self.bus, 9)
    }
}

#[test]
fn an_absent_board_costs_another_boards_heartbeat_only_its_retries() {
    let w = run(|_| Box::new(std::future::pending()));
    let times = check(&w);
    // Board 10's first heartbeat is due 100 µs before DB 9's and takes 2.4 ms of NACKed
    // attempts and backoff (`RetryPolicy::DEFAULT`); DB 9's follows at once. From then on
    // board 10's tries fall between DB 9's (50 ms apart, then 100 ms apart but out of step),
    // so DB 9's heartbeats go out every 100.1 ms, far inside its 300 ms failsafe.
    assert_eq!(
        times,
        [1_100, 103_502, 203_602, 303_702, 403_802, 503_902, 604_002, 704_102, 804_202, 904_302]
    );
}

#[test]
fn a_heartbeat_waits_for_an_absent_board_and_one_stalled_read_at_most() {
    // A program keeps the bus busy with reads of a board that stretches the clock (25 ms
    // each, then `Timeout`). The dispatcher sends keepalives itself, between jobs, due ones
    // first: DB 9's, due while board 10's is being NACKed, goes right after board 10's gave
    // up, before the program's next read. So a heartbeat waits for one stalled read (the
    // one on the bus when it fell due) and the absent board's retries at most, far inside
    // the 300 ms failsafe: heartbeats are due at a third of the timeout, and each keepalive
    // gives up after a twelfth.
    let s1 = Port::sensor(1).unwrap();
    let w = run(|w| {
        Box::new(async move {
            loop {
                let r = w.mb.call(addr(0x20), Op::AnalogRead(s1)).await;
                assert_eq!(r, Err(LinkError::Timeout));
            }
        })
    });
    let to9 = w.writes_to_9();
    let times: Vec<u64> = to9.iter().map(|(t, _)| *t).collect();
    assert_eq!(
        times,
        [1_100, 104_116, 204_816, 305_416, 406_016, 506_616, 607_216, 707_816, 808_416, 909_016]
    );
    for (k, (_, bytes)) in to9.iter().enumerate().skip(1) {
        assert_eq!(bytes, &heartbeat(9, k as u8));
    }
    // Round 1: board 10's heartbeat NACKed five times, then DB 9's at once (the dispatcher
    // sends due keepalives before the next job), then the program's read.
    let round1: Vec<_> = w
        .bus
        .seen()
        .into_iter()
        .filter(|(t, _)| (101_600..=129_316).contains(t))
        .collect();
    assert_eq!(
        round1,
        [
            (101_600, Seen::Write(10, heartbeat(10, 1))),
            (101_806, Seen::Write(10, heartbeat(10, 1))),
            (102_197, Seen::Write(10, heartbeat(10, 1))),
            (102_726, Seen::Write(10, heartbeat(10, 1))),
            (104_016, Seen::Write(10, heartbeat(10, 1))),
            (104_116, Seen::Write(9, heartbeat(9, 1))),
            (
                104_216,
                Seen::WriteRead(0x20, vec![0x30, 0x20, 0x80, 0x04], 5)
            ),
            (
                129_316,
                Seen::WriteRead(0x20, vec![0x30, 0x20, 0x80, 0x05], 5)
            ),
        ]
    );
    let dd = w.db9.diagnostics();
    assert_eq!((dd.failsafe_trips, dd.frames_ok), (0, 10));
}
