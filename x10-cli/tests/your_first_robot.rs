//! `docs/your-first-robot.md` cannot drift from the template: every Rust or TOML block in it is
//! a file of `templates/robot/`, word for word (and `./test-all` builds, runs and tests a crate
//! made from that template: `templates/check.sh`), and the template is what `x10 new` writes.

use std::path::Path;

const DOC: &str = include_str!("../../docs/your-first-robot.md");

/// (file named by the marker above the block, fence language, block text).
fn blocks() -> Vec<(Option<String>, String, String)> {
    let mut out = Vec::new();
    let mut lines = DOC.lines().peekable();
    let mut marker: Option<String> = None;
    while let Some(line) = lines.next() {
        if let Some(rest) = line.strip_prefix("<!-- file: ") {
            marker = rest.strip_suffix(" -->").map(str::to_string);
            continue;
        }
        if let Some(lang) = line.strip_prefix("```") {
            let mut text = Vec::new();
            for l in lines.by_ref() {
                if l == "```" {
                    break;
                }
                text.push(l);
            }
            out.push((marker.take(), lang.to_string(), text.join("\n")));
            continue;
        }
        if !line.trim().is_empty() {
            marker = None;
        }
    }
    out
}

#[test]
fn every_rust_and_toml_block_is_a_template_file_word_for_word() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../templates/robot");
    let mut checked = 0;
    for (file, lang, text) in blocks() {
        if lang != "rust" && lang != "toml" {
            continue;
        }
        let file =
            file.unwrap_or_else(|| panic!("a ```{lang} block without a file marker:\n{text}"));
        let want = std::fs::read_to_string(root.join(&file)).unwrap();
        assert_eq!(
            text,
            want.trim_end_matches('\n'),
            "{file} differs from the doc"
        );
        checked += 1;
    }
    assert_eq!(checked, 10);
}

/// Commands of the guide that CI cannot run: they flash a board through a probe or its boot
/// drive, or watch a running board over USB (their build is the guide's `cargo build
/// --release …` lines, which CI runs; `x10 uf2` and `x10 monitor` have their own tests).
const FLASHING: [&str; 5] = [
    "cargo mb-pico",
    "cargo mb-g431",
    "cargo x10 uf2 target/thumbv6m-none-eabi/release/mb-pico --copy",
    "cargo x10 monitor --world ~/robots/rover/world.toml --html rover.html",
    "cargo x10 monitor --world ~/robots/rover/world.toml --mcap rover.mcap",
];

#[test]
fn every_command_of_the_guide_is_run_by_ci() {
    let script = include_str!("../../templates/check.sh");
    let mut checked = 0;
    for (_, lang, text) in blocks() {
        if lang != "sh" {
            continue;
        }
        for line in text.lines() {
            // The command without its comment; `cd` only moves (check.sh has its own).
            let command = line.split(" #").next().unwrap_or("").trim();
            if command.is_empty() || command.starts_with("cd ") || FLASHING.contains(&command) {
                continue;
            }
            // The guide's folders are check.sh's: the new crate and this checkout.
            let run = command
                .replace("../my-robot", "\"$dir\"")
                .replace("../x10/", "\"$root\"/");
            assert!(
                script.lines().any(|l| l.trim() == run
                    || l.trim().starts_with(&format!("{run} |"))
                    || l.trim().starts_with(&format!("(cd \"$root\" && {run})"))),
                "the guide's `{command}` is not run by templates/check.sh (as `{run}`)"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 18);
}

/// The robot's tasks are named once, in `src/lib.rs` (`x10::robot!`): `cargo sim`, the tests
/// and both images take them from `robot::Robot`. So the guide's section 7 robot
/// (`templates/shared/`) is only a `src/lib.rs` and its tests, run with the template's own
/// `sim.rs` and images (templates/check.sh copies the two files over a new crate).
#[test]
fn the_tasks_are_named_once_in_the_lib() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../templates");
    for rel in [
        "src/bin/sim.rs",
        "src/bin/mb-pico.rs",
        "src/bin/mb-g431.rs",
        "tests/sim.rs",
    ] {
        let text = std::fs::read_to_string(root.join("robot").join(rel)).unwrap();
        for named in [
            "robot::blink",
            "robot::drive",
            "with_robot",
            "embassy_executor::task",
        ] {
            assert!(
                !text.contains(named),
                "templates/robot/{rel} names `{named}`"
            );
        }
        assert!(text.contains("robot::Robot"), "templates/robot/{rel}");
    }
    let lib = std::fs::read_to_string(root.join("robot/src/lib.rs")).unwrap();
    assert!(lib.contains("pub struct Robot { blink, drive }"));
    let shared = std::fs::read_to_string(root.join("shared/src/lib.rs")).unwrap();
    assert!(shared.contains("pub struct Robot { drive, bumper }"));
    let mut files: Vec<String> = walk(&root.join("shared"));
    files.sort();
    assert_eq!(files, ["src/lib.rs", "tests/sim.rs"]);
    // Section 8's robot in an arena: its lib, its world and its test, over the same crate.
    let arena = std::fs::read_to_string(root.join("arena/src/lib.rs")).unwrap();
    assert!(arena.contains("pub struct Robot { explore }"));
    let mut files: Vec<String> = walk(&root.join("arena"));
    files.sort();
    assert_eq!(files, ["src/lib.rs", "tests/sim.rs", "world.toml"]);
}

/// The files under `dir`, relative to it.
fn walk(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap();
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out
}

#[test]
fn the_template_is_what_x10_new_writes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../templates/robot");
    for (rel, text) in x10_cli::new::TEMPLATE {
        if rel == ".gitignore" {
            continue;
        }
        let on_disk = std::fs::read_to_string(root.join(rel)).unwrap();
        assert_eq!(text, on_disk, "{rel}");
    }
}

#[test]
fn no_output_is_left_to_fill() {
    assert!(
        !DOC.contains("@@"),
        "an output placeholder is left in the guide"
    );
}
