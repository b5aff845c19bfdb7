//! Test doubles for the motherboard runtime: the daughterboard tests' clock, driver and
//! recording `Ports` (shared source), and a loopback bus with scripted daughterboards.
#![allow(dead_code)]

#[path = "../../../firmware-db/tests/common/mod.rs"]
mod db_common;

use std::cell::RefCell;
use std::collections::{BTreeMap, VecDeque};
use std::future::{poll_fn, Future};
use std::rc::Rc;
use std::task::{Poll, Waker};

pub use db_common::{run, FakePorts, PortOp, TestClock};
use embassy_futures::join::join;
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig};
use firmware_mb::{MbConfig, Motherboard};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::time::{Clock, Instant};
use x10_microcode::{Address, BoardKind};

pub type Db = Daughterboard<NoopRawMutex, FakePorts>;

/// Virtual time one bus transaction takes.
pub const TRANSFER_US: u64 = 100;
/// The port's own timeout for a target that stretches the clock forever.
pub const BUS_TIMEOUT_US: u64 = 25_000;
/// The motherboard's address in these tests.
pub const MB: u8 = 0x08;

/// The `boot` event a board at `source` with `identity` sends after a power-on start, as it
/// goes on the bus: identity, reset reason 0, and always its check (a CRC-16: 17 bytes).
pub fn boot_event(source: u8, identity: &x10_microcode::Identity) -> Vec<u8> {
    let mut b = vec![source, 0x07, 0x00, 0x00, 0x00, 0x0B];
    b.extend_from_slice(&identity.to_bytes());
    b.push(0x00);
    let n = b.len();
    b.resize(n + x10_microcode::pec::check_len(n), 0);
    x10_microcode::pec::append(MB << 1, &mut b, n).unwrap();
    b
}

pub fn mb_address() -> Address {
    Address::external(MB).unwrap()
}

/// A daughterboard core at `addr` with 3 sensor and 2 actuator ports.
pub fn db(clock: &TestClock, addr: u8) -> Db {
    let cfg = DbConfig::new(Address::external(addr).unwrap(), BoardKind::SIMULATED);
    Daughterboard::new(FakePorts::new(clock.clone(), 3, 2), cfg)
}

/// A scripted target: request bytes in, (delay in µs, reply bytes) out.
pub type Responder = dyn FnMut(&[u8]) -> (u64, Vec<u8>);

/// How a node on the bus behaves.
pub enum Node {
    /// A real `firmware-db` core.
    Db(Rc<Db>),
    /// Nobody at this address: every transaction is NACKed.
    Absent,
    /// Holds SCL forever: the port times out after [`BUS_TIMEOUT_US`].
    Silent,
    /// Answers a write-then-read with these bytes after this delay (µs).
    Script(Box<Responder>),
}

/// A scripted failure of the next transaction to an address, optionally with the event
/// the arbitration winner writes to the motherboard at the same time.
#[derive(Clone, Debug)]
pub struct Fault {
    pub error: BusError,
    pub event: Option<Vec<u8>>,
}

/// One transaction the motherboard made, as the bus saw it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Seen {
    Write(u8, Vec<u8>),
    WriteRead(u8, Vec<u8>, usize),
    Respond(Vec<u8>),
}

#[derive(Default)]
struct Inner {
    nodes: RefCell<BTreeMap<u8, Node>>,
    faults: RefCell<BTreeMap<u8, VecDeque<Fault>>>,
    /// Bit masks XORed into the next replies read from an address (the board has the
    /// request; its reply is corrupted on the wire).
    reply_flips: RefCell<BTreeMap<u8, VecDeque<Vec<u8>>>>,
    to_mb: RefCell<VecDeque<Vec<u8>>>,
    /// Every write to the motherboard, with its virtual time.
    to_mb_log: RefCell<Vec<(u64, Vec<u8>)>>,
    listener: RefCell<Option<Waker>>,
    seen: RefCell<Vec<(u64, Seen)>>,
}

/// The motherboard's port on a loopback bus.
#[derive(Clone)]
pub struct LoopBus {
    inner: Rc<Inner>,
    clock: TestClock,
}

impl LoopBus {
    pub fn new(clock: &TestClock) -> Self {
        LoopBus {
            inner: Rc::default(),
            clock: clock.clone(),
        }
    }

    pub fn attach(&self, addr: u8, node: Node) {
        self.inner.nodes.borrow_mut().insert(addr, node);
    }

    pub fn fault(&self, addr: u8, f: Fault) {
        self.inner
            .faults
            .borrow_mut()
            .entry(addr)
            .or_default()
            .push_back(f);
    }

    /// The next reply read from `addr` reaches the motherboard with `mask` XORed into it
    /// (byte by byte from the first): the board received and executed the request.
    pub fn flip_reply(&self, addr: u8, mask: Vec<u8>) {
        self.inner
            .reply_flips
            .borrow_mut()
            .entry(addr)
            .or_default()
            .push_back(mask);
    }

    /// A daughterboard writes `bytes` to the motherboard.
    pub fn to_mb(&self, bytes: Vec<u8>) {
        self.inner
            .to_mb_log
            .borrow_mut()
            .push((self.clock.now_us(), bytes.clone()));
        self.inner.to_mb.borrow_mut().push_back(bytes);
        if let Some(w) = self.inner.listener.borrow_mut().take() {
            w.wake();
        }
    }

    /// Every write to the motherboard so far (events), with its virtual time.
    pub fn to_mb_log(&self) -> Vec<(u64, Vec<u8>)> {
        self.inner.to_mb_log.borrow().clone()
    }

    pub fn seen(&self) -> Vec<(u64, Seen)> {
        self.inner.seen.borrow().clone()
    }

    fn record(&self, s: Seen) {
        self.inner.seen.borrow_mut().push((self.clock.now_us(), s));
    }

    async fn transaction(&self, addr: u8) -> Result<(), BusError> {
        let at = self.clock.now().plus_us(TRANSFER_US);
        self.clock.sleep_until(at).await;
        let fault = self
            .inner
            .faults
            .borrow_mut()
            .get_mut(&addr)
            .and_then(VecDeque::pop_front);
        if let Some(f) = fault {
            if let Some(ev) = f.event {
                self.to_mb(ev);
            }
            return Err(f.error);
        }
        Ok(())
    }

    /// Runs every real DB attached: background work and event delivery to the MB.
    pub async fn run_dbs(&self) {
        let dbs: Vec<Rc<Db>> = self
            .inner
            .nodes
            .borrow()
            .values()
            .filter_map(|n| match n {
                Node::Db(d) => Some(d.clone()),
                _ => None,
            })
            .collect();
        let futs: Vec<_> = dbs.iter().map(|d| Box::pin(self.run_db(d))).collect();
        // join a dynamic number of never-ending futures: poll them all by hand
        let mut futs = futs;
        poll_fn(|cx| {
            for f in futs.iter_mut() {
                let _ = f.as_mut().poll(cx);
            }
            Poll::<()>::Pending
        })
        .await
    }

    async fn run_db(&self, d: &Db) {
        let pump = async {
            loop {
                let ev = d.next_event().await;
                let mut buf = [0u8; 40];
                let n = d.encode_event(&ev, mb_address(), &mut buf);
                self.to_mb(buf[..n].to_vec());
            }
        };
        let _ = select(d.run_background(&self.clock), pump).await;
    }
}

impl MultiMaster for LoopBus {
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        self.record(Seen::Write(addr, bytes.to_vec()));
        self.transaction(addr).await?;
        let db = match self.inner.nodes.borrow().get(&addr) {
            Some(Node::Db(d)) => Some(d.clone()),
            Some(Node::Script(_)) => None,
            Some(Node::Silent) => return Err(BusError::Timeout),
            Some(Node::Absent) | None => return Err(BusError::Nack),
        };
        if let Some(d) = db {
            d.handle_write(bytes, false);
        }
        Ok(())
    }

    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        self.record(Seen::WriteRead(addr, bytes.to_vec(), read.len()));
        self.transaction(addr).await?;
        enum Do {
            Db(Rc<Db>),
            Reply(u64, Vec<u8>),
            Stretch,
            Nack,
        }
        let what = match self.inner.nodes.borrow_mut().get_mut(&addr) {
            Some(Node::Db(d)) => Do::Db(d.clone()),
            Some(Node::Script(f)) => {
                let (delay, reply) = f(bytes);
                Do::Reply(delay, reply)
            }
            Some(Node::Silent) => Do::Stretch,
            Some(Node::Absent) | None => Do::Nack,
        };
        read.fill(0xFF);
        match what {
            Do::Db(d) => {
                d.handle_write(bytes, true);
                let mut buf = [0u8; 40];
                let n = d.take_reply(&mut buf).min(read.len());
                read[..n].copy_from_slice(&buf[..n]);
                let flip = self
                    .inner
                    .reply_flips
                    .borrow_mut()
                    .get_mut(&addr)
                    .and_then(VecDeque::pop_front);
                for (r, m) in read.iter_mut().zip(flip.unwrap_or_default()) {
                    *r ^= m;
                }
                Ok(())
            }
            Do::Reply(delay, reply) => {
                let at = self.clock.now().plus_us(delay);
                self.clock.sleep_until(at).await;
                let n = reply.len().min(read.len());
                read[..n].copy_from_slice(&reply[..n]);
                Ok(())
            }
            Do::Stretch => {
                let at = self.clock.now().plus_us(BUS_TIMEOUT_US);
                self.clock.sleep_until(at).await;
                Err(BusError::Timeout)
            }
            Do::Nack => Err(BusError::Nack),
        }
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        poll_fn(|cx| {
            if self.inner.to_mb.borrow().is_empty() {
                *self.inner.listener.borrow_mut() = Some(cx.waker().clone());
                Poll::Pending
            } else {
                Poll::Ready(Ok(()))
            }
        })
        .await
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        poll_fn(|cx| match self.inner.to_mb.borrow_mut().pop_front() {
            Some(b) if b.len() > buf.len() => Poll::Ready(Err(BusError::Overrun)),
            Some(b) => {
                buf[..b.len()].copy_from_slice(&b);
                Poll::Ready(Ok(Incoming::Write(b.len())))
            }
            None => {
                *self.inner.listener.borrow_mut() = Some(cx.waker().clone());
                Poll::Pending
            }
        })
        .await
    }

    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        self.record(Seen::Respond(bytes.to_vec()));
        Ok(())
    }
}

/// Runs `body` to completion while `background` (never-ending runtime futures) runs beside it.
pub fn sim<T>(clock: &TestClock, background: impl Future, body: impl Future<Output = T>) -> T {
    match run(clock, select(body, background)) {
        Either::First(v) => v,
        Either::Second(_) => panic!("background ended"),
    }
}

/// The motherboard under test: its internal board on recording ports, the test clock.
pub type Mb = Motherboard<FakePorts>;

/// A motherboard at [`MB`] and a real daughterboard at 9 on one loopback bus.
pub struct World {
    pub clock: TestClock,
    pub mb: &'static Mb,
    pub bus: LoopBus,
    pub db9: Rc<Db>,
}

impl World {
    /// The motherboard with 2 + 2 internal ports, and DB 9 attached, in the thesis's exact
    /// mode (no PEC, no failsafe unless a test asks for them): these tests check the
    /// dispatcher's mechanisms on the thesis's bytes. [`World::safe`] has the defaults.
    pub fn new() -> World {
        Self::with_config(MbConfig::thesis_compatible(mb_address()))
    }

    /// The same with the safe defaults ([`MbConfig::new`]: PEC and a failsafe on every board).
    pub fn safe() -> World {
        Self::with_config(MbConfig::new(mb_address()))
    }

    pub fn with_config(config: MbConfig) -> World {
        let clock = TestClock::new();
        // Robot handles are `'static`: each test leaks its motherboard.
        let mb: &'static Mb = Box::leak(Box::new(Motherboard::new(
            config,
            FakePorts::new(clock.clone(), 2, 2),
        )));
        let bus = LoopBus::new(&clock);
        let db9 = Rc::new(db(&clock, 9));
        bus.attach(9, Node::Db(db9.clone()));
        World {
            clock,
            mb,
            bus,
            db9,
        }
    }

    /// Runs `body` while the motherboard and the bus's daughterboards run beside it.
    pub fn sim<T>(&self, body: impl Future<Output = T>) -> T {
        sim(
            &self.clock,
            join(self.mb.run(self.bus.clone()), self.bus.run_dbs()),
            body,
        )
    }

    /// Sleeps until `t` µs.
    pub async fn at(&self, t: u64) {
        self.clock.sleep_until(Instant(t)).await;
    }
}
