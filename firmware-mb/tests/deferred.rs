//! Requests whose caller gave up while the board still had work for them: a late deferred
//! reply never completes another request, and a `set_pec` / `set_failsafe` the board applied
//! is applied on the motherboard's side too.

mod common;

use common::{PortOp, Seen, World};
use std::rc::Rc;
use x10_devices::LinkError;
use x10_microcode::{Address, Edge, Op, Pin, Port};

impl World {
    /// The sequence numbers of the pulse-ins sent to DB 9, in order.
    fn pulse_in_seqs(&self) -> Vec<u8> {
        self.pulse_in_seqs_to(9)
    }

    /// The sequence numbers of the pulse-ins sent to board `db`, in order.
    fn pulse_in_seqs_to(&self, db: u8) -> Vec<u8> {
        self.bus
            .seen()
            .into_iter()
            .filter_map(|(_, s)| match s {
                Seen::WriteRead(a, b, _) if a == db && b[0] & 0xFE == 0x12 => Some(b[3]),
                _ => None,
            })
            .collect()
    }
}

fn nine() -> Address {
    Address::external(9).unwrap()
}

fn pulse_in(port: u8) -> Op<'static> {
    Op::PulseIn {
        pin: Port::sensor(port).unwrap().pin(Pin::A),
        edge: Edge::Rising,
        timeout_ms: Some(1000),
    }
}

/// The review's scenario: pulse-in A (S1.A) is given up while the board measures, 255 pings
/// wrap the board's sequence counter, pulse-in B (S2.A) follows. A's deferred reply must not
/// complete B: A's sequence number is still held (B gets the next one), and A's reply is
/// counted as late.
#[test]
fn a_late_deferred_reply_never_completes_a_request_after_the_sequence_counter_wraps() {
    let w = World::new();
    // A's measurement ends after 500 ms with 77 µs; B's after 600 ms with 999 µs.
    w.db9
        .ports()
        .pulses
        .borrow_mut()
        .extend([(500_000, Ok(77)), (600_000, Ok(999))]);
    let (a, b) = w.sim(async {
        w.at(1_000).await;
        let a = w.mb.call_with_timeout(nine(), pulse_in(1), 10_000).await;
        for _ in 0..255 {
            w.mb.call(nine(), Op::Ping).await.unwrap();
        }
        let b = w.mb.call(nine(), pulse_in(2)).await;
        (a, b.map(|p| p.to_vec()))
    });
    assert_eq!(a, Err(LinkError::Timeout));
    assert_eq!(b, Ok(999u32.to_le_bytes().to_vec()));
    // A had 0, the pings 1..=255; 0 is still held by A, so B gets 1.
    assert_eq!(w.pulse_in_seqs(), [0, 1]);
    // Both measured on the board, each on its own pin with its full timeout.
    let measured: Vec<PortOp> = w
        .db9
        .ports()
        .take_log()
        .into_iter()
        .filter(|op| matches!(op, PortOp::PulseIn(..)))
        .collect();
    let s = |n| Port::sensor(n).unwrap().pin(Pin::A);
    assert_eq!(
        measured,
        [
            PortOp::PulseIn(s(1), Edge::Rising, 1000),
            PortOp::PulseIn(s(2), Edge::Rising, 1000)
        ]
    );
    let d = w.mb.diagnostics();
    assert_eq!(
        (d.late_replies, d.duplicate_replies, d.unknown_replies),
        (1, 0, 0)
    );
    assert_eq!((d.timeouts, d.completed), (1, 256));
}

/// A `set_failsafe` whose caller gave up while it was on the bus: the board has it, so the
/// motherboard keeps it alive all the same.
#[test]
fn a_failsafe_acknowledged_after_its_caller_gave_up_is_kept_alive() {
    let w = World::new();
    w.sim(async {
        w.at(1_000).await;
        // The transfer takes 100 µs; the caller waits 50.
        let r =
            w.mb.call_with_timeout(nine(), Op::SetFailsafe { timeout_ms: 300 }, 50)
                .await;
        assert_eq!(r, Err(LinkError::Timeout));
        w.at(1_001_000).await;
    });
    assert_eq!(w.db9.failsafe_timeout_ms(), 300);
    assert_eq!(w.mb.keepalive_ms(nine()), 300);
    let d = w.mb.diagnostics();
    // The set_failsafe is read back (the board's reply confirms it): that reply came after
    // its caller gave up, and is counted as late.
    assert_eq!((d.timeouts, d.keepalives, d.late_replies), (1, 9, 1));
    assert_eq!(w.db9.diagnostics().failsafe_trips, 0);
}

/// A `set_pec` whose caller gave up while it was on the bus: the board has PEC on, and so
/// does the motherboard for it.
#[test]
fn pec_acknowledged_after_its_caller_gave_up_is_on_for_the_motherboard_too() {
    let w = World::new();
    let ping = w.sim(async {
        w.at(1_000).await;
        let r = w.mb.call_with_timeout(nine(), Op::SetPec(true), 50).await;
        assert_eq!(r, Err(LinkError::Timeout));
        w.at(2_000).await;
        assert!(w.mb.pec_enabled(nine()));
        w.mb.call(nine(), Op::Ping).await
    });
    assert_eq!(ping.map(|p| p.to_vec()), Ok(vec![]));
    let d = w.mb.diagnostics();
    assert_eq!((d.pec_resyncs, d.status_errors), (0, 0));
    assert_eq!(w.db9.diagnostics().pec_errors, 0);
}

/// Issue 22 item 8: a pulse-in whose `pending` reply is lost (here: garbled on the wire, so
/// it ends in `BadReply`) may be measuring on the board all the same. Its sequence number
/// stays held until the board's deadline: after 255 pings wrap the board's counter, the next
/// pulse-in on the same pin gets another number, so the old measurement's deferred reply is
/// counted as late and the new one gets its own value. (Before: the number was free again
/// after 16 requests, and the old reply completed the new pulse-in with the old value.)
#[test]
fn a_pulse_in_whose_pending_reply_was_lost_keeps_its_number_until_the_boards_deadline() {
    use common::Node;
    use std::cell::Cell;
    use x10_microcode::{PinRef, Status};
    let w = World::new();
    let s1a = Port::sensor(1).unwrap().pin(Pin::A);
    let pulse_ins = Rc::new(Cell::new(0u32));
    let n = pulse_ins.clone();
    // board 0x11: pings answered `ok`; the first pulse-in's `pending` arrives garbled (its
    // LEN byte says 5), the others intact
    w.bus.attach(
        0x11,
        Node::Script(Box::new(move |req: &[u8]| match req[0] {
            0x13 => {
                n.set(n.get() + 1);
                let len = if n.get() == 1 { 0x05 } else { 0x00 };
                (10, vec![req[3], 0x01, len])
            }
            _ => (10, vec![req[3], 0x00, 0x00]),
        })),
    );
    let eleven = Address::external(0x11).unwrap();
    let deferred = move |seq: u8, width: u32| {
        let mut f = vec![
            0x11,
            0x03,
            PinRef::to_byte(s1a),
            seq,
            Status::Ok.to_byte(),
            4,
        ];
        f.extend_from_slice(&width.to_le_bytes());
        f
    };
    let (a, b, seqs) = w.sim(async {
        w.at(1_000).await;
        let a = w.mb.call(eleven, pulse_in(1)).await;
        for _ in 0..255 {
            w.mb.call(eleven, Op::Ping).await.unwrap();
        }
        let seqs = w
            .bus
            .seen()
            .into_iter()
            .filter_map(|(_, s)| match s {
                Seen::WriteRead(0x11, b, _) if b[0] == 0x13 => Some(b[3]),
                _ => None,
            })
            .collect::<Vec<u8>>();
        let a_seq = seqs[0];
        let answer = async {
            w.at(w.clock.now_us() + 1_000).await;
            // the old measurement's deferred reply (77 µs), then the new one's (999 µs)
            w.bus.to_mb(deferred(a_seq, 77));
            w.at(w.clock.now_us() + 1_000).await;
            let b_seq = w.bus.seen().into_iter().rev().find_map(|(_, s)| match s {
                Seen::WriteRead(0x11, b, _) if b[0] == 0x13 => Some(b[3]),
                _ => None,
            });
            w.bus.to_mb(deferred(b_seq.unwrap(), 999));
        };
        let (_, b) = embassy_futures::join::join(answer, w.mb.call(eleven, pulse_in(1))).await;
        (a, b.map(|p| p.to_vec()), seqs)
    });
    assert_eq!(a, Err(LinkError::BadReply));
    assert_eq!(b, Ok(999u32.to_le_bytes().to_vec()));
    assert_eq!(seqs, [0]);
    let b_seq = w.pulse_in_seqs_to(0x11);
    assert_eq!(b_seq, [0, 1], "the second pulse-in skips the held number");
    let d = w.mb.diagnostics();
    assert_eq!((d.late_replies, d.bad_replies), (1, 1));
}

/// Issue 22 item 8: replies checked against the operation. A pulse-in answered `ok` at once
/// (instead of `pending`) is a bad reply; a deferred reply with `ok` and a payload of the
/// wrong length, or an error status with a payload, is a bad reply, not a value or that
/// status.
#[test]
fn immediate_ok_to_a_pulse_in_and_misshapen_deferred_replies_are_bad_replies() {
    use common::Node;
    use x10_microcode::{PinRef, Status};
    let w = World::new();
    let s1a = Port::sensor(1).unwrap().pin(Pin::A);
    // board 0x11 answers every pulse-in `pending` at once, except sequence 0: `ok`
    w.bus.attach(
        0x11,
        Node::Script(Box::new(|req: &[u8]| {
            let status = if req[3] == 0 { 0x00 } else { 0x01 };
            (10, vec![req[3], status, 0x00])
        })),
    );
    let eleven = Address::external(0x11).unwrap();
    let deferred = |seq: u8, status: Status, payload: &[u8]| {
        let mut f = vec![0x11, 0x03, PinRef::to_byte(s1a), seq, status.to_byte()];
        f.push(payload.len() as u8);
        f.extend_from_slice(payload);
        f
    };
    let (first, second, third, fourth) = w.sim(async {
        w.at(1_000).await;
        let first = w.mb.call(eleven, pulse_in(1)).await;
        let second = async {
            w.at(2_000).await;
            w.bus.to_mb(deferred(1, Status::Ok, &[1, 2]));
        };
        let (_, second) = embassy_futures::join::join(second, w.mb.call(eleven, pulse_in(1))).await;
        let third = async {
            w.at(3_000).await;
            w.bus.to_mb(deferred(2, Status::Timeout, &[1]));
        };
        let (_, third) = embassy_futures::join::join(third, w.mb.call(eleven, pulse_in(1))).await;
        let fourth = async {
            w.at(4_000).await;
            w.bus.to_mb(deferred(3, Status::Timeout, &[]));
        };
        let (_, fourth) = embassy_futures::join::join(fourth, w.mb.call(eleven, pulse_in(1))).await;
        (first, second, third, fourth)
    });
    assert_eq!(first, Err(LinkError::BadReply));
    assert_eq!(second, Err(LinkError::BadReply));
    assert_eq!(third, Err(LinkError::BadReply));
    assert_eq!(fourth, Err(LinkError::Status(Status::Timeout)));
}
