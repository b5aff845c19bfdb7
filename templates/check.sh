#!/usr/bin/env bash
# What a new user does, checked: every command of docs/your-first-robot.md (but the two that
# flash a board; x10-cli/tests/your_first_robot.rs checks that each is here). Makes a robot
# crate from the template with `cargo x10 new` in a temporary folder outside this repository,
# then in that crate runs the simulator command (`cargo sim` and its options), the host test
# (`cargo test`), and builds the motherboard image for the Raspberry Pi Pico
# (thumbv6m-none-eabi) and the STM32G431 (thumbv7em-none-eabihf). Then the guide's section 7:
# the two tasks that share the motor through a `static` embassy-sync Mutex
# (templates/shared/), whose test binary must pass 20 runs in a row; and section 8: the robot
# in an arena (templates/arena/), its simulator run and its test.
# Called by ./test-all. Builds go to target/template/ (kept between runs).
set -Eeuo pipefail
trap 'echo "FAILED: $BASH_COMMAND" >&2' ERR
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
dir="$work/my-robot"

(cd "$root" && cargo x10 new "$dir")
# The crate names the X10 checkout by a relative path, in Cargo.toml and build.rs.
if grep -q "\"$root" "$dir/Cargo.toml" "$dir/build.rs"; then
    echo "x10 new wrote an absolute path of the checkout" >&2
    exit 1
fi
grep -q 'x10 = { path = "\.\./' "$dir/Cargo.toml"
# The checkout's own target directory (its CARGO_TARGET_DIR, else target/), where `cargo xtask
# size` has built db-pico and cut its slot bytes into carry/db-pico.bin: the new crate's
# build script builds its carried images there too (X10_CARRY_TARGET_DIR), reusing that build.
checkout_target=$(cd "$root" && mkdir -p "${CARGO_TARGET_DIR:-target}" && cd "${CARGO_TARGET_DIR:-target}" && pwd)
export X10_CARRY_TARGET_DIR="$checkout_target"
cd "$dir"
export CARGO_TARGET_DIR="$root/target/template"
# As the repository's own dev profile (Cargo.toml): line tables only, to keep target/ small.
export CARGO_PROFILE_DEV_DEBUG=line-tables-only

echo "-- cargo sim (in $dir)"
cargo sim | tee "$work/sim.out"
# The summary names what the robot did: the motor ran forward after the press, and stopped.
grep -q "motor" "$work/sim.out"
grep -q "forward 60 %" "$work/sim.out"

echo "-- cargo sim's options"
cargo sim --help | grep -q -- "--duration-ms"
cargo sim -- --help | grep -q -- "--duration-ms"
cargo sim --trace | grep -q "1.000000 INFO  mb: A1.A pwm 153"
cargo sim -- --trace | grep -q "1.000000 INFO  mb: A1.A pwm 153"
cargo sim --svg timeline.svg
cargo sim --html timeline.html
cargo sim --vcd bus.vcd
cargo sim --mcap run.mcap
test -s timeline.svg && test -s timeline.html && test -s bus.vcd
test "$(head -c 5 run.mcap | tail -c 4)" = MCAP   # the MCAP magic

echo "-- cargo test"
cargo test

echo "-- cargo build: the Pico image (thumbv6m-none-eabi) and the STM32G431 image (thumbv7em-none-eabihf)"
cargo build --release --target thumbv6m-none-eabi --features rp2040 --bin mb-pico
cargo build --release --target thumbv7em-none-eabihf --features stm32g431 --bin mb-g431
ls -l "$CARGO_TARGET_DIR"/thumbv6m-none-eabi/release/mb-pico "$CARGO_TARGET_DIR"/thumbv7em-none-eabihf/release/mb-g431

echo "-- the Pico image carries the checkout's db-pico and links the updater; the G431 image carries none"
# Section .x10_carried holds exactly db-pico's slot bytes as the checkout cut them (the same
# file `cargo xtask size` and the checkout's `cargo mb-pico` embed), and the updater's log line
# is linked (defmt keeps its strings in the ELF's symbol names).
objcopy=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-objcopy)
elf="$CARGO_TARGET_DIR"/thumbv6m-none-eabi/release/mb-pico
"$objcopy" -O binary --only-section=.x10_carried "$elf" "$work/carried.bin"
slot="$checkout_target/carry/db-pico.bin"
n=$(wc -c <"$slot")
# The section ends 4-aligned (carried.x): at most 3 bytes of padding after the image.
test "$(wc -c <"$work/carried.bin")" -eq $(((n + 3) / 4 * 4))
cmp -n "$n" "$work/carried.bin" "$slot"
echo "mb-pico carries db-pico: $n B, the bytes of $slot"
grep -q -a "carries board kind {} firmware" "$elf"
g431="$CARGO_TARGET_DIR"/thumbv7em-none-eabihf/release/mb-g431
if grep -q -a "carries board kind {} firmware" "$g431"; then
    echo "mb-g431 links the updater" >&2
    exit 1
fi

echo "-- cargo plan: what the Pico image would update in the world"
cargo plan | tee "$work/plan.out"
grep -qx "the motherboard carries pico $(sed -n 's/^version = "\(.*\)"/\1/p' "$root/Cargo.toml" | head -1) (fakes of the right length and CRC in the simulator)" "$work/plan.out"

echo "-- cargo clippy (host and both boards)"
cargo clippy --all-targets -- -D warnings
cargo clippy --release --target thumbv6m-none-eabi --features rp2040 --bin mb-pico -- -D warnings
cargo clippy --release --target thumbv7em-none-eabihf --features stm32g431 --bin mb-g431 -- -D warnings
echo "-- the update policies src/bin/mb-pico.rs documents (UpdatePolicy::Never, ::Except) compile"
cp src/bin/mb-pico.rs "$work/mb-pico.rs"
sed -n 's/^\/\/! `\(, updates: .*)\)`.*$/\1/p' "$work/mb-pico.rs" >"$work/policies"
test "$(wc -l <"$work/policies")" -eq 2
while IFS= read -r policy; do
    # The image's last line, `x10_boards::mb_image!(x10_boards::pico, robot::Robot);`, with it.
    grep -v '^x10_boards::mb_image!' "$work/mb-pico.rs" >src/bin/mb-pico.rs
    echo "x10_boards::mb_image!(x10_boards::pico, robot::Robot$policy;" >>src/bin/mb-pico.rs
    tail -1 src/bin/mb-pico.rs
    cargo clippy --release --target thumbv6m-none-eabi --features rp2040 --bin mb-pico -- -D warnings
done <"$work/policies"
cp "$work/mb-pico.rs" src/bin/mb-pico.rs
echo "-- section 7: two tasks share the motor through a static Mutex (templates/shared)"
cp -r "$root"/templates/shared/. .
cargo sim | tee "$work/shared.out"
grep -q "reverse 50 %" "$work/shared.out"
cargo test
# Its images spawn the two tasks (a few seconds each: the dependencies are built above).
cargo build --release --target thumbv6m-none-eabi --features rp2040 --bin mb-pico
cargo build --release --target thumbv7em-none-eabihf --features stm32g431 --bin mb-g431
cargo clippy --all-targets -- -D warnings
# The same test binary 20 times in a row: each test's simulation has its statics to itself.
bin=$(cargo test --no-run 2>&1 | sed -n 's/.*Executable tests\/sim.rs (\(.*\))$/\1/p')
test -x "$bin"
for run in $(seq 20); do
    "$bin" -q >"$work/run.out" 2>&1 || { cat "$work/run.out"; echo "run $run of 20 failed" >&2; exit 1; }
done
echo "20 runs passed"
echo "-- section 8: the robot in an arena (templates/arena)"
cp -r "$root"/templates/arena/. .
cargo sim | tee "$work/arena.out"
grep -q "chassis: ended at" "$work/arena.out"
cargo test
cargo clippy --all-targets -- -D warnings
echo "template OK"
