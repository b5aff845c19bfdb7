//! The simulation: the real motherboard runtime (`firmware-mb`, with its internal
//! daughterboard on simulated ports), any number of real daughterboards (`firmware-db`) at their
//! addresses, robot programs (plain `async fn`s that take an [`X10`]) and test tasks, on one
//! simulated bus, in virtual time. [`Sim::run`] returns everything that happened as a
//! [`SimOutcome`].
//!
//! ```
//! use embassy_time::Timer;
//! use x10_devices::{DigitalOutput, Pin, SELF};
//! use x10_sim::sim::{Sim, SimConfig, X10};
//!
//! async fn blink(x10: X10) -> Result<(), x10_devices::Error> {
//!     let mut led = DigitalOutput::new(x10, SELF, 1, Pin::A)?;
//!     loop {
//!         led.toggle().await?;
//!         Timer::after_millis(500).await;
//!     }
//! }
//!
//! let config = SimConfig { duration_ms: 1_200, ..SimConfig::default() };
//! let outcome = Sim::new(config).with_robot("blink", blink).run().unwrap();
//! // Low at boot (the safe state), then high at 0 s, low at 0.5 s, high at 1.0 s.
//! let a1a = x10_microcode::Port::actuator(1).unwrap().pin(Pin::A);
//! let levels: Vec<bool> = outcome.log.of("mb", a1a).iter().map(|c| {
//!     c.change == x10_sim::ports::Change::Digital(x10_microcode::Level::High)
//! }).collect();
//! assert_eq!(levels, [false, true, false, true]);
//! ```

use std::fmt;
use std::future::Future;
use std::io::Write as _;
use std::pin::Pin;
use std::rc::Rc;
use std::sync::Mutex;

use firmware_mb::{
    CallObserver, CallRecord, InternalBoard, KnownBoard, MbConfig, MbDiagnostics, Motherboard,
    PinnedAddress,
};
use x10_microcode::{Address, Diagnostics, Op, Payload, Status, Uid};

pub use firmware_mb::X10;

use crate::board::{board_name, DbBoard, Notes};
use crate::bus::{BusConfig, BusRecord, BusStats, FaultConfig, NodeConfig, NodeId, Role, SimBus};
use crate::exec::{current_task, Executor, Nanos, RunError, SimClock};
use crate::ports::{ActuatorLog, SimPorts};
use crate::timing::Speed;
use crate::trace::{self, BusNames, Severity, Trace, TraceLine};

/// Entries of the motherboard's directory with [`SimConfig::plug_and_play`] (every address).
pub const DIRECTORY_ENTRIES: usize = 128;

/// How long an unplugged board stays down ([`Sim::unplug_at`]): longer than any run.
pub const UNPLUGGED_NS: Nanos = Nanos::MAX / 4;

/// The motherboard runtime as the simulator runs it.
pub type SimMotherboard = Motherboard<SimPorts>;

std::thread_local! {
    /// The motherboards of the runs under way on this thread: where [`SimInternal`] finds
    /// its run's internal daughterboard.
    static RUNNING: std::cell::RefCell<Vec<&'static SimMotherboard>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// The internal daughterboard of one run for the motherboard's direct path (issue 27: robot
/// calls to `SELF` run it in the calling task, as on the boards, where
/// `start_motherboard` calls `Motherboard::serve_internal_directly`). The simulator's ports
/// are not `Sync` (one thread runs a simulation), so the core gets this stand-in instead,
/// which is: it names its motherboard by address and finds it among the runs of the
/// calling thread. From another thread it finds none, and the call takes the internal
/// worker's queue (the same outcome).
struct SimInternal {
    mb: usize,
}

impl InternalBoard for SimInternal {
    fn execute(&self, op: &Op<'_>, value: &mut Payload) -> Option<Status> {
        let mb = RUNNING.with(|r| {
            r.borrow()
                .iter()
                .copied()
                .find(|&m| std::ptr::from_ref(m) as usize == self.mb)
        })?;
        Some(mb.execute_internal(op, value))
    }
}

/// Robot calls to `SELF` on `mb` run its internal daughterboard in the calling task (the
/// motherboard's direct path, as on the boards) while this lives; it must live on the thread
/// that runs the simulation. [`Sim`]'s runs do this themselves; a program that builds its
/// own [`SimMotherboard`] (the soak) calls it.
pub struct DirectInternal(&'static SimMotherboard);

impl DirectInternal {
    /// Starts the direct path of `mb` on this thread (see [`DirectInternal`]). The first
    /// call for `mb` gives its core the stand-in; it stays the stand-in for good.
    pub fn start(mb: &'static SimMotherboard) -> DirectInternal {
        RUNNING.with(|r| r.borrow_mut().push(mb));
        let stand_in: &'static SimInternal = Box::leak(Box::new(SimInternal {
            mb: std::ptr::from_ref(mb) as usize,
        }));
        mb.core().set_internal_board(stand_in);
        DirectInternal(mb)
    }
}

impl Drop for DirectInternal {
    fn drop(&mut self) {
        RUNNING.with(|r| r.borrow_mut().retain(|&m| !std::ptr::eq(m, self.0)));
    }
}

/// Settings of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimConfig {
    /// Bus clock.
    pub speed: Speed,
    /// Seed of everything random (fault injection, the runtimes' backoff jitter).
    pub seed: u64,
    /// Virtual time to run, in ms.
    pub duration_ms: u64,
    /// The motherboard's own bus address.
    pub mb_address: Address,
    /// The motherboard's I2C role handling.
    pub mb_role: Role,
    /// Bus fault injection.
    pub faults: FaultConfig,
    /// The motherboard's request timeout, in µs.
    pub request_timeout_us: u64,
    /// Longest a target may stretch SCL, in µs.
    pub stretch_timeout_us: u64,
    /// Trace every call robots make through their link (one line per call).
    pub trace_calls: bool,
    /// End the run as soon as every test task ([`Sim::with_task`]) has finished (and at
    /// `duration_ms` at the latest).
    pub stop_when_tasks_done: bool,
    /// Keep the wire symbols of every transaction, for [`SimOutcome::vcd`].
    pub record_wire: bool,
    /// The motherboard's safe defaults ([`MbConfig::new`]: PEC and a failsafe on every
    /// board), as on a board: the default. `false` runs [`MbConfig::thesis_compatible`] (the
    /// thesis's exact frames; the tests of mechanisms measured on those frames, and the
    /// latency table compared with the thesis's, choose it explicitly).
    pub mb_safe_defaults: bool,
    /// Plug and play on the motherboard (`Motherboard::with_directory`, room for 128 boards):
    /// it sweeps the bus at start, gives unaddressed boards an address, reports boards that
    /// stop answering and collisions. Off by default (the sweep adds 110 short writes at
    /// start); on whenever a board has no build-time address ([`Sim::with_unaddressed_board`]).
    pub plug_and_play: bool,
    /// Addresses pinned by the robot's configuration (`MbConfig::pinned`).
    pub pinned: &'static [PinnedAddress],
    /// What the run keeps: everything (the default), or a summary built as it goes, in
    /// memory that does not grow with the run's length.
    pub keep: Keep,
}

/// What a run keeps ([`SimConfig::keep`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Keep {
    /// Everything: every bus transaction ([`SimOutcome::records`], with its wire symbols
    /// when [`SimConfig::record_wire`]), every call ([`SimOutcome::calls`]), every trace
    /// line. Memory grows with the run: about 6 MB per virtual minute of Figure 4.4's bus
    /// (docs/performance.md). What the trace, the timeline pages and the VCD need.
    #[default]
    All,
    /// A summary built as the run goes, in memory bounded by [`KEEP_CAP`] entries per list,
    /// whatever the run's length: every counter ([`SimOutcome::bus`] with the bus's busy
    /// time, the boards' and the motherboard's), the number of calls and failed calls
    /// ([`SimOutcome::kept`]); of the lists, only what goes wrong, the first [`KEEP_CAP`]
    /// of each: failed or faulted bus transactions, failed calls, the simulator's warning
    /// notes (resets, task ends), device warnings, and the first [`KEEP_CAP`] output
    /// changes (all of them in a world with physics, which reads them as the run goes).
    /// The trace holds the warnings only, [`SimOutcome::calls`] is empty, no wire symbols are
    /// kept. What is past a cap is counted ([`Kept`]) and the summary says so.
    Summary,
}

/// Entries a bounded run ([`Keep::Summary`]) keeps per list.
pub const KEEP_CAP: usize = 10_000;

/// What a run kept and what it only counted ([`SimConfig::keep`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Kept {
    /// The mode of the run.
    pub keep: Keep,
    /// Calls of robot and test tasks, and of those the failed ones (whatever was kept).
    pub calls: (u64, u64),
    /// Failed calls whose trace line was not kept (past the cap).
    pub call_lines_dropped: u64,
    /// Bus records past the cap (failed or faulted transactions), counted, not kept.
    pub records_dropped: u64,
    /// Of those, the failures that [`SimOutcome::problems`] counts.
    pub dropped_failures: crate::bus::DroppedFailures,
    /// Output changes, device warnings, and other log entries (safe states, latches,
    /// blinks) past the cap.
    pub log_dropped: (u64, u64, u64),
    /// Notes (resets, task ends) past the cap.
    pub notes_dropped: u64,
}

impl Kept {
    /// Entries counted but not kept, in all.
    pub fn dropped(&self) -> u64 {
        self.call_lines_dropped
            + self.records_dropped
            + self.log_dropped.0
            + self.log_dropped.1
            + self.log_dropped.2
            + self.notes_dropped
    }

    /// Warning lines the trace would hold past the caps (failed calls, device warnings,
    /// notes; a failed bus transaction past the cap counts once, though its full trace may
    /// give it more than one line).
    pub fn warnings_dropped(&self) -> u64 {
        self.call_lines_dropped + self.records_dropped + self.log_dropped.1 + self.notes_dropped
    }

    /// The summary's line saying what a bounded run kept (`None` for [`Keep::All`]).
    pub fn summary_line(&self) -> Option<String> {
        if self.keep == Keep::All {
            return None;
        }
        let mut s = format!(
            "record: a summary (a long run): the counts and the bus load cover the whole run ({} calls, {} failed); kept of the lists only the first {KEEP_CAP} of each (failed bus transactions, failed calls, warnings, output changes)",
            self.calls.0, self.calls.1
        );
        if self.dropped() == 0 {
            s.push_str(": nothing was past that");
        } else {
            let (changes, warnings, others) = self.log_dropped;
            s.push_str(&format!(
                "; counted, not kept: {} bus transactions, {} failed calls, {changes} output changes, {warnings} device warnings, {} notes, {others} other log entries",
                self.records_dropped, self.call_lines_dropped, self.notes_dropped
            ));
        }
        Some(s)
    }
}

/// The default motherboard address (the lowest ordinary I2C address, so events sent to it
/// win arbitration against requests to any daughterboard).
pub const MB_ADDRESS: Address = match Address::external(0x08) {
    Ok(a) => a,
    Err(_) => Address::INTERNAL,
};

impl Default for SimConfig {
    /// 400 kHz, seed 1, 5 s, MB at 0x08 (dual-role), no faults, 100 ms request timeout, 25 ms stretch timeout, calls traced, runs the full duration,
    /// wire symbols kept.
    fn default() -> Self {
        SimConfig {
            speed: Speed::Fast,
            seed: 1,
            duration_ms: 5_000,
            mb_address: MB_ADDRESS,
            mb_role: Role::DualRole,
            faults: FaultConfig::NONE,
            request_timeout_us: 100_000,
            stretch_timeout_us: 25_000,
            trace_calls: true,
            stop_when_tasks_done: false,
            record_wire: true,
            mb_safe_defaults: true,
            plug_and_play: false,
            pinned: &[],
            keep: Keep::All,
        }
    }
}

/// What a test task gets: the running motherboard and the simulation around it.
#[derive(Clone)]
pub struct Ctx {
    /// The motherboard runtime.
    pub mb: &'static SimMotherboard,
    /// Virtual time.
    pub clock: SimClock,
    /// The bus.
    pub bus: SimBus,
    /// Lines for the trace.
    pub notes: Notes,
    /// Output changes of every board.
    pub log: ActuatorLog,
    nodes: Rc<Vec<(String, NodeId)>>,
}

impl Ctx {
    /// The robot programs' handle on the motherboard (calls are traced under the task's
    /// name).
    pub fn handle(&self) -> X10 {
        self.mb.handle()
    }

    /// The bus node called `name` (`mb`, `db09`, or a raw node's name).
    pub fn node(&self, name: &str) -> Option<NodeId> {
        self.nodes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, id)| *id)
    }
}

/// A future a task runs.
pub type LocalFuture = Pin<Box<dyn Future<Output = ()>>>;

/// A test task: given the context, the future to run.
pub type TaskFn = Box<dyn FnOnce(Ctx) -> LocalFuture>;

/// Makes a [`TaskFn`] from a closure (helps type inference).
pub fn task<F>(f: F) -> TaskFn
where
    F: FnOnce(Ctx) -> LocalFuture + 'static,
{
    Box::new(f)
}

/// How a robot task ended, as the simulator reports it: `()` and `Ok(_)` are a normal end,
/// `Err(e)` is traced as a warning with `e`'s text.
pub trait TaskEnd {
    /// The error's text, if the task ended with one.
    fn error(self) -> Option<String>;
}

impl TaskEnd for () {
    fn error(self) -> Option<String> {
        None
    }
}

impl TaskEnd for core::convert::Infallible {
    fn error(self) -> Option<String> {
        None
    }
}

impl<T, E: fmt::Display> TaskEnd for Result<T, E> {
    fn error(self) -> Option<String> {
        self.err().map(|e| e.to_string())
    }
}

impl x10::Tasks for Sim {
    fn task<F, Fut>(&mut self, name: &'static str, task: F)
    where
        F: FnOnce(X10) -> Fut + 'static,
        Fut: Future + 'static,
        Fut::Output: x10::TaskEnd,
    {
        self.add_robot_task(name, move |x10| async move {
            match x10::TaskEnd::into_error(task(x10).await) {
                Some(e) => Err(e),
                None => Ok(()),
            }
        });
    }
}

/// A robot task: given the handle, the future to run.
type RobotFn = Box<dyn FnOnce(X10, Notes, SimClock) -> LocalFuture>;

/// The value of a reply in words: a level, a number, or the bytes.
fn value_text(op: &Op<'_>, p: &Payload) -> String {
    match (op, p.as_slice()) {
        (Op::DigitalRead(_), [v]) => if *v != 0 { "high" } else { "low" }.to_string(),
        (Op::AnalogRead(_), [a, b]) => u16::from_le_bytes([*a, *b]).to_string(),
        (Op::PulseIn { .. }, [a, b, c, d]) => format!("{}us", u32::from_le_bytes([*a, *b, *c, *d])),
        (_, []) => "ok".to_string(),
        (_, bytes) => trace::hex(bytes),
    }
}

fn db_label(db: Address) -> String {
    if db.is_internal() {
        "SELF".to_string()
    } else {
        board_name(db)
    }
}

/// One call a robot or test task made, from its start to its result (what the timeline plot
/// draws in the task's lane).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CallSpan {
    /// The task that called.
    pub task: String,
    /// When the call started (ns).
    pub start_ns: Nanos,
    /// When its result came (ns).
    pub end_ns: Nanos,
    /// The call as the trace prints it: board, operation, outcome, time taken
    /// (`SELF io high A1.A -> ok in 0us`).
    pub text: String,
    /// False when the call failed.
    pub ok: bool,
}

/// Traces every call a robot or test task makes (one line per call: board, operation,
/// outcome, time taken), under the task's name, and keeps it as a [`CallSpan`]. The
/// motherboard's own calls (keepalives, in its task `mb`) are left out.
struct CallTracer {
    lines: Mutex<Vec<TraceLine>>,
    spans: Mutex<Vec<CallSpan>>,
    /// The boards the tasks called, each once, in the order of their first call.
    called: Mutex<Vec<u8>>,
    /// Told of everything too ([`Sim::also_observe`]).
    also: Option<&'static dyn CallObserver>,
    /// Keeps only failed calls' lines, at most [`KEEP_CAP`], and no spans.
    bounded: bool,
    /// Calls, failed calls, failed calls' lines not kept.
    counts: Mutex<(u64, u64, u64)>,
}

impl CallObserver for CallTracer {
    fn event(&self, event: &x10_microcode::Event<'_>, at: x10_hal::time::Instant) {
        if let Some(also) = self.also {
            also.event(event, at);
        }
    }

    fn update(
        &self,
        db: Address,
        from: x10_microcode::Version,
        to: x10_microcode::Version,
        end: Option<&Result<(), firmware_mb::update::UpdateError>>,
        at: x10_hal::time::Instant,
    ) {
        if let Some(also) = self.also {
            also.update(db, from, to, end, at);
        }
    }

    fn observe(&self, call: &CallRecord<'_>) {
        if let Some(also) = self.also {
            also.observe(call);
        }
        let task = current_task();
        let who: &str = task.as_deref().unwrap_or("?");
        if who == "mb" {
            return;
        }
        if let Ok(mut called) = self.called.lock() {
            if !called.contains(&call.db.get()) {
                called.push(call.db.get());
            }
        }
        if let Ok(mut counts) = self.counts.lock() {
            counts.0 += 1;
            if call.result.is_err() {
                counts.1 += 1;
                if self.bounded && self.lines.lock().map_or(0, |l| l.len()) >= KEEP_CAP {
                    counts.2 += 1;
                    return;
                }
            } else if self.bounded {
                return;
            }
        }
        let took = trace::micros(call.ended.since(call.started).saturating_mul(1_000));
        let (severity, outcome) = match call.result {
            Ok(p) => (Severity::Info, value_text(call.op, p)),
            Err(e) => (Severity::Warn, format!("error: {e}")),
        };
        let text = format!(
            "{} {} -> {outcome} in {took}",
            db_label(call.db),
            trace::describe_op(call.op)
        );
        let end_ns = call.ended.as_micros().saturating_mul(1_000);
        if self.bounded {
            if let Ok(mut lines) = self.lines.lock() {
                lines.push(TraceLine::new(end_ns, severity, who.to_string(), text));
            }
            return;
        }
        if let Ok(mut spans) = self.spans.lock() {
            spans.push(CallSpan {
                task: who.to_string(),
                start_ns: call.started.as_micros().saturating_mul(1_000),
                end_ns,
                text: text.clone(),
                ok: call.result.is_ok(),
            });
        }
        if let Ok(mut lines) = self.lines.lock() {
            lines.push(TraceLine::new(end_ns, severity, who.to_string(), text));
        }
    }
}

/// Why a simulation could not run.
#[derive(Debug)]
pub enum SimError {
    /// The executor found a task that never stops waking itself.
    Run(RunError),
    /// A board name used twice, or an address used by two boards.
    Config(String),
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Run(e) => write!(f, "simulation stopped: {e}"),
            SimError::Config(s) => write!(f, "bad simulation setup: {s}"),
        }
    }
}

impl std::error::Error for SimError {}

/// Everything a run produced.
pub struct SimOutcome {
    /// The readable trace.
    pub trace: Trace,
    /// Every bus transaction.
    pub records: Vec<BusRecord>,
    /// Every output change.
    pub log: ActuatorLog,
    /// The motherboard's counters at the end.
    pub mb: MbDiagnostics,
    /// The internal daughterboard's counters at the end.
    pub internal: Diagnostics,
    /// Each external board's counters at the end (of its last boot).
    pub boards: Vec<(String, Diagnostics)>,
    /// Bus counters.
    pub bus: BusStats,
    /// Virtual time at the end (ns).
    pub end_ns: Nanos,
    /// The bus clock.
    pub speed: Speed,
    /// Instants at which tasks were busy-looping when time moved on
    /// ([`crate::exec::SPIN_POLLS`]): 0 unless some task spins.
    pub spins: u64,
    /// Task polls the executor made in all (the simulator's unit of work: each wake-up of a
    /// runtime's task, a board's, the bus engine's or a robot's).
    pub polls: u64,
    /// Every call of a robot or test task, in the order they ended (whether or not the trace
    /// keeps them, [`SimConfig::trace_calls`]).
    pub calls: Vec<CallSpan>,
    /// The addresses of the boards on the bus (the internal board, 0, first).
    pub board_addresses: Vec<u8>,
    /// Boards the robot and test tasks called that are not on the bus, in the order of the
    /// first call.
    pub unknown_boards: Vec<u8>,
    /// Robot tasks that ended with an error: (task, the error's text).
    pub task_errors: Vec<(String, String)>,
    /// Device warnings: a user's program broke a documented limit of a device model
    /// (e.g. ultrasonic measurements closer together than the part allows).
    pub device_warnings: Vec<String>,
    /// Ground truth of plug and play: for each external board, every address it started at,
    /// with the time (ns; `0x77` while unaddressed).
    pub addresses: Vec<(String, Vec<(u64, Address)>)>,
    /// What the run kept and what it only counted ([`SimConfig::keep`]).
    pub kept: Kept,
    /// Lines of the streamed record ([`Sim::record_to`]) that could not be written, and 1
    /// more if its last flush failed.
    pub record_errors: u64,
}

impl SimOutcome {
    /// The SDA/SCL waveform of the whole run as a VCD file (empty of transitions when the run
    /// did not keep wire symbols, [`SimConfig::record_wire`]).
    pub fn vcd(&self) -> String {
        crate::vcd::render(&self.records, self.speed.timing(), self.speed.label())
    }

    /// A board's counters by name (`mb` is the internal board).
    pub fn board(&self, name: &str) -> Option<&Diagnostics> {
        if name == "mb" {
            return Some(&self.internal);
        }
        self.boards.iter().find(|(n, _)| n == name).map(|(_, d)| d)
    }

    /// What went wrong in the run, one sentence each, the worst first: a call to a board the
    /// world does not have, a robot task that ended with an error, and bus transactions that
    /// failed (NACK, timeout, bus fault) with no injected fault or board reset to explain
    /// them. Empty for a correct run; `cargo sim` and `x10 sim` exit non-zero otherwise.
    /// `world` names the world in the text (`world.toml`).
    pub fn problems(&self, world: &str) -> Vec<String> {
        let mut out = Vec::new();
        let boards: Vec<String> = self
            .board_addresses
            .iter()
            .map(|&a| {
                if a == 0 {
                    "SELF".to_string()
                } else {
                    format!("{a:#04x}")
                }
            })
            .collect();
        for a in &self.unknown_boards {
            out.push(format!(
                "the program called board {a:#04x}, which is not in {world} (boards: {})",
                boards.join(", ")
            ));
        }
        for (task, e) in &self.task_errors {
            out.push(format!("the task {task} ended with an error: {e}"));
        }
        let failed = self
            .records
            .iter()
            .filter(|r| r.outcome != crate::bus::Outcome::Ok && r.faults.is_empty())
            .filter(|r| match r.target {
                Some(_) => true,
                // Nobody answered: a board that was down (reset) or one the world lacks
                // (reported above when the program called it).
                None => self.bus.resets == 0 && self.board_addresses.contains(&r.addr),
            })
            .count() as u64;
        let d = &self.kept.dropped_failures;
        let unanswered: u64 = d
            .unanswered
            .iter()
            .enumerate()
            .filter(|(a, _)| {
                self.bus.resets == 0
                    && u8::try_from(*a).is_ok_and(|a| self.board_addresses.contains(&a))
            })
            .map(|(_, n)| n)
            .sum();
        let failed = failed + d.answered + unanswered;
        if failed > 0 {
            let noun = if failed == 1 {
                "transaction"
            } else {
                "transactions"
            };
            out.push(format!(
                "{failed} bus {noun} failed (NACK, timeout or bus fault) with no injected fault or board reset to explain them"
            ));
        }
        out
    }
}

struct ScheduledReset {
    board: String,
    at_ns: Nanos,
    down_ns: Nanos,
}

/// A simulation being set up.
pub struct Sim {
    config: SimConfig,
    clock: SimClock,
    log: ActuatorLog,
    notes: Notes,
    mb_ports: SimPorts,
    boards: Vec<DbBoard>,
    raw_nodes: Vec<NodeConfig>,
    robots: Vec<(String, RobotFn)>,
    tasks: Vec<(String, TaskFn)>,
    resets: Vec<ScheduledReset>,
    mb_stop_ns: Option<Nanos>,
    task_errors: TaskErrors,
    shared_addresses: bool,
    also_observe: Option<&'static dyn CallObserver>,
    record_to: Option<Box<dyn std::io::Write>>,
}

/// The robot tasks that ended with an error: (task, error text).
type TaskErrors = Rc<std::cell::RefCell<Vec<(String, String)>>>;

impl Sim {
    /// A simulation with a motherboard whose internal board has 2 idle sensor ports and 2
    /// actuator ports, no daughterboards and no program.
    pub fn new(config: SimConfig) -> Sim {
        let clock = SimClock::new();
        let log = ActuatorLog::new();
        let mb_ports = SimPorts::new("mb", clock.clone(), log.clone(), 2, 2);
        Sim {
            config,
            clock,
            log,
            notes: Notes::new(),
            mb_ports,
            boards: Vec::new(),
            raw_nodes: Vec::new(),
            robots: Vec::new(),
            tasks: Vec::new(),
            resets: Vec::new(),
            mb_stop_ns: None,
            task_errors: TaskErrors::default(),
            shared_addresses: false,
            also_observe: None,
            record_to: None,
        }
    }

    /// Streams the bus's record to `out` as the run goes: the lines `--trace` prints for each
    /// transaction (`seconds LEVEL source: what`: frames, replies, events, faults, lost
    /// arbitrations), written as each transaction ends, whatever the run keeps
    /// ([`SimConfig::keep`]). Write errors are counted ([`SimOutcome::record_errors`]), the
    /// run goes on.
    pub fn record_to(mut self, out: Box<dyn std::io::Write>) -> Sim {
        self.record_to = Some(out);
        self
    }

    /// Tells `observer` too of every call (the robot tasks' and the motherboard's own) and
    /// every routed event, as a board's observer is told: the USB link's recorder
    /// (`x10_link::recorder::Recorder`) sees a simulated robot this way.
    pub fn also_observe(mut self, observer: &'static dyn CallObserver) -> Sim {
        self.also_observe = Some(observer);
        self
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The virtual clock (to build ports before the run).
    pub fn clock(&self) -> &SimClock {
        &self.clock
    }

    /// The output log (to build ports before the run).
    pub fn log(&self) -> &ActuatorLog {
        &self.log
    }

    /// Ports for a board called `name`, on this simulation's clock and log.
    pub fn ports(&self, name: &str, sensor_ports: u8, actuator_ports: u8) -> SimPorts {
        SimPorts::new(
            name,
            self.clock.clone(),
            self.log.clone(),
            sensor_ports,
            actuator_ports,
        )
    }

    /// Replaces the internal daughterboard's ports (name them `mb`).
    pub fn with_internal_ports(mut self, ports: SimPorts) -> Sim {
        self.mb_ports = ports;
        self
    }

    /// Adds a daughterboard at `address` with `ports`; returns it for further setup through
    /// [`Sim::board_mut`].
    pub fn with_board(mut self, address: Address, ports: SimPorts) -> Sim {
        self.boards
            .push(DbBoard::new(address, self.config.mb_address, ports));
        self
    }

    /// Adds a daughterboard called `name` without a build-time address (plug and play): it
    /// boots unaddressed, announces itself with its ID (`uid`, or one made from its name,
    /// [`crate::board::uid_of_name`]) and takes the address the motherboard gives it, kept in
    /// its simulated record across resets. Turns [`SimConfig::plug_and_play`] on.
    pub fn with_unaddressed_board(mut self, name: &str, uid: Option<Uid>, ports: SimPorts) -> Sim {
        let uid = uid.unwrap_or_else(|| crate::board::uid_of_name(name));
        self.boards.push(DbBoard::unaddressed(
            name,
            uid,
            self.config.mb_address,
            ports,
        ));
        self.config.plug_and_play = true;
        self
    }

    /// Powers board `name` up only at `at_ms` (plugged in while the robot runs).
    pub fn plug_at(mut self, name: &str, at_ms: u64) -> Sim {
        if let Some(b) = self.board_mut(name) {
            b.power_on_ns = at_ms * 1_000_000;
        }
        self
    }

    /// Unplugs board `name` at `at_ms` for good (it NACKs everything from then on).
    pub fn unplug_at(mut self, name: &str, at_ms: u64) -> Sim {
        self.resets.push(ScheduledReset {
            board: name.to_string(),
            at_ns: at_ms * 1_000_000,
            down_ns: UNPLUGGED_NS,
        });
        self
    }

    /// Lets two boards have one address (two boards built with the same override): the
    /// motherboard must report the collision (a write reaches both; a read is answered by
    /// the first).
    pub fn allow_shared_addresses(mut self) -> Sim {
        self.shared_addresses = true;
        self
    }

    /// Adds a daughterboard called `name` with the build-time address `address` (its ID made
    /// from its name): as [`Sim::with_board`], for a second board built with an address
    /// another already has ([`Sim::allow_shared_addresses`]).
    pub fn with_board_named(mut self, name: &str, address: Address, ports: SimPorts) -> Sim {
        let mut b = DbBoard::new(address, self.config.mb_address, ports);
        b.name = name.to_string();
        b.uid = crate::board::uid_of_name(name);
        self.boards.push(b);
        self
    }

    /// Gives board `name` a flash with A/B slots and a bootloader (issue 25): it reports the
    /// version its active slot holds and can be updated over the bus; `fw` is shared, so the
    /// caller sees what it holds after the run.
    pub fn with_firmware(mut self, name: &str, fw: crate::firmware::SimFirmware) -> Sim {
        if let Some(b) = self.board_mut(name) {
            b.record.firmware = Some(fw);
        }
        self
    }

    /// Makes board `name` an STM32C011 (kind 5) with its flash and ROM bootloader (issue 25):
    /// it reports the version its flash holds and is updated through the ROM at 0x64; `rom`
    /// is shared, so the caller sees what the flash holds after the run.
    pub fn with_rom(mut self, name: &str, rom: crate::firmware::SimRom) -> Sim {
        if let Some(b) = self.board_mut(name) {
            b.record.rom = Some(rom);
            b.config.board = x10_microcode::BoardKind::C011;
        }
        self
    }

    /// The board called `name`, to change its configuration.
    pub fn board_mut(&mut self, name: &str) -> Option<&mut DbBoard> {
        self.boards.iter_mut().find(|b| b.name == name)
    }

    /// Adds a bus node that runs no firmware (a test task drives it through
    /// [`Ctx::node`] and [`SimBus::port`]).
    pub fn with_raw_node(mut self, node: NodeConfig) -> Sim {
        self.raw_nodes.push(node);
        self
    }

    /// Runs a robot task called `name`: `robot(x10)`, an `async fn` that takes the handle
    /// (the same function a firmware image spawns as an embassy task). Its calls are traced
    /// under `name`; an `Err` it returns is traced as a warning. Add as many as the robot has.
    pub fn with_robot<F, Fut>(mut self, name: &str, robot: F) -> Sim
    where
        F: FnOnce(X10) -> Fut + 'static,
        Fut: Future + 'static,
        Fut::Output: TaskEnd,
    {
        self.add_robot_task(name, robot);
        self
    }

    /// Runs every task of `robot`, a robot declared once with `x10::robot!` (its tasks named
    /// as it names them): the same list the board images spawn.
    ///
    /// ```ignore
    /// let outcome = world.sim(config)?.robot(robot::Robot).run()?;
    /// ```
    pub fn robot<R: x10::Robot>(mut self, _robot: R) -> Sim {
        R::tasks(&mut self);
        self
    }

    fn add_robot_task<F, Fut>(&mut self, name: &str, robot: F)
    where
        F: FnOnce(X10) -> Fut + 'static,
        Fut: Future + 'static,
        Fut::Output: TaskEnd,
    {
        let who = name.to_string();
        let errors = self.task_errors.clone();
        let f: RobotFn = Box::new(move |x10, notes, clock| {
            Box::pin(async move {
                let end = robot(x10).await;
                let (severity, text) = match end.error() {
                    Some(e) => {
                        errors.borrow_mut().push((who.clone(), e.clone()));
                        (Severity::Warn, format!("ended with an error: {e}"))
                    }
                    None => (Severity::Info, "ended".to_string()),
                };
                notes.push(TraceLine::new(clock.now_ns(), severity, who, text));
            })
        });
        self.robots.push((name.to_string(), f));
    }

    /// Runs a test task next to everything else.
    pub fn with_task(mut self, name: &str, f: TaskFn) -> Sim {
        self.tasks.push((name.to_string(), f));
        self
    }

    /// Resets board `name` at `at_ms` for `down_ms` (its firmware restarts afterwards).
    pub fn reset_at(mut self, name: &str, at_ms: u64, down_ms: u64) -> Sim {
        self.resets.push(ScheduledReset {
            board: name.to_string(),
            at_ns: at_ms * 1_000_000,
            down_ns: down_ms * 1_000_000,
        });
        self
    }

    /// Stops the motherboard at `at_ms`, as a crash or a power loss would: its runtime stops
    /// (no more dispatching, listening or keepalive) and its bus node is gone for good (it
    /// NACKs whatever is addressed to it). Robot calls made after that never complete.
    pub fn stop_mb_at(mut self, at_ms: u64) -> Sim {
        self.mb_stop_ns = Some(at_ms * 1_000_000);
        self
    }

    fn check(&self) -> Result<(), SimError> {
        let mut addrs = vec![self.config.mb_address.get()];
        let mut names = vec!["mb".to_string()];
        for (name, addr) in self
            .boards
            .iter()
            .map(|b| {
                let shared = self.shared_addresses || b.override_address.is_none();
                (b.name.clone(), (!shared).then(|| b.start_address().get()))
            })
            .chain(self.raw_nodes.iter().map(|n| (n.name.clone(), n.address)))
        {
            if names.contains(&name) {
                return Err(SimError::Config(format!("two boards are called {name}")));
            }
            if let Some(a) = addr {
                if addrs.contains(&a) {
                    return Err(SimError::Config(format!("address {a:#04x} is used twice")));
                }
                addrs.push(a);
            }
            names.push(name);
        }
        for r in &self.resets {
            if !names.contains(&r.board) {
                return Err(SimError::Config(format!(
                    "no board called {} to reset",
                    r.board
                )));
            }
        }
        Ok(())
    }

    /// Runs the simulation for the configured duration.
    ///
    /// # Errors
    /// [`SimError::Config`] for clashing names or addresses, [`SimError::Program`] when the
    /// program's robots cannot be built, [`SimError::Run`] when a task livelocks.
    pub fn run(self) -> Result<SimOutcome, SimError> {
        self.check()?;
        let Sim {
            config,
            clock,
            log,
            notes,
            mb_ports,
            boards,
            raw_nodes,
            robots,
            tasks,
            resets,
            mb_stop_ns,
            task_errors,
            shared_addresses: _,
            also_observe,
            record_to,
        } = self;
        let mut board_addresses = vec![0];
        board_addresses.extend(
            boards
                .iter()
                .filter_map(|b| b.override_address)
                .map(Address::get),
        );
        board_addresses.extend(raw_nodes.iter().filter_map(|n| n.address));
        let mut bus_cfg = BusConfig::new(config.speed);
        bus_cfg.seed = config.seed;
        bus_cfg.faults = config.faults;
        bus_cfg.stretch_timeout_ns = config.stretch_timeout_us * 1_000;
        bus_cfg.record_wire = config.record_wire;
        let bounded = config.keep == Keep::Summary;
        if bounded {
            bus_cfg.record_wire = false;
            bus_cfg.keep_clean_records = false;
            bus_cfg.keep_failed_records = true;
            bus_cfg.record_cap = KEEP_CAP;
            log.bound_to(KEEP_CAP);
            notes.bound_to(KEEP_CAP);
        }
        let bus = SimBus::new(clock.clone(), bus_cfg);
        let mb_node = bus.add_node(
            NodeConfig::new("mb", Some(config.mb_address.get())).with_role(config.mb_role),
        );
        let mut nodes = vec![("mb".to_string(), mb_node)];
        let board_nodes: Vec<NodeId> = boards
            .iter()
            .map(|b| {
                let id = bus.add_node(b.node_config());
                if b.power_on_ns > 0 {
                    bus.power_on_at(id, b.power_on_ns);
                }
                nodes.push((b.name.clone(), id));
                id
            })
            .collect();
        for n in raw_nodes {
            let name = n.name.clone();
            nodes.push((name, bus.add_node(n)));
        }
        let nodes = Rc::new(nodes);
        let record_errors = Rc::new(std::cell::Cell::new(0u64));
        let record_out = record_to.map(|out| Rc::new(std::cell::RefCell::new(out)));
        if let Some(out) = record_out.clone() {
            let mut names = vec![String::new(); nodes.len()];
            for (name, id) in nodes.iter() {
                if let Some(slot) = names.get_mut(*id) {
                    *slot = name.clone();
                }
            }
            let mb_address = config.mb_address.get();
            let errors = record_errors.clone();
            bus.on_record(Box::new(move |rec: &BusRecord| {
                let bus_names = BusNames {
                    names: &names,
                    mb_address: Some(mb_address),
                };
                let mut lines = trace::bus_lines(rec, &bus_names);
                lines.sort_by_key(|l| l.t_ns);
                let mut out = out.borrow_mut();
                for l in lines {
                    if writeln!(out, "{l}").is_err() {
                        errors.set(errors.get() + 1);
                    }
                }
            }));
        }

        let mut mb_cfg = if config.mb_safe_defaults {
            MbConfig::new(config.mb_address)
        } else {
            MbConfig::thesis_compatible(config.mb_address)
        };
        mb_cfg.request_timeout_us = config.request_timeout_us;
        mb_cfg.pinned = config.pinned;
        mb_cfg.seed = (config.seed as u32)
            ^ ((config.seed >> 32) as u32)
            ^ u32::from(config.mb_address.get());
        // Robot tasks hold a `'static` handle: each run leaks its motherboard (a few KiB).
        let tracer: &'static CallTracer = Box::leak(Box::new(CallTracer {
            lines: Mutex::new(Vec::new()),
            spans: Mutex::new(Vec::new()),
            called: Mutex::new(Vec::new()),
            also: also_observe,
            bounded,
            counts: Mutex::new((0, 0, 0)),
        }));
        let mut motherboard = Motherboard::new(mb_cfg, mb_ports).with_observer(tracer);
        if config.plug_and_play {
            let entries = vec![KnownBoard::EMPTY; DIRECTORY_ENTRIES].into_boxed_slice();
            motherboard = motherboard.with_directory(Box::leak(entries));
        }
        let mb: &'static SimMotherboard = Box::leak(Box::new(motherboard));
        let _direct = DirectInternal::start(mb);

        let run = {
            let mut ex = Executor::with_clock(&clock);
            ex.spawn("bus", bus.engine());
            let mb_ref = mb;
            let mb_port = bus.port(mb_node);
            let (mb_bus, mb_clock) = (bus.clone(), clock.clone());
            ex.spawn("mb", async move {
                match mb_stop_ns {
                    None => mb_ref.run(mb_port).await,
                    Some(at) => {
                        embassy_futures::select::select(
                            mb_ref.run(mb_port),
                            mb_clock.sleep_until_ns(at),
                        )
                        .await;
                        // Down for longer than any simulation runs.
                        mb_bus.reset_node(mb_node, Nanos::MAX / 4);
                    }
                }
            });
            for (b, &node) in boards.iter().zip(&board_nodes) {
                ex.spawn(b.name.clone(), b.run(bus.clone(), node, notes.clone()));
            }
            for r in resets {
                let Some(&(_, node)) = nodes.iter().find(|(n, _)| *n == r.board) else {
                    continue;
                };
                let (bus, clock) = (bus.clone(), clock.clone());
                ex.spawn(format!("reset {}", r.board), async move {
                    clock.sleep_until_ns(r.at_ns).await;
                    bus.reset_node(node, r.down_ns);
                });
            }
            for (name, robot) in robots {
                ex.spawn(name, robot(mb.handle(), notes.clone(), clock.clone()));
            }
            let running = Rc::new(std::cell::Cell::new(tasks.len()));
            for (name, f) in tasks {
                let ctx = Ctx {
                    mb,
                    clock: clock.clone(),
                    bus: bus.clone(),
                    notes: notes.clone(),
                    log: log.clone(),
                    nodes: nodes.clone(),
                };
                let fut = f(ctx);
                let running = running.clone();
                ex.spawn(name, async move {
                    fut.await;
                    running.set(running.get().saturating_sub(1));
                });
            }
            let stop_early = config.stop_when_tasks_done;
            let keep_going = || !stop_early || running.get() > 0;
            ex.run_while(config.duration_ms.saturating_mul(1_000_000), &keep_going)
                .map_err(SimError::Run)?
        };
        let end_ns = run.end_ns;
        if let Some(out) = &record_out {
            if out.borrow_mut().flush().is_err() {
                record_errors.set(record_errors.get() + 1);
            }
        }
        // Every address a board had is on the bus (calls to them are no unknown board's).
        for b in &boards {
            for (_, a) in b.addresses.starts() {
                if !board_addresses.contains(&a.get()) {
                    board_addresses.push(a.get());
                }
            }
        }
        let addresses = boards
            .iter()
            .map(|b| (b.name.clone(), b.addresses.starts()))
            .collect();

        let names: Vec<String> = {
            let mut v = vec![String::new(); nodes.len()];
            for (name, id) in nodes.iter() {
                if let Some(slot) = v.get_mut(*id) {
                    *slot = name.clone();
                }
            }
            v
        };
        let records = bus.take_records();
        let bus_names = BusNames {
            names: &names,
            mb_address: Some(config.mb_address.get()),
        };
        let mut trace = Trace::new();
        let mut lines: Vec<TraceLine> = records
            .iter()
            .flat_map(|r| trace::bus_lines(r, &bus_names))
            .collect();
        lines.extend(bus.yields().iter().map(|y| {
            TraceLine::new(
                y.t_ns,
                Severity::Info,
                names.get(y.node).cloned().unwrap_or_default(),
                format!(
                    "gives up starting its transaction to {:#04x}: it is being addressed (serves it, then retries)",
                    y.addr
                ),
            )
        }));
        lines.extend(log.changes().iter().map(trace::change_line));
        let device_warnings = log.device_warnings();
        lines.extend(
            device_warnings
                .iter()
                .map(|w| TraceLine::new(w.t_ns, Severity::Warn, w.board.clone(), w.text.clone())),
        );
        let calls = tracer.lines.lock().map(|mut l| std::mem::take(&mut *l));
        let mut calls = calls.unwrap_or_default();
        let notes_dropped = notes.dropped();
        let mut notes = notes.lines();
        let task_errors = task_errors.take();
        for (task, e) in &task_errors {
            once_per_error(task, e, &mut calls, &mut notes);
        }
        lines.extend(
            notes
                .into_iter()
                .chain(calls)
                .filter(|l| config.trace_calls || l.severity >= Severity::Warn),
        );
        if bounded {
            // Only what went wrong: the summary reads the warnings and the resets.
            lines.retain(|l| l.severity >= Severity::Warn);
        }
        trace.extend(lines);
        let (calls_made, calls_failed, call_lines_dropped) =
            tracer.counts.lock().map(|c| *c).unwrap_or_default();
        let kept = Kept {
            keep: config.keep,
            calls: (calls_made, calls_failed),
            call_lines_dropped,
            records_dropped: bus.stats().records_dropped,
            dropped_failures: bus.dropped_failures(),
            log_dropped: log.dropped(),
            notes_dropped,
        };
        Ok(SimOutcome {
            trace,
            records,
            log,
            mb: mb.diagnostics(),
            internal: mb.internal().diagnostics(),
            boards: boards
                .iter()
                .map(|b| (b.name.clone(), b.diagnostics.get()))
                .collect(),
            bus: bus.stats(),
            end_ns,
            speed: config.speed,
            spins: run.spins,
            polls: run.polls,
            calls: tracer
                .spans
                .lock()
                .map(|mut s| std::mem::take(&mut *s))
                .unwrap_or_default(),
            unknown_boards: tracer
                .called
                .lock()
                .map(|c| c.clone())
                .unwrap_or_default()
                .into_iter()
                .filter(|a| !board_addresses.contains(a))
                .collect(),
            board_addresses,
            task_errors,
            device_warnings: device_warnings.into_iter().map(|w| w.text).collect(),
            addresses,
            kept,
            record_errors: record_errors.get(),
        })
    }
}

/// A task that ended with error `e` is one warning, not two: when its last call failed (the
/// cause), that call's line becomes an information line and the task's end line names it.
fn once_per_error(task: &str, e: &str, calls: &mut [TraceLine], notes: &mut [TraceLine]) {
    let Some(call) = calls.iter_mut().rev().find(|l| l.source == task) else {
        return;
    };
    if call.severity < Severity::Warn {
        return;
    }
    let end = format!("ended with an error: {e}");
    if let Some(note) = notes
        .iter_mut()
        .rev()
        .find(|l| l.source == task && l.text == end)
    {
        call.severity = Severity::Info;
        note.text = format!(
            "{end} (its call at {}: {})",
            trace::timestamp(call.t_ns),
            call.text
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(n: u8) -> Address {
        Address::external(n).unwrap()
    }

    #[test]
    fn clashing_addresses_and_names_are_refused() {
        let sim = Sim::new(SimConfig::default());
        let p1 = sim.ports("db09", 1, 1);
        let p2 = sim.ports("db09b", 1, 1);
        let err = sim
            .with_board(addr(9), p1)
            .with_raw_node(NodeConfig::new("other", Some(9)))
            .run()
            .err()
            .map(|e| e.to_string());
        assert_eq!(
            err.as_deref(),
            Some("bad simulation setup: address 0x09 is used twice")
        );
        let sim = Sim::new(SimConfig::default());
        let err = sim
            .with_board(addr(8), p2)
            .run()
            .err()
            .map(|e| e.to_string());
        assert_eq!(
            err.as_deref(),
            Some("bad simulation setup: address 0x08 is used twice")
        );
        let err = Sim::new(SimConfig::default())
            .reset_at("db42", 1, 1)
            .run()
            .err()
            .map(|e| e.to_string());
        assert_eq!(
            err.as_deref(),
            Some("bad simulation setup: no board called db42 to reset")
        );
    }

    #[test]
    fn failed_transactions_are_a_problem_unless_a_fault_or_a_reset_explains_them() {
        use crate::bus::{Outcome, WireSym};
        let sim = Sim::new(SimConfig {
            duration_ms: 10,
            ..SimConfig::default()
        });
        let ports = sim.ports("db09", 1, 1);
        let mut o = sim.with_board(addr(9), ports).run().unwrap();
        assert_eq!(o.board_addresses, [0, 9]);
        assert_eq!(o.problems("w.toml"), Vec::<String>::new());
        let nack = |target: Option<NodeId>, addr: u8, faults: Vec<String>| BusRecord {
            txn: 0,
            start_ns: 0,
            end_ns: 1,
            master: 0,
            addr,
            target,
            written: vec![0x12],
            received: vec![],
            is_read: false,
            read: vec![],
            outcome: Outcome::Nack { byte: 1 },
            losers: vec![],
            stretch_ns: 0,
            faults,
            wire: vec![(0, WireSym::Start)],
        };
        // Explained: an injected fault; nobody at an address no board has (the program's
        // call to it is its own problem).
        o.records = vec![
            nack(Some(1), 9, vec!["flip".to_string()]),
            nack(None, 0x0a, vec![]),
        ];
        assert_eq!(o.problems("w.toml"), Vec::<String>::new());
        // Unexplained: a board that NACKs a byte; a board that does not answer, no reset.
        o.records = vec![nack(Some(1), 9, vec![]), nack(None, 9, vec![])];
        assert_eq!(
            o.problems("w.toml"),
            ["2 bus transactions failed (NACK, timeout or bus fault) with no injected fault or board reset to explain them"]
        );
        // A board that was reset does not answer while it is down.
        o.bus.resets = 1;
        assert_eq!(o.problems("w.toml").len(), 1);
        o.records.truncate(1);
        o.unknown_boards = vec![0x0a];
        assert_eq!(
            o.problems("w.toml"),
            [
                "the program called board 0x0a, which is not in w.toml (boards: SELF, 0x09)",
                "1 bus transaction failed (NACK, timeout or bus fault) with no injected fault or board reset to explain them"
            ]
        );
    }

    #[test]
    fn reply_values_in_words() {
        let s1 = x10_microcode::Port::sensor(1).unwrap();
        let p = |b: &[u8]| Payload::from_slice(b).unwrap();
        assert_eq!(value_text(&Op::AnalogRead(s1), &p(&[0xc8, 0x02])), "712");
        assert_eq!(value_text(&Op::DigitalRead(s1.into()), &p(&[1])), "high");
        assert_eq!(value_text(&Op::Ping, &p(&[])), "ok");
        assert_eq!(value_text(&Op::Identify, &p(&[1, 2])), "[01 02]");
        assert_eq!(db_label(Address::INTERNAL), "SELF");
        assert_eq!(db_label(addr(0x6c)), "db6c");
    }

    #[test]
    fn tasks_can_end_the_run_early() {
        let config = SimConfig {
            stop_when_tasks_done: true,
            duration_ms: 10_000,
            ..SimConfig::default()
        };
        let o = Sim::new(config)
            .with_task(
                "short",
                task(|ctx| {
                    Box::pin(async move {
                        ctx.clock.sleep_ns(3_000_000).await;
                    })
                }),
            )
            .run()
            .unwrap();
        assert_eq!(o.end_ns, 3_000_000);
    }
}
