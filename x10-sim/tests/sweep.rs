//! Boards that act together (issue 27 items 3 and 4), on the simulated bus with the real
//! firmware: a whole bus read in one sweep, checked against the world, against one `scan` per
//! board; outputs on two boards applied by one general call; what happens to staged outputs
//! that get no `apply`.
//!
//! The figures (`cargo test -p x10-sim --test sweep -- --nocapture` prints them) are in
//! docs/performance.md.

use std::cell::RefCell;
use std::rc::Rc;

use x10_devices::LinkError;
use x10_microcode::{Address, Op, Pin, Port, ScanResult, Status};
use x10_sim::bus::{BusRecord, Outcome};
use x10_sim::exec::Nanos;
use x10_sim::ports::{Analog, Change, Digital, SensorScript};
use x10_sim::sim::{task, Sim, SimConfig, SimOutcome};
use x10_sim::timing::Speed;

/// The analog value of sensor port `port` (1-based) of the board at `addr` at `t_us`: a
/// different 12-bit value per board, port and millisecond.
fn analog(addr: u8, port: u8, t_us: u64) -> u16 {
    let ms = t_us / 1000;
    ((u64::from(addr) * 37 + u64::from(port) * 501 + ms * 13) % 4096) as u16
}

/// Pin A of each sensor port toggles every 3 ms from a time of its own; pin B is port-parity.
fn script(addr: u8, port: u8) -> SensorScript {
    let first = u64::from(addr % 3) + u64::from(port);
    SensorScript {
        a: Digital::Toggles {
            initial: false,
            toggles_ms: (0..100).map(|k| first + 3 * k).collect(),
        },
        b: Digital::Const(port % 2 == 1),
        analog: Analog::Func(Rc::new(move |t_us| analog(addr, port, t_us))),
    }
}

/// What the world says board `addr`'s 8 sensor ports read at `t_ns`.
fn truth(addr: u8, t_ns: Nanos) -> ScanResult {
    let mut r = ScanResult {
        ports: 8,
        ..ScanResult::default()
    };
    for port in 1..=8u8 {
        let s = script(addr, port);
        let i = usize::from(port - 1);
        r.analog[i] = s.analog.value_at(t_ns);
        r.digital |= u16::from(s.a.level_at(t_ns)) << (2 * i);
        r.digital |= u16::from(s.b.level_at(t_ns)) << (2 * i + 1);
    }
    r
}

fn config(duration_ms: u64) -> SimConfig {
    SimConfig {
        speed: Speed::FastPlus,
        duration_ms,
        trace_calls: false,
        stop_when_tasks_done: true,
        record_wire: false,
        ..SimConfig::default()
    }
}

/// Bus time between two instants: the sum of the transactions' durations, and their number.
fn bus_time(records: &[BusRecord], from: Nanos, to: Nanos) -> (Nanos, usize) {
    let rs: Vec<_> = records
        .iter()
        .filter(|r| r.start_ns >= from && r.end_ns <= to)
        .collect();
    (rs.iter().map(|r| r.end_ns - r.start_ns).sum(), rs.len())
}

type Spans = Rc<
    RefCell<
        Vec<(
            &'static str,
            Nanos,
            Nanos,
            Vec<(u8, Result<ScanResult, LinkError>)>,
        )>,
    >,
>;

/// `boards` boards of 8 sensor ports each (0x09 on), at 1 MHz with the safe defaults (PEC):
/// a warm-up `scan` of each board (which prepares it: PEC on, failsafe), then one `scan`
/// per board, then a sweep. Returns the outcome and the two
/// measured spans.
fn full_bus(boards: u8) -> (SimOutcome, Spans) {
    let spans: Spans = Rc::new(RefCell::new(Vec::new()));
    let out = spans.clone();
    let addrs: Vec<u8> = (0x09..0x09 + boards).collect();
    let mut sim = Sim::new(config(400));
    for &a in &addrs {
        let mut ports = sim.ports(&format!("db{a:02x}"), 8, 0).with_adc_bits(12);
        for port in 1..=8 {
            ports = ports.with_sensor(port, script(a, port));
        }
        sim = sim.with_board(Address::external(a).unwrap(), ports);
    }
    let list: Vec<Address> = addrs
        .iter()
        .map(|&a| Address::external(a).unwrap())
        .collect();
    let sim = sim.with_task(
        "sweep",
        task(move |ctx| {
            Box::pin(async move {
                ctx.clock.sleep_ns(60_000_000).await;
                let x10 = ctx.handle();
                let mut values = vec![Ok(ScanResult::default()); list.len()];
                // Warm-up: every board prepared (PEC on, failsafe) by its first request.
                for &db in &list {
                    x10.call(db, Op::Scan).await.expect("warm-up scan");
                }
                let t0 = ctx.clock.now_ns();
                let mut scans = Vec::new();
                for &db in &list {
                    let r = x10
                        .call(db, Op::Scan)
                        .await
                        .and_then(|p| ScanResult::parse(&p).map_err(|_| LinkError::BadReply));
                    scans.push((db.get(), r));
                }
                let t1 = ctx.clock.now_ns();
                out.borrow_mut().push(("scan", t0, t1, scans));
                let t0 = ctx.clock.now_ns();
                let summary = x10.sweep(&list, &mut values).await;
                let t1 = ctx.clock.now_ns();
                assert_eq!(summary.swept, list.len(), "{summary:?}");
                let swept = list.iter().map(|d| d.get()).zip(values).collect();
                out.borrow_mut().push(("sweep", t0, t1, swept));
            })
        }),
    );
    let outcome = sim.run().expect("sim runs");
    assert!(outcome.task_errors.is_empty(), "{:?}", outcome.task_errors);
    (outcome, spans)
}

#[test]
fn a_full_bus_is_read_in_one_sweep_within_22_ms_every_value_from_the_world() {
    let (outcome, spans) = full_bus(110);
    let spans = spans.borrow();
    assert_eq!(spans.len(), 2);
    let mut figures = Vec::new();
    for (what, t0, t1, values) in spans.iter() {
        let (busy, n) = bus_time(&outcome.records, *t0, *t1);
        figures.push((*what, busy, n, t1 - t0));
        assert_eq!(values.len(), 110);
        for (addr, r) in values {
            let got = r
                .as_ref()
                .unwrap_or_else(|e| panic!("{what} {addr:#04x}: {e:?}"));
            // When the board read its ports: the sample (general call) of the sweep, the
            // board's own transaction for a scan.
            let at = outcome
                .records
                .iter()
                .filter(|r| r.start_ns >= *t0 && r.end_ns <= *t1)
                .filter(|r| r.outcome == Outcome::Ok)
                .rfind(|r| {
                    if *what == "sweep" {
                        r.addr == 0
                    } else {
                        r.addr == *addr && r.written.first() == Some(&0x60)
                    }
                })
                .map(|r| (r.start_ns, r.end_ns))
                .expect("the transaction");
            // The board reads its ports inside that transaction (steps of the world fall on
            // whole ms, so at most one inside it): the world at its START or at its STOP.
            let (first, last) = (truth(*addr, at.0), truth(*addr, at.1));
            assert!(
                *got == first || *got == last,
                "{what} {addr:#04x}: {got:?}, the world {first:?} .. {last:?}"
            );
        }
    }
    for (what, busy, n, span) in &figures {
        println!(
            "{what}: 110 boards x 8 sensor ports at 1 MHz, PEC: {:.2} ms of bus time in {n} transactions, {:.2} ms from first call to last result",
            *busy as f64 / 1e6,
            *span as f64 / 1e6
        );
    }
    let (_, scan_busy, scan_n, _) = figures[0];
    let (_, sweep_busy, sweep_n, _) = figures[1];
    assert_eq!(scan_n, 110);
    // One general call and one read per board.
    assert_eq!(sweep_n, 111);
    assert!(sweep_busy <= 22_000_000, "{sweep_busy} ns");
    assert!(sweep_busy < scan_busy);
    // The sample: 1 MHz, START, address byte, 5 bytes (frame and PEC), STOP; each read: a
    // plain read of 19 bytes (reply header, levels, 12 bytes of packed values, CRC-16).
    let t = Speed::FastPlus.timing();
    let sample = outcome.records.iter().find(|r| r.addr == 0).unwrap();
    assert_eq!(sample.written.len(), 5);
    assert_eq!(sample.end_ns - sample.start_ns, t.write_ns(5));
    let (t0, t1) = (spans[1].1, spans[1].2);
    let reads: Vec<_> = outcome
        .records
        .iter()
        .filter(|r| r.start_ns >= t0 && r.end_ns <= t1 && r.addr != 0)
        .collect();
    assert_eq!(reads.len(), 110);
    assert!(reads
        .iter()
        .all(|r| r.is_read && r.written.is_empty() && r.read.len() == 19));
}

#[test]
fn two_boards_move_together() {
    let log_out = Rc::new(RefCell::new(Vec::new()));
    let out = log_out.clone();
    let mut sim = Sim::new(config(400));
    let a = Address::external(0x09).unwrap();
    let b = Address::external(0x0a).unwrap();
    for (name, addr) in [("db09", a), ("db0a", b)] {
        let ports = sim.ports(name, 0, 2);
        sim = sim.with_board(addr, ports);
    }
    let motor = Port::actuator(1).unwrap().pin(Pin::A);
    let dir = Port::actuator(2).unwrap().pin(Pin::B);
    let sim = sim.with_task(
        "together",
        task(move |ctx| {
            Box::pin(async move {
                ctx.clock.sleep_ns(60_000_000).await;
                let x10 = ctx.handle();
                // Set both motors, then apply together.
                let r = x10
                    .together(|t| {
                        t.set(a, Op::PwmDuty(motor, 200))?;
                        t.set(a, Op::DigitalWrite(dir, x10_microcode::Level::High))?;
                        t.set(b, Op::PwmDuty(motor, 180))
                    })
                    .await;
                out.borrow_mut().push(format!("{r:?}"));
                // An apply with nothing staged: nothing moves, nothing fails.
                let r = x10.together(|_| Ok(())).await;
                out.borrow_mut().push(format!("{r:?}"));
                // A stage that never gets its apply is dropped after 100 ms, and reported.
                let staged = x10_microcode::Batch::new_checked(&[0x20, 0x00, 0x01, 0x10]).unwrap();
                let r = x10.call(a, Op::Stage(staged)).await;
                out.borrow_mut().push(format!("{r:?}"));
                ctx.clock.sleep_ns(150_000_000).await;
                // Its apply, too late, moves nothing.
                let r = x10.call(a, Op::Apply).await;
                out.borrow_mut().push(format!("{r:?}"));
            })
        }),
    );
    let outcome = sim.run().expect("sim runs");
    assert_eq!(
        *log_out.borrow(),
        ["Ok(())", "Ok(())", "Ok([])", "Ok([])"],
        "{:?}",
        outcome.task_errors
    );
    let duty = |board: &str| {
        outcome
            .log
            .of(board, motor)
            .into_iter()
            .filter(|c| matches!(c.change, Change::Duty(d) if d > 0))
            .collect::<Vec<_>>()
    };
    let (da, db) = (duty("db09"), duty("db0a"));
    assert_eq!(da.len(), 1, "{da:?}");
    assert_eq!(db.len(), 1, "{db:?}");
    assert_eq!(da[0].change, Change::Duty(200));
    assert_eq!(db[0].change, Change::Duty(180));
    let apart = da[0].t_ns.abs_diff(db[0].t_ns);
    println!("together: the two boards' outputs changed {apart} ns apart");
    assert!(apart <= 50_000, "{apart} ns");
    let dir_change = outcome
        .log
        .of("db09", dir)
        .into_iter()
        .find(|c| c.change == Change::Digital(x10_microcode::Level::High))
        .expect("direction pin set");
    assert_eq!(dir_change.t_ns, da[0].t_ns);
    // The dropped stage: counted by the board as a timeout, reported to the MB.
    let (_, d) = outcome.boards.iter().find(|(n, _)| n == "db09").unwrap();
    assert_eq!(d.other_errors, 1);
    assert_eq!(outcome.mb.rejected, 1);
    // Duty 0x10 on A1.A never came out.
    assert!(outcome
        .log
        .of("db09", motor)
        .iter()
        .all(|c| c.change != Change::Duty(0x10)));
    let _ = Status::Ok;
}

#[test]
fn a_missing_board_fails_alone() {
    let out = Rc::new(RefCell::new(None));
    let o = out.clone();
    let mut sim = Sim::new(config(300));
    let addrs = [0x09u8, 0x0a, 0x0b];
    for &a in &addrs {
        let mut ports = sim.ports(&format!("db{a:02x}"), 8, 0).with_adc_bits(12);
        for port in 1..=8 {
            ports = ports.with_sensor(port, script(a, port));
        }
        sim = sim.with_board(Address::external(a).unwrap(), ports);
    }
    let list: Vec<Address> = addrs
        .iter()
        .map(|&a| Address::external(a).unwrap())
        .collect();
    let sim = sim.unplug_at("db0a", 50).with_task(
        "sweep",
        task(move |ctx| {
            Box::pin(async move {
                ctx.clock.sleep_ns(60_000_000).await;
                let x10 = ctx.handle();
                let mut values = vec![Ok(ScanResult::default()); 3];
                let summary = x10.sweep(&list, &mut values).await;
                *o.borrow_mut() = Some((ctx.clock.now_ns(), summary, values));
            })
        }),
    );
    let outcome = sim.run().expect("sim runs");
    let (_, summary, values) = out.borrow_mut().take().expect("the sweep ended");
    assert_eq!((summary.swept, summary.failed), (2, 1), "{summary:?}");
    assert_eq!(values[1], Err(LinkError::Nack));
    let sample = outcome.records.iter().find(|r| r.addr == 0).unwrap();
    for i in [0, 2] {
        let got = values[i].as_ref().unwrap();
        let a = addrs[i];
        assert!(
            *got == truth(a, sample.start_ns) || *got == truth(a, sample.end_ns),
            "{a:#04x}"
        );
    }
}
