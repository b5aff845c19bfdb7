//! Each simulation of a test in a process of its own (cargo-nextest's model, without the tool):
//! [`isolated`].
//!
//! `cargo test` runs the tests of a crate as threads of one process, so they share its
//! `static`s. A robot program written the embassy way keeps what its tasks share in statics
//! (an embassy-sync `Mutex`, `Signal`, `Channel` or `Watch`, a `StaticCell`): in one process,
//! two simulations running side by side (or one after the other) see each other's values, and
//! a test passes or fails with the scheduling of threads. [`isolated`] runs a test's body in a
//! fresh process of the same test binary, where every static starts as the image's would.

use std::ffi::OsStr;
use std::process::Command;

/// Set in the child process that runs one test's body.
pub const CHILD_VAR: &str = "X10_SIM_ISOLATED";

/// Runs `body` in a process of its own: the current test binary, started again to run only
/// the current test (`--exact NAME --nocapture --test-threads=1`, with [`CHILD_VAR`] set).
/// The parent waits, prints the child's output (captured by the test harness as any test's
/// output is) and panics when the child failed, with the child's panic message. In the child,
/// `body` runs. Outside a test (no test thread name, e.g. from a `main`), `body` runs here.
///
/// ```no_run
/// #[test]
/// fn the_motor_runs() {
///     x10_sim::isolated(|| {
///         // build the world, run the simulation, assert: statics are this test's own
///     });
/// }
/// ```
///
/// # Panics
/// When the child process fails (its test failed), cannot be started, or did not run exactly
/// this one test.
pub fn isolated(body: impl FnOnce()) {
    if std::env::var_os(CHILD_VAR).is_some() {
        body();
        return;
    }
    let thread = std::thread::current();
    let Some(name) = thread.name().filter(|n| *n != "main") else {
        body();
        return;
    };
    let exe = std::env::current_exe().expect("the path of the test binary");
    let out = Command::new(&exe)
        .args([
            OsStr::new(name),
            OsStr::new("--exact"),
            OsStr::new("--nocapture"),
            OsStr::new("--test-threads=1"),
        ])
        .env(CHILD_VAR, "1")
        .output()
        .unwrap_or_else(|e| panic!("cannot start {} for test {name}: {e}", exe.display()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    print!("{stdout}");
    eprint!("{stderr}");
    if !out.status.success() {
        let why = panic_message(&stderr).unwrap_or("see its output above");
        panic!(
            "test {name} failed in its own process ({}): {why}",
            out.status
        );
    }
    assert!(
        stdout.contains("test result: ok. 1 passed"),
        "test {name} did not run in its own process (no such test in {})",
        exe.display()
    );
}

/// The message of the first panic in a test's stderr: the lines after `panicked at FILE:`
/// up to the `note:` or `stack backtrace:` line.
fn panic_message(stderr: &str) -> Option<&str> {
    let start = stderr.find("panicked at ")?;
    let rest = &stderr[start..];
    let body = rest.find('\n').map(|i| &rest[i + 1..])?;
    let end = ["\nnote:", "\nstack backtrace:"]
        .iter()
        .filter_map(|m| body.find(m))
        .min()
        .unwrap_or(body.len());
    Some(body[..end].trim_end())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// Counts the bodies run in this process.
    static RUNS: AtomicU32 = AtomicU32::new(0);

    #[test]
    fn the_body_runs_in_a_child_process_with_fresh_statics() {
        // Runs in the parent and again in the child (a fresh process: 0 -> 1 in each).
        assert_eq!(RUNS.fetch_add(1, Ordering::SeqCst), 0);
        isolated(|| {
            assert!(std::env::var_os(CHILD_VAR).is_some());
            RUNS.fetch_add(10, Ordering::SeqCst);
        });
        // In the parent, the body did not run (in the child it did: 11).
        let want = if std::env::var_os(CHILD_VAR).is_some() {
            11
        } else {
            1
        };
        assert_eq!(RUNS.load(Ordering::SeqCst), want);
    }

    #[test]
    #[should_panic(expected = "failed in its own process")]
    fn a_failure_in_the_child_fails_the_test() {
        isolated(|| {
            assert_eq!(1 + 1, 3, "the child's own assertion");
        });
    }

    #[test]
    fn the_childs_panic_message_is_found() {
        let stderr = "\nthread 'x' (12) panicked at tests/sim.rs:3:5:\nassertion `left == right` failed\n  left: 1\n right: 2\nnote: run with `RUST_BACKTRACE=1`\n";
        assert_eq!(
            panic_message(stderr),
            Some("assertion `left == right` failed\n  left: 1\n right: 2")
        );
        assert_eq!(panic_message("all fine"), None);
    }
}
