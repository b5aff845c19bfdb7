//! The fake bus: the MB's `MultiMaster` port, whose transactions are answered from the fuzz
//! input. By default (and once the input is used up) it behaves as honest boards would
//! (valid replies in the request's mode, `pending` then a deferred reply for a pulse-in); each
//! transaction's byte may instead NACK it, lose arbitration, time out, fail, delay it, mutate
//! the honest reply or replace it with raw bytes, and queue events to the MB.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::task::{Poll, Waker};

use x10_hal::bus::{BusError, Incoming, MultiMaster};

use crate::oracle::{check_of, with_check, with_crc16, Sent, Txn};
use crate::vtime::{now_us, sleep_until, wake_at};

/// Reads the input from the front; zeros once used up.
#[derive(Clone, Debug, Default)]
pub struct Reader {
    bytes: Vec<u8>,
    pos: usize,
}

impl Reader {
    pub fn new(bytes: &[u8]) -> Reader {
        Reader {
            bytes: bytes.to_vec(),
            pos: 0,
        }
    }

    /// The next byte, 0 once used up.
    pub fn byte(&mut self) -> u8 {
        let b = self.bytes.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    pub fn is_empty(&self) -> bool {
        self.pos >= self.bytes.len()
    }
}

/// The honest state of one fake board.
#[derive(Clone, Debug, Default)]
struct Board {
    pec: bool,
    /// The board's own event counter.
    ev_seq: u8,
    /// Pulse-ins answered `pending`: (seq, pin byte, width, board deadline).
    pending: VecDeque<(u8, u8, u32)>,
    last_seq: u8,
    last_port: u8,
    level: u8,
}

impl Board {
    fn next_seq(&mut self) -> u8 {
        let s = self.ev_seq;
        self.ev_seq = self.ev_seq.wrapping_add(1);
        s
    }
}

/// Everything the fake bus shares with the scheduled-event task and the oracle.
pub struct World {
    pub mb: u8,
    pub boards: Vec<u8>,
    input: Reader,
    state: Vec<Board>,
    pub txns: Vec<Txn>,
    pub sent: Vec<Sent>,
    /// Events written to the MB and not yet received: (index in `sent`, bytes).
    to_mb: VecDeque<(usize, Vec<u8>)>,
    listener: Option<Waker>,
    /// Events to write at a time: (at, bytes).
    schedule: Vec<(u64, Vec<u8>)>,
    injector: Option<Waker>,
}

pub type Shared = Rc<RefCell<World>>;

/// What a transaction's byte says.
enum Action {
    Honest,
    Mutate(u8, u8),
    Raw(Vec<u8>),
    Fail(BusError),
}

impl World {
    pub fn new(mb: u8, boards: Vec<u8>, bus_input: &[u8]) -> Shared {
        let n = boards.len();
        Rc::new(RefCell::new(World {
            mb,
            boards,
            input: Reader::new(bus_input),
            state: vec![Board::default(); n],
            txns: Vec::new(),
            sent: Vec::new(),
            to_mb: VecDeque::new(),
            listener: None,
            schedule: Vec::new(),
            injector: None,
        }))
    }

    fn board(&mut self, addr: u8) -> Option<&mut Board> {
        let i = self.boards.iter().position(|&a| a == addr)?;
        self.state.get_mut(i)
    }

    /// Writes `bytes` to the MB now.
    pub fn to_mb(&mut self, bytes: Vec<u8>) {
        self.sent.push(Sent {
            at: now_us(),
            bytes: bytes.clone(),
            delivered: None,
        });
        let index = self.sent.len() - 1;
        self.to_mb.push_back((index, bytes));
        if let Some(w) = self.listener.take() {
            w.wake();
        }
    }

    /// Schedules `bytes` to be written to the MB at `at`.
    pub fn schedule(&mut self, at: u64, bytes: Vec<u8>) {
        self.schedule.push((at, bytes));
        if let Some(w) = self.injector.take() {
            w.wake();
        }
    }

    /// An event of board index `bi` of kind `template` (see [`World::event`]).
    pub fn event_for(&mut self, template: u8, mutation: u8) -> Option<Vec<u8>> {
        let bi = usize::from(template >> 3) % self.boards.len();
        let addr = self.boards[bi];
        let mut bytes = self.event(addr, template, mutation)?;
        if mutation == 0xff {
            // Sent without its check, whatever the board's PEC setting.
            if let Some(n) = bytes.get(5).map(|&n| 6 + usize::from(n)) {
                bytes.truncate(n);
            }
        } else if mutation != 0 {
            let bit = usize::from(mutation) % (bytes.len() * 8);
            bytes[bit / 8] ^= 1 << (bit % 8);
        }
        Some(bytes)
    }

    /// An honest event of board `addr`: `template % 8` picks the kind, the higher bits the
    /// pin and value.
    fn event(&mut self, addr: u8, template: u8, param: u8) -> Option<Vec<u8>> {
        let mb = self.mb;
        let b = self.board(addr)?;
        let pins = [0x80u8, 0x81, 0x82];
        let pin = pins[usize::from(template >> 4) % 3];
        let (kind, port, seq, status, payload): (u8, u8, u8, u8, Vec<u8>) = match template % 8 {
            0 | 7 => {
                b.level ^= 1;
                let lv = b.level;
                (0x01, pin, b.next_seq(), 0, vec![lv, 1 - lv, 0, lv, 0])
            }
            1 => (0x02, 0x80, b.next_seq(), 0, vec![param, 0x02, param & 1]),
            2 => match b.pending.pop_front() {
                Some((seq, pin, width)) => (0x03, pin, seq, 0, width.to_le_bytes().to_vec()),
                // None pending: one for the last request, on pin S1.A or S1.B, by
                // `template >> 6`: status timeout, ok with 2 bytes, timeout with a payload,
                // ok with 4 bytes.
                None => {
                    let pin = pins[usize::from(template >> 4) & 1];
                    match template >> 6 {
                        0 => (0x03, pin, b.last_seq, 0x0c, vec![]),
                        1 => (0x03, pin, b.last_seq, 0, vec![param, 0]),
                        2 => (0x03, pin, b.last_seq, 0x0c, vec![param]),
                        _ => (0x03, pin, b.last_seq, 0, vec![param, 0, 0, 0]),
                    }
                }
            },
            3 if template >> 6 == 3 => {
                // An unaddressed board announces itself from 0x77 (plug and play): identity,
                // reset reason, its ID; always with its check. (This motherboard keeps no
                // directory: it counts the announce and drops it.)
                let frame = [
                    0x77, 0x08, 0, 0, 0, 19, 1, 0, 1, 0, 1, 2, 2, 0xff, 0x01, 12, 0, param, 1, 2,
                    3, 4, 5, 6, 7,
                ];
                return Some(with_check(mb << 1, &frame));
            }
            3 => {
                b.pec = false;
                b.ev_seq = 1;
                b.pending.clear();
                // Identity, then the reset reason (power-on), then the board's ID (plug and
                // play); always with its check.
                let frame = [
                    addr, 0x07, 0, 0, 0, 19, 1, 0, 1, 0, 1, 2, 2, 0xff, 0x01, 12, 0, addr, 1, 2, 3,
                    4, 5, 6, 7,
                ];
                return Some(with_check(mb << 1, &frame));
            }
            4 => (0x05, b.last_port, b.last_seq, 0x08, vec![]),
            5 => (0x04, 0, b.next_seq(), 0, vec![0x2c, 0x01]),
            _ => (0x06, 0, b.next_seq(), 0, vec![1, 0, 1, 0, 0, 0]),
        };
        let mut frame = vec![addr, kind, port, seq, status, payload.len() as u8];
        frame.extend(payload);
        Some(if b.pec {
            with_check(mb << 1, &frame)
        } else {
            frame
        })
    }

    fn action(&mut self) -> (Action, u64) {
        let a = self.input.byte();
        let delay = 60 + u64::from(a >> 3).pow(2) * 100;
        let act = match a & 7 {
            1 => {
                let m = self.input.byte();
                let p = self.input.byte();
                Action::Mutate(m, p)
            }
            2 => {
                let n = usize::from(self.input.byte()) % 40;
                Action::Raw((0..n).map(|_| self.input.byte()).collect())
            }
            3 => Action::Fail(BusError::Nack),
            4 => Action::Fail(BusError::ArbitrationLost),
            5 => Action::Fail(BusError::Timeout),
            6 => Action::Fail(BusError::Bus),
            _ => Action::Honest,
        };
        if a & 7 == 7 || a & 7 == 4 {
            // Queue an event too (the arbitration winner, or one right after).
            let e = self.input.byte();
            let m = if e & 0x80 != 0 { self.input.byte() } else { 0 };
            if let Some(ev) = self.event_for(e, m) {
                let at = now_us() + delay / 2;
                self.schedule(at, ev);
            }
        }
        (act, delay)
    }

    /// The honest reply to `written` sent to `addr` (`None`: not a board), and the board's
    /// state updated as an honest board's.
    fn honest_reply(&mut self, addr: u8, written: &[u8]) -> Option<Vec<u8>> {
        let mb = self.mb;
        let now = now_us();
        // The request's check, if it carried one.
        let body_len = match written.len() {
            n if n >= 5
                && n - 1 <= 13
                && check_of(addr << 1, &written[..n - 1]) == written[n - 1..] =>
            {
                n - 1
            }
            n if n >= 16 && check_of(addr << 1, &written[..n - 2]) == written[n - 2..] => n - 2,
            n => n,
        };
        let checked = body_len != written.len();
        let body = &written[..body_len];
        let b = self.board(addr)?;
        if body.len() < 4 {
            return Some(vec![0, 0x02, 0]);
        }
        let (fn_op, port, seq, data) = (body[0], body[2], body[3], &body[4..]);
        b.last_seq = seq;
        b.last_port = port;
        let mut mode = checked;
        let mut deferred = None;
        let (status, payload): (u8, Vec<u8>) = match fn_op {
            // Ping, the system writes and every output (read back: ok, no payload).
            0x00 | 0x02 | 0x03 | 0x04 | 0x06 | 0x11 | 0x12 | 0x20 | 0x21 | 0x22 | 0x40 | 0x42 => {
                (0, vec![])
            }
            0x07 => {
                mode = data.first() == Some(&1);
                b.pec = mode;
                (0, vec![])
            }
            0x01 => (0, vec![1, 0, 1, 0, 1, 2, 2, 0xff, 0x01, 12]),
            0x05 => (0, vec![0; 28]),
            0x10 => (0, vec![b.level]),
            0x13 | 0x14 => {
                let width = 1_000 + (now / 100 % 10_000) as u32;
                b.pending.push_back((seq, port, width));
                // The board's pulse timeout (data, else the default 1 s), and when within it
                // the pulse ends: 1 ms + the next input byte x 4 ms, at most the timeout + 1 ms.
                let timeout_ms = match *data {
                    [lo, hi] => u64::from(u16::from_le_bytes([lo, hi])),
                    _ => 1_000,
                };
                deferred = Some((seq, port, width, timeout_ms));
                (0x01, vec![])
            }
            0x30 => (0, vec![seq, 0x01]),
            0x41 => (
                0,
                data.first()
                    .map(|&n| vec![0x61; usize::from(n.min(3))])
                    .unwrap_or_default(),
            ),
            0x60 => (0, vec![2, b.level, 0, 0x10, 0, 0x20, 0]),
            0x50 => {
                // One result per item: io input, analog read, outputs; others refused.
                let mut results = Vec::new();
                let mut items = data;
                while let [fn_op, _port, n, ref rest @ ..] = *items {
                    let n = usize::from(n).min(rest.len());
                    match fn_op {
                        0x10 => results.extend([0, 1, b.level]),
                        0x30 => results.extend([0, 2, seq, 0x01]),
                        0x11 | 0x12 | 0x20 => results.extend([0, 0]),
                        _ => results.extend([0x03, 0]),
                    }
                    items = &rest[n..];
                }
                (0, results)
            }
            _ => (0x03, vec![]),
        };
        let pec_now = b.pec;
        if let Some((seq, port, width, timeout_ms)) = deferred {
            let after_us = (1 + 4 * u64::from(self.input.byte())).min(timeout_ms + 1) * 1_000;
            let mut frame = vec![addr, 0x03, port, seq, 0, 4];
            frame.extend(width.to_le_bytes());
            let ev = if pec_now {
                with_check(mb << 1, &frame)
            } else {
                frame
            };
            if let Some(b) = self.board(addr) {
                b.pending.retain(|p| p.0 != seq);
            }
            self.schedule(now + after_us, ev);
        }
        let mut frame = vec![seq, status, payload.len() as u8];
        frame.extend(payload);
        Some(if !mode {
            frame
        } else if matches!(fn_op, 0x41 | 0x50 | 0x60) {
            // A reply whose length varies: always a CRC-16.
            with_crc16(addr << 1 | 1, &frame)
        } else {
            with_check(addr << 1 | 1, &frame)
        })
    }

    fn take_event(&mut self) -> Option<Vec<u8>> {
        let (index, bytes) = self.to_mb.pop_front()?;
        if let Some(s) = self.sent.get_mut(index) {
            s.delivered = Some(now_us());
        }
        Some(bytes)
    }
}

/// Applies mutation `m` with parameter `p` to `reply`.
fn mutate(reply: &mut Vec<u8>, m: u8, p: u8) {
    if reply.is_empty() {
        reply.push(p);
        return;
    }
    let len = reply.len();
    match m % 6 {
        0 => {
            let bit = usize::from(p) % (len * 8);
            reply[bit / 8] ^= 1 << (bit % 8);
        }
        1 => reply[0] = p,
        2 if len > 1 => reply[1] = p,
        3 if len > 2 => reply[2] = p,
        4 => reply.truncate(usize::from(p) % len),
        _ => reply.push(p),
    }
}

/// The MB's port on the fake bus.
#[derive(Clone)]
pub struct FuzzBus {
    pub world: Shared,
}

impl FuzzBus {
    async fn transaction(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: Option<&mut [u8]>,
    ) -> Result<(), BusError> {
        let start = now_us();
        let (action, delay) = self.world.borrow_mut().action();
        sleep_until(start + delay).await;
        let mut w = self.world.borrow_mut();
        let known = w.boards.contains(&addr);
        let read_len = read.as_ref().map(|r| r.len());
        let result: Result<Vec<u8>, BusError> = match action {
            Action::Fail(e) => Err(e),
            _ if !known => Err(BusError::Nack),
            Action::Honest | Action::Mutate(..) if read.is_none() => {
                if let Action::Mutate(..) = action {
                    // The board refuses the output: a `rejected` event follows.
                    if let Some(ev) = w.event(addr, 4, 0) {
                        w.schedule(now_us() + 200, ev);
                    }
                } else {
                    let _ = w.honest_reply(addr, bytes);
                }
                Ok(vec![])
            }
            Action::Raw(_) if read.is_none() => Ok(vec![]),
            Action::Honest => Ok(w.honest_reply(addr, bytes).unwrap_or_default()),
            Action::Mutate(m, p) => {
                let mut r = w.honest_reply(addr, bytes).unwrap_or_default();
                mutate(&mut r, m, p);
                Ok(r)
            }
            Action::Raw(r) => Ok(r),
        };
        let recorded = match (&result, read) {
            (Ok(reply), Some(buf)) => {
                buf.fill(0xFF);
                let n = reply.len().min(buf.len());
                buf[..n].copy_from_slice(&reply[..n]);
                Ok(buf.to_vec())
            }
            (Ok(_), None) => Ok(vec![]),
            (Err(e), _) => Err(match e {
                BusError::Nack => "nack",
                BusError::ArbitrationLost => "arbitration lost",
                BusError::Timeout => "timeout",
                BusError::Bus => "bus",
                BusError::Overrun => "overrun",
            }),
        };
        w.txns.push(Txn {
            start,
            end: now_us(),
            addr,
            written: bytes.to_vec(),
            read_len,
            result: recorded,
        });
        result.map(|_| ())
    }
}

impl MultiMaster for FuzzBus {
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        self.transaction(addr, bytes, None).await
    }

    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        self.transaction(addr, bytes, Some(read)).await
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        std::future::poll_fn(|cx| {
            let mut w = self.world.borrow_mut();
            if w.to_mb.is_empty() {
                w.listener = Some(cx.waker().clone());
                Poll::Pending
            } else {
                Poll::Ready(Ok(()))
            }
        })
        .await
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        std::future::poll_fn(|cx| {
            let mut w = self.world.borrow_mut();
            match w.take_event() {
                Some(b) if b.len() > buf.len() => Poll::Ready(Err(BusError::Overrun)),
                Some(b) => {
                    buf[..b.len()].copy_from_slice(&b);
                    Poll::Ready(Ok(Incoming::Write(b.len())))
                }
                None => {
                    w.listener = Some(cx.waker().clone());
                    Poll::Pending
                }
            }
        })
        .await
    }

    async fn respond(&mut self, _bytes: &[u8]) -> Result<(), BusError> {
        Ok(())
    }
}

/// Writes the scheduled events to the MB at their times; never ends.
pub async fn injector(world: Shared) {
    std::future::poll_fn(|cx| {
        let mut w = world.borrow_mut();
        let now = now_us();
        loop {
            let due = w
                .schedule
                .iter()
                .enumerate()
                .filter(|(_, (at, _))| *at <= now)
                .min_by_key(|(i, (at, _))| (*at, *i))
                .map(|(i, _)| i);
            let Some(i) = due else { break };
            let (_, bytes) = w.schedule.remove(i);
            w.to_mb(bytes);
        }
        if let Some(at) = w.schedule.iter().map(|(at, _)| *at).min() {
            wake_at(at, cx.waker());
        }
        w.injector = Some(cx.waker().clone());
        Poll::<()>::Pending
    })
    .await
}
