// Crashes injected into a running image (tests: test/reset.test.js; scenarios: scenarios/30-crash.mjs).
//
// Both take the core where the image's own code would be: in thread mode (the executor and its
// tasks), never in the middle of an interrupt handler, so they stand for a task that panics and
// a task that never yields.

const SRAM = 0x20000000;
/** `b .`: a branch to itself. */
const SPIN = 0xe7fe;
/**
 * Where `injectHang` puts its loop: SRAM4 (0x20040000), past the 256 KiB the Pico images' memory
 * map gives them (their stack starts at 0x20040000 and grows down), so no byte of the image's
 * RAM changes.
 */
export const HANG_AT = 0x20041000;
/** 64 zero bytes in SRAM4, where `injectPanic`'s `PanicInfo` pointer (r0) points. */
export const ZEROS_AT = 0x20041100;

/** Runs `chip` instruction by instruction until its core is in thread mode (IPSR 0). */
function toThreadMode(chip) {
  const core = chip.rp.core;
  let n = 0;
  while (core.IPSR !== 0) {
    if (++n > 1e6) throw new Error(`${chip.name}: still in exception ${core.IPSR} after 10^6 instructions`);
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
 * A panic in a task: the core jumps to the image's panic handler in thread mode, interrupts as
 * they were, as `core::panicking::panic_fmt` calls it. r0, the `&PanicInfo`, points to zeros
 * (ZEROS_AT): the DB image's handler does not read it; the MB images' reads its message, and
 * every pointer in it is null, every length 0 (address 0 reads as zeros here): an empty
 * literal message. Returns the handler's address.
 */
export function injectPanic(chip) {
  toThreadMode(chip);
  const core = chip.rp.core;
  const at = panicHandler(chip);
  chip.rp.sram.fill(0, ZEROS_AT - SRAM, ZEROS_AT - SRAM + 64);
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
