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

/// Serves the bus for `db`; never returns.
///
/// While no event is waiting the port listens at the board's address: a write is executed
/// ([`Daughterboard::handle_write`]), a write-then-read is executed and answered in the same
/// transaction, a plain read gets the held reply ([`Daughterboard::take_reply`]). A listen
/// error (a write too long for the buffer) counts as `bad_length`.
///
/// When an event is queued the port becomes a brief master and writes it to
/// `config.mb_address` (with PEC when negotiated). NACK, arbitration loss, bus timeout or
/// fault make it wait the [`Backoff`] delay of `config.retry`, listening meanwhile (the MB may
/// be talking to this board: that is often why arbitration was lost), and try again; every
/// retry counts in `event_retries`, every arbitration loss in `arbitration_lost`, every
/// delivery in `events_sent`. When the attempts are used up the event is dropped, counted in
/// `events_dropped` and reported by an overflow event.
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
    loop {
        let r = select(bus.listen(&mut rx), db.next_event()).await;
        match r {
            Either::First(incoming) => serve(db, &mut bus, incoming, &rx, &mut tx).await,
            Either::Second(ev) => {
                sent = sent.wrapping_add(1);
                deliver(db, &mut bus, &clock, &config, &ev, sent, &mut rx, &mut tx).await;
            }
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

/// Serves one transaction addressed to the board.
async fn serve<M: RawMutex, P: Ports, B: MultiMaster>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    incoming: Result<Incoming, BusError>,
    rx: &[u8],
    tx: &mut [u8],
) {
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
        Err(_) => {}
    }
}

/// Delivers one event, retrying with backoff while serving the listener.
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
) {
    let mut frame = [0u8; MAX_FRAME_LEN];
    let len = db.encode_event(ev, config.mb_address, &mut frame);
    let Some(bytes) = frame.get(..len).filter(|b| !b.is_empty()) else {
        db.event_lost();
        return;
    };
    let seed = (u32::from(db.address().get()) << 24) ^ nth;
    let mut backoff = Backoff::new(config.retry, seed);
    loop {
        match bus.write(config.mb_address.get(), bytes).await {
            Ok(()) => {
                db.with(|s| bump(&mut s.diag.events_sent));
                return;
            }
            Err(e) => {
                if e == BusError::ArbitrationLost {
                    db.with(|s| bump(&mut s.diag.arbitration_lost));
                }
                match backoff.next_delay_us() {
                    Some(delay) => {
                        db.with(|s| bump(&mut s.diag.event_retries));
                        let until = clock.now().plus_us(u64::from(delay));
                        listen_until(db, bus, clock, until, rx, tx).await;
                    }
                    None => {
                        db.event_lost();
                        return;
                    }
                }
            }
        }
    }
}

/// Serves the listener until `until`.
async fn listen_until<M: RawMutex, P: Ports, B: MultiMaster, C: Clock>(
    db: &Daughterboard<M, P>,
    bus: &mut B,
    clock: &C,
    until: Instant,
    rx: &mut [u8],
    tx: &mut [u8],
) {
    loop {
        let r = select(bus.listen(rx), clock.sleep_until(until)).await;
        match r {
            Either::First(incoming) => serve(db, bus, incoming, rx, tx).await,
            Either::Second(()) => return,
        }
    }
}
