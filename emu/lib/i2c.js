// The RP2040 I2C block (Synopsys DW_apb_i2c) as the X10 images use it, on a shared bus model
// (./bus.js): controller and target (slave) mode.
//
// rp2040js 1.4.1's RPI2C is a controller only, driven by callbacks, and drops IC_INTR_MASK
// writes. This subclass keeps its register storage (SCL counts, thresholds, TAR, SAR, CON) and
// replaces what the X10 images need, each point written from the RP2040 datasheet §4.3:
// * IC_INTR_MASK writes reach the model; the IRQ line is (IC_RAW_INTR_STAT & IC_INTR_MASK) != 0,
//   with TX_EMPTY and RX_FULL as levels (TX_EMPTY_CTRL honoured);
// * target mode: address match against IC_SAR (when IC_CON.IC_SLAVE_DISABLE is 0 and the block
//   is enabled), SLV_ACTIVITY, RD_REQ, RX_DONE, RESTART_DET, STOP_DET (IC_CON.STOP_DET_IFADDRESSED),
//   START_DET; IC_DATA_CMD writes in target mode fill the TX FIFO; FIRST_DATA_BYTE is bit 11;
//   clock stretching on RD_REQ with an empty TX FIFO and on a full RX FIFO
//   (RX_FIFO_FULL_HLD_CTRL); on a read request with bytes left in the TX FIFO the FIFO is flushed
//   with TX_ABRT (ABRT_SLVFLUSH_TXFIFO, TX_FLUSH_CNT) and stays flushed until TX_ABRT is
//   cleared; IC_CLR_RESTART_DET, IC_ACK_GENERAL_CALL, IC_SLV_DATA_NACK_ONLY;
// * IC_SDA_HOLD: stored (reset value 1, writes taken only while the block is disabled), not
//   timed (the bus is modelled per byte);
// * the controller runs its TX FIFO commands on the bus (START/RESTART, address, data, STOP
//   bit), stalls with SCL low when its FIFO runs empty without a STOP, aborts with the DW abort
//   sources (7-bit address NACK, data NACK, arbitration lost, user abort);
// * resetBlock(): what RESETS does to the block (./patches.js).
import { RPI2C } from 'rp2040js';
import { FIFO } from 'rp2040js';

// Registers.
const IC_CON = 0x00, IC_TAR = 0x04, IC_SAR = 0x08, IC_DATA_CMD = 0x10;
const IC_INTR_STAT = 0x2c, IC_INTR_MASK = 0x30, IC_RAW_INTR_STAT = 0x34;
const IC_RX_TL = 0x38, IC_TX_TL = 0x3c, IC_CLR_INTR = 0x40, IC_CLR_RX_UNDER = 0x44;
const IC_CLR_RX_OVER = 0x48, IC_CLR_TX_OVER = 0x4c, IC_CLR_RD_REQ = 0x50, IC_CLR_TX_ABRT = 0x54;
const IC_CLR_RX_DONE = 0x58, IC_CLR_ACTIVITY = 0x5c, IC_CLR_STOP_DET = 0x60, IC_CLR_START_DET = 0x64;
const IC_CLR_GEN_CALL = 0x68, IC_ENABLE = 0x6c, IC_STATUS = 0x70, IC_TXFLR = 0x74, IC_RXFLR = 0x78;
const IC_SDA_HOLD = 0x7c, IC_TX_ABRT_SOURCE = 0x80, IC_SLV_DATA_NACK_ONLY = 0x84, IC_ACK_GENERAL_CALL = 0x98;
const IC_ENABLE_STATUS = 0x9c, IC_CLR_RESTART_DET = 0xa8;

// IC_CON bits.
const MASTER_MODE = 1 << 0, SLAVE_DISABLE = 1 << 6, STOP_DET_IFADDRESSED = 1 << 7;
const TX_EMPTY_CTRL = 1 << 8, RX_FIFO_FULL_HLD_CTRL = 1 << 9;
// IC_DATA_CMD bits.
const CMD_READ = 1 << 8, CMD_STOP = 1 << 9, CMD_RESTART = 1 << 10;
export const FIRST_DATA_BYTE = 1 << 11;
// Interrupt bits.
export const INTR = {
  RX_UNDER: 1 << 0, RX_OVER: 1 << 1, RX_FULL: 1 << 2, TX_OVER: 1 << 3, TX_EMPTY: 1 << 4,
  RD_REQ: 1 << 5, TX_ABRT: 1 << 6, RX_DONE: 1 << 7, ACTIVITY: 1 << 8, STOP_DET: 1 << 9,
  START_DET: 1 << 10, GEN_CALL: 1 << 11, RESTART_DET: 1 << 12,
};
const LEVELS = INTR.TX_EMPTY | INTR.RX_FULL;
// IC_STATUS bits.
export const STATUS = { ACTIVITY: 1, TFNF: 2, TFE: 4, RFNE: 8, RFF: 16, MST_ACTIVITY: 32, SLV_ACTIVITY: 64 };
// IC_TX_ABRT_SOURCE bits.
export const ABRT = {
  ADDR7_NOACK: 1 << 0, TXDATA_NOACK: 1 << 3, GCALL_NOACK: 1 << 4, ARB_LOST: 1 << 12,
  SLVFLUSH_TXFIFO: 1 << 13, USER_ABRT: 1 << 16,
};
const FLUSH_CNT_SHIFT = 23;

export class I2CBlock extends RPI2C {
  constructor(rp2040, name, irq) {
    super(rp2040, name, irq);
    /** The bus this block's pins are on (set by Bus.attach). */
    this.bus = null;
    this.resetState();
  }

  /** Power-on values of everything this model adds or replaces. */
  resetState() {
    this.control = SLAVE_DISABLE | (1 << 5) | (2 << 1) | MASTER_MODE;
    this.slaveAddress = 0x55;
    this.targetAddress = 0x55;
    this.rxThreshold = 0;
    this.txThreshold = 0;
    this.enable = 0;
    this.intRaw = 0;
    this.intEnable = 0x8ff; // IC_INTR_MASK's reset value
    this.abortSource = 0;
    this.rxFIFO = new FIFO(16);
    this.txFIFO = new FIFO(16);
    this.ackGeneralCall = 1;
    this.slvDataNackOnly = 0;
    this.sdaHold = 1;
    /** True while TX_ABRT holds the TX FIFO flushed (target and controller). */
    this.txFlushed = false;
    /** Controller: in a transfer (from START to STOP) or waiting for the bus. */
    this.mstActive = false;
    /** Target: addressed in the current transfer (from address match to STOP). */
    this.slvActive = false;
    /** Target: the next received byte is the first after the address. */
    this.firstByte = false;
    /** The bus is waiting on this block: 'rd' (TX data for a read), 'rx' (RX FIFO space), 'cmd'. */
    this.stall = null;
  }

  /** RESETS: the block goes back to its reset state; its transfer ends without a STOP. */
  resetBlock() {
    if (this.bus) this.bus.blockReset(this);
    this.resetState();
    this.checkInterrupts();
  }

  get enabled() { return !!(this.enable & 1); }
  get isController() { return !!(this.control & MASTER_MODE); }
  get targetEnabled() { return this.enabled && !(this.control & SLAVE_DISABLE); }

  /** SCL period of this block as a controller, in ns (clk_sys from the chip). */
  get sclPeriodNs() {
    const std = ((this.control >> 1) & 3) === 1;
    const h = std ? this.ssClockHighPeriod : this.fsClockHighPeriod;
    const l = std ? this.ssClockLowPeriod : this.fsClockLowPeriod;
    return ((h + l) * 1e9) / this.rp2040.clkSys;
  }
  get sclHighNs() {
    const std = ((this.control >> 1) & 3) === 1;
    return ((std ? this.ssClockHighPeriod : this.fsClockHighPeriod) * 1e9) / this.rp2040.clkSys;
  }

  /** Raw interrupt status, with the level-triggered bits computed. */
  get rawIntr() {
    let raw = this.intRaw & ~LEVELS;
    if (this.rxFIFO.itemCount > this.rxThreshold) raw |= INTR.RX_FULL;
    const txLow = this.txFIFO.itemCount <= this.txThreshold;
    // TX_EMPTY_CTRL: also wait until the last command popped has left the shift register.
    const shifting = this.control & TX_EMPTY_CTRL && this.bus && this.bus.shifting(this);
    if (this.enabled && txLow && !shifting) raw |= INTR.TX_EMPTY;
    return raw;
  }
  get intStatus() { return this.rawIntr & this.intEnable; }

  checkInterrupts() { this.rp2040.setInterrupt(this.irq, !!this.intStatus); }
  raise(mask) { this.intRaw |= mask; this.checkInterrupts(); }
  clear(mask) {
    const was = this.intRaw & mask;
    this.intRaw &= ~mask;
    if (mask & INTR.TX_ABRT && was & INTR.TX_ABRT) {
      this.abortSource = 0;
      this.txFlushed = false;
    }
    this.checkInterrupts();
    return was ? 1 : 0;
  }

  /** Flushes the TX FIFO with TX_ABRT and the abort source `reason`. */
  abortTx(reason) {
    this.abortSource = reason | (this.txFIFO.itemCount << FLUSH_CNT_SHIFT);
    this.txFIFO.reset();
    this.txFlushed = true;
    this.raise(INTR.TX_ABRT);
  }

  // --- target side, called by the bus -------------------------------------------------
  /** Pushes a received byte; false when the RX FIFO is full (stretch, or RX_OVER). */
  targetReceive(byte) {
    if (this.rxFIFO.full) {
      if (this.control & RX_FIFO_FULL_HLD_CTRL) return false;
      this.raise(INTR.RX_OVER);
      return true;
    }
    this.rxFIFO.push(byte | (this.firstByte ? FIRST_DATA_BYTE : 0));
    this.firstByte = false;
    this.checkInterrupts();
    return true;
  }

  // --- registers ------------------------------------------------------------------------
  readUint32(offset) {
    switch (offset) {
      case IC_CON: return this.control;
      case IC_TAR: return this.targetAddress;
      case IC_SAR: return this.slaveAddress;
      case IC_DATA_CMD: {
        if (this.rxFIFO.empty) {
          this.raise(INTR.RX_UNDER);
          return 0;
        }
        const v = this.rxFIFO.pull();
        this.checkInterrupts();
        if (this.stall === 'rx' && this.bus) this.bus.unstall(this);
        return v;
      }
      case IC_INTR_STAT: return this.intStatus;
      case IC_INTR_MASK: return this.intEnable;
      case IC_RAW_INTR_STAT: return this.rawIntr;
      case IC_RX_TL: return this.rxThreshold;
      case IC_TX_TL: return this.txThreshold;
      case IC_CLR_INTR:
        return this.clear(INTR.RX_UNDER | INTR.RX_OVER | INTR.TX_OVER | INTR.RD_REQ | INTR.TX_ABRT |
          INTR.RX_DONE | INTR.ACTIVITY | INTR.STOP_DET | INTR.START_DET | INTR.GEN_CALL | INTR.RESTART_DET);
      case IC_CLR_RX_UNDER: return this.clear(INTR.RX_UNDER);
      case IC_CLR_RX_OVER: return this.clear(INTR.RX_OVER);
      case IC_CLR_TX_OVER: return this.clear(INTR.TX_OVER);
      case IC_CLR_RD_REQ: return this.clear(INTR.RD_REQ);
      case IC_CLR_TX_ABRT: return this.clear(INTR.TX_ABRT);
      case IC_CLR_RX_DONE: return this.clear(INTR.RX_DONE);
      case IC_CLR_ACTIVITY: return this.clear(INTR.ACTIVITY);
      case IC_CLR_STOP_DET: return this.clear(INTR.STOP_DET);
      case IC_CLR_START_DET: return this.clear(INTR.START_DET);
      case IC_CLR_GEN_CALL: return this.clear(INTR.GEN_CALL);
      case IC_CLR_RESTART_DET: return this.clear(INTR.RESTART_DET);
      case IC_ENABLE: return this.enable;
      case IC_STATUS:
        return (this.mstActive ? STATUS.MST_ACTIVITY : 0) |
          (this.slvActive ? STATUS.SLV_ACTIVITY : 0) |
          (this.mstActive || this.slvActive ? STATUS.ACTIVITY : 0) |
          (this.rxFIFO.full ? STATUS.RFF : 0) | (!this.rxFIFO.empty ? STATUS.RFNE : 0) |
          (this.txFIFO.empty ? STATUS.TFE : 0) | (!this.txFIFO.full ? STATUS.TFNF : 0);
      case IC_TXFLR: return this.txFIFO.itemCount;
      case IC_RXFLR: return this.rxFIFO.itemCount;
      case IC_TX_ABRT_SOURCE: return this.abortSource;
      case IC_SLV_DATA_NACK_ONLY: return this.slvDataNackOnly;
      case IC_SDA_HOLD: return this.sdaHold;
      case IC_ACK_GENERAL_CALL: return this.ackGeneralCall;
      case IC_ENABLE_STATUS: return this.enable & 1;
    }
    return super.readUint32(offset);
  }

  writeUint32(offset, value) {
    switch (offset) {
      case IC_INTR_MASK:
        this.intEnable = value & 0x1fff;
        this.checkInterrupts();
        return;
      case IC_DATA_CMD:
        if (this.txFlushed) return; // held flushed until TX_ABRT is cleared
        if (this.txFIFO.full) {
          this.raise(INTR.TX_OVER);
          return;
        }
        // A target stores data bytes only; a controller, commands.
        this.txFIFO.push(this.isController ? value & 0x7ff : value & 0xff);
        this.checkInterrupts();
        if (this.bus) this.bus.txWritten(this);
        return;
      case IC_ENABLE: {
        const was = this.enabled;
        if (value & 2 && this.mstActive) {
          // ABORT: the controller flushes, ends with a STOP; the bit clears when done.
          this.abortTx(ABRT.USER_ABRT);
          if (this.bus) this.bus.userAbort(this);
          value &= ~2;
        }
        this.enable = value & 5;
        if (was && !this.enabled) {
          this.txFIFO.reset();
          this.rxFIFO.reset();
          if (this.bus) this.bus.blockReset(this);
          this.mstActive = false;
          this.slvActive = false;
          this.stall = null;
        }
        this.checkInterrupts();
        if (this.bus && this.enabled) this.bus.txWritten(this);
        return;
      }
      case IC_SLV_DATA_NACK_ONLY: this.slvDataNackOnly = value & 1; return;
      case IC_SDA_HOLD:
        if (!this.enabled) this.sdaHold = value & 0xffffff;
        return;
      case IC_ACK_GENERAL_CALL: this.ackGeneralCall = value & 1; return;
      case IC_CON:
        this.control = value & 0x7ff;
        this.checkInterrupts();
        return;
      case IC_RX_TL:
      case IC_TX_TL:
        super.writeUint32(offset, value);
        this.checkInterrupts();
        return;
    }
    super.writeUint32(offset, value);
  }
}
