//! The motherboard runtime on a loopback bus with scripted daughterboards.

mod common;

use std::cell::{Cell, RefCell};
use std::rc::Rc;
use x10_microcode::test_support::{a, s};

use common::{db, mb_address, Db, Fault, LoopBus, Node, PortOp, Seen, BUS_TIMEOUT_US, TRANSFER_US};
use embassy_futures::join::{join, join_array};
use embassy_futures::select::{select, Either};
use firmware_mb::{MbConfig, MAX_PENDING};
use x10_devices::LinkError;
use x10_hal::bus::BusError;
use x10_hal::time::{Clock, Instant};
use x10_microcode::{pec, Address, Edge, EventConfig, EventKind, Level, Op, Pin, Status};

/// The shared world (MB and DB 9) plus a second real daughterboard at 17.
struct TwoBoards {
    w: common::World,
    db17: Rc<Db>,
}

impl std::ops::Deref for TwoBoards {
    type Target = common::World;

    fn deref(&self) -> &common::World {
        &self.w
    }
}

fn world() -> TwoBoards {
    let w = common::World::new();
    let db17 = Rc::new(db(&w.clock, 17));
    w.bus.attach(17, Node::Db(db17.clone()));
    TwoBoards { w, db17 }
}

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

/// When the tests that must not see the boards' boot events start their calls.
const BOOTED_US: u64 = 1_000;

/// Runs `call` once the boot events of the world's boards (sent again at the start of every
/// `common::World::sim`) have been routed.
async fn after_boot<T>(w: &TwoBoards, call: impl std::future::Future<Output = T>) -> T {
    w.clock
        .sleep_until(Instant(w.clock.now_us() + BOOTED_US))
        .await;
    call.await
}

/// The transactions to `node` (retries included).
fn to(bus: &LoopBus, node: u8) -> Vec<(u64, Seen)> {
    bus.seen()
        .into_iter()
        .filter(|(_, s)| matches!(s, Seen::Write(n, _) | Seen::WriteRead(n, _, _) if *n == node))
        .collect()
}

#[test]
fn outputs_are_one_write_and_inputs_one_write_read() {
    let w = world();
    w.db9.ports().analog.borrow_mut().insert(1, 0x0321);
    let (out, inp) = w.sim(async {
        let out =
            w.mb.call(addr(9), Op::DigitalWrite(a(1).pin(Pin::B), Level::High))
                .await;
        let inp = w.mb.call(addr(9), Op::AnalogRead(s(1))).await;
        (out, inp)
    });
    assert_eq!(out.unwrap().len(), 0);
    assert_eq!(inp.unwrap()[..], [0x21, 0x03]);
    assert_eq!(
        to(&w.bus, 9),
        [
            (0, Seen::Write(9, vec![0x12, 0x09, 0x01, 0x00])),
            (
                TRANSFER_US,
                Seen::WriteRead(9, vec![0x30, 0x09, 0x80, 0x01], 5)
            ),
        ]
    );
    assert!(w
        .db9
        .ports()
        .log
        .borrow()
        .contains(&PortOp::DigitalWrite(a(1).pin(Pin::B), Level::High)));
}

#[test]
fn many_concurrent_callers_each_get_their_own_reply() {
    let w = world();
    for p in 1..=3u8 {
        w.db9
            .ports()
            .analog
            .borrow_mut()
            .insert(p, 900 + u16::from(p));
        w.db17
            .ports()
            .analog
            .borrow_mut()
            .insert(p, 1700 + u16::from(p));
    }
    for p in 1..=2u8 {
        w.mb.internal()
            .ports()
            .analog
            .borrow_mut()
            .insert(p, u16::from(p));
    }
    let link = w.mb.handle();
    let results = w.sim(join_array(core::array::from_fn::<_, 12, _>(
        |i| async move {
            let board = [9u8, 17, 0][i % 3];
            let port = (i / 3 % 2) as u8 + 1;
            let mut got = Vec::new();
            for _ in 0..5 {
                let v = link
                    .call(addr(board), Op::AnalogRead(s(port)))
                    .await
                    .unwrap();
                got.push(u16::from_le_bytes([v[0], v[1]]));
            }
            (board, port, got)
        },
    )));
    for (board, port, got) in results {
        let expect = match board {
            9 => 900,
            17 => 1700,
            _ => 0,
        } + u16::from(port);
        assert_eq!(got, vec![expect; 5], "board {board} port {port}");
    }
    let d = w.mb.diagnostics();
    assert_eq!((d.requests, d.completed), (60, 60));
    assert_eq!(
        (d.late_replies, d.duplicate_replies, d.unknown_replies),
        (0, 0, 0)
    );
    // sequence numbers are per board: 20 requests each to 9 and 17, numbered 0..20
    let mut seqs: Vec<u8> = to(&w.bus, 9)
        .iter()
        .map(|(_, s)| match s {
            Seen::WriteRead(_, b, _) => b[3],
            _ => panic!(),
        })
        .collect();
    seqs.sort();
    assert_eq!(seqs, (0..20).collect::<Vec<u8>>());
}

#[test]
fn sequence_numbers_wrap_without_reusing_one_still_pending() {
    let w = world();
    // a pulse-in on DB 9 that takes 2 s stays pending with seq 0
    w.db9
        .ports()
        .pulses
        .borrow_mut()
        .push_back((2_000_000, Ok(4_321)));
    let (pulse, pings) = w.sim(async {
        let pulse = w.mb.call(
            addr(9),
            Op::PulseIn {
                pin: s(1).pin(Pin::A),
                edge: Edge::Rising,
                timeout_ms: Some(3_000),
            },
        );
        let pings = async {
            let mut n = 0;
            for _ in 0..300 {
                w.mb.call(addr(9), Op::Ping).await.unwrap();
                n += 1;
            }
            n
        };
        join(pulse, pings).await
    });
    assert_eq!(pulse.unwrap()[..], 4_321u32.to_le_bytes());
    assert_eq!(pings, 300);
    let seqs: Vec<u8> = to(&w.bus, 9)
        .iter()
        .map(|(_, s)| match s {
            Seen::WriteRead(_, b, _) => b[3],
            _ => panic!(),
        })
        .collect();
    assert_eq!(seqs.len(), 301);
    assert_eq!(seqs[0], 0, "the pulse-in");
    // pings 1..=255, then 0 is skipped (still pending): 1, 2, ...
    assert_eq!(seqs[1..256], (1..=255).collect::<Vec<u8>>()[..]);
    assert_eq!(seqs[256..259], [1, 2, 3]);
    assert!(seqs[1..].iter().all(|&s| s != 0));
    let d = w.mb.diagnostics();
    assert_eq!(
        (d.completed, d.unknown_replies, d.late_replies),
        (301, 0, 0)
    );
}

#[test]
fn a_silent_board_times_out_and_the_dispatcher_goes_on() {
    let w = world();
    w.bus.attach(0x20, Node::Silent);
    let (r, t, after) = w.sim(async {
        let r =
            w.mb.call(addr(0x20), Op::DigitalRead(s(1).pin(Pin::A)))
                .await;
        let t = w.clock.now();
        let after = w.mb.call(addr(9), Op::Ping).await;
        (r, t, after)
    });
    assert_eq!(r, Err(LinkError::Timeout));
    assert_eq!(t, Instant(TRANSFER_US + BUS_TIMEOUT_US));
    assert!(after.is_ok());
    // the caller's own deadline ends it sooner when shorter than the port's timeout
    let (r, t) = w.sim(async {
        let start = w.clock.now();
        let r = w.mb.call_with_timeout(addr(0x20), Op::Ping, 5_000).await;
        (r, w.clock.now().since(start))
    });
    assert_eq!((r, t), (Err(LinkError::Timeout), 5_000));
    let d = w.mb.diagnostics();
    assert_eq!(d.timeouts, 2);
    assert_eq!(d.late_replies, 0, "a bus timeout is no reply");
}

#[test]
fn a_late_reply_is_dropped_counted_and_never_given_to_the_next_caller() {
    let w = world();
    let delays = Rc::new(RefCell::new(vec![150_000u64, 0]));
    let d2 = delays.clone();
    w.bus.attach(
        0x21,
        Node::Script(Box::new(move |req| {
            let delay = d2.borrow_mut().remove(0);
            (delay, vec![req[3], 0x00, 0x01, req[3] & 1])
        })),
    );
    let (first, second) = w.sim(async {
        let first =
            w.mb.call(addr(0x21), Op::DigitalRead(s(1).pin(Pin::A)))
                .await;
        let second =
            w.mb.call(addr(0x21), Op::DigitalRead(s(1).pin(Pin::A)))
                .await;
        (first, second)
    });
    assert_eq!(first, Err(LinkError::Timeout));
    assert_eq!(
        second.unwrap()[..],
        [0x01],
        "the second request's own reply (seq 1)"
    );
    let d = w.mb.diagnostics();
    assert_eq!((d.timeouts, d.late_replies, d.completed), (1, 1, 1));
}

#[test]
fn a_late_deferred_reply_is_dropped_and_counted() {
    let w = world();
    w.db9
        .ports()
        .pulses
        .borrow_mut()
        .push_back((500_000, Ok(77)));
    let r = w.sim(async {
        let op = Op::PulseIn {
            pin: s(2).pin(Pin::B),
            edge: Edge::Falling,
            timeout_ms: Some(50),
        };
        assert_eq!(w.mb.timeout_us(&op), 150_000);
        let r = w.mb.call(addr(9), op).await;
        // wait past the deferred reply
        w.clock.sleep_until(Instant(600_000)).await;
        r
    });
    assert_eq!(r, Err(LinkError::Timeout));
    let d = w.mb.diagnostics();
    assert_eq!((d.timeouts, d.late_replies), (1, 1));
}

#[test]
fn replies_with_the_wrong_sequence_number_are_bad_replies_and_counted() {
    let w = world();
    w.bus.attach(
        0x22,
        Node::Script(Box::new(|req| {
            (0, vec![req[3].wrapping_add(7), 0x00, 0x00])
        })),
    );
    w.bus.attach(
        0x23,
        Node::Script(Box::new(|_| (0, vec![0x00, 0x00, 0x1F]))),
    );
    let (a, b) = w.sim(async {
        (
            w.mb.call(addr(0x22), Op::Ping).await,
            w.mb.call(addr(0x23), Op::Ping).await,
        )
    });
    assert_eq!((a, b), (Err(LinkError::BadReply), Err(LinkError::BadReply)));
    let d = w.mb.diagnostics();
    assert_eq!((d.unknown_replies, d.bad_replies), (1, 2));
}

#[test]
fn an_absent_board_is_nacked_after_every_retry() {
    let w = world();
    let r = w.sim(w.mb.call(addr(0x30), Op::DigitalWrite(a(1).pin(Pin::A), Level::High)));
    assert_eq!(r, Err(LinkError::Nack));
    let tries = to(&w.bus, 0x30);
    assert_eq!(tries.len(), 5);
    // backoff between attempts: 100·2^n µs plus up to half again, after each 100 µs transfer
    for (n, pair) in tries.windows(2).enumerate() {
        let gap = pair[1].0 - pair[0].0 - TRANSFER_US;
        let base = 100u64 << n;
        assert!((base..base + base / 2).contains(&gap), "gap {n}: {gap}");
    }
    let d = w.mb.diagnostics();
    assert_eq!((d.nacked, d.retries, d.nacks), (5, 4, 1));
}

#[test]
fn an_absent_board_is_tried_once_per_call_until_it_answers_again() {
    // Its first call is NACKed at all five attempts; from then on it is silent and each call
    // is a single attempt, so it holds the bus queue 0.1 ms instead of 2.4 ms. Once it answers
    // (an acknowledged transaction), a call that fails again gets every attempt.
    let w = world();
    let ping = || w.mb.call(addr(0x30), Op::Ping);
    let first = w.sim(async { (ping().await, ping().await, ping().await) });
    assert_eq!(
        first,
        (
            Err(LinkError::Nack),
            Err(LinkError::Nack),
            Err(LinkError::Nack)
        )
    );
    assert_eq!(to(&w.bus, 0x30).len(), 5 + 1 + 1);
    w.bus.attach(
        0x30,
        Node::Script(Box::new(|req| (0, vec![req[3], 0x00, 0x00]))),
    );
    assert_eq!(w.sim(ping()), Ok(heapless::Vec::new()));
    assert_eq!(to(&w.bus, 0x30).len(), 8);
    w.bus.attach(0x30, Node::Absent);
    assert_eq!(w.sim(ping()), Err(LinkError::Nack));
    assert_eq!(to(&w.bus, 0x30).len(), 8 + 5);
    let d = w.mb.diagnostics();
    assert_eq!((d.nacked, d.nacks, d.completed), (5 + 1 + 1 + 5, 4, 1));
}

#[test]
fn arbitration_loss_is_retried_then_succeeds_or_ends_typed() {
    let w = world();
    // A scripted board (no boot events in flight) answering analog reads with 7.
    w.bus.attach(
        0x22,
        Node::Script(Box::new(|req| (0, vec![req[3], 0x00, 0x02, 7, 0]))),
    );
    w.bus.fault(
        0x22,
        Fault {
            error: BusError::ArbitrationLost,
            event: None,
        },
    );
    let r = w.sim(after_boot(&w, w.mb.call(addr(0x22), Op::AnalogRead(s(3)))));
    assert_eq!(r.unwrap()[..], [7, 0]);
    let d = w.mb.diagnostics();
    assert_eq!(
        (
            d.arbitration_lost,
            d.retries,
            d.yields,
            d.arbitration_failures
        ),
        (1, 1, 0, 0)
    );
    // No event came: the dispatcher listened its full arbitration wait (400 µs, more than the
    // 100..150 µs backoff) before the retry.
    let tries = to(&w.bus, 0x22);
    assert_eq!(tries.len(), 2);
    assert_eq!(
        tries[1].0 - tries[0].0,
        TRANSFER_US + u64::from(MbConfig::new(mb_address()).arbitration_wait_us)
    );
    assert_eq!(MbConfig::new(mb_address()).arbitration_wait_us, 400);
    for _ in 0..5 {
        w.bus.fault(
            0x22,
            Fault {
                error: BusError::ArbitrationLost,
                event: None,
            },
        );
    }
    let r = w.sim(after_boot(&w, w.mb.call(addr(0x22), Op::AnalogRead(s(3)))));
    assert_eq!(r, Err(LinkError::ArbitrationLost));
    let d = w.mb.diagnostics();
    assert_eq!((d.arbitration_lost, d.arbitration_failures), (6, 1));
    // 1 + 4 retries, waits of at least 400 µs and then the backoff's 800..1200 µs
    let tries = to(&w.bus, 0x22);
    let gaps: Vec<u64> = tries[2..]
        .windows(2)
        .map(|p| p[1].0 - p[0].0 - TRANSFER_US)
        .collect();
    assert_eq!(&gaps[..2], &[400, 400], "{gaps:?}");
    assert!((400..600).contains(&gaps[2]), "{gaps:?}");
    assert!((800..1200).contains(&gaps[3]), "{gaps:?}");
}

#[test]
fn a_lost_attempt_followed_by_the_winners_event_is_retried_at_once_and_not_counted() {
    let w = world();
    w.bus.attach(
        0x22,
        Node::Script(Box::new(|req| (0, vec![req[3], 0x00, 0x02, 7, 0]))),
    );
    let s1a = s(1).pin(Pin::A);
    let event = |src: u8, n: u8| vec![src, 0x01, s1a.to_byte(), n, 0x00, 0x01, n & 1];
    // Six losses in a row, each to an event written to us (more than the 5 attempts), then
    // a NACK from the board addressed while it sends us an event (a single-role board in its
    // controller window), then a NACK with an event from another board: that one counts.
    for n in 0..6 {
        w.bus.fault(
            0x22,
            Fault {
                error: BusError::ArbitrationLost,
                event: Some(event(0x30 + n, n)),
            },
        );
    }
    w.bus.fault(
        0x22,
        Fault {
            error: BusError::Nack,
            event: Some(event(0x22, 6)),
        },
    );
    w.bus.fault(
        0x22,
        Fault {
            error: BusError::Nack,
            event: Some(event(0x31, 7)),
        },
    );
    let r = w.sim(after_boot(&w, w.mb.call(addr(0x22), Op::AnalogRead(s(3)))));
    assert_eq!(r.unwrap()[..], [7, 0]);
    let tries = to(&w.bus, 0x22);
    let starts: Vec<u64> = tries.iter().map(|t| t.0).collect();
    // each forgiven retry starts right after the failed transfer (the event is routed at once)
    let at_once: Vec<u64> = (0..8).map(|i| BOOTED_US + i * TRANSFER_US).collect();
    assert_eq!(&starts[..8], &at_once[..], "{starts:?}");
    // the last NACK counted: the 100..150 µs backoff
    assert_eq!(starts.len(), 9);
    let gap = starts[8] - starts[7] - TRANSFER_US;
    assert!((100..150).contains(&gap), "{gap}");
    let d = w.mb.diagnostics();
    assert_eq!(
        (d.arbitration_lost, d.nacked, d.yields, d.retries, d.events),
        (6, 2, 7, 8, 8 + 3)
    );
    // (and the boot events of the internal board, DB 9 and DB 17, before the call)
    assert_eq!((d.completed, d.boots), (1, 3));
}

#[test]
fn an_event_arriving_while_dispatching_is_routed_and_nothing_is_lost() {
    let w = world();
    let s1a = s(1).pin(Pin::A);
    // DB 17 wins arbitration against our request to DB 9 and writes a pin-change event
    let event = vec![17, 0x01, s1a.to_byte(), 5, 0x00, 0x01, 0x01];
    w.bus.fault(
        9,
        Fault {
            error: BusError::ArbitrationLost,
            event: Some(event),
        },
    );
    let got_at = Cell::new(0u64);
    let (ev, r) = w.sim(async {
        let waiter = async {
            let ev = w.mb.wait_event(addr(17), s1a).await;
            got_at.set(w.clock.now_us());
            ev
        };
        join(
            waiter,
            after_boot(
                &w,
                w.mb.call(addr(9), Op::DigitalWrite(a(2).pin(Pin::A), Level::High)),
            ),
        )
        .await
    });
    let ev = ev.unwrap();
    assert_eq!(
        (ev.source, ev.kind, ev.pin, &ev.value[..]),
        (addr(17), EventKind::PinChange, s1a, &[1u8][..])
    );
    assert!(r.is_ok());
    let writes = to(&w.bus, 9);
    assert_eq!(writes.len(), 2);
    // the event is routed as soon as it arrives, and the request is retried right after it
    // (the bus is free again), without a backoff, and that attempt does not count
    assert_eq!(writes[1].0, writes[0].0 + TRANSFER_US);
    assert_eq!(got_at.get(), writes[1].0, "event routed before the retry");
    let d = w.mb.diagnostics();
    assert_eq!((d.arbitration_lost, d.yields, d.retries), (1, 1, 1));
}

#[test]
fn pin_events_are_enabled_on_a_real_board_and_queued_until_claimed() {
    let w = world();
    let s2b = s(2).pin(Pin::B);
    let cfg = EventConfig {
        rising: true,
        falling: true,
        ..EventConfig::OFF
    };
    let evs = w.sim(async {
        w.mb.call(addr(17), Op::EventEnable(s2b, cfg))
            .await
            .unwrap();
        // the board samples every 10 ms; two edges happen before anyone waits
        w.clock.sleep_until(Instant(15_000)).await;
        w.db17.ports().set_level(s2b, true);
        w.clock.sleep_until(Instant(25_000)).await;
        w.db17.ports().set_level(s2b, false);
        w.clock.sleep_until(Instant(50_000)).await;
        let a = w.mb.wait_event(addr(17), s2b).await.unwrap();
        let b = w.mb.wait_event(addr(17), s2b).await.unwrap();
        (a.value.to_vec(), b.value.to_vec())
    });
    // Level, then the rising and falling edges counted since the pin's previous event.
    assert_eq!(evs, (vec![1, 1, 0, 0, 0], vec![0, 0, 0, 1, 0]));
}

#[test]
fn pec_is_negotiated_per_board_and_reset_by_its_boot_event() {
    let w = world();
    w.db9.ports().analog.borrow_mut().insert(1, 0x0102);
    let r = w.sim(async {
        // the boards' boot events come first
        w.clock.sleep_until(Instant(1_000)).await;
        w.mb.call(addr(9), Op::SetPec(true)).await.unwrap();
        w.mb.call(addr(9), Op::AnalogRead(s(1))).await
    });
    assert_eq!(r.unwrap()[..], [0x02, 0x01]);
    assert!(w.mb.pec_enabled(addr(9)) && w.db9.pec_enabled());
    assert!(!w.mb.pec_enabled(addr(17)));
    let seen = to(&w.bus, 9);
    let frame = [0x30, 0x09, 0x80, 0x01];
    let mut with_pec = frame.to_vec();
    with_pec.push(pec::compute(0x12, &frame));
    assert_eq!(seen[1].1, Seen::WriteRead(9, with_pec, 6));
    // the board restarts: its boot event turns PEC off on the MB side
    let boot = common::boot_event(9, &w.db9.identity());
    w.bus.to_mb(boot);
    w.sim(w.clock.sleep_until(Instant(w.clock.now_us() + 1)));
    assert!(!w.mb.pec_enabled(addr(9)));
}

#[test]
fn a_stale_pec_setting_is_corrected_from_the_boards_replies() {
    let w = world();
    w.db9.ports().analog.borrow_mut().insert(1, 0x0102);
    let (first, second) = w.sim(async {
        w.clock.sleep_until(Instant(1_000)).await;
        w.mb.call(addr(9), Op::SetPec(true)).await.unwrap();
        // a boot event older than our set_pec arrives late: the MB turns PEC off, the board
        // still checks it
        let boot = common::boot_event(9, &w.db9.identity());
        w.bus.to_mb(boot);
        w.clock.sleep_until(Instant(2_000)).await;
        let first = w.mb.call(addr(9), Op::AnalogRead(s(1))).await;
        let second = w.mb.call(addr(9), Op::AnalogRead(s(1))).await;
        (first, second)
    });
    assert_eq!(first, Err(LinkError::Status(Status::PecMismatch)));
    assert_eq!(second.unwrap()[..], [0x02, 0x01]);
    // the other way round: the board restarted (PEC off) and its boot event was lost
    let (first, second) = w.sim(async {
        w.db9.handle_write(
            &[
                0x07,
                0x09,
                0x00,
                0x77,
                0x00,
                pec::compute(0x12, &[0x07, 0x09, 0x00, 0x77, 0x00]),
            ],
            false,
        );
        let first = w.mb.call(addr(9), Op::AnalogRead(s(1))).await;
        let second = w.mb.call(addr(9), Op::AnalogRead(s(1))).await;
        (first, second)
    });
    assert!(!w.db9.pec_enabled());
    assert_eq!(first, Err(LinkError::BadReply));
    assert_eq!(second.unwrap()[..], [0x02, 0x01]);
    assert_eq!(w.mb.diagnostics().pec_resyncs, 2);
}

#[test]
fn a_refused_request_ends_in_its_status_and_refused_outputs_are_counted() {
    let w = world();
    let (read, out) = w.sim(async {
        let read = w.mb.call(addr(9), Op::AnalogRead(s(9))).await;
        let out =
            w.mb.call(addr(9), Op::DigitalWrite(a(7).pin(Pin::A), Level::High))
                .await;
        w.clock.sleep_until(Instant(w.clock.now_us() + 1_000)).await;
        (read, out)
    });
    assert_eq!(read, Err(LinkError::Status(Status::PortOutOfRange)));
    // Issue 22 item 11: the motherboard knows the board's ports from its boot event, so an
    // output to a port it lacks fails at once, as the read does, never `Ok` followed by a
    // `rejected` event. Nothing of it goes on the bus.
    assert_eq!(out, Err(LinkError::Status(Status::PortOutOfRange)));
    assert!(!w
        .bus
        .seen()
        .iter()
        .any(|(_, s)| matches!(s, Seen::Write(9, b) if b[0] == 0x12)));
    assert_eq!(w.mb.diagnostics().rejected, 0);
}

/// A board whose ports the motherboard does not know yet (it sent no boot event): an output
/// to a port it lacks goes out (the board's refusal would come as a `rejected` event). Its
/// `identify` reply teaches the motherboard its ports: the same output then fails at once.
#[test]
fn an_identify_reply_teaches_the_motherboard_a_boards_ports() {
    let w = world();
    // board 0x11 answers identify (2 sensor and 2 actuator ports) and nothing else
    w.bus.attach(
        0x11,
        Node::Script(Box::new(|req: &[u8]| {
            let mut r = vec![req[3], 0x00, 0x0A];
            r.extend_from_slice(&[1, 0, 1, 0, 1, 2, 2, 0xFD, 0x01, 12]);
            (10, r)
        })),
    );
    let out = Op::DigitalWrite(a(3).pin(Pin::A), Level::High);
    let (before, id, after) = w.sim(async {
        let before = w.mb.call(addr(0x11), out).await;
        let id = w.mb.call(addr(0x11), Op::Identify).await.map(|_| ());
        let after = w.mb.call(addr(0x11), out).await;
        (before, id, after)
    });
    assert_eq!((before.map(|_| ()), id), (Ok(()), Ok(())));
    assert_eq!(after, Err(LinkError::Status(Status::PortOutOfRange)));
    let writes = w
        .bus
        .seen()
        .iter()
        .filter(|(_, s)| matches!(s, Seen::Write(0x11, _)))
        .count();
    assert_eq!(writes, 1);
}

#[test]
fn invalid_operations_are_refused_before_anything_is_sent() {
    let w = world();
    let r = w.sim(w.mb.call(addr(9), Op::PwmDuty(s(1).pin(Pin::A), 10)));
    assert!(matches!(r, Err(LinkError::Invalid(_))));
    let r = w.sim(w.mb.call(addr(common::MB), Op::Ping));
    assert_eq!(
        r,
        Err(LinkError::Invalid(x10_microcode::Error::BadAddress(
            common::MB
        )))
    );
    assert!(w.bus.seen().is_empty());
    assert_eq!(w.mb.diagnostics().requests, 0);
}

#[test]
fn the_internal_board_is_reached_without_the_bus() {
    let w = world();
    let ports = w.mb.internal().ports();
    ports.set_level(s(2).pin(Pin::A), true);
    ports.pulses.borrow_mut().push_back((3_000, Ok(1_500)));
    let (read, write, pulse, rejected) = w.sim(async {
        let read =
            w.mb.call(Address::INTERNAL, Op::DigitalRead(s(2).pin(Pin::A)))
                .await;
        let write =
            w.mb.call(Address::INTERNAL, Op::PwmDuty(a(1).pin(Pin::B), 128))
                .await;
        let pulse =
            w.mb.call(
                Address::INTERNAL,
                Op::PulseIn {
                    pin: s(1).pin(Pin::B),
                    edge: Edge::Rising,
                    timeout_ms: None,
                },
            )
            .await;
        let rejected =
            w.mb.call(
                Address::INTERNAL,
                Op::DigitalWrite(a(3).pin(Pin::A), Level::Low),
            )
            .await;
        w.clock.sleep_until(Instant(w.clock.now_us() + 10)).await;
        (read, write, pulse, rejected)
    });
    assert_eq!(read.unwrap()[..], [1]);
    assert!(write.is_ok());
    assert_eq!(pulse.unwrap()[..], 1_500u32.to_le_bytes());
    // An output to a port the internal board does not have: read back (it costs no bus),
    // so the refusal is the call's result, not a later `rejected` event.
    assert_eq!(
        rejected,
        Err(LinkError::Status(x10_microcode::Status::PortOutOfRange))
    );
    assert!(ports
        .log
        .borrow()
        .contains(&PortOp::PwmDuty(a(1).pin(Pin::B), 128)));
    assert!(w
        .bus
        .seen()
        .iter()
        .all(|(_, s)| !matches!(s, Seen::Write(0, _) | Seen::WriteRead(0, _, _))));
    let d = w.mb.diagnostics();
    assert_eq!((d.rejected, d.completed, d.status_errors), (0, 3, 1));
    // the internal board's boot event was routed too (and DB 9's and 17's over the bus)
    assert_eq!(d.boots, 3);
}

/// Issue 22 item 15: a caller that finds every pending slot taken waits for one (until its
/// deadline) instead of failing at once with `Busy` (callers retrying on `Busy` spun every
/// few µs). With room in its deadline it gets the first slot freed; without, it ends in
/// `Busy` at its deadline, counted once.
#[test]
fn a_caller_waits_for_a_slot_until_its_deadline() {
    let w = world();
    w.bus.attach(
        0x24,
        Node::Script(Box::new(|req| (50_000, vec![req[3], 0x00, 0x00]))),
    );
    let results = w.sim(join_array(
        core::array::from_fn::<_, { MAX_PENDING + 1 }, _>(|_| async {
            let r =
                w.mb.call_with_timeout(addr(0x24), Op::Ping, 10_000_000)
                    .await;
            (r.map(|_| ()), w.clock.now_us())
        }),
    ));
    assert!(results.iter().all(|(r, _)| r.is_ok()), "{results:?}");
    // The 17th went out when the first ended: its reply came one transfer later.
    let mut ends: Vec<u64> = results.iter().map(|(_, t)| *t).collect();
    ends.sort_unstable();
    assert!(ends[MAX_PENDING] >= ends[0] + 50_000, "{ends:?}");
    assert_eq!(w.mb.diagnostics().busy, 0);
    // A deadline shorter than the wait: `Busy` at the deadline, counted once.
    let w = world();
    w.bus.attach(
        0x24,
        Node::Script(Box::new(|req| (50_000, vec![req[3], 0x00, 0x00]))),
    );
    let wr = &w;
    let results = w.sim(join_array(
        core::array::from_fn::<_, { MAX_PENDING + 1 }, _>(|i| async move {
            let timeout = if i == MAX_PENDING { 10_000 } else { 10_000_000 };
            let r = wr.mb.call_with_timeout(addr(0x24), Op::Ping, timeout).await;
            (r.map(|_| ()), wr.clock.now_us())
        }),
    ));
    let busy: Vec<_> = results
        .iter()
        .filter(|(r, _)| *r == Err(LinkError::Busy))
        .collect();
    assert_eq!(busy.len(), 1);
    assert_eq!(busy[0].1, 10_000);
    assert_eq!(w.mb.diagnostics().busy, 1);
}

#[test]
fn a_dropped_caller_frees_its_slot_and_its_job_is_not_sent() {
    let w = world();
    w.bus.attach(
        0x25,
        Node::Script(Box::new(|req| (1_000, vec![req[3], 0x00, 0x00]))),
    );
    let r = w.sim(async {
        // the first call occupies the dispatcher for 1.1 ms; the second is dropped while queued
        let first = w.mb.call(addr(0x25), Op::Ping);
        let second = async {
            match select(
                w.mb.call(addr(0x25), Op::Ping),
                w.clock.sleep_until(Instant(500)),
            )
            .await
            {
                Either::First(_) => panic!("should still be queued"),
                Either::Second(()) => {}
            }
        };
        let (r, ()) = join(first, second).await;
        w.clock.sleep_until(Instant(10_000)).await;
        r
    });
    assert!(r.is_ok());
    let d = w.mb.diagnostics();
    // the dropped request left the queue at once: the dispatcher never saw it
    assert_eq!((d.cancelled, d.abandoned), (1, 0));
    assert_eq!(to(&w.bus, 0x25).len(), 1);
}

#[test]
fn every_pending_slot_fits_in_the_queue_and_requests_go_out_oldest_first() {
    let w = world();
    // A slow board: each ping takes 100 µs on the bus plus 1 ms before it answers.
    w.bus.attach(
        0x25,
        Node::Script(Box::new(|req| (1_000, vec![req[3], 0x00, 0x00]))),
    );
    let ends: RefCell<Vec<(usize, u64)>> = RefCell::new(Vec::new());
    let results = w.sim(after_boot(
        &w,
        join_array(core::array::from_fn::<_, MAX_PENDING, _>(|i| {
            let (mb, clock, ends) = (&w.mb, &w.clock, &ends);
            async move {
                let r = mb.call(addr(0x25), Op::Ping).await;
                ends.borrow_mut().push((i, clock.now_us()));
                r
            }
        })),
    ));
    assert!(results.iter().all(Result::is_ok), "{results:?}");
    // All 16 were queued at once (none waited for room): the transactions follow each
    // other back to back, in the order of the calls (sequence numbers 0..15), and each
    // caller is answered when its own transaction ends.
    let tries = to(&w.bus, 0x25);
    let seqs: Vec<u8> = tries
        .iter()
        .map(|(_, s)| match s {
            Seen::WriteRead(_, b, _) => b[3],
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(seqs, (0..MAX_PENDING as u8).collect::<Vec<_>>());
    let starts: Vec<u64> = tries.iter().map(|t| t.0).collect();
    let expected: Vec<u64> = (0..MAX_PENDING as u64)
        .map(|i| BOOTED_US + i * (TRANSFER_US + 1_000))
        .collect();
    assert_eq!(starts, expected);
    let ends = ends.take();
    assert_eq!(
        ends,
        (0..MAX_PENDING)
            .map(|i| (i, BOOTED_US + (i as u64 + 1) * (TRANSFER_US + 1_000)))
            .collect::<Vec<_>>()
    );
    let d = w.mb.diagnostics();
    assert_eq!(
        (d.completed, d.busy, d.timeouts, d.abandoned),
        (16, 0, 0, 0)
    );
}

#[test]
fn requests_that_time_out_while_queued_leave_the_queue_and_free_their_slots() {
    let w = world();
    // The dispatcher is stuck 25 ms on a board that stretches the clock; meanwhile 15
    // callers with a 2 ms timeout give up while queued, and 15 more take their slots.
    w.bus.attach(0x26, Node::Silent);
    let (stuck, (first, second)) = w.sim(after_boot(&w, async {
        let queued = || {
            join_array(core::array::from_fn::<_, 15, _>(|_| {
                w.mb.call_with_timeout(addr(9), Op::Ping, 2_000)
            }))
        };
        let later = async { (queued().await, queued().await) };
        join(w.mb.call(addr(0x26), Op::Ping), later).await
    }));
    assert_eq!(stuck, Err(LinkError::Timeout));
    assert!(first.iter().all(|r| *r == Err(LinkError::Timeout)));
    assert!(second.iter().all(|r| *r == Err(LinkError::Timeout)));
    let d = w.mb.diagnostics();
    // Every slot came free when its caller gave up (no `Busy`), no job of a caller that gave
    // up reached the bus or the dispatcher, and nothing was sent to DB 9.
    assert_eq!((d.busy, d.abandoned, d.timeouts), (0, 0, 31));
    assert_eq!(to(&w.bus, 9).len(), 0);
    assert_eq!(to(&w.bus, 0x26).len(), 1);
}

#[test]
fn bad_event_frames_and_reads_of_the_mb_are_counted() {
    let w = world();
    w.bus.to_mb(vec![0x09, 0x01]); // truncated
    w.bus.to_mb(vec![0x00, 0x01, 0x80, 0x00, 0x00, 0x01, 0x01]); // claims to be the internal board
    let mut ev = vec![0x09, 0x06, 0x00, 0x03, 0x00, 0x02, 0x05, 0x00]; // overflow, with PEC
    ev.push(pec::compute(MB_ADDR_BYTE, &ev));
    w.bus.to_mb(ev.clone());
    ev[8] ^= 0xFF; // wrong PEC
    w.bus.to_mb(ev);
    w.sim(w.clock.sleep_until(Instant(1)));
    let d = w.mb.diagnostics();
    assert_eq!((d.bad_events, d.overflows), (3, 1));
}

const MB_ADDR_BYTE: u8 = common::MB << 1;

#[test]
fn the_robot_runner_steps_at_its_period_and_goes_on_after_errors() {
    // A robot task in the loop()-style: a ping first (no board 0x31: NACKed), then every
    // 10 ms a write and every third step a read of a port that does not exist. Errors are
    // values the task handles; it goes on.
    let w = world();
    let x10 = w.mb.handle();
    let steps = Cell::new(0u32);
    let errors = RefCell::new(Vec::new());
    w.sim(async {
        let robot = async {
            if let Err(e) = x10.call(addr(0x31), Op::Ping).await {
                errors.borrow_mut().push((w.clock.now_us(), "setup", e));
            }
            let mut ticker = embassy_time::Ticker::every(embassy_time::Duration::from_millis(10));
            loop {
                let n = steps.get();
                steps.set(n + 1);
                let level = if n.is_multiple_of(2) {
                    Level::High
                } else {
                    Level::Low
                };
                let mut r = x10
                    .call(Address::INTERNAL, Op::DigitalWrite(a(1).pin(Pin::A), level))
                    .await;
                if r.is_ok() && n % 3 == 2 {
                    r = x10.call(Address::INTERNAL, Op::AnalogRead(s(5))).await;
                }
                if let Err(e) = r {
                    errors.borrow_mut().push((w.clock.now_us(), "step", e));
                }
                ticker.next().await;
            }
        };
        let _ = select(robot, w.clock.sleep_until(Instant(100_000))).await;
    });
    // the ping NACKed (no board 0x31) after ~1.6 ms of retries, then steps every 10 ms
    let errors = errors.into_inner();
    assert_eq!(errors[0].1, "setup");
    assert_eq!(errors[0].2, LinkError::Nack);
    assert_eq!(steps.get(), 10);
    let step_errors: Vec<_> = errors[1..].iter().map(|e| (e.1, e.2)).collect();
    assert_eq!(
        step_errors,
        vec![("step", LinkError::Status(Status::PortOutOfRange)); 3]
    );
    let writes =
        w.mb.internal()
            .ports()
            .log
            .borrow()
            .iter()
            .filter(|o| matches!(o, PortOp::DigitalWrite(p, _) if *p == a(1).pin(Pin::A)))
            .count();
    assert_eq!(writes, 10 + 1, "10 steps, plus the safe state at boot");
}

#[test]
fn the_same_scenario_gives_the_same_bus_log_byte_for_byte() {
    let scenario = || {
        let w = world();
        w.bus.fault(
            9,
            Fault {
                error: BusError::ArbitrationLost,
                event: None,
            },
        );
        w.bus.fault(
            17,
            Fault {
                error: BusError::Nack,
                event: None,
            },
        );
        let link = w.mb.handle();
        let _ = w.sim(join_array(core::array::from_fn::<_, 6, _>(
            |i| async move {
                let board = [9u8, 17, 0x30][i % 3];
                for _ in 0..3 {
                    let _ = link.call(addr(board), Op::AnalogRead(s(1))).await;
                }
            },
        )));
        (w.bus.seen(), w.mb.diagnostics())
    };
    let (a, da) = scenario();
    let (b, db) = scenario();
    assert!(a.len() > 18);
    assert_eq!(a, b);
    assert_eq!(da, db);
}

/// Issue 22 item 14: a `scan` reply that reports another number of sensor ports than the
/// board has (as its identify reply said) is a bad reply, not a value.
#[test]
fn a_scan_that_disagrees_with_the_boards_port_count_is_a_bad_reply() {
    let w = world();
    // board 0x11: 2 sensor ports; its scan claims 3
    w.bus.attach(
        0x11,
        Node::Script(Box::new(|req: &[u8]| match req[0] {
            0x01 => {
                let mut r = vec![req[3], 0x00, 0x0A];
                r.extend_from_slice(&[1, 0, 1, 0, 1, 2, 2, 0xFD, 0x01, 12]);
                (10, r)
            }
            _ => (10, vec![req[3], 0x00, 0x09, 3, 0, 0, 1, 0, 2, 0, 3, 0]),
        })),
    );
    let (unknown, id, known) = w.sim(async {
        let unknown = w.mb.call(addr(0x11), Op::Scan).await.map(|p| p.len());
        let id = w.mb.call(addr(0x11), Op::Identify).await.map(|_| ());
        let known = w.mb.call(addr(0x11), Op::Scan).await.map(|p| p.len());
        (unknown, id, known)
    });
    // Before the board's ports are known the reply is taken as it is.
    assert_eq!((unknown, id), (Ok(9), Ok(())));
    assert_eq!(known, Err(LinkError::BadReply));
}
