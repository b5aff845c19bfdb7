//! PEC on events: from a board with PEC negotiated an event must carry a valid PEC byte (a
//! `boot` event without PEC excepted); from a board with PEC off one with a valid PEC byte is
//! accepted too.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use common::{Db, World};
use embassy_futures::join::join;
use embassy_futures::select::{select, Either};
use x10_microcode::test_support::db9;
use x10_microcode::{pec, EventKind, Op, Pin, PinRef, Port};

impl World {
    /// Negotiates PEC with DB 9 (at 1 000 µs).
    async fn pec_on(&self) {
        self.at(1_000).await;
        self.mb.call(db9(), Op::SetPec(true)).await.unwrap();
        assert!(self.mb.pec_enabled(db9()) && self.db9.pec_enabled());
    }

    /// Waits for a pin event from S1A of DB 9 until `until`: its value and arrival time, or
    /// `None` if none came.
    async fn pin_event_until(&self, until: u64) -> Option<(Vec<u8>, u64)> {
        match select(self.mb.wait_event(db9(), s1a()), self.at(until)).await {
            Either::First(ev) => Some((ev.unwrap().value.to_vec(), self.clock.now_us())),
            Either::Second(()) => None,
        }
    }
}

fn s1a() -> PinRef {
    Port::sensor(1).unwrap().pin(Pin::A)
}

/// The PEC of an event covers the MB's address, write.
const MB_ADDR_BYTE: u8 = common::MB << 1;

/// A pin-change event from DB 9 on S1A, event counter `seq`, value `level`, without PEC.
fn pin_change(seq: u8, level: u8) -> Vec<u8> {
    vec![0x09, 0x01, s1a().to_byte(), seq, 0x00, 0x01, level]
}

fn with_pec(mut frame: Vec<u8>) -> Vec<u8> {
    frame.push(pec::compute(MB_ADDR_BYTE, &frame));
    frame
}

/// DB 9's boot event (always with its check).
fn boot(db9: &Db) -> Vec<u8> {
    common::boot_event(9, &db9.identity())
}

#[test]
fn an_event_with_a_good_pec_from_a_board_with_pec_is_delivered() {
    let w = World::new();
    let ev = with_pec(pin_change(1, 1));
    assert_eq!(ev, [0x09, 0x01, 0x80, 0x01, 0x00, 0x01, 0x01, ev[7]]);
    let got = w.sim(async {
        w.pec_on().await;
        w.at(2_000).await;
        w.bus.to_mb(ev);
        w.pin_event_until(10_000).await
    });
    assert_eq!(got, Some((vec![0x01], 2_000)));
    let d = w.mb.diagnostics();
    assert_eq!(d.bad_events, 0);
    assert!(w.mb.pec_enabled(db9()));
}

#[test]
fn an_event_with_a_bad_or_missing_pec_from_a_board_with_pec_is_counted_and_dropped() {
    let w = World::new();
    let good = with_pec(pin_change(4, 1));
    let mut wrong_pec = with_pec(pin_change(1, 1));
    *wrong_pec.last_mut().unwrap() ^= 0x5A;
    // The review's case: a frame with PEC whose LEN byte was corrupted by +1 reads, without
    // PEC, as a valid event with a two-byte value (the PEC byte taken for data).
    let mut long_len = with_pec(pin_change(2, 1));
    long_len[5] += 1;
    assert!(x10_microcode::Event::parse(&long_len).is_ok());
    let (dropped, first, got) = w.sim(async {
        w.pec_on().await;
        let events_before = w.mb.diagnostics().events;
        let dropped = async {
            w.at(2_000).await;
            w.bus.to_mb(wrong_pec);
            w.at(3_000).await;
            w.bus.to_mb(long_len);
            w.at(4_000).await;
            w.bus.to_mb(pin_change(3, 1)); // no PEC at all
            w.at(5_000).await;
            let d = w.mb.diagnostics();
            (d.bad_events, d.events - events_before)
        };
        // one task waits through all three: none wakes it
        let (dropped, first) = join(dropped, w.pin_event_until(6_000)).await;
        w.bus.to_mb(good);
        (dropped, first, w.pin_event_until(20_000).await)
    });
    assert_eq!(first, None);
    assert_eq!(dropped, (3, 0));
    // the waiter was live: the good event that came next reached it at once
    assert_eq!(got, Some((vec![0x01], 6_000)));
    let d = w.mb.diagnostics();
    assert_eq!((d.bad_events, d.events_dropped), (3, 0));
    assert!(w.mb.pec_enabled(db9()));
}

/// Issue 22 item 7: a `boot` event is accepted only with its check (a board sends it so
/// whatever its PEC setting); one without is counted and dropped like any other event without
/// PEC from a board with PEC on. A checked one turns PEC off.
#[test]
fn a_boot_event_needs_its_check_and_turns_pec_off() {
    let w = World::new();
    let rejected = vec![0x09, 0x05, 0x00, 0x07, 0x03, 0x00];
    assert_eq!(
        x10_microcode::Event::parse(&rejected).unwrap().kind,
        EventKind::Rejected
    );
    let checked = boot(&w.db9);
    let unchecked = checked[..checked.len() - 2].to_vec();
    assert!(x10_microcode::Event::parse(&unchecked).is_ok());
    let (before, after_unchecked, after_boot) = w.sim(async {
        w.pec_on().await;
        let before = w.mb.diagnostics();
        w.at(2_000).await;
        w.bus.to_mb(rejected);
        w.bus.to_mb(unchecked);
        w.at(3_000).await;
        let after = (w.mb.diagnostics(), w.mb.pec_enabled(db9()));
        w.bus.to_mb(checked);
        w.at(4_000).await;
        (before, after, w.mb.diagnostics())
    });
    let (d, pec) = after_unchecked;
    assert_eq!(
        (d.bad_events, d.rejected, d.boots, pec),
        (before.bad_events + 2, before.rejected, before.boots, true)
    );
    assert_eq!(
        (after_boot.bad_events, after_boot.boots),
        (d.bad_events, d.boots + 1)
    );
    assert!(!w.mb.pec_enabled(db9()));
    // The same unchecked boot from a board with PEC off is refused too.
    let w = World::new();
    let unchecked = boot(&w.db9)[..boot(&w.db9).len() - 2].to_vec();
    let d = w.sim(async {
        w.at(1_000).await;
        let before = w.mb.diagnostics();
        w.bus.to_mb(unchecked);
        w.at(2_000).await;
        (before, w.mb.diagnostics())
    });
    assert_eq!((d.1.bad_events, d.1.boots), (d.0.bad_events + 1, d.0.boots));
}

#[test]
fn a_board_with_pec_off_may_send_events_with_or_without_pec() {
    let w = World::new();
    let got = w.sim(async {
        w.at(1_000).await;
        assert!(!w.mb.pec_enabled(db9()));
        // with PEC (the board turned it on before the motherboard recorded it)
        w.bus.to_mb(with_pec(pin_change(1, 1)));
        let first = w.pin_event_until(2_000).await;
        w.at(3_000).await;
        w.bus.to_mb(pin_change(2, 0));
        let second = w.pin_event_until(4_000).await;
        (first, second)
    });
    assert_eq!(got, (Some((vec![0x01], 1_000)), Some((vec![0x00], 3_000))));
    assert_eq!(w.mb.diagnostics().bad_events, 0);
    assert!(!w.mb.pec_enabled(db9()));
}
