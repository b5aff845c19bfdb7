// The USB link (docs/usb-link.md): the real mb-pico image (Figure 4.4) plugged into the rig's
// USB host (lib/usb.js), its byte stream handed to `x10 monitor --from FILE`.
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { UsbHost, LAPTOP, recordTimes, messages, varints } from '../lib/usb.js';
import { sensorPort, parseSignals, parseSimSummary } from '../lib/world.js';

const JUMPERS_OPEN = { 20: 1, 21: 1, 22: 1 };
const MB_A2A = 8; // the MB's actuator port 2, pin A (x10-boards' Pico table)

export default [
  {
    name: 'usb',
    about: 'mb-pico (Figure 4.4) and db-pico 9 with the MB on the rig\'s USB host: it enumerates, answers the laptop\'s hello, and `x10 monitor --from` its recorded stream shows each motor\'s changes as `x10 sim fig4_4 --clock 100k` does (values and order equal, times within 30 ms); a laptop call (io high A2.A) drives the MB\'s pin; the MB\'s defmt log line at each hello comes over USB and `x10 monitor --elf` decodes it; unplugged and plugged in again at 2.5 s, the records resume within 1 s',
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
      const monitor = ctx.x10(['monitor', '--from', file, '--example', 'fig4_4', '--html', page, '--elf', ctx.mbElf]);
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
      // The defmt log over the link (docs/usb-link.md, "The log"): the MB logs a line when a
      // laptop says hello; `x10 monitor --elf` decodes it from the USB stream alone (the file
      // holds only what came over USB), and the same line is in the RTT log the rig reads.
      const LOG_LINE = 'USB link: a laptop listens (link version 2)';
      const overUsb = monitor.split('\n').filter((l) => l.endsWith(` INFO  log: ${LOG_LINE}`));
      ctx.check(`x10 monitor prints the MB's log line "${LOG_LINE}" decoded from the USB stream, once per hello`, overUsb.length === 2,
        overUsb.join(' | ') || monitor.split('\n').find((l) => l.startsWith('log:')));
      ctx.check('every log frame over USB decodes', /^log: \d+ bytes over the link, \d+ lines decoded, 0 frames undecoded$/m.test(monitor),
        monitor.split('\n').find((l) => l.startsWith('log:')));
      const rtt = ctx.defmt(mb).filter((l) => l.text === `INFO ${LOG_LINE}`);
      ctx.check('the same line is in the RTT log (probe-rs and defmt-print read the same control block as with defmt-rtt)', rtt.length === 2, `${rtt.length} times`);
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
  {
    name: 'usb-load',
    about: 'the doorbell image (button on DB 9 S1.A, chime on the MB\'s A1.A) on the rig\'s USB host: a button edge to the chime\'s output record at the laptop, over 30 edges (p50/p99); then the button toggled every 8 ms for 400 ms twice, once with no laptop listening and once with the laptop listening and calling analog read S1 on the MB twice a millisecond: the robot\'s chime changes per second both ways (busy within 25 % of idle); the records per second the link carried, with none dropped',
    run(ctx) {
      if (!ctx.mbDoorbellElf) {
        ctx.check('the doorbell image was given (--mb-doorbell)', false);
        return;
      }
      const S1A = 14, CHIME = 4;
      const TAG = { log: 1, call: 2, event: 3, output: 4, dropped: 5, reply: 6 };
      const RECORDS = [TAG.call, TAG.event, TAG.output];
      const wall0 = Date.now();
      /** A rig with the doorbell MB on the USB host and DB 9; booted, DB 9's events on. */
      const start = () => {
        const rig = ctx.rig();
        const mb = rig.addChip('mb', ctx.mbDoorbellElf, { watch: [CHIME] });
        const db = rig.addChip('db09', ctx.dbElf, { inputs: JUMPERS_OPEN });
        db.setPin(S1A, false);
        const host = new UsbHost(mb.rp);
        rig.run(100e6);
        return { rig, mb, db, host };
      };
      const chimes = (mb, from, to) => mb.pinLog.filter((p) => p.pin === CHIME && p.t >= from && p.t < to).length;

      // 1. Latency: 30 edges, 30 to 49 ms apart (no common period with the MB's 1 ms tick or
      // the DB's latch poll), each to the first output record that arrives after it.
      const a = start();
      a.host.send(LAPTOP.hello());
      a.rig.run(a.rig.now() + 20e6);
      const edges = [];
      let level = false;
      for (let k = 0; k < 30; k++) {
        level = !level;
        edges.push(a.rig.now());
        a.db.setPin(S1A, level);
        a.rig.run(a.rig.now() + (30 + ((k * 7) % 20)) * 1e6);
      }
      const outs = recordTimes(a.host.received).filter((r) => r.kind === 'output');
      const lat = [];
      for (const t of edges) {
        const r = outs.find((o) => o.t > t);
        if (r) lat.push((r.t - t) / 1e6);
      }
      lat.sort((x, y) => x - y);
      const pct = (q) => lat[Math.min(lat.length - 1, Math.floor(q * lat.length))];
      ctx.check('every button edge reaches the laptop as the chime\'s output record', lat.length === edges.length, `${lat.length} of ${edges.length}`);
      const p99 = lat.length ? pct(0.99) : Infinity;
      ctx.check('button edge to the line on the laptop: p99 within 20 ms', p99 <= 20, `p50 ${lat.length ? pct(0.5).toFixed(2) : '-'} ms, p99 ${p99.toFixed(2)} ms`);
      ctx.figure('USB link: button edge on DB 9 to the chime\'s record at the laptop, 30 edges (ms, p50 / p99 / max; the rig\'s host takes each IN packet 10 µs after it is armed)',
        lat.length ? `${pct(0.5).toFixed(2)} / ${p99.toFixed(2)} / ${lat[lat.length - 1].toFixed(2)}` : 'none');

      // 2. Load: the button toggled every 8 ms for 400 ms (the robot follows a change in
      // about 3.7 ms: latch poll, event, one confirming read), once with nobody listening and
      // once with the laptop listening and calling `analog read S1` on the MB's own ports
      // twice a millisecond (each call a record and a reply, on top of the robot's records).
      const LOAD_MS = 400, TOGGLE_MS = 8;
      const load = (listen) => {
        const r = start();
        if (listen) {
          r.host.send(LAPTOP.hello());
          r.rig.run(r.rig.now() + 20e6);
        }
        const from = r.rig.now();
        const before = r.host.received.length;
        let lv = false, edges = 0, asked = 0;
        for (let ms = 1; ms <= LOAD_MS; ms++) {
          if (ms % TOGGLE_MS === 0) {
            lv = !lv;
            edges++;
            r.db.setPin(S1A, lv);
          }
          if (listen) {
            for (let i = 0; i < 2; i++) r.host.send(LAPTOP.call(1 + (asked++ % 120), 0, 0x30, 0x80));
          }
          r.rig.run(from + ms * 1e6);
        }
        const to = r.rig.now();
        // Let the ring drain, then count what came.
        r.rig.run(to + 20e6);
        const msgs = messages(r.host.received.slice(before));
        const dropped = msgs.filter((m) => m.tag === TAG.dropped).map((m) => varints(m.body));
        const last = dropped.length ? dropped[dropped.length - 1] : [0, 0, 0, 0, 0];
        const inRun = r.host.received.slice(before).filter((p) => p.t >= from && p.t < to);
        return {
          edges,
          chimes: chimes(r.mb, from, to + 20e6),
          calls: chimes(r.mb, from, to) / (LOAD_MS / 1000),
          records: msgs.filter((m) => RECORDS.includes(m.tag) && m.t < to).length / (LOAD_MS / 1000),
          replies: msgs.filter((m) => m.tag === TAG.reply).length,
          asked,
          bytes: inRun.reduce((n, p) => n + p.bytes.length, 0) / (LOAD_MS / 1000),
          lost: last[0] + last[1] + last[2] + last[3],
          bad: msgs.filter((m) => m.tag === null).length,
        };
      };
      const idle = load(false);
      const busy = load(true);
      // The doorbell robot does not follow every 8 ms change (its `Button` reports a change once
      // its confirming read agrees): the measure is how many it follows per second, idle vs busy.
      ctx.check('link busy: the robot\'s chime changes per second within 25 % of the idle link\'s', idle.chimes > 0 && busy.calls >= 0.75 * idle.calls,
        `idle ${idle.chimes}, busy ${busy.chimes} chime changes for ${idle.edges} button changes`);
      ctx.check('the busy link drops nothing, every frame decodes, and the laptop\'s calls are answered', busy.lost === 0 && busy.bad === 0 && busy.records > 0 && busy.replies > 0,
        `${busy.records.toFixed(0)} records/s, ${busy.replies} of ${busy.asked} calls answered in the run, ${busy.lost} records dropped, ${busy.bad} bad frames`);
      ctx.figure('USB link: the robot\'s chime changes per second, button toggled every 8 ms, link idle / busy', `${idle.calls.toFixed(0)} / ${busy.calls.toFixed(0)}`);
      ctx.figure('USB link busy: records per second carried with none dropped / laptop calls answered per second / bytes per second', `${busy.records.toFixed(0)} / ${(busy.replies / (LOAD_MS / 1000)).toFixed(0)} / ${busy.bytes.toFixed(0)}`);
      ctx.figure('simulated s per wall s (usb-load: 3 rigs of 2 chips and USB)', ((a.rig.now() + 2 * (100e6 + (LOAD_MS + 40) * 1e6)) / 1e9 / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  },
];
