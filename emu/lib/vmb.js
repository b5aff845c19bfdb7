// A scripted motherboard on the bus: no firmware, its I2C blocks driven from JavaScript, so a
// scenario can send exact frames to a db-pico with exact timing (bus speed, STOP gap, aborts).
// I2C0 is its controller; I2C1 is its target at the MB address, which records every event a
// daughterboard writes (the real MB switches one block between roles; this one needs not).
import { RP2040 } from 'rp2040js';
import { applyAll } from './patches.js';

const CON = 0x00, TAR = 0x04, SAR = 0x08, DATA = 0x10, FS_H = 0x1c, FS_L = 0x20, SS_H = 0x14, SS_L = 0x18;
const RAW = 0x34, CLR_INTR = 0x40, ENABLE = 0x6c, RXFLR = 0x78, ABRT_SRC = 0x80;

export class VirtualMb {
  constructor(rig, options = {}) {
    this.rig = rig;
    this.rp = new RP2040();
    this.rp.logger = { debug() {}, info() {}, warn() {}, error() {} };
    applyAll(this.rp);
    this.ctrl = this.rp.i2c[0];
    this.tgt = this.rp.i2c[1];
    rig.bus.attach(this.ctrl, 'vmb');
    rig.bus.attach(this.tgt, 'vmb@08');
    this.setHz(options.hz ?? 100000);
    // Target at the MB address, as embassy-rp sets one up.
    this.w(this.tgt, SAR, options.address ?? 0x08);
    this.w(this.tgt, CON, (1 << 8) | (1 << 9) | (2 << 1) | (1 << 7));
    // Its own general calls are not events (IC_ACK_GENERAL_CALL resets to 1).
    this.w(this.tgt, 0x98, 0);
    this.w(this.tgt, ENABLE, 1);
    this.events = []; // { t, bytes }
    this.rx = [];
    this.seq = 0;
    this.result = null;
    this.job = null;
    rig.hooks.push(() => this.poll());
  }

  w(b, off, v) { b.writeUint32(off, v); }
  r(b, off) { return b.readUint32(off); }

  /** Sets the controller's SCL frequency (clk_sys 125 MHz, even high/low counts). */
  setHz(hz) {
    this.hz = hz;
    const half = Math.round(125e6 / hz / 2);
    this.w(this.ctrl, ENABLE, 0);
    const speed = hz > 100000 ? 2 : 1;
    this.w(this.ctrl, CON, 1 | (1 << 6) | (1 << 5) | (speed << 1) | (1 << 8));
    this.w(this.ctrl, speed === 1 ? SS_H : FS_H, half);
    this.w(this.ctrl, speed === 1 ? SS_L : FS_L, half);
    this.w(this.ctrl, ENABLE, 1);
  }

  /** Next sequence number (1..255). */
  nextSeq() { this.seq = (this.seq % 255) + 1; return this.seq; }

  /**
   * Starts one transaction: `bytes` written, then (repeated START) `readLen` bytes read.
   * Commands beyond the 16-entry FIFO are fed as it drains.
   */
  start(addr, bytes, readLen = 0) {
    this.w(this.ctrl, ENABLE, 0);
    this.w(this.ctrl, TAR, addr);
    this.w(this.ctrl, ENABLE, 1);
    this.r(this.ctrl, CLR_INTR);
    const cmds = bytes.map((b, i) => b | (i === bytes.length - 1 && readLen === 0 ? 1 << 9 : 0));
    for (let i = 0; i < readLen; i++) cmds.push((1 << 8) | (i === 0 && bytes.length ? 1 << 10 : 0) | (i === readLen - 1 ? 1 << 9 : 0));
    this.job = { cmds, readLen, got: [], t0: this.rig.now() };
    this.result = null;
    this.feed();
  }

  feed() {
    const j = this.job;
    while (j.cmds.length && this.r(this.ctrl, 0x74) < 16) this.w(this.ctrl, DATA, j.cmds.shift());
  }

  /** Called every quantum: feeds commands, collects read bytes and events. */
  poll() {
    const j = this.job;
    if (j) {
      while (this.r(this.ctrl, RXFLR) > 0) j.got.push(this.r(this.ctrl, DATA) & 0xff);
      const raw = this.r(this.ctrl, RAW);
      if (raw & (1 << 6)) {
        const src = this.r(this.ctrl, ABRT_SRC);
        this.r(this.ctrl, CLR_INTR);
        j.abort = src;
        j.cmds = [];
      } else this.feed();
      if (raw & (1 << 9) && !this.ctrl.mstActive) {
        this.r(this.ctrl, CLR_INTR);
        this.result = { ok: !j.abort, abort: j.abort ?? 0, read: j.got, t0: j.t0, t1: this.rig.now() };
        this.job = null;
      }
    }
    // Events: bytes written to the MB address, one frame per STOP.
    while (this.r(this.tgt, RXFLR) > 0) this.rx.push(this.r(this.tgt, DATA) & 0xff);
    if (this.r(this.tgt, RAW) & (1 << 9)) {
      this.r(this.tgt, 0x60);
      if (this.rx.length) this.events.push({ t: this.rig.now(), bytes: this.rx });
      this.rx = [];
    }
  }

  /** Runs one transaction to its end (or `timeoutNs`); returns its result or null. */
  transact(addr, bytes, readLen = 0, timeoutNs = 20e6) {
    this.start(addr, bytes, readLen);
    this.rig.run(this.rig.now() + timeoutNs, () => this.result !== null);
    if (!this.result) {
      // Timed out: reset the block (as the real MB does), no STOP.
      this.ctrl.resetBlock();
      this.setHz(this.hz ?? 100000);
      this.job = null;
      return null;
    }
    return this.result;
  }

  /** Sends a request frame (write only). */
  send(frame) { return this.transact(frame[1], frame, 0); }

  /** Sends a request and reads `readLen` bytes; returns the reply bytes or null. */
  ask(frame, readLen) {
    const r = this.transact(frame[1], frame, readLen);
    return r && r.ok ? r.read : null;
  }
}

/** Request frame bytes: function|operand, DB address, port byte, sequence number, data. */
export function request(op, db, port, seq, data = []) {
  return [op, db, port, seq, ...data];
}

/** Port byte of sensor port n (1-based), pin 'A' or 'B'. */
export const sensor = (n, pin = 'A') => 0x80 | ((n - 1) << 1) | (pin === 'B' ? 1 : 0);
export const actuator = (n, pin = 'A') => ((n - 1) << 1) | (pin === 'B' ? 1 : 0);

/** Parses a reply read: { seq, status, payload } or null when the length byte is wrong. */
export function parseReply(bytes) {
  if (!bytes || bytes.length < 3) return null;
  const [seq, status, n] = bytes;
  if (n > 28 || bytes.length < 3 + n) return null;
  return { seq, status, payload: bytes.slice(3, 3 + n) };
}
