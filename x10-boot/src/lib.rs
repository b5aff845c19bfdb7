//! # x10-boot: the daughterboard bootloader's update session (issue 25)
//!
//! A daughterboard's application has no room for a firmware transfer, so the transfer runs in
//! a stated *update mode* served by the board's bootloader. This crate is that mode, portable:
//! the chip's bootloader image glues an I2C target and a reset to it.
//!
//! * [`Session`] answers the frames of function 7 (`docs/protocol.md`, "Firmware over the
//!   bus"): `begin` (length, CRC-32, board kind, version), `chunk` (offset, up to
//!   [`x10_microcode::CHUNK_MAX`] bytes, only in order, a repeat of the last one answered `ok`
//!   again), `commit` (verifies length, the CRC-32 read back from the slot, kind and version
//!   against a floor compiled into the bootloader, then marks the slot for the swap), `status`
//!   and `leave`. Every frame must carry its check (PEC byte or CRC-16); every refusal is a
//!   status of its own.
//! * The image goes into embassy-boot's DFU partition through
//!   `embedded_storage::nor_flash::NorFlash`, a sector erased only when the transfer first
//!   reaches it, written [`Session`]'s `W` bytes at a time (a multiple of the flash's write size
//!   that divides its erase size).
//! * The A/B bookkeeping is embassy-boot's: `commit` sets the state partition's swap magic
//!   (`BlockingFirmwareState::mark_updated`); at the next start [`BootLoader::prepare_boot`]
//!   swaps the slots, power-fail-safe, and reverts them at the start after that unless the new
//!   image confirmed itself ([`confirm_firmware`], System 13). The application enters update
//!   mode with [`enter_update`] (System 12: embassy-boot's DFU-detach magic), and the
//!   bootloader's start decides with [`start_mode`].
//!
//! Nothing in the active slot changes before a verified `commit`.
//!
//! [`BootLoader::prepare_boot`]: embassy_boot::BootLoader::prepare_boot
#![no_std]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

#[cfg(feature = "model")]
pub mod model;

use embassy_boot::{BlockingFirmwareState, FirmwareUpdaterError, State};
use embedded_storage::nor_flash::NorFlash;
use x10_microcode::{
    pec, Address, BoardKind, ImageInfo, Op, Reply, RequestFrame, Status, UpdateOp, UpdateReport,
    UpdateState, Version, CHUNK_MAX, MAX_REPLY_LEN,
};

/// Flash work a reply does not wait for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Work {
    None,
    /// Erase the first sector (after `begin`).
    Start,
    /// Write the full buffer, erase the next sector when the next buffer starts one.
    Flush,
    /// Mark the slot for the swap (after a verified `commit`).
    Mark,
}

pub use embassy_boot;

/// The CRC-32/ISO-HDLC of the update frames, bitwise (no 1 KiB table in a bootloader).
static CRC32: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// What a bootloader is built with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BootConfig {
    /// The board kind this bootloader takes images for (`begin` with another: `wrong_kind`).
    pub board: BoardKind,
    /// The oldest version it installs (`too_old` below it).
    pub floor: Version,
    /// The board's address (the application's, as kept in its record).
    pub address: Address,
}

/// What the bootloader does at start, after [`embassy_boot::BootLoader::prepare_boot`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StartMode {
    /// Start the image in the active slot (swapped in, reverted, or unchanged).
    Application,
    /// Stay in update mode and serve a [`Session`]: the application asked for it
    /// ([`enter_update`]), and a reset keeps the board there until `commit` or `leave`.
    Update,
}

/// The decision for the state `prepare_boot` returned.
pub fn start_mode(state: &State) -> StartMode {
    match state {
        State::DfuDetach => StartMode::Update,
        State::Boot | State::Swap | State::Revert => StartMode::Application,
    }
}

/// System 12 in the application: marks the state partition so that the bootloader stays in
/// update mode at the next start (embassy-boot's DFU-detach magic; the caller then resets once
/// its reply has been read). An image that was swapped in and not yet confirmed is kept as it
/// is (no revert happens from update mode): it booted and answered the motherboard.
///
/// # Errors
/// The flash error.
pub fn enter_update<S: NorFlash>(
    state: &mut BlockingFirmwareState<'_, S>,
) -> Result<(), FirmwareUpdaterError> {
    state.mark_dfu()
}

/// System 13 in the application: the running image marks itself good (embassy-boot's boot
/// magic), so the next start keeps it; nothing is written when there was nothing to confirm.
///
/// # Errors
/// The flash error.
pub fn confirm_firmware<S: NorFlash>(
    state: &mut BlockingFirmwareState<'_, S>,
) -> Result<(), FirmwareUpdaterError> {
    match state.get_state()? {
        State::Swap => state.mark_booted(),
        _ => Ok(()),
    }
}

/// What the glue does once the reply of the last request has been read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Exit {
    /// Keep serving.
    Stay,
    /// Reset: `commit` marked the new image, `prepare_boot` swaps it in.
    Reset,
    /// `leave`: reset into the image in the active slot (the state partition says boot).
    Leave,
}

/// The bootloader's update session over the DFU partition `D` and the state partition `S`.
///
/// `W` is the write buffer: chunks collect there and go to the flash `W` bytes at a time. It
/// must be a multiple of `D::WRITE_SIZE` and divide `D::ERASE_SIZE` (checked at compile time).
///
/// The transport calls [`Session::handle_write`] for each write addressed to the board and
/// [`Session::take_reply`] for each read, then [`Session::exit`].
pub struct Session<'d, D: NorFlash, S: NorFlash, const W: usize> {
    config: BootConfig,
    dfu: D,
    state: BlockingFirmwareState<'d, S>,
    info: Option<ImageInfo>,
    phase: UpdateState,
    /// Image bytes taken (the next offset expected).
    received: u32,
    /// Offset and length of the last chunk taken (a repeat of it is answered `ok`).
    last_chunk: Option<(u32, usize)>,
    /// Bytes of the slot erased since `begin` (whole sectors, from 0).
    erased: u32,
    buf: [u8; W],
    /// The bytes of the chunk that filled `buf` beyond it (they go into `buf` once it has been
    /// written).
    carry: [u8; CHUNK_MAX],
    /// Image offset of `buf[0]`.
    buf_start: u32,
    /// Flash work that waits until the reply has been read ([`Session::work`]).
    pending: Work,
    last_error: Status,
    reply: [u8; MAX_REPLY_LEN + 1],
    reply_len: usize,
    exit: Exit,
    pec_errors: u16,
}

impl<'d, D: NorFlash, S: NorFlash, const W: usize> Session<'d, D, S, W> {
    const CHECK: () = {
        assert!(W > 0 && W.is_multiple_of(D::WRITE_SIZE) && D::ERASE_SIZE.is_multiple_of(W));
    };

    /// A session on the DFU partition `dfu` and the state partition `state` (as embassy-boot's
    /// `BlockingFirmwareState`), idle.
    pub fn new(config: BootConfig, dfu: D, state: BlockingFirmwareState<'d, S>) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Session {
            config,
            dfu,
            state,
            info: None,
            phase: UpdateState::Idle,
            received: 0,
            last_chunk: None,
            erased: 0,
            buf: [0xff; W],
            carry: [0xff; CHUNK_MAX],
            buf_start: 0,
            pending: Work::None,
            last_error: Status::Ok,
            reply: [0; MAX_REPLY_LEN + 1],
            reply_len: 0,
            exit: Exit::Stay,
            pec_errors: 0,
        }
    }

    /// The longest image this slot takes: the DFU partition less the one sector embassy-boot's
    /// swap needs.
    pub fn max_len(&self) -> u32 {
        (self.dfu.capacity().saturating_sub(D::ERASE_SIZE)) as u32
    }

    /// The `status` report now.
    pub fn report(&self) -> UpdateReport {
        UpdateReport {
            state: self.phase,
            received: self.received,
            last_error: self.last_error,
        }
    }

    /// Frames refused for a wrong or missing check.
    pub fn pec_errors(&self) -> u16 {
        self.pec_errors
    }

    /// What to do now that the last reply has been read.
    pub fn exit(&self) -> Exit {
        if self.reply_len == 0 && self.pending == Work::None {
            self.exit
        } else {
            Exit::Stay
        }
    }

    /// Does the flash work the last request left (an erase, a buffer's write, the swap mark).
    /// The glue calls it once the reply has been read, before it listens again: an erase
    /// (45 ms on the Pico's flash) never delays a reply past an SMBus stretch timeout; the
    /// motherboard's next request meanwhile finds the board deaf and is tried again. A
    /// failure drops the transfer (`flash_error` in `status`; the next chunk is answered
    /// `no_session`).
    pub fn work(&mut self) {
        let r = match core::mem::replace(&mut self.pending, Work::None) {
            Work::None => return,
            Work::Start => self.erase_for(0),
            Work::Flush => self.flush_full(),
            Work::Mark => match self.state.mark_updated() {
                Ok(()) => {
                    self.phase = UpdateState::Committed;
                    self.exit = Exit::Reset;
                    Ok(())
                }
                Err(_) => Err(Status::FlashError),
            },
        };
        if let Err(s) = r {
            self.last_error = s;
            self.drop_transfer();
        }
    }

    /// The DFU partition (for tests and the glue's own checks).
    pub fn dfu(&mut self) -> &mut D {
        &mut self.dfu
    }

    /// Executes one write addressed to the board: `bytes` as received, check included. The
    /// reply is held for the next read.
    pub fn handle_write(&mut self, bytes: &[u8]) {
        // Work the glue left undone (it should call `work` after each reply) comes first.
        self.work();
        let seq = bytes.get(3).copied().unwrap_or(0);
        let addr_byte = self.config.address.addr_byte(false);
        let (status, payload) = match pec::strip(addr_byte, bytes) {
            Err(e) => {
                self.pec_errors = self.pec_errors.saturating_add(1);
                (e.status(), None)
            }
            Ok(body) => self.execute(body),
        };
        if !status.is_ok() {
            self.last_error = status;
        }
        let reply = Reply {
            seq,
            status,
            payload: payload.as_ref().map_or(&[][..], |p| &p[..]),
        };
        // A reply's check covers the read address byte, as every reply's does.
        self.reply_len = reply
            .emit_with_pec(self.config.address, &mut self.reply)
            .unwrap_or(0);
    }

    /// Writes the held reply (or a `no_request` reply) into `buf`; returns its length.
    pub fn take_reply(&mut self, buf: &mut [u8]) -> usize {
        if self.reply_len == 0 {
            let reply = Reply {
                seq: 0,
                status: Status::NoRequest,
                payload: &[],
            };
            return reply.emit_with_pec(self.config.address, buf).unwrap_or(0);
        }
        let n = self.reply_len;
        self.reply_len = 0;
        match (buf.get_mut(..n), self.reply.get(..n)) {
            (Some(out), Some(r)) => {
                out.copy_from_slice(r);
                n
            }
            _ => 0,
        }
    }

    fn execute(&mut self, body: &[u8]) -> (Status, Option<[u8; UpdateReport::LEN]>) {
        let frame = match RequestFrame::new_checked(body) {
            Ok(f) => f,
            Err(e) => return (e.status(), None),
        };
        if frame.db() != self.config.address.get() {
            return (Status::WrongAddress, None);
        }
        let op = match Op::parse(frame.fn_op(), frame.port_byte(), frame.data()) {
            Ok(op) => op,
            Err(e) => return (e.status(), None),
        };
        match op {
            Op::Update(f) => match f.op() {
                UpdateOp::Status => (Status::Ok, Some(self.report().to_bytes())),
                u => (self.update(u), None),
            },
            // A bootloader is found by a ping; the application's operations wait for it.
            Op::Ping => (Status::Ok, None),
            _ => (Status::Unsupported, None),
        }
    }

    /// Executes one operation of function 7 (but `status`) and returns its status.
    pub fn update(&mut self, op: UpdateOp<'_>) -> Status {
        match op {
            UpdateOp::Begin(info) => self.begin(info),
            UpdateOp::Chunk { offset, data } => self.chunk(offset, data),
            UpdateOp::Commit => self.commit(),
            UpdateOp::Status => Status::Ok,
            UpdateOp::Leave => match self.state.mark_booted() {
                Ok(()) => {
                    self.drop_transfer();
                    self.exit = Exit::Leave;
                    Status::Ok
                }
                Err(_) => Status::FlashError,
            },
        }
    }

    fn drop_transfer(&mut self) {
        self.pending = Work::None;
        self.info = None;
        self.phase = UpdateState::Idle;
        self.received = 0;
        self.last_chunk = None;
        self.erased = 0;
        self.buf_start = 0;
    }

    /// Kind, length and version of an image announced or about to be committed.
    fn check_info(&self, info: &ImageInfo) -> Status {
        if info.board != self.config.board {
            Status::WrongKind
        } else if info.len == 0 || info.len > self.max_len() {
            Status::TooLarge
        } else if info.version < self.config.floor {
            Status::TooOld
        } else {
            Status::Ok
        }
    }

    fn begin(&mut self, info: ImageInfo) -> Status {
        // Committed: the slot holds a verified image marked for the swap and the board is
        // about to reset into it. A new transfer now would write into the slot the swap
        // reads: refused.
        if self.phase == UpdateState::Committed {
            return Status::Busy;
        }
        self.drop_transfer();
        let status = self.check_info(&info);
        if status.is_ok() {
            self.info = Some(info);
            self.phase = UpdateState::Receiving;
            self.last_error = Status::Ok;
            self.pending = Work::Start;
        }
        status
    }

    fn chunk(&mut self, offset: u32, data: &[u8]) -> Status {
        let Some(info) = self.info.filter(|_| self.phase == UpdateState::Receiving) else {
            return Status::NoSession;
        };
        if self.last_chunk == Some((offset, data.len())) {
            return Status::Ok;
        }
        if offset != self.received {
            return Status::OutOfOrder;
        }
        let end = u64::from(offset) + data.len() as u64;
        if end > u64::from(info.len) {
            return Status::TooLarge;
        }
        for &b in data {
            let i = (self.received - self.buf_start) as usize;
            let slot = if i < W {
                self.buf.get_mut(i)
            } else {
                self.carry.get_mut(i - W)
            };
            if let Some(slot) = slot {
                *slot = b;
            }
            self.received += 1;
        }
        if (self.received - self.buf_start) as usize >= W {
            self.pending = Work::Flush;
        }
        self.last_chunk = Some((offset, data.len()));
        Status::Ok
    }

    /// Erases the sector that holds image offset `at`, unless done already (the transfer goes
    /// forward only, so `erased` is where erased flash ends).
    fn erase_for(&mut self, at: u32) -> Result<(), Status> {
        while self.erased <= at {
            let from = self.erased;
            let to = from + D::ERASE_SIZE as u32;
            self.dfu.erase(from, to).map_err(|_| Status::FlashError)?;
            self.erased = to;
        }
        Ok(())
    }

    /// Writes the full buffer, moves the carried bytes in, and erases the next sector when
    /// the next buffer starts one.
    fn flush_full(&mut self) -> Result<(), Status> {
        let start = self.buf_start;
        self.erase_for(start)?;
        self.dfu
            .write(start, &self.buf)
            .map_err(|_| Status::FlashError)?;
        self.buf_start = start + W as u32;
        self.buf.fill(0xff);
        let carried = (self.received - self.buf_start) as usize;
        if let (Some(to), Some(from)) = (self.buf.get_mut(..carried), self.carry.get(..carried)) {
            to.copy_from_slice(from);
        }
        self.carry.fill(0xff);
        if let Some(info) = self.info {
            if self.buf_start < info.len {
                self.erase_for(self.buf_start)?;
            }
        }
        Ok(())
    }

    /// Writes what the buffer holds of the image's end (padded with the erased value).
    fn flush_tail(&mut self) -> Result<(), Status> {
        if self.pending == Work::Flush {
            self.pending = Work::None;
            self.flush_full()?;
        }
        let start = self.buf_start;
        if self.received == start {
            return Ok(());
        }
        self.erase_for(start)?;
        self.dfu
            .write(start, &self.buf)
            .map_err(|_| Status::FlashError)?;
        self.buf_start = self.received;
        self.buf.fill(0xff);
        Ok(())
    }

    fn commit(&mut self) -> Status {
        // A repeated commit (its reply was lost on the way): the image is verified and the
        // swap marked, or about to be; it is answered as the first was.
        if self.phase == UpdateState::Committed {
            return Status::Ok;
        }
        let Some(info) = self.info.filter(|_| self.phase == UpdateState::Receiving) else {
            return Status::NoSession;
        };
        if self.received != info.len {
            return Status::Incomplete;
        }
        let status = self.verify(&info);
        if status.is_ok() {
            // The mark (an erase and two writes of the state sector) once the reply is read.
            self.pending = Work::Mark;
        } else {
            self.drop_transfer();
        }
        status
    }

    fn verify(&mut self, info: &ImageInfo) -> Status {
        if let Err(s) = self.flush_tail() {
            return s;
        }
        let status = self.check_info(info);
        if !status.is_ok() {
            return status;
        }
        // The CRC-32 of what the slot holds, read back.
        let mut digest = CRC32.digest();
        let mut at = 0u32;
        while at < info.len {
            let n = (info.len - at).min(W as u32) as usize;
            let Some(piece) = self.buf.get_mut(..n) else {
                return Status::FlashError;
            };
            if self.dfu.read(at, piece).is_err() {
                return Status::FlashError;
            }
            digest.update(piece);
            at += n as u32;
        }
        self.buf.fill(0xff);
        if digest.finalize() == info.crc32 {
            Status::Ok
        } else {
            Status::BadCrc
        }
    }
}
