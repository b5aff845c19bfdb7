//! Plug and play (issue 24) on a faulty bus: ten unaddressed boards powered together while
//! NACKs (5 % of transactions), bursts of flipped bits (10 %), flipped address bits (2 %) and board resets (0.5 %) hit the bus. Checked
//! against the simulator's ground truth: where each board really is (the address it last
//! started at), and which board's port a write really reached.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

use firmware_mb::KnownBoard;
use x10_microcode::{Address, Level, Op, Pin, Port, Uid};
use x10_sim::board::uid_of_name;
use x10_sim::bus::FaultConfig;
use x10_sim::sim::{task, Sim, SimConfig};

const MS: u64 = 1_000_000;

fn names() -> Vec<String> {
    (0..10).map(|i| format!("pnp{i}")).collect()
}

#[derive(Default)]
struct Seen {
    /// The motherboard's directory at the end.
    known: Vec<KnownBoard>,
    /// Writes made: (the board's ID, the address used, when it ended, Ok).
    writes: Vec<(Uid, Address, u64, bool)>,
}

fn run(seed: u64) {
    let config = SimConfig {
        seed,
        duration_ms: 6_000,
        stop_when_tasks_done: true,
        record_wire: false,
        trace_calls: false,
        faults: FaultConfig {
            nack_ppm: 50_000,
            corrupt_ppm: 100_000,
            burst_bits: 6,
            address_ppm: 20_000,
            reset_ppm: 5_000,
            reset_ns: 3_000_000,
            ..FaultConfig::NONE
        },
        ..SimConfig::default()
    };
    let mut sim = Sim::new(config);
    for name in names() {
        let ports = sim.ports(&name, 1, 1);
        sim = sim.with_unaddressed_board(&name, None, ports);
    }
    let seen = Rc::new(RefCell::new(Seen::default()));
    let s = seen.clone();
    let sim = sim.with_task(
        "robot",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                let pin = Port::actuator(1).unwrap().pin(Pin::A);
                ctx.clock.sleep_ns(3_000 * MS).await;
                // Each board the motherboard knows, its output high at the address it knows.
                for round in 0..3 {
                    let mut out = vec![KnownBoard::EMPTY; 32];
                    let n = x10.boards(&mut out);
                    for b in out[..n].iter().filter(|b| b.present) {
                        let r = x10
                            .call(b.address, Op::DigitalWrite(pin, Level::High))
                            .await;
                        s.borrow_mut().writes.push((
                            b.uid,
                            b.address,
                            ctx.clock.now_ns(),
                            r.is_ok(),
                        ));
                    }
                    if round < 2 {
                        ctx.clock.sleep_ns(500 * MS).await;
                    }
                }
                let mut out = vec![KnownBoard::EMPTY; 32];
                let n = x10.boards(&mut out);
                s.borrow_mut().known = out[..n].to_vec();
            })
        }),
    );
    let o = sim.run().unwrap();
    assert!(o.task_errors.is_empty(), "{:?}", o.task_errors);
    assert!(o.bus.injected > 20, "faults were injected: {:?}", o.bus);
    // Ground truth: where each board is now, by ID.
    let at: BTreeMap<Uid, (String, u8)> = o
        .addresses
        .iter()
        .map(|(name, starts)| {
            (
                uid_of_name(name),
                (name.clone(), starts.last().unwrap().1.get()),
            )
        })
        .collect();
    let mut distinct: Vec<u8> = at.values().map(|(_, a)| *a).collect();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), 10, "two boards share an address: {at:?}");
    assert!(
        at.values().all(|(_, a)| *a != Address::UNADDRESSED.get()),
        "a board was left unaddressed: {at:?}"
    );
    let seen = seen.borrow();
    // The motherboard's directory: every present board is where it says.
    for b in seen.known.iter().filter(|b| b.present) {
        let (name, a) = &at[&b.uid];
        assert_eq!(
            b.address.get(),
            *a,
            "{name}: the directory says {:#04x}",
            b.address.get()
        );
    }
    assert_eq!(seen.known.iter().filter(|b| b.present).count(), 10);
    // Every write told `Ok` reached that board's port, and no write reached another board.
    let pin = Port::actuator(1).unwrap().pin(Pin::A);
    let mut ok = 0;
    for (uid, address, t, good) in &seen.writes {
        let (name, _) = &at[uid];
        if *good {
            ok += 1;
            assert_eq!(
                o.log.level_at(name, pin, *t),
                Some(Level::High),
                "{name} at {address:?}"
            );
        }
    }
    for (name, _) in at.values() {
        let highs = o
            .log
            .of(name, pin)
            .iter()
            .filter(|c| c.change == x10_sim::ports::Change::Digital(Level::High))
            .count();
        let sent = seen.writes.iter().filter(|w| &at[&w.0].0 == name).count();
        assert!(
            highs <= sent,
            "{name}: {highs} changes to high, {sent} writes sent to it"
        );
    }
    println!(
        "seed {seed}: 10 boards addressed, {ok} writes Ok of {}, faults {}",
        seen.writes.len(),
        o.bus.injected
    );
    assert!(ok >= 20, "{ok}");
}

#[test]
fn ten_unaddressed_boards_on_a_faulty_bus_each_get_their_own_address() {
    let offset: u64 = std::env::var("X10_SEED_OFFSET")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    run(5 + offset);
}
