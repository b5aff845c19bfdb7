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
    assert_eq!(checked, 5);
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
