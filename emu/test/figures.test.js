// The generated figures block of lib/figures.js (docs/emulation.md's "Figures").
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { BEGIN, END, figuresBlock, isWall } from '../lib/figures.js';

test('the block lists every figure but the wall-clock ones, scenario by scenario, between its markers', () => {
  const block = figuresBlock([
    { scenario: 'boot', figures: [{ name: 'boot to first MB frame (ms)', value: '4.160' }, { name: 'simulated s per wall s (2 chips)', value: '0.08' }] },
    { scenario: 'identify', figures: [] },
    { scenario: 'doorbell', figures: [{ name: 'edge to chime (µs, min/max)', value: '3100 / 3600' }, { name: 'a | b', value: 'x|y' }] },
  ]);
  assert.equal(block, [
    BEGIN,
    '| scenario | figure | value |',
    '|---|---|---|',
    '| `boot` | boot to first MB frame (ms) | 4.160 |',
    '| `doorbell` | edge to chime (µs, min/max) | 3100 / 3600 |',
    '| `doorbell` | a \\| b | x\\|y |',
    END,
    '',
  ].join('\n'));
});

test('wall-clock figures are the ones whose name says wall', () => {
  assert.equal(isWall('simulated s per wall s (2 chips, fig4_4)'), true);
  assert.equal(isWall('stack high-water mark after fig4_4, mb-pico / db-pico (bytes)'), false);
  assert.equal(isWall('wallpaper'), false);
});
