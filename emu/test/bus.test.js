// Timing, arbitration and the STOP gap of lib/bus.js.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { Bus } from '../lib/bus.js';
import { chip, clock, controller, target, rd, wr, R, pair } from './helpers.js';
import { ABRT, INTR } from '../lib/i2c.js';

const BIT_NS = 10000; // 100 kHz

test('a one-byte write takes START + 2 bytes of 9 SCL periods + STOP, from the SCL counts', () => {
  const { c, bus, m } = pair();
  wr(m, R.DATA_CMD, 0x42 | (1 << 9));
  c.run(1e6);
  const [tr] = bus.transfers;
  // START hold = SCL high time (5 µs); 18 bits; STOP after SCL high time (5 µs).
  assert.equal(tr.parts[0].t, 5000);
  assert.equal(tr.t1, 5000 + 18 * BIT_NS + 5000);
  assert.deepEqual(tr.parts[0].bytes, [0x42]);
});

test('the STOP gap is configurable', () => {
  const { c, bus, m } = pair({ stopGapNs: 40000 });
  wr(m, R.DATA_CMD, 0x42 | (1 << 9));
  c.run(1e6);
  assert.equal(bus.transfers[0].t1, 5000 + 18 * BIT_NS + 40000);
});

test('two controllers starting together: the lower address byte wins, the other aborts with ARB_LOST', () => {
  const c = clock();
  const bus = new Bus(c);
  const a = chip(), b = chip(), t9 = chip(), t10 = chip();
  for (const [n, x] of [['a', a], ['b', b], ['t9', t9], ['t10', t10]]) bus.attach(x.i2c[0], n);
  controller(a, 0x0a);
  controller(b, 0x09);
  target(t9, 0x09);
  target(t10, 0x0a);
  wr(a, R.DATA_CMD, 0x11 | (1 << 9));
  wr(b, R.DATA_CMD, 0x22 | (1 << 9));
  c.run(2e5);
  assert.equal(rd(a, R.ABRT_SRC) & ABRT.ARB_LOST, ABRT.ARB_LOST);
  assert.notEqual(rd(a, R.RAW) & INTR.TX_ABRT, 0);
  assert.equal(bus.transfers.length, 1);
  assert.equal(bus.transfers[0].master, 'b');
  assert.equal(rd(t9, R.DATA_CMD) & 0xff, 0x22);
  assert.equal(rd(t10, R.RXFLR), 0);
});

test('a controller that starts while the bus is busy waits for the STOP and the bus free time', () => {
  const c = clock();
  const bus = new Bus(c);
  const a = chip(), b = chip(), t9 = chip();
  for (const [n, x] of [['a', a], ['b', b], ['t9', t9]]) bus.attach(x.i2c[0], n);
  controller(a, 0x09);
  controller(b, 0x09);
  target(t9, 0x09);
  wr(a, R.DATA_CMD, 0x11 | (1 << 9));
  c.run(50000);
  wr(b, R.DATA_CMD, 0x22 | (1 << 9));
  c.run(2e6);
  assert.equal(bus.transfers.length, 2);
  assert.equal(bus.transfers[1].master, 'b');
  assert.ok(bus.transfers[1].t0 >= bus.transfers[0].t1 + 5000);
});

test('a controller reset mid-transfer leaves without a STOP; its target stays active until the next START', () => {
  const { c, bus, m, t } = pair();
  wr(m, R.DATA_CMD, 0x42);
  c.run(1e5 + 15000);
  m.i2c[0].resetBlock();
  c.run(1e6);
  assert.equal(bus.transfers[0].end, 'abandoned');
  assert.notEqual(rd(t, R.STATUS) & 0x40, 0, 'SLV_ACTIVITY stays set');
  assert.equal(rd(t, R.RAW) & INTR.STOP_DET, 0);
});

test('a general call (a write to 0x00) reaches every target that acknowledges general calls, and no other', () => {
  const c = clock();
  const bus = new Bus(c);
  const m = chip(), t9 = chip(), t10 = chip(), t11 = chip();
  for (const [n, x] of [['m', m], ['t9', t9], ['t10', t10], ['t11', t11]]) bus.attach(x.i2c[0], n);
  controller(m, 0x00);
  target(t9, 0x09);
  target(t10, 0x0a);
  target(t11, 0x0b);
  wr(t11, R.ACK_GENERAL_CALL, 0);
  wr(m, R.DATA_CMD, 0x81);
  wr(m, R.DATA_CMD, 0x00 | (1 << 9));
  c.run(1e6);
  const [tr] = bus.transfers;
  assert.equal(tr.parts[0].addr, 0);
  assert.equal(tr.parts[0].ack, true);
  assert.deepEqual(tr.parts[0].bytes, [0x81, 0x00]);
  for (const t of [t9, t10]) {
    assert.equal(rd(t, R.RXFLR), 2);
    // The first byte is flagged FIRST_DATA_BYTE (bit 11), as after an addressed write.
    assert.equal(rd(t, R.DATA_CMD), 0x81 | (1 << 11));
    assert.equal(rd(t, R.DATA_CMD) & 0xff, 0x00);
  }
  assert.equal(rd(t11, R.RXFLR), 0);
  assert.equal(rd(m, R.ABRT_SRC), 0);
});
