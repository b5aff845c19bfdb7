//! An STM32C011 updated through ST's ROM bootloader in the simulator (issue 25): the real
//! motherboard runtime and its updater (`firmware_mb::update`), a C011 board whose System 12
//! jumps into `x10_stmboot::model::RomModel` (AN4221 at 0x64 on the simulated bus, until
//! `Go`), while a robot task keeps calling another board. The updater's AN4221 transfers go
//! through the motherboard's dispatcher as raw jobs, between the robot's requests.
//!
//! Checked against the ground truth: what the C011's flash holds and runs, its version in
//! `identify`, every robot call's result and the output level it left.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use firmware_mb::update::{
    DbImage, NoRom, RomMethod, UpdateConfig, UpdateError, UpdatePolicy, WithRom,
};
use x10_microcode::{Address, BoardKind, Identity, Level, Op, Pin, Port};
use x10_sim::firmware::{fake_image, update_until, SimRom};
use x10_sim::sim::{task, Sim, SimConfig};
use x10_stmboot::model::Boot;

const MS: u64 = 1_000_000;
const OLD: [u8; 3] = [0, 1, 0];
const NEW: [u8; 3] = [0, 2, 0];

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

struct Outcome {
    /// Every result the updater reported.
    results: Vec<Result<(), UpdateError>>,
    /// Robot calls to the other board (their start, ns): all ok.
    calls: Vec<u64>,
    calls_ok: bool,
    /// The C011's version in `identify` after the updates.
    version_after: Option<[u8; 3]>,
    /// When the updates began and ended (ns).
    window: (u64, u64),
    done: u16,
    failed: u16,
    refused: u16,
}

/// db22 is a C011 running `OLD`, db30 the robot's board; the motherboard carries a C011 image
/// of `NEW` and runs update passes (at most `passes`) until db22 reports `NEW`, its updater
/// with `R`'s way for a C011 (`WithRom`: through its ROM bootloader, as an image that carries
/// a C011 image links; `NoRom`: refused).
fn run<R: RomMethod + 'static>(
    rom: &SimRom,
    image: &'static [u8],
    setup: impl FnOnce(Sim) -> Sim,
    passes: usize,
) -> Outcome {
    let images: &'static [DbImage] = Box::leak(Box::new([DbImage {
        kind: BoardKind::C011,
        version: NEW,
        bytes: image,
        crc32: x10_microcode::image_crc32(image),
    }]));
    let config = SimConfig {
        duration_ms: 60_000,
        stop_when_tasks_done: true,
        record_wire: false,
        trace_calls: false,
        plug_and_play: true,
        ..SimConfig::default()
    };
    let mut sim = Sim::new(config);
    for a in [0x22u8, 0x30] {
        let ports = sim.ports(&format!("db{a:02x}"), 1, 1);
        sim = sim.with_board(addr(a), ports);
    }
    sim = setup(sim.with_rom("db22", rom.clone()));
    let out = Rc::new(RefCell::new(Outcome {
        results: Vec::new(),
        calls: Vec::new(),
        calls_ok: true,
        version_after: None,
        window: (0, 0),
        done: 0,
        failed: 0,
        refused: 0,
    }));
    let finished = Rc::new(Cell::new(false));
    let (o1, f1) = (out.clone(), finished.clone());
    let sim = sim.with_task(
        "updater",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                ctx.clock.sleep_ns(1_000 * MS).await;
                o1.borrow_mut().window.0 = ctx.clock.now_ns();
                let state = update_until::<R>(
                    &x10,
                    &UpdateConfig::for_bus_hz(400_000),
                    images,
                    UpdatePolicy::Auto,
                    passes,
                    |boards| {
                        boards
                            .iter()
                            .any(|b| b.kind == BoardKind::C011 && b.firmware == NEW && b.present)
                    },
                    |_, _, r| o1.borrow_mut().results.push(*r),
                )
                .await;
                let version = x10
                    .call(addr(0x22), Op::Identify)
                    .await
                    .ok()
                    .and_then(|p| Identity::parse(&p).ok())
                    .map(|id| id.firmware);
                let mut o = o1.borrow_mut();
                o.window.1 = ctx.clock.now_ns();
                o.version_after = version;
                o.done = state.stats.done;
                o.failed = state.stats.failed;
                o.refused = state.stats.refused;
                f1.set(true);
            })
        }),
    );
    let (o2, f2) = (out.clone(), finished.clone());
    let last = Rc::new(Cell::new(None));
    let l2 = last.clone();
    let sim = sim.with_task(
        "robot",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                let pin = Port::actuator(1).unwrap().pin(Pin::A);
                let mut level = Level::Low;
                while !f2.get() {
                    level = if level == Level::Low {
                        Level::High
                    } else {
                        Level::Low
                    };
                    let t = ctx.clock.now_ns();
                    let r = x10.call(addr(0x30), Op::DigitalWrite(pin, level)).await;
                    {
                        let mut o = o2.borrow_mut();
                        o.calls.push(t);
                        o.calls_ok &= r.is_ok();
                    }
                    if r.is_ok() {
                        l2.set(Some((ctx.clock.now_ns(), level)));
                    }
                    ctx.clock.sleep_ns(5 * MS).await;
                }
            })
        }),
    );
    let o = sim.run().unwrap();
    // The robot's board holds the last level it commanded.
    let (t, level) = last.get().unwrap();
    let pin = Port::actuator(1).unwrap().pin(Pin::A);
    assert_eq!(o.log.level_at("db30", pin, t), Some(level));
    Rc::try_unwrap(out).ok().unwrap().into_inner()
}

fn new_image() -> &'static [u8] {
    Box::leak(fake_image(NEW, 30_000).into_boxed_slice())
}

#[test]
fn a_c011_is_updated_through_its_rom_while_the_robot_drives_another_board() {
    let rom = SimRom::new(OLD);
    let image = new_image();
    let o = run::<WithRom>(&rom, image, |s| s, 20);
    assert_eq!(o.results, [Ok(())]);
    assert_eq!((o.done, o.failed), (1, 0));
    // Ground truth: the flash holds the new image and nothing else, the chip runs it, and it
    // says so at its address.
    assert!(rom.holds(image));
    assert_eq!(rom.boot(), Boot::Flash);
    assert_eq!(rom.version(), NEW);
    assert_eq!(o.version_after, Some(NEW));
    assert!(o.calls_ok, "a robot call failed");
    // The robot's call rate to the other board: alone (the first second) and during.
    let (start, end) = o.window;
    let before = o.calls.iter().filter(|t| **t < start).count() as f64 / (start as f64 / 1e9);
    let during = o.calls.iter().filter(|t| **t >= start && **t < end).count() as f64
        / ((end - start) as f64 / 1e9);
    println!(
        "C011 30 000 B through the ROM in the simulator at 400 kHz: {:.2} s; robot calls to another board {before:.0}/s without, {during:.0}/s during, all ok; ROM: {} erases, {} double words",
        (end - start) as f64 / 1e9,
        rom.stats().erases,
        rom.stats().programs
    );
    assert!(during > 0.5 * before, "{during} vs {before}");
}

/// The C011 loses power (50 ms) 2 s into its update, after its first page was erased: it
/// comes back in its ROM bootloader at 0x64 (the empty check), the updater's transfer fails,
/// and its next pass finds the board at 0x64 and finishes it.
#[test]
fn a_power_cut_mid_update_is_finished_through_0x64() {
    let rom = SimRom::new(OLD);
    let image = new_image();
    let o = run::<WithRom>(&rom, image, |s| s.reset_at("db22", 3_000, 50), 40);
    assert_eq!(o.results.len(), 1, "{:?}", o.results);
    assert!(o.results[0].is_err());
    // The failed try, then the rescue through 0x64.
    assert_eq!((o.done, o.failed), (1, 1));
    assert!(rom.holds(image));
    assert_eq!(rom.boot(), Boot::Flash);
    assert_eq!(o.version_after, Some(NEW));
    assert!(o.calls_ok, "a robot call failed");
}

/// A chip whose product ID is not the C011's is refused before any erase, reported, sent
/// back to its image, and tried twice (`UpdateConfig::tries`), not for ever.
#[test]
fn a_refused_chip_id_is_reported_and_tried_no_more() {
    let rom = SimRom::new(OLD);
    rom.0.borrow_mut().pid = 0x466;
    let image = new_image();
    let o = run::<WithRom>(&rom, image, |s| s, 10);
    let wrong = Err(UpdateError::Rom(x10_stmboot::Error::WrongChip {
        pid: 0x466,
    }));
    assert_eq!(o.results, [wrong, wrong]);
    assert_eq!((o.done, o.failed), (0, 2));
    assert_eq!(rom.stats().erases, 0);
    assert_eq!(rom.boot(), Boot::Flash);
    assert_eq!(o.version_after, Some(OLD));
    assert!(o.calls_ok, "a robot call failed");
}

/// An updater without the ROM method (`NoRom`, what an image that carries no C011 image links)
/// given a C011 image all the same: the C011 is refused with `NoMethod`, once in ten passes,
/// and nothing reaches it (no ROM transaction, nothing erased); it keeps running `OLD`.
#[test]
fn without_the_rom_method_a_c011_is_refused_once_and_left_alone() {
    let rom = SimRom::new(OLD);
    let image = new_image();
    let o = run::<NoRom>(&rom, image, |s| s, 10);
    assert_eq!(o.results, [Err(UpdateError::NoMethod)]);
    assert_eq!((o.done, o.failed, o.refused), (0, 0, 1));
    let stats = rom.stats();
    assert_eq!(
        (stats.transactions, stats.erases, stats.programs),
        (0, 0, 0)
    );
    assert_eq!(rom.boot(), Boot::Flash);
    assert_eq!(rom.version(), OLD);
    assert_eq!(o.version_after, Some(OLD));
    assert!(o.calls_ok, "a robot call failed");
}
