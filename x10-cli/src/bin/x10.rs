//! `x10`: the X10 command-line tool.
//!
//! * `x10 decode HEX…` prints bus frames in words, or as JSON with `--json` (one frame per
//!   argument, or one frame given as one byte per argument: [`codec::frames_of_args`]);
//! * `x10 encode --json OBJECT…` turns such JSON back into frame bytes.
//!
//! Each subcommand is one variant of [`Command`] and one arm in [`main`]. Every error is one
//! line on standard error and a non-zero exit status; nothing a user types can panic the tool.

use std::collections::HashMap;
use std::io::{self, BufRead, Write};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use x10_cli::codec::{self, Answers, DecodeOptions, FrameKind};
use x10_microcode::Address;

#[derive(Parser)]
#[command(
    name = "x10",
    version,
    about = "X10 modular robots: tools for the microcode wire protocol (docs/protocol.md)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Decode frames captured from the bus, in words or as JSON.
    Decode(DecodeArgs),
    /// Encode frames from JSON (what `decode --json` prints) into hex.
    Encode(EncodeArgs),
    /// Run a robot program against simulated boards and print the trace.
    Sim(x10_cli::cli_sim::SimArgs),
    /// Print the latency table: simulated, wire minimum and the thesis's figures.
    Report(x10_cli::cli_sim::ReportArgs),
    /// Print what a world gives each board's sensor ports over time, as JSON lines (for rigs
    /// that drive real or emulated boards from the same world as the simulator).
    Signals(x10_cli::cli_sim::SignalsArgs),
    /// Print what the motherboard would update in a world (the images it carries, each
    /// board's firmware version), before any run.
    Plan(x10_cli::cli_sim::PlanArgs),
    /// Create a robot crate of your own (program, world, simulator command, host test,
    /// Pico and STM32G431 images) in PATH, outside this repository.
    New(NewArgs),
    /// Many calls from 12 tasks to 8 boards and SELF on a faulty bus, checked against the
    /// simulator's ground truth, per PEC mode and corruption level (docs/reliability.md).
    /// Fails (exit 1) when a mode that must be clean is not.
    Soak(x10_cli::soak::SoakArgs),
    /// Write a Pico image (ELF) as a UF2 file and, with --copy, copy it to the Pico's boot
    /// drive (hold BOOTSEL while plugging it in): flashing without a probe.
    Uf2(Uf2Args),
    /// Watch a real robot over its motherboard's USB link: every call and output change live,
    /// then the summary and the timeline page the simulator makes (docs/usb-link.md).
    Monitor(x10_cli::monitor::MonitorArgs),
    /// List the boards the motherboard knows over its USB link: address, unique ID, kind,
    /// firmware version and state (present, lost, updating).
    Boards(x10_cli::link_requests::BoardsArgs),
    /// Give the board with a unique ID an address, over the motherboard's USB link.
    Assign(x10_cli::link_requests::AssignArgs),
    /// Update one board (or --all out of date) now with the images the motherboard carries,
    /// over its USB link, and follow the update.
    Update(x10_cli::link_requests::UpdateArgs),
}

const UF2_HELP: &str = "\
EXAMPLE
  cargo build --release -p x10-robots --target thumbv6m-none-eabi --features rp2040 --bin mb-pico
  x10 uf2 target/thumbv6m-none-eabi/release/mb-pico --copy
  (or copy target/thumbv6m-none-eabi/release/mb-pico.uf2 to the RPI-RP2 drive yourself)

See docs/getting-started.md, \"Flashing without a probe\".";

#[derive(Args)]
#[command(after_help = UF2_HELP)]
struct Uf2Args {
    /// The image: an ELF file built for the RP2040.
    elf: std::path::PathBuf,
    /// The UF2 file to write (default: the ELF's path with .uf2).
    #[arg(short, long, value_name = "FILE")]
    out: Option<std::path::PathBuf>,
    /// Copy the file to the Pico's boot drive (RPI-RP2, found under /media, /run/media or
    /// /Volumes), or to this folder when given.
    #[arg(long, value_name = "DIR", num_args = 0..=1, default_missing_value = "")]
    copy: Option<std::path::PathBuf>,
}

fn uf2_main(args: Uf2Args) -> ExitCode {
    use x10_cli::uf2;
    let (file, blocks) = match uf2::convert(&args.elf, args.out.as_deref()) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("x10 uf2: {e}");
            return ExitCode::FAILURE;
        }
    };
    println!(
        "Wrote {} ({blocks} blocks of 256 bytes, family RP2040).",
        file.display()
    );
    let Some(dir) = args.copy else {
        return ExitCode::SUCCESS;
    };
    let dir = if dir.as_os_str().is_empty() {
        match uf2::find_boot_drive() {
            Some(d) => d,
            None => {
                eprintln!("x10 uf2: no RPI-RP2 drive found: hold BOOTSEL while plugging the Pico in, or name the folder with --copy DIR");
                return ExitCode::FAILURE;
            }
        }
    } else {
        dir
    };
    let name = file
        .file_name()
        .map_or_else(|| "x10.uf2".into(), |n| n.to_owned());
    let to = dir.join(name);
    match std::fs::copy(&file, &to) {
        Ok(_) => {
            println!(
                "Copied to {}: the Pico flashes it and restarts.",
                to.display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("x10 uf2: {}: {e}", to.display());
            ExitCode::FAILURE
        }
    }
}

const NEW_HELP: &str = "\
WHAT YOU GET
  src/lib.rs          the robot: async fns that take an X10 handle (no_std)
  world.toml          the boards and devices it runs against in the simulator
  src/bin/sim.rs      `cargo sim`: the robot in the simulator, with a summary
  tests/sim.rs        `cargo test`: asserts what the devices did over virtual time
  src/bin/mb-*.rs     `cargo mb-pico` / `cargo mb-g431`: build, flash (probe-rs), defmt log
  The crate depends on this X10 checkout by path, with its Cargo.lock.

EXAMPLE
  x10 new ~/robots/rover && cd ~/robots/rover && cargo sim && cargo test

See docs/your-first-robot.md.";

#[derive(Args)]
#[command(after_help = NEW_HELP)]
struct NewArgs {
    /// The folder to create (must not exist, or be empty).
    path: std::path::PathBuf,
    /// The package name (default: the folder's name).
    #[arg(long)]
    name: Option<String>,
    /// The X10 checkout to depend on (default: the one this tool was built from).
    #[arg(long, value_name = "DIR")]
    x10: Option<std::path::PathBuf>,
}

fn new_main(args: NewArgs) -> ExitCode {
    use x10_cli::new;
    let raw = match &args.name {
        Some(n) => n.clone(),
        None => args
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
    };
    let name = match new::crate_name(&raw) {
        Ok(n) => n,
        Err(e) => {
            eprintln!("x10 new: {e}");
            return ExitCode::from(2);
        }
    };
    let x10 = args.x10.unwrap_or_else(new::own_checkout);
    let x10 = x10.canonicalize().unwrap_or(x10);
    match new::create(&args.path, &name, &x10) {
        Ok(files) => {
            println!(
                "Created the robot crate `{name}` in {} ({} files), on the X10 crates in {} (by a relative path: move both folders together).",
                args.path.display(),
                files.len(),
                x10.display()
            );
            println!("Next:");
            println!("  cd {}", args.path.display());
            println!("  cargo sim        # the robot against world.toml in the simulator");
            println!("  cargo test       # its host test");
            println!(
                "  cargo mb-pico    # build and flash the Pico image (probe-rs), or cargo mb-g431"
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("x10 new: {e}");
            ExitCode::FAILURE
        }
    }
}

const DECODE_HELP: &str = "\
FRAMES
  One argument per frame, in hex: 12090102, \"12 09 01 02\", 12:09:01:02 or 0x12,0x09,0x01,0x02
  (bytes are pairs of hex digits, optionally separated by spaces, :, ,, - or _, each group
  optionally prefixed 0x). Except: when there are two or more arguments and every one is a
  single byte (one or two hex digits, optionally prefixed 0x), they are the bytes of ONE frame,
  as logic analyzers print them: 12 09 01 02, or 0x12 0x09 0x01 0x02, is one frame; the first
  byte may carry the frame's prefix (reply:04 00 02 00 02). Frames are requests unless --reply
  or --event says otherwise; a prefix on one frame overrides that: reply:010000,
  \"event:09 01 80 07 00 01 01\", request:12090102. With no FRAMES, frames are read from
  standard input, one per line (blank lines and lines starting with # are skipped).

REPLIES
  A reply does not say which request it answers. When a request with the same sequence number
  was decoded earlier in the same run, or --answers names the operation, the payload is decoded
  too (level, value, identity, diagnostics, scan, batch results).

EXAMPLES
  x10 decode \"12 09 01 02\"
  x10 decode 12 09 01 02
  x10 decode --json 30098004 \"reply:04000200 02\"
  x10 decode --pec 0x09 \"12 09 01 02 9c\"
  x10 decode --event --pec 0x10 \"09 01 80 07 00 01 01 95\"";

#[derive(Args)]
#[command(after_help = DECODE_HELP)]
struct DecodeArgs {
    /// Frames in hex, one per argument, or the bytes of one frame, one per argument (see FRAMES
    /// below).
    frames: Vec<String>,
    /// Print one JSON object per frame instead of words.
    #[arg(long)]
    json: bool,
    /// Frames are replies (DB → MB, the read half of a transaction).
    #[arg(long, conflicts_with = "event")]
    reply: bool,
    /// Frames are events (DB → MB, written by a DB acting as master).
    #[arg(long)]
    event: bool,
    /// Frames end with an SMBus PEC byte covering ADDR: the DB's address for requests and
    /// replies, the MB's address for events (decimal or 0x hex).
    #[arg(long, value_name = "ADDR", value_parser = address)]
    pec: Option<Address>,
    /// Decode reply payloads as the answer to this operation: function.operation, e.g.
    /// io.input, analog.read, system.identify, system.read_diagnostics, scan.scan, batch.batch.
    #[arg(long, value_name = "OP", value_parser = answers)]
    answers: Option<Answers>,
}

const ENCODE_HELP: &str = "\
OBJECTS
  One JSON object per argument, with the keys `x10 decode --json` prints; `data` (requests) and
  `payload` (replies, events) may be left out and are then built from the decoded fields, e.g.
  {\"function\":\"pwm\",\"operation\":\"duty\",\"db\":9,\"port_kind\":\"actuator\",\"port\":1,\"pin\":\"B\",\"seq\":3,\"duty\":128}.
  `kind` defaults to request. With `pec_addr` the PEC byte is appended. With no OBJECTS, objects
  are read from standard input, one per line, so `x10 decode --json … | x10 encode --json`
  gives back the frames.

OUTPUT
  One frame per line in lowercase hex, bytes separated by spaces (what `x10 decode` reads).";

#[derive(Args)]
#[command(after_help = ENCODE_HELP)]
struct EncodeArgs {
    /// Read JSON objects (the input format; required).
    #[arg(long, required = true)]
    json: bool,
    /// JSON objects, one per argument (see OBJECTS below).
    objects: Vec<String>,
}

fn address(s: &str) -> Result<Address, String> {
    codec::parse_address(s).map_err(|e| e.to_string())
}

fn answers(s: &str) -> Result<Answers, String> {
    Answers::parse(s).map_err(|e| e.to_string())
}

/// Where a command's output stopped.
enum Stop {
    /// The reader of standard output went away (`x10 decode … | head`): stop quietly.
    Closed,
    /// Writing failed otherwise.
    Failed(io::Error),
}

fn emit(out: &mut impl Write, line: &str) -> Result<(), Stop> {
    writeln!(out, "{line}").map_err(|e| {
        if e.kind() == io::ErrorKind::BrokenPipe {
            Stop::Closed
        } else {
            Stop::Failed(e)
        }
    })
}

/// The inputs of a command: its arguments, or the lines of standard input when there are none.
fn inputs(args: Vec<String>) -> Result<Vec<String>, io::Error> {
    if !args.is_empty() {
        return Ok(args);
    }
    let mut lines = Vec::new();
    for line in io::stdin().lock().lines() {
        let line = line?;
        let t = line.trim();
        if !t.is_empty() && !t.starts_with('#') {
            lines.push(t.to_string());
        }
    }
    Ok(lines)
}

fn decode(args: DecodeArgs) -> ExitCode {
    let default_kind = if args.reply {
        FrameKind::Reply
    } else if args.event {
        FrameKind::Event
    } else {
        FrameKind::Request
    };
    let frames = match inputs(codec::frames_of_args(args.frames)) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("x10 decode: cannot read standard input: {e}");
            return ExitCode::FAILURE;
        }
    };
    // What each sequence number's reply answers, from requests decoded earlier in this run.
    let mut pending: HashMap<u8, Answers> = HashMap::new();
    let mut failed = false;
    let mut out = io::stdout().lock();
    for (i, frame) in frames.iter().enumerate() {
        let (prefix, hex) = codec::split_prefix(frame);
        let kind = prefix.unwrap_or(default_kind);
        let decoded = codec::parse_hex(hex).and_then(|bytes| {
            let mut opts = DecodeOptions::new(kind);
            opts.pec = args.pec;
            if kind == FrameKind::Reply {
                let seq = bytes.first().copied().unwrap_or(0);
                opts.answers = args.answers.clone().or_else(|| pending.remove(&seq));
            }
            codec::decode(&bytes, &opts)
        });
        let line = match decoded {
            Ok(v) => {
                if let (Some(a), Some(seq)) = (
                    Answers::of_request(&v),
                    v.get("seq").and_then(|s| s.as_u64()),
                ) {
                    pending.insert(u8::try_from(seq).unwrap_or(0), a);
                }
                if args.json {
                    v.to_string()
                } else {
                    codec::describe(&v)
                }
            }
            Err(e) => {
                eprintln!("x10 decode: frame {} `{}`: {e}", i + 1, frame.trim());
                failed = true;
                continue;
            }
        };
        match emit(&mut out, &line) {
            Ok(()) => {}
            Err(Stop::Closed) => return ExitCode::SUCCESS,
            Err(Stop::Failed(e)) => {
                eprintln!("x10 decode: cannot write: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn encode(args: EncodeArgs) -> ExitCode {
    // `--json` is required by clap; it names the only input format there is so far.
    let _ = args.json;
    let objects = match inputs(args.objects) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("x10 encode: cannot read standard input: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut failed = false;
    let mut out = io::stdout().lock();
    for (i, text) in objects.iter().enumerate() {
        let encoded = serde_json::from_str::<serde_json::Value>(text)
            .map_err(|e| format!("not JSON: {e}"))
            .and_then(|v| codec::encode(&v).map_err(|e| e.to_string()));
        match encoded {
            Ok(bytes) => match emit(&mut out, &codec::to_hex(&bytes)) {
                Ok(()) => {}
                Err(Stop::Closed) => return ExitCode::SUCCESS,
                Err(Stop::Failed(e)) => {
                    eprintln!("x10 encode: cannot write: {e}");
                    return ExitCode::FAILURE;
                }
            },
            Err(e) => {
                eprintln!("x10 encode: object {}: {e}", i + 1);
                failed = true;
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                // Help and version text are meant to be long.
                let _ = e.print();
                return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
            }
            // Usage errors in one line, like every other error of the tool.
            // clap's message is its first paragraph (the usage hint follows a blank line).
            let text = e.render().to_string();
            let message: Vec<&str> = text
                .lines()
                .map(str::trim)
                .skip_while(|l| l.is_empty())
                .take_while(|l| !l.is_empty())
                .collect();
            let message = message.join(" ");
            let message = message.strip_prefix("error: ").unwrap_or(&message);
            eprintln!("x10: {message} (see x10 --help)");
            return ExitCode::from(2);
        }
    };
    match cli.command {
        Command::Decode(args) => decode(args),
        Command::Encode(args) => encode(args),
        Command::Sim(args) => x10_cli::cli_sim::sim_main(args),
        Command::Report(args) => x10_cli::cli_sim::report_main(args),
        Command::Signals(args) => x10_cli::cli_sim::signals_main(args),
        Command::Plan(args) => x10_cli::cli_sim::plan_main(args),
        Command::New(args) => new_main(args),
        Command::Soak(args) => x10_cli::soak::soak_main(&args),
        Command::Uf2(args) => uf2_main(args),
        Command::Monitor(args) => x10_cli::monitor::monitor_main(&args),
        Command::Boards(args) => x10_cli::link_requests::boards_main(&args),
        Command::Assign(args) => x10_cli::link_requests::assign_main(&args),
        Command::Update(args) => x10_cli::link_requests::update_main(&args),
    }
}
