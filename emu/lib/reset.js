// What rp2040js 1.4.1 lacks for the crash paths, the watchdog and software resets of the images
// (tests: test/reset.test.js, test/flash.test.js): an undefined instruction's HardFault, the
// watchdog's reset keeping SCRATCH and REASON, SCB AIRCR.SYSRESETREQ, and the chip-level reset
// flags. lib/rig.js applies `applyResetModel` to every chip and calls `watchdogReset` when a
// chip's watchdog fired, `sysReset` when its core asked for a reset.
import { BasePeripheral } from 'rp2040js';

const WATCHDOG = 0x40058;
const VREG_AND_CHIP_RESET = 0x40064;
const EXC_HARDFAULT = 3;

/** VREG_AND_CHIP_RESET.CHIP_RESET: the last chip-level reset was power-on (datasheet §2.10). */
export const HAD_POR = 1 << 8;
/** WATCHDOG.REASON bits (datasheet §4.7.6). */
export const REASON_TIMER = 1 << 0;
export const REASON_FORCE = 1 << 1;

/**
 * UDF and BKPT raise a HardFault, as on a Cortex-M0+ without a debugger (ARMv6-M ARM B1.5.6):
 * rp2040js hands both to `onBreak`, a debugger hook that does nothing by default, and the core
 * runs on past them. The fault is taken after the instruction, with the stacked return address
 * at the instruction itself (the core's `breakRewind`, as its GDB server rewinds).
 */
export function fixUdf(rp2040) {
  const core = rp2040.core;
  let fault = false;
  rp2040.onBreak = () => { fault = true; };
  const execute = core.executeInstruction.bind(core);
  core.executeInstruction = () => {
    const cycles = execute();
    if (fault) {
      fault = false;
      core.PC -= core.breakRewind;
      core.exceptionEntry(EXC_HARDFAULT);
    }
    return cycles;
  };
}

/** The VREG_AND_CHIP_RESET block, which rp2040js lacks (its reads return 0xffffffff). */
class ChipResetBlock extends BasePeripheral {
  constructor(rp2040) {
    super(rp2040, 'VREG_AND_CHIP_RESET');
    this.vreg = 0xb1; // reset values: EN, VSEL 1.10 V
    this.bod = 0x91;
    this.chipReset = HAD_POR;
  }

  readUint32(offset) {
    switch (offset) {
      case 0x0: return this.vreg;
      case 0x4: return this.bod;
      case 0x8: return this.chipReset;
    }
    return super.readUint32(offset);
  }

  writeUint32(offset, value) {
    switch (offset) {
      case 0x0: this.vreg = value & 0xf3; return;
      case 0x4: this.bod = value & 0xf1; return;
      // Only PSM_RESTART_FLAG (bit 24) is writable (write 1 to clear); the HAD_ bits are read-only.
      case 0x8: if (value & (1 << 24)) this.chipReset &= ~(1 << 24); return;
    }
    super.writeUint32(offset, value);
  }
}

/** CHIP_RESET reads HAD_POR: every chip of the rig starts from power-on. */
export function fixChipReset(rp2040) {
  rp2040.peripherals[VREG_AND_CHIP_RESET] = new ChipResetBlock(rp2040);
}

/**
 * The watchdog's trigger resets the chip. rp2040js models the WATCHDOG block (LOAD, the
 * countdown at twice the 1 µs tick of erratum RP2040-E1, REASON set to TIMER or FORCE,
 * SCRATCH0-7) but its trigger only logs. Here it records what the reset keeps (REASON and the
 * eight SCRATCH registers: the watchdog block is reset only by a chip-level reset, datasheet
 * §4.7.1) in `rp2040.watchdogFired` and stops the core, as the reset does within a few cycles;
 * the rig then replaces the chip (`watchdogReset`) at the end of its time step.
 */
export function fixWatchdog(rp2040) {
  const wd = rp2040.peripherals[WATCHDOG];
  const core = rp2040.core;
  rp2040.watchdogFired = null;
  wd.onWatchdogTrigger = () => {
    if (rp2040.watchdogFired) return;
    rp2040.watchdogFired = { reason: wd.reason, scratch: Array.from(wd.scratchData), t: rp2040.clock.nanos };
    wd.timer.enable = false;
    wd.alarm.enable = false;
  };
  const execute = core.executeInstruction.bind(core);
  // Held in reset: time passes, nothing runs.
  core.executeInstruction = () => (rp2040.watchdogFired ? 1 : execute());
}

/** SCB AIRCR (ARMv6-M ARM §B3.2.6): VECTKEY to write, VECTKEYSTAT read, SYSRESETREQ bit 2. */
const AIRCR = 0xd0c;
const VECTKEY = 0x05fa;

/**
 * SCB AIRCR.SYSRESETREQ resets the chip: rp2040js 1.4.1 does not implement AIRCR (its reads
 * and writes only log). A write with VECTKEY 0x05FA and SYSRESETREQ set (cortex-m's
 * `SCB::sys_reset`) records the request in `rp2040.sysResetRequested` and stops the core, as
 * the reset does within a few cycles; the rig replaces the chip (`sysReset`) at the end of its
 * time step. AIRCR reads VECTKEYSTAT (0xFA05), little-endian, PRIGROUP 0.
 */
export function fixSysReset(rp2040) {
  const ppb = rp2040.ppb;
  const core = rp2040.core;
  rp2040.sysResetRequested = null;
  const read = ppb.readUint32.bind(ppb);
  const write = ppb.writeUint32.bind(ppb);
  ppb.readUint32 = (offset) => (offset === AIRCR ? 0xfa050000 : read(offset));
  ppb.writeUint32 = (offset, value) => {
    if (offset !== AIRCR) return write(offset, value);
    if (value >>> 16 === VECTKEY && value & (1 << 2) && !rp2040.sysResetRequested) {
      rp2040.sysResetRequested = { t: rp2040.clock.nanos };
    }
  };
  const execute = core.executeInstruction.bind(core);
  core.executeInstruction = () => (rp2040.sysResetRequested ? 1 : execute());
}

/** Every model of this file, on a chip before its image runs. */
export function applyResetModel(rp2040) {
  fixUdf(rp2040);
  fixChipReset(rp2040);
  fixWatchdog(rp2040);
  fixSysReset(rp2040);
}

/**
 * Replaces `chip`, whose watchdog fired, with a fresh chip of the same image booting now
 * (`rig.powerCycle`, which keeps the flash), and gives it what a watchdog reset keeps:
 * WATCHDOG.REASON and SCRATCH0-7. What the reset does not change stays too: the levels driven
 * into its input pins and its ADC inputs. Its logs go on in the same arrays; `chip.resets`
 * lists each reset (time, kind, REASON, SCRATCH0). SRAM is not kept (the images do not rely on
 * it), nor the watchdog's enable and count: the fresh chip's watchdog is stopped until its
 * image starts it.
 */
export function watchdogReset(rig, chip) {
  const fired = chip.rp.watchdogFired;
  return warmReset(rig, chip, { ...fired, kind: 'watchdog' });
}

/**
 * Replaces `chip`, whose core wrote AIRCR.SYSRESETREQ, with a fresh chip of the same image
 * booting now (from its vector table; the flash kept). The WATCHDOG block is not reset by it
 * (only a chip-level reset does, datasheet §4.7.1): REASON and SCRATCH0-7 keep the values they
 * had. Approximate: the rig starts every other block afresh too, where on the chip the
 * request restarts the processors and the peripherals may keep their state; the images'
 * start-up (embassy-rp's init) resets the blocks they use either way.
 */
export function sysReset(rig, chip) {
  const wd = chip.rp.peripherals[WATCHDOG];
  const t = chip.rp.sysResetRequested.t;
  return warmReset(rig, chip, { t, kind: 'sysreset', reason: wd.reason, scratch: Array.from(wd.scratchData) });
}

function warmReset(rig, chip, { t, kind, reason, scratch }) {
  chip.readRtt();
  const inputs = chip.rp.gpio.map((g) => g.rawInputValue);
  const adc = Array.from(chip.rp.adc.channelValues);
  const fresh = rig.powerCycle(chip, { warm: true });
  fresh.clock.nanosCounter = Math.max(t, rig.now());
  fresh.lastRtt = fresh.clock.nanosCounter;
  const wd = fresh.rp.peripherals[WATCHDOG];
  wd.reason = reason;
  wd.scratchData.set(scratch);
  inputs.forEach((level, pin) => fresh.setPin(pin, level));
  adc.forEach((v, i) => { fresh.rp.adc.channelValues[i] = v; });
  fresh.defmt = chip.defmt;
  fresh.pinLog = chip.pinLog;
  fresh.pwmLog = chip.pwmLog;
  fresh.resets = [...(chip.resets ?? []), { t, kind, reason, scratch0: scratch[0] }];
  return fresh;
}
