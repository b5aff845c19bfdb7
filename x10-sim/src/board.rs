//! A simulated daughterboard: the real `firmware-db` runtime on [`SimPorts`] and a
//! [`crate::bus::SimPort`], restarted from scratch whenever the bus resets its node.

use std::cell::RefCell;
use std::future::{poll_fn, Future};
use std::pin::pin;
use std::rc::Rc;

use embassy_futures::select::select;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, TargetConfig};
use x10_microcode::{Address, BoardKind, Diagnostics};

use crate::bus::{NodeConfig, NodeId, Role, SimBus};
use crate::ports::SimPorts;
use crate::trace::{Severity, TraceLine};

/// Lines the simulator adds to the trace (resets, robot errors, …). Cloning shares them.
#[derive(Clone, Default)]
pub struct Notes {
    lines: Rc<RefCell<Vec<TraceLine>>>,
}

impl Notes {
    /// No notes yet.
    pub fn new() -> Notes {
        Notes::default()
    }

    /// Adds a line.
    pub fn push(&self, line: TraceLine) {
        self.lines.borrow_mut().push(line);
    }

    /// Every line so far.
    pub fn lines(&self) -> Vec<TraceLine> {
        self.lines.borrow().clone()
    }
}

/// The diagnostics counters of a running board, as of its task's last poll (shared; cloning
/// shares them).
#[derive(Clone, Default)]
pub struct DiagnosticsCell {
    inner: Rc<RefCell<Diagnostics>>,
}

impl DiagnosticsCell {
    /// The latest counters (of the current boot).
    pub fn get(&self) -> Diagnostics {
        *self.inner.borrow()
    }

    fn set(&self, d: Diagnostics) {
        *self.inner.borrow_mut() = d;
    }
}

/// A daughterboard of the simulation.
pub struct DbBoard {
    /// Name in traces (`db09`).
    pub name: String,
    /// Runtime configuration (its address is the board's bus address).
    pub config: DbConfig,
    /// Where and how events go.
    pub target: TargetConfig,
    /// The board's ports as they are at power-up (each boot starts from [`SimPorts::fresh`]).
    pub ports: SimPorts,
    /// Role handling of its I2C peripheral.
    pub role: Role,
    /// True when the fault injector may reset it.
    pub resettable: bool,
    /// The latest diagnostics counters.
    pub diagnostics: DiagnosticsCell,
    /// When the board's PEC setting changed (ground truth for checking frames).
    pub pec: PecLog,
}

/// Every change of a board's PEC setting, with its time (ns): `false` at each boot, then
/// whatever `set_pec` frames it accepted. Cloning shares the log.
#[derive(Clone, Default)]
pub struct PecLog {
    changes: Rc<RefCell<Vec<(u64, bool)>>>,
}

impl PecLog {
    /// The setting just before `t_ns` (the setting a frame that ends at `t_ns` meets).
    pub fn before(&self, t_ns: u64) -> bool {
        self.changes
            .borrow()
            .iter()
            .rev()
            .find(|(t, _)| *t < t_ns)
            .is_some_and(|(_, on)| *on)
    }

    fn note(&self, t_ns: u64, on: bool) {
        let mut c = self.changes.borrow_mut();
        if c.last().map(|(_, o)| *o) != Some(on) {
            c.push((t_ns, on));
        }
    }
}

impl DbBoard {
    /// A dual-role board at `address` (external), named `dbXX` after its address, sending
    /// events to `mb`.
    pub fn new(address: Address, mb: Address, ports: SimPorts) -> DbBoard {
        DbBoard {
            name: board_name(address),
            config: DbConfig::new(address, BoardKind::SIMULATED),
            target: TargetConfig::new(mb),
            ports,
            role: Role::DualRole,
            resettable: false,
            diagnostics: DiagnosticsCell::default(),
            pec: PecLog::default(),
        }
    }

    /// The bus node for this board.
    pub fn node_config(&self) -> NodeConfig {
        let mut n = NodeConfig::new(self.name.clone(), Some(self.config.address.get()))
            .with_role(self.role);
        n.resettable = self.resettable;
        n
    }

    /// Runs the board on `node` of `bus` forever: boots, serves, and on every reset of the
    /// node waits until it is up again and boots afresh.
    pub async fn run(&self, bus: SimBus, node: NodeId, notes: Notes) {
        let clock = bus.clock().clone();
        loop {
            let generation = bus.reset_generation(node);
            clock.sleep_until_ns(bus.alive_from(node)).await;
            let db: Daughterboard<NoopRawMutex, SimPorts> =
                Daughterboard::new(self.ports.fresh(), self.config);
            let serve = async {
                let runtime = firmware_db::run(&db, bus.port(node), clock.clone(), self.target);
                let mut runtime = pin!(runtime);
                // Publish the counters after every poll of the runtime: they are exact at any
                // instant, whenever the run ends.
                poll_fn(|cx| {
                    let r = runtime.as_mut().poll(cx);
                    self.diagnostics.set(db.diagnostics());
                    self.pec.note(clock.now_ns(), db.pec_enabled());
                    r
                })
                .await
            };
            self.pec.note(clock.now_ns(), db.pec_enabled());
            select(serve, bus.wait_reset(node, generation)).await;
            // Power is gone: PWM outputs stop now, not when the next boot sets them.
            db.ports().power_off();
            self.diagnostics.set(db.diagnostics());
            notes.push(TraceLine::new(
                clock.now_ns(),
                Severity::Warn,
                self.name.clone(),
                format!(
                    "reset: firmware restarts at {}",
                    crate::trace::timestamp(bus.alive_from(node))
                ),
            ));
        }
    }
}

/// `db09` for address 0x09, `mb` for the internal board.
pub fn board_name(address: Address) -> String {
    if address.is_internal() {
        "mb".to_string()
    } else {
        format!("db{:02x}", address.get())
    }
}

#[cfg(test)]
#[path = "board_tests.rs"]
mod tests;
