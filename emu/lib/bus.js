// One I2C bus joining the I2C blocks (./i2c.js) of two or more emulated RP2040s.
//
// Byte-level model, timed from the controller's SCL counts (IC_*_SCL_HCNT/LCNT and clk_sys):
// START (tHD;STA = SCL high time), each byte with its ACK bit = 9 SCL periods, a repeated START
// = one period, STOP after a configurable gap (tSU;STO = SCL high time unless `stopGapNs` is
// given), bus free time before the next START = SCL low time. A byte starts only when both
// sides are ready: the target stretches SCL on a read request with an empty TX FIFO (RD_REQ)
// and on a full RX FIFO; the controller holds SCL low when its command FIFO runs empty without
// a STOP. Two controllers that start within the same START window arbitrate on the address
// byte (SDA low wins, so the lower byte); the losers abort with ARB_LOST. A controller whose
// block is reset or disabled mid-transfer disappears without a STOP: a target it had
// addressed stays active until the next START.
//
// Every transfer is recorded in `transfers` (times in ns of the shared clock): the rig's logic
// analyzer.

export class Bus {
  /**
   * @param {{now: () => number, at: (ns: number, fn: () => void) => void}} clock the rig's
   *   shared virtual time
   * @param {{stopGapNs?: number, log?: (s: string) => void}} options
   */
  constructor(clock, options = {}) {
    this.clock = clock;
    this.stopGapNs = options.stopGapNs ?? null;
    this.log = options.log ?? null;
    this.nodes = [];
    this.names = new Map();
    this.state = 'idle'; // idle | start | busy
    this.freeAt = 0;
    this.pending = new Set();
    this.gen = 0;
    this.cur = null;
    this.transfers = [];
  }

  attach(block, name) {
    block.bus = this;
    this.nodes.push(block);
    this.names.set(block, name);
  }

  /** Takes `block` off the bus (its chip was power-cycled). */
  detach(block) {
    this.blockReset(block);
    this.nodes = this.nodes.filter((n) => n !== block);
    block.bus = null;
  }

  now() { return this.clock.now(); }
  at(delayNs, fn) {
    const gen = this.gen;
    this.clock.at(this.now() + Math.max(0, delayNs), () => { if (gen === this.gen) fn(); });
  }
  name(b) { return this.names.get(b) ?? '?'; }

  /** True while `b`, as the controller, has a popped command not yet on the wire. */
  shifting(b) { return !!(this.cur && this.cur.master === b && this.cur.inFlight); }

  // --- calls from the blocks -----------------------------------------------------------
  txWritten(b) {
    if (b.isController) {
      if (!b.enabled || b.txFIFO.empty) return;
      if (this.cur && this.cur.master === b) {
        if (b.stall === 'cmd') { b.stall = null; this.nextCmd(); }
        return;
      }
      if (!b.mstActive) this.requestStart(b);
    } else if (b.stall === 'rd') {
      this.unstall(b);
    }
  }

  unstall(b) {
    const s = b.stall;
    b.stall = null;
    if (!this.cur) return;
    if (s === 'rd') this.readByte();
    else if (s === 'rx') this.writeByte();
    else if (s === 'cmd') this.nextCmd();
  }

  userAbort(b) {
    if (this.cur && this.cur.master === b) this.cur.abort = true;
    else { this.pending.delete(b); b.mstActive = false; }
  }

  /** `b` was reset or disabled: it lets go of the bus at once. */
  blockReset(b) {
    this.pending.delete(b);
    const c = this.cur;
    if (!c) return;
    if (process.env.EMU_DEBUG && (c.master === b || c.target === b)) {
      const core = b.rp2040?.core;
      const hex = (v) => `0x${(v >>> 0).toString(16)}`;
      console.log(`  [debug] ${(this.now() / 1e6).toFixed(3)} ms ${this.name(b)} reset/disabled as ${c.master === b ? 'controller' : 'target'}: pc ${hex(core?.PC)} lr ${hex(core?.registers?.[14])} abrt ${hex(b.abortSource)} raw ${hex(b.intRaw)} tx ${b.txFIFO.itemCount} stall ${b.stall} inFlight ${c.inFlight} part ${c.part?.dir}${c.part?.bytes?.length} abort ${c.abort}`);
    }
    if (c.master === b) {
      // Gone without a STOP: the transfer is abandoned; a START may come at any time.
      this.record('abandoned');
      this.gen++;
      this.cur = null;
      this.state = 'idle';
      this.freeAt = this.now();
      this.kick();
    } else if (c.target === b) {
      c.target = null; // its bytes now read as 0xFF and writes are not acknowledged
      if (b.stall) { b.stall = null; this.at(0, () => this.resume()); }
    }
  }

  // --- START and arbitration ----------------------------------------------------------
  requestStart(b) {
    b.mstActive = true;
    this.pending.add(b);
    this.kick();
  }

  kick() {
    if (this.state !== 'idle' || this.pending.size === 0) return;
    this.state = 'start';
    const first = [...this.pending][0];
    const wait = Math.max(0, this.freeAt - this.now());
    this.at(wait + first.sclHighNs, () => this.resolveStart());
  }

  resolveStart() {
    const contenders = [...this.pending].filter((b) => b.enabled && !b.txFIFO.empty);
    for (const b of this.pending) if (!contenders.includes(b)) b.mstActive = false;
    this.pending.clear();
    if (contenders.length === 0) { this.state = 'idle'; return; }
    const addrByte = (b) => ((b.targetAddress & 0x7f) << 1) | (b.txFIFO.peek() & 0x100 ? 1 : 0);
    contenders.sort((x, y) => addrByte(x) - addrByte(y));
    const [master, ...losers] = contenders;
    for (const l of losers) {
      l.abortTx(1 << 12); // ARB_LOST (on the address byte; equal bytes: approximate, see docs)
      l.mstActive = false;
    }
    this.state = 'busy';
    this.gen++;
    // A START resets every other target's state machine (one left active by an abandoned
    // transfer included).
    for (const n of this.nodes) {
      if (n !== master && n.slvActive) n.slvActive = false;
      if (n.enabled) n.raise(1 << 10); // START_DET
    }
    this.cur = {
      master, target: null, addr: master.targetAddress & 0x7f, read: false, inFlight: false,
      abort: false, addressedOnce: null,
      rec: { t0: this.now(), master: this.name(master), addr: master.targetAddress & 0x7f, parts: [], end: null },
    };
    this.addressPhase();
  }

  /** The address byte of the current segment (after START or RESTART). */
  addressPhase() {
    const c = this.cur;
    const m = c.master;
    c.read = !!(m.txFIFO.peek() & 0x100);
    c.addr = m.targetAddress & 0x7f;
    c.part = { dir: c.read ? 'r' : 'w', addr: c.addr, bytes: [], ack: true, t: this.now() };
    c.rec.parts.push(c.part);
    this.at(9 * m.sclPeriodNs, () => {
      // A write to 0x00 is a general call: every target with IC_ACK_GENERAL_CALL set takes
      // it (the first is `target`, the others `also`); a read from 0x00 is NACKed.
      const general = c.addr === 0 && !c.read;
      const takers = general
        ? this.nodes.filter((n) => n !== m && n.targetEnabled && n.ackGeneralCall)
        : [];
      c.also = takers.slice(1);
      for (const o of c.also) { o.slvActive = true; o.firstByte = true; }
      const t = general
        ? takers[0]
        : this.nodes.find((n) => n !== m && n.targetEnabled && (n.slaveAddress & 0x7f) === c.addr);
      if (!t) {
        c.part.ack = false;
        m.abortTx(1 << 0); // ABRT_7B_ADDR_NOACK
        this.stop();
        return;
      }
      if (c.addressedOnce === t) t.raise(1 << 12); // RESTART_DET
      c.addressedOnce = t;
      c.target = t;
      t.slvActive = true;
      t.firstByte = true;
      if (c.read && !t.txFIFO.empty) t.abortTx(1 << 13); // ABRT_SLVFLUSH_TXFIFO
      this.nextCmd();
    });
  }

  /** Continues after a stall released by a reset target. */
  resume() {
    if (!this.cur) return;
    if (this.cur.inFlight) return;
    this.nextCmd();
  }

  nextCmd() {
    const c = this.cur;
    if (!c) return;
    const m = c.master;
    if (c.abort) { this.stop(); return; }
    if (m.txFIFO.empty) { m.stall = 'cmd'; m.checkInterrupts(); return; }
    const cmd = m.txFIFO.peek();
    const read = !!(cmd & 0x100);
    if (cmd & 0x400 || read !== c.read) {
      // Repeated START (asked for, or the direction changes).
      c.cmdRestart = true;
      this.at(m.sclPeriodNs, () => this.addressPhase());
      // Clear the RESTART bit so the segment's first command is not taken again as a restart.
      m.txFIFO.buffer[m.txFIFO.start] = cmd & ~0x400;
      return;
    }
    if (read) this.readByte(); else this.writeByte();
  }

  writeByte() {
    const c = this.cur;
    const m = c.master;
    if (!c.inFlight) {
      c.cmd = m.txFIFO.pull();
      c.inFlight = true;
      m.checkInterrupts();
      this.at(9 * m.sclPeriodNs, () => this.writeByteEnd());
    } else {
      this.writeByteEnd();
    }
  }

  writeByteEnd() {
    const c = this.cur;
    // The transfer ended (its STOP) while this byte was on its way: nothing left to clock.
    if (!c) return;
    const m = c.master;
    const t = c.target;
    const byte = c.cmd & 0xff;
    if (t && !t.slvDataNackOnly) {
      if (!t.targetReceive(byte)) { t.stall = 'rx'; return; } // SCL held low
      // The other targets of a general call receive the same byte (a full RX FIFO there
      // drops it: not modelled further, each holds 16 bytes and a general call is 5).
      for (const o of c.also ?? []) o.targetReceive(byte);
      c.part.bytes.push(byte);
      c.inFlight = false;
      m.checkInterrupts();
      if (c.cmd & 0x200) this.stop(); else this.nextCmd();
    } else {
      c.part.bytes.push(byte);
      c.part.ack = false;
      c.inFlight = false;
      m.abortTx(1 << 3); // ABRT_TXDATA_NOACK
      this.stop();
    }
  }

  readByte() {
    const c = this.cur;
    const m = c.master;
    const t = c.target;
    if (t && t.txFIFO.empty) {
      t.raise(1 << 5); // RD_REQ: SCL held low until the TX FIFO has a byte
      t.stall = 'rd';
      return;
    }
    c.cmd = m.txFIFO.pull();
    c.inFlight = true;
    m.checkInterrupts();
    const byte = t ? t.txFIFO.pull() : 0xff;
    if (t) t.checkInterrupts();
    this.at(9 * m.sclPeriodNs, () => {
      c.inFlight = false;
      c.part.bytes.push(byte);
      if (m.rxFIFO.full) m.raise(1 << 1); else m.rxFIFO.push(byte);
      m.checkInterrupts();
      const last = !!(c.cmd & 0x200);
      if (last && c.target) c.target.raise(1 << 7); // RX_DONE: the controller NACKed
      if (last) this.stop(); else this.nextCmd();
    });
  }

  // --- STOP ---------------------------------------------------------------------------
  stop() {
    const c = this.cur;
    const m = c.master;
    const gap = this.stopGapNs ?? m.sclHighNs;
    this.at(gap, () => {
      c.rec.end = 'stop';
      c.rec.t1 = this.now();
      this.transfers.push(c.rec);
      if (this.log) this.log(this.describe(c.rec));
      m.mstActive = false;
      m.stall = null;
      m.raise(1 << 9); // STOP_DET
      for (const n of this.nodes) {
        if (n === m || !n.enabled) continue;
        const addressed = n === c.addressedOnce || (c.also ?? []).includes(n);
        if (addressed) n.slvActive = false;
        // Another master's STOP: a target sees it unless STOP_DET_IFADDRESSED; a controller
        // unless STOP_DET_IF_MASTER_ACTIVE (IC_CON bit 10, reset value 0: it does).
        const sees = n.isController ? !(n.control & (1 << 10)) : addressed || !(n.control & (1 << 7));
        if (sees) n.raise(1 << 9);
      }
      this.cur = null;
      // What this transfer still had scheduled (a byte its controller queued after the abort
      // that sent this STOP) is dropped with it, never clocked into the next transfer.
      this.gen++;
      this.state = 'idle';
      this.freeAt = this.now() + (m.sclPeriodNs - m.sclHighNs);
      // A controller with more commands queued starts again.
      for (const n of this.nodes) if (n.isController && n.enabled && !n.txFIFO.empty && !n.txFlushed) this.requestStart(n);
      this.kick();
    });
  }

  record(end) {
    const c = this.cur;
    c.rec.end = end;
    c.rec.t1 = this.now();
    this.transfers.push(c.rec);
    if (this.log) this.log(this.describe(c.rec));
  }

  describe(rec) {
    const hex = (b) => b.toString(16).padStart(2, '0');
    const parts = rec.parts.map((p) => `${p.dir === 'r' ? 'R' : 'W'} ${hex(p.addr)}${p.ack ? '' : ' NACK'}: ${p.bytes.map(hex).join(' ')}`);
    return `${(rec.t0 / 1e6).toFixed(3)} ms ${rec.master} ${parts.join(' | ')} ${rec.end === 'stop' ? 'P' : '(no STOP)'}`;
  }
}
