//! A simulated daughterboard: the real `firmware-db` runtime on [`SimPorts`] and a
//! [`crate::bus::SimPort`], restarted from scratch whenever the bus resets its node.

use std::cell::{Cell, RefCell};
use std::future::{poll_fn, Future};
use std::pin::pin;
use std::rc::Rc;

use embassy_futures::select::{select, select3, Either, Either3};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{
    start_address, AddressRecord, Daughterboard, DbConfig, StoreError, TargetConfig,
};
use x10_microcode::{Address, BoardKind, Diagnostics, ResetReason, Uid};

use crate::bus::{NodeConfig, NodeId, Role, SimBus};
use crate::ports::SimPorts;
use crate::trace::{Severity, TraceLine};

/// Lines the simulator adds to the trace (resets, robot errors, …). Cloning shares them.
#[derive(Clone, Default)]
pub struct Notes {
    lines: Rc<RefCell<Vec<TraceLine>>>,
    /// Lines kept at most (0: no cap) and lines counted but not kept.
    bound: Rc<(Cell<usize>, Cell<u64>)>,
}

impl Notes {
    /// No notes yet.
    pub fn new() -> Notes {
        Notes::default()
    }

    /// Adds a line (counts it only, once [`Notes::bound_to`]'s cap is reached).
    pub fn push(&self, line: TraceLine) {
        let mut lines = self.lines.borrow_mut();
        let cap = self.bound.0.get();
        if cap > 0 && lines.len() >= cap {
            self.bound.1.set(self.bound.1.get() + 1);
        } else {
            lines.push(line);
        }
    }

    /// Keeps at most `cap` lines (a bounded run, [`crate::sim::Keep::Summary`]).
    pub fn bound_to(&self, cap: usize) {
        self.bound.0.set(cap);
    }

    /// Lines counted but not kept.
    pub fn dropped(&self) -> u64 {
        self.bound.1.get()
    }

    /// Every line so far.
    pub fn lines(&self) -> Vec<TraceLine> {
        self.lines.borrow().clone()
    }
}

/// A board's simulated address record: what it keeps across its resets, in memory (the
/// image's power-cut-safe flash record, as far as the runtime can tell). Cloning shares it.
#[derive(Clone, Debug, Default)]
pub struct SimRecord {
    kept: Rc<Cell<Option<Address>>>,
    writes: Rc<Cell<u32>>,
    /// The board has a build-time address: it keeps none (`set_address` is `unsupported`).
    fixed: bool,
    /// Its flash with A/B slots and a bootloader (issue 25), if it has one.
    pub firmware: Option<crate::firmware::SimFirmware>,
    /// Or: an STM32C011's flash and ROM bootloader (issue 25).
    pub rom: Option<crate::firmware::SimRom>,
}

impl SimRecord {
    /// The address kept, if any.
    pub fn kept(&self) -> Option<Address> {
        self.kept.get()
    }

    /// Record writes so far.
    pub fn writes(&self) -> u32 {
        self.writes.get()
    }
}

impl AddressRecord for SimRecord {
    fn load(&mut self) -> Option<Address> {
        self.kept.get()
    }

    fn store(&mut self, address: Address) -> Result<(), StoreError> {
        if self.fixed {
            return Err(StoreError::NoRecord);
        }
        self.kept.set(Some(address));
        self.writes.set(self.writes.get() + 1);
        Ok(())
    }

    fn enter_update(&mut self) -> Result<(), StoreError> {
        if let Some(rom) = &self.rom {
            // The C011 image's System 12: a jump into the ROM bootloader (at the reset that
            // follows the reply).
            rom.0.borrow_mut().enter_rom();
            return Ok(());
        }
        match &self.firmware {
            None => Err(StoreError::NoRecord),
            Some(f) if f.enter_update() => Ok(()),
            Some(_) => Err(StoreError::Failed),
        }
    }

    fn confirm_firmware(&mut self) -> Result<(), StoreError> {
        match &self.firmware {
            Some(f) if !f.confirm() => Err(StoreError::Failed),
            _ => Ok(()),
        }
    }
}

/// The sim's unique ID of a board named `name` (FNV-1a over the name, 64 bits, little-endian):
/// the same name always gives the same ID.
pub fn uid_of_name(name: &str) -> Uid {
    let h = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    Uid(h.to_le_bytes())
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
    /// Its build-time address (an override, which always wins); `None`: it starts at the
    /// address its record keeps, or unaddressed.
    pub override_address: Option<Address>,
    /// Its unique ID.
    pub uid: Uid,
    /// Its address record, kept across resets.
    pub record: SimRecord,
    /// When it is powered up (ns; a board plugged in while the robot runs), 0 at the start.
    pub power_on_ns: u64,
    /// Every address it started at, with the time (ground truth: `0x77` while unaddressed).
    pub addresses: AddressLog,
}

/// Every address a board started at, with the time (ns). Cloning shares it.
#[derive(Clone, Debug, Default)]
pub struct AddressLog {
    starts: Rc<RefCell<Vec<(u64, Address)>>>,
}

impl AddressLog {
    /// Every start so far: (time in ns, address).
    pub fn starts(&self) -> Vec<(u64, Address)> {
        self.starts.borrow().clone()
    }

    /// The address of the last start (`None` before the first).
    pub fn current(&self) -> Option<Address> {
        self.starts.borrow().last().map(|(_, a)| *a)
    }
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
        let name = board_name(address);
        let uid = uid_of_name(&name);
        DbBoard {
            name,
            config: DbConfig::new(address, BoardKind::SIMULATED),
            target: TargetConfig::new(mb),
            ports,
            role: Role::DualRole,
            resettable: false,
            diagnostics: DiagnosticsCell::default(),
            pec: PecLog::default(),
            override_address: Some(address),
            uid,
            record: SimRecord {
                fixed: true,
                ..SimRecord::default()
            },
            power_on_ns: 0,
            addresses: AddressLog::default(),
        }
    }

    /// A dual-role board called `name` without a build-time address (plug and play): it
    /// starts at the address its record keeps (none at first: unaddressed, at `0x77`), with
    /// ID `uid`, sending events to `mb`.
    pub fn unaddressed(name: &str, uid: Uid, mb: Address, ports: SimPorts) -> DbBoard {
        DbBoard {
            name: name.to_string(),
            config: DbConfig::new(Address::UNADDRESSED, BoardKind::SIMULATED),
            override_address: None,
            uid,
            record: SimRecord::default(),
            ..DbBoard::new(Address::UNADDRESSED, mb, ports)
        }
    }

    /// The address the board starts at now (its override, else its record, else
    /// unaddressed).
    pub fn start_address(&self) -> Address {
        start_address(self.override_address, &mut self.record.clone())
    }

    /// The bus node for this board.
    pub fn node_config(&self) -> NodeConfig {
        let mut n = NodeConfig::new(self.name.clone(), Some(self.start_address().get()))
            .with_role(self.role)
            .with_general_call();
        n.resettable = self.resettable;
        n
    }

    /// Runs the board on `node` of `bus` forever: boots, serves, and on every reset of the
    /// node waits until it is up again and boots afresh.
    pub async fn run(&self, bus: SimBus, node: NodeId, notes: Notes) {
        let clock = bus.clock().clone();
        let mut moved = false;
        loop {
            let generation = bus.reset_generation(node);
            clock.sleep_until_ns(bus.alive_from(node)).await;
            // Where it starts: its override, else what its record keeps, else unaddressed.
            let address = self.start_address();
            bus.set_node_address(node, Some(address.get()));
            self.addresses
                .starts
                .borrow_mut()
                .push((clock.now_ns(), address));
            let mut config = self.config;
            config.address = address;
            config.uid = self.uid;
            if moved {
                config.reset_reason = ResetReason::Software;
            }
            if let Some(rom) = &self.record.rom {
                // A power cut (not the restart after System 12 or Go): the C0 boots again,
                // the ROM bootloader if the first word of flash is erased.
                if !moved {
                    rom.0.borrow_mut().power_on();
                }
                if rom.boot() == x10_stmboot::model::Boot::Rom {
                    bus.set_node_address(node, Some(Address::STM32_BOOTLOADER));
                    let end =
                        select(self.rom(&bus, node, rom), bus.wait_reset(node, generation)).await;
                    let text = match end {
                        Either::First(()) => {
                            bus.restart_node(node);
                            moved = true;
                            "ROM bootloader: Go, restarting".to_string()
                        }
                        Either::Second(()) => {
                            moved = false;
                            "reset in the ROM bootloader".to_string()
                        }
                    };
                    notes.push(TraceLine::new(
                        clock.now_ns(),
                        Severity::Info,
                        self.name.clone(),
                        text,
                    ));
                    continue;
                }
                config.firmware = rom.version();
                config.board = BoardKind::C011;
            }
            if let Some(fw) = &self.record.firmware {
                // The bootloader first: the swap (or revert) costs its flash time.
                let (mode, spent) = fw.start();
                clock.sleep_ns(spent).await;
                if mode == x10_boot::StartMode::Update {
                    let end = select(
                        self.bootloader(&bus, node, fw, address),
                        bus.wait_reset(node, generation),
                    )
                    .await;
                    let text = match end {
                        Either::First(exit) => {
                            bus.restart_node(node);
                            moved = true;
                            format!("bootloader: {exit:?}, restarting")
                        }
                        Either::Second(()) => "reset in the bootloader".to_string(),
                    };
                    notes.push(TraceLine::new(
                        clock.now_ns(),
                        Severity::Info,
                        self.name.clone(),
                        text,
                    ));
                    continue;
                }
                config.firmware = fw.version();
            }
            let db: Daughterboard<NoopRawMutex, SimPorts, SimRecord> =
                Daughterboard::with_record(self.ports.fresh(), config, self.record.clone());
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
            let end = select3(serve, bus.wait_reset(node, generation), db.moved()).await;
            // Power is gone: PWM outputs stop now, not when the next boot sets them.
            db.ports().power_off();
            self.diagnostics.set(db.diagnostics());
            moved = matches!(end, Either3::Third(_));
            let text = match end {
                Either3::Third(to) => {
                    // The board keeps its new address and starts again there at once.
                    bus.restart_node(node);
                    format!("takes address {to}: firmware restarts there")
                }
                _ if bus.alive_from(node) >= crate::sim::UNPLUGGED_NS => "unplugged".to_string(),
                _ => format!(
                    "reset: firmware restarts at {}",
                    crate::trace::timestamp(bus.alive_from(node))
                ),
            };
            let severity = if moved {
                Severity::Info
            } else {
                Severity::Warn
            };
            notes.push(TraceLine::new(
                clock.now_ns(),
                severity,
                self.name.clone(),
                text,
            ));
        }
    }
}

impl DbBoard {
    /// The board in its ROM bootloader: the model answers at 0x64 until `Go` (the return).
    /// Each transfer's bytes go to the model at the simulator's time; a read gets as many
    /// bytes as the model's protocol says the client reads.
    async fn rom(&self, bus: &SimBus, node: NodeId, rom: &crate::firmware::SimRom) {
        use x10_hal::bus::{Incoming, MultiMaster};
        let clock = bus.clock().clone();
        let mut port = bus.port(node);
        let mut rx = [0u8; 2 * x10_microcode::MAX_FRAME_LEN];
        let mut tx = [0u8; 2 * x10_microcode::MAX_FRAME_LEN];
        loop {
            if port.addressed().await.is_err() {
                continue;
            }
            let incoming = port.listen(&mut rx).await;
            let reply = {
                let mut m = rom.0.borrow_mut();
                m.catch_up_ns(clock.now_ns());
                let (written, read) = match incoming {
                    Ok(Incoming::Write(n)) => (n, false),
                    Ok(Incoming::WriteRead(n)) => (n, true),
                    Ok(Incoming::Read) => (0, true),
                    Err(_) => continue,
                };
                if written > 0 {
                    let _ = m.write(rx.get(..written).unwrap_or(&[]));
                }
                if read {
                    let k = m.next_read_len().min(tx.len());
                    let _ = m.read(&mut tx[..k]);
                    Some(k)
                } else {
                    None
                }
            };
            if let Some(k) = reply {
                let _ = port.respond(&tx[..k]).await;
            }
            if rom.boot() == x10_stmboot::model::Boot::Flash {
                return;
            }
        }
    }

    /// The board in update mode: x10-boot's session on its port until `commit` or `leave`
    /// (the exit), deaf while it works its flash.
    async fn bootloader(
        &self,
        bus: &SimBus,
        node: NodeId,
        fw: &crate::firmware::SimFirmware,
        address: Address,
    ) -> x10_boot::Exit {
        use x10_hal::bus::{Incoming, MultiMaster};
        let clock = bus.clock().clone();
        let mut aligned = [0u8; 1];
        let state = embassy_boot::BlockingFirmwareState::new(fw.part(0), &mut aligned);
        let cfg = x10_boot::BootConfig {
            board: self.config.board,
            floor: [0, 0, 0],
            address,
        };
        let mut s: x10_boot::Session<'_, _, _, 256> =
            x10_boot::Session::new(cfg, fw.part(2), state);
        let mut port = bus.port(node);
        let mut rx = [0u8; x10_microcode::MAX_FRAME_LEN];
        let mut tx = [0u8; x10_microcode::MAX_FRAME_LEN];
        loop {
            if port.addressed().await.is_err() {
                continue;
            }
            match port.listen(&mut rx).await {
                Ok(Incoming::Write(n)) => s.handle_write(rx.get(..n).unwrap_or(&[])),
                Ok(Incoming::WriteRead(n)) => {
                    s.handle_write(rx.get(..n).unwrap_or(&[]));
                    let m = s.take_reply(&mut tx);
                    let _ = port.respond(&tx[..m]).await;
                }
                Ok(Incoming::Read) => {
                    let m = s.take_reply(&mut tx);
                    let _ = port.respond(&tx[..m]).await;
                }
                Err(_) => continue,
            }
            let before = fw.busy_ns();
            s.work();
            let spent = fw.busy_ns() - before;
            if spent > 0 {
                clock.sleep_ns(spent).await;
            }
            match s.exit() {
                x10_boot::Exit::Stay => {}
                exit => return exit,
            }
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
