//! The motherboard's updater takes an STM32C011 through ST's ROM bootloader (issue 25): the
//! board's application (System 12 jumps into the ROM, `identify` answers the version its
//! flash holds) and `x10_stmboot::model::RomModel` (AN4221 at 0x64, the C011's flash and
//! boot, power cuts) behind the updater's `UpdateLink`, whose raw I2C transfers carry at most
//! what the motherboard's dispatcher carries (a 36-byte frame out, 28 bytes in). Time is the
//! model's: wire time at the bus clock, the flash's typical times, the updater's pauses.
//!
//! Checked against the model's ground truth (its flash, what it boots): an update end to end,
//! a power cut at every 97th step of it recovered through 0x64 (the board found there at
//! start-up), a refused chip ID reported and not tried for ever (the old image runs again),
//! and an updater without the ROM method (`NoRom`) refusing a C011 once, sending it nothing.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use firmware_mb::update::{
    rescue_rom, update_board, update_pass, DbImage, Method, NoRom, RomMethod, UpdateConfig,
    UpdateError, UpdateLink, UpdatePolicy, UpdateState, UpdateStats, WithRom,
};
use firmware_mb::KnownBoard;
use x10_devices::LinkError;
use x10_microcode::{
    Address, BoardKind, Capabilities, Identity, Op, Payload, Uid, Version, MAX_FRAME_LEN,
    MAX_PAYLOAD, PROTOCOL_VERSION,
};
use x10_stmboot::model::{Boot, ModelError, RomModel};

const OLD: Version = [0, 1, 0];
const NEW: Version = [0, 2, 0];
const DB: u8 = 0x2c;

/// An image: a vector table's first double word that is not erased, the version at 4..7
/// (where the model's application reads it), filler.
fn image(len: usize, version: Version, seed: u8) -> &'static [u8] {
    let mut v: Vec<u8> = (0..len)
        .map(|i| (i as u8).wrapping_mul(29) ^ seed)
        .collect();
    v[..4].copy_from_slice(&[0x00, 0x30, 0x00, 0x20]);
    v[4..7].copy_from_slice(&version);
    Box::leak(v.into_boxed_slice())
}

fn db_image(bytes: &'static [u8]) -> DbImage {
    DbImage {
        kind: BoardKind::C011,
        version: [bytes[4], bytes[5], bytes[6]],
        bytes,
        crc32: x10_microcode::image_crc32(bytes),
    }
}

/// One C011 on the motherboard's bus.
struct RomLink {
    model: Rc<RefCell<RomModel>>,
    updating: Cell<Option<Address>>,
    /// Raw transfers, and the largest write and read among them.
    raw: Cell<(u32, usize, usize)>,
}

impl RomLink {
    fn new(model: RomModel) -> RomLink {
        RomLink {
            model: Rc::new(RefCell::new(model)),
            updating: Cell::new(None),
            raw: Cell::new((0, 0, 0)),
        }
    }

    fn version(&self) -> Version {
        let m = self.model.borrow();
        [m.flash()[4], m.flash()[5], m.flash()[6]]
    }
}

impl UpdateLink for RomLink {
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        assert_eq!(db.get(), DB);
        // A short request and its reply on the wire (about 12 bytes at the model's clock).
        let mut m = self.model.borrow_mut();
        let ns = 12 * 9 * 1_000_000_000 / u64::from(m.bus_hz);
        m.advance_ns(ns);
        if m.boot() != Boot::Flash {
            return Err(LinkError::Nack);
        }
        match op {
            Op::EnterUpdate => {
                m.enter_rom();
                Ok(Payload::new())
            }
            Op::Identify => {
                drop(m);
                let id = Identity {
                    protocol_version: PROTOCOL_VERSION,
                    firmware: self.version(),
                    board: BoardKind::C011,
                    sensor_ports: 2,
                    actuator_ports: 2,
                    capabilities: Capabilities(0),
                    adc_bits: 12,
                };
                Ok(Payload::from_slice(&id.to_bytes()).unwrap())
            }
            _ => Ok(Payload::new()),
        }
    }

    fn set_updating(&self, db: Option<Address>) {
        self.updating.set(db);
    }

    async fn pause(&self, us: u64) {
        self.model.borrow_mut().advance_ns(us * 1_000);
    }

    fn now_us(&self) -> u64 {
        self.model.borrow().now_ns() / 1_000
    }

    async fn i2c(&self, addr: u8, write: &[u8], read: &mut [u8]) -> Result<(), LinkError> {
        // What the motherboard's dispatcher carries.
        assert!(write.len() <= MAX_FRAME_LEN, "{} bytes out", write.len());
        assert!(read.len() <= MAX_PAYLOAD, "{} bytes in", read.len());
        let (n, w, r) = self.raw.get();
        self.raw.set((n + 1, w.max(write.len()), r.max(read.len())));
        if addr != Address::STM32_BOOTLOADER {
            return Err(LinkError::Nack);
        }
        let mut m = self.model.borrow_mut();
        let err = |e: ModelError| match e {
            ModelError::NoAck => LinkError::Nack,
            ModelError::Protocol => LinkError::Bus,
        };
        if !write.is_empty() || read.is_empty() {
            m.write(write).map_err(err)?;
        }
        if !read.is_empty() {
            m.read(read).map_err(err)?;
        }
        Ok(())
    }
}

fn run<F: core::future::Future>(f: F) -> F::Output {
    embassy_futures::block_on(f)
}

fn board(kind: BoardKind, firmware: Version) -> KnownBoard {
    let mut b = KnownBoard::EMPTY;
    b.uid = Uid([0xc0, 0x11, 0, 0, 0, 0, 0, 1]);
    b.address = Address::new(DB).unwrap();
    b.kind = kind;
    b.firmware = firmware;
    b.present = true;
    b
}

fn cfg() -> UpdateConfig {
    UpdateConfig::for_bus_hz(400_000)
}

#[test]
fn a_c011_is_updated_through_its_rom_bootloader() {
    let old = image(20_000, OLD, 1);
    let new = db_image(image(30_000, NEW, 2));
    let mut model = RomModel::c011(old);
    model.bus_hz = 400_000;
    let link = RomLink::new(model);
    let mut stats = UpdateStats::default();
    let r = run(update_board::<WithRom, _>(
        &link,
        &cfg(),
        Address::new(DB).unwrap(),
        BoardKind::C011,
        &new,
        &mut stats,
    ));
    assert_eq!(r, Ok(()));
    // Ground truth: the flash holds the new image and nothing else, the chip runs it.
    let m = link.model.borrow();
    assert!(m.holds(new.bytes));
    assert_eq!(m.boot(), Boot::Flash);
    assert_eq!(link.version(), NEW);
    assert_eq!((stats.done, stats.failed), (1, 0));
    assert_eq!(link.updating.get(), None);
    // Every raw transfer fit the dispatcher's: the longest out is the erase of pages 1 to 15
    // (two bytes a page and the XOR: 31), the longest in a 24-byte block read back.
    let (n, w, r) = link.raw.get();
    assert_eq!((w, r), (31, 24));
    println!(
        "C011 30 000 B through the ROM at 400 kHz, 24-byte blocks: {:.2} s, {n} raw transfers, {} erases, {} double words",
        m.now_ns() as f64 / 1e9,
        m.stats().erases,
        m.stats().programs
    );
}

/// The power goes at every 97th step of an update (a bus transaction, a page erase, a
/// double-word program). When it comes back the board runs the old image (cut before page
/// 0's erase), the new one (cut after its first double word), or its ROM bootloader (the
/// first word erased): then the motherboard finds it at 0x64 at start-up and finishes it.
#[test]
fn a_power_cut_at_any_step_is_recovered_through_0x64() {
    let old = image(4_000, OLD, 1);
    let new = db_image(image(5_000, NEW, 2));
    let total = {
        let link = RomLink::new(RomModel::c011(old));
        let mut stats = UpdateStats::default();
        let db = Address::new(DB).unwrap();
        run(update_board::<WithRom, _>(
            &link,
            &cfg(),
            db,
            BoardKind::C011,
            &new,
            &mut stats,
        ))
        .unwrap();
        let steps = link.model.borrow().steps();
        steps
    };
    let (mut old_runs, mut rescued) = (0, 0);
    for cut in (0..total).step_by(97) {
        let link = RomLink::new(RomModel::c011(old));
        link.model.borrow_mut().cut_at(cut);
        let mut stats = UpdateStats::default();
        let db = Address::new(DB).unwrap();
        let r = run(update_board::<WithRom, _>(
            &link,
            &cfg(),
            db,
            BoardKind::C011,
            &new,
            &mut stats,
        ));
        assert!(r.is_err(), "cut at step {cut}");
        let boot = link.model.borrow_mut().power_on();
        match boot {
            Boot::Flash => {
                // Whole: the old image or the new one, nothing between.
                let v = link.version();
                let m = link.model.borrow();
                assert!(
                    (v == OLD && m.flash()[..4000] == old[..]) || m.holds(new.bytes),
                    "cut at step {cut}: {v:?}"
                );
                old_runs += usize::from(v == OLD);
            }
            Boot::Rom => {
                // The motherboard starts: its first pass looks at 0x64 first.
                let mut state = UpdateState::default();
                let n = run(update_pass::<WithRom, _>(
                    &link,
                    &cfg(),
                    core::slice::from_ref(&new),
                    UpdatePolicy::Auto,
                    &[],
                    &mut state,
                    |_, _, _| {},
                ));
                assert_eq!(n, 1, "cut at step {cut}");
                assert_eq!((state.stats.done, state.stats.failed), (1, 0));
                let m = link.model.borrow();
                assert!(m.holds(new.bytes), "cut at step {cut}");
                assert_eq!(m.boot(), Boot::Flash);
                rescued += 1;
            }
            Boot::Off => unreachable!(),
        }
    }
    println!(
        "{total} steps; cut at every 97th: old image {old_runs}, finished through 0x64 {rescued}"
    );
    assert!(old_runs > 0 && rescued > 10, "{old_runs} {rescued}");
}

/// A chip that answers another product ID is refused before any erase, reported, sent back
/// to its image (Go), and tried no more than `UpdateConfig::tries` times.
#[test]
fn a_refused_chip_id_is_reported_not_retried_for_ever() {
    let old = image(4_000, OLD, 1);
    let new = db_image(image(5_000, NEW, 2));
    let mut model = RomModel::c011(old);
    model.pid = 0x466;
    let link = RomLink::new(model);
    let mut state = UpdateState::default();
    let mut results = Vec::new();
    let boards = [board(BoardKind::C011, OLD)];
    for _ in 0..5 {
        run(update_pass::<WithRom, _>(
            &link,
            &cfg(),
            core::slice::from_ref(&new),
            UpdatePolicy::Auto,
            &boards,
            &mut state,
            |_, _, r| results.push(*r),
        ));
    }
    let wrong = Err(UpdateError::Rom(x10_stmboot::Error::WrongChip {
        pid: 0x466,
    }));
    assert_eq!(results, [wrong, wrong]);
    assert_eq!((state.stats.done, state.stats.failed), (0, 2));
    assert_eq!(state.tries(boards[0].uid), 2);
    // Nothing was erased; the old image runs again.
    let m = link.model.borrow();
    assert_eq!(m.stats().erases, 0);
    assert_eq!(m.boot(), Boot::Flash);
    assert_eq!(link.version(), OLD);
    drop(m);
    // Nobody at 0x64 now.
    let mut stats = UpdateStats::default();
    assert_eq!(
        run(rescue_rom(
            &link,
            &cfg(),
            core::slice::from_ref(&new),
            &mut stats
        )),
        None
    );
}

/// `NoRom` (a motherboard image that carries no C011 image): the C011 has no method
/// (`method_for`), and an updater given a C011 image all the same refuses the board with
/// `NoMethod` once in five passes (its tries used up, counted as refused, neither done nor
/// failed), tries none, and sends nothing: no call, no raw transfer (the model's clock, which
/// every request advances, stays at 0), nothing erased; a board at 0x64 is not looked for.
#[test]
fn without_the_rom_method_a_c011_is_refused_once_and_sent_nothing() {
    assert_eq!(NoRom::method_for(BoardKind::C011), Method::None);
    assert_eq!(WithRom::method_for(BoardKind::C011), Method::StRom);
    for kind in [BoardKind::SIMULATED, BoardKind::PICO, BoardKind::G431] {
        assert_eq!(NoRom::method_for(kind), Method::X10Boot);
        assert_eq!(WithRom::method_for(kind), Method::X10Boot);
    }
    let old = image(4_000, OLD, 1);
    let new = db_image(image(5_000, NEW, 2));
    let link = RomLink::new(RomModel::c011(old));
    let mut state = UpdateState::default();
    let mut results = Vec::new();
    let boards = [board(BoardKind::C011, OLD)];
    for _ in 0..5 {
        let n = run(update_pass::<NoRom, _>(
            &link,
            &cfg(),
            core::slice::from_ref(&new),
            UpdatePolicy::Auto,
            &boards,
            &mut state,
            |b, i, r| results.push((b.uid, i.version, *r)),
        ));
        assert_eq!(n, 0);
    }
    assert_eq!(results, [(boards[0].uid, NEW, Err(UpdateError::NoMethod))]);
    assert_eq!(
        state.stats,
        UpdateStats {
            refused: 1,
            ..UpdateStats::default()
        }
    );
    assert_eq!(state.tries(boards[0].uid), cfg().tries);
    // update_board alone: the same refusal, before the board is marked as updating.
    let mut stats = UpdateStats::default();
    let r = run(update_board::<NoRom, _>(
        &link,
        &cfg(),
        Address::new(DB).unwrap(),
        BoardKind::C011,
        &new,
        &mut stats,
    ));
    assert_eq!(r, Err(UpdateError::NoMethod));
    assert_eq!(stats, UpdateStats::default());
    assert_eq!(link.updating.get(), None);
    assert_eq!(link.raw.get(), (0, 0, 0));
    let m = link.model.borrow();
    assert_eq!(m.now_ns(), 0);
    assert_eq!(m.stats().transactions, 0);
    assert_eq!(m.stats().erases, 0);
    assert_eq!(m.boot(), Boot::Flash);
    drop(m);
    assert_eq!(link.version(), OLD);

    // A C011 left in its ROM bootloader (at 0x64) is not looked for: WithRom finishes it.
    let cut = RomLink::new(RomModel::c011(old));
    cut.model.borrow_mut().enter_rom();
    let images = core::slice::from_ref(&new);
    let mut state = UpdateState::default();
    let n = run(update_pass::<NoRom, _>(
        &cut,
        &cfg(),
        images,
        UpdatePolicy::Auto,
        &[],
        &mut state,
        |_, _, _| {},
    ));
    assert_eq!((n, cut.raw.get().0), (0, 0));
    let mut state = UpdateState::default();
    let n = run(update_pass::<WithRom, _>(
        &cut,
        &cfg(),
        images,
        UpdatePolicy::Auto,
        &[],
        &mut state,
        |_, _, _| {},
    ));
    assert_eq!((n, state.stats.done), (1, 1));
    assert!(cut.model.borrow().holds(new.bytes));
}
