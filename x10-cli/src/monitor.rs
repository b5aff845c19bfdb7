//! `x10 monitor`: the live robot on the laptop, over the motherboard's USB link
//! (docs/usb-link.md). It finds the board's serial port, says hello, prints every call and
//! output change as they come in the simulator's trace words, records the byte stream to a
//! file, and at the end (Ctrl-C, the end of a file, `--duration-s`) prints the summary in
//! `cargo sim`'s words and writes the same HTML timeline page, against the robot's world
//! (which device is on which port).
//!
//! [`LinkRun`] is the laptop's view of a run, fed with [`LinkRun::feed`] (bytes) or
//! [`LinkRun::push`] (messages); [`Robot`] is the small API a laptop program uses to call the
//! robot through the link.

use std::fmt::Write as _;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use x10_link::{
    encode, AssignStatus, BoardEntry, CallError, CallRec, Dropped, Feed, FrameReader, Hello,
    Outcome, OutputValue, ToDevice, ToHost, UpdatePhase, UpdateRec, UpdateStatus, WireOp,
    DIAG_NAMES, LINK_VERSION, MAX_FRAME,
};
use x10_microcode::{Address, Level, Op, PinRef, Status};
use x10_sim::ports::{Change, OutputChange};
use x10_sim::sim::CallSpan;
use x10_sim::timeline::{device_summary, timeline_html_of, Timeline};
use x10_sim::trace::{self, Severity, TraceLine};
use x10_sim::world::World;

/// `1.234 s` from ns (the simulator summary's form).
fn seconds(t_ns: u64) -> String {
    let ms = t_ns / 1_000_000;
    format!("{}.{:03} s", ms / 1_000, ms % 1_000)
}

/// The USB IDs of an X10 motherboard (`x10_boards::usb_link::USB_VID_PID`).
pub const USB_VID_PID: (u16, u16) = (0x1209, 0x0001);

/// The hello the laptop sends.
pub fn laptop_hello() -> ToDevice<'static> {
    ToDevice::Hello(Hello {
        version: LINK_VERSION,
        address: 0,
        board: "x10 monitor",
        robot: "",
    })
}

/// `msg` as one frame.
pub fn frame(msg: &ToDevice<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    match encode(msg, &mut buf) {
        Ok(n) => buf.get(..n).unwrap_or(&[]).to_vec(),
        Err(_) => Vec::new(),
    }
}

/// A board's name in the trace: `mb` for the motherboard's own ports, `db09` for board 9.
pub fn board_name(db: u8) -> String {
    if db == 0 {
        "mb".to_string()
    } else {
        format!("db{db:02x}")
    }
}

/// A call's board as the simulator's trace says it.
fn db_label(db: u8) -> String {
    if db == 0 {
        "SELF".to_string()
    } else {
        format!("db{db:02x}")
    }
}

/// A call error in words.
pub fn error_text(e: &CallError) -> String {
    match e {
        CallError::Nack => "no acknowledge (NACK) after every retry".into(),
        CallError::Timeout => "no reply in time".into(),
        CallError::ArbitrationLost => "arbitration lost on every retry".into(),
        CallError::Bus => "bus fault".into(),
        CallError::BadReply => "malformed reply".into(),
        CallError::Status(s) => format!("board answered {}", Status::from_byte(*s)),
        CallError::Invalid => "invalid operation".into(),
        CallError::Busy => "no free request slot".into(),
        CallError::Unsupported => "not supported by the link".into(),
        CallError::BadAddress => "bad board address".into(),
        CallError::Updating => "the board's firmware is being updated".into(),
    }
}

/// The value of a reply in words (as the simulator's trace prints it).
fn value_text(op: Option<&Op<'_>>, p: &[u8]) -> String {
    match (op, p) {
        (Some(Op::DigitalRead(_)), [v]) => if *v != 0 { "high" } else { "low" }.to_string(),
        (Some(Op::AnalogRead(_)), [a, b]) => u16::from_le_bytes([*a, *b]).to_string(),
        (Some(Op::PulseIn { .. }), [a, b, c, d]) => {
            format!("{}us", u32::from_le_bytes([*a, *b, *c, *d]))
        }
        (_, []) => "ok".to_string(),
        (_, bytes) => trace::hex(bytes),
    }
}

/// What an output record changed, as the simulator logs it.
pub fn output_change(db: u8, port: u8, value: OutputValue, at_us: u64) -> OutputChange {
    let change = match value {
        OutputValue::Level(h) => Change::Digital(if h { Level::High } else { Level::Low }),
        OutputValue::Duty(d) => Change::Duty(d),
        OutputValue::FrequencyHz(hz) => Change::Frequency(u16::try_from(hz).unwrap_or(u16::MAX)),
        OutputValue::PulseWidthUs(us) => Change::PulseWidth(us),
    };
    OutputChange {
        t_ns: at_us.saturating_mul(1_000),
        board: board_name(db),
        pin: PinRef::from_byte(port),
        change,
    }
}

/// The motherboard's hello.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BoardHello {
    /// Its link version.
    pub version: u16,
    /// Its bus address.
    pub address: u8,
    /// The board.
    pub board: String,
    /// The robot program.
    pub robot: String,
}

/// The motherboard's answer to a request.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Answer {
    /// A call's reply payload or error.
    Reply(Result<Vec<u8>, CallError>),
    /// The counters, named.
    Diagnostics(Vec<(&'static str, u32)>),
    /// The boards' addresses.
    Boards(Vec<u8>),
    /// Refused (a request this motherboard does not know).
    Refused,
    /// A page of the boards plug and play knows (link version 2).
    BoardList {
        /// How many boards the motherboard knows.
        total: u8,
        /// The index of `boards[0]`.
        first: u8,
        /// The boards.
        boards: Vec<BoardEntry>,
    },
    /// How an assign ended (link version 2).
    Assigned(AssignStatus),
    /// The answer to a request to update now (link version 2).
    UpdateAnswer(UpdateStatus),
}

/// The motherboard's defmt log as it comes over the link (`Log` messages: rzCOBS frames,
/// each ended by a zero byte, split anywhere), decoded frame by frame with the image's table
/// (`x10 monitor --elf IMAGE`) by `defmt-print`, the decoder of probe-rs's project (the
/// defmt-decoder crate itself would turn on serde_json's `arbitrary_precision` for the whole
/// workspace, which changes the JSON codec's errors).
pub struct DefmtLog {
    decoder: Box<LogDecoder>,
    pending: Vec<u8>,
    /// Frames that did not decode (a piece dropped by the motherboard, another image).
    pub undecoded: usize,
}

/// Whole defmt frames in, the (level, text) of each line out.
pub type LogDecoder = dyn FnMut(&[u8]) -> Result<Vec<(String, String)>, String>;

impl std::fmt::Debug for DefmtLog {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DefmtLog")
            .field("pending", &self.pending.len())
            .field("undecoded", &self.undecoded)
            .finish_non_exhaustive()
    }
}

/// The level and text of each line `defmt-print --json` printed (its first line, the
/// schema's version, and anything not a log line are skipped).
pub fn defmt_print_lines(json: &str) -> Vec<(String, String)> {
    json.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v.get("schema_version").is_none())
        .filter_map(|v| {
            let text = v.get("data")?.as_str()?.to_string();
            let level = v
                .get("level")
                .and_then(|l| l.as_str())
                .unwrap_or("print")
                .to_ascii_lowercase();
            Some((level, text))
        })
        .collect()
}

impl DefmtLog {
    /// Decodes with `defmt-print -e ELF --json` (`cargo install defmt-print`).
    ///
    /// # Errors
    /// `defmt-print` cannot be run.
    pub fn with_defmt_print(elf: &Path) -> Result<DefmtLog, String> {
        std::process::Command::new("defmt-print")
            .arg("--version")
            .output()
            .map_err(|e| format!("--elf needs defmt-print (cargo install defmt-print): {e}"))?;
        let elf = elf.to_path_buf();
        Ok(DefmtLog::with_decoder(move |frames| {
            let mut child = std::process::Command::new("defmt-print")
                .arg("-e")
                .arg(&elf)
                .arg("--json")
                .stdin(std::process::Stdio::piped())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .map_err(|e| format!("defmt-print: {e}"))?;
            if let Some(mut stdin) = child.stdin.take() {
                stdin
                    .write_all(frames)
                    .map_err(|e| format!("defmt-print: {e}"))?;
            }
            let out = child
                .wait_with_output()
                .map_err(|e| format!("defmt-print: {e}"))?;
            if !out.status.success() {
                return Err(format!(
                    "defmt-print: {}",
                    String::from_utf8_lossy(&out.stderr).trim()
                ));
            }
            Ok(defmt_print_lines(&String::from_utf8_lossy(&out.stdout)))
        }))
    }

    /// Decodes with `decoder`: whole frames in, one (level, text) per frame out.
    pub fn with_decoder(
        decoder: impl FnMut(&[u8]) -> Result<Vec<(String, String)>, String> + 'static,
    ) -> DefmtLog {
        DefmtLog {
            decoder: Box::new(decoder),
            pending: Vec::new(),
            undecoded: 0,
        }
    }

    /// Takes log bytes; returns the level (`info`, `warn`...) and text of each frame they
    /// completed. A frame that does not decode is counted; a decoder that cannot run counts
    /// all of them.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<(String, String)> {
        let mut frames = Vec::new();
        let mut count: usize = 0;
        for &b in bytes {
            self.pending.push(b);
            if b != 0 {
                continue;
            }
            let frame = std::mem::take(&mut self.pending);
            if frame.len() == 1 {
                // A lone zero (defmt's encoder starts with one): no frame.
                continue;
            }
            frames.extend_from_slice(&frame);
            count += 1;
        }
        if count == 0 {
            return Vec::new();
        }
        let lines = (self.decoder)(&frames).unwrap_or_default();
        self.undecoded += count.saturating_sub(lines.len());
        lines
    }
}

/// The laptop's view of one run: everything the motherboard sent, kept for the summary and
/// the page.
#[derive(Debug, Default)]
pub struct LinkRun {
    /// The motherboard's hello, once it came.
    pub hello: Option<BoardHello>,
    /// Every output change, in the order they came.
    pub outputs: Vec<OutputChange>,
    /// Every call, as the timeline draws them (task `robot`).
    pub calls: Vec<CallSpan>,
    /// Events routed.
    pub events: usize,
    /// Every event, in the order they came (for `--mcap`).
    pub event_records: Vec<crate::foxglove::EventRecord>,
    /// Failed calls as warning lines.
    pub warnings: Vec<TraceLine>,
    /// The motherboard's last drop report.
    pub dropped: Dropped,
    /// Frames from the motherboard that did not decode.
    pub bad_frames: usize,
    /// defmt log bytes.
    pub log: Vec<u8>,
    /// The log's decoder, when the image is known ([`LinkRun::decode_log`]).
    pub defmt: Option<DefmtLog>,
    /// Log lines decoded.
    pub log_lines: usize,
    /// Answers to requests, by request id, not yet taken.
    pub answers: Vec<(u16, Answer)>,
    /// The first and last record times (µs of the motherboard's clock).
    pub span_us: Option<(u64, u64)>,
    /// Every update record (link version 2), in the order they came.
    pub updates: Vec<UpdateRec>,
    reader: Option<Box<FrameReader<{ MAX_FRAME }>>>,
}

impl LinkRun {
    /// An empty run.
    pub fn new() -> LinkRun {
        LinkRun::default()
    }

    fn saw(&mut self, t_us: u64) {
        self.span_us = Some(match self.span_us {
            None => (t_us, t_us),
            Some((a, b)) => (a.min(t_us), b.max(t_us)),
        });
    }

    /// Decodes the log with `log` from now on: each line becomes a trace line (source `log`,
    /// at the time of the last record), a warning or error one of the summary's warnings.
    pub fn decode_log(&mut self, log: DefmtLog) {
        self.defmt = Some(log);
    }

    /// Takes bytes of the stream; returns the trace lines of the messages they completed.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<TraceLine> {
        let mut reader = self.reader.take().unwrap_or_default();
        let mut lines = Vec::new();
        for &b in bytes {
            match reader.feed(b) {
                Feed::Pending => {}
                Feed::TooLong => self.bad_frames += 1,
                Feed::Frame => match reader.decode::<ToHost>() {
                    Ok(msg) => lines.extend(self.push(&msg)),
                    Err(_) => self.bad_frames += 1,
                },
            }
        }
        self.reader = Some(reader);
        lines
    }

    /// Takes one message; returns its trace lines (none for some).
    pub fn push(&mut self, msg: &ToHost<'_>) -> Vec<TraceLine> {
        match msg {
            ToHost::Hello(h) => {
                self.hello = Some(BoardHello {
                    version: h.version,
                    address: h.address,
                    board: h.board.to_string(),
                    robot: h.robot.to_string(),
                });
                vec![TraceLine::new(
                    0,
                    Severity::Info,
                    "link",
                    format!(
                        "hello from the motherboard at {:#04x} on a {} running {} (link version {})",
                        h.address, h.board, h.robot, h.version
                    ),
                )]
            }
            ToHost::Log(bytes) => {
                self.log.extend_from_slice(bytes);
                let Some(d) = self.defmt.as_mut() else {
                    return Vec::new();
                };
                let t_ns = self.span_us.map_or(0, |(_, b)| b.saturating_mul(1_000));
                let mut lines = Vec::new();
                for (level, text) in d.feed(bytes) {
                    let severity = match level.as_str() {
                        "error" => Severity::Error,
                        "warn" => Severity::Warn,
                        "info" | "print" => Severity::Info,
                        _ => Severity::Debug,
                    };
                    let line = TraceLine::new(t_ns, severity, "log", text);
                    if severity >= Severity::Warn {
                        self.warnings.push(line.clone());
                    }
                    lines.push(line);
                }
                self.log_lines += lines.len();
                lines
            }
            ToHost::Call(c) => vec![self.call(c)],
            ToHost::Event(e) => {
                self.events += 1;
                self.event_records
                    .push(crate::foxglove::EventRecord::from_link(e));
                self.saw(e.at_us);
                Vec::new()
            }
            ToHost::Output(o) => {
                self.saw(o.at_us);
                let change = output_change(o.db, o.port, o.value, o.at_us);
                let line = trace::change_line(&change);
                self.outputs.push(change);
                vec![line]
            }
            ToHost::Dropped(d) => {
                self.dropped = *d;
                vec![TraceLine::new(
                    self.span_us.map_or(0, |(_, b)| b * 1_000),
                    Severity::Warn,
                    "link",
                    format!(
                        "the motherboard dropped {} calls, {} events, {} output changes, {} log bytes (its buffer was full); {} frames from the laptop did not decode",
                        d.calls, d.events, d.outputs, d.log_bytes, d.bad_frames
                    ),
                )]
            }
            ToHost::Reply { id, outcome } => {
                let r = match outcome {
                    Outcome::Ok(p) => Ok(p.to_vec()),
                    Outcome::Err(e) => Err(*e),
                };
                self.answers.push((*id, Answer::Reply(r)));
                Vec::new()
            }
            ToHost::Diagnostics { id, counters } => {
                let named = DIAG_NAMES
                    .iter()
                    .copied()
                    .zip(counters.iter().copied())
                    .collect();
                self.answers.push((*id, Answer::Diagnostics(named)));
                Vec::new()
            }
            ToHost::Boards { id, addresses } => {
                self.answers
                    .push((*id, Answer::Boards(addresses.iter().copied().collect())));
                Vec::new()
            }
            ToHost::Refused { id } => {
                self.answers.push((*id, Answer::Refused));
                Vec::new()
            }
            ToHost::BoardList {
                id,
                total,
                first,
                boards,
            } => {
                let page = Answer::BoardList {
                    total: *total,
                    first: *first,
                    boards: boards.to_vec(),
                };
                self.answers.push((*id, page));
                Vec::new()
            }
            ToHost::Assigned { id, status } => {
                self.answers.push((*id, Answer::Assigned(*status)));
                Vec::new()
            }
            ToHost::UpdateAnswer { id, status } => {
                self.answers.push((*id, Answer::UpdateAnswer(*status)));
                Vec::new()
            }
            ToHost::Update(r) => {
                self.saw(r.at_us);
                self.updates.push(*r);
                let severity = match r.phase {
                    UpdatePhase::Failed(_) => Severity::Warn,
                    _ => Severity::Info,
                };
                let line = TraceLine::new(
                    r.at_us.saturating_mul(1_000),
                    severity,
                    "update",
                    crate::link_requests::update_text(r),
                );
                if severity == Severity::Warn {
                    self.warnings.push(line.clone());
                }
                vec![line]
            }
        }
    }

    fn call(&mut self, c: &CallRec<'_>) -> TraceLine {
        self.saw(c.start_us);
        self.saw(c.end_us);
        let op = Op::parse(c.op.fn_op, c.op.port, c.op.data).ok();
        let what = op.as_ref().map_or_else(
            || format!("operation {:#04x} {}", c.op.fn_op, trace::hex(c.op.data)),
            trace::describe_op,
        );
        let took = trace::micros(c.end_us.saturating_sub(c.start_us).saturating_mul(1_000));
        let (severity, outcome, ok) = match &c.outcome {
            Outcome::Ok(p) => (Severity::Info, value_text(op.as_ref(), p), true),
            Outcome::Err(e) => (Severity::Warn, format!("error: {}", error_text(e)), false),
        };
        let text = format!("{} {what} -> {outcome} in {took}", db_label(c.db));
        let end_ns = c.end_us.saturating_mul(1_000);
        self.calls.push(CallSpan {
            task: "robot".to_string(),
            start_ns: c.start_us.saturating_mul(1_000),
            end_ns,
            text: text.clone(),
            ok,
        });
        let line = TraceLine::new(end_ns, severity, "robot", text);
        if !ok {
            self.warnings.push(line.clone());
        }
        line
    }

    /// The end of the run (ns of the motherboard's clock): its last record.
    pub fn end_ns(&self) -> u64 {
        self.span_us.map_or(0, |(_, b)| b.saturating_mul(1_000))
    }

    /// The devices of `world` over the run.
    pub fn timeline(&self, world: &World) -> Timeline {
        Timeline::from_changes(world, &self.outputs, &[], self.end_ns())
    }

    /// The end-of-run text, in `cargo sim`'s words: the devices, then the link's own counts
    /// (where the simulator counts the bus, which the link does not carry), then the
    /// warnings (failed calls, drops).
    pub fn summary(&self, world: &World) -> String {
        let tl = self.timeline(world);
        let mut s = String::new();
        let on = self.hello.as_ref().map_or_else(
            || "the robot".to_string(),
            |h| format!("the {} running {}", h.board, h.robot),
        );
        let _ = writeln!(s, "devices, {} on {on}:", seconds(self.end_ns()));
        s.push_str(&device_summary(&tl));
        let failed = self.calls.iter().filter(|c| !c.ok).count();
        let d = &self.dropped;
        let _ = writeln!(
            s,
            "link: {} calls ({failed} failed), {} events, {} output changes; dropped by the motherboard: {} calls, {} events, {} output changes, {} log bytes; {} bad frames",
            self.calls.len(),
            self.events,
            self.outputs.len(),
            d.calls,
            d.events,
            d.outputs,
            d.log_bytes,
            self.bad_frames
        );
        if !self.log.is_empty() {
            match &self.defmt {
                Some(d) => {
                    let _ = writeln!(
                        s,
                        "log: {} bytes over the link, {} lines decoded, {} frames undecoded",
                        self.log.len(),
                        self.log_lines,
                        d.undecoded
                    );
                }
                None => {
                    let _ = writeln!(
                        s,
                        "log: {} bytes over the link (x10 monitor --elf IMAGE decodes them)",
                        self.log.len()
                    );
                }
            }
        }
        if self.warnings.is_empty() {
            s.push_str("warnings and errors: none\n");
        } else {
            let _ = writeln!(s, "warnings and errors: {}", self.warnings.len());
            for l in self
                .warnings
                .iter()
                .take(x10_sim::timeline::SUMMARY_WARNINGS)
            {
                let _ = writeln!(s, "  {l}");
            }
            if self.warnings.len() > x10_sim::timeline::SUMMARY_WARNINGS {
                let _ = writeln!(
                    s,
                    "  … {} more",
                    self.warnings.len() - x10_sim::timeline::SUMMARY_WARNINGS
                );
            }
        }
        s
    }

    /// The HTML timeline page (the simulator's page: plot, changes, summary).
    pub fn html(&self, world: &World, title: &str) -> String {
        let tl = self.timeline(world);
        let plot_title = format!(
            "X10 timeline: {} of the robot's clock, over the USB link",
            seconds(self.end_ns())
        );
        timeline_html_of(&tl, &self.calls, &plot_title, &self.summary(world), title)
    }
}

/// The serial ports of X10 motherboards: `/sys/class/tty/*` whose USB device has the X10
/// IDs (Linux), sorted.
pub fn find_ports() -> Vec<PathBuf> {
    find_ports_in(Path::new("/sys/class/tty"), Path::new("/dev"))
}

/// [`find_ports`] over the tty class folder `class` (each `ttyACM*` entry's `device` links to
/// the USB interface, whose parent folder holds `idVendor` and `idProduct`), naming the ports
/// in `dev`.
pub fn find_ports_in(class: &Path, dev: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let Ok(entries) = std::fs::read_dir(class) else {
        return found;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.starts_with("ttyACM") {
            continue;
        }
        // `device` -> the interface; the OS resolves `..` from the link's target.
        let usb = e.path().join("device").join("..");
        let read = |f: &str| {
            std::fs::read_to_string(usb.join(f))
                .ok()
                .and_then(|s| u16::from_str_radix(s.trim(), 16).ok())
        };
        if read("idVendor") == Some(USB_VID_PID.0) && read("idProduct") == Some(USB_VID_PID.1) {
            found.push(dev.join(&name));
        }
    }
    found.sort();
    found
}

/// Why the robot could not be reached or answered.
#[derive(Debug)]
pub enum RobotError {
    /// The port could not be opened, read or written.
    Io(String),
    /// No answer within the time given.
    NoAnswer,
    /// The call failed on the robot.
    Call(CallError),
    /// The operation could not be encoded.
    Invalid,
    /// The motherboard refused the request: it does not know it (an older link version: see
    /// its hello) or its request queue was full.
    Refused,
}

impl std::fmt::Display for RobotError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RobotError::Io(e) => write!(f, "{e}"),
            RobotError::NoAnswer => write!(f, "no answer from the robot"),
            RobotError::Call(e) => write!(f, "{}", error_text(e)),
            RobotError::Invalid => write!(f, "the operation could not be encoded"),
            RobotError::Refused => write!(
                f,
                "the motherboard refused the request (an older link version does not know it; this x10 speaks version {LINK_VERSION})"
            ),
        }
    }
}

impl std::error::Error for RobotError {}

/// A robot reached through its USB link, for a laptop program:
///
/// ```no_run
/// use x10_cli::monitor::Robot;
/// use x10_microcode::{Address, Level, Op, Port, Pin};
/// let mut robot = Robot::open_first().unwrap();
/// let a1b = Port::actuator(1).unwrap().pin(Pin::B);
/// robot.call(Address::INTERNAL, &Op::DigitalWrite(a1b, Level::High)).unwrap();
/// ```
pub struct Robot<S: Read + Write> {
    port: S,
    /// Everything the robot sent so far (records too).
    pub run: LinkRun,
    next_id: u16,
    /// How long [`Robot::call`] waits for its answer.
    pub timeout: Duration,
}

impl Robot<Box<dyn serialport::SerialPort>> {
    /// Opens the first X10 motherboard found ([`find_ports`]) and says hello.
    ///
    /// # Errors
    /// [`RobotError::Io`] when none is found or it cannot be opened.
    pub fn open_first() -> Result<Self, RobotError> {
        let path = find_ports()
            .into_iter()
            .next()
            .ok_or_else(|| RobotError::Io("no X10 motherboard found on USB".into()))?;
        Self::open(&path)
    }

    /// Opens `path` (115 200 baud is ignored by CDC-ACM) and says hello.
    ///
    /// # Errors
    /// [`RobotError::Io`].
    pub fn open(path: &Path) -> Result<Self, RobotError> {
        let port = serialport::new(path.to_string_lossy(), 115_200)
            .timeout(Duration::from_millis(50))
            .open()
            .map_err(|e| RobotError::Io(format!("{}: {e}", path.display())))?;
        Robot::new(port)
    }
}

impl<S: Read + Write> Robot<S> {
    /// The robot on `port`, after sending it the laptop's hello.
    ///
    /// # Errors
    /// [`RobotError::Io`] when the hello cannot be written.
    pub fn new(mut port: S) -> Result<Self, RobotError> {
        port.write_all(&frame(&laptop_hello()))
            .map_err(|e| RobotError::Io(e.to_string()))?;
        Ok(Robot {
            port,
            run: LinkRun::new(),
            next_id: 1,
            timeout: Duration::from_secs(2),
        })
    }

    /// Calls `op` on board `db` as a robot task would; returns the reply's payload.
    ///
    /// # Errors
    /// [`RobotError::Call`] (the robot's error), [`RobotError::NoAnswer`], [`RobotError::Io`],
    /// [`RobotError::Invalid`].
    pub fn call(&mut self, db: Address, op: &Op<'_>) -> Result<Vec<u8>, RobotError> {
        let mut data = [0u8; 64];
        let n = op.emit_data(&mut data).map_err(|_| RobotError::Invalid)?;
        let id = self.fresh_id();
        let req = ToDevice::Call {
            id,
            db: db.get(),
            op: WireOp {
                fn_op: op.fn_op_byte(),
                port: op.port_byte(),
                data: data.get(..n).unwrap_or(&[]),
            },
        };
        match self.ask(id, &req)? {
            Answer::Reply(Ok(p)) => Ok(p),
            Answer::Reply(Err(e)) => Err(RobotError::Call(e)),
            _ => Err(RobotError::Call(CallError::Unsupported)),
        }
    }

    /// The motherboard's counters, named.
    ///
    /// # Errors
    /// [`RobotError::NoAnswer`], [`RobotError::Io`].
    pub fn diagnostics(&mut self) -> Result<Vec<(&'static str, u32)>, RobotError> {
        let id = self.fresh_id();
        match self.ask(id, &ToDevice::Diagnostics { id })? {
            Answer::Diagnostics(d) => Ok(d),
            _ => Err(RobotError::Call(CallError::Unsupported)),
        }
    }

    /// The boards the motherboard called or heard from (0: its own ports).
    ///
    /// # Errors
    /// [`RobotError::NoAnswer`], [`RobotError::Io`].
    pub fn boards(&mut self) -> Result<Vec<u8>, RobotError> {
        let id = self.fresh_id();
        match self.ask(id, &ToDevice::ListBoards { id })? {
            Answer::Boards(b) => Ok(b),
            _ => Err(RobotError::Call(CallError::Unsupported)),
        }
    }

    pub(crate) fn fresh_id(&mut self) -> u16 {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1).max(1);
        id
    }

    pub(crate) fn ask(&mut self, id: u16, req: &ToDevice<'_>) -> Result<Answer, RobotError> {
        self.port
            .write_all(&frame(req))
            .map_err(|e| RobotError::Io(e.to_string()))?;
        self.wait_answer(id)
    }

    pub(crate) fn wait_answer(&mut self, id: u16) -> Result<Answer, RobotError> {
        let deadline = std::time::Instant::now() + self.timeout;
        let mut buf = [0u8; 256];
        loop {
            if let Some(i) = self.run.answers.iter().position(|(a, _)| *a == id) {
                return Ok(self.run.answers.remove(i).1);
            }
            // A request the motherboard could not decode (an older link version) is refused
            // with id 0.
            if let Some(i) = self
                .run
                .answers
                .iter()
                .position(|(a, r)| *a == 0 && *r == Answer::Refused)
            {
                self.run.answers.remove(i);
                return Err(RobotError::Refused);
            }
            if std::time::Instant::now() > deadline {
                return Err(RobotError::NoAnswer);
            }
            match self.port.read(&mut buf) {
                Ok(n) => {
                    self.feed(buf.get(..n).unwrap_or(&[]));
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(RobotError::Io(e.to_string())),
            }
        }
    }

    pub(crate) fn feed(&mut self, bytes: &[u8]) {
        self.run.feed(bytes);
    }

    /// Reads what the robot sends for up to `within` (or until `done` says so of the run),
    /// feeding [`Robot::run`].
    ///
    /// # Errors
    /// [`RobotError::Io`].
    pub fn read_for(
        &mut self,
        within: Duration,
        done: impl Fn(&LinkRun) -> bool,
    ) -> Result<(), RobotError> {
        let deadline = std::time::Instant::now() + within;
        let mut buf = [0u8; 256];
        while !done(&self.run) && std::time::Instant::now() < deadline {
            match self.port.read(&mut buf) {
                Ok(0) => return Ok(()),
                Ok(n) => self.feed(buf.get(..n).unwrap_or(&[])),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(RobotError::Io(e.to_string())),
            }
        }
        Ok(())
    }
}

const MONITOR_HELP: &str = "\
SOURCES
  Live (default): the first X10 motherboard on USB (/sys/class/tty/ttyACM* with USB IDs
  1209:0001), or --port PATH. The laptop says hello; the motherboard answers and sends every
  call, event and output change from then on. Ctrl-C (or --duration-s) ends the run.
  --from FILE or --replay FILE: a byte stream recorded by `x10 monitor --record` (the default
  is x10-monitor.x10link) or by the emulator's rig (`cargo xtask emu usb`).

WORLD
  Which device is on which port: --world FILE, or --example NAME, or else the example named by
  the robot in its hello (fig4_4 for the Figure 4.4 images). Without one, the summary lists no
  devices (the calls are still printed and counted).

LOG
  The motherboard's defmt log comes over the link too (from the laptop's hello on). With
  --elf IMAGE (the motherboard's image, e.g. target/thumbv6m-none-eabi/release/mb-pico) each
  log line is decoded and printed with the records (`log:`); without it the bytes are counted
  and kept in the recording, which a later `--replay FILE --elf IMAGE` decodes.

OUTPUT
  One line per call and output change as they come, in the simulator's trace words; at the end
  the summary in `cargo sim`'s words (the devices' changes, then the link's counts and the
  failed calls) and the simulator's HTML timeline page (--html FILE, default
  x10-monitor.html). --mcap FILE writes the run for Foxglove as it comes (with --replay: a
  recording converted): plot /x10/outputs/BOARD/PIN/KIND .value (docs/usb-link.md). Built
  with the feature foxglove-live, --foxglove-ws serves it live to Foxglove's Open connection
  (ws://localhost:8765).

EXAMPLES
  x10 monitor
  x10 monitor --example fig4_4 --html run.html --duration-s 10
  x10 monitor --replay x10-monitor.x10link --elf target/thumbv6m-none-eabi/release/mb-pico
  x10 monitor --replay x10-monitor.x10link --mcap run.mcap     # open run.mcap in Foxglove";

/// Arguments of `x10 monitor`.
#[derive(clap::Args, Debug)]
#[command(after_help = MONITOR_HELP)]
pub struct MonitorArgs {
    /// The serial port (default: the first X10 motherboard found).
    #[arg(long, value_name = "PATH", conflicts_with_all = ["from", "replay"])]
    pub port: Option<PathBuf>,
    /// Read a recorded byte stream instead of a port.
    #[arg(long, value_name = "FILE", conflicts_with = "replay")]
    pub from: Option<PathBuf>,
    /// Replay a run recorded with --record (the same as --from).
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,
    /// The robot's world file.
    #[arg(long, value_name = "FILE", conflicts_with = "example")]
    pub world: Option<PathBuf>,
    /// An example's world (fig4_2, fig4_4, fig4_6, bumper, doorbell).
    #[arg(long, value_name = "NAME")]
    pub example: Option<String>,
    /// Where a live run's bytes are recorded.
    #[arg(long, value_name = "FILE", default_value = "x10-monitor.x10link")]
    pub record: PathBuf,
    /// The timeline page to write at the end.
    #[arg(long, value_name = "FILE", default_value = "x10-monitor.html")]
    pub html: PathBuf,
    /// Stop a live run after this many seconds.
    #[arg(long, value_name = "S")]
    pub duration_s: Option<f64>,
    /// Print no line per record, only the summary.
    #[arg(long)]
    pub quiet: bool,
    /// Write the run to FILE as MCAP for Foxglove, as it comes: output changes on
    /// /x10/outputs/BOARD/PIN/KIND (plot `.value`), calls, events and the lines printed
    /// (docs/usb-link.md, "Plotting in Foxglove"). With --replay: a recorded run converted.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Serve the live run to Foxglove's Open connection (the Foxglove WebSocket protocol)
    /// at ADDR (default 127.0.0.1:8765, Foxglove's own: ws://localhost:8765).
    #[cfg(feature = "foxglove-live")]
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove_ws::DEFAULT_ADDR, conflicts_with_all = ["from", "replay"])]
    pub foxglove_ws: Option<String>,
    /// The motherboard's image (ELF): its defmt log, which comes over the link, is decoded
    /// with it and printed with the records.
    #[arg(long, value_name = "IMAGE")]
    pub elf: Option<PathBuf>,
}

/// The world for the run: `--world`, `--example`, else the example the hello names.
fn world_of(args: &MonitorArgs, run: &LinkRun) -> Result<(World, String), String> {
    if let Some(p) = &args.world {
        return World::load(p)
            .map(|w| (w, p.display().to_string()))
            .map_err(|e| format!("{}: {e}", p.display()));
    }
    let name = args.example.clone().or_else(|| {
        run.hello
            .as_ref()
            .map(|h| h.robot.to_ascii_lowercase())
            .filter(|n| x10_sim::examples::find(n).is_some())
    });
    match name {
        Some(n) => {
            let e = x10_sim::examples::find(&n).ok_or_else(|| {
                format!(
                    "unknown example {n} (known: {})",
                    x10_sim::examples::names()
                )
            })?;
            e.world()
                .map(|w| (w, format!("robots/worlds/{}.toml", e.name)))
                .map_err(|e| e.to_string())
        }
        None => Ok((World::new(), "no world".to_string())),
    }
}

/// `--mcap FILE` and `--foxglove-ws`: the run for Foxglove, written and served as it comes.
struct Plot {
    out: Option<crate::foxglove::McapOut<std::io::BufWriter<std::fs::File>>>,
    #[cfg(feature = "foxglove-live")]
    live: Option<crate::foxglove_ws::LiveServer>,
    cursor: crate::foxglove::LinkCursor,
    /// The world naming the devices, once known (`--world`, `--example` or the hello).
    world: Option<World>,
    path: PathBuf,
}

impl Plot {
    /// The file and the server `args` ask for; `None` when neither.
    fn create(args: &MonitorArgs) -> Result<Option<Plot>, String> {
        let out = match &args.mcap {
            Some(path) => Some(
                crate::foxglove::McapOut::create(path)
                    .map_err(|e| format!("{}: {e}", path.display()))?,
            ),
            None => None,
        };
        #[cfg(feature = "foxglove-live")]
        let live = match &args.foxglove_ws {
            Some(addr) => {
                let server = crate::foxglove_ws::LiveServer::start(addr.as_str(), "x10 monitor")
                    .map_err(|e| format!("--foxglove-ws {addr}: {e}"))?;
                println!(
                    "x10 monitor: Foxglove's Open connection: ws://{}",
                    server.addr()
                );
                Some(server)
            }
            None => None,
        };
        #[cfg(feature = "foxglove-live")]
        let none = out.is_none() && live.is_none();
        #[cfg(not(feature = "foxglove-live"))]
        let none = out.is_none();
        if none {
            return Ok(None);
        }
        Ok(Some(Plot {
            out,
            #[cfg(feature = "foxglove-live")]
            live,
            cursor: crate::foxglove::LinkCursor::new(),
            world: None,
            path: args.mcap.clone().unwrap_or_default(),
        }))
    }

    /// Writes (and serves) what `run` got since the last call and the `lines` it printed. A
    /// file that cannot be written is given up, said once.
    fn update(
        &mut self,
        args: &MonitorArgs,
        run: &LinkRun,
        lines: &[TraceLine],
    ) -> Result<(), String> {
        if self.world.is_none() {
            self.world = world_of(args, run)
                .ok()
                .map(|(w, _)| w)
                .filter(|w| !w.devices().is_empty());
        }
        let mut failed = None;
        for m in self.cursor.take(run, lines, self.world.as_ref()) {
            if let Some(out) = self.out.as_mut() {
                if let Err(e) = out.write(&m) {
                    failed = Some(format!(
                        "{}: {e}; the MCAP file stops here",
                        self.path.display()
                    ));
                    self.out = None;
                }
            }
            #[cfg(feature = "foxglove-live")]
            if let Some(live) = &self.live {
                live.publish(m);
            }
        }
        failed.map_or(Ok(()), Err)
    }

    /// Completes the file.
    fn finish(self) -> Result<(), String> {
        let path = self.path;
        let Some(out) = self.out else {
            return Ok(());
        };
        out.finish()
            .and_then(|mut w| {
                w.flush()
                    .map_err(|e| crate::foxglove::McapError(e.to_string()))
            })
            .map_err(|e| format!("{}: {e}", path.display()))?;
        println!("for Foxglove: {}", path.display());
        Ok(())
    }
}

fn finish(args: &MonitorArgs, run: &LinkRun, source: &str) -> std::process::ExitCode {
    let (world, world_name) = match world_of(args, run) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("x10 monitor: {e}");
            return std::process::ExitCode::FAILURE;
        }
    };
    print!("{}", run.summary(&world));
    let title = format!("x10 monitor: {source}, against {world_name}");
    match std::fs::write(&args.html, run.html(&world, &title)) {
        Ok(()) => {
            println!("timeline page: {}", args.html.display());
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("x10 monitor: {}: {e}", args.html.display());
            std::process::ExitCode::FAILURE
        }
    }
}

fn print_lines(args: &MonitorArgs, lines: &[TraceLine]) {
    if !args.quiet {
        for l in lines {
            println!("{l}");
        }
    }
}

/// `x10 monitor`.
pub fn monitor_main(args: &MonitorArgs) -> std::process::ExitCode {
    let mut run = LinkRun::new();
    if let Some(elf) = &args.elf {
        match std::fs::metadata(elf)
            .map_err(|e| e.to_string())
            .and_then(|_| DefmtLog::with_defmt_print(elf))
        {
            Ok(d) => run.decode_log(d),
            Err(e) => {
                eprintln!("x10 monitor: {}: {e}", elf.display());
                return std::process::ExitCode::FAILURE;
            }
        }
    }
    if let Some(file) = args.from.as_ref().or(args.replay.as_ref()) {
        let bytes = match std::fs::read(file) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("x10 monitor: {}: {e}", file.display());
                return std::process::ExitCode::FAILURE;
            }
        };
        let lines = run.feed(&bytes);
        print_lines(args, &lines);
        let written = Plot::create(args).and_then(|plot| {
            plot.map_or(Ok(()), |mut p| {
                p.update(args, &run, &lines)?;
                p.finish()
            })
        });
        if let Err(e) = written {
            eprintln!("x10 monitor: {e}");
            return std::process::ExitCode::FAILURE;
        }
        return finish(args, &run, &file.display().to_string());
    }
    let path = match args
        .port
        .clone()
        .or_else(|| find_ports().into_iter().next())
    {
        Some(p) => p,
        None => {
            eprintln!("x10 monitor: no X10 motherboard found on USB (no /dev/ttyACM* with USB IDs 1209:0001); plug it in, or give --port PATH or --from FILE");
            return std::process::ExitCode::FAILURE;
        }
    };
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        // A second handler cannot be set: then Ctrl-C ends the process as usual.
        let _ = ctrlc::set_handler(move || stop.store(true, std::sync::atomic::Ordering::SeqCst));
    }
    let mut record = match std::fs::File::create(&args.record) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("x10 monitor: {}: {e}", args.record.display());
            return std::process::ExitCode::FAILURE;
        }
    };
    let mut plot = match Plot::create(args) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("x10 monitor: {e}");
            return std::process::ExitCode::FAILURE;
        }
    };
    let started = std::time::Instant::now();
    let mut port: Option<Box<dyn serialport::SerialPort>> = None;
    let mut buf = [0u8; 4096];
    println!("x10 monitor: {} (Ctrl-C ends the run)", path.display());
    while !stop.load(std::sync::atomic::Ordering::SeqCst)
        && args
            .duration_s
            .is_none_or(|d| started.elapsed().as_secs_f64() < d)
    {
        // (Re)open the port: after an unplug the board comes back at the same path, and a
        // new hello starts its records again.
        let Some(p) = port.as_mut() else {
            match serialport::new(path.to_string_lossy(), 115_200)
                .timeout(Duration::from_millis(50))
                .open()
            {
                Ok(mut p) => {
                    if p.write_all(&frame(&laptop_hello())).is_ok() {
                        port = Some(p);
                    }
                }
                Err(_) => std::thread::sleep(Duration::from_millis(200)),
            }
            continue;
        };
        match p.read(&mut buf) {
            Ok(n) => {
                let bytes = buf.get(..n).unwrap_or(&[]);
                if let Err(e) = record.write_all(bytes) {
                    eprintln!("x10 monitor: {}: {e}", args.record.display());
                }
                let lines = run.feed(bytes);
                print_lines(args, &lines);
                if let Some(Err(e)) = plot.as_mut().map(|p| p.update(args, &run, &lines)) {
                    eprintln!("x10 monitor: {e}");
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => {
                println!("x10 monitor: the port went away; waiting for it to come back");
                port = None;
            }
        }
    }
    if let Some(mut p) = port {
        let _ = p.write_all(&frame(&ToDevice::Bye));
    }
    println!("recorded: {}", args.record.display());
    if let Some(Err(e)) = plot.map(Plot::finish) {
        eprintln!("x10 monitor: {e}");
    }
    finish(args, &run, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::VecDeque;
    use x10_microcode::{Pin, Port};

    /// A port that keeps what is written and reads what the test put in.
    struct FakePort {
        written: Vec<u8>,
        to_read: VecDeque<u8>,
    }

    impl Read for FakePort {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.to_read.is_empty() {
                return Err(std::io::ErrorKind::TimedOut.into());
            }
            let n = buf.len().min(self.to_read.len());
            for b in buf.iter_mut().take(n) {
                *b = self.to_read.pop_front().unwrap();
            }
            Ok(n)
        }
    }

    impl Write for FakePort {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.written.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    fn host_frame(m: &ToHost<'_>) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(m, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn a_laptop_program_calls_the_robot_through_the_link() {
        let mut answers = Vec::new();
        answers.extend(host_frame(&ToHost::Reply {
            id: 1,
            outcome: Outcome::Ok(&[]),
        }));
        answers.extend(host_frame(&ToHost::Reply {
            id: 2,
            outcome: Outcome::Err(CallError::Status(5)),
        }));
        let port = FakePort {
            written: Vec::new(),
            to_read: answers.into_iter().collect(),
        };
        let mut robot = Robot::new(port).unwrap();
        let a1b = Port::actuator(1).unwrap().pin(Pin::B);
        assert_eq!(
            robot
                .call(Address::INTERNAL, &Op::DigitalWrite(a1b, Level::High))
                .unwrap(),
            Vec::<u8>::new()
        );
        let refused = robot.call(
            Address::new(9).unwrap(),
            &Op::DigitalWrite(a1b, Level::High),
        );
        assert!(matches!(
            refused,
            Err(RobotError::Call(CallError::Status(5)))
        ));
        // The hello, then the two calls, exactly as docs/usb-link.md frames them.
        let mut want = frame(&laptop_hello());
        want.extend(frame(&ToDevice::Call {
            id: 1,
            db: 0,
            op: WireOp {
                fn_op: 0x12,
                port: 0x01,
                data: &[],
            },
        }));
        want.extend(frame(&ToDevice::Call {
            id: 2,
            db: 9,
            op: WireOp {
                fn_op: 0x12,
                port: 0x01,
                data: &[],
            },
        }));
        assert_eq!(robot.port.written, want);
        // Nothing more comes: no answer, after the timeout.
        robot.timeout = Duration::from_millis(1);
        assert!(matches!(robot.boards(), Err(RobotError::NoAnswer)));
    }

    #[test]
    #[cfg(unix)]
    fn the_port_is_found_by_its_usb_ids() {
        // sysfs as Linux lays it out: class/tty/ttyACMn/device -> the USB interface folder,
        // whose parent (the device) holds idVendor and idProduct.
        let root = std::env::temp_dir().join(format!("x10-sysfs-{}", std::process::id()));
        let class = root.join("class/tty");
        std::fs::create_dir_all(&class).unwrap();
        for (n, vid, pid) in [
            (0, "1209", "0001"),
            (1, "2e8a", "000a"),
            (2, "1209", "0001"),
        ] {
            let usb = root.join(format!("devices/usb1/1-{n}"));
            let iface = usb.join(format!("1-{n}:1.0"));
            std::fs::create_dir_all(&iface).unwrap();
            std::fs::write(usb.join("idVendor"), format!("{vid}\n")).unwrap();
            std::fs::write(usb.join("idProduct"), format!("{pid}\n")).unwrap();
            let tty = class.join(format!("ttyACM{n}"));
            std::fs::create_dir_all(&tty).unwrap();
            std::os::unix::fs::symlink(&iface, tty.join("device")).unwrap();
        }
        // Not a CDC-ACM port: skipped whatever it is.
        std::fs::create_dir_all(class.join("ttyS0")).unwrap();
        let found = find_ports_in(&class, Path::new("/dev"));
        std::fs::remove_dir_all(&root).unwrap();
        assert_eq!(
            found,
            [PathBuf::from("/dev/ttyACM0"), PathBuf::from("/dev/ttyACM2")]
        );
        assert!(find_ports_in(Path::new("/nonexistent/x10"), Path::new("/dev")).is_empty());
    }

    /// The defmt frame of `info!("USB link: a laptop listens (link version {=u16})", v)` at
    /// table index `index`, as the images' logger encodes it (defmt's own encoder: rzCOBS,
    /// ended by a zero).
    fn log_frame(index: u16, v: u16) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = defmt::Encoder::new();
        enc.start_frame(|b| out.extend_from_slice(b));
        enc.write(&index.to_le_bytes(), |b| out.extend_from_slice(b));
        enc.write(&v.to_le_bytes(), |b| out.extend_from_slice(b));
        enc.end_frame(|b| out.extend_from_slice(b));
        out
    }

    /// A decoder standing for `defmt-print` with an image whose index 1 is
    /// `info!("USB link: a laptop listens (link version {=u16})")` and index 2
    /// `warn!("bus fault {=u16}")`: it knows the frames of the test by their bytes.
    fn fake_decoder() -> DefmtLog {
        let known: Vec<(Vec<u8>, (&str, String))> = vec![
            (
                log_frame(1, 1),
                ("info", "USB link: a laptop listens (link version 2)".into()),
            ),
            (
                log_frame(1, 2),
                ("info", "USB link: a laptop listens (link version 2)".into()),
            ),
            (log_frame(2, 7), ("warn", "bus fault 7".into())),
        ];
        DefmtLog::with_decoder(move |mut frames| {
            let mut out = Vec::new();
            while let Some(end) = frames.iter().position(|&b| b == 0) {
                let (frame, rest) = frames.split_at(end + 1);
                frames = rest;
                for (bytes, (level, text)) in &known {
                    // Without the encoder's leading zero.
                    if bytes[1..] == *frame {
                        out.push((level.to_string(), text.clone()));
                    }
                }
            }
            Ok(out)
        })
    }

    #[test]
    fn defmt_prints_json_lines_are_read() {
        let out = "{\"schema_version\":1}\n{\"data\":\"USB link: a laptop listens (link version 2)\",\"level\":\"INFO\",\"location\":null}\nnot json\n{\"data\":\"x\",\"level\":null}\n";
        assert_eq!(
            defmt_print_lines(out),
            [
                (
                    "info".to_string(),
                    "USB link: a laptop listens (link version 2)".to_string()
                ),
                ("print".to_string(), "x".to_string())
            ]
        );
    }

    #[test]
    fn the_log_over_the_link_is_decoded_into_trace_lines() {
        let mut run = LinkRun::new();
        run.decode_log(fake_decoder());
        let mut bytes = log_frame(1, 1);
        let first = bytes.len();
        bytes.extend(log_frame(2, 7));
        // Each encoder starts with a lone zero (a delimiter), then index, value, rzCOBS, zero.
        assert_eq!(
            bytes,
            [0x00, 0x01, 0x01, 0x7a, 0x00, 0x00, 0x02, 0x07, 0x7a, 0x00]
        );
        // A call first (the lines take the time of the last record), then the log in two
        // `Log` messages cut inside the second frame.
        let call = CallRec {
            db: 0,
            op: WireOp {
                fn_op: 0x12,
                port: 0x01,
                data: &[],
            },
            outcome: Outcome::Ok(&[]),
            start_us: 1_000_000,
            end_us: 1_000_450,
        };
        let mut lines: Vec<String> = run
            .push(&ToHost::Call(call))
            .iter()
            .map(ToString::to_string)
            .collect();
        let (a, b) = bytes.split_at(first + 2);
        for piece in [a, b] {
            lines.extend(
                run.push(&ToHost::Log(piece))
                    .iter()
                    .map(ToString::to_string),
            );
        }
        assert_eq!(
            lines,
            [
                "1.000450 INFO  robot: SELF io high A1.B -> ok in 450us",
                "1.000450 INFO  log: USB link: a laptop listens (link version 2)",
                "1.000450 WARN  log: bus fault 7",
            ]
        );
        assert_eq!(run.log_lines, 2);
        assert_eq!(run.warnings.len(), 1);
        let world = World::new();
        assert!(run
            .summary(&world)
            .contains("log: 10 bytes over the link, 2 lines decoded, 0 frames undecoded\n"));
        // A piece the motherboard dropped: that frame is lost, the next one decodes.
        let lost = run.push(&ToHost::Log(bytes.get(3..first).unwrap()));
        assert!(lost.is_empty());
        let again = run.push(&ToHost::Log(&log_frame(1, 2)));
        assert_eq!(
            again.iter().map(ToString::to_string).collect::<Vec<_>>(),
            ["1.000450 INFO  log: USB link: a laptop listens (link version 2)"]
        );
        assert_eq!(run.defmt.as_ref().unwrap().undecoded, 1);
        // Without the image, the bytes are only counted.
        let mut plain = LinkRun::new();
        assert!(plain.push(&ToHost::Log(&bytes)).is_empty());
        assert!(plain
            .summary(&world)
            .contains("log: 10 bytes over the link (x10 monitor --elf IMAGE decodes them)\n"));
    }

    #[test]
    fn output_records_become_the_simulators_output_changes() {
        let c = output_change(9, 0x00, OutputValue::Duty(127), 1_500);
        assert_eq!(
            trace::change_line(&c).to_string(),
            "0.001500 INFO  db09: A1.A pwm 127"
        );
        let c = output_change(0, 0x01, OutputValue::Level(true), 2);
        assert_eq!(c.to_string(), "mb A1.B high");
    }
}
