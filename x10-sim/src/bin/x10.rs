//! The `x10` command-line tool.
fn main() {}
