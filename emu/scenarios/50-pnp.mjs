// Plug and play on the emulated Pico pair: two db-pico from one image with no address override
// (`target/emu/db-pico-pnp`), each with its own flash unique ID, and mb-pico-pnp, whose robot
// waits for two boards and toggles actuator port 1, pin A (GP4) on each every 50 ms. And the
// address record in the Pico's flash (our own flash driver, `x10_boards::pico::PicoFlash`): a
// scripted motherboard moves a board while the power is cut at instants around the record's
// write.
import { VirtualMb, request, parseReply } from '../lib/vmb.js';

const PIN_A1_A = 4;
/** Where db-pico keeps its address: the last two 4 KiB sectors of the 2 MiB flash. */
const RECORD = 0x1fe000;
const SECTOR = 4096;
const UNADDRESSED = 0x77;

/** The addresses a DB logged at each of its starts ("... on a Pico at 0xNN ..."). */
function starts(lines) {
  return lines.map((l) => /daughterboard on a Pico at (0x[0-9a-f]+)/.exec(l)).filter(Boolean).map((m) => Number(m[1]));
}

/** The 8 bytes of an x10-store slot holding `value` with sequence number `seq`. */
const slot = (value, seq) => [0x58, value, seq & 0xff, seq >> 8, 0xa7, ~value & 0xff, ~seq & 0xff, (~seq >> 8) & 0xff];

/** The value of the record in `nor`'s array (the newest valid slot of the two sectors), or null. */
function recordValue(nor) {
  let best = null;
  for (let a = RECORD; a < RECORD + 2 * SECTOR; a += 8) {
    const b = nor.data.subarray(a, a + 8);
    if (b[0] !== 0x58 || [0, 1, 2, 3].some((i) => (b[i] ^ b[i + 4]) !== 0xff)) continue;
    const seq = b[2] | (b[3] << 8);
    if (!best || ((seq - best.seq) & 0xffff) < 0x8000) best = { seq, value: b[1] };
  }
  return best ? best.value : null;
}

/** The instants (ns) at which a watched pin changed. */
function toggles(chip, pin, from = 0) {
  return chip.pinLog.filter((e) => e.pin === pin && e.t >= from);
}

export default [
  {
    name: 'plug-and-play',
    resets: true,
    about: 'two db-pico from one image (no address override) start unaddressed at 0x77, announce themselves, are given two distinct addresses by mb-pico-pnp, keep them in their flash and restart there; its robot then drives both (A1.A toggling); after a software reset each comes back at its address, and after a power cycle too (the address read back from the flash record)',
    async run(ctx) {
      if (!ctx.dbPnpElf || !ctx.mbPnpElf) {
        ctx.check('the plug-and-play images were given (--db-pnp, --mb-pnp)', false);
        return;
      }
      const rig = ctx.rig();
      const mb = rig.addChip('mb', ctx.mbPnpElf, {});
      let dbs = [
        rig.addChip('dba', ctx.dbPnpElf, { watch: [PIN_A1_A] }),
        rig.addChip('dbb', ctx.dbPnpElf, { watch: [PIN_A1_A] }),
      ];
      // Each DB's log across its resets (and, carried over by hand, its power cycle).
      const logOf = (c) => ctx.defmt(c).map((l) => l.text);
      const wall0 = Date.now();
      rig.run(1000e6);
      dbs = rig.chips.slice(1);
      const first = dbs.map((c) => starts(logOf(c)));
      ctx.check('both DBs start unaddressed (0x77)', first.every((s) => s[0] === UNADDRESSED), JSON.stringify(first));
      const given = first.map((s) => s[s.length - 1]);
      ctx.check('each restarts at an address it was given, the two distinct',
        given.every((a) => a !== UNADDRESSED && a >= 0x08 && a < 0x77) && given[0] !== given[1], JSON.stringify(first));
      const mbLog = ctx.defmt(mb).map((l) => l.text).join('\n');
      ctx.check('the MB logs its robot program', /robot program TwoBoards/.test(mbLog));
      const moved = dbs.map((c) => (c.resets ?? []).filter((r) => r.kind === 'sysreset').length);
      ctx.check('each DB restarted once (software reset) to move', moved.every((n) => n === 1), JSON.stringify(moved));
      const lastStart = Math.max(...dbs.map((c) => (c.resets ?? []).map((r) => r.t).reduce((a, b) => Math.max(a, b), 0)));
      const driven = dbs.map((c) => toggles(c, PIN_A1_A, lastStart).length);
      ctx.check('the robot drives both boards after they moved (A1.A toggles on each)', driven.every((n) => n >= 4), JSON.stringify(driven));
      ctx.figure('plug and play: power-up to both boards addressed and driven (first A1.A toggle on each) (ms)',
        (Math.max(...dbs.map((c) => (toggles(c, PIN_A1_A, lastStart)[0] ?? { t: NaN }).t)) / 1e6).toFixed(1));

      // Each kept its address in its flash record, through the real driver (pico::PicoFlash:
      // the boot ROM's program, called from RAM): a page program in the record's sectors.
      const kept = dbs.map((c) => recordValue(c.nor));
      const programs = dbs.map((c) => c.nor.ops.filter((o) => o.cmd === 0x02 && o.addr >= RECORD && o.addr < RECORD + 2 * SECTOR).length);
      ctx.check('each DB programmed its address into its flash record, once',
        JSON.stringify(kept) === JSON.stringify(given) && programs.every((n) => n === 1), JSON.stringify({ kept, programs }));

      // A software reset of each: it comes back at the same address.
      const t1 = rig.now();
      for (const c of dbs) c.rp.sysResetRequested = { t: t1 };
      rig.run(t1 + 300e6);
      dbs = rig.chips.slice(1);
      const all = dbs.map((c) => starts(logOf(c)));
      const afterReset = all.map((s) => s[s.length - 1]);
      ctx.check('after a software reset each DB starts at its address again (a third start)',
        JSON.stringify(afterReset) === JSON.stringify(given) && all.every((s) => s.length === 3), JSON.stringify(all));

      // A power cycle of board A: SRAM and every register (SCRATCH included) are lost, the flash
      // is kept: it starts at its address at once, read from its record.
      const t2 = rig.now();
      const old = dbs[0];
      old.readRtt();
      const fresh = rig.powerCycle(old);
      fresh.defmt = old.defmt; // one log across the power cycle
      rig.run(t2 + 1000e6);
      dbs = rig.chips.slice(1);
      const a = starts(logOf(dbs[0]));
      ctx.check('after a power cycle board A starts at its address at once (kept in flash; no start at 0x77)',
        a.length === 4 && a[3] === given[0], JSON.stringify(a));
      const drivenAgain = toggles(rig.chips[1], PIN_A1_A, t2 + 500e6).length;
      ctx.check('and the robot drives it again', drivenAgain >= 2, String(drivenAgain));
      ctx.figure('simulated s per wall s (3 chips, plug and play)', (2.3 / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  },
  {
    name: 'address-record',
    resets: true,
    about: 'issue 24 on the emulated Pico: db-pico (plug and play) keeps its address in its flash through our own driver (pico::PicoFlash, the boot ROM called from RAM): a board whose record holds 0x20 starts there; a scripted MB moves it to 0x21 (set_address); the power is cut at instants before, during and after the record\'s write, and each time the board comes back at 0x20 or 0x21, never without an address',
    async run(ctx) {
      if (!ctx.dbPnpElf) {
        ctx.check('the plug-and-play image was given (--db-pnp)', false);
        return;
      }
      const FROM = 0x20, TO = 0x21;
      const logOf = (c) => ctx.defmt(c).map((l) => l.text);
      // A rig with the scripted MB and one db-pico whose record holds FROM, booted.
      const setup = () => {
        const rig = ctx.rig();
        const vmb = new VirtualMb(rig);
        const db = rig.addChip('db', ctx.dbPnpElf, {});
        db.nor.data.set(slot(FROM, 0), RECORD);
        rig.run(20e6);
        return { rig, vmb, nor: db.nor };
      };
      const moveFrame = (vmb) => request(0x09, FROM, 0, vmb.nextSeq(), [TO]);

      // Without a cut: set_address answered ok, the slot programmed, the board at TO.
      let { rig, vmb, nor } = setup();
      const booted = starts(logOf(rig.chips[0]));
      ctx.check('a board whose record holds 0x20 starts there', JSON.stringify(booted) === JSON.stringify([FROM]), JSON.stringify(booted));
      // Its boot event carries the unique ID the driver read from the flash (command 0x4B
      // through the SSI, from RAM): the rig's flash model's ID for this chip.
      const uid = Array.from(nor.uid);
      const hex = (b) => b.map((x) => x.toString(16).padStart(2, '0')).join('');
      const boot = vmb.events.find((e) => e.bytes[0] === FROM);
      ctx.check('its boot event carries its flash\'s unique ID (read with 0x4B by the driver)',
        !!boot && hex(boot.bytes).includes(hex(uid)), `${boot ? hex(boot.bytes) : 'no event'} / ${hex(uid)}`);
      const tAsk = rig.now();
      const reply = parseReply(vmb.ask(moveFrame(vmb), 3));
      rig.run(tAsk + 30e6);
      const prog = nor.ops.filter((o) => o.cmd === 0x02 && o.addr >= RECORD);
      const moved = starts(logOf(rig.chips[0]));
      // The driver programs the slot's whole 256-byte page, 0xFF but for the slot's 8 bytes.
      const second = Array.from(nor.data.subarray(RECORD + 8, RECORD + 16));
      ctx.check('set_address 0x21 is answered ok, one page program writes the second slot (58 21 01 00 A7 DE FE FF), and the board restarts at 0x21',
        reply?.status === 0 && prog.length === 1 && prog[0].addr === RECORD && JSON.stringify(second) === JSON.stringify(slot(TO, 1))
          && recordValue(nor) === TO
          && JSON.stringify(moved) === JSON.stringify([FROM, TO]),
        JSON.stringify({ reply, prog: prog.map((o) => o.addr.toString(16)), moved }));
      if (prog.length !== 1) return;
      const tProg = prog[0].t;
      ctx.figure('address record: set_address request to the slot programmed (µs)', ((tProg - tAsk) / 1e3).toFixed(0));

      // The same again, the power cut at each instant (ns from the program command's end: the
      // flash model applies a program when its command ends; x10-store's host tests cut in
      // the middle of one, bit by bit).
      const cuts = [-2e6, -200e3, -5e3, -1e3, 1e3, 100e3, 2e6, 10e6];
      const outcomes = [];
      for (const dt of cuts) {
        ({ rig, vmb, nor } = setup());
        vmb.start(FROM, moveFrame(vmb), 3);
        rig.run(tProg + dt);
        const chip = rig.chips[0];
        chip.readRtt();
        const fresh = rig.powerCycle(chip);
        fresh.defmt = chip.defmt;
        const tCut = rig.now();
        rig.run(tCut + 30e6);
        const s = starts(logOf(rig.chips[0]));
        outcomes.push({ dt, at: s[s.length - 1], record: recordValue(nor) });
      }
      const right = outcomes.every((o) => o.at === (o.dt < 0 ? FROM : TO) && o.record === o.at);
      ctx.check('a power cut before the program leaves 0x20, after it 0x21; the board always starts at the address its record holds',
        right, JSON.stringify(outcomes.map((o) => `${o.dt / 1e3}us:${o.at?.toString(16)}/${o.record?.toString(16)}`)));
    },
  },
];
