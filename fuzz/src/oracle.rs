//! The oracle: what the protocol (docs/protocol.md) says a frame means, re-derived here with
//! the `crc` crate and byte offsets, without x10-microcode's parsers, and the checks of a
//! finished case against it.
//!
//! * every call ended, within its timeout (request timeout, plus the pulse timeout for a
//!   pulse-in), in virtual time;
//! * an `Ok` only when a transaction to that board, inside the call, validly answered that
//!   request: the request's bytes on the wire are the operation's (any sequence number), the
//!   reply echoes that sequence number with status `ok`, a payload length the operation allows
//!   (and the value it returned), the check (CRC-8/SMBUS up to 13 bytes, CRC-16/IBM-3740 above,
//!   over the read address byte) right when the request carried one (for `set_pec`, in the new
//!   mode). An output is `Ok` only when its write was acknowledged. A pulse-in is `Ok` only with
//!   a valid `pending` and then a valid `deferred_reply` event of that board, sequence number and
//!   pin, carrying a 4-byte width, sent after the `pending` and not possibly the answer of an
//!   earlier pulse-in of the same board, number and pin still within its deadline;
//! * a `Status(s)` only when a valid reply (or deferred reply) carried `s` with no payload;
//! * a waiter gets only pin events that were sent: same board, pin, kind and payload, well
//!   formed, checked when the board had PEC on (confirmed by a valid reply, until its boot
//!   event), each at most once per waiting task and in the order sent.

use std::fmt;

use crc::{Crc, CRC_16_IBM_3740, CRC_8_SMBUS};

/// CRC-8/SMBUS: polynomial 0x07, init 0.
const CRC8: Crc<u8> = Crc::<u8>::new(&CRC_8_SMBUS);
/// CRC-16/IBM-3740: polynomial 0x1021, init 0xFFFF.
const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// Largest payload of any frame.
pub const MAX_PAYLOAD: usize = 28;

/// The check a frame of `frame_len` bytes carries with PEC on (protocol.md, "The check").
pub fn check_of(addr_byte: u8, frame: &[u8]) -> Vec<u8> {
    if frame.len() <= 13 {
        let mut d = CRC8.digest();
        d.update(&[addr_byte]);
        d.update(frame);
        vec![d.finalize()]
    } else {
        let mut d = CRC16.digest();
        d.update(&[addr_byte]);
        d.update(frame);
        d.finalize().to_le_bytes().to_vec()
    }
}

/// `frame` with its check appended.
pub fn with_check(addr_byte: u8, frame: &[u8]) -> Vec<u8> {
    let mut v = frame.to_vec();
    v.extend(check_of(addr_byte, frame));
    v
}

/// A reply as a receiver reads it from `read` (frame, check if `pec`, then padding):
/// (seq, status, payload). `None` when malformed or the check is wrong.
pub fn parse_reply(db: u8, pec: bool, read: &[u8]) -> Option<(u8, u8, Vec<u8>)> {
    let n = usize::from(*read.get(2)?);
    if n > MAX_PAYLOAD {
        return None;
    }
    let frame = read.get(..3 + n)?;
    if pec {
        let check = check_of(db << 1 | 1, frame);
        if read.get(3 + n..3 + n + check.len())? != check.as_slice() {
            return None;
        }
    }
    Some((frame[0], frame[1], frame[3..].to_vec()))
}

/// A reply read with the always-CRC-16 check: the frame, then two CRC-16 bytes.
fn parse_reply16(db: u8, read: &[u8]) -> Option<(u8, u8, Vec<u8>)> {
    let n = usize::from(*read.get(2)?);
    if n > MAX_PAYLOAD {
        return None;
    }
    let frame = read.get(..3 + n)?;
    let mut d = CRC16.digest();
    d.update(&[db << 1 | 1]);
    d.update(frame);
    if read.get(3 + n..5 + n)? != d.finalize().to_le_bytes().as_slice() {
        return None;
    }
    Some((frame[0], frame[1], frame[3..].to_vec()))
}

/// A reply to an operation of rule `rule`: with PEC, an operation whose reply length varies
/// (`scan`, `serial read`, `batch`) is answered with a CRC-16 whatever its length
/// (protocol.md, "Reply lengths"); a status-only reply with a PEC byte (from a board that could
/// not tell the operation) is read too, but never as `ok`.
pub fn parse_reply_for(
    db: u8,
    pec: bool,
    read: &[u8],
    rule: ReplyRule,
) -> Option<(u8, u8, Vec<u8>)> {
    let varies = matches!(
        rule,
        ReplyRule::Scan | ReplyRule::UpTo(_) | ReplyRule::Batch(_)
    );
    if !pec || !varies {
        return parse_reply(db, pec, read);
    }
    parse_reply16(db, read)
        .or_else(|| parse_reply(db, true, read).filter(|r| r.1 != 0 && r.2.is_empty()))
}

/// `frame` with a CRC-16 (low byte first) appended, whatever its length.
pub fn with_crc16(addr_byte: u8, frame: &[u8]) -> Vec<u8> {
    let mut d = CRC16.digest();
    d.update(&[addr_byte]);
    d.update(frame);
    let mut v = frame.to_vec();
    v.extend(d.finalize().to_le_bytes());
    v
}

/// An event frame, exactly the bytes written to the MB.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EventView {
    pub source: u8,
    pub kind: u8,
    pub port: u8,
    pub seq: u8,
    pub status: u8,
    pub payload: Vec<u8>,
    /// It carried a valid check.
    pub checked: bool,
}

/// An event as the protocol reads it: without a check, or with a valid one for MB `mb`.
pub fn parse_event(mb: u8, bytes: &[u8]) -> Option<EventView> {
    let n = usize::from(*bytes.get(5)?);
    if n > MAX_PAYLOAD || !(0x08..=0x77).contains(&bytes[0]) {
        return None;
    }
    let frame = bytes.get(..6 + n)?;
    let rest = &bytes[6 + n..];
    let checked = if rest.is_empty() {
        false
    } else if rest == check_of(mb << 1, frame).as_slice() {
        true
    } else {
        return None;
    };
    Some(EventView {
        source: frame[0],
        kind: frame[1],
        port: frame[2],
        seq: frame[3],
        status: frame[4],
        payload: frame[6..].to_vec(),
        checked,
    })
}

/// What a request's reply may be, per the protocol's operation table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplyRule {
    /// An output: a single write, no reply read.
    Write,
    /// An `ok` reply with exactly this many payload bytes.
    Exact(usize),
    /// `io input`: one byte, 0 or 1.
    Level,
    /// `serial read`: up to this many bytes.
    UpTo(usize),
    /// `scan`: 3 + 2n bytes, n = byte 0, n <= 8.
    Scan,
    /// Pulse-in: `pending` with no payload, then a deferred reply of 4 bytes.
    Deferred,
    /// A batch: one result per item, in order, each `status, n, value`: for `ok` a value
    /// the item's rule allows, else no value (protocol.md, "Batch items and results").
    Batch(&'static [ReplyRule]),
}

impl ReplyRule {
    /// The longest `ok` payload the rule allows (the reply capacity, protocol.md's table).
    pub fn capacity(self) -> usize {
        match self {
            ReplyRule::Write | ReplyRule::Deferred => 0,
            ReplyRule::Exact(n) | ReplyRule::UpTo(n) => n,
            ReplyRule::Level => 1,
            ReplyRule::Scan => 3 + 2 * 8,
            ReplyRule::Batch(items) => items.iter().map(|i| 2 + i.capacity()).sum(),
        }
    }

    /// True when the reply's length varies: with PEC it always ends in a CRC-16.
    pub fn varies(self) -> bool {
        matches!(
            self,
            ReplyRule::Scan | ReplyRule::UpTo(_) | ReplyRule::Batch(_)
        )
    }

    /// True when `payload` is an `ok` payload this rule allows.
    pub fn allows(self, payload: &[u8]) -> bool {
        self.allows_with(payload, true)
    }

    /// As [`ReplyRule::allows`], a level of any value when not `strict_level`.
    pub fn allows_with(self, payload: &[u8], strict_level: bool) -> bool {
        match self {
            ReplyRule::Write => payload.is_empty(),
            ReplyRule::Exact(n) => payload.len() == n,
            ReplyRule::Level => {
                payload == [0] || payload == [1] || (!strict_level && payload.len() == 1)
            }
            ReplyRule::UpTo(n) => payload.len() <= n,
            ReplyRule::Scan => payload
                .first()
                .is_some_and(|&k| k <= 8 && payload.len() == 3 + 2 * usize::from(k)),
            ReplyRule::Deferred => payload.len() == 4,
            ReplyRule::Batch(items) => {
                let mut rest = payload;
                for item in items {
                    let [status, n, ref tail @ ..] = *rest else {
                        return false;
                    };
                    let Some(value) = tail.get(..usize::from(n)) else {
                        return false;
                    };
                    let fits = if status == 0 {
                        item.allows_with(value, strict_level)
                    } else {
                        value.is_empty()
                    };
                    if !fits {
                        return false;
                    }
                    rest = &tail[usize::from(n)..];
                }
                rest.is_empty()
            }
        }
    }
}

/// One operation of the fuzz scripts, encoded by the oracle itself (protocol.md's table).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OpBytes {
    /// Request byte 0.
    pub fn_op: u8,
    /// Request byte 2.
    pub port: u8,
    /// Request bytes 4..
    pub data: Vec<u8>,
    pub rule: ReplyRule,
    /// `Some(on)` for `set_pec`: its reply comes in the new mode.
    pub set_pec: Option<bool>,
    /// The call's timeout in µs (request timeout, plus the pulse timeout for a pulse-in).
    pub timeout_us: u64,
}

/// The board's deadline for a pulse-in request `written` (its timeout, or the default 1 s,
/// + 1 ms), from its acceptance. A 4-byte body (5 with its check) has no timeout data.
pub fn pulse_deadline_us(written: &[u8]) -> u64 {
    let ms = match written.len() {
        6 | 7 => u64::from(u16::from_le_bytes([written[4], written[5]])),
        _ => 1_000,
    };
    (ms + 1) * 1_000
}

/// One transaction the MB made on the fake bus.
#[derive(Clone, Debug)]
pub struct Txn {
    pub start: u64,
    pub end: u64,
    pub addr: u8,
    pub written: Vec<u8>,
    /// `Some(n)`: a write-then-read of n bytes.
    pub read_len: Option<usize>,
    /// The bus's outcome: the bytes read (write-then-read) or empty (write), or an error name.
    pub result: Result<Vec<u8>, &'static str>,
}

/// An event the fake bus wrote to the MB.
#[derive(Clone, Debug)]
pub struct Sent {
    pub at: u64,
    pub bytes: Vec<u8>,
    /// When the MB took it off the bus (listened), if it did.
    pub delivered: Option<u64>,
}

impl Sent {
    /// When the MB received it (when it was sent if never received).
    pub fn received(&self) -> u64 {
        self.delivered.unwrap_or(self.at)
    }
}

/// One finished (or unfinished) call.
#[derive(Clone, Debug)]
pub struct CallRec {
    pub task: usize,
    pub db: u8,
    pub op: OpBytes,
    pub start: u64,
    pub end: Option<u64>,
    /// `Ok(payload)`, or the error's `Debug`, with `Status(code)` kept apart.
    pub result: Option<CallResult>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CallResult {
    Ok(Vec<u8>),
    Status(u8),
    Other(String),
}

/// One pin event a waiting task got.
#[derive(Clone, Debug)]
pub struct WaitRec {
    pub task: usize,
    pub db: u8,
    pub pin: u8,
    pub at: u64,
    pub source: u8,
    pub kind: u8,
    pub got_pin: u8,
    pub value: Vec<u8>,
}

/// A wait for a pin event that ended without one (its window passed).
#[derive(Clone, Debug)]
pub struct WaitSpan {
    pub task: usize,
    pub db: u8,
    pub pin: u8,
    pub start: u64,
    pub end: u64,
}

/// A broken promise, with what the MB did and what the oracle expected.
#[derive(Clone, Debug)]
pub struct Violation {
    /// What kind of violation, as the oracle can tell (see [`Record::classify`]): the long
    /// runs may allow known classes (`X10_FUZZ_ALLOW`) so that they look for others.
    pub class: &'static str,
    pub what: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{}] {}", self.class, self.what)
    }
}

/// Everything a case recorded.
#[derive(Clone, Debug, Default)]
pub struct Record {
    pub mb: u8,
    /// The safe defaults (`MbConfig::new`): every event from an external board must carry
    /// its check (protocol.md, "PEC").
    pub safe: bool,
    pub txns: Vec<Txn>,
    pub sent: Vec<Sent>,
    pub calls: Vec<CallRec>,
    pub waits: Vec<WaitRec>,
    pub timeouts: Vec<WaitSpan>,
}

/// The request `written` carries `op` to `db`: its sequence number and whether it carried a
/// (valid) check. `None` when it is another request or its check is wrong.
fn request_of(db: u8, op: &OpBytes, written: &[u8]) -> Option<(u8, bool)> {
    let body_len = 4 + op.data.len();
    let body = written.get(..body_len)?;
    if body[0] != op.fn_op || body[1] != db || body[2] != op.port || body[4..] != op.data[..] {
        return None;
    }
    let rest = &written[body_len..];
    if rest.is_empty() {
        Some((body[3], false))
    } else if rest == check_of(db << 1, body).as_slice() {
        Some((body[3], true))
    } else {
        None
    }
}

impl Record {
    /// The PEC state of board `db` at time `at` as the MB may know it: on from the end of a
    /// `set_pec(1)` transaction answered validly in the new mode (`ok`, or `pec_mismatch`
    /// with a check), off from a `boot` event of the board with its check (when the MB
    /// received it: events reach it in order, when it listens) or a confirmed `set_pec(0)`.
    fn pec_on_at(&self, db: u8, at: u64, event: usize) -> bool {
        let mut changes: Vec<(u64, bool)> = Vec::new();
        for t in &self.txns {
            if t.addr != db || t.end > at || t.read_len.is_none() {
                continue;
            }
            let Ok(read) = &t.result else { continue };
            let w = &t.written;
            if w.len() < 5 || w[0] != 0x07 || w[1] != db || w[2] != 0 || w[4] > 1 {
                continue;
            }
            let on = w[4] == 1;
            if let Some((seq, status, payload)) = parse_reply(db, on, read) {
                let ok =
                    seq == w[3] && payload.is_empty() && (status == 0 || (on && status == 0x08));
                if ok {
                    changes.push((t.end, on));
                }
            }
        }
        // Events the MB received before event `event` (at the same instant: in the order
        // received, which is the order sent).
        for (j, e) in self.sent.iter().enumerate() {
            let Some(got) = e.delivered else { continue };
            if got > at || (got == at && j >= event) {
                continue;
            }
            if let Some(ev) = parse_event(self.mb, &e.bytes) {
                // A boot event always carries its check (protocol.md, "PEC").
                if ev.source == db && ev.kind == 0x07 && ev.checked {
                    changes.push((got, false));
                }
            }
        }
        changes.sort_by_key(|c| c.0);
        changes.last().is_some_and(|c| c.1)
    }

    /// The event sent at index `i`, if it is valid: well formed, and checked with the safe
    /// defaults or when its board had PEC on when the MB received it.
    fn valid_event(&self, i: usize) -> Option<EventView> {
        let e = &self.sent[i];
        let ev = parse_event(self.mb, &e.bytes)?;
        if !ev.checked && (self.safe || self.pec_on_at(ev.source, e.received(), i)) {
            return None;
        }
        Some(ev)
    }

    /// The first violation, if any.
    pub fn check(&self) -> Result<(), Violation> {
        for c in &self.calls {
            self.check_call(c)?;
        }
        self.check_waits()
    }

    fn check_call(&self, c: &CallRec) -> Result<(), Violation> {
        let (Some(end), Some(result)) = (c.end, &c.result) else {
            return Err(Violation {
                class: "never-ended",
                what: format!(
                    "call never ended: task {} {:02x?} to {:#04x} started at {} us",
                    c.task, c.op, c.db, c.start
                ),
            });
        };
        if end > c.start + c.op.timeout_us {
            return Err(Violation {
                class: "late",
                what: format!(
                    "call ended after its timeout: task {} {:02x?} to {:#04x}: {} .. {} us \
                     ({} us allowed), result {:?}",
                    c.task, c.op, c.db, c.start, end, c.op.timeout_us, result
                ),
            });
        }
        // Every read of the request takes the longest reply it may have, with its check.
        for t in &self.txns {
            if t.addr != c.db || t.start < c.start || t.end > end {
                continue;
            }
            let (Some((_, checked)), Some(n)) = (request_of(c.db, &c.op, &t.written), t.read_len)
            else {
                continue;
            };
            let frame = 3 + c.op.rule.capacity();
            let check = match c.op.set_pec.unwrap_or(checked) {
                false => 0,
                true if c.op.rule.varies() || frame > 13 => 2,
                true => 1,
            };
            if n < frame + check {
                return Err(Violation {
                    class: "read-too-short",
                    what: format!(
                        "the MB read {n} bytes for {:02x?} (wrote {:02x?}); its longest valid \
                         reply is {} bytes: {frame} and a {}-byte check",
                        c.op,
                        t.written,
                        frame + check,
                        check
                    ),
                });
            }
        }
        let justified = match result {
            CallResult::Ok(payload) => self.justify(c, end, Some(payload), None),
            CallResult::Status(s) => self.justify(c, end, None, Some(*s)),
            CallResult::Other(e) if e == "BadReply" => return self.check_bad_reply(c, end),
            CallResult::Other(_) => return Ok(()),
        };
        if justified {
            return Ok(());
        }
        Err(Violation {
            class: self.classify(c, end, result),
            what: format!(
                "{:?} with no valid answer: task {} op {:02x?} to board {:#04x}, call {} .. {} us; \
                 expected: a transaction inside the call whose reply echoes the request's \
                 sequence number with {}, an allowed payload length and a right check",
                result,
                c.task,
                c.op,
                c.db,
                c.start,
                end,
                match result {
                    CallResult::Status(s) => format!("status {s:#04x} and no payload"),
                    _ => "status ok".to_string(),
                }
            ),
        })
    }

    /// True when some transaction (and for a pulse-in, some event) validly gave the call's
    /// result: `payload` for an `Ok`, or `status`.
    fn justify(
        &self,
        c: &CallRec,
        end: u64,
        payload: Option<&Vec<u8>>,
        status: Option<u8>,
    ) -> bool {
        let op = &c.op;
        if let Some(s) = status {
            if self.preparation_refused(c, end, s) {
                return true;
            }
            if s == 0x05 && self.port_known_missing(c, end) {
                return true;
            }
        }
        for t in &self.txns {
            if t.addr != c.db || t.start < c.start || t.end > end {
                continue;
            }
            let Some((seq, checked)) = request_of(c.db, op, &t.written) else {
                continue;
            };
            let Ok(read) = &t.result else { continue };
            if t.read_len.is_none() {
                // An output written alone: acknowledged, `Ok` and empty. (Read back, it is
                // judged as a reply below: `ok` with no payload.)
                if op.rule == ReplyRule::Write && payload.is_some_and(|p| p.is_empty()) {
                    return true;
                }
                continue;
            }
            let mode = op.set_pec.unwrap_or(checked);
            let Some((rseq, rstatus, rpayload)) = parse_reply_for(c.db, mode, read, op.rule) else {
                continue;
            };
            if rseq != seq {
                continue;
            }
            if op.rule == ReplyRule::Deferred {
                if rstatus == 0x01 && rpayload.is_empty() {
                    if self.deferred_answers(c, t, seq, checked, end, payload, status) {
                        return true;
                    }
                    continue;
                }
                // Refused at once: an error status with no payload.
                if let Some(s) = status {
                    if rstatus == s && s != 0 && s != 0x01 && rpayload.is_empty() {
                        return true;
                    }
                }
                continue;
            }
            match (payload, status) {
                (Some(p), _) => {
                    if rstatus == 0 && op.rule.allows(&rpayload) && rpayload == *p {
                        return true;
                    }
                }
                (None, Some(s)) => {
                    if rstatus == s && rpayload.is_empty() {
                        return true;
                    }
                }
                (None, None) => {}
            }
        }
        false
    }

    /// A `BadReply` while the last transaction of the call read a valid `ok` answer to it
    /// (its number, a payload length the operation allows, the right check): the MB refused
    /// a valid reply. Not judged for a scan (the MB also compares its port count with the
    /// board's, which the oracle does not follow) nor a pulse-in (its outcome is the event's).
    fn check_bad_reply(&self, c: &CallRec, end: u64) -> Result<(), Violation> {
        let op = &c.op;
        if matches!(op.rule, ReplyRule::Scan | ReplyRule::Deferred) {
            return Ok(());
        }
        let last = self
            .txns
            .iter()
            .filter(|t| t.addr == c.db && t.start >= c.start && t.end <= end)
            .rfind(|t| request_of(c.db, op, &t.written).is_some());
        let Some(t) = last else { return Ok(()) };
        let (Some((seq, checked)), Ok(read)) = (request_of(c.db, op, &t.written), &t.result) else {
            return Ok(());
        };
        if t.read_len.is_none() || t.end != end {
            return Ok(());
        }
        let mode = op.set_pec.unwrap_or(checked);
        match parse_reply_for(c.db, mode, read, op.rule) {
            Some((rseq, 0, payload)) if rseq == seq && op.rule.allows(&payload) => Err(Violation {
                class: "valid-reply-refused",
                what: format!(
                    "BadReply for a valid answer: task {} op {:02x?} to board {:#04x}, call {} .. {} us; \
                     the MB wrote {:02x?} and read {:02x?} ({} bytes), a valid ok reply with \
                     payload {:02x?}",
                    c.task,
                    op,
                    c.db,
                    c.start,
                    end,
                    t.written,
                    read,
                    read.len(),
                    payload
                ),
            }),
            _ => Ok(()),
        }
    }

    /// What an unjustified result was, as far as the oracle can tell: the known defects of
    /// issue 22 by name, else `unjustified`.
    pub fn classify(&self, c: &CallRec, end: u64, result: &CallResult) -> &'static str {
        let op = &c.op;
        for t in &self.txns {
            if t.addr != c.db || t.start < c.start || t.end > end || t.read_len.is_none() {
                continue;
            }
            let Some((seq, checked)) = request_of(c.db, op, &t.written) else {
                continue;
            };
            let Ok(read) = &t.result else { continue };
            let mode = op.set_pec.unwrap_or(checked);
            let Some((rseq, rstatus, rpayload)) = parse_reply_for(c.db, mode, read, op.rule) else {
                continue;
            };
            if rseq != seq {
                continue;
            }
            match (op.rule, result) {
                (ReplyRule::Deferred, CallResult::Ok(p)) if rstatus == 0 && rpayload == *p => {
                    return "item8-pulse-in-ok-reply";
                }
                (ReplyRule::Deferred, _) if rstatus == 0x01 => {
                    for (i, e) in self.sent.iter().enumerate() {
                        if e.delivered.is_none() || e.received() < t.end || e.received() > end {
                            continue;
                        }
                        let Some(ev) = parse_event(self.mb, &e.bytes) else {
                            continue;
                        };
                        if ev.kind != 0x03
                            || ev.source != c.db
                            || ev.seq != seq
                            || ev.port != op.port
                        {
                            continue;
                        }
                        let fits = match result {
                            CallResult::Ok(p) => ev.status == 0 && ev.payload == *p,
                            CallResult::Status(s) => ev.status == *s,
                            CallResult::Other(_) => false,
                        };
                        if fits && !ev.checked && (checked || self.valid_event(i).is_none()) {
                            let boot_between = self.sent.iter().enumerate().any(|(j, b)| {
                                b.delivered
                                    .is_some_and(|got| got >= t.start && got <= e.received())
                                    && j != i
                                    && parse_event(self.mb, &b.bytes).is_some_and(|b| {
                                        b.source == c.db && b.kind == 0x07 && b.checked
                                    })
                            });
                            return if boot_between {
                                "deferred-unchecked-after-boot"
                            } else {
                                "deferred-unchecked"
                            };
                        }
                        match result {
                            CallResult::Ok(p) if ev.status == 0 && ev.payload == *p => {
                                return if p.len() == 4 {
                                    "item8-stale-deferred-reply"
                                } else {
                                    "item8-deferred-length"
                                };
                            }
                            CallResult::Status(s) if ev.status == *s && !ev.payload.is_empty() => {
                                return "item8-deferred-status-with-payload";
                            }
                            _ => {}
                        }
                    }
                }
                (ReplyRule::Scan, CallResult::Ok(p)) if rstatus == 0 && rpayload == *p => {
                    return "item14-scan-length";
                }
                (ReplyRule::Level, CallResult::Ok(p)) if rstatus == 0 && rpayload == *p => {
                    return "level-out-of-domain";
                }
                (ReplyRule::Batch(_), CallResult::Ok(p)) if rstatus == 0 && rpayload == *p => {
                    return if op.rule.allows_with(p, false) {
                        "level-out-of-domain"
                    } else {
                        "batch-results"
                    };
                }
                (_, CallResult::Ok(p)) if rstatus == 0 && rpayload == *p => {
                    return "reply-length";
                }
                (_, CallResult::Status(s)) if rstatus == *s && !rpayload.is_empty() => {
                    return "status-with-payload";
                }
                _ => {}
            }
        }
        "unjustified"
    }

    /// The MB knows each board's ports from its `identify` replies and checked `boot` events
    /// (docs/protocol.md, issue 22 item 11) and refuses an operation on a port the board lacks
    /// with `port_out_of_range` without sending it: true when the latest identity the board
    /// gave by `end` has fewer ports of the operation's kind than its port needs.
    fn port_known_missing(&self, c: &CallRec, end: u64) -> bool {
        // The ports the request names: its own (io, PWM, analog, serial), or its batch items'.
        let on_port = |fn_op: u8| (1..=4).contains(&(fn_op >> 4));
        let mut ports = Vec::new();
        if c.op.fn_op == 0x50 {
            let mut items = c.op.data.as_slice();
            while let [fn_op, port, n, ref rest @ ..] = *items {
                if on_port(fn_op) {
                    ports.push(port);
                }
                items = rest.get(usize::from(n)..).unwrap_or(&[]);
            }
        } else if on_port(c.op.fn_op) {
            ports.push(c.op.port);
        }
        if ports.is_empty() {
            return false;
        }
        let mut latest: Option<(u64, Vec<u8>)> = None;
        for t in &self.txns {
            let w = &t.written;
            if t.addr != c.db || t.end > end || w.len() < 4 || w[0] != 0x01 || w[1] != c.db {
                continue;
            }
            let Ok(read) = &t.result else { continue };
            let pec = w.len() > 4;
            if let Some((seq, 0, payload)) = parse_reply(c.db, pec, read) {
                if seq == w[3]
                    && payload.len() == 10
                    && latest.as_ref().is_none_or(|l| l.0 <= t.end)
                {
                    latest = Some((t.end, payload));
                }
            }
        }
        for (i, e) in self.sent.iter().enumerate() {
            let Some(got) = e.delivered.filter(|&g| g <= end) else {
                continue;
            };
            if let Some(ev) = self.valid_event(i) {
                if ev.source == c.db
                    && ev.kind == 0x07
                    && ev.checked
                    && ev.payload.len() >= 10
                    && latest.as_ref().is_none_or(|l| l.0 <= got)
                {
                    latest = Some((got, ev.payload[..10].to_vec()));
                }
            }
        }
        let Some((_, id)) = latest else { return false };
        let (sensors, actuators) = (id[5], id[6]);
        ports.iter().any(|&port| {
            let index = (port >> 1) & 0x3f;
            if port & 0x80 != 0 {
                index >= sensors
            } else {
                index >= actuators
            }
        })
    }

    /// With the safe defaults the MB prepares a board (`set_pec(1)`, `set_failsafe`) before
    /// a request reaches it, and a board that refuses that ends the request in the board's
    /// status (`MbConfig::pec`: "its requests end in `LinkError::Status(unsupported)`"): true
    /// when such a set-up request inside the call got a valid reply (in either mode) with
    /// status `s` and no payload.
    fn preparation_refused(&self, c: &CallRec, end: u64, s: u8) -> bool {
        self.txns.iter().any(|t| {
            let w = &t.written;
            if t.addr != c.db || t.start < c.start || t.end > end || t.read_len.is_none() {
                return false;
            }
            if w.len() < 5 || (w[0] != 0x07 && w[0] != 0x03) || w[1] != c.db || w[2] != 0 {
                return false;
            }
            let body_len = if w[0] == 0x07 { 5 } else { 6 };
            let Some(body) = w.get(..body_len) else {
                return false;
            };
            let rest = &w[body_len..];
            if !rest.is_empty() && rest != check_of(c.db << 1, body).as_slice() {
                return false;
            }
            let Ok(read) = &t.result else { return false };
            [false, true].iter().any(|&mode| {
                parse_reply(c.db, mode, read).is_some_and(|(seq, status, payload)| {
                    seq == w[3] && status == s && s != 0 && payload.is_empty()
                })
            })
        })
    }

    /// A deferred reply sent after transaction `t` (the `pending`) and by `end` completes the
    /// pulse-in of sequence number `seq` with `payload` (or `status`).
    #[allow(clippy::too_many_arguments)]
    fn deferred_answers(
        &self,
        c: &CallRec,
        t: &Txn,
        seq: u8,
        checked: bool,
        end: u64,
        payload: Option<&Vec<u8>>,
        status: Option<u8>,
    ) -> bool {
        for (i, e) in self.sent.iter().enumerate() {
            if e.delivered.is_none() || e.received() < t.end || e.received() > end {
                continue;
            }
            let Some(ev) = self.valid_event(i) else {
                continue;
            };
            if ev.kind != 0x03 || ev.source != c.db || ev.seq != seq || ev.port != c.op.port {
                continue;
            }
            // Sent with PEC: its deferred reply must be checked too.
            if checked && !ev.checked {
                continue;
            }
            let fits = match (payload, status) {
                (Some(p), _) => ev.status == 0 && ev.payload.len() == 4 && ev.payload == *p,
                (None, Some(s)) => ev.status == s && ev.payload.is_empty(),
                _ => false,
            };
            if !fits {
                continue;
            }
            // Not possibly the answer of an earlier pulse-in of the same board, number and
            // pin (sent before this call started: another request; a retry of this one is
            // the same request) that the board may have accepted and may still answer.
            let ambiguous = self.txns.iter().any(|u| {
                u.start < c.start
                    && u.addr == c.db
                    && u.result != Err("nack")
                    && u.written.len() >= 4
                    && (u.written[0] == 0x13 || u.written[0] == 0x14)
                    && u.written[2] == c.op.port
                    && u.written[3] == seq
                    && u.start + pulse_deadline_us(&u.written) >= e.at
                    && !self.ended_before(c.db, seq, c.op.port, u, t.start)
            });
            if !ambiguous {
                return true;
            }
        }
        false
    }

    /// True when the board can no longer answer the pulse-in `u` (number `seq`, pin `port`)
    /// after time `by`: a deferred reply for it came (a board sends one per request), or a
    /// checked `boot` of the board (it lost its measurements), received after `u` and
    /// before `by`.
    fn ended_before(&self, db: u8, seq: u8, port: u8, u: &Txn, by: u64) -> bool {
        self.sent.iter().enumerate().any(|(i, e)| {
            e.delivered.is_some_and(|got| got >= u.end && got <= by)
                && self.valid_event(i).is_some_and(|ev| {
                    ev.source == db
                        && ((ev.kind == 0x03 && ev.seq == seq && ev.port == port)
                            || (ev.kind == 0x07 && ev.checked))
                })
        })
    }

    fn check_waits(&self) -> Result<(), Violation> {
        // A task that waited for a pin and got nothing: no valid pin event of that board and
        // pin reached the MB while it waited.
        for w in &self.timeouts {
            let lost = (0..self.sent.len()).find(|&i| {
                self.sent[i]
                    .delivered
                    .is_some_and(|got| got > w.start && got < w.end)
                    && self.valid_event(i).is_some_and(|ev| {
                        (ev.kind == 0x01 || ev.kind == 0x02)
                            && ev.source == w.db
                            && ev.port == w.pin
                    })
            });
            if let Some(i) = lost {
                return Err(Violation {
                    class: "event-lost-while-waiting",
                    what: format!(
                        "waiter task {} waited for board {:#04x} pin {:#04x} from {} to {} us and \
                         got nothing, though the MB received the valid event {:02x?} at {} us",
                        w.task,
                        w.db,
                        w.pin,
                        w.start,
                        w.end,
                        self.sent[i].bytes,
                        self.sent[i].received()
                    ),
                });
            }
        }
        let mut keys: Vec<(usize, u8, u8)> =
            self.waits.iter().map(|w| (w.task, w.db, w.pin)).collect();
        keys.sort_unstable();
        keys.dedup();
        for (task, db, pin) in keys {
            // The events one task got for one pin: a subsequence of those sent, in order.
            let mut next = 0usize;
            for w in self
                .waits
                .iter()
                .filter(|w| (w.task, w.db, w.pin) == (task, db, pin))
            {
                let matches = |ev: &EventView| {
                    (ev.kind == 0x01 || ev.kind == 0x02)
                        && ev.source == w.db
                        && ev.source == w.source
                        && ev.port == w.pin
                        && ev.port == w.got_pin
                        && ev.kind == w.kind
                        && ev.payload == w.value
                };
                let found = (next..self.sent.len()).find(|&i| {
                    self.sent[i].delivered.is_some_and(|got| got <= w.at)
                        && self.valid_event(i).is_some_and(|ev| matches(&ev))
                });
                match found {
                    Some(i) => next = i + 1,
                    None => {
                        // Sent, but without the check its board had on: accepted unchecked.
                        let unchecked = (next..self.sent.len()).any(|i| {
                            self.sent[i].delivered.is_some_and(|got| got <= w.at)
                                && parse_event(self.mb, &self.sent[i].bytes)
                                    .is_some_and(|ev| matches(&ev))
                        });
                        // Sent and valid, but before the previous one this task got.
                        let reordered = (0..next).any(|i| {
                            self.sent[i].delivered.is_some_and(|got| got <= w.at)
                                && self.valid_event(i).is_some_and(|ev| matches(&ev))
                        });
                        return Err(Violation {
                            class: if unchecked {
                                "event-unchecked-while-pec-on"
                            } else if reordered {
                                "event-out-of-order"
                            } else {
                                "event-not-sent"
                            },
                            what: format!(
                                "waiter task {} (board {:#04x}, pin {:#04x}) got an event that \
                                 was not validly sent (or not after its previous one): at {} us, \
                                 source {:#04x} kind {:#04x} pin {:#04x} value {:02x?}{}",
                                task,
                                w.db,
                                w.pin,
                                w.at,
                                w.source,
                                w.kind,
                                w.got_pin,
                                w.value,
                                if unchecked {
                                    "; it was sent without a check while the board had PEC on \
                                     (confirmed by a valid set_pec(1) reply, no boot since)"
                                } else {
                                    ""
                                }
                            ),
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// A readable account of the case (for findings).
    pub fn dump(&self) -> String {
        let mut s = String::new();
        for t in &self.txns {
            s += &format!(
                "{:>9}..{:<9} txn {:#04x} wrote {:02x?}{} -> {}\n",
                t.start,
                t.end,
                t.addr,
                t.written,
                t.read_len.map(|n| format!(" read {n}")).unwrap_or_default(),
                match &t.result {
                    Ok(b) if t.read_len.is_some() => format!("{b:02x?}"),
                    Ok(_) => "ack".to_string(),
                    Err(e) => e.to_string(),
                }
            );
        }
        for e in &self.sent {
            s += &format!("{:>9} event to MB {:02x?}\n", e.at, e.bytes);
        }
        for c in &self.calls {
            s += &format!(
                "task {} call {:#04x} {:02x?}: {} .. {:?} -> {:?}\n",
                c.task, c.db, c.op, c.start, c.end, c.result
            );
        }
        for w in &self.timeouts {
            s += &format!(
                "task {} wait {:#04x}/{:#04x} {} .. {}: nothing\n",
                w.task, w.db, w.pin, w.start, w.end
            );
        }
        for w in &self.waits {
            s += &format!(
                "task {} wait {:#04x}/{:#04x} at {}: source {:#04x} kind {} pin {:#04x} {:02x?}\n",
                w.task, w.db, w.pin, w.at, w.source, w.kind, w.got_pin, w.value
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // protocol.md's example frames, checked with the oracle's own CRCs.
    #[test]
    fn doc_examples() {
        assert_eq!(check_of(0x12, &[0x12, 0x09, 0x01, 0x02]), vec![0x9c]);
        assert_eq!(check_of(0x13, &[0x09, 0x00, 0x01, 0x01]), vec![0x20]);
        assert_eq!(
            check_of(
                0x12,
                &[
                    0x50, 0x09, 0x00, 0x12, 0x12, 0x01, 0x00, 0x20, 0x00, 0x01, 0xc8, 0x30, 0x80,
                    0x00
                ]
            ),
            vec![0xad, 0x96]
        );
        assert_eq!(
            parse_reply(9, true, &[0x09, 0x00, 0x01, 0x01, 0x20, 0xff]),
            Some((9, 0, vec![1]))
        );
        assert_eq!(parse_reply(9, true, &[0x09, 0x00, 0x01, 0x01, 0x21]), None);
        let ev = parse_event(
            0x10,
            &[
                0x09, 0x03, 0x85, 0x0b, 0x00, 0x04, 0xf0, 0x05, 0x00, 0x00, 0x63,
            ],
        )
        .unwrap();
        assert!(ev.checked);
        assert_eq!(ev.payload, vec![0xf0, 0x05, 0, 0]);
        assert_eq!(
            parse_event(0x10, &[0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01, 0x96]),
            None
        );
        assert_eq!(
            parse_event(0x10, &[0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01]).map(|e| e.checked),
            Some(false)
        );
    }

    #[test]
    fn scan_rule() {
        assert!(ReplyRule::Scan.allows(&[2, 0, 0, 1, 0, 2, 0]));
        // issue 22 item 14: 9 bytes that claim 5 ports.
        assert!(!ReplyRule::Scan.allows(&[5, 0, 0, 1, 0, 2, 0, 3, 0]));
        assert!(!ReplyRule::Level.allows(&[2]));
        let batch = ReplyRule::Batch(&[ReplyRule::Level, ReplyRule::Exact(2), ReplyRule::Write]);
        assert!(batch.allows(&[0, 1, 1, 0, 2, 5, 1, 0, 0]));
        assert!(batch.allows(&[0, 1, 1, 0x05, 0, 0, 0]));
        assert!(!batch.allows(&[0, 1, 1, 0, 2, 5, 1]));
        assert!(!batch.allows(&[0, 1, 1, 0, 2, 5, 1, 0, 0, 0]));
        assert!(!batch.allows(&[0, 1, 2, 0, 2, 5, 1, 0, 0]));
        assert!(!batch.allows(&[0, 1, 1, 0x05, 1, 0, 0, 0]));
    }
}
