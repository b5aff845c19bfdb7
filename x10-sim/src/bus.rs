//! One simulated multi-master I2C bus with many nodes.
//!
//! Every node gets a [`SimPort`], which implements [`x10_hal::bus::MultiMaster`]. A bus
//! *engine* task ([`SimBus::engine`], spawned on the [`crate::exec::Executor`]) plays the wire:
//!
//! * **Timing**: each transaction takes the time of [`crate::timing`] at the configured clock:
//!   START, 9 bits per byte, repeated START, STOP, then `t_BUF` before the next START, plus any
//!   clock stretching.
//! * **Arbitration**: every master that wants the bus when it becomes free (or in the same
//!   virtual instant while it is free) starts together. Their address and data bits are compared
//!   bit by bit as a wired-AND bus does: at the first bit where they differ the masters sending 1
//!   lose and get [`BusError::ArbitrationLost`] at the end of that bit. Two masters sending the
//!   same bits to the end of the shorter one are a case the I2C spec leaves undefined: the lower
//!   node index wins and the others lose at the first bit past the common part.
//! * **Acknowledge**: the address is NACKed when no node has it, when the node is resetting, and
//!   when the node is [`Role::SingleRole`] (RP2040-like) and inside its controller window: from
//!   the START of its own transaction (it switches roles only once the bus is idle, as
//!   `PLATFORM-FACTS.md` prescribes) until its call returned plus the role-switch time.
//! * **Addressed, then received**: a node's [`SimPort`] reports the address match through
//!   `addressed` (its controller is stretched at the address ACK until the node calls
//!   `listen`, or a `listen` was already waiting). From the first data bit on, the transfer
//!   belongs to that `listen` future: dropping it before it returned loses the transfer, as
//!   on the real ports (the bytes the RP2040 driver already drained are gone; the STM32 one
//!   leaves SCL stretched). The bytes still play out on the wire, the node never sees them;
//!   each loss is counted in [`BusStats::lost_transfers`] and noted in the transaction's
//!   record (`faults`: "lost: listen dropped"), so a runtime that races `listen` shows in tests.
//! * **General call**: a write to address 0x00 is acknowledged and received by every node
//!   configured to take general calls ([`NodeConfig::with_general_call`]: the daughterboards)
//!   that is not deaf at that moment; a read from 0x00 is NACKed.
//! * **Stretching**: an addressed target that has no `listen` waiting holds SCL low until one is,
//!   and a target asked for a read holds SCL low until it calls `respond`; past the configured
//!   stretch timeout the controller gets [`BusError::Timeout`]. While a node is stretched
//!   like this, its own controller calls waiting for the bus fail at once with
//!   [`BusError::ArbitrationLost`] (counted in [`BusStats::yielded`]): a port that sees its
//!   address-match flag while it waits to start (STM32 `ADDR`, RP2040 `slv_activity`) must
//!   give up rather than wait for a bus it holds itself, so the caller serves its listener
//!   and retries.
//! * **Faults**: a seeded [`FaultConfig`] injects NACKs, corrupted bytes, node resets and stuck
//!   lines, as smoltcp's `phy::FaultInjector` does for packets.
//!
//! Every transaction is recorded as a [`BusRecord`] (time, master, address, bytes, outcome and
//! the wire symbols), from which the trace and the VCD waveform are made.

use std::cell::RefCell;
use std::collections::{BTreeMap, VecDeque};
use std::future::{poll_fn, Future};
use std::pin::Pin;
use std::rc::Rc;
use std::task::{Context, Poll, Waker};

use embassy_futures::select::select;
use x10_hal::bus::{BusError, Incoming, MultiMaster};

use crate::exec::{Nanos, Rng, SimClock};
use crate::timing::{Speed, Timing};

/// Noted in a record's `faults` when its target lost it (see [`BusStats::lost_transfers`]).
pub const LOST_NOTE: &str = "lost: listen dropped";

/// Index of a node on the bus, in the order nodes were added.
pub type NodeId = usize;

/// How a node's I2C peripheral handles the two roles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Controller or target, one at a time (RP2040): deaf to its own address from the START
    /// of its own transaction until `switch_ns` after its call returned.
    SingleRole {
        /// Time to tear down the controller and re-arm the target, in ns.
        switch_ns: Nanos,
    },
    /// Both at once (STM32 I2C v2 `MultiMaster`): always answers its address.
    DualRole,
}

/// One node of the bus.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// Name used in traces (`mb`, `db09`, …).
    pub name: String,
    /// Own 7-bit target address, if the node listens at all.
    pub address: Option<u8>,
    /// Role handling.
    pub role: Role,
    /// True when the fault injector may reset this node.
    pub resettable: bool,
    /// True when the node's target also acknowledges and receives writes to the general
    /// call address (0x00), as daughterboards do (a sweep's `sample`, an `apply`).
    pub general_call: bool,
}

impl NodeConfig {
    /// A dual-role node at `address`.
    pub fn new(name: impl Into<String>, address: Option<u8>) -> NodeConfig {
        NodeConfig {
            name: name.into(),
            address,
            role: Role::DualRole,
            resettable: false,
            general_call: false,
        }
    }

    /// This node, whose target takes general calls too.
    pub fn with_general_call(mut self) -> NodeConfig {
        self.general_call = true;
        self
    }

    /// This node with role handling `role`.
    pub fn with_role(mut self, role: Role) -> NodeConfig {
        self.role = role;
        self
    }

    /// This node, which the fault injector may reset.
    pub fn resettable(mut self) -> NodeConfig {
        self.resettable = true;
        self
    }
}

/// Seeded fault injection, per transaction (probabilities in parts per million).
///
/// Each transaction rolls its faults at its START, in a fixed order, whatever its scope
/// ([`FaultConfig::only_address`], [`FaultConfig::window_ns`]): a fault rolled outside the
/// scope is dropped, so narrowing the scope never changes which faults the transactions
/// inside it get. The original four faults (stuck SDA, reset, NACK, corruption) draw from the
/// bus's generator exactly as before these options existed; bursts, address flips, stuck SCL
/// and the recovery point of a stuck SDA draw from a second generator of the same seed, so a
/// configuration that leaves them off replays older runs bit for bit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultConfig {
    /// A NACK on the address or one data byte.
    pub nack_ppm: u32,
    /// A burst of flipped bits on the wire in the data part (written, then read bytes): the
    /// receiver sees it, the sender does not. See [`FaultConfig::burst_bits`].
    pub corrupt_ppm: u32,
    /// A resettable node restarts (NACKs for `reset_ns`, loses what it had received).
    pub reset_ppm: u32,
    /// SDA stuck low (a target interrupted in the middle of a byte it was sending holds it):
    /// the transaction ends in [`BusError::Bus`], and the bus stays unusable until the target
    /// lets go by itself after `stuck_ns`, or until a master clocks it free with the standard
    /// 9-clock recovery ([`SimBus::recover`]).
    pub stuck_ppm: u32,
    /// How long a reset node stays deaf.
    pub reset_ns: Nanos,
    /// How long a stuck line stays stuck when nobody recovers it.
    pub stuck_ns: Nanos,
    /// Bits in one corruption burst, counted along the wire from a random first bit (MSB
    /// first, across byte boundaries, the ACK bits not counted): the first and the last bit of
    /// the burst are flipped, each bit between them with probability 1/2. 0 and 1 flip one bit.
    pub burst_bits: u8,
    /// One of the 7 address bits flipped (the targets see the other address, the master does
    /// not notice): the transaction goes to the node at that address, or is NACKed when there
    /// is none. A write-read's repeated START carries the same flipped address.
    pub address_ppm: u32,
    /// SCL held low by a target for `stuck_ns` (a hung target): the transaction ends in
    /// [`BusError::Timeout`] at the stretch timeout, and the bus is unusable until the target
    /// lets go (clocking cannot recover a stuck SCL).
    pub stuck_scl_ppm: u32,
    /// Faults only in transactions to or from the node at this address (its resets only, if
    /// it is resettable); `None`: every transaction.
    pub only_address: Option<u8>,
    /// Faults only in transactions that start in `from..until` (ns); `None`: always.
    pub window_ns: Option<(Nanos, Nanos)>,
}

impl FaultConfig {
    /// No faults.
    pub const NONE: FaultConfig = FaultConfig {
        nack_ppm: 0,
        corrupt_ppm: 0,
        reset_ppm: 0,
        stuck_ppm: 0,
        reset_ns: 0,
        stuck_ns: 0,
        burst_bits: 0,
        address_ppm: 0,
        stuck_scl_ppm: 0,
        only_address: None,
        window_ns: None,
    };

    fn in_window(&self, t: Nanos) -> bool {
        self.window_ns
            .is_none_or(|(from, until)| from <= t && t < until)
    }
}

/// Bus configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusConfig {
    /// Bus clock.
    pub speed: Speed,
    /// Longest a target may stretch SCL before the controller gives up.
    pub stretch_timeout_ns: Nanos,
    /// Longest a controller waits for a busy bus before it gives up.
    pub busy_timeout_ns: Nanos,
    /// Fault injection.
    pub faults: FaultConfig,
    /// Seed of the fault injector.
    pub seed: u64,
    /// Keep each transaction's wire symbols ([`BusRecord::wire`], for the waveform); long
    /// runs without a waveform can save the memory.
    pub record_wire: bool,
    /// Keep the record of every transaction; when false only those with a fault noted (an
    /// injected fault, a lost transfer) are kept, so a long soak keeps its memory bounded by
    /// its faults. [`BusStats`] counts every transaction either way.
    pub keep_clean_records: bool,
    /// Keep the record of every transaction addressed to this address, clean or not, even
    /// when `keep_clean_records` is false (the soak keeps every event written to the
    /// motherboard).
    pub keep_records_to: Option<u8>,
    /// Keep the record of every transaction that failed (NACK, timeout, bus fault), clean or
    /// not, even when `keep_clean_records` is false (a bounded run keeps its failures for
    /// its trace and its problems).
    pub keep_failed_records: bool,
    /// The most records kept: past it, records are counted ([`BusStats::records_dropped`],
    /// [`SimBus::dropped_failures`]) and dropped, so a run that fails often still keeps its
    /// memory bounded. `usize::MAX`: no limit.
    pub record_cap: usize,
}

impl BusConfig {
    /// No faults, SMBus-like 25 ms stretch timeout, 50 ms busy timeout, wire symbols kept.
    pub fn new(speed: Speed) -> BusConfig {
        BusConfig {
            speed,
            stretch_timeout_ns: 25_000_000,
            busy_timeout_ns: 50_000_000,
            faults: FaultConfig::NONE,
            seed: 0,
            record_wire: true,
            keep_clean_records: true,
            keep_records_to: None,
            keep_failed_records: false,
            record_cap: usize::MAX,
        }
    }
}

/// A symbol on the wire, for the waveform. Each starts with SCL low, except START.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WireSym {
    /// START: SDA falls with SCL high, then SCL falls after `t_HD;STA`.
    Start,
    /// One bit: SCL low, SDA set, SCL high, SCL low again. A gap before a symbol is SCL held
    /// low by a stretching target.
    Bit {
        /// SDA level (an ACK is 0, a NACK 1).
        value: bool,
    },
    /// Repeated START.
    RepeatedStart,
    /// STOP.
    Stop,
    /// SDA held low (stuck line) until the given time.
    Stuck {
        /// When SDA is released.
        until: Nanos,
    },
    /// SCL held low (a hung target) until the given time.
    SclStuck {
        /// When SCL is released.
        until: Nanos,
    },
}

/// What happened to the transaction, from the winning master's side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Delivered (and read back).
    Ok,
    /// NACK on byte `byte` (0 = the address byte, 1 = first data byte, …).
    Nack {
        /// Which byte was not acknowledged.
        byte: usize,
    },
    /// A stretching target did not release SCL in time.
    Timeout,
    /// Bus fault (stuck line).
    Bus,
}

/// One master that lost arbitration in a transaction.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Loser {
    /// The node.
    pub node: NodeId,
    /// Address it wanted.
    pub addr: u8,
    /// Bytes it wanted to write.
    pub write: Vec<u8>,
    /// Bit index (0 = MSB of the address byte, 8 = MSB of the first data byte, …) where it lost.
    pub bit: usize,
}

/// One transaction on the bus, as recorded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BusRecord {
    /// Sequence number of the transaction.
    pub txn: u64,
    /// START (ns).
    pub start_ns: Nanos,
    /// End of STOP (ns).
    pub end_ns: Nanos,
    /// Master that won the bus.
    pub master: NodeId,
    /// Target address.
    pub addr: u8,
    /// Target node, if any node has that address.
    pub target: Option<NodeId>,
    /// Bytes the master sent.
    pub written: Vec<u8>,
    /// Bytes the target received (differs from `written` when a byte was corrupted or cut).
    pub received: Vec<u8>,
    /// True for write-then-read.
    pub is_read: bool,
    /// Bytes the master read.
    pub read: Vec<u8>,
    /// Outcome for the winner.
    pub outcome: Outcome,
    /// Masters that lost arbitration to this one.
    pub losers: Vec<Loser>,
    /// Time SCL was stretched by the target, in all (ns).
    pub stretch_ns: Nanos,
    /// Faults injected into this transaction, described.
    pub faults: Vec<String>,
    /// Wire symbols with their start times (ns), for the waveform.
    pub wire: Vec<(Nanos, WireSym)>,
}

impl BusRecord {
    /// Duration START to end of STOP (ns).
    pub fn duration_ns(&self) -> Nanos {
        self.end_ns.saturating_sub(self.start_ns)
    }
}

/// A controller call given up because its node was being addressed (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Yield {
    /// When (ns).
    pub t_ns: Nanos,
    /// The node that gave up.
    pub node: NodeId,
    /// The address it wanted.
    pub addr: u8,
}

/// Counters of the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Transactions started (winners only).
    pub transactions: u64,
    /// Arbitration losses.
    pub arbitration_lost: u64,
    /// NACKs (address or data).
    pub nacks: u64,
    /// Stretch or busy timeouts.
    pub timeouts: u64,
    /// Bus faults.
    pub bus_faults: u64,
    /// Faults injected.
    pub injected: u64,
    /// Node resets.
    pub resets: u64,
    /// Controller calls given up at once (as `ArbitrationLost`) because the node was being
    /// addressed by another master at the time.
    pub yielded: u64,
    /// Transfers lost by their target because its `listen` future was dropped after the
    /// transfer had started (see the module doc).
    pub lost_transfers: u64,
    /// Stuck lines injected (SDA or SCL).
    pub stuck: u64,
    /// 9-clock recoveries that freed a stuck SDA ([`SimBus::recover`]).
    pub recoveries: u64,
    /// Time the bus was unusable because of a stuck line, in all (ns).
    pub stuck_ns: Nanos,
    /// Time the bus carried transactions, START to end of STOP, in all (ns): the sum of
    /// [`BusRecord::duration_ns`] over every transaction, kept or not.
    pub busy_ns: Nanos,
    /// Records the bus would have kept but dropped at its [`BusConfig::record_cap`].
    pub records_dropped: u64,
}

/// What [`SimBus::on_record`] calls with each transaction as it ends.
pub type RecordSink = Box<dyn FnMut(&BusRecord)>;

/// Failed transactions (NACK, timeout, bus fault) with no fault noted whose records were
/// dropped at the [`BusConfig::record_cap`]: what [`crate::sim::SimOutcome::problems`] needs
/// of them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DroppedFailures {
    /// Those a node answered (its address matched).
    pub answered: u64,
    /// Those nobody answered, by address (index: the 7-bit address).
    pub unanswered: Vec<u64>,
}

/// Which line is stuck.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line {
    /// The data line, held low by a target in the middle of a byte.
    Sda,
    /// The clock line, held low by a hung target.
    Scl,
}

/// A stuck line, from its start until it is released.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct StuckLine {
    line: Line,
    from: Nanos,
    until: Nanos,
    /// Clocks after which the target holding SDA lets go (1..=9).
    release_clocks: u8,
    /// The transaction it happened in.
    txn: u64,
}

/// The faults of the options, rolled from the second generator.
struct ExtRolls {
    scl: bool,
    flip: Option<u8>,
    burst: Option<u64>,
    release: Option<u8>,
}

/// What a 9-clock recovery ([`SimBus::recover`]) did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recovery {
    /// No line was stuck: nothing to do (a real master would still clock and STOP).
    NotStuck,
    /// SDA was released after this many clocks; a STOP followed and the bus is free.
    Released {
        /// Clock pulses given (1 to 9).
        clocks: u8,
    },
}

#[derive(Debug)]
enum ReqState {
    Waiting,
    InFlight,
    Done {
        result: Result<Vec<u8>, BusError>,
        at: Nanos,
    },
}

#[derive(Debug)]
struct Request {
    node: NodeId,
    addr: u8,
    write: Vec<u8>,
    read_len: Option<usize>,
    registered: Nanos,
    state: ReqState,
    waker: Option<Waker>,
}

#[derive(Clone, Copy, Debug)]
enum DeliveryKind {
    Write,
    WriteRead,
    Read,
    Overrun,
}

#[derive(Debug)]
struct Delivery {
    txn: u64,
    kind: DeliveryKind,
    bytes: Vec<u8>,
    ready_at: Nanos,
}

#[derive(Debug, Clone)]
enum RespondState {
    Idle,
    Awaiting { txn: u64 },
    Given { txn: u64, bytes: Vec<u8> },
    Done { txn: u64, at: Nanos },
    Expired { txn: u64 },
}

#[derive(Debug)]
struct Node {
    cfg: NodeConfig,
    /// Its controller transaction is on the wire (from START until its call returns).
    controller_active: bool,
    deaf_until: Nanos,
    alive_from: Nanos,
    generation: u64,
    listen_cap: Option<usize>,
    waiters: Vec<Waker>,
    inbox: VecDeque<Delivery>,
    respond: RespondState,
    /// The engine holds a transaction to this node at the address ACK, waiting for `listen`.
    addressed: bool,
    /// A transaction whose data phase started with this node's `listen` armed, until it is
    /// delivered to the inbox.
    receiving: Option<u64>,
    /// A transaction lost by a dropped `listen`: its delivery is thrown away.
    discard: Option<u64>,
}

impl Node {
    /// True when a transaction to `addr` is for this node: its own address, or the general
    /// call when it takes those.
    fn listens_at(&self, addr: u8) -> bool {
        self.cfg.address == Some(addr)
            || (addr == 0 && self.cfg.general_call && self.cfg.address.is_some())
    }

    fn wake(&mut self) {
        for w in self.waiters.drain(..) {
            w.wake();
        }
    }

    /// Wakes the waiters at `at` (now if that has passed): what they wait for is theirs from
    /// `at` on (a delivery ready then, a reply whose STOP ends then), so they are polled then
    /// and not also now only to start sleeping until `at`. They stay registered meanwhile:
    /// a reset before `at` ([`BusInner::restart`]) still wakes them at once.
    fn wake_at(&mut self, clock: &SimClock, at: Nanos) {
        for w in &self.waiters {
            clock.wake_at(at, w.clone());
        }
    }
}

struct BusInner {
    cfg: BusConfig,
    /// The bus's clock (a finished request wakes its caller when its result is due).
    clock: SimClock,
    timing: Timing,
    nodes: Vec<Node>,
    requests: BTreeMap<u64, Request>,
    next_req: u64,
    next_txn: u64,
    free_at: Nanos,
    engine_waker: Option<Waker>,
    rng: Rng,
    records: Vec<BusRecord>,
    yields: Vec<Yield>,
    stats: BusStats,
    /// Failed transactions whose records were dropped at the cap.
    dropped: DroppedFailures,
    /// Told of every transaction as it ends, kept or not ([`SimBus::on_record`]).
    sink: Option<RecordSink>,
    /// Per 7-bit address: the first node at it and how many nodes are at it (a lookup per
    /// transaction that does not grow with the number of nodes).
    by_addr: Vec<(Option<NodeId>, usize)>,
    /// Transactions lost by a dropped `listen` before their record was made.
    lost: Vec<u64>,
    /// The newest transaction that has ended (records of older ones are made or dropped).
    closed_txn: Option<u64>,
    /// The second generator (bursts, address flips, stuck SCL, recovery points).
    rng_ext: Rng,
    /// The stuck line, if any.
    stuck: Option<StuckLine>,
}

impl BusInner {
    fn wake_engine(&mut self) {
        if let Some(w) = self.engine_waker.take() {
            w.wake();
        }
    }

    fn finish(&mut self, id: u64, result: Result<Vec<u8>, BusError>, at: Nanos) {
        if let Some(r) = self.requests.get_mut(&id) {
            r.state = ReqState::Done { result, at };
            // The caller sleeps until `at` once it has its result: it is woken then.
            if let Some(w) = r.waker.take() {
                self.clock.wake_at(at, w);
            }
        }
    }

    /// Fails, as `ArbitrationLost`, every controller request of `node` still waiting for the
    /// bus: the node is being addressed, and a port that sees its address-match flag set
    /// while it waits to start (STM32 `ADDR`, RP2040 `slv_activity`) gives up rather than
    /// wait for a bus it holds itself.
    fn yield_requests_of(&mut self, node: NodeId, now: Nanos) {
        let ids: Vec<(u64, u8)> = self
            .requests
            .iter()
            .filter(|(_, r)| r.node == node && matches!(r.state, ReqState::Waiting))
            .map(|(&id, r)| (id, r.addr))
            .collect();
        for (id, addr) in ids {
            self.stats.yielded += 1;
            if self.yields.len() < self.cfg.record_cap {
                self.yields.push(Yield {
                    t_ns: now,
                    node,
                    addr,
                });
            }
            self.finish(id, Err(BusError::ArbitrationLost), now);
        }
    }

    fn push_record(&mut self, mut rec: BusRecord) {
        if !self.cfg.record_wire {
            rec.wire = Vec::new();
        }
        if let Some(k) = self.lost.iter().position(|&t| t == rec.txn) {
            self.lost.swap_remove(k);
            rec.faults.push(LOST_NOTE.to_string());
            self.stats.lost_transfers += 1;
        }
        self.closed_txn = Some(rec.txn);
        self.stats.busy_ns = self.stats.busy_ns.saturating_add(rec.duration_ns());
        if let Some(sink) = self.sink.as_mut() {
            sink(&rec);
        }
        let failed = rec.outcome != Outcome::Ok;
        if !(self.cfg.keep_clean_records
            || !rec.faults.is_empty()
            || self.cfg.keep_records_to == Some(rec.addr)
            || (self.cfg.keep_failed_records && failed))
        {
            return;
        }
        if self.records.len() < self.cfg.record_cap {
            self.records.push(rec);
            return;
        }
        self.stats.records_dropped += 1;
        if failed && rec.faults.is_empty() {
            match rec.target {
                Some(_) => self.dropped.answered += 1,
                None => {
                    let i = usize::from(rec.addr & 0x7f);
                    if self.dropped.unanswered.len() <= i {
                        self.dropped.unanswered.resize(i + 1, 0);
                    }
                    if let Some(n) = self.dropped.unanswered.get_mut(i) {
                        *n += 1;
                    }
                }
            }
        }
    }

    /// The `listen` future of `node` was dropped: a transfer it had started receiving is lost
    /// (counted when it ends on the wire), one received but not returned yet is lost now.
    fn listen_dropped(&mut self, node: NodeId) {
        let Some(n) = self.nodes.get_mut(node) else {
            return;
        };
        n.listen_cap = None;
        if let Some(txn) = n.receiving.take() {
            n.discard = Some(txn);
            return;
        }
        let Some(txn) = n.inbox.front().map(|d| d.txn) else {
            return;
        };
        n.inbox.retain(|d| d.txn != txn);
        self.count_lost(txn);
    }

    /// Counts `txn` as lost once it has ended on the wire (a transfer cut only by the end of
    /// the simulation is not counted).
    fn count_lost(&mut self, txn: u64) {
        if let Some(rec) = self.records.iter_mut().rev().find(|r| r.txn == txn) {
            rec.faults.push(LOST_NOTE.to_string());
            self.stats.lost_transfers += 1;
        } else if self.closed_txn.is_some_and(|c| c >= txn) {
            // Ended, and its clean record was not kept.
            self.stats.lost_transfers += 1;
        } else {
            self.lost.push(txn);
        }
    }

    fn has_waiting(&self) -> bool {
        self.requests
            .values()
            .any(|r| matches!(r.state, ReqState::Waiting))
    }

    fn node_by_addr(&self, addr: u8) -> Option<NodeId> {
        match self.by_addr.get(usize::from(addr)) {
            Some(&(first, _)) => first,
            None => self.nodes.iter().position(|n| n.cfg.address == Some(addr)),
        }
    }

    /// How many nodes have target address `addr`.
    fn nodes_at(&self, addr: u8) -> usize {
        match self.by_addr.get(usize::from(addr)) {
            Some(&(_, n)) => n,
            None => self
                .nodes
                .iter()
                .filter(|n| n.cfg.address == Some(addr))
                .count(),
        }
    }

    /// Rebuilds [`BusInner::by_addr`] (after a node was added or changed its address).
    fn index_addresses(&mut self) {
        self.by_addr = vec![(None, 0); 128];
        for (i, n) in self.nodes.iter().enumerate() {
            if let Some(e) = n
                .cfg
                .address
                .and_then(|a| self.by_addr.get_mut(usize::from(a)))
            {
                e.0 = e.0.or(Some(i));
                e.1 += 1;
            }
        }
    }

    fn is_deaf(&self, node: NodeId, now: Nanos) -> bool {
        let Some(n) = self.nodes.get(node) else {
            return true;
        };
        if now < n.alive_from {
            return true;
        }
        match n.cfg.role {
            Role::DualRole => false,
            Role::SingleRole { .. } => n.controller_active || now < n.deaf_until,
        }
    }

    fn reset(&mut self, node: NodeId, now: Nanos, down_ns: Nanos) {
        self.restart(node, now, down_ns);
        if node < self.nodes.len() {
            self.stats.resets += 1;
        }
    }

    /// A reset that is not counted as one (a board that restarts at its new address).
    fn restart(&mut self, node: NodeId, now: Nanos, down_ns: Nanos) {
        if let Some(n) = self.nodes.get_mut(node) {
            n.alive_from = now.saturating_add(down_ns);
            n.generation += 1;
            n.inbox.clear();
            n.receiving = None;
            n.respond = match n.respond {
                RespondState::Awaiting { txn } | RespondState::Given { txn, .. } => {
                    RespondState::Expired { txn }
                }
                _ => RespondState::Idle,
            };
            n.wake();
        }
        self.wake_engine();
    }
}

/// The simulated bus. Cloning gives another handle to the same bus.
#[derive(Clone)]
pub struct SimBus {
    inner: Rc<RefCell<BusInner>>,
    clock: SimClock,
}

impl SimBus {
    /// A bus without nodes.
    pub fn new(clock: SimClock, cfg: BusConfig) -> SimBus {
        SimBus {
            inner: Rc::new(RefCell::new(BusInner {
                cfg,
                clock: clock.clone(),
                timing: cfg.speed.timing(),
                nodes: Vec::new(),
                requests: BTreeMap::new(),
                next_req: 0,
                next_txn: 0,
                free_at: 0,
                engine_waker: None,
                rng: Rng::new(cfg.seed ^ 0x05ee_db05),
                records: Vec::new(),
                yields: Vec::new(),
                dropped: DroppedFailures::default(),
                by_addr: vec![(None, 0); 128],
                sink: None,
                lost: Vec::new(),
                stats: BusStats::default(),
                closed_txn: None,
                rng_ext: Rng::new(cfg.seed ^ 0xb125_7f11_a6e5_0d3c),
                stuck: None,
            })),
            clock,
        }
    }

    /// The configuration.
    pub fn config(&self) -> BusConfig {
        self.inner.borrow().cfg
    }

    /// The clock the bus runs on.
    pub fn clock(&self) -> &SimClock {
        &self.clock
    }

    /// Adds a node and returns its id.
    pub fn add_node(&self, cfg: NodeConfig) -> NodeId {
        let mut b = self.inner.borrow_mut();
        b.nodes.push(Node {
            cfg,
            controller_active: false,
            deaf_until: 0,
            alive_from: 0,
            generation: 0,
            listen_cap: None,
            waiters: Vec::new(),
            inbox: VecDeque::new(),
            respond: RespondState::Idle,
            addressed: false,
            receiving: None,
            discard: None,
        });
        b.index_addresses();
        b.nodes.len() - 1
    }

    /// The node's configuration.
    pub fn node_config(&self, node: NodeId) -> Option<NodeConfig> {
        self.inner.borrow().nodes.get(node).map(|n| n.cfg.clone())
    }

    /// Name of a node (`?` for an unknown id).
    pub fn node_name(&self, node: NodeId) -> String {
        self.node_config(node)
            .map_or_else(|| "?".to_string(), |c| c.name)
    }

    /// The node's port: its handle to the bus as controller and target.
    pub fn port(&self, node: NodeId) -> SimPort {
        SimPort {
            bus: self.clone(),
            node,
        }
    }

    /// Transactions so far.
    pub fn records(&self) -> Vec<BusRecord> {
        self.inner.borrow().records.clone()
    }

    /// Calls `sink` with every transaction as it ends (its record as it is then: a lost
    /// transfer found out later is not in it), whether the bus keeps its record or not: a
    /// long run streams its record to a file this way.
    pub fn on_record(&self, sink: RecordSink) {
        self.inner.borrow_mut().sink = Some(sink);
    }

    /// Every transaction recorded, taken out of the bus (which keeps recording from none).
    pub fn take_records(&self) -> Vec<BusRecord> {
        std::mem::take(&mut self.inner.borrow_mut().records)
    }

    /// Failed transactions with no fault noted whose records were dropped at the
    /// [`BusConfig::record_cap`].
    pub fn dropped_failures(&self) -> DroppedFailures {
        self.inner.borrow().dropped.clone()
    }

    /// Number of transactions recorded so far.
    pub fn record_count(&self) -> usize {
        self.inner.borrow().records.len()
    }

    /// Transactions from index `from` on.
    pub fn records_from(&self, from: usize) -> Vec<BusRecord> {
        self.inner
            .borrow()
            .records
            .get(from..)
            .map(<[BusRecord]>::to_vec)
            .unwrap_or_default()
    }

    /// Controller calls given up so far because their node was being addressed.
    pub fn yields(&self) -> Vec<Yield> {
        self.inner.borrow().yields.clone()
    }

    /// Counters.
    pub fn stats(&self) -> BusStats {
        self.inner.borrow().stats
    }

    /// Resets `node` now: it NACKs everything for `down_ns`, loses its inbox, and every
    /// [`SimBus::wait_reset`] on it completes (the simulator restarts its firmware there).
    pub fn reset_node(&self, node: NodeId, down_ns: Nanos) {
        let now = self.clock.now_ns();
        self.inner.borrow_mut().reset(node, now, down_ns);
    }

    /// Powers `node` up only at `at_ns` (a board plugged in while the robot runs): until then
    /// it NACKs everything, as a reset node does, but nothing is counted as a reset. Call it
    /// before the node's firmware starts.
    pub fn power_on_at(&self, node: NodeId, at_ns: Nanos) {
        if let Some(n) = self.inner.borrow_mut().nodes.get_mut(node) {
            n.alive_from = at_ns;
        }
    }

    /// Restarts `node` now, as [`SimBus::reset_node`] with no time down, without counting a
    /// reset (a board that took a new address restarts itself).
    pub fn restart_node(&self, node: NodeId) {
        let now = self.clock.now_ns();
        self.inner.borrow_mut().restart(node, now, 0);
    }

    /// Changes the target address of `node` (a board that took a new address and started
    /// again there). Several nodes may share an address: a write goes to every one of them
    /// (see the module docs), a read to the first.
    pub fn set_node_address(&self, node: NodeId, address: Option<u8>) {
        let mut b = self.inner.borrow_mut();
        if let Some(n) = b.nodes.get_mut(node) {
            n.cfg.address = address;
        }
        b.index_addresses();
    }

    /// How many times `node` was reset.
    pub fn reset_generation(&self, node: NodeId) -> u64 {
        self.inner
            .borrow()
            .nodes
            .get(node)
            .map_or(0, |n| n.generation)
    }

    /// Time from which a reset node answers again (ns).
    pub fn alive_from(&self, node: NodeId) -> Nanos {
        self.inner
            .borrow()
            .nodes
            .get(node)
            .map_or(0, |n| n.alive_from)
    }

    /// Completes once `node` has been reset more than `generation` times.
    pub async fn wait_reset(&self, node: NodeId, generation: u64) {
        poll_fn(|cx| {
            let mut b = self.inner.borrow_mut();
            match b.nodes.get_mut(node) {
                Some(n) if n.generation > generation => Poll::Ready(()),
                Some(n) => {
                    register(&mut n.waiters, cx.waker());
                    Poll::Pending
                }
                None => Poll::Pending,
            }
        })
        .await
    }

    /// The line stuck now, if any, and until when it stays stuck unless recovered (ns).
    pub fn stuck(&self) -> Option<(Line, Nanos)> {
        let now = self.clock.now_ns();
        self.inner
            .borrow()
            .stuck
            .filter(|s| s.until > now)
            .map(|s| (s.line, s.until))
    }

    /// The standard bus recovery (I2C spec 3.1.16, SMBus): a master that finds SDA held low
    /// clocks SCL until the target holding it lets go (at most 9 clocks), then sends a STOP.
    /// The target injected with [`FaultConfig::stuck_ppm`] lets go after a number of clocks
    /// drawn at the fault (1 to 9, from the seed); the bus is free after the STOP and `t_BUF`.
    /// Takes the wire time of the clocks and the STOP.
    ///
    /// The `MultiMaster` trait the runtimes use has no recovery: nothing calls this but
    /// tests and harnesses, and a runtime's calls wait for the stuck line to let go by itself
    /// ([`FaultConfig::stuck_ns`]) or time out.
    ///
    /// # Errors
    /// [`BusError::Bus`] at once when SCL is the stuck line: clocking cannot free it.
    pub async fn recover(&self) -> Result<Recovery, BusError> {
        let now = self.clock.now_ns();
        let end = {
            let mut b = self.inner.borrow_mut();
            let t = b.timing;
            let Some(stuck) = b.stuck.filter(|s| s.until > now) else {
                return Ok(Recovery::NotStuck);
            };
            if stuck.line == Line::Scl {
                return Err(BusError::Bus);
            }
            let clocks = stuck.release_clocks.clamp(1, 9);
            let end = now + Nanos::from(clocks) * t.bit_ns + t.stop_ns();
            if end < stuck.until {
                b.stats.stuck_ns -= stuck.until - end;
                b.stats.recoveries += 1;
                b.stuck = Some(StuckLine {
                    until: end,
                    ..stuck
                });
                b.free_at = end + t.buf_ns;
                if let Some(rec) = b.records.iter_mut().rev().find(|r| r.txn == stuck.txn) {
                    rec.end_ns = end;
                    rec.faults
                        .push(format!("recovered: SDA released after {clocks} clocks"));
                    if let Some((_, WireSym::Stuck { until })) = rec.wire.first_mut() {
                        *until = end;
                    }
                }
                b.wake_engine();
            }
            (end.min(stuck.until), clocks)
        };
        let (at, clocks) = end;
        self.clock.sleep_until_ns(at).await;
        Ok(Recovery::Released { clocks })
    }

    /// The engine: plays every transaction on the wire. Spawn it once, before the nodes' tasks.
    pub fn engine(&self) -> impl Future<Output = ()> + 'static {
        let bus = self.clone();
        async move { bus.run_engine().await }
    }

    /// Waits until `cond` holds (true) or `deadline` passes (false); the engine's only wait.
    async fn wait_until(
        &self,
        deadline: Nanos,
        mut cond: impl FnMut(&mut BusInner) -> bool,
    ) -> bool {
        // One timer for the whole wait, however often the engine is woken before it.
        let mut timeout = std::pin::pin!(self.clock.sleep_until_ns(deadline));
        loop {
            if cond(&mut self.inner.borrow_mut()) {
                return true;
            }
            if self.clock.now_ns() >= deadline {
                return false;
            }
            let inner = &self.inner;
            let notified = WakeOnce::new(|w: &Waker| {
                inner.borrow_mut().engine_waker = Some(w.clone());
            });
            if deadline == Nanos::MAX {
                notified.await;
            } else {
                select(timeout.as_mut(), notified).await;
            }
        }
    }

    async fn run_engine(&self) {
        loop {
            self.wait_until(Nanos::MAX, |b| b.has_waiting()).await;
            if !self.wait_bus_free().await {
                continue;
            }
            self.transaction().await;
        }
    }

    /// Waits for the bus to be free with requests still waiting; times out requests that
    /// waited too long. False when no request is left.
    async fn wait_bus_free(&self) -> bool {
        loop {
            let now = self.clock.now_ns();
            let wake_at = {
                let mut b = self.inner.borrow_mut();
                let busy_timeout = b.cfg.busy_timeout_ns;
                let free_at = b.free_at;
                if now >= free_at {
                    return b.has_waiting();
                }
                let expired: Vec<u64> = b
                    .requests
                    .iter()
                    .filter(|(_, r)| {
                        matches!(r.state, ReqState::Waiting)
                            && r.registered.saturating_add(busy_timeout) <= now
                    })
                    .map(|(&id, _)| id)
                    .collect();
                for id in expired {
                    b.stats.timeouts += 1;
                    b.finish(id, Err(BusError::Timeout), now);
                }
                let earliest = b
                    .requests
                    .values()
                    .filter(|r| matches!(r.state, ReqState::Waiting))
                    .map(|r| r.registered.saturating_add(busy_timeout))
                    .min();
                match earliest {
                    None => return false,
                    Some(e) => e.min(free_at),
                }
            };
            // A recovery ([`SimBus::recover`]) can free the bus earlier: it wakes the engine.
            let inner = &self.inner;
            let notified = WakeOnce::new(|w: &Waker| {
                inner.borrow_mut().engine_waker = Some(w.clone());
            });
            select(self.clock.sleep_until_ns(wake_at), notified).await;
        }
    }

    /// Ends the transaction: STOP at `stop_at`, the winner's result, losers still in the
    /// race get `others`, the record is stored. Returns the end of STOP.
    fn close(
        &self,
        mut rec: BusRecord,
        stop_at: Nanos,
        win: (u64, Result<Vec<u8>, BusError>),
        others: &[(u64, usize)],
        others_result: BusError,
    ) -> Nanos {
        let t = self.inner.borrow().timing;
        if self.inner.borrow().cfg.record_wire || !rec.wire.is_empty() {
            rec.wire.push((stop_at, WireSym::Stop));
        }
        let end = stop_at + t.stop_ns();
        rec.end_ns = end;
        let mut b = self.inner.borrow_mut();
        match &win.1 {
            Err(BusError::Nack) => b.stats.nacks += 1,
            Err(BusError::Timeout) => b.stats.timeouts += 1,
            Err(BusError::Bus) => b.stats.bus_faults += 1,
            _ => {}
        }
        b.finish(win.0, win.1, end);
        for &(id, _) in others {
            match others_result {
                BusError::Nack => b.stats.nacks += 1,
                BusError::Timeout => b.stats.timeouts += 1,
                _ => {}
            }
            b.finish(id, Err(others_result), end);
        }
        b.free_at = end + t.buf_ns;
        b.stats.transactions += 1;
        b.push_record(rec);
        end
    }

    /// Ends a transaction that failed with `outcome`, a NACK or a timeout: STOP at
    /// `stop_at`, the winner `win_id` and the losers still `racing` it get that error, the
    /// record is stored. Returns the end of STOP.
    fn fail(
        &self,
        mut rec: BusRecord,
        stop_at: Nanos,
        outcome: Outcome,
        win_id: u64,
        racing: &[(u64, usize)],
    ) -> Nanos {
        let error = if matches!(outcome, Outcome::Timeout) {
            BusError::Timeout
        } else {
            BusError::Nack
        };
        rec.outcome = outcome;
        self.close(rec, stop_at, (win_id, Err(error)), racing, error)
    }

    fn deliver(&self, node: NodeId, txn: u64, kind: DeliveryKind, bytes: Vec<u8>, ready_at: Nanos) {
        let mut b = self.inner.borrow_mut();
        if let Some(n) = b.nodes.get_mut(node) {
            if n.receiving == Some(txn) {
                n.receiving = None;
            }
            if n.discard == Some(txn) {
                n.discard = None;
                b.count_lost(txn);
                return;
            }
            n.inbox.push_back(Delivery {
                txn,
                kind,
                bytes,
                ready_at,
            });
            n.wake_at(&self.clock, ready_at);
        }
    }

    fn note_fault(&self, rec: &mut BusRecord, what: String) {
        rec.faults.push(what);
        self.inner.borrow_mut().stats.injected += 1;
    }

    #[allow(clippy::too_many_lines)]
    async fn transaction(&self) {
        // Without a waveform, the bits' times are counted, their symbols not stored.
        let wire_on = self.inner.borrow().cfg.record_wire;
        let t0 = self.clock.now_ns();
        // Contenders: every waiting request, in node order.
        let (t, faults, contenders, txn) = {
            let mut b = self.inner.borrow_mut();
            let mut c: Vec<Contender> = b
                .requests
                .iter()
                .filter(|(_, r)| matches!(r.state, ReqState::Waiting))
                .map(|(&id, r)| Contender {
                    id,
                    node: r.node,
                    addr: r.addr,
                    write: r.write.clone(),
                    read_len: r.read_len,
                })
                .collect();
            c.sort_by_key(|c| (c.node, c.id));
            for c in &c {
                if let Some(r) = b.requests.get_mut(&c.id) {
                    r.state = ReqState::InFlight;
                }
                if let Some(n) = b.nodes.get_mut(c.node) {
                    n.controller_active = true;
                }
            }
            let txn = b.next_txn;
            b.next_txn += 1;
            (b.timing, b.cfg.faults, c, txn)
        };
        let Some(first) = contenders.first() else {
            return;
        };
        let mut rec = BusRecord {
            txn,
            start_ns: t0,
            end_ns: t0,
            master: first.node,
            addr: first.addr,
            target: None,
            // The winner's, once arbitration has chosen it (the first's for a stuck line).
            written: Vec::new(),
            received: Vec::new(),
            is_read: first.read_len.is_some(),
            read: Vec::new(),
            outcome: Outcome::Ok,
            losers: Vec::new(),
            stretch_ns: 0,
            faults: Vec::new(),
            // The waveform's symbols, when one is kept (the record drops them otherwise).
            wire: if wire_on {
                vec![(t0, WireSym::Start)]
            } else {
                Vec::new()
            },
        };

        // Faults rolled at START, in a fixed order; those of the options from the second
        // generator. Then the scope: time window and board.
        let in_window = faults.in_window(t0);
        let (stuck, reset, nack_roll, corrupt_roll, ext) = {
            let mut b = self.inner.borrow_mut();
            let stuck = b.rng.chance_ppm(faults.stuck_ppm);
            let reset = if b.rng.chance_ppm(faults.reset_ppm) {
                let eligible: Vec<NodeId> = (0..b.nodes.len())
                    .filter(|&i| {
                        b.nodes.get(i).is_some_and(|n| {
                            n.cfg.resettable
                                && faults.only_address.is_none_or(|a| n.cfg.address == Some(a))
                        })
                    })
                    .collect();
                let k = b.rng.below(eligible.len() as u64) as usize;
                eligible.get(k).copied()
            } else {
                None
            };
            let nack = b.rng.chance_ppm(faults.nack_ppm).then(|| b.rng.next_u64());
            let corrupt = b
                .rng
                .chance_ppm(faults.corrupt_ppm)
                .then(|| b.rng.next_u64());
            let scl = b.rng_ext.chance_ppm(faults.stuck_scl_ppm);
            let flip = b
                .rng_ext
                .chance_ppm(faults.address_ppm)
                .then(|| b.rng_ext.below(7) as u8);
            let burst = (faults.burst_bits > 1 && corrupt.is_some()).then(|| b.rng_ext.next_u64());
            let release = stuck.then(|| 1 + b.rng_ext.below(9) as u8);
            let ext = ExtRolls {
                scl,
                flip,
                burst,
                release,
            };
            (stuck, reset, nack, corrupt, ext)
        };
        let scoped = |c: &Contender| {
            faults.only_address.is_none_or(|a| {
                c.addr == a
                    || self
                        .node_config(c.node)
                        .is_some_and(|n| n.address == Some(a))
            })
        };
        let line_scope = in_window && contenders.iter().any(scoped);
        if let Some(node) = reset.filter(|_| in_window) {
            let name = self.node_name(node);
            self.note_fault(&mut rec, format!("reset {name}"));
            self.inner.borrow_mut().reset(node, t0, faults.reset_ns);
        }
        let stuck_line = if stuck && line_scope {
            Some(Line::Sda)
        } else if ext.scl && line_scope {
            Some(Line::Scl)
        } else {
            None
        };
        if let Some(line) = stuck_line {
            let until = t0 + faults.stuck_ns.max(t.bit_ns);
            let (sym, outcome, error, at) = match line {
                Line::Sda => (
                    WireSym::Stuck { until },
                    Outcome::Bus,
                    BusError::Bus,
                    t0 + t.start_ns(),
                ),
                Line::Scl => (
                    WireSym::SclStuck { until },
                    Outcome::Timeout,
                    BusError::Timeout,
                    until.min(t0 + self.config().stretch_timeout_ns),
                ),
            };
            let name = if line == Line::Sda { "SDA" } else { "SCL" };
            self.note_fault(
                &mut rec,
                format!("{name} stuck low {} us", faults.stuck_ns / 1000),
            );
            rec.wire = vec![(t0, sym)];
            rec.written = first.write.clone();
            rec.outcome = outcome;
            rec.end_ns = until;
            let mut b = self.inner.borrow_mut();
            match error {
                BusError::Bus => b.stats.bus_faults += contenders.len() as u64,
                _ => b.stats.timeouts += contenders.len() as u64,
            }
            for c in &contenders {
                b.finish(c.id, Err(error), at);
            }
            b.free_at = until + t.buf_ns;
            b.stuck = Some(StuckLine {
                line,
                from: t0,
                until,
                release_clocks: ext.release.unwrap_or(9),
                txn,
            });
            b.stats.stuck += 1;
            b.stats.stuck_ns += until - t0;
            b.stats.transactions += 1;
            b.push_record(rec);
            return;
        }

        // Arbitration, bit by bit over address and data.
        let (win_idx, lost_at) = arbitrate(&contenders);
        let Some(winner) = contenders.get(win_idx).cloned() else {
            return;
        };
        rec.master = winner.node;
        rec.addr = winner.addr;
        rec.is_read = winner.read_len.is_some();
        // Outside the scope, the rolled NACK, corruption and address flip are dropped.
        let in_scope = in_window && scoped(&winner);
        let (nack_roll, corrupt_roll, flip) = if in_scope {
            (nack_roll, corrupt_roll, ext.flip)
        } else {
            (None, None, None)
        };
        let mut losers: Vec<(u64, usize)> = Vec::new();
        for (c, lost) in contenders.iter().zip(&lost_at) {
            if let Some(bit) = *lost {
                rec.losers.push(Loser {
                    node: c.node,
                    addr: c.addr,
                    write: c.write.clone(),
                    bit,
                });
                losers.push((c.id, bit));
            }
        }
        let first_bit_at = t0 + t.start_ns();
        // A loser ends at the end of the bit it lost on.
        let loser_end = |bit: usize, data_start: Nanos| -> Nanos {
            if bit < 8 {
                first_bit_at + (bit as Nanos + 1) * t.bit_ns
            } else {
                let k = bit - 8;
                data_start + ((k / 8) * 9 + k % 8 + 1) as Nanos * t.bit_ns
            }
        };
        {
            let mut b = self.inner.borrow_mut();
            for &(id, bit) in &losers {
                if bit < 8 {
                    b.stats.arbitration_lost += 1;
                    b.finish(id, Err(BusError::ArbitrationLost), loser_end(bit, 0));
                }
            }
        }
        let mut racing: Vec<(u64, usize)> =
            losers.iter().copied().filter(|&(_, b)| b >= 8).collect();

        let Contender {
            id: win_id,
            node: win_node,
            addr,
            write,
            read_len,
        } = winner;
        rec.written.clone_from(&write);
        let plain_read = write.is_empty() && read_len.is_some();
        // The address the targets see (one bit flipped by an injected fault).
        let seen_addr = flip.map_or(addr, |bit| addr ^ (1 << bit));
        if seen_addr != addr {
            self.note_fault(
                &mut rec,
                format!("address {addr:#04x} seen as {seen_addr:#04x}"),
            );
        }
        let mut cursor = first_bit_at;
        push_byte(
            wire_on,
            &mut rec.wire,
            &mut cursor,
            (seen_addr << 1) | u8::from(plain_read),
            t,
        );

        // Address acknowledge, decided at the ACK bit.
        self.clock.sleep_until_ns(cursor).await;
        let (target, refused, co_targets) = {
            let b = self.inner.borrow();
            // A general call (a write to 0x00) is taken by every node that listens to it and
            // is not deaf now: the first is the target, the others receive it alongside.
            let general = seen_addr == 0 && read_len.is_none();
            let target = if general {
                (0..b.nodes.len()).find(|&i| {
                    i != win_node
                        && b.nodes.get(i).is_some_and(|n| n.listens_at(0))
                        && !b.is_deaf(i, cursor)
                })
            } else {
                b.node_by_addr(seen_addr)
            };
            let refused = match target {
                None => true,
                Some(n) => n == win_node || b.is_deaf(n, cursor),
            };
            // Other nodes at the same address (unaddressed boards at 0x77, two boards built
            // with one address) acknowledge a plain write too and each receive it; a read
            // is answered by the first alone (on a real bus their answers would mix, bit by
            // bit, and the check refuse them).
            let co: Vec<NodeId> =
                if refused || read_len.is_some() || (!general && b.nodes_at(seen_addr) < 2) {
                    Vec::new()
                } else {
                    b.nodes
                        .iter()
                        .enumerate()
                        .filter(|(i, n)| {
                            Some(*i) != target
                                && *i != win_node
                                && n.listens_at(seen_addr)
                                && !b.is_deaf(*i, cursor)
                        })
                        .map(|(i, _)| i)
                        .collect()
                };
            (target, refused, co)
        };
        rec.target = target;
        // Injected NACK: on the address (index 0) or a written data byte.
        let injected_nack = nack_roll.map(|r| (r % (write.len() as u64 + 1)) as usize);
        if injected_nack == Some(0) && !refused {
            self.note_fault(&mut rec, "NACK address".to_string());
        }
        let (Some(target), false) = (target, refused || injected_nack == Some(0)) else {
            push_bit(wire_on, &mut rec.wire, &mut cursor, true, t);
            self.fail(rec, cursor, Outcome::Nack { byte: 0 }, win_id, &racing);
            return;
        };
        push_bit(wire_on, &mut rec.wire, &mut cursor, false, t);

        // Stretch until the target has a listener (or went away).
        self.clock.sleep_until_ns(cursor).await;
        let stretch_deadline = cursor.saturating_add(self.config().stretch_timeout_ns);
        let clock = self.clock.clone();
        for &t in std::iter::once(&target).chain(&co_targets) {
            if let Some(n) = self.inner.borrow_mut().nodes.get_mut(t) {
                // `addressed` returns now; the transfer waits for `listen`.
                n.addressed = true;
                n.wake();
            }
        }
        let armed = self
            .wait_until(stretch_deadline, |b| {
                b.yield_requests_of(target, clock.now_ns());
                for &t in &co_targets {
                    b.yield_requests_of(t, clock.now_ns());
                }
                std::iter::once(&target).chain(&co_targets).all(|&t| {
                    b.nodes
                        .get(t)
                        .is_none_or(|n| n.listen_cap.is_some() || n.alive_from > cursor)
                })
            })
            .await;
        let now = self.clock.now_ns();
        rec.stretch_ns = now.saturating_sub(cursor);
        cursor = now;
        for &t in std::iter::once(&target).chain(&co_targets) {
            if let Some(n) = self.inner.borrow_mut().nodes.get_mut(t) {
                n.addressed = false;
            }
        }
        if !armed {
            self.fail(rec, cursor, Outcome::Timeout, win_id, &racing);
            return;
        }
        let (cap, gone) = {
            let mut b = self.inner.borrow_mut();
            let n = b.nodes.get_mut(target);
            let gone = n.as_ref().is_none_or(|n| n.alive_from > now);
            let cap = n.as_ref().and_then(|n| n.listen_cap).unwrap_or(0);
            if let Some(n) = n.filter(|_| !gone) {
                // From here on the transfer belongs to the armed `listen`.
                n.receiving = Some(txn);
            }
            for &t in &co_targets {
                if let Some(n) = b.nodes.get_mut(t).filter(|n| n.alive_from <= now) {
                    n.receiving = Some(txn);
                }
            }
            (cap, gone)
        };
        let data_start = cursor;

        // Corruption: a burst from one bit of one byte of the data part (written, then read),
        // as a mask of flipped bits per data byte.
        let data_len = write.len() + read_len.unwrap_or(0);
        let corrupt = corrupt_roll.and_then(|r| {
            (data_len > 0).then(|| ((r % data_len as u64) as usize, ((r >> 32) % 8) as u8))
        });
        // Empty (no byte flipped) unless a corruption was rolled.
        let mut mask = Vec::new();
        let mut burst_note = None;
        if let Some((k, bit)) = corrupt {
            mask = vec![0u8; data_len];
            let len = burst_mask(&mut mask, k, bit, faults.burst_bits, ext.burst);
            if faults.burst_bits > 1 {
                let flipped: u32 = mask.iter().map(|m| m.count_ones()).sum();
                burst_note = Some(format!(
                    "burst of {len} bits from data byte {k} bit {bit}: {flipped} flipped"
                ));
            }
        }
        let mut corrupt_noted = false;
        let mut note_corrupt = |bus: &SimBus, rec: &mut BusRecord, what: &str, i: usize, m: u8| {
            if m != 0 && !corrupt_noted {
                corrupt_noted = true;
                let text = burst_note.clone().map_or_else(
                    || format!("corrupt {what} byte {i} bit {}", m.trailing_zeros()),
                    |b| format!("corrupt {b}"),
                );
                bus.note_fault(rec, text);
            }
        };

        // Write phase: bytes until the end, an overrun, a reset target or an injected NACK.
        let overrun_at = (write.len() > cap && !gone).then_some(cap);
        let refused_at = gone.then_some(0);
        let data_nack = injected_nack.filter(|&k| k > 0).map(|k| k - 1);
        let nack_at = [overrun_at, refused_at, data_nack]
            .into_iter()
            .flatten()
            .min();
        let mut received = Vec::new();
        for (i, &byte) in write.iter().enumerate() {
            push_byte(wire_on, &mut rec.wire, &mut cursor, byte, t);
            if nack_at == Some(i) {
                push_bit(wire_on, &mut rec.wire, &mut cursor, true, t);
                break;
            }
            let m = mask.get(i).copied().unwrap_or(0);
            note_corrupt(self, &mut rec, "written", i, m);
            let seen = byte ^ m;
            received.push(seen);
            push_bit(wire_on, &mut rec.wire, &mut cursor, false, t);
        }
        // Losers that lost on a byte that went out end now; those past a NACK see the NACK.
        let sent_bytes = nack_at.map_or(write.len(), |k| k + 1);
        {
            let mut b = self.inner.borrow_mut();
            racing.retain(|&(id, bit)| {
                if (bit - 8) / 8 < sent_bytes {
                    b.stats.arbitration_lost += 1;
                    b.finish(
                        id,
                        Err(BusError::ArbitrationLost),
                        loser_end(bit, data_start),
                    );
                    false
                } else {
                    true
                }
            });
        }
        rec.received = received.clone();
        if let Some(k) = nack_at {
            let kind = if overrun_at == Some(k) {
                DeliveryKind::Overrun
            } else {
                if data_nack == Some(k) && refused_at != Some(k) {
                    self.note_fault(&mut rec, format!("NACK data byte {k}"));
                }
                DeliveryKind::Write
            };
            let end = self.fail(rec, cursor, Outcome::Nack { byte: k + 1 }, win_id, &racing);
            for &t in &co_targets {
                self.deliver(t, txn, kind, received.clone(), end);
            }
            if !gone {
                self.deliver(target, txn, kind, received, end);
            }
            return;
        }

        let Some(read_len) = read_len else {
            // A plain write.
            let end = self.close(
                rec,
                cursor,
                (win_id, Ok(Vec::new())),
                &racing,
                BusError::Nack,
            );
            for &t in &co_targets {
                self.deliver(t, txn, DeliveryKind::Write, received.clone(), end);
            }
            self.deliver(target, txn, DeliveryKind::Write, received, end);
            return;
        };

        // Read phase: repeated START and address+R (unless it is a plain read).
        if !plain_read {
            if wire_on {
                rec.wire.push((cursor, WireSym::RepeatedStart));
            }
            cursor += t.repeated_start_ns();
            push_byte(wire_on, &mut rec.wire, &mut cursor, (seen_addr << 1) | 1, t);
            if self.inner.borrow().is_deaf(target, cursor) {
                if let Some(n) = self.inner.borrow_mut().nodes.get_mut(target) {
                    if n.receiving == Some(txn) {
                        n.receiving = None;
                    }
                }
                push_bit(wire_on, &mut rec.wire, &mut cursor, true, t);
                let outcome = Outcome::Nack {
                    byte: write.len() + 1,
                };
                self.fail(rec, cursor, outcome, win_id, &racing);
                return;
            }
            push_bit(wire_on, &mut rec.wire, &mut cursor, false, t);
        }
        self.deliver(
            target,
            txn,
            if plain_read {
                DeliveryKind::Read
            } else {
                DeliveryKind::WriteRead
            },
            received,
            cursor,
        );
        if let Some(n) = self.inner.borrow_mut().nodes.get_mut(target) {
            n.respond = RespondState::Awaiting { txn };
        }
        // Stretch until the target responds (or is reset, which releases the lines).
        self.clock.sleep_until_ns(cursor).await;
        let deadline = cursor.saturating_add(self.config().stretch_timeout_ns);
        let answered = self
            .wait_until(deadline, |b| {
                b.yield_requests_of(target, clock.now_ns());
                b.nodes.get(target).is_none_or(|n| match &n.respond {
                    RespondState::Given { txn: x, .. } | RespondState::Expired { txn: x } => {
                        *x == txn
                    }
                    _ => false,
                })
            })
            .await;
        let now = self.clock.now_ns();
        rec.stretch_ns += now.saturating_sub(cursor);
        cursor = now;
        let reply = {
            let mut b = self.inner.borrow_mut();
            match b.nodes.get_mut(target) {
                Some(n) if answered => match &n.respond {
                    RespondState::Given { bytes, .. } => Some(bytes.clone()),
                    // Reset mid-read: SDA floats high, the master reads 0xFF.
                    _ => Some(Vec::new()),
                },
                Some(n) => {
                    if matches!(n.respond, RespondState::Awaiting { txn: x } if x == txn) {
                        n.respond = RespondState::Expired { txn };
                    }
                    n.wake();
                    None
                }
                None => None,
            }
        };
        let Some(reply) = reply else {
            self.fail(rec, cursor, Outcome::Timeout, win_id, &racing);
            return;
        };
        let mut read = Vec::with_capacity(read_len);
        for i in 0..read_len {
            let byte = reply.get(i).copied().unwrap_or(0xFF);
            let m = mask.get(write.len() + i).copied().unwrap_or(0);
            note_corrupt(self, &mut rec, "read", i, m);
            let seen = byte ^ m;
            push_byte(wire_on, &mut rec.wire, &mut cursor, seen, t);
            // The master ACKs every byte but the last.
            push_bit(wire_on, &mut rec.wire, &mut cursor, i + 1 == read_len, t);
            read.push(seen);
        }
        rec.read = read.clone();
        let end = self.close(rec, cursor, (win_id, Ok(read)), &racing, BusError::Nack);
        let mut b = self.inner.borrow_mut();
        if let Some(n) = b.nodes.get_mut(target) {
            if matches!(&n.respond, RespondState::Given { txn: x, .. } if *x == txn) {
                n.respond = RespondState::Done { txn, at: end };
                // `respond` sleeps until the end of STOP once it sees this: it is woken then.
                n.wake_at(&self.clock, end);
            } else {
                n.wake();
            }
        }
    }
}

/// Flips a burst into `mask` (one byte per data byte): from bit `bit` (0 = LSB) of byte
/// `byte`, `burst_bits` bits along the wire (MSB first; at least 1, at most 64), the first and
/// the last flipped, those between by the bits of `inner` (bit 0 first). Clipped at the end
/// of the data. Returns the burst's length.
fn burst_mask(mask: &mut [u8], byte: usize, bit: u8, burst_bits: u8, inner: Option<u64>) -> usize {
    let len = usize::from(burst_bits.clamp(1, 64));
    let start = byte * 8 + usize::from(7 - bit.min(7));
    let mut inner = inner.unwrap_or(0);
    for j in 0..len {
        let flip = if j == 0 || j + 1 == len {
            true
        } else {
            let f = inner & 1 == 1;
            inner >>= 1;
            f
        };
        let s = start + j;
        if let (true, Some(m)) = (flip, mask.get_mut(s / 8)) {
            *m ^= 0x80 >> (s % 8);
        }
    }
    len
}

#[derive(Clone, Debug)]
struct Contender {
    id: u64,
    node: NodeId,
    addr: u8,
    write: Vec<u8>,
    read_len: Option<usize>,
}

/// Wired-AND arbitration over the address byte and the written bytes. Returns the winner's
/// index and, per contender, the stream bit (0 = address MSB) where it lost.
fn arbitrate(contenders: &[Contender]) -> (usize, Vec<Option<usize>>) {
    if contenders.len() < 2 {
        // Alone on the bus (the usual case): nothing to compare.
        return (0, vec![None; contenders.len()]);
    }
    let streams: Vec<Vec<bool>> = contenders
        .iter()
        .map(|c| {
            let rw = u8::from(c.write.is_empty() && c.read_len.is_some());
            std::iter::once((c.addr << 1) | rw)
                .chain(c.write.iter().copied())
                .flat_map(|b| (0..8).rev().map(move |i| (b >> i) & 1 == 1))
                .collect()
        })
        .collect();
    let mut alive: Vec<usize> = (0..contenders.len()).collect();
    let mut lost_at: Vec<Option<usize>> = vec![None; contenders.len()];
    let mut bit = 0usize;
    while alive.len() > 1 {
        let vals: Vec<Option<bool>> = alive
            .iter()
            .map(|&i| streams.get(i).and_then(|s| s.get(bit).copied()))
            .collect();
        if vals.iter().any(Option::is_none) {
            // A stream ended while the others agree so far: undefined by the spec; the
            // lowest node index wins, the others lose at this bit.
            for &i in alive.iter().skip(1) {
                if let Some(l) = lost_at.get_mut(i) {
                    *l = Some(bit);
                }
            }
            alive.truncate(1);
            break;
        }
        if vals.contains(&Some(false)) && vals.contains(&Some(true)) {
            let mut next = Vec::new();
            for (&i, v) in alive.iter().zip(&vals) {
                if *v == Some(true) {
                    if let Some(l) = lost_at.get_mut(i) {
                        *l = Some(bit);
                    }
                } else {
                    next.push(i);
                }
            }
            alive = next;
        }
        bit += 1;
    }
    (alive.first().copied().unwrap_or(0), lost_at)
}

/// Adds `w` to `wakers` unless it wakes the same task as one already there.
fn register(wakers: &mut Vec<Waker>, w: &Waker) {
    if !wakers.iter().any(|x| x.will_wake(w)) {
        wakers.push(w.clone());
    }
}

/// One byte's 8 bits (MSB first) from `cursor` on, stored in `wire` when `on`.
fn push_byte(on: bool, wire: &mut Vec<(Nanos, WireSym)>, cursor: &mut Nanos, byte: u8, t: Timing) {
    if !on {
        *cursor += 8 * t.bit_ns;
        return;
    }
    for i in (0..8).rev() {
        push_bit(on, wire, cursor, (byte >> i) & 1 == 1, t);
    }
}

/// One bit (an ACK is a 0 bit, a NACK a 1 bit) at `cursor`, stored in `wire` when `on`.
fn push_bit(
    on: bool,
    wire: &mut Vec<(Nanos, WireSym)>,
    cursor: &mut Nanos,
    value: bool,
    t: Timing,
) {
    if on {
        wire.push((*cursor, WireSym::Bit { value }));
    }
    *cursor += t.bit_ns;
}

/// Completes on its second poll; on the first it hands the task's waker to `register` (the
/// engine's waker slot, or a node's waiters) and yields.
struct WakeOnce<F: FnMut(&Waker)> {
    register: F,
    armed: bool,
}

impl<F: FnMut(&Waker)> WakeOnce<F> {
    fn new(register: F) -> Self {
        WakeOnce {
            register,
            armed: false,
        }
    }
}

impl<F: FnMut(&Waker) + Unpin> Future for WakeOnce<F> {
    type Output = ();

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        if self.armed {
            return Poll::Ready(());
        }
        self.armed = true;
        (self.register)(cx.waker());
        Poll::Pending
    }
}

/// A node's handle to the bus: [`MultiMaster`] as controller and target.
pub struct SimPort {
    bus: SimBus,
    node: NodeId,
}

impl SimPort {
    /// This port's node.
    pub fn node(&self) -> NodeId {
        self.node
    }

    /// The bus.
    pub fn bus(&self) -> &SimBus {
        &self.bus
    }

    /// `listen` without its guard.
    async fn receive(&self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let inner = &self.bus.inner;
        let clock = &self.bus.clock;
        let node = self.node;
        loop {
            let next_ready = {
                let mut b = inner.borrow_mut();
                let now = clock.now_ns();
                let alive = b.nodes.get(node).is_some_and(|n| n.alive_from <= now);
                let Some(n) = b.nodes.get_mut(node) else {
                    return Err(BusError::Bus);
                };
                let cap = alive.then_some(buf.len());
                let newly_armed = n.listen_cap.is_none() && cap.is_some();
                n.listen_cap = cap;
                if newly_armed && n.addressed {
                    // Tell the engine, stretching the clock for this node's listener, that
                    // it is here (its other waits do not look at listeners).
                    b.wake_engine();
                }
                let Some(n) = b.nodes.get_mut(node) else {
                    return Err(BusError::Bus);
                };
                match n.inbox.front() {
                    Some(d) if d.ready_at <= now => {
                        let Some(d) = n.inbox.pop_front() else {
                            return Err(BusError::Bus);
                        };
                        n.listen_cap = None;
                        let len = d.bytes.len();
                        let Some(dst) = buf.get_mut(..len) else {
                            return Err(BusError::Overrun);
                        };
                        dst.copy_from_slice(&d.bytes);
                        return match d.kind {
                            DeliveryKind::Write => Ok(Incoming::Write(len)),
                            DeliveryKind::WriteRead => Ok(Incoming::WriteRead(len)),
                            DeliveryKind::Read => Ok(Incoming::Read),
                            DeliveryKind::Overrun => Err(BusError::Overrun),
                        };
                    }
                    Some(d) => Some(d.ready_at),
                    None => (!alive).then(|| b.nodes.get(node).map_or(0, |n| n.alive_from)),
                }
            };
            let wait = WakeOnce::new(|w: &Waker| {
                if let Some(n) = inner.borrow_mut().nodes.get_mut(node) {
                    register(&mut n.waiters, w);
                }
            });
            match next_ready {
                Some(at) => {
                    select(clock.sleep_until_ns(at), wait).await;
                }
                None => wait.await,
            }
        }
    }

    async fn transact(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: Option<&mut [u8]>,
    ) -> Result<(), BusError> {
        let inner = &self.bus.inner;
        let clock = &self.bus.clock;
        let _call = ControllerCall {
            inner,
            clock,
            node: self.node,
        };
        let id = {
            let mut b = inner.borrow_mut();
            let id = b.next_req;
            b.next_req += 1;
            b.requests.insert(
                id,
                Request {
                    node: self.node,
                    addr: addr & 0x7f,
                    write: bytes.to_vec(),
                    read_len: read.as_ref().map(|r| r.len()),
                    registered: clock.now_ns(),
                    state: ReqState::Waiting,
                    waker: None,
                },
            );
            b.wake_engine();
            id
        };
        let guard = RequestGuard { inner, id };
        let (result, at) = poll_fn(|cx| {
            let mut b = inner.borrow_mut();
            let Some(r) = b.requests.get_mut(&id) else {
                return Poll::Ready((Err(BusError::Bus), 0));
            };
            if matches!(r.state, ReqState::Done { .. }) {
                let Some(done) = b.requests.remove(&id) else {
                    return Poll::Ready((Err(BusError::Bus), 0));
                };
                match done.state {
                    ReqState::Done { result, at } => Poll::Ready((result, at)),
                    _ => Poll::Ready((Err(BusError::Bus), 0)),
                }
            } else {
                r.waker = Some(cx.waker().clone());
                Poll::Pending
            }
        })
        .await;
        drop(guard);
        clock.sleep_until_ns(at).await;
        let data = result?;
        if let Some(read) = read {
            for (dst, src) in read
                .iter_mut()
                .zip(data.iter().chain(std::iter::repeat(&0xFF)))
            {
                *dst = *src;
            }
        }
        Ok(())
    }
}

/// Ends a node's controller window when its call returns: a single-role node that took part
/// in a transaction stays deaf for its role-switch time after that.
struct ControllerCall<'a> {
    inner: &'a Rc<RefCell<BusInner>>,
    clock: &'a SimClock,
    node: NodeId,
}

impl Drop for ControllerCall<'_> {
    fn drop(&mut self) {
        let now = self.clock.now_ns();
        if let Ok(mut b) = self.inner.try_borrow_mut() {
            if let Some(n) = b.nodes.get_mut(self.node) {
                if n.controller_active {
                    n.controller_active = false;
                    if let Role::SingleRole { switch_ns } = n.cfg.role {
                        n.deaf_until = now.saturating_add(switch_ns);
                    }
                }
            }
        }
    }
}

/// Withdraws a request whose caller went away (a started transaction plays out on the wire).
struct RequestGuard<'a> {
    inner: &'a Rc<RefCell<BusInner>>,
    id: u64,
}

impl Drop for RequestGuard<'_> {
    fn drop(&mut self) {
        if let Ok(mut b) = self.inner.try_borrow_mut() {
            let remove = match b.requests.get(&self.id) {
                Some(r) => !matches!(r.state, ReqState::InFlight),
                None => false,
            };
            if remove {
                b.requests.remove(&self.id);
            } else if let Some(r) = b.requests.get_mut(&self.id) {
                // In flight: the engine finishes it; nobody collects the result.
                r.waker = None;
            }
        }
    }
}

/// Arms a node's target side for the listen future's lifetime; dropped before `done`, it
/// loses the transfer the future had started to receive.
struct ListenGuard<'a> {
    inner: &'a Rc<RefCell<BusInner>>,
    node: NodeId,
    done: bool,
}

impl Drop for ListenGuard<'_> {
    fn drop(&mut self) {
        if let Ok(mut b) = self.inner.try_borrow_mut() {
            if self.done {
                if let Some(n) = b.nodes.get_mut(self.node) {
                    n.listen_cap = None;
                }
            } else {
                b.listen_dropped(self.node);
            }
        }
    }
}

impl MultiMaster for SimPort {
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError> {
        self.transact(addr, bytes, None).await
    }

    async fn write_read(
        &mut self,
        addr: u8,
        bytes: &[u8],
        read: &mut [u8],
    ) -> Result<(), BusError> {
        self.transact(addr, bytes, Some(read)).await
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        let inner = &self.bus.inner;
        let node = self.node;
        poll_fn(|cx| {
            let mut b = inner.borrow_mut();
            let Some(n) = b.nodes.get_mut(node) else {
                return Poll::Ready(Err(BusError::Bus));
            };
            if n.addressed || !n.inbox.is_empty() {
                Poll::Ready(Ok(()))
            } else {
                register(&mut n.waiters, cx.waker());
                Poll::Pending
            }
        })
        .await
    }

    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError> {
        let this = &*self;
        let mut guard = ListenGuard {
            inner: &this.bus.inner,
            node: this.node,
            done: false,
        };
        let r = this.receive(buf).await;
        guard.done = true;
        r
    }

    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError> {
        let inner = &self.bus.inner;
        let clock = &self.bus.clock;
        let node = self.node;
        let txn = {
            let mut b = inner.borrow_mut();
            let Some(n) = b.nodes.get_mut(node) else {
                return Err(BusError::Bus);
            };
            match n.respond.clone() {
                RespondState::Awaiting { txn } => {
                    n.respond = RespondState::Given {
                        txn,
                        bytes: bytes.to_vec(),
                    };
                    b.wake_engine();
                    txn
                }
                RespondState::Expired { .. } => {
                    n.respond = RespondState::Idle;
                    return Err(BusError::Timeout);
                }
                _ => return Err(BusError::Bus),
            }
        };
        let (result, at) = poll_fn(|cx| {
            let mut b = inner.borrow_mut();
            let Some(n) = b.nodes.get_mut(node) else {
                return Poll::Ready((Err(BusError::Bus), 0));
            };
            match n.respond {
                RespondState::Done { txn: x, at } if x == txn => {
                    n.respond = RespondState::Idle;
                    Poll::Ready((Ok(()), at))
                }
                RespondState::Expired { txn: x } if x == txn => {
                    n.respond = RespondState::Idle;
                    Poll::Ready((Err(BusError::Timeout), 0))
                }
                RespondState::Given { txn: x, .. } if x == txn => {
                    register(&mut n.waiters, cx.waker());
                    Poll::Pending
                }
                _ => Poll::Ready((Err(BusError::Bus), 0)),
            }
        })
        .await;
        clock.sleep_until_ns(at).await;
        result
    }
}

#[cfg(test)]
#[path = "bus_tests.rs"]
mod tests;
