//! What a finished transfer means for its request: the reply read checked against the
//! operation (sequence number, status, PEC in either mode), the request ended or deferred,
//! the board's PEC state and keepalive updated from what the transfer proved. Shared by the
//! dispatcher and the internal worker; owns no state (it acts on [`crate::table`]'s parts).

use x10_devices::LinkError;
use x10_hal::bus::BusError;
use x10_microcode::{Address, Op, Payload, Reply, Status};

use crate::boards::pec_change;
use crate::diag::bump;
use crate::jobs::{Job, JobMeta};
use crate::mb_core::{now, MbCore};

/// The error a request ends in after a bus error (its last attempt's).
pub(crate) fn link_error(e: BusError) -> LinkError {
    match e {
        BusError::Nack => LinkError::Nack,
        BusError::ArbitrationLost => LinkError::ArbitrationLost,
        BusError::Timeout => LinkError::Timeout,
        BusError::Bus | BusError::Overrun => LinkError::Bus,
    }
}

/// True when a request that ended in `e` may have reached the board and been accepted: every
/// error but a NACK (the board took nothing: a write is NACKed before its end) and a status
/// the board answered.
fn board_may_have_accepted(e: &LinkError) -> bool {
    !matches!(e, LinkError::Nack | LinkError::Status(_))
}

/// The operation of a request frame (PEC byte excluded).
pub(crate) fn request_op(frame: &[u8]) -> Option<Op<'_>> {
    let f = x10_microcode::RequestFrame::new_checked(frame).ok()?;
    let (fn_op, port) = (f.fn_op(), f.port_byte());
    let data = frame.get(x10_microcode::REQUEST_HEADER_LEN..)?;
    Op::parse(fn_op, port, data).ok()
}

/// What a finished transfer means for its request.
pub(crate) enum Outcome {
    Complete(Result<Payload, LinkError>),
    /// `pending`: the board measures; `checked`, the reply carried its check.
    Defer {
        checked: bool,
    },
}

impl MbCore {
    /// Ends a transfer sent with PEC `pec`: `Ok(None)` a write acknowledged,
    /// `Ok(Some(bytes))` the bytes read, or the bus error after every retry.
    pub(crate) fn finish_transfer(&self, job: &Job, pec: bool, r: Result<Option<&[u8]>, BusError>) {
        let meta = &job.meta;
        let replied = matches!(r, Ok(Some(_)));
        // The board saw a transaction: that keeps its failsafe alive (recorded below).
        let acked = r.is_ok();
        if meta.kind != crate::jobs::JobKind::Request {
            // A general call or a plain read: the bytes go back raw, their caller checks them.
            let raw = match r {
                Ok(bytes) => {
                    Payload::from_slice(bytes.unwrap_or(&[])).map_err(|_| LinkError::BadReply)
                }
                Err(e) => Err(link_error(e)),
            };
            self.end_job(meta, Outcome::Complete(raw), acked, replied);
            return;
        }
        let outcome = match r {
            Ok(None) => Outcome::Complete(Ok(Payload::new())),
            Ok(Some(read)) => match request_op(&job.frame) {
                Some(op) => {
                    let (outcome, state) = self.interpret(meta, pec, &op, read);
                    self.board_pec_is(meta.db, state);
                    match (op, &outcome) {
                        (Op::EventEnable(pin, cfg), Outcome::Complete(Ok(_))) => {
                            self.with(|t| {
                                if !t.boards.enabled(meta.db, pin, cfg) {
                                    warn!("no room to remember an event enable");
                                }
                            });
                            outcome
                        }
                        (Op::Identify, Outcome::Complete(Ok(p))) => {
                            if let Ok(id) = x10_microcode::Identity::parse(p) {
                                self.with(|t| {
                                    t.boards.identified(meta.db, &id);
                                    t.directory.identified(meta.db, &id);
                                });
                            }
                            outcome
                        }
                        // A scan must report the ports the board has.
                        (Op::Scan, Outcome::Complete(Ok(p)))
                            if !self.with(|t| t.boards.scan_fits(meta.db, p)) =>
                        {
                            Outcome::Complete(Err(LinkError::BadReply))
                        }
                        _ => outcome,
                    }
                }
                None => Outcome::Complete(Err(LinkError::BadReply)),
            },
            Err(e) => Outcome::Complete(Err(link_error(e))),
        };
        // The board's own reply (its sequence number, its check): it is there.
        if matches!(
            outcome,
            Outcome::Complete(Ok(_) | Err(LinkError::Status(_))) | Outcome::Defer { .. }
        ) && replied
            && self.with(|t| t.directory.answered(meta.db))
        {
            info!("board {} answers again", meta.db.get());
        }
        self.end_job(meta, outcome, acked, replied);
    }

    /// Ends request `meta` with `outcome` (`acked`: the board saw the transaction;
    /// `replied`: a reply was read).
    pub(crate) fn end_job(&self, meta: &JobMeta, outcome: Outcome, acked: bool, replied: bool) {
        self.with(|t| {
            // The clock is read only for a board whose failsafe is kept alive.
            if acked && t.boards.keepalive.tracks(meta.db) {
                t.boards.keepalive.sent(meta.db, now());
            }
            match outcome {
                Outcome::Defer { checked } => {
                    if !t.requests.defer(meta.ticket, meta.deferred, checked, now()) {
                        bump(&mut t.diag.late_replies);
                    }
                }
                Outcome::Complete(r) => {
                    // A `set_failsafe` the board applied is kept alive, whether or not the
                    // caller still waits (a `set_pec`: `board_pec_is`).
                    if let (Ok(_), Some(ms)) = (&r, meta.failsafe_change) {
                        t.boards.failsafe_set(meta.db, ms, now());
                    }
                    // A deferred request that ends without a reply that proves the board
                    // refused it (its `pending` lost to a bus error or a bad check) may be
                    // measuring all the same: its (board, sequence number) pair is held
                    // until the board's deadline, so its deferred reply, if it comes, is
                    // counted as late and never completes a later request.
                    if let (Err(e), Some(deferred)) = (&r, meta.deferred) {
                        if board_may_have_accepted(e) {
                            t.requests.hold(meta.ticket, deferred, now());
                        }
                    }
                    // Likewise a `set_failsafe` the board may have applied: the faster of
                    // the two keepalives is kept, so the board trips with neither.
                    if let (Err(e), Some(ms)) = (&r, meta.failsafe_change) {
                        if board_may_have_accepted(e) {
                            t.boards.keepalive.maybe_set(meta.db, ms, now());
                            t.boards.keepalive_changed_now();
                        }
                    }
                    if t.requests.complete(meta.ticket, &r, &mut t.diag) {
                        if let Some(s) = self.done.get(meta.ticket.index) {
                            s.signal(r);
                        }
                    } else {
                        if replied {
                            // The caller gave up while the transfer was on the bus.
                            bump(&mut t.diag.late_replies);
                        }
                        t.requests.transfer_ended(meta.ticket);
                        t.slot_waiters.wake();
                    }
                }
            }
        });
        self.notify_keepalive();
    }

    /// What the bytes read for request `meta` (operation `op`, sent with PEC `pec`) mean, and
    /// the PEC state of the board when the reply proves it.
    ///
    /// The reply must fit the operation ([`Reply::parse_read_for`]: an `ok` of a length the
    /// operation allows, anything else empty; the PEC byte located without trusting an
    /// unchecked byte). A `set_pec` is answered in its new mode: its reply is parsed that way
    /// first, and only a reply checked in the new mode (for `set_pec(1)`: with its PEC)
    /// confirms the switch. A `pec_mismatch` answer to a frame sent without PEC counts only
    /// with a valid PEC byte (only a board with PEC on sends it, and a flipped status bit
    /// must not turn it into `ok`): it proves the board has PEC on.
    pub(crate) fn interpret(
        &self,
        meta: &JobMeta,
        pec: bool,
        op: &Op<'_>,
        read: &[u8],
    ) -> (Outcome, Option<bool>) {
        let db = meta.db;
        let switch = pec_change(op);
        let mode = switch.unwrap_or(pec);
        // A board that refused the switch answers in the old mode.
        let parsed = match Reply::parse_read_for(db, mode, read, op) {
            Ok(r) => Some((r, mode)),
            Err(_) if mode != pec => Reply::parse_read_for(db, pec, read, op)
                .ok()
                .map(|r| (r, pec)),
            Err(_) => None,
        };
        let Some((reply, answered_in)) = parsed else {
            self.pec_off_sign(meta, pec, op, read);
            return (Outcome::Complete(Err(LinkError::BadReply)), None);
        };
        if reply.seq != meta.seq {
            warn!(
                "reply from {} has seq {} for request {}",
                db.get(),
                reply.seq,
                meta.seq
            );
            self.with(|t| t.requests.stray(db, reply.seq, &mut t.diag));
            return (Outcome::Complete(Err(LinkError::BadReply)), None);
        }
        match reply.status {
            // A switch is confirmed only by an `ok` in its new mode.
            Status::Ok if switch.is_some() && answered_in != mode => {
                (Outcome::Complete(Err(LinkError::BadReply)), None)
            }
            Status::Ok => match Payload::from_slice(reply.payload) {
                Ok(p) => (Outcome::Complete(Ok(p)), switch),
                Err(_) => (Outcome::Complete(Err(LinkError::BadReply)), None),
            },
            Status::Pending if meta.deferred.is_some() => (
                Outcome::Defer {
                    checked: answered_in,
                },
                None,
            ),
            Status::Pending => (Outcome::Complete(Err(LinkError::BadReply)), None),
            Status::PecMismatch if !pec => {
                // Only a board that checks PEC answers this, with its PEC byte: check it.
                match Reply::parse_read_for(db, true, read, op) {
                    Ok(r) if r.seq == meta.seq && r.status == Status::PecMismatch => {
                        warn!("board {} checks PEC: PEC on", db.get());
                        self.with(|t| bump(&mut t.diag.pec_resyncs));
                        (
                            Outcome::Complete(Err(LinkError::Status(Status::PecMismatch))),
                            Some(true),
                        )
                    }
                    _ => (Outcome::Complete(Err(LinkError::BadReply)), None),
                }
            }
            s => (Outcome::Complete(Err(LinkError::Status(s))), None),
        }
    }

    /// Records the PEC state a reply proved for `db`. With the safe defaults a board found
    /// with PEC off is prepared again before its next request.
    pub(crate) fn board_pec_is(&self, db: Address, state: Option<bool>) {
        let Some(on) = state else { return };
        let manages = self.config.pec;
        self.with(|t| {
            t.boards.set_pec(db, on);
            if !on && manages {
                t.boards.set_ready(db, false);
            }
        });
    }

    /// A reply that failed its PEC check but reads, without PEC, as `bad_length`: the board
    /// took our PEC byte for data, so it has PEC off (it restarted and its boot event was
    /// lost). Recorded here as unchecked ([`crate::boards::Boards::pec_lost_unchecked`]): it
    /// only ever leads to switching PEC on again, never to accepting a value or an unchecked
    /// event.
    fn pec_off_sign(&self, meta: &JobMeta, pec: bool, op: &Op<'_>, read: &[u8]) {
        if !pec {
            return;
        }
        if let Ok(reply) = Reply::parse_read_for(meta.db, false, read, op) {
            if reply.seq == meta.seq && reply.status == Status::BadLength {
                warn!("board {} has PEC off", meta.db.get());
                // Unchecked: requests go without PEC (prepared again first with the safe
                // defaults), events must still be checked.
                self.with(|t| {
                    bump(&mut t.diag.pec_resyncs);
                    t.boards.pec_lost_unchecked(meta.db);
                });
            }
        }
    }
}
