//! `x10 new PATH`: writes a new robot crate from the template in `templates/robot/` of the X10
//! repository (compiled into the tool, so the template and the tool never disagree).
//!
//! The crate depends on the X10 crates by path (nothing is published yet): on this
//! repository's checkout by default, or on the one `--x10 DIR` names. The path is relative
//! (`../x10/x10`, from the crate's folder to the checkout), in `Cargo.toml` and `build.rs`
//! alike, so both folders can move together (side by side, into another home, a container's
//! mount). It gets this repository's `Cargo.lock`, so it builds with the crate versions X10 is
//! tested with.

use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

/// The template's files: path inside the new crate, contents with `{{name}}` and `{{x10}}`
/// placeholders.
pub const TEMPLATE: [(&str, &str); 11] = [
    (
        "Cargo.toml",
        include_str!("../../templates/robot/Cargo.toml"),
    ),
    (
        ".cargo/config.toml",
        include_str!("../../templates/robot/.cargo/config.toml"),
    ),
    (
        "rust-toolchain.toml",
        include_str!("../../templates/robot/rust-toolchain.toml"),
    ),
    ("build.rs", include_str!("../../templates/robot/build.rs")),
    (
        "world.toml",
        include_str!("../../templates/robot/world.toml"),
    ),
    (
        "src/lib.rs",
        include_str!("../../templates/robot/src/lib.rs"),
    ),
    (
        "src/bin/sim.rs",
        include_str!("../../templates/robot/src/bin/sim.rs"),
    ),
    (
        "src/bin/mb-pico.rs",
        include_str!("../../templates/robot/src/bin/mb-pico.rs"),
    ),
    (
        "src/bin/mb-g431.rs",
        include_str!("../../templates/robot/src/bin/mb-g431.rs"),
    ),
    (
        "tests/sim.rs",
        include_str!("../../templates/robot/tests/sim.rs"),
    ),
    (".gitignore", "/target\n"),
];

/// Why `x10 new` wrote nothing.
#[derive(Debug, PartialEq, Eq)]
pub enum NewError {
    /// The target folder exists and is not empty.
    NotEmpty(PathBuf),
    /// No crate name can be made from the folder's name (give `--name`).
    BadName(String),
    /// The X10 checkout has no `x10/Cargo.toml`.
    NotX10(PathBuf),
    /// Writing failed.
    Io(PathBuf, String),
}

impl fmt::Display for NewError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NewError::NotEmpty(p) => write!(f, "{} exists and is not empty", p.display()),
            NewError::BadName(n) => write!(
                f,
                "{n:?} is not a crate name: use letters, digits, '-' and '_', starting with a letter (or give --name)"
            ),
            NewError::NotX10(p) => write!(
                f,
                "{} is not an X10 checkout (no x10/Cargo.toml there): give --x10 DIR",
                p.display()
            ),
            NewError::Io(p, e) => write!(f, "cannot write {}: {e}", p.display()),
        }
    }
}

impl std::error::Error for NewError {}

/// A crate name from a folder name: lower case, anything but letters, digits, `-` and `_`
/// becomes `-`; must start with a letter.
///
/// # Errors
/// [`NewError::BadName`] when nothing usable is left.
pub fn crate_name(raw: &str) -> Result<String, NewError> {
    let name: String = raw
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    let name = name.trim_matches('-').to_string();
    if name.starts_with(|c: char| c.is_ascii_lowercase()) {
        Ok(name)
    } else {
        Err(NewError::BadName(raw.to_string()))
    }
}

/// The X10 checkout this tool was built from.
pub fn own_checkout() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    dir.canonicalize().unwrap_or(dir)
}

/// Fills the placeholders of one template file.
pub fn fill(text: &str, name: &str, x10: &Path) -> String {
    // TOML strings: a Windows path's backslashes must be escaped.
    let x10 = x10.display().to_string().replace('\\', "\\\\");
    text.replace("{{name}}", name).replace("{{x10}}", &x10)
}

/// The path from folder `from` to `to`, both absolute (`..` up to their common folder, then
/// down); `to` itself when they share nothing (another drive on Windows).
pub fn relative(from: &Path, to: &Path) -> PathBuf {
    let (f, t): (Vec<_>, Vec<_>) = (from.components().collect(), to.components().collect());
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return to.to_path_buf();
    }
    let mut out = PathBuf::new();
    for _ in common..f.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c);
    }
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    out
}

/// Writes the new crate `name` into `dir` (created if missing, must be empty), depending on
/// the X10 checkout `x10` by a path relative to `dir` ([`relative`]). Returns the files
/// written.
///
/// # Errors
/// [`NewError`]: nothing is written when `dir` is not empty or `x10` is not a checkout.
pub fn create(dir: &Path, name: &str, x10: &Path) -> Result<Vec<PathBuf>, NewError> {
    if !x10.join("x10").join("Cargo.toml").is_file() {
        return Err(NewError::NotX10(x10.to_path_buf()));
    }
    if dir.exists() {
        let empty = fs::read_dir(dir)
            .map(|mut d| d.next().is_none())
            .unwrap_or(false);
        if !empty {
            return Err(NewError::NotEmpty(dir.to_path_buf()));
        }
    }
    let io = |p: &Path, e: std::io::Error| NewError::Io(p.to_path_buf(), e.to_string());
    fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let (here, there) = (dir.canonicalize(), x10.canonicalize());
    let (here, there) = (
        here.map_err(|e| io(dir, e))?,
        there.map_err(|e| io(x10, e))?,
    );
    let from_crate = relative(&here, &there);
    let mut written = Vec::new();
    for (rel, text) in TEMPLATE {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            fs::create_dir_all(parent).map_err(|e| io(parent, e))?;
        }
        fs::write(&path, fill(text, name, &from_crate)).map_err(|e| io(&path, e))?;
        written.push(path);
    }
    // The versions X10 is tested with (cargo drops what the new crate does not use).
    let lock = x10.join("Cargo.lock");
    if lock.is_file() {
        let path = dir.join("Cargo.lock");
        fs::copy(&lock, &path).map_err(|e| io(&path, e))?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crate_names_from_folder_names() {
        assert_eq!(crate_name("my-robot").as_deref(), Ok("my-robot"));
        assert_eq!(crate_name("My Robot").as_deref(), Ok("my-robot"));
        assert_eq!(crate_name("rover_2").as_deref(), Ok("rover_2"));
        assert_eq!(
            crate_name("2fast"),
            Err(NewError::BadName("2fast".to_string()))
        );
        assert_eq!(crate_name("--"), Err(NewError::BadName("--".to_string())));
    }

    #[test]
    fn placeholders_are_filled_and_none_is_left() {
        let x10 = Path::new("/src/x10");
        for (rel, text) in TEMPLATE {
            let out = fill(text, "rover", x10);
            assert!(!out.contains("{{"), "{rel} keeps a placeholder");
        }
        let cargo = fill(TEMPLATE[0].1, "rover", x10);
        assert!(cargo.contains("name = \"rover\""));
        assert!(cargo.contains("x10 = { path = \"/src/x10/x10\" }"));
    }

    #[test]
    fn relative_paths_between_folders() {
        let r = |a: &str, b: &str| relative(Path::new(a), Path::new(b));
        assert_eq!(r("/w/my-robot", "/w/x10"), Path::new("../x10"));
        assert_eq!(r("/w/x10/robots/mine", "/w/x10"), Path::new("../.."));
        assert_eq!(r("/home/a/r", "/w/x10"), Path::new("../../../w/x10"));
        assert_eq!(r("/w/x10", "/w/x10"), Path::new("."));
    }

    #[test]
    fn a_crate_is_written_once_and_never_over_another() {
        let base = std::env::temp_dir().join(format!("x10-new-test-{}", std::process::id()));
        let _ = fs::remove_dir_all(&base);
        let dir = base.join("rover");
        let written = create(&dir, "rover", &own_checkout()).unwrap();
        assert_eq!(written.len(), TEMPLATE.len() + 1);
        assert!(dir.join("src/lib.rs").is_file());
        assert!(dir.join("Cargo.lock").is_file());
        // Relative paths: no absolute path of the checkout in Cargo.toml or build.rs.
        let up = relative(&dir.canonicalize().unwrap(), &own_checkout());
        assert!(up.is_relative() && up.starts_with(".."), "{}", up.display());
        let cargo = fs::read_to_string(dir.join("Cargo.toml")).unwrap();
        let want = format!("x10 = {{ path = \"{}/x10\" }}", up.display());
        assert!(cargo.contains(&want), "{want} not in Cargo.toml");
        let build = fs::read_to_string(dir.join("build.rs")).unwrap();
        let want = format!("include!(\"{}/x10-boards/link_args.rs\");", up.display());
        assert!(build.contains(&want), "{want} not in build.rs");
        let checkout = format!("\"{}", own_checkout().display());
        assert!(!cargo.contains(&checkout) && !build.contains(&checkout));
        assert_eq!(
            create(&dir, "rover", &own_checkout()),
            Err(NewError::NotEmpty(dir.clone()))
        );
        assert_eq!(
            create(&base.join("other"), "other", &base),
            Err(NewError::NotX10(base.clone()))
        );
        let _ = fs::remove_dir_all(&base);
    }
}
