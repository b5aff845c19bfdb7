//! Writes the `mb_reply` target's seed inputs ([`x10_fuzz::seeds`]: valid frames from honest
//! boards, a few faults) into the directory given, one file per seed. The checked-in copy is
//! `seeds/mb_reply/` (`cargo run --release --bin mb_seeds seeds/mb_reply`; a test keeps it equal).
use std::path::PathBuf;

fn main() -> std::io::Result<()> {
    let Some(dir) = std::env::args_os().nth(1).map(PathBuf::from) else {
        eprintln!("usage: mb_seeds DIR");
        std::process::exit(2);
    };
    std::fs::create_dir_all(&dir)?;
    for (name, input) in x10_fuzz::seeds() {
        std::fs::write(dir.join(format!("seed-{name}")), input)?;
    }
    Ok(())
}
