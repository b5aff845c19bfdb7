//! `x10 uf2`: a firmware image (ELF) as a UF2 file, the format the RP2040's boot ROM takes on
//! its USB mass-storage drive (hold BOOTSEL while plugging the Pico in: a drive `RPI-RP2`
//! appears; copy the file to it and the Pico flashes it and starts). No probe needed.
//!
//! The format (Microsoft's UF2 specification, and the RP2040 datasheet §2.8.4.2): 512-byte
//! blocks, each `magic0 magic1 flags addr size block_no num_blocks family`, then 476 bytes of
//! data (the first `size` used) and `magic_end`, every word little-endian. Like the Pico SDK's
//! elf2uf2 this writes 256-byte payloads, one per 256-byte-aligned page of flash that the
//! ELF's loadable segments touch (the bytes of a page no segment covers are 0), with the
//! family-ID flag and the RP2040's family ID.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use object::elf::PT_LOAD;
use object::read::elf::{ElfFile32, FileHeader, ProgramHeader};
use object::Endianness;

/// First magic word.
pub const MAGIC0: u32 = 0x0A32_4655;
/// Second magic word.
pub const MAGIC1: u32 = 0x9E5D_5157;
/// Last word of a block.
pub const MAGIC_END: u32 = 0x0AB1_6F30;
/// The flag "family ID present" (the word at offset 28 is a family ID, not a file size).
pub const FLAG_FAMILY_ID: u32 = 0x0000_2000;
/// The RP2040's family ID.
pub const RP2040_FAMILY: u32 = 0xE48B_FF56;
/// Payload bytes per block.
pub const PAGE: u32 = 256;
/// The RP2040's flash in its address space (XIP, up to 16 MiB).
pub const RP2040_FLASH: std::ops::Range<u32> = 0x1000_0000..0x1100_0000;

/// Why no UF2 file was made.
#[derive(Debug)]
pub enum Uf2Error {
    /// The file could not be read or written.
    Io(PathBuf, std::io::Error),
    /// Not a 32-bit little-endian ELF file, or its program headers do not parse.
    Elf(String),
    /// A loadable segment lies (partly) outside the chip's flash: this image is not for the
    /// Pico's flash (a RAM-only image, or another chip's).
    OutsideFlash {
        /// The segment's load address.
        addr: u32,
        /// Its length.
        len: u32,
    },
    /// No loadable bytes at all.
    Empty,
    /// A UF2 file that does not parse (which block, what is wrong).
    BadBlock(usize, &'static str),
}

impl fmt::Display for Uf2Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Uf2Error::Io(p, e) => write!(f, "{}: {e}", p.display()),
            Uf2Error::Elf(e) => write!(f, "not a 32-bit ELF image: {e}"),
            Uf2Error::OutsideFlash { addr, len } => write!(
                f,
                "a loadable segment at {addr:#010x} ({len} bytes) is outside the RP2040's flash (0x10000000..0x11000000)"
            ),
            Uf2Error::Empty => write!(f, "the ELF file has no loadable bytes"),
            Uf2Error::BadBlock(i, why) => write!(f, "UF2 block {i}: {why}"),
        }
    }
}

impl std::error::Error for Uf2Error {}

/// The bytes an ELF image puts in memory: each loadable segment's file bytes at its load
/// (physical) address, so `.data`'s initial values come at their place in flash.
///
/// # Errors
/// [`Uf2Error::Elf`] when it does not parse.
pub fn load_segments(elf: &[u8]) -> Result<Vec<(u32, Vec<u8>)>, Uf2Error> {
    let file = ElfFile32::<Endianness>::parse(elf).map_err(|e| Uf2Error::Elf(e.to_string()))?;
    let endian = file.endian();
    let headers = file
        .elf_header()
        .program_headers(endian, elf)
        .map_err(|e| Uf2Error::Elf(e.to_string()))?;
    let mut out = Vec::new();
    for ph in headers {
        if ph.p_type(endian) != PT_LOAD || ph.p_filesz(endian) == 0 {
            continue;
        }
        let data = ph
            .data(endian, elf)
            .map_err(|()| Uf2Error::Elf("a segment's bytes lie outside the file".into()))?;
        out.push((ph.p_paddr(endian), data.to_vec()));
    }
    Ok(out)
}

/// The UF2 file of `segments` for a chip of family `family` whose flash is `flash`.
///
/// # Errors
/// [`Uf2Error::OutsideFlash`], [`Uf2Error::Empty`].
pub fn from_segments(
    segments: &[(u32, Vec<u8>)],
    family: u32,
    flash: std::ops::Range<u32>,
) -> Result<Vec<u8>, Uf2Error> {
    // Page address -> its 256 bytes.
    let mut pages: BTreeMap<u32, [u8; PAGE as usize]> = BTreeMap::new();
    for (addr, data) in segments {
        let len = u32::try_from(data.len()).map_err(|_| Uf2Error::OutsideFlash {
            addr: *addr,
            len: u32::MAX,
        })?;
        let end = addr.checked_add(len);
        if !flash.contains(addr) || end.is_none_or(|e| e > flash.end) {
            return Err(Uf2Error::OutsideFlash { addr: *addr, len });
        }
        for (i, b) in data.iter().enumerate() {
            // Within flash: no overflow (checked above).
            let a = addr + u32::try_from(i).unwrap_or(0);
            let page = pages.entry(a & !(PAGE - 1)).or_insert([0; PAGE as usize]);
            page[(a % PAGE) as usize] = *b;
        }
    }
    if pages.is_empty() {
        return Err(Uf2Error::Empty);
    }
    let total = u32::try_from(pages.len()).unwrap_or(u32::MAX);
    let mut out = Vec::with_capacity(pages.len() * 512);
    for (n, (addr, data)) in pages.iter().enumerate() {
        let n = u32::try_from(n).unwrap_or(u32::MAX);
        for w in [
            MAGIC0,
            MAGIC1,
            FLAG_FAMILY_ID,
            *addr,
            PAGE,
            n,
            total,
            family,
        ] {
            out.extend_from_slice(&w.to_le_bytes());
        }
        out.extend_from_slice(data);
        out.resize(out.len() + 476 - PAGE as usize, 0);
        out.extend_from_slice(&MAGIC_END.to_le_bytes());
    }
    Ok(out)
}

/// One block of a UF2 file, as [`parse`] reads it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Block {
    /// Flags word.
    pub flags: u32,
    /// Target address.
    pub addr: u32,
    /// Its number.
    pub block_no: u32,
    /// How many blocks the file says it has.
    pub num_blocks: u32,
    /// Family ID (or file size without [`FLAG_FAMILY_ID`]).
    pub family: u32,
    /// The payload.
    pub data: Vec<u8>,
}

fn word(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        w.copy_from_slice(s);
    }
    u32::from_le_bytes(w)
}

/// Reads a UF2 file's blocks, checking the magic words and the payload size.
///
/// # Errors
/// [`Uf2Error::BadBlock`].
pub fn parse(bytes: &[u8]) -> Result<Vec<Block>, Uf2Error> {
    if !bytes.len().is_multiple_of(512) {
        return Err(Uf2Error::BadBlock(
            bytes.len() / 512,
            "file not a whole number of 512-byte blocks",
        ));
    }
    bytes
        .chunks(512)
        .enumerate()
        .map(|(i, b)| {
            if word(b, 0) != MAGIC0 || word(b, 4) != MAGIC1 || word(b, 508) != MAGIC_END {
                return Err(Uf2Error::BadBlock(i, "bad magic"));
            }
            let size = word(b, 16) as usize;
            if size > 476 {
                return Err(Uf2Error::BadBlock(i, "payload over 476 bytes"));
            }
            Ok(Block {
                flags: word(b, 8),
                addr: word(b, 12),
                block_no: word(b, 20),
                num_blocks: word(b, 24),
                family: word(b, 28),
                data: b.get(32..32 + size).unwrap_or(&[]).to_vec(),
            })
        })
        .collect()
}

/// The RP2040's boot drive, if one is mounted: a folder named `RPI-RP2` holding
/// `INFO_UF2.TXT`, under /media/USER, /run/media/USER or /Volumes.
pub fn find_boot_drive() -> Option<PathBuf> {
    let mut roots: Vec<PathBuf> = vec![PathBuf::from("/Volumes")];
    for base in ["/media", "/run/media"] {
        roots.push(PathBuf::from(base));
        if let Ok(users) = std::fs::read_dir(base) {
            roots.extend(users.flatten().map(|e| e.path()));
        }
    }
    roots
        .into_iter()
        .map(|r| r.join("RPI-RP2"))
        .find(|d| d.join("INFO_UF2.TXT").is_file())
}

/// `x10 uf2 ELF`: writes `out` (default: the ELF's path with `.uf2`), and copies it to `drive`
/// when given. Returns the file written and its block count.
///
/// # Errors
/// Reading, converting, writing.
pub fn convert(elf: &Path, out: Option<&Path>) -> Result<(PathBuf, usize), Uf2Error> {
    let data = std::fs::read(elf).map_err(|e| Uf2Error::Io(elf.to_owned(), e))?;
    let uf2 = from_segments(&load_segments(&data)?, RP2040_FAMILY, RP2040_FLASH)?;
    let out = out.map_or_else(|| elf.with_extension("uf2"), Path::to_path_buf);
    std::fs::write(&out, &uf2).map_err(|e| Uf2Error::Io(out.clone(), e))?;
    Ok((out, uf2.len() / 512))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 32-bit little-endian ARM ELF file with one program header per `(paddr, vaddr,
    /// bytes, memsz)`, the bytes after the headers.
    fn elf(segments: &[(u32, u32, Vec<u8>, u32)]) -> Vec<u8> {
        let phnum = segments.len() as u16;
        let mut f = vec![0x7f, b'E', b'L', b'F', 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        f.extend_from_slice(&2u16.to_le_bytes()); // ET_EXEC
        f.extend_from_slice(&40u16.to_le_bytes()); // EM_ARM
        f.extend_from_slice(&1u32.to_le_bytes());
        f.extend_from_slice(&0x1000_0101u32.to_le_bytes()); // entry
        f.extend_from_slice(&52u32.to_le_bytes()); // phoff
        f.extend_from_slice(&0u32.to_le_bytes()); // shoff
        f.extend_from_slice(&0x0500_0200u32.to_le_bytes());
        for h in [52u16, 32, phnum, 40, 0, 0] {
            f.extend_from_slice(&h.to_le_bytes());
        }
        let mut offset = 52 + 32 * u32::from(phnum);
        for (paddr, vaddr, bytes, memsz) in segments {
            for w in [
                PT_LOAD,
                offset,
                *vaddr,
                *paddr,
                bytes.len() as u32,
                *memsz,
                5,
                4,
            ] {
                f.extend_from_slice(&w.to_le_bytes());
            }
            offset += bytes.len() as u32;
        }
        for (_, _, bytes, _) in segments {
            f.extend_from_slice(bytes);
        }
        f
    }

    #[test]
    fn the_blocks_carry_exactly_the_elfs_loadable_bytes() {
        // Code over two pages and a bit, `.data` loaded in flash after it (run from RAM),
        // `.bss` (no file bytes): like a firmware image.
        let text: Vec<u8> = (0..600u32).map(|i| (i * 7 + 1) as u8).collect();
        let data: Vec<u8> = (0..10u8).map(|i| 0xA0 + i).collect();
        let file = elf(&[
            (0x1000_0000, 0x1000_0000, text.clone(), 600),
            (0x1000_0258, 0x2000_0000, data.clone(), 10),
            (0x2000_000C, 0x2000_000C, Vec::new(), 400),
        ]);
        let segments = load_segments(&file).unwrap();
        assert_eq!(
            segments,
            vec![(0x1000_0000, text.clone()), (0x1000_0258, data.clone())]
        );
        let uf2 = from_segments(&segments, RP2040_FAMILY, RP2040_FLASH).unwrap();
        assert_eq!(uf2.len(), 3 * 512);
        let blocks = parse(&uf2).unwrap();
        let addrs: Vec<u32> = blocks.iter().map(|b| b.addr).collect();
        assert_eq!(addrs, [0x1000_0000, 0x1000_0100, 0x1000_0200]);
        for (i, b) in blocks.iter().enumerate() {
            assert_eq!(b.flags, FLAG_FAMILY_ID);
            assert_eq!(b.family, 0xe48b_ff56);
            assert_eq!(b.block_no, i as u32);
            assert_eq!(b.num_blocks, 3);
            assert_eq!(b.data.len(), 256);
        }
        // The image back from the blocks: the text, then the data at 0x258, zeros between
        // and after.
        let image: Vec<u8> = blocks.iter().flat_map(|b| b.data.clone()).collect();
        assert_eq!(&image[..600], &text[..]);
        assert_eq!(&image[600..610], &data[..]);
        assert!(image[610..].iter().all(|&b| b == 0));
        // The unused tail of each block's data area is zero.
        assert!(uf2[32 + 256..508].iter().all(|&b| b == 0));
    }

    #[test]
    fn a_segment_outside_flash_is_refused() {
        let file = elf(&[(0x2000_0000, 0x2000_0000, vec![1, 2, 3], 3)]);
        let err = from_segments(&load_segments(&file).unwrap(), RP2040_FAMILY, RP2040_FLASH);
        assert!(matches!(
            err,
            Err(Uf2Error::OutsideFlash {
                addr: 0x2000_0000,
                len: 3
            })
        ));
        // Running over the end of flash.
        let file = elf(&[(0x10FF_FFFE, 0x10FF_FFFE, vec![1, 2, 3], 3)]);
        assert!(
            from_segments(&load_segments(&file).unwrap(), RP2040_FAMILY, RP2040_FLASH).is_err()
        );
    }

    #[test]
    fn not_an_elf_and_nothing_to_load_are_errors() {
        assert!(matches!(load_segments(b"hello"), Err(Uf2Error::Elf(_))));
        assert!(matches!(
            from_segments(&[], RP2040_FAMILY, RP2040_FLASH),
            Err(Uf2Error::Empty)
        ));
        assert!(matches!(
            parse(&[0u8; 512]),
            Err(Uf2Error::BadBlock(0, "bad magic"))
        ));
        assert!(parse(&[0u8; 100]).is_err());
    }
}
