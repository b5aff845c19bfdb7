//! A simulated board's firmware (issue 25): its flash (embassy-boot's state, active and DFU
//! partitions, in memory, kept across the board's resets), the image the active slot holds,
//! and the bootloader's start.
//!
//! The images are fakes of the right length and CRC: a header (`X10I`, the version) and
//! filler. What runs is the simulator's board model; the image only says which version it
//! reports. The bootloader is the real `x10-boot` session and embassy-boot's `prepare_boot`;
//! every erase and write costs the typical time of the Pico's flash (W25Q16JV datasheet: 45 ms
//! per 4 KiB sector erase, 0.4 ms per 256-byte page program), which the board spends deaf.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use embassy_boot::{BlockingFirmwareState, BootLoader, BootLoaderConfig, State};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use x10_boot::StartMode;
use x10_microcode::Version;

/// Sector erase (the Pico's flash).
pub const ERASE: usize = 4096;
/// The active slot: a DB image's 32 KiB.
pub const ACTIVE: usize = 32 * 1024;
/// The DFU slot: one sector more.
pub const DFU: usize = ACTIVE + ERASE;
/// The state partition.
pub const STATE: usize = ERASE;
/// Time of a sector erase (ns, typical).
pub const ERASE_NS: u64 = 45_000_000;
/// Time of a 256-byte page program (ns, typical).
pub const PROGRAM_NS: u64 = 400_000;

/// A fake image of `len` bytes for `version`.
pub fn fake_image(version: Version, len: usize) -> Vec<u8> {
    let mut v: Vec<u8> = (0..len)
        .map(|i| (i as u8).wrapping_mul(97) ^ version[1])
        .collect();
    if len >= 7 {
        v[..4].copy_from_slice(b"X10I");
        v[4..7].copy_from_slice(&version);
    }
    v
}

/// The flash error (never happens in the simulation).
#[derive(Debug)]
pub struct NoError;

impl NorFlashError for NoError {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::Other
    }
}

/// One partition of a board's flash.
pub struct Part {
    mem: Rc<RefCell<Vec<u8>>>,
    base: usize,
    len: usize,
    busy_ns: Rc<Cell<u64>>,
}

impl ErrorType for Part {
    type Error = NoError;
}

impl ReadNorFlash for Part {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), NoError> {
        let o = self.base + offset as usize;
        bytes.copy_from_slice(&self.mem.borrow()[o..o + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.len
    }
}

impl NorFlash for Part {
    const WRITE_SIZE: usize = 1;
    const ERASE_SIZE: usize = ERASE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), NoError> {
        let (f, t) = (self.base + from as usize, self.base + to as usize);
        self.mem.borrow_mut()[f..t].fill(0xff);
        self.busy_ns
            .set(self.busy_ns.get() + ERASE_NS * ((t - f) / ERASE) as u64);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), NoError> {
        let o = self.base + offset as usize;
        for (m, b) in self.mem.borrow_mut()[o..o + bytes.len()]
            .iter_mut()
            .zip(bytes)
        {
            *m &= *b;
        }
        self.busy_ns
            .set(self.busy_ns.get() + PROGRAM_NS * bytes.len().div_ceil(256) as u64);
        Ok(())
    }
}

/// A board's flash and what it holds. Cloning shares it (it outlives the board's resets).
#[derive(Clone, Debug)]
pub struct SimFirmware {
    mem: Rc<RefCell<Vec<u8>>>,
    busy_ns: Rc<Cell<u64>>,
    updates: Rc<Cell<u32>>,
}

impl SimFirmware {
    /// A board flashed (by a probe) with a fake image of `version`, 20 000 bytes.
    pub fn new(version: Version) -> SimFirmware {
        let mut mem = vec![0xffu8; STATE + ACTIVE + DFU];
        let img = fake_image(version, 20_000);
        mem[STATE..STATE + img.len()].copy_from_slice(&img);
        SimFirmware {
            mem: Rc::new(RefCell::new(mem)),
            busy_ns: Rc::new(Cell::new(0)),
            updates: Rc::new(Cell::new(0)),
        }
    }

    /// A partition: 0 state, 1 active, 2 DFU.
    pub fn part(&self, which: usize) -> Part {
        let (base, len) = match which {
            0 => (0, STATE),
            1 => (STATE, ACTIVE),
            _ => (STATE + ACTIVE, DFU),
        };
        Part {
            mem: self.mem.clone(),
            base,
            len,
            busy_ns: self.busy_ns.clone(),
        }
    }

    /// The version the active slot's image reports.
    pub fn version(&self) -> Version {
        let m = self.mem.borrow();
        [m[STATE + 4], m[STATE + 5], m[STATE + 6]]
    }

    /// Flash time spent so far (ns).
    pub fn busy_ns(&self) -> u64 {
        self.busy_ns.get()
    }

    /// Swaps that brought in a new image so far.
    pub fn updates(&self) -> u32 {
        self.updates.get()
    }

    /// The bootloader's start: `prepare_boot`, then the mode, and the flash time it took.
    pub fn start(&self) -> (StartMode, u64) {
        let before = self.busy_ns.get();
        let mut bl = BootLoader::new(BootLoaderConfig {
            active: self.part(1),
            dfu: self.part(2),
            state: self.part(0),
        });
        let mut buf = [0u8; 256];
        let state = bl.prepare_boot(&mut buf).unwrap_or(State::Boot);
        let spent = self.busy_ns.get() - before;
        if state == State::Swap && spent > 0 && self.state() == State::Swap {
            self.updates.set(self.updates.get() + 1);
        }
        (x10_boot::start_mode(&state), spent)
    }

    /// The state partition's mark.
    pub fn state(&self) -> State {
        let m = self.mem.borrow();
        State::from(&m[0..1])
    }

    /// System 12's hook.
    pub fn enter_update(&self) -> bool {
        let mut aligned = [0u8; 1];
        let mut st = BlockingFirmwareState::new(self.part(0), &mut aligned);
        x10_boot::enter_update(&mut st).is_ok()
    }

    /// System 13's hook.
    pub fn confirm(&self) -> bool {
        let mut aligned = [0u8; 1];
        let mut st = BlockingFirmwareState::new(self.part(0), &mut aligned);
        x10_boot::confirm_firmware(&mut st).is_ok()
    }
}

/// An STM32C011 board's flash and ROM bootloader (issue 25): `x10_stmboot::model::RomModel`,
/// kept across the board's resets. The board runs the image its flash holds (a fake: the
/// version at bytes 4..7, as [`fake_image`] writes it); System 12 jumps into the ROM, which
/// answers AN4221 at 0x64 until `Go`; a power cut with the first word erased starts the ROM
/// again (the C0's empty check). Cloning shares it.
#[derive(Clone)]
pub struct SimRom(pub Rc<RefCell<x10_stmboot::model::RomModel>>);

impl std::fmt::Debug for SimRom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SimRom({:?}, {:?})", self.version(), self.boot())
    }
}

impl SimRom {
    /// A C011 flashed (by a probe) with a fake image of `version`, 20 000 bytes.
    pub fn new(version: Version) -> SimRom {
        let img = fake_image(version, 20_000);
        SimRom(Rc::new(RefCell::new(x10_stmboot::model::RomModel::c011(
            &img,
        ))))
    }

    /// The version the image in flash reports.
    pub fn version(&self) -> Version {
        let m = self.0.borrow();
        let f = m.flash();
        [f[4], f[5], f[6]]
    }

    /// What the chip runs.
    pub fn boot(&self) -> x10_stmboot::model::Boot {
        self.0.borrow().boot()
    }

    /// Whether the flash holds `image` and nothing else.
    pub fn holds(&self, image: &[u8]) -> bool {
        self.0.borrow().holds(image)
    }

    /// Counts of the ROM's bus and flash work so far.
    pub fn stats(&self) -> x10_stmboot::model::Stats {
        self.0.borrow().stats()
    }
}

/// What the motherboard would update in `world`, one line per daughterboard, in words: the
/// decision is `firmware_mb::update::decide`'s, the one the motherboard's updater takes, for
/// each board's kind (as its chip reports it), version ([`crate::world::Board::firmware_version`])
/// and unique ID, with the images the world says the motherboard carries (`[[image]]`) and the
/// boards it pins (`update = false`). `x10 plan` prints it.
pub fn update_plan(world: &crate::world::World) -> Vec<String> {
    use firmware_mb::update::{decide, DbImage, Decision, UpdatePolicy};
    let images: Vec<DbImage> = world
        .images()
        .iter()
        .map(|i| DbImage {
            kind: i.kind.wire_kind(),
            version: i.version,
            // The decision reads kind and version only.
            bytes: &[],
            crc32: 0,
        })
        .collect();
    let boards: Vec<_> = world
        .boards()
        .into_iter()
        .filter(|b| !b.is_internal())
        .collect();
    // `UpdatePolicy::Except` takes a list that lives as long as the motherboard's program.
    let pinned: &'static [x10_microcode::Uid] = Box::leak(
        boards
            .iter()
            .filter(|b| b.is_pinned())
            .map(|b| b.unique_id())
            .collect::<Vec<_>>()
            .into_boxed_slice(),
    );
    let v = |v: Version| format!("{}.{}.{}", v[0], v[1], v[2]);
    let mut out = Vec::new();
    if images.is_empty() {
        out.push(
            "the motherboard carries no daughterboard images: no board is updated".to_string(),
        );
    } else {
        let carried: Vec<String> = world
            .images()
            .iter()
            .map(|i| format!("{} {}", i.kind.label(), v(i.version)))
            .collect();
        out.push(format!(
            "the motherboard carries {} (fakes of the right length and CRC in the simulator)",
            carried.join(", ")
        ));
    }
    for b in &boards {
        let who = match (b.is_unaddressed(), b.alias()) {
            (true, Some(n)) => format!("board \"{n}\" (no address yet)"),
            (false, Some(n)) => format!("board 0x{:02x} \"{n}\"", b.address()),
            _ => format!("board 0x{:02x}", b.address()),
        };
        let kind = b.kind().label();
        let runs = v(b.firmware_version());
        let line = match decide(
            &images,
            UpdatePolicy::Except(pinned),
            b.unique_id(),
            b.wire_kind(),
            b.firmware_version(),
        ) {
            Decision::Update(i) => format!(
                "{who} ({kind}) runs {runs}, the motherboard carries {}: it will be updated",
                v(i.version)
            ),
            Decision::UpToDate(_) => format!("{who} ({kind}) runs {runs}: up to date, not updated"),
            Decision::Pinned => {
                format!("{who} ({kind}) runs {runs}: pinned (update = false), not updated")
            }
            Decision::NoImage => format!(
                "{who} ({kind}) runs {runs}: the motherboard carries no {kind} image, not updated"
            ),
            Decision::Never => format!("{who} ({kind}) runs {runs}: updates are off, not updated"),
        };
        out.push(line);
    }
    out
}

/// A carried image for a simulated motherboard: [`fake_image`] of `len` bytes for `kind` and
/// `version`, with its CRC-32, kept for the rest of the run.
pub fn carried(
    kind: x10_microcode::BoardKind,
    version: Version,
    len: usize,
) -> &'static [firmware_mb::update::DbImage] {
    let bytes: &'static [u8] = Box::leak(fake_image(version, len).into_boxed_slice());
    Box::leak(Box::new([firmware_mb::update::DbImage {
        kind,
        version,
        bytes,
        crc32: x10_microcode::image_crc32(bytes),
    }]))
}

/// The motherboard's updater as its image runs it (`firmware_mb::update::run_updates`), but
/// for a test: an `update_pass` over the boards the directory knows, every 100 ms, until
/// `done` says so of the boards or after `passes` passes; `on_result` hears every update's end.
/// Returns what the updater remembers (its counters).
pub async fn update_until(
    x10: &firmware_mb::X10,
    cfg: &firmware_mb::update::UpdateConfig,
    images: &[firmware_mb::update::DbImage],
    policy: firmware_mb::update::UpdatePolicy,
    passes: usize,
    done: impl Fn(&[firmware_mb::KnownBoard]) -> bool,
    mut on_result: impl FnMut(
        &firmware_mb::KnownBoard,
        &firmware_mb::update::DbImage,
        &Result<(), firmware_mb::update::UpdateError>,
    ),
) -> firmware_mb::update::UpdateState {
    use firmware_mb::update::UpdateLink;
    let mut state = firmware_mb::update::UpdateState::default();
    for _ in 0..passes {
        let mut list = [firmware_mb::KnownBoard::EMPTY; 16];
        let n = x10.boards(&mut list);
        let boards = list.get(..n).unwrap_or(&[]);
        if done(boards) {
            break;
        }
        firmware_mb::update::update_pass(
            x10,
            cfg,
            images,
            policy,
            boards,
            &mut state,
            &mut on_result,
        )
        .await;
        x10.pause(firmware_mb::update::UPDATE_POLL_US).await;
    }
    state
}
