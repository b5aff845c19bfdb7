// Chips without firmware for the unit tests: registers are driven by the test itself.
import { RP2040 } from 'rp2040js';
import { applyAll } from '../lib/patches.js';
import { Bus } from '../lib/bus.js';

export const I2C0 = 0x40044000;
export const R = {
  CON: 0x00, TAR: 0x04, SAR: 0x08, DATA_CMD: 0x10, SS_HCNT: 0x14, SS_LCNT: 0x18,
  INTR_STAT: 0x2c, INTR_MASK: 0x30, RAW: 0x34, RX_TL: 0x38, TX_TL: 0x3c, CLR_INTR: 0x40,
  CLR_RD_REQ: 0x50, CLR_TX_ABRT: 0x54, CLR_RX_DONE: 0x58, CLR_STOP_DET: 0x60, ENABLE: 0x6c,
  STATUS: 0x70, TXFLR: 0x74, RXFLR: 0x78, ABRT_SRC: 0x80, SLV_DATA_NACK_ONLY: 0x84,
  ACK_GENERAL_CALL: 0x98, CLR_RESTART_DET: 0xa8,
};

/** A bare chip with the rig's fixes. */
export function chip() {
  const rp = new RP2040();
  rp.logger = { debug() {}, info() {}, warn() {}, error() {} };
  applyAll(rp);
  return rp;
}

/** Shared virtual time for a bus without cores. */
export function clock() {
  const c = { t: 0, q: [] };
  c.now = () => c.t;
  c.at = (t, fn) => { c.q.push({ t, fn }); c.q.sort((a, b) => a.t - b.t); };
  c.run = (until) => {
    while (c.q.length && c.q[0].t <= until) {
      const e = c.q.shift();
      c.t = e.t;
      e.fn();
    }
    c.t = Math.max(c.t, until);
  };
  return c;
}

export const rd = (rp, off) => rp.readUint32(I2C0 + off);
export const wr = (rp, off, v) => rp.writeUint32(I2C0 + off, v);

/** Controller at 100 kHz (125 MHz clk_sys: 625 + 625 cycles = 10 µs per bit). */
export function controller(rp, tar) {
  wr(rp, R.ENABLE, 0);
  wr(rp, R.CON, 1 | (1 << 6) | (1 << 5) | (1 << 1) | (1 << 8));
  wr(rp, R.SS_HCNT, 625);
  wr(rp, R.SS_LCNT, 625);
  wr(rp, R.TAR, tar);
  wr(rp, R.ENABLE, 1);
}

/** Target as embassy-rp 0.10's I2cSlave::reset sets it up. */
export function target(rp, sar) {
  wr(rp, R.ENABLE, 0);
  wr(rp, R.SAR, sar);
  wr(rp, R.CON, (1 << 8) | (1 << 9) | (2 << 1) | (1 << 7));
  wr(rp, R.TX_TL, 0);
  wr(rp, R.RX_TL, 0);
  wr(rp, R.ENABLE, 1);
}

/** A controller chip `m` and a target chip `t` at 0x09 on one bus. */
export function pair(options = {}) {
  const c = clock();
  const bus = new Bus(c, options);
  const m = chip();
  const t = chip();
  bus.attach(m.i2c[0], 'm');
  bus.attach(t.i2c[0], 't');
  controller(m, 0x09);
  target(t, 0x09);
  return { c, bus, m, t };
}
