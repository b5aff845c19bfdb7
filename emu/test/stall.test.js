// lib/stall.js: a held core runs no instruction while its clock and alarms go on.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { RP2040 } from 'rp2040js';
import { hold, stallWhen } from '../lib/stall.js';

/** A stand-in chip: its runUntil records the spans it ran and moves its clock. */
function fake() {
  const rp = new RP2040();
  const chip = { clock: rp.clock, ran: [] };
  chip.runUntil = (ns) => {
    if (ns > chip.clock.nanosCounter) chip.ran.push([chip.clock.nanosCounter, ns]);
    chip.clock.tick(ns - chip.clock.nanosCounter);
  };
  return chip;
}

test('a held chip runs nothing until the hold ends; alarms still fire', () => {
  const chip = fake();
  const fired = [];
  chip.clock.createAlarm(() => fired.push(chip.clock.nanos)).schedule(1500);
  hold(chip, 3000);
  chip.runUntil(1000);
  chip.runUntil(2000);
  assert.deepEqual(chip.ran, []);
  assert.deepEqual(fired, [1500]);
  chip.runUntil(4000);
  assert.deepEqual(chip.ran, [[3000, 4000]], 'runs again from the end of the hold');
  assert.equal(chip.heldNs, 3000);
});

test('stallWhen holds once, from the first quantum its condition holds', () => {
  const chip = fake();
  const rig = { t: 0, hooks: [], now() { return this.t; } };
  let go = false;
  const s = stallWhen(rig, chip, () => go, 5000);
  for (const t of [1000, 2000]) { rig.t = t; chip.runUntil(t); rig.hooks.forEach((h) => h()); }
  assert.equal(s.at, null);
  go = true;
  rig.hooks.forEach((h) => h());
  assert.equal(s.at, 2000);
  chip.runUntil(6000);
  assert.deepEqual(chip.ran, [[0, 1000], [1000, 2000]]);
  rig.t = 8000;
  rig.hooks.forEach((h) => h());
  chip.runUntil(8000);
  assert.deepEqual(chip.ran.at(-1), [7000, 8000], 'not held again');
});
