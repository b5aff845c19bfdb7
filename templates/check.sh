#!/usr/bin/env bash
# What a new user does, checked: makes a robot crate from the template with `x10 new` in a
# temporary folder outside this repository, then in that crate runs the simulator command
# (`cargo sim`), the host test (`cargo test`), and builds the motherboard image for the
# Raspberry Pi Pico (thumbv6m-none-eabi) and the STM32G431 (thumbv7em-none-eabihf).
# Called by ./test-all. Builds go to target/template/ (kept between runs).
set -Eeuo pipefail
trap 'echo "FAILED: $BASH_COMMAND" >&2' ERR
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
dir="$work/my-robot"

cargo run -q --manifest-path "$root/Cargo.toml" -p x10-cli --bin x10 -- new "$dir"
cd "$dir"
export CARGO_TARGET_DIR="$root/target/template"
# As the repository's own dev profile (Cargo.toml): line tables only, to keep target/ small.
export CARGO_PROFILE_DEV_DEBUG=line-tables-only

echo "-- cargo sim (in $dir)"
cargo sim | tee "$work/sim.out"
# The summary names what the robot did: the motor ran forward after the press, and stopped.
grep -q "motor" "$work/sim.out"
grep -q "forward 60 %" "$work/sim.out"

echo "-- cargo test"
cargo test

echo "-- cargo build: the Pico image (thumbv6m-none-eabi) and the STM32G431 image (thumbv7em-none-eabihf)"
cargo build --release --target thumbv6m-none-eabi --features rp2040 --bin mb-pico
cargo build --release --target thumbv7em-none-eabihf --features stm32g431 --bin mb-g431
ls -l "$CARGO_TARGET_DIR"/thumbv6m-none-eabi/release/mb-pico "$CARGO_TARGET_DIR"/thumbv7em-none-eabihf/release/mb-g431

echo "-- cargo clippy (host and both boards)"
cargo clippy --all-targets -- -D warnings
cargo clippy --release --target thumbv6m-none-eabi --features rp2040 --bin mb-pico -- -D warnings
cargo clippy --release --target thumbv7em-none-eabihf --features stm32g431 --bin mb-g431 -- -D warnings
echo "template OK"
