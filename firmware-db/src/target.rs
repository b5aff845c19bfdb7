//! A daughterboard on the bus: the target listener and the event sender, on one
//! [`MultiMaster`] port.

use embassy_futures::join::join;
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::RawMutex;
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::retry::Backoff;
use x10_hal::time::{Clock, Instant};
use x10_microcode::MAX_FRAME_LEN;

use crate::config::TargetConfig;
use crate::daughterboard::{bump, Daughterboard};
use crate::event::OutEvent;
use x10_hal::ports::Ports;

/// Attempts of one event that may fail because the board was being addressed without
/// counting against its [`x10_hal::retry::RetryPolicy`] (see [`run_target`]). Past this many
/// the attempts count again, so an event cannot be postponed forever by a motherboard that
/// polls the board back to back and wins every arbitration (an MB whose own address is not the
/// lowest on the bus).
pub const MAX_EVENT_YIELDS: u8 = 16;

/// While the motherboard is taken to be gone (see [`run_target`]), the head event is tried
/// once every this many µs (100 ms): delivery resumes when the MB is back even if it never
/// addresses the board, and a dead MB sees at most ten short writes a second.
pub const MB_GONE_RETRY_US: u64 = 100_000;

/// Serves the bus for `db`; never returns.
///
/// While no event is waiting the port waits to be addressed at the board's address
/// ([`MultiMaster::addressed`], the only bus call ever raced against something else); once
/// addressed, the transaction is received ([`MultiMaster::listen`]) and served to the end, an
/// event queued meanwhile waits: a write is executed ([`Daughterboard::handle_write`]), a
/// write-then-read is executed and answered in the same transaction, a plain read gets the
/// held reply ([`Daughterboard::take_reply`]). A listen error (a write too long for the
/// buffer) counts as `bad_length`.
///
/// When an event is queued the port becomes a brief master and writes it to
/// `config.mb_address` (with PEC when negotiated). A failed attempt waits while listening (the
/// MB may be talking to this board: that is often why the write could not go out), then the
/// event is tried again:
///
/// * `ArbitrationLost` or `Nack`, and within the wait a transaction addressed to this board is
///   served: this board was being addressed (a port that sees its own address while its write
///   waits for the bus gives up with `ArbitrationLost`, see [`MultiMaster`]). The event is
///   retried right after serving that transaction and the attempt does not count: the bus
///   frees after the STOP, and an event to the MB's (lowest) address wins the arbitration
///   against the MB's next request. At most [`MAX_EVENT_YIELDS`] attempts per event are
///   forgiven this way. The wait is the [`Backoff`] delay of `config.retry` (or its
///   `base_us` once the attempts are used up);
/// * otherwise (and for `Timeout` or `Bus`) the attempt counts: the [`Backoff`] delay is
///   waited out, listening, and the event is tried again.
///
/// Every retry counts in `event_retries`, every arbitration loss in `arbitration_lost`, every
/// delivery in `events_sent`. When the attempts are used up the event is dropped, counted in
/// `events_dropped` and reported by an overflow event.
///
/// After an event has been dropped this way the MB is taken to be gone (reset, crashed,
/// unpowered, or a single-role MB busy as controller for longer than the retries last). The
/// board then listens, and tries the head event of its queue (the overflow report, usually)
/// once every [`MB_GONE_RETRY_US`], each try counted in `event_retries`: no burst of retries,
/// so a dead MB does not turn into a flooded bus. Other events wait in the queue (what does
/// not fit is counted in `events_dropped`). The first of those tries that is delivered, or the
/// first transaction addressed to the board, shows the MB is back, and delivery resumes with
/// the full retry policy.
///
/// Run it next to [`Daughterboard::run_background`] (or use [`run`], which joins both).
pub async fn run_target<M, P, B, C>(
    db: &Daughterboard<M, P>,
    mut bus: B,
    clock: C,
    config: TargetConfig,
) -> !
where
    M: RawMutex,
    P: Ports,
    B: MultiMaster,
    C: Clock,
{
    let mut rx = [0u8; MAX_FRAME_LEN];
    let mut tx = [0u8; MAX_FRAME_LEN];
    let mut sent: u32 = 0;
    // False once an event could not be delivered, until the MB shows it is back.
    let mut mb_present = true;
    // The head event, taken out of the queue while the MB is gone.
    let mut held: Option<OutEvent> = None;
    let mut retry_at = clock.now();
    loop {
        if !mb_present {
            match held.as_ref() {
                None => match select(bus.addressed(), db.next_event()).await {
                    Either::First(a) => {
                        mb_present = receive(db, &mut bus, a, &mut rx, &mut tx).await;
                    }
                    Either::Second(ev) => {
                        held = Some(ev);
                        retry_at = clock.now().plus_us(MB_GONE_RETRY_US);
                    }
                },
                Some(ev) => match select(bus.addressed(), clock.sleep_until(retry_at)).await {
                    Either::First(a) => {
                        mb_present = receive(db, &mut bus, a, &mut rx, &mut tx).await;
                    }
                    Either::Second(()) => {
                        db.with(|s| bump(&mut s.diag.event_retries));
                        if try_once(db, &mut bus, &config, ev, &mut tx).await {
                            held = None;
                            mb_present = true;
                        } else {
                            retry_at = clock.now().plus_us(MB_GONE_RETRY_US);
                        }
                    }
                },
            }
            continue;
        }
        let ev = match held.take() {
            Some(ev) => ev,
            None => match select(bus.addressed(), db.next_event()).await {
                Either::First(a) => {
                    receive(db, &mut bus, a, &mut rx, &mut tx).await;
                    continue;
                }
                Either::Second(ev) => ev,
            },
        };
        sent = sent.wrapping_add(1);
        mb_present = deliver(db, &mut bus, &clock, &config, &ev, sent, &mut rx, &mut tx).await;
    }
}

/// One attempt to write `ev` to the MB, while it is taken to be gone. True when delivered
/// (counted in `events_sent`).
async fn try_once<M: RawMutex, P: Ports, B: MultiMaster>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    config: &TargetConfig,
    ev: &OutEvent,
    frame: &mut [u8],
) -> bool {
    let len = db.encode_event(ev, config.mb_address, frame);
    let Some(bytes) = frame.get(..len).filter(|b| !b.is_empty()) else {
        // Cannot be encoded: nothing to retry.
        db.event_lost();
        return true;
    };
    match bus.write(config.mb_address.get(), bytes).await {
        Ok(()) => {
            db.with(|s| bump(&mut s.diag.events_sent));
            true
        }
        Err(e) => {
            if e == BusError::ArbitrationLost {
                db.with(|s| bump(&mut s.diag.arbitration_lost));
            }
            false
        }
    }
}

/// A daughterboard on the bus, complete: [`Daughterboard::run_background`] and
/// [`run_target`] joined. Never returns.
pub async fn run<M, P, B, C>(db: &Daughterboard<M, P>, bus: B, clock: C, config: TargetConfig) -> !
where
    M: RawMutex,
    P: Ports,
    B: MultiMaster,
    C: Clock,
{
    let (never, _) = join(
        db.run_background(&clock),
        run_target(db, bus, &clock, config),
    )
    .await;
    never
}

/// After [`MultiMaster::addressed`] returned: receives that transaction and serves it, never
/// raced. True when one addressed to the board was served (see [`serve`]).
async fn receive<M: RawMutex, P: Ports, B: MultiMaster>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    addressed: Result<(), BusError>,
    rx: &mut [u8],
    tx: &mut [u8],
) -> bool {
    let incoming = match addressed {
        Ok(()) => bus.listen(rx).await,
        Err(e) => Err(e),
    };
    serve(db, bus, incoming, rx, tx).await
}

/// Serves one transaction; true when it was addressed to the board (including a write too
/// long for the buffer).
async fn serve<M: RawMutex, P: Ports, B: MultiMaster>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    incoming: Result<Incoming, BusError>,
    rx: &[u8],
    tx: &mut [u8],
) -> bool {
    match incoming {
        Ok(Incoming::Write(n)) => db.handle_write(rx.get(..n).unwrap_or(rx), false).await,
        Ok(Incoming::WriteRead(n)) => {
            db.handle_write(rx.get(..n).unwrap_or(rx), true).await;
            let len = db.take_reply(tx);
            let _ = bus.respond(tx.get(..len).unwrap_or(&[])).await;
        }
        Ok(Incoming::Read) => {
            let len = db.take_reply(tx);
            let _ = bus.respond(tx.get(..len).unwrap_or(&[])).await;
        }
        Err(BusError::Overrun) => {
            db.with(|s| bump(&mut s.diag.bad_length));
            db.heard.signal(());
        }
        Err(_) => return false,
    }
    true
}

/// Delivers one event, retrying with backoff while serving the listener. False when it was
/// dropped because every attempt failed (the MB is taken to be gone).
#[allow(clippy::too_many_arguments)]
async fn deliver<M: RawMutex, P: Ports, B: MultiMaster, C: Clock>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    clock: &C,
    config: &TargetConfig,
    ev: &OutEvent,
    nth: u32,
    rx: &mut [u8],
    tx: &mut [u8],
) -> bool {
    let mut frame = [0u8; MAX_FRAME_LEN];
    let seed = (u32::from(db.address().get()) << 24) ^ nth;
    let mut backoff = Backoff::new(config.retry, seed);
    let mut yields: u8 = 0;
    loop {
        // Encoded for each attempt: the MB may switch PEC (set_pec, served while this event
        // waited) between two attempts, and the event must go out as the MB now expects it.
        let len = db.encode_event(ev, config.mb_address, &mut frame);
        let Some(bytes) = frame.get(..len).filter(|b| !b.is_empty()) else {
            db.event_lost();
            return true;
        };
        let e = match bus.write(config.mb_address.get(), bytes).await {
            Ok(()) => {
                db.with(|s| bump(&mut s.diag.events_sent));
                return true;
            }
            Err(e) => e,
        };
        if e == BusError::ArbitrationLost {
            db.with(|s| bump(&mut s.diag.arbitration_lost));
        }
        // The attempt counts only if nobody addresses us while we wait: decide on a copy.
        let mut counted = backoff.clone();
        let delay = counted.next_delay_us();
        let may_yield =
            matches!(e, BusError::ArbitrationLost | BusError::Nack) && yields < MAX_EVENT_YIELDS;
        if may_yield {
            let wait = delay.unwrap_or(config.retry.base_us);
            let until = clock.now().plus_us(u64::from(wait));
            if listen_until(db, bus, clock, until, rx, tx, true).await {
                yields += 1;
                db.with(|s| bump(&mut s.diag.event_retries));
                continue;
            }
            backoff = counted;
            if delay.is_none() {
                db.event_lost();
                return false;
            }
            db.with(|s| bump(&mut s.diag.event_retries));
            continue;
        }
        backoff = counted;
        let Some(delay) = delay else {
            db.event_lost();
            return false;
        };
        db.with(|s| bump(&mut s.diag.event_retries));
        let until = clock.now().plus_us(u64::from(delay));
        listen_until(db, bus, clock, until, rx, tx, false).await;
    }
}

/// Serves the listener until `until`, or, with `stop_when_addressed`, until the first
/// transaction addressed to the board has been served. True when one was served.
async fn listen_until<M: RawMutex, P: Ports, B: MultiMaster, C: Clock>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    clock: &C,
    until: Instant,
    rx: &mut [u8],
    tx: &mut [u8],
    stop_when_addressed: bool,
) -> bool {
    let mut served = false;
    loop {
        let r = select(bus.addressed(), clock.sleep_until(until)).await;
        match r {
            Either::First(addressed) => {
                // Past `until` if need be: a transaction under way is received whole.
                served |= receive(db, bus, addressed, rx, tx).await;
                if served && stop_when_addressed {
                    return true;
                }
            }
            Either::Second(()) => return served,
        }
    }
}
