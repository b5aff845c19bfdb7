//! Counters of the motherboard runtime: [`MbDiagnostics`], kept with the bookkeeping under
//! the motherboard's lock and counted by every part of it.

use x10_devices::LinkError;

/// What the motherboard runtime counted since start (each saturating at `u32::MAX`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MbDiagnostics {
    /// Requests accepted by `call` (valid operation, a free pending slot).
    pub requests: u32,
    /// Requests that ended with a value.
    pub completed: u32,
    /// Requests that ended in `LinkError::Timeout`.
    pub timeouts: u32,
    /// Requests that ended in `LinkError::Nack` (after every retry).
    pub nacks: u32,
    /// Requests that ended in `LinkError::ArbitrationLost` (after every retry).
    pub arbitration_failures: u32,
    /// Requests that ended in `LinkError::Bus`.
    pub bus_errors: u32,
    /// Requests that ended in `LinkError::BadReply` (unparsable reply or wrong PEC).
    pub bad_replies: u32,
    /// Requests that ended in `LinkError::Status` (the board refused them).
    pub status_errors: u32,
    /// Requests refused with `LinkError::Busy` (no free pending slot or sequence number).
    pub busy: u32,
    /// Bus transactions lost in arbitration (each attempt).
    pub arbitration_lost: u32,
    /// Bus transactions NACKed (each attempt).
    pub nacked: u32,
    /// Heartbeats the failsafe keepalive sent (by the dispatcher, or the internal worker, between jobs).
    pub keepalives: u32,
    /// Failsafes the keepalive set again after the board's `boot` event.
    pub failsafe_resends: u32,
    /// Keepalive attempts that failed (also counted as the request's own outcome).
    pub keepalive_failures: u32,
    /// Bus transactions retried.
    pub retries: u32,
    /// Failed attempts not counted against the retry policy because a write to the
    /// motherboard (an event that won the bus) arrived before the retry.
    pub yields: u32,
    /// Requests whose caller went away (its future was dropped) before they ended.
    pub cancelled: u32,
    /// Jobs dropped by the dispatcher because their caller had already given up.
    pub abandoned: u32,
    /// Replies or deferred replies for a request that had already timed out or been dropped.
    pub late_replies: u32,
    /// Replies or deferred replies for a request that had already completed.
    pub duplicate_replies: u32,
    /// Replies or deferred replies matching no recent request.
    pub unknown_replies: u32,
    /// Events received (bus and internal board).
    pub events: u32,
    /// Writes to the motherboard that were not a valid event (length, source, a wrong check,
    /// or none from a board with PEC on, or a `boot` event without its check), or an event
    /// of unknown kind.
    pub bad_events: u32,
    /// Pin events that no task claimed and that were pushed out of the unclaimed queue.
    pub events_dropped: u32,
    /// `rejected` events (a board refused an output).
    pub rejected: u32,
    /// `failsafe_tripped` events.
    pub failsafe_trips: u32,
    /// `boot` events (a board started or restarted).
    pub boots: u32,
    /// `boot` events whose reason is the board's watchdog (its executor hung).
    pub watchdog_resets: u32,
    /// `boot` events whose reason is a panic of the board's firmware.
    pub panic_resets: u32,
    /// `boot` events whose reason is a processor fault (HardFault) on the board.
    pub fault_resets: u32,
    /// `overflow` events (a board dropped events).
    pub overflows: u32,
    /// Events missing from a board's event counter (byte 3 of every event but
    /// `deferred_reply` and `rejected`): events the board dropped (also reported in
    /// `events_lost`) or that were lost on the bus (then in `bad_events` or nowhere else).
    pub event_gaps: u32,
    /// Events the boards reported dropped, from the cumulative count of their `overflow`
    /// events (so a lost report loses no count).
    pub events_lost: u32,
    /// Times the PEC setting of a board was corrected from what it sent (it answered
    /// `pec_mismatch` to a frame without PEC, or `bad_length` without PEC to one with PEC,
    /// or sent an event without PEC while the motherboard had PEC on for it).
    pub pec_resyncs: u32,
    /// Reads addressed to the motherboard (answered with nothing).
    pub unexpected_reads: u32,
    /// Listener errors.
    pub listener_errors: u32,
    /// `announce` events received (plug and play: from unaddressed boards, and boards
    /// answering `who_is_there`).
    pub announces: u32,
    /// `assign` frames sent to unaddressed boards.
    pub assigns: u32,
    /// Announces from unaddressed boards that got no address (no directory, no room, no free
    /// address, or no ID).
    pub unassigned: u32,
    /// Boards first known by their ID (from a `boot` or an `announce`, an unaddressed
    /// board's included).
    pub boards_found: u32,
    /// Known boards that stopped answering (a request to them ended in a NACK).
    pub boards_lost: u32,
    /// Two IDs heard from one address (two boards answer there).
    pub collisions: u32,
}

impl MbDiagnostics {
    /// Every counter at 0 (as `Default`, for a `const` table).
    pub(crate) const fn new() -> MbDiagnostics {
        MbDiagnostics {
            requests: 0,
            completed: 0,
            timeouts: 0,
            nacks: 0,
            arbitration_failures: 0,
            bus_errors: 0,
            bad_replies: 0,
            status_errors: 0,
            busy: 0,
            arbitration_lost: 0,
            nacked: 0,
            retries: 0,
            yields: 0,
            keepalives: 0,
            failsafe_resends: 0,
            keepalive_failures: 0,
            abandoned: 0,
            cancelled: 0,
            late_replies: 0,
            duplicate_replies: 0,
            unknown_replies: 0,
            events: 0,
            bad_events: 0,
            events_dropped: 0,
            rejected: 0,
            failsafe_trips: 0,
            boots: 0,
            watchdog_resets: 0,
            panic_resets: 0,
            fault_resets: 0,
            overflows: 0,
            event_gaps: 0,
            events_lost: 0,
            pec_resyncs: 0,
            unexpected_reads: 0,
            listener_errors: 0,
            announces: 0,
            assigns: 0,
            unassigned: 0,
            boards_found: 0,
            boards_lost: 0,
            collisions: 0,
        }
    }
}

/// Adds one, stopping at the maximum.
pub(crate) fn bump(c: &mut u32) {
    *c = c.saturating_add(1);
}

/// Counts how a request ended: `completed`, or the counter of its error.
pub(crate) fn count_outcome<T>(d: &mut MbDiagnostics, result: &Result<T, LinkError>) {
    match result {
        Ok(_) => bump(&mut d.completed),
        Err(LinkError::Timeout) => bump(&mut d.timeouts),
        Err(LinkError::Nack) => bump(&mut d.nacks),
        Err(LinkError::ArbitrationLost) => bump(&mut d.arbitration_failures),
        Err(LinkError::Bus) => bump(&mut d.bus_errors),
        Err(LinkError::BadReply) => bump(&mut d.bad_replies),
        Err(LinkError::Status(_)) => bump(&mut d.status_errors),
        Err(
            LinkError::Invalid(_) | LinkError::Busy | LinkError::Unsupported | LinkError::Updating,
        ) => {}
    }
}
