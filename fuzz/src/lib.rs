//! The `mb_reply` fuzz target's harness: the real motherboard runtime (`firmware-mb`'s
//! `Motherboard`: dispatcher, requests table, event routing, waiters) on a fake bus whose
//! replies and events come from the input ([`bus`]), driven by a deterministic executor in
//! virtual time ([`vtime`], also embassy-time's driver), and checked by an oracle that reads the
//! frames itself ([`oracle`]).
//!
//! An input is a script, then the bus's bytes:
//!
//! | bytes | meaning |
//! |---|---|
//! | 0 | flags: bit 0 the safe defaults (`MbConfig::new`, else `thesis_compatible`); bit 1 two boards (0x09 and 0x0a, else 0x09) |
//! | 1 | the number of commands *n* (at most [`MAX_COMMANDS`]) |
//! | 2 .. 2 + 5*n* | commands of 5 bytes `[kind, a, b, c, d]`, see [`Command`] |
//! | the rest | one action per bus transaction, in the order the MB makes them ([`bus`]) |

pub mod bus;
pub mod oracle;
pub mod vtime;

use std::cell::RefCell;
use std::rc::Rc;

use embassy_futures::select::{select, Either};
use firmware_mb::{MbConfig, Motherboard};
use x10_devices::LinkError;
use x10_hal::ports::{EdgeCount, PortError, Ports};
use x10_microcode::{Address, Edge, EventConfig, Level, Op, PinRef, Port};

use crate::bus::{injector, FuzzBus, World};
use crate::oracle::{
    CallRec, CallResult, OpBytes, Record, ReplyRule, Violation, WaitRec, WaitSpan,
};
use crate::vtime::{now_us, sleep_until, Executor, Stop};

/// The MB's own address.
pub const MB: u8 = 0x08;
/// Commands per input, at most.
pub const MAX_COMMANDS: usize = 24;
/// Caller tasks.
pub const CALLERS: usize = 4;
/// Waiting tasks.
pub const WAITERS: usize = 2;
/// The motherboard's request timeout (`MbConfig::new`), in µs.
pub const REQUEST_TIMEOUT_US: u64 = 100_000;
/// The default pulse-in timeout (`MbConfig::new`), in ms.
pub const DEFAULT_PULSE_MS: u64 = 1_000;
/// The pins the scripts use: S1.A, S1.B, S2.A.
pub const PINS: [u8; 3] = [0x80, 0x81, 0x82];

/// One script command `[kind, a, b, c, d]`; `kind % 4`:
///
/// * 0, 1: a call by caller task `a % 4`, after a pause of `b` × 200 µs, to board `c & 1`,
///   operation `d % 16` with parameter `c >> 1` ([`op_of`]; 15 is a batch);
/// * 2: waiter task `a % 2` waits `1 + d % 4` times for an event of board `c & 1`, pin
///   `PINS[(c >> 1) % 3]`, each wait given up after `(1 + b)` ms;
/// * 3: an event written to the MB at `(a | b << 8)` × 10 µs: template `c`, bit `d` flipped
///   (0: none; 0xff: the check left out) ([`bus::World::event_for`]). A template's bits 0..2
///   are the kind (0 and 7 pin change, 1 analog threshold, 2 deferred reply, 3 boot,
///   4 rejected, 5 failsafe tripped, 6 overflow), bit 3 the board (with two), bits 4..7 the pin
///   (`PINS[(c >> 4) % 3]`); a deferred reply answers the board's oldest pulse-in still
///   pending, else the last request, by `c >> 6`: timeout, ok with 2 bytes, timeout with a
///   byte, ok with 4 bytes.
///
/// The bus's bytes ([`bus`]): one per transaction, `a`: `a & 7` 0 honest, 1 honest then
/// mutated (2 more bytes: how, where), 2 raw reply (a length byte, the bytes), 3 NACK,
/// 4 arbitration lost (and an event: 1 more byte, its template, and with bit 7 a mutation
/// byte), 5 timeout, 6 bus error, 7 honest and an event (as 4); the transfer takes
/// 60 + (a >> 3)² × 100 µs. An honest `pending` takes one more byte: its deferred reply comes
/// 1 + 4 × that ms later (at most the pulse timeout + 1 ms). Used up: honest, at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Command(pub [u8; 5]);

/// An operation of the scripts: the oracle's bytes for it (its own encoding of protocol.md's
/// table) and how many times it is called in a row (a burst of pings wraps the board's
/// sequence numbers).
pub fn op_of(sel: u8, p: u8) -> (OpBytes, usize) {
    let sensor = |p: u8| 0x80 | ((p % 2) << 1);
    let actuator = |p: u8| (p % 2) << 1;
    let pin_bit = |p: u8| (p >> 1) & 1;
    let mk = |fn_op: u8, port: u8, data: Vec<u8>, rule: ReplyRule| OpBytes {
        fn_op,
        port,
        data,
        rule,
        set_pec: None,
        timeout_us: REQUEST_TIMEOUT_US,
    };
    let op = match sel % 16 {
        0 | 14 => mk(0x00, 0, vec![], ReplyRule::Exact(0)),
        1 => mk(0x01, 0, vec![], ReplyRule::Exact(10)),
        2 => mk(0x05, 0, vec![], ReplyRule::Exact(28)),
        3 => mk(0x60, 0, vec![], ReplyRule::Scan),
        4 => mk(0x10, sensor(p) | pin_bit(p), vec![], ReplyRule::Level),
        5 => mk(0x30, sensor(p), vec![], ReplyRule::Exact(2)),
        6 => mk(
            0x41,
            sensor(p),
            vec![1 + (p >> 1) % 28],
            ReplyRule::UpTo(usize::from(1 + (p >> 1) % 28)),
        ),
        7 => {
            let fn_op = if p & 4 != 0 { 0x13 } else { 0x14 };
            let (data, ms) = if p & 8 != 0 {
                let ms = 1 + u16::from(p >> 4);
                (ms.to_le_bytes().to_vec(), u64::from(ms))
            } else {
                (vec![], DEFAULT_PULSE_MS)
            };
            let mut o = mk(fn_op, sensor(p) | pin_bit(p), data, ReplyRule::Deferred);
            o.timeout_us += ms * 1_000;
            o
        }
        8 => mk(
            0x11 + ((p >> 2) & 1),
            actuator(p) | pin_bit(p),
            vec![],
            ReplyRule::Write,
        ),
        9 => mk(
            0x20,
            actuator(p) | pin_bit(p),
            vec![p.wrapping_mul(37)],
            ReplyRule::Write,
        ),
        10 => mk(
            0x04,
            sensor(p) | pin_bit(p),
            vec![0x03, 0, 0, 0, 0],
            ReplyRule::Exact(0),
        ),
        11 => {
            let mut o = mk(0x07, 0, vec![p & 1], ReplyRule::Exact(0));
            o.set_pec = Some(p & 1 == 1);
            o
        }
        12 => mk(
            0x03,
            0,
            (u16::from(p) * 10).to_le_bytes().to_vec(),
            ReplyRule::Exact(0),
        ),
        13 => mk(0x06, 0, vec![], ReplyRule::Write),
        // A batch: io input S1.A, analog read S1, PWM duty on A1.A.
        _ => mk(
            0x50,
            0,
            vec![0x10, 0x80, 0, 0x30, 0x80, 0, 0x20, 0x00, 1, p],
            ReplyRule::Batch(&[ReplyRule::Level, ReplyRule::Exact(2), ReplyRule::Write]),
        ),
    };
    let times = if sel % 16 == 14 {
        2 + usize::from(p) * 2
    } else {
        1
    };
    (op, times)
}

/// The runtime's `Op` for the oracle's bytes (through x10-microcode's types, as a program
/// builds it).
fn runtime_op(o: &OpBytes) -> Op<'_> {
    let pin = PinRef::from_byte(o.port);
    let port = Port::from_byte(o.port);
    let u16_at = |i: usize| u16::from_le_bytes([o.data[i], o.data[i + 1]]);
    match o.fn_op {
        0x00 => Op::Ping,
        0x01 => Op::Identify,
        0x02 => Op::Heartbeat,
        0x03 => Op::SetFailsafe {
            timeout_ms: u16_at(0),
        },
        0x04 => Op::EventEnable(
            pin,
            EventConfig {
                rising: true,
                falling: true,
                analog_window: false,
                low: 0,
                high: 0,
            },
        ),
        0x05 => Op::ReadDiagnostics,
        0x06 => Op::ClearDiagnostics,
        0x07 => Op::SetPec(o.data[0] == 1),
        0x10 => Op::DigitalRead(pin),
        0x11 => Op::DigitalWrite(pin, Level::Low),
        0x12 => Op::DigitalWrite(pin, Level::High),
        0x13 | 0x14 => Op::PulseIn {
            pin,
            edge: if o.fn_op == 0x13 {
                Edge::Rising
            } else {
                Edge::Falling
            },
            timeout_ms: (o.data.len() == 2).then(|| u16_at(0)),
        },
        0x20 => Op::PwmDuty(pin, o.data[0]),
        0x30 => Op::AnalogRead(port),
        0x41 => Op::SerialRead(port, o.data[0]),
        0x50 => match x10_microcode::Batch::new_checked(&o.data) {
            Ok(b) => Op::Batch(b),
            Err(_) => Op::Ping,
        },
        _ => Op::Scan,
    }
}

/// The MB's internal board's ports: 2 sensor and 2 actuator ports that do nothing (the
/// internal board is not what this target fuzzes).
struct QuietPorts;

impl Ports for QuietPorts {
    fn sensor_ports(&self) -> u8 {
        2
    }
    fn actuator_ports(&self) -> u8 {
        2
    }
    fn adc_bits(&self) -> u8 {
        12
    }
    fn digital_read(&self, _pin: PinRef) -> Result<Level, PortError> {
        Ok(Level::Low)
    }
    fn digital_write(&self, _pin: PinRef, _level: Level) -> Result<(), PortError> {
        Ok(())
    }
    fn pwm_duty(&self, _pin: PinRef, _duty: u8) -> Result<(), PortError> {
        Ok(())
    }
    fn pwm_frequency(&self, _port: Port, _hz: u16) -> Result<(), PortError> {
        Ok(())
    }
    fn pwm_pulse_width(&self, _pin: PinRef, _us: u16) -> Result<(), PortError> {
        Ok(())
    }
    fn analog_read(&self, _port: Port) -> Result<u16, PortError> {
        Ok(0)
    }
    async fn pulse_in(
        &self,
        _pin: PinRef,
        _edge: Edge,
        _timeout_ms: u16,
    ) -> Result<u32, PortError> {
        Err(PortError::Timeout)
    }
    fn take_edges(&self, _pin: PinRef) -> Result<EdgeCount, PortError> {
        Err(PortError::Unsupported)
    }
}

/// A decoded input.
#[derive(Clone, Debug)]
pub struct Case {
    pub safe: bool,
    pub boards: Vec<u8>,
    pub commands: Vec<Command>,
    pub bus: Vec<u8>,
}

impl Case {
    /// Decodes an input (never fails: missing bytes are zeros).
    pub fn decode(input: &[u8]) -> Case {
        let flags = input.first().copied().unwrap_or(0);
        let n = usize::from(input.get(1).copied().unwrap_or(0)).min(MAX_COMMANDS);
        let mut commands = Vec::new();
        let mut pos = 2;
        for _ in 0..n {
            let mut c = [0u8; 5];
            for b in c.iter_mut() {
                *b = input.get(pos).copied().unwrap_or(0);
                pos += 1;
            }
            commands.push(Command(c));
        }
        Case {
            safe: flags & 1 != 0,
            boards: if flags & 2 != 0 {
                vec![0x09, 0x0a]
            } else {
                vec![0x09]
            },
            commands,
            bus: input.get(pos..).unwrap_or(&[]).to_vec(),
        }
    }

    /// The input that decodes to this case.
    pub fn encode(&self) -> Vec<u8> {
        let mut v = vec![
            u8::from(self.safe) | (u8::from(self.boards.len() > 1) << 1),
            self.commands.len() as u8,
        ];
        for c in &self.commands {
            v.extend(c.0);
        }
        v.extend(&self.bus);
        v
    }
}

/// Runs one input and checks it; the record either way.
pub fn run(input: &[u8]) -> (Record, Result<(), Violation>) {
    let case = Case::decode(input);
    let mb_addr = Address::external(MB).expect("0x08 is an external address");
    let config = if case.safe {
        MbConfig::new(mb_addr)
    } else {
        MbConfig::thesis_compatible(mb_addr)
    };
    let mb = Motherboard::new(config, QuietPorts);
    let world = World::new(MB, case.boards.clone(), &case.bus);
    let calls: Rc<RefCell<Vec<CallRec>>> = Rc::default();
    let waits: Rc<RefCell<Vec<WaitRec>>> = Rc::default();
    let timeouts: Rc<RefCell<Vec<WaitSpan>>> = Rc::default();
    let busy: Rc<RefCell<usize>> = Rc::default();

    // Per task: its list of commands.
    let mut callers: Vec<Vec<(u64, u8, OpBytes, usize)>> = vec![Vec::new(); CALLERS];
    let mut waiters: Vec<Vec<(u8, u8, usize, u64)>> = vec![Vec::new(); WAITERS];
    for Command([kind, a, b, c, d]) in &case.commands {
        let board = case.boards[usize::from(c & 1) % case.boards.len()];
        match kind % 4 {
            0 | 1 => {
                let (op, times) = op_of(*d, c >> 1);
                callers[usize::from(a % 4)].push((u64::from(*b) * 200, board, op, times));
            }
            2 => waiters[usize::from(a % 2)].push((
                board,
                PINS[usize::from(c >> 1) % 3],
                1 + usize::from(d % 4),
                (1 + u64::from(*b)) * 1_000,
            )),
            _ => {
                let at = (u64::from(*a) | u64::from(*b) << 8) * 10;
                let mut w = world.borrow_mut();
                if let Some(ev) = w.event_for(*c, *d) {
                    w.schedule(at, ev);
                }
            }
        }
    }

    let stop = {
        let mut ex = Executor::new();
        ex.spawn(async {
            mb.run(FuzzBus {
                world: world.clone(),
            })
            .await;
        });
        ex.spawn(injector(world.clone()));
        for (task, list) in callers.into_iter().enumerate() {
            if list.is_empty() {
                continue;
            }
            *busy.borrow_mut() += 1;
            let (calls, busy, core) = (calls.clone(), busy.clone(), mb.core());
            ex.spawn(async move {
                for (pause, board, op, times) in list {
                    sleep_until(now_us() + pause).await;
                    let addr = Address::external(board).expect("board addresses are external");
                    for _ in 0..times {
                        let i = {
                            let mut c = calls.borrow_mut();
                            c.push(CallRec {
                                task,
                                db: board,
                                op: op.clone(),
                                start: now_us(),
                                end: None,
                                result: None,
                            });
                            c.len() - 1
                        };
                        let r = core.call(addr, runtime_op(&op)).await;
                        let result = match r {
                            Ok(p) => CallResult::Ok(p.to_vec()),
                            Err(LinkError::Status(s)) => CallResult::Status(s.to_byte()),
                            Err(e) => CallResult::Other(format!("{e:?}")),
                        };
                        let mut c = calls.borrow_mut();
                        c[i].end = Some(now_us());
                        c[i].result = Some(result);
                    }
                }
                *busy.borrow_mut() -= 1;
            });
        }
        for (wi, list) in waiters.into_iter().enumerate() {
            if list.is_empty() {
                continue;
            }
            *busy.borrow_mut() += 1;
            let (waits, timeouts, busy, core) =
                (waits.clone(), timeouts.clone(), busy.clone(), mb.core());
            ex.spawn(async move {
                for (board, pin, count, window) in list {
                    let addr = Address::external(board).expect("board addresses are external");
                    for _ in 0..count {
                        let start = now_us();
                        let r = select(
                            core.wait_event(addr, PinRef::from_byte(pin)),
                            sleep_until(now_us() + window),
                        )
                        .await;
                        if let Either::Second(()) = r {
                            timeouts.borrow_mut().push(WaitSpan {
                                task: CALLERS + wi,
                                db: board,
                                pin,
                                start,
                                end: now_us(),
                            });
                        }
                        if let Either::First(Ok(ev)) = r {
                            waits.borrow_mut().push(WaitRec {
                                task: CALLERS + wi,
                                db: board,
                                pin,
                                at: now_us(),
                                source: ev.source.get(),
                                kind: ev.kind.to_byte(),
                                got_pin: ev.pin.to_byte(),
                                value: ev.value.to_vec(),
                            });
                        }
                    }
                }
                *busy.borrow_mut() -= 1;
            });
        }
        let b = busy.clone();
        ex.run(3_600_000_000, &move || *b.borrow() == 0)
    };

    let w = world.borrow();
    let record = Record {
        mb: MB,
        safe: case.safe,
        txns: w.txns.clone(),
        sent: w.sent.clone(),
        calls: calls.borrow().clone(),
        waits: waits.borrow().clone(),
        timeouts: timeouts.borrow().clone(),
    };
    let verdict = match stop {
        Stop::Livelock(at) => Err(Violation {
            class: "livelock",
            what: format!("livelock: tasks kept waking each other at {at} us without time moving"),
        }),
        _ => record.check(),
    };
    (record, verdict)
}

/// Seed inputs built from valid frames: every operation answered honestly, in both
/// configurations, with one and two boards, waiters and events, and a few faults.
pub fn seeds() -> Vec<(String, Vec<u8>)> {
    let call = |task: u8, pause: u8, board: u8, p: u8, sel: u8| {
        Command([0, task, pause, board | (p << 1), sel])
    };
    let wait = |w: u8, window_ms: u8, board: u8, pin: u8, count: u8| {
        Command([2, w, window_ms, board | (pin << 1), count])
    };
    let event = |at_10us: u16, template: u8, flip: u8| {
        Command([3, at_10us as u8, (at_10us >> 8) as u8, template, flip])
    };
    let mut out = Vec::new();
    for safe in [false, true] {
        let name = if safe { "safe" } else { "thesis" };
        // Every operation once, in order, from one task.
        let all: Vec<Command> = (0..16u8).map(|sel| call(0, 1, 0, 3, sel)).collect();
        out.push((
            format!("{name}-every-op"),
            Case {
                safe,
                boards: vec![0x09],
                commands: all,
                bus: vec![],
            },
        ));
        // Four callers on two boards, two waiters, pin events of both boards.
        let mut cmds = vec![
            call(0, 0, 0, 0, 4),
            call(1, 2, 1, 1, 5),
            call(2, 1, 0, 2, 3),
            call(3, 3, 1, 4, 7),
            call(0, 5, 1, 8, 8),
            call(1, 5, 0, 0, 10),
            wait(0, 50, 0, 0, 3),
            wait(1, 50, 1, 2, 2),
        ];
        for (i, t) in [0u8, 0x08, 0x20, 0x28, 0x01].iter().enumerate() {
            cmds.push(event(50 + 40 * i as u16, *t, 0));
        }
        out.push((
            format!("{name}-two-boards"),
            Case {
                safe,
                boards: vec![0x09, 0x0a],
                commands: cmds,
                bus: vec![],
            },
        ));
        // Pulse-ins with and without a timeout; a boot event between them.
        let cmds = vec![
            call(0, 0, 0, 0x0c, 7),
            call(1, 1, 0, 0x05, 7),
            event(2_000, 3, 0),
            call(0, 10, 0, 0x1c, 7),
            call(2, 20, 0, 0, 0),
        ];
        out.push((
            format!("{name}-pulse-in"),
            Case {
                safe,
                boards: vec![0x09],
                commands: cmds,
                bus: vec![],
            },
        ));
        // Faults: NACK, arbitration lost with an event, timeout, bus error, a mutated and a
        // raw reply, a slow one.
        let cmds = vec![
            call(0, 0, 0, 0, 0),
            call(0, 0, 0, 0, 1),
            call(0, 0, 0, 0, 4),
            call(0, 0, 0, 0, 5),
            call(0, 0, 0, 0, 3),
            call(1, 0, 0, 0, 8),
            wait(0, 20, 0, 0, 2),
        ];
        let bus = vec![
            3, 0, 4, 0x00, 0, 5, 6, 1, 0, 9, 2, 4, 0x05, 0x00, 0x01, 0x01, 0xf8, 0, 0x07, 0x10,
        ];
        out.push((
            format!("{name}-faults"),
            Case {
                safe,
                boards: vec![0x09],
                commands: cmds,
                bus,
            },
        ));
    }
    // A burst of pings that wraps the sequence numbers, beside a pulse-in.
    let cmds = vec![call(0, 0, 0, 0x0c, 7), call(1, 1, 0, 127, 14)];
    out.push((
        "safe-seq-wrap".to_string(),
        Case {
            safe: true,
            boards: vec![0x09],
            commands: cmds,
            bus: vec![],
        },
    ));
    out.into_iter().map(|(n, c)| (n, c.encode())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Honest boards never break the oracle: the seeds are clean, but for the defects pinned
    /// in regressions/open (CLASS--name) while they are open.
    #[test]
    fn seeds_are_clean() {
        let open = concat!(env!("CARGO_MANIFEST_DIR"), "/regressions/open");
        let open: Vec<String> = std::fs::read_dir(open)
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .filter_map(|e| {
                        let n = e.file_name().to_string_lossy().into_owned();
                        n.split_once("--").map(|(c, _)| c.to_string())
                    })
                    .collect()
            })
            .unwrap_or_default();
        for (name, input) in seeds() {
            let (record, verdict) = run(&input);
            if let Err(v) = verdict {
                if open.iter().any(|c| c == v.class) {
                    continue;
                }
                panic!("seed {name}: {v}\n{}", record.dump());
            }
            assert!(!record.calls.is_empty(), "{name}");
        }
    }
}

#[cfg(test)]
mod dump {
    #[test]
    #[ignore]
    fn dump_seeds() {
        for (name, input) in super::seeds() {
            let (record, verdict) = super::run(&input);
            println!("== {name}: {verdict:?}\n{}", record.dump());
        }
    }
}

#[cfg(test)]
mod checked_in {
    /// `seeds/mb_reply/` holds exactly [`super::seeds`] (run.sh fuzzes from it).
    #[test]
    fn seed_files_are_current() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/seeds/mb_reply");
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .expect("seeds/mb_reply exists")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let mut want: Vec<(String, Vec<u8>)> = super::seeds()
            .into_iter()
            .map(|(n, b)| (format!("seed-{n}"), b))
            .collect();
        want.sort();
        assert_eq!(names, want.iter().map(|w| w.0.clone()).collect::<Vec<_>>());
        for (name, bytes) in want {
            assert_eq!(
                std::fs::read(format!("{dir}/{name}")).expect("readable"),
                bytes,
                "{name}: run `cargo run --release --bin mb_seeds seeds/mb_reply`"
            );
        }
    }
}

#[cfg(test)]
mod regressions {
    /// The regression inputs, as fuzz/run.sh replays them: `regressions/*` clean,
    /// `regressions/open/CLASS--name` failing with exactly CLASS.
    #[test]
    fn replay() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/regressions");
        let mut seen = 0;
        for sub in ["", "/open"] {
            for entry in std::fs::read_dir(format!("{dir}{sub}")).expect("regressions/ exists") {
                let path = entry.expect("entry").path();
                if !path.is_file() {
                    continue;
                }
                seen += 1;
                let name = path
                    .file_name()
                    .expect("a name")
                    .to_string_lossy()
                    .into_owned();
                let (record, verdict) = super::run(&std::fs::read(&path).expect("readable"));
                match (sub, verdict) {
                    ("", Ok(())) => {}
                    ("", Err(v)) => panic!("{name}: {v}\n{}", record.dump()),
                    (_, Err(v)) if name.starts_with(&format!("{}--", v.class)) => {}
                    (_, other) => panic!("{name}: {other:?}\n{}", record.dump()),
                }
            }
        }
        assert!(seen > 0);
    }
}
