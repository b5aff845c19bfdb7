//! The dispatcher: the only user of the bus controller role, and, while idle, the
//! DB-interrupt listener at the motherboard's own address.

use embassy_futures::select::{select, Either};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::retry::Backoff;
use x10_hal::time::Instant;
use x10_microcode::MAX_FRAME_LEN;

use crate::diag::bump;
use crate::motherboard::{now, sleep_until, MbCore};
use crate::table::Job;

impl MbCore {
    /// The dispatcher and the DB-interrupt listener on `bus`; never returns. Part of
    /// [`crate::Motherboard::run`].
    ///
    /// Idle, it waits to be addressed at the motherboard's address
    /// ([`MultiMaster::addressed`], polled before the request queue; the only bus call that is
    /// ever raced). Once addressed, the transaction is received ([`MultiMaster::listen`]) and
    /// served to the end before anything else, so a transfer under way is never cut by a
    /// request, a timer or anything else: writes are events or deferred replies and are
    /// routed; reads get nothing. A request from the queue goes out as one `write`
    /// (outputs) or one `write_read` with a repeated START (inputs, reading the reply header,
    /// the operation's reply capacity and the PEC byte if negotiated). After a NACK or a lost
    /// arbitration the listener runs again (the winner of the arbitration is usually a
    /// daughterboard writing an event to us), for the [`Backoff`] delay, and after a lost
    /// arbitration for at least `MbConfig::arbitration_wait_us`:
    ///
    /// * if a write to the motherboard arrives meanwhile (after a NACK: an event from the
    ///   board addressed, which was busy sending it), the transaction is retried right after
    ///   it and the attempt does not count (`yields`);
    /// * otherwise the attempt counts, and when the attempts are used up the request ends in
    ///   `Nack` (at once) or `ArbitrationLost` (after that last wait).
    ///
    /// Retries go on only while the caller waits, so forgiven attempts are bounded by the
    /// request's deadline. A bus timeout ends the request in `Timeout`, a bus fault in
    /// `Bus`. A request whose caller already gave up is not sent.
    pub async fn run_dispatcher<B: MultiMaster>(&self, mut bus: B) -> ! {
        let mut rx = [0u8; MAX_FRAME_LEN];
        let mut nth: u32 = 0;
        loop {
            let r = select(bus.addressed(), self.next_job()).await;
            match r {
                Either::First(addressed) => {
                    self.receive(&mut bus, addressed, &mut rx).await;
                }
                Either::Second(job) => {
                    nth = nth.wrapping_add(1);
                    self.dispatch(&mut bus, &job, nth, &mut rx).await;
                }
            }
        }
    }

    /// After [`MultiMaster::addressed`] returned: receives and serves that transaction, never
    /// raced. The source (first byte) of a write, if one was received.
    async fn receive<B: MultiMaster>(
        &self,
        bus: &mut B,
        addressed: Result<(), BusError>,
        rx: &mut [u8],
    ) -> Option<u8> {
        let incoming = match addressed {
            Ok(()) => bus.listen(rx).await,
            Err(e) => Err(e),
        };
        let source = match incoming {
            Ok(Incoming::Write(n)) if n > 0 => rx.first().copied(),
            _ => None,
        };
        self.serve_listener(bus, incoming, rx).await;
        source
    }

    async fn serve_listener<B: MultiMaster>(
        &self,
        bus: &mut B,
        incoming: Result<Incoming, BusError>,
        rx: &[u8],
    ) {
        match incoming {
            Ok(Incoming::Write(n)) => self.route_event_bytes(rx.get(..n).unwrap_or(rx)),
            Ok(Incoming::Read | Incoming::WriteRead(_)) => {
                self.with(|t| bump(&mut t.diag.unexpected_reads));
                let _ = bus.respond(&[]).await;
            }
            Err(_) => self.with(|t| bump(&mut t.diag.listener_errors)),
        }
    }

    /// Listens until `until`, or until a write to the motherboard whose first byte (an
    /// event's source) satisfies `wanted` has been served. True when one was.
    async fn listen_until<B: MultiMaster>(
        &self,
        bus: &mut B,
        until: Instant,
        rx: &mut [u8],
        wanted: impl Fn(u8) -> bool,
    ) -> bool {
        loop {
            let r = select(bus.addressed(), sleep_until(until)).await;
            match r {
                Either::First(addressed) => {
                    // Past `until` if need be: a transaction under way is received whole.
                    let source = self.receive(bus, addressed, rx).await;
                    if source.is_some_and(&wanted) {
                        return true;
                    }
                }
                Either::Second(()) => return false,
            }
        }
    }

    async fn dispatch<B: MultiMaster>(&self, bus: &mut B, job: &Job, nth: u32, rx: &mut [u8]) {
        let meta = &job.meta;
        if !self.is_queued(meta.ticket) {
            self.with(|t| bump(&mut t.diag.abandoned));
            return;
        }
        let seed = self.config.seed
            ^ nth.rotate_left(16)
            ^ (u32::from(meta.db.get()) << 8)
            ^ u32::from(meta.seq);
        let mut backoff = Backoff::new(self.config.retry, seed);
        let mut read = [0u8; MAX_FRAME_LEN];
        let addr = meta.db.get();
        loop {
            let result = if meta.read_len > 0 {
                match read.get_mut(..meta.read_len) {
                    Some(buf) => bus.write_read(addr, &job.frame, buf).await.map(|()| true),
                    None => Err(BusError::Overrun),
                }
            } else {
                bus.write(addr, &job.frame).await.map(|()| false)
            };
            let e = match result {
                Ok(was_read) => {
                    let bytes = if was_read {
                        read.get(..meta.read_len)
                    } else {
                        None
                    };
                    self.finish_transfer(meta, Ok(bytes));
                    return;
                }
                Err(e) => e,
            };
            let retry = match e {
                BusError::Nack => {
                    self.with(|t| bump(&mut t.diag.nacked));
                    true
                }
                BusError::ArbitrationLost => {
                    self.with(|t| bump(&mut t.diag.arbitration_lost));
                    true
                }
                BusError::Timeout | BusError::Bus | BusError::Overrun => false,
            };
            // The attempt counts only if no write to us arrives while we wait: decide on a
            // copy of the backoff.
            let mut counted = backoff.clone();
            let delay = if retry { counted.next_delay_us() } else { None };
            let wait = match (e, delay) {
                (BusError::ArbitrationLost, d) => {
                    Some(d.unwrap_or(0).max(self.config.arbitration_wait_us))
                }
                (_, d) => d,
            };
            let Some(wait) = wait else {
                warn!(
                    "request {} to {} failed after {} attempts",
                    meta.seq,
                    addr,
                    counted.attempts()
                );
                self.finish_transfer(meta, Err(e));
                return;
            };
            let until = now().plus_us(u64::from(wait));
            // After a lost arbitration any write to us may be what won the bus (or what a
            // single-role port was too busy to ACK); after a NACK only one from the board we
            // addressed is (it was busy sending it to us).
            let yielded = if e == BusError::ArbitrationLost {
                self.listen_until(bus, until, rx, |_| true).await
            } else {
                self.listen_until(bus, until, rx, |source| source == addr)
                    .await
            };
            if yielded {
                // The bus is free again: retry at once, and the attempt does not count.
                self.with(|t| bump(&mut t.diag.yields));
            } else if delay.is_none() {
                warn!(
                    "request {} to {} failed after {} attempts",
                    meta.seq,
                    addr,
                    counted.attempts()
                );
                self.finish_transfer(meta, Err(e));
                return;
            } else {
                backoff = counted;
            }
            self.with(|t| bump(&mut t.diag.retries));
            if !self.is_queued(meta.ticket) {
                self.with(|t| bump(&mut t.diag.abandoned));
                return;
            }
        }
    }
}
