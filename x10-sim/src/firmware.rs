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

use embassy_boot::{BlockingFirmwareState, State};
use x10_boot::model::{Flash, SECTOR};
pub use x10_boot::model::{Part, ACTIVE, DFU, ERASE_NS, PROGRAM_NS, STATE};
use x10_boot::StartMode;
use x10_microcode::Version;

/// Sector erase (the Pico's flash).
pub const ERASE: usize = SECTOR;

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

/// A board's flash and what it holds (`x10_boot::model::Flash`, with the Pico flash's times).
/// Cloning shares it (it outlives the board's resets).
#[derive(Clone, Debug)]
pub struct SimFirmware {
    flash: Flash,
    updates: Rc<Cell<u32>>,
}

impl SimFirmware {
    /// A board flashed (by a probe) with a fake image of `version`, 20 000 bytes.
    pub fn new(version: Version) -> SimFirmware {
        SimFirmware {
            flash: Flash::with_active(&fake_image(version, 20_000)),
            updates: Rc::new(Cell::new(0)),
        }
    }

    /// A partition: 0 state, 1 active, 2 DFU.
    pub fn part(&self, which: usize) -> Part {
        self.flash.part(which)
    }

    /// The version the active slot's image reports.
    pub fn version(&self) -> Version {
        [4, 5, 6].map(|i| self.flash.active_byte(i))
    }

    /// Flash time spent so far (ns).
    pub fn busy_ns(&self) -> u64 {
        self.flash.busy_ns()
    }

    /// Swaps that brought in a new image so far.
    pub fn updates(&self) -> u32 {
        self.updates.get()
    }

    /// The bootloader's start: `prepare_boot`, then the mode, and the flash time it took.
    pub fn start(&self) -> (StartMode, u64) {
        let before = self.flash.busy_ns();
        let mut buf = [0u8; 256];
        let state = self
            .flash
            .bootloader()
            .prepare_boot(&mut buf)
            .unwrap_or(State::Boot);
        let spent = self.flash.busy_ns() - before;
        if state == State::Swap && spent > 0 && self.state() == State::Swap {
            self.updates.set(self.updates.get() + 1);
        }
        (x10_boot::start_mode(&state), spent)
    }

    /// The state partition's mark.
    pub fn state(&self) -> State {
        self.flash.state()
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

/// The motherboard's updater as its image runs it (`firmware_mb::update::run_updates::<R>`),
/// but for a test: an `update_pass` over the boards the directory knows, every 100 ms, until
/// `done` says so of the boards or after `passes` passes; `on_result` hears every update's end.
/// `R` as the image's: `WithRom` updates a C011 through ST's ROM bootloader, `NoRom` refuses
/// it. Returns what the updater remembers (its counters).
pub async fn update_until<R: firmware_mb::update::RomMethod>(
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
        firmware_mb::update::update_pass::<R, _>(
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
