// Scenarios with db-pico against a scripted motherboard (lib/vmb.js): exact frames and timing.
import { VirtualMb, request, sensor, actuator, parseReply } from '../lib/vmb.js';

const JUMPERS_OPEN = { 20: 1, 21: 1, 22: 1 };
const S1A = 14; // GP14: sensor port 1 pin A

function setup(ctx, options = {}) {
  const rig = ctx.rig({ stopGapNs: options.stopGapNs });
  const vmb = new VirtualMb(rig, { hz: options.hz ?? 100000 });
  const dbs = (options.dbs ?? [9]).map((a) =>
    rig.addChip(`db${String(a).padStart(2, '0')}`, options.dbElf ?? ctx.dbElf, {
      // Jumper 0 fitted (low) adds 1 to the base address 9.
      inputs: { ...JUMPERS_OPEN, 20: a === 10 ? 0 : 1, [S1A]: 0 },
      watch: [4, 5],
    }));
  rig.run(5e6); // boot (and the boot event)
  return { rig, vmb, dbs };
}

const ask = (vmb, db, op, port, data, readLen) => {
  const seq = vmb.nextSeq();
  const read = vmb.ask(request(op, db, port, seq, data), readLen);
  return { seq, read, reply: parseReply(read) };
};

/**
 * Enables pin-change events (both edges) on sensor port 1 pin A of `db`. firmware-db samples
 * the pins every 10 ms and compares with the level it sampled before: an edge before its first
 * sample is not an event, so scenarios wait SETTLE_NS before the first edge.
 */
function enableEvents(vmb, db) {
  return vmb.send(request(0x04, db, sensor(1), vmb.nextSeq(), [0x03, 0, 0, 0, 0]));
}
const SETTLE_NS = 25e6;

const pinChanges = (vmb, src) => vmb.events.filter((e) => e.bytes[0] === src && e.bytes[1] === 0x01);
// The edges the pin_change events of board `src` carry: rising + falling counts of each
// 5-byte payload (an event carries the edges its pin made while its previous event waited),
// 1 for a level-only payload.
const edgesCarried = (vmb, src) =>
  pinChanges(vmb, src).reduce((n, e) => {
    const b = e.bytes;
    return n + (b[5] === 5 ? (b[7] | (b[8] << 8)) + (b[9] | (b[10] << 8)) : 1);
  }, 0);

export default [
  {
    name: 'identify',
    about: 'identify and ping db-pico 9 (the reply to identify is 13 bytes)',
    run(ctx) {
      const { vmb } = setup(ctx);
      const id = ask(vmb, 9, 0x01, 0, [], 13);
      ctx.check('identify answered ok with its sequence number', id.reply && id.reply.seq === id.seq && id.reply.status === 0, JSON.stringify(id.read));
      const p = id.reply?.payload ?? [];
      ctx.check('identity: protocol 1, board pico (3), 3 sensor and 3 actuator ports, 12-bit ADC', p[0] === 1 && p[4] === 3 && p[5] === 3 && p[6] === 3 && p[9] === 12, JSON.stringify(p));
      const ping = ask(vmb, 9, 0x00, 0, [], 3);
      ctx.check('ping answered', ping.reply && ping.reply.seq === ping.seq && ping.reply.status === 0);
      ctx.check('boot event received', vmb.events.some((e) => e.bytes[0] === 9 && e.bytes[1] === 0x07));
    },
  },
  {
    name: 'long-reply',
    about: 'replies over 16 bytes (issue 16 defect 1): diagnostics (31 bytes), a batch of two identify (27 bytes), then a full scan',
    run(ctx) {
      const { vmb } = setup(ctx);
      // Make a counter beyond byte 16 non-zero: one event sent (events_sent is bytes 16..17).
      enableEvents(vmb, 9);
      vmb.rig.run(vmb.rig.now() + SETTLE_NS);
      vmb.rig.chips[0].setPin(S1A, 1);
      vmb.rig.run(vmb.rig.now() + 10e6);
      const d = ask(vmb, 9, 0x05, 0, [], 31);
      const ok = d.reply && d.reply.seq === d.seq && d.reply.status === 0 && d.reply.payload.length === 28;
      const p = d.reply?.payload ?? [];
      const u16 = (i) => p[i] | (p[i + 1] << 8);
      ctx.check('read_diagnostics: 31 bytes, none lost (no 0xFF from byte 17 on)', ok && d.read.slice(16).every((b) => b !== 0xff),
        d.read ? d.read.map((b) => b.toString(16).padStart(2, '0')).join(' ') : 'no reply');
      // events_sent counts every event delivered: the boot event and the pin change.
      const sent = vmb.events.filter((e) => e.bytes[0] === 9).length;
      ctx.check(`events_sent counts the events the MB received (${sent}: boot, pin change)`, ok && sent === 2 && u16(16) === sent, `events_sent=${u16(16)}`);
      const b = ask(vmb, 9, 0x50, 0, [0x01, 0, 0, 0x01, 0, 0], 31);
      const bp = b.reply?.payload ?? [];
      ctx.check('batch of two identify: both results whole (27-byte reply)', b.reply && b.reply.seq === b.seq && bp.length === 24 && bp[12] === 0 && bp[13] === 10 && bp[14 + 4] === 3,
        b.read ? b.read.map((x) => x.toString(16).padStart(2, '0')).join(' ') : 'no reply');
      const s = ask(vmb, 9, 0x60, 0, [], 22);
      ctx.check('full scan answered (3 ports)', s.reply && s.reply.seq === s.seq && s.reply.payload[0] === 3, JSON.stringify(s.read));
      const after = ask(vmb, 9, 0x00, 0, [], 3);
      ctx.check('the next request is answered too', after.reply && after.reply.seq === after.seq);
    },
  },
  {
    name: 'short-reply',
    about: 'issue 11 item 1: a reply shorter than the read leaves padding in the TX FIFO; the next reads must still be answered',
    run(ctx) {
      const { vmb } = setup(ctx);
      let answered = 0;
      const n = 6;
      for (let i = 0; i < n; i++) {
        // Unknown function: a 3-byte error reply, read as 5 (an analog read's size).
        ask(vmb, 9, 0x70, 0, [], 5);
        const a = ask(vmb, 9, 0x30, sensor(1), [], 5);
        if (a.reply && a.reply.seq === a.seq && a.reply.status === 0) answered++;
      }
      ctx.check(`${n} analog reads after ${n} short replies all answered with their sequence numbers`, answered === n, `${answered} of ${n}`);
    },
  },
  {
    name: 'stop-gap',
    about: 'issue 16 defect 2: a pin event must go out while the MB polls, whatever the gap before its STOP (sweep)',
    run(ctx) {
      for (const gapUs of [5, 18, 19, 30, 60]) {
        const { rig, vmb, dbs } = setup(ctx, { stopGapNs: gapUs * 1000 });
        enableEvents(vmb, 9);
        const edgeAt = rig.now() + SETTLE_NS;
        const end = edgeAt + 100e6;
        let edged = false;
        while (rig.now() < end && !pinChanges(vmb, 9).length) {
          if (!edged && rig.now() >= edgeAt) { dbs[0].setPin(S1A, 1); edged = true; }
          ask(vmb, 9, 0x30, sensor(1), [], 5); // write-then-read, as the MB polls
          rig.run(rig.now() + 1e6);
        }
        const ev = pinChanges(vmb, 9)[0];
        ctx.check(`STOP gap ${gapUs} µs: pin event delivered within 100 ms of polling`, ev, ev ? `after ${((ev.t - edgeAt) / 1e6).toFixed(2)} ms` : 'never');
      }
    },
  },
  {
    name: 'event-latency',
    about: 'a pin edge on db-pico 9 to its event at the MB, with the MB idle (no polling), at 100 kHz, 400 kHz and 1 MHz (db-pico built for each): edge-to-event latency',
    run(ctx) {
      const buses = [[100000, ctx.dbElf], ...Object.entries(ctx.dbAt ?? {}).map(([hz, elf]) => [Number(hz), elf])];
      for (const [hz, dbElf] of buses) {
        const { rig, vmb, dbs } = setup(ctx, { hz, dbElf });
        enableEvents(vmb, 9);
        rig.run(rig.now() + SETTLE_NS);
        const lat = [];
        for (let i = 0; i < 4; i++) {
          const before = pinChanges(vmb, 9).length;
          const t = rig.now();
          dbs[0].setPin(S1A, i % 2 === 0);
          rig.run(t + 20e6, () => pinChanges(vmb, 9).length > before);
          const ev = pinChanges(vmb, 9)[before];
          if (ev) lat.push((ev.t - t) / 1e3);
          // Isolated edges: firmware-db reports a pin at most once per sample interval (10 ms).
          rig.run(rig.now() + 15e6);
        }
        const k = `${hz / 1000} kHz`;
        ctx.check(`${k}: 4 edges, 4 events`, lat.length === 4, lat.map((l) => `${l.toFixed(0)} µs`).join(', '));
        ctx.figure(`edge to event at the MB, ${k}, MB idle, isolated edges (µs, min/max; db-pico latches edges, looks every 200 µs)`, lat.length ? `${Math.min(...lat).toFixed(0)} / ${Math.max(...lat).toFixed(0)}` : 'none');
      }
    },
  },
  {
    name: 'short-pulse',
    about: 'a 20 µs pulse on db-pico 9, far shorter than its 10 ms sample interval, becomes a pin_change event with one rising and one falling edge (hardware edge latches)',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx);
      enableEvents(vmb, 9);
      rig.run(rig.now() + SETTLE_NS);
      const before = pinChanges(vmb, 9).length;
      const t = rig.now();
      dbs[0].setPin(S1A, true);
      rig.run(t + 20e3);
      dbs[0].setPin(S1A, false);
      rig.run(t + 30e6, () => pinChanges(vmb, 9).length > before);
      const ev = pinChanges(vmb, 9)[before];
      const b = ev?.bytes ?? [];
      const u16 = (i) => b[i] | (b[i + 1] << 8);
      ctx.check('one pin_change event: level 0, 1 rising and 1 falling edge', !!ev && b[5] === 5 && b[6] === 0 && u16(7) === 1 && u16(9) === 1,
        ev ? `${b.map((x) => x.toString(16).padStart(2, '0')).join(' ')} after ${((ev.t - t) / 1e3).toFixed(0)} µs` : 'no event in 30 ms');
    },
  },
  {
    name: 'pulse-in',
    about: 'issue 11 item 9 (Pico): pulse-in measures a 3 ms pulse; a pulse-in that timed out must not leave its edge armed, so the next one (falling) is not started by a rising edge',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx);
      const deferred = (seq) => vmb.events.find((e) => e.bytes[0] === 9 && e.bytes[1] === 0x03 && e.bytes[3] === seq);
      const width = (ev) => ev && ev.bytes[4] === 0 && ev.bytes[5] === 4 ? ev.bytes[6] | (ev.bytes[7] << 8) | (ev.bytes[8] << 16) | (ev.bytes[9] << 24) : null;
      // Pin low. 1: a high pulse of 3 ms, 2 ms after the request.
      let r = ask(vmb, 9, 0x13, sensor(1), [100, 0], 3);
      let t = rig.now();
      rig.run(t + 2e6); dbs[0].setPin(S1A, true);
      rig.run(t + 5e6); dbs[0].setPin(S1A, false);
      rig.run(t + 30e6, () => deferred(r.seq));
      let w = width(deferred(r.seq));
      ctx.check('pulse_in_rising: 3000 µs (±100)', r.reply?.status === 1 && w !== null && Math.abs(w - 3000) <= 100, `reply status ${r.reply?.status}, width ${w} µs`);
      // 2: a rising pulse-in that times out (10 ms, no edge).
      r = ask(vmb, 9, 0x13, sensor(1), [10, 0], 3);
      rig.run(rig.now() + 30e6, () => deferred(r.seq));
      const timedOut = deferred(r.seq);
      ctx.check('a pulse-in without a pulse ends with status timeout', !!timedOut && timedOut.bytes[4] === 0x0c, timedOut ? `status ${timedOut.bytes[4]}` : 'no deferred reply');
      // 3: a falling pulse-in; the pin rises at +2 ms (not its edge), falls at +5 ms, rises at +8 ms: 3 ms.
      r = ask(vmb, 9, 0x14, sensor(1), [100, 0], 3);
      t = rig.now();
      rig.run(t + 2e6); dbs[0].setPin(S1A, true);
      rig.run(t + 5e6); dbs[0].setPin(S1A, false);
      rig.run(t + 8e6); dbs[0].setPin(S1A, true);
      rig.run(t + 30e6, () => deferred(r.seq));
      w = width(deferred(r.seq));
      ctx.check('pulse_in_falling after the timeout: 3000 µs (±100), not started by the rising edge', w !== null && Math.abs(w - 3000) <= 100, `width ${w} µs`);
      dbs[0].setPin(S1A, false);
    },
  },
  {
    name: 'two-dbs',
    about: 'db-pico 9 and 10 (jumper 0) push events while the MB polls both',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx, { dbs: [9, 10] });
      enableEvents(vmb, 9);
      enableEvents(vmb, 10);
      rig.run(rig.now() + SETTLE_NS);
      const edges = 6;
      const t0 = rig.now();
      for (let step = 0; step < 150; step++) {
        const ms = (rig.now() - t0) / 1e6;
        const k = Math.floor(ms / 10);
        if (k < edges) for (const d of dbs) d.setPin(S1A, k % 2 === 0);
        ask(vmb, step % 2 ? 9 : 10, 0x30, sensor(1), [], 5);
        rig.run(rig.now() + 0.5e6);
      }
      rig.run(rig.now() + 30e6);
      const n9 = edgesCarried(vmb, 9), n10 = edgesCarried(vmb, 10);
      const e9 = pinChanges(vmb, 9).length, e10 = pinChanges(vmb, 10).length;
      ctx.check('every edge of DB 9 arrived in its events', n9 === edges, `${n9} of ${edges} in ${e9} events`);
      ctx.check('every edge of DB 10 arrived in its events', n10 === edges, `${n10} of ${edges} in ${e10} events`);
      const arb = rig.bus.transfers.filter((t) => t.parts[0].addr === 0x08).length;
      ctx.figure('two-dbs: event transfers on the bus', arb);
    },
  },
  {
    name: 'db-reset',
    about: 'db-pico 9 power-cycled in the middle of a transfer: the MB sees an error, not a hang; the DB boots and answers',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx);
      // A 31-byte diagnostics read; the DB goes away after a few bytes.
      vmb.start(9, request(0x05, 9, 0, vmb.nextSeq()), 31);
      rig.run(rig.now() + 0.8e6);
      const fresh = rig.powerCycle(dbs[0]);
      rig.run(rig.now() + 20e6, () => vmb.result !== null);
      const r = vmb.result;
      ctx.check('the interrupted read ends (bytes after the reset read 0xFF)', r && r.read.length === 31 && r.read[30] === 0xff, r ? r.read.map((b) => b.toString(16)).join(' ') : 'hung');
      rig.run(rig.now() + 10e6);
      ctx.check('the DB boots again and sends its boot event', vmb.events.filter((e) => e.bytes[0] === 9 && e.bytes[1] === 0x07).length === 2);
      const id = ask(vmb, 9, 0x01, 0, [], 13);
      ctx.check('and answers identify', id.reply && id.reply.seq === id.seq && id.reply.status === 0);
      void fresh;
    },
  },
  {
    name: 'split-write',
    about: 'issue 11 item 4: a write arriving right after a write-then-read must not be split by a stale STOP_DET (1 MHz MB)',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx, { hz: 1000000 });
      let ok = 0;
      const n = 6;
      for (let i = 0; i < n; i++) {
        ask(vmb, 9, 0x30, sensor(1), [], 5);
        vmb.send(request(i % 2 ? 0x11 : 0x12, 9, actuator(1), vmb.nextSeq())); // io high / low A1.A
        rig.run(rig.now() + 2e6);
        if (dbs[0].pinState(4) === (i % 2 ? 'low' : 'high')) ok++;
      }
      ctx.check(`${n} output writes right after a read all applied`, ok === n, `${ok} of ${n}`);
      const d = ask(vmb, 9, 0x05, 0, [], 31);
      const p = d.reply?.payload ?? [];
      ctx.check('no bad_length counted', d.reply && (p[2] | (p[3] << 8)) === 0, `bad_length=${p[2] | (p[3] << 8)}`);
    },
  },
  {
    name: 'abort-no-stop',
    about: 'issue 11 item 5 (Pico part): the MB\'s block is reset in the middle of a write to DB 9 (no STOP); DB 9 must still deliver its next event',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx);
      enableEvents(vmb, 9);
      rig.run(rig.now() + SETTLE_NS);
      vmb.start(9, [0x12, 9, 0, 1], 0);
      rig.run(rig.now() + 0.15e6); // address and first byte on the wire
      vmb.ctrl.resetBlock();
      vmb.setHz(100000);
      vmb.job = null;
      const t = rig.now();
      dbs[0].setPin(S1A, 1);
      rig.run(t + 50e6, () => pinChanges(vmb, 9).length > 0);
      const ev = pinChanges(vmb, 9)[0];
      ctx.check('the event is delivered without any other traffic', ev, ev ? `after ${((ev.t - t) / 1e6).toFixed(2)} ms` : 'not in 50 ms');
    },
  },
];
