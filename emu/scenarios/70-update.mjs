// Firmware over the bus on the emulated Pico (issue 25): db-pico 0.1.0 under boot-pico, updated
// to 2.0.0 by a scripted motherboard (lib/vmb.js) speaking the update frames of
// docs/protocol.md ("Firmware over the bus"): System 12 enter_update to the application, then
// function 7 (begin, chunk, commit) to the bootloader's update mode (h13-update's
// x10_boot::Session behind boot-pico's I2C target), the swap at the reset, 2.0.0's boot event,
// System 13 confirm_firmware. mb-pico's own updater (carrying the image) is not wired yet.
import { VirtualMb, request } from '../lib/vmb.js';
import { readElf } from '../lib/elf.js';

const FLASH = 0x10000000;
const STATE = 0x8000;
const ACTIVE = 0x9000;
const ACTIVE_LEN = 32 * 1024;
const RECORD = 0x1fe000;
const ADDRESS = 0x20;
const PICO = 3;
/** embassy-boot 0.7's magics (lib.rs 33-36). */
const BOOT_MAGIC = 0xd0, DFU_DETACH_MAGIC = 0xe0;
/** Image bytes per chunk (x10_microcode::CHUNK_MAX). */
const CHUNK = 24;

const slot = (value, seq) => [0x58, value, seq & 0xff, seq >> 8, 0xa7, ~value & 0xff, ~seq & 0xff, (~seq >> 8) & 0xff];

function crc8(bytes) {
  let c = 0;
  for (const b of bytes) {
    c ^= b;
    for (let i = 0; i < 8; i++) c = c & 0x80 ? ((c << 1) ^ 0x07) & 0xff : (c << 1) & 0xff;
  }
  return c;
}
function crc16(bytes) { // CRC-16/IBM-3740
  let c = 0xffff;
  for (const b of bytes) {
    c ^= b << 8;
    for (let i = 0; i < 8; i++) c = c & 0x8000 ? ((c << 1) ^ 0x1021) & 0xffff : (c << 1) & 0xffff;
  }
  return c;
}
function crc32(bytes) { // CRC-32/ISO-HDLC
  let c = 0xffffffff;
  for (const b of bytes) {
    c ^= b;
    for (let i = 0; i < 8; i++) c = c & 1 ? (c >>> 1) ^ 0xedb88320 : c >>> 1;
  }
  return (c ^ 0xffffffff) >>> 0;
}
const u32 = (v) => [v & 0xff, (v >>> 8) & 0xff, (v >>> 16) & 0xff, (v >>> 24) & 0xff];
/** A request with its check over the write address byte: CRC-8 up to 13 bytes, else CRC-16. */
function checked(frame) {
  const cover = [frame[1] << 1, ...frame];
  if (frame.length <= 13) return [...frame, crc8(cover)];
  const c = crc16(cover);
  return [...frame, c & 0xff, c >> 8];
}

/** The image of an ELF linked into ACTIVE: its bytes from ACTIVE to its last flash byte. */
function image(elf) {
  let end = 0;
  for (const s of elf.segments) {
    const off = s.paddr - FLASH - ACTIVE;
    if (off >= 0 && off < ACTIVE_LEN) end = Math.max(end, off + s.data.length);
  }
  const out = new Uint8Array(end).fill(0xff);
  for (const s of elf.segments) {
    const off = s.paddr - FLASH - ACTIVE;
    if (off >= 0 && off < ACTIVE_LEN) out.set(s.data, off);
  }
  return out;
}

const bootVersions = (vmb) => vmb.events
  .filter((e) => e.bytes[0] === ADDRESS && e.bytes[1] === 0x07)
  .map((e) => e.bytes.slice(7, 10).join('.'));

/** One request to the board, its reply read (`n` bytes); the status byte or null. */
function ask(vmb, frame, n, timeoutNs = 200e6) {
  const r = vmb.transact(ADDRESS, frame, n, timeoutNs);
  return r && r.ok ? r.read[1] : null;
}

/**
 * `ask`, tried again every 5 ms while the transaction fails or is answered `pec_mismatch`
 * (0x08), at most 20 times: the bootloader does a request's flash work (a 45 ms sector erase)
 * after its reply, interrupts off; a request arriving meanwhile finds the I2C block taking
 * bytes the core does not drain (its 16-byte FIFO overflows), and the frame reaches the
 * session broken. Counts the tries again in `retries.n`.
 */
function askRetrying(vmb, frame, n, retries) {
  for (let i = 0; i < 20; i++) {
    const st = ask(vmb, frame, n);
    if (st !== null && st !== 0x08) return st;
    retries.n++;
    vmb.rig.run(vmb.rig.now() + 5e6);
  }
  return null;
}

/**
 * The transfer of `img` to the bootloader: begin, the chunks from `from` (each retried once
 * when its transaction fails), commit unless `stopAt` (a chunk offset) comes first. Returns
 * { statuses: the begin's, any chunk's not ok, the commit's }.
 */
function transfer(vmb, img, { stopAt = Infinity } = {}) {
  const seq = () => vmb.nextSeq();
  const info = [...u32(img.length), ...u32(crc32(img)), PICO, 2, 0, 0];
  const retries = { n: 0 };
  const out = { begin: askRetrying(vmb, checked(request(0x70, ADDRESS, 0, seq(), info)), 4, retries), bad: [], chunks: 0, retries };
  for (let off = 0; off < img.length; off += CHUNK) {
    if (off >= stopAt) return out;
    const data = Array.from(img.subarray(off, off + CHUNK));
    const st = askRetrying(vmb, checked(request(0x71, ADDRESS, 0, seq(), [...u32(off), ...data])), 4, retries);
    if (st !== 0) out.bad.push({ off, st });
    out.chunks++;
  }
  out.commit = askRetrying(vmb, checked(request(0x72, ADDRESS, 0, seq())), 4, retries);
  return out;
}

function setup(ctx) {
  const rig = ctx.rig();
  const vmb = new VirtualMb(rig);
  const db = rig.addChip('db', ctx.dbSlotElf, { boot: ctx.bootElf });
  db.nor.data.set(slot(ADDRESS, 0), RECORD);
  rig.run(30e6);
  return { rig, vmb, nor: db.nor };
}

export default [
  {
    name: 'update',
    resets: true,
    about: 'issue 25 end to end on the emulated Pico: a scripted MB updates db-pico 0.1.0 (under boot-pico) to 2.0.0 over the I2C bus: enter_update, the bootloader\'s update mode at the board\'s address (begin, 24-byte chunks, commit; every frame checked), the swap at the reset, 2.0.0\'s boot event, confirm_firmware, and 2.0.0 kept at the next reset; then the same with the power cut in the middle of the transfer: the board comes back in update mode on 0.1.0 and the MB finishes',
    async run(ctx) {
      if (!ctx.bootElf || !ctx.dbSlotElf || !ctx.dbSlotV2Elf) {
        ctx.check('the bootloader images were given (--boot, --db-slot, --db-slot-v2)', false);
        return;
      }
      const v1 = image(readElf(ctx.dbSlotElf));
      const v2 = image(readElf(ctx.dbSlotV2Elf));
      const same = (a, b) => Buffer.compare(Buffer.from(a), Buffer.from(b)) === 0;
      const wall0 = Date.now();
      let { rig, vmb, nor } = setup(ctx);
      ctx.check('db-pico 0.1.0 runs under boot-pico (boot event 0.1.0)', JSON.stringify(bootVersions(vmb)) === '["0.1.0"]', JSON.stringify(bootVersions(vmb)));

      const t0 = rig.now();
      const enter = ask(vmb, request(0x0c, ADDRESS, 0, vmb.nextSeq()), 3);
      rig.run(rig.now() + 30e6);
      ctx.check('enter_update is answered ok; STATE holds the DFU-detach mark; the board resets into update mode',
        enter === 0 && nor.data[STATE] === DFU_DETACH_MAGIC, `status ${enter}, STATE ${nor.data[STATE].toString(16)}`);
      const status = vmb.transact(ADDRESS, checked(request(0x73, ADDRESS, 0, vmb.nextSeq())), 10, 50e6);
      ctx.check('the bootloader answers status at the board\'s address (idle, nothing received)',
        !!status?.ok && status.read[1] === 0 && status.read[3] === 0, JSON.stringify(status?.read));

      const t1 = rig.now();
      const sent = transfer(vmb, v2);
      const t2 = rig.now();
      ctx.check('begin, every chunk and commit are answered ok (requests that found the board erasing tried again)',
        sent.begin === 0 && sent.bad.length === 0 && sent.commit === 0, JSON.stringify({ begin: sent.begin, bad: sent.bad.slice(0, 3), chunks: sent.chunks, commit: sent.commit, retries: sent.retries.n }));
      rig.run(rig.now() + 3000e6, () => bootVersions(vmb).length >= 2 && rig.now() > t2 + 10e6);
      const t3 = rig.now();
      ctx.check('at the reset the bootloader swaps and 2.0.0 boots: its boot event says 2.0.0',
        bootVersions(vmb)[1] === '2.0.0' && same(nor.data.slice(ACTIVE, ACTIVE + v2.length), v2), JSON.stringify(bootVersions(vmb)));
      const confirm = ask(vmb, request(0x0d, ADDRESS, 0, vmb.nextSeq()), 3);
      ctx.check('confirm_firmware is answered ok and STATE holds the boot mark', confirm === 0 && nor.data[STATE] === BOOT_MAGIC,
        `status ${confirm}, STATE ${nor.data[STATE].toString(16)}`);
      const t4 = rig.now();
      rig.chips[0].rp.sysResetRequested = { t: t4 };
      rig.run(t4 + 2000e6, () => bootVersions(vmb).length >= 3 && rig.now() > t4 + 10e6);
      ctx.check('confirmed, 2.0.0 is kept at the next reset', bootVersions(vmb)[2] === '2.0.0' && same(nor.data.slice(ACTIVE, ACTIVE + v2.length), v2),
        JSON.stringify(bootVersions(vmb)));
      ctx.figure('update at 100 kHz: enter_update to 2.0.0\'s boot event (s, virtual)', ((t3 - t0) / 1e9).toFixed(2));
      ctx.figure('update at 100 kHz: the transfer, begin to commit answered (s, virtual; image bytes; requests tried again)', `${((t2 - t1) / 1e9).toFixed(2)}; ${v2.length}; ${sent.retries.n}`);

      // The power cut in the middle of the transfer.
      ({ rig, vmb, nor } = setup(ctx));
      ask(vmb, request(0x0c, ADDRESS, 0, vmb.nextSeq()), 3);
      rig.run(rig.now() + 30e6);
      const half = Math.floor(v2.length / 2 / CHUNK) * CHUNK;
      const part = transfer(vmb, v2, { stopAt: half });
      const chip = rig.chips[0];
      chip.readRtt();
      const fresh = rig.powerCycle(chip);
      fresh.defmt = chip.defmt;
      rig.run(rig.now() + 30e6);
      const again = vmb.transact(ADDRESS, checked(request(0x73, ADDRESS, 0, vmb.nextSeq())), 10, 50e6);
      ctx.check('cut after half the chunks: the board comes back in update mode (status answered), ACTIVE still 0.1.0',
        part.begin === 0 && part.bad.length === 0 && !!again?.ok && same(nor.data.slice(ACTIVE, ACTIVE + v1.length), v1) && nor.data[STATE] === DFU_DETACH_MAGIC,
        JSON.stringify({ chunks: part.chunks, status: again?.read }));
      const rest = transfer(vmb, v2);
      const tc = rig.now();
      rig.run(tc + 3000e6, () => bootVersions(vmb).length >= 2 && rig.now() > tc + 10e6);
      ctx.check('the MB begins again and finishes: 2.0.0 boots', rest.commit === 0 && rest.bad.length === 0 && bootVersions(vmb)[1] === '2.0.0',
        JSON.stringify({ commit: rest.commit, versions: bootVersions(vmb) }));
      ctx.figure('simulated s per wall s (update)', ((rig.now() / 1e9) / ((Date.now() - wall0) / 1000)).toFixed(2));
    },
  },
];
