// Firmware over the bus on the emulated Pico pair (issue 25), end to end with the real images:
// db-pico 0.1.0 under boot-pico, and mb-pico carrying db-pico 2.0.0 (`target/emu/mb-pico-carry`:
// `cargo xtask emu` built it with X10_CARRY naming the 2.0.0 slot image, which its build script
// embedded with its CRC-32 in the section `.x10_carried`). mb-pico's own updater
// (`firmware_mb::update::run_updates`, spawned by `mb_image!` because the image carries an
// image) finds the board in its directory (boot event: kind Pico, 0.1.0), sends it System 12
// enter_update, function 7 (begin, 24-byte chunks, commit) to the bootloader's update mode at
// the board's address, waits for the swap and 2.0.0's identify, and confirms it (System 13).
// Then the same from a fresh rig with the board's power cut after half the chunks.
// `update-400k` and `update-1m`: the same update (no power cut) with mb-pico and db-pico's slot
// builds built for a 400 kHz and a 1 MHz bus (X10_BUS_HZ; boot-pico is a target only and has no
// bus clock), against the wire-time floor of the image at that clock, with where the time goes.
import { readElf } from '../lib/elf.js';
import { BEGIN, CHUNK, CHUNK_OP, CHUNK_WIRE_BITS, COMMIT, floorNs, transferTime } from '../lib/update.js';

const FLASH = 0x10000000;
const STATE = 0x8000;
const ACTIVE = 0x9000;
const ACTIVE_LEN = 32 * 1024;
const RECORD = 0x1fe000;
const ADDRESS = 0x20;
const MB = 0x08;
/** embassy-boot 0.7's magics (lib.rs 33-36). */
const BOOT_MAGIC = 0xd0;
/** First bytes of the requests: System 12 enter_update, System 13 confirm_firmware. */
const ENTER = 0x0c, CONFIRM = 0x0d;
/** A bus clock in words: 100 kHz, 400 kHz, 1 MHz. */
const clock = (hz) => (hz >= 1e6 ? `${hz / 1e6} MHz` : `${hz / 1000} kHz`);

const slot = (value, seq) => [0x58, value, seq & 0xff, seq >> 8, 0xa7, ~value & 0xff, ~seq & 0xff, (~seq >> 8) & 0xff];

/** The image of an ELF linked into ACTIVE: its bytes from ACTIVE to its last flash byte. */
function image(elf) {
  let end = 0;
  for (const s of elf.segments) {
    const off = s.paddr - FLASH - ACTIVE;
    if (off >= 0 && off < ACTIVE_LEN) end = Math.max(end, off + s.data.length);
  }
  const out = new Uint8Array(end).fill(0xff);
  for (const s of elf.segments) {
    const off = s.paddr - FLASH - ACTIVE;
    if (off >= 0 && off < ACTIVE_LEN) out.set(s.data, off);
  }
  return out;
}

/**
 * What the bus carried so far, read incrementally (the stop conditions run every quantum: a
 * scan of every transfer there would cost more than the chips): the board's `boot` events to
 * the MB (`{ t, v: "a.b.c" }`) and the MB's acknowledged requests to the board by first byte.
 */
class Watch {
  constructor(rig) { this.rig = rig; this.seen = 0; this.boots = []; this.sent = new Map(); }

  update() {
    const trs = this.rig.bus.transfers;
    for (; this.seen < trs.length; this.seen++) {
      const tr = trs[this.seen];
      for (const p of tr.parts) {
        if (p.dir === 'r' || !p.bytes.length) continue;
        if (tr.master === 'db' && p.addr === MB && p.bytes[0] === ADDRESS && p.bytes[1] === 0x07) {
          this.boots.push({ t: tr.t0, v: p.bytes.slice(7, 10).join('.') });
        }
        if (tr.master === 'mb' && p.addr === ADDRESS && p.ack) {
          const op = p.bytes[0];
          if (!this.sent.has(op)) this.sent.set(op, []);
          this.sent.get(op).push({ t: tr.t0, t1: tr.t1, bytes: p.bytes });
        }
      }
    }
    return this;
  }

  /** The MB's requests whose first byte is `op`. */
  of(op) { return this.update().sent.get(op) ?? []; }

  /** The board's boot events, in order. */
  booted() { return this.update().boots; }
}

/** A fresh rig: `imgs.mbCarryElf` and boot-pico with `imgs.dbSlotElf` in ACTIVE (record 0x20). */
function setup(ctx, imgs) {
  const rig = ctx.rig();
  const mb = rig.addChip('mb', imgs.mbCarryElf, {});
  const db = rig.addChip('db', imgs.dbSlotElf, { boot: ctx.bootElf });
  db.nor.data.set(slot(ADDRESS, 0), RECORD);
  return { rig, mb, nor: db.nor, w: new Watch(rig) };
}

const same = (a, b) => Buffer.compare(Buffer.from(a), Buffer.from(b)) === 0;


/**
 * True once 2.0.0 has booted and 200 ms have passed since the MB sent confirm_firmware (the
 * board writes embassy-boot's state after its reply: a sector erase and a program): the stop
 * condition of the runs (with 30 virtual s as their limit).
 */
function settled(rig, w) {
  const confirm = w.of(CONFIRM);
  return confirm.length > 0 && w.booted().some((b) => b.v === '2.0.0') && rig.now() > confirm[0].t + 200e6;
}

/**
 * Where the time of an update went (virtual ns, printed in s): the phases enter_update to begin
 * (the board resets into its bootloader, the MB finds it there), begin to the last commit (the
 * transfer), that commit to 2.0.0's boot event (the reset, the swap, the new image's start);
 * and the transfer split by what the bus did (lib/update.js, `transferTime`; the other
 * transfers on the bus are Figure 4.4's requests to board 9, absent here).
 */
function breakdown(rig, w, imageLen, tBoot) {
  const enter = w.of(ENTER)[0].t, begin = w.of(BEGIN)[0].t, commit = w.of(COMMIT).at(-1).t;
  const { t, n } = transferTime(rig.bus.transfers, { address: ADDRESS, begin, commit, imageLen });
  const s = (ns) => (ns / 1e9).toFixed(2);
  const ms = (ns, k) => (k ? (ns / k / 1e6).toFixed(2) : '-');
  return {
    phases: `${s(begin - enter)} / ${s(commit - begin)} / ${s(tBoot - commit)}`,
    transfer: `${s(t.wire)} (${n.wire}) / ${s(t.begin)} / ${s(t.erase)} (${n.erase}) / ${s(t.quiet)} (${n.quiet}, ${ms(t.quiet, n.quiet)} ms each) / ${s(t.behind)} (${n.behind}, ${ms(t.behind, n.behind)} ms each) / ${s(t.commit)}`,
  };
}

/**
 * The update on a fresh rig of `imgs` (mb-pico carrying 2.0.0 and db-pico 0.1.0 in ACTIVE,
 * built for a bus of `hz`): runs it until 2.0.0 has booted and the MB has confirmed it, checks
 * it end to end, prints its figures at `hz` (with `detail`: the wire-time floor and where the
 * time goes), then checks that a further reset keeps 2.0.0.
 */
function updateOnce(ctx, imgs, hz, detail) {
  const at = clock(hz);
  const v2 = image(readElf(imgs.dbSlotV2Elf));
  const chunks = Math.ceil(v2.length / CHUNK);
  const { rig, mb, nor, w } = setup(ctx, imgs);
  const mbLog = () => ctx.defmt(mb).map((l) => l.text).join('\n');
  // mb-pico's core awake (not in WFI/WFE) per virtual ms, sampled every quantum (1 µs).
  const busy = [];
  rig.hooks.push(() => {
    if (!mb.rp.core.waiting) {
      const k = Math.floor(rig.t / 1e6);
      busy[k] = (busy[k] ?? 0) + 1;
    }
  });
  // The bootloader's target SDA hold time (IC_SDA_HOLD), read when the first chunk goes by.
  let bootHold = null;
  rig.hooks.push(() => {
    if (bootHold === null && w.of(CHUNK_OP).length > 0) {
      bootHold = rig.chips.find((c) => c.name === 'db').i2c0.readUint32(0x7c) & 0xffff;
    }
  });
  rig.run(30000e6, () => settled(rig, w));
  ctx.check('boot-pico\'s target holds SDA 300 ns after SCL falls (IC_SDA_TX_HOLD 38 at 125 MHz), whatever the bus clock',
    bootHold === 38, `${bootHold}`);
  const log = mbLog();
  ctx.check('mb-pico carries db-pico 2.0.0 (its log: kind 3, 2.0.0, the slot\'s bytes)',
    log.includes(`carries board kind 3 firmware 2.0.0, ${v2.length} B`), log.split('\n').filter((l) => /carries/.test(l)).join('; '));
  const b = w.booted();
  ctx.check('db-pico 0.1.0 starts under boot-pico (first boot event 0.1.0)', b[0]?.v === '0.1.0', JSON.stringify(b.map((x) => x.v)));
  const enter = w.of(ENTER), begin = w.of(BEGIN), chunk = w.of(CHUNK_OP), commit = w.of(COMMIT);
  ctx.check('the MB sends enter_update once, then begin, every chunk and commit to the bootloader at 0x20',
    enter.length === 1 && begin.length === 1 && commit.length >= 1 && new Set(chunk.map((w) => w.bytes.slice(4, 8).join(','))).size === chunks,
    JSON.stringify({ enter: enter.length, begin: begin.length, chunks: chunk.length, distinct: chunks, commit: commit.length }));
  ctx.check('after the swap 2.0.0 boots (its boot event says 2.0.0) and ACTIVE holds the carried image',
    b.length >= 2 && b[b.length - 1].v === '2.0.0' && same(nor.data.slice(ACTIVE, ACTIVE + v2.length), v2), JSON.stringify(b.map((x) => x.v)));
  ctx.check('the MB confirms it (confirm_firmware, sent again while its reply is lost; STATE holds the boot mark) and logs the update done',
    w.of(CONFIRM).length >= 1 && nor.data[STATE] === BOOT_MAGIC && /update: board 32 done/.test(log),
    `STATE ${nor.data[STATE].toString(16)}; ${log.split('\n').filter((l) => /update:/.test(l)).join('; ')}`);
  const tEnter = enter[0]?.t ?? NaN, tBoot = b[b.length - 1]?.t ?? NaN;
  ctx.figure(`update by mb-pico at ${at}: enter_update to 2.0.0's boot event (s, virtual)`, ((tBoot - tEnter) / 1e9).toFixed(2));
  ctx.figure(`update by mb-pico at ${at}: the transfer, begin to commit (s, virtual; image bytes; chunk requests sent again)`,
    `${(((commit[commit.length - 1]?.t ?? NaN) - (begin[0]?.t ?? NaN)) / 1e9).toFixed(2)}; ${v2.length}; ${chunk.length - chunks}`);
  if (detail && enter.length && begin.length && commit.length && b.length >= 2) {
    ctx.figure(`update by mb-pico at ${at}: wire-time floor, chunks × ${CHUNK_WIRE_BITS} bit times / clock (s; chunks)`,
      `${(floorNs(v2.length, hz) / 1e9).toFixed(2)}; ${chunks}`);
    const d = breakdown(rig, w, v2.length, tBoot);
    // The share of whole ms from `a` to `b` (ns) that mb-pico's core was awake, %.
    const awake = (a, b) => {
      const [from, to] = [Math.ceil(a / 1e6), Math.floor(b / 1e6)];
      let sum = 0;
      for (let k = from; k < to; k++) sum += busy[k] ?? 0;
      return ((100 * sum) / ((to - from) * 1000)).toFixed(0);
    };
    ctx.figure(`update by mb-pico at ${at}: enter_update to begin / begin to commit / commit to 2.0.0's boot event (s, virtual)`, d.phases);
    ctx.figure(`update by mb-pico at ${at}: mb-pico's core awake (not in WFI/WFE) in the 40 ms before enter_update / from begin to commit (%, sampled every µs)`,
      `${awake(tEnter - 40e6, tEnter)} / ${awake(begin[0].t, commit.at(-1).t)}`);
    ctx.figure(`update by mb-pico at ${at}: begin to commit: the MB's transactions to the board on the wire (how many) / then until its next one: after begin (the first erase) / after the chunks that fill a sector (the next one's erase; how many) / after the other chunks, bus quiet (how many, mean) / after the other chunks, behind Figure 4.4's requests to absent board 9 (how many, mean) / after a commit (read-back) (s, virtual)`, d.transfer);
  }

  // A further reset keeps 2.0.0, and the MB leaves the board alone.
  const t4 = rig.now();
  rig.chips[1].rp.sysResetRequested = { t: t4 };
  rig.run(t4 + 300e6);
  const after = w.booted().filter((x) => x.t > t4);
  ctx.check('confirmed, 2.0.0 is kept at the next reset (boot event 2.0.0) and the MB sends no second enter_update',
    after.length === 1 && after[0].v === '2.0.0' && w.of(ENTER).length === 1 && same(nor.data.slice(ACTIVE, ACTIVE + v2.length), v2),
    JSON.stringify({ boots: after.map((x) => x.v), enter: w.of(ENTER).length }));
  return rig.now();
}

/** The images for the bus at `hz` (`cargo xtask emu` passes them with --*-at HZ=ELF). */
function imagesAt(ctx, hz) {
  const a = ctx.updateAt?.[hz];
  return a && { mbCarryElf: a.mbCarry, dbSlotElf: a.dbSlot, dbSlotV2Elf: a.dbSlotV2 };
}

/** The update at a faster bus (no power cut: that path is the 100 kHz scenario's). */
function fast(hz, name) {
  return {
    name,
    resets: true,
    about: `issue 25 at ${clock(hz)}: the \`update\` scenario's update (no power cut) with mb-pico carrying db-pico 2.0.0 and db-pico 0.1.0 in ACTIVE both built for a ${clock(hz)} bus (X10_BUS_HZ; boot-pico unchanged: a target without a bus clock), against the image's wire-time floor at ${clock(hz)}, with where the time goes`,
    async run(ctx) {
      const imgs = imagesAt(ctx, hz);
      if (!ctx.bootElf || !imgs?.mbCarryElf || !imgs.dbSlotElf || !imgs.dbSlotV2Elf) {
        ctx.check(`the images were given (--boot, --mb-carry-at, --db-slot-at, --db-slot-v2-at ${hz}=…)`, false);
        return;
      }
      const wall0 = Date.now();
      const sim = updateOnce(ctx, imgs, hz, true);
      ctx.figure(`simulated s per wall s (${name})`, ((sim / 1e9) / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  };
}

export default [
  {
    name: 'update',
    resets: true,
    about: 'issue 25 end to end on the emulated Pico pair with the real images: mb-pico carrying db-pico 2.0.0 (X10_CARRY, section .x10_carried) and db-pico 0.1.0 under boot-pico (record 0x20) start; mb-pico\'s updater sees 0.1.0 in the board\'s boot event and updates it over the emulated I2C (enter_update, begin, 24-byte chunks, commit, each checked), the board swaps at its reset and boots 2.0.0 (its boot event says so), the MB confirms it, a further reset keeps 2.0.0 and the MB leaves the board alone; then from a fresh rig the board\'s power is cut after half the chunks and the MB finishes the update',
    async run(ctx) {
      if (!ctx.bootElf || !ctx.dbSlotElf || !ctx.dbSlotV2Elf || !ctx.mbCarryElf) {
        ctx.check('the images were given (--boot, --db-slot, --db-slot-v2, --mb-carry)', false);
        return;
      }
      const imgs = { mbCarryElf: ctx.mbCarryElf, dbSlotElf: ctx.dbSlotElf, dbSlotV2Elf: ctx.dbSlotV2Elf };
      const v1 = image(readElf(ctx.dbSlotElf));
      const v2 = image(readElf(ctx.dbSlotV2Elf));
      const chunks = Math.ceil(v2.length / CHUNK);
      const wall0 = Date.now();
      const simFirst = updateOnce(ctx, imgs, 100000, true);

      // The power cut in the middle of the transfer.
      const { rig, mb, nor, w } = setup(ctx, imgs);
      const half = Math.floor(chunks / 2);
      rig.run(30000e6, () => w.of(CHUNK_OP).length >= half);
      const chip = rig.chips[1];
      chip.readRtt();
      const tCut = rig.now();
      const fresh = rig.powerCycle(chip);
      fresh.defmt = chip.defmt;
      ctx.check('the power is cut after half the chunks, ACTIVE still 0.1.0', w.of(CHUNK_OP).length >= half && same(nor.data.slice(ACTIVE, ACTIVE + v1.length), v1),
        `${w.of(CHUNK_OP).length} chunks at ${(tCut / 1e9).toFixed(2)} s`);
      rig.run(tCut + 30000e6, () => settled(rig, w));
      const b2 = w.booted();
      const log2 = ctx.defmt(mb).map((l) => l.text).join('\n');
      ctx.check('the MB begins again and finishes: 2.0.0 boots, is confirmed, ACTIVE holds the carried image',
        w.of(BEGIN).length >= 2 && b2[b2.length - 1]?.v === '2.0.0' && w.of(CONFIRM).length >= 1 && nor.data[STATE] === BOOT_MAGIC
          && same(nor.data.slice(ACTIVE, ACTIVE + v2.length), v2) && /update: board 32 done/.test(log2),
        JSON.stringify({ begins: w.of(BEGIN).length, boots: b2.map((x) => x.v), log: log2.split('\n').filter((l) => /update:/.test(l)) }));
      ctx.figure('update by mb-pico, power cut after half the chunks: the cut to 2.0.0\'s boot event (s, virtual)',
        (((b2[b2.length - 1]?.t ?? NaN) - tCut) / 1e9).toFixed(2));
      ctx.figure('simulated s per wall s (update)', (((simFirst + rig.now()) / 1e9) / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  },
  fast(400000, 'update-400k'),
  fast(1000000, 'update-1m'),
];
