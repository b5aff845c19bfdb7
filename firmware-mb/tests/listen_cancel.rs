//! The runtimes never drop `MultiMaster::listen` once a transfer to the node has started
//! (review finding D1). Real ports cannot give back bytes they already took off the wire (the
//! RP2040 driver keeps them in locals; the STM32 one leaves SCL stretched for good), so the
//! only call that may be raced against a job, a timer or an event is `addressed`.
//!
//! The double here models a port on which a transfer to the node starts at a chosen time and
//! lasts `transfer_us`: `addressed` returns once it has started; `listen` returns at its end,
//! and a `listen` future dropped in between is counted. The runtimes that selected on `listen`
//! failed all three tests.

#[allow(unused)]
mod common;

use std::cell::{Cell, RefCell};
use std::future::poll_fn;
use std::rc::Rc;
use std::task::{Poll, Waker};

use common::{mb_address, sim, FakePorts, TestClock};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_mb::{MbConfig, Motherboard};
use x10_hal::bus::{BusError, Incoming, MultiMaster};
use x10_hal::time::{Clock, Instant};
use x10_microcode::{Address, Level, Op, Pin, Port};

#[derive(Clone, Default)]
struct Probe {
    /// A transfer to the node started at this time (µs) and lasts `transfer_us`.
    started: Rc<Cell<Option<u64>>>,
    transfer_us: Rc<Cell<u64>>,
    waker: Rc<RefCell<Option<Waker>>>,
    /// Controller calls that lose arbitration to a transfer to the node (which then starts).
    lose_next: Rc<Cell<u32>>,
    /// `listen` futures dropped while a transfer was being received.
    dropped_mid_transfer: Rc<Cell<u32>>,
    /// Transfers received whole.
    received: Rc<Cell<u32>>,
    /// Controller writes that went out.
    writes: Rc<RefCell<Vec<(u64, u8)>>>,
}

impl Probe {
    fn start(&self, at_us: u64) {
        self.started.set(Some(at_us));
        if let Some(w) = self.waker.borrow_mut().take() {
            w.wake();
        }
    }

    async fn wait_started(&self) -> u64 {
        poll_fn(|cx| match self.started.get() {
            Some(t) => Poll::Ready(t),
            None => {
                *self.waker.borrow_mut() = Some(cx.waker().clone());
                Poll::Pending
            }
        })
        .await
    }
}

struct PartialBus {
    clock: TestClock,
    probe: Probe,
}

struct ListenGuard {
    probe: Probe,
    done: bool,
}

impl Drop for ListenGuard {
    fn drop(&mut self) {
        if !self.done && self.probe.started.get().is_some() {
            let n = self.probe.dropped_mid_transfer.get();
            self.probe.dropped_mid_transfer.set(n + 1);
        }
    }
}

impl MultiMaster for PartialBus {
    async fn write(&mut self, addr: u8, _bytes: &[u8]) -> Result<(), BusError> {
        if self.probe.lose_next.get() > 0 {
            // Lost in the address byte to a transfer to us, which goes on on the wire.
            self.probe.lose_next.set(self.probe.lose_next.get() - 1);
            let at = self.clock.now().plus_us(50);
            self.clock.sleep_until(at).await;
            self.probe.start(self.clock.now_us());
            return Err(BusError::ArbitrationLost);
        }
        let at = self.clock.now().plus_us(100);
        self.clock.sleep_until(at).await;
        self.probe
            .writes
            .borrow_mut()
            .push((self.clock.now_us(), addr));
        Ok(())
    }

    async fn write_read(&mut self, _a: u8, _b: &[u8], read: &mut [u8]) -> Result<(), BusError> {
        read.fill(0xFF);
        Err(BusError::Nack)
    }

    async fn addressed(&mut self) -> Result<(), BusError> {
        self.probe.wait_started().await;
        Ok(())
    }

    async fn listen(&mut self, _buf: &mut [u8]) -> Result<Incoming, BusError> {
        let mut guard = ListenGuard {
            probe: self.probe.clone(),
            done: false,
        };
        let from = self.probe.wait_started().await;
        let end = Instant(from + self.probe.transfer_us.get());
        self.clock.sleep_until(end).await;
        guard.done = true;
        self.probe.started.set(None);
        self.probe.received.set(self.probe.received.get() + 1);
        // An empty write: nothing to route (counted as a bad event), the point is the timing.
        Ok(Incoming::Write(0))
    }

    async fn respond(&mut self, _bytes: &[u8]) -> Result<(), BusError> {
        Ok(())
    }
}

fn motherboard(clock: &TestClock) -> Motherboard<FakePorts> {
    Motherboard::new(
        MbConfig::thesis_compatible(mb_address()),
        FakePorts::new(clock.clone(), 2, 2),
    )
}

fn output() -> Op<'static> {
    Op::DigitalWrite(Port::actuator(1).unwrap().pin(Pin::A), Level::High)
}

#[test]
fn a_request_queued_while_a_write_to_the_mb_is_received_waits_for_its_end() {
    let clock = TestClock::new();
    let mb = motherboard(&clock);
    let probe = Probe::default();
    probe.transfer_us.set(1_000);
    let bus = PartialBus {
        clock: clock.clone(),
        probe: probe.clone(),
    };
    let ten = Address::new(0x0a).unwrap();
    sim(&clock, mb.run(bus), async {
        clock.sleep_until(Instant(10_000)).await;
        // A daughterboard's event to the MB starts now (address matched, bytes flowing)...
        probe.start(clock.now_us());
        clock.sleep_until(Instant(10_300)).await;
        // ...and 300 µs into it a robot task sends an output.
        mb.call(ten, output()).await.unwrap();
    });
    assert_eq!(probe.dropped_mid_transfer.get(), 0);
    assert_eq!(probe.received.get(), 1);
    // The output went out after the event's end (11 ms), taking 100 µs.
    assert_eq!(*probe.writes.borrow(), vec![(11_100, 0x0a)]);
}

/// The usual arbitration path: the MB's write loses to a DB's event (a pin-change event is
/// 8 bytes with the address = 720 µs at the boards' 100 kHz), longer than
/// `arbitration_wait_us` (400 µs): the event is received whole, then the write is retried.
#[test]
fn an_event_that_won_arbitration_is_received_whole_even_past_the_arbitration_wait() {
    let clock = TestClock::new();
    let mb = motherboard(&clock);
    let probe = Probe::default();
    probe.transfer_us.set(720);
    probe.lose_next.set(1);
    let bus = PartialBus {
        clock: clock.clone(),
        probe: probe.clone(),
    };
    let ten = Address::new(0x0a).unwrap();
    sim(&clock, mb.run(bus), async {
        clock.sleep_until(Instant(10_000)).await;
        mb.call(ten, output()).await.unwrap();
    });
    assert_eq!(probe.dropped_mid_transfer.get(), 0);
    assert_eq!(probe.received.get(), 1);
    // Lost at 10 050, the event ends at 10 770 (past the 400 µs wait), the retry ends 100 µs
    // later. (The double's transfer is empty, not an event, so the attempt counts.)
    assert_eq!(*probe.writes.borrow(), vec![(10_870, 0x0a)]);
    let d = mb.diagnostics();
    assert_eq!((d.arbitration_lost, d.yields, d.retries), (1, 0, 1));
}

/// The same on a daughterboard: an MB request to the board is being received when the board
/// queues an event of its own (its failsafe trips at 2 ms): the event waits for the end of the
/// request.
#[test]
fn a_daughterboard_event_queued_mid_request_waits_for_the_request_to_end() {
    use firmware_db::{Daughterboard, DbConfig, TargetConfig};
    use x10_microcode::BoardKind;
    let clock = TestClock::new();
    let mut cfg = DbConfig::new(Address::new(9).unwrap(), BoardKind::SIMULATED);
    cfg.failsafe_timeout_ms = 2;
    let db: Daughterboard<NoopRawMutex, FakePorts> =
        Daughterboard::new(FakePorts::new(clock.clone(), 2, 2), cfg);
    let probe = Probe::default();
    probe.transfer_us.set(500); // the MB's 4-byte request + address at 100 kHz: 450 µs
    let bus = PartialBus {
        clock: clock.clone(),
        probe: probe.clone(),
    };
    sim(
        &clock,
        firmware_db::run(&db, bus, &clock, TargetConfig::new(mb_address())),
        async {
            clock.sleep_until(Instant(1_900)).await;
            // An MB request to the board starts at 1.9 ms; the failsafe trips at 2.0 ms.
            probe.start(1_900);
            clock.sleep_until(Instant(4_300)).await;
        },
    );
    assert_eq!(db.diagnostics().failsafe_trips, 1);
    assert_eq!(probe.dropped_mid_transfer.get(), 0);
    assert_eq!(probe.received.get(), 1);
    // The boot event at 0 (+100 µs), the failsafe event right after the request ended at
    // 2.4 ms, then the one reporting that request (empty here, a bad length), paced: it waits
    // 0.5..1.5 ms after the failsafe event (`TargetConfig::event_gap_us`, 1 ms randomized;
    // a write is logged when it ends, 100 µs later).
    let mb = mb_address().get();
    let writes = probe.writes.borrow().clone();
    assert_eq!(writes.len(), 3, "{writes:?}");
    assert_eq!(writes[..2], [(100, mb), (2_500, mb)]);
    assert_eq!(writes[2].1, mb);
    assert!((3_100..4_100).contains(&writes[2].0), "{writes:?}");
    assert_eq!(db.diagnostics().bad_length, 1);
}
