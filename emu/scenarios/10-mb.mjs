// Scenarios with the real mb-pico images (thesis Figure 4.4; the doorbell) against db-pico 9.
import { motorTrack } from '../lib/world.js';

const JUMPERS_OPEN = { 20: 1, 21: 1, 22: 1 }; // no jumper fitted (pull-ups are not modelled)
const MOTOR_PINS = [2, 4, 5];

function pair(ctx, options = {}) {
  const rig = ctx.rig(options);
  const mb = rig.addChip('mb', options.mbElf ?? ctx.mbElf, { watch: MOTOR_PINS });
  const db = rig.addChip('db09', ctx.dbElf, { inputs: JUMPERS_OPEN, watch: MOTOR_PINS });
  return { rig, mb, db };
}

export default [
  {
    name: 'boot',
    about: 'mb-pico and db-pico 9 boot, DB 9 announces itself, the MB starts polling it',
    run(ctx) {
      const { rig, mb, db } = pair(ctx);
      let firstMbFrame = null;
      const wall0 = Date.now();
      rig.run(60e6, () => {
        if (firstMbFrame === null) {
          const f = rig.bus.transfers.find((t) => t.master === 'mb' && t.end === 'stop' && t.parts[0].ack);
          if (f) firstMbFrame = f.t0;
        }
        return false;
      });
      const wall = (Date.now() - wall0) / 1000;
      const mbLog = ctx.defmt(mb).map((l) => l.text).join('\n');
      const dbLog = ctx.defmt(db).map((l) => l.text).join('\n');
      ctx.check('db-pico logs its address', /daughterboard on a Pico at 0x09/.test(dbLog), dbLog.split('\n')[0]);
      ctx.check('mb-pico logs the robot program', /Figure 4.4/.test(mbLog));
      const boot = rig.bus.transfers.find((t) => t.master === 'db09' && t.parts[0].addr === 0x08 && t.parts[0].ack && t.parts[0].bytes[1] === 0x07);
      ctx.check('DB 9 sends its boot event to the MB (0x08)', boot, boot && rig.bus.describe(boot));
      ctx.check('the MB logs "board 9 booted"', /board 9 booted/.test(mbLog));
      const poll = rig.bus.transfers.filter((t) => t.master === 'mb' && t.parts[0].bytes[0] === 0x30 && t.parts.length === 2);
      ctx.check('the MB reads DB 9\'s light sensor (analog read S1) every 20 ms', poll.length >= 2, `${poll.length} reads`);
      ctx.figure('boot to first MB frame (ms)', firstMbFrame === null ? 'none' : (firstMbFrame / 1e6).toFixed(3));
      ctx.figure('simulated s per wall s (2 chips)', (0.06 / wall).toFixed(2));
      ctx.figure('stack high-water mark mb-pico / db-pico (bytes)', `${mb.stackUsed()} / ${db.stackUsed()}`);
    },
  },
  {
    name: 'fig4_4',
    about: 'thesis Figure 4.4 end to end: robots/worlds/fig4_4.toml inputs, actuator changes as the simulator gives them',
    run(ctx) {
      const { rig, mb, db } = pair(ctx);
      // The world of robots/worlds/fig4_4.toml, as pin and ADC inputs.
      const light = (ms) => (ms < 500 ? 200 : ms < 2500 ? 200 + ((ms - 500) * 700) / 2000 : ms < 4000 ? 900 : 300);
      const force = (ms) => (ms < 3600 ? 40 : ms < 4200 ? 350 : 40);
      const button = (ms) => ms >= 2000 && ms < 3000;
      const END_MS = 4500;
      const wall0 = Date.now();
      for (let ms = 0; ms <= END_MS; ms += 1) {
        db.setAdc(0, Math.round(light(ms)));
        mb.setAdc(0, force(ms));
        mb.setPin(17, button(ms));
        rig.run(ms * 1e6);
      }
      const wall = (Date.now() - wall0) / 1000;
      const want = {
        mb: [[0, 'stop'], [2000, 'forward 100%'], [3000, 'stop'], [3600, 'forward 100%'], [4200, 'stop']],
        db09: [[0, 'stop'], [1929, 'forward 50%'], [4000, 'stop']],
      };
      const TOL_MS = 45; // 20 ms program period + the bus + the emulator's quantum
      for (const chip of [mb, db]) {
        const got = motorTrack(chip);
        const w = want[chip.name];
        const same = got.length === w.length && got.every((g, i) => g.state === w[i][1] && (i === 0 || Math.abs(g.ms - w[i][0]) <= TOL_MS));
        ctx.check(`${chip.name === 'mb' ? 'SELF' : 'DB 9'} motor A1: ${w.map(([t, s]) => `${s}@${t}`).join(', ')} (±${TOL_MS} ms)`, same,
          got.map((g) => `${g.state}@${g.ms.toFixed(0)}`).join(', '));
      }
      ctx.figure('simulated s per wall s (2 chips, fig4_4)', (END_MS / 1000 / wall).toFixed(2));
      ctx.figure('stack high-water mark after fig4_4, mb-pico / db-pico (bytes)', `${mb.stackUsed()} / ${db.stackUsed()}`);
    },
  },
  {
    name: 'doorbell',
    about: 'a pin event from db-pico 9 wakes a task on the real mb-pico (robots/src/doorbell.rs): button on DB 9 S1.A to chime on the MB\'s A1.A, edge-to-task latency',
    run(ctx) {
      if (!ctx.mbDoorbellElf) {
        ctx.check('the doorbell image was given (--mb-doorbell)', false);
        return;
      }
      const S1A = 14, CHIME = 4;
      const { rig, mb, db } = pair(ctx, { mbElf: ctx.mbDoorbellElf });
      db.setPin(S1A, false);
      rig.run(100e6); // boot, prepare DB 9, enable its events
      const chime = () => mb.pinLog.filter((p) => p.pin === CHIME);
      const lat = [];
      const states = [];
      for (const [press, holdMs] of [[true, 300], [false, 300], [true, 50], [false, 300]]) {
        const before = chime().length;
        const t = rig.now();
        db.setPin(S1A, press);
        rig.run(t + 100e6, () => chime().length > before);
        const c = chime()[before];
        if (c) { lat.push((c.t - t) / 1e3); states.push(c.v); }
        rig.run(rig.now() + holdMs * 1e6);
      }
      const mbLog = ctx.defmt(mb).map((l) => l.text).join('\n');
      ctx.check('mb-pico logs the robot program', /doorbell/.test(mbLog), mbLog.split('\n').find((l) => /robot program/.test(l)));
      ctx.check('four button changes, four chime changes: on, off, on, off', lat.length === 4 && states.join(',') === 'high,low,high,low',
        `${states.join(', ')} after ${lat.map((l) => `${l.toFixed(0)} µs`).join(', ')}`);
      ctx.figure('button edge on DB 9 to the chime pin on the MB, 100 kHz (µs, min/max: latch poll, event, MB task, one debounce read of DB 9, the GPIO write)', lat.length ? `${Math.min(...lat).toFixed(0)} / ${Math.max(...lat).toFixed(0)}` : 'none');
      ctx.figure('stack high-water mark after doorbell, mb-pico-doorbell / db-pico (bytes)', `${mb.stackUsed()} / ${db.stackUsed()}`);
    },
  },
];
