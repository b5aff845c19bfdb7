// Scenarios with the real mb-pico images (thesis Figure 4.4; the doorbell) against db-pico 9.
import { motorTrack, actuatorPort, sensorPort, parseSignals, parseSimSummary } from '../lib/world.js';

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
      ctx.check('mb-pico logs the robot program', /robot program Fig4_4/.test(mbLog));
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
    about: 'thesis Figure 4.4 end to end from the simulator\'s world: the inputs of robots/worlds/fig4_4.toml as `x10 signals` reads them, and each motor changing as `x10 sim fig4_4 --clock 100k` says (values and order equal, times within 30 ms)',
    run(ctx) {
      const END_MS = 4500;
      const TOL_MS = 30; // the program's 20 ms period, the bus and the emulator's quantum
      const signals = ctx.x10(['signals', 'fig4_4', '--duration-ms', String(END_MS)]);
      const summary = ctx.x10(['sim', 'fig4_4', '--clock', '100k', '--duration-ms', String(END_MS)]);
      if (signals === null || summary === null) {
        ctx.check('the x10 tool was given (--x10)', false);
        return;
      }
      const world = parseSignals(signals);
      const { rig, mb, db } = pair(ctx);
      const chips = { 0: mb, 9: db };
      const wall0 = Date.now();
      let next = 0;
      for (let ms = 0; ms <= END_MS; ms += 1) {
        for (; next < world.changes.length && world.changes[next].t_ms <= ms; next++) {
          const c = world.changes[next];
          const chip = chips[c.board];
          const p = sensorPort(c.port);
          chip.setPin(p.a, c.a);
          chip.setPin(p.b, c.b);
          chip.setAdc(p.adc, c.analog);
        }
        rig.run(ms * 1e6);
      }
      const wall = (Date.now() - wall0) / 1000;
      const motors = world.devices.filter((d) => d.output && d.kind === 'dc_motor');
      const want = parseSimSummary(summary, motors.map((d) => d.device));
      ctx.check('the world has the two motors of Figure 4.4', motors.length === 2, motors.map((d) => d.device).join(', '));
      let worst = 0;
      for (const d of motors) {
        // The image's first command (stop, at start) is not a change in the simulator's summary.
        const got = motorTrack(chips[d.board], actuatorPort(d.port)).filter((g, k) => !(k === 0 && g.state === 'stop'));
        const w = want[d.device];
        const same = got.length === w.length && got.every((g, k) => g.state === w[k].state && Math.abs(g.ms - w[k].ms) <= TOL_MS);
        for (const [k, g] of got.entries()) if (w[k]) worst = Math.max(worst, Math.abs(g.ms - w[k].ms));
        ctx.check(`${d.device} (board ${d.board} A${d.port}) as in the simulator: ${w.map((x) => `${x.state}@${x.ms.toFixed(0)}`).join(', ')} (±${TOL_MS} ms)`, same,
          got.map((g) => `${g.state}@${g.ms.toFixed(0)}`).join(', '));
      }
      ctx.figure('largest difference from the simulator\'s times (ms)', worst.toFixed(1));
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
