//! What the bus can do to a daughterboard: any bytes at all, and output requests hit by bit
//! flips. Nothing panics, every reply fits the reply buffer, and with PEC on (the
//! motherboard's default) a flipped request never reaches a port: what the ports were really
//! told (the fake ports' log) is the ground truth.

mod common;

use common::{FakePorts, TestClock};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig};
use proptest::prelude::*;
use x10_microcode::{pec, Address, BoardKind};

type Db = Daughterboard<NoopRawMutex, FakePorts>;

fn board() -> Db {
    let clock = TestClock::new();
    let cfg = DbConfig::new(Address::external(9).unwrap(), BoardKind::SIMULATED);
    Daughterboard::new(FakePorts::new(clock, 2, 2), cfg)
}

/// `frame` with its PEC over the write address byte of board 9.
fn with_pec(frame: &[u8]) -> Vec<u8> {
    let mut v = frame.to_vec();
    v.push(pec::compute(0x12, frame));
    v
}

/// A board with PEC on (set_pec(1), as the motherboard negotiates it).
fn board_with_pec() -> Db {
    let db = board();
    db.handle_write(&[0x07, 0x09, 0x00, 0x01, 0x01], true);
    let mut rx = [0u8; 40];
    let _ = db.take_reply(&mut rx);
    assert!(db.pec_enabled());
    db
}

/// Output requests of every kind an actuator port takes, each valid (PEC added later).
const OUTPUTS: &[&[u8]] = &[
    &[0x12, 0x09, 0x01, 0x02],             // digital HIGH, actuator 1 pin B
    &[0x11, 0x09, 0x02, 0x03],             // digital LOW, actuator 2 pin A
    &[0x20, 0x09, 0x02, 0x04, 200],        // PWM duty 200, actuator 2 pin A
    &[0x21, 0x09, 0x00, 0x05, 0xE8, 0x03], // PWM 1000 Hz, actuator 1
    &[0x22, 0x09, 0x01, 0x06, 0xDC, 0x05], // pulse width 1500 µs, actuator 1 pin B
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Any bytes, written alone or read after: no panic, and a reply always fits.
    #[test]
    fn any_bytes_get_a_bounded_reply_or_none(
        writes in proptest::collection::vec(
            (proptest::collection::vec(any::<u8>(), 0..40), any::<bool>(), any::<bool>()),
            0..24,
        ),
        pec_on in any::<bool>(),
    ) {
        let db = if pec_on { board_with_pec() } else { board() };
        for (bytes, read_after, read) in &writes {
            db.handle_write(bytes, *read_after);
            if *read {
                let mut rx = [0u8; 40];
                let n = db.take_reply(&mut rx);
                prop_assert!((3..=rx.len()).contains(&n), "reply of {} bytes", n);
            }
        }
    }

    /// With PEC on, an output request with one to three bits flipped (anywhere, its PEC
    /// included) reaches no port and is counted; the same request unflipped does.
    #[test]
    fn a_flipped_output_request_never_moves_a_port(
        which in 0..OUTPUTS.len(),
        bits in proptest::collection::btree_set(0usize..64, 1..4),
        read_after in any::<bool>(),
    ) {
        let db = board_with_pec();
        let _ = db.ports().take_log();
        let sent = with_pec(OUTPUTS[which]);
        let n = sent.len() * 8;
        let mut f = sent.clone();
        let bits: std::collections::BTreeSet<usize> = bits.into_iter().map(|b| b % n).collect();
        for b in &bits {
            f[b / 8] ^= 1 << (b % 8);
        }
        prop_assume!(f != sent);
        let errors = db.diagnostics().pec_errors;
        db.handle_write(&f, read_after);
        prop_assert!(db.ports().take_log().is_empty(), "flipped bits {:?} moved a port", bits);
        prop_assert_eq!(db.diagnostics().pec_errors, errors + 1);
        db.handle_write(&sent, read_after);
        prop_assert_eq!(db.ports().take_log().len(), 1);
    }
}
