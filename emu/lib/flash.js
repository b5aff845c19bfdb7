// The flash path of embassy-rp 0.10 on rp2040js 1.4.1 (tests: test/flash.test.js): a NOR flash
// holding the chip's flash array, the SSI (XIP_SSI) in front of it, XIP_CTRL and IO_QSPI as
// registers, and a boot ROM of our own whose flash functions trap to JS. lib/rig.js applies
// `applyFlashModel` to every chip.
//
// What embassy-rp's `Flash` does (flash.rs, rom_data/rp2040.rs of embassy-rp 0.10):
// - erase and write: `in_ram` waits for XIP_CTRL.STREAM_CTR to read 0, then a RAM function calls
//   the boot ROM's connect_internal_flash, flash_exit_xip, flash_range_erase or
//   flash_range_program, flash_flush_cache, and (USE_BOOT2) the image's own boot2, copied to
//   the stack with the ROM's memcpy44, to enter XIP again. Every pointer comes from the ROM's
//   table through rom_table_lookup (its address at 0x18, the table's at 0x14).
// - the unique ID (0x4B) and the JEDEC ID (0x9F): its own RAM code drives the SSI registers
//   (transfer mode 3, EEPROM read: command bytes, then CTRLR1+1 frames), between the ROM's
//   connect/exit calls and boot2.
// - boot2 (W25Q080): reads status register 2 (0x35) through the SSI in transfer mode 0, then
//   sets the SSI up for quad XIP reads.
// The real B1 bootrom is not in the npm package and is not used: the ROM here is a table, a
// lookup routine in Thumb code, and one stub per function (BKPT #n; BX LR) that JS handles.
import { BasePeripheral } from 'rp2040js';

/** Sizes of the NOR flash (Winbond W25Q series, as on the Pico). */
export const PAGE = 256;
export const SECTOR = 4096;

/**
 * Busy times of the W25Q16JV datasheet (typical, §9.6 "AC Electrical Characteristics"): the
 * ROM's flash functions hold the core this long, as the real ROM polls the status register.
 */
export const BUSY_NS = { page: 0.4e6, sector: 45e6, block32: 120e6, block64: 150e6, chip: 5e9, status: 10e6 };

/**
 * The chip's default unique ID: 8 bytes from the chip's name (FNV-1a), so two chips of one rig
 * running the same image differ. A scenario may give its own (`options.uid`).
 */
export function defaultUid(name) {
  const out = [];
  for (const seed of [0x811c9dc5, 0x01000193]) {
    let h = seed;
    for (const c of `x10-emu-uid:${name}`) h = Math.imul(h ^ c.charCodeAt(0), 0x01000193) >>> 0;
    out.push(h >>> 24, (h >>> 16) & 0xff, (h >>> 8) & 0xff, h & 0xff);
  }
  return out;
}

/**
 * A serial NOR flash (W25Q-like) over the chip's flash array: what it answers and does between
 * chip select falling (`select`) and rising (`deselect`), one byte at a time (`exchange`).
 * Commands: 06/04 write enable/disable, 05/35 status 1/2, 01/31 write status, 20/52/D8/C7/60
 * erase 4 KiB/32 KiB/64 KiB/chip, 02 page program (wrapping inside the page, bits only cleared),
 * 03/0B read, 4B unique ID (4 dummy bytes, then the 8 ID bytes), 9F JEDEC ID, AB release from
 * power-down; anything else is ignored. Erase, program and status writes need WEL, run when chip
 * select rises, clear WEL and keep WIP set for their `BUSY_NS` (no command but the status reads
 * is taken meanwhile). The array is the one XIP reads, so a write is seen by the next fetch.
 */
export class NorFlash {
  constructor(data, uid, now = () => 0) {
    this.data = data;
    this.uid = Uint8Array.from(uid);
    if (this.uid.length !== 8) throw new Error('the unique ID is 8 bytes');
    this.now = now;
    this.sr1 = 0;
    this.sr2 = 0x02; // QE set, as the Pico's flash leaves the factory (boot2 skips its write)
    this.wel = false;
    this.busyUntil = 0;
    this.selected = false;
    this.bytes = [];
    /** Every erase, program and status write run (`{ cmd, addr, t }`, `t` in ns), in order. */
    this.ops = [];
    /** The first byte of every command the flash was selected for, in order (reads included). */
    this.commands = [];
    // JEDEC: Winbond, W25Q..JV IQ, capacity code log2(size) (2 MiB: 0x15; rp2040js maps 16 MiB: 0x18).
    this.jedec = [0xef, 0x40, Math.log2(data.length)];
  }

  get busy() { return this.now() < this.busyUntil; }

  /**
   * Power lost and back: not busy, write enable off, deselected. An erase or program that was
   * still busy stays done (the model applies them at once): a cut in the middle of one is not
   * modelled.
   */
  powerUp() {
    this.busyUntil = 0;
    this.wel = false;
    this.selected = false;
    this.bytes = [];
  }

  select() {
    this.selected = true;
    this.bytes = [];
  }

  /** Shifts `b` in and the flash's byte out (0xff while the flash does not drive the line). */
  exchange(b) {
    if (!this.selected) return 0xff;
    const rx = this.bytes;
    rx.push(b & 0xff);
    const i = rx.length - 1;
    const addr = () => ((rx[1] << 16) | (rx[2] << 8) | rx[3]) & (this.data.length - 1);
    switch (rx[0]) {
      case 0x05: return i >= 1 ? this.sr1 | (this.wel ? 2 : 0) | (this.busy ? 1 : 0) : 0xff;
      case 0x35: return i >= 1 ? this.sr2 : 0xff;
      case 0x03: return !this.busy && i >= 4 ? this.data[(addr() + i - 4) & (this.data.length - 1)] : 0xff;
      case 0x0b: return !this.busy && i >= 5 ? this.data[(addr() + i - 5) & (this.data.length - 1)] : 0xff;
      case 0x4b: return !this.busy && i >= 5 ? this.uid[(i - 5) % 8] : 0xff;
      case 0x9f: return !this.busy && i >= 1 ? this.jedec[(i - 1) % 3] : 0xff;
      case 0xab: return !this.busy && i >= 4 ? this.jedec[2] - 1 : 0xff;
    }
    return 0xff;
  }

  deselect() {
    if (!this.selected) return;
    this.selected = false;
    const rx = this.bytes;
    this.bytes = [];
    if (!rx.length) return;
    this.commands.push(rx[0]);
    if (this.busy) return;
    const cmd = rx[0];
    const addr = rx.length >= 4 ? ((rx[1] << 16) | (rx[2] << 8) | rx[3]) & (this.data.length - 1) : 0;
    const done = (ns) => {
      this.wel = false;
      this.busyUntil = this.now() + ns;
      this.ops.push({ cmd, addr, t: this.now() });
    };
    switch (cmd) {
      case 0x06: this.wel = true; return;
      case 0x04: this.wel = false; return;
      case 0x01:
        if (!this.wel || rx.length < 2) return;
        this.sr1 = rx[1] & 0xfc;
        if (rx.length >= 3) this.sr2 = rx[2];
        return done(BUSY_NS.status);
      case 0x31:
        if (!this.wel || rx.length < 2) return;
        this.sr2 = rx[1];
        return done(BUSY_NS.status);
      case 0x20: case 0x52: case 0xd8: {
        if (!this.wel || rx.length < 4) return;
        const size = cmd === 0x20 ? SECTOR : cmd === 0x52 ? 8 * SECTOR : 16 * SECTOR;
        const start = addr - (addr % size);
        this.data.fill(0xff, start, start + size);
        return done(cmd === 0x20 ? BUSY_NS.sector : cmd === 0x52 ? BUSY_NS.block32 : BUSY_NS.block64);
      }
      case 0xc7: case 0x60:
        if (!this.wel) return;
        this.data.fill(0xff);
        return done(BUSY_NS.chip);
      case 0x02: {
        if (!this.wel || rx.length < 5) return;
        const page = addr - (addr % PAGE);
        // More than a page: only the last 256 bytes are kept (W25Q: "the last 256 data bytes").
        const bytes = rx.slice(4).slice(-PAGE);
        const first = rx.length - 4 > PAGE ? addr + (rx.length - 4 - PAGE) : addr;
        bytes.forEach((b, k) => {
          const a = page + ((first - page + k) % PAGE);
          this.data[a] &= b;
        });
        return done(BUSY_NS.page);
      }
    }
  }

  /** One whole command: select, every byte, deselect; the bytes shifted out. */
  command(bytes) {
    this.select();
    const out = bytes.map((b) => this.exchange(b));
    this.deselect();
    return out;
  }
}

/** IO_QSPI's GPIO_QSPI_SS_CTRL.OUTOVER values (datasheet §2.19.6.2). */
const OUTOVER_NORMAL = 0, OUTOVER_INVERT = 1, OUTOVER_LOW = 2, OUTOVER_HIGH = 3;

/**
 * IO_QSPI as registers: the six pins' STATUS (reads 0) and CTRL, the interrupt registers read 0.
 * The one that acts: GPIO_QSPI_SS_CTRL (0x0c) OUTOVER, the flash's chip select forced low or
 * high (the boot ROM holds it over a command this way), or left to the SSI.
 */
class IoQspi extends BasePeripheral {
  constructor(rp2040, onSs) {
    super(rp2040, 'IO_QSPI');
    this.ctrl = new Array(6).fill(0x1f);
    this.onSs = onSs;
  }

  get ssOutover() { return (this.ctrl[1] >> 8) & 3; }

  readUint32(offset) {
    if (offset < 0x30 && offset % 8 === 4) return this.ctrl[offset >> 3];
    if (offset < 0x30) return 0;
    return 0;
  }

  writeUint32(offset, value) {
    if (offset < 0x30 && offset % 8 === 4) {
      this.ctrl[offset >> 3] = value >>> 0;
      if (offset === 0x0c) this.onSs();
    }
  }
}

/**
 * XIP_CTRL as plain registers (datasheet §2.6.3.1): CTRL, FLUSH (write: nothing to flush here,
 * there is no cache), STAT (FLUSH_READY and FIFO_EMPTY), the counters (0), STREAM_ADDR and
 * STREAM_CTR (streaming reads are not modelled: the counter reads 0, a stream done at once).
 */
class XipCtrl extends BasePeripheral {
  constructor(rp2040) {
    super(rp2040, 'XIP_CTRL');
    this.ctrl = 3;
    this.streamAddr = 0;
  }

  readUint32(offset) {
    switch (offset) {
      case 0x00: return this.ctrl;
      case 0x08: return 0b011;
      case 0x14: return this.streamAddr;
    }
    return 0;
  }

  writeUint32(offset, value) {
    if (offset === 0x00) this.ctrl = value & 0xf;
    else if (offset === 0x14) this.streamAddr = value & ~3;
  }
}

/** SSI register offsets (datasheet §4.10.13). */
const S = {
  CTRLR0: 0x00, CTRLR1: 0x04, SSIENR: 0x08, SER: 0x10, BAUDR: 0x14, TXFTLR: 0x18, RXFTLR: 0x1c,
  TXFLR: 0x20, RXFLR: 0x24, SR: 0x28, IMR: 0x2c, ISR: 0x30, RISR: 0x34, DMACR: 0x4c, IDR: 0x58,
  VERSION: 0x5c, DR0: 0x60, RX_SAMPLE_DLY: 0xf0, SPI_CTRLR0: 0xf4, TXD_DRIVE_EDGE: 0xf8,
};
const FIFO = 16;

/**
 * The SSI (DW_apb_ssi as XIP_SSI) in front of the NOR flash, in its serial modes: transfer mode
 * 0 (transmit and receive: a frame in for every frame out), 1 (transmit only), 3 (EEPROM read:
 * the frames written, then CTRLR1.NDF+1 frames in); standard SPI frames of DFS_32+1 bits
 * (8 to 32), most significant byte first. Quad and dual frames (boot2 setting up XIP reads) go
 * through the FIFOs but not to the flash: XIP reads come from the array, so the flash's
 * continuous-read state is not modelled.
 *
 * Timing is lazy, not per bit: the frames written wait in the TX FIFO until the core looks
 * (SR, TXFLR, RXFLR or DR read, SSIENR written), and then all go out in one chip-select
 * period, as they would on the chip when the core writes them faster than the SSI shifts (the
 * FIFO never runs dry in the middle). The SSI's own chip select falls when its frames start
 * (SER bit 0) and rises when the TX FIFO is empty and the receive count is done; IO_QSPI's
 * SS_CTRL.OUTOVER overrides it. The RX FIFO holds 16 frames: an EEPROM read of more waits for
 * the core to take some (the SSI stops its clock), as the real one does.
 */
export class Ssi extends BasePeripheral {
  constructor(rp2040, nor) {
    super(rp2040, 'SSI');
    this.nor = nor;
    this.ioQspi = null;
    this.ctrlr0 = 0x07 << 16; // DFS_32 reset value 0 is not a frame; 8 bits as the ROM sets it
    this.ctrlr1 = 0;
    this.ssienr = 0;
    this.ser = 0;
    this.baudr = 0;
    this.txftlr = 0;
    this.rxftlr = 0;
    this.imr = 0x3f;
    this.dmacr = 0;
    this.rxSampleDly = 0;
    this.spiCtrlr0 = 0x03000218;
    this.txdDriveEdge = 0;
    this.tx = [];
    this.rx = [];
    this.pending = 0; // frames still to receive (EEPROM read)
    this.active = false; // the SSI's own chip select asserted
  }

  get tmod() { return (this.ctrlr0 >> 8) & 3; }
  get frf() { return (this.ctrlr0 >> 21) & 3; }
  get frameBytes() { return Math.max(1, Math.floor((((this.ctrlr0 >> 16) & 0x1f) + 1) / 8)); }

  /** The flash's chip select, low (true) or high, from the SSI and IO_QSPI's override. */
  updateCs() {
    const own = this.active && (this.ser & 1) === 1;
    const over = this.ioQspi ? this.ioQspi.ssOutover : OUTOVER_NORMAL;
    const low = over === OUTOVER_LOW ? true : over === OUTOVER_HIGH ? false : over === OUTOVER_INVERT ? !own : own;
    if (low && !this.nor.selected) this.nor.select();
    else if (!low && this.nor.selected) this.nor.deselect();
  }

  frame(value) {
    if (this.frf !== 0) return 0;
    let v = 0;
    for (let k = this.frameBytes - 1; k >= 0; k--) v = (v << 8) | this.nor.exchange((value >>> (8 * k)) & 0xff);
    return v >>> 0;
  }

  /** Runs what the SSI has to do now (see the class comment). */
  settle() {
    if (!this.ssienr) return;
    if (this.tx.length) {
      if (this.frf === 0 && !this.active) {
        this.active = true;
        this.updateCs();
      }
      for (const v of this.tx) {
        const got = this.frame(v);
        if (this.tmod === 0 && this.rx.length < FIFO) this.rx.push(got);
      }
      this.tx = [];
      if (this.tmod === 3 || this.tmod === 2) this.pending = (this.ctrlr1 & 0xffff) + 1;
    }
    while (this.pending > 0 && this.rx.length < FIFO) {
      this.rx.push(this.frame(0));
      this.pending--;
    }
    if (this.active && this.pending === 0) {
      this.active = false;
      this.updateCs();
    }
  }

  clear() {
    this.tx = [];
    this.rx = [];
    this.pending = 0;
    this.active = false;
    this.updateCs();
  }

  readUint32(offset) {
    if (offset >= S.DR0 && offset < S.RX_SAMPLE_DLY) {
      this.settle();
      const v = this.rx.length ? this.rx.shift() : 0;
      this.settle();
      return v;
    }
    switch (offset) {
      case S.CTRLR0: return this.ctrlr0;
      case S.CTRLR1: return this.ctrlr1;
      case S.SSIENR: return this.ssienr;
      case S.SER: return this.ser;
      case S.BAUDR: return this.baudr;
      case S.TXFTLR: return this.txftlr;
      case S.RXFTLR: return this.rxftlr;
      case S.TXFLR: this.settle(); return this.tx.length;
      case S.RXFLR: this.settle(); return this.rx.length;
      case S.SR:
        this.settle();
        // TFNF, TFE (the FIFO has gone out), RFNE, RFF; never BUSY once settled.
        return (1 << 1) | (1 << 2) | (this.rx.length ? 1 << 3 : 0) | (this.rx.length === FIFO ? 1 << 4 : 0);
      case S.IMR: return this.imr;
      case S.DMACR: return this.dmacr;
      case S.IDR: return 0x51535049;
      case S.VERSION: return 0x3430312a;
      case S.RX_SAMPLE_DLY: return this.rxSampleDly;
      case S.SPI_CTRLR0: return this.spiCtrlr0;
      case S.TXD_DRIVE_EDGE: return this.txdDriveEdge;
    }
    return 0; // ISR, RISR and the interrupt-clear registers: no interrupt is raised
  }

  writeUint32(offset, value) {
    value >>>= 0;
    if (offset >= S.DR0 && offset < S.RX_SAMPLE_DLY) {
      if (!this.ssienr || this.tx.length >= FIFO) return;
      const bits = ((this.ctrlr0 >> 16) & 0x1f) + 1;
      this.tx.push(bits >= 32 ? value : value & ((1 << bits) - 1));
      return;
    }
    switch (offset) {
      case S.CTRLR0: this.ctrlr0 = value; return;
      case S.CTRLR1: this.ctrlr1 = value & 0xffff; return;
      case S.SSIENR:
        this.settle();
        this.ssienr = value & 1;
        if (!this.ssienr) this.clear();
        return;
      case S.SER: this.ser = value & 1; this.updateCs(); return;
      case S.BAUDR: this.baudr = value & 0xffff; return;
      case S.TXFTLR: this.txftlr = value & 0xff; return;
      case S.RXFTLR: this.rxftlr = value & 0xff; return;
      case S.IMR: this.imr = value & 0x3f; return;
      case S.DMACR: this.dmacr = value & 3; return;
      case S.RX_SAMPLE_DLY: this.rxSampleDly = value & 0xff; return;
      case S.SPI_CTRLR0: this.spiCtrlr0 = value; return;
      case S.TXD_DRIVE_EDGE: this.txdDriveEdge = value & 0xff; return;
    }
  }
}

/** ROM layout: header, lookup routine, tables, stubs (datasheet §2.8.2 for the header). */
const ROM_LOOKUP = 0x20;
const ROM_LOOP = 0x40;
const ROM_FUNC_TABLE = 0x100;
const ROM_DATA_TABLE = 0x180;
const ROM_STUBS = 0x200;

/** Thumb encodings used by the ROM (ARMv6-M ARM §A6.7). */
export const T = {
  ldrh: (rt, rn, off) => 0x8800 | ((off >> 1) << 6) | (rn << 3) | rt,
  cmpReg: (rn, rm) => 0x4280 | (rm << 3) | rn,
  cmpImm: (rn, imm) => 0x2800 | (rn << 8) | imm,
  addsImm: (rdn, imm) => 0x3000 | (rdn << 8) | imm,
  movsImm: (rd, imm) => 0x2000 | (rd << 8) | imm,
  /** B<cond> from the halfword at `at` to `to` (both ROM offsets). */
  bcond: (cond, at, to) => 0xd000 | (cond << 8) | (((to - at - 4) >> 1) & 0xff),
  b: (at, to) => 0xe000 | (((to - at - 4) >> 1) & 0x7ff),
  bxLr: 0x4770,
  bkpt: (n) => 0xbe00 | n,
};
const EQ = 0;

/**
 * rom_table_lookup(table: *const u16, code: u32) -> ptr: walks the table's (code, pointer)
 * halfword pairs until the code or the terminating 0, as the real ROM's does.
 */
function lookupRoutine() {
  const at = (i) => ROM_LOOKUP + 2 * i;
  return [
    /* 0 loop:  */ T.ldrh(2, 0, 0),
    /* 1 */ T.cmpReg(2, 1),
    /* 2 */ T.bcond(EQ, at(2), at(7)),
    /* 3 */ T.cmpImm(2, 0),
    /* 4 */ T.bcond(EQ, at(4), at(9)),
    /* 5 */ T.addsImm(0, 4),
    /* 6 */ T.b(at(6), at(0)),
    /* 7 found: */ T.ldrh(0, 0, 2),
    /* 8 */ T.bxLr,
    /* 9 none: */ T.movsImm(0, 0),
    /* 10 */ T.bxLr,
  ];
}

const code = (s) => s.charCodeAt(0) | (s.charCodeAt(1) << 8);

/**
 * The ROM image (16 KiB, as words) with one stub for each function of `codes` (two-letter
 * table codes, stub n is `BKPT #n; BX LR`) in the function table; returns the image and a map
 * from each stub's ROM address to its code.
 */
export function buildRom(codes) {
  const bytes = new Uint8Array(16 * 1024);
  const v = new DataView(bytes.buffer);
  const h = (off, x) => v.setUint16(off, x, true);
  v.setUint32(0x00, 0x20042000, true); // initial SP: the top of SRAM
  v.setUint32(0x04, ROM_LOOP | 1, true); // reset: a loop (the rig starts at the image's vector table)
  v.setUint32(0x08, ROM_LOOP | 1, true);
  v.setUint32(0x0c, ROM_LOOP | 1, true);
  bytes.set([0x4d, 0x75, 0x01, 0x02], 0x10); // 'M', 'u', 1, version 2 (B1)
  h(0x14, ROM_FUNC_TABLE);
  h(0x16, ROM_DATA_TABLE);
  h(0x18, ROM_LOOKUP | 1);
  lookupRoutine().forEach((x, i) => h(ROM_LOOKUP + 2 * i, x));
  h(ROM_LOOP, T.b(ROM_LOOP, ROM_LOOP));
  const stubs = new Map();
  codes.forEach((c, i) => {
    const at = ROM_STUBS + 4 * i;
    h(at, T.bkpt(i));
    h(at + 2, T.bxLr);
    h(ROM_FUNC_TABLE + 4 * i, code(c));
    h(ROM_FUNC_TABLE + 4 * i + 2, at | 1);
    stubs.set(at, c);
  });
  h(ROM_FUNC_TABLE + 4 * codes.length, 0);
  h(ROM_DATA_TABLE, 0); // no public data
  return { words: new Uint32Array(bytes.buffer), stubs };
}

/** Every model of this file on `rp`, over `nor` (which holds the flash array the chip reads). */
export function applyFlashModel(rp, nor) {
  const core = rp.core;
  // The chip's flash is the NOR's array (kept across the rig's resets).
  rp.flash = nor.data;
  rp.flash16 = new Uint16Array(nor.data.buffer);
  rp.flashView = new DataView(nor.data.buffer);
  nor.now = () => rp.clock.nanos;
  const ssi = new Ssi(rp, nor);
  const io = new IoQspi(rp, () => ssi.updateCs());
  ssi.ioQspi = io;
  rp.peripherals[0x18000] = ssi;
  rp.peripherals[0x40018] = io;
  rp.peripherals[0x14000] = new XipCtrl(rp);
  rp.flashModel = { nor, ssi, io };

  const reg = (n) => core.registers[n] >>> 0;
  const ssiInit = () => {
    // flash_init_spi of the ROM: standard SPI, 8-bit frames, transmit and receive, slave 0.
    ssi.writeUint32(S.SSIENR, 0);
    ssi.baudr = 6;
    ssi.ctrlr0 = (7 << 16) | (0 << 8);
    ssi.ser = 1;
    ssi.writeUint32(S.SSIENR, 1);
  };
  const ss = (over) => io.writeUint32(0x0c, (io.ctrl[1] & ~0x300) | (over << 8));
  /**
   * Runs `commands` (byte arrays) as the ROM does, each after the flash is ready again (it polls
   * status register 1), on a clock of its own that starts now; the core is then held until the
   * last is done (`rp.flashHeldUntil`).
   */
  const sequence = (commands) => {
    let t = Math.max(rp.clock.nanos, nor.busyUntil);
    nor.now = () => t;
    for (const c of commands) {
      nor.command(c);
      t = Math.max(t, nor.busyUntil);
    }
    nor.now = () => rp.clock.nanos;
    rp.flashHeldUntil = t;
  };
  const addr24 = (a) => [(a >> 16) & 0xff, (a >> 8) & 0xff, a & 0xff];
  const fns = {
    IF: () => { // connect_internal_flash: the QSPI pins to the XIP function, chip select to the SSI
      for (let i = 0; i < 6; i++) io.ctrl[i] = 0;
      ssi.updateCs();
    },
    EX: () => { // flash_exit_xip: the SSI to serial mode, the flash out of continuous reads (FF FF)
      ssiInit();
      ss(OUTOVER_NORMAL);
      sequence([[0xff, 0xff]]);
    },
    RE: () => { // flash_range_erase(addr, count, block_size, block_cmd): 4 KiB sectors, or blocks
      const addr = reg(0), count = reg(1), blockSize = reg(2), blockCmd = reg(3) & 0xff;
      const commands = [];
      for (let a = addr - (addr % SECTOR); a < addr + count;) {
        const block = blockSize >= SECTOR && blockSize <= 0x10000 && a % blockSize === 0 && a + blockSize <= addr + count;
        commands.push([0x06], [block ? blockCmd : 0x20, ...addr24(a)]);
        a += block ? blockSize : SECTOR;
      }
      sequence(commands);
    },
    RP: () => { // flash_range_program(addr, data, count): page by page
      const addr = reg(0), data = reg(1), count = reg(2);
      const commands = [];
      for (let k = 0; k < count;) {
        const a = addr + k;
        const n = Math.min(count - k, PAGE - (a % PAGE));
        const bytes = [];
        for (let j = 0; j < n; j++) bytes.push(rp.readUint8(data + k + j));
        commands.push([0x06], [0x02, ...addr24(a), ...bytes]);
        k += n;
      }
      sequence(commands);
    },
    FC: () => { ss(OUTOVER_NORMAL); }, // flash_flush_cache: no cache here; chip select back to the SSI
    CX: () => { // flash_enter_cmd_xip: serial 03 reads through the SSI (XIP reads come from the array)
      ssi.writeUint32(S.SSIENR, 0);
      ssi.ctrlr0 = (31 << 16) | (3 << 8);
      ssi.spiCtrlr0 = (0x03 << 24) | (2 << 8) | (6 << 2);
      ssi.writeUint32(S.SSIENR, 1);
    },
    C4: () => { // memcpy44(dest, src, n): words
      const d = reg(0), s = reg(1), n = reg(2);
      for (let i = 0; i < n; i += 4) rp.writeUint32(d + i, rp.readUint32(s + i));
    },
    MC: () => { // memcpy(dest, src, n)
      const d = reg(0), s = reg(1), n = reg(2);
      for (let i = 0; i < n; i++) rp.writeUint8(d + i, rp.readUint8(s + i));
    },
    MS: () => { // memset(ptr, c, n)
      const d = reg(0), c = reg(1) & 0xff, n = reg(2);
      for (let i = 0; i < n; i++) rp.writeUint8(d + i, c);
    },
    S4: () => { // memset4(ptr, c, n): words
      const d = reg(0), c = (reg(1) & 0xff) * 0x01010101, n = reg(2);
      for (let i = 0; i < n; i += 4) rp.writeUint32(d + i, c >>> 0);
    },
  };
  const { words, stubs } = buildRom(Object.keys(fns));
  rp.bootrom.set(words);
  rp.romCalls = [];
  const onBreak = rp.onBreak;
  rp.onBreak = (imm) => {
    const name = stubs.get((core.PC - 2) >>> 0);
    if (name === undefined) return onBreak(imm);
    rp.romCalls.push(name);
    fns[name]();
  };
  // A flash operation holds the core until the flash is done (the ROM polls its status).
  const execute = core.executeInstruction.bind(core);
  core.executeInstruction = () => {
    const until = rp.flashHeldUntil ?? 0;
    if (until > rp.clock.nanos) return Math.min(125, Math.ceil((until - rp.clock.nanos) / 8));
    return execute();
  };
}
