// Crashes injected into a running image (tests: test/reset.test.js; scenarios: scenarios/30-crash.mjs).
//
// Both take the core where the image's own code would be: in thread mode (the executor and its
// tasks), never in the middle of an interrupt handler or a critical section, so they stand for a
// task that panics and a task that never yields.

const SRAM = 0x20000000;
/** `b .`: a branch to itself. */
const SPIN = 0xe7fe;
/**
 * Where `injectHang` puts its loop: SRAM4 (0x20040000), past the 256 KiB the Pico images' memory
 * map gives them (their stack starts at 0x20040000 and grows down), so no byte of the image's
 * RAM changes.
 */
export const HANG_AT = 0x20041000;
/**
 * `injectPanic`'s `PanicInfo` in SRAM4 (r0 points here): its first two words (the message's
 * `&fmt::Arguments` and the `&Location`) point 32 bytes on, to zeros, and the rest is zeros.
 */
export const ZEROS_AT = 0x20041100;

/**
 * Runs `chip` instruction by instruction until its core is in thread mode (IPSR 0) with
 * interrupts on (PRIMASK clear): out of every critical section. One taken in the middle (in
 * embassy-rp's, after the spinlock was claimed and before its owner was recorded) would leave
 * the handler's own critical section spinning for ever, which no task's panic can do.
 */
function toThreadMode(chip) {
  const core = chip.rp.core;
  let n = 0;
  while (core.IPSR !== 0 || core.PM) {
    if (++n > 1e6) throw new Error(`${chip.name}: still in exception ${core.IPSR} or a critical section after 10^6 instructions`);
    if (core.waiting) chip.clock.tick(1000);
    else chip.clock.tick(core.executeInstruction() * 8);
  }
}

/** The image's panic handler (`#[panic_handler]`, the symbol `…rust_begin_unwind`). */
export function panicHandler(chip) {
  for (const [name, s] of chip.elf.symbols) {
    if (name.endsWith('rust_begin_unwind')) return s.value & ~1;
  }
  throw new Error(`${chip.name}: no panic handler (rust_begin_unwind) in ${chip.elf.path}`);
}

/**
 * A panic in a task: the core jumps to the image's panic handler in thread mode, interrupts on,
 * as `core::panicking::panic_fmt` calls it. r0, the `&PanicInfo`, points to ZEROS_AT: the DB
 * image's handler does not read it; the MB images' reads its message, whose `fmt::Arguments`
 * and `Location` are zeros (every slice empty): an empty literal message. (No pointer in it is
 * null: address 0 is the ROM, lib/flash.js.) Returns the handler's address.
 */
export function injectPanic(chip) {
  toThreadMode(chip);
  const core = chip.rp.core;
  const at = panicHandler(chip);
  chip.rp.sram.fill(0, ZEROS_AT - SRAM, ZEROS_AT - SRAM + 64);
  chip.rp.sramView.setUint32(ZEROS_AT - SRAM, ZEROS_AT + 32, true);
  chip.rp.sramView.setUint32(ZEROS_AT - SRAM + 4, ZEROS_AT + 32, true);
  core.registers[0] = ZEROS_AT;
  core.waiting = false;
  core.PC = at;
  return at;
}

/**
 * A task that never yields: the core spins at HANG_AT in thread mode with interrupts on. The
 * interrupt handlers still run (the time driver, the I2C block's), the executor never polls
 * again.
 */
export function injectHang(chip) {
  toThreadMode(chip);
  const core = chip.rp.core;
  chip.rp.sramView.setUint16(HANG_AT - SRAM, SPIN, true);
  core.waiting = false;
  core.PM = false;
  core.PC = HANG_AT;
  return HANG_AT;
}
