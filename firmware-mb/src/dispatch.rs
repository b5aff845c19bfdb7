//! The dispatcher: the only user of the bus controller role, and, while idle, the
//! DB-interrupt listener at the motherboard's own address.

use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::RawMutex;
use firmware_db::Ports;
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::retry::Backoff;
use x10_hal::time::{Clock, Instant};
use x10_microcode::MAX_FRAME_LEN;

use crate::diag::bump;
use crate::motherboard::{Job, Motherboard};

impl<M: RawMutex, P: Ports, C: Clock> Motherboard<M, P, C> {
    /// The dispatcher and the DB-interrupt listener on `bus`; never returns. Part of
    /// [`Motherboard::run`].
    ///
    /// Idle, it listens at the motherboard's address (polled before the request channel, so a
    /// transaction already under way is never cut): writes are events or deferred replies and
    /// are routed; reads get nothing. A request from the channel goes out as one `write`
    /// (outputs) or one `write_read` with a repeated START (inputs, reading the reply header,
    /// the operation's reply capacity and the PEC byte if negotiated). NACK and arbitration
    /// loss are retried after a [`Backoff`] delay during which the listener runs again (the
    /// winner of the arbitration is often a daughterboard writing an event to us); when the
    /// attempts are used up the request ends in `Nack` or `ArbitrationLost`. A bus timeout
    /// ends it in `Timeout`, a bus fault in `Bus`. A request whose caller already gave up is
    /// not sent.
    pub async fn run_dispatcher<B: MultiMaster>(&self, mut bus: B) -> ! {
        let mut rx = [0u8; MAX_FRAME_LEN];
        let mut nth: u32 = 0;
        loop {
            let r = select(bus.listen(&mut rx), self.requests.receive()).await;
            match r {
                Either::First(incoming) => self.serve_listener(&mut bus, incoming, &rx).await,
                Either::Second(job) => {
                    nth = nth.wrapping_add(1);
                    self.dispatch(&mut bus, &job, nth, &mut rx).await;
                }
            }
        }
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

    async fn listen_until<B: MultiMaster>(&self, bus: &mut B, until: Instant, rx: &mut [u8]) {
        loop {
            let r = select(bus.listen(rx), self.clock.sleep_until(until)).await;
            match r {
                Either::First(incoming) => self.serve_listener(bus, incoming, rx).await,
                Either::Second(()) => return,
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
            let delay = if retry { backoff.next_delay_us() } else { None };
            let Some(delay) = delay else {
                warn!(
                    "request {} to {} failed after {} attempts",
                    meta.seq,
                    addr,
                    backoff.attempts()
                );
                self.finish_transfer(meta, Err(e));
                return;
            };
            self.with(|t| bump(&mut t.diag.retries));
            let until = self.clock.now().plus_us(u64::from(delay));
            self.listen_until(bus, until, rx).await;
            if !self.is_queued(meta.ticket) {
                self.with(|t| bump(&mut t.diag.abandoned));
                return;
            }
        }
    }
}
