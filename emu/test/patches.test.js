// One test per rp2040js fix of lib/patches.js.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { RP2040 } from 'rp2040js';
import { fixSev, bootFromFlash, applyAll } from '../lib/patches.js';
import { chip, rd, wr, R } from './helpers.js';

/** A flash image: vector table at 0x100 (SP, reset -> 0x200), `code` (halfwords) at 0x200. */
function program(rp, code) {
  rp.flashView.setUint32(0x100, 0x20001000, true);
  rp.flashView.setUint32(0x104, 0x10000201, true);
  code.forEach((h, i) => rp.flashView.setUint16(0x200 + 2 * i, h, true));
}
const SEV = 0xbf40, WFE = 0xbf20, LOOP = 0xe7fe;

test('SEV sets the event register, so the next WFE does not sleep', () => {
  const bare = new RP2040();
  bare.logger = { debug() {}, info() {}, warn() {}, error() {} };
  program(bare, [SEV, WFE, LOOP]);
  bootFromFlash(bare);
  bare.core.executeInstruction();
  bare.core.executeInstruction();
  assert.equal(bare.core.waiting, true, 'rp2040js 1.4.1 alone sleeps after SEV; WFE');

  const rp = new RP2040();
  rp.logger = { debug() {}, info() {}, warn() {}, error() {} };
  fixSev(rp);
  program(rp, [SEV, WFE, LOOP]);
  bootFromFlash(rp);
  rp.core.executeInstruction();
  assert.equal(rp.core.eventRegistered, true);
  rp.core.executeInstruction();
  assert.equal(rp.core.waiting, false);
  assert.equal(rp.core.eventRegistered, false, 'WFE consumed the event');
});

test('boot from the vector table at 0x10000100', () => {
  const rp = chip();
  program(rp, [LOOP]);
  bootFromFlash(rp);
  assert.equal(rp.core.SP, 0x20001000);
  assert.equal(rp.core.PC, 0x10000200);
  assert.equal(rp.core.VTOR, 0x10000100);
});

test('IC_INTR_MASK writes reach the I2C model and drive the IRQ line', () => {
  const rp = chip();
  wr(rp, R.INTR_MASK, 0);
  assert.equal(rd(rp, R.INTR_MASK), 0);
  rd(rp, R.DATA_CMD); // empty RX FIFO: RX_UNDER
  assert.equal(rd(rp, R.RAW) & 1, 1);
  assert.equal(rd(rp, R.INTR_STAT) & 1, 0);
  assert.equal(rp.core.pendingInterrupts & (1 << 23), 0);
  wr(rp, R.INTR_MASK, 1);
  assert.equal(rd(rp, R.INTR_STAT) & 1, 1);
  assert.notEqual(rp.core.pendingInterrupts & (1 << 23), 0, 'I2C0_IRQ pending');
});

test('RESETS resets the I2C block', () => {
  const rp = chip();
  wr(rp, R.ENABLE, 0);
  wr(rp, R.SAR, 0x09);
  wr(rp, R.CON, 0x300);
  wr(rp, R.ENABLE, 1);
  wr(rp, R.DATA_CMD, 0x42);
  assert.equal(rd(rp, R.SAR), 0x09);
  const RESETS = 0x4000c000;
  rp.writeUint32(RESETS + 0x2000, 1 << 3); // atomic set: assert I2C0's reset
  assert.equal(rp.readUint32(RESETS + 8) & (1 << 3), 0, 'RESET_DONE low while in reset');
  rp.writeUint32(RESETS + 0x3000, 1 << 3); // atomic clear
  assert.notEqual(rp.readUint32(RESETS + 8) & (1 << 3), 0);
  assert.equal(rd(rp, R.SAR), 0x55);
  assert.equal(rd(rp, R.ENABLE), 0);
  assert.equal(rd(rp, R.TXFLR), 0);
  assert.equal(rd(rp, R.CON) & 1, 1, 'master mode after reset');
});

test('applyAll replaces both I2C blocks on the bus map', () => {
  const rp = new RP2040();
  applyAll(rp);
  assert.equal(rp.peripherals[0x40044], rp.i2c[0]);
  assert.equal(rp.peripherals[0x40048], rp.i2c[1]);
});
