// One test per model of lib/reset.js and per injection of lib/inject.js.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { RP2040 } from 'rp2040js';
import { applyAll, bootFromFlash } from '../lib/patches.js';
import { applyResetModel, watchdogReset, HAD_POR, REASON_TIMER, REASON_FORCE } from '../lib/reset.js';
import { injectPanic, injectHang, HANG_AT } from '../lib/inject.js';

const WATCHDOG = 0x40058000;
const CTRL = WATCHDOG, LOAD = WATCHDOG + 4, REASON = WATCHDOG + 8, SCRATCH0 = WATCHDOG + 0xc;
const CHIP_RESET = 0x40064008;
const UDF = 0xde00, LOOP = 0xe7fe, NOP = 0xbf00;

/** A chip with the rig's fixes and models, running `code` (halfwords) at 0x10000200; its
 * HardFault vector points to a loop at 0x10000300. */
function chip(code) {
  const rp = new RP2040();
  rp.logger = { debug() {}, info() {}, warn() {}, error() {} };
  applyAll(rp);
  applyResetModel(rp);
  rp.flashView.setUint32(0x100, 0x20001000, true);
  rp.flashView.setUint32(0x104, 0x10000201, true);
  rp.flashView.setUint32(0x10c, 0x10000301, true); // HardFault
  code.forEach((h, i) => rp.flashView.setUint16(0x200 + 2 * i, h, true));
  rp.flashView.setUint16(0x300, LOOP, true);
  bootFromFlash(rp);
  return rp;
}

/** Runs the core for `ns` of virtual time, as the rig does. */
function run(rp, ns) {
  const end = rp.clock.nanosCounter + ns;
  while (rp.clock.nanosCounter < end) {
    if (rp.core.waiting) rp.clock.tick(Math.min(1000, end - rp.clock.nanosCounter));
    else rp.clock.tick(rp.core.executeInstruction() * 8);
  }
}

test('UDF raises a HardFault whose stacked return address is the UDF', () => {
  const rp = chip([NOP, UDF, NOP]);
  rp.core.executeInstruction();
  rp.core.executeInstruction();
  assert.equal(rp.core.IPSR, 3, 'in HardFault');
  assert.equal(rp.core.PC & ~1, 0x10000300);
  assert.equal(rp.readUint32(rp.core.SP + 0x18), 0x10000202, 'stacked PC: the UDF');
});

test('CHIP_RESET reads HAD_POR, and its HAD_ bits are read-only', () => {
  const rp = chip([LOOP]);
  assert.equal(rp.readUint32(CHIP_RESET), HAD_POR);
  rp.writeUint32(CHIP_RESET, 0xffffffff);
  assert.equal(rp.readUint32(CHIP_RESET), HAD_POR);
});

test('the watchdog fires LOAD/2 µs after it is enabled and unfed, and the core stops', () => {
  const rp = chip([NOP, LOOP]);
  rp.writeUint32(LOAD, 2000); // 1 ms (the counter goes down twice per µs tick)
  rp.writeUint32(CTRL, 1 << 30);
  rp.writeUint32(SCRATCH0, 0x58313002);
  run(rp, 900e3);
  assert.equal(rp.watchdogFired, null, 'not before 1 ms');
  run(rp, 200e3);
  assert.ok(rp.watchdogFired, 'fired by 1.1 ms');
  assert.equal(rp.watchdogFired.reason, REASON_TIMER);
  assert.equal(rp.watchdogFired.scratch[0], 0x58313002);
  assert.ok(Math.abs(rp.watchdogFired.t - 1e6) < 2e3, `at ${rp.watchdogFired.t} ns`);
  const pc = rp.core.PC;
  run(rp, 10e3);
  assert.equal(rp.core.PC, pc, 'held in reset');
});

test('a fed watchdog does not fire; CTRL.TRIGGER fires it at once with REASON FORCE', () => {
  const rp = chip([LOOP]);
  rp.writeUint32(LOAD, 2000);
  rp.writeUint32(CTRL, 1 << 30);
  for (let i = 0; i < 5; i++) {
    run(rp, 800e3);
    rp.writeUint32(LOAD, 2000);
  }
  assert.equal(rp.watchdogFired, null);
  rp.writeUint32(CTRL, (1 << 30) | (1 << 31));
  assert.equal(rp.watchdogFired.reason, REASON_FORCE);
});

test('a watchdog reset keeps REASON, SCRATCH, the input levels and the logs; the chip boots afresh', () => {
  const old = chip([LOOP]);
  old.writeUint32(SCRATCH0, 0x58313003);
  old.writeUint32(SCRATCH0 + 4 * 7, 77);
  old.gpio[14].setInputValue(true);
  old.adc.channelValues[1] = 1234;
  old.writeUint32(CTRL, (1 << 30) | (1 << 31));
  const logs = { defmt: [1], pinLog: [2], pwmLog: [3] };
  const before = { rp: old, readRtt() {}, ...logs };
  const fresh = { rp: chip([LOOP]), clock: null, setPin(p, l) { this.rp.gpio[p].setInputValue(!!l); } };
  fresh.clock = fresh.rp.clock;
  const rig = { now: () => 5e6, powerCycle: (c) => { assert.equal(c, before); return fresh; } };
  const after = watchdogReset(rig, before);
  assert.equal(after, fresh);
  assert.equal(after.rp.readUint32(REASON), REASON_FORCE);
  assert.equal(after.rp.readUint32(SCRATCH0), 0x58313003);
  assert.equal(after.rp.readUint32(SCRATCH0 + 4 * 7), 77);
  assert.equal(after.rp.gpio[14].rawInputValue, true);
  assert.equal(after.rp.adc.channelValues[1], 1234);
  assert.equal(after.rp.watchdogFired, null, 'the fresh chip runs');
  assert.equal(after.clock.nanosCounter, 5e6);
  assert.deepEqual([after.defmt, after.pinLog, after.pwmLog], [logs.defmt, logs.pinLog, logs.pwmLog]);
  assert.deepEqual(after.resets, [{ t: 0, kind: 'watchdog', reason: REASON_FORCE, scratch0: 0x58313003 }]);
});

test('injected panic and hang start in thread mode: the panic handler, a spin at HANG_AT', () => {
  // The chip sits in its HardFault handler (an exception) when the injections come.
  const rp = chip([UDF]);
  rp.flashView.setUint16(0x300, NOP, true);
  rp.flashView.setUint16(0x302, 0x4770, true); // bx lr: returns to thread mode
  rp.core.executeInstruction();
  assert.equal(rp.core.IPSR, 3);
  rp.flashView.setUint16(0x200, LOOP, true);
  const c = { name: 'c', rp, clock: rp.clock, elf: { path: 'x', symbols: new Map([['_RNvCs_7___rustc17rust_begin_unwind', { value: 0x10000400 }]]) } };
  assert.equal(injectPanic(c), 0x10000400);
  assert.equal(rp.core.IPSR, 0);
  assert.equal(rp.core.PC, 0x10000400);
  assert.equal(injectHang(c), HANG_AT);
  assert.equal(rp.core.PC, HANG_AT);
  assert.equal(rp.core.PM, false, 'interrupts on');
  rp.core.executeInstruction();
  assert.equal(rp.core.PC, HANG_AT, 'spins');
});

test('the injections wait until the core leaves its critical section (PRIMASK clear)', () => {
  const CPSIE = 0xb662;
  const rp = chip([NOP, CPSIE, LOOP]);
  rp.core.PM = true; // in a critical section, two instructions from its end
  const c = { name: 'c', rp, clock: rp.clock, elf: { path: 'x', symbols: new Map() } };
  assert.equal(injectHang(c), HANG_AT);
  assert.equal(rp.core.PM, false);
  assert.equal(rp.clock.nanos > 0, true, 'ran the NOP and the CPSIE first');
});
