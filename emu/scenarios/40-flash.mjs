// The flash path of the emulated RP2040 (lib/flash.js) under real embassy-rp code: the test image
// emu/fw-flash (its own crate) on two chips, each with its own unique ID. Each reads its unique
// ID and a counter from its last flash sector, writes the counter + 1 and resets itself with
// SYSRESETREQ until the counter is 2; then one chip is power-cycled and must still read 2.
import { defaultUid } from '../lib/flash.js';

const UID_A = [0xe6, 0x60, 0x58, 0x38, 0x1b, 0x2f, 0x41, 0x2c];
const SECTOR = 0x1ff000;
const hex = (b) => Array.from(b).map((x) => x.toString(16).padStart(2, '0')).join(', ');

export default [
  {
    name: 'flash',
    resets: true,
    about: 'embassy-rp 0.10\'s Flash on the rig\'s ROM, SSI and NOR flash (emu/fw-flash on two chips): each logs its own unique ID (0x4B through the SSI), reads a counter from its last sector, erases it, writes the counter + 1, reads it back and resets itself (SYSRESETREQ), through two resets: counters 0, 1, 2; a power cycle keeps the flash (counter 2 again, REASON and SCRATCH cleared)',
    async run(ctx) {
      if (!ctx.fwFlashElf) {
        ctx.check('the fw-flash image was given (--fw-flash)', false);
        return;
      }
      const rig = ctx.rig();
      rig.addChip('a', ctx.fwFlashElf, { uid: UID_A });
      rig.addChip('b', ctx.fwFlashElf);
      const log = (i) => ctx.defmt(rig.chips[i]);
      // Three boots: two erase + program (45.4 ms each, the W25Q16JV's typical times), then done.
      rig.run(150e6);
      for (const [i, uid] of [[0, UID_A], [1, defaultUid('b')]]) {
        const chip = rig.chips[i];
        const lines = log(i).map((l) => l.text.replace(/^\S+\s+/, ''));
        const name = chip.name;
        const ids = lines.filter((l) => l.startsWith('unique id'));
        ctx.check(`chip ${name}: its unique ID (${hex(uid)}) and the JEDEC ID ef4018 at each of its 3 boots`,
          ids.length === 3 && ids.every((l) => l === `unique id [${hex(uid)}] jedec ef4018`), ids.join(' | '));
        const want = ['counter 0', 'wrote 1, read back 1; reset', 'counter 1', 'wrote 2, read back 2; reset', 'counter 2', 'done'];
        const got = lines.filter((l) => !l.startsWith('unique id'));
        ctx.check(`chip ${name}: counters 0, 1, 2, each write read back, then done`, JSON.stringify(got) === JSON.stringify(want), got.join(' | '));
        const resets = chip.resets ?? [];
        ctx.check(`chip ${name}: two software resets (SYSRESETREQ), REASON 0`,
          resets.length === 2 && resets.every((r) => r.kind === 'sysreset' && r.reason === 0), JSON.stringify(resets));
        const word = chip.rp.readUint32(0x10000000 + SECTOR);
        ctx.check(`chip ${name}: the counter word in flash (XIP) is 2, the rest of its page erased`,
          word === 2 && chip.rp.readUint32(0x10000000 + SECTOR + 4) === 0xffffffff, `0x${word.toString(16)}`);
        const ops = chip.nor.ops.map((o) => `${o.cmd.toString(16)}@${o.addr.toString(16)}`);
        ctx.check(`chip ${name}: the flash saw sector erase, page program, twice`,
          JSON.stringify(ops) === JSON.stringify(['20@1ff000', '2@1ff000', '20@1ff000', '2@1ff000']), ops.join(' '));
        // boot2 (entered again after every flash operation) reads status register 2 (0x35).
        ctx.check(`chip ${name}: the image's boot2 ran after the flash operations (0x35 through the SSI)`,
          chip.nor.commands.filter((c) => c === 0x35).length >= 2, chip.nor.commands.map((c) => c.toString(16)).join(' '));
      }
      const a = rig.chips[0];
      const [r1, r2] = a.resets;
      ctx.figure('flash: one counter update (sector erase and page program through the ROM, then the reset) (ms)', ((r2.t - r1.t) / 1e6).toFixed(3));
      // A power cut: everything but the flash lost.
      const before = ctx.defmt(a).length;
      a.rp.writeUint32(0x4005800c, 0x58313003); // SCRATCH0, which a power cut clears
      const fresh = rig.powerCycle(a);
      fresh.defmt = a.defmt; // one log across the power cycle
      ctx.check('power cycle: REASON 0 and SCRATCH0 0 on the fresh chip', fresh.rp.readUint32(0x40058008) === 0 && fresh.rp.readUint32(0x4005800c) === 0);
      rig.run(rig.now() + 20e6);
      fresh.readRtt();
      const after = ctx.defmt(fresh).slice(before).map((l) => l.text.replace(/^\S+\s+/, ''));
      ctx.check('power cycle: the chip boots with its unique ID, reads counter 2 from flash, done; no reset', JSON.stringify(after) === JSON.stringify([`unique id [${hex(UID_A)}] jedec ef4018`, 'counter 2', 'done']) && !fresh.resets, `${after.join(' | ')} (before: ${before} lines)`);
    },
  },
];
