//! Boards that act together (issue 27 items 3 and 4): a whole bus read in one sweep
//! ([`MbCore::sweep`]) and outputs on several boards applied at once
//! ([`MbCore::together`]). The frames are `x10_microcode::sweep`'s; the general call and the
//! plain reads are jobs of their own kind ([`JobKind`]) in the one queue the dispatcher
//! serves, so they interleave with other callers' requests as any request does.

use embassy_futures::select::{select, Either};
use heapless::Vec;
use x10_devices::LinkError;
use x10_microcode::sweep::{frame_len, unpack};
use x10_microcode::{
    Address, Op, Payload, Reply, Request, ScanResult, Status, MAX_FRAME_LEN, MAX_REQUEST_DATA,
};

use crate::jobs::{Job, JobKind, JobMeta};
use crate::mb_core::{now, sleep_until, MbCore};
use crate::requests::Ended;

/// Boards one [`MbCore::together`] may name.
pub const MAX_TOGETHER: usize = 8;

/// What one board gave in a [`MbCore::sweep`].
pub type SweepResult = Result<ScanResult, LinkError>;

/// How a sweep went: boards read from the one `sample`, boards read with a `scan` of their
/// own instead (their sweep frame was missing or refused: the board missed the general call,
/// its ports were not known yet, a flipped bit), boards that failed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SweepSummary {
    /// Boards whose values came from the sweep frame.
    pub swept: usize,
    /// Boards read with their own `scan` instead.
    pub scanned: usize,
    /// Boards with an error in their slot of the results.
    pub failed: usize,
}

/// The outputs of a [`MbCore::together`], grouped by board: what the closure set.
#[derive(Default)]
pub struct Together {
    boards: Vec<(Address, Vec<u8, MAX_REQUEST_DATA>), MAX_TOGETHER>,
}

impl Together {
    /// Adds output `op` (io low/high, pwm duty, frequency, pulse width) on board `db`.
    ///
    /// # Errors
    /// [`LinkError::Invalid`] when `op` cannot be staged (not such an output, or a value out
    /// of range), when the board's outputs no longer fit one frame (28 bytes: seven items of
    /// 4 bytes), or when more than [`MAX_TOGETHER`] boards are named.
    pub fn set(&mut self, db: Address, op: Op<'_>) -> Result<(), LinkError> {
        if !op.is_stageable() {
            return Err(LinkError::Invalid(x10_microcode::Error::BadArgument));
        }
        let i = match self.boards.iter().position(|(b, _)| *b == db) {
            Some(i) => i,
            None => {
                self.boards
                    .push((db, Vec::new()))
                    .map_err(|_| LinkError::Invalid(x10_microcode::Error::TooLong))?;
                self.boards.len() - 1
            }
        };
        let Some((_, items)) = self.boards.get_mut(i) else {
            return Err(LinkError::Invalid(x10_microcode::Error::TooLong));
        };
        op.validate()?;
        let mut data = [0u8; MAX_REQUEST_DATA];
        let n = op.emit_data(&mut data)?;
        let too_long = LinkError::Invalid(x10_microcode::Error::TooLong);
        let len = u8::try_from(n).map_err(|_| too_long)?;
        items
            .extend_from_slice(&[op.fn_op_byte(), op.port_byte(), len])
            .map_err(|_| too_long)?;
        items
            .extend_from_slice(data.get(..n).unwrap_or(&[]))
            .map_err(|_| too_long)?;
        Ok(())
    }

    /// The boards named, in the order they were first set.
    pub fn boards(&self) -> impl Iterator<Item = Address> + '_ {
        self.boards.iter().map(|(b, _)| *b)
    }
}

/// A board of a [`MbCore::together`] that did not apply with the others.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotTogether {
    /// The board.
    pub db: Address,
    /// What went wrong: the `stage` refused or lost (nothing was applied anywhere); or the
    /// board did not confirm the general call's `apply` and was sent its own: `Timeout`
    /// when that applied it (late), else that request's error.
    pub error: LinkError,
    /// True when the staging failed: no board applied anything (what the others held is
    /// dropped after `x10_microcode::sweep::STAGE_TIMEOUT_MS`, counted by them).
    pub before_apply: bool,
}

impl MbCore {
    /// One transfer of its own kind ([`JobKind::GeneralCall`] with `frame(seq)` as its
    /// frame, or [`JobKind::PlainRead`] of `read` bytes) through the queue, with a pending
    /// slot and a sequence number of `db` (the motherboard's own address for a general call:
    /// no board's numbers are taken). The sequence number and the raw bytes read.
    async fn raw_call(
        &self,
        db: Address,
        kind: JobKind,
        op: Option<Op<'_>>,
        read: Option<usize>,
    ) -> Result<(u8, Payload), LinkError> {
        self.raw_job(db, kind, read, |seq, frame| {
            if let Some(op) = op {
                let req = Request {
                    db: Address::new(0)?,
                    seq,
                    op,
                };
                let _ = frame.resize(req.buffer_len().min(MAX_FRAME_LEN), 0);
                let n = req.emit(frame).map_err(LinkError::Invalid)?;
                frame.truncate(n);
            }
            Ok(())
        })
        .await
    }

    /// One transfer of kind `kind` through the queue, its frame written by `fill` (given the
    /// sequence number), with a pending slot of `db`: the sequence number and the raw bytes
    /// read.
    pub(crate) async fn raw_job(
        &self,
        db: Address,
        kind: JobKind,
        read: Option<usize>,
        fill: impl FnOnce(u8, &mut Vec<u8, MAX_FRAME_LEN>) -> Result<(), LinkError>,
    ) -> Result<(u8, Payload), LinkError> {
        let deadline = now().plus_us(self.config.request_timeout_us);
        let (ticket, seq) = self.claim_slot(db, deadline).await?;
        let mut frame: Vec<u8, MAX_FRAME_LEN> = Vec::new();
        if let Err(e) = fill(seq, &mut frame) {
            self.with(|t| t.release(ticket, Ended::GaveUp));
            return Err(e);
        }
        let meta = JobMeta {
            ticket,
            kind,
            db,
            seq,
            read,
            deferred: None,
            failsafe_change: None,
        };
        if self.with(|t| t.jobs.push(Job { meta, frame })).is_err() {
            self.with(|t| t.release(ticket, Ended::GaveUp));
            return Err(LinkError::Busy);
        }
        self.job_ready_signal();
        let Some(signal) = self.done.get(ticket.index) else {
            self.with(|t| t.release(ticket, Ended::GaveUp));
            return Err(LinkError::Busy);
        };
        let r = match select(signal.wait(), sleep_until(deadline)).await {
            Either::First(r) => r,
            Either::Second(()) => signal.try_take().unwrap_or(Err(LinkError::Timeout)),
        };
        self.with(|t| t.release(ticket, Ended::Completed));
        r.map(|p| (seq, p))
    }

    /// Reads the sensor ports of every board in `boards` from one moment: one `sample`
    /// written to the general call address (every board samples at once), then one plain
    /// read of each board's sweep frame (its CRC-16, the sample's sequence number and its
    /// status checked). A board whose frame is missing or refused, whose ports are not known
    /// yet, or the internal board (address 0), is read with a `scan` of its own instead; a
    /// board that does not answer gets its error. One board's failure never fails another's.
    /// Results go to `out` in the order of `boards` (as many as both have room for).
    pub async fn sweep(&self, boards: &[Address], out: &mut [SweepResult]) -> SweepSummary {
        let mut summary = SweepSummary::default();
        let sample = self
            .raw_call(
                self.config.address,
                JobKind::GeneralCall,
                Some(Op::Sample),
                None,
            )
            .await
            .ok()
            .map(|(seq, _)| seq);
        for (&db, slot) in boards.iter().zip(out.iter_mut()) {
            let ports = self.with(|t| t.boards.sensor_ports(db));
            let swept = match (sample, ports) {
                (Some(seq), Some(ports)) if !db.is_internal() => {
                    let r = self
                        .raw_call(db, JobKind::PlainRead, None, Some(frame_len(ports)))
                        .await;
                    match r {
                        Ok((_, bytes)) => Reply::parse_read_for(db, true, &bytes, &Op::Sample)
                            .ok()
                            .filter(|r| r.seq == seq && r.status == Status::Ok)
                            .and_then(|r| unpack(ports, r.payload).ok())
                            .map(Ok),
                        // Not there: a scan would not find it either.
                        Err(LinkError::Nack) => Some(Err(LinkError::Nack)),
                        Err(_) => None,
                    }
                }
                _ => None,
            };
            let r = match swept {
                Some(r) => {
                    summary.swept += usize::from(r.is_ok());
                    r
                }
                None => {
                    summary.scanned += 1;
                    self.call(db, Op::Scan)
                        .await
                        .and_then(|p| ScanResult::parse(&p).map_err(|_| LinkError::BadReply))
                }
            };
            summary.failed += usize::from(r.is_err());
            *slot = r;
        }
        summary
    }

    /// Sets outputs on several boards so that they change at once: `set` names them
    /// ([`Together::set`]); each board gets them in one `stage` (checked and held, read back),
    /// then one `apply` written to the general call address makes every board execute what
    /// it holds from the same bytes on the wire (the internal board, address 0, right
    /// after). Each board's confirmation is then read (a plain read of the status it holds);
    /// a board that missed the general call is sent its own `apply` (late) and reported.
    ///
    /// # Errors
    /// The first board that did not apply with the others ([`NotTogether`]); when its
    /// `stage` failed nothing was applied anywhere. A `set` that fails ends it before
    /// anything is sent ([`NotTogether::before_apply`], board 0).
    pub async fn together(
        &self,
        set: impl FnOnce(&mut Together) -> Result<(), LinkError>,
    ) -> Result<(), NotTogether> {
        let mut t = Together::default();
        let internal = Address::new(0).map_err(|e| NotTogether {
            db: self.config.address,
            error: LinkError::Invalid(e),
            before_apply: true,
        })?;
        set(&mut t).map_err(|error| NotTogether {
            db: internal,
            error,
            before_apply: true,
        })?;
        for (db, items) in &t.boards {
            let staged = match x10_microcode::Batch::new_checked(items) {
                Ok(b) => self.call(*db, Op::Stage(b)).await.map(|_| ()),
                Err(e) => Err(LinkError::Invalid(e)),
            };
            staged.map_err(|error| NotTogether {
                db: *db,
                error,
                before_apply: true,
            })?;
        }
        let external = t.boards.iter().any(|(db, _)| !db.is_internal());
        let apply = if external {
            self.raw_call(
                self.config.address,
                JobKind::GeneralCall,
                Some(Op::Apply),
                None,
            )
            .await
            .ok()
            .map(|(seq, _)| seq)
        } else {
            None
        };
        let mut first_err = None;
        for (db, _) in &t.boards {
            let r = if db.is_internal() {
                self.call(*db, Op::Apply).await.map(|_| ())
            } else {
                match apply {
                    Some(seq) if self.applied(*db, seq).await => continue,
                    _ => self.apply_late(*db).await,
                }
            };
            if let (Err(error), None) = (r, &first_err) {
                first_err = Some(NotTogether {
                    db: *db,
                    error,
                    before_apply: false,
                });
            }
        }
        first_err.map_or(Ok(()), Err)
    }

    /// A board that did not confirm the general call's `apply` (it missed it, or its
    /// confirmation was lost): its own `apply`, late. `Err(Timeout)` when that applied it (a
    /// board that had applied already holds nothing and answers `ok` too), else its error.
    async fn apply_late(&self, db: Address) -> Result<(), LinkError> {
        match self.call(db, Op::Apply).await {
            Ok(_) => Err(LinkError::Timeout),
            Err(e) => Err(e),
        }
    }

    /// True when board `db` confirms the `apply` of sequence number `seq` with `ok` (a plain
    /// read of the status reply it holds, with its PEC byte: a general call's reply always
    /// has its check).
    async fn applied(&self, db: Address, seq: u8) -> bool {
        let len = x10_microcode::REPLY_HEADER_LEN + 1;
        match self.raw_call(db, JobKind::PlainRead, None, Some(len)).await {
            Ok((_, bytes)) => Reply::parse_read_for(db, true, &bytes, &Op::Apply)
                .is_ok_and(|r| r.seq == seq && r.status == Status::Ok),
            Err(_) => false,
        }
    }
}
