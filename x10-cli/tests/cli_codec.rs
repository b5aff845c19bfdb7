//! The `x10 decode` / `x10 encode` commands, run as a user runs them (the built binary).
//!
//! * Every example frame of `docs/protocol.md` decodes (`--json`) to the fields the document
//!   states, and `encode --json` of that output gives back exactly the same bytes.
//! * Refused frames and bad input give one line on standard error and a non-zero exit status,
//!   never a panic.

use std::io::Write;
use std::process::{Command, Output, Stdio};

use serde_json::Value;

fn x10(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_x10"))
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run x10")
}

fn x10_stdin(args: &[&str], input: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_x10"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run x10");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("write stdin");
    child.wait_with_output().expect("x10 output")
}

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).expect("utf-8 stdout")
}

fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).expect("utf-8 stderr")
}

/// Asserts a failure with exactly one line on standard error, and returns that line.
fn one_line_error(o: &Output, code: i32) -> String {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(code), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.lines().count(), 1, "not one line: {err:?}");
    err.trim_end().to_string()
}

// ---------------------------------------------------------------------------------------------
// The document's examples
// ---------------------------------------------------------------------------------------------

struct Example {
    line: usize,
    kind: String,
    pec: Option<String>,
    hex: String,
    fields: Vec<(String, String)>,
}

fn examples() -> Vec<Example> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    let text = std::fs::read_to_string(path).expect("docs/protocol.md");
    let start = text
        .find("\n## Example frames\n")
        .expect("## Example frames");
    let first_line = text[..start].lines().count() + 1;
    let mut out = Vec::new();
    for (i, line) in text[start..].lines().enumerate() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 6 || !["request", "reply", "event"].contains(&cells[1]) {
            continue;
        }
        let unquote = |s: &str| s.trim_matches('`').trim().to_string();
        out.push(Example {
            line: first_line + i,
            kind: cells[1].to_string(),
            pec: (cells[2] != "-").then(|| unquote(cells[2])),
            hex: unquote(cells[3]),
            fields: unquote(cells[4])
                .split_whitespace()
                .map(|kv| {
                    let (k, v) = kv.split_once('=').expect("key=value");
                    (k.to_string(), v.to_string())
                })
                .collect(),
        });
    }
    assert!(out.len() >= 20, "only {} examples", out.len());
    out
}

fn int(s: &str) -> Option<u64> {
    match s.strip_prefix("0x") {
        Some(h) => u64::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

/// The doc's value syntax as JSON.
fn doc_value(s: &str) -> Value {
    match s {
        "null" => Value::Null,
        "true" => Value::Bool(true),
        "false" => Value::Bool(false),
        _ => {
            if let Some(inner) = s.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
                Value::Array(
                    inner
                        .split(',')
                        .filter(|x| !x.is_empty())
                        .map(|x| Value::from(int(x).expect("list of integers")))
                        .collect(),
                )
            } else if let Some(n) = int(s) {
                Value::from(n)
            } else {
                Value::String(s.to_string())
            }
        }
    }
}

/// `items.1.duty` → `v["items"][1]["duty"]`.
fn at<'v>(v: &'v Value, path: &str) -> Option<&'v Value> {
    path.split('.')
        .try_fold(v, |v, seg| match seg.parse::<usize>() {
            Ok(i) if v.is_array() => v.get(i),
            _ => v.get(seg),
        })
}

fn decode_args(ex: &Example) -> Vec<String> {
    let mut args = vec!["decode".to_string(), "--json".to_string()];
    match ex.kind.as_str() {
        "reply" => args.push("--reply".into()),
        "event" => args.push("--event".into()),
        _ => {}
    }
    if let Some(p) = &ex.pec {
        args.extend(["--pec".to_string(), p.clone()]);
    }
    if let Some((_, a)) = ex.fields.iter().find(|(k, _)| k == "answers") {
        args.extend(["--answers".to_string(), a.clone()]);
    }
    args.push(ex.hex.clone());
    args
}

#[test]
fn documented_examples_decode_and_encode_back() {
    let mut checked = 0;
    for ex in examples() {
        let args = decode_args(&ex);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = x10(&args);
        if let Some((_, status)) = ex.fields.iter().find(|(k, _)| k == "error") {
            let line = one_line_error(&out, 1);
            assert!(
                line.contains(&format!("status {status}")),
                "line {}: {line}",
                ex.line
            );
            assert!(stdout(&out).is_empty());
            continue;
        }
        assert!(out.status.success(), "line {}: {}", ex.line, stderr(&out));
        let text = stdout(&out);
        assert_eq!(text.lines().count(), 1, "line {}: {text}", ex.line);
        let json: Value = serde_json::from_str(text.trim()).expect("JSON");
        assert_eq!(
            json["kind"],
            Value::from(ex.kind.as_str()),
            "line {}",
            ex.line
        );
        for (k, v) in &ex.fields {
            assert_eq!(
                at(&json, k),
                Some(&doc_value(v)),
                "line {}: `{k}` in {json}",
                ex.line
            );
        }
        // ... and back.
        let out = x10(&["encode", "--json", text.trim()]);
        assert!(out.status.success(), "line {}: {}", ex.line, stderr(&out));
        assert_eq!(stdout(&out).trim(), ex.hex, "line {}", ex.line);
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} round trips");
}

#[test]
fn documented_examples_round_trip_through_a_pipe() {
    // All request frames without PEC through standard input, as a capture would be fed.
    let frames: Vec<String> = examples()
        .into_iter()
        .filter(|e| e.kind == "request" && e.pec.is_none())
        .filter(|e| !e.fields.iter().any(|(k, _)| k == "error"))
        .map(|e| e.hex)
        .collect();
    let input = format!("# a capture\n\n{}\n", frames.join("\n"));
    let decoded = x10_stdin(&["decode", "--json"], &input);
    assert!(decoded.status.success(), "{}", stderr(&decoded));
    assert_eq!(stdout(&decoded).lines().count(), frames.len());
    let encoded = x10_stdin(&["encode", "--json"], &stdout(&decoded));
    assert!(encoded.status.success(), "{}", stderr(&encoded));
    let lines: Vec<String> = stdout(&encoded).lines().map(str::to_string).collect();
    assert_eq!(lines, frames);
}

// ---------------------------------------------------------------------------------------------
// Words, forms of input, context
// ---------------------------------------------------------------------------------------------

#[test]
fn words() {
    let out = x10(&[
        "decode",
        "12 09 01 02",
        "30098004",
        "reply:04000200 02",
        "event:09 03 85 0b 00 04 f0 05 00 00",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        stdout(&out),
        "request to DB 0x09 seq 2: io high on actuator port 1 pin B\n\
         request to DB 0x09 seq 4: analog read on sensor port 1\n\
         reply seq 4 to analog.read: ok, value 512\n\
         event from DB 0x09 seq 11: deferred_reply on sensor port 3 pin B, status ok, width_us 1520\n"
    );
    let out = x10(&["decode", "--pec", "9", "12 09 01 02 9c"]);
    assert_eq!(
        stdout(&out),
        "request to DB 0x09 seq 2: io high on actuator port 1 pin B [PEC 0x9c ok, address 0x09]\n"
    );
}

#[test]
fn hex_forms_and_prefixes_agree() {
    let want = stdout(&x10(&["decode", "--json", "12 09 01 02"]));
    for form in [
        "12090102",
        "12:09:01:02",
        "0x12,0x09,0x01,0x02",
        "request:12 09 01 02",
    ] {
        assert_eq!(stdout(&x10(&["decode", "--json", form])), want, "{form}");
    }
    let flag = stdout(&x10(&["decode", "--json", "--reply", "04 00 02 00 02"]));
    let prefix = stdout(&x10(&["decode", "--json", "reply:04 00 02 00 02"]));
    assert_eq!(flag, prefix);
    let flag = stdout(&x10(&[
        "decode",
        "--json",
        "--event",
        "09 01 80 07 00 01 01",
    ]));
    let prefix = stdout(&x10(&["decode", "--json", "event:09 01 80 07 00 01 01"]));
    assert_eq!(flag, prefix);
    // A prefix overrides the flag.
    let out = x10(&["decode", "--json", "--reply", "request:12 09 01 02"]);
    assert_eq!(stdout(&out), want);
}

#[test]
fn bytes_as_separate_arguments_are_one_frame() {
    // As a logic analyzer prints them: two or more arguments, each one byte (one or two hex
    // digits, optionally 0x), are the bytes of one frame.
    let io_high = "request to DB 0x09 seq 2: io high on actuator port 1 pin B\n";
    for args in [
        &["decode", "12", "09", "01", "02"][..],
        &["decode", "0x12", "0x09", "0x01", "0x02"],
        &["decode", "12", "9", "1", "2"],
        &["decode", "request:12", "09", "01", "02"],
    ] {
        let out = x10(args);
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        assert_eq!(stdout(&out), io_high, "{args:?}");
    }
    assert_eq!(
        stdout(&x10(&["decode", "--json", "30", "09", "80", "04"])),
        stdout(&x10(&["decode", "--json", "30 09 80 04"]))
    );
    let out = x10(&["decode", "reply:04", "00", "02", "00", "02"]);
    assert_eq!(stdout(&out), "reply seq 4: ok, payload [00 02]\n");
    let out = x10(&["decode", "--pec", "9", "12", "09", "01", "02", "9c"]);
    assert_eq!(
        stdout(&out),
        "request to DB 0x09 seq 2: io high on actuator port 1 pin B [PEC 0x9c ok, address 0x09]\n"
    );
    // The joined frame is named as one frame in errors.
    let line = one_line_error(&x10(&["decode", "12", "09", "01"]), 1);
    assert_eq!(
        line,
        "x10 decode: frame 1 `12 09 01`: invalid request: frame truncated (a board answers status bad_length)"
    );
    // Arguments of several bytes are one frame each, as before ...
    let out = x10(&["decode", "12090102", "30 09 80 04"]);
    assert_eq!(
        stdout(&out),
        "request to DB 0x09 seq 2: io high on actuator port 1 pin B\n\
         request to DB 0x09 seq 4: analog read on sensor port 1\n"
    );
    // ... and so is every argument once one of them is not a single byte.
    let out = x10(&["decode", "12", "09", "01", "0102"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(stdout(&out), "");
    assert_eq!(
        stderr(&out),
        "x10 decode: frame 1 `12`: invalid request: frame truncated (a board answers status bad_length)\n\
         x10 decode: frame 2 `09`: invalid request: frame truncated (a board answers status bad_length)\n\
         x10 decode: frame 3 `01`: invalid request: frame truncated (a board answers status bad_length)\n\
         x10 decode: frame 4 `0102`: invalid request: frame truncated (a board answers status bad_length)\n"
    );
    let help = stdout(&x10(&["decode", "--help"]));
    assert!(help.contains("they are the bytes of ONE frame"), "{help}");
}

#[test]
fn a_reply_is_decoded_as_the_answer_to_the_request_before_it() {
    let out = x10(&[
        "decode",
        "--json",
        "01 09 00 02",
        "reply:02 00 0a 01 00 01 00 03 04 04 ff 01 0c",
        "reply:02 00 0a 01 00 01 00 03 04 04 ff 01 0c",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let lines: Vec<Value> = stdout(&out)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines[1]["answers"], "system.identify");
    assert_eq!(lines[1]["identity"]["board"], "pico");
    assert_eq!(lines[1]["identity"]["capabilities"], 511);
    // The context is used once: a second reply with the same sequence number is plain.
    assert_eq!(lines[2].get("answers"), None);
    // Each line encodes back.
    for l in &lines {
        let out = x10(&["encode", "--json", &l.to_string()]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
}

#[test]
fn encode_from_decoded_fields() {
    let out = x10(&[
        "encode",
        "--json",
        r#"{"function":"pwm","operation":"duty","db":9,"port_kind":"actuator","port":1,"pin":"B","seq":3,"duty":128}"#,
        r#"{"kind":"event","source":9,"event":"pin_change","port_kind":"sensor","port":1,"pin":"A","seq":7,"level":1,"pec_addr":16}"#,
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(stdout(&out), "20 09 01 03 80\n09 01 80 07 00 01 01 95\n");
}

// ---------------------------------------------------------------------------------------------
// Bad input: one line, non-zero exit, no panic
// ---------------------------------------------------------------------------------------------

#[test]
fn bad_hex() {
    let line = one_line_error(&x10(&["decode", "12g90102"]), 1);
    assert_eq!(
        line,
        "x10 decode: frame 1 `12g90102`: `g` is not a hex digit (in `12g90102`)"
    );
    let line = one_line_error(&x10(&["decode", "12 9 01 02"]), 1);
    assert_eq!(
        line,
        "x10 decode: frame 1 `12 9 01 02`: `9` has an odd number of hex digits"
    );
    let line = one_line_error(&x10(&["decode", "reply:"]), 1);
    assert_eq!(line, "x10 decode: frame 1 `reply:`: no bytes given");
}

#[test]
fn bad_frames() {
    let cases: &[(&[&str], &str)] = &[
        (
            &["decode", "12 09 01"],
            "x10 decode: frame 1 `12 09 01`: invalid request: frame truncated (a board answers status bad_length)",
        ),
        (
            &["decode", "f0 09 00 01"],
            "x10 decode: frame 1 `f0 09 00 01`: invalid request: unknown function 0xf (a board answers status unknown_function)",
        ),
        (
            &["decode", "--reply", "01 00 05 00"],
            "x10 decode: frame 1 `01 00 05 00`: invalid reply: frame truncated (a board answers status bad_length)",
        ),
        (
            &["decode", "--event", "--pec", "0x10", "09 01 80 07 00 01 01 00"],
            "x10 decode: frame 1 `09 01 80 07 00 01 01 00`: invalid event: PEC mismatch: received 0x00, computed 0x95 (a board answers status pec_mismatch)",
        ),
    ];
    for (args, want) in cases {
        assert_eq!(one_line_error(&x10(args), 1), *want, "{args:?}");
    }
    // Good frames around a bad one are still decoded; the exit status says one failed.
    let out = x10(&["decode", "12 09 01 02", "zz", "30 09 80 04"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(stdout(&out).lines().count(), 2);
    assert_eq!(stderr(&out).lines().count(), 1);
}

#[test]
fn bad_json() {
    let cases: &[(&str, &str)] = &[
        ("{\"x\":1", "not JSON: EOF while parsing an object at line 1 column 6"),
        ("[1,2]", "expected a JSON object, got [1,2]"),
        (
            r#"{"function":"io","operation":"high","db":9,"seq":2,"port_kind":"actuator","port":1,"pin":"B","colour":1}"#,
            "unknown key `colour` for io high",
        ),
        (
            r#"{"function":"io","operation":"high","db":9,"seq":256,"port_kind":"actuator","port":1}"#,
            "`seq` must be an integer 0..=255, got 256",
        ),
        (
            r#"{"function":"io","operation":"high","db":9,"seq":2,"port_kind":"actuator","port":0}"#,
            "`port` must be 1..=64, got 0",
        ),
        (
            r#"{"function":"analog","operation":"read","db":9,"seq":2,"port_kind":"actuator","port":1}"#,
            "invalid request: operation not available on this kind of port (a board answers status wrong_port_kind)",
        ),
        (
            r#"{"function":"pwm","operation":"duty","db":9,"seq":2,"port_kind":"actuator","port":1,"duty":1,"data":[2]}"#,
            "`duty` is 1 but the frame says 2",
        ),
        (
            r#"{"kind":"reply","seq":1,"status":"ok","payload":[1,2],"answers":"analog.read","value":3}"#,
            "`value` is 3 but the frame says 513",
        ),
        (
            r#"{"kind":"event","source":9,"event":"pin_change","seq":1,"payload":[300]}"#,
            "`payload` holds bytes 0..=255, got 300",
        ),
    ];
    for (object, want) in cases {
        let line = one_line_error(&x10(&["encode", "--json", object]), 1);
        assert_eq!(line, format!("x10 encode: object 1: {want}"), "{object}");
    }
}

#[test]
fn bad_usage() {
    let cases: &[(&[&str], &str)] = &[
        (
            &["decode", "--bogus", "12"],
            "x10: unexpected argument '--bogus' found",
        ),
        (
            &["decode", "--pec", "0x80", "12"],
            "x10: invalid value '0x80' for '--pec <ADDR>'",
        ),
        (
            &["decode", "--answers", "io.high", "12"],
            "x10: invalid value 'io.high' for '--answers <OP>'",
        ),
        (
            &["decode", "--reply", "--event", "12"],
            "x10: the argument '--reply' cannot be used with '--event'",
        ),
        (
            &["encode", "{}"],
            "x10: the following required arguments were not provided: --json",
        ),
        (&["frobnicate"], "x10: unrecognized subcommand 'frobnicate'"),
    ];
    for (args, want) in cases {
        let line = one_line_error(&x10(args), 2);
        assert!(line.starts_with(want), "{args:?}: {line}");
    }
    // Help is not an error.
    let out = x10(&["decode", "--help"]);
    assert!(out.status.success());
    assert!(stdout(&out).contains("--pec <ADDR>"));
    assert!(stdout(&out).contains("reply:"));
    let out = x10(&["encode", "--help"]);
    assert!(out.status.success());
    assert!(stdout(&out).contains("pec_addr"));
}
