#!/usr/bin/env node
// Runs the emulator scenarios (scenarios/*.mjs) on the release Pico images.
//
//   node run.mjs --mb MB_ELF --db DB_ELF [--x10 X10_TOOL] [--out DIR] [SCENARIO...]
//
// `cargo xtask emu [SCENARIO]` builds the images and calls this. Each scenario prints its
// checks (PASS/FAIL), its figures, and writes its bus trace (decoded with `x10 decode` when
// --x10 is given) and the chips' defmt logs to DIR/SCENARIO.txt. Exit status 1 when a check
// failed.
import { spawnSync } from 'node:child_process';
import { mkdirSync, writeFileSync, readdirSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { Rig } from './lib/rig.js';
import { figuresBlock } from './lib/figures.js';

const here = dirname(fileURLToPath(import.meta.url));
const args = process.argv.slice(2);
const opt = (name) => {
  const i = args.indexOf(name);
  if (i < 0) return null;
  const v = args[i + 1];
  args.splice(i, 2);
  return v;
};
const mbElf = opt('--mb');
const dbElf = opt('--db');
const mbDoorbellElf = opt('--mb-doorbell');
// The flash test image (emu/fw-flash), for the `flash` scenario.
const fwFlashElf = opt('--fw-flash');
// Plug and play: db-pico without an address override, and the motherboard that drives two.
const dbPnpElf = opt('--db-pnp');
const mbPnpElf = opt('--mb-pnp');
// The Pico's bootloader (boot-pico) and db-pico built into its ACTIVE slot, as 0.1.0 and 2.0.0.
const bootElf = opt('--boot');
const dbSlotElf = opt('--db-slot');
const dbSlotV2Elf = opt('--db-slot-v2');
// mb-pico carrying db-pico 2.0.0 (X10_CARRY): the `update` scenario.
const mbCarryElf = opt('--mb-carry');
// db-pico built for faster buses: --db-at HZ=ELF, any number of times.
const dbAt = {};
for (let v = opt('--db-at'); v; v = opt('--db-at')) {
  const [hz, path] = v.split('=');
  dbAt[Number(hz)] = path;
}
// The update at faster buses: --mb-carry-at, --db-slot-at, --db-slot-v2-at HZ=ELF (mb-pico
// carrying 2.0.0, db-pico 0.1.0 and 2.0.0 in ACTIVE, each built for that bus).
const updateAt = {};
for (const [flag, key] of [['--mb-carry-at', 'mbCarry'], ['--db-slot-at', 'dbSlot'], ['--db-slot-v2-at', 'dbSlotV2']]) {
  for (let v = opt(flag); v; v = opt(flag)) {
    const i = v.indexOf('=');
    const hz = Number(v.slice(0, i));
    updateAt[hz] = { ...updateAt[hz], [key]: v.slice(i + 1) };
  }
}
const x10 = opt('--x10');
const out = opt('--out') ?? join(here, 'out');
const list = args.includes('--list');

const scenarios = [];
for (const f of readdirSync(join(here, 'scenarios')).filter((f) => f.endsWith('.mjs')).sort()) {
  const mod = await import(join(here, 'scenarios', f));
  scenarios.push(...mod.default);
}
if (list) {
  for (const s of scenarios) console.log(`${s.name.padEnd(22)} ${s.about}`);
  process.exit(0);
}
if (!mbElf || !dbElf) {
  console.error('usage: node run.mjs --mb MB_ELF --db DB_ELF [--db-at HZ=DB_ELF]... [--mb-doorbell MB_ELF] [--fw-flash ELF] [--db-pnp ELF] [--mb-pnp ELF] [--boot ELF --db-slot ELF --db-slot-v2 ELF --mb-carry ELF] [--mb-carry-at HZ=ELF --db-slot-at HZ=ELF --db-slot-v2-at HZ=ELF]... [--x10 X10] [--out DIR] [SCENARIO...] | --list');
  process.exit(2);
}
const wanted = args.filter((a) => !a.startsWith('--'));
const unknown = wanted.filter((w) => !scenarios.some((s) => s.name === w));
if (unknown.length) {
  console.error(`unknown scenario ${unknown.join(', ')}; known: ${scenarios.map((s) => s.name).join(', ')}`);
  process.exit(2);
}
mkdirSync(out, { recursive: true });

/** defmt frames of a chip decoded by defmt-print (one JSON line per frame). */
export function decodeDefmt(chip) {
  const frames = chip.defmt;
  if (!frames.length) return [];
  const r = spawnSync('defmt-print', ['-e', chip.elf.path, '--json'], { input: Buffer.from(frames.flatMap((f) => f.bytes)) });
  if (r.error) throw new Error(`defmt-print: ${r.error.message} (cargo install defmt-print)`);
  const lines = r.stdout.toString().split('\n').filter((l) => l.startsWith('{') && !l.includes('schema_version'));
  // A lone delimiter (defmt-rtt starts each boot with one) is no frame: each line gets the time
  // of its own frame.
  const timed = frames.filter((f) => f.bytes.length > 1);
  return lines.map((l, i) => {
    let text = l;
    try {
      const j = JSON.parse(l);
      text = `${j.level ?? ''} ${j.data}`.trim();
    } catch { /* printed as is */ }
    return { t: timed[i]?.t ?? NaN, chip: chip.name, text };
  });
}

/** SMBus PEC: CRC-8 (polynomial 0x07) over the address byte and the bytes. */
function pec(bytes) {
  let c = 0;
  for (const b of bytes) {
    c ^= b;
    for (let i = 0; i < 8; i++) c = c & 0x80 ? ((c << 1) ^ 0x07) & 0xff : (c << 1) & 0xff;
  }
  return c;
}

/** CRC-16/IBM-3740 (polynomial 0x1021, initial 0xFFFF): the check of frames over 13 bytes. */
function crc16(bytes) {
  let c = 0xffff;
  for (const b of bytes) {
    c ^= b << 8;
    for (let i = 0; i < 8; i++) c = c & 0x8000 ? ((c << 1) ^ 0x1021) & 0xffff : (c << 1) & 0xffff;
  }
  return c;
}

/** True when `bytes` end in the check of the rest (x10-microcode's pec::strip rule). */
function checked(addrByte, bytes) {
  const n = bytes.length;
  if (n >= 2 && n <= 14) return pec([addrByte, ...bytes.slice(0, -1)]) === bytes[n - 1];
  if (n >= 16) return crc16([addrByte, ...bytes.slice(0, -2)]) === (bytes[n - 2] | (bytes[n - 1] << 8));
  return false;
}

/**
 * The transfers' frames in words, by `x10 decode`. A frame that ends in the check of the rest
 * (its PEC byte, or its CRC-16 when it is longer than 13 bytes) (covering the DB's address for requests and replies, the MB's for events, as
 * docs/protocol.md says) is decoded with `--pec`: frames are grouped by the PEC address they
 * need, one `x10 decode` run per group (a reply is decoded with its request's operation when
 * both are in the same group), and the lines put back in bus order.
 */
function decodeFrames(transfers) {
  const hex = (b) => b.map((x) => x.toString(16).padStart(2, '0')).join('');
  const frames = [];
  for (const tr of transfers) {
    for (const p of tr.parts) {
      if (!p.bytes.length) continue;
      const kind = p.dir === 'r' ? 'reply' : p.addr === 0x08 ? 'event' : 'request';
      // The address byte as on the wire: the DB's (write) for requests, (read) for replies;
      // the MB's (write) for events.
      const addrByte = (p.addr << 1) | (p.dir === 'r' ? 1 : 0);
      const withPec = checked(addrByte, p.bytes);
      frames.push({ line: `${kind}:${hex(p.bytes)}`, group: withPec ? String(p.addr) : '' });
    }
  }
  if (!x10 || !frames.length) return null;
  const text = new Array(frames.length);
  for (const group of new Set(frames.map((f) => f.group))) {
    const idx = frames.map((f, i) => (f.group === group ? i : -1)).filter((i) => i >= 0);
    const args = ['decode', ...(group ? ['--pec', group] : [])];
    const r = spawnSync(x10, args, { input: idx.map((i) => frames[i].line).join('\n') + '\n' });
    // One stdout line per decoded frame, in order; each failure named by its number on stderr.
    const bad = new Map();
    for (const l of r.stderr.toString().split('\n')) {
      const m = /^x10 decode: frame (\d+) /.exec(l);
      if (m) bad.set(Number(m[1]) - 1, l);
    }
    const ok = r.stdout.toString().split('\n').filter((l) => l.length);
    if (ok.length + bad.size !== idx.length) return null;
    let k = 0;
    idx.forEach((frameIndex, j) => { text[frameIndex] = bad.get(j) ?? ok[k++]; });
  }
  return text.join('\n');
}

let failed = 0;
const summary = [];
const results = [];
for (const s of scenarios.filter((s) => !wanted.length || wanted.includes(s.name))) {
  const checks = [];
  const figures = [];
  const rigs = [];
  const ctx = {
    mbElf, dbElf, dbAt, mbDoorbellElf, fwFlashElf, dbPnpElf, mbPnpElf, bootElf, dbSlotElf, dbSlotV2Elf, mbCarryElf, updateAt, out,
    rig(options = {}) { const r = new Rig(options); rigs.push(r); return r; },
    check(name, ok, detail = '') { checks.push({ name, ok: !!ok, detail }); },
    figure(name, value) { figures.push({ name, value }); },
    defmt: decodeDefmt,
    /** Runs the `x10` tool (null when none was given): its stdout, or throws. */
    x10(args) {
      if (!x10) return null;
      const r = spawnSync(x10, args, { maxBuffer: 64 << 20 });
      if (r.status !== 0) throw new Error(`x10 ${args.join(' ')}: ${r.stderr}`);
      return r.stdout.toString();
    },
  };
  const wall0 = Date.now();
  try {
    await s.run(ctx);
  } catch (e) {
    checks.push({ name: 'ran to the end', ok: false, detail: e.stack });
  }
  // Every image runs its watchdog: a reset no scenario asked for (`resets: true`) is a failure.
  const resets = rigs.flatMap((r) => r.chips.flatMap((c) => (c.resets ?? []).map((x) => `${c.name} at ${(x.t / 1e6).toFixed(3)} ms (REASON ${x.reason})`)));
  if (!s.resets) checks.push({ name: 'no watchdog reset', ok: resets.length === 0, detail: resets.join(', ') });
  const wall = (Date.now() - wall0) / 1000;
  const sim = rigs.reduce((a, r) => a + r.t, 0) / 1e9;
  const bad = checks.filter((c) => !c.ok).length;
  // A scenario of a defect not fixed yet is expected to fail (`knownDefect` names it); passing
  // is then an error too, so the mark is removed with the fix.
  const expectedFail = !!s.knownDefect;
  failed += (bad > 0) !== expectedFail ? 1 : 0;
  console.log(`\n== ${s.name}: ${s.about}`);
  if (expectedFail) console.log(`  known defect: ${s.knownDefect}`);
  for (const c of checks) console.log(`  ${c.ok ? 'PASS' : 'FAIL'} ${c.name}${c.detail ? `: ${c.detail}` : ''}`);
  for (const f of figures) console.log(`  figure: ${f.name} = ${f.value}`);
  console.log(`  ${sim.toFixed(3)} simulated s in ${wall.toFixed(1)} wall s`);
  const verdict = expectedFail ? (bad ? 'known defect, fails as expected:' : 'PASSES but is marked as a known defect (remove the mark):') : bad ? 'FAIL' : 'pass';
  summary.push(`${verdict} ${s.name}`);
  results.push({ scenario: s.name, figures });
  // Trace file: bus transfers (raw and decoded) and every chip's log.
  const text = [];
  for (const [i, r] of rigs.entries()) {
    text.push(`# rig ${i + 1}: bus transfers`);
    for (const tr of r.bus.transfers) text.push(r.bus.describe(tr));
    const dec = decodeFrames(r.bus.transfers);
    if (dec) text.push(`# decoded by x10 decode`, dec);
    for (const c of r.chips) {
      text.push(`# ${c.name}: defmt log (virtual ms, line)`);
      for (const l of decodeDefmt(c)) text.push(`${(l.t / 1e6).toFixed(3)} ${l.text}`);
      text.push(`# ${c.name}: pins`, ...c.pinLog.map((p) => `${(p.t / 1e6).toFixed(3)} GP${p.pin} ${p.v}`));
    }
  }
  writeFileSync(join(out, `${s.name}.txt`), text.join('\n') + '\n');
}
console.log(`\n${summary.join('\n')}`);
// The figures of a full run, for docs/emulation.md (lib/figures.js).
if (!wanted.length) writeFileSync(join(out, 'figures.md'), figuresBlock(results));
process.exit(failed ? 1 : 0);
