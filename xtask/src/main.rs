//! `cargo xtask`: project tasks for CI.
//!
//! `cargo xtask size [--no-build]` builds the four firmware images in release, one cargo call
//! per image (two chips' features in one call would clash), then reads each ELF and prints its
//! flash (everything loaded from flash: vector table, code, read-only data, the initial values
//! of `.data`, the RP2040's boot2) and static RAM (`.data`, `.bss`, `.uninit`: everything with
//! a RAM address; the stack comes on top). It fails when a daughterboard image exceeds
//! 48 KiB of flash or 12 KiB of static RAM. `--no-build` measures the ELFs already built.

use std::env;
use std::fmt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::Instant;

use object::{Object, ObjectSection, SectionFlags};

/// One firmware image: how to build it and its limits.
struct Image {
    bin: &'static str,
    package: &'static str,
    target: &'static str,
    feature: &'static str,
    /// Daughterboard images have size limits.
    daughterboard: bool,
}

const IMAGES: [Image; 4] = [
    Image {
        bin: "mb-pico",
        package: "firmware-mb",
        target: "thumbv6m-none-eabi",
        feature: "rp2040",
        daughterboard: false,
    },
    Image {
        bin: "db-pico",
        package: "firmware-db",
        target: "thumbv6m-none-eabi",
        feature: "rp2040",
        daughterboard: true,
    },
    Image {
        bin: "mb-g431",
        package: "firmware-mb",
        target: "thumbv7em-none-eabihf",
        feature: "stm32g431",
        daughterboard: false,
    },
    Image {
        bin: "db-g431",
        package: "firmware-db",
        target: "thumbv7em-none-eabihf",
        feature: "stm32g431",
        daughterboard: true,
    },
];

/// Daughterboard flash limit in bytes.
const DB_FLASH_LIMIT: u64 = 48 * 1024;
/// Daughterboard static RAM limit in bytes.
const DB_RAM_LIMIT: u64 = 12 * 1024;

/// RAM starts here on both chips (SRAM at 0x2000_0000).
const RAM_START: u64 = 0x2000_0000;

/// Flash and static RAM of one ELF, in bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Usage {
    flash: u64,
    ram: u64,
}

/// Why a task failed.
#[derive(Debug)]
enum Error {
    Usage(String),
    Io(PathBuf, std::io::Error),
    Elf(PathBuf, object::Error),
    Build(&'static str),
    Metadata(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Usage(s) => write!(f, "{s}\nusage: cargo xtask size [--no-build]"),
            Error::Io(p, e) => write!(f, "{}: {e}", p.display()),
            Error::Elf(p, e) => write!(f, "{}: not an ELF file: {e}", p.display()),
            Error::Build(bin) => write!(f, "building {bin} failed"),
            Error::Metadata(s) => write!(f, "cargo metadata: {s}"),
        }
    }
}

/// Sizes from the sections of an ELF image.
///
/// # Errors
/// [`Error::Io`], [`Error::Elf`].
fn usage(path: &Path) -> Result<Usage, Error> {
    let data = std::fs::read(path).map_err(|e| Error::Io(path.to_owned(), e))?;
    let file = object::File::parse(&*data).map_err(|e| Error::Elf(path.to_owned(), e))?;
    let mut u = Usage::default();
    for s in file.sections() {
        let alloc = match s.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !alloc || s.size() == 0 {
            continue;
        }
        // Sections with file contents are stored in flash (`.data` too: its initial values,
        // copied to RAM at boot); NOBITS sections have none.
        if s.file_range().is_some() {
            u.flash += s.size();
        }
        if s.address() >= RAM_START {
            u.ram += s.size();
        }
    }
    Ok(u)
}

/// The workspace's target directory.
///
/// # Errors
/// [`Error::Metadata`] when cargo metadata fails or says nothing about it.
fn target_dir(cargo: &str) -> Result<PathBuf, Error> {
    if let Some(dir) = env::var_os("CARGO_TARGET_DIR") {
        return Ok(PathBuf::from(dir));
    }
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .output()
        .map_err(|e| Error::Metadata(e.to_string()))?;
    if !out.status.success() {
        return Err(Error::Metadata(
            String::from_utf8_lossy(&out.stderr).into_owned(),
        ));
    }
    let v: serde_json::Value =
        serde_json::from_slice(&out.stdout).map_err(|e| Error::Metadata(e.to_string()))?;
    v.get("target_directory")
        .and_then(|d| d.as_str())
        .map(PathBuf::from)
        .ok_or_else(|| Error::Metadata("no target_directory".into()))
}

/// Builds one image in release.
///
/// # Errors
/// [`Error::Build`] when cargo fails.
fn build(cargo: &str, image: &Image) -> Result<(), Error> {
    let status = Command::new(cargo)
        .args([
            "build",
            "--release",
            "-p",
            image.package,
            "--target",
            image.target,
        ])
        .args(["--features", image.feature, "--bin", image.bin])
        .status()
        .map_err(|_| Error::Build(image.bin))?;
    if status.success() {
        Ok(())
    } else {
        Err(Error::Build(image.bin))
    }
}

fn kib(bytes: u64) -> String {
    format!("{:.1} KiB", bytes as f64 / 1024.0)
}

/// Runs `cargo xtask size`; `Ok(false)` when a limit is exceeded.
///
/// # Errors
/// Build, metadata and ELF errors.
fn size(build_first: bool) -> Result<bool, Error> {
    let cargo = env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let dir = target_dir(&cargo)?;
    let mut rows = Vec::new();
    for image in &IMAGES {
        let secs = if build_first {
            let t = Instant::now();
            build(&cargo, image)?;
            Some(t.elapsed().as_secs_f64())
        } else {
            None
        };
        let elf = dir.join(image.target).join("release").join(image.bin);
        rows.push((image, usage(&elf)?, secs));
    }
    let mut ok = true;
    println!();
    println!("| image | target | flash | static RAM | limit (DB: 48 KiB / 12 KiB) | build |");
    println!("|---|---|---|---|---|---|");
    for (image, u, secs) in rows {
        let verdict = if !image.daughterboard {
            "-".to_owned()
        } else if u.flash > DB_FLASH_LIMIT || u.ram > DB_RAM_LIMIT {
            ok = false;
            "EXCEEDED".to_owned()
        } else {
            format!(
                "ok ({} / {} left)",
                kib(DB_FLASH_LIMIT - u.flash),
                kib(DB_RAM_LIMIT - u.ram)
            )
        };
        let secs = secs.map_or("-".to_owned(), |s| format!("{s:.0} s"));
        println!(
            "| {} | {} | {} B ({}) | {} B ({}) | {} | {} |",
            image.bin,
            image.target,
            u.flash,
            kib(u.flash),
            u.ram,
            kib(u.ram),
            verdict,
            secs
        );
    }
    Ok(ok)
}

/// Parses the arguments and runs the task.
///
/// # Errors
/// [`Error::Usage`] for unknown arguments, and the task's errors.
fn run(args: &[String]) -> Result<bool, Error> {
    match args {
        [task] if task == "size" => size(true),
        [task, flag] if task == "size" && flag == "--no-build" => size(false),
        _ => Err(Error::Usage(format!("unknown arguments {args:?}"))),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = env::args().skip(1).collect();
    match run(&args) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => {
            eprintln!("a daughterboard image exceeds its size limit");
            ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("xtask: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arguments() {
        assert!(matches!(run(&["sizes".into()]), Err(Error::Usage(_))));
        assert!(matches!(run(&[]), Err(Error::Usage(_))));
    }

    #[test]
    fn a_non_elf_file_is_an_error() {
        let path = env::temp_dir().join(format!("xtask-not-elf-{}", std::process::id()));
        std::fs::write(&path, b"not an elf").unwrap();
        let r = usage(&path);
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(r, Err(Error::Elf(..))));
    }

    /// A little-endian ELF32 executable with the given sections
    /// `(name, sh_type, sh_flags, address, size)`; PROGBITS sections get zeroed contents.
    fn elf(sections: &[(&str, u32, u32, u32, u32)]) -> Vec<u8> {
        let mut names = vec![0u8];
        let mut name_at = Vec::new();
        for (name, ..) in sections {
            name_at.push(names.len() as u32);
            names.extend_from_slice(name.as_bytes());
            names.push(0);
        }
        let shstrtab_name = names.len() as u32;
        names.extend_from_slice(b".shstrtab\0");
        let mut body = Vec::new();
        let mut offsets = Vec::new();
        for &(_, ty, _, _, size) in sections {
            offsets.push(52 + body.len() as u32);
            if ty != 8 {
                body.resize(body.len() + size as usize, 0);
            }
        }
        let names_off = 52 + body.len() as u32;
        body.extend_from_slice(&names);
        let shoff = 52 + body.len() as u32;
        let shnum = sections.len() as u16 + 2;
        let mut out = vec![0x7f, b'E', b'L', b'F', 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        for v in [2u16, 40] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [1u32, 0, 0, shoff, 0x0500_0200] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [52u16, 32, 0, 40, shnum, shnum - 1] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&body);
        let mut header = |v: [u32; 10]| {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        };
        header([0; 10]);
        for (i, &(_, ty, flags, addr, size)) in sections.iter().enumerate() {
            header([name_at[i], ty, flags, addr, offsets[i], size, 0, 0, 4, 0]);
        }
        header([
            shstrtab_name,
            3,
            0,
            0,
            names_off,
            names.len() as u32,
            0,
            0,
            1,
            0,
        ]);
        out
    }

    #[test]
    fn flash_is_loaded_contents_and_ram_is_everything_at_ram_addresses() {
        const PROGBITS: u32 = 1;
        const NOBITS: u32 = 8;
        const AX: u32 = 0x6;
        const WA: u32 = 0x3;
        let bytes = elf(&[
            (".vector_table", PROGBITS, 0x2, 0x0800_0000, 0x1d8),
            (".text", PROGBITS, AX, 0x0800_01d8, 1_000),
            (".rodata", PROGBITS, 0x2, 0x0800_05c0, 200),
            (".data", PROGBITS, WA, 0x2000_0000, 80),
            (".bss", NOBITS, WA, 0x2000_0050, 3_308),
            (".uninit", NOBITS, WA, 0x2000_0d3c, 1_024),
            (".defmt", PROGBITS, 0, 0, 23),
            (".debug_info", PROGBITS, 0, 0, 500),
        ]);
        let path = env::temp_dir().join(format!("xtask-elf-{}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        let u = usage(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(
            u.unwrap(),
            Usage {
                flash: 0x1d8 + 1_000 + 200 + 80,
                ram: 80 + 3_308 + 1_024
            }
        );
    }

    #[test]
    fn limits_are_the_issue_s() {
        assert_eq!(DB_FLASH_LIMIT, 49_152);
        assert_eq!(DB_RAM_LIMIT, 12_288);
        assert_eq!(IMAGES.iter().filter(|i| i.daughterboard).count(), 2);
    }
}
