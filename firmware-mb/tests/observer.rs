//! The call observer (`Motherboard::with_observer`) hears of every finished call and, since the
//! USB link (issue 26), of every routed event with the time it was routed.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use std::sync::Mutex;

use common::{db, mb_address, sim, LoopBus, Node, TestClock};
use embassy_futures::join::join;
use firmware_mb::{CallObserver, CallRecord, MbConfig, Motherboard};
use x10_hal::time::{Clock, Instant};
use x10_microcode::{Address, Event, Level, Op, Pin, Port};

#[derive(Default)]
struct Heard(Mutex<Vec<String>>);

impl CallObserver for Heard {
    fn observe(&self, call: &CallRecord<'_>) {
        self.0.lock().unwrap().push(format!(
            "call db{} {} {:?} {}..{}",
            call.db.get(),
            call.op.name(),
            call.result.as_ref().map(|p| p.len()),
            call.started.as_micros(),
            call.ended.as_micros()
        ));
    }

    fn event(&self, ev: &Event<'_>, at: Instant) {
        self.0.lock().unwrap().push(format!(
            "event db{} {} seq {} at {}",
            ev.source.get(),
            ev.kind.name(),
            ev.seq,
            at.as_micros()
        ));
    }
}

#[test]
fn the_observer_hears_calls_and_routed_events_in_order() {
    let heard: &'static Heard = Box::leak(Box::default());
    let clock = TestClock::new();
    let mb = Box::leak(Box::new(
        Motherboard::new(
            MbConfig::thesis_compatible(mb_address()),
            common::FakePorts::new(clock.clone(), 2, 2),
        )
        .with_observer(heard),
    ));
    let bus = LoopBus::new(&clock);
    bus.attach(9, Node::Db(std::rc::Rc::new(db(&clock, 9))));
    let x10 = mb.handle();
    let pin = Port::sensor(1).unwrap().pin(Pin::A).to_byte();
    sim(&clock, join(mb.run(bus.clone()), bus.run_dbs()), async {
        clock.sleep_until(Instant(1_000)).await;
        let a1a = Port::actuator(1).unwrap().pin(Pin::A);
        x10.call(Address::INTERNAL, Op::DigitalWrite(a1a, Level::High))
            .await
            .unwrap();
        clock.sleep_until(Instant(5_000)).await;
        bus.to_mb(vec![
            0x09, 0x01, pin, 1, 0x00, 0x05, 0x01, 0x01, 0x00, 0x00, 0x00,
        ]);
        clock.sleep_until(Instant(10_000)).await;
    });
    let heard = heard.0.lock().unwrap().clone();
    let ours: Vec<&String> = heard
        .iter()
        .filter(|l| l.starts_with("call") || l.contains("pin_change"))
        .collect();
    assert_eq!(ours.len(), 2, "{heard:#?}");
    assert!(
        ours[0].starts_with("call db0 high Ok(0) 1000.."),
        "{}",
        ours[0]
    );
    assert!(
        ours[1].starts_with("event db9 pin_change seq 1 at "),
        "{}",
        ours[1]
    );
    // The boot events of the internal board and DB 9 were heard too, before the call.
    assert!(
        heard.iter().filter(|l| l.contains(" boot ")).count() >= 1,
        "{heard:#?}"
    );
}
