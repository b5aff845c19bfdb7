//! Firmware over the bus in the simulator (issue 25): boards with a flash of A/B slots and the
//! real bootloader session (x10-boot, embassy-boot's swap), a motherboard carrying a newer
//! image (a fake of the right length and CRC: `x10_sim::firmware::fake_image`) and updating
//! them with its updater (`firmware_mb::update`), while a robot task keeps calling another
//! board. Checked against the simulator's ground truth: the version each board's flash holds
//! and reports, the output levels the robot commanded, every call's result.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use firmware_mb::update::{NoRom, UpdateConfig, UpdatePolicy};
use x10_devices::LinkError;
use x10_microcode::{Address, BoardKind, Level, Op, Pin, Port};
use x10_sim::board::uid_of_name;
use x10_sim::firmware::{carried, update_until, SimFirmware};
use x10_sim::sim::{task, Sim, SimConfig};

const MS: u64 = 1_000_000;
const OLD: [u8; 3] = [0, 1, 0];
const NEW: [u8; 3] = [0, 2, 0];

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

struct Run {
    /// Robot calls to the other board: (start ns, result ok).
    calls: Vec<(u64, bool)>,
    /// Calls to a board being updated, by outcome.
    to_updating: Vec<Result<(), LinkError>>,
    /// When the updates began and ended (ns).
    window: (u64, u64),
    last_level: Option<(u64, Level)>,
    /// Requests of the transfers sent again (they met a busy or reset board).
    retries: u32,
}

#[test]
fn the_motherboard_updates_two_boards_while_the_robot_drives_a_third() {
    let (restarts, retries) = updates(|sim| sim);
    assert_eq!(restarts, 0);
    // The updater waits out each sector erase: no request meets a busy board.
    assert_eq!(retries, 0);
}

/// Power cuts (board resets) in the middle of each board's transfer: the board comes back in
/// its bootloader, the motherboard begins its transfer again and finishes.
#[test]
fn power_cuts_mid_update_are_recovered() {
    let (restarts, _) = updates(|sim| sim.reset_at("db20", 3_000, 50).reset_at("db21", 7_000, 50));
    assert_eq!(restarts, 2);
}

/// Runs the scenario with `setup` applied to the simulation; returns the transfers the
/// updater began again.
fn updates(setup: impl FnOnce(Sim) -> Sim) -> (u16, u32) {
    let fw20 = SimFirmware::new(OLD);
    let fw21 = SimFirmware::new(OLD);
    let images = carried(BoardKind::SIMULATED, NEW, 32 * 1024);
    let config = SimConfig {
        duration_ms: 30_000,
        stop_when_tasks_done: true,
        record_wire: false,
        trace_calls: false,
        plug_and_play: true,
        ..SimConfig::default()
    };
    let mut sim = Sim::new(config);
    for a in [0x20u8, 0x21, 0x30] {
        let ports = sim.ports(&format!("db{a:02x}"), 1, 1);
        sim = sim.with_board(addr(a), ports);
    }
    sim = setup(
        sim.with_firmware("db20", fw20.clone())
            .with_firmware("db21", fw21.clone()),
    );
    let restarts = Rc::new(Cell::new(0u16));
    let r0 = restarts.clone();
    let run = Rc::new(RefCell::new(Run {
        calls: Vec::new(),
        to_updating: Vec::new(),
        window: (0, 0),
        last_level: None,
        retries: 0,
    }));
    let updating_done = Rc::new(Cell::new(false));
    let pinned: &'static [x10_microcode::Uid] = Box::leak(Box::new([uid_of_name("db30")]));
    let (r1, d1) = (run.clone(), updating_done.clone());
    let sim = sim.with_task(
        "updater",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                // The robot runs alone for 2 s first (the rate without an update).
                ctx.clock.sleep_ns(2_000 * MS).await;
                r1.borrow_mut().window.0 = ctx.clock.now_ns();
                // The gap between chunks scaled to the bus clock (400 kHz), the flash work
                // waited out.
                let cfg = UpdateConfig::for_bus_hz(400_000);
                let state = update_until::<NoRom>(
                    &x10,
                    &cfg,
                    images,
                    // db30 runs the robot's outputs and has no bootloader: pinned.
                    UpdatePolicy::Except(pinned),
                    usize::MAX,
                    |boards| {
                        boards
                            .iter()
                            .filter(|b| b.kind == BoardKind::SIMULATED && b.firmware == NEW)
                            .count()
                            == 2
                    },
                    |b, _, r| assert_eq!(*r, Ok(()), "board {}", b.address.get()),
                )
                .await;
                assert!(state.stats.failed == 0, "{:?}", state.stats);
                r1.borrow_mut().window.1 = ctx.clock.now_ns();
                assert_eq!(state.stats.done, 2);
                r0.set(state.stats.restarts);
                r1.borrow_mut().retries = state.stats.chunk_retries;
                d1.set(true);
            })
        }),
    );
    let (r2, d2) = (run.clone(), updating_done.clone());
    let sim = sim.with_task(
        "robot",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                let pin = Port::actuator(1).unwrap().pin(Pin::A);
                let mut level = Level::Low;
                while !d2.get() {
                    level = if level == Level::Low {
                        Level::High
                    } else {
                        Level::Low
                    };
                    let t = ctx.clock.now_ns();
                    let r = x10.call(addr(0x30), Op::DigitalWrite(pin, level)).await;
                    r2.borrow_mut().calls.push((t, r.is_ok()));
                    if r.is_ok() {
                        r2.borrow_mut().last_level = Some((ctx.clock.now_ns(), level));
                    }
                    // A call to a board under update: refused at once, or served.
                    let u = x10.call(addr(0x20), Op::DigitalWrite(pin, level)).await;
                    r2.borrow_mut().to_updating.push(u.map(|_| ()));
                    ctx.clock.sleep_ns(5 * MS).await;
                }
                // One more after the end: both updated boards answer again.
                for a in [0x20, 0x21] {
                    x10.call(addr(a), Op::DigitalWrite(pin, Level::High))
                        .await
                        .unwrap();
                }
            })
        }),
    );
    let o = sim.run().unwrap();
    let run = run.borrow();
    // Ground truth: both flashes hold the new image, swapped in once, confirmed.
    for fw in [&fw20, &fw21] {
        assert_eq!(fw.version(), NEW);
        assert_eq!(fw.updates(), 1);
        assert_eq!(fw.state(), embassy_boot::State::Boot);
    }
    // Every robot call to the third board succeeded, and its pin holds the last level.
    assert!(run.calls.iter().all(|(_, ok)| *ok), "a call failed");
    let (t, level) = run.last_level.unwrap();
    let pin = Port::actuator(1).unwrap().pin(Pin::A);
    assert_eq!(o.log.level_at("db30", pin, t), Some(level));
    // Calls to the board under update: `Ok` or `Updating`, never anything else, never a hang.
    assert!(run
        .to_updating
        .iter()
        .all(|r| matches!(r, Ok(()) | Err(LinkError::Updating))));
    assert!(run.to_updating.contains(&Err(LinkError::Updating)));
    // The rate of the robot's calls without and during the updates.
    let (start, end) = run.window;
    let before = run.calls.iter().filter(|(t, _)| *t < start).count();
    let during = run
        .calls
        .iter()
        .filter(|(t, _)| *t >= start && *t < end)
        .count();
    let rate_before = before as f64 / (start as f64 / 1e9);
    let rate_during = during as f64 / ((end - start) as f64 / 1e9);
    println!(
        "two 32 KiB updates at 400 kHz: {:.2} s; robot calls to a third board: {:.0}/s without, {:.0}/s during; requests sent again: {}",
        (end - start) as f64 / 1e9,
        rate_before,
        rate_during,
        run.retries
    );
    assert!(
        rate_during > 0.5 * rate_before,
        "{rate_during} vs {rate_before}"
    );
    (restarts.get(), run.retries)
}
