// A robot crate's own motherboard image carries the daughterboard images (issue 25,
// docs/boards.md "The motherboard carries the images"): the build script of a crate made by
// `cargo x10 new` includes this file after `carry.rs` and calls
// `carry_from_checkout("PATH/TO/X10")` (the checkout its Cargo.toml names). For the Pico's
// image (target thumbv6m-none-eabi) it runs `cargo xtask carry` in the X10 checkout, which
// builds the carried daughterboard images exactly as the checkout's `cargo mb-pico` and
// `cargo xtask size` do (the kinds of `X10_CARRY_KINDS`, default `pico`; the same features,
// `DEFMT_LOG` and toolchain: the checkout's own `.cargo/config.toml` and
// `rust-toolchain.toml`), cuts each slot's bytes into `target/carry/NAME.bin` and prints
// `X10_CARRY`, which `carried_images_of` (`carry.rs`) embeds. The nested cargo:
//
// * gets none of the variables the outer build set for this script or for its own
//   compilation ([`outer_build_var`]: `CARGO_TARGET_DIR`, `CARGO_ENCODED_RUSTFLAGS`, `RUSTC`,
//   the rustc wrappers of `cargo clippy`, `CARGO_FEATURE_*`, `TARGET`, `DEFMT_LOG` (the robot
//   crate's `info` would grow db-pico and change its bytes), `RUSTUP_TOOLCHAIN`, …);
// * builds in the checkout's `target/` (so a `cargo xtask size` or `cargo mb-pico` of the
//   checkout already built it; `X10_CARRY_TARGET_DIR` names another, when the checkout's own
//   builds use a `CARGO_TARGET_DIR`), unless that is the outer build's own target directory,
//   which the outer cargo holds locked (a deadlock): then in `carry-build/` below it;
// * reruns only when a source file of the carried images (their dep-info) changes, or one of
//   the variables below.
//
// Nothing is run for host builds (`cargo sim`, `cargo test`, `cargo clippy` on the host) nor
// for the STM32G431 image (its 128 KiB carry none). `X10_CARRY` set (even empty) is used as
// it is, and `X10_CARRY_KINDS=` (empty) carries nothing: both skip the checkout.

/// Whether the variable `name`, set in this build script's environment, is one of those the
/// outer build set (for this script, for its compilation or through its own configuration)
/// that would change the nested build of the checkout's images, or point it at the outer
/// build's files.
fn outer_build_var(name: &str) -> bool {
    const EXACT: &[&str] = &[
        "CARGO",
        "RUSTC",
        "RUSTDOC",
        "RUSTC_WRAPPER",
        "RUSTC_WORKSPACE_WRAPPER",
        "RUSTC_LINKER",
        "RUSTFLAGS",
        "RUSTDOCFLAGS",
        "RUSTUP_TOOLCHAIN",
        "TARGET",
        "HOST",
        "OUT_DIR",
        "OPT_LEVEL",
        "PROFILE",
        "DEBUG",
        "NUM_JOBS",
        "MAKEFLAGS",
        "MFLAGS",
        "DEFMT_LOG",
        "DEFMT_RTT_BUFFER_SIZE",
        "X10_CARRY",
        "X10_DB_ADDR",
    ];
    const PREFIXES: &[&str] = &[
        "CARGO_FEATURE_",
        "CARGO_CFG_",
        "CARGO_PKG_",
        "CARGO_MANIFEST_",
        "CARGO_ENCODED_",
        "CARGO_TARGET_",
        "CARGO_BUILD_",
        "CARGO_PROFILE_",
        "CARGO_MAKEFLAGS",
        "CARGO_PRIMARY_PACKAGE",
        "CARGO_CRATE_",
        "CARGO_BIN_",
        "CARGO_INCREMENTAL",
        "CARGO_RUSTC_",
        "CLIPPY_",
        "DEP_",
        "__CARGO",
    ];
    EXACT.contains(&name) || PREFIXES.iter().any(|p| name.starts_with(p))
}

/// The outer build's target directory: the first directory above `out_dir` (its `OUT_DIR`)
/// that holds cargo's `CACHEDIR.TAG`.
fn outer_target_dir(out_dir: &std::path::Path) -> Option<std::path::PathBuf> {
    out_dir
        .ancestors()
        .find(|d| d.join("CACHEDIR.TAG").is_file())
        .map(std::path::Path::to_path_buf)
}

/// The target directory of the nested build: the checkout's `target/`, or `target/carry-build/`
/// below it when the outer build uses the checkout's `target/` itself.
fn nested_target_dir(
    checkout_target: &std::path::Path,
    outer: Option<&std::path::Path>,
) -> std::path::PathBuf {
    let same = |a: &std::path::Path, b: &std::path::Path| match (
        std::fs::canonicalize(a),
        std::fs::canonicalize(b),
    ) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    };
    match outer {
        Some(o) if same(o, checkout_target) => checkout_target.join("carry-build"),
        _ => checkout_target.to_path_buf(),
    }
}

/// Splits `cargo xtask carry`'s output into its `cargo:` directives (passed on as they are)
/// and the value of its `X10_CARRY=` line.
///
/// # Errors
/// The output has no `X10_CARRY=` line.
fn carry_output(stdout: &str) -> Result<(Vec<&str>, &str), String> {
    let mut directives = Vec::new();
    let mut value = None;
    for line in stdout.lines() {
        if line.starts_with("cargo:") {
            directives.push(line);
        } else if let Some(v) = line.strip_prefix("X10_CARRY=") {
            value = Some(v);
        }
    }
    value
        .map(|v| (directives, v))
        .ok_or_else(|| format!("`cargo xtask carry` printed no X10_CARRY line:\n{stdout}"))
}

/// Runs `cargo xtask carry` in the checkout at `checkout` without the outer build's variables;
/// its directives and `X10_CARRY`'s value.
///
/// # Errors
/// The command cannot be run, fails (its standard error) or prints no `X10_CARRY`.
fn run_checkout_carry(checkout: &std::path::Path) -> Result<(Vec<String>, String), String> {
    let outer =
        std::env::var_os("OUT_DIR").and_then(|o| outer_target_dir(std::path::Path::new(&o)));
    // The checkout's target directory: `X10_CARRY_TARGET_DIR` when its builds use another
    // than `target/` (its own `CARGO_TARGET_DIR`, which this build's environment does not have).
    let checkout_target = std::env::var_os("X10_CARRY_TARGET_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| checkout.join("target"));
    let target = nested_target_dir(&checkout_target, outer.as_deref());
    let mut c = std::process::Command::new("cargo");
    c.current_dir(checkout);
    for (name, _) in std::env::vars_os() {
        if name.to_str().is_some_and(outer_build_var) {
            c.env_remove(&name);
        }
    }
    c.env("CARGO_TARGET_DIR", &target).args(["xtask", "carry"]);
    let out = c
        .output()
        .map_err(|e| format!("cannot run cargo in {}: {e}", checkout.display()))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(format!(
            "`cargo xtask carry` in {} failed:\n{}",
            checkout.display(),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let (directives, value) = carry_output(&stdout)?;
    Ok((
        directives.into_iter().map(str::to_owned).collect(),
        value.to_owned(),
    ))
}

/// The build script's part: with the Pico's image (thumbv6m-none-eabi), the daughterboard
/// images the X10 checkout at `checkout` (relative to the crate) builds, carried as
/// `carry.rs` embeds them; for other builds none. A failure fails the build, saying why.
fn carry_from_checkout(checkout: &str) {
    for var in [
        "X10_CARRY",
        "X10_CARRY_KINDS",
        "X10_FW_VERSION",
        "X10_BUS_HZ",
        "X10_CARRY_TARGET_DIR",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    if std::env::var_os("X10_CARRY").is_some() {
        carried_images();
        return;
    }
    let pico = std::env::var("TARGET").as_deref() == Ok("thumbv6m-none-eabi");
    let none_wanted = std::env::var("X10_CARRY_KINDS").is_ok_and(|k| k.trim().is_empty());
    if !pico || none_wanted {
        carried_images_of("");
        return;
    }
    let dir = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_default()
        .join(checkout);
    match run_checkout_carry(&dir) {
        Ok((directives, value)) => {
            for d in directives {
                println!("{d}");
            }
            carried_images_of(&value);
        }
        Err(e) => {
            eprintln!("error: the daughterboard images this motherboard image carries: {e}");
            eprintln!("(X10_CARRY_KINDS= builds it carrying none; docs/boards.md)");
            std::process::exit(1);
        }
    }
}
