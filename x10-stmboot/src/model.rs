//! A model of the STM32C011's ROM bootloader on I2C (AN4221) and of the chip's flash and
//! boot, for host tests and the simulator: what the [`Client`](crate::Client) talks to when
//! no board is at hand.
//!
//! What it models, and on what it rests:
//!
//! * the protocol: each command code with its complement, then [`ACK`] or [`NACK`]; the
//!   address frame (four bytes and their XOR); Read Memory's length and its complement;
//!   Write Memory's `n - 1`, data and XOR; the extended Erase's count and page list, each
//!   with its XOR (AN4221). A bad checksum, an unknown command, an address outside main
//!   flash, a page that does not exist, a no-stretch command before protocol version 1.1
//!   are all refused with [`NACK`] and the command ends there;
//! * the no-stretch commands answer [`BUSY`] until the flash is done, the stretching ones
//!   hold the clock (the read of their status takes that long);
//! * the flash: 2 KiB pages erased to 0xFF, programmed by double word (8 bytes at a multiple
//!   of 8; the model refuses other writes), a double word programmed only when erased (else
//!   the chip's `PROGERR`: [`NACK`]); the typical times of the datasheet for a page erase
//!   ([`T_ERASE_NS`]) and a double-word program ([`T_PROG_NS`]);
//! * power: [`RomModel::cut_at`] cuts the power before a chosen step (a step is every bus
//!   transaction, every page erase and every double-word program), after which the board
//!   answers nothing; [`RomModel::power_on`] boots it as the C0 does: the ROM bootloader if
//!   the first word of flash is 0xFFFFFFFF (the empty check, RM0490 §3.1.4), else the image
//!   in flash, whatever it is ([`RomModel::boot`] says which);
//! * time: the bus's wire time (nine bit times per byte and the address, two for start and
//!   stop, no gaps) at [`RomModel::bus_hz`], plus the flash's work, plus the client's
//!   delays ([`ModelDelay`]).
//!
//! A double-word program is one step: the model does not tear one in half (see
//! `docs/boards.md`, "Updating the boards", for that window).

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use embedded_hal_async::i2c::{ErrorKind, ErrorType, NoAcknowledgeSource, Operation};

use crate::{cmd, xor, Target, ACK, BUSY, C011, DOUBLE_WORD, NACK, ROM_ADDRESS};

/// Typical time to erase one 2 KiB page (STM32C011 datasheet, "Flash memory
/// characteristics", t_ERASE typical 22 ms).
pub const T_ERASE_NS: u64 = 22_000_000;
/// Typical time to program one double word (same table, t_prog typical 85 µs).
pub const T_PROG_NS: u64 = 85_000;

/// What the chip runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Boot {
    /// No power.
    Off,
    /// The ROM bootloader, answering at [`ROM_ADDRESS`].
    Rom,
    /// The image in main flash (whatever its bytes are): it does not answer at
    /// [`ROM_ADDRESS`].
    Flash,
}

/// Counts of what crossed the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// I2C transactions (each a start, the address, the bytes, a stop).
    pub transactions: u64,
    /// Bytes written and read, without the address bytes.
    pub bytes: u64,
    /// Pages erased.
    pub erases: u64,
    /// Double words programmed.
    pub programs: u64,
}

#[derive(Clone, Copy, Debug)]
enum Proto {
    Idle,
    Address(u8),
    ReadLength(u32),
    WriteData(u8, u32),
    EraseCount(u8),
    ErasePages(u8, u16),
}

#[derive(Clone, Copy, Debug)]
enum Out {
    /// An answer byte: ACK or NACK.
    Byte(u8),
    /// A data byte (Get Version's, Get ID's, Read Memory's): the client reads a command's
    /// data bytes in one read.
    Data(u8),
    /// A status byte ready at a time: before it, [`BUSY`] (no-stretch) or a stretched read.
    Status {
        byte: u8,
        ready_ns: u64,
        stretch: bool,
    },
}

/// The model's bus errors: nobody answered the address, or the client broke the protocol
/// (read with nothing to read, wrote while a reply was pending).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelError {
    /// No acknowledge of the address: the board is off or not in its bootloader.
    NoAck,
    /// A read when the bootloader has nothing to send, a write while it has.
    Protocol,
}

impl embedded_hal_async::i2c::Error for ModelError {
    fn kind(&self) -> ErrorKind {
        match self {
            ModelError::NoAck => ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address),
            ModelError::Protocol => ErrorKind::Other,
        }
    }
}

/// The chip: flash, boot state, the ROM bootloader's protocol state, a clock.
pub struct RomModel {
    flash: Vec<u8>,
    target: Target,
    /// The I2C protocol version Get Version answers.
    pub version: u8,
    /// The product ID Get ID answers.
    pub pid: u16,
    /// The bus clock, for the wire time.
    pub bus_hz: u32,
    boot: Boot,
    proto: Proto,
    out: VecDeque<Out>,
    pending_go: bool,
    now_ns: u64,
    step: u64,
    cut_at: Option<u64>,
    corrupt_write: Option<u32>,
    stuck_bit: Option<(usize, u8)>,
    stats: Stats,
}

impl RomModel {
    /// A C011 at 100 kHz running `image` (the rest of flash erased), protocol version 1.2.
    pub fn c011(image: &[u8]) -> Self {
        let target = C011;
        let mut flash = vec![0xFF; target.flash_size as usize];
        flash[..image.len()].copy_from_slice(image);
        RomModel {
            flash,
            target,
            version: 0x12,
            pid: target.pid,
            bus_hz: 100_000,
            boot: Boot::Flash,
            proto: Proto::Idle,
            out: VecDeque::new(),
            pending_go: false,
            now_ns: 0,
            step: 0,
            cut_at: None,
            corrupt_write: None,
            stuck_bit: None,
            stats: Stats::default(),
        }
    }

    /// Main flash.
    pub fn flash(&self) -> &[u8] {
        &self.flash
    }

    /// Whether main flash holds `image` followed by erased bytes only.
    pub fn holds(&self, image: &[u8]) -> bool {
        self.flash.starts_with(image) && self.flash[image.len()..].iter().all(|&b| b == 0xFF)
    }

    /// What the chip runs.
    pub fn boot(&self) -> Boot {
        self.boot
    }

    /// The model's clock: nanoseconds since it was made.
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Moves the model's clock on by `ns` (time spent elsewhere: the rest of the bus, the
    /// motherboard's pauses).
    pub fn advance_ns(&mut self, ns: u64) {
        self.now_ns += ns;
    }

    /// Moves the model's clock on to `ns` unless it is there already (a bus whose own clock
    /// counted the wire time: the simulator's).
    pub fn catch_up_ns(&mut self, ns: u64) {
        self.now_ns = self.now_ns.max(ns);
    }

    /// How many bytes the client's next read takes, by AN4221's order: one for an answer
    /// (ACK, NACK or BUSY), else the data bytes before the next answer (Get Version's
    /// version, Get ID's three, Read Memory's block). For a target on a bus that does not
    /// tell it the read's length (the simulator's).
    pub fn next_read_len(&self) -> usize {
        match self.out.front() {
            None => 0,
            Some(Out::Status { .. } | Out::Byte(_)) => 1,
            Some(Out::Data(_)) => self
                .out
                .iter()
                .take_while(|o| matches!(o, Out::Data(_)))
                .count(),
        }
    }

    /// Steps so far (bus transactions, page erases, double-word programs).
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// Counts of the bus and flash work so far.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// Cuts the power just before step `step` (counted from the model's creation).
    pub fn cut_at(&mut self, step: u64) {
        self.cut_at = Some(step);
    }

    /// Flips the lowest bit of the last byte of the `n`-th frame the client writes from now
    /// (0: the next one), a glitch on the wire: the byte that carries the checksum.
    pub fn corrupt_write(&mut self, n: u32) {
        self.corrupt_write = Some(n);
    }

    /// A flash cell that stays 1: bit `mask` of byte `offset` never programs.
    pub fn stick_bit(&mut self, offset: usize, mask: u8) {
        self.stuck_bit = Some((offset, mask));
    }

    /// The running image's System 12: it jumps into the ROM bootloader (`c011::enter_rom` in
    /// x10-boards). Nothing happens unless the image runs.
    pub fn enter_rom(&mut self) {
        if self.boot == Boot::Flash {
            self.boot = Boot::Rom;
            self.reset_protocol();
        }
    }

    /// Power comes back: the C0's boot (the empty check picks the ROM bootloader when the
    /// first word of flash is erased). The cut, if any, is spent.
    pub fn power_on(&mut self) -> Boot {
        self.cut_at = None;
        self.reset_protocol();
        self.boot = if self.flash[..4] == [0xFF; 4] {
            Boot::Rom
        } else {
            Boot::Flash
        };
        self.boot
    }

    fn reset_protocol(&mut self) {
        self.proto = Proto::Idle;
        self.out.clear();
        self.pending_go = false;
    }

    /// Counts a step; false (and the power off) if the cut falls on it.
    fn step(&mut self) -> bool {
        if self.boot == Boot::Off {
            return false;
        }
        if self.cut_at == Some(self.step) {
            self.boot = Boot::Off;
            self.reset_protocol();
            return false;
        }
        self.step += 1;
        true
    }

    fn wire(&mut self, bytes: usize) {
        self.stats.transactions += 1;
        self.stats.bytes += bytes as u64;
        let bits = 9 * (1 + bytes as u64) + 2;
        self.now_ns += bits * 1_000_000_000 / u64::from(self.bus_hz);
    }

    fn end(&self) -> u32 {
        self.target.flash_base + self.target.flash_size
    }

    fn nack(&mut self) {
        self.out.push_back(Out::Byte(NACK));
        self.proto = Proto::Idle;
    }

    fn status(&mut self, byte: u8, work_ns: u64, command: u8) {
        let stretch = !matches!(
            command,
            cmd::NO_STRETCH_WRITE_MEMORY | cmd::NO_STRETCH_ERASE
        );
        self.out.push_back(Out::Status {
            byte,
            ready_ns: self.now_ns + work_ns,
            stretch,
        });
        self.proto = Proto::Idle;
    }

    /// The master writes `bytes` to the board.
    ///
    /// # Errors
    /// [`ModelError::NoAck`] when the board is off or not in its bootloader,
    /// [`ModelError::Protocol`] when a reply is still waiting to be read.
    pub fn write(&mut self, bytes: &[u8]) -> Result<(), ModelError> {
        if !self.step() || self.boot != Boot::Rom {
            return Err(ModelError::NoAck);
        }
        if !self.out.is_empty() {
            return Err(ModelError::Protocol);
        }
        self.wire(bytes.len());
        let mut b = bytes.to_vec();
        match self.corrupt_write {
            Some(0) => {
                self.corrupt_write = None;
                if let Some(x) = b.last_mut() {
                    *x ^= 0x01;
                }
            }
            Some(n) => self.corrupt_write = Some(n - 1),
            None => {}
        }
        match self.proto {
            Proto::Idle => self.command(&b),
            Proto::Address(c) => self.address(c, &b),
            Proto::ReadLength(a) => self.read_length(a, &b),
            Proto::WriteData(c, a) => self.write_data(c, a, &b),
            Proto::EraseCount(c) => self.erase_count(c, &b),
            Proto::ErasePages(c, n) => self.erase_pages(c, n, &b),
        }
        Ok(())
    }

    fn command(&mut self, b: &[u8]) {
        let [c, check] = b else {
            return self.nack();
        };
        let no_stretch = matches!(*c, cmd::NO_STRETCH_WRITE_MEMORY | cmd::NO_STRETCH_ERASE);
        if *check != !*c || (no_stretch && self.version < crate::FIRST_NO_STRETCH_VERSION) {
            return self.nack();
        }
        let c = *c;
        match c {
            cmd::GET_VERSION => {
                let v = self.version;
                self.out
                    .extend([Out::Byte(ACK), Out::Data(v), Out::Byte(ACK)]);
            }
            cmd::GET_ID => {
                let [hi, lo] = self.pid.to_be_bytes();
                self.out.push_back(Out::Byte(ACK));
                self.out.extend([1, hi, lo].map(Out::Data));
                self.out.push_back(Out::Byte(ACK));
            }
            cmd::READ_MEMORY | cmd::GO | cmd::WRITE_MEMORY | cmd::NO_STRETCH_WRITE_MEMORY => {
                self.out.push_back(Out::Byte(ACK));
                self.proto = Proto::Address(c);
            }
            cmd::ERASE | cmd::NO_STRETCH_ERASE => {
                self.out.push_back(Out::Byte(ACK));
                self.proto = Proto::EraseCount(c);
            }
            _ => self.nack(),
        }
    }

    fn address(&mut self, c: u8, b: &[u8]) {
        let [a0, a1, a2, a3, check] = b else {
            return self.nack();
        };
        let a = [*a0, *a1, *a2, *a3];
        let address = u32::from_be_bytes(a);
        let in_flash = (self.target.flash_base..self.end()).contains(&address);
        let aligned = (address as usize).is_multiple_of(DOUBLE_WORD);
        let writes = matches!(c, cmd::WRITE_MEMORY | cmd::NO_STRETCH_WRITE_MEMORY);
        if *check != xor(&a) || !in_flash || (writes && !aligned) {
            return self.nack();
        }
        self.out.push_back(Out::Byte(ACK));
        self.proto = match c {
            cmd::READ_MEMORY => Proto::ReadLength(address),
            cmd::GO => {
                self.pending_go = true;
                Proto::Idle
            }
            _ => Proto::WriteData(c, address),
        };
    }

    fn read_length(&mut self, address: u32, b: &[u8]) {
        let [n, check] = b else {
            return self.nack();
        };
        let n = usize::from(*n) + 1;
        let start = (address - self.target.flash_base) as usize;
        if *check != !b[0] || start + n > self.flash.len() {
            return self.nack();
        }
        self.out.push_back(Out::Byte(ACK));
        for i in start..start + n {
            self.out.push_back(Out::Data(self.flash[i]));
        }
        self.proto = Proto::Idle;
    }

    fn write_data(&mut self, c: u8, address: u32, b: &[u8]) {
        let Some((&check, rest)) = b.split_last() else {
            return self.nack();
        };
        let Some((&m, data)) = rest.split_first() else {
            return self.nack();
        };
        let start = (address - self.target.flash_base) as usize;
        if check != xor(rest)
            || data.len() != usize::from(m) + 1
            || data.len() % DOUBLE_WORD != 0
            || start + data.len() > self.flash.len()
        {
            return self.nack();
        }
        let mut work = 0;
        for (i, dw) in data.chunks_exact(DOUBLE_WORD).enumerate() {
            if !self.step() {
                return;
            }
            let at = start + i * DOUBLE_WORD;
            let cell = &mut self.flash[at..at + DOUBLE_WORD];
            if cell.iter().any(|&x| x != 0xFF) {
                // PROGERR: a double word programmed twice.
                return self.status(NACK, work, c);
            }
            cell.copy_from_slice(dw);
            if let Some((o, mask)) = self.stuck_bit {
                if (at..at + DOUBLE_WORD).contains(&o) {
                    self.flash[o] |= mask;
                }
            }
            self.stats.programs += 1;
            work += T_PROG_NS;
        }
        self.status(ACK, work, c);
    }

    fn erase_count(&mut self, c: u8, b: &[u8]) {
        let [hi, lo, check] = b else {
            return self.nack();
        };
        let v = u16::from_be_bytes([*hi, *lo]);
        // The special codes (0xFFFF mass erase, 0xFFFE/0xFFFD banks) are refused: the
        // client never sends them, and the model need not model them.
        if *check != hi ^ lo || v >= self.target.pages() {
            return self.nack();
        }
        self.out.push_back(Out::Byte(ACK));
        self.proto = Proto::ErasePages(c, v + 1);
    }

    fn erase_pages(&mut self, c: u8, count: u16, b: &[u8]) {
        let Some((&check, list)) = b.split_last() else {
            return self.nack();
        };
        if check != xor(list) || list.len() != 2 * usize::from(count) {
            return self.nack();
        }
        let pages: Vec<u16> = list
            .chunks_exact(2)
            .map(|p| u16::from_be_bytes([p[0], p[1]]))
            .collect();
        if pages.iter().any(|&p| p >= self.target.pages()) {
            return self.nack();
        }
        let size = self.target.page_size as usize;
        let mut work = 0;
        for p in pages {
            if !self.step() {
                return;
            }
            let at = usize::from(p) * size;
            self.flash[at..at + size].fill(0xFF);
            self.stats.erases += 1;
            work += T_ERASE_NS;
        }
        self.status(ACK, work, c);
    }

    /// The master reads `buf.len()` bytes from the board.
    ///
    /// # Errors
    /// [`ModelError::NoAck`] when the board is off or not in its bootloader,
    /// [`ModelError::Protocol`] when it has fewer bytes to send.
    pub fn read(&mut self, buf: &mut [u8]) -> Result<(), ModelError> {
        if !self.step() || self.boot != Boot::Rom {
            return Err(ModelError::NoAck);
        }
        self.wire(buf.len());
        for b in buf.iter_mut() {
            *b = match self.out.front().copied() {
                None => return Err(ModelError::Protocol),
                Some(Out::Byte(x) | Out::Data(x)) => {
                    self.out.pop_front();
                    x
                }
                Some(Out::Status {
                    byte,
                    ready_ns,
                    stretch,
                }) => {
                    if self.now_ns < ready_ns && !stretch {
                        BUSY
                    } else {
                        self.now_ns = self.now_ns.max(ready_ns);
                        self.out.pop_front();
                        byte
                    }
                }
            };
        }
        if self.pending_go && self.out.is_empty() {
            // Go: the bootloader has acknowledged the address and jumps.
            self.pending_go = false;
            self.boot = Boot::Flash;
        }
        Ok(())
    }
}

/// The model on an I2C bus: it answers [`ROM_ADDRESS`] only.
#[derive(Clone)]
pub struct ModelBus(pub Rc<RefCell<RomModel>>);

impl ErrorType for ModelBus {
    type Error = ModelError;
}

impl embedded_hal_async::i2c::I2c for ModelBus {
    async fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), ModelError> {
        if address != ROM_ADDRESS {
            return Err(ModelError::NoAck);
        }
        let mut m = self.0.borrow_mut();
        for op in operations {
            match op {
                Operation::Write(b) => m.write(b)?,
                Operation::Read(b) => m.read(b)?,
            }
        }
        Ok(())
    }
}

/// The client's delay on the model's clock (no real waiting).
#[derive(Clone)]
pub struct ModelDelay(pub Rc<RefCell<RomModel>>);

impl embedded_hal_async::delay::DelayNs for ModelDelay {
    async fn delay_ns(&mut self, ns: u32) {
        self.0.borrow_mut().now_ns += u64::from(ns);
    }
}

/// A model shared by a [`ModelBus`] and a [`ModelDelay`], and both.
pub fn rig(model: RomModel) -> (Rc<RefCell<RomModel>>, ModelBus, ModelDelay) {
    let m = Rc::new(RefCell::new(model));
    (m.clone(), ModelBus(m.clone()), ModelDelay(m))
}
