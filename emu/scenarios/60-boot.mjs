// The Pico's bootloader (issue 25): boot-pico (boot2, the bootloader, embassy-boot's STATE,
// ACTIVE, DFU: x10_boards::rp_flash::layout) with db-pico built into ACTIVE (`active-slot`),
// version 0.1.0, and a second build of the same source with X10_FW_VERSION=2.0.0. The update
// is staged here as embassy-boot's FirmwareUpdater leaves it (the new image in DFU, STATE's
// magic SWAP); the bus session that writes it is h13-update's x10-boot crate, not wired yet.
import { VirtualMb } from '../lib/vmb.js';
import { readElf } from '../lib/elf.js';

const FLASH = 0x10000000;
const STATE = 0x8000;
const ACTIVE = 0x9000;
const ACTIVE_LEN = 32 * 1024;
const DFU = ACTIVE + ACTIVE_LEN;
const SECTOR = 4096;
const RECORD = 0x1fe000;
/** embassy-boot 0.7's magics (lib.rs 33-36). */
const SWAP_MAGIC = 0xf0, REVERT_MAGIC = 0xc0;
const ADDRESS = 0x20;

/** The 8 bytes of an x10-store slot holding `value` with sequence number `seq`. */
const slot = (value, seq) => [0x58, value, seq & 0xff, seq >> 8, 0xa7, ~value & 0xff, ~seq & 0xff, (~seq >> 8) & 0xff];

/** The ACTIVE slot's bytes of an image linked there: its flash segments from ACTIVE on. */
function slotBytes(elf) {
  const out = new Uint8Array(ACTIVE_LEN).fill(0xff);
  for (const s of elf.segments) {
    const off = s.paddr - FLASH - ACTIVE;
    if (off >= 0 && off + s.data.length <= ACTIVE_LEN) out.set(s.data, off);
  }
  return out;
}

/** The firmware versions in the `boot` events board ADDRESS sent, in order ("a.b.c"). */
const bootVersions = (vmb) => vmb.events
  .filter((e) => e.bytes[0] === ADDRESS && e.bytes[1] === 0x07)
  .map((e) => e.bytes.slice(7, 10).join('.'));

export default [
  {
    name: 'bootloader',
    resets: true,
    about: 'issue 25 on the emulated Pico: boot-pico runs embassy-boot over our flash driver and jumps to db-pico 0.1.0 in ACTIVE; an update staged as embassy-boot leaves it (db-pico 2.0.0 in DFU, STATE marked swap) is swapped in at the next reset and 2.0.0 boots (its boot event says so); not confirmed, it is swapped back at the reset after, and 0.1.0 boots again with STATE marked revert; an update that hangs is reset by the watchdog the bootloader started before its jump, and swapped back',
    async run(ctx) {
      if (!ctx.bootElf || !ctx.dbSlotElf || !ctx.dbSlotV2Elf) {
        ctx.check('the bootloader images were given (--boot, --db-slot, --db-slot-v2)', false);
        return;
      }
      const rig = ctx.rig();
      const vmb = new VirtualMb(rig);
      let db = rig.addChip('db', ctx.dbSlotElf, { boot: ctx.bootElf });
      const nor = db.nor;
      nor.data.set(slot(ADDRESS, 0), RECORD);
      const v1 = slotBytes(readElf(ctx.dbSlotElf));
      const v2 = slotBytes(readElf(ctx.dbSlotV2Elf));
      const logOf = () => ctx.defmt(rig.chips[0]).map((l) => l.text);
      const wall0 = Date.now();
      rig.run(30e6);
      const log = logOf();
      ctx.check('boot-pico jumps to db-pico in ACTIVE, which starts at its address (record kept in flash)',
        log.some((l) => /daughterboard on a Pico at 0x20/.test(l)), log[0] ?? 'no log');
      ctx.check('its boot event says version 0.1.0', JSON.stringify(bootVersions(vmb)) === '["0.1.0"]', JSON.stringify(bootVersions(vmb)));
      ctx.check('a plain boot leaves the slots as they were (no flash write)', nor.ops.length === 0, JSON.stringify(nor.ops.map((o) => o.cmd)));

      // The update, staged: 2.0.0 in DFU, STATE erased and marked swap.
      nor.data.set(v2, DFU);
      nor.data.fill(0xff, STATE, STATE + SECTOR);
      nor.data[STATE] = SWAP_MAGIC;
      const t1 = rig.now();
      db.rp.sysResetRequested = { t: t1 };
      rig.run(t1 + 2000e6, () => bootVersions(vmb).length >= 2 && rig.now() > t1 + 10e6);
      const swapped = rig.now();
      const active = nor.data.slice(ACTIVE, ACTIVE + ACTIVE_LEN);
      // embassy-boot's swap moves each ACTIVE page one page up in DFU (DFU's extra page first).
      const same = (a, b) => Buffer.compare(Buffer.from(a), Buffer.from(b)) === 0;
      const kept = nor.data.slice(DFU + SECTOR, DFU + SECTOR + ACTIVE_LEN);
      ctx.check('at the reset the bootloader swaps: ACTIVE holds 2.0.0, DFU 0.1.0 (one page up)',
        same(active, v2) && same(kept, v1), `ACTIVE ${same(active, v2) ? '=' : '!='} 2.0.0, DFU ${same(kept, v1) ? '=' : '!='} 0.1.0`);
      ctx.check('and 2.0.0 boots: its boot event says 2.0.0', bootVersions(vmb)[1] === '2.0.0', JSON.stringify(bootVersions(vmb)));
      const erases = nor.ops.filter((o) => o.cmd === 0x20).length;
      const programs = nor.ops.filter((o) => o.cmd === 0x02).length;
      ctx.figure('bootloader: swap of a 32 KiB image, reset to the new image\'s boot event (ms)', ((swapped - t1) / 1e6).toFixed(0));
      ctx.figure('bootloader: flash operations of the swap (4 KiB erases / 256 B programs)', `${erases} / ${programs}`);

      // Not confirmed (mark_booted): the next reset swaps back.
      db = rig.chips[0];
      const t2 = rig.now();
      db.rp.sysResetRequested = { t: t2 };
      rig.run(t2 + 2000e6, () => bootVersions(vmb).length >= 3 && rig.now() > t2 + 10e6);
      const back = nor.data.slice(ACTIVE, ACTIVE + ACTIVE_LEN);
      ctx.check('not confirmed, 2.0.0 is rolled back at the next reset: ACTIVE holds 0.1.0 again, which boots',
        same(back, v1) && bootVersions(vmb)[2] === '0.1.0',
        JSON.stringify(bootVersions(vmb)));
      ctx.check('STATE is marked revert', nor.data[STATE] === REVERT_MAGIC, nor.data[STATE].toString(16));

      // An update that hangs before it ever feeds the watchdog: its vector table's reset
      // handler is `b .`. The bootloader started the watchdog (200 ms) before the jump, so the
      // chip resets, and the bootloader, finding the update swapped in and not confirmed,
      // swaps back.
      const hang = new Uint8Array(ACTIVE_LEN).fill(0xff);
      const hv = new DataView(hang.buffer);
      hv.setUint32(0, 0x20040000, true); // initial SP: the top of SRAM
      hv.setUint32(4, (FLASH + ACTIVE + 0xc0) | 1, true); // reset handler
      hv.setUint16(0xc0, 0xe7fe, true); // b .
      nor.data.set(hang, DFU);
      nor.data.fill(0xff, STATE, STATE + SECTOR);
      nor.data[STATE] = SWAP_MAGIC;
      db = rig.chips[0];
      const t3 = rig.now();
      db.rp.sysResetRequested = { t: t3 };
      rig.run(t3 + 4000e6, () => bootVersions(vmb).length >= 4 && rig.now() > t3 + 10e6);
      const resets = (rig.chips[0].resets ?? []).filter((r) => r.t > t3).map((r) => r.kind);
      const last = vmb.events.filter((e) => e.bytes[0] === ADDRESS && e.bytes[1] === 0x07).pop();
      ctx.check('a swapped-in image that hangs is reset by the watchdog the bootloader started, and rolled back: 0.1.0 boots, its boot event says watchdog',
        same(nor.data.slice(ACTIVE, ACTIVE + ACTIVE_LEN), v1) && bootVersions(vmb)[3] === '0.1.0'
          && resets.includes('watchdog') && last?.bytes[16] === 1,
        JSON.stringify({ versions: bootVersions(vmb), resets, reason: last?.bytes[16] }));
      ctx.figure('simulated s per wall s (bootloader)', ((rig.now() / 1e9) / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  },
];
