// One test per fix of the USB host model (lib/usb.js), against rp2040js 1.4.1's USB block
// driven by the test as embassy-rp drives it (no firmware).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { RP2040, USBCDC } from 'rp2040js';
import { UsbHost, keepOutAvailable, controlLineStatePacket, BUF_AVAILABLE, BUF_FULL } from '../lib/usb.js';

const DPRAM = 0x50100000;
const EP1_OUT_CONTROL = 0x0c; // endpoint control: enable, buffer address
const EP1_OUT_BUFFER_CONTROL = 0x8c;
const EP_ENABLE = 1 << 31;
const BUFFER = 0x180;

function bare() {
  const rp = new RP2040();
  rp.logger = { debug() {}, info() {}, warn() {}, error() {} };
  return rp;
}

/** Arms endpoint 1 OUT for `len` bytes, as embassy-rp's `EndpointOut::read` does. */
function armOut(rp, len) {
  rp.writeUint32(DPRAM + EP1_OUT_CONTROL, EP_ENABLE | BUFFER);
  rp.writeUint32(DPRAM + EP1_OUT_BUFFER_CONTROL, len);
  rp.writeUint32(DPRAM + EP1_OUT_BUFFER_CONTROL, len | BUF_AVAILABLE);
}
const ctrl = (rp) => rp.usbDPRAMView.getUint32(EP1_OUT_BUFFER_CONTROL, true);

test('an armed OUT buffer keeps AVAILABLE until the host fills it', () => {
  // rp2040js alone: AVAILABLE is gone the moment the buffer is armed.
  const stock = bare();
  armOut(stock, 64);
  assert.equal(ctrl(stock) & BUF_AVAILABLE, 0, 'rp2040js 1.4.1 clears AVAILABLE at once');

  const rp = bare();
  keepOutAvailable(rp.usbCtrl);
  const asked = [];
  rp.usbCtrl.onEndpointRead = (ep, size) => asked.push([ep, size]);
  armOut(rp, 64);
  assert.deepEqual(asked, [[1, 64]]);
  assert.equal(ctrl(rp) & BUF_AVAILABLE, BUF_AVAILABLE, 'still armed, nothing received');
  rp.usbCtrl.endpointReadDone(1, Uint8Array.from([7, 8, 9]));
  rp.clock.tick(10_000);
  assert.equal(ctrl(rp) & BUF_AVAILABLE, 0);
  assert.equal(ctrl(rp) & BUF_FULL, BUF_FULL);
  assert.equal(ctrl(rp) & 0x3ff, 3, 'the length is what came, not what was armed');
  assert.deepEqual(Array.from(rp.usbDPRAM.subarray(BUFFER, BUFFER + 3)), [7, 8, 9]);
  assert.equal(rp.usbCtrl.buffStatus & (1 << 3), 1 << 3, 'EP1 OUT done in BUFF_STATUS');
});

test('an armed OUT buffer waits for data instead of a zero-length packet', () => {
  // rp2040js's host answers at once with what its FIFO holds: nothing, a zero-length packet.
  const stock = bare();
  const cdc = new USBCDC(stock.usbCtrl);
  cdc.outEndpoint = 1;
  keepOutAvailable(stock.usbCtrl);
  armOut(stock, 64);
  stock.clock.tick(10_000);
  assert.equal(ctrl(stock) & BUF_FULL, BUF_FULL);
  assert.equal(ctrl(stock) & 0x3ff, 0, 'stock host: a zero-length packet');

  const rp = bare();
  const host = new UsbHost(rp);
  host.cdc.outEndpoint = 1;
  armOut(rp, 64);
  rp.clock.tick(1_000_000);
  assert.equal(ctrl(rp) & BUF_FULL, 0, 'held: no packet without data');
  assert.equal(host.zlpsHeld, 1);
  host.send([1, 2, 3, 4, 5]);
  rp.clock.tick(10_000);
  assert.equal(ctrl(rp) & 0x3ff, 5);
  assert.deepEqual(Array.from(rp.usbDPRAM.subarray(BUFFER, BUFFER + 5)), [1, 2, 3, 4, 5]);
  // More than the armed length waits for the next arming.
  host.send(new Array(70).fill(0xaa));
  armOut(rp, 64);
  rp.clock.tick(10_000);
  assert.equal(ctrl(rp) & 0x3ff, 64);
  assert.equal(host.tx.length, 6);
});

test('SET_CONTROL_LINE_STATE goes to the CDC interface, not the device', () => {
  const rp = bare();
  const stock = new USBCDC(rp.usbCtrl);
  stock.cdcSetControlLineState();
  const sent = Array.from(rp.usbDPRAM.subarray(0, 8));
  assert.equal(sent[0], 0x20, 'rp2040js 1.4.1: class request to the device (bmRequestType 0x20)');

  const host = new UsbHost(bare());
  host.cdc.cdcSetControlLineState();
  assert.deepEqual(
    Array.from(host.rp.usbDPRAM.subarray(0, 8)),
    [0x21, 0x22, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00],
    'class request to interface 0: DTR and RTS',
  );
  assert.deepEqual(Array.from(controlLineStatePacket(0, 0)), [0x21, 0x22, 0, 0, 0, 0, 0, 0]);
});

test('the rig writes the link frames of docs/usb-link.md', async () => {
  const { linkFrame, LAPTOP } = await import('../lib/usb.js');
  assert.deepEqual(linkFrame([4, 9]), [0x05, 0x04, 0x09, 0xe2, 0x40, 0x00], 'ListBoards { id: 9 }');
  assert.deepEqual(LAPTOP.hello(), [0x01, 0x02, 0x01, 0x05, 0x03, 0x78, 0x31, 0x30, 0x03, 0x3b, 0x57, 0x00]);
  assert.deepEqual(LAPTOP.call(7, 0, 0x12, 0x01), [0x03, 0x02, 0x07, 0x03, 0x12, 0x01, 0x03, 0xb6, 0xfc, 0x00]);
});

test('the rig reads the records\' time stamps back from the link frames', async () => {
  const { recordTimes } = await import('../lib/usb.js');
  // docs/usb-link.md: Call (pwm duty A1.A 127, ok, end 1000450), Output (Duty 127 at 1000450),
  // Output (Level true at 1000900), split over two packets; then a Dropped frame (skipped).
  const call = [0x02, 0x02, 0x02, 0x20, 0x03, 0x01, 0x7f, 0x01, 0x09, 0xc0, 0x84, 0x3d, 0x82, 0x88, 0x3d, 0xbe, 0x4d, 0x00];
  const duty = [0x02, 0x04, 0x01, 0x08, 0x01, 0x7f, 0x82, 0x88, 0x3d, 0x6c, 0x22, 0x00];
  const level = [0x02, 0x04, 0x02, 0x01, 0x07, 0x01, 0xc4, 0x8b, 0x3d, 0xec, 0xd7, 0x00];
  const dropped = [0x03, 0x05, 0x03, 0x02, 0x02, 0x04, 0x01, 0x82, 0xdd, 0x00];
  const all = [...call, ...duty, ...level, ...dropped];
  const got = recordTimes([{ t: 5, bytes: all.slice(0, 25) }, { t: 9, bytes: all.slice(25) }]);
  assert.deepEqual(got, [
    { kind: 'call', us: 1000450, t: 5 },
    { kind: 'output', us: 1000450, t: 9 },
    { kind: 'output', us: 1000900, t: 9 },
  ]);
});

test('the link messages of a byte stream, each with the time its frame ended', async () => {
  const { messages, varints, linkFrame, LAPTOP } = await import('../lib/usb.js');
  // docs/usb-link.md's example frames: Refused { id: 10 }, then Dropped { 3, 0, 2, 0, 1 }
  // cut across two packets, a damaged frame, and a frame of its own.
  const refused = [0x05, 0x09, 0x0a, 0xdd, 0x06, 0x00];
  const dropped = [0x03, 0x05, 0x03, 0x02, 0x02, 0x04, 0x01, 0x82, 0xdd, 0x00];
  assert.deepEqual(linkFrame([5, 3, 0, 2, 0, 1]), dropped);
  const received = [
    { t: 10, bytes: [...refused, ...dropped.slice(0, 4)] },
    { t: 20, bytes: [...dropped.slice(4), 0x03, 0x09, 0x0b, 0x00] },
    { t: 30, bytes: LAPTOP.diagnostics(8) },
  ];
  const m = messages(received);
  assert.deepEqual(m.map((x) => [x.tag, x.t]), [[9, 10], [5, 20], [null, 20], [3, 30]]);
  assert.deepEqual(varints(m[1].body), [3, 0, 2, 0, 1]);
  assert.deepEqual(LAPTOP.diagnostics(8), [0x05, 0x03, 0x08, 0x54, 0xc9, 0x00]);
});
