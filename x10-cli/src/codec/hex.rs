//! Frames as people and logic analyzers write them: hex bytes, one frame per argument or one
//! byte per argument, an optional `request:` / `reply:` / `event:` prefix; addresses.

use x10_microcode::Address;

use super::{CodecError, FrameKind, Result};

/// Splits an optional `request:`, `reply:` or `event:` prefix off a frame argument.
pub fn split_prefix(arg: &str) -> (Option<FrameKind>, &str) {
    let arg = arg.trim();
    if let Some((head, rest)) = arg.split_once(':') {
        if let Some(kind) = FrameKind::from_name(head.trim()) {
            return (Some(kind), rest);
        }
    }
    (None, arg)
}

/// Parses hex bytes: pairs of hex digits, optionally separated by spaces, `:`, `,`, `-` or
/// `_`, each group optionally prefixed `0x`. `12090102`, `12 09 01 02`, `12:09:01:02` and
/// `0x12,0x09,0x01,0x02` are the same frame.
///
/// # Errors
/// A character that is not a hex digit, a group with an odd number of digits, no bytes at all.
pub fn parse_hex(text: &str) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for group in text
        .split(|c: char| c.is_whitespace() || matches!(c, ':' | ',' | '-' | '_'))
        .filter(|g| !g.is_empty())
    {
        let digits = group
            .strip_prefix("0x")
            .or_else(|| group.strip_prefix("0X"))
            .unwrap_or(group);
        if let Some(bad) = digits.chars().find(|c| !c.is_ascii_hexdigit()) {
            return Err(CodecError::new(format!(
                "`{bad}` is not a hex digit (in `{group}`)"
            )));
        }
        if digits.is_empty() || digits.len() % 2 != 0 {
            return Err(CodecError::new(format!(
                "`{group}` has an odd number of hex digits"
            )));
        }
        for pair in digits.as_bytes().chunks(2) {
            let s = std::str::from_utf8(pair).map_err(|_| CodecError::new("bad hex"))?;
            let b = u8::from_str_radix(s, 16)
                .map_err(|_| CodecError::new(format!("`{s}` is not a hex byte")))?;
            out.push(b);
        }
    }
    if out.is_empty() {
        return Err(CodecError::new("no bytes given"));
    }
    Ok(out)
}

/// Lowercase hex, one space between bytes: the format [`parse_hex`] reads.
pub fn to_hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The frames given as command-line arguments. One argument is one frame, in any form
/// [`parse_hex`] reads, except when there are two or more arguments and every one is a single
/// byte — one or two hex digits, optionally prefixed `0x` — as logic analyzers print them: then
/// they are the bytes of one frame, and the first may carry a `request:`, `reply:` or `event:`
/// prefix. `12 09 01 02` (four arguments) is the frame `12 09 01 02`; `12090102 30098004` are
/// two frames. A frame of one byte is too short for every kind, so this does not change what
/// any valid input means.
pub fn frames_of_args(args: Vec<String>) -> Vec<String> {
    fn byte(arg: &str) -> Option<u8> {
        let arg = arg.trim();
        let digits = arg
            .strip_prefix("0x")
            .or_else(|| arg.strip_prefix("0X"))
            .unwrap_or(arg);
        if (1..=2).contains(&digits.len()) && digits.chars().all(|c| c.is_ascii_hexdigit()) {
            u8::from_str_radix(digits, 16).ok()
        } else {
            None
        }
    }
    let Some((first, rest)) = args.split_first() else {
        return args;
    };
    if rest.is_empty() {
        return args;
    }
    let (prefix, first) = split_prefix(first);
    let bytes: Option<Vec<u8>> = std::iter::once(first)
        .chain(rest.iter().map(String::as_str))
        .map(byte)
        .collect();
    match bytes {
        Some(bytes) => {
            let prefix = prefix.map_or(String::new(), |k| format!("{}:", k.name()));
            vec![format!("{prefix}{}", to_hex(&bytes))]
        }
        None => args,
    }
}

/// Parses an address given on the command line: decimal, or hex with `0x`.
///
/// # Errors
/// Not a number, or not a valid address (0 or `0x08..=0x77`).
pub fn parse_address(text: &str) -> Result<Address> {
    let t = text.trim();
    let n = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => u8::from_str_radix(h, 16),
        None => t.parse::<u8>(),
    }
    .map_err(|_| CodecError::new(format!("`{text}` is not an address (0..=0x77)")))?;
    Address::new(n).map_err(|e| CodecError::new(e.to_string()))
}
