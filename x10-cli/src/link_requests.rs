//! The laptop's plug-and-play and update requests over the USB link (link version 2,
//! docs/usb-link.md): `x10 boards` lists the boards the motherboard knows (address, unique ID,
//! kind, firmware, state), `x10 assign UID ADDRESS` gives a board an address, `x10 update`
//! starts the update of one board or of every board out of date and follows it. The same as
//! [`Robot`] methods for a laptop program.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use x10_link::{
    AssignStatus, BoardEntry, BoardState, ToDevice, UpdateFailure, UpdatePhase, UpdateRec,
    UpdateStatus,
};
use x10_microcode::BoardKind;

use crate::monitor::{error_text, Answer, LinkRun, Robot, RobotError};

/// A version as `major.minor.patch`.
pub fn version_text(v: [u8; 3]) -> String {
    format!("{}.{}.{}", v[0], v[1], v[2])
}

/// A unique ID as 16 hex digits (how `x10 boards` prints it and `x10 assign` takes it).
pub fn uid_text(uid: [u8; 8]) -> String {
    uid.iter().map(|b| format!("{b:02x}")).collect()
}

/// A unique ID from 16 hex digits (spaces, `:` and `-` between them ignored).
///
/// # Errors
/// A line saying what is wrong.
pub fn parse_uid(s: &str) -> Result<[u8; 8], String> {
    let digits: String = s
        .chars()
        .filter(|c| !matches!(c, ' ' | ':' | '-'))
        .collect();
    let bad = || format!("{s:?} is not a unique ID (16 hex digits, as `x10 boards` prints it)");
    if digits.len() != 16 || !digits.is_ascii() {
        return Err(bad());
    }
    let mut uid = [0u8; 8];
    for (i, b) in uid.iter_mut().enumerate() {
        let pair = digits.get(2 * i..2 * i + 2).ok_or_else(bad)?;
        *b = u8::from_str_radix(pair, 16).map_err(|_| bad())?;
    }
    Ok(uid)
}

/// A bus address, `0x40` or `64`.
///
/// # Errors
/// A line saying what is wrong.
pub fn parse_address(s: &str) -> Result<u8, String> {
    let v = match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(hex) => u8::from_str_radix(hex, 16),
        None => s.parse(),
    };
    v.map_err(|_| format!("{s:?} is not an address (0x08..=0x76, as 0x40 or 64)"))
}

/// A board kind's name.
pub fn kind_text(kind: u8) -> String {
    match BoardKind(kind) {
        BoardKind::G431 => "STM32G431".into(),
        BoardKind::PICO => "Pico".into(),
        BoardKind::SIMULATED => "simulated".into(),
        BoardKind::INTERNAL => "internal".into(),
        BoardKind::C011 => "STM32C011".into(),
        _ => format!("kind {kind}"),
    }
}

/// One line of `x10 boards`: `0x20  e661385283 3f5c2a  Pico  0.1.0  present`.
pub fn board_line(b: &BoardEntry) -> String {
    let state = match b.state {
        BoardState::Present => "present",
        BoardState::Lost => "lost",
        BoardState::Updating => "updating",
        BoardState::Collided => "collided (another board answers at its address)",
    };
    format!(
        "{:#04x}  {}  {:<9}  {:<7}  {state}",
        b.address,
        uid_text(b.uid),
        kind_text(b.kind),
        version_text(b.firmware)
    )
}

/// An update record in words: `board 0x20: updating 0.1.0 → 2.0.0 ...`, then `... done` or
/// `... failed: WHY`.
pub fn update_text(r: &UpdateRec) -> String {
    let head = format!(
        "board {:#04x}: updating {} \u{2192} {} ...",
        r.db,
        version_text(r.from),
        version_text(r.to)
    );
    match r.phase {
        UpdatePhase::Started => head,
        UpdatePhase::Done => format!("{head} done"),
        UpdatePhase::Failed(f) => format!("{head} failed: {}", failure_text(&f)),
    }
}

/// Why an update failed, in words.
pub fn failure_text(f: &UpdateFailure) -> String {
    match f {
        UpdateFailure::NoMethod => "no update method for its kind",
        UpdateFailure::Enter => "it refused enter_update",
        UpdateFailure::NoBootloader => "its bootloader did not answer",
        UpdateFailure::Refused => "its bootloader refused the image",
        UpdateFailure::Link => "the transfer failed on the bus",
        UpdateFailure::NotBack => "it did not come back in time",
        UpdateFailure::RolledBack => "it came back with its old version (rolled back)",
        UpdateFailure::Rom => "the ROM bootloader refused or failed",
    }
    .into()
}

/// How an assign ended, in words.
pub fn assign_text(uid: [u8; 8], address: u8, s: &AssignStatus) -> String {
    let who = format!("board {}", uid_text(uid));
    match s {
        AssignStatus::Done => format!("{who} answers at {address:#04x}"),
        AssignStatus::UnknownUid => format!("{who}: the motherboard knows no such board"),
        AssignStatus::Reserved => format!(
            "{address:#04x} is reserved (a board takes 0x08..=0x76, not the motherboard's own, not 0x64)"
        ),
        AssignStatus::Taken => format!("{address:#04x} is taken by another board"),
        AssignStatus::Collided => format!(
            "{who} shares its address with another board: it cannot be moved alone (unplug the other one)"
        ),
        AssignStatus::NotConfirmed(e) => {
            format!("{who} did not confirm {address:#04x}: {}", error_text(e))
        }
    }
}

/// The answer to a request to update now, in words.
pub fn update_status_text(s: &UpdateStatus) -> String {
    match s {
        UpdateStatus::Started(n) => format!("started: {n} board(s) to update"),
        UpdateStatus::NoImages => {
            "refused: this motherboard image carries no daughterboard images".into()
        }
        UpdateStatus::UnknownUid => "refused: the motherboard knows no such board".into(),
        UpdateStatus::NotPresent => "refused: the board does not answer".into(),
        UpdateStatus::NoImage => "refused: no image of the board's kind is carried".into(),
        UpdateStatus::UpToDate => "up to date: nothing to update".into(),
        UpdateStatus::Busy(0) => "busy: an update is about to start".into(),
        UpdateStatus::Busy(a) => format!("busy: board {a:#04x} is being updated"),
    }
}

/// How long [`Robot::assign`] waits for the board at its new address (a board restarts in a
/// few ms; an unaddressed one's `assign` is sent again at its next announce).
pub const ASSIGN_WAIT: Duration = Duration::from_secs(2);

fn unexpected() -> RobotError {
    RobotError::Call(x10_link::CallError::Unsupported)
}

impl<S: Read + Write> Robot<S> {
    /// Every board plug and play knows, in the order it first heard them (as many requests as
    /// pages: 8 boards a page).
    ///
    /// # Errors
    /// [`RobotError::Refused`] from a motherboard of link version 1, [`RobotError::NoAnswer`],
    /// [`RobotError::Io`].
    pub fn board_list(&mut self) -> Result<Vec<BoardEntry>, RobotError> {
        let mut all: Vec<BoardEntry> = Vec::new();
        loop {
            let first = u8::try_from(all.len()).map_err(|_| unexpected())?;
            let id = self.fresh_id();
            match self.ask(id, &ToDevice::Boards { id, first })? {
                Answer::BoardList { total, boards, .. } => {
                    let empty = boards.is_empty();
                    all.extend(boards);
                    if empty || all.len() >= usize::from(total) {
                        return Ok(all);
                    }
                }
                Answer::Refused => return Err(RobotError::Refused),
                _ => return Err(unexpected()),
            }
        }
    }

    /// Gives the board `uid` the address `address`: the motherboard's answer, and once it is
    /// `Done` (the board confirmed, or its `assign` was sent) the board list is read until
    /// the board is present there, at most [`ASSIGN_WAIT`]; `NotConfirmed(Timeout)` if not.
    ///
    /// # Errors
    /// [`RobotError::Refused`], [`RobotError::NoAnswer`], [`RobotError::Io`].
    pub fn assign(&mut self, uid: [u8; 8], address: u8) -> Result<AssignStatus, RobotError> {
        let id = self.fresh_id();
        let status = match self.ask(id, &ToDevice::Assign { id, uid, address })? {
            Answer::Assigned(s) => s,
            Answer::Refused => return Err(RobotError::Refused),
            _ => return Err(unexpected()),
        };
        if status != AssignStatus::Done {
            return Ok(status);
        }
        let deadline = std::time::Instant::now() + ASSIGN_WAIT;
        loop {
            let there = self
                .board_list()?
                .iter()
                .any(|b| b.uid == uid && b.address == address && b.state == BoardState::Present);
            if there {
                return Ok(AssignStatus::Done);
            }
            if std::time::Instant::now() >= deadline {
                return Ok(AssignStatus::NotConfirmed(x10_link::CallError::Timeout));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Starts the update of the board `uid` now (whatever the image's policy), or of every
    /// board out of date (`None`).
    ///
    /// # Errors
    /// [`RobotError::Refused`], [`RobotError::NoAnswer`], [`RobotError::Io`].
    pub fn start_update(&mut self, uid: Option<[u8; 8]>) -> Result<UpdateStatus, RobotError> {
        let id = self.fresh_id();
        match self.ask(id, &ToDevice::Update { id, uid })? {
            Answer::UpdateAnswer(s) => Ok(s),
            Answer::Refused => Err(RobotError::Refused),
            _ => Err(unexpected()),
        }
    }

    /// Waits up to `within` until `n` updates have ended since [`Robot::run`]'s update record
    /// number `from`; returns the records from there.
    ///
    /// # Errors
    /// [`RobotError::NoAnswer`] when they did not end in time, [`RobotError::Io`].
    pub fn wait_updates(
        &mut self,
        from: usize,
        n: usize,
        within: Duration,
    ) -> Result<Vec<UpdateRec>, RobotError> {
        let ended = |run: &LinkRun| {
            run.updates
                .iter()
                .skip(from)
                .filter(|r| r.phase != UpdatePhase::Started)
                .count()
        };
        self.read_for(within, |run| ended(run) >= n)?;
        if ended(&self.run) < n {
            return Err(RobotError::NoAnswer);
        }
        Ok(self.run.updates.iter().skip(from).copied().collect())
    }
}

const BOARDS_HELP: &str = "\
Needs a motherboard image of link version 2 (an older one refuses the request).

EXAMPLE
  x10 boards
  0x20  e6613852833f5c2a  Pico       0.1.0    present";

/// Arguments of `x10 boards`.
#[derive(clap::Args, Debug)]
#[command(after_help = BOARDS_HELP)]
pub struct BoardsArgs {
    /// The serial port (default: the first X10 motherboard found).
    #[arg(long, value_name = "PATH")]
    pub port: Option<PathBuf>,
}

/// Arguments of `x10 assign`.
#[derive(clap::Args, Debug)]
pub struct AssignArgs {
    /// The board's unique ID, 16 hex digits (as `x10 boards` prints it).
    pub uid: String,
    /// Its new address, 0x08..=0x76 (`0x40` or `64`).
    pub address: String,
    /// The serial port (default: the first X10 motherboard found).
    #[arg(long, value_name = "PATH")]
    pub port: Option<PathBuf>,
}

/// Arguments of `x10 update`.
#[derive(clap::Args, Debug)]
pub struct UpdateArgs {
    /// The board's unique ID, 16 hex digits (as `x10 boards` prints it).
    #[arg(required_unless_present = "all", conflicts_with = "all")]
    pub uid: Option<String>,
    /// Every board whose firmware differs from the image the motherboard carries for its kind
    /// (a `Never` policy of the image overridden; boards it pins are kept).
    #[arg(long)]
    pub all: bool,
    /// Do not wait for the updates to end.
    #[arg(long)]
    pub no_wait: bool,
    /// How long to wait for them, in seconds.
    #[arg(long, value_name = "S", default_value_t = 120.0)]
    pub timeout_s: f64,
    /// The serial port (default: the first X10 motherboard found).
    #[arg(long, value_name = "PATH")]
    pub port: Option<PathBuf>,
}

fn open(port: Option<&PathBuf>) -> Result<Robot<Box<dyn serialport::SerialPort>>, RobotError> {
    match port {
        Some(p) => Robot::open(p),
        None => Robot::open_first(),
    }
}

fn fail(cmd: &str, e: &dyn std::fmt::Display) -> ExitCode {
    eprintln!("x10 {cmd}: {e}");
    ExitCode::FAILURE
}

/// `x10 boards`: one line per board.
pub fn boards_main(args: &BoardsArgs) -> ExitCode {
    let boards = open(args.port.as_ref()).and_then(|mut r| r.board_list());
    match boards {
        Ok(b) => {
            print!("{}", boards_text(&b));
            ExitCode::SUCCESS
        }
        Err(e) => fail("boards", &e),
    }
}

/// What `x10 boards` prints.
pub fn boards_text(boards: &[BoardEntry]) -> String {
    if boards.is_empty() {
        return "no board known yet\n".into();
    }
    boards.iter().map(|b| board_line(b) + "\n").collect()
}

/// `x10 assign UID ADDRESS`.
pub fn assign_main(args: &AssignArgs) -> ExitCode {
    let (uid, address) = match (parse_uid(&args.uid), parse_address(&args.address)) {
        (Ok(u), Ok(a)) => (u, a),
        (Err(e), _) | (_, Err(e)) => return fail("assign", &e),
    };
    let status = open(args.port.as_ref()).and_then(|mut r| r.assign(uid, address));
    match status {
        Ok(s) => {
            let text = assign_text(uid, address, &s);
            if s == AssignStatus::Done {
                println!("{text}");
                ExitCode::SUCCESS
            } else {
                fail("assign", &text)
            }
        }
        Err(e) => fail("assign", &e),
    }
}

/// `x10 update UID` or `x10 update --all`: starts, then prints each update's lines until
/// they end.
pub fn update_main(args: &UpdateArgs) -> ExitCode {
    let uid = match args.uid.as_deref().map(parse_uid).transpose() {
        Ok(u) => u,
        Err(e) => return fail("update", &e),
    };
    let mut robot = match open(args.port.as_ref()) {
        Ok(r) => r,
        Err(e) => return fail("update", &e),
    };
    let from = robot.run.updates.len();
    let n = match robot.start_update(uid) {
        Ok(UpdateStatus::Started(n)) => n,
        Ok(UpdateStatus::UpToDate) => {
            println!("{}", update_status_text(&UpdateStatus::UpToDate));
            return ExitCode::SUCCESS;
        }
        Ok(s) => return fail("update", &update_status_text(&s)),
        Err(e) => return fail("update", &e),
    };
    println!("{}", update_status_text(&UpdateStatus::Started(n)));
    if args.no_wait {
        return ExitCode::SUCCESS;
    }
    let within = Duration::from_secs_f64(args.timeout_s.max(0.0));
    match robot.wait_updates(from, usize::from(n), within) {
        Ok(records) => {
            for r in &records {
                println!("{}", update_text(r));
            }
            if records
                .iter()
                .any(|r| matches!(r.phase, UpdatePhase::Failed(_)))
            {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            }
        }
        Err(e) => fail("update", &e),
    }
}
