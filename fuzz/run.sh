#!/usr/bin/env bash
# The mb_reply fuzz target (docs/reliability.md, "The fuzz target"): built with coverage
# instrumentation on the pinned stable toolchain, it replays every input of regressions/, then
# fuzzes from the seeds for FUZZ_SECS seconds (45 by default: ./test-all's short run). A panic,
# a call that never ends or ends late, an Ok or status no valid reply gave, or a pin event that
# was not sent stops it with the input saved (crash-*) and exit status 1.
#
#   FUZZ_SECS=1800 FUZZ_CORPUS=/tmp/mb-corpus bash fuzz/run.sh   # a long run, corpus kept
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
secs=${FUZZ_SECS:-45}
target=x86_64-unknown-linux-gnu
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares -Cdebug-assertions --cfg fuzzing"
cargo build -q --release --target "$target" --bin mb_reply
bin=target/$target/release
corpus=${FUZZ_CORPUS:-$(mktemp -d)}
mkdir -p "$corpus"
cp seeds/mb_reply/* "$corpus"/
artifacts=$(mktemp -d)
status=0
if compgen -G "regressions/*" >/dev/null; then
    echo "mb_reply: replaying $(ls regressions | wc -l) regression inputs"
    "$bin/mb_reply" -runs=1 regressions/* 2>"$artifacts/replay.log" || {
        cat "$artifacts/replay.log" >&2
        echo "FUZZ FAILED: a regression input of fuzz/regressions/ breaks the oracle (above)" >&2
        exit 1
    }
fi
"$bin/mb_reply" -max_total_time="$secs" -seed="${FUZZ_SEED:-1}" -print_final_stats=1 \
    -artifact_prefix="$artifacts/" "$corpus" 2>"$artifacts/fuzz.log" || status=$?
grep -E '^#[0-9]+ +(DONE|pulse)|^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)|cov:' \
    "$artifacts/fuzz.log" | tail -4
if [ "$status" -ne 0 ]; then
    tail -60 "$artifacts/fuzz.log" >&2
    echo "FUZZ FAILED: mb_reply found an input that breaks the oracle or panics; saved in:" >&2
    ls "$artifacts"/crash-* "$artifacts"/timeout-* 2>/dev/null >&2 || true
    exit 1
fi
echo "mb_reply: clean for ${secs} s"
