// Crashes of db-pico (issue 21 item 2): an injected panic and an injected hang (lib/inject.js),
// the watchdog's reset (lib/reset.js), the outputs read from the emulated GPIOs and PWM slices,
// the boot event's reset reason read from the scripted motherboard's record.
import { VirtualMb, request, actuator } from '../lib/vmb.js';
import { injectPanic, injectHang } from '../lib/inject.js';
import { REASON_FORCE, REASON_TIMER } from '../lib/reset.js';

const JUMPERS_OPEN = { 20: 1, 21: 1, 22: 1 };
/** Actuator ports 1-3 of the Pico (x10-boards pins.rs): PWM A/B on slices 1, 3, 5, digital A/B. */
const PORTS = [
  { n: 1, slice: 1, pwm: [2, 3], dig: [4, 5] },
  { n: 2, slice: 3, pwm: [6, 7], dig: [8, 9] },
  { n: 3, slice: 5, pwm: [10, 11], dig: [12, 13] },
];
const PINS = PORTS.flatMap((p) => [...p.pwm, ...p.dig]);
/** ResetReason bytes (x10-microcode): power-on, watchdog, panic. */
const POWER_ON = 0, WATCHDOG = 1, PANIC = 2;
/** crash::marker(Crash::Panic) in x10-boards. */
const PANIC_MARKER = 0x58313002;

function setup(ctx) {
  const rig = ctx.rig();
  const vmb = new VirtualMb(rig, { hz: 100000 });
  rig.addChip('db09', ctx.dbElf, { inputs: { ...JUMPERS_OPEN, 14: 0 }, watch: PINS });
  rig.run(5e6);
  return { rig, vmb };
}

const bootEvents = (vmb) => vmb.events.filter((e) => e.bytes[0] === 9 && e.bytes[1] === 0x07);
/** The reset reason of a boot event: the byte after the 10-byte identity (then, since issue 24,
 * the board's 8-byte unique ID: a 19-byte payload; 11 bytes from a board of an earlier version). */
const reasonOf = (ev) => (ev && (ev.bytes[5] === 19 || ev.bytes[5] === 11) ? ev.bytes[16] : undefined);
const hex = (b) => (b ?? []).map((x) => x.toString(16).padStart(2, '0')).join(' ');

/** Every actuator output on: PWM A at 50 %, PWM B at 100 %, digital A and B high. */
function outputsOn(vmb) {
  for (const p of PORTS) {
    vmb.send(request(0x20, 9, actuator(p.n, 'A'), vmb.nextSeq(), [128]));
    vmb.send(request(0x20, 9, actuator(p.n, 'B'), vmb.nextSeq(), [255]));
    vmb.send(request(0x12, 9, actuator(p.n, 'A'), vmb.nextSeq()));
    vmb.send(request(0x12, 9, actuator(p.n, 'B'), vmb.nextSeq()));
  }
}

/** The outputs of `chip` now: pin levels and PWM slices (enable, compare A/B). */
function outputs(chip) {
  return {
    pins: PINS.map((g) => chip.pinState(g)),
    slices: PORTS.map((p) => {
      const ch = chip.rp.pwm.channels[p.slice];
      return { en: ch.csr & 1, a: ch.cc & 0xffff, b: ch.cc >>> 16 };
    }),
  };
}
const allLow = (o) => o.pins.every((s) => s === 'low');
/** Every actuator pin's function is SIO (IO_BANK0 GPIOn_CTRL FUNCSEL 5): off its PWM slice. */
const onSio = (chip) => PINS.every((g) => chip.rp.gpio[g].functionSelect === 5);
const atZero = (o) => o.slices.every((s) => s.a === 0 && s.b === 0);
const show = (o) => `pins ${o.pins.join(',')}; slices ${o.slices.map((s) => `${s.en}:${s.a}/${s.b}`).join(' ')}`;

/** The last level each pin was set to at or before `t` (from the chip's pin log). */
function levelsAt(chip, t) {
  return PINS.map((g) => {
    const e = chip.pinLog.filter((l) => l.pin === g && l.t <= t);
    return e.length ? e[e.length - 1].v : 'input';
  });
}

/** Outputs on, checked, then the boot event's reason of the first boot. */
function running(ctx, rig, vmb) {
  const first = bootEvents(vmb)[0];
  ctx.check('the first boot event says power-on', reasonOf(first) === POWER_ON, hex(first?.bytes));
  outputsOn(vmb);
  rig.run(rig.now() + 3e6);
  const on = outputs(rig.chips[0]);
  ctx.check('outputs on: digital pins high, PWM slices running with A at 50 % and B at 100 %',
    PORTS.every((p, i) => p.dig.every((g) => rig.chips[0].pinState(g) === 'high') && on.slices[i].en === 1 && on.slices[i].a > 0 && on.slices[i].b > on.slices[i].a),
    show(on));
}

/** After the reset: the new chip boots, sends a boot event with `reason`, its outputs are low. */
function rebooted(ctx, rig, vmb, reason, name) {
  rig.run(rig.now() + 10e6, () => bootEvents(vmb).length >= 2);
  const ev = bootEvents(vmb)[1];
  ctx.check(`the board boots again and its boot event says ${name}`, reasonOf(ev) === reason, hex(ev?.bytes));
  rig.run(rig.now() + 2e6);
  const after = outputs(rig.chips[0]);
  ctx.check('after the boot: every actuator pin low, every PWM compare 0', allLow(after) && atZero(after), show(after));
  const scratch0 = rig.chips[0].rp.peripherals[0x40058].scratchData[0];
  ctx.check('the boot cleared the crash record (WATCHDOG.SCRATCH0 = 0)', scratch0 === 0, `0x${scratch0.toString(16)}`);
}

export default [
  {
    name: 'panic',
    resets: true,
    about: 'issue 21 item 2: a panic injected into db-pico (the core jumps to its panic handler) puts every actuator pin low (SIO, off its PWM slice) before the watchdog resets the chip; the boot event says panic',
    run(ctx) {
      const { rig, vmb } = setup(ctx);
      running(ctx, rig, vmb);
      const db = rig.chips[0];
      const t = rig.now();
      const at = injectPanic(db);
      rig.run(t + 5e6, () => rig.chips[0] !== db);
      const reset = rig.chips[0].resets?.[0];
      ctx.check('the chip resets through its watchdog (REASON FORCE) with the panic recorded in SCRATCH0',
        !!reset && reset.reason === REASON_FORCE && reset.scratch0 === PANIC_MARKER,
        reset ? `REASON ${reset.reason}, SCRATCH0 0x${reset.scratch0.toString(16)}, ${((reset.t - t) / 1e3).toFixed(1)} µs after the jump to 0x${at.toString(16)}` : 'no reset in 5 ms');
      if (!reset) return;
      // The old chip, as the reset found it.
      const atReset = outputs(db);
      ctx.check('before the reset: every actuator pin driven low by SIO (the PWM pins taken off their slices, which run on)',
        allLow(atReset) && onSio(db) && levelsAt(db, reset.t).every((v) => v === 'low'), show(atReset));
      ctx.figure('panic: injection to reset (µs)', ((reset.t - t) / 1e3).toFixed(1));
      rebooted(ctx, rig, vmb, PANIC, 'panic');
    },
  },
  {
    name: 'hang',
    resets: true,
    about: 'issue 21 item 2: a healthy db-pico never lets its watchdog fire; a hang injected into it (the core spins in thread mode, interrupts on) stops the feeding, and the watchdog resets the chip 150 to 200 ms later; the boot event says watchdog and the outputs are low',
    run(ctx) {
      const { rig, vmb } = setup(ctx);
      running(ctx, rig, vmb);
      const db = rig.chips[0];
      rig.run(rig.now() + 600e6);
      ctx.check('600 ms of a healthy runtime: no watchdog reset', rig.chips[0] === db && !db.resets);
      const t = rig.now();
      injectHang(db);
      rig.run(t + 400e6, () => rig.chips[0] !== db);
      const reset = rig.chips[0].resets?.[0];
      const ms = reset ? (reset.t - t) / 1e6 : NaN;
      ctx.check('the watchdog resets the hung chip (REASON TIMER, no crash record) 150 to 200 ms after the hang',
        !!reset && reset.reason === REASON_TIMER && reset.scratch0 === 0 && ms >= 150 && ms <= 200.1,
        reset ? `REASON ${reset.reason}, SCRATCH0 0x${reset.scratch0.toString(16)}, ${ms.toFixed(1)} ms` : 'no reset in 400 ms');
      if (!reset) return;
      ctx.figure('hang: hang to watchdog reset (ms)', ms.toFixed(1));
      // A hang runs no crash path: the outputs stay as they were until the reset.
      const atReset = outputs(db);
      ctx.check('until the reset the outputs stay as the hang left them (no code runs to change them)',
        PORTS.every((p) => p.dig.every((g) => db.pinState(g) === 'high')) && atReset.slices.every((s) => s.en === 1), show(atReset));
      rebooted(ctx, rig, vmb, WATCHDOG, 'watchdog');
    },
  },
  {
    name: 'mb-panic',
    resets: true,
    about: 'issue 21 item 2 on the motherboard: the real mb-pico-doorbell with db-pico 9; with the chime (the MB\'s A1.A, GP4) on, a panic injected into the MB drops its actuator pins low before it resets; it boots again and logs "board 0 booted (panic)"; then a panic injected into DB 9 is logged as "board 9 booted (panic)"',
    run(ctx) {
      if (!ctx.mbDoorbellElf) {
        ctx.check('the doorbell image was given (--mb-doorbell)', false);
        return;
      }
      const S1A = 14, CHIME = 4;
      const rig = ctx.rig();
      rig.addChip('mb', ctx.mbDoorbellElf, { watch: PINS });
      rig.addChip('db09', ctx.dbElf, { inputs: { ...JUMPERS_OPEN, [S1A]: 0 }, watch: PINS });
      rig.run(100e6); // boot, prepare DB 9, enable its events
      const mbLog = () => ctx.defmt(rig.chips[0]).map((l) => l.text).join('\n');
      const boots = () => mbLog().split('\n').filter((l) => /booted/.test(l)).join(' | ');
      ctx.check('the MB logs "board 0 booted (power_on)" (its own) and "board 9 booted (power_on)"',
        /board 0 booted \(power_on\)/.test(mbLog()) && /board 9 booted \(power_on\)/.test(mbLog()), boots());
      // The chime on, then a panic on the MB.
      rig.chips[1].setPin(S1A, true);
      rig.run(rig.now() + 100e6, () => rig.chips[0].pinState(CHIME) === 'high');
      const mb = rig.chips[0];
      ctx.check('the chime is on (the MB\'s GP4 high)', mb.pinState(CHIME) === 'high');
      const t = rig.now();
      injectPanic(mb);
      rig.run(t + 5e6, () => rig.chips[0] !== mb);
      const reset = rig.chips[0].resets?.[0];
      ctx.check('the MB resets through its watchdog (REASON FORCE) with the panic recorded in SCRATCH0',
        !!reset && reset.reason === REASON_FORCE && reset.scratch0 === PANIC_MARKER,
        reset ? `REASON ${reset.reason}, SCRATCH0 0x${reset.scratch0.toString(16)}, ${((reset.t - t) / 1e3).toFixed(1)} µs after the jump` : 'no reset in 5 ms');
      if (!reset) return;
      const atReset = outputs(mb);
      ctx.check('before the MB\'s reset: every actuator pin of its internal board driven low by SIO (the chime too)',
        allLow(atReset) && onSio(mb) && levelsAt(mb, reset.t).every((v) => v === 'low'), show(atReset));
      ctx.figure('mb-panic: injection to reset (µs)', ((reset.t - t) / 1e3).toFixed(1));
      rig.run(rig.now() + 100e6);
      const afterBoot = rig.chips[0].pinState(CHIME);
      // The button released and pressed again: the rebooted MB's task rings.
      rig.chips[1].setPin(S1A, false);
      rig.run(rig.now() + 50e6);
      rig.chips[1].setPin(S1A, true);
      rig.run(rig.now() + 100e6, () => rig.chips[0].pinState(CHIME) === 'high');
      const robot = mbLog().split('\n').filter((l) => /robot program/.test(l)).length;
      ctx.check('the rebooted MB logs its own board\'s reason: "board 0 booted (panic)"', /board 0 booted \(panic\)/.test(mbLog()), boots());
      ctx.check('the MB boots again (its start-up line twice in its log), its chime low after the boot, then following the button again',
        robot === 2 && afterBoot === 'low' && rig.chips[0].pinState(CHIME) === 'high',
        `${robot} start-up lines, chime ${afterBoot} after the boot, ${rig.chips[0].pinState(CHIME)} after the next press`);
      // A panic on DB 9.
      const db = rig.chips[1];
      injectPanic(db);
      rig.run(rig.now() + 100e6, () => /board 9 booted \(panic\)/.test(mbLog()));
      ctx.check('DB 9 panics, resets and boots; the MB logs "board 9 booted (panic)"', rig.chips[1] !== db && /board 9 booted \(panic\)/.test(mbLog()), boots());
    },
  },
];
