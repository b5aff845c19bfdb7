//! `cargo xtask emu [--list] [SCENARIO...]`: the real Pico images on emulated RP2040s.
//!
//! Builds mb-pico and db-pico in release (the same cargo calls as `cargo xtask size`, one per
//! image; db-pico with the address override `X10_DB_ADDR=9`: DB 10 is the same image with
//! jumper 0 fitted; db-pico without it, plug and play, as `target/emu/db-pico-pnp`; db-pico
//! built into the bootloader's ACTIVE slot as `target/emu/db-pico-slot` and, as 2.0.0,
//! `db-pico-slot-v2`, with `boot-pico`, and mb-pico carrying `db-pico-slot-v2`'s slot bytes as
//! 2.0.0 (`X10_CARRY`), `target/emu/mb-pico-carry`; db-pico (without the bootloader: the
//! standalone build, not `cargo db-pico`'s ACTIVE-slot one) also for 400 kHz and 1 MHz buses,
//! `X10_BUS_HZ`, copied to `target/emu/db-pico-HZ`; for those buses too the two slot builds,
//! `db-pico-slot-HZ` and `db-pico-slot-v2-HZ`, and mb-pico carrying the latter,
//! `mb-pico-carry-HZ`: boot-pico is a target only, built without a bus clock, and serves every
//! bus), the flash path's test image `emu/fw-flash` (its own workspace) and
//! the host `x10` tool, installs the rig's Node packages from `emu/package-lock.json`
//! with `npm ci` when `emu/node_modules` is missing or older than the lock file, then runs
//! `node emu/run.mjs` on the two ELFs. The rig, its scenarios and what they check are in
//! `emu/` and `docs/emulation.md`; the trace of each scenario (bus transfers decoded by
//! `x10 decode`, defmt logs decoded by `defmt-print`, pins) goes to `target/emu/SCENARIO.txt`.
//!
//! A run of every scenario also writes the figures they measured as one Markdown block,
//! `target/emu/figures.md` (`emu/lib/figures.js`), the block docs/emulation.md holds between
//! its markers: `--write-docs` puts it there, `--check-docs` (`./test-all`) fails when the docs
//! hold another, so the emulator's figures are written in one place and cannot drift.

use std::path::Path;
use std::process::{Command, ExitCode};

use crate::{target_dir, Error, IMAGES};

/// Runs the task with its arguments (scenario names, `--list`).
///
/// # Errors
/// Build failures, and `npm`/`node` that cannot be started.
pub fn emu(args: &[String]) -> Result<ExitCode, Error> {
    let docs = if args.iter().any(|a| a == "--check-docs") {
        Some(Docs::Check)
    } else if args.iter().any(|a| a == "--write-docs") {
        Some(Docs::Write)
    } else {
        None
    };
    let args: Vec<String> = args
        .iter()
        .filter(|a| *a != "--check-docs" && *a != "--write-docs")
        .cloned()
        .collect();
    if docs.is_some() && args.iter().any(|a| !a.starts_with("--")) {
        return Err(Error::Usage(
            "--check-docs and --write-docs need every scenario: name none".into(),
        ));
    }
    let code = run(&args)?;
    let Some(docs) = docs else {
        return Ok(code);
    };
    if code != ExitCode::SUCCESS {
        return Ok(code);
    }
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let figures_path = target_dir(&cargo)?.join("emu").join("figures.md");
    let figures =
        std::fs::read_to_string(&figures_path).map_err(|e| Error::Io(figures_path.clone(), e))?;
    let doc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/emulation.md");
    let doc = std::fs::read_to_string(&doc_path).map_err(|e| Error::Io(doc_path.clone(), e))?;
    let updated = replace_block(&doc, &figures).map_err(Error::Usage)?;
    match docs {
        Docs::Write => {
            std::fs::write(&doc_path, updated).map_err(|e| Error::Io(doc_path.clone(), e))?;
            println!(
                "docs/emulation.md: figures written from {}",
                figures_path.display()
            );
            Ok(ExitCode::SUCCESS)
        }
        Docs::Check if updated == doc => Ok(ExitCode::SUCCESS),
        Docs::Check => {
            eprintln!(
                "docs/emulation.md's figures differ from this run's ({}):\n{figures}\nrun `cargo xtask emu --write-docs` and commit the change",
                figures_path.display()
            );
            Ok(ExitCode::FAILURE)
        }
    }
}

/// What to do with docs/emulation.md after a full run.
#[derive(Clone, Copy)]
enum Docs {
    /// Fail when its figures block differs from the run's.
    Check,
    /// Put the run's block in.
    Write,
}

/// `doc` with its figures block (from the line starting `<!-- figures:` to the line starting
/// `<!-- end of the generated figures`) replaced by `block` (the same two marker lines
/// included).
///
/// # Errors
/// When `doc` or `block` lacks the markers, or has them out of order.
fn replace_block(doc: &str, block: &str) -> Result<String, String> {
    const BEGIN: &str = "<!-- figures:";
    const END: &str = "<!-- end of the generated figures";
    let bounds = |text: &str| -> Option<(usize, usize)> {
        let a = text
            .find(&format!("\n{BEGIN}"))
            .map(|i| i + 1)
            .or_else(|| text.starts_with(BEGIN).then_some(0))?;
        let e = a + text[a..].find(&format!("\n{END}"))? + 1;
        let end = e + text[e..].find('\n').map_or(text.len() - e, |n| n + 1);
        Some((a, end))
    };
    let (a, b) =
        bounds(doc).ok_or_else(|| format!("docs/emulation.md has no `{BEGIN}` … `{END}` block"))?;
    if bounds(block) != Some((0, block.len())) {
        return Err(format!(
            "the figures file is not one `{BEGIN}` … `{END}` block"
        ));
    }
    Ok(format!("{}{block}{}", &doc[..a], &doc[b..]))
}

fn run(args: &[String]) -> Result<ExitCode, Error> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .ok_or_else(|| Error::Usage("xtask has no parent directory".into()))?
        .to_path_buf();
    let emu = root.join("emu");
    npm_ci(&emu)?;
    if args.iter().any(|a| a == "--list") {
        return node(&emu, &["run.mjs".into(), "--list".into()]);
    }
    let out = target_dir(&cargo)?.join("emu");
    std::fs::create_dir_all(&out).map_err(Error::Run)?;
    let mut elfs = Vec::new();
    let mut fast = Vec::new();
    let mut pnp_elf = None;
    for name in ["mb-pico", "db-pico"] {
        let row = IMAGES
            .iter()
            .find(|i| i.bin == name)
            .ok_or_else(|| Error::Usage(format!("no image {name}")))?;
        // db-pico's row is the ACTIVE-slot build (`cargo db-pico`, under boot-pico); the
        // scenarios without the bootloader run the standalone build.
        let standalone = crate::Image {
            features: STANDALONE_DB_PICO,
            ..*row
        };
        let image = if name == "db-pico" { &standalone } else { row };
        crate::check_targets("cargo xtask emu", &[image.target])?;
        let elf = target_dir(&cargo)?
            .join(image.target)
            .join("release")
            .join(name);
        if name == "db-pico" {
            // The plug-and-play build (one image for every board: no address override),
            // copied aside for the `plug-and-play` scenario.
            build_with(&cargo, image, None, false)?;
            let pnp = out.join("db-pico-pnp");
            std::fs::copy(&elf, &pnp).map_err(Error::Run)?;
            pnp_elf = Some(pnp);
            // db-pico for the faster buses too (`X10_BUS_HZ`, a rebuild of x10-boards and a
            // link: seconds), each copied aside; the default build comes last.
            for hz in FAST_BUSES {
                build_at(&cargo, image, Some(hz))?;
                let copy = out.join(format!("db-pico-{hz}"));
                std::fs::copy(&elf, &copy).map_err(Error::Run)?;
                fast.push(format!("{hz}={}", copy.display()));
            }
        }
        if name == "db-pico" {
            // db-pico built into the bootloader's ACTIVE slot (plug and play), as this
            // version and as 2.0.0 (`X10_FW_VERSION`), each copied aside, and the bootloader:
            // the `bootloader` scenario.
            let slot = crate::Image {
                features: "daughterboard,active-slot,together",
                ..*row
            };
            // The same two for the faster buses (`update-400k`, `update-1m`), copied aside as
            // `db-pico-slot-HZ` and `db-pico-slot-v2-HZ`; the default bus's last.
            for hz in FAST_BUSES.map(Some).into_iter().chain([None]) {
                let suffix = hz.map_or(String::new(), |hz| format!("-{hz}"));
                for (version, copy) in [(None, "db-pico-slot"), (Some("2.0.0"), "db-pico-slot-v2")]
                {
                    build_slot(&cargo, &slot, version, hz)?;
                    std::fs::copy(&elf, out.join(format!("{copy}{suffix}"))).map_err(Error::Run)?;
                }
            }
            let boot = IMAGES
                .iter()
                .find(|i| i.bin == "boot-pico")
                .ok_or_else(|| Error::Usage("no image boot-pico".into()))?;
            build_at(&cargo, boot, None)?;
        }
        build_at(&cargo, image, None)?;
        elfs.push(elf);
    }
    let release = target_dir(&cargo)?
        .join("thumbv6m-none-eabi")
        .join("release");
    // mb-pico carrying db-pico 2.0.0 (the slot build above) for the `update` scenario, and for
    // each faster bus mb-pico built for it carrying that bus's 2.0.0 (`update-400k`,
    // `update-1m`), each copied aside; then the plain mb-pico again, which the other scenarios
    // run from `release`.
    let carry_mb = build_carrying(&cargo, &out, &out.join("db-pico-slot-v2"), "2.0.0", None)?;
    let mut update_at = Vec::new();
    for hz in FAST_BUSES {
        let mb = build_carrying(
            &cargo,
            &out,
            &out.join(format!("db-pico-slot-v2-{hz}")),
            "2.0.0",
            Some(hz),
        )?;
        update_at.push((hz, mb));
    }
    build_at(&cargo, mb_row()?, None)?;
    // The doorbell example's motherboard image: a DB event waking an MB task.
    let mb = mb_row()?;
    let doorbell = crate::Image {
        bin: "mb-pico-doorbell",
        ..*mb
    };
    build_at(&cargo, &doorbell, None)?;
    let doorbell_elf = target_dir(&cargo)?
        .join(mb.target)
        .join("release")
        .join(doorbell.bin);
    // The plug-and-play example's motherboard image: two boards addressed over the bus.
    let pnp_mb = crate::Image {
        bin: "mb-pico-pnp",
        ..*mb
    };
    build_at(&cargo, &pnp_mb, None)?;
    let pnp_mb_elf = target_dir(&cargo)?
        .join(mb.target)
        .join("release")
        .join(pnp_mb.bin);
    let fw_flash = build_fw_flash(&cargo, &root)?;
    let status = Command::new(&cargo)
        .args(["build", "-q", "-p", "x10-cli", "--bin", "x10"])
        .status()
        .map_err(Error::Run)?;
    if !status.success() {
        return Err(Error::Build("x10"));
    }
    let x10 = target_dir(&cargo)?.join("debug").join("x10");
    let mut a: Vec<String> = vec![
        "run.mjs".into(),
        "--mb".into(),
        elfs[0].display().to_string(),
        "--db".into(),
        elfs[1].display().to_string(),
        "--x10".into(),
        x10.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    a.push("--mb-carry".into());
    a.push(carry_mb.display().to_string());
    a.push("--mb-doorbell".into());
    a.push(doorbell_elf.display().to_string());
    a.push("--fw-flash".into());
    a.push(fw_flash.display().to_string());
    for f in fast {
        a.push("--db-at".into());
        a.push(f);
    }
    // The faster buses' update images: mb-pico carrying 2.0.0, db-pico 0.1.0 and 2.0.0 in ACTIVE.
    for (hz, mb) in update_at {
        for (flag, path) in [
            ("--mb-carry-at", mb),
            ("--db-slot-at", out.join(format!("db-pico-slot-{hz}"))),
            ("--db-slot-v2-at", out.join(format!("db-pico-slot-v2-{hz}"))),
        ] {
            a.push(flag.into());
            a.push(format!("{hz}={}", path.display()));
        }
    }
    if let Some(p) = pnp_elf {
        a.push("--db-pnp".into());
        a.push(p.display().to_string());
    }
    a.push("--mb-pnp".into());
    a.push(pnp_mb_elf.display().to_string());
    for (flag, path) in [
        ("--boot", release.join("boot-pico")),
        ("--db-slot", out.join("db-pico-slot")),
        ("--db-slot-v2", out.join("db-pico-slot-v2")),
    ] {
        a.push(flag.into());
        a.push(path.display().to_string());
    }
    a.extend(args.iter().cloned());
    node(&emu, &a)
}

/// The test image of the flash path, `emu/fw-flash` (its own workspace, with its own lock file),
/// built in release for the RP2040 into the main target directory (it shares the images'
/// compiled dependencies there); its ELF's path.
///
/// # Errors
/// [`Error::Build`] when cargo fails.
fn build_fw_flash(cargo: &str, root: &Path) -> Result<std::path::PathBuf, Error> {
    const TARGET: &str = "thumbv6m-none-eabi";
    let target = target_dir(cargo)?;
    let status = Command::new(cargo)
        .args([
            "build",
            "--release",
            "--locked",
            "--target",
            TARGET,
            "--manifest-path",
        ])
        .arg(root.join("emu").join("fw-flash").join("Cargo.toml"))
        .arg("--target-dir")
        .arg(&target)
        .status()
        .map_err(Error::Run)?;
    if !status.success() {
        return Err(Error::Build("emu/fw-flash"));
    }
    Ok(target.join(TARGET).join("release").join("x10-emu-fw-flash"))
}

/// mb-pico's row in [`IMAGES`].
fn mb_row() -> Result<&'static crate::Image, Error> {
    IMAGES
        .iter()
        .find(|i| i.bin == "mb-pico")
        .ok_or_else(|| Error::Usage("no image mb-pico".into()))
}

/// Builds mb-pico for a bus of `hz` (`X10_BUS_HZ`; `None`: the default bus) carrying the slot
/// image of the db-pico ELF `slot_elf` as `version` (`X10_CARRY`, the slot bytes written to
/// `SLOT_ELF.bin`), and copies it to `out/mb-pico-carry` (`out/mb-pico-carry-HZ`); the copy's
/// path. The ELF in the target directory is then the carrying one: the caller builds the plain
/// mb-pico again.
///
/// # Errors
/// Build, ELF and slot errors.
fn build_carrying(
    cargo: &str,
    out: &Path,
    slot_elf: &Path,
    version: &str,
    hz: Option<u32>,
) -> Result<std::path::PathBuf, Error> {
    let carry = &crate::CARRIES[0];
    let segments = crate::loaded_segments(slot_elf)?;
    let parts: Vec<(u64, &[u8])> = segments.iter().map(|(a, b)| (*a, b.as_slice())).collect();
    let bytes = crate::slot_image(&parts, carry.slot, carry.slot_len)
        .map_err(|e| Error::Usage(format!("{}: {e}", slot_elf.display())))?;
    let bin = slot_elf.with_extension("bin");
    std::fs::write(&bin, bytes).map_err(|e| Error::Io(bin.clone(), e))?;
    let mb = mb_row()?;
    let mut c = crate::build_command(cargo, mb);
    match hz {
        Some(hz) => c.env("X10_BUS_HZ", hz.to_string()),
        None => c.env_remove("X10_BUS_HZ"),
    };
    c.env_remove("X10_DB_ADDR").env(
        "X10_CARRY",
        format!("{}@{version}={}", carry.kind, bin.display()),
    );
    if !c.status().map_err(Error::Run)?.success() {
        return Err(Error::Build("mb-pico (carrying db-pico)"));
    }
    let elf = target_dir(cargo)?
        .join(mb.target)
        .join("release")
        .join(mb.bin);
    let copy = out.join(hz.map_or("mb-pico-carry".to_owned(), |hz| {
        format!("mb-pico-carry-{hz}")
    }));
    std::fs::copy(&elf, &copy).map_err(Error::Run)?;
    Ok(copy)
}

/// db-pico's features without the bootloader (its row in [`IMAGES`] is the ACTIVE slot's).
const STANDALONE_DB_PICO: &str = "rp2040,daughterboard,together";

/// The bus frequencies, besides the default 100 kHz, that the `event-latency` scenario
/// measures with a db-pico built for them, and the `update-400k` and `update-1m` scenarios
/// with mb-pico and db-pico's slot builds built for them.
const FAST_BUSES: [u32; 2] = [400_000, 1_000_000];

/// Builds `image` for a bus of `hz` (`X10_BUS_HZ`), or for the default bus (the variable
/// removed, whatever the caller's environment holds).
fn build_at(cargo: &str, image: &crate::Image, hz: Option<u32>) -> Result<(), Error> {
    build_with(cargo, image, hz, image.bin == "db-pico")
}

/// As [`build_at`]; `at_9`: with the build-time address override `X10_DB_ADDR=9` (the
/// scenarios' DB 9, and DB 10 with jumper 0 fitted), else the plug-and-play build (no override:
/// the board keeps what it is given over the bus).
fn build_with(cargo: &str, image: &crate::Image, hz: Option<u32>, at_9: bool) -> Result<(), Error> {
    let mut c = crate::build_command(cargo, image);
    match hz {
        Some(hz) => c.env("X10_BUS_HZ", hz.to_string()),
        None => c.env_remove("X10_BUS_HZ"),
    };
    // The motherboard images the scenarios run carry nothing (but `mb-pico-carry`).
    c.env_remove("X10_CARRY");
    if at_9 {
        c.env("X10_DB_ADDR", "9");
    } else {
        c.env_remove("X10_DB_ADDR");
    }
    if c.status().map_err(Error::Run)?.success() {
        Ok(())
    } else {
        Err(Error::Build(image.bin))
    }
}

/// Builds db-pico for the bootloader's ACTIVE slot (`image`: its `active-slot` row), plug and
/// play, for a bus of `hz` (`X10_BUS_HZ`; `None`: the default bus), with `X10_FW_VERSION` set
/// to `version` (or removed).
fn build_slot(
    cargo: &str,
    image: &crate::Image,
    version: Option<&str>,
    hz: Option<u32>,
) -> Result<(), Error> {
    let mut c = crate::build_command(cargo, image);
    match hz {
        Some(hz) => c.env("X10_BUS_HZ", hz.to_string()),
        None => c.env_remove("X10_BUS_HZ"),
    };
    c.env_remove("X10_DB_ADDR");
    match version {
        Some(v) => c.env("X10_FW_VERSION", v),
        None => c.env_remove("X10_FW_VERSION"),
    };
    if c.status().map_err(Error::Run)?.success() {
        Ok(())
    } else {
        Err(Error::Build(image.bin))
    }
}

/// `npm ci` in `emu/` unless its packages are installed and newer than the lock file.
fn npm_ci(emu: &Path) -> Result<(), Error> {
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let lock = modified(&emu.join("package-lock.json"));
    let installed = modified(&emu.join("node_modules").join(".package-lock.json"));
    if matches!((lock, installed), (Some(l), Some(i)) if i >= l) {
        return Ok(());
    }
    let status = Command::new("npm")
        .args(["ci", "--no-audit", "--no-fund"])
        .current_dir(emu)
        .status()
        .map_err(Error::Run)?;
    if status.success() {
        Ok(())
    } else {
        Err(Error::Build("emu (npm ci)"))
    }
}

fn node(emu: &Path, args: &[String]) -> Result<ExitCode, Error> {
    let status = Command::new("node")
        .args(args)
        .current_dir(emu)
        .status()
        .map_err(Error::Run)?;
    Ok(if status.success() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

#[cfg(test)]
mod tests {
    use super::replace_block;

    const BLOCK: &str =
        "<!-- figures: generated -->\n| a | b |\n<!-- end of the generated figures -->\n";

    #[test]
    fn the_block_is_replaced_and_nothing_else() {
        let doc = "# Doc\n\ntext\n<!-- figures: generated -->\n| old |\n<!-- end of the generated figures -->\nafter\n";
        assert_eq!(
            replace_block(doc, BLOCK).unwrap(),
            format!("# Doc\n\ntext\n{BLOCK}after\n")
        );
        // Idempotent: the same block leaves the doc as it is.
        let once = replace_block(doc, BLOCK).unwrap();
        assert_eq!(replace_block(&once, BLOCK).unwrap(), once);
    }

    #[test]
    fn missing_markers_are_errors() {
        assert!(replace_block("# Doc\nno block\n", BLOCK).is_err());
        let doc = "x\n<!-- figures: generated -->\nno end\n";
        assert!(replace_block(doc, BLOCK).is_err());
        let doc = "x\n<!-- figures: generated -->\n<!-- end of the generated figures -->\n";
        assert!(replace_block(doc, "| a |\n").is_err());
    }

    /// The docs hold the block the way the check finds it.
    #[test]
    fn docs_emulation_md_has_one_figures_block() {
        let doc = include_str!("../../docs/emulation.md");
        assert_eq!(doc.matches("\n<!-- figures:").count(), 1);
        assert_eq!(
            doc.matches("\n<!-- end of the generated figures -->")
                .count(),
            1
        );
        assert!(replace_block(doc, BLOCK).is_ok());
    }
}
