//! Every Rust example in the docs compiles (issue 23 item 9). A ```` ```rust ```` block of
//! `docs/*.md` or the README is one of:
//!
//! * part of a doc that runs as doctests (its ```` ```rust ```` blocks compiled and run by
//!   `cargo test --doc`): `docs/world.md` (x10-sim), `docs/drivers.md` (x10-devices);
//! * a file of the robot template, word for word, under a `<!-- file: PATH -->` line
//!   (`docs/your-first-robot.md`, checked by x10-cli's `tests/your_first_robot.rs`; the
//!   template is built by `templates/check.sh`);
//! * an excerpt of a source file that the workspace compiles, fenced ```` ```rust,ignore ````
//!   under an `<!-- excerpt: PATH -->` line: its lines (comment lines aside) appear in that file
//!   in the same order, each whole (leading and trailing spaces aside).
//!
//! Anything else fails here, so no example can sit in the docs uncompiled.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The docs whose Rust blocks are doctests, and the crate source that includes each.
const DOCTESTED: [(&str, &str); 2] = [
    ("docs/world.md", "x10-sim/src/world.rs"),
    ("docs/drivers.md", "x10-devices/src/lib.rs"),
];

/// One fenced block: the marker line above it (if any), its fence info, its lines.
struct Block {
    marker: Option<String>,
    info: String,
    lines: Vec<String>,
    line_no: usize,
}

fn blocks(doc: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut marker = None;
    let mut lines = doc.lines().enumerate();
    while let Some((i, line)) = lines.next() {
        if line.starts_with("<!-- ") && line.ends_with(" -->") {
            marker = Some(line.to_string());
            continue;
        }
        if let Some(info) = line.strip_prefix("```") {
            let mut text = Vec::new();
            for (_, l) in lines.by_ref() {
                if l == "```" {
                    break;
                }
                text.push(l.to_string());
            }
            out.push(Block {
                marker: marker.take(),
                info: info.to_string(),
                lines: text,
                line_no: i + 1,
            });
            continue;
        }
        if !line.trim().is_empty() {
            marker = None;
        }
    }
    out
}

/// `Ok` when the excerpt's lines (comments aside) appear in `source` in order, each whole.
fn is_excerpt(excerpt: &[String], source: &str) -> Result<(), String> {
    let mut src = source.lines().map(str::trim);
    for want in excerpt.iter().map(|l| l.trim()) {
        if want.is_empty() || want.starts_with("//") {
            continue;
        }
        if !src.any(|l| l == want) {
            return Err(format!(
                "`{want}` is not in the file (after the lines before it)"
            ));
        }
    }
    Ok(())
}

fn docs() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    v.push(root().join("README.md"));
    v.sort();
    v
}

#[test]
fn every_rust_example_in_the_docs_is_compiled() {
    let mut checked = (0, 0, 0);
    for path in docs() {
        let name = path
            .strip_prefix(root())
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let doc = std::fs::read_to_string(&path).unwrap();
        let doctested = DOCTESTED.iter().any(|(d, _)| *d == name);
        for b in blocks(&doc) {
            let lang = b.info.split(',').next().unwrap_or("");
            if lang != "rust" {
                // Rustdoc compiles unlabelled blocks of a doctested doc as Rust.
                assert!(
                    !(doctested && b.info.is_empty()),
                    "{name}:{}: a block without a language (```text?)",
                    b.line_no
                );
                continue;
            }
            let marker = b.marker.as_deref().unwrap_or("");
            if let Some(file) = marker
                .strip_prefix("<!-- excerpt: ")
                .and_then(|m| m.strip_suffix(" -->"))
            {
                assert_eq!(
                    b.info, "rust,ignore",
                    "{name}:{}: an excerpt is fenced ```rust,ignore",
                    b.line_no
                );
                let source = std::fs::read_to_string(root().join(file))
                    .unwrap_or_else(|e| panic!("{name}:{}: {file}: {e}", b.line_no));
                if let Err(e) = is_excerpt(&b.lines, &source) {
                    panic!("{name}:{}: not an excerpt of {file}: {e}", b.line_no);
                }
                checked.0 += 1;
            } else if marker.starts_with("<!-- file: ") && name == "docs/your-first-robot.md" {
                checked.1 += 1;
            } else {
                assert!(
                    doctested && b.info == "rust",
                    "{name}:{}: a ```{} block that nothing compiles: make it a doctest of a \
                     doctested doc, a template file, or a marked excerpt",
                    b.line_no,
                    b.info
                );
                checked.2 += 1;
            }
        }
    }
    // Excerpts, template files, doctests.
    assert_eq!(checked, (5, 8, 5));
}

#[test]
fn the_doctested_docs_are_included_as_doctests() {
    for (doc, source) in DOCTESTED {
        let text = std::fs::read_to_string(root().join(source)).unwrap();
        let include = format!("#[cfg(doctest)]\n#[doc = include_str!(\"../../{doc}\")]");
        assert!(text.contains(&include), "{source} does not include {doc}");
    }
}

#[test]
fn an_excerpt_must_match_its_file_in_order() {
    let source = "fn a() {\n    let x = 1;\n    let y = 2;\n}\n";
    let lines = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert!(is_excerpt(&lines(&["fn a() {", "// …", "let y = 2;", "}"]), source).is_ok());
    assert!(is_excerpt(&lines(&["let y = 2;", "let x = 1;"]), source).is_err());
    assert!(is_excerpt(&lines(&["let x = 1; let y = 2;"]), source).is_err());
}
