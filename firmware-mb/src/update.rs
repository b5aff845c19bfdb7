//! Firmware over the bus on the motherboard (issue 25): an MB image carries the daughterboards'
//! images ([`DbImage`]) and brings every board of a carried kind to the carried version
//! (`docs/protocol.md`, "Firmware over the bus").
//!
//! [`run_updates`] is a task of its own, started by an image (or the simulator) that carries
//! images: an MB image that carries none does not link it. It looks at the boards the
//! directory knows (their `boot`, `announce` and `identify` give kind and version) at start and
//! every [`UPDATE_POLL_US`], and updates a board of a carried kind that runs another version,
//! one board at a time, as [`update_board`] says. Every request goes through the normal
//! request queue, one at a time, so the robot's calls to the other boards interleave; between
//! two chunks the updater leaves the bus alone for [`UpdateConfig::chunk_gap_us`], which bounds
//! its share of the bus. While a board is updated, the robot's calls to it end at once in
//! `LinkError::Updating`, never a hang.
//!
//! A C011 board has no room for a bootloader of ours: its method is ST's ROM bootloader over
//! I2C (AN4221, the `x10-stmboot` crate). `enter_update` sends the board into its ROM, which
//! answers at `Address::STM32_BOOTLOADER` (0x64); the updater speaks AN4221 there through the
//! motherboard's own bus ([`UpdateLink::i2c`]: raw transfers through the dispatcher's queue,
//! between the robot's requests, outside the robot's API), one C011 at a time, then waits for
//! the board at its address with the new version (it keeps its address in its OTP area, which
//! no page erase touches). A C011 found answering at 0x64 ([`rescue_rom`]: an update cut by
//! power) is updated first.

use x10_devices::LinkError;
use x10_microcode::{
    Address, BoardKind, Identity, ImageInfo, Op, Status, Uid, UpdateOp, UpdateReport, Version,
    CHUNK_MAX, MAX_REQUEST_DATA,
};

/// An image of a daughterboard's firmware, as an MB image carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DbImage {
    /// The board kind it is built for.
    pub kind: BoardKind,
    /// Its firmware version (what the board reports once it runs it).
    pub version: Version,
    /// The image, as it goes into the board's slot.
    pub bytes: &'static [u8],
    /// CRC-32/ISO-HDLC of `bytes` (`x10_microcode::image_crc32`, computed at build time).
    pub crc32: u32,
}

impl DbImage {
    /// What `begin` announces.
    pub fn info(&self) -> ImageInfo {
        ImageInfo {
            len: self.bytes.len() as u32,
            crc32: self.crc32,
            board: self.kind,
            version: self.version,
        }
    }
}

/// Which boards the motherboard updates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdatePolicy {
    /// Every board of a carried kind that runs another version (the default).
    Auto,
    /// None.
    Never,
    /// Every board but these (pinned to the firmware they run).
    Except(&'static [Uid]),
}

/// How a board kind is updated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Method {
    /// `enter_update`, then function 7 answered by the board's bootloader (`x10-boot`):
    /// RP2040 and STM32G431 boards, and the simulator's.
    X10Boot,
    /// ST's ROM bootloader over I2C (AN4221, `x10-stmboot`): the STM32C011, whose 32 KiB
    /// hold one image.
    StRom,
    /// No known way.
    None,
}

impl Method {
    /// The method for a board kind.
    pub const fn for_kind(kind: BoardKind) -> Method {
        match kind.0 {
            1 | 3 | 4 => Method::X10Boot,
            5 => Method::StRom,
            _ => Method::None,
        }
    }
}

/// Timing of the updater.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UpdateConfig {
    /// The bus is left alone this long after each chunk's reply (µs): the robot's requests
    /// queued meanwhile go first. [`UpdateConfig::for_bus_hz`] makes it one chunk
    /// transaction's wire time, which caps the update at half of the bus.
    pub chunk_gap_us: u64,
    /// How often a board is asked whether it is back (its bootloader, its new image), µs.
    pub poll_us: u64,
    /// How long a board may take to come back in its bootloader, µs.
    pub bootloader_wait_us: u64,
    /// How long it may take to come back with the new image (the swap of two 32 KiB slots on
    /// an RP2040 takes about 0.8 s), µs.
    pub boot_wait_us: u64,
    /// Tries per board; a board that failed this often (e.g. rolled back each time) is left
    /// alone until the motherboard restarts.
    pub tries: u8,
    /// Tries of one request of the transfer after a transport error (a lost reply: the
    /// repeat is idempotent; a board whose flash work took longer than [`FlashTiming`] says).
    pub chunk_retries: u8,
    /// Waits out the flash work the board's kind is known to do after `begin` and a chunk
    /// ([`FlashTiming`]) instead of sending into it (true; false: only the gap).
    pub wait_flash: bool,
}

/// Bits on the wire of one chunk transaction: START, the address byte, the 34-byte request
/// (4 header, 28 data, the CRC-16), repeated START, the address byte, the 4-byte reply
/// (3 header, the PEC byte), STOP; 9 bits a byte and 3 for the START, repeated START and
/// STOP.
pub const CHUNK_WIRE_BITS: u64 = (1 + 34 + 1 + 4) * 9 + 3;

impl UpdateConfig {
    /// 1 ms between chunks (the gap [`UpdateConfig::for_bus_hz`] gives at 363 kHz), polls
    /// every 20 ms, 2 s for the bootloader, 5 s for the new image, 2 tries per board, 5 per
    /// chunk, the flash work waited out.
    pub const DEFAULT: UpdateConfig = UpdateConfig {
        chunk_gap_us: 1_000,
        poll_us: 20_000,
        bootloader_wait_us: 2_000_000,
        boot_wait_us: 5_000_000,
        tries: 2,
        chunk_retries: 5,
        wait_flash: true,
    };

    /// [`UpdateConfig::DEFAULT`] with the gap between chunks scaled to the bus clock `hz`:
    /// the wire time of one chunk transaction ([`CHUNK_WIRE_BITS`]), rounded up, so that the
    /// update takes at most half of the bus whatever its clock (3.63 ms at 100 kHz, 0.91 ms
    /// at 400 kHz, 0.37 ms at 1 MHz). An MB image passes the clock its bus runs at.
    pub const fn for_bus_hz(hz: u32) -> UpdateConfig {
        let hz = if hz == 0 { 1 } else { hz as u64 };
        let mut c = Self::DEFAULT;
        c.chunk_gap_us = (CHUNK_WIRE_BITS * 1_000_000).div_ceil(hz);
        c
    }
}

/// What the motherboard knows of a board kind's flash as its bootloader works it, so that it
/// waits the flash work out instead of sending into it: a board erasing or programming its
/// flash does not answer (the RP2040 runs from that flash: XIP is off, its I2C target deaf),
/// and a request sent then is lost and tried again ([`UpdateStats::chunk_retries`]).
///
/// The bootloader (`x10-boot`) erases a sector after `begin` (the first) and after the chunk
/// that fills the last page of a sector (the next one), and programs a page after the chunk
/// that fills it ([`FlashTiming::work_after_chunk_us`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlashTiming {
    /// Bytes of one erase sector.
    pub sector: u32,
    /// Time of one sector erase, µs, with a margin.
    pub erase_us: u32,
    /// Time of one page program (the bootloader's write buffer), µs, with a margin.
    pub program_us: u32,
}

impl FlashTiming {
    /// The flash of a board kind: the RP2040's W25Q16JV (and the simulator's board, which
    /// models it): 4 KiB sectors, 45 ms per erase and 0.4 ms per 256-byte page (typical,
    /// W25Q16JV datasheet, "AC Electrical Characteristics": tSE, tPP), plus 1 ms and 0.1 ms.
    /// Other kinds: `None` (no planned waits: a request that meets a busy board is tried
    /// again).
    pub const fn for_kind(kind: BoardKind) -> Option<FlashTiming> {
        match kind.0 {
            1 | 3 => Some(FlashTiming {
                sector: 4096,
                erase_us: 46_000,
                program_us: 500,
            }),
            _ => None,
        }
    }

    /// How long the board works its flash after answering the chunk of `len` bytes at
    /// `offset` of an image of `image_len` bytes, µs: a page program at most, and the erase of
    /// the next sector when the chunk ends in another sector than it began (and the image
    /// goes on).
    pub const fn work_after_chunk_us(&self, offset: u32, len: u32, image_len: u32) -> u32 {
        let end = offset.saturating_add(len);
        let sector = if self.sector == 0 { 1 } else { self.sector };
        let next = end / sector * sector;
        if next > offset && next < image_len {
            self.erase_us + self.program_us
        } else {
            self.program_us
        }
    }
}

impl Default for UpdateConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why an update failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdateError {
    /// The board's kind has no update method here ([`Method`]).
    NoMethod,
    /// `enter_update` refused (`unsupported`: no bootloader) or failed.
    Enter(LinkError),
    /// The bootloader did not answer in time.
    NoBootloader,
    /// The bootloader refused `begin`, a chunk or `commit` with this status.
    Refused(Status),
    /// A transfer failed on the bus after every retry.
    Link(LinkError),
    /// The board did not come back with a version in time.
    NotBack,
    /// It came back with this version instead of the new one (rolled back).
    RolledBack(Version),
    /// The ROM bootloader refused, or the update through it failed (AN4221: a wrong chip, a
    /// refusal, a read-back that differs, the bus).
    Rom(RomError),
}

/// Why an update through the ROM bootloader failed (`x10_stmboot::Error`, its bus error a
/// [`RomBusError`]).
pub type RomError = x10_stmboot::Error<RomBusError>;

/// A raw transfer's [`LinkError`] as an `embedded_hal_async` I2C error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RomBusError(pub LinkError);

impl embedded_hal_async::i2c::Error for RomBusError {
    fn kind(&self) -> embedded_hal_async::i2c::ErrorKind {
        use embedded_hal_async::i2c::{ErrorKind, NoAcknowledgeSource};
        match self.0 {
            LinkError::Nack => ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address),
            LinkError::ArbitrationLost => ErrorKind::ArbitrationLoss,
            LinkError::Bus => ErrorKind::Bus,
            _ => ErrorKind::Other,
        }
    }
}

/// What the updater needs of the motherboard: calls that bypass the `Updating` refusal, the
/// mark that refuses the others, and time.
#[allow(async_fn_in_trait)]
pub trait UpdateLink {
    /// Sends `op` to `db` through the request queue (the board may be marked as updating).
    ///
    /// # Errors
    /// As `X10::call`.
    async fn call(&self, db: Address, op: Op<'_>) -> Result<x10_microcode::Payload, LinkError>;
    /// Marks `db` as being updated (`Some`) or no board (`None`).
    fn set_updating(&self, db: Option<Address>);
    /// Waits `us` microseconds.
    async fn pause(&self, us: u64);
    /// Microseconds since start.
    fn now_us(&self) -> u64;
    /// An update of the board at `db` from `from` to `to` starts (`end` is `None`) or ended:
    /// the USB link's records (`CallObserver::update`). By default nothing.
    fn report(
        &self,
        db: Address,
        from: Version,
        to: Version,
        end: Option<&Result<(), UpdateError>>,
    ) {
        let _ = (db, from, to, end);
    }
    /// A raw I2C transfer through the motherboard's bus, outside the microcode (no frame, no
    /// check, no board prepared): `write` to the 7-bit address `addr`, then, unless `read`
    /// is empty, `read.len()` bytes after a repeated START (a plain read when `write` is
    /// empty). At most a job's frame out (`x10_microcode::MAX_FRAME_LEN`, 36 bytes) and a
    /// payload in (`x10_microcode::MAX_PAYLOAD`, 28 bytes). For ST's ROM bootloader.
    ///
    /// # Errors
    /// As `X10::call` for the bus; [`LinkError::Unsupported`] where there is no such path.
    async fn i2c(&self, addr: u8, write: &[u8], read: &mut [u8]) -> Result<(), LinkError> {
        let _ = (addr, write, read);
        Err(LinkError::Unsupported)
    }
}

/// Bytes per Write Memory and Read Memory through [`UpdateLink::i2c`]: a multiple of the
/// C011's double word that a raw transfer carries (the data frame is two bytes more).
pub const ROM_BLOCK: usize = 24;

/// [`UpdateLink::i2c`] as the `embedded_hal_async` bus and delay `x10_stmboot::Client` takes.
struct RomBus<'l, L>(&'l L);

impl<L> embedded_hal_async::i2c::ErrorType for RomBus<'_, L> {
    type Error = RomBusError;
}

impl<L: UpdateLink> embedded_hal_async::i2c::I2c for RomBus<'_, L> {
    async fn transaction(
        &mut self,
        address: u8,
        operations: &mut [embedded_hal_async::i2c::Operation<'_>],
    ) -> Result<(), RomBusError> {
        use embedded_hal_async::i2c::Operation;
        match operations {
            [Operation::Write(w)] => self.0.i2c(address, w, &mut []).await,
            [Operation::Read(r)] => self.0.i2c(address, &[], r).await,
            [Operation::Write(w), Operation::Read(r)] => self.0.i2c(address, w, r).await,
            _ => Err(LinkError::Unsupported),
        }
        .map_err(RomBusError)
    }
}

impl<L: UpdateLink> embedded_hal_async::delay::DelayNs for RomBus<'_, L> {
    async fn delay_ns(&mut self, ns: u32) {
        self.0.pause(u64::from(ns).div_ceil(1_000)).await;
    }
}

/// Counters of the updater.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UpdateStats {
    /// Boards brought to the carried version.
    pub done: u16,
    /// Updates that failed (each try counts).
    pub failed: u16,
    /// Of those, boards that came back with their old version.
    pub rolled_back: u16,
    /// Requests of the transfer sent again after a transport error.
    pub chunk_retries: u32,
    /// Transfers started again from `begin` (the board lost its session: a reset).
    pub restarts: u16,
    /// Boards not tried, the updater having no method for their kind ([`update_pass`]).
    pub refused: u16,
}

/// What the motherboard does with one board, and why ([`decide`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Decision<'a> {
    /// It runs another version than the image carried for its kind: updated to it.
    Update(&'a DbImage),
    /// It runs the version carried for its kind.
    UpToDate(&'a DbImage),
    /// The policy pins it ([`UpdatePolicy::Except`]).
    Pinned,
    /// The policy updates no board ([`UpdatePolicy::Never`]).
    Never,
    /// No image of its kind is carried.
    NoImage,
}

/// What the motherboard does with a board of `kind` running `version` under `policy`, given
/// the images it carries: pure, the whole decision ([`plan`] is its yes or no; `x10 plan`
/// prints it in words).
pub fn decide(
    images: &[DbImage],
    policy: UpdatePolicy,
    uid: Uid,
    kind: BoardKind,
    version: Version,
) -> Decision<'_> {
    match policy {
        UpdatePolicy::Never => return Decision::Never,
        UpdatePolicy::Except(pinned) if pinned.contains(&uid) => return Decision::Pinned,
        _ => {}
    }
    match images.iter().find(|i| i.kind == kind) {
        None => Decision::NoImage,
        Some(i) if i.version == version => Decision::UpToDate(i),
        Some(i) => Decision::Update(i),
    }
}

/// The image `images` carries for a board of `kind` running `version` under `policy`, when the
/// board is to be updated ([`decide`] says [`Decision::Update`]).
pub fn plan(
    images: &[DbImage],
    policy: UpdatePolicy,
    uid: Uid,
    kind: BoardKind,
    version: Version,
) -> Option<&DbImage> {
    match decide(images, policy, uid, kind, version) {
        Decision::Update(i) => Some(i),
        _ => None,
    }
}

async fn wait_for<L: UpdateLink, T>(
    link: &L,
    cfg: &UpdateConfig,
    within_us: u64,
    mut ask: impl AsyncFnMut() -> Option<T>,
) -> Option<T> {
    let end = link.now_us().saturating_add(within_us);
    loop {
        if let Some(v) = ask().await {
            return Some(v);
        }
        if link.now_us() >= end {
            return None;
        }
        link.pause(cfg.poll_us).await;
    }
}

/// `op` to `db`, tried again after a transport error or `pec_mismatch` (the board is deaf
/// while it erases or writes its flash; a bit flipped on the way; a repeated chunk or commit
/// is idempotent) up to [`UpdateConfig::chunk_retries`]
/// times, [`UpdateConfig::poll_us`] apart.
async fn call_retrying<L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    db: Address,
    op: Op<'_>,
    stats: &mut UpdateStats,
) -> Result<x10_microcode::Payload, LinkError> {
    let mut tries = 0u8;
    loop {
        match link.call(db, op).await {
            // `pec_mismatch`: the request was hit on the way (the board executed nothing),
            // as a transport error is; every other status is the board's answer.
            Err(LinkError::Status(s)) if s != Status::PecMismatch => {
                return Err(LinkError::Status(s))
            }
            Err(e) if tries >= cfg.chunk_retries => return Err(e),
            Err(_) => {
                tries += 1;
                stats.chunk_retries += 1;
                link.pause(cfg.poll_us).await;
            }
            ok => return ok,
        }
    }
}

/// One transfer: `begin`, the chunks, `commit`. `Ok(false)`: the board lost its session
/// (`no_session`, or no answer after the retries: it was reset): start again from `begin`.
async fn transfer<L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    db: Address,
    image: &DbImage,
    stats: &mut UpdateStats,
) -> Result<bool, UpdateError> {
    let flash = FlashTiming::for_kind(image.kind).filter(|_| cfg.wait_flash);
    let refused = |e: LinkError| match e {
        LinkError::Status(Status::NoSession) => Ok(false),
        LinkError::Status(s) => Err(UpdateError::Refused(s)),
        _ => Ok(false),
    };
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let begin = UpdateOp::Begin(image.info()).to_op(&mut buf);
    if let Err(e) = call_retrying(link, cfg, db, begin, stats).await {
        return refused(e);
    }
    // The first sector's erase.
    if let Some(f) = flash {
        link.pause(u64::from(f.erase_us)).await;
    }
    let mut offset = 0usize;
    for data in image.bytes.chunks(CHUNK_MAX) {
        let mut buf = [0u8; MAX_REQUEST_DATA];
        let op = UpdateOp::Chunk {
            offset: offset as u32,
            data,
        }
        .to_op(&mut buf);
        if let Err(e) = call_retrying(link, cfg, db, op, stats).await {
            return refused(e);
        }
        let work = flash.map_or(0, |f| {
            f.work_after_chunk_us(offset as u32, data.len() as u32, image.bytes.len() as u32)
        });
        offset += data.len();
        link.pause(cfg.chunk_gap_us.max(u64::from(work))).await;
    }
    let commit = UpdateOp::Commit.to_op(&mut buf);
    match call_retrying(link, cfg, db, commit, stats).await {
        Ok(_) => Ok(true),
        // No answer after the tries, or an application's `unsupported`: the board may have
        // taken the commit and reset into its swap, the `ok` lost on the way. What it runs
        // next says (`update_marked`).
        Err(LinkError::Status(Status::Unsupported)) => Ok(true),
        Err(LinkError::Status(s)) => refused(LinkError::Status(s)),
        Err(_) => Ok(true),
    }
}

/// What a board that was sent `commit` does next.
enum After {
    /// It runs an image of this version (it answered `identify`).
    Runs(Version),
    /// Its bootloader answers, without a committed image: the commit did not arrive.
    NotCommitted,
}

/// Waits until the board answers `identify` (the new image, or the old one rolled back),
/// or its bootloader answers `status` without a committed image; `None` after
/// [`UpdateConfig::boot_wait_us`].
async fn after_commit<L: UpdateLink>(link: &L, cfg: &UpdateConfig, db: Address) -> Option<After> {
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let status = UpdateOp::Status.to_op(&mut buf);
    wait_for(link, cfg, cfg.boot_wait_us, async || {
        if let Ok(p) = link.call(db, Op::Identify).await {
            return Identity::parse(&p).ok().map(|id| After::Runs(id.firmware));
        }
        // Committed: the bootloader resets into the swap any moment now.
        let p = link.call(db, status).await.ok()?;
        UpdateReport::parse(&p)
            .ok()
            .filter(|r| r.state != x10_microcode::UpdateState::Committed)
            .map(|_| After::NotCommitted)
    })
    .await
}

/// How boards updated through ST's ROM bootloader (the C011's) are handled: [`WithRom`]
/// updates them, [`NoRom`] refuses them ([`UpdateError::NoMethod`], nothing sent) and links
/// none of that method's code (`x10-stmboot`'s client, the flash timings, the rescue at 0x64:
/// 11.2 KiB of flash and 600 B of RAM on the Pico). A motherboard image names [`WithRom`]
/// only when it carries a C011 image (`mb_image!`, the cfg `x10_carry_rom` of
/// `x10-boards/carry.rs`). A type, not a flag: the future of a branch an `async fn` never
/// takes is still compiled into it.
#[allow(async_fn_in_trait)]
pub trait RomMethod {
    /// True when the method through ST's ROM bootloader is linked.
    const LINKED: bool;

    /// The method this updater has for a board of `kind`: [`Method::for_kind`], but
    /// [`Method::None`] for [`Method::StRom`] when that method is not linked.
    fn method_for(kind: BoardKind) -> Method {
        match Method::for_kind(kind) {
            Method::StRom if !Self::LINKED => Method::None,
            m => m,
        }
    }

    /// Updates the board at `db` (or the one found at 0x64, `None`) through the ROM.
    async fn update<L: UpdateLink>(
        link: &L,
        cfg: &UpdateConfig,
        db: Option<Address>,
        image: &DbImage,
    ) -> Result<(), UpdateError>;
    /// [`rescue_rom`].
    async fn rescue<L: UpdateLink>(
        link: &L,
        cfg: &UpdateConfig,
        images: &[DbImage],
        stats: &mut UpdateStats,
    ) -> Option<Result<(), UpdateError>>;
}

/// The ROM method linked: a C011 is updated through ST's ROM bootloader.
pub enum WithRom {}

/// No ROM method: a motherboard image that carries no C011 image.
pub enum NoRom {}

impl RomMethod for WithRom {
    const LINKED: bool = true;

    async fn update<L: UpdateLink>(
        link: &L,
        cfg: &UpdateConfig,
        db: Option<Address>,
        image: &DbImage,
    ) -> Result<(), UpdateError> {
        update_rom(link, cfg, db, image).await
    }

    async fn rescue<L: UpdateLink>(
        link: &L,
        cfg: &UpdateConfig,
        images: &[DbImage],
        stats: &mut UpdateStats,
    ) -> Option<Result<(), UpdateError>> {
        rescue_rom(link, cfg, images, stats).await
    }
}

impl RomMethod for NoRom {
    const LINKED: bool = false;

    /// Not reached from [`update_board`] ([`RomMethod::method_for`] says [`Method::None`]
    /// first): the same refusal.
    async fn update<L: UpdateLink>(
        _: &L,
        _: &UpdateConfig,
        _: Option<Address>,
        _: &DbImage,
    ) -> Result<(), UpdateError> {
        Err(UpdateError::NoMethod)
    }

    /// Nobody is looked for at 0x64: without the method no C011 image is carried either, and
    /// [`rescue_rom`] would find none to finish it with.
    async fn rescue<L: UpdateLink>(
        _: &L,
        _: &UpdateConfig,
        _: &[DbImage],
        _: &mut UpdateStats,
    ) -> Option<Result<(), UpdateError>> {
        None
    }
}

/// Updates the board at `db` to `image`: `enter_update`; waits until its bootloader answers
/// `status`; `begin`, every chunk, `commit` (from `begin` again, once more, when the board
/// lost its session: it was reset); waits until the board answers `identify` with the new
/// version, then `confirm_firmware`. The board is marked as updating from the first request
/// to the end. A C011 is updated through ST's ROM bootloader instead ([`Method::StRom`]),
/// when `R` links that method ([`RomMethod`]).
///
/// # Errors
/// [`UpdateError`]; [`UpdateError::NoMethod`] at once, nothing sent, when `R` has no method
/// for `kind` ([`RomMethod::method_for`]).
pub async fn update_board<R: RomMethod, L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    db: Address,
    kind: BoardKind,
    image: &DbImage,
    stats: &mut UpdateStats,
) -> Result<(), UpdateError> {
    let method = R::method_for(kind);
    if method == Method::None {
        return Err(UpdateError::NoMethod);
    }
    link.set_updating(Some(db));
    let r = if method == Method::StRom {
        R::update(link, cfg, Some(db), image).await
    } else {
        update_marked(link, cfg, db, image, stats).await
    };
    link.set_updating(None);
    match r {
        Ok(()) => stats.done = stats.done.saturating_add(1),
        Err(e) => {
            stats.failed = stats.failed.saturating_add(1);
            if matches!(e, UpdateError::RolledBack(_)) {
                stats.rolled_back = stats.rolled_back.saturating_add(1);
            }
        }
    }
    r
}

async fn update_marked<L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    db: Address,
    image: &DbImage,
    stats: &mut UpdateStats,
) -> Result<(), UpdateError> {
    // A board already in its bootloader (a power cut during an earlier update) answers
    // `status`; an application answers it `unsupported`, and takes `enter_update`.
    let mut buf = [0u8; MAX_REQUEST_DATA];
    let status = UpdateOp::Status.to_op(&mut buf);
    let in_bootloader = link.call(db, status).await.is_ok();
    if !in_bootloader {
        // Refused (`unsupported`: no bootloader): the board stays as it is. No reply: the
        // board may have taken it and written its bootloader's state with the bus unserved (a
        // 45 ms sector erase on the Pico), then reset; whether its bootloader answers below
        // tells (`NoBootloader` if not).
        if let Err(LinkError::Status(s)) = link.call(db, Op::EnterUpdate).await {
            return Err(UpdateError::Enter(LinkError::Status(s)));
        }
    }
    let mut restarts = 0u8;
    let version = loop {
        let up = wait_for(link, cfg, cfg.bootloader_wait_us, async || {
            let p = link.call(db, status).await.ok()?;
            UpdateReport::parse(&p).ok()
        })
        .await;
        if up.is_none() {
            return Err(UpdateError::NoBootloader);
        }
        if transfer(link, cfg, db, image, stats).await? {
            // The board resets, embassy-boot swaps the slots, the new image starts (its
            // `boot` event reaches the directory) and answers `identify`.
            match after_commit(link, cfg, db).await {
                Some(After::Runs(v)) => break v,
                Some(After::NotCommitted) => {}
                None => return Err(UpdateError::NotBack),
            }
        }
        restarts += 1;
        stats.restarts = stats.restarts.saturating_add(1);
        if restarts > cfg.tries {
            return Err(UpdateError::Refused(Status::NoSession));
        }
    };
    if version != image.version {
        return Err(UpdateError::RolledBack(version));
    }
    // Tried again when its reply is lost: the board may write its bootloader's state (a
    // sector erase) before the reply is read, and a repeated confirm is answered `ok`.
    call_retrying(link, cfg, db, Op::ConfirmFirmware, stats)
        .await
        .map_err(UpdateError::Link)?;
    Ok(())
}

/// Updates a board through ST's ROM bootloader: `enter_update` to `db` (unless `db` is
/// `None` or the ROM already answers at 0x64: a board left there by a cut update), waits
/// until the ROM answers Get Version, `x10_stmboot::update` (Get ID checked against the
/// kind's target, page 0 erased first, the first double word written last, everything read
/// back, Go), then waits until `db` answers `identify` with the new version. The image has
/// no slot to roll back to: nothing to confirm.
async fn update_rom<L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    db: Option<Address>,
    image: &DbImage,
) -> Result<(), UpdateError> {
    let target = x10_stmboot::Target::for_board_kind(image.kind.0).ok_or(UpdateError::NoMethod)?;
    if !rom_answers(link).await {
        let db = db.ok_or(UpdateError::NoBootloader)?;
        link.call(db, Op::EnterUpdate)
            .await
            .map_err(UpdateError::Enter)?;
        let up = wait_for(link, cfg, cfg.bootloader_wait_us, async || {
            rom_answers(link).await.then_some(())
        })
        .await;
        if up.is_none() {
            return Err(UpdateError::NoBootloader);
        }
    }
    let mut client = x10_stmboot::Client::new(RomBus(link), RomBus(link));
    client.block = ROM_BLOCK;
    match x10_stmboot::update(&mut client, &target, image.bytes).await {
        Ok(_) => {}
        // Refused before any erase: the old image is whole, start it again.
        Err(e @ x10_stmboot::Error::WrongChip { .. }) => {
            let _ = client.go(target.flash_base).await;
            return Err(UpdateError::Rom(e));
        }
        Err(e) => return Err(UpdateError::Rom(e)),
    }
    let Some(db) = db else {
        return Ok(());
    };
    let version = wait_for(link, cfg, cfg.boot_wait_us, async || {
        let p = link.call(db, Op::Identify).await.ok()?;
        Identity::parse(&p).ok().map(|id| id.firmware)
    })
    .await
    .ok_or(UpdateError::NotBack)?;
    if version != image.version {
        return Err(UpdateError::RolledBack(version));
    }
    Ok(())
}

/// True when a ROM bootloader answers Get Version at `Address::STM32_BOOTLOADER`.
async fn rom_answers<L: UpdateLink>(link: &L) -> bool {
    let mut client = x10_stmboot::Client::new(RomBus(link), RomBus(link));
    client.get_version().await.is_ok()
}

/// A board answering at `Address::STM32_BOOTLOADER` (0x64) is an STM32C011 whose update was
/// cut (its first word erased: every power-on starts the ROM bootloader). When `images`
/// carries an image for a kind updated through the ROM, the board is updated with it and
/// started; it then boots at the address it keeps and announces itself. `None`: no board
/// answers there, or no such image is carried.
pub async fn rescue_rom<L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    images: &[DbImage],
    stats: &mut UpdateStats,
) -> Option<Result<(), UpdateError>> {
    let image = images
        .iter()
        .find(|i| Method::for_kind(i.kind) == Method::StRom)?;
    if !rom_answers(link).await {
        return None;
    }
    info!("update: a board in its ROM bootloader at 0x64");
    let r = update_rom(link, cfg, None, image).await;
    match r {
        Ok(()) => stats.done = stats.done.saturating_add(1),
        Err(_) => stats.failed = stats.failed.saturating_add(1),
    }
    Some(r)
}

/// True for the operations the updater sends (they pass while their board is marked as
/// updating); `identify` and `ping` too, so that anyone may see whether the board is back.
pub(crate) const fn is_update_op(op: &Op<'_>) -> bool {
    matches!(
        op,
        Op::Update(_) | Op::EnterUpdate | Op::ConfirmFirmware | Op::Identify | Op::Ping
    )
}

impl UpdateLink for crate::X10 {
    async fn call(&self, db: Address, op: Op<'_>) -> Result<x10_microcode::Payload, LinkError> {
        crate::X10::call(self, db, op).await
    }

    fn set_updating(&self, db: Option<Address>) {
        self.core().with(|t| t.updating = db);
    }

    async fn pause(&self, us: u64) {
        crate::mb_core::sleep_until(crate::mb_core::now().plus_us(us)).await;
    }

    fn now_us(&self) -> u64 {
        crate::mb_core::now().0
    }

    #[inline(never)]
    fn report(
        &self,
        db: Address,
        from: Version,
        to: Version,
        end: Option<&Result<(), UpdateError>>,
    ) {
        if let Some(o) = self.core().observer {
            o.update(db, from, to, end, crate::mb_core::now());
        }
    }

    /// A job of its own kind in the dispatcher's queue (a plain transfer: the bytes as they
    /// are, no board prepared), between the robot's requests.
    async fn i2c(&self, addr: u8, write: &[u8], read: &mut [u8]) -> Result<(), LinkError> {
        let n = read.len();
        let (_, p) = self
            .core()
            .raw_job(
                Address::new(addr)?,
                crate::jobs::JobKind::PlainRead,
                (n > 0).then_some(n),
                |_, frame| {
                    frame
                        .extend_from_slice(write)
                        .map_err(|_| LinkError::Invalid(x10_microcode::Error::BufferTooShort))
                },
            )
            .await?;
        read.copy_from_slice(p.get(..n).ok_or(LinkError::BadReply)?);
        Ok(())
    }
}

/// How often [`run_updates`] looks at the directory (100 ms).
pub const UPDATE_POLL_US: u64 = 100_000;

/// Boards whose tries [`run_updates`] counts (more are tried once per start of it).
pub const MAX_TRACKED: usize = 16;

/// What [`update_pass`] remembers between passes: the tries per board and the counters.
#[derive(Clone, Debug, Default)]
pub struct UpdateState {
    tried: heapless::Vec<(Uid, u8), MAX_TRACKED>,
    /// 0x64 was looked at since the start or the last failed update through the ROM.
    rom_checked: bool,
    /// Updates of a board found at 0x64 ([`rescue_rom`]) so far: at most
    /// [`UpdateConfig::tries`].
    rom_rescues: u8,
    /// The counters.
    pub stats: UpdateStats,
}

impl UpdateState {
    /// Tries so far for the board `uid` (a refused board's are all used up).
    pub fn tries(&self, uid: Uid) -> u8 {
        self.tried
            .iter()
            .find(|(u, _)| *u == uid)
            .map_or(0, |(_, c)| *c)
    }

    /// Forgets the tries of every board: a request to update now
    /// ([`crate::X10::start_update`]) tries again a board that failed too often.
    pub fn forget(&mut self) {
        self.tried.clear();
    }

    /// `uid` is not tried (no method for its kind): its tries are used up (`tries`).
    fn refuse(&mut self, uid: Uid, tries: u8) {
        match self.tried.iter_mut().find(|(u, _)| *u == uid) {
            Some(e) => e.1 = tries,
            None => {
                let _ = self.tried.push((uid, tries));
            }
        }
    }

    fn count(&mut self, uid: Uid) {
        match self.tried.iter_mut().find(|(u, _)| *u == uid) {
            Some(e) => e.1 = e.1.saturating_add(1),
            None => {
                let _ = self.tried.push((uid, 1));
            }
        }
    }
}

/// One look at the boards: each present board of `boards` that [`plan`] says to update, and
/// that has had fewer than [`UpdateConfig::tries`] tries, is updated ([`update_board`]), one
/// after the other; `on_result` hears every end (the log line). Returns how many were tried.
/// A board for which `R` has no method ([`RomMethod::method_for`]: a C011 with [`NoRom`]) is
/// not tried: `on_result` hears [`UpdateError::NoMethod`] and one line is logged, once (its
/// tries are used up: [`UpdateStats::refused`]), and nothing is sent to it.
pub async fn update_pass<R: RomMethod, L: UpdateLink>(
    link: &L,
    cfg: &UpdateConfig,
    images: &[DbImage],
    policy: UpdatePolicy,
    boards: &[crate::KnownBoard],
    state: &mut UpdateState,
    mut on_result: impl FnMut(&crate::KnownBoard, &DbImage, &Result<(), UpdateError>),
) -> usize {
    let mut n = 0;
    // First a C011 left in its ROM bootloader by a cut update (at start, and after an update
    // through the ROM failed): it cannot be called at its address until it is whole.
    if !state.rom_checked && state.rom_rescues < cfg.tries {
        state.rom_checked = true;
        if let Some(r) = R::rescue(link, cfg, images, &mut state.stats).await {
            state.rom_rescues += 1;
            n += 1;
            if r.is_err() {
                warn!("update: the board at 0x64 failed");
                state.rom_checked = false;
            }
        }
    }
    for b in boards {
        if !b.present {
            continue;
        }
        let Some(image) = plan(images, policy, b.uid, b.kind, b.firmware) else {
            continue;
        };
        if state.tries(b.uid) >= cfg.tries {
            continue;
        }
        if R::method_for(b.kind) == Method::None {
            state.refuse(b.uid, cfg.tries);
            state.stats.refused = state.stats.refused.saturating_add(1);
            warn!(
                "update: board {} (kind {}): no update method in this image",
                b.address.get(),
                b.kind.0
            );
            on_result(b, image, &Err(UpdateError::NoMethod));
            continue;
        }
        state.count(b.uid);
        n += 1;
        info!(
            "update: board {} from {}.{}.{} to {}.{}.{}",
            b.address.get(),
            b.firmware[0],
            b.firmware[1],
            b.firmware[2],
            image.version[0],
            image.version[1],
            image.version[2]
        );
        link.report(b.address, b.firmware, image.version, None);
        let r = update_board::<R, L>(link, cfg, b.address, b.kind, image, &mut state.stats).await;
        link.report(b.address, b.firmware, image.version, Some(&r));
        match r {
            Ok(()) => info!("update: board {} done", b.address.get()),
            Err(_) => {
                warn!("update: board {} failed", b.address.get());
                if Method::for_kind(b.kind) == Method::StRom {
                    state.rom_checked = false;
                }
            }
        }
        on_result(b, image, &r);
    }
    n
}

/// Why a request to update now ([`crate::X10::start_update`], the USB link's) was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UpdateRefusal {
    /// This motherboard image carries no daughterboard images (or its updater does not run).
    NoImages,
    /// No board with that unique ID is known.
    UnknownUid,
    /// The board does not answer (lost, or not yet addressed).
    NotPresent,
    /// No image of the board's kind is carried.
    NoImage,
    /// The board runs the carried version already (for every board: all of them do).
    UpToDate,
    /// An update is under way (of the board at this address), or a request waits for the
    /// updater: one at a time.
    Busy(Option<Address>),
}

/// The policy of a request to update every board now: `Never` is overridden, a pin
/// (`Except`) is kept.
pub const fn requested(policy: UpdatePolicy) -> UpdatePolicy {
    match policy {
        UpdatePolicy::Never => UpdatePolicy::Auto,
        p => p,
    }
}

/// Whether a request to update `target` (one board by its ID; `None`: every present board
/// out of date) starts now, given the `images` the updater carries (empty: it does not run),
/// its `policy`, the `boards` known, the board `updating` and whether a request is `pending`:
/// how many boards it will update, or why not. Pure ([`crate::X10::start_update`] applies
/// it). A board named by its ID is updated whatever the policy; every board: as
/// [`requested`] says.
///
/// # Errors
/// [`UpdateRefusal`].
pub fn start_decision(
    images: &[DbImage],
    policy: UpdatePolicy,
    boards: &[crate::KnownBoard],
    updating: Option<Address>,
    pending: bool,
    target: Option<Uid>,
) -> Result<u8, UpdateRefusal> {
    if images.is_empty() {
        return Err(UpdateRefusal::NoImages);
    }
    if updating.is_some() || pending {
        return Err(UpdateRefusal::Busy(updating));
    }
    let Some(uid) = target else {
        let n = boards
            .iter()
            .filter(|b| b.present)
            .filter(|b| plan(images, requested(policy), b.uid, b.kind, b.firmware).is_some())
            .count();
        return match u8::try_from(n) {
            Ok(0) => Err(UpdateRefusal::UpToDate),
            n => Ok(n.unwrap_or(u8::MAX)),
        };
    };
    let b = boards
        .iter()
        .find(|b| b.uid == uid)
        .ok_or(UpdateRefusal::UnknownUid)?;
    if !b.present {
        return Err(UpdateRefusal::NotPresent);
    }
    match decide(images, UpdatePolicy::Auto, uid, b.kind, b.firmware) {
        Decision::Update(_) => Ok(1),
        Decision::UpToDate(_) => Err(UpdateRefusal::UpToDate),
        _ => Err(UpdateRefusal::NoImage),
    }
}

/// The updater task on the motherboard: at start and every [`UPDATE_POLL_US`], an
/// [`update_pass`] over the boards its directory knows (`Motherboard::with_directory`). It
/// leaves `images` and `policy` with the motherboard, so that a request to update now
/// ([`crate::X10::start_update`]: one board whatever the policy, or every board with `Never`
/// overridden) is answered at once and run at its next look, its tries counted afresh.
/// `R`: [`WithRom`] when `images` may hold one updated through ST's ROM bootloader (a
/// C011's); an image that carries none names `run_updates::<NoRom>`, and that method is not
/// linked (a C011 board is then refused, `UpdateError::NoMethod`).
pub async fn run_updates<R: RomMethod>(
    x10: crate::X10,
    cfg: UpdateConfig,
    images: &'static [DbImage],
    policy: UpdatePolicy,
) -> ! {
    x10.core().with(|t| {
        t.carried = images;
        t.update_policy = policy;
    });
    let mut state = UpdateState::default();
    let mut list = [crate::KnownBoard::EMPTY; MAX_TRACKED];
    loop {
        let n = x10.boards(&mut list);
        let boards = list.get(..n).unwrap_or(&[]);
        // A request to update now: one board, or every board with `Never` overridden; the
        // tries counted afresh.
        let (boards, policy) = match x10.core().with(|t| t.update_now.take()) {
            None => (boards, policy),
            Some(target) => {
                state.forget();
                match target {
                    Some(uid) => (
                        boards
                            .iter()
                            .position(|b| b.uid == uid)
                            .and_then(|i| boards.get(i..=i))
                            .unwrap_or(&[]),
                        UpdatePolicy::Auto,
                    ),
                    None => (boards, requested(policy)),
                }
            }
        };
        update_pass::<R, _>(&x10, &cfg, images, policy, boards, &mut state, |_, _, _| {}).await;
        UpdateLink::pause(&x10, UPDATE_POLL_US).await;
    }
}
