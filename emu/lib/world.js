// Reading actuator states back from a chip's recorded pins and PWM registers.

/** Actuator port A1 of the Pico map: digital A = GP4, digital B = GP5, PWM A = GP2 (slice 1 A). */
export const A1 = { a: 4, b: 5, slice: 1 };

/** Actuator port `n` (from 1) of the Pico map (x10-boards/src/pins.rs): A1 as above, A2 = GP8/GP9
 * with slice 3, A3 = GP12/GP13 with slice 5. */
export const actuatorPort = (n) => ({ a: 4 + 4 * (n - 1), b: 5 + 4 * (n - 1), slice: 1 + 2 * (n - 1) });

/** Sensor port `n` (from 1) of the Pico map: digital A = GP14, B = GP15 on S1 (two more per
 * port), analog = ADC channel n - 1. */
export const sensorPort = (n) => ({ a: 14 + 2 * (n - 1), b: 15 + 2 * (n - 1), adc: n - 1 });

/**
 * A world's devices and input signals, from `x10 signals` (x10-cli: the simulator's own
 * reading of the world file): { devices: [...], changes: [{ t_ms, board, port, a, b, analog }] }.
 */
export function parseSignals(text) {
  const devices = [];
  const changes = [];
  for (const line of text.split('\n').filter((l) => l.trim())) {
    const v = JSON.parse(line);
    if ('device' in v) devices.push(v); else changes.push(v);
  }
  return { devices, changes };
}

/**
 * The output devices' changes in `x10 sim`'s summary, by device name: { name: [{ ms, state }] },
 * with motor states written as motorTrack writes them ('forward 50%', 'stop').
 */
export function parseSimSummary(text, names) {
  const out = Object.fromEntries(names.map((n) => [n, []]));
  for (const line of text.split('\n')) {
    const m = /^\s+(\d+\.\d+) s\s+(\S+)\s+(.+?)\s*$/.exec(line);
    if (!m || !(m[2] in out)) continue;
    const state = m[3] === 'stopped' ? 'stop' : m[3].replace(/ %$/, '%');
    out[m[2]].push({ ms: Number(m[1]) * 1000, state });
  }
  return out;
}

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
