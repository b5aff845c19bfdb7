// The USB host the rig plugs an emulated Pico into: rp2040js 1.4.1's own CDC-ACM host model
// (dist/esm/usb/cdc.js: reset, address, configuration descriptor, SET_CONFIGURATION) with the
// three fixes an embassy-usb 0.6 CDC-ACM device needs (docs/emulation.md, "USB"; tests:
// test/usb.test.js), and a byte stream each way: `send(bytes)` to the device's OUT endpoint,
// `received` (with the virtual time of each IN packet) from its IN endpoint.
import { USBCDC, createSetupPacket, DataDirection, SetupType, SetupRecipient } from 'rp2040js';

/** Buffer-control bits of the USB block's DPRAM (RP2040 datasheet 4.1.2.5.1). */
export const BUF_FULL = 1 << 15;
export const BUF_AVAILABLE = 1 << 10;
const LEN_MASK = 0x3ff;
/** EP0_IN_BUFFER_CONTROL: the buffer-control words start here, IN then OUT, per endpoint. */
const EP0_IN_BUFFER_CONTROL = 0x80;
const EP15_OUT_BUFFER_CONTROL = 0xfc;
const CDC_SET_CONTROL_LINE_STATE = 0x22;

/** The buffer-control word's endpoint and direction at DPRAM offset `offset`, or null. */
export function bufferControlAt(offset) {
  if (offset < EP0_IN_BUFFER_CONTROL || offset > EP15_OUT_BUFFER_CONTROL) return null;
  return { endpoint: (offset - EP0_IN_BUFFER_CONTROL) >> 3, out: !!(offset & 4) };
}

/**
 * Fix 1, AVAILABLE kept on armed OUT buffers. rp2040js clears an OUT buffer's AVAILABLE bit
 * as soon as the firmware arms it (`DPRAMUpdated`), before the host has sent anything;
 * embassy-rp's `EndpointOut::read` waits for AVAILABLE to clear and then takes the buffer's
 * length field, its own armed length, as the bytes received: stale bytes. Here an armed OUT
 * buffer of endpoints 1-15 keeps AVAILABLE (the host is told, `onEndpointRead`, as before)
 * until the host fills it (`finishRead`), which clears AVAILABLE, sets FULL and the length.
 */
export function keepOutAvailable(usb) {
  const dpramUpdated = usb.DPRAMUpdated.bind(usb);
  usb.DPRAMUpdated = (offset, value) => {
    const at = bufferControlAt(offset);
    if (!usb.hostMode && at && at.out && at.endpoint > 0 && value & BUF_AVAILABLE) {
      usb.onEndpointRead?.(at.endpoint, value & LEN_MASK);
      return;
    }
    dpramUpdated(offset, value);
  };
  usb.finishRead = (endpoint, buffer) => {
    const reg = EP0_IN_BUFFER_CONTROL + endpoint * 8 + 4;
    const view = usb.rp2040.usbDPRAMView;
    let ctrl = view.getUint32(reg, true);
    const n = Math.min(buffer.length, ctrl & LEN_MASK);
    ctrl = (ctrl & ~LEN_MASK & ~BUF_AVAILABLE) | BUF_FULL | n;
    usb.rp2040.usbDPRAM.set(buffer.subarray(0, n), usb.getEndpointBufferOffset(endpoint, true));
    view.setUint32(reg, ctrl, true);
    usb.indicateBufferReady(endpoint, true);
  };
}

/**
 * Fix 3, SET_CONTROL_LINE_STATE to the interface. rp2040js's host sends it with the device as
 * recipient; embassy-usb routes class requests by interface, so the CDC-ACM class never sees
 * it (DTR stays off). Sent here to interface 0, the communication interface.
 */
export function controlLineStatePacket(value = 0b11, iface = 0) {
  return createSetupPacket({
    dataDirection: DataDirection.HostToDevice,
    type: SetupType.Class,
    recipient: SetupRecipient.Interface,
    bRequest: CDC_SET_CONTROL_LINE_STATE,
    wValue: value,
    wIndex: iface,
    wLength: 0,
  });
}

/** The host: one CDC-ACM device on `rp.usbCtrl`, with the fixes above. */
export class UsbHost {
  constructor(rp) {
    this.rp = rp;
    this.usb = rp.usbCtrl;
    keepOutAvailable(this.usb);
    this.cdc = new USBCDC(this.usb);
    this.cdc.cdcSetControlLineState = (value = 0b11, iface = 0) => {
      this.usb.sendSetupPacket(controlLineStatePacket(value, iface));
      this.cdc.initialized = true;
    };
    this.connected = null; // virtual ns when configured
    this.received = []; // { t, bytes }
    this.tx = [];
    this.armed = 0; // length of the armed OUT buffer, 0 when none
    this.zlpsHeld = 0;
    this.cdc.onDeviceConnected = () => { this.connected = rp.clock.nanos; };
    this.cdc.onSerialData = (buffer) => this.received.push({ t: rp.clock.nanos, bytes: Array.from(buffer) });
    // Fix 2, zero-length packets held. rp2040js's host answers every armed OUT buffer at once
    // with what its FIFO holds, most often nothing: a zero-length packet every 10 µs, which
    // the device reads as an empty transfer and re-arms. Here an armed buffer waits for data.
    this.usb.onEndpointRead = (endpoint, size) => {
      if (endpoint !== this.cdc.outEndpoint) return;
      this.armed = size;
      this.pump();
    };
  }

  /**
   * Unplugs the device and plugs it in again: the host forgets it (its descriptors, its
   * configuration, what was queued) and resets the bus after rp2040js's 10 ms; the device is
   * enumerated again from its address.
   */
  replug() {
    Object.assign(this.cdc, { descriptorsSize: null, descriptors: [], initialized: false, inEndpoint: -1, outEndpoint: -1 });
    this.connected = null;
    this.armed = 0;
    this.tx = [];
    this.replugs = (this.replugs ?? 0) + 1;
    this.usb.resetDevice();
  }

  /** Queues bytes for the device's OUT endpoint. */
  send(bytes) {
    this.tx.push(...bytes);
    this.pump();
  }

  pump() {
    if (!this.armed) return;
    if (!this.tx.length) { this.zlpsHeld++; return; }
    const n = Math.min(this.armed, this.tx.length);
    this.armed = 0;
    this.usb.endpointReadDone(this.cdc.outEndpoint, Uint8Array.from(this.tx.splice(0, n)));
  }

  /** Every byte received so far, in order. */
  bytes() { return this.received.flatMap((r) => r.bytes); }
}

/** CRC-16/IBM-3740 (poly 0x1021, init 0xffff), the link's frame check. */
export function crc16(bytes) {
  let c = 0xffff;
  for (const b of bytes) {
    c ^= b << 8;
    for (let i = 0; i < 8; i++) c = c & 0x8000 ? ((c << 1) ^ 0x1021) & 0xffff : (c << 1) & 0xffff;
  }
  return c;
}

/** COBS-encodes `bytes` (no zero in the result). */
export function cobs(bytes) {
  const out = [0];
  let code = 0, codeAt = 0;
  for (const b of bytes) {
    if (b === 0) { out[codeAt] = code + 1; codeAt = out.length; out.push(0); code = 0; continue; }
    out.push(b);
    code++;
    if (code === 254) { out[codeAt] = 255; codeAt = out.length; out.push(0); code = 0; }
  }
  out[codeAt] = code + 1;
  return out;
}

/** A link frame (docs/usb-link.md) around a message's postcard bytes: CRC, COBS, a zero. */
export function linkFrame(message) {
  const c = crc16(message);
  return [...cobs([...message, c & 0xff, c >> 8]), 0];
}

/** The laptop's messages the rig sends (postcard, docs/usb-link.md). */
export const LAPTOP = {
  /** ToDevice::Hello { version 1, address 0, board "x10", robot "" }. */
  hello: () => linkFrame([0, 1, 0, 3, 0x78, 0x31, 0x30, 0]),
  /** ToDevice::Call { id, db, op: { fn_op, port, data } } (id < 128). */
  call: (id, db, fnOp, port, data = []) => linkFrame([2, id, db, fnOp, port, data.length, ...data]),
  /** ToDevice::Diagnostics { id } (id < 128). */
  diagnostics: (id) => linkFrame([3, id]),
};

/** Decodes COBS (`bytes` without the final zero); null when malformed. */
export function uncobs(bytes) {
  const out = [];
  let i = 0;
  while (i < bytes.length) {
    const code = bytes[i];
    if (code === 0 || i + code > bytes.length) return null;
    out.push(...bytes.slice(i + 1, i + code));
    i += code;
    if (code !== 255 && i < bytes.length) out.push(0);
  }
  return out;
}

/**
 * The time stamps (µs of the MB's clock) of the link's records in `received` (the host's IN
 * packets), with the virtual time their frame's last packet arrived: [{ kind, us, t }] for
 * every `Call` (its end) and `Output` (docs/usb-link.md). Other messages are skipped.
 */
export function recordTimes(received) {
  const out = [];
  let frame = [];
  for (const p of received) {
    for (const b of p.bytes) {
      if (b !== 0) { frame.push(b); continue; }
      const msg = uncobs(frame);
      frame = [];
      if (!msg || msg.length < 3) continue;
      const body = msg.slice(0, -2);
      const c = crc16(body);
      if (msg[msg.length - 2] !== (c & 0xff) || msg[msg.length - 1] !== c >> 8) continue;
      let i = 0;
      const varint = () => { let v = 0, s = 1; for (;;) { const x = body[i++]; v += (x & 0x7f) * s; s *= 128; if (x < 0x80) return v; } };
      const tag = varint();
      // (`i += varint()` would add to the old `i`: each length is read first.)
      const skip = (n) => { i += n; };
      if (tag === 2) { // Call: db, fn_op, port, data, outcome, start_us, end_us
        skip(3);
        skip(varint());
        if (varint() === 0) skip(varint()); else if (varint() === 5) skip(1);
        varint();
        out.push({ kind: 'call', us: varint(), t: p.t });
      } else if (tag === 4) { // Output: db, port, value, at_us
        skip(2);
        const v = varint();
        if (v <= 1) skip(1); else varint();
        out.push({ kind: 'output', us: varint(), t: p.t });
      }
    }
  }
  return out;
}

/**
 * Every link message in `received` (the host's IN packets), with the virtual time the packet
 * that ended its frame arrived: [{ tag, body, t }] (`tag`: the `ToHost` variant,
 * docs/usb-link.md; `body`: the postcard bytes after it). A frame that does not decode (COBS,
 * CRC) is { tag: null }.
 */
export function messages(received) {
  const out = [];
  let frame = [];
  for (const p of received) {
    for (const b of p.bytes) {
      if (b !== 0) { frame.push(b); continue; }
      const msg = frame.length ? uncobs(frame) : null;
      const empty = !frame.length;
      frame = [];
      if (empty) continue;
      const body = msg && msg.length >= 3 ? msg.slice(0, -2) : null;
      const c = body ? crc16(body) : -1;
      if (!body || msg[msg.length - 2] !== (c & 0xff) || msg[msg.length - 1] !== c >> 8) {
        out.push({ tag: null, body: [], t: p.t });
        continue;
      }
      // Variants below 128: one byte.
      out.push({ tag: body[0], body: body.slice(1), t: p.t });
    }
  }
  return out;
}

/** The varints of `bytes`, in order (a `Dropped` message's five counters). */
export function varints(bytes) {
  const out = [];
  let v = 0, s = 1;
  for (const x of bytes) {
    v += (x & 0x7f) * s;
    s *= 128;
    if (x < 0x80) { out.push(v); v = 0; s = 1; }
  }
  return out;
}
