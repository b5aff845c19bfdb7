//! The laptop's plug-and-play and update requests (link version 2), served by
//! `x10_link::recorder::serve` on the simulated motherboard: the boards listed in full, a board
//! moved by its unique ID with every refusal typed, and an update started (and refused) by
//! request with its records. Checked against the simulator's ground truth: where each board
//! started, which port a call reached, the version each board's flash holds.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use firmware_mb::update::{run_updates, NoRom, UpdateConfig, UpdatePolicy};
use firmware_mb::BoardQuery;
use x10_link::recorder::{serve, Identity, Recorder};
use x10_link::{Feed, FrameReader, Hello, ToDevice, ToHost, WireOp, MAX_FRAME};
use x10_microcode::{Address, BoardKind, Level, Op, Pin, Port};
use x10_sim::board::uid_of_name;
use x10_sim::firmware::{carried, SimFirmware};
use x10_sim::sim::{task, Sim, SimConfig, TaskFn};

const MS: u64 = 1_000_000;

const WHO: Identity = Identity {
    address: 8,
    board: "sim",
    robot: "test",
};

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

/// The address plug and play gives an ID when nothing else is taken (as in x10-sim's
/// plug_and_play tests: `0x08 + hash % 111`, the MB's 0x08 and 0x64 skipped).
fn hashed(uid: x10_microcode::Uid) -> u8 {
    match 0x08 + (uid.hash32() % 111) as u8 {
        0x08 => 0x09,
        0x64 => 0x65,
        a => a,
    }
}

/// What the laptop got: every frame the recorder sent, decoded (Rust's `Debug` form).
type Got = Rc<RefCell<Vec<String>>>;

/// The USB task of a test: drains the recorder every ms into `got`, until `done` (then once
/// more).
fn drainer<const N: usize>(rec: &'static Recorder<N>, got: Got, done: Rc<Cell<bool>>) -> TaskFn {
    task(move |ctx| {
        Box::pin(async move {
            let mut reader: FrameReader<{ MAX_FRAME }> = FrameReader::new();
            let mut buf = [0u8; 64];
            loop {
                let last = done.get();
                loop {
                    let n = rec.take(&mut buf);
                    if n == 0 {
                        break;
                    }
                    for &b in &buf[..n] {
                        if reader.feed(b) == Feed::Frame {
                            got.borrow_mut()
                                .push(format!("{:?}", reader.decode::<ToHost>().unwrap()));
                        }
                    }
                }
                if last {
                    return;
                }
                ctx.clock.sleep_ns(MS).await;
            }
        })
    })
}

/// The frames that are not records of calls, events or outputs (nor logs, drops).
fn answers(got: &Got) -> Vec<String> {
    got.borrow()
        .iter()
        .filter(|f| {
            !["Call(", "Event(", "Output(", "Dropped(", "Log("]
                .iter()
                .any(|p| f.starts_with(p))
        })
        .cloned()
        .collect()
}

fn hello() -> ToDevice<'static> {
    ToDevice::Hello(Hello {
        version: 2,
        address: 0,
        board: "x10",
        robot: "",
    })
}

fn uid_text(u: x10_microcode::Uid) -> String {
    format!("{:?}", u.0)
}

static ASSIGN_REC: Recorder<4096> = Recorder::new();

#[test]
fn the_laptop_lists_the_boards_and_moves_one_by_its_unique_id() {
    let (u0, u1) = (uid_of_name("pnp0"), uid_of_name("pnp1"));
    let (h0, h1) = (hashed(u0), hashed(u1));
    assert_ne!(h0, h1);
    let got: Got = Rc::default();
    let done = Rc::new(Cell::new(false));
    let d = done.clone();
    let mut sim = Sim::new(SimConfig {
        duration_ms: 3_000,
        stop_when_tasks_done: true,
        ..SimConfig::default()
    });
    for name in ["pnp0", "pnp1"] {
        let ports = sim.ports(name, 1, 1);
        sim = sim.with_unaddressed_board(name, None, ports);
    }
    let pin = Port::actuator(1).unwrap().pin(Pin::A);
    let high = Op::DigitalWrite(pin, Level::High);
    let mut data = [0u8; 4];
    let n = high.emit_data(&mut data).unwrap();
    let data: &'static [u8] = Vec::leak(data[..n].to_vec());
    let op = WireOp {
        fn_op: high.fn_op_byte(),
        port: high.port_byte(),
        data,
    };
    let o = sim
        .also_observe(&ASSIGN_REC)
        .with_task("usb", drainer(&ASSIGN_REC, got.clone(), done))
        .with_task(
            "laptop",
            task(move |ctx| {
                Box::pin(async move {
                    let x10 = ctx.handle();
                    for u in [u0, u1] {
                        x10.wait_for_board(BoardQuery::Uid(u), 1_000_000)
                            .await
                            .unwrap();
                    }
                    let rec = &ASSIGN_REC;
                    serve(rec, x10, WHO, hello()).await;
                    serve(rec, x10, WHO, ToDevice::Boards { id: 1, first: 0 }).await;
                    serve(rec, x10, WHO, ToDevice::Boards { id: 2, first: 1 }).await;
                    serve(rec, x10, WHO, ToDevice::Boards { id: 3, first: 5 }).await;
                    let assign = |id, uid: x10_microcode::Uid, address| ToDevice::Assign {
                        id,
                        uid: uid.0,
                        address,
                    };
                    // Refused: an unknown ID, reserved addresses, the other board's address.
                    serve(rec, x10, WHO, assign(10, x10_microcode::Uid([7; 8]), 0x40)).await;
                    for (id, a) in [(11, 0x08), (12, 0x64), (13, 0x77), (14, 0x00), (15, 0x80)] {
                        serve(rec, x10, WHO, assign(id, u0, a)).await;
                    }
                    serve(rec, x10, WHO, assign(16, u0, h1)).await;
                    // Moved: answered once it confirmed; the laptop then lists the boards
                    // until it is present there (x10-cli's `Robot::assign`).
                    serve(rec, x10, WHO, assign(17, u0, 0x40)).await;
                    let mut polls = 0;
                    while !x10
                        .board(BoardQuery::Uid(u0))
                        .is_some_and(|b| b.present && b.address == addr(0x40))
                    {
                        polls += 1;
                        assert!(polls < 100, "not at 0x40 within 1 s");
                        ctx.clock.sleep_ns(10 * MS).await;
                    }
                    // Where it is already: done at once.
                    serve(rec, x10, WHO, assign(18, u0, 0x40)).await;
                    serve(
                        rec,
                        x10,
                        WHO,
                        ToDevice::Call {
                            id: 20,
                            db: 0x40,
                            op,
                        },
                    )
                    .await;
                    serve(rec, x10, WHO, ToDevice::Call { id: 21, db: h0, op }).await;
                    serve(rec, x10, WHO, ToDevice::Boards { id: 22, first: 0 }).await;
                    // This image runs no updater: refused, typed.
                    serve(rec, x10, WHO, ToDevice::Update { id: 23, uid: None }).await;
                    d.set(true);
                })
            }),
        )
        .run()
        .unwrap();
    let entry = |a: u8, u, state: &str| {
        format!(
            "BoardEntry {{ address: {a}, uid: {}, kind: {}, firmware: [0, 1, 0], state: {state} }}",
            uid_text(u),
            BoardKind::SIMULATED.0
        )
    };
    assert_eq!(
        answers(&got),
        [
            "Hello(Hello { version: 2, address: 8, board: \"sim\", robot: \"test\" })".to_string(),
            format!(
                "BoardList {{ id: 1, total: 2, first: 0, boards: [{}, {}] }}",
                entry(h0, u0, "Present"),
                entry(h1, u1, "Present")
            ),
            format!(
                "BoardList {{ id: 2, total: 2, first: 1, boards: [{}] }}",
                entry(h1, u1, "Present")
            ),
            "BoardList { id: 3, total: 2, first: 5, boards: [] }".to_string(),
            "Assigned { id: 10, status: UnknownUid }".to_string(),
            "Assigned { id: 11, status: Reserved }".to_string(),
            "Assigned { id: 12, status: Reserved }".to_string(),
            "Assigned { id: 13, status: Reserved }".to_string(),
            "Assigned { id: 14, status: Reserved }".to_string(),
            "Assigned { id: 15, status: Reserved }".to_string(),
            "Assigned { id: 16, status: Taken }".to_string(),
            "Assigned { id: 17, status: Done }".to_string(),
            "Assigned { id: 18, status: Done }".to_string(),
            "Reply { id: 20, outcome: Ok([]) }".to_string(),
            "Reply { id: 21, outcome: Err(Nack) }".to_string(),
            format!(
                "BoardList {{ id: 22, total: 2, first: 0, boards: [{}, {}] }}",
                entry(0x40, u0, "Present"),
                entry(h1, u1, "Present")
            ),
            "UpdateAnswer { id: 23, status: NoImages }".to_string(),
        ]
    );
    // Ground truth: pnp0 started unaddressed, at its address, then at 0x40; pnp1 never moved;
    // the call to 0x40 drove pnp0's pin and no other board's.
    let starts = |name: &str| -> Vec<u8> {
        o.addresses
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, s)| s.iter().map(|(_, a)| a.get()).collect())
            .unwrap()
    };
    assert_eq!(starts("pnp0"), [0x77, h0, 0x40]);
    assert_eq!(starts("pnp1"), [0x77, h1]);
    // Each start sets the pin low (its safe state); the one high is the laptop's call.
    let highs = |name: &str| {
        o.log
            .of(name, pin)
            .iter()
            .filter(|c| c.change == x10_sim::ports::Change::Digital(Level::High))
            .count()
    };
    assert_eq!((highs("pnp0"), highs("pnp1")), (1, 0));
}

static UPDATE_REC: Recorder<4096> = Recorder::new();

#[test]
fn the_laptop_starts_an_update_that_the_policy_forbids_and_sees_it_through() {
    const OLD: [u8; 3] = [0, 1, 0];
    const NEW: [u8; 3] = [2, 0, 0];
    let fw = SimFirmware::new(OLD);
    let images = carried(BoardKind::SIMULATED, NEW, 8 * 1024);
    let uid = uid_of_name("db20");
    let got: Got = Rc::default();
    let done = Rc::new(Cell::new(false));
    let d = done.clone();
    let updates_before = Rc::new(Cell::new(u32::MAX));
    let before = updates_before.clone();
    let fw_seen = fw.clone();
    let mut sim = Sim::new(SimConfig {
        duration_ms: 20_000,
        plug_and_play: true,
        record_wire: false,
        ..SimConfig::default()
    });
    let ports = sim.ports("db20", 1, 1);
    sim = sim
        .with_board(addr(0x20), ports)
        .with_firmware("db20", fw.clone());
    let o = sim
        .also_observe(&UPDATE_REC)
        .with_task("usb", drainer(&UPDATE_REC, got.clone(), done))
        .with_task(
            "updater",
            task(move |ctx| {
                Box::pin(async move {
                    // The image's updater, with a policy that updates nothing by itself.
                    let cfg = UpdateConfig::for_bus_hz(400_000);
                    run_updates::<NoRom>(ctx.handle(), cfg, images, UpdatePolicy::Never).await;
                })
            }),
        )
        .with_task(
            "laptop",
            task(move |ctx| {
                Box::pin(async move {
                    let x10 = ctx.handle();
                    x10.wait_for_board(BoardQuery::Uid(uid), 1_000_000)
                        .await
                        .unwrap();
                    // A second of `Never`: nothing is updated.
                    ctx.clock.sleep_ns(1_000 * MS).await;
                    before.set(fw_seen.updates());
                    let rec = &UPDATE_REC;
                    let update = |id, uid: Option<x10_microcode::Uid>| ToDevice::Update {
                        id,
                        uid: uid.map(|u| u.0),
                    };
                    serve(rec, x10, WHO, hello()).await;
                    let unknown = x10_microcode::Uid([7; 8]);
                    serve(rec, x10, WHO, update(1, Some(unknown))).await;
                    serve(rec, x10, WHO, update(2, Some(uid))).await;
                    // Taken at the updater's next look: until then, busy.
                    serve(rec, x10, WHO, update(3, None)).await;
                    while x10.updating().is_none() {
                        ctx.clock.sleep_ns(MS).await;
                    }
                    serve(rec, x10, WHO, update(4, Some(uid))).await;
                    serve(rec, x10, WHO, ToDevice::Boards { id: 5, first: 0 }).await;
                    while x10.updating().is_some() {
                        ctx.clock.sleep_ns(10 * MS).await;
                    }
                    serve(rec, x10, WHO, update(6, Some(uid))).await;
                    serve(rec, x10, WHO, update(7, None)).await;
                    serve(rec, x10, WHO, ToDevice::Boards { id: 8, first: 0 }).await;
                    d.set(true);
                })
            }),
        )
        .run()
        .unwrap();
    assert!(o.task_errors.is_empty(), "{:?}", o.task_errors);
    let entry = |firmware: [u8; 3], state: &str| {
        format!(
            "BoardList {{ id: {}, total: 1, first: 0, boards: [BoardEntry {{ address: 32, uid: {}, kind: {}, firmware: {firmware:?}, state: {state} }}] }}",
            if state == "Updating" { 5 } else { 8 },
            uid_text(uid),
            BoardKind::SIMULATED.0
        )
    };
    let mut at = Vec::new();
    let answers: Vec<String> = answers(&got)
        .into_iter()
        .map(|f| match f.split_once(", at_us: ") {
            Some((head, t)) => {
                at.push(t.trim_end_matches(" })").parse::<u64>().unwrap());
                format!("{head} }})")
            }
            None => f,
        })
        .collect();
    assert_eq!(
        answers,
        [
            "Hello(Hello { version: 2, address: 8, board: \"sim\", robot: \"test\" })".to_string(),
            "UpdateAnswer { id: 1, status: UnknownUid }".to_string(),
            "UpdateAnswer { id: 2, status: Started(1) }".to_string(),
            "UpdateAnswer { id: 3, status: Busy(0) }".to_string(),
            "Update(UpdateRec { db: 32, from: [0, 1, 0], to: [2, 0, 0], phase: Started })"
                .to_string(),
            "UpdateAnswer { id: 4, status: Busy(32) }".to_string(),
            entry(OLD, "Updating"),
            "Update(UpdateRec { db: 32, from: [0, 1, 0], to: [2, 0, 0], phase: Done })".to_string(),
            "UpdateAnswer { id: 6, status: UpToDate }".to_string(),
            "UpdateAnswer { id: 7, status: UpToDate }".to_string(),
            entry(NEW, "Present"),
        ]
    );
    // Ground truth: nothing was updated under `Never` before the request; then the board's
    // flash holds the new image, swapped in once.
    assert_eq!(updates_before.get(), 0);
    assert_eq!((fw.version(), fw.updates()), (NEW, 1));
    let [started, ended] = at[..] else {
        panic!("{at:?}")
    };
    println!(
        "an 8 KiB update asked for by the laptop: {:.2} s from its start record to its end",
        (ended - started) as f64 / 1e6
    );
    assert!(ended > started);
}
