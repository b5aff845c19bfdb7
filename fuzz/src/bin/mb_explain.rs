//! Replays `mb_reply` inputs without instrumentation and prints, for each, what the MB did
//! (its transactions, the events written to it, the calls and the events waiters got) and the
//! oracle's verdict: `cargo run --release --bin mb_explain FILE...`.
fn main() -> std::io::Result<()> {
    for path in std::env::args_os().skip(1) {
        let input = std::fs::read(&path)?;
        let (record, verdict) = x10_fuzz::run(&input);
        println!("== {}: input {}", path.to_string_lossy(), hex(&input));
        print!("{}", record.dump());
        match verdict {
            Ok(()) => println!("verdict: clean"),
            Err(v) => println!("verdict: {v}"),
        }
    }
    Ok(())
}

fn hex(b: &[u8]) -> String {
    b.iter()
        .map(|x| format!("{x:02x}"))
        .collect::<Vec<_>>()
        .join("")
}
