// Where an update's time goes (lib/update.js), on a hand-made bus trace.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { CHUNK_WIRE_BITS, floorNs, transferTime } from '../lib/update.js';

/** A transfer of the MB to `addr` writing `bytes`, from `t0` to `t1` (µs). */
const tr = (t0, t1, addr, bytes) => ({ t0: t0 * 1e3, t1: t1 * 1e3, master: 'mb', addr, parts: [{ dir: 'w', addr, ack: addr === 0x20, bytes }] });
/** A chunk request at `off` (4 header bytes, the offset u32 LE; its image bytes left out). */
const chunk = (t0, t1, off) => tr(t0, t1, 0x20, [0x71, 0x20, 0x00, 0x01, off & 0xff, (off >> 8) & 0xff, (off >> 16) & 0xff, off >>> 24]);

test('the floor is 363 bit times a chunk: 1363 chunks of a 32 712-byte image', () => {
  assert.equal(CHUNK_WIRE_BITS, 363);
  assert.equal(floorNs(32712, 400000), 1363 * 363 * 2500);
  assert.equal(floorNs(25, 1000000), 2 * 363 * 1000);
});

test('the transfer is split into the wire and what came between the MB\'s transactions to the board', () => {
  const trace = [
    tr(0, 5, 0x20, [0x0c, 0x20, 0x00, 0x01]), // enter_update: before begin, not counted
    tr(100, 110, 0x20, [0x70, 0x20, 0x00, 0x02]), // begin; 50 µs to the next: the first erase
    chunk(160, 170, 0), // 20 µs, bus quiet
    chunk(190, 200, 4080), // reaches sector 1 (4080 + 24 > 4096): 300 µs, its erase
    chunk(500, 510, 4104), // then a request to board 9 in between: 40 µs behind it
    tr(520, 521, 0x09, [0x12]),
    chunk(550, 560, 4128), // 5 µs quiet
    tr(565, 570, 0x20, [0x72, 0x20, 0x00, 0x03]), // commit, unanswered: 30 µs, read-back
    tr(600, 605, 0x20, [0x72, 0x20, 0x00, 0x04]), // the last commit ends the transfer
  ];
  const { t, n } = transferTime(trace, { address: 0x20, begin: 100e3, commit: 600e3, imageLen: 8192 });
  assert.deepEqual(t, { wire: 55e3, begin: 50e3, erase: 300e3, commit: 30e3, quiet: 25e3, behind: 40e3 });
  assert.deepEqual(n, { wire: 6, erase: 1, quiet: 2, behind: 1 });
  assert.equal(Object.values(t).reduce((a, b) => a + b), 600e3 - 100e3);
});

test('the erase follows the chunk that fills a sector, not the one that starts the next, and none after the image\'s last sector', () => {
  const trace = [
    chunk(0, 10, 0), // sector 0: erased after begin
    chunk(20, 30, 4072), // ends at 4096: fills sector 0, sector 1 is erased
    chunk(80, 90, 4096), // starts sector 1
    chunk(100, 110, 8184), // 8184 + 8 (the image's last bytes) = 8192: the image ends, no erase
    tr(120, 121, 0x20, [0x72]),
  ];
  const { t, n } = transferTime(trace, { address: 0x20, begin: 0, commit: 120e3, imageLen: 8192 });
  assert.deepEqual(n, { wire: 4, erase: 1, quiet: 3, behind: 0 });
  assert.equal(t.erase, 50e3);
  assert.equal(t.quiet, 10e3 + 10e3 + 10e3);
});
