//! Firmware over the bus on a faulty bus (issue 25): NACKs, bursts of flipped bits, flipped
//! address bits while the motherboard updates two boards and a robot keeps driving a third.
//! Checked against the simulator's ground truth: what each board's flash really holds, byte for
//! byte, and what the robot's port really was told.

use std::cell::RefCell;
use std::rc::Rc;

use embedded_storage::nor_flash::ReadNorFlash;
use firmware_mb::update::{NoRom, UpdateConfig, UpdatePolicy};
use x10_devices::LinkError;
use x10_microcode::{Address, BoardKind, Level, Op, Pin, Port};
use x10_sim::board::uid_of_name;
use x10_sim::bus::FaultConfig;
use x10_sim::firmware::{carried, update_until, SimFirmware};
use x10_sim::sim::{task, Sim, SimConfig};

const MS: u64 = 1_000_000;
const OLD: [u8; 3] = [0, 1, 0];
const NEW: [u8; 3] = [0, 2, 0];

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

/// The active slot of `fw`, as much of it as `len`.
fn active(fw: &SimFirmware, len: usize) -> Vec<u8> {
    let mut buf = vec![0u8; len];
    fw.part(1).read(0, &mut buf).unwrap();
    buf
}

#[derive(Default)]
struct Seen {
    /// Robot writes to the third board: (level, ended at, result ok).
    writes: Vec<(Level, u64, bool)>,
    /// Calls to the boards under update.
    to_updating: Vec<Result<(), LinkError>>,
    stats: Option<firmware_mb::update::UpdateStats>,
}

fn run(seed: u64) {
    let images = carried(BoardKind::SIMULATED, NEW, 24 * 1024);
    let image = images[0].bytes;
    let fws = [SimFirmware::new(OLD), SimFirmware::new(OLD)];
    let old_image = active(&fws[0], 20_000);
    let config = SimConfig {
        seed,
        duration_ms: 40_000,
        stop_when_tasks_done: true,
        record_wire: false,
        trace_calls: false,
        plug_and_play: true,
        faults: FaultConfig {
            nack_ppm: 10_000,
            corrupt_ppm: 20_000,
            burst_bits: 6,
            address_ppm: 3_000,
            ..FaultConfig::NONE
        },
        ..SimConfig::default()
    };
    let mut sim = Sim::new(config);
    for a in [0x20u8, 0x21, 0x30] {
        let ports = sim.ports(&format!("db{a:02x}"), 1, 1);
        sim = sim.with_board(addr(a), ports);
    }
    sim = sim
        .with_firmware("db20", fws[0].clone())
        .with_firmware("db21", fws[1].clone());
    let seen = Rc::new(RefCell::new(Seen::default()));
    let done = Rc::new(std::cell::Cell::new(false));
    let pinned: &'static [x10_microcode::Uid] = Box::leak(Box::new([uid_of_name("db30")]));
    let (s1, d1) = (seen.clone(), done.clone());
    let sim = sim.with_task(
        "updater",
        task(move |ctx| {
            Box::pin(async move {
                let x10 = ctx.handle();
                ctx.clock.sleep_ns(500 * MS).await;
                let state = update_until::<NoRom>(
                    &x10,
                    &UpdateConfig::DEFAULT,
                    images,
                    UpdatePolicy::Except(pinned),
                    200,
                    |boards| {
                        boards
                            .iter()
                            .filter(|b| b.kind == BoardKind::SIMULATED && b.firmware == NEW)
                            .count()
                            == 2
                    },
                    |b, _, r| {
                        if let Err(e) = r {
                            println!("update of {} failed: {e:?}", b.address.get())
                        }
                    },
                )
                .await;
                s1.borrow_mut().stats = Some(state.stats);
                d1.set(true);
            })
        }),
    );
    let (s2, d2) = (seen.clone(), done.clone());
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
                    let r = x10.call(addr(0x30), Op::DigitalWrite(pin, level)).await;
                    s2.borrow_mut()
                        .writes
                        .push((level, ctx.clock.now_ns(), r.is_ok()));
                    for a in [0x20, 0x21] {
                        let u = x10.call(addr(a), Op::DigitalWrite(pin, level)).await;
                        s2.borrow_mut().to_updating.push(u.map(|_| ()));
                    }
                    ctx.clock.sleep_ns(7 * MS).await;
                }
            })
        }),
    );
    let o = sim.run().unwrap();
    assert!(o.task_errors.is_empty(), "{:?}", o.task_errors);
    assert!(o.bus.injected > 50, "faults were injected: {:?}", o.bus);
    let seen = seen.borrow();
    let stats = seen.stats.expect("the updater ended");
    // Ground truth: each flash holds the new image byte for byte, confirmed; or (an update that
    // failed) still the old one. Never anything else.
    for (name, fw) in ["db20", "db21"].iter().zip(&fws) {
        let now = active(fw, image.len());
        if fw.version() == NEW {
            assert!(
                now == image,
                "{name}: the active slot is not the image sent"
            );
            assert_eq!(fw.state(), embassy_boot::State::Boot, "{name}: confirmed");
        } else {
            assert_eq!(
                &now[..old_image.len()],
                &old_image[..],
                "{name}: old image intact"
            );
        }
    }
    println!(
        "seed {seed}: updated {} of 2 ({:?}); faults injected {}",
        fws.iter().filter(|f| f.version() == NEW).count(),
        stats,
        o.bus.injected
    );
    assert_eq!(stats.done, 2, "{stats:?}");
    // Every write the robot was told `Ok` is what its port held at that moment.
    let pin = Port::actuator(1).unwrap().pin(Pin::A);
    let ok: Vec<_> = seen.writes.iter().filter(|w| w.2).collect();
    assert!(
        ok.len() > seen.writes.len() / 2,
        "{} of {}",
        ok.len(),
        seen.writes.len()
    );
    for (level, at, _) in ok {
        assert_eq!(o.log.level_at("db30", pin, *at), Some(*level), "at {at} ns");
    }
    assert!(seen.to_updating.contains(&Err(LinkError::Updating)));
}

#[test]
fn two_boards_are_updated_exactly_through_a_faulty_bus() {
    let offset: u64 = std::env::var("X10_SEED_OFFSET")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    run(3 + offset);
}
