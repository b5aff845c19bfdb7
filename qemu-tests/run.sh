#!/usr/bin/env bash
# Builds and runs the QEMU suites (microcode, daughterboard, motherboard) on both instruction
# sets, and fails on any failure:
#   thumbv6m-none-eabi    → qemu-system-arm -machine microbit   (Cortex-M0)
#   thumbv7em-none-eabihf → qemu-system-arm -machine mps2-an386 (Cortex-M4)
# Needs qemu-system-arm (Debian: apt-get install qemu-system-arm) and defmt-print
# (cargo install defmt-print --locked). Honours CARGO_TARGET_DIR.
# Release builds, as the firmware images are (opt-level s, fat LTO): unoptimised code needs more
# stack than the micro:bit's 16 KiB of RAM leaves for the motherboard suite.
set -euo pipefail
cd "$(dirname "$0")"

for tool in qemu-system-arm defmt-print; do
    if ! command -v "$tool" >/dev/null; then
        echo "run.sh: $tool not found (qemu-system-arm: apt-get install qemu-system-arm;" \
            "defmt-print: cargo install defmt-print --locked)" >&2
        exit 1
    fi
done

for target in thumbv6m-none-eabi thumbv7em-none-eabihf; do
    echo "=== QEMU suites on $target"
    cargo test --release --target "$target"
done
echo "=== QEMU suites passed on thumbv6m-none-eabi (microbit) and thumbv7em-none-eabihf (mps2-an386)"
