// The flash path of lib/flash.js (ROM, NOR flash, SSI, IO_QSPI, XIP_CTRL) and the resets that
// keep the flash (lib/reset.js, lib/rig.js).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { RP2040 } from 'rp2040js';
import { applyAll } from '../lib/patches.js';
import { applyResetModel, REASON_FORCE } from '../lib/reset.js';
import { NorFlash, applyFlashModel, defaultUid, BUSY_NS, T } from '../lib/flash.js';
import { Rig } from '../lib/rig.js';

const UID = [0xe6, 0x60, 0x58, 0x38, 0x1b, 0x2f, 0x41, 0x2c];
const SSI = 0x18000000;
const IO_QSPI_SS_CTRL = 0x4001800c;
const XIP_STAT = 0x14000008, STREAM_CTR = 0x14000018;
const HALT = 0x20040000; // a `b .` the ROM calls return to
const WATCHDOG = 0x40058000, REASON = WATCHDOG + 8, SCRATCH0 = WATCHDOG + 0xc;
const AIRCR = 0xe000ed0c;

/** A bare chip with every model of the rig, its flash over a NOR with UID. */
function chip() {
  const rp = new RP2040();
  rp.logger = { debug() {}, info() {}, warn() {}, error() {} };
  applyAll(rp);
  applyResetModel(rp);
  const nor = new NorFlash(rp.flash, UID);
  applyFlashModel(rp, nor);
  rp.sramView.setUint16(HALT - 0x20000000, T.b(0, 0), true);
  return { rp, nor };
}

/** Calls the ROM's `code` function (found through its own table and lookup) with `args`; runs
 * until it returns and the flash is done; returns r0 and the virtual time it took. */
function romCall(rp, code, args) {
  const fn = lookup(rp, 0x14, code);
  assert.notEqual(fn, 0, `ROM function ${code}`);
  return call(rp, fn, args);
}

function call(rp, fn, args) {
  args.forEach((a, i) => { rp.core.registers[i] = a; });
  rp.core.LR = HALT | 1;
  rp.core.PC = fn & ~1;
  const t0 = rp.clock.nanos;
  for (let n = 0; rp.core.PC !== HALT || (rp.flashHeldUntil ?? 0) > rp.clock.nanos; n++) {
    assert.ok(n < 1e6, 'returns');
    rp.clock.tick(rp.core.executeInstruction() * 8);
  }
  return { r0: rp.core.registers[0] >>> 0, ns: rp.clock.nanos - t0 };
}

/** rom_table_lookup(table at the halfword pointer `ptr`, code), run on the core. */
function lookup(rp, ptr, code) {
  const fn = rp.readUint16(0x18);
  const table = rp.readUint16(ptr);
  return call(rp, fn, [table, code.charCodeAt(0) | (code.charCodeAt(1) << 8)]).r0;
}

test('the ROM: header, and rom_table_lookup in Thumb code finds each flash function and no other', () => {
  const { rp } = chip();
  assert.deepEqual([0x10, 0x11, 0x12].map((a) => rp.readUint8(a)), [0x4d, 0x75, 0x01]);
  const found = ['IF', 'EX', 'RE', 'RP', 'FC', 'CX', 'C4'].map((c) => lookup(rp, 0x14, c));
  for (const p of found) assert.ok(p & 1 && p > 0x100 && p < 0x4000, `thumb pointer into the ROM: ${p.toString(16)}`);
  assert.equal(new Set(found).size, found.length);
  assert.equal(lookup(rp, 0x14, 'ZZ'), 0, 'an unknown code: null');
  assert.equal(lookup(rp, 0x16, 'CR'), 0, 'no public data');
});

test('the NOR flash: write enable, sector erase, page program (AND, wrapping), read, status, IDs', () => {
  const data = new Uint8Array(1 << 21).fill(0);
  let now = 0;
  const nor = new NorFlash(data, UID, () => now);
  nor.command([0x20, 0x00, 0x10, 0x00]);
  assert.equal(data[0x1000], 0, 'no erase without write enable');
  nor.command([0x06]);
  assert.deepEqual(nor.command([0x05, 0]), [0xff, 0x02], 'WEL');
  nor.command([0x20, 0x00, 0x1f, 0xff]);
  assert.deepEqual([data[0xfff], data[0x1000], data[0x1fff], data[0x2000]], [0, 0xff, 0xff, 0], 'the 4 KiB sector of 0x1fff');
  assert.deepEqual(nor.command([0x05, 0]), [0xff, 0x01], 'WIP, WEL cleared');
  nor.command([0x06]);
  assert.equal(nor.command([0x05, 0])[1] & 2, 0, 'write enable refused while busy');
  now += BUSY_NS.sector;
  assert.deepEqual(nor.command([0x05, 0]), [0xff, 0x00]);
  nor.command([0x06]);
  nor.command([0x02, 0x00, 0x10, 0xfe, 0xa5, 0x0f, 0x3c]);
  now += BUSY_NS.page;
  assert.deepEqual([data[0x10fe], data[0x10ff], data[0x1000], data[0x1001]], [0xa5, 0x0f, 0x3c, 0xff], 'wraps inside its page');
  nor.command([0x06]);
  nor.command([0x02, 0x00, 0x10, 0xfe, 0xff, 0xf1]);
  now += BUSY_NS.page;
  assert.equal(data[0x10ff], 0x01, 'programming only clears bits');
  assert.deepEqual(nor.command([0x03, 0x00, 0x10, 0xfe, 0, 0, 0]).slice(4), [0xa5, 0x01, 0xff], "reads go on past the page");
  assert.deepEqual(nor.command([0x0b, 0x00, 0x10, 0xfe, 0, 0, 0]).slice(5), [0xa5, 0x01]);
  assert.deepEqual(nor.command([0x4b, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]).slice(5), UID);
  assert.deepEqual(nor.command([0x9f, 0, 0, 0]).slice(1), [0xef, 0x40, 0x15]);
  assert.deepEqual(nor.command([0x35, 0]), [0xff, 0x02], 'QE set');
  nor.command([0x06]);
  nor.command([0x04]);
  nor.command([0x20, 0x00, 0x10, 0x00]);
  assert.equal(data[0x10fe], 0xa5, 'write disable (04): no erase');
  assert.deepEqual(nor.ops.map((o) => [o.cmd, o.addr]), [[0x20, 0x1fff], [0x02, 0x10fe], [0x02, 0x10fe]]);
});

test('the SSI: embassy-rp\'s unique-ID read (transfer mode 3) and boot2\'s status read (mode 0)', () => {
  const { rp } = chip();
  const w = (off, v) => rp.writeUint32(SSI + off, v);
  const r = (off) => rp.readUint32(SSI + off);
  // As the ROM's flash_exit_xip leaves it: 8-bit frames, TX and RX, slave 0.
  romCall(rp, 'IF', []);
  romCall(rp, 'EX', []);
  assert.equal(r(0x00), 7 << 16);
  assert.equal(r(0x10), 1);
  // embassy-rp flash.rs read_flash_inner: TMOD 3, CTRLR1 = 4 + 8 - 1, 0x4B by STRB, poll RFNE.
  w(0x08, 0);
  w(0x00, r(0x00) | 0x300);
  w(0x04, 11);
  w(0x08, 1);
  rp.writeUint8(SSI + 0x60, 0x4b);
  const got = [];
  for (let i = 0; i < 12; i++) {
    assert.ok(r(0x28) & 0x8, 'RFNE');
    got.push(rp.readUint8(SSI + 0x60));
  }
  assert.equal(r(0x28) & 0x8, 0, 'nothing more');
  assert.deepEqual(got.slice(4), UID);
  w(0x08, 0);
  w(0x04, 0);
  // boot2 (W25Q080) read_flash_sreg: TMOD 0, 0x35 twice, wait TFE and not BUSY, read two.
  w(0x00, 7 << 16);
  w(0x08, 1);
  w(0x60, 0x35);
  w(0x60, 0x35);
  assert.equal(r(0x28) & 0x5, 0x4, 'TFE, not BUSY');
  assert.equal(r(0x24), 2);
  assert.deepEqual([r(0x60), r(0x60)], [0xff, 0x02]);
  // The chip select held low by IO_QSPI (OUTOVER 2) keeps one command over separate writes.
  rp.writeUint32(IO_QSPI_SS_CTRL, 2 << 8);
  w(0x60, 0x9f);
  assert.equal(r(0x28) & 0x4, 0x4);
  w(0x60, 0);
  w(0x60, 0);
  w(0x60, 0);
  assert.deepEqual([r(0x60), r(0x60), r(0x60), r(0x60)], [0xff, 0xef, 0x40, 0x18]);
  rp.writeUint32(IO_QSPI_SS_CTRL, 3 << 8);
  assert.equal(rp.readUint32(XIP_STAT) & 1, 1, 'XIP_CTRL FLUSH_READY');
  assert.equal(rp.readUint32(STREAM_CTR), 0, 'no stream in flight');
});

test('erase and program through the ROM: XIP reads see them, the core is held for the flash times', () => {
  const { rp, nor } = chip();
  const at = 0x1ff000;
  rp.flash.fill(0x00, at, at + 0x1000);
  for (const c of ['IF', 'EX']) romCall(rp, c, []);
  const erase = romCall(rp, 'RE', [at, 0x1000, 1 << 31, 0]);
  assert.equal(erase.ns >= BUSY_NS.sector && erase.ns < BUSY_NS.sector + 10e3, true, `${erase.ns} ns`);
  assert.equal(rp.readUint32(0x10000000 + at), 0xffffffff);
  const src = 0x20001000;
  [0x01, 0x02, 0x03, 0x04].forEach((b, i) => rp.writeUint8(src + i, b));
  for (let i = 4; i < 256; i++) rp.writeUint8(src + i, 0xff);
  const prog = romCall(rp, 'RP', [at + 0x100, src, 256]);
  assert.ok(prog.ns >= BUSY_NS.page && prog.ns < BUSY_NS.page + 10e3, `${prog.ns} ns`);
  for (const c of ['FC', 'CX']) romCall(rp, c, []);
  assert.equal(rp.readUint32(0x10000000 + at + 0x100), 0x04030201, 'XIP');
  assert.equal(rp.readUint32(0x13000000 + at + 0x104), 0xffffffff, 'XIP_NOCACHE_NOALLOC');
  assert.deepEqual(nor.ops.map((o) => o.cmd), [0x20, 0x02]);
  const dst = 0x20002000;
  assert.equal(romCall(rp, 'C4', [dst, 0x10000000 + at + 0x100, 8]).r0, dst, 'memcpy44 returns dest');
  assert.equal(rp.readUint32(dst), 0x04030201);
  assert.deepEqual(rp.romCalls, ['IF', 'EX', 'RE', 'RP', 'FC', 'CX', 'C4']);
  // With a block size and command, aligned 64 KiB blocks go in one command each, the rest by sector.
  rp.flash.fill(0, 0x100000, 0x122000);
  const blocks = romCall(rp, 'RE', [0x100000, 0x21000, 0x10000, 0xd8]);
  assert.ok(blocks.ns >= 2 * BUSY_NS.block64 + BUSY_NS.sector, `${blocks.ns} ns`);
  assert.deepEqual(nor.ops.slice(2).map((o) => [o.cmd, o.addr]), [[0xd8, 0x100000], [0xd8, 0x110000], [0x20, 0x120000]]);
  assert.equal(rp.flash.subarray(0x100000, 0x121000).every((b) => b === 0xff), true);
  assert.equal(rp.flash[0x121000], 0);
});

test('a BKPT outside the ROM still raises a HardFault', () => {
  const { rp } = chip();
  rp.sramView.setUint16(0x3000, T.bkpt(0), true);
  rp.core.PC = 0x20003000;
  rp.core.executeInstruction();
  assert.equal(rp.core.IPSR, 3);
});

test('each chip has its own unique ID: the default from its name, or the one given', () => {
  assert.notDeepEqual(defaultUid('db09'), defaultUid('db10'));
  assert.equal(defaultUid('db09').length, 8);
  const rig = new Rig();
  const a = rig.addChip('a', image([T.b(0, 0)]));
  const b = rig.addChip('b', image([T.b(0, 0)]), { uid: '0102030405060708' });
  assert.deepEqual(Array.from(a.nor.uid), defaultUid('a'));
  assert.deepEqual(Array.from(b.nor.uid), [1, 2, 3, 4, 5, 6, 7, 8]);
});

/** An image: the vector table at 0x10000100 (SP, reset at 0x10000200), `code` at 0x10000200. */
function image(code) {
  const data = new Uint8Array(0x200);
  const v = new DataView(data.buffer);
  v.setUint32(0, 0x20040000, true);
  v.setUint32(4, 0x10000201, true);
  code.forEach((h, i) => v.setUint16(0x100 + 2 * i, h, true));
  return { path: 'test', segments: [{ paddr: 0x10000100, data }], symbols: new Map() };
}

/** ldr r0, [pc, #4]; ldr r1, [pc, #8]; str r1, [r0]; b .; AIRCR; VECTKEY | SYSRESETREQ. */
const SYS_RESET = [0x4801, 0x4902, 0x6001, 0xe7fe, AIRCR & 0xffff, AIRCR >>> 16, 0x0004, 0x05fa];

test('SYSRESETREQ resets the chip: it boots from its vector table, flash, REASON and SCRATCH kept', () => {
  const rig = new Rig();
  const old = rig.addChip('c', image(SYS_RESET));
  old.rp.flash[0x1ff000] = 0x42;
  old.rp.writeUint32(SCRATCH0 + 4, 0x1234);
  old.rp.peripherals[WATCHDOG >>> 12].reason = REASON_FORCE;
  rig.run(1000);
  const fresh = rig.chips[0];
  assert.notEqual(fresh, old, 'a fresh chip');
  assert.deepEqual(fresh.resets.map((r) => r.kind), ['sysreset']);
  assert.equal(fresh.rp.core.PC, 0x10000200, 'at the reset vector');
  assert.equal(fresh.rp.readUint8(0x101ff000), 0x42, 'flash kept');
  assert.equal(fresh.nor, old.nor);
  assert.equal(fresh.rp.flash, old.rp.flash, 'one array: XIP reads what was written');
  assert.equal(fresh.rp.readUint32(SCRATCH0 + 4), 0x1234);
  assert.equal(fresh.rp.readUint32(REASON), REASON_FORCE);
  assert.equal(old.rp.readUint32(AIRCR) >>> 16, 0xfa05, 'VECTKEYSTAT');
  // A write without the key does nothing.
  const rig2 = new Rig();
  const c = rig2.addChip('c', image([0x4801, 0x4902, 0x6001, 0xe7fe, AIRCR & 0xffff, AIRCR >>> 16, 0x0004, 0x05fb]));
  rig2.run(1000);
  assert.equal(rig2.chips[0], c);
});

test('a power cycle keeps the flash and the unique ID, and clears REASON, SCRATCH and the flash\'s busy state', () => {
  const rig = new Rig();
  const old = rig.addChip('c', image([T.b(0, 0)]), { uid: UID });
  old.rp.flash[0x1ff000] = 0x42;
  old.rp.writeUint32(SCRATCH0, 0x1234);
  old.rp.writeUint32(WATCHDOG, 1 << 31); // a watchdog reset first (TRIGGER): REASON FORCE
  rig.run(1000);
  const afterWd = rig.chips[0];
  assert.equal(afterWd.rp.readUint32(REASON), REASON_FORCE);
  assert.equal(afterWd.rp.readUint8(0x101ff000), 0x42);
  afterWd.nor.busyUntil = rig.now() + BUSY_NS.sector; // an erase under way
  afterWd.nor.wel = true;
  const fresh = rig.powerCycle(afterWd);
  assert.equal(fresh.nor.busy, false, 'the flash powered up again: not busy');
  assert.equal(fresh.nor.wel, false);
  assert.equal(fresh.rp.readUint8(0x101ff000), 0x42, 'flash kept');
  assert.equal(fresh.rp.readUint8(0x10000100 + 4), 0x01, 'the image too');
  assert.deepEqual(Array.from(fresh.nor.uid), UID);
  assert.equal(fresh.rp.readUint32(REASON), 0);
  assert.equal(fresh.rp.readUint32(SCRATCH0), 0);
});
