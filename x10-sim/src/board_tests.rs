//! The real firmware-db on the simulated bus, driven by a hand-written master.

use std::cell::RefCell;

use x10_hal::bus::{Incoming, MultiMaster};
use x10_microcode::{Address, Event, EventKind, Level, Op, Pin, Port, Reply, Request, Status};

use super::*;
use crate::bus::{BusConfig, SimBus};
use crate::exec::{Executor, SimClock};
use crate::ports::{ActuatorLog, Analog, Digital, SensorScript};
use crate::timing::Speed;

fn frame(db: u8, seq: u8, op: Op<'_>) -> Vec<u8> {
    let req = Request {
        db: Address::new(db).unwrap(),
        seq,
        op,
    };
    let mut buf = [0u8; 32];
    let n = req.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

#[test]
fn real_daughterboard_serves_writes_reads_events_and_failsafe() {
    let clock = SimClock::new();
    let log = ActuatorLog::new();
    let notes = Notes::new();
    let ports = SimPorts::new("db09", clock.clone(), log.clone(), 2, 2).with_sensor(
        1,
        SensorScript {
            a: Digital::pressed_at(2_000),
            b: Digital::Const(false),
            analog: Analog::Const(712),
        },
    );
    let board = DbBoard::new(
        Address::external(0x09).unwrap(),
        Address::external(0x08).unwrap(),
        ports,
    );
    let events = RefCell::new(Vec::new());
    let replies = RefCell::new(Vec::new());
    let mut ex = Executor::with_clock(&clock);
    let bus = SimBus::new(clock.clone(), BusConfig::new(Speed::Fast));
    ex.spawn("bus", bus.engine());
    let mb = bus.add_node(NodeConfig::new("mb", Some(0x08)));
    let db = bus.add_node(board.node_config());
    ex.spawn("db09", board.run(bus.clone(), db, notes.clone()));
    // The MB's listener: collects events.
    let mut listen_port = bus.port(mb);
    let ev = &events;
    let c = clock.clone();
    ex.spawn("mb-listen", async move {
        let mut buf = [0u8; 40];
        loop {
            if let Ok(Incoming::Write(n)) = listen_port.listen(&mut buf).await {
                let e = parse_event(&buf[..n]);
                ev.borrow_mut()
                    .push((c.now_ns() / 1_000_000, e.kind, e.seq, e.payload.to_vec()));
            }
        }
    });
    // The MB's controller side (a second handle on the same node).
    let mut p = bus.port(mb);
    let rp = &replies;
    let c = clock.clone();
    let a1b = Port::actuator(1).unwrap().pin(Pin::B);
    let s1a = Port::sensor(1).unwrap().pin(Pin::A);
    ex.spawn("mb", async move {
        c.sleep_ns(10_000_000).await;
        p.write(0x09, &frame(9, 2, Op::DigitalWrite(a1b, Level::High)))
            .await
            .unwrap();
        let mut rd = [0u8; 4];
        p.write_read(0x09, &frame(9, 3, Op::DigitalRead(s1a)), &mut rd)
            .await
            .unwrap();
        rp.borrow_mut().push(rd.to_vec());
        let mut rd = [0u8; 5];
        p.write_read(0x09, &frame(9, 4, Op::AnalogRead(s1a.port)), &mut rd)
            .await
            .unwrap();
        rp.borrow_mut().push(rd.to_vec());
        p.write(0x09, &frame(9, 5, Op::SetFailsafe { timeout_ms: 100 }))
            .await
            .unwrap();
        // Then silence: the failsafe trips 100 ms after this last transaction.
    });
    ex.run_until_ns(3_000_000_000).unwrap();

    assert_eq!(
        *replies.borrow(),
        vec![vec![3, 0, 1, 0], vec![4, 0, 2, 0xc8, 0x02]]
    );
    let ev = events.borrow();
    assert_eq!(ev[0].1, EventKind::Boot);
    assert_eq!(ev[1].1, EventKind::FailsafeTripped);
    assert_eq!(ev[1].3, vec![100, 0]);
    assert!((110..=112).contains(&ev[1].0), "{:?}", ev[1]);
    // The actuator went high at the end of the write, and low again when the failsafe tripped.
    let changes = log.of("db09", a1b);
    let levels: Vec<_> = changes
        .iter()
        .map(|c| (c.change, c.t_ns / 1_000_000))
        .collect();
    assert_eq!(
        levels,
        vec![
            (crate::ports::Change::Digital(Level::Low), 0),
            (crate::ports::Change::Digital(Level::High), 10),
            (crate::ports::Change::Digital(Level::Low), 110),
        ]
    );
    let d = board.diagnostics.get();
    assert_eq!(d.failsafe_trips, 1);
    assert!(notes.lines().is_empty());
    // Status bytes decode.
    assert_eq!(
        Reply::parse(&replies.borrow()[0]).unwrap().status,
        Status::Ok
    );
}

#[test]
fn reset_restarts_the_firmware_and_sends_boot_again() {
    let clock = SimClock::new();
    let log = ActuatorLog::new();
    let notes = Notes::new();
    let board = DbBoard::new(
        Address::external(0x0A).unwrap(),
        Address::external(0x08).unwrap(),
        SimPorts::new("db0a", clock.clone(), log.clone(), 1, 1),
    );
    let boots = RefCell::new(Vec::new());
    let mut ex = Executor::with_clock(&clock);
    let bus = SimBus::new(clock.clone(), BusConfig::new(Speed::Standard));
    ex.spawn("bus", bus.engine());
    let mb = bus.add_node(NodeConfig::new("mb", Some(0x08)));
    let db = bus.add_node(board.node_config());
    ex.spawn("db", board.run(bus.clone(), db, notes.clone()));
    let mut port = bus.port(mb);
    let b = &boots;
    let c = clock.clone();
    ex.spawn("mb", async move {
        let mut buf = [0u8; 40];
        loop {
            if let Ok(Incoming::Write(n)) = port.listen(&mut buf).await {
                if parse_event(&buf[..n]).kind == EventKind::Boot {
                    b.borrow_mut().push(c.now_ns() / 1_000_000);
                }
            }
        }
    });
    let bus2 = bus.clone();
    let c = clock.clone();
    ex.spawn("resetter", async move {
        c.sleep_ns(50_000_000).await;
        bus2.reset_node(db, 5_000_000);
    });
    ex.run_until_ns(100_000_000).unwrap();
    // A boot event (the address byte, 25 bytes and its CRC-16: 28 bytes of 9 bits) takes
    // 2.5 ms at 100 kHz; it is seen when it ends.
    assert_eq!(*boots.borrow(), vec![2, 57]);
    let n = notes.lines();
    assert_eq!(n.len(), 1);
    assert_eq!(
        n[0].to_string(),
        "0.050000 WARN  db0a: reset: firmware restarts at 0.055000"
    );
}

/// A reset cuts the board's power: its PWM outputs stop at once. The log records the duty
/// falling to 0 at the instant of the reset, not only when (or if) the firmware sets it again.
#[test]
fn a_reset_records_the_pwm_duty_falling_to_0() {
    let clock = SimClock::new();
    let log = ActuatorLog::new();
    let board = DbBoard::new(
        Address::external(0x0A).unwrap(),
        Address::external(0x08).unwrap(),
        SimPorts::new("db0a", clock.clone(), log.clone(), 1, 1),
    );
    let mut ex = Executor::with_clock(&clock);
    let bus = SimBus::new(clock.clone(), BusConfig::new(Speed::Fast));
    ex.spawn("bus", bus.engine());
    let mb = bus.add_node(NodeConfig::new("mb", Some(0x08)));
    let db = bus.add_node(board.node_config());
    ex.spawn("db", board.run(bus.clone(), db, Notes::new()));
    let mut listen_port = bus.port(mb);
    ex.spawn("mb-listen", async move {
        let mut buf = [0u8; 40];
        loop {
            let _ = listen_port.listen(&mut buf).await;
        }
    });
    let a1a = Port::actuator(1).unwrap().pin(Pin::A);
    let mut p = bus.port(mb);
    let c = clock.clone();
    let bus2 = bus.clone();
    ex.spawn("mb", async move {
        c.sleep_ns(10_000_000).await;
        p.write(0x0A, &frame(0x0A, 2, Op::PwmDuty(a1a, 200)))
            .await
            .unwrap();
        c.sleep_until_ns(20_000_000).await;
        bus2.reset_node(db, 5_000_000);
    });
    ex.run_until_ns(50_000_000).unwrap();
    let duty: Vec<_> = log
        .of("db0a", a1a)
        .iter()
        .filter_map(|c| match c.change {
            crate::ports::Change::Duty(d) => Some((c.t_ns, d)),
            _ => None,
        })
        .collect();
    let n = frame(0x0A, 2, Op::PwmDuty(a1a, 200)).len();
    let written = 10_000_000 + Speed::Fast.timing().write_ns(n);
    assert_eq!(duty, vec![(written, 200), (20_000_000, 0)]);
    assert_eq!(log.duty_at("db0a", a1a, 30_000_000), 0);
    // The firmware's safe state at each power-up (0 s, and 5 ms after the reset).
    let safe: Vec<_> = log.safe_states().iter().map(|s| s.t_ns).collect();
    assert_eq!(safe, vec![0, 25_000_000]);
}

/// An event as the MB at 0x08 reads it: without a check, or with one (the `boot` event always
/// carries its check).
fn parse_event(bytes: &[u8]) -> Event<'_> {
    Event::parse(bytes)
        .or_else(|_| Event::parse_with_pec(Address::external(0x08).unwrap(), bytes))
        .unwrap()
}
