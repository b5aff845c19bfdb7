// The USB link (docs/usb-link.md): the real mb-pico image (Figure 4.4) plugged into the rig's
// USB host (lib/usb.js), its byte stream handed to `x10 monitor --from FILE`.
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { UsbHost, LAPTOP, recordTimes } from '../lib/usb.js';
import { sensorPort, parseSignals, parseSimSummary } from '../lib/world.js';

const JUMPERS_OPEN = { 20: 1, 21: 1, 22: 1 };
const MB_A2A = 8; // the MB's actuator port 2, pin A (x10-boards' Pico table)

export default [
  {
    name: 'usb',
    about: 'mb-pico (Figure 4.4) and db-pico 9 with the MB on the rig\'s USB host: it enumerates, answers the laptop\'s hello, and `x10 monitor --from` its recorded stream shows each motor\'s changes as `x10 sim fig4_4 --clock 100k` does (values and order equal, times within 30 ms); a laptop call (io high A2.A) drives the MB\'s pin; unplugged and plugged in again at 2.5 s, the records resume within 1 s',
    run(ctx) {
      const END_MS = 4500;
      const CALL_MS = 4300;
      const REPLUG_MS = 2500; // no motor changes near it (fig4_4: 1.95, 2.02, 3.02, 3.6, 4.0, 4.2 s)
      const TOL_MS = 30;
      const signals = ctx.x10(['signals', 'fig4_4', '--duration-ms', String(END_MS)]);
      const summary = ctx.x10(['sim', 'fig4_4', '--clock', '100k', '--duration-ms', String(END_MS)]);
      if (signals === null || summary === null) {
        ctx.check('the x10 tool was given (--x10)', false);
        return;
      }
      const world = parseSignals(signals);
      const rig = ctx.rig();
      const mb = rig.addChip('mb', ctx.mbElf, { watch: [2, 4, 5, MB_A2A] });
      const db = rig.addChip('db09', ctx.dbElf, { inputs: JUMPERS_OPEN, watch: [2, 4, 5] });
      const host = new UsbHost(mb.rp);
      const chips = { 0: mb, 9: db };
      const wall0 = Date.now();
      let next = 0, helloAt = null, callAt = null, replugAt = null, helloAgain = null, configuredAt = null;
      for (let ms = 0; ms <= END_MS; ms += 1) {
        for (; next < world.changes.length && world.changes[next].t_ms <= ms; next++) {
          const c = world.changes[next];
          const chip = chips[c.board];
          const p = sensorPort(c.port);
          chip.setPin(p.a, c.a);
          chip.setPin(p.b, c.b);
          chip.setAdc(p.adc, c.analog);
        }
        if (host.connected !== null && helloAt === null) {
          host.send(LAPTOP.hello());
          helloAt = rig.now();
          configuredAt = host.connected;
        }
        if (ms === REPLUG_MS) {
          host.replug();
          replugAt = rig.now();
        }
        if (replugAt !== null && host.connected !== null && helloAgain === null) {
          host.send(LAPTOP.hello());
          helloAgain = rig.now();
        }
        if (ms === CALL_MS) {
          host.send(LAPTOP.call(1, 0, 0x12, 0x02)); // io high A2.A on the MB's own ports
          callAt = rig.now();
        }
        rig.run(ms * 1e6);
      }
      const wall = (Date.now() - wall0) / 1000;
      ctx.check('the MB enumerates on the USB host (configured, control line state sent)', configuredAt !== null,
        configuredAt === null ? 'never' : `at ${(configuredAt / 1e6).toFixed(1)} ms`);
      const bytes = host.bytes();
      const file = join(ctx.out, 'usb.x10link');
      writeFileSync(file, Uint8Array.from(bytes));
      ctx.check('the MB sends frames once the laptop said hello', bytes.length > 0, `${bytes.length} bytes, hello at ${helloAt === null ? '-' : (helloAt / 1e6).toFixed(1)} ms`);
      const page = join(ctx.out, 'usb.html');
      const monitor = ctx.x10(['monitor', '--from', file, '--example', 'fig4_4', '--html', page]);
      ctx.check('x10 monitor reads the hello', /hello from the motherboard at 0x08 on a Pico running Fig4_4/.test(monitor),
        monitor.split('\n').find((l) => /hello/.test(l)));
      const motors = world.devices.filter((d) => d.output && d.kind === 'dc_motor').map((d) => d.device);
      const want = parseSimSummary(summary, motors);
      const got = parseSimSummary(monitor, motors);
      let worst = 0;
      for (const m of motors) {
        const w = want[m], g = got[m];
        const same = g.length === w.length && g.every((x, k) => x.state === w[k].state && Math.abs(x.ms - w[k].ms) <= TOL_MS);
        for (const [k, x] of g.entries()) if (w[k]) worst = Math.max(worst, Math.abs(x.ms - w[k].ms));
        ctx.check(`x10 monitor: ${m} as in the simulator: ${w.map((x) => `${x.state}@${x.ms.toFixed(0)}`).join(', ')} (±${TOL_MS} ms)`, same,
          g.map((x) => `${x.state}@${x.ms.toFixed(0)}`).join(', '));
      }
      // The frame cut by the unplug is the only one that may not decode.
      ctx.check('x10 monitor counts no drop, and no bad frame but the one the unplug may cut', /dropped by the motherboard: 0 calls, 0 events, 0 output changes, 0 log bytes; [01] bad frames/.test(monitor),
        monitor.split('\n').find((l) => l.startsWith('link:')));
      const after = host.received.find((r) => r.t > (helloAgain ?? Infinity));
      ctx.check('unplugged and plugged in again at 2.5 s, the MB is enumerated again and its records resume within 1 s', after && after.t - replugAt <= 1e9,
        after ? `configured again ${((host.connected - replugAt) / 1e6).toFixed(1)} ms after the replug, records again after ${((after.t - replugAt) / 1e6).toFixed(1)} ms` : 'never');
      ctx.check('x10 monitor reads both hellos', (monitor.match(/hello from the motherboard/g) ?? []).length === 2);
      const high = mb.pinLog.find((p) => p.pin === MB_A2A && p.v === 'high' && p.t >= callAt);
      ctx.check('the laptop\'s call drives the MB\'s A2.A high', high, high ? `${((high.t - callAt) / 1e3).toFixed(0)} µs after the request` : 'never');
      ctx.check('x10 monitor shows the laptop\'s call', /SELF io high A2\.A -> ok/.test(monitor), monitor.split('\n').find((l) => /A2\.A/.test(l)));
      ctx.figure('USB link, x10 monitor against the simulator: largest difference (ms)', worst.toFixed(1));
      ctx.figure('USB link: laptop request to the MB\'s pin (µs)', high ? ((high.t - callAt) / 1e3).toFixed(0) : 'none');
      ctx.figure('USB link: unplug and plug in again to the first record at the host (ms; rp2040js resets the bus 10 ms after)', after ? ((after.t - replugAt) / 1e6).toFixed(1) : 'none');
      ctx.figure('USB link: bytes the MB sent over 4.5 s of Figure 4.4', String(bytes.length));
      // From the MB's time stamp of a record (a call's end, an output change) to the arrival of
      // the USB packet that ends its frame at the host.
      const lat = recordTimes(host.received).map((r) => (r.t - r.us * 1000) / 1e6).sort((a, b) => a - b);
      const pct = (q) => lat[Math.min(lat.length - 1, Math.floor(q * lat.length))];
      ctx.check('every record reaches the host', lat.length > 0 && lat.every((x) => x >= 0), `${lat.length} records`);
      if (lat.length) ctx.figure('USB link: record on the MB to the host (ms, p50 / p99 / max)', `${pct(0.5).toFixed(2)} / ${pct(0.99).toFixed(2)} / ${lat[lat.length - 1].toFixed(2)}`);
      ctx.figure('simulated s per wall s (2 chips and USB, fig4_4)', (END_MS / 1000 / wall).toFixed(2));
    },
  },
];
