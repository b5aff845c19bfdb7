// Scenarios of the Pico bus adapter (x10-boards/src/pico.rs) against the scripted motherboard
// (lib/vmb.js): db-pico's core held (lib/stall.js) at a chosen moment, to see what a late look
// at the I2C block does; the target's SDA hold time.
import { VirtualMb, request, sensor, actuator, parseReply } from '../lib/vmb.js';
import { INTR } from '../lib/i2c.js';
import { hold, stallWhen } from '../lib/stall.js';

const A1A = 4; // GP4: actuator port 1 pin A
const S1A = 14; // GP14: sensor port 1 pin A

function setup(ctx) {
  const rig = ctx.rig();
  const vmb = new VirtualMb(rig, { hz: 100000 });
  const db = rig.addChip('db09', ctx.dbElf, { inputs: { 20: 1, 21: 1, 22: 1, 14: 0 }, watch: [A1A] });
  rig.run(5e6); // boot (and the boot event)
  return { rig, vmb, db };
}

/** Holds DB 9's core for `ns` from the moment its block reports a read's last byte (RX_DONE). */
const stallAfterRead = (rig, db, ns) => stallWhen(rig, db, () => db.i2c0.rawIntr & INTR.RX_DONE, ns);

export default [
  {
    name: 'late-poll',
    about: 'issue 21 item 5: db-pico\'s core held 2 ms after a reply\'s last byte; meanwhile the MB ends the read, writes an output (ACKed) and starts the next transfer; the output must be applied',
    run(ctx) {
      // 1: the next transfer is a read (no write before it): the output's STOP and the read's
      // are one STOP_DET.
      {
        const { rig, vmb, db } = setup(ctx);
        const s = stallAfterRead(rig, db, 2e6);
        const ping = vmb.ask(request(0x00, 9, 0, vmb.nextSeq()), 3);
        const out = vmb.send(request(0x12, 9, actuator(1), vmb.nextSeq())); // io high A1.A
        const read = vmb.transact(9, [], 3);
        rig.run(rig.now() + 5e6);
        ctx.check('the core was held over the output write', s.at !== null && out && out.t1 < s.at + s.ns, `held at ${s.at} ns, output ended at ${out?.t1} ns`);
        ctx.check('ping answered, output write ACKed, the read after it ended', parseReply(ping) && out?.ok && read?.ok, JSON.stringify({ ping, out: out?.ok, read: read?.ok }));
        ctx.check('an output the MB saw ACKed is applied (A1.A high)', db.pinState(A1A) === 'high', `A1.A ${db.pinState(A1A)}`);
      }
      // 2: two outputs back to back, then the MB is idle.
      {
        const { rig, vmb, db } = setup(ctx);
        stallAfterRead(rig, db, 1.5e6);
        vmb.ask(request(0x00, 9, 0, vmb.nextSeq()), 3);
        const a = vmb.send(request(0x12, 9, actuator(1), vmb.nextSeq())); // high
        const b = vmb.send(request(0x11, 9, actuator(1), vmb.nextSeq())); // low
        const c = vmb.send(request(0x12, 9, actuator(1), vmb.nextSeq())); // high
        rig.run(rig.now() + 30e6);
        const rises = db.pinLog.filter((p) => p.pin === A1A && p.v === 'high').length;
        ctx.check('three outputs ACKed, all applied: A1.A high, low, high', a?.ok && b?.ok && c?.ok && db.pinState(A1A) === 'high' && rises === 2,
          db.pinLog.map((p) => `${(p.t / 1e6).toFixed(3)} ${p.v}`).join(', '));
      }
    },
  },
  {
    name: 'sda-hold',
    about: 'issue 21 item 6: db-pico\'s target holds SDA 300 ns after SCL falls (IC_SDA_HOLD 38 at 125 MHz), also after the block reset that follows a reply the MB read short',
    run(ctx) {
      const { vmb, db } = setup(ctx);
      const hold = () => db.i2c0.readUint32(0x7c) & 0xffff;
      const boot = hold();
      // identify (13 bytes) read as 3: 10 bytes left in the TX FIFO, the block is reset.
      vmb.ask(request(0x01, 9, 0, vmb.nextSeq()), 3);
      const ping = vmb.ask(request(0x00, 9, 0, vmb.nextSeq()), 3);
      ctx.check('after boot, the target: IC_SDA_TX_HOLD 38', boot === 38, `${boot}`);
      ctx.check('after the reset that follows a short read: 38, and the next request answered', hold() === 38 && parseReply(ping)?.status === 0, `${hold()}, ping ${JSON.stringify(ping)}`);
    },
  },
  {
    name: 'pulse-in-latched',
    about: 'issue 21 item 6: pulse-in on a pin with pin-change events; a 20 µs pulse ends while db-pico\'s core is held 200 µs from its start edge: the pulse is measured and the event still reports its rising and its falling edge',
    run(ctx) {
      const { rig, vmb, db } = setup(ctx);
      vmb.send(request(0x04, 9, sensor(1), vmb.nextSeq(), [0x03, 0, 0, 0, 0])); // events, both edges
      rig.run(rig.now() + 25e6); // past the first 10 ms sample
      const events = () => vmb.events.filter((e) => e.bytes[0] === 9 && e.bytes[1] === 0x01);
      const before = events().length;
      const r = vmb.ask(request(0x13, 9, sensor(1), vmb.nextSeq(), [100, 0]), 3); // pulse_in_rising, 100 ms
      const seq = r?.[0];
      const deferred = () => vmb.events.find((e) => e.bytes[0] === 9 && e.bytes[1] === 0x03 && e.bytes[3] === seq);
      rig.run(rig.now() + 2e6);
      db.setPin(S1A, true);
      hold(db, rig.now() + 200e3);
      rig.run(rig.now() + 20e3);
      db.setPin(S1A, false);
      rig.run(rig.now() + 40e6, () => deferred() && events().length > before);
      const d = deferred()?.bytes ?? [];
      const w = d[4] === 0 && d[5] === 4 ? d[6] | (d[7] << 8) | (d[8] << 16) | (d[9] << 24) : null;
      ctx.check('pulse_in_rising ends with a width, not a timeout (a pulse over before the core woke is measured as at most its wake-up: 0..260 µs)', w !== null && w <= 260, `width ${w} µs`);
      const ev = events()[before];
      const b = ev?.bytes ?? [];
      const u16 = (i) => b[i] | (b[i + 1] << 8);
      ctx.check('the pin_change event: level 0, 1 rising and 1 falling edge', !!ev && b[5] === 5 && b[6] === 0 && u16(7) === 1 && u16(9) === 1,
        ev ? b.map((x) => x.toString(16).padStart(2, '0')).join(' ') : 'no event');
    },
  },
];
