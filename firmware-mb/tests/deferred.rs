//! Requests whose caller gave up while the board still had work for them: a late deferred
//! reply never completes another request, and a `set_pec` / `set_failsafe` the board applied
//! is applied on the motherboard's side too.

mod common;

use common::{PortOp, Seen, World};
use x10_devices::LinkError;
use x10_microcode::{Address, Edge, Op, Pin, Port};

impl World {
    /// The sequence numbers of the pulse-ins sent to DB 9, in order.
    fn pulse_in_seqs(&self) -> Vec<u8> {
        self.bus
            .seen()
            .into_iter()
            .filter_map(|(_, s)| match s {
                Seen::WriteRead(9, b, _) if b[0] & 0xFE == 0x12 => Some(b[3]),
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
