// The rig: emulated RP2040s running real ELF images in lockstep on one virtual clock, joined
// by one I2C bus (./bus.js), with the inputs a scenario drives and the outputs it records.
import { RP2040, GPIOPinState, LogLevel, ConsoleLogger } from 'rp2040js';
import { readElf } from './elf.js';
import { applyAll, bootFromFlash } from './patches.js';
import { Bus } from './bus.js';
import { driveLines } from './lines.js';
import { applyResetModel, watchdogReset, sysReset } from './reset.js';
import { NorFlash, applyFlashModel, defaultUid } from './flash.js';

const FLASH = 0x10000000;
const SRAM = 0x20000000;
const PAINT = 0x57a0c5ed;

/** The 8-byte unique ID of `options.uid`: an array of bytes or 16 hex digits. */
function uidOf(uid) {
  if (typeof uid === 'string') return uid.match(/../g).map((x) => parseInt(x, 16));
  return uid;
}

/**
 * One emulated Pico running one image. Its flash (`nor`, lib/flash.js: the array XIP reads, and
 * the unique ID `options.uid`, by default one from the chip's name) is loaded from the ELF when
 * the chip is first made; a chip made by a reset or power cycle is given the old one's.
 */
export class Chip {
  constructor(rig, name, elfPath, options = {}, nor = null) {
    this.rig = rig;
    this.name = name;
    this.options = options;
    // An image: an ELF file's path, or its contents as readElf returns them (the tests' images).
    this.elf = typeof elfPath === 'string' ? readElf(elfPath) : elfPath;
    // The package does not export SimulationClock: each chip keeps the one RP2040 makes.
    const rp = (this.rp = new RP2040());
    this.clock = rp.clock;
    rp.logger = new ConsoleLogger(options.verbose ? LogLevel.Info : LogLevel.Error, false);
    applyAll(rp);
    applyResetModel(rp);
    const programmed = !!nor;
    this.nor = nor ?? new NorFlash(rp.flash, uidOf(options.uid) ?? defaultUid(name));
    applyFlashModel(rp, this.nor);
    for (const s of this.elf.segments) {
      if (s.paddr >= FLASH && s.paddr < FLASH + rp.flash.length) {
        if (!programmed) rp.flash.set(s.data, s.paddr - FLASH);
      }
      else if (s.paddr >= SRAM && s.paddr < SRAM + rp.sram.length) rp.sram.set(s.data, s.paddr - SRAM);
    }
    // A bootloader (`options.boot`, an ELF path: boot-pico) programmed with the image: its
    // flash segments (boot2 and the bootloader from 0x10000100, where the chip starts); the
    // image is then one linked into a slot behind it, and its symbols (RTT) are the chip's.
    if (options.boot && !programmed) {
      this.bootElf = typeof options.boot === 'string' ? readElf(options.boot) : options.boot;
      for (const s of this.bootElf.segments) {
        if (s.paddr >= FLASH && s.paddr < FLASH + rp.flash.length) rp.flash.set(s.data, s.paddr - FLASH);
      }
    }
    // Stack high-water mark: paint the stack region before reset (cortex-m-rt does not touch it).
    const sym = (n) => this.elf.symbols.get(n)?.value;
    this.stackTop = sym('_stack_start') ?? SRAM + rp.sram.length;
    this.stackEnd = sym('_stack_end') ?? sym('__sheap') ?? sym('__ebss');
    for (let a = this.stackEnd; a < this.stackTop; a += 4) rp.sramView.setUint32(a - SRAM, PAINT, true);
    bootFromFlash(rp);
    // RTT up-buffer 0 (defmt), read straight from SRAM.
    this.rtt = sym('_SEGGER_RTT');
    this.defmt = []; // { t: ns, bytes: number[] } one per defmt frame (rzCOBS, 0x00-delimited)
    this.partial = null;
    this.lastRtt = 0;
    // Inputs: pins driven by the scenario (pull-ups are not modelled).
    for (const [pin, level] of Object.entries(options.inputs ?? {})) this.setPin(Number(pin), level);
    // Outputs: GPIO levels and PWM slice registers, each change with its time.
    this.pinLog = [];
    for (const pin of options.watch ?? []) {
      rp.gpio[pin].addListener((v) => this.pinLog.push({ t: this.clock.nanos, pin, v: stateName(v) }));
    }
    this.pwmLog = [];
    const pwm = rp.pwm;
    const write = pwm.writeUint32.bind(pwm);
    pwm.writeUint32 = (offset, value) => {
      write(offset, value);
      if (offset < 0xa0) {
        const ch = pwm.channels[Math.floor(offset / 0x14)];
        this.pwmLog.push({ t: this.clock.nanos, slice: ch.index, en: ch.csr & 1, top: ch.top, a: ch.cc & 0xffff, b: ch.cc >>> 16 });
      }
    };
  }

  get i2c0() { return this.rp.i2c[0]; }

  /** Drives an input pin (true = high). */
  setPin(pin, level) {
    const g = this.rp.gpio[pin];
    if (g.rawInputValue !== !!level) g.setInputValue(!!level);
  }

  /** Sets the voltage on an ADC input as a 12-bit count (GPIO 26..29 = channels 0..3). */
  setAdc(channel, counts) { this.rp.adc.channelValues[channel] = counts; }

  /** Output level of a GPIO: 'high', 'low' or 'input'. */
  pinState(pin) { return stateName(this.rp.gpio[pin].value); }

  /** Runs the core until its clock reaches `ns`. */
  runUntil(ns) {
    const { clock, rp } = this;
    const core = rp.core;
    while (clock.nanosCounter < ns) {
      if (core.waiting) {
        const next = clock.nextAlarm ? clock.nextAlarm.nanos : Infinity;
        clock.tick(Math.max(0, Math.min(next, ns) - clock.nanosCounter));
      } else {
        clock.tick(core.executeInstruction() * 8);
      }
    }
    if (this.rtt && ns - this.lastRtt >= 20000) this.readRtt();
  }

  readRtt() {
    this.lastRtt = this.clock.nanos;
    const v = this.rp.sramView;
    const up = this.rtt - SRAM + 24;
    const buf = v.getUint32(up + 4, true) - SRAM;
    const size = v.getUint32(up + 8, true);
    let rd = v.getUint32(up + 16, true);
    const wr = v.getUint32(up + 12, true);
    if (!size || rd === wr) return;
    // Before the image's start-up wrote its control block (a bootloader still running), the
    // words there are someone else's: only a block that points into SRAM is read.
    if (buf < 0 || size > this.rp.sram.length || buf + size > this.rp.sram.length || rd >= size || wr >= size) return;
    while (rd !== wr) {
      const b = this.rp.sram[buf + rd];
      rd = (rd + 1) % size;
      if (!this.partial) this.partial = { t: this.clock.nanos, bytes: [] };
      this.partial.bytes.push(b);
      if (b === 0) { this.defmt.push(this.partial); this.partial = null; }
    }
    v.setUint32(up + 16, rd, true);
  }

  /** Bytes of stack used so far (lowest address whose paint was overwritten). */
  stackUsed() {
    for (let a = this.stackEnd; a < this.stackTop; a += 4) {
      if (this.rp.sramView.getUint32(a - SRAM, true) !== PAINT) return this.stackTop - a;
    }
    return 0;
  }
}

function stateName(v) {
  if (v === GPIOPinState.High) return 'high';
  if (v === GPIOPinState.Low) return 'low';
  return 'input';
}

/** Chips, bus and timed actions on one virtual clock (ns). */
export class Rig {
  constructor(options = {}) {
    this.quantumNs = options.quantumNs ?? 1000;
    this.t = 0;
    this.queue = []; // sorted by time: { t, seq, fn }
    this.seq = 0;
    this.chips = [];
    /** Called after every quantum (the scripted motherboard polls its registers here). */
    this.hooks = [];
    this.bus = new Bus({ now: () => this.t, at: (t, fn) => this.at(t, fn) }, { stopGapNs: options.stopGapNs, log: options.busLog });
    driveLines(this); // SDA/SCL as pin levels (./lines.js)
  }

  now() { return this.t; }

  /** Runs `fn` at virtual time `t` (ns). */
  at(t, fn) {
    const e = { t, seq: this.seq++, fn };
    let i = this.queue.length;
    while (i > 0 && (this.queue[i - 1].t > t)) i--;
    this.queue.splice(i, 0, e);
  }

  addChip(name, elfPath, options = {}) {
    const chip = new Chip(this, name, elfPath, options);
    this.bus.attach(chip.i2c0, name);
    this.chips.push(chip);
    return chip;
  }

  /**
   * Power-cycles `chip`: its I2C block lets go of the bus at once (no STOP), and a fresh chip
   * with the same image and options boots in its place at the current time. Only the flash
   * (contents and unique ID) is kept: every register (WATCHDOG's REASON and SCRATCH included)
   * and SRAM start from their power-on values, and the flash is powered up again (not busy,
   * write enable off). The resets build on it with `warm` (lib/reset.js): the flash stays
   * powered through them.
   */
  powerCycle(chip, { warm = false } = {}) {
    const i = this.chips.indexOf(chip);
    if (!warm) chip.nor.powerUp();
    this.bus.detach(chip.i2c0);
    const fresh = new Chip(this, chip.name, chip.elf, chip.options, chip.nor);
    fresh.clock.nanosCounter = this.t;
    fresh.lastRtt = this.t;
    this.bus.attach(fresh.i2c0, chip.name);
    this.chips[i] = fresh;
    return fresh;
  }

  /** Runs until `ns`, or until `stop()` returns true (checked every quantum). */
  run(ns, stop = null) {
    while (this.t < ns) {
      const next = Math.min(ns, this.t + this.quantumNs);
      for (const c of this.chips) c.runUntil(next);
      for (const c of this.chips) {
        if (c.rp.watchdogFired) watchdogReset(this, c);
        else if (c.rp.sysResetRequested) sysReset(this, c);
      }
      while (this.queue.length && this.queue[0].t <= next) {
        const e = this.queue.shift();
        this.t = Math.max(this.t, e.t);
        e.fn();
      }
      this.t = next;
      for (const h of this.hooks) h();
      if (stop && stop()) return true;
    }
    return false;
  }
}
