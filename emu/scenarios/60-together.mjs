// Boards that act together (issue 27 items 3 and 4) on the emulated Pico pair: two db-pico
// (DB 9 and 10) against the scripted motherboard (lib/vmb.js), which writes the general calls
// (`sample`, `apply`, always with their check over the address byte 0x00) and does the plain
// reads, as firmware-mb's sweep and together do. They run the shipping db-pico, which is
// built with `together` (`cargo xtask size`'s build).
import { VirtualMb, request, actuator, parseReply } from '../lib/vmb.js';

const JUMPERS_OPEN = { 20: 1, 21: 1, 22: 1 };
const S1A = 14; // GP14: sensor port 1 pin A
const A1A = 4; // GP4: actuator port 1 pin A

function crc8(bytes) {
  let c = 0;
  for (const b of bytes) {
    c ^= b;
    for (let i = 0; i < 8; i++) c = c & 0x80 ? ((c << 1) ^ 0x07) & 0xff : (c << 1) & 0xff;
  }
  return c;
}

function crc16(bytes) {
  let c = 0xffff;
  for (const b of bytes) {
    c ^= b << 8;
    for (let i = 0; i < 8; i++) c = c & 0x8000 ? ((c << 1) ^ 0x1021) & 0xffff : (c << 1) & 0xffff;
  }
  return c;
}

/** A general-call frame (byte 1 = 0) with its PEC byte over the address byte 0x00. */
const general = (fnOp, seq) => {
  const f = [fnOp, 0x00, 0x00, seq];
  return [...f, crc8([0x00, ...f])];
};

/**
 * The reply to `sample` of a board of `ports` sensor ports read from `db` (seq, status, LEN,
 * levels and 12-bit packed values, CRC-16): checked and decoded, or null.
 */
function sweepFrame(db, ports, read) {
  const payload = 2 + Math.ceil((3 * ports) / 2);
  const len = 3 + payload + 2;
  if (!read || read.length < len || read[2] !== payload) return null;
  const f = read.slice(0, len - 2);
  const crc = read[len - 2] | (read[len - 1] << 8);
  if (crc16([(db << 1) | 1, ...f]) !== crc) return null;
  const analog = [];
  for (let i = 0; i < ports; i++) {
    const bit = 12 * i, k = bit >> 3;
    const word = f[5 + k] | (f[6 + k] << 8) | ((f[7 + k] ?? 0) << 16);
    analog.push((word >> (bit % 8)) & 0xfff);
  }
  return { seq: f[0], status: f[1], digital: f[3] | (f[4] << 8), analog };
}

function setup(ctx, hz, elf) {
  const rig = ctx.rig({});
  const vmb = new VirtualMb(rig, { hz });
  const dbs = [9, 10].map((a) =>
    rig.addChip(`db${String(a).padStart(2, '0')}`, elf, {
      // Jumper 0 fitted (low) adds 1 to the base address 9.
      inputs: { ...JUMPERS_OPEN, 20: a === 10 ? 0 : 1, [S1A]: a === 10 ? 1 : 0 },
      watch: [A1A],
    }));
  rig.run(5e6); // boot (and the boot events)
  return { rig, vmb, dbs };
}

const busTime = (vmb, from) => vmb.rig.bus.transfers.filter((t) => t.t0 >= from).reduce((s, t) => s + (t.t1 - t.t0), 0);

export default [
  {
    name: 'sweep',
    about: 'DB 9 and DB 10 (the shipping db-pico) sample their sensor ports on one general call (`sample`), then each is read with a plain read: its reply (CRC-16, the sample\'s sequence number) holds what a `scan` of the same board reads',
    run(ctx) {
      const { rig, vmb } = setup(ctx, 100000, ctx.dbElf);
      const t0 = rig.now();
      const seq = vmb.nextSeq();
      const s = vmb.transact(0x00, general(0x80, seq));
      ctx.check('the general call is acknowledged', s && s.ok, JSON.stringify(s));
      const frames = [9, 10].map((db) => {
        const r = vmb.transact(db, [], 12);
        return r && r.ok ? sweepFrame(db, 3, r.read) : null;
      });
      const sweepNs = busTime(vmb, t0);
      ctx.check('both sweep frames: CRC-16 valid, the sample\'s sequence number, status ok',
        frames.every((f) => f && f.seq === seq && f.status === 0), JSON.stringify(frames));
      // S1.A is high on DB 10 only (its input pin set), low on DB 9.
      ctx.check('S1.A as wired: low on DB 9, high on DB 10',
        frames[0] && frames[1] && (frames[0].digital & 1) === 0 && (frames[1].digital & 1) === 1, JSON.stringify(frames));
      // A scan of each, for comparison: the same levels and values.
      const scans = [9, 10].map((db) => {
        const q = vmb.nextSeq();
        const read = vmb.ask(request(0x60, db, 0, q, []), 3 + 9);
        return parseReply(read);
      });
      const same = scans.every((r, i) => {
        const f = frames[i];
        if (!r || !f || r.payload.length !== 9) return false;
        const p = r.payload;
        const analog = [0, 1, 2].map((k) => p[3 + 2 * k] | (p[4 + 2 * k] << 8));
        return p[0] === 3 && (p[1] | (p[2] << 8)) === f.digital && analog.every((a, k) => a === f.analog[k]);
      });
      ctx.check('each sweep frame holds what a scan of the board reads', same, JSON.stringify({ frames, scans }));
      // Read again: nothing held any more (a reply is given once).
      const again = vmb.transact(9, [], 3);
      ctx.check('the reply is given once: the next plain read is no_request', again && again.read[1] === 0x0d, JSON.stringify(again));
      ctx.figure('sweep of 2 db-pico at 100 kHz: bus time of the sample and both reads (µs)', (sweepNs / 1e3).toFixed(1));
    },
  },
  {
    name: 'together',
    about: 'HIGH on A1.A staged on DB 9 and DB 10 (read back ok), then one general-call `apply`: both pins rise within 50 µs of each other, and each board confirms with its status reply; a stage that never gets its apply is dropped after 100 ms with a `rejected` event (timeout)',
    run(ctx) {
      const { rig, vmb, dbs } = setup(ctx, 400000, ctx.dbElf);
      const item = [0x12, actuator(1, 'A'), 0x00];
      const staged = [9, 10].map((db) => {
        const q = vmb.nextSeq();
        const r = parseReply(vmb.ask(request(0x90, db, 0, q, item), 3));
        return r && r.seq === q && r.status === 0;
      });
      ctx.check('both stages read back ok', staged.every(Boolean), JSON.stringify(staged));
      const tStaged = rig.now();
      rig.run(tStaged + 2e6);
      ctx.check('nothing moved before the apply', dbs.every((c) => c.pinState(A1A) === 'low'),
        dbs.map((c) => c.pinState(A1A)).join(','));
      const seq = vmb.nextSeq();
      const tApply = rig.now();
      const a = vmb.transact(0x00, general(0x81, seq));
      ctx.check('the apply is acknowledged', a && a.ok, JSON.stringify(a));
      rig.run(rig.now() + 2e6);
      const rise = dbs.map((c) => c.pinLog.find((p) => p.pin === A1A && p.t >= tApply && p.v === 'high'));
      const ok = rise.every(Boolean);
      const apart = ok ? Math.abs(rise[0].t - rise[1].t) : NaN;
      ctx.check('A1.A rose on both boards within 50 µs of each other', ok && apart <= 50e3, JSON.stringify(rise));
      const confirm = [9, 10].map((db) => {
        const r = vmb.transact(db, [], 4);
        const p = r && r.ok ? parseReply(r.read) : null;
        // Always with its PEC byte (a general call's reply).
        return p && p.seq === seq && p.status === 0 && r.read[3] === crc8([(db << 1) | 1, ...r.read.slice(0, 3)]);
      });
      ctx.check('each board confirms the apply (its sequence number, ok)', confirm.every(Boolean), JSON.stringify(confirm));
      // A stage without its apply: dropped after 100 ms, reported.
      const q = vmb.nextSeq();
      vmb.send(request(0x90, 9, 0, q, [0x11, actuator(1, 'A'), 0x00]));
      rig.run(rig.now() + 150e6);
      const rejected = vmb.events.find((e) => e.bytes[0] === 9 && e.bytes[1] === 0x05 && e.bytes[3] === q);
      ctx.check('the unapplied stage is dropped: a rejected event with its sequence number, status timeout',
        rejected && rejected.bytes[4] === 0x0c, JSON.stringify(vmb.events.map((e) => e.bytes)));
      ctx.check('and A1.A stays high', dbs[0].pinState(A1A) === 'high');
      ctx.figure('together on 2 db-pico at 400 kHz: A1.A edges apart after one general-call apply (µs)', (apart / 1e3).toFixed(2));
      ctx.figure('together on 2 db-pico at 400 kHz: from the apply\'s START to the later A1.A edge (µs)',
        ok ? ((Math.max(rise[0].t, rise[1].t) - tApply) / 1e3).toFixed(1) : 'NaN');
    },
  },
];
