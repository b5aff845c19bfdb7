//! Events waiting to be delivered to the motherboard.

use heapless::Vec;
use x10_microcode::{Address, BootInfo, Event, EventKind, PinRef, Status};

/// Largest payload of an event this runtime queues (the boot event's [`BootInfo`] without the
/// board's ID, which is appended when the event is encoded).
pub const EVENT_PAYLOAD_LEN: usize = BootInfo::LEN_NO_UID;

/// An event in the queue of a daughterboard, before the sender's address and the PEC are
/// added. The transport turns it into an [`Event`] with [`OutEvent::as_event`].
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OutEvent {
    /// What happened.
    pub kind: EventKind,
    /// Port and pin concerned (`PinRef::from_byte(0)` when none).
    pub pin: PinRef,
    /// The request's sequence number (deferred reply, rejected), otherwise the board's own
    /// event counter.
    pub seq: u8,
    /// The request's status (deferred reply, rejected), otherwise `ok`.
    pub status: Status,
    /// Value bytes.
    pub payload: Vec<u8, EVENT_PAYLOAD_LEN>,
}

impl OutEvent {
    /// An event; a payload longer than [`EVENT_PAYLOAD_LEN`] is cut there (the runtime never
    /// builds one).
    pub fn new(kind: EventKind, pin: PinRef, seq: u8, status: Status, payload: &[u8]) -> OutEvent {
        let n = payload.len().min(EVENT_PAYLOAD_LEN);
        let mut v = Vec::new();
        // Cannot fail: `n` is at most the capacity.
        let _ = v.extend_from_slice(payload.get(..n).unwrap_or(&[]));
        OutEvent {
            kind,
            pin,
            seq,
            status,
            payload: v,
        }
    }

    /// The wire representation, sent by board `source`.
    pub fn as_event(&self, source: Address) -> Event<'_> {
        Event {
            source,
            kind: self.kind,
            pin: self.pin,
            seq: self.seq,
            status: self.status,
            payload: &self.payload,
        }
    }
}
