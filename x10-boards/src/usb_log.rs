//! The defmt global logger of the motherboard images with the USB link (feature `usb-log`):
//! it writes the RTT up-channel exactly as defmt-rtt 1.x does (the same `_SEGGER_RTT` control
//! block, one up-channel named `defmt` of 1 KiB, the same rzCOBS frames from defmt's own
//! encoder), so `probe-rs run`, `defmt-print` and the emulator rig read the log as before, and
//! copies every frame to the link's recorder ([`crate::usb_link::RECORDER`]) as `Log`
//! messages while a laptop listens (docs/usb-link.md, "The log").
//!
//! defmt allows one global logger per image, and defmt-rtt's gives no way to see its bytes:
//! an image with this feature does not link defmt-rtt (`use defmt_rtt as _` only without it).
//!
//! Never blocking a robot task: the copy to the link takes the recorder's critical section and
//! drops (and counts, `Dropped.log_bytes`) what does not fit its ring. The RTT side waits for
//! room only when a probe asked for it (blocking mode, as defmt-rtt). A log statement inside
//! a log statement (a panic while logging) is dropped instead of panicking again. The ring
//! arithmetic and the cutting into messages are [`crate::rtt`], tested on the host.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

use crate::rtt::{host_waits, put, room, Chunker, MODE_NON_BLOCKING_TRIM};

/// Bytes of the RTT up-channel (defmt-rtt's default).
pub const RTT_BYTES: usize = 1024;

/// One RTT up-channel, laid out as SEGGER's `SEGGER_RTT_BUFFER_UP`.
#[repr(C)]
struct Channel {
    name: *const u8,
    buffer: *mut u8,
    size: u32,
    write: AtomicU32,
    read: AtomicU32,
    flags: AtomicU32,
}

/// The control block the host finds by its id (`SEGGER RTT`) or by the symbol.
#[repr(C)]
struct Header {
    id: [u8; 16],
    max_up_channels: u32,
    max_down_channels: u32,
    up: Channel,
}

// SAFETY: the host reads and writes the block behind the target's back by design; on the
// target every access is from inside the logger's critical section (`acquire`..`release`)
// or through the atomics.
unsafe impl Sync for Header {}

struct Ring(UnsafeCell<[u8; RTT_BYTES]>);

// SAFETY: written only inside the logger's critical section.
unsafe impl Sync for Ring {}

/// The channel's bytes: not zeroed at boot (`.uninit`, as defmt-rtt's).
#[link_section = ".uninit.x10-log.BUFFER"]
static BUFFER: Ring = Ring(UnsafeCell::new([0; RTT_BYTES]));

/// In RAM, so the host can read the whole block from RAM.
#[link_section = ".data.x10-log.NAME"]
static NAME: [u8; 6] = *b"defmt\0";

#[no_mangle]
static _SEGGER_RTT: Header = Header {
    id: *b"SEGGER RTT\0\0\0\0\0\0",
    max_up_channels: 1,
    max_down_channels: 0,
    up: Channel {
        name: NAME.as_ptr(),
        buffer: BUFFER.0.get().cast(),
        // RTT_BYTES is 1024: no truncation.
        size: RTT_BYTES as u32,
        write: AtomicU32::new(0),
        read: AtomicU32::new(0),
        flags: AtomicU32::new(MODE_NON_BLOCKING_TRIM),
    },
};

/// Writes `bytes` to the up-channel: all of them, waiting for room when the host asked for it.
fn rtt_write(mut bytes: &[u8]) {
    let ch = &_SEGGER_RTT.up;
    let waits = host_waits(ch.flags.load(Ordering::Relaxed));
    // SAFETY: inside the logger's critical section (only `Logger`'s methods call this), so
    // nothing else on the target touches the ring; the host only reads it.
    let ring = unsafe { &mut *BUFFER.0.get() };
    while !bytes.is_empty() {
        let write = ch.write.load(Ordering::Acquire) as usize;
        let limit = if waits {
            room(ch.read.load(Ordering::Relaxed) as usize, write, RTT_BYTES)
        } else {
            RTT_BYTES
        };
        let (n, next) = put(ring, write, bytes, limit);
        // `next` < RTT_BYTES: fits.
        ch.write.store(next as u32, Ordering::Release);
        bytes = bytes.get(n..).unwrap_or(&[]);
    }
}

/// The logger's state, used between `acquire` and `release` only.
struct State {
    /// Nesting of `acquire` (more than 1: a log inside a log, dropped).
    depth: UnsafeCell<u8>,
    restore: UnsafeCell<critical_section::RestoreState>,
    encoder: UnsafeCell<defmt::Encoder>,
    link: UnsafeCell<Chunker<{ x10_link::MAX_LOG_CHUNK }>>,
}

// SAFETY: every field is accessed inside the critical section `acquire` takes.
unsafe impl Sync for State {}

static STATE: State = State {
    depth: UnsafeCell::new(0),
    restore: UnsafeCell::new(critical_section::RestoreState::invalid()),
    encoder: UnsafeCell::new(defmt::Encoder::new()),
    link: UnsafeCell::new(Chunker::new()),
};

/// Every encoded byte: to RTT, and to the link's piece of the frame.
fn out(bytes: &[u8]) {
    rtt_write(bytes);
    // SAFETY: inside the critical section, depth 1 (see `Logger`).
    let link = unsafe { &mut *STATE.link.get() };
    link.push(bytes, &mut |piece| crate::usb_link::RECORDER.log(piece));
}

#[defmt::global_logger]
struct Logger;

// SAFETY: `acquire` takes a critical section that `release` gives back, so the encoder and
// the ring have one user at a time; nested use is counted and ignored.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with the `release` in `Logger::release`.
        let restore = unsafe { critical_section::acquire() };
        // SAFETY: inside the critical section.
        unsafe {
            let depth = &mut *STATE.depth.get();
            *depth = depth.saturating_add(1);
            if *depth > 1 {
                // A log inside a log: give this critical section back at once (the outer one
                // still holds), and ignore everything until the matching release.
                critical_section::release(restore);
                return;
            }
            STATE.restore.get().write(restore);
            (*STATE.encoder.get()).start_frame(out);
        }
    }

    unsafe fn flush() {
        let ch = &_SEGGER_RTT.up;
        if !host_waits(ch.flags.load(Ordering::Relaxed)) {
            return;
        }
        while ch.read.load(Ordering::Relaxed) != ch.write.load(Ordering::Relaxed) {}
    }

    unsafe fn release() {
        // SAFETY: called after `acquire`, inside its critical section.
        unsafe {
            let depth = &mut *STATE.depth.get();
            if *depth != 1 {
                *depth = depth.saturating_sub(1);
                return;
            }
            (*STATE.encoder.get()).end_frame(out);
            (*STATE.link.get()).end(&mut |piece| crate::usb_link::RECORDER.log(piece));
            *depth = 0;
            critical_section::release(STATE.restore.get().read());
        }
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: called after `acquire`, inside its critical section.
        unsafe {
            if *STATE.depth.get() != 1 {
                return;
            }
            (*STATE.encoder.get()).write(bytes, out);
        }
    }
}
