//! Issue 10, motherboard side: the safe defaults (PEC and a failsafe on every board, again
//! after each boot), replies checked against the operation, PEC switches applied only once
//! the board confirmed them.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use common::{Node, Seen, World};
use firmware_db::{Daughterboard, DbConfig, ALL_CAPABILITIES};
use std::rc::Rc;
use x10_devices::LinkError;
use x10_microcode::{pec, Address, BoardKind, Capabilities, Op, Port, Status};

fn db(b: u8) -> Address {
    Address::external(b).unwrap()
}

fn s1() -> Port {
    Port::sensor(1).unwrap()
}

/// `frame` with the PEC byte of a request to DB `b`.
fn req_pec(b: u8, frame: &[u8]) -> Vec<u8> {
    let mut f = frame.to_vec();
    f.push(pec::compute(b << 1, frame));
    f
}

/// `frame` with the PEC byte of a reply from DB `b`.
fn reply_pec(b: u8, frame: &[u8]) -> Vec<u8> {
    let mut f = frame.to_vec();
    f.push(pec::compute(b << 1 | 1, frame));
    f
}

/// The transactions to `b`: (start, bytes, bytes read; 0 for a write).
fn to(w: &World, b: u8) -> Vec<(u64, Vec<u8>, usize)> {
    w.bus
        .seen()
        .into_iter()
        .filter_map(|(t, s)| match s {
            Seen::Write(a, bytes) if a == b => Some((t, bytes, 0)),
            Seen::WriteRead(a, bytes, n) if a == b => Some((t, bytes, n)),
            _ => None,
        })
        .collect()
}

#[test]
fn by_default_pec_and_the_failsafe_are_on_before_the_first_request() {
    let w = World::safe();
    let v = w.sim(async {
        w.at(1_000).await;
        w.mb.call(db(9), Op::AnalogRead(s1())).await
    });
    assert!(v.is_ok(), "{v:?}");
    assert!(w.mb.pec_enabled(db(9)) && w.db9.pec_enabled());
    assert_eq!(w.db9.failsafe_timeout_ms(), 300);
    assert_eq!(w.mb.keepalive_ms(db(9)), 300);
    // set_pec(1) without PEC, its reply read with PEC (4 bytes); then set_failsafe(300) and
    // the read itself (sequence number 0, taken by the caller first), both with PEC.
    assert_eq!(
        to(&w, 9),
        [
            (1_000, vec![0x07, 0x09, 0x00, 0x01, 0x01], 4),
            (1_100, req_pec(9, &[0x03, 0x09, 0x00, 0x02, 0x2c, 0x01]), 4),
            (1_200, req_pec(9, &[0x30, 0x09, 0x80, 0x00]), 6),
        ]
    );
    // The internal board has no bus: no PEC, no set-up.
    let w = World::safe();
    w.sim(async { w.mb.call(Address::INTERNAL, Op::Ping).await.unwrap() });
    assert!(!w.mb.pec_enabled(Address::INTERNAL));
    assert!(to(&w, 0).is_empty());
}

/// A board that reset has PEC off: after its boot event nothing reaches it before PEC is on
/// again, and requests queued meanwhile go out with PEC. The dispatcher prepares it again at
/// once (its failsafe was off too), not only before its next request.
#[test]
fn after_a_boot_pec_is_turned_on_again_before_anything_else_reaches_the_board() {
    let w = World::safe();
    w.sim(async {
        w.at(1_000).await;
        w.mb.call(db(9), Op::Ping).await.unwrap();
        // DB 9 restarts: PEC off, and its boot event reaches the motherboard.
        w.at(10_000).await;
        let off = req_pec(9, &[0x07, 0x09, 0x00, 0x50, 0x00]);
        w.db9.handle_write(&off, false);
        assert!(!w.db9.pec_enabled());
        let boot = common::boot_event(9, &w.db9.identity());
        w.bus.to_mb(boot);
        w.at(11_000).await;
        assert!(w.mb.pec_enabled(db(9)) && w.db9.pec_enabled());
        assert_eq!(w.db9.failsafe_timeout_ms(), 300);
        w.mb.call(db(9), Op::Ping).await.unwrap();
    });
    assert!(w.db9.pec_enabled());
    let after: Vec<_> = to(&w, 9).into_iter().filter(|t| t.0 >= 10_000).collect();
    assert_eq!(after.len(), 3, "{after:?}");
    assert_eq!(after[0].1[..4], [0x07, 0x09, 0x00, after[0].1[3]]);
    assert_eq!(after[0].1.len(), 5, "set_pec(1) goes without PEC");
    assert_eq!(after[1].1[0], 0x03, "then the failsafe");
    assert_eq!(after[2].1[0], 0x00, "then the ping");
    assert_eq!(after[2].1.len(), 5, "with PEC");
    assert_eq!(w.db9.diagnostics().pec_errors, 0);
}

/// Finding "PEC switch refused silently": the motherboard applied a `set_pec` once the write
/// was acknowledged, so a board that refused it (no PEC capability) was then sent frames with
/// PEC it took for data. Now the switch is read back: refused, it is not applied.
#[test]
fn a_refused_pec_switch_is_not_applied() {
    let w = World::new();
    let plain = Rc::new(Daughterboard::new(
        common::FakePorts::new(w.clock.clone(), 3, 2),
        DbConfig {
            capabilities: Capabilities(ALL_CAPABILITIES.0 & !Capabilities::PEC),
            ..DbConfig::new(db(0x11), BoardKind::SIMULATED)
        },
    ));
    w.bus.attach(0x11, Node::Db(plain.clone()));
    let r = w.sim(async { w.mb.call(db(0x11), Op::SetPec(true)).await });
    assert_eq!(r, Err(LinkError::Status(Status::Unsupported)));
    assert!(!w.mb.pec_enabled(db(0x11)));
    // With the safe defaults such a board cannot be reached: nothing unchecked goes to it.
    let w = World::safe();
    let plain = Rc::new(Daughterboard::new(
        common::FakePorts::new(w.clock.clone(), 3, 2),
        DbConfig {
            capabilities: Capabilities(ALL_CAPABILITIES.0 & !Capabilities::PEC),
            ..DbConfig::new(db(0x11), BoardKind::SIMULATED)
        },
    ));
    w.bus.attach(0x11, Node::Db(plain.clone()));
    let r = w.sim(async { w.mb.call(db(0x11), Op::AnalogRead(s1())).await });
    assert_eq!(r, Err(LinkError::Status(Status::Unsupported)));
    assert!(to(&w, 0x11).iter().all(|(_, b, _)| b[0] == 0x07));
}

/// Issue 10 (a): analog reads returned `Ok` with an empty payload. A reply whose LEN byte
/// says 0 where the operation has 2 bytes is refused, even with a PEC byte that matches.
#[test]
fn a_reply_of_a_length_the_operation_does_not_allow_is_a_bad_reply() {
    let w = World::safe();
    w.bus.attach(
        0x12,
        Node::Script(Box::new(|req| {
            let seq = req[3];
            let reply = match req[0] {
                // set_pec and set_failsafe: ok, with PEC.
                0x07 | 0x03 => vec![seq, 0x00, 0x00],
                // the analog read: `ok`, no payload, with a PEC that matches.
                _ => vec![seq, 0x00, 0x00],
            };
            (0, reply_pec(0x12, &reply))
        })),
    );
    let r = w.sim(async { w.mb.call(db(0x12), Op::AnalogRead(s1())).await });
    assert_eq!(r, Err(LinkError::BadReply));
    assert_eq!(w.mb.diagnostics().bad_replies, 1);
}

/// Issue 10 (b): a `pec_mismatch` reply to a frame sent without PEC was taken unchecked, and
/// a flipped status bit made it `ok`. Now it counts only with a valid PEC byte (and then
/// shows that the board has PEC on); anything else is a bad reply.
#[test]
fn a_pec_mismatch_reply_is_checked_with_its_pec() {
    for (reply, want, pec_on) in [
        // The board's genuine answer: seq, pec_mismatch, 0, PEC.
        (
            reply_pec(0x13, &[0x00, 0x08, 0x00]),
            Err(LinkError::Status(Status::PecMismatch)),
            true,
        ),
        // The same with a wrong PEC byte.
        (
            vec![0x00, 0x08, 0x00, 0x00],
            Err(LinkError::BadReply),
            false,
        ),
        // Status bit 3 flipped: `ok` with no payload, the PEC of the original frame.
        (
            {
                let mut r = reply_pec(0x13, &[0x00, 0x08, 0x00]);
                r[1] = 0x00;
                r
            },
            Err(LinkError::BadReply),
            false,
        ),
    ] {
        let w = World::new();
        w.bus
            .attach(0x13, Node::Script(Box::new(move |_| (0, reply.clone()))));
        let r = w.sim(async { w.mb.call(db(0x13), Op::AnalogRead(s1())).await });
        assert_eq!(r, want);
        assert_eq!(w.mb.pec_enabled(db(0x13)), pec_on);
    }
}

/// The thesis-exact mode stays available: thesis bytes, no set-up, no failsafe.
#[test]
fn the_thesis_mode_sends_the_thesis_bytes() {
    let w = World::new();
    w.sim(async {
        w.at(1_000).await;
        w.mb.call(db(9), Op::AnalogRead(s1())).await.unwrap();
    });
    assert_eq!(to(&w, 9), [(1_000, vec![0x30, 0x09, 0x80, 0x00], 5)]);
    assert_eq!(w.db9.failsafe_timeout_ms(), 0);
}

/// With the defaults a program cannot switch PEC off on a board (nothing is sent).
#[test]
fn pec_off_is_refused_with_the_safe_defaults() {
    let w = World::safe();
    let r = w.sim(async { w.mb.call(db(9), Op::SetPec(false)).await });
    assert!(matches!(r, Err(LinkError::Invalid(_))));
    assert!(to(&w, 9).is_empty());
}

/// An `event_enable` is read back: one the board refuses ends in its status, not `Ok` (a
/// program would otherwise wait for events that never come: the soak counted such losses as
/// silent).
#[test]
fn a_refused_event_enable_ends_in_the_boards_status() {
    use x10_microcode::{EventConfig, Pin};
    let w = World::safe();
    // DB 9 has 3 sensor ports: only the board knows that port 5 is not there.
    let missing = Port::sensor(5).unwrap().pin(Pin::A);
    let edges = EventConfig {
        rising: true,
        ..EventConfig::OFF
    };
    let (refused, accepted) = w.sim(async {
        w.at(1_000).await;
        let refused = w.mb.call(db(9), Op::EventEnable(missing, edges)).await;
        let accepted =
            w.mb.call(db(9), Op::EventEnable(s1().pin(Pin::A), edges))
                .await;
        (refused, accepted)
    });
    // Refused, and the caller learns it.
    assert_eq!(refused, Err(LinkError::Status(Status::PortOutOfRange)));
    assert_eq!(accepted.map(|p| p.len()), Ok(0));
    // Both went out as a write and a read of the 3-byte status reply plus its PEC byte.
    let enables: Vec<usize> = to(&w, 9)
        .into_iter()
        .filter(|(_, bytes, _)| bytes.first() == Some(&0x07) && bytes.get(3) != Some(&0x01))
        .map(|(_, _, read)| read)
        .collect();
    assert!(enables.iter().all(|&n| n == 4), "{enables:?}");
}

/// Issue 22 item 7: a board restarts and its `boot` event is lost. Its first output, framed
/// with PEC and read back (the defaults), is refused (`bad_length`: the board took the check
/// for data): the caller sees it (`BadReply`: the refusal comes without PEC, so it cannot be
/// trusted as a status), never `Ok`. The unchecked refusal shows the board lost PEC: the
/// motherboard prepares it again (PEC, failsafe, both read back), and the next output
/// reaches the port (checked on the port itself). (Outputs not read back, as with
/// `confirm_outputs: false`, get the same re-preparation from the unchecked `rejected`
/// event: `routing.rs`.)
#[test]
fn a_board_whose_boot_event_was_lost_is_prepared_again_when_it_refuses_our_pec() {
    let unconfirmed = firmware_mb::MbConfig {
        confirm_outputs: false,
        ..firmware_mb::MbConfig::new(common::mb_address())
    };
    // (outputs read back?, the first output's outcome, bad_events)
    for (w, confirmed) in [
        (World::safe(), true),
        (World::with_config(unconfirmed), false),
    ] {
        let a1b = Port::actuator(1).unwrap().pin(x10_microcode::Pin::B);
        let (first, second) = w.sim(async {
            w.at(1_000).await;
            w.mb.call(db(9), Op::Ping).await.unwrap();
            // DB 9 restarts: PEC and failsafe off; its boot event never arrives.
            w.at(10_000).await;
            let off = req_pec(9, &[0x07, 0x09, 0x00, 0x50, 0x00]);
            w.db9.handle_write(&off, false);
            let no_failsafe = [0x03, 0x09, 0x00, 0x51, 0x00, 0x00];
            w.db9.handle_write(&no_failsafe, false);
            assert!(!w.db9.pec_enabled());
            let high = Op::DigitalWrite(a1b, x10_microcode::Level::High);
            let first = w.mb.call(db(9), high).await;
            w.at(20_000).await;
            let second = w.mb.call(db(9), high).await;
            w.at(21_000).await;
            (first, second)
        });
        // Read back, the first is refused and its caller knows; a single write is
        // acknowledged on the bus and its refusal comes after, as an unchecked `rejected`
        // event that shows the board lost PEC. Either way the second went out once the board
        // was prepared again.
        let (first_expected, bad_events) = if confirmed {
            (Err(LinkError::BadReply), 0)
        } else {
            (Ok(Default::default()), 1)
        };
        assert_eq!((first, second), (first_expected, Ok(Default::default())));
        assert!(w.db9.pec_enabled());
        assert_eq!(w.db9.failsafe_timeout_ms(), 300);
        assert!(w.db9.ports().digital.borrow()[&a1b.to_byte()]);
        let d = w.mb.diagnostics();
        assert_eq!(
            (d.pec_resyncs, d.bad_events, d.rejected),
            (1, bad_events, 0)
        );
    }
}

/// Issue 22 item 10: a program's `set_failsafe(100)` reaches the board (which had 300 ms),
/// but its reply is garbled on the wire: the call ends in `BadReply`, and the board may run
/// either failsafe. The motherboard keeps the faster keepalive, so the board never trips
/// (before: it kept the 300 ms schedule and the board tripped ten times a second).
#[test]
fn a_failsafe_whose_reply_was_lost_is_kept_alive_at_the_faster_rate() {
    let w = World::safe();
    let r = w.sim(async {
        w.at(1_000).await;
        w.mb.call(db(9), Op::Ping).await.unwrap();
        w.bus.flip_reply(9, vec![0x00, 0x01]);
        let r = w.mb.call(db(9), Op::SetFailsafe { timeout_ms: 100 }).await;
        w.at(1_001_000).await;
        r
    });
    assert_eq!(r, Err(LinkError::BadReply));
    assert_eq!(w.db9.failsafe_timeout_ms(), 100);
    assert_eq!(w.mb.keepalive_ms(db(9)), 100);
    assert_eq!(w.db9.diagnostics().failsafe_trips, 0);
}

/// Issue 22 item 10: a program turns PEC on for the internal board; its keepalive goes on
/// with PEC and is read back, so the board's failsafe never trips and no heartbeat counts as
/// sent unless the board took it (before: every internal heartbeat was refused as
/// `bad_length`, and counted as sent).
#[test]
fn internal_heartbeats_follow_the_internal_boards_pec_setting() {
    let w = World::new();
    w.sim(async {
        w.at(1_000).await;
        let internal = Address::INTERNAL;
        w.mb.call(internal, Op::SetFailsafe { timeout_ms: 300 })
            .await
            .unwrap();
        w.mb.call(internal, Op::SetPec(true)).await.unwrap();
        w.at(1_001_000).await;
    });
    let internal = w.mb.internal().diagnostics();
    assert_eq!(
        (
            internal.failsafe_trips,
            internal.pec_errors,
            internal.bad_length
        ),
        (0, 0, 0)
    );
    let d = w.mb.diagnostics();
    assert_eq!((d.keepalives, d.keepalive_failures, d.rejected), (9, 0, 0));
}
