#!/usr/bin/env bash
# Instructions per operation of the portable X10 cores (wire protocol, daughterboard
# interpreter, motherboard call to its internal daughterboard) on both instruction sets:
#   thumbv6m-none-eabi    → qemu-system-arm -machine microbit   (Cortex-M0)
#   thumbv7em-none-eabihf → qemu-system-arm -machine mps2-an386 (Cortex-M4)
# Runs benches/instructions.rs (release profile: opt-level s, fat LTO; the inliner threshold
# 35 of every firmware build, from the workspace root's .cargo/config.toml) under QEMU with
# -icount shift=0,sleep=off (qemu-run.sh), where one instruction is one nanosecond of virtual
# time, and prints one markdown table on stdout; the same bytes on every run. Build messages
# and progress go to stderr. Fails if a run fails (including its calibration check).
# Needs qemu-system-arm and defmt-print, as run.sh. Honours CARGO_TARGET_DIR.
set -euo pipefail
cd "$(dirname "$0")"

for tool in qemu-system-arm defmt-print; do
    if ! command -v "$tool" >/dev/null; then
        echo "bench.sh: $tool not found (qemu-system-arm: apt-get install qemu-system-arm;" \
            "defmt-print: cargo install defmt-print --locked)" >&2
        exit 1
    fi
done

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

for target in thumbv6m-none-eabi thumbv7em-none-eabihf; do
    echo "bench.sh: building and running on $target" >&2
    if ! cargo bench -q --target "$target" --bench instructions >"$tmp/$target.log"; then
        cat "$tmp/$target.log" >&2
        echo "bench.sh: the benchmark failed on $target" >&2
        exit 1
    fi
    # "INFO  bench | <what> | <instructions>" → "<what>|<instructions>"
    sed -n 's/^INFO  bench | \(.*\) | \([0-9]*\)$/\1|\2/p' "$tmp/$target.log" >"$tmp/$target.txt"
    if [ ! -s "$tmp/$target.txt" ]; then
        cat "$tmp/$target.log" >&2
        echo "bench.sh: no figures from $target" >&2
        exit 1
    fi
done

if ! cmp -s <(cut -d'|' -f1 "$tmp/thumbv6m-none-eabi.txt") \
    <(cut -d'|' -f1 "$tmp/thumbv7em-none-eabihf.txt"); then
    echo "bench.sh: the two machines reported different figures" >&2
    exit 1
fi

rustc_version=$(rustc --version | cut -d' ' -f1-2)
qemu_version=$(qemu-system-arm --version | sed -n '1s/.*version \([0-9.]*\).*/\1/p')
echo "Instructions per operation, $rustc_version (opt-level s, inline threshold 35, fat LTO), QEMU $qemu_version -icount shift=0;"
echo "mean of 10000 repetitions, empty loop subtracted. µs columns: the count at one instruction"
echo "per cycle (RP2040, Cortex-M0+, 125 MHz: M0 count; STM32G431, Cortex-M4, 170 MHz: M4 count)."
echo
paste -d'|' "$tmp/thumbv6m-none-eabi.txt" "$tmp/thumbv7em-none-eabihf.txt" | awk -F'|' '
    BEGIN {
        print "| operation | Cortex-M0 | Cortex-M4 | M0 at 125 MHz, µs | M4 at 170 MHz, µs |"
        print "|---|--:|--:|--:|--:|"
    }
    {
        if ($1 ~ /^calibration/ || $1 ~ /loop/) {
            printf "| %s | %d | %d | - | - |\n", $1, $2, $4
        } else {
            printf "| %s | %d | %d | %.2f | %.2f |\n", $1, $2, $4, $2 / 125, $4 / 170
        }
    }'
