// The bus lines as the chips' pins see them: SDA (GP0) and SCL (GP1) of every chip on the rig,
// set from the bus model (./bus.js) after every quantum, so that firmware sampling its pins
// (db-pico and mb-pico before a block reset starts a transfer, issue 21 item 3) sees the bus.
//
// Approximate, as the bus model is per byte: idle (no START pending, no transfer) = both high;
// a transfer under way = SDA low and SCL toggling every quantum (1 µs), or held low while a
// block stretches SCL (a read request with an empty TX FIFO, a full RX FIFO, a controller
// without commands). Not modelled: the real bit pattern, SDA's changes, rise times.
export const SDA_GPIO = 0;
export const SCL_GPIO = 1;

/** Drives GP0/GP1 of every chip of `rig` from its bus, after every quantum. */
export function driveLines(rig) {
  let phase = false;
  rig.hooks.push(() => {
    const bus = rig.bus;
    const idle = bus.state === 'idle';
    const held = !idle && bus.nodes.some((n) => n.stall);
    phase = !phase;
    const scl = idle || (!held && phase);
    for (const c of rig.chips) {
      c.setPin(SDA_GPIO, idle);
      c.setPin(SCL_GPIO, scl);
    }
  });
}
