//! The failsafe keepalive: a daughterboard whose failsafe a robot program armed hears from the
//! motherboard at least every third of its timeout, even when the program sends nothing.
//!
//! A board's failsafe trips when no transaction has been addressed to it for its timeout. A
//! program that only sends on change (a motor command when the wanted speed changes) would
//! trip it although the motherboard is alive. So the motherboard remembers every failsafe a
//! program sets through its [`x10_devices::Link`] (`Op::SetFailsafe` with a non-zero timeout,
//! alone or in a batch, once the board accepted it) and, whenever nothing has been sent to
//! that board for a third of the timeout, sends it `Op::Heartbeat`. `SetFailsafe` 0 stops it.
//! When the board reports a `boot` event (it restarted, and its failsafe is off again), the
//! motherboard sends the same `SetFailsafe` again. Only a motherboard that stopped running
//! (or lost the bus) leaves the board silent for the full timeout, and then it trips.

use embassy_futures::join::join_array;
use embassy_futures::select::select;
use embassy_sync::signal::Signal;
use heapless::Vec;
use x10_devices::LinkError;
use x10_hal::time::Instant;
use x10_microcode::{Address, Op};

use crate::diag::{bump, MbDiagnostics};
use crate::motherboard::{now, sleep_until, MbCore, M};

/// Boards whose failsafe the motherboard keeps alive at the same time. A `SetFailsafe` with a
/// non-zero timeout to one more board is refused with `LinkError::Busy` before it is sent.
pub const MAX_KEEPALIVES: usize = 16;

/// Keepalives on their way at the same time (heartbeats or failsafes set again). Each worker
/// holds a whole call future (about 540 bytes on a Cortex-M0), and with more than one the
/// motherboard and a daughterboard no longer fit the 16 KiB of the QEMU Cortex-M0 suite, so
/// there is one: a keepalive waits for the one before it, which gives up after a sixth of its
/// board's failsafe timeout at most (an absent board costs only its NACK retries, about
/// 2.5 ms). Heartbeats are due at a third of the timeout, so a few silent boards cannot make a
/// live one's failsafe trip.
pub(crate) const KEEPALIVE_WORKERS: usize = 1;

/// One board's failsafe as the motherboard keeps it.
#[derive(Clone, Copy, Debug)]
struct Entry {
    board: Address,
    /// The timeout the board accepted (0: reserved by a `SetFailsafe` in flight, or stopped).
    timeout_ms: u16,
    /// When something was last sent to the board.
    last: Instant,
    /// No keepalive before this (after a failed attempt).
    not_before: Instant,
    /// The board rebooted: its failsafe must be set again.
    resend: bool,
    /// A keepalive to the board is on its way (taken by one worker).
    in_flight: bool,
}

/// What the keepalive task does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Next {
    /// Send `op` to `board` now, giving up after `timeout_us` (see [`keepalive_timeout_us`]).
    Send(Address, KeepaliveOp, u64),
    /// Nothing before this instant.
    At(Instant),
    /// No failsafe to keep alive.
    Idle,
}

/// How a keepalive attempt ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// The board acknowledged it.
    Sent,
    /// No free pending slot: nothing was sent.
    Busy,
    /// Sent, but it failed (NACK, timeout, bus error, refused).
    Failed,
}

/// Wait before another keepalive attempt when every pending slot was in use, in µs.
pub const BUSY_RETRY_US: u64 = 1_000;

/// What the keepalive sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum KeepaliveOp {
    Heartbeat,
    SetFailsafe(u16),
}

/// The failsafes being kept alive (part of the pending table, under its lock).
pub(crate) struct Keepalives {
    entries: Vec<Entry, MAX_KEEPALIVES>,
}

/// A third of `timeout_ms`, in µs.
fn interval_us(timeout_ms: u16) -> u64 {
    u64::from(timeout_ms) * 1_000 / 3
}

/// How long a keepalive to a board with failsafe `timeout_ms` may take in all (queueing and
/// bus retries): half the keepalive interval (a sixth of the failsafe), at most
/// `request_timeout_us`. A keepalive is a single write; one to a board that does not answer
/// gives up by then, and the dispatcher stops retrying it, so it holds the bus queue only
/// that long (and only its retries when they end sooner, as after NACKs with
/// `RetryPolicy::DEFAULT`).
pub(crate) fn keepalive_timeout_us(timeout_ms: u16, request_timeout_us: u64) -> u64 {
    (interval_us(timeout_ms) / 2).min(request_timeout_us)
}

impl Keepalives {
    pub(crate) const fn new() -> Keepalives {
        Keepalives {
            entries: Vec::new(),
        }
    }

    fn find(&mut self, board: Address) -> Option<&mut Entry> {
        self.entries.iter_mut().find(|e| e.board == board)
    }

    /// Makes room for a failsafe on `board` before a `SetFailsafe` to it is sent. Entries not
    /// in use (`timeout_ms` 0) are reused unless `in_flight(board)` says a `SetFailsafe` to
    /// that board is still pending.
    ///
    /// # Errors
    /// `()` when [`MAX_KEEPALIVES`] boards are kept alive or have a `SetFailsafe` in flight.
    pub(crate) fn reserve(
        &mut self,
        board: Address,
        now: Instant,
        in_flight: impl Fn(Address) -> bool,
    ) -> Result<(), ()> {
        if self.find(board).is_some() {
            return Ok(());
        }
        if self.entries.is_full() {
            let idle = self
                .entries
                .iter()
                .position(|e| e.timeout_ms == 0 && !in_flight(e.board));
            match idle {
                Some(i) => {
                    self.entries.swap_remove(i);
                }
                None => return Err(()),
            }
        }
        self.entries
            .push(Entry {
                board,
                timeout_ms: 0,
                last: now,
                not_before: now,
                resend: false,
                in_flight: false,
            })
            .map_err(|_| ())
    }

    /// The board accepted `SetFailsafe { timeout_ms }`: keep it alive (or stop, for 0).
    pub(crate) fn set(&mut self, board: Address, timeout_ms: u16) {
        if let Some(e) = self.find(board) {
            e.timeout_ms = timeout_ms;
            e.resend = false;
        }
    }

    /// True when `board` has an entry (a failsafe kept alive, reserved or stopped): only
    /// then does [`Keepalives::sent`] record anything.
    pub(crate) fn tracks(&self, board: Address) -> bool {
        self.entries.iter().any(|e| e.board == board)
    }

    /// Something was sent to `board` (a transaction it acknowledged) at `now`.
    pub(crate) fn sent(&mut self, board: Address, now: Instant) {
        if let Some(e) = self.find(board) {
            if now > e.last {
                e.last = now;
            }
        }
    }

    /// `board` rebooted. True when its failsafe must be set again.
    pub(crate) fn booted(&mut self, board: Address) -> bool {
        match self.find(board) {
            Some(e) if e.timeout_ms > 0 => {
                e.resend = true;
                true
            }
            _ => false,
        }
    }

    /// What to do at `now`: the board whose keepalive is due first (a re-send at once, a
    /// heartbeat a third of the timeout after the last transaction), or when to look again.
    /// Boards with a keepalive on its way are left out. A board returned in [`Next::Send`] is
    /// taken: it is left out too until [`Keepalives::done`].
    pub(crate) fn claim(&mut self, now: Instant, request_timeout_us: u64) -> Next {
        let due = self
            .entries
            .iter_mut()
            .filter(|e| e.timeout_ms > 0 && !e.in_flight)
            .map(|e| {
                let at = if e.resend {
                    e.not_before
                } else {
                    e.last.plus_us(interval_us(e.timeout_ms)).max(e.not_before)
                };
                (at, e)
            })
            .min_by_key(|(at, _)| *at);
        match due {
            None => Next::Idle,
            Some((at, e)) if at <= now => {
                e.in_flight = true;
                let op = if e.resend {
                    KeepaliveOp::SetFailsafe(e.timeout_ms)
                } else {
                    KeepaliveOp::Heartbeat
                };
                let timeout_us = keepalive_timeout_us(e.timeout_ms, request_timeout_us);
                Next::Send(e.board, op, timeout_us)
            }
            Some((at, _)) => Next::At(at),
        }
    }

    /// A keepalive to `board` ended at `now`: counted when it went through. When it failed
    /// the next try comes [`BUSY_RETRY_US`] later if there was no free pending slot
    /// (`busy`), else a third of the timeout later (a board that does not answer is not
    /// flooded); a re-send stays due until it succeeds.
    pub(crate) fn done(
        &mut self,
        board: Address,
        op: KeepaliveOp,
        outcome: Outcome,
        now: Instant,
        diag: &mut MbDiagnostics,
    ) {
        if let Some(e) = self.find(board) {
            e.in_flight = false;
        }
        if outcome == Outcome::Sent {
            // Already recorded by `sent` at the end of the transfer; this only guarantees
            // that the next one is never due at once.
            self.sent(board, now);
        }
        match (op, outcome) {
            (KeepaliveOp::Heartbeat, Outcome::Sent) => bump(&mut diag.keepalives),
            (KeepaliveOp::SetFailsafe(_), Outcome::Sent) => bump(&mut diag.failsafe_resends),
            (_, failed) => {
                bump(&mut diag.keepalive_failures);
                if let Some(e) = self.find(board) {
                    let wait = match failed {
                        Outcome::Busy => BUSY_RETRY_US,
                        _ => interval_us(e.timeout_ms),
                    };
                    e.not_before = now.plus_us(wait);
                }
            }
        }
    }

    /// The timeout kept alive for `board` (0: none).
    pub(crate) fn timeout_ms(&self, board: Address) -> u16 {
        self.entries
            .iter()
            .find(|e| e.board == board)
            .map_or(0, |e| e.timeout_ms)
    }
}

/// The last `set_failsafe` of an operation (or of a batch's items).
pub(crate) fn failsafe_change(op: &Op<'_>) -> Option<u16> {
    match op {
        Op::SetFailsafe { timeout_ms } => Some(*timeout_ms),
        Op::Batch(b) => b.iter().fold(None, |acc, item| match item {
            Op::SetFailsafe { timeout_ms } => Some(timeout_ms),
            _ => acc,
        }),
        _ => None,
    }
}

impl MbCore {
    /// The failsafe keepalive (see the module docs); never returns. Part of
    /// [`crate::Motherboard::run`].
    ///
    /// It sends through [`Motherboard::call_with_timeout`] like any robot task: a heartbeat
    /// takes a pending slot and a sequence number, and queues behind the requests already
    /// waiting. Keepalives go out one at a time (see `KEEPALIVE_WORKERS`); each gives up
    /// after half the board's keepalive interval (at most the request timeout), and the
    /// dispatcher then stops retrying it, so a board that does not answer holds back the
    /// heartbeats of the others by its NACK retries, or by that give-up time at most.
    /// Heartbeats sent are counted in [`MbDiagnostics::keepalives`], failsafes set again
    /// after a boot in [`MbDiagnostics::failsafe_resends`], failed attempts in
    /// [`MbDiagnostics::keepalive_failures`] (and in the request counters).
    pub async fn run_keepalive(&self) -> ! {
        let workers = self
            .keepalive_changed
            .each_ref()
            .map(|changed| self.keepalive_worker(changed));
        let [never, ..] = join_array(workers).await;
        never
    }

    /// One keepalive worker: takes the keepalive due first, sends it, and records how it
    /// ended; sleeps until the next one is due or `changed` is signalled.
    async fn keepalive_worker(&self, changed: &Signal<M, ()>) -> ! {
        loop {
            let t_now = now();
            let timeout = self.config.request_timeout_us;
            match self.with(|t| t.keepalive.claim(t_now, timeout)) {
                Next::Send(board, op, timeout_us) => {
                    let op_sent = match op {
                        KeepaliveOp::Heartbeat => Op::Heartbeat,
                        KeepaliveOp::SetFailsafe(timeout_ms) => Op::SetFailsafe { timeout_ms },
                    };
                    let r = self.call_with_timeout(board, op_sent, timeout_us).await;
                    let outcome = match r {
                        Ok(_) => Outcome::Sent,
                        Err(LinkError::Busy) => Outcome::Busy,
                        Err(e) => {
                            warn!("keepalive of board {} failed: {}", board.get(), e);
                            Outcome::Failed
                        }
                    };
                    let t_now = now();
                    self.with(|t| t.keepalive.done(board, op, outcome, t_now, &mut t.diag));
                    // The board can be taken again: wake the workers that left it out.
                    self.wake_keepalive_workers();
                }
                Next::At(at) => {
                    select(sleep_until(at), changed.wait()).await;
                }
                Next::Idle => changed.wait().await,
            }
        }
    }

    /// Wakes every keepalive worker to look at the table again.
    pub(crate) fn wake_keepalive_workers(&self) {
        for s in &self.keepalive_changed {
            s.signal(());
        }
    }

    /// The failsafe timeout the motherboard keeps alive for `db`, in ms (0: none).
    pub fn keepalive_ms(&self, db: Address) -> u16 {
        self.with(|t| t.keepalive.timeout_ms(db))
    }
}
