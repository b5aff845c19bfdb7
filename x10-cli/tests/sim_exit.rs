//! A run that went wrong exits non-zero and says what went wrong on its first line; a correct
//! run exits 0 with no warning (issue 23 items 3 and 4).

use std::path::PathBuf;
use std::process::{Command, ExitCode};

use clap::Parser;
use x10_cli::app::{self, RunArgs};
use x10_devices::{Address, DcMotor, Error};
use x10_sim::sim::{SimConfig, X10};
use x10_sim::world::World;

fn x10(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_x10"))
        .args(args)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn a_correct_run_exits_0_with_no_warning() {
    // fig4_4 has two boards that both send at boot: their arbitration is not a warning.
    for example in ["fig4_4", "fig4_6"] {
        let (code, out) = x10(&["sim", example]);
        assert_eq!(code, Some(0), "{out}");
        assert!(
            out.starts_with(&format!("# x10 sim {example} against")),
            "{out}"
        );
        assert!(out.ends_with("warnings and errors: none\n"), "{out}");
    }
    let (code, out) = x10(&["sim", "fig4_6", "--trace"]);
    assert_eq!(code, Some(0));
    assert!(
        out.contains(" INFO  db11: lost arbitration to db0a"),
        "{out}"
    );
    assert!(!out.contains(" WARN "), "{out}");
}

#[test]
fn a_world_without_the_board_the_program_drives_exits_1_naming_it() {
    let world = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robots/worlds/fig4_4.toml"
    ))
    .unwrap();
    // The program drives DB 9; the world declares its board at 0x0c.
    let world = world
        .replace("address = 9 ", "address = 12 ")
        .replace("\"db09\"", "\"db0c\"");
    assert!(world.contains("address = 12 "));
    let path = std::env::temp_dir().join(format!("x10-sim-exit-{}.toml", std::process::id()));
    std::fs::write(&path, world).unwrap();
    let file = path.display().to_string();
    let (code, out) = x10(&["sim", "fig4_4", "--world", &file]);
    let _ = std::fs::remove_file(&path);
    assert_eq!(code, Some(1), "{out}");
    assert_eq!(
        out.lines().next(),
        Some(
            format!(
                "error: the program called board 0x09, which is not in {file} (boards: SELF, 0x0c)"
            )
            .as_str()
        )
    );
}

/// Drives a motor on board 0x0a, which the world does not have: the call fails, the task ends
/// with that error.
async fn drive_missing_board(x10: X10) -> Result<(), Error> {
    let board = Address::external(0x0a).map_err(|_| Error::BadPort(0))?;
    let mut motor = DcMotor::new(x10, board, 1)?;
    motor.stop().await
}

#[test]
fn a_task_that_ends_with_an_error_is_one_warning_and_a_failed_run() {
    let world = World::new();
    let config = SimConfig {
        duration_ms: 1_000,
        ..SimConfig::default()
    };
    let outcome = world
        .sim(config)
        .unwrap()
        .with_robot("drive", drive_missing_board)
        .run()
        .unwrap();
    assert_eq!(outcome.unknown_boards, [0x0a]);
    let problems = outcome.problems("world.toml");
    assert_eq!(problems.len(), 2, "{problems:?}");
    assert_eq!(
        problems[0],
        "the program called board 0x0a, which is not in world.toml (boards: SELF)"
    );
    assert!(
        problems[1].starts_with("the task drive ended with an error: "),
        "{problems:?}"
    );
    // The error is printed once: the task's end line (naming its failed call), not also the
    // call's own line.
    let error = &outcome.task_errors[0].1;
    let warnings: Vec<String> = outcome
        .trace
        .lines()
        .iter()
        .filter(|l| l.source == "drive" && l.severity >= x10_sim::trace::Severity::Warn)
        .map(|l| l.text.clone())
        .collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&format!("ended with an error: {error} (its call at ")),
        "{warnings:?}"
    );

    // `cargo sim`'s run: exit code 1.
    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        run: RunArgs,
    }
    let args = Cli::parse_from(["sim", "--duration-ms", "1000"]).run;
    let code = app::run(
        &args,
        &world,
        |sim| sim.with_robot("drive", drive_missing_board),
        "test",
        "world.toml",
    );
    assert_eq!(code, ExitCode::FAILURE);
}

#[test]
fn cargo_sims_separator_is_accepted() {
    let args = |v: &[&'static str]| app::without_separator(v.iter().copied());
    assert_eq!(args(&["sim", "--", "--trace"]), ["sim", "--trace"]);
    assert_eq!(args(&["sim", "--trace"]), ["sim", "--trace"]);
    assert_eq!(args(&["sim"]), ["sim"]);
    let _ = PathBuf::new();
}
