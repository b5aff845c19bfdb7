//! The motherboard: [`Motherboard`], the shared [`MbCore`] plus the internal daughterboard
//! on the board's own ports, and its tasks ([`Motherboard::run`]): the dispatcher
//! ([`crate::dispatch`]), the internal daughterboard's request worker (with its keepalive),
//! its background work and the routing of its events. The top of the crate: it uses every
//! other part, nothing uses it.

use core::ops::Deref;

use embassy_futures::join::join4;
use embassy_futures::select::{select, select3, Either, Either3};
use embassy_sync::blocking_mutex::Mutex as BlockingMutex;
use firmware_db::{Daughterboard, Ports, REPLY_BUF_LEN};
use heapless::Vec;
use x10_hal::bus::MultiMaster;
use x10_hal::time::EmbassyClock;
use x10_microcode::{Address, Op, Payload, Request, Status, MAX_FRAME_LEN};

use crate::config::MbConfig;
use crate::diag::bump;
use crate::directory::KnownBoard;
use crate::handle::X10;
use crate::jobs::Job;
use crate::keepalive::{KeepaliveOp, Next};
use crate::mb_core::{now, sleep_until, InternalBoard, MbCore, M};
use crate::observe::CallObserver;
use crate::transfer::Outcome;

/// The motherboard runtime: the shared [`MbCore`] and the internal daughterboard (address 0)
/// on the board's own ports `P`. It names no chip.
///
/// Give it a `'static` home (a `StaticCell` on a board; the simulator leaks one per run), run
/// [`Motherboard::run`] once in a task of its own, and hand [`Motherboard::handle`] (an
/// [`X10`]) to any number of robot tasks.
pub struct Motherboard<P: Ports> {
    core: MbCore,
    internal: Daughterboard<M, P>,
    /// Held while the internal daughterboard executes a request (a critical section): the
    /// internal worker's transactions and the callers' direct ones never overlap.
    internal_lock: BlockingMutex<M, ()>,
}

impl<P: Ports> Deref for Motherboard<P> {
    type Target = MbCore;

    fn deref(&self) -> &MbCore {
        &self.core
    }
}

impl<P: Ports> Motherboard<P> {
    /// A motherboard with its internal daughterboard on `internal_ports`.
    /// The internal board always has address 0, whatever `config.internal.address` says.
    pub fn new(config: MbConfig, internal_ports: P) -> Self {
        let mut internal = config.internal;
        internal.address = Address::INTERNAL;
        Motherboard {
            core: MbCore::new(config),
            internal: Daughterboard::new(internal_ports, internal),
            internal_lock: BlockingMutex::new(()),
        }
    }

    /// Executes `op` on the internal daughterboard in the calling task, under the lock
    /// around it (the direct path: see [`InternalBoard`]): its status, its value in `value`.
    pub fn execute_internal(&self, op: &Op<'_>, value: &mut Payload) -> Status {
        self.internal_lock
            .lock(|()| self.internal.execute(0, op, value))
    }

    /// One transaction of the internal worker: `frame` written, the reply read into `buf`;
    /// its length. Under the lock around the internal board.
    fn internal_transaction(&self, frame: &[u8], buf: &mut [u8]) -> usize {
        self.internal_lock.lock(|()| {
            self.internal.handle_write(frame, true);
            self.internal.take_reply(buf)
        })
    }

    /// The same motherboard, reporting every finished call to `observer` (the simulator
    /// traces robot calls this way; boards leave it unset).
    pub fn with_observer(mut self, observer: &'static dyn CallObserver) -> Self {
        self.core.observer = Some(observer);
        self
    }

    /// The same motherboard, knowing boards by their unique ID in `entries` (plug and play:
    /// it gives unaddressed boards an address, sweeps the bus once at start, reports boards
    /// that stop answering and collisions; see `docs/protocol.md`, "Addresses over the
    /// bus"). One entry per board it can know (a board uses its entry for good: 16 bytes
    /// each). Without this call none of that happens: announces are counted in `unassigned`
    /// and dropped.
    pub fn with_directory(self, entries: &'static mut [KnownBoard]) -> Self {
        self.core.with(|t| t.directory.set_storage(entries));
        self
    }

    /// The shared part, which robot tasks reach through [`X10`].
    pub fn core(&self) -> &MbCore {
        &self.core
    }

    /// The internal daughterboard (address 0).
    pub fn internal(&self) -> &Daughterboard<M, P> {
        &self.internal
    }

    /// The robot programs' handle: one concrete, `Copy` type whatever the board.
    pub fn handle(&'static self) -> X10 {
        X10::new(&self.core)
    }

    /// Runs the robot programs' calls to the internal daughterboard in the calling task from
    /// now on (ports, ping, heartbeat, scan: see [`InternalBoard`]): no queue, no frame, no
    /// worker in between, one yield per call. Once; the board crates' `start_motherboard`
    /// calls it. Without it (or for the other operations) the calls go to the internal
    /// worker's queue, with the same outcomes.
    pub fn serve_internal_directly(&'static self)
    where
        P: Sync,
    {
        let _ = self.core.set_internal_board(self);
    }

    /// Runs the motherboard; never returns. Run it in a task of its own: the dispatcher with
    /// its DB-interrupt listener on `bus`, the internal daughterboard (its requests, its
    /// background work, the routing of its events). The failsafe keepalive needs no task of
    /// its own: the dispatcher sends it to external boards between jobs, the internal
    /// worker to the internal board.
    pub async fn run<B: MultiMaster>(&self, bus: B) -> ! {
        let (never, _, _, _) = join4(
            self.core.run_dispatcher(bus),
            self.run_internal_requests(),
            self.internal.run_background(EmbassyClock),
            self.run_internal_events(),
        )
        .await;
        never
    }

    /// Serves the requests to the internal daughterboard, oldest first: the same bytes as on
    /// the bus, the same reply parsing; and keeps a failsafe set on it alive, between two
    /// requests, as the dispatcher does for external boards. Never returns. Part of
    /// [`Motherboard::run`].
    pub async fn run_internal_requests(&self) -> ! {
        loop {
            let t_now = now();
            let timeout = self.core.config.request_timeout_us;
            let next = self
                .core
                .with(|t| t.boards.keepalive.next(t_now, true, timeout));
            let changed = &self.core.internal_keepalive_changed;
            let job = match next {
                Next::Send(board, op, _) => {
                    self.internal_keepalive(board, op).await;
                    continue;
                }
                Next::At(at) => {
                    match select3(
                        self.core.next_internal_job(),
                        sleep_until(at),
                        changed.wait(),
                    )
                    .await
                    {
                        Either3::First(job) => job,
                        Either3::Second(()) | Either3::Third(()) => continue,
                    }
                }
                Next::Idle => match select(self.core.next_internal_job(), changed.wait()).await {
                    Either::First(job) => job,
                    Either::Second(()) => continue,
                },
            };
            let meta = &job.meta;
            if !self.core.is_queued(meta.ticket) {
                self.core.with(|t| bump(&mut t.diag.abandoned));
                continue;
            }
            // Every request is read back, outputs too (it costs no bus): a refusal ends the
            // call in its status, never in `Ok` followed by a `rejected` event.
            let (frame, pec) = self.core.frame_to_send(&job);
            let mut reply = [0u8; REPLY_BUF_LEN];
            let n = self.internal_transaction(&frame, &mut reply);
            self.core.finish_transfer(&job, pec, Ok(reply.get(..n)));
        }
    }

    /// A keepalive to the internal board: a heartbeat, or its failsafe set again, with a
    /// fresh sequence number, framed as the board's PEC setting is (a program may have
    /// turned it on) and read back: it counts as sent only when the board answered `ok`.
    async fn internal_keepalive(&self, board: Address, op: KeepaliveOp) {
        let seq = self.core.with(|t| t.requests.fresh_seq(board));
        let op_sent = match op {
            KeepaliveOp::Heartbeat => Op::Heartbeat,
            KeepaliveOp::SetFailsafe(timeout_ms) => Op::SetFailsafe { timeout_ms },
        };
        let req = Request {
            db: board,
            seq,
            op: op_sent,
        };
        let mut frame: Vec<u8, MAX_FRAME_LEN> = Vec::new();
        let _ = frame.resize(req.buffer_len().min(MAX_FRAME_LEN), 0);
        let ok = match req.emit(&mut frame) {
            Ok(n) => {
                frame.truncate(n);
                let job = Job::own(board, seq, Some(0), frame);
                let (tx, pec) = self.core.frame_to_send(&job);
                let mut reply = [0u8; REPLY_BUF_LEN];
                let n = self.internal_transaction(&tx, &mut reply);
                let read = reply.get(..n).unwrap_or(&[]);
                let (outcome, _) = self.core.interpret(&job.meta, pec, &op_sent, read);
                matches!(outcome, Outcome::Complete(Ok(_)))
            }
            Err(_) => false,
        };
        let t_now = now();
        self.core
            .with(|t| t.boards.keepalive.done(board, op, ok, t_now, &mut t.diag));
    }

    /// Routes the internal daughterboard's events (deferred replies, pin events, rejections)
    /// exactly as events that arrive over the bus. Never returns. Part of
    /// [`Motherboard::run`].
    pub async fn run_internal_events(&self) -> ! {
        loop {
            let ev = self.internal.next_event().await;
            // The internal board's events never cross a bus: as good as checked.
            self.core.route_event(&ev.as_event(Address::INTERNAL), true);
        }
    }
}

impl<P: Ports + Sync> InternalBoard for Motherboard<P> {
    fn execute(&self, op: &Op<'_>, value: &mut Payload) -> Option<Status> {
        Some(self.execute_internal(op, value))
    }
}
