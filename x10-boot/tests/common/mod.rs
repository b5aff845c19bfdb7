//! A NOR flash in memory that loses power after a given number of erase and write operations,
//! and the board around it: the state, active and DFU partitions of embassy-boot, the
//! application's two hooks and the bootloader's start.
#![allow(dead_code)]

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use embassy_boot::{BlockingFirmwareState, BootLoader, BootLoaderConfig, State};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use x10_boot::{BootConfig, Exit, Session, StartMode};
use x10_microcode::{
    pec, Address, BoardKind, ImageInfo, Reply, Request, Status, UpdateOp, UpdateReport, CHUNK_MAX,
};

/// Erase sector (the RP2040's flash: 4 KiB).
pub const ERASE: usize = 4096;
/// Write granularity (4: stricter than the RP2040's 1, looser than the G4's 8).
pub const WRITE: usize = 4;
/// Active slot: 32 KiB, the DB images' budget.
pub const ACTIVE: usize = 32 * 1024;
/// DFU slot: one sector more (embassy-boot's swap needs it).
pub const DFU: usize = ACTIVE + ERASE;
/// State partition: one sector.
pub const STATE: usize = ERASE;
/// The session's write buffer.
pub const BUF: usize = 256;

/// How an operation that the power cut interrupts ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// It does not happen at all.
    Clean,
    /// Half of it happens (the first half of an erase's range is erased, the first half of a
    /// write's bytes programmed).
    Torn,
}

/// The power supply: how many more operations complete before the one the cut interrupts.
#[derive(Debug)]
pub struct Power {
    left: Cell<Option<u64>>,
    gone: Cell<bool>,
    cut: Cut,
    pub ops: Cell<u64>,
}

impl Power {
    pub fn new(left: Option<u64>, cut: Cut) -> Rc<Power> {
        Rc::new(Power {
            left: Cell::new(left),
            gone: Cell::new(false),
            cut,
            ops: Cell::new(0),
        })
    }

    pub fn dead(&self) -> bool {
        self.gone.get()
    }

    /// `Ok(true)`: the operation runs whole; `Ok(false)`: it is the one cut (torn or not);
    /// `Err`: no power.
    fn take(&self) -> Result<bool, FlashError> {
        if self.gone.get() {
            return Err(FlashError::PowerCut);
        }
        match self.left.get() {
            Some(0) => {
                self.gone.set(true);
                Ok(false)
            }
            Some(n) => {
                self.left.set(Some(n - 1));
                self.ops.set(self.ops.get() + 1);
                Ok(true)
            }
            None => {
                self.ops.set(self.ops.get() + 1);
                Ok(true)
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    PowerCut,
    NotAligned,
    OutOfBounds,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::PowerCut => NorFlashErrorKind::Other,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
        }
    }
}

/// One partition of the shared flash memory.
pub struct Part {
    pub mem: Rc<RefCell<Vec<u8>>>,
    pub base: usize,
    pub len: usize,
    pub power: Rc<Power>,
}

impl ErrorType for Part {
    type Error = FlashError;
}

impl ReadNorFlash for Part {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let o = offset as usize;
        if o + bytes.len() > self.len {
            return Err(FlashError::OutOfBounds);
        }
        let mem = self.mem.borrow();
        bytes.copy_from_slice(&mem[self.base + o..self.base + o + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.len
    }
}

impl NorFlash for Part {
    const WRITE_SIZE: usize = WRITE;
    const ERASE_SIZE: usize = ERASE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let (f, t) = (from as usize, to as usize);
        if !f.is_multiple_of(ERASE) || !t.is_multiple_of(ERASE) || f > t {
            return Err(FlashError::NotAligned);
        }
        if t > self.len {
            return Err(FlashError::OutOfBounds);
        }
        let whole = self.power.take()?;
        let end = if whole || self.power.cut == Cut::Clean {
            if whole {
                t
            } else {
                f
            }
        } else {
            f + (t - f) / 2
        };
        self.mem.borrow_mut()[self.base + f..self.base + end].fill(0xff);
        if whole {
            Ok(())
        } else {
            Err(FlashError::PowerCut)
        }
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let o = offset as usize;
        if !o.is_multiple_of(WRITE) || !bytes.len().is_multiple_of(WRITE) {
            return Err(FlashError::NotAligned);
        }
        if o + bytes.len() > self.len {
            return Err(FlashError::OutOfBounds);
        }
        let whole = self.power.take()?;
        let n = if whole {
            bytes.len()
        } else if self.power.cut == Cut::Torn {
            bytes.len() / 2
        } else {
            0
        };
        let mut mem = self.mem.borrow_mut();
        for (m, b) in mem[self.base + o..self.base + o + n].iter_mut().zip(bytes) {
            // NOR programming only clears bits.
            *m &= *b;
        }
        if whole {
            Ok(())
        } else {
            Err(FlashError::PowerCut)
        }
    }
}

/// A test image: `len` bytes from `seed`, its first bytes its version.
pub fn image(len: usize, version: [u8; 3], seed: u32) -> Vec<u8> {
    let mut x = seed.wrapping_mul(2_654_435_761).max(1);
    let mut v: Vec<u8> = (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect();
    v[..3].copy_from_slice(&version);
    v
}

pub const DB: u8 = 0x2a;
pub const KIND: BoardKind = BoardKind::PICO;

pub fn config() -> BootConfig {
    BootConfig {
        board: KIND,
        floor: [0, 2, 0],
        address: Address::new(DB).unwrap(),
    }
}

pub fn info(img: &[u8], version: [u8; 3]) -> ImageInfo {
    ImageInfo {
        len: img.len() as u32,
        crc32: x10_microcode::image_crc32(img),
        board: KIND,
        version,
    }
}

/// The flash of one board: state | active | DFU.
pub struct Board {
    pub mem: Rc<RefCell<Vec<u8>>>,
}

impl Board {
    /// A board whose active slot holds `img` (flashed by a probe), state erased (boot).
    pub fn new(img: &[u8]) -> Board {
        let mut mem = vec![0xffu8; STATE + ACTIVE + DFU];
        mem[STATE..STATE + img.len()].copy_from_slice(img);
        Board {
            mem: Rc::new(RefCell::new(mem)),
        }
    }

    pub fn part(&self, which: usize, power: &Rc<Power>) -> Part {
        let (base, len) = match which {
            0 => (0, STATE),
            1 => (STATE, ACTIVE),
            _ => (STATE + ACTIVE, DFU),
        };
        Part {
            mem: self.mem.clone(),
            base,
            len,
            power: power.clone(),
        }
    }

    pub fn active_is(&self, img: &[u8]) -> bool {
        self.mem.borrow()[STATE..STATE + img.len()] == *img
    }

    /// The bootloader's start: `prepare_boot`, then the mode.
    pub fn start(&self, power: &Rc<Power>) -> Result<(State, StartMode), ()> {
        let mut bl = BootLoader::new(BootLoaderConfig {
            active: self.part(1, power),
            dfu: self.part(2, power),
            state: self.part(0, power),
        });
        let mut buf = [0u8; BUF];
        let state = bl.prepare_boot(&mut buf).map_err(|_| ())?;
        let mode = x10_boot::start_mode(&state);
        Ok((state, mode))
    }

    /// System 12 in the application.
    pub fn enter_update(&self, power: &Rc<Power>) -> Result<(), ()> {
        let mut aligned = [0u8; WRITE];
        let mut st = BlockingFirmwareState::new(self.part(0, power), &mut aligned);
        x10_boot::enter_update(&mut st).map_err(|_| ())
    }

    /// System 13 in the application.
    pub fn confirm(&self, power: &Rc<Power>) -> Result<(), ()> {
        let mut aligned = [0u8; WRITE];
        let mut st = BlockingFirmwareState::new(self.part(0, power), &mut aligned);
        x10_boot::confirm_firmware(&mut st).map_err(|_| ())
    }

    pub fn state_magic(&self) -> State {
        let m = self.mem.borrow();
        State::from(&m[0..WRITE])
    }
}

/// The MB's side of one request to the bootloader: the frame with its check, the reply read
/// and checked; then the glue's part, the flash work.
pub fn call<D: NorFlash, S: NorFlash, const W: usize>(
    s: &mut Session<'_, D, S, W>,
    seq: u8,
    op: UpdateOp<'_>,
) -> (Status, Vec<u8>) {
    let mut data = [0u8; 28];
    let req = Request {
        db: Address::new(DB).unwrap(),
        seq,
        op: op.to_op(&mut data),
    };
    let mut buf = [0u8; 40];
    let n = req.emit_with_pec(&mut buf).unwrap();
    s.handle_write(&buf[..n]);
    read_reply(s, seq)
}

pub fn read_reply<D: NorFlash, S: NorFlash, const W: usize>(
    s: &mut Session<'_, D, S, W>,
    seq: u8,
) -> (Status, Vec<u8>) {
    let mut rx = [0u8; 40];
    let n = s.take_reply(&mut rx);
    let body = pec::strip(Address::new(DB).unwrap().addr_byte(true), &rx[..n]).unwrap();
    let r = Reply::parse(body).unwrap();
    assert_eq!(r.seq, seq);
    let out = (r.status, r.payload.to_vec());
    // The glue: the flash work once the reply has been read.
    s.work();
    out
}

/// A whole transfer: begin, every chunk, commit. The first status other than `ok`, or `ok`.
pub fn transfer<D: NorFlash, S: NorFlash, const W: usize>(
    s: &mut Session<'_, D, S, W>,
    img: &[u8],
    version: [u8; 3],
) -> Status {
    let (st, _) = call(s, 1, UpdateOp::Begin(info(img, version)));
    if st != Status::Ok {
        return st;
    }
    for (i, c) in img.chunks(CHUNK_MAX).enumerate() {
        let (st, _) = call(
            s,
            (i % 200) as u8 + 2,
            UpdateOp::Chunk {
                offset: (i * CHUNK_MAX) as u32,
                data: c,
            },
        );
        if st != Status::Ok {
            return st;
        }
    }
    call(s, 250, UpdateOp::Commit).0
}

pub fn status<D: NorFlash, S: NorFlash, const W: usize>(
    s: &mut Session<'_, D, S, W>,
) -> UpdateReport {
    let (st, p) = call(s, 251, UpdateOp::Status);
    assert_eq!(st, Status::Ok);
    UpdateReport::parse(&p).unwrap()
}

/// Runs a session in update mode on `board` with `power`: the transfer of `img`; its status
/// and the session's exit.
pub fn update_mode(
    board: &Board,
    power: &Rc<Power>,
    img: &[u8],
    version: [u8; 3],
) -> (Status, Exit) {
    let mut aligned = [0u8; WRITE];
    let st = BlockingFirmwareState::new(board.part(0, power), &mut aligned);
    let mut s: Session<'_, Part, Part, BUF> = Session::new(config(), board.part(2, power), st);
    let status = transfer(&mut s, img, version);
    (status, s.exit())
}
