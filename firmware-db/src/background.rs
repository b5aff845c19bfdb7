//! Work a daughterboard does between requests: pulse-in measurements, event sampling and the
//! failsafe. All timing comes from the [`Clock`] given to [`Daughterboard::run_background`].

use embassy_futures::join::join3;
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::RawMutex;
use heapless::Vec;
use x10_hal::time::{Clock, Instant};
#[cfg(feature = "together")]
use x10_microcode::sweep::STAGE_TIMEOUT_MS;
use x10_microcode::{EventConfig, EventKind, Pin, PinRef, Port, Status};

use crate::daughterboard::{bump, port_status, Daughterboard, MAX_EVENT_PINS};
use crate::event::OutEvent;
use crate::record::AddressRecord;
use x10_hal::ports::{EdgeCount, PortError, Ports};

impl<M: RawMutex, P: Ports, R: AddressRecord> Daughterboard<M, P, R> {
    /// Runs the board's background work; never returns. Call once, next to the transport.
    ///
    /// At start every actuator port goes to its safe state and a `boot` event (payload: the
    /// board's identity, why it started and its ID, `BootInfo`) is queued.
    ///
    /// An **unaddressed** board ([`Daughterboard::is_unaddressed`]) queues an `announce`
    /// instead (and [`crate::run_target`] announces it again until an `assign` moves it); it takes no
    /// request but that `assign`, so nothing below ever drives an output. Concurrently:
    ///
    /// * pulse-in measurements accepted with `pending` run ([`crate::DEFERRED_WORKERS`] at a
    ///   time, on different pins); each result goes out as a `deferred_reply` event with the
    ///   request's sequence number and pin. A measurement's timeout counts from its
    ///   acceptance (the time is taken when this task is first polled after the accepting
    ///   write, in the same executor pass), not from when a worker becomes free: a job that
    ///   waited gets what is left of its timeout (rounded up to whole ms), and one whose
    ///   timeout passed while it waited is answered `timeout` at once without measuring. So
    ///   the deferred reply is queued no later than acceptance + timeout + 1 ms (plus however
    ///   long the port overruns its timeout), inside the motherboard's deadline for the request
    ///   (its request timeout + the pulse timeout, counted from before the request was sent);
    /// * every `sample_interval_us` (on a fixed grid from the moment events were enabled) the
    ///   pins with events enabled are sampled: a digital level that changed in an enabled
    ///   direction queues a `pin_change` event (payload: new level); an analog value queues an
    ///   `analog_threshold` event (payload: value u16 LE, then 1 inside / 0 outside the window)
    ///   at its first sample and whenever it crosses into or out of the window. A port error
    ///   while sampling skips that sample;
    /// * the failsafe: when no transaction has been addressed to the board for the failsafe
    ///   timeout (measured from start, or from the last one), every actuator port goes to
    ///   [`Ports::safe_state`], `failsafe_trips` is counted and a `failsafe_tripped` event
    ///   (payload: timeout in ms, u16 LE) is queued, once per silence.
    pub async fn run_background<C: Clock>(&self, clock: C) -> ! {
        self.apply_safe_state();
        self.push_event(
            if self.is_unaddressed() {
                EventKind::Announce
            } else {
                EventKind::Boot
            },
            PinRef::from_byte(0),
            None,
            Status::Ok,
            &self.boot_info(),
        );
        let (never, _, _) = join3(
            self.failsafe_loop(&clock),
            self.sample_loop(&clock),
            join3(
                self.stamp_pulse_jobs(&clock),
                self.pulse_worker(&clock),
                self.pulse_worker(&clock),
            ),
        )
        .await;
        never
    }

    /// Puts every actuator port into its safe state: PWM duty of pins A and B, then the
    /// levels of digital pins A and B. Port errors are skipped so one bad pin does not keep
    /// the others from their safe state. Synchronous, as the port calls are (an `async fn`
    /// here cost its state machine at both callers).
    pub fn apply_safe_state(&self) {
        let n = self.ports().actuator_ports().min(Port::MAX_PORTS);
        for number in 1..=n {
            let Ok(port) = Port::actuator(number) else {
                continue;
            };
            let safe = self.ports().safe_state(port);
            for (pin, duty) in [(Pin::A, safe.pwm[0]), (Pin::B, safe.pwm[1])] {
                let _ = self.ports().pwm_duty(port.pin(pin), duty);
            }
            for (pin, level) in [(Pin::A, safe.digital[0]), (Pin::B, safe.digital[1])] {
                let _ = self.ports().digital_write(port.pin(pin), level);
            }
        }
    }

    #[cfg(not(feature = "together"))]
    async fn failsafe_loop<C: Clock>(&self, clock: &C) -> ! {
        let mut last = clock.now();
        let mut tripped = false;
        loop {
            let timeout_ms = self.failsafe_timeout_ms();
            if timeout_ms == 0 || tripped {
                self.heard.wait().await;
                last = clock.now();
                tripped = false;
                continue;
            }
            let deadline = last.plus_ms(u64::from(timeout_ms));
            match select(self.heard.wait(), clock.sleep_until(deadline)).await {
                Either::First(()) => {
                    last = clock.now();
                    tripped = false;
                }
                Either::Second(()) => {
                    tripped = true;
                    self.trip(timeout_ms);
                }
            }
        }
    }

    /// The failsafe, and the timeout of staged outputs: what a `stage` holds is dropped
    /// [`STAGE_TIMEOUT_MS`] after it (each `stage` is heard: the time starts then) unless an
    /// `apply` took it.
    #[cfg(feature = "together")]
    async fn failsafe_loop<C: Clock>(&self, clock: &C) -> ! {
        let mut last = clock.now();
        let mut tripped = false;
        // Far in the future while nothing is staged.
        let mut stage_until = Instant(u64::MAX);
        loop {
            let now = clock.now();
            let (fresh, timeout_ms) =
                self.with(|s| (core::mem::take(&mut s.stage_fresh), s.failsafe_ms));
            if fresh {
                stage_until = now.plus_ms(u64::from(STAGE_TIMEOUT_MS));
            }
            let failsafe_at = if timeout_ms == 0 || tripped {
                Instant(u64::MAX)
            } else {
                last.plus_ms(u64::from(timeout_ms))
            };
            let deadline = stage_until.min(failsafe_at);
            let woke = if deadline == Instant(u64::MAX) {
                self.heard.wait().await;
                Either::First(())
            } else {
                select(self.heard.wait(), clock.sleep_until(deadline)).await
            };
            match woke {
                Either::First(()) => {
                    last = clock.now();
                    tripped = false;
                }
                Either::Second(()) => {
                    let now = clock.now();
                    if now >= stage_until {
                        stage_until = Instant(u64::MAX);
                        self.drop_stage();
                    }
                    if now >= failsafe_at {
                        tripped = true;
                        self.trip(timeout_ms);
                    }
                }
            }
        }
    }

    fn trip(&self, timeout_ms: u16) {
        self.with(|s| {
            // Staged outputs never move an actuator the failsafe stopped.
            #[cfg(feature = "together")]
            let _ = s.drop_staged();
            bump(&mut s.diag.failsafe_trips);
        });
        self.apply_safe_state();
        self.push_event(
            EventKind::FailsafeTripped,
            PinRef::from_byte(0),
            None,
            Status::Ok,
            &timeout_ms.to_le_bytes(),
        );
    }

    async fn sample_loop<C: Clock>(&self, clock: &C) -> ! {
        let interval = u64::from(self.config().sample_interval_us.max(1));
        let mut next: Option<Instant> = None;
        loop {
            // Pins that need the sampling grid: analog windows and pins the port cannot latch.
            let Some(sampled) = self.with(|s| {
                (!s.watches.is_empty()).then(|| {
                    s.watches.iter().any(|w| {
                        w.cfg.analog_window || ((w.cfg.rising || w.cfg.falling) && !w.latched)
                    })
                })
            }) else {
                next = None;
                self.wake.wait().await;
                continue;
            };
            let mut at = match next {
                Some(t) => t,
                None => clock.now().plus_us(interval),
            };
            // At most one pass per interval: a fast pin costs one event per interval at most.
            clock.sleep_until(at).await;
            if !sampled {
                // Only latched pins: pass as soon as an edge is latched (at once if one is
                // waiting), so an isolated edge is reported without waiting for the grid, or
                // when woken: an event left the queue (a `pin_change`, so the pin may queue
                // its next one; a pulse-in's deferred reply, so its pin is free to read
                // again), so the edges a pin carries go out without waiting for another edge;
                // the enables changed (the pass reads the new ones).
                select(self.ports().wait_edge(), self.wake.wait()).await;
                at = clock.now();
            }
            next = Some(at.plus_us(interval));
            let watches: Vec<(PinRef, EventConfig, u16), MAX_EVENT_PINS> = self.with(|s| {
                s.watches
                    .iter()
                    .map(|w| (w.pin, w.cfg, w.generation))
                    .collect()
            });
            for (pin, cfg, generation) in watches {
                if cfg.rising || cfg.falling {
                    let edges = self.ports().take_edges(pin).ok();
                    let level = self.ports().digital_read(pin);
                    self.sampled_level(pin, generation, level.ok().map(|l| l.is_high()), edges);
                }
                if cfg.analog_window {
                    if let Ok(v) = self.ports().analog_read(pin.port) {
                        self.sampled_analog(pin, generation, v);
                    }
                }
            }
        }
    }

    /// One sample of a pin with edge events: adds the edges latched by the port (`latched`)
    /// or, without a latch, the level change the sample shows, to the pin's count; queues a
    /// `pin_change` event when an edge in an enabled direction was counted and the pin's last
    /// event has left the queue (otherwise the edges are carried: when it leaves, the
    /// sampler is woken). The event carries the level and every edge counted since the
    /// pin's previous event, rising and falling; one dropped on a full queue is counted and
    /// its edges carried to the pin's next event.
    ///
    /// `read` is the level the sample read, `None` when the read failed (a pulse-in holds
    /// the pin: `Busy`). A latched pin's level then follows from its last level and the
    /// parity of the edges latched since (every edge is latched exactly once); with no
    /// level known yet, the latched edges are carried to the next sample. Taken edges are
    /// never dropped.
    fn sampled_level(
        &self,
        pin: PinRef,
        generation: u16,
        read: Option<bool>,
        latched: Option<EdgeCount>,
    ) {
        let fire = self.with(|s| {
            let w = s
                .watches
                .iter_mut()
                .find(|w| w.pin == pin && w.generation == generation)?;
            let taken = latched.unwrap_or(EdgeCount::NONE);
            let high = match (read, w.level) {
                (Some(high), _) => high,
                (None, Some(last)) if latched.is_some() => {
                    last ^ ((taken.rising ^ taken.falling) & 1 == 1)
                }
                _ => {
                    w.edges = w.edges.plus(taken);
                    return None;
                }
            };
            let prev = w.level.replace(high);
            let seen = match latched {
                Some(n) => n,
                None => match prev {
                    Some(false) if high => EdgeCount {
                        rising: 1,
                        falling: 0,
                    },
                    Some(true) if !high => EdgeCount {
                        rising: 0,
                        falling: 1,
                    },
                    _ => EdgeCount::NONE,
                },
            };
            w.edges = w.edges.plus(seen);
            let due =
                (w.cfg.rising && w.edges.rising > 0) || (w.cfg.falling && w.edges.falling > 0);
            (due && !w.queued).then(|| (core::mem::replace(&mut w.edges, EdgeCount::NONE), high))
        });
        if let Some((n, high)) = fire {
            let [r0, r1] = n.rising.to_le_bytes();
            let [f0, f1] = n.falling.to_le_bytes();
            let payload = [high as u8, r0, r1, f0, f1];
            let queued = self.push_event(EventKind::PinChange, pin, None, Status::Ok, &payload);
            self.with(|s| {
                if let Some(w) = s.watches.iter_mut().find(|w| w.pin == pin) {
                    if queued {
                        w.queued = true;
                    } else {
                        // Dropped (and counted): its edges go with the pin's next event.
                        w.edges = w.edges.plus(n);
                    }
                }
            });
        }
    }

    fn sampled_analog(&self, pin: PinRef, generation: u16, v: u16) {
        let fire = self.with(|s| {
            let w = s
                .watches
                .iter_mut()
                .find(|w| w.pin == pin && w.generation == generation)?;
            let inside = (w.cfg.low..=w.cfg.high).contains(&v);
            let prev = w.inside.replace(inside);
            (prev != Some(inside)).then_some(inside)
        });
        if let Some(inside) = fire {
            let [a, b] = v.to_le_bytes();
            self.push_event(
                EventKind::AnalogThreshold,
                pin,
                None,
                Status::Ok,
                &[a, b, inside as u8],
            );
        }
    }

    /// Stamps each accepted pulse-in with the time it was accepted and hands it to the
    /// workers.
    async fn stamp_pulse_jobs<C: Clock>(&self, clock: &C) -> ! {
        loop {
            let mut job = self.jobs.receive().await;
            job.accepted = Some(clock.now());
            // Never waits: at most DEFERRED_QUEUE_LEN jobs are accepted and unfinished.
            self.stamped.send(job).await;
        }
    }

    async fn pulse_worker<C: Clock>(&self, clock: &C) -> ! {
        loop {
            let job = self.stamped.receive().await;
            // What is left of the timeout counted from acceptance, in whole ms, rounded up: a
            // job a worker starts at once gets its whole timeout (a few µs pass between the
            // stamp and the start), and no measurement ends more than 1 ms after acceptance +
            // timeout, well inside the MB's deadline (its request timeout + the pulse timeout).
            let waited_us = job
                .accepted
                .map_or(0, |at| clock.now().0.saturating_sub(at.0));
            let left_ms = (u64::from(job.timeout_ms) * 1000)
                .saturating_sub(waited_us)
                .div_ceil(1000);
            let r = match u16::try_from(left_ms).unwrap_or(job.timeout_ms) {
                0 => Err(PortError::Timeout),
                ms => self.ports().pulse_in(job.pin, job.edge, ms).await,
            };
            self.with(|s| s.pulse_pins.retain(|p| *p != job.pin));
            let ev = match r {
                Ok(us) => OutEvent::new(
                    EventKind::DeferredReply,
                    job.pin,
                    job.seq,
                    Status::Ok,
                    &us.to_le_bytes(),
                ),
                Err(e) => OutEvent::new(
                    EventKind::DeferredReply,
                    job.pin,
                    job.seq,
                    port_status(e),
                    &[],
                ),
            };
            self.send_event(ev).await;
        }
    }
}
