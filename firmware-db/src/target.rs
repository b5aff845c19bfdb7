//! A daughterboard on the bus: the target listener and the event sender, on one
//! [`MultiMaster`] port.

use embassy_futures::join::join;
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::RawMutex;
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::retry::{Backoff, RetryPolicy};
use x10_hal::time::{Clock, Instant};
use x10_microcode::{EventKind, PinRef, Status, MAX_FRAME_LEN};

use crate::config::TargetConfig;
use crate::daughterboard::{bump, Daughterboard};
use crate::event::OutEvent;
use crate::record::AddressRecord;
use x10_hal::ports::Ports;

/// Attempts of one event that may be NACKed because the board was being addressed without
/// counting against its [`x10_hal::retry::RetryPolicy`] (see [`run_target`]). Past this many
/// the NACKs count again, so an MB that NACKs while polling the board back to back is
/// eventually taken for gone.
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
/// * `ArbitrationLost`: another master has the bus, so the bus and probably the MB are alive.
///   The attempt never counts against the retry policy, however often it happens: the event is
///   tried again after a random delay, uniform over a window that starts at `retry.base_us`
///   and doubles with each loss in a row up to `retry.max_us` (plus `base_us / 2`), or right
///   after a transaction addressed to this board has been served. A board that loses to a
///   flood keeps trying at a bounded interval; it never takes the MB for gone;
/// * `Nack`, and within the wait a transaction addressed to this board is served: this board
///   was being addressed (a single-role MB NACKs while it is a controller). The attempt does
///   not count, at most [`MAX_EVENT_YIELDS`] times per event;
/// * otherwise (`Nack`, `Timeout`, `Bus`) the attempt counts: the [`Backoff`] delay of
///   `config.retry` is waited out, listening, and the event is tried again.
///
/// Every retry (every write of an event after its first) counts in `event_retries`, every
/// arbitration loss in `arbitration_lost`, every delivery in `events_sent`. An event the
/// board keeps is never counted in `events_dropped`: only the queue's overflows are.
///
/// **Pacing**: after an event has been delivered, the next write waits a random delay (while
/// the board listens), uniform in `[g/2, 3g/2)` where `g` is the larger of
/// `config.event_gap_us` and twice the time the last delivery took (the wait for the bus
/// included). So one board uses a bounded share of the bus, whatever its event rate, and two
/// flooding boards interleave instead of the lower address winning every time. Events that
/// come faster wait in the queue, where pin events coalesce (one per pin, carrying every edge
/// counted meanwhile).
///
/// When the attempts that count are used up the MB is taken to be gone (reset, crashed,
/// unpowered, or a single-role MB busy as controller for longer than the retries last). The
/// event is **kept**, not dropped: the board listens, and tries it once every
/// [`MB_GONE_RETRY_US`], each try counted in `event_retries`: no burst of retries, so a dead
/// MB does not turn into a flooded bus. Other events wait in the queue (what does not fit is
/// counted in `events_dropped` and reported by an overflow event). The first of those tries
/// that is delivered, or the first transaction addressed to the board, shows the MB is back,
/// and delivery resumes with the full retry policy. So a `boot` event sent before the MB is
/// up reaches it as soon as it is.
///
/// Run it next to [`Daughterboard::run_background`] (or use [`run`], which joins both).
pub async fn run_target<M, P, R, B, C>(
    db: &Daughterboard<M, P, R>,
    mut bus: B,
    clock: C,
    config: TargetConfig,
) -> !
where
    M: RawMutex,
    P: Ports,
    R: AddressRecord,
    B: MultiMaster,
    C: Clock,
{
    let mut rx = [0u8; MAX_FRAME_LEN];
    let mut tx = [0u8; MAX_FRAME_LEN];
    let mut jitter = Jitter::new(db);
    // False once an event could not be delivered, until the MB shows it is back.
    let mut mb_present = true;
    // The head event, kept while the MB is gone.
    let mut held: Option<OutEvent> = None;
    let mut retry_at = clock.now();
    // Pacing: no event write before this.
    let mut next_write = clock.now();
    loop {
        if !mb_present {
            let Some(ev) = held.as_ref() else {
                mb_present = true;
                continue;
            };
            match select(bus.addressed(), clock.sleep_until(retry_at)).await {
                Either::First(a) => {
                    mb_present = receive(db, &mut bus, a, &mut rx, &mut tx).await;
                }
                Either::Second(()) => {
                    db.with(|s| bump(&mut s.diag.event_retries));
                    if try_once(db, &mut bus, &config, ev, &mut tx).await {
                        held = None;
                        mb_present = true;
                        next_write = clock.now().plus_us(delivered(db, &mut jitter, &config, 0));
                    } else {
                        retry_at = clock.now().plus_us(MB_GONE_RETRY_US);
                    }
                }
            }
            continue;
        }
        let ev = match held.take() {
            // The kept event, again with the full retry policy: the MB showed it is back.
            Some(ev) => {
                db.with(|s| bump(&mut s.diag.event_retries));
                ev
            }
            None => match select(bus.addressed(), db.next_event()).await {
                Either::First(a) => {
                    receive(db, &mut bus, a, &mut rx, &mut tx).await;
                    continue;
                }
                Either::Second(ev) => ev,
            },
        };
        if clock.now() < next_write {
            listen_until(db, &mut bus, &clock, next_write, &mut rx, &mut tx, false).await;
        }
        let started = clock.now();
        if deliver(
            db,
            &mut bus,
            &clock,
            &config,
            &ev,
            &mut jitter,
            &mut rx,
            &mut tx,
        )
        .await
        {
            let took = clock.now().0.saturating_sub(started.0);
            next_write = clock
                .now()
                .plus_us(delivered(db, &mut jitter, &config, took));
        } else {
            held = Some(ev);
            mb_present = false;
            retry_at = clock.now().plus_us(MB_GONE_RETRY_US);
        }
    }
}

/// An unaddressed board announces itself again after at least this many µs (200 ms)...
pub const ANNOUNCE_MIN_US: u64 = 200_000;
/// ... plus a random delay below this many µs (200 ms), seeded by its ID.
pub const ANNOUNCE_WINDOW_US: u32 = 200_000;

/// After an event was delivered (in `took` µs): the pause before the next write. An
/// unaddressed board (whose only events are its announces) queues its next `announce` now, and
/// the pause, [`ANNOUNCE_MIN_US`] plus a random delay below [`ANNOUNCE_WINDOW_US`] (from the
/// generator seeded by its ID, so boards powered up together differ), holds it back until an
/// `assign` moves the board ([`Daughterboard::moved`]).
fn delivered<M: RawMutex, P: Ports, R: AddressRecord>(
    db: &Daughterboard<M, P, R>,
    jitter: &mut Jitter,
    config: &TargetConfig,
    took: u64,
) -> u64 {
    if db.is_unaddressed() {
        db.push_event(
            EventKind::Announce,
            PinRef::from_byte(0),
            None,
            Status::Ok,
            &db.boot_info(),
        );
        ANNOUNCE_MIN_US + u64::from(jitter.below(ANNOUNCE_WINDOW_US))
    } else {
        jitter.gap(config.event_gap_us, took)
    }
}

/// The board's source of random delays (xorshift32, seeded by its address, or while it is
/// unaddressed by its unique ID: boards differ, a simulation replays exactly).
struct Jitter(u32);

impl Jitter {
    pub(crate) fn new<M: RawMutex, P: Ports, R: AddressRecord>(
        db: &Daughterboard<M, P, R>,
    ) -> Jitter {
        let seed = if db.is_unaddressed() {
            db.config().uid.hash32()
        } else {
            u32::from(db.address().get()) << 24 | 0x5A_5A5A
        };
        Jitter(seed.wrapping_mul(0x9E37_79B9) | 1)
    }

    fn next(&mut self) -> u32 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.0 = x;
        x
    }

    /// Uniform in `[0, n)` (0 when `n` is 0).
    fn below(&mut self, n: u32) -> u32 {
        if n == 0 {
            0
        } else {
            self.next() % n
        }
    }

    /// The pause after a delivery that took `took_us`: uniform in `[g/2, 3g/2)`, `g` the
    /// larger of `gap_us` and `2 · took_us`.
    fn gap(&mut self, gap_us: u32, took_us: u64) -> u64 {
        let g = u64::from(gap_us)
            .max(took_us.saturating_mul(2))
            .min(u64::from(u32::MAX));
        let g = u32::try_from(g).unwrap_or(u32::MAX);
        u64::from(g / 2) + u64::from(self.below(g))
    }

    /// The wait after the `lost`-th arbitration loss in a row: uniform over a window of
    /// `base · 2^(lost-1)` capped at `max`, plus `base / 2`.
    fn contention(&mut self, policy: &RetryPolicy, lost: u32) -> u32 {
        let shift = lost.saturating_sub(1).min(16);
        let window = policy
            .base_us
            .max(1)
            .saturating_mul(1 << shift)
            .min(policy.max_us.max(1));
        policy.base_us / 2 + self.below(window)
    }
}

/// One attempt to write `ev` to the MB, while it is taken to be gone. True when delivered
/// (counted in `events_sent`).
async fn try_once<M: RawMutex, P: Ports, R: AddressRecord, B: MultiMaster>(
    db: &Daughterboard<M, P, R>,
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
pub async fn run<M, P, R, B, C>(
    db: &Daughterboard<M, P, R>,
    bus: B,
    clock: C,
    config: TargetConfig,
) -> !
where
    M: RawMutex,
    P: Ports,
    R: AddressRecord,
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
async fn receive<M: RawMutex, P: Ports, R: AddressRecord, B: MultiMaster>(
    db: &Daughterboard<M, P, R>,
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
async fn serve<M: RawMutex, P: Ports, R: AddressRecord, B: MultiMaster>(
    db: &Daughterboard<M, P, R>,
    bus: &mut B,
    incoming: Result<Incoming, BusError>,
    rx: &[u8],
    tx: &mut [u8],
) -> bool {
    // One await of each (each await point of an async fn costs code and state: issue 12).
    let (write, read) = match incoming {
        Ok(Incoming::Write(n)) => (Some(n), false),
        // An empty write before the read (a controller that cannot read without one): a
        // plain read, which must not replace the reply held (a sweep's sample).
        #[cfg(feature = "together")]
        Ok(Incoming::WriteRead(0)) => (None, true),
        Ok(Incoming::WriteRead(n)) => (Some(n), true),
        Ok(Incoming::Read) => (None, true),
        Err(BusError::Overrun) => {
            db.with(|s| bump(&mut s.diag.bad_length));
            db.heard.signal(());
            return true;
        }
        Err(_) => return false,
    };
    if let Some(n) = write {
        db.handle_write(rx.get(..n).unwrap_or(rx), read);
    }
    if read {
        let len = db.take_reply(tx);
        let _ = bus.respond(tx.get(..len).unwrap_or(&[])).await;
    }
    db.served();
    true
}

/// Delivers one event, retrying while serving the listener (see [`run_target`]). False when
/// the attempts that count are used up (the MB is taken to be gone; the event is kept).
#[allow(clippy::too_many_arguments)]
async fn deliver<M: RawMutex, P: Ports, R: AddressRecord, B: MultiMaster, C: Clock>(
    db: &Daughterboard<M, P, R>,
    bus: &mut B,
    clock: &C,
    config: &TargetConfig,
    ev: &OutEvent,
    jitter: &mut Jitter,
    rx: &mut [u8],
    tx: &mut [u8],
) -> bool {
    let mut frame = [0u8; MAX_FRAME_LEN];
    let mut backoff = Backoff::new(config.retry, jitter.next());
    let mut yields: u8 = 0;
    let mut lost: u32 = 0;
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
        // What to wait for before the next attempt; one await of `listen_until` for all
        // three cases (each await point costs code and state: issue 12).
        let mut counted = backoff.clone();
        let mut delay = None;
        let mut nack_yield = false;
        let (wait, stop_when_addressed) = if e == BusError::ArbitrationLost {
            // Never counted: someone else has the bus.
            db.with(|s| {
                bump(&mut s.diag.arbitration_lost);
                bump(&mut s.diag.event_retries);
            });
            lost = lost.saturating_add(1);
            (jitter.contention(&config.retry, lost), true)
        } else {
            lost = 0;
            // The attempt counts only if nobody addresses us while we wait: decide on a copy.
            delay = counted.next_delay_us();
            if e == BusError::Nack && yields < MAX_EVENT_YIELDS {
                nack_yield = true;
                (delay.unwrap_or(config.retry.base_us), true)
            } else {
                backoff = counted.clone();
                // The last counted failure is no retry: the slow tries while the MB is taken
                // for gone count their own.
                let Some(d) = delay else {
                    return false;
                };
                db.with(|s| bump(&mut s.diag.event_retries));
                (d, false)
            }
        };
        let until = clock.now().plus_us(u64::from(wait));
        let served = listen_until(db, bus, clock, until, rx, tx, stop_when_addressed).await;
        if nack_yield {
            if served {
                yields += 1;
            } else {
                backoff = counted;
                if delay.is_none() {
                    return false;
                }
            }
            db.with(|s| bump(&mut s.diag.event_retries));
        }
    }
}

/// Serves the listener until `until`, or, with `stop_when_addressed`, until the first
/// transaction addressed to the board has been served. True when one was served.
async fn listen_until<M: RawMutex, P: Ports, R: AddressRecord, B: MultiMaster, C: Clock>(
    db: &Daughterboard<M, P, R>,
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
