//! Issue 10, finding "keepalive starved": with the failsafe on by default, callers that keep
//! every pending slot busy must not delay the keepalive of a quiet board until its failsafe
//! trips; and every board of a full bus (110 DBs) is prepared and kept alive.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use std::rc::Rc;

use common::{db, Node, Seen, World};
use embassy_futures::join::join_array;
use x10_microcode::{Address, Op, Pin, Port};

fn addr(b: u8) -> Address {
    Address::external(b).unwrap()
}

/// Sixteen tasks (one per pending slot) read DB 10 back to back for a second; DB 9, prepared
/// at first contact with the default 300 ms failsafe, hears nothing from them. Before the
/// fix the keepalive needed a pending slot, never found one free, and DB 9 tripped.
#[test]
fn callers_that_keep_every_slot_busy_do_not_starve_the_keepalive() {
    let w = World::safe();
    let db10 = Rc::new(db(&w.clock, 10));
    w.bus.attach(10, Node::Db(db10.clone()));
    let s1a = Port::sensor(1).unwrap().pin(Pin::A);
    let done = w.sim(async {
        w.at(1_000).await;
        w.mb.call(addr(9), Op::Ping).await.unwrap();
        w.mb.call(addr(10), Op::Ping).await.unwrap();
        let callers: [_; firmware_mb::MAX_PENDING] = core::array::from_fn(|_| async {
            let mut n = 0u32;
            while w.clock.now_us() < 1_000_000 {
                if w.mb.call(addr(10), Op::DigitalRead(s1a)).await.is_ok() {
                    n += 1;
                }
            }
            n
        });
        join_array(callers).await
    });
    let total: u32 = done.iter().sum();
    assert!(total > 1_000, "the callers did work: {total}");
    assert_eq!(w.db9.diagnostics().failsafe_trips, 0, "DB 9 tripped");
    assert_eq!(db10.diagnostics().failsafe_trips, 0);
    // Heartbeats reached DB 9 every 100 ms or so.
    let to9 = w
        .bus
        .seen()
        .into_iter()
        .filter(|(t, s)| *t > 200_000 && matches!(s, Seen::Write(9, _) | Seen::WriteRead(9, _, _)))
        .count();
    assert!(to9 >= 7, "{to9} transactions to DB 9 after 200 ms");
    assert!(w.mb.diagnostics().keepalives >= 7);
}

/// A full bus: 110 daughterboards (0x09..=0x76, the MB at 0x08; 0x77 is where unaddressed
/// boards listen, never a board's address), each prepared with the defaults (PEC, 300 ms
/// failsafe) and then left quiet: none trips. Before the fix the 17th board failed its
/// preparation with `Busy` (16 keepalive entries).
#[test]
fn a_full_bus_of_110_boards_is_prepared_and_kept_alive() {
    let w = World::safe();
    let boards: Vec<u8> = (0x0A..=0x76).collect();
    assert_eq!(boards.len() + 1, 110);
    let dbs: Vec<_> = boards
        .iter()
        .map(|&b| {
            let d = Rc::new(db(&w.clock, b));
            w.bus.attach(b, Node::Db(d.clone()));
            d
        })
        .collect();
    let results = w.sim(async {
        w.at(1_000).await;
        let mut r = vec![w.mb.call(addr(9), Op::Ping).await];
        for &b in &boards {
            r.push(w.mb.call(addr(b), Op::Ping).await);
        }
        w.at(2_000_000).await;
        r
    });
    assert!(results.iter().all(Result::is_ok), "{results:?}");
    for d in dbs.iter().chain([&w.db9]) {
        assert!(d.pec_enabled());
        assert_eq!(d.failsafe_timeout_ms(), 300);
        assert_eq!(d.diagnostics().failsafe_trips, 0);
    }
    for b in boards.iter().copied().chain([9]) {
        assert_eq!(w.mb.keepalive_ms(addr(b)), 300, "board {b}");
    }
}
