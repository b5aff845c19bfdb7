// Target (slave) mode of lib/i2c.js on the bus of lib/bus.js: one test per point of the
// DW_apb_i2c behaviour the X10 images rely on.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { pair, rd, wr, R } from './helpers.js';
import { FIRST_DATA_BYTE, INTR, STATUS, ABRT } from '../lib/i2c.js';

const BIT_NS = 10000; // 100 kHz

test('a write to IC_SAR is received with FIRST_DATA_BYTE (bit 11) on its first byte, then STOP_DET', () => {
  const { c, m, t } = pair();
  wr(m, R.DATA_CMD, 0x12);
  wr(m, R.DATA_CMD, 0x34 | (1 << 9)); // STOP
  c.run(1e5 + 5 * BIT_NS);
  assert.equal(rd(t, R.STATUS) & STATUS.SLV_ACTIVITY, STATUS.SLV_ACTIVITY, 'active until the STOP');
  c.run(1e6);
  assert.equal(rd(t, R.RXFLR), 2);
  assert.equal(rd(t, R.DATA_CMD), 0x12 | FIRST_DATA_BYTE);
  assert.equal(rd(t, R.DATA_CMD), 0x34);
  assert.notEqual(rd(t, R.RAW) & INTR.STOP_DET, 0);
  assert.equal(rd(t, R.STATUS) & STATUS.SLV_ACTIVITY, 0);
  assert.notEqual(rd(m, R.RAW) & INTR.STOP_DET, 0, 'the controller sees its STOP');
});

test('another address is not acknowledged: the controller aborts with ABRT_7B_ADDR_NOACK', () => {
  const { c, m, t } = pair();
  wr(m, R.ENABLE, 0);
  wr(m, R.TAR, 0x0a);
  wr(m, R.ENABLE, 1);
  wr(m, R.DATA_CMD, 0x12 | (1 << 9));
  c.run(1e6);
  assert.notEqual(rd(m, R.RAW) & INTR.TX_ABRT, 0);
  assert.equal(rd(m, R.ABRT_SRC) & ABRT.ADDR7_NOACK, ABRT.ADDR7_NOACK);
  assert.equal(rd(t, R.RXFLR), 0);
  assert.equal(rd(t, R.RAW) & INTR.STOP_DET, 0, 'STOP_DET_IFADDRESSED: not addressed, no STOP_DET');
});

test('a read raises RD_REQ and stretches SCL until IC_DATA_CMD is written; the NACK of the last byte raises RX_DONE', () => {
  const { c, bus, m, t } = pair();
  wr(m, R.DATA_CMD, 1 << 8);
  wr(m, R.DATA_CMD, (1 << 8) | (1 << 9));
  c.run(1e6);
  assert.notEqual(rd(t, R.RAW) & INTR.RD_REQ, 0);
  assert.equal(bus.transfers.length, 0, 'held: no STOP yet');
  rd(t, R.CLR_RD_REQ);
  wr(t, R.DATA_CMD, 0xa1);
  c.run(1.2e6);
  assert.notEqual(rd(t, R.RAW) & INTR.RD_REQ, 0, 'second byte requested');
  wr(t, R.DATA_CMD, 0xa2);
  c.run(3e6);
  assert.equal(rd(m, R.DATA_CMD) & 0xff, 0xa1);
  assert.equal(rd(m, R.DATA_CMD) & 0xff, 0xa2);
  assert.notEqual(rd(t, R.RAW) & INTR.RX_DONE, 0);
  assert.equal(bus.transfers.length, 1);
  assert.ok(bus.transfers[0].t1 > 1.2e6, 'the transfer lasted as long as the stretch');
});

test('bytes left in the TX FIFO are flushed with TX_ABRT on the next read, and the FIFO stays flushed until TX_ABRT is cleared', () => {
  const { c, m, t } = pair();
  wr(m, R.DATA_CMD, (1 << 8) | (1 << 9)); // read one byte
  c.run(5e5);
  assert.notEqual(rd(t, R.RAW) & INTR.RD_REQ, 0);
  rd(t, R.CLR_RD_REQ);
  for (const b of [1, 2, 3]) wr(t, R.DATA_CMD, b); // answer with 3: 2 left
  c.run(1e6);
  assert.equal(rd(m, R.DATA_CMD) & 0xff, 1);
  assert.equal(rd(t, R.TXFLR), 2);
  wr(m, R.DATA_CMD, (1 << 8) | (1 << 9));
  c.run(1.5e6);
  assert.notEqual(rd(t, R.RAW) & INTR.TX_ABRT, 0);
  const src = rd(t, R.ABRT_SRC);
  assert.equal(src & ABRT.SLVFLUSH_TXFIFO, ABRT.SLVFLUSH_TXFIFO);
  assert.equal(src >>> 23, 2, 'TX_FLUSH_CNT');
  assert.equal(rd(t, R.TXFLR), 0);
  assert.notEqual(rd(t, R.RAW) & INTR.RD_REQ, 0);
  wr(t, R.DATA_CMD, 9);
  assert.equal(rd(t, R.TXFLR), 0, 'ignored while TX_ABRT is set');
  rd(t, R.CLR_TX_ABRT);
  wr(t, R.DATA_CMD, 9);
  c.run(3e6);
  assert.equal(rd(m, R.DATA_CMD) & 0xff, 9);
});

test('write then read with a repeated START raises RESTART_DET; IC_CLR_RESTART_DET clears it', () => {
  const { c, m, t } = pair();
  wr(m, R.DATA_CMD, 0x30);
  wr(m, R.DATA_CMD, (1 << 8) | (1 << 10) | (1 << 9)); // RESTART, read, STOP
  c.run(1e6);
  const raw = rd(t, R.RAW);
  assert.notEqual(raw & INTR.RESTART_DET, 0);
  assert.notEqual(raw & INTR.RD_REQ, 0);
  assert.equal(rd(t, R.DATA_CMD), 0x30 | FIRST_DATA_BYTE);
  rd(t, R.CLR_RESTART_DET);
  assert.equal(rd(t, R.RAW) & INTR.RESTART_DET, 0);
});

test('a full RX FIFO stretches SCL (RX_FIFO_FULL_HLD_CTRL) until a byte is read', () => {
  const { c, bus, m, t } = pair();
  for (let i = 0; i < 17; i++) wr(m, R.DATA_CMD, i | (i === 16 ? 1 << 9 : 0));
  // 16 commands fit in the controller's FIFO; the 17th is dropped (TX_OVER): send it later.
  c.run(5e6);
  assert.equal(rd(t, R.RXFLR), 16);
  assert.equal(bus.transfers.length, 0);
  wr(m, R.DATA_CMD, 16 | (1 << 9));
  c.run(6e6);
  assert.equal(bus.transfers.length, 0, 'held while the FIFO is full');
  rd(t, R.DATA_CMD);
  c.run(8e6);
  assert.equal(bus.transfers.length, 1);
  assert.equal(rd(t, R.RXFLR), 16);
  assert.equal(rd(t, R.RAW) & INTR.RX_OVER, 0, 'nothing lost');
});

test('IC_SLV_DATA_NACK_ONLY makes the target NACK data: the controller aborts with ABRT_TXDATA_NOACK', () => {
  const { c, m, t } = pair();
  wr(t, R.SLV_DATA_NACK_ONLY, 1);
  assert.equal(rd(t, R.SLV_DATA_NACK_ONLY), 1);
  wr(m, R.DATA_CMD, 0x55 | (1 << 9));
  c.run(1e6);
  assert.equal(rd(m, R.ABRT_SRC) & ABRT.TXDATA_NOACK, ABRT.TXDATA_NOACK);
  assert.equal(rd(t, R.RXFLR), 0);
});

test('IC_ACK_GENERAL_CALL is a register (read back as written)', () => {
  const { t } = pair();
  assert.equal(rd(t, R.ACK_GENERAL_CALL), 1);
  wr(t, R.ACK_GENERAL_CALL, 0);
  assert.equal(rd(t, R.ACK_GENERAL_CALL), 0);
});

test('IC_SDA_HOLD resets to 1 and takes writes only while the block is disabled', () => {
  const { t } = pair();
  const SDA_HOLD = 0x7c;
  assert.equal(rd(t, SDA_HOLD), 1);
  wr(t, SDA_HOLD, 38);
  assert.equal(rd(t, SDA_HOLD), 1, 'enabled: the write is dropped');
  wr(t, R.ENABLE, 0);
  wr(t, SDA_HOLD, 38);
  wr(t, R.ENABLE, 1);
  assert.equal(rd(t, SDA_HOLD), 38);
});
