//! The motherboard's own postcard: [`ToHost`] written and [`ToDevice`] read by hand, byte
//! for byte as postcard 1.x (serde) does (docs/usb-link.md, "Framing"), without serde's
//! generic code in the images (issue 26's flash budget). The laptop keeps serde
//! ([`crate::encode`], [`crate::decode`]); `tests/wire.rs` checks that both agree on every
//! example frame and on random messages and bytes.

use crate::msg::{
    AssignStatus, CallError, CallRec, DiagCounters, EventRec, Hello, Outcome, OutputValue,
    ToDevice, ToHost, UpdatePhase, UpdateStatus, WireOp,
};

/// Writes postcard bytes into a buffer; remembers when it ran out of room.
struct Out<'a> {
    buf: &'a mut [u8],
    n: usize,
    full: bool,
}

impl Out<'_> {
    /// Not inlined: called at some forty sites of the motherboard's encoder (issue 26's
    /// flash budget).
    #[inline(never)]
    fn byte(&mut self, b: u8) {
        match self.buf.get_mut(self.n) {
            Some(slot) => {
                *slot = b;
                self.n += 1;
            }
            None => self.full = true,
        }
    }

    /// An unsigned integer as a varint: 7 bits a byte, least significant first.
    fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            // Truncation intended: the low 7 bits and the continuation bit.
            self.byte((v as u8) | 0x80);
            v >>= 7;
        }
        self.byte(v as u8);
    }

    /// A byte slice or string: its length, then its bytes.
    fn bytes(&mut self, b: &[u8]) {
        self.varint(b.len() as u64);
        for &x in b {
            self.byte(x);
        }
    }

    fn hello(&mut self, h: &Hello<'_>) {
        self.varint(u64::from(h.version));
        self.byte(h.address);
        self.bytes(h.board.as_bytes());
        self.bytes(h.robot.as_bytes());
    }

    fn op(&mut self, op: &WireOp<'_>) {
        self.byte(op.fn_op);
        self.byte(op.port);
        self.bytes(op.data);
    }

    fn outcome(&mut self, o: &Outcome<'_>) {
        match o {
            Outcome::Ok(p) => {
                self.byte(0);
                self.bytes(p);
            }
            Outcome::Err(e) => {
                self.byte(1);
                self.error(e);
            }
        }
    }

    fn error(&mut self, e: &CallError) {
        let (index, status) = match e {
            CallError::Nack => (0, None),
            CallError::Timeout => (1, None),
            CallError::ArbitrationLost => (2, None),
            CallError::Bus => (3, None),
            CallError::BadReply => (4, None),
            CallError::Status(s) => (5, Some(*s)),
            CallError::Invalid => (6, None),
            CallError::Busy => (7, None),
            CallError::Unsupported => (8, None),
            CallError::BadAddress => (9, None),
            CallError::Updating => (10, None),
        };
        self.tagged(index, status);
    }

    fn call(&mut self, c: &CallRec<'_>) {
        self.byte(c.db);
        self.op(&c.op);
        self.outcome(&c.outcome);
        self.varint(c.start_us);
        self.varint(c.end_us);
    }

    fn event(&mut self, e: &EventRec<'_>) {
        for b in [e.db, e.kind, e.port, e.seq, e.status] {
            self.byte(b);
        }
        self.bytes(e.payload);
        self.varint(e.at_us);
    }

    /// A unit variant's index, or a one-field variant's index and that field.
    fn tagged(&mut self, index: u8, field: Option<u8>) {
        self.byte(index);
        if let Some(f) = field {
            self.byte(f);
        }
    }

    fn counters(&mut self, c: &DiagCounters) {
        self.varint(c.len() as u64);
        for &v in c {
            self.varint(u64::from(v));
        }
    }
}

/// Writes `msg`'s postcard bytes into `out`; returns their length, or `None` when `out` is
/// too short.
pub fn write_to_host(msg: &ToHost<'_>, out: &mut [u8]) -> Option<usize> {
    let mut o = Out {
        buf: out,
        n: 0,
        full: false,
    };
    match msg {
        ToHost::Hello(h) => {
            o.byte(0);
            o.hello(h);
        }
        ToHost::Log(b) => {
            o.byte(1);
            o.bytes(b);
        }
        ToHost::Call(c) => {
            o.byte(2);
            o.call(c);
        }
        ToHost::Event(e) => {
            o.byte(3);
            o.event(e);
        }
        ToHost::Output(r) => {
            o.byte(4);
            o.byte(r.db);
            o.byte(r.port);
            match r.value {
                OutputValue::Level(h) => {
                    o.byte(0);
                    o.byte(u8::from(h));
                }
                OutputValue::Duty(d) => {
                    o.byte(1);
                    o.byte(d);
                }
                OutputValue::FrequencyHz(hz) => {
                    o.byte(2);
                    o.varint(u64::from(hz));
                }
                OutputValue::PulseWidthUs(us) => {
                    o.byte(3);
                    o.varint(u64::from(us));
                }
            }
            o.varint(r.at_us);
        }
        ToHost::Dropped(d) => {
            o.byte(5);
            for v in [d.calls, d.events, d.outputs, d.log_bytes, d.bad_frames] {
                o.varint(u64::from(v));
            }
        }
        ToHost::Reply { id, outcome } => {
            o.byte(6);
            o.varint(u64::from(*id));
            o.outcome(outcome);
        }
        ToHost::Diagnostics { id, counters } => {
            o.byte(7);
            o.varint(u64::from(*id));
            o.counters(counters);
        }
        ToHost::Boards { id, addresses } => {
            o.byte(8);
            o.varint(u64::from(*id));
            o.bytes(addresses);
        }
        ToHost::Refused { id } => {
            o.byte(9);
            o.varint(u64::from(*id));
        }
        ToHost::BoardList {
            id,
            total,
            first,
            boards,
        } => {
            o.byte(10);
            o.varint(u64::from(*id));
            o.byte(*total);
            o.byte(*first);
            o.varint(boards.len() as u64);
            for b in boards {
                o.byte(b.address);
                b.uid.iter().for_each(|&x| o.byte(x));
                o.byte(b.kind);
                b.firmware.iter().for_each(|&x| o.byte(x));
                o.byte(b.state as u8);
            }
        }
        ToHost::Assigned { id, status } => {
            o.byte(11);
            o.varint(u64::from(*id));
            match status {
                AssignStatus::NotConfirmed(e) => {
                    o.byte(5);
                    o.error(e);
                }
                AssignStatus::Done => o.byte(0),
                AssignStatus::UnknownUid => o.byte(1),
                AssignStatus::Reserved => o.byte(2),
                AssignStatus::Taken => o.byte(3),
                AssignStatus::Collided => o.byte(4),
            }
        }
        ToHost::UpdateAnswer { id, status } => {
            o.byte(12);
            o.varint(u64::from(*id));
            let (index, field) = match *status {
                UpdateStatus::Started(n) => (0, Some(n)),
                UpdateStatus::NoImages => (1, None),
                UpdateStatus::UnknownUid => (2, None),
                UpdateStatus::NotPresent => (3, None),
                UpdateStatus::NoImage => (4, None),
                UpdateStatus::UpToDate => (5, None),
                UpdateStatus::Busy(a) => (6, Some(a)),
            };
            o.tagged(index, field);
        }
        ToHost::Update(r) => {
            o.byte(13);
            o.byte(r.db);
            r.from.iter().chain(r.to.iter()).for_each(|&x| o.byte(x));
            match &r.phase {
                UpdatePhase::Started => o.byte(0),
                UpdatePhase::Done => o.byte(1),
                UpdatePhase::Failed(f) => o.tagged(2, Some(*f as u8)),
            }
            o.varint(r.at_us);
        }
    }
    if o.full {
        None
    } else {
        Some(o.n)
    }
}

/// Reads postcard bytes.
struct In<'a> {
    rest: &'a [u8],
}

impl<'a> In<'a> {
    fn byte(&mut self) -> Option<u8> {
        let (&b, rest) = self.rest.split_first()?;
        self.rest = rest;
        Some(b)
    }

    /// A varint of at most `max` bytes whose value is at most `limit` (postcard refuses a
    /// longer one, and a last byte that would overflow the type).
    fn varint(&mut self, max: u32, limit: u64) -> Option<u64> {
        let mut v: u64 = 0;
        for i in 0..max {
            let b = self.byte()?;
            // The last byte may hold only the bits the type has left.
            if i + 1 == max && u64::from(b) > limit >> (7 * i) {
                return None;
            }
            v |= u64::from(b & 0x7f) << (7 * i);
            if b & 0x80 == 0 {
                return (v <= limit).then_some(v);
            }
        }
        None
    }

    fn u16(&mut self) -> Option<u16> {
        self.varint(3, u64::from(u16::MAX))
            .and_then(|v| u16::try_from(v).ok())
    }

    /// A length (`usize`, 32 bits on the boards: 5 bytes at most).
    fn len(&mut self) -> Option<usize> {
        let max = if usize::BITS == 64 { 10 } else { 5 };
        self.varint(max, usize::MAX as u64)
            .and_then(|v| usize::try_from(v).ok())
    }

    fn bytes(&mut self) -> Option<&'a [u8]> {
        let n = self.len()?;
        if n > self.rest.len() {
            return None;
        }
        let (b, rest) = self.rest.split_at(n);
        self.rest = rest;
        Some(b)
    }

    /// A unique ID: 8 bytes as they are (postcard's array).
    fn uid(&mut self) -> Option<[u8; 8]> {
        let (head, rest) = self.rest.split_first_chunk::<8>()?;
        self.rest = rest;
        Some(*head)
    }

    /// A string the motherboard does not read (the laptop's hello names itself): skipped as
    /// the bytes it is, its UTF-8 not checked (core's validation is 0.4 KiB of flash).
    fn skip_str(&mut self) -> Option<&'static str> {
        self.bytes().map(|_| "")
    }
}

/// Reads a [`ToDevice`] from its postcard bytes, as postcard would: `None` for an unknown
/// variant, a truncated or overlong field or bytes left over. One difference: the names in a
/// [`ToDevice::Hello`] are skipped, not read (they come back empty, and bytes that are not
/// UTF-8 there are not refused): the motherboard does not use them.
pub fn read_to_device(bytes: &[u8]) -> Option<ToDevice<'_>> {
    let mut i = In { rest: bytes };
    let msg = match i.varint(5, u64::from(u32::MAX))? {
        0 => ToDevice::Hello(Hello {
            version: i.u16()?,
            address: i.byte()?,
            board: i.skip_str()?,
            robot: i.skip_str()?,
        }),
        1 => ToDevice::Bye,
        2 => ToDevice::Call {
            id: i.u16()?,
            db: i.byte()?,
            op: WireOp {
                fn_op: i.byte()?,
                port: i.byte()?,
                data: i.bytes()?,
            },
        },
        3 => ToDevice::Diagnostics { id: i.u16()? },
        4 => ToDevice::ListBoards { id: i.u16()? },
        5 => ToDevice::Boards {
            id: i.u16()?,
            first: i.byte()?,
        },
        6 => ToDevice::Assign {
            id: i.u16()?,
            uid: i.uid()?,
            address: i.byte()?,
        },
        7 => ToDevice::Update {
            id: i.u16()?,
            uid: match i.byte()? {
                0 => None,
                1 => Some(i.uid()?),
                _ => return None,
            },
        },
        _ => return None,
    };
    i.rest.is_empty().then_some(msg)
}
