//! Bus tests against small fake nodes.

use std::cell::RefCell;

use x10_hal::bus::{BusError, Incoming, MultiMaster};

use super::*;
use crate::exec::Executor;
use crate::timing::Speed;

const T100: Timing = Speed::Standard.timing();

struct Fixture<'a> {
    ex: Executor<'a>,
    bus: SimBus,
}

fn fixture<'a>(speed: Speed) -> Fixture<'a> {
    fixture_with(BusConfig::new(speed))
}

fn fixture_with<'a>(cfg: BusConfig) -> Fixture<'a> {
    let mut ex = Executor::new();
    let bus = SimBus::new(ex.clock(), cfg);
    ex.spawn("bus", bus.engine());
    Fixture { ex, bus }
}

/// A target that echoes: stores every write, answers reads with `reply`.
async fn echo_target(
    mut port: SimPort,
    log: &RefCell<Vec<(u64, Incoming, Vec<u8>)>>,
    reply: Vec<u8>,
) {
    let clock = port.bus().clock().clone();
    let mut buf = [0u8; 8];
    loop {
        match port.listen(&mut buf).await {
            Ok(inc) => {
                let n = match inc {
                    Incoming::Write(n) | Incoming::WriteRead(n) => n,
                    Incoming::Read => 0,
                };
                log.borrow_mut()
                    .push((clock.now_ns(), inc, buf.get(..n).unwrap_or(&[]).to_vec()));
                if !matches!(inc, Incoming::Write(_)) {
                    port.respond(&reply).await.unwrap();
                }
            }
            Err(e) => log
                .borrow_mut()
                .push((clock.now_ns(), Incoming::Read, vec![e as u8 + 0xE0])),
        }
    }
}

#[test]
fn write_takes_wire_time_and_arrives() {
    let log = RefCell::new(Vec::new());
    let done = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let mb = f.bus.add_node(NodeConfig::new("mb", Some(0x08)));
    let db = f.bus.add_node(NodeConfig::new("db09", Some(0x09)));
    f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x09, &[0x12, 0x09, 0x01, 0x02]).await;
        d.borrow_mut().push((clock.now_ns(), r));
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    let end = T100.write_ns(4);
    assert_eq!(*done.borrow(), vec![(end, Ok(()))]);
    assert_eq!(
        *log.borrow(),
        vec![(end, Incoming::Write(4), vec![0x12, 0x09, 0x01, 0x02])]
    );
    let recs = f.bus.records();
    assert_eq!(recs.len(), 1);
    let r = &recs[0];
    assert_eq!(
        (r.start_ns, r.end_ns, r.addr, r.master, r.target),
        (0, end, 0x09, mb, Some(db))
    );
    assert_eq!(r.outcome, Outcome::Ok);
    assert_eq!(r.stretch_ns, 0);
    // START, 5 bytes of 9 bits, STOP
    assert_eq!(r.wire.len(), 1 + 45 + 1);
}

#[test]
fn absent_address_is_nacked_after_the_address_byte() {
    let done = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Fast);
    let mb = f.bus.add_node(NodeConfig::new("mb", Some(0x08)));
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x33, &[1, 2, 3]).await;
        d.borrow_mut().push((clock.now_ns(), r));
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    let t = Speed::Fast.timing();
    assert_eq!(
        *done.borrow(),
        vec![(
            t.start_ns() + t.byte_ns() + t.stop_ns(),
            Err(BusError::Nack)
        )]
    );
    assert_eq!(f.bus.records()[0].outcome, Outcome::Nack { byte: 0 });
    assert_eq!(f.bus.stats().nacks, 1);
}

#[test]
fn write_read_returns_the_response_and_pads_with_ff() {
    let log = RefCell::new(Vec::new());
    let done = RefCell::new(Vec::new());
    let mut f = fixture(Speed::FastPlus);
    let mb = f.bus.add_node(NodeConfig::new("mb", Some(0x08)));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    f.ex.spawn(
        "db",
        echo_target(f.bus.port(db), &log, vec![0x02, 0x00, 0x01]),
    );
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        let mut read = [0u8; 5];
        let r = p
            .write_read(0x09, &[0x10, 0x09, 0x80, 0x02], &mut read)
            .await;
        d.borrow_mut().push((clock.now_ns(), r, read));
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    let t = Speed::FastPlus.timing();
    let end = t.write_read_ns(4, 5);
    assert_eq!(
        *done.borrow(),
        vec![(end, Ok(()), [0x02, 0x00, 0x01, 0xFF, 0xFF])]
    );
    // The target learns of the read at the end of address+R.
    let at = t.start_ns() + 5 * t.byte_ns() + t.repeated_start_ns() + t.byte_ns();
    assert_eq!(
        *log.borrow(),
        vec![(at, Incoming::WriteRead(4), vec![0x10, 0x09, 0x80, 0x02])]
    );
    let r = &f.bus.records()[0];
    assert!(r.is_read);
    assert_eq!(r.read, vec![0x02, 0x00, 0x01, 0xFF, 0xFF]);
}

#[test]
fn simultaneous_starts_arbitrate_bit_by_bit_lower_address_wins() {
    let log = RefCell::new(Vec::new());
    let done = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let a = f.bus.add_node(NodeConfig::new("a", Some(0x08)));
    let b = f.bus.add_node(NodeConfig::new("b", Some(0x0A)));
    let t1 = f.bus.add_node(NodeConfig::new("t10", Some(0x10)));
    let t2 = f.bus.add_node(NodeConfig::new("t20", Some(0x20)));
    f.ex.spawn("t10", echo_target(f.bus.port(t1), &log, vec![]));
    f.ex.spawn("t20", echo_target(f.bus.port(t2), &log, vec![]));
    for (node, addr) in [(a, 0x20u8), (b, 0x10u8)] {
        let mut p = f.bus.port(node);
        let clock = f.ex.clock();
        let d = &done;
        f.ex.spawn("m", async move {
            let r = p.write(addr, &[0xAA]).await;
            d.borrow_mut().push((node, clock.now_ns(), r));
            if r.is_err() {
                let r = p.write(addr, &[0xAA]).await;
                d.borrow_mut().push((node, clock.now_ns(), r));
            }
        });
    }
    f.ex.run_until_ns(10_000_000).unwrap();
    // 0x20<<1 = 0100_0000, 0x10<<1 = 0010_0000: they differ at bit 1, where a sends 1.
    let lost = T100.start_ns() + 2 * T100.bit_ns;
    let first_end = T100.write_ns(1);
    let second_end = first_end + T100.buf_ns + T100.write_ns(1);
    assert_eq!(
        *done.borrow(),
        vec![
            (a, lost, Err(BusError::ArbitrationLost)),
            (b, first_end, Ok(())),
            (a, second_end, Ok(())),
        ]
    );
    let recs = f.bus.records();
    assert_eq!(recs[0].master, b);
    assert_eq!(
        recs[0].losers,
        vec![Loser {
            node: a,
            addr: 0x20,
            write: vec![0xAA],
            bit: 1
        }]
    );
    assert_eq!(recs[1].start_ns, first_end + T100.buf_ns);
    assert_eq!(f.bus.stats().arbitration_lost, 1);
}

#[test]
fn same_address_arbitrates_in_the_data_bytes() {
    let log = RefCell::new(Vec::new());
    let done = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let a = f.bus.add_node(NodeConfig::new("a", None));
    let b = f.bus.add_node(NodeConfig::new("b", None));
    let t = f.bus.add_node(NodeConfig::new("t", Some(0x09)));
    f.ex.spawn("t", echo_target(f.bus.port(t), &log, vec![]));
    for (node, data) in [(a, [0x12u8, 0x09]), (b, [0x12u8, 0x01])] {
        let mut p = f.bus.port(node);
        let clock = f.ex.clock();
        let d = &done;
        f.ex.spawn("m", async move {
            let r = p.write(0x09, &data).await;
            d.borrow_mut().push((node, clock.now_ns(), r));
        });
    }
    f.ex.run_until_ns(10_000_000).unwrap();
    // 0x09 = 0000_1001 vs 0x01 = 0000_0001: differ at bit 4 of the second data byte.
    let lost_bit = 8 + 8 + 4;
    let lost_at = T100.start_ns() + (2 * 9 + 4 + 1) * T100.bit_ns;
    assert_eq!(
        *done.borrow(),
        vec![
            (a, lost_at, Err(BusError::ArbitrationLost)),
            (b, T100.write_ns(2), Ok(()))
        ]
    );
    assert_eq!(f.bus.records()[0].losers[0].bit, lost_bit);
    assert_eq!(log.borrow()[0].2, vec![0x12, 0x01]);
}

#[test]
fn single_role_node_is_deaf_in_its_controller_window_dual_role_is_not() {
    for (role, expect) in [
        (Role::SingleRole { switch_ns: 50_000 }, Err(BusError::Nack)),
        (Role::DualRole, Ok(())),
    ] {
        let log = RefCell::new(Vec::new());
        let done = RefCell::new(Vec::new());
        let mut f = fixture(Speed::Fast);
        let mb = f
            .bus
            .add_node(NodeConfig::new("mb", Some(0x08)).with_role(role));
        let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
        // The MB listens between its own writes to an absent board.
        let mut p = f.bus.port(mb);
        let l = &log;
        f.ex.spawn("mb", async move {
            let mut buf = [0u8; 8];
            p.write(0x40, &[1]).await.ok();
            let r = p.listen(&mut buf).await;
            l.borrow_mut().push(r);
        });
        let mut q = f.bus.port(db);
        let clock = f.ex.clock();
        let d = &done;
        f.ex.spawn("db", async move {
            // Starts while the MB's write is on the wire: waits for the bus, then writes to
            // the MB right after t_BUF, inside the MB's role-switch time.
            clock.sleep_ns(1_000).await;
            let r = q.write(0x08, &[7, 7]).await;
            d.borrow_mut().push(r);
        });
        f.ex.run_until_ns(10_000_000).unwrap();
        assert_eq!(*done.borrow(), vec![expect], "{role:?}");
        if expect.is_ok() {
            assert_eq!(*log.borrow(), vec![Ok(Incoming::Write(2))]);
        } else {
            assert!(log.borrow().is_empty());
        }
    }
}

#[test]
fn target_without_listener_stretches_until_it_listens() {
    let done = RefCell::new(Vec::new());
    let got = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    let mut q = f.bus.port(db);
    let clock = f.ex.clock();
    let g = &got;
    f.ex.spawn("db", async move {
        clock.sleep_ns(300_000).await;
        let mut buf = [0u8; 4];
        let r = q.listen(&mut buf).await;
        g.borrow_mut().push((clock.now_ns(), r, buf));
    });
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x09, &[5, 6]).await;
        d.borrow_mut().push((clock.now_ns(), r));
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    let ack_end = T100.start_ns() + T100.byte_ns();
    let stretch = 300_000 - ack_end;
    let end = T100.write_ns(2) + stretch;
    assert_eq!(*done.borrow(), vec![(end, Ok(()))]);
    assert_eq!(
        *got.borrow(),
        vec![(end, Ok(Incoming::Write(2)), [5, 6, 0, 0])]
    );
    assert_eq!(f.bus.records()[0].stretch_ns, stretch);
}

#[test]
fn stretch_timeouts_for_no_listener_and_no_response() {
    let done = RefCell::new(Vec::new());
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.stretch_timeout_ns = 1_000_000;
    let mut f = fixture_with(cfg);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let deaf = f.bus.add_node(NodeConfig::new("never-listens", Some(0x09)));
    let mute = f
        .bus
        .add_node(NodeConfig::new("never-responds", Some(0x0A)));
    let _ = deaf;
    let mut q = f.bus.port(mute);
    f.ex.spawn("mute", async move {
        let mut buf = [0u8; 8];
        loop {
            let _ = q.listen(&mut buf).await;
        }
    });
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x09, &[1]).await;
        d.borrow_mut().push((clock.now_ns(), r));
        let mut rd = [0u8; 2];
        let r = p.write_read(0x0A, &[1], &mut rd).await;
        d.borrow_mut().push((clock.now_ns(), r));
    });
    f.ex.run_until_ns(100_000_000).unwrap();
    let t = Speed::Fast.timing();
    let first_end = t.start_ns() + t.byte_ns() + 1_000_000 + t.stop_ns();
    let second_start = first_end + t.buf_ns;
    let ar_end =
        second_start + t.start_ns() + 2 * t.byte_ns() + t.repeated_start_ns() + t.byte_ns();
    let second_end = ar_end + 1_000_000 + t.stop_ns();
    assert_eq!(
        *done.borrow(),
        vec![
            (first_end, Err(BusError::Timeout)),
            (second_end, Err(BusError::Timeout))
        ]
    );
    assert_eq!(f.bus.stats().timeouts, 2);
}

#[test]
fn late_respond_after_timeout_is_refused() {
    let results = RefCell::new(Vec::new());
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.stretch_timeout_ns = 100_000;
    let mut f = fixture_with(cfg);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    let mut q = f.bus.port(db);
    let clock = f.ex.clock();
    let r = &results;
    f.ex.spawn("db", async move {
        let mut buf = [0u8; 8];
        let inc = q.listen(&mut buf).await;
        clock.sleep_ns(500_000).await;
        let resp = q.respond(&[1, 2]).await;
        r.borrow_mut().push(format!("{inc:?} {resp:?}"));
    });
    let mut p = f.bus.port(mb);
    f.ex.spawn("mb", async move {
        let mut rd = [0u8; 2];
        let _ = p.write_read(0x09, &[1], &mut rd).await;
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    assert_eq!(
        *results.borrow(),
        vec!["Ok(WriteRead(1)) Err(Timeout)".to_string()]
    );
}

#[test]
fn write_larger_than_listen_buffer_is_nacked_and_reported_as_overrun() {
    let done = RefCell::new(Vec::new());
    let got = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    let mut q = f.bus.port(db);
    let g = &got;
    f.ex.spawn("db", async move {
        let mut buf = [0u8; 2];
        let r = q.listen(&mut buf).await;
        g.borrow_mut().push(r);
    });
    let mut p = f.bus.port(mb);
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x09, &[1, 2, 3, 4]).await;
        d.borrow_mut().push(r);
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    assert_eq!(*done.borrow(), vec![Err(BusError::Nack)]);
    assert_eq!(*got.borrow(), vec![Err(BusError::Overrun)]);
    assert_eq!(f.bus.records()[0].outcome, Outcome::Nack { byte: 3 });
}

#[test]
fn reset_node_nacks_while_down_then_answers() {
    let done = RefCell::new(Vec::new());
    let log = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Fast);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
    let bus = f.bus.clone();
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        bus.reset_node(db, 1_000_000);
        let r = p.write(0x09, &[1]).await;
        d.borrow_mut().push(r);
        clock.sleep_until_ns(1_000_000).await;
        let r = p.write(0x09, &[2]).await;
        d.borrow_mut().push(r);
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    assert_eq!(*done.borrow(), vec![Err(BusError::Nack), Ok(())]);
    assert_eq!(log.borrow().len(), 1);
    assert_eq!(f.bus.reset_generation(db), 1);
    assert_eq!(f.bus.stats().resets, 1);
}

#[test]
fn stuck_line_fails_the_transaction_and_blocks_until_released() {
    let done = RefCell::new(Vec::new());
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.faults.stuck_ppm = 1_000_000;
    cfg.faults.stuck_ns = 2_000_000;
    cfg.busy_timeout_ns = 1_000_000;
    let mut f = fixture_with(cfg);
    let a = f.bus.add_node(NodeConfig::new("a", None));
    let b = f.bus.add_node(NodeConfig::new("b", None));
    let mut p = f.bus.port(a);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("a", async move {
        let r = p.write(0x09, &[1]).await;
        d.borrow_mut().push(("a", clock.now_ns(), r));
    });
    let mut q = f.bus.port(b);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("b", async move {
        clock.sleep_ns(10_000).await;
        let r = q.write(0x09, &[1]).await;
        d.borrow_mut().push(("b", clock.now_ns(), r));
    });
    f.ex.run_until_ns(100_000_000).unwrap();
    let t = Speed::Fast.timing();
    assert_eq!(
        *done.borrow(),
        vec![
            ("a", t.start_ns(), Err(BusError::Bus)),
            ("b", 1_010_000, Err(BusError::Timeout))
        ]
    );
    assert_eq!(f.bus.records()[0].outcome, Outcome::Bus);
}

/// Runs 200 writes through a faulty bus and returns what the target saw and the counters.
fn faulty_run(seed: u64) -> (Vec<Vec<u8>>, BusStats, Vec<Result<(), BusError>>) {
    let log = RefCell::new(Vec::new());
    let results = RefCell::new(Vec::new());
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.seed = seed;
    cfg.faults.nack_ppm = 100_000;
    cfg.faults.corrupt_ppm = 100_000;
    let stats;
    {
        let mut f = fixture_with(cfg);
        let mb = f.bus.add_node(NodeConfig::new("mb", None));
        let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
        f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
        let mut p = f.bus.port(mb);
        let r = &results;
        f.ex.spawn("mb", async move {
            for i in 0..200u8 {
                let res = p.write(0x09, &[i, 0x55, 0xAA]).await;
                r.borrow_mut().push(res);
            }
        });
        f.ex.run_until_ns(1_000_000_000).unwrap();
        stats = f.bus.stats();
    }
    let seen = log.into_inner().into_iter().map(|(_, _, b)| b).collect();
    (seen, stats, results.into_inner())
}

#[test]
fn fault_injection_is_seeded() {
    let (seen_a, stats_a, res_a) = faulty_run(7);
    let (seen_b, stats_b, res_b) = faulty_run(7);
    let (seen_c, _, _) = faulty_run(8);
    assert_eq!(seen_a, seen_b);
    assert_eq!(stats_a, stats_b);
    assert_eq!(res_a, res_b);
    assert_ne!(seen_a, seen_c);
    // About 10 % of each, never all, never none.
    let nacks = res_a.iter().filter(|r| **r == Err(BusError::Nack)).count();
    assert!((5..50).contains(&nacks), "{nacks}");
    let corrupted = seen_a
        .iter()
        .enumerate()
        .filter(|(_, b)| b.len() == 3 && (b[1] != 0x55 || b[2] != 0xAA))
        .count();
    assert!(corrupted > 0, "no corruption seen");
    assert_eq!(stats_a.transactions, 200);
}

#[test]
fn injected_reset_takes_a_resettable_node_down() {
    let done = RefCell::new(Vec::new());
    let log = RefCell::new(Vec::new());
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.faults.reset_ppm = 1_000_000;
    cfg.faults.reset_ns = 1_000_000;
    let mut f = fixture_with(cfg);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f
        .bus
        .add_node(NodeConfig::new("db", Some(0x09)).resettable());
    f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
    let mut p = f.bus.port(mb);
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x09, &[1]).await;
        d.borrow_mut().push(r);
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    assert_eq!(*done.borrow(), vec![Err(BusError::Nack)]);
    assert_eq!(f.bus.reset_generation(db), 1);
    assert_eq!(f.bus.alive_from(db), 1_000_000);
    assert_eq!(f.bus.records()[0].faults, vec!["reset db".to_string()]);
    assert_eq!(f.bus.stats().injected, 1);
}

#[test]
fn addressed_announces_the_transfer_and_listen_then_receives_it_whole() {
    let done = RefCell::new(Vec::new());
    let got = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    let mut q = f.bus.port(db);
    let clock = f.ex.clock();
    let g = &got;
    f.ex.spawn("db", async move {
        // A wait on `addressed` raced against a timer and dropped loses nothing.
        let early = select(q.addressed(), clock.sleep_ns(10_000)).await;
        g.borrow_mut().push((clock.now_ns(), format!("{early:?}")));
        let r = q.addressed().await;
        g.borrow_mut().push((clock.now_ns(), format!("{r:?}")));
        // Announced, not consumed: a second call returns at once.
        let r = q.addressed().await;
        g.borrow_mut().push((clock.now_ns(), format!("{r:?}")));
        let mut buf = [0u8; 4];
        let r = q.listen(&mut buf).await;
        g.borrow_mut()
            .push((clock.now_ns(), format!("{r:?} {buf:?}")));
    });
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        clock.sleep_ns(50_000).await;
        let r = p.write(0x09, &[5, 6]).await;
        d.borrow_mut().push((clock.now_ns(), r));
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    let ack_end = 50_000 + T100.start_ns() + T100.byte_ns();
    let end = 50_000 + T100.write_ns(2);
    assert_eq!(*done.borrow(), vec![(end, Ok(()))]);
    assert_eq!(
        *got.borrow(),
        vec![
            (10_000, "Second(())".to_string()),
            (ack_end, "Ok(())".to_string()),
            (ack_end, "Ok(())".to_string()),
            (end, "Ok(Write(2)) [5, 6, 0, 0]".to_string()),
        ]
    );
    assert_eq!(f.bus.records()[0].stretch_ns, 0);
    assert_eq!(f.bus.stats().lost_transfers, 0);
}

#[test]
fn a_listen_dropped_mid_transfer_loses_it_counted_and_noted() {
    let done = RefCell::new(Vec::new());
    let got = RefCell::new(Vec::new());
    let mut f = fixture(Speed::Standard);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    let mut q = f.bus.port(db);
    let clock = f.ex.clock();
    let g = &got;
    f.ex.spawn("db", async move {
        let mut buf = [0u8; 8];
        // Cut 100 µs into the 4-byte write (which lasts ~460 µs at 100 kHz).
        q.addressed().await.unwrap();
        let cut = select(q.listen(&mut buf), clock.sleep_ns(100_000)).await;
        g.borrow_mut().push((clock.now_ns(), format!("{cut:?}")));
        // The next listen does not get the tail of the lost one, only the next transfer.
        let r = q.listen(&mut buf).await;
        g.borrow_mut()
            .push((clock.now_ns(), format!("{r:?} {:?}", &buf[..2])));
    });
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let d = &done;
    f.ex.spawn("mb", async move {
        let r = p.write(0x09, &[1, 2, 3, 4]).await;
        d.borrow_mut().push((clock.now_ns(), r));
        clock.sleep_ns(1_000_000).await;
        let r = p.write(0x09, &[7, 8]).await;
        d.borrow_mut().push((clock.now_ns(), r));
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    let ack_end = T100.start_ns() + T100.byte_ns();
    let first_end = T100.write_ns(4);
    let second_start = first_end + 1_000_000;
    let second_end = second_start + T100.write_ns(2);
    // The controller saw every byte ACKed; the target lost them.
    assert_eq!(
        *done.borrow(),
        vec![(first_end, Ok(())), (second_end, Ok(()))]
    );
    assert_eq!(
        *got.borrow(),
        vec![
            (ack_end + 100_000, "Second(())".to_string()),
            (second_end, "Ok(Write(2)) [7, 8]".to_string()),
        ]
    );
    assert_eq!(f.bus.stats().lost_transfers, 1);
    let recs = f.bus.records();
    assert_eq!(recs[0].faults, vec![LOST_NOTE.to_string()]);
    assert!(recs[1].faults.is_empty());
}

#[test]
fn a_burst_flips_its_first_and_last_bit_and_the_inner_bits_it_is_told() {
    let mut m = [0u8; 3];
    // From byte 0 bit 0 (the 8th bit on the wire), 4 bits: the 1st and 4th, and the 2nd
    // (inner bit 0 of 0b01).
    assert_eq!(burst_mask(&mut m, 0, 0, 4, Some(0b01)), 4);
    assert_eq!(m, [0x01, 0xA0, 0x00]);
    // One bit: today's single flip.
    let mut m = [0u8; 2];
    assert_eq!(burst_mask(&mut m, 1, 3, 0, None), 1);
    assert_eq!(m, [0x00, 0x08]);
    // Clipped at the end of the data; 64 bits at most.
    let mut m = [0u8; 1];
    assert_eq!(burst_mask(&mut m, 0, 1, 200, Some(u64::MAX)), 64);
    assert_eq!(m, [0x03]);
}

/// What an [`echo_target`] saw.
type TargetLog = RefCell<Vec<(u64, Incoming, Vec<u8>)>>;

/// The writes' times and results, the recovery's result, the counters.
type StuckRun = (
    Vec<(u64, Result<(), BusError>)>,
    Option<Result<Recovery, BusError>>,
    BusStats,
);

/// One write of `bytes` to 0x09 through a bus with `faults`; returns what each target at
/// `addrs` received, the write's result and its record.
fn one_write(
    faults: FaultConfig,
    seed: u64,
    addrs: &[u8],
    bytes: &[u8],
) -> (Vec<Vec<Vec<u8>>>, Result<(), BusError>, BusRecord) {
    let logs: Vec<TargetLog> = addrs.iter().map(|_| RefCell::new(Vec::new())).collect();
    let result = RefCell::new(None);
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.faults = faults;
    cfg.seed = seed;
    let records;
    {
        let mut f = fixture_with(cfg);
        let mb = f.bus.add_node(NodeConfig::new("mb", None));
        for (a, log) in addrs.iter().zip(&logs) {
            let n = f
                .bus
                .add_node(NodeConfig::new(format!("t{a:02x}"), Some(*a)));
            f.ex.spawn("t", echo_target(f.bus.port(n), log, vec![]));
        }
        let mut p = f.bus.port(mb);
        let (r, bytes) = (&result, bytes.to_vec());
        f.ex.spawn("mb", async move {
            *r.borrow_mut() = Some(p.write(0x09, &bytes).await);
        });
        f.ex.run_until_ns(10_000_000).unwrap();
        records = f.bus.records();
    }
    let seen = logs
        .into_iter()
        .map(|l| l.into_inner().into_iter().map(|(_, _, b)| b).collect())
        .collect();
    (seen, result.into_inner().unwrap(), records[0].clone())
}

#[test]
fn a_burst_of_two_flips_two_neighbouring_bits() {
    let faults = FaultConfig {
        corrupt_ppm: 1_000_000,
        burst_bits: 2,
        ..FaultConfig::NONE
    };
    let (seen, r, rec) = one_write(faults, 3, &[0x09], &[0, 0, 0, 0]);
    assert_eq!(r, Ok(()));
    assert_eq!(seen, vec![vec![vec![0x06, 0x00, 0x00, 0x00]]]);
    assert_eq!(
        rec.faults,
        vec!["corrupt burst of 2 bits from data byte 0 bit 2: 2 flipped"]
    );
    assert_eq!(rec.written, vec![0, 0, 0, 0]);
    assert_eq!(rec.received, vec![0x06, 0x00, 0x00, 0x00]);
}

#[test]
fn an_address_flip_sends_the_frame_to_another_board_or_nobody() {
    let faults = FaultConfig {
        address_ppm: 1_000_000,
        ..FaultConfig::NONE
    };
    // Every neighbour of 0x09 at one bit listens: exactly one gets the frame, 0x09 none.
    let neighbours: Vec<u8> = (0..7).map(|b| 0x09 ^ (1 << b)).collect();
    let mut addrs = vec![0x09];
    addrs.extend(&neighbours);
    let (seen, r, rec) = one_write(faults, 5, &addrs, &[0x12, 0x09, 0x01, 0x02]);
    assert_eq!(r, Ok(()));
    let got: Vec<usize> = seen.iter().map(Vec::len).collect();
    // Seed 5 flips bit 6: 0x49 gets it.
    assert_eq!(got, vec![0, 0, 0, 0, 0, 0, 0, 1]);
    assert_eq!(rec.faults, vec!["address 0x09 seen as 0x49"]);
    assert_eq!(rec.addr, 0x09);
    assert_eq!(rec.target, Some(8));
    // Nobody at the flipped address: NACK.
    let (seen, r, rec) = one_write(faults, 5, &[0x09], &[1]);
    assert_eq!((seen, r), (vec![vec![]], Err(BusError::Nack)));
    assert_eq!(rec.outcome, Outcome::Nack { byte: 0 });
}

#[test]
fn faults_can_be_limited_to_one_board_and_a_time_window() {
    let results = RefCell::new(Vec::new());
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.faults = FaultConfig {
        nack_ppm: 1_000_000,
        only_address: Some(0x0A),
        window_ns: Some((1_000_000, 2_000_000)),
        ..FaultConfig::NONE
    };
    let log = RefCell::new(Vec::new());
    let mut f = fixture_with(cfg);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    for a in [0x09, 0x0A] {
        let n = f
            .bus
            .add_node(NodeConfig::new(format!("t{a:02x}"), Some(a)));
        f.ex.spawn("t", echo_target(f.bus.port(n), &log, vec![]));
    }
    let mut p = f.bus.port(mb);
    let clock = f.ex.clock();
    let r = &results;
    f.ex.spawn("mb", async move {
        for at in [0, 1_000_000, 2_000_000] {
            clock.sleep_until_ns(at).await;
            for a in [0x09, 0x0A] {
                let res = p.write(a, &[1, 2]).await;
                r.borrow_mut().push((at / 1_000_000, a, res.is_ok()));
            }
        }
    });
    f.ex.run_until_ns(10_000_000).unwrap();
    assert_eq!(
        *results.borrow(),
        vec![
            (0, 0x09, true),
            (0, 0x0A, true),
            (1, 0x09, true),
            (1, 0x0A, false),
            (2, 0x09, true),
            (2, 0x0A, true),
        ]
    );
    assert_eq!(f.bus.stats().injected, 1);
}

/// A write at 0 that meets a stuck line (only the transaction starting at 0 is in the
/// fault window), then, after an optional 9-clock recovery, a second write.
fn stuck_then_write(faults: FaultConfig, recover: bool) -> StuckRun {
    let done = RefCell::new(Vec::new());
    let recovered = RefCell::new(None);
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.stretch_timeout_ns = 5_000_000;
    cfg.faults = FaultConfig {
        stuck_ns: 10_000_000,
        window_ns: Some((0, 1)),
        ..faults
    };
    let log = RefCell::new(Vec::new());
    let stats = {
        let mut f = fixture_with(cfg);
        let mb = f.bus.add_node(NodeConfig::new("mb", None));
        let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
        f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
        let mut p = f.bus.port(mb);
        let clock = f.ex.clock();
        let bus = f.bus.clone();
        let (d, rc) = (&done, &recovered);
        f.ex.spawn("mb", async move {
            let r = p.write(0x09, &[1]).await;
            d.borrow_mut().push((clock.now_ns(), r));
            if recover {
                *rc.borrow_mut() = Some(bus.recover().await);
            }
            let r = p.write(0x09, &[2]).await;
            d.borrow_mut().push((clock.now_ns(), r));
        });
        f.ex.run_until_ns(100_000_000).unwrap();
        f.bus.stats()
    };
    (done.into_inner(), recovered.into_inner(), stats)
}

#[test]
fn a_stuck_sda_is_freed_by_the_9_clock_recovery_or_by_itself() {
    let t = Speed::Fast.timing();
    let sda = FaultConfig {
        stuck_ppm: 1_000_000,
        ..FaultConfig::NONE
    };
    // Nobody recovers: the second write waits for the target to let go at 10 ms.
    let (done, _, stats) = stuck_then_write(sda, false);
    assert_eq!(
        done,
        vec![
            (t.start_ns(), Err(BusError::Bus)),
            (10_000_000 + t.buf_ns + t.write_ns(1), Ok(()))
        ]
    );
    assert_eq!(
        (stats.stuck, stats.recoveries, stats.stuck_ns),
        (1, 0, 10_000_000)
    );
    // Recovered: seed 0 lets go after 1 clock; STOP, t_BUF, and the write goes out.
    let (done, recovered, stats) = stuck_then_write(sda, true);
    assert_eq!(recovered, Some(Ok(Recovery::Released { clocks: 1 })));
    let freed = t.start_ns() + t.bit_ns + t.stop_ns();
    assert_eq!(
        done,
        vec![
            (t.start_ns(), Err(BusError::Bus)),
            (freed + t.buf_ns + t.write_ns(1), Ok(()))
        ]
    );
    assert_eq!((stats.stuck, stats.recoveries), (1, 1));
    assert_eq!(stats.stuck_ns, freed);
}

#[test]
fn a_stuck_scl_times_out_and_cannot_be_clocked_free() {
    let t = Speed::Fast.timing();
    let scl = FaultConfig {
        stuck_scl_ppm: 1_000_000,
        ..FaultConfig::NONE
    };
    let (done, recovered, stats) = stuck_then_write(scl, true);
    assert_eq!(recovered, Some(Err(BusError::Bus)));
    assert_eq!(
        done,
        vec![
            (5_000_000, Err(BusError::Timeout)),
            (10_000_000 + t.buf_ns + t.write_ns(1), Ok(()))
        ]
    );
    assert_eq!((stats.stuck, stats.recoveries, stats.timeouts), (1, 0, 1));
}

#[test]
fn nothing_stuck_nothing_to_recover() {
    let (done, recovered, stats) = stuck_then_write(FaultConfig::NONE, true);
    assert_eq!(recovered, Some(Ok(Recovery::NotStuck)));
    assert!(done.iter().all(|(_, r)| r.is_ok()));
    assert_eq!(stats.stuck, 0);
}

#[test]
fn a_soak_keeps_only_the_records_with_faults() {
    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.faults.nack_ppm = 200_000;
    cfg.seed = 9;
    cfg.keep_clean_records = false;
    let log = RefCell::new(Vec::new());
    let mut f = fixture_with(cfg);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
    let mut p = f.bus.port(mb);
    f.ex.spawn("mb", async move {
        for i in 0..50u8 {
            let _ = p.write(0x09, &[i]).await;
        }
    });
    f.ex.run_until_ns(100_000_000).unwrap();
    let recs = f.bus.records();
    let stats = f.bus.stats();
    assert_eq!(stats.transactions, 50);
    assert_eq!(recs.len() as u64, stats.injected);
    assert!(recs.iter().all(|r| !r.faults.is_empty()));
    assert_eq!((stats.injected, stats.nacks), (13, 13));
}

#[test]
fn the_new_faults_are_seeded_and_leave_the_old_ones_alone() {
    let run = |faults: FaultConfig, seed| {
        let (seen, r, rec) = one_write(faults, seed, &[0x09, 0x0b, 0x0d], &[7, 7, 7, 7, 7, 7]);
        (seen, r, rec.faults)
    };
    let all = FaultConfig {
        corrupt_ppm: 500_000,
        nack_ppm: 300_000,
        burst_bits: 5,
        address_ppm: 500_000,
        ..FaultConfig::NONE
    };
    for seed in 0..20 {
        assert_eq!(run(all, seed), run(all, seed));
    }
    // The NACKs and corruptions of the old options fall on the same transactions whether
    // or not the new ones are on (single-bit corruption vs a burst starting at that bit).
    let old = FaultConfig {
        burst_bits: 0,
        address_ppm: 0,
        ..all
    };
    for seed in 0..20 {
        let (_, r_old, f_old) = run(old, seed);
        let (_, r_new, f_new) = run(
            FaultConfig {
                address_ppm: 0,
                ..all
            },
            seed,
        );
        assert_eq!(r_old, r_new, "seed {seed}");
        let starts = |f: &[String]| f.iter().map(|s| s.contains("corrupt")).collect::<Vec<_>>();
        assert_eq!(starts(&f_old), starts(&f_new), "seed {seed}");
    }
}

fn ten_clean_seven_nacked(cfg: BusConfig) -> (Vec<BusRecord>, BusStats, DroppedFailures) {
    let log = RefCell::new(Vec::new());
    let mut f = fixture_with(cfg);
    let mb = f.bus.add_node(NodeConfig::new("mb", None));
    let db = f.bus.add_node(NodeConfig::new("db", Some(0x09)));
    f.ex.spawn("db", echo_target(f.bus.port(db), &log, vec![]));
    let mut p = f.bus.port(mb);
    f.ex.spawn("mb", async move {
        // 10 clean writes, then 7 to an address nobody has (NACKed, no fault noted).
        for i in 0..10u8 {
            let _ = p.write(0x09, &[i]).await;
        }
        for i in 0..7u8 {
            let _ = p.write(0x0a, &[i]).await;
        }
    });
    f.ex.run_until_ns(100_000_000).unwrap();
    let recs = f.bus.take_records();
    assert!(f.bus.records().is_empty());
    (recs, f.bus.stats(), f.bus.dropped_failures())
}

#[test]
fn a_bounded_bus_keeps_failures_up_to_its_cap_and_counts_the_rest() {
    let (all, all_stats, none) = ten_clean_seven_nacked(BusConfig::new(Speed::Fast));
    assert_eq!(all.len(), 17);
    assert_eq!(
        (all_stats.records_dropped, none),
        (0, DroppedFailures::default())
    );
    let busy: Nanos = all.iter().map(BusRecord::duration_ns).sum();
    assert_eq!(all_stats.busy_ns, busy);

    let mut cfg = BusConfig::new(Speed::Fast);
    cfg.keep_clean_records = false;
    cfg.keep_failed_records = true;
    cfg.record_cap = 3;
    let (recs, stats, dropped) = ten_clean_seven_nacked(cfg);
    assert_eq!((stats.transactions, stats.nacks), (17, 7));
    // The first 3 failures kept, the 4 others counted by address.
    assert_eq!(recs.as_slice(), &all[10..13]);
    assert_eq!(stats.records_dropped, 4);
    assert_eq!(dropped.answered, 0);
    assert_eq!(dropped.unanswered.get(0x0a), Some(&4));
    assert_eq!(dropped.unanswered.iter().sum::<u64>(), 4);
    // The busy time still covers every transaction.
    assert_eq!(stats.busy_ns, busy);
}
