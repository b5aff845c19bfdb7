// Where the time of a firmware update over the bus goes (issue 25), from a rig's bus trace:
// the `update`, `update-400k` and `update-1m` scenarios (scenarios/70-update.mjs) print it.

/** First bytes of the requests of function 7: begin, chunk, commit. */
export const BEGIN = 0x70, CHUNK_OP = 0x71, COMMIT = 0x72;
/** Image bytes per chunk (x10_microcode::CHUNK_MAX). */
export const CHUNK = 24;
/** 4 KiB erase sectors of the Pico's flash (firmware_mb::update::FlashTiming::for_kind). */
export const SECTOR = 4096;
/**
 * Bit times on the wire of one chunk transaction (firmware_mb::update::CHUNK_WIRE_BITS): START,
 * the address byte, the 34-byte request (4 header, 4 offset, 24 image bytes, the CRC-16),
 * repeated START, the address byte, the 4-byte reply (3 header, the PEC byte), STOP: 40 bytes
 * of 9 bits (8 and the ACK) and 3 for START, repeated START and STOP.
 */
export const CHUNK_WIRE_BITS = (1 + 34 + 1 + 4) * 9 + 3;

/** The wire-time floor of an image of `len` bytes at `hz` (ns): its chunks on the wire and nothing else. */
export const floorNs = (len, hz) => Math.ceil(len / CHUNK) * CHUNK_WIRE_BITS * 1e9 / hz;

/** The first request the transfer `tr` wrote (`{ addr, bytes }`), or undefined. */
const request = (tr) => tr.parts.find((p) => p.dir !== 'r' && p.bytes.length);

/**
 * The time of the transfer from `begin` to `commit` (ns: the t0 of the transfers that carried
 * the first begin and the last commit) split by what the bus did, over `transfers` (the bus
 * model's records: `{ t0, t1, master, addr, parts }`), the board at `address`, the image
 * `imageLen` bytes long:
 * - `wire`: the motherboard's transactions to the board on the wire, the board's clock
 *   stretching included (`n.wire` of them; the commit at `commit` not counted: it ends the
 *   transfer);
 * - then the time from the end of each to the start of the next one, by the request it carried:
 *   `begin` (the first sector's erase, waited out), `erase` (a chunk that fills a sector: the
 *   next sector's erase, waited out; `n.erase`), `commit` (a commit sent again: the board
 *   reads the slot back for its CRC before it answers), and after the other chunks `quiet`
 *   (nothing else on the bus in between: the updater's pause after each chunk, the larger of
 *   the gap and a page program, and the motherboard's own work; `n.quiet`) or `behind` (other
 *   transfers in between: the updater's next request queued behind another task's request
 *   and its retries; `n.behind`).
 * The parts add up to `commit - begin`.
 */
export function transferTime(transfers, { address, begin, commit, imageLen }) {
  const idx = [];
  transfers.forEach((tr, i) => {
    if (tr.master === 'mb' && tr.addr === address && tr.t0 >= begin && tr.t0 <= commit) idx.push(i);
  });
  const t = { wire: 0, begin: 0, erase: 0, commit: 0, quiet: 0, behind: 0 };
  const n = { wire: 0, erase: 0, quiet: 0, behind: 0 };
  idx.forEach((i, k) => {
    if (k + 1 === idx.length) return;
    const tr = transfers[i];
    t.wire += tr.t1 - tr.t0;
    n.wire += 1;
    const next = idx[k + 1];
    const idle = transfers[next].t0 - tr.t1;
    const req = request(tr);
    const op = req?.bytes[0];
    if (op === BEGIN) {
      t.begin += idle;
    } else if (op === COMMIT) {
      t.commit += idle;
    } else if (op === CHUNK_OP && erasesAfter(req.bytes, imageLen)) {
      t.erase += idle;
      n.erase += 1;
    } else if (next > i + 1) {
      t.behind += idle;
      n.behind += 1;
    } else {
      t.quiet += idle;
      n.quiet += 1;
    }
  });
  return { t, n };
}

/**
 * True when the board erases a sector after the chunk request `bytes` (4 header bytes, the
 * offset u32 LE, the image bytes): the chunk ends in another sector than it began, or at a
 * sector's end, and the image goes on (x10-boot erases the next sector once the last page of
 * one is filled; the first sector after begin). The motherboard's rule:
 * firmware_mb::update::FlashTiming::work_after_chunk_us.
 */
function erasesAfter(bytes, imageLen) {
  const off = (bytes[4] | (bytes[5] << 8) | (bytes[6] << 16) | (bytes[7] << 24)) >>> 0;
  const end = off + Math.min(CHUNK, imageLen - off);
  const next = Math.floor(end / SECTOR) * SECTOR;
  return next > off && next < imageLen;
}
