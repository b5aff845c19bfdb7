// Executor stalls: a chip's core held for a chosen time (no instruction runs, as when an
// interrupt handler or a critical section keeps the executor from polling), while its clock,
// timers and I2C block go on and the bus keeps running. Shows what a late poll of the block
// does (issue 21 item 5: one snapshot of the target's flags standing for two bus histories).
//
// Kept out of ./rig.js: a chip becomes holdable when first held, by wrapping its runUntil.

/** Holds `chip`'s core from now until virtual time `untilNs`. */
export function hold(chip, untilNs) {
  if (chip.heldUntil === undefined) {
    chip.heldUntil = 0;
    chip.heldNs = 0;
    const run = chip.runUntil.bind(chip);
    chip.runUntil = (ns) => {
      const clock = chip.clock;
      if (chip.heldUntil > clock.nanosCounter) {
        const to = Math.min(ns, chip.heldUntil);
        chip.heldNs += to - clock.nanosCounter;
        // Alarms (the timer) still fire; their interrupts wait for the core.
        clock.tick(to - clock.nanosCounter);
      }
      run(ns);
    };
  }
  chip.heldUntil = Math.max(chip.heldUntil, untilNs);
}

/**
 * Holds `chip`'s core for `ns` once `when()` first returns true (checked after every rig
 * quantum, so up to one quantum late). Returns a record: `at` is the virtual time the stall
 * began (null until it has).
 */
export function stallWhen(rig, chip, when, ns) {
  const s = { at: null, ns };
  const hook = () => {
    if (s.at !== null || !when()) return;
    s.at = rig.now();
    hold(chip, s.at + ns);
  };
  rig.hooks.push(hook);
  return s;
}
