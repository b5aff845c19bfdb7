#!/usr/bin/env bash
# The mb_reply fuzz target (docs/reliability.md, "The fuzz target"), built with coverage
# instrumentation on the pinned stable toolchain:
#
# 1. every input of regressions/ must be clean;
# 2. every input of regressions/open/ (a defect found and not fixed yet; its file name is
#    CLASS--name) must still break the oracle with its class: when one is clean the defect is
#    fixed, and the file moves to regressions/;
# 3. then it fuzzes from seeds/mb_reply, the classes of regressions/open/ allowed (they are
#    pinned by step 2): FUZZ_RUNS cases (40 000 by default, about 35 s here: ./test-all's short
#    run, the same cases on every machine: seed 1, no corpus reload), or for FUZZ_SECS seconds
#    when that is set. A panic, a call that never ends or ends late, an Ok or status no valid
#    reply gave, or a pin event that was not sent stops it, with the input saved, and exit
#    status 1.
#
#   FUZZ_SECS=1800 FUZZ_CORPUS=/tmp/mb-corpus bash fuzz/run.sh   # a long run, corpus kept
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
if [ -n "${FUZZ_SECS:-}" ]; then
    limit=(-max_total_time="$FUZZ_SECS")
    what="for $FUZZ_SECS s"
else
    limit=(-runs="${FUZZ_RUNS:-40000}")
    what="for ${FUZZ_RUNS:-40000} cases"
fi
if ! command -v c++ >/dev/null 2>&1; then
    echo "fuzz/run.sh: no C++ compiler (libfuzzer-sys builds libFuzzer): install one (Debian/Ubuntu: sudo apt-get install g++), then run it again" >&2
    exit 1
fi
target=x86_64-unknown-linux-gnu
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares -Cdebug-assertions --cfg fuzzing"
cargo build -q --release --target "$target" --bin mb_reply
bin=target/$target/release/mb_reply
work=$(mktemp -d)
fail() {
    echo "FUZZ FAILED: $*" >&2
    exit 1
}

n=0
for f in regressions/*; do
    [ -f "$f" ] || continue
    n=$((n + 1))
    "$bin" -runs=1 "$f" >"$work/replay.log" 2>&1 || {
        cat "$work/replay.log" >&2
        fail "regression input $f breaks the oracle again (above)"
    }
done
echo "mb_reply: $n regression inputs clean"

allow=()
for f in regressions/open/*; do
    [ -f "$f" ] || continue
    class=$(basename "$f")
    class=${class%%--*}
    allow+=("$class")
    X10_FUZZ_EXPECT="$class" "$bin" -runs=1 "$f" >"$work/open.log" 2>&1 || {
        grep -E "expected a violation|oracle violation" "$work/open.log" >&2 || tail -20 "$work/open.log" >&2
        fail "$f no longer fails as $class (above): if the defect is fixed, git mv it to fuzz/regressions/"
    }
done
allowed=$(printf '%s\n' "${allow[@]}" | sort -u | paste -sd, -)
echo "mb_reply: ${#allow[@]} open defects still reproduce (classes: ${allowed:-none})"

corpus=${FUZZ_CORPUS:-$work/corpus}
mkdir -p "$corpus"
cp seeds/mb_reply/* "$corpus"/
status=0
X10_FUZZ_ALLOW="$allowed" "$bin" "${limit[@]}" -seed="${FUZZ_SEED:-1}" -reload=0 \
    -print_final_stats=1 -artifact_prefix="$work/" "$corpus" >"$work/fuzz.log" 2>&1 || status=$?
grep -E '^#[0-9]+[[:space:]]+(DONE|pulse)' "$work/fuzz.log" | tail -1 || true
grep -E '^stat::(number_of_executed_units|average_exec_per_sec|new_units_added)' "$work/fuzz.log" || true
if [ "$status" -ne 0 ]; then
    grep -v '^ *[0-9]*: \|^ *at ' "$work/fuzz.log" | tail -60 >&2
    fail "mb_reply found an input that breaks the oracle or panics: $(ls "$work"/crash-* "$work"/timeout-* "$work"/oom-* 2>/dev/null | paste -sd' ' -)"
fi
echo "mb_reply: clean $what"
