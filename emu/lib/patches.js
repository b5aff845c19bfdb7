// The fixes the X10 images need on rp2040js 1.4.1, one function each (tests: test/patches.test.js).
import { I2CBlock } from './i2c.js';

/**
 * SEV sets the event register. rp2040js 1.4.1 only logs "SEV" (through the core's logger, at
 * info level); embassy's executor pends itself with SEV and then sleeps in WFE, which without
 * the event never returns. The logger is the one hook the core offers at that instruction.
 */
export function fixSev(rp2040) {
  const base = rp2040.logger;
  rp2040.logger = {
    debug: (c, m) => base.debug(c, m),
    warn: (c, m) => base.warn(c, m),
    error: (c, m) => base.error(c, m),
    info: (c, m) => {
      if (m === 'SEV') { rp2040.core.eventRegistered = true; return; }
      base.info(c, m);
    },
  };
}

/** RESETS bits of the two I2C blocks. */
const RESET_I2C = [1 << 3, 1 << 4];

/**
 * RESETS resets the I2C blocks: rp2040js 1.4.1 stores RESET and always reports every block
 * done. Asserting a block's reset bit now puts the block back to its reset state (embassy-rp
 * resets the block each time it builds an I2C driver, which the Pico adapter does to switch
 * between controller and target), and RESET_DONE is the complement of RESET. (The package
 * does not export its RESETS class, so the instance is patched.)
 */
export function fixResets(rp2040) {
  const resets = rp2040.peripherals[0x4000c];
  const write = resets.writeUint32.bind(resets);
  const read = resets.readUint32.bind(resets);
  resets.writeUint32 = (offset, value) => {
    if (offset === 0) {
      const rose = value & ~resets.reset;
      resets.reset = value & 0x1ffffff;
      RESET_I2C.forEach((bit, i) => { if (rose & bit) rp2040.i2c[i].resetBlock(); });
      return;
    }
    write(offset, value);
  };
  resets.readUint32 = (offset) => (offset === 8 ? ~resets.reset & 0x1ffffff : read(offset));
}

/** Replaces both I2C blocks with the target-capable model of ./i2c.js. */
export function fixI2c(rp2040) {
  const blocks = [new I2CBlock(rp2040, 'I2C0', 23), new I2CBlock(rp2040, 'I2C1', 24)];
  rp2040.i2c = blocks;
  rp2040.peripherals[0x40044] = blocks[0];
  rp2040.peripherals[0x40048] = blocks[1];
}

/**
 * Starts from the image's vector table at 0x10000100, past boot2: the npm package ships no
 * bootrom, and the bootrom path stops (VREG_AND_CHIP_RESET reads 0xffffffff). boot2 (the flash
 * setup) is not needed: flash is plain memory here.
 */
export function bootFromFlash(rp2040) {
  const vtor = 0x10000100;
  rp2040.core.VTOR = vtor;
  rp2040.core.SP = rp2040.readUint32(vtor);
  rp2040.core.PC = rp2040.readUint32(vtor + 4) & 0xfffffffe;
}

/** Every fix, in the order they must be applied (before the image runs). */
export function applyAll(rp2040) {
  fixSev(rp2040);
  fixResets(rp2040);
  fixI2c(rp2040);
}
