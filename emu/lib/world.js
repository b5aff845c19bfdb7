// Reading actuator states back from a chip's recorded pins and PWM registers.

/** Actuator port A1 of the Pico map: digital A = GP4, digital B = GP5, PWM A = GP2 (slice 1 A). */
export const A1 = { a: 4, b: 5, slice: 1 };

/**
 * The H-bridge motor on `port` as a list of { ms, state } changes ('stop', 'forward 50%', ...).
 * A motor command is several writes (two pins, then the duty): states that last less than
 * `settleMs` are the steps of one command and are left out.
 */
export function motorTrack(chip, port = A1, settleMs = 5) {
  const ev = [];
  for (const p of chip.pinLog) if (p.pin === port.a || p.pin === port.b) ev.push({ t: p.t, pin: p.pin, v: p.v === 'high' });
  for (const w of chip.pwmLog) if (w.slice === port.slice) ev.push({ t: w.t, duty: w.en ? Math.round((Math.min(w.a, w.top + 1) * 100) / (w.top + 1)) : 0 });
  ev.sort((x, y) => x.t - y.t);
  let a = false, b = false, duty = 0;
  const states = [];
  for (const e of ev) {
    if (e.pin === port.a) a = e.v;
    else if (e.pin === port.b) b = e.v;
    else duty = e.duty;
    const s = a && !b ? `forward ${duty}%` : !a && b ? `reverse ${duty}%` : a && b ? 'brake' : 'stop';
    states.push({ ms: e.t / 1e6, state: s });
  }
  const out = [];
  for (let i = 0; i < states.length; i++) {
    const next = states[i + 1];
    if (next && next.ms - states[i].ms < settleMs) continue;
    if (!out.length || out[out.length - 1].state !== states[i].state) out.push(states[i]);
  }
  // The first settled state counts from its command's first write.
  return out;
}
