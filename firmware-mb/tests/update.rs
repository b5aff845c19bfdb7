//! The motherboard's updater (issue 25) against boards made of the real parts: x10-boot's
//! session as the bootloader, embassy-boot's `prepare_boot` at every start, an application that
//! answers `identify` with the version its slot holds and takes `enter_update` and
//! `confirm_firmware` through x10-boot's hooks. Every frame is encoded and checked as on the
//! bus (with its check). Time is virtual: each transaction costs its wire time at the bus
//! clock, each flash operation the RP2040 flash's typical time (W25Q16JV datasheet: 4 KiB
//! sector erase 45 ms, 256-byte page program 0.4 ms), each start the swap's flash work.
//!
//! Checked: an update end to end (new version, confirmed, counters), a power cut (board reset)
//! in the middle of the transfer and during the swap (the update finishes), a new image that
//! never comes back is rolled back and reported, bounded tries, refusals reported, policy,
//! the plan; and the printed time of a 32 KiB update at 100 kHz, 400 kHz and 1 MHz against
//! the wire-time floor.

use std::cell::{Cell, RefCell};

use embassy_boot::BlockingFirmwareState;
use firmware_mb::update::{
    plan, update_board, update_pass, DbImage, NoRom, UpdateConfig, UpdateError, UpdateLink,
    UpdatePolicy, UpdateState, UpdateStats,
};
use firmware_mb::KnownBoard;
use x10_boot::model::{Flash, Part, ACTIVE};
use x10_boot::{BootConfig, Exit, Session, StartMode};
use x10_devices::LinkError;
use x10_microcode::{
    pec, Address, BoardKind, Capabilities, Identity, Op, Payload, Reply, Request, Status, Uid,
    UpdateOp, Version, PROTOCOL_VERSION,
};

/// The board's start before its image answers (ns).
const BOOT_NS: u64 = 20_000_000;

/// A fake image: a header (`X10I`, version, good flag) and filler.
fn image(len: usize, version: Version, good: bool, seed: u8) -> &'static [u8] {
    let mut v: Vec<u8> = (0..len)
        .map(|i| (i as u8).wrapping_mul(31) ^ seed)
        .collect();
    v[..4].copy_from_slice(b"X10I");
    v[4..7].copy_from_slice(&version);
    v[7] = good as u8;
    Box::leak(v.into_boxed_slice())
}

fn db_image(bytes: &'static [u8]) -> DbImage {
    DbImage {
        kind: BoardKind::SIMULATED,
        version: [bytes[4], bytes[5], bytes[6]],
        bytes,
        crc32: x10_microcode::image_crc32(bytes),
    }
}

enum Mode {
    App,
    Boot(Box<Session<'static, Part, Part, 256>>),
    Down,
}

/// One board: flash, what runs, when it is up again.
struct Board {
    addr: Address,
    /// Its flash (x10_boot::model: the Pico's layout and flash times), kept across resets.
    flash: Flash,
    mode: RefCell<Mode>,
    up_at: Cell<u64>,
    /// Resets (power cuts) to inject: at these chunk offsets.
    cut_at_offset: RefCell<Vec<u32>>,
    /// Cut the power during the start that swaps (once).
    cut_in_swap: Cell<bool>,
    starts: Cell<u32>,
    /// Busy with flash work after its last reply until then (ns): it does not answer.
    deaf_until: Cell<u64>,
    /// Commits whose reply is lost on the way back (the board executed them).
    lose_commit_replies: Cell<u8>,
    /// Commits lost on the way (the board never sees them).
    lose_commits: Cell<u8>,
}

impl Board {
    fn new(addr: u8, img: &[u8]) -> Board {
        Board {
            addr: Address::new(addr).unwrap(),
            flash: Flash::with_active(img),
            mode: RefCell::new(Mode::App),
            up_at: Cell::new(0),
            cut_at_offset: RefCell::new(Vec::new()),
            cut_in_swap: Cell::new(false),
            starts: Cell::new(0),
            deaf_until: Cell::new(0),
            lose_commit_replies: Cell::new(0),
            lose_commits: Cell::new(0),
        }
    }

    fn part(&self, which: usize) -> Part {
        self.flash.part(which)
    }

    fn version(&self) -> Version {
        [4, 5, 6].map(|i| self.flash.active_byte(i))
    }

    fn good(&self) -> bool {
        self.flash.active_byte(7) == 1
    }

    /// The board goes down now and starts at `at`.
    fn reset(&self, now: u64) {
        *self.mode.borrow_mut() = Mode::Down;
        self.up_at.set(now + BOOT_NS);
    }

    /// Brings the board up if its time has come: the bootloader's start.
    fn poll_up(&self, now: &Cell<u64>) {
        if !matches!(*self.mode.borrow(), Mode::Down) || now.get() < self.up_at.get() {
            return;
        }
        self.starts.set(self.starts.get() + 1);
        loop {
            let before = self.flash.busy_ns();
            let mut buf = [0u8; 256];
            let state = self.flash.bootloader().prepare_boot(&mut buf).unwrap();
            now.set(now.get() + self.flash.busy_ns() - before);
            if self.cut_in_swap.get() && self.flash.busy_ns() > before {
                // The power goes in the middle of that swap: undo nothing, start again (the
                // swap goes on where its progress says).
                self.cut_in_swap.set(false);
                continue;
            }
            match x10_boot::start_mode(&state) {
                StartMode::Update => {
                    let aligned: &'static mut [u8] = Box::leak(Box::new([0u8; 1]));
                    let st = BlockingFirmwareState::new(self.part(0), aligned);
                    let cfg = BootConfig {
                        board: BoardKind::SIMULATED,
                        floor: [0, 1, 0],
                        address: self.addr,
                    };
                    *self.mode.borrow_mut() =
                        Mode::Boot(Box::new(Session::new(cfg, self.part(2), st)));
                }
                StartMode::Application if !self.good() => {
                    // A bad image: its watchdog resets it before it answers anyone.
                    continue;
                }
                StartMode::Application => *self.mode.borrow_mut() = Mode::App,
            }
            return;
        }
    }

    /// The application's answer.
    fn app(&self, op: &Op<'_>, now: u64) -> (Status, Vec<u8>, bool) {
        let mut aligned = [0u8; 1];
        let mut st = BlockingFirmwareState::new(self.part(0), &mut aligned);
        match op {
            Op::Identify => {
                let id = Identity {
                    protocol_version: PROTOCOL_VERSION,
                    firmware: self.version(),
                    board: BoardKind::SIMULATED,
                    sensor_ports: 2,
                    actuator_ports: 2,
                    capabilities: Capabilities(0),
                    adc_bits: 12,
                };
                (Status::Ok, id.to_bytes().to_vec(), false)
            }
            Op::Ping => (Status::Ok, vec![], false),
            Op::EnterUpdate => {
                x10_boot::enter_update(&mut st).unwrap();
                let _ = now;
                (Status::Ok, vec![], true)
            }
            Op::ConfirmFirmware => {
                x10_boot::confirm_firmware(&mut st).unwrap();
                (Status::Ok, vec![], false)
            }
            Op::Update(_) => (Status::Unsupported, vec![], false),
            _ => (Status::Ok, vec![], false),
        }
    }
}

/// The bus: one board, virtual time, the wire time of every transaction at `hz`.
struct Bus {
    board: Board,
    now: Cell<u64>,
    hz: u64,
    wire_ns: Cell<u64>,
    transactions: Cell<u64>,
    updating: Cell<Option<Address>>,
    /// The board takes `enter_update` but its reply never reaches the MB (on the emulated
    /// Pico it writes embassy-boot's state, a sector erase, before the reply is read).
    lose_enter_reply: Cell<bool>,
    /// Likewise the first `confirm_firmware`'s reply (the board writes the state before it).
    lose_confirm_reply: Cell<bool>,
}

impl Bus {
    fn new(board: Board, hz: u64) -> Bus {
        Bus {
            board,
            now: Cell::new(0),
            hz,
            wire_ns: Cell::new(0),
            transactions: Cell::new(0),
            updating: Cell::new(None),
            lose_enter_reply: Cell::new(false),
            lose_confirm_reply: Cell::new(false),
        }
    }

    /// START, address and `w` bytes, repeated START, address and `r` bytes, STOP: 9 bits a byte.
    fn spend_wire(&self, w: usize, r: usize) {
        let bits = (1 + w + 1 + r) as u64 * 9 + 3;
        let ns = bits * 1_000_000_000 / self.hz;
        self.wire_ns.set(self.wire_ns.get() + ns);
        self.now.set(self.now.get() + ns);
        self.transactions.set(self.transactions.get() + 1);
    }
}

impl UpdateLink for Bus {
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        assert_eq!(db, self.board.addr);
        let b = &self.board;
        b.poll_up(&self.now);
        let req = Request { db, seq: 7, op };
        let mut buf = [0u8; 40];
        let n = req.emit_with_pec(&mut buf).unwrap();
        if let Some(UpdateOp::Chunk { offset, .. }) = match op {
            Op::Update(f) => Some(f.op()),
            _ => None,
        } {
            let cut = b.cut_at_offset.borrow().first() == Some(&offset);
            if cut {
                b.cut_at_offset.borrow_mut().remove(0);
                b.reset(self.now.get());
            }
        }
        if matches!(*b.mode.borrow(), Mode::Down) || self.now.get() < b.deaf_until.get() {
            self.spend_wire(0, 0);
            return Err(LinkError::Nack);
        }
        let commit = matches!(op, Op::Update(f) if f.op() == UpdateOp::Commit);
        if commit && b.lose_commits.get() > 0 {
            b.lose_commits.set(b.lose_commits.get() - 1);
            self.spend_wire(n, 0);
            return Err(LinkError::Nack);
        }
        let read = 3 + op.reply_capacity() + 1;
        self.spend_wire(n, read);
        let (status, payload, reset) = {
            let mut mode = b.mode.borrow_mut();
            match &mut *mode {
                Mode::Boot(s) => {
                    let before = b.flash.busy_ns();
                    s.handle_write(&buf[..n]);
                    let mut rx = [0u8; 40];
                    let m = s.take_reply(&mut rx);
                    // Reading back the slot for the CRC at commit, or the final write.
                    self.now.set(self.now.get() + b.flash.busy_ns() - before);
                    // The flash work after the reply: the board is deaf meanwhile.
                    let before = b.flash.busy_ns();
                    s.work();
                    b.deaf_until
                        .set(self.now.get() + b.flash.busy_ns() - before);
                    let body = pec::strip(db.addr_byte(true), &rx[..m]).unwrap();
                    let r = Reply::parse(body).unwrap();
                    (r.status, r.payload.to_vec(), s.exit() != Exit::Stay)
                }
                Mode::App => {
                    drop(mode);
                    b.app(&op, self.now.get())
                }
                Mode::Down => unreachable!(),
            }
        };
        if reset {
            b.reset(self.now.get());
        }
        if self.lose_enter_reply.get() && op == Op::EnterUpdate {
            return Err(LinkError::Timeout);
        }
        if self.lose_confirm_reply.get() && op == Op::ConfirmFirmware {
            self.lose_confirm_reply.set(false);
            return Err(LinkError::Timeout);
        }
        if commit && b.lose_commit_replies.get() > 0 {
            b.lose_commit_replies.set(b.lose_commit_replies.get() - 1);
            return Err(LinkError::BadReply);
        }
        match status {
            Status::Ok => Ok(Payload::from_slice(&payload).unwrap()),
            s => Err(LinkError::Status(s)),
        }
    }

    fn set_updating(&self, db: Option<Address>) {
        self.updating.set(db);
    }

    async fn pause(&self, us: u64) {
        self.now.set(self.now.get() + us * 1_000);
    }

    fn now_us(&self) -> u64 {
        self.now.get() / 1_000
    }
}

fn run<F: core::future::Future>(f: F) -> F::Output {
    embassy_futures::block_on(f)
}

const OLD: Version = [0, 1, 0];
const NEW: Version = [0, 2, 0];

fn update(bus: &Bus, img: &DbImage) -> (Result<(), UpdateError>, UpdateStats) {
    let mut stats = UpdateStats::default();
    let cfg = UpdateConfig::DEFAULT;
    let r = run(update_board::<NoRom, _>(
        bus,
        &cfg,
        bus.board.addr,
        BoardKind::SIMULATED,
        img,
        &mut stats,
    ));
    (r, stats)
}

#[test]
fn an_update_end_to_end() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let bus = Bus::new(Board::new(0x2a, image(20_000, OLD, true, 1)), 400_000);
    let (r, stats) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!(bus.board.version(), NEW);
    // The board is deaf while it erases a sector (45 ms) after the reply of the chunk that
    // reached it: the updater waits that out (`FlashTiming`), so no request meets a busy
    // board (with `wait_flash: false` the next chunk was tried again 3 times per sector: 24).
    assert_eq!(
        (
            stats.done,
            stats.failed,
            stats.restarts,
            stats.chunk_retries
        ),
        (1, 0, 0, 0)
    );
    assert_eq!(bus.updating.get(), None);
    // Confirmed: a reset keeps it.
    bus.board.reset(bus.now.get());
    bus.now.set(bus.now.get() + BOOT_NS);
    bus.board.poll_up(&bus.now);
    assert_eq!(bus.board.version(), NEW);
    assert!(matches!(*bus.board.mode.borrow(), Mode::App));
}

#[test]
fn a_commit_whose_reply_is_lost_is_confirmed_all_the_same() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let board = Board::new(0x2a, image(20_000, OLD, true, 1));
    // The board takes the commit and resets into its swap; the `ok` never reaches the
    // motherboard, whose tries of the commit again find the board deaf.
    board.lose_commit_replies.set(1);
    let bus = Bus::new(board, 400_000);
    let (r, stats) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!(bus.board.version(), NEW);
    assert_eq!((stats.done, stats.restarts), (1, 0), "{stats:?}");
    // Confirmed: a reset keeps it.
    bus.board.reset(bus.now.get());
    bus.now.set(bus.now.get() + BOOT_NS);
    bus.board.poll_up(&bus.now);
    assert_eq!(bus.board.version(), NEW);
}

#[test]
fn a_commit_that_never_arrives_is_found_out_and_the_transfer_done_again() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let board = Board::new(0x2a, image(20_000, OLD, true, 1));
    // The commit and all its tries are lost: the board is still in its bootloader, its
    // transfer whole but not committed.
    board
        .lose_commits
        .set(1 + UpdateConfig::DEFAULT.chunk_retries);
    let bus = Bus::new(board, 400_000);
    let (r, stats) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!(bus.board.version(), NEW);
    assert_eq!((stats.done, stats.restarts), (1, 1), "{stats:?}");
}

#[test]
fn an_enter_update_whose_reply_is_lost_goes_on_when_the_bootloader_answers() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let bus = Bus::new(Board::new(0x2a, image(20_000, OLD, true, 1)), 400_000);
    bus.lose_enter_reply.set(true);
    let (r, stats) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!(bus.board.version(), NEW);
    assert_eq!((stats.done, stats.failed, stats.restarts), (1, 0, 0));
}

#[test]
fn a_confirm_whose_reply_is_lost_is_sent_again() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let bus = Bus::new(Board::new(0x2a, image(20_000, OLD, true, 1)), 400_000);
    bus.lose_confirm_reply.set(true);
    let (r, stats) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!((stats.done, stats.failed), (1, 0));
    // Confirmed: a reset keeps it.
    bus.board.reset(bus.now.get());
    bus.now.set(bus.now.get() + BOOT_NS);
    bus.board.poll_up(&bus.now);
    assert_eq!(bus.board.version(), NEW);
}

#[test]
fn power_cuts_mid_transfer_are_recovered_within_the_update() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let board = Board::new(0x2a, image(20_000, OLD, true, 1));
    *board.cut_at_offset.borrow_mut() = vec![24 * 700, 24 * 1000];
    let bus = Bus::new(board, 400_000);
    let (r, stats) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!(bus.board.version(), NEW);
    // Each cut: the chunk is not acknowledged and tried again 20 ms later; the board is back
    // in its bootloader by then, without the session (`no_session`): the transfer starts again
    // from `begin`.
    assert_eq!(stats.restarts, 2, "{stats:?}");
    assert!(bus.board.cut_at_offset.borrow().is_empty());
}

#[test]
fn a_reset_before_the_confirm_rolls_back_and_the_next_try_finishes() {
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let board = Board::new(0x2a, image(20_000, OLD, true, 1));
    // The board resets once more right after its swap, before it could answer: embassy-boot
    // reverts the unconfirmed image.
    board.cut_in_swap.set(true);
    let bus = Bus::new(board, 400_000);
    let mut b = KnownBoard::EMPTY;
    b.uid = Uid([3; 8]);
    b.address = bus.board.addr;
    b.kind = BoardKind::SIMULATED;
    b.firmware = OLD;
    b.present = true;
    let mut state = UpdateState::default();
    let mut ends = Vec::new();
    for _ in 0..2 {
        run(update_pass::<NoRom, _>(
            &bus,
            &UpdateConfig::DEFAULT,
            &[new],
            UpdatePolicy::Auto,
            &[b],
            &mut state,
            |_, _, r| ends.push(*r),
        ));
    }
    assert_eq!(ends, [Err(UpdateError::RolledBack(OLD)), Ok(())]);
    assert_eq!(bus.board.version(), NEW);
    assert_eq!((state.stats.done, state.stats.rolled_back), (1, 1));
}

#[test]
fn an_image_that_never_comes_back_is_rolled_back_and_tries_are_bounded() {
    let bad = db_image(image(ACTIVE, NEW, false, 3));
    let bus = Bus::new(Board::new(0x2a, image(20_000, OLD, true, 1)), 400_000);
    let mut b = KnownBoard::EMPTY;
    b.uid = Uid([1; 8]);
    b.address = bus.board.addr;
    b.kind = BoardKind::SIMULATED;
    b.firmware = OLD;
    b.present = true;
    let cfg = UpdateConfig::DEFAULT;
    let mut state = UpdateState::default();
    let mut ends = Vec::new();
    for _ in 0..4 {
        run(update_pass::<NoRom, _>(
            &bus,
            &cfg,
            &[bad],
            UpdatePolicy::Auto,
            &[b],
            &mut state,
            |_, _, r| ends.push(*r),
        ));
    }
    assert_eq!(
        ends,
        [
            Err(UpdateError::RolledBack(OLD)),
            Err(UpdateError::RolledBack(OLD))
        ]
    );
    assert_eq!(state.tries(b.uid), 2);
    assert_eq!(
        (
            state.stats.done,
            state.stats.failed,
            state.stats.rolled_back
        ),
        (0, 2, 2)
    );
    assert_eq!(bus.board.version(), OLD);
    assert!(matches!(*bus.board.mode.borrow(), Mode::App));
}

#[test]
fn refusals_are_reported_and_leave_the_old_image() {
    let bus = Bus::new(Board::new(0x2a, image(20_000, OLD, true, 1)), 400_000);
    // Older than the bootloader's floor (0.1.0).
    let old = db_image(image(1_000, [0, 0, 9], true, 4));
    let (r, _) = update(&bus, &old);
    assert_eq!(r, Err(UpdateError::Refused(Status::TooOld)));
    // A wrong CRC.
    let mut corrupt = db_image(image(1_000, NEW, true, 5));
    corrupt.crc32 ^= 1;
    let (r, _) = update(&bus, &corrupt);
    assert_eq!(r, Err(UpdateError::Refused(Status::BadCrc)));
    assert_eq!(bus.board.version(), OLD);
    // The board stays in its bootloader (it was asked to), answers `status`, and a right
    // image goes through from there.
    let new = db_image(image(1_000, NEW, true, 6));
    let (r, _) = update(&bus, &new);
    assert_eq!(r, Ok(()));
    assert_eq!(bus.board.version(), NEW);
}

#[test]
fn plan_follows_kind_version_and_policy() {
    let img = db_image(image(100, NEW, true, 7));
    let u = Uid([2; 8]);
    assert_eq!(
        plan(&[img], UpdatePolicy::Auto, u, BoardKind::SIMULATED, OLD),
        Some(&img)
    );
    assert_eq!(
        plan(&[img], UpdatePolicy::Auto, u, BoardKind::SIMULATED, NEW),
        None
    );
    assert_eq!(
        plan(&[img], UpdatePolicy::Auto, u, BoardKind::PICO, OLD),
        None
    );
    assert_eq!(
        plan(&[img], UpdatePolicy::Never, u, BoardKind::SIMULATED, OLD),
        None
    );
    let pinned: &'static [Uid] = Box::leak(Box::new([u]));
    assert_eq!(
        plan(
            &[img],
            UpdatePolicy::Except(pinned),
            u,
            BoardKind::SIMULATED,
            OLD
        ),
        None
    );
    assert_eq!(
        firmware_mb::update::Method::for_kind(BoardKind::C011),
        firmware_mb::update::Method::StRom
    );
}

/// The time of a 32 KiB update at three bus clocks, against the wire-time floor (every chunk
/// and its status reply once, nothing else), with the flash's typical times: before (a fixed
/// 1 ms between chunks, requests sent into the board's erases and tried again) and now (the
/// gap scaled to the clock, `UpdateConfig::for_bus_hz`, and the flash work waited out,
/// `FlashTiming`). Printed; run with `--nocapture`. Asserted: now, the update takes at most
/// half of the bus at every clock, no request meets a busy board, and 400 kHz takes < 5 s.
#[test]
fn time_of_a_32_kib_update() {
    println!("32 KiB update (1366 chunks of 24 bytes), flash: 45 ms per 4 KiB erase, 0.4 ms per 256 B program (W25Q16JV typ.)");
    println!("| bus | floor (chunks on the wire) | before: 1 ms gap, sent into erases | bus share | retries | now: gap scaled, erases waited out | bus share | retries |");
    println!("|---|---|---|---|---|---|---|---|");
    for hz in [100_000u64, 400_000, 1_000_000] {
        let mut row = Vec::new();
        let before = UpdateConfig {
            chunk_gap_us: 1_000,
            wait_flash: false,
            ..UpdateConfig::DEFAULT
        };
        for cfg in [before, UpdateConfig::for_bus_hz(hz as u32)] {
            let new = db_image(image(ACTIVE, NEW, true, 2));
            let bus = Bus::new(Board::new(0x2a, image(20_000, OLD, true, 1)), hz);
            let mut stats = UpdateStats::default();
            let t0 = bus.now.get();
            let r = run(update_board::<NoRom, _>(
                &bus,
                &cfg,
                bus.board.addr,
                BoardKind::SIMULATED,
                &new,
                &mut stats,
            ));
            assert_eq!(r, Ok(()), "{hz} Hz, {cfg:?}: {stats:?}");
            let total = bus.now.get() - t0;
            row.push((total, bus.wire_ns.get(), stats.chunk_retries));
        }
        // The floor: each chunk request (4 + 28 data + 2 check) and its reply (3 + 1).
        let chunks = ACTIVE.div_ceil(24) as u64;
        let floor = chunks * firmware_mb::update::CHUNK_WIRE_BITS * 1_000_000_000 / hz;
        let share = |(t, w, _): (u64, u64, u32)| 100.0 * w as f64 / t as f64;
        println!(
            "| {} kHz | {:.2} s | {:.2} s | {:.0} % | {} | {:.2} s | {:.0} % | {} |",
            hz / 1000,
            floor as f64 / 1e9,
            row[0].0 as f64 / 1e9,
            share(row[0]),
            row[0].2,
            row[1].0 as f64 / 1e9,
            share(row[1]),
            row[1].2,
        );
        assert!(share(row[1]) <= 50.0, "{hz} Hz: {:.1} %", share(row[1]));
        assert_eq!(row[1].2, 0, "{hz} Hz: requests sent into flash work");
        assert!(row[0].2 > 0, "the model's board is deaf while erasing");
        if hz == 400_000 {
            assert!(row[1].0 < 5_000_000_000, "{} ns at 400 kHz", row[1].0);
        }
    }
}

#[test]
fn a_request_to_update_now_is_answered_exactly() {
    use firmware_mb::update::{requested, start_decision, UpdateRefusal};
    let new = db_image(image(ACTIVE, NEW, true, 2));
    let images = [new];
    let board = |n: u8, kind: BoardKind, firmware, present| {
        let mut b = KnownBoard::EMPTY;
        b.uid = Uid([n; 8]);
        b.address = Address::new(0x20 + n).unwrap();
        b.kind = kind;
        b.firmware = firmware;
        b.present = present;
        b
    };
    let old = board(1, BoardKind::SIMULATED, OLD, true);
    let current = board(2, BoardKind::SIMULATED, NEW, true);
    let gone = board(3, BoardKind::SIMULATED, OLD, false);
    let other_kind = board(4, BoardKind::G431, OLD, true);
    let boards = [old, current, gone, other_kind];
    let ask = |images: &[DbImage], policy, updating, pending, target| {
        start_decision(images, policy, &boards, updating, pending, target)
    };
    let auto = UpdatePolicy::Auto;
    // No images carried: refused, whatever else.
    assert_eq!(
        ask(&[], auto, None, false, Some(old.uid)),
        Err(UpdateRefusal::NoImages)
    );
    // One board, whatever the policy: pinned or `Never` are overridden.
    let pins: &'static [Uid] = Box::leak(Box::new([old.uid]));
    for policy in [auto, UpdatePolicy::Never, UpdatePolicy::Except(pins)] {
        assert_eq!(ask(&images, policy, None, false, Some(old.uid)), Ok(1));
    }
    assert_eq!(
        ask(&images, auto, None, false, Some(current.uid)),
        Err(UpdateRefusal::UpToDate)
    );
    assert_eq!(
        ask(&images, auto, None, false, Some(gone.uid)),
        Err(UpdateRefusal::NotPresent)
    );
    assert_eq!(
        ask(&images, auto, None, false, Some(other_kind.uid)),
        Err(UpdateRefusal::NoImage)
    );
    assert_eq!(
        ask(&images, auto, None, false, Some(Uid([9; 8]))),
        Err(UpdateRefusal::UnknownUid)
    );
    // Busy: an update under way, or a request not yet taken.
    assert_eq!(
        ask(&images, auto, Some(current.address), false, Some(old.uid)),
        Err(UpdateRefusal::Busy(Some(current.address)))
    );
    assert_eq!(
        ask(&images, auto, None, true, None),
        Err(UpdateRefusal::Busy(None))
    );
    // Every board: the present ones out of date of a carried kind; `Never` overridden, a pin
    // kept.
    assert_eq!(ask(&images, UpdatePolicy::Never, None, false, None), Ok(1));
    assert_eq!(requested(UpdatePolicy::Never), UpdatePolicy::Auto);
    assert_eq!(
        ask(&images, UpdatePolicy::Except(pins), None, false, None),
        Err(UpdateRefusal::UpToDate)
    );
    assert_eq!(
        start_decision(&images, auto, &[current, gone], None, false, None),
        Err(UpdateRefusal::UpToDate)
    );
}
