//! Where events go: a write to the motherboard's address parsed as an event (PEC as the
//! board has it), then a deferred reply to its waiting request, a pin event to the tasks
//! waiting for it ([`crate::waiters`]) or the unclaimed queue, the rest to the counters and
//! the log; and [`MbCore::wait_event`], the waiting side. Bus events and the internal
//! daughterboard's events go the same way. Owns no state.

use embassy_sync::signal::Signal;
use x10_devices::{LinkError, PinEvent};
use x10_microcode::{
    Address, BootInfo, Edge, Event, EventKind, Op, Payload, PinRef, ResetReason, Status,
};

use crate::diag::bump;
use crate::directory::Heard;
use crate::mb_core::{now, MbCore};
use crate::table::Table;
use crate::waiters::WaiterTicket;

/// Unregisters an event waiter whose future is dropped; an event already delivered to it goes
/// back to the front of the unclaimed queue.
struct WaiterGuard<'a> {
    mb: &'a MbCore,
    ticket: WaiterTicket,
    armed: bool,
}

impl Drop for WaiterGuard<'_> {
    fn drop(&mut self) {
        if !self.armed {
            return;
        }
        let (mb, ticket) = (self.mb, self.ticket);
        mb.with(|t| {
            if t.waiters.unwait(ticket) {
                if let Some(ev) = mb.waiters.get(ticket.index).and_then(Signal::try_take) {
                    t.waiters.keep_unclaimed(ev, true, &mut t.diag);
                }
            }
        });
    }
}

impl MbCore {
    /// Parses a write to the motherboard's own address as an event and routes it. Anything
    /// else is counted in `bad_events` and dropped.
    ///
    /// A `boot` event is accepted only with its check (a PEC byte, or the CRC-16 of a long
    /// frame): a board sends it so whatever its PEC setting, since it is the one frame sent
    /// before the motherboard could switch PEC on. From a board with PEC negotiated
    /// ([`MbCore::pec_enabled`]) every event must carry a valid check. From a board with PEC
    /// off, the frame is parsed without PEC first and, if that fails, with PEC: a board that
    /// has just executed a `set_pec(true)` the motherboard has not recorded yet sends its
    /// events with PEC. The two readings never both succeed: the LEN byte fixes the frame's
    /// length, and the check makes it one or two bytes longer.
    ///
    /// An event without its check from a board with PEC negotiated is dropped; but when the
    /// motherboard prepares its boards (`MbConfig::pec`) and that event is a `rejected` with
    /// status `bad_length` (the board took our check for data: it has PEC off, so it
    /// restarted and its `boot` event was lost), the board is taken as restarted: PEC off,
    /// prepared again before its next request, its failsafe set again. An unchecked frame
    /// only ever leads to that preparation, never to a value or an output.
    pub(crate) fn route_event_bytes(&self, bytes: &[u8]) {
        let source = bytes.first().and_then(|&b| Address::new(b).ok());
        // With the safe defaults every external board's events carry their check; otherwise
        // once a checked reply showed the board has PEC on (an unchecked sign that it lost
        // PEC does not lift this: only a checked boot event or a confirmed `set_pec(0)`).
        let pec_on = source.is_some_and(|source| {
            !source.is_internal()
                && (self.config.pec || self.with(|t| t.boards.events_checked(source)))
        });
        let with_pec = || Event::parse_with_pec(self.config.address, bytes);
        let unchecked = || {
            Event::parse(bytes).and_then(|ev| {
                if ev.always_checked() {
                    Err(x10_microcode::Error::CrcMismatch)
                } else {
                    Ok(ev)
                }
            })
        };
        let parsed = if pec_on {
            with_pec().map(|ev| (ev, true))
        } else {
            unchecked()
                .map(|ev| (ev, false))
                .or_else(|_| with_pec().map(|ev| (ev, true)))
        };
        match parsed {
            Ok((ev, checked)) if !ev.source.is_internal() => self.route_event(&ev, checked),
            _ => {
                warn!("bad event ({} bytes)", bytes.len());
                self.with(|t| bump(&mut t.diag.bad_events));
                match source {
                    Some(board)
                        if pec_on
                            && self.with(|t| t.boards.pec(board))
                            && self.lost_pec_sign(board, bytes) =>
                    {
                        warn!("board {} refuses our PEC: it restarted", board.get());
                        let t_now = now();
                        self.with(|t| {
                            bump(&mut t.diag.pec_resyncs);
                            t.boards.pec_lost_unchecked(board);
                            // Its failsafe is off too: set it again at once.
                            if t.boards.keepalive.booted(board, t_now) {
                                t.boards.keepalive_changed_now();
                            }
                        });
                        self.notify_keepalive();
                    }
                    _ => {}
                }
            }
        }
    }

    /// True when `bytes`, without a check, read as a `rejected` event with status
    /// `bad_length` from `board`, and the motherboard prepares its boards: see
    /// [`MbCore::route_event_bytes`].
    fn lost_pec_sign(&self, board: Address, bytes: &[u8]) -> bool {
        self.config.pec
            && !board.is_internal()
            && Event::parse(bytes).is_ok_and(|ev| {
                ev.source == board
                    && ev.kind == EventKind::Rejected
                    && ev.status == Status::BadLength
            })
    }

    /// Routes one event: a deferred reply to its waiting request, a pin event to its waiters
    /// (or the unclaimed queue), the rest to the counters and the log.
    pub(crate) fn route_event(&self, ev: &Event<'_>, checked: bool) {
        if let Some(observer) = self.observer {
            observer.event(ev, now());
        }
        self.with(|t| {
            bump(&mut t.diag.events);
            t.events_in.received(ev, &mut t.diag);
        });
        match ev.kind {
            EventKind::DeferredReply => self.with(|t| {
                // Matched by board, sequence number and pin; a reply for a request that gave
                // up is counted as late (see `Requests::take_deferred`).
                let Some(ticket) =
                    t.requests
                        .take_deferred(ev.source, ev.seq, ev.pin, checked, &mut t.diag)
                else {
                    // A late reply may have freed its abandoned request's slot.
                    t.slot_waiters.wake();
                    return;
                };
                // Checked against the operation: every deferred request is a pulse-in
                // (`ok` with its 4-byte width, or another status with nothing).
                let pulse_in = Op::PulseIn {
                    pin: ev.pin,
                    edge: Edge::Rising,
                    timeout_ms: None,
                };
                let r = match (pulse_in.check_deferred(ev.status, ev.payload), ev.status) {
                    (Err(_), _) => Err(LinkError::BadReply),
                    (Ok(()), Status::Ok) => {
                        Payload::from_slice(ev.payload).map_err(|_| LinkError::BadReply)
                    }
                    (Ok(()), s) => Err(LinkError::Status(s)),
                };
                if t.requests.complete(ticket, &r, &mut t.diag) {
                    if let Some(s) = self.done.get(ticket.index) {
                        s.signal(r);
                    }
                }
            }),
            EventKind::PinChange | EventKind::AnalogThreshold => {
                let Ok(value) = Payload::from_slice(ev.payload) else {
                    return;
                };
                let pe = PinEvent {
                    source: ev.source,
                    kind: ev.kind,
                    pin: ev.pin,
                    value,
                };
                self.with(|t| {
                    t.waiters.deliver(&pe, &mut t.diag, |i| {
                        if let Some(s) = self.waiters.get(i) {
                            s.signal(pe.clone());
                        }
                    })
                });
            }
            EventKind::Rejected => {
                warn!(
                    "board {} rejected request {}: {}",
                    ev.source.get(),
                    ev.seq,
                    ev.status.name()
                );
                self.with(|t| bump(&mut t.diag.rejected));
            }
            EventKind::FailsafeTripped => {
                warn!("board {} failsafe tripped", ev.source.get());
                self.with(|t| bump(&mut t.diag.failsafe_trips));
            }
            EventKind::Overflow => {
                warn!("board {} dropped events", ev.source.get());
                self.with(|t| bump(&mut t.diag.overflows));
            }
            EventKind::Announce => self.announced(ev),
            EventKind::Boot => {
                let boot = BootInfo::parse(ev.payload).ok();
                let reason = boot.map_or(ResetReason::Unknown(0xFF), |b| b.reset_reason);
                info!("board {} booted ({})", ev.source.get(), reason.name());
                if let Some(b) = &boot {
                    self.seen(ev.source, b);
                }
                self.with(|t| {
                    if let Some(b) = boot {
                        t.boards.identified(ev.source, &b.identity);
                    }
                    bump(&mut t.diag.boots);
                    match reason {
                        ResetReason::Watchdog => bump(&mut t.diag.watchdog_resets),
                        ResetReason::Panic => bump(&mut t.diag.panic_resets),
                        ResetReason::Fault => bump(&mut t.diag.fault_resets),
                        _ => {}
                    }
                    t.boards.booted(ev.source, now());
                });
            }
            EventKind::Unknown(_) => self.with(|t| bump(&mut t.diag.bad_events)),
        }
        self.notify_keepalive();
    }

    /// A board said who it is from `source` (its `boot`, or an `announce` answering
    /// `who_is_there`): recorded in the directory; a second ID from one address is a
    /// collision, counted and logged, never merged.
    fn seen(&self, source: Address, info: &BootInfo) {
        let t_now = now();
        let heard = self.with(|t| {
            let h = t.directory.seen(source, info, t_now);
            match h {
                Heard::New => bump(&mut t.diag.boards_found),
                Heard::Collision => bump(&mut t.diag.collisions),
                _ => {}
            }
            h
        });
        if heard == Heard::Collision {
            warn!("two boards answer at {}: collision", source.get());
        }
    }

    /// An `announce`: from an unaddressed board, an address is chosen and an `assign` queued
    /// for the dispatcher; from a board with an address, as [`MbCore::seen`]. One without a
    /// valid `BootInfo` with an ID is counted in `bad_events` and dropped.
    fn announced(&self, ev: &Event<'_>) {
        let info = match BootInfo::parse(ev.payload) {
            Ok(b) if b.uid.is_some() => b,
            _ => {
                self.with(|t| bump(&mut t.diag.bad_events));
                return;
            }
        };
        self.with(|t| bump(&mut t.diag.announces));
        if !ev.source.is_unaddressed() {
            self.seen(ev.source, &info);
            return;
        }
        let t_now = now();
        let heard = self.with(|t| {
            let Table {
                directory,
                boards,
                diag,
                ..
            } = t;
            let h = directory.announced(
                &info,
                self.config.pinned,
                self.config.address,
                |a| boards.ports_known(a),
                t_now,
            );
            match h {
                Heard::NoRoom => bump(&mut diag.unassigned),
                Heard::Assign { new: true, .. } => bump(&mut diag.boards_found),
                _ => {}
            }
            h
        });
        if let Heard::Assign { address, .. } = heard {
            info!("unaddressed board gets {}", address.get());
            // The dispatcher looks at its work again.
            self.notify_keepalive();
        } else {
            warn!("unaddressed board: no address for it");
        }
    }

    /// Waits for the next pin-change or analog-threshold event from `pin` on board `db`. An
    /// event that arrived while no task waited for it is kept (up to
    /// [`crate::UNCLAIMED_EVENTS`], oldest dropped first and counted) and returned at once.
    /// Every task waiting for the same pin gets the event.
    ///
    /// # Errors
    /// [`LinkError::Busy`] when [`crate::MAX_EVENT_WAITERS`] tasks already wait.
    pub async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        // The task's waker identifies it: its next wait for the same pin takes the same slot.
        let task = core::future::poll_fn(|cx| core::task::Poll::Ready(cx.waker().clone())).await;
        let registered = self.with(|t| {
            let r = t.waiters.wait_for(db, pin, &task, &mut t.diag);
            if let Ok(Err(ticket)) = r {
                if let Some(s) = self.waiters.get(ticket.index) {
                    s.reset();
                }
            }
            r
        })?;
        let ticket = match registered {
            Ok(ev) => return Ok(ev),
            Err(ticket) => ticket,
        };
        let Some(signal) = self.waiters.get(ticket.index) else {
            return Err(LinkError::Busy);
        };
        let mut guard = WaiterGuard {
            mb: self,
            ticket,
            armed: true,
        };
        let ev = signal.wait().await;
        guard.armed = false;
        self.with(|t| t.waiters.took(ticket));
        Ok(ev)
    }
}
