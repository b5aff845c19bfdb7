// Plug and play on the emulated Pico pair: two db-pico from one image with no address override
// (`target/emu/db-pico-pnp`), each with its own flash unique ID, and mb-pico-pnp, whose robot
// waits for two boards and toggles actuator port 1, pin A (GP4) on each every 50 ms.
const PIN_A1_A = 4;
const UNADDRESSED = 0x77;

/** The addresses a DB logged at each of its starts ("... on a Pico at 0xNN ..."). */
function starts(lines) {
  return lines.map((l) => /daughterboard on a Pico at (0x[0-9a-f]+)/.exec(l)).filter(Boolean).map((m) => Number(m[1]));
}

/** The instants (ns) at which a watched pin changed. */
function toggles(chip, pin, from = 0) {
  return chip.pinLog.filter((e) => e.pin === pin && e.t >= from);
}

export default [
  {
    name: 'plug-and-play',
    resets: true,
    about: 'two db-pico from one image (no address override) start unaddressed at 0x77, announce themselves, are given two distinct addresses by mb-pico-pnp and restart there; its robot then drives both (A1.A toggling); after a software reset each comes back at its address, after a power cycle (the address kept by SCRATCH1 lost) the MB gives the same address back by the unique ID',
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

      // A software reset of each: it comes back at the same address (SCRATCH1 kept).
      const t1 = rig.now();
      for (const c of dbs) c.rp.sysResetRequested = { t: t1 };
      rig.run(t1 + 300e6);
      dbs = rig.chips.slice(1);
      const all = dbs.map((c) => starts(logOf(c)));
      const afterReset = all.map((s) => s[s.length - 1]);
      ctx.check('after a software reset each DB starts at its address again (a third start)',
        JSON.stringify(afterReset) === JSON.stringify(given) && all.every((s) => s.length === 3), JSON.stringify(all));

      // A power cycle of board A: SCRATCH1 is lost, it starts unaddressed and the MB gives the
      // same address back (its directory knows the unique ID).
      const t2 = rig.now();
      const old = dbs[0];
      old.readRtt();
      const fresh = rig.powerCycle(old);
      fresh.defmt = old.defmt; // one log across the power cycle
      rig.run(t2 + 1000e6);
      dbs = rig.chips.slice(1);
      const a = starts(logOf(dbs[0]));
      ctx.check('after a power cycle board A starts unaddressed and gets the same address back',
        a[a.length - 1] === given[0] && a.includes(UNADDRESSED, 2), JSON.stringify(a));
      const drivenAgain = toggles(rig.chips[1], PIN_A1_A, t2 + 500e6).length;
      ctx.check('and the robot drives it again', drivenAgain >= 2, String(drivenAgain));
      ctx.figure('simulated s per wall s (3 chips, plug and play)', (2.3 / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  },
];
