//! # x10-stmboot: updating an STM32C011 daughterboard through ST's ROM bootloader
//!
//! The STM32C011 has 32 KiB of flash: one X10 image fills it, and there is no room for a
//! bootloader of our own, let alone two slots. Every STM32 carries ST's bootloader in its
//! system memory (ROM, 0x1FFF0000), which speaks ST's I2C protocol (application note AN4221)
//! on the pins the C011 board already uses for the X10 bus (I2C1, PB6/PB7), at 7-bit address
//! [`ROM_ADDRESS`] (0x64). Arduino's Modulino boards (the same chip) are updated this way.
//! This crate is the motherboard's side: a [`Client`] of that protocol, async over
//! `embedded_hal_async::i2c::I2c`, and [`update`], the order of operations that keeps the
//! board updatable whatever happens. `docs/boards.md` ("Updating the boards") says what each
//! claim about the chip rests on.
//!
//! ## Why a power cut cannot brick the board
//!
//! The C0 boots from main flash, except when the first word of main flash reads 0xFFFFFFFF
//! at power-on: then its "empty check" boots the ROM bootloader instead (RM0490 §3.1, table
//! "Boot modes", note 1, and §3.1.4; the `EMPTY` bit of `FLASH_ACR`). So [`update`]:
//!
//! 1. asks the bootloader's version (Get Version) and the chip's product ID (Get ID), and
//!    refuses any chip but the [`Target`]'s;
//! 2. erases page 0 first: from that moment on, every power-on starts the ROM bootloader,
//!    which answers the motherboard at [`ROM_ADDRESS`];
//! 3. erases the other pages;
//! 4. writes the image except its first double word (bytes 8 to the end), skipping blocks
//!    that are all 0xFF, and reads it back (Read Memory);
//! 5. writes the first double word (the initial stack pointer and the reset vector) last,
//!    reads it back, then jumps to the image (Go).
//!
//! A power cut before step 2 leaves the old image; from step 2 until the first double word
//! is programmed, a board whose first word is erased (the ROM bootloader answers, the
//! motherboard starts again); after it, the new image, whole and verified. The model
//! ([`model`], feature `model`) checks this at every step: `tests/power_cut.rs`.
//!
//! ## No clock stretching
//!
//! Erasing a 2 KiB page takes about 22 ms and programming 256 bytes about 2.7 ms. The plain
//! Write Memory and Erase commands hold SCL low (clock stretching) while the flash is busy,
//! which would stop every other call of the robot on the shared bus. From I2C protocol
//! version 1.1 the bootloader has "no-stretch" variants (0x32, 0x45) that answer
//! [`BUSY`] (0x76) instead while the flash works; the client uses them when the version
//! allows and polls the status with a delay in between, leaving the bus free.
//!
//! ## One board at a time
//!
//! Every C011 in its ROM bootloader answers the same address, 0x64: the motherboard sends one
//! board at a time into it and finishes that board before the next. A board found answering
//! at 0x64 at start-up is one whose update was cut: the motherboard updates it first.
#![cfg_attr(not(feature = "model"), no_std)]

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;

#[cfg(feature = "model")]
pub mod model;

/// The 7-bit I2C address of the STM32C011's ROM bootloader: Arduino's Modulino library's
/// `MODULINO_BOOTLOADER_ADDR` and its MicroPython flasher's `BOOTLOADER_I2C_ADDRESS`, for the
/// same chip on the same pins (AN2606's STM32C011xx section was not at hand).
pub const ROM_ADDRESS: u8 = 0x64;

/// The bootloader's acknowledge byte.
pub const ACK: u8 = 0x79;
/// The bootloader's refusal: an unknown command, a bad checksum, an address it does not
/// accept, or a flash operation that failed.
pub const NACK: u8 = 0x1F;
/// The no-stretch commands' "still working" answer: read the status again later.
pub const BUSY: u8 = 0x76;

/// The AN4221 command codes the client uses.
pub mod cmd {
    /// Get Version: the I2C protocol version (one byte, 0x10 is 1.0).
    pub const GET_VERSION: u8 = 0x01;
    /// Get ID: the chip's product ID (two bytes).
    pub const GET_ID: u8 = 0x02;
    /// Read Memory: up to 256 bytes from an address.
    pub const READ_MEMORY: u8 = 0x11;
    /// Go: jump to the image whose vector table is at an address.
    pub const GO: u8 = 0x21;
    /// Write Memory (stretches the clock while programming).
    pub const WRITE_MEMORY: u8 = 0x31;
    /// No-Stretch Write Memory (answers [`BUSY`](crate::BUSY) while programming).
    pub const NO_STRETCH_WRITE_MEMORY: u8 = 0x32;
    /// Erase (the extended erase: two-byte page numbers; stretches the clock).
    pub const ERASE: u8 = 0x44;
    /// No-Stretch Erase (answers [`BUSY`](crate::BUSY) while erasing).
    pub const NO_STRETCH_ERASE: u8 = 0x45;
}

/// The first I2C protocol version with the no-stretch commands (1.1).
pub const FIRST_NO_STRETCH_VERSION: u8 = 0x11;

/// The most bytes one Read Memory or Write Memory carries.
pub const MAX_BLOCK: usize = 256;

/// The flash programs double words: every write is a multiple of 8 bytes at an address
/// that is a multiple of 8 (the client pads the image's last block with 0xFF).
pub const DOUBLE_WORD: usize = 8;

/// The chip being updated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Target {
    /// Where main flash starts (its first double word is the vector table's start).
    pub flash_base: u32,
    /// Bytes of main flash the image may use.
    pub flash_size: u32,
    /// Bytes of one erase page.
    pub page_size: u32,
    /// The product ID Get ID must answer.
    pub pid: u16,
}

/// The STM32C011F6: 32 KiB of flash at 0x08000000 in 2 KiB pages (embassy-stm32 0.6's
/// generated `BANK1_REGION` for the chip), product ID 0x443 (the C011's `DEV_ID`, which
/// the bootloader's Get ID returns).
pub const C011: Target = Target {
    flash_base: 0x0800_0000,
    flash_size: 32 * 1024,
    page_size: 2048,
    pid: 0x443,
};

impl Target {
    /// The target of an X10 board kind (`x10_microcode::BoardKind`'s code) updated through
    /// the ROM bootloader: 5, the STM32C011 ([`C011`]). `None` for every other kind.
    pub const fn for_board_kind(kind: u8) -> Option<Target> {
        match kind {
            5 => Some(C011),
            _ => None,
        }
    }

    /// Number of erase pages of main flash.
    pub const fn pages(&self) -> u16 {
        (self.flash_size / self.page_size) as u16
    }
}

/// XOR of all bytes: AN4221's checksum (a single byte is sent with its complement instead).
pub fn xor(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |a, b| a ^ b)
}

/// A command: its code and the code's complement.
pub const fn command_frame(code: u8) -> [u8; 2] {
    [code, !code]
}

/// An address: four bytes, most significant first, then their XOR.
pub fn address_frame(address: u32) -> [u8; 5] {
    let a = address.to_be_bytes();
    [a[0], a[1], a[2], a[3], xor(&a)]
}

/// Read Memory's length: `n - 1` and its complement (`n` in `1..=256`).
pub fn length_frame(n: usize) -> Option<[u8; 2]> {
    let m = u8::try_from(n.checked_sub(1)?).ok()?;
    Some([m, !m])
}

/// Erase's first frame: the number of pages minus one, two bytes, then their XOR.
pub fn erase_count_frame(count: u16) -> Option<[u8; 3]> {
    let c = count.checked_sub(1)?.to_be_bytes();
    Some([c[0], c[1], c[0] ^ c[1]])
}

/// Erase's second frame for `count` pages from `first`: each page number in two bytes,
/// most significant first, then the XOR of them all. `None` if they do not fit `buf`.
pub fn erase_pages_frame(first: u16, count: u16, buf: &mut [u8]) -> Option<&[u8]> {
    let n = 2 * usize::from(count) + 1;
    let frame = buf.get_mut(..n)?;
    for (i, pair) in frame.chunks_exact_mut(2).enumerate() {
        let page = first.checked_add(u16::try_from(i).ok()?)?;
        pair.copy_from_slice(&page.to_be_bytes());
    }
    frame[n - 1] = xor(&frame[..n - 1]);
    Some(frame)
}

/// Write Memory's data frame: `n - 1`, the `n` bytes, then the XOR of all that (`n` in
/// `1..=256`). `None` if `data` is empty or too long.
pub fn data_frame<'a>(data: &[u8], buf: &'a mut [u8; MAX_BLOCK + 2]) -> Option<&'a [u8]> {
    let m = u8::try_from(data.len().checked_sub(1)?).ok()?;
    buf[0] = m;
    buf[1..=data.len()].copy_from_slice(data);
    buf[data.len() + 1] = xor(&buf[..=data.len()]);
    Some(&buf[..data.len() + 2])
}

/// The blocks [`update`] writes in step 4: the image but its first double word, cut at
/// multiples of [`MAX_BLOCK`] from the start of flash, each `(offset, length)` with the
/// length rounded up to a whole double word (the part past the image is padded with 0xFF).
pub fn blocks(image_len: usize) -> impl Iterator<Item = (usize, usize)> {
    blocks_of(image_len, MAX_BLOCK)
}

/// [`blocks`] cut at multiples of `block` bytes instead (a multiple of [`DOUBLE_WORD`] up to
/// [`MAX_BLOCK`]; [`Client::block`]).
pub fn blocks_of(image_len: usize, block: usize) -> impl Iterator<Item = (usize, usize)> {
    let block = block.clamp(DOUBLE_WORD, MAX_BLOCK) / DOUBLE_WORD * DOUBLE_WORD;
    let end = image_len.div_ceil(DOUBLE_WORD) * DOUBLE_WORD;
    (0..end.div_ceil(block)).filter_map(move |i| {
        let start = (i * block).max(DOUBLE_WORD);
        let stop = ((i + 1) * block).min(end);
        (start < stop).then_some((start, stop - start))
    })
}

/// Which part of a command the bootloader refused or answered oddly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Phase {
    /// The command code.
    Command,
    /// The address frame.
    Address,
    /// Read Memory's length frame.
    Length,
    /// Erase's page count.
    Count,
    /// Erase's page list (the erase itself).
    Pages,
    /// Write Memory's data (the programming itself).
    Data,
}

/// What can go wrong: the bus, the bootloader's refusals, a wrong chip, a wrong image, a
/// read-back that differs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The bus failed: no board at the address (not in its bootloader, or unpowered), an
    /// arbitration loss, a timeout.
    Bus(E),
    /// The bootloader answered [`NACK`].
    Nack {
        /// The command.
        command: u8,
        /// What it refused.
        phase: Phase,
    },
    /// The bootloader answered something that is neither [`ACK`], [`NACK`] nor [`BUSY`].
    Unexpected {
        /// The command.
        command: u8,
        /// Where.
        phase: Phase,
        /// The byte.
        byte: u8,
    },
    /// Still [`BUSY`] after the client's time budget (`Client::busy_timeout_us`).
    StillBusy {
        /// The command.
        command: u8,
    },
    /// A reply whose length byte is not the one the command has.
    BadReply {
        /// The command.
        command: u8,
    },
    /// The chip is not the target (its product ID).
    WrongChip {
        /// What Get ID answered.
        pid: u16,
    },
    /// The image is empty or larger than the target's flash.
    BadImage {
        /// Its length in bytes.
        len: usize,
    },
    /// A Read Memory or Write Memory of no bytes or of more than [`MAX_BLOCK`].
    BadLength {
        /// The length asked.
        len: usize,
    },
    /// The flash read back differs from the image: the first differing address.
    Verify {
        /// Its address.
        address: u32,
    },
}

/// What an [`update`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Report {
    /// The bootloader's I2C protocol version.
    pub version: u8,
    /// Whether it used the no-stretch commands.
    pub no_stretch: bool,
    /// Bytes programmed (the image rounded up to double words, without the blocks of 0xFF
    /// left out).
    pub written: u32,
    /// Blocks left out because they were all 0xFF (erased flash already reads so).
    pub skipped: u32,
    /// [`BUSY`] answers read while the flash worked.
    pub busy_polls: u32,
}

/// A client of the ROM bootloader over I2C: one command at a time, each answered by
/// [`ACK`] or a typed [`Error`].
pub struct Client<I, D> {
    i2c: I,
    delay: D,
    address: u8,
    /// Microseconds between two reads of a [`BUSY`] status.
    pub poll_us: u32,
    /// Microseconds of [`BUSY`] answers after which a command fails with
    /// [`Error::StillBusy`].
    pub busy_timeout_us: u32,
    /// Bytes [`update`] writes and reads back per Write Memory and Read Memory: a multiple of
    /// [`DOUBLE_WORD`] up to [`MAX_BLOCK`] (the default). A bus whose transfers are shorter
    /// (the motherboard's: 24 bytes) sets it lower.
    pub block: usize,
    no_stretch: bool,
    busy_polls: u32,
}

impl<I: I2c, D: DelayNs> Client<I, D> {
    /// A client of the bootloader at [`ROM_ADDRESS`], polling every 500 µs, giving up after
    /// 2 s of [`BUSY`] (the C011's worst page erase is 40 ms, fifteen pages 0.6 s). It uses
    /// the stretching commands until [`get_version`](Self::get_version) says otherwise.
    pub fn new(i2c: I, delay: D) -> Self {
        Client {
            i2c,
            delay,
            address: ROM_ADDRESS,
            poll_us: 500,
            busy_timeout_us: 2_000_000,
            block: MAX_BLOCK,
            no_stretch: false,
            busy_polls: 0,
        }
    }

    /// The bus and the delay back.
    pub fn release(self) -> (I, D) {
        (self.i2c, self.delay)
    }

    /// Whether Write Memory and Erase use the no-stretch variants.
    pub fn no_stretch(&self) -> bool {
        self.no_stretch
    }

    async fn send(&mut self, bytes: &[u8]) -> Result<(), Error<I::Error>> {
        self.i2c
            .write(self.address, bytes)
            .await
            .map_err(Error::Bus)
    }

    async fn receive(&mut self, buf: &mut [u8]) -> Result<(), Error<I::Error>> {
        self.i2c.read(self.address, buf).await.map_err(Error::Bus)
    }

    /// Reads the status byte until it is not [`BUSY`].
    async fn status(&mut self, command: u8, phase: Phase) -> Result<(), Error<I::Error>> {
        let mut waited: u32 = 0;
        loop {
            let mut b = [0u8];
            self.receive(&mut b).await?;
            match b[0] {
                ACK => return Ok(()),
                NACK => return Err(Error::Nack { command, phase }),
                BUSY if waited < self.busy_timeout_us => {
                    self.busy_polls += 1;
                    self.delay.delay_us(self.poll_us).await;
                    waited = waited.saturating_add(self.poll_us.max(1));
                }
                BUSY => return Err(Error::StillBusy { command }),
                byte => {
                    return Err(Error::Unexpected {
                        command,
                        phase,
                        byte,
                    })
                }
            }
        }
    }

    async fn frame(
        &mut self,
        bytes: &[u8],
        command: u8,
        phase: Phase,
    ) -> Result<(), Error<I::Error>> {
        self.send(bytes).await?;
        self.status(command, phase).await
    }

    async fn command(&mut self, code: u8) -> Result<(), Error<I::Error>> {
        self.frame(&command_frame(code), code, Phase::Command).await
    }

    /// Get Version: the I2C protocol version; from 1.1 ([`FIRST_NO_STRETCH_VERSION`]) on,
    /// later writes and erases use the no-stretch commands.
    ///
    /// # Errors
    /// The bus's, a [`NACK`].
    pub async fn get_version(&mut self) -> Result<u8, Error<I::Error>> {
        self.command(cmd::GET_VERSION).await?;
        let mut v = [0u8];
        self.receive(&mut v).await?;
        self.status(cmd::GET_VERSION, Phase::Command).await?;
        self.no_stretch = v[0] >= FIRST_NO_STRETCH_VERSION;
        Ok(v[0])
    }

    /// Get ID: the chip's product ID.
    ///
    /// # Errors
    /// The bus's, a [`NACK`], [`Error::BadReply`] if the reply is not two bytes long.
    pub async fn get_id(&mut self) -> Result<u16, Error<I::Error>> {
        self.command(cmd::GET_ID).await?;
        let mut r = [0u8; 3];
        self.receive(&mut r).await?;
        self.status(cmd::GET_ID, Phase::Command).await?;
        if r[0] != 1 {
            return Err(Error::BadReply {
                command: cmd::GET_ID,
            });
        }
        Ok(u16::from_be_bytes([r[1], r[2]]))
    }

    /// Read Memory: `buf.len()` bytes (1 to 256) from `address`.
    ///
    /// # Errors
    /// The bus's, a [`NACK`] (an address the bootloader does not read), [`Error::BadLength`].
    pub async fn read_memory(
        &mut self,
        address: u32,
        buf: &mut [u8],
    ) -> Result<(), Error<I::Error>> {
        let len = length_frame(buf.len()).ok_or(Error::BadLength { len: buf.len() })?;
        let c = cmd::READ_MEMORY;
        self.command(c).await?;
        self.frame(&address_frame(address), c, Phase::Address)
            .await?;
        self.frame(&len, c, Phase::Length).await?;
        self.receive(buf).await
    }

    /// Write Memory: `data` (1 to 256 bytes) at `address`, with the no-stretch command
    /// when the version allows it.
    ///
    /// # Errors
    /// The bus's, a [`NACK`] (a bad address, a bad checksum, a failed program),
    /// [`Error::StillBusy`], [`Error::BadLength`].
    pub async fn write_memory(&mut self, address: u32, data: &[u8]) -> Result<(), Error<I::Error>> {
        let mut buf = [0u8; MAX_BLOCK + 2];
        let frame = data_frame(data, &mut buf).ok_or(Error::BadLength { len: data.len() })?;
        let c = if self.no_stretch {
            cmd::NO_STRETCH_WRITE_MEMORY
        } else {
            cmd::WRITE_MEMORY
        };
        self.command(c).await?;
        self.frame(&address_frame(address), c, Phase::Address)
            .await?;
        self.frame(frame, c, Phase::Data).await
    }

    /// Erase: `count` pages (1 to 64 here) from page `first`.
    ///
    /// # Errors
    /// The bus's, a [`NACK`] (a page that does not exist, a failed erase),
    /// [`Error::StillBusy`], [`Error::BadLength`] for 0 or more than 64 pages.
    pub async fn erase_pages(&mut self, first: u16, count: u16) -> Result<(), Error<I::Error>> {
        let mut buf = [0u8; 2 * 64 + 1];
        let bad = || Error::BadLength {
            len: usize::from(count),
        };
        let head = erase_count_frame(count).ok_or_else(bad)?;
        let pages = erase_pages_frame(first, count, &mut buf).ok_or_else(bad)?;
        let c = if self.no_stretch {
            cmd::NO_STRETCH_ERASE
        } else {
            cmd::ERASE
        };
        self.command(c).await?;
        self.frame(&head, c, Phase::Count).await?;
        self.frame(pages, c, Phase::Pages).await
    }

    /// Go: the bootloader jumps to the image whose vector table is at `address`.
    ///
    /// # Errors
    /// The bus's, a [`NACK`] (an address it does not jump to).
    pub async fn go(&mut self, address: u32) -> Result<(), Error<I::Error>> {
        let c = cmd::GO;
        self.command(c).await?;
        self.frame(&address_frame(address), c, Phase::Address).await
    }

    /// Reads `image.len()` bytes at `address` back and compares them.
    async fn verify(&mut self, address: u32, image: &[u8]) -> Result<(), Error<I::Error>> {
        let mut buf = [0u8; MAX_BLOCK];
        let got = &mut buf[..image.len()];
        self.read_memory(address, got).await?;
        match got.iter().zip(image).position(|(a, b)| a != b) {
            None => Ok(()),
            Some(i) => Err(Error::Verify {
                address: address + i as u32,
            }),
        }
    }
}

/// Writes `image` to the target's flash through the bootloader, in the order that keeps the
/// board updatable across a power cut at any step (the crate's documentation), then starts
/// it (Go). The client must be talking to a board already in its bootloader.
///
/// # Errors
/// [`Error::BadImage`] before any bus traffic for an empty image or one larger than the
/// flash; [`Error::WrongChip`]; the client's errors. After an error the board is left
/// either as it was (before the first erase) or with its first word erased: call `update`
/// again (after a power cycle if it no longer answers).
pub async fn update<I: I2c, D: DelayNs>(
    client: &mut Client<I, D>,
    target: &Target,
    image: &[u8],
) -> Result<Report, Error<I::Error>> {
    if image.is_empty() || image.len() > target.flash_size as usize {
        return Err(Error::BadImage { len: image.len() });
    }
    client.busy_polls = 0;
    let version = client.get_version().await?;
    let pid = client.get_id().await?;
    if pid != target.pid {
        return Err(Error::WrongChip { pid });
    }
    // Page 0 first: from here on every power-on boots the ROM bootloader (empty check).
    client.erase_pages(0, 1).await?;
    if target.pages() > 1 {
        client.erase_pages(1, target.pages() - 1).await?;
    }
    let base = target.flash_base;
    let mut written = 0u32;
    let mut skipped = 0u32;
    let mut block = [0xFFu8; MAX_BLOCK];
    for (offset, len) in blocks_of(image.len(), client.block) {
        let b = fill(&mut block, image, offset, len);
        if b.iter().all(|&x| x == 0xFF) {
            skipped += 1;
            continue;
        }
        client.write_memory(base + offset as u32, b).await?;
        written += len as u32;
    }
    for (offset, len) in blocks_of(image.len(), client.block) {
        let b = fill(&mut block, image, offset, len);
        let mut want = [0u8; MAX_BLOCK];
        want[..len].copy_from_slice(b);
        client.verify(base + offset as u32, &want[..len]).await?;
    }
    // The first double word last: the image exists only once it is whole.
    let first = fill(&mut block, image, 0, DOUBLE_WORD);
    let mut head = [0u8; DOUBLE_WORD];
    head.copy_from_slice(first);
    client.write_memory(base, &head).await?;
    written += DOUBLE_WORD as u32;
    client.verify(base, &head).await?;
    client.go(base).await?;
    Ok(Report {
        version,
        no_stretch: client.no_stretch,
        written,
        skipped,
        busy_polls: client.busy_polls,
    })
}

/// `len` bytes of `image` from `offset`, padded with 0xFF past its end, in `block`.
fn fill<'a>(block: &'a mut [u8; MAX_BLOCK], image: &[u8], offset: usize, len: usize) -> &'a [u8] {
    let b = &mut block[..len];
    b.fill(0xFF);
    let have = image.len().saturating_sub(offset).min(len);
    b[..have].copy_from_slice(&image[offset..offset + have]);
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_carry_an4221_checksums() {
        assert_eq!(command_frame(cmd::NO_STRETCH_WRITE_MEMORY), [0x32, 0xCD]);
        assert_eq!(command_frame(cmd::GET_VERSION), [0x01, 0xFE]);
        assert_eq!(address_frame(0x0800_0100), [0x08, 0x00, 0x01, 0x00, 0x09]);
        assert_eq!(length_frame(256), Some([0xFF, 0x00]));
        assert_eq!(length_frame(1), Some([0x00, 0xFF]));
        assert_eq!(length_frame(0), None);
        assert_eq!(length_frame(257), None);
        assert_eq!(erase_count_frame(15), Some([0x00, 0x0E, 0x0E]));
        assert_eq!(erase_count_frame(0), None);
        let mut buf = [0u8; 16];
        assert_eq!(
            erase_pages_frame(1, 3, &mut buf),
            Some(&[0x00, 0x01, 0x00, 0x02, 0x00, 0x03, 0x00][..])
        );
        assert_eq!(erase_pages_frame(0, 8, &mut buf), None);
        let mut d = [0u8; MAX_BLOCK + 2];
        assert_eq!(
            data_frame(&[0x11, 0x22, 0x33], &mut d),
            Some(&[0x02, 0x11, 0x22, 0x33, 0x02 ^ 0x11 ^ 0x22 ^ 0x33][..])
        );
        assert_eq!(data_frame(&[], &mut d), None);
        assert_eq!(data_frame(&[0; 257], &mut d), None);
    }

    #[test]
    fn blocks_leave_out_the_first_double_word_and_pad_to_double_words() {
        let b: Vec<_> = blocks(5).collect();
        assert_eq!(b, []);
        let b: Vec<_> = blocks(9).collect();
        assert_eq!(b, [(8, 8)]);
        let b: Vec<_> = blocks(600).collect();
        assert_eq!(b, [(8, 248), (256, 256), (512, 88)]);
        let b: Vec<_> = blocks(32 * 1024).collect();
        assert_eq!(b.len(), 128);
        assert_eq!(b[0], (8, 248));
        assert_eq!(b[127], (32 * 1024 - 256, 256));
        assert_eq!(C011.pages(), 16);
        let b: Vec<_> = blocks_of(60, 24).collect();
        assert_eq!(b, [(8, 16), (24, 24), (48, 16)]);
        assert_eq!(blocks_of(32 * 1024, 24).count(), 1366);
        assert_eq!(Target::for_board_kind(5), Some(C011));
        assert_eq!(Target::for_board_kind(3), None);
    }
}
