//! `Kept` outputs (`DcMotor`, `DigitalOutput`) against the recording double: when the state is
//! sent, re-sent and forgotten, as exact frames.

use embassy_futures::block_on;
use x10_devices::testing::RecordingLink;
use x10_devices::{
    DcMotor, DigitalOutput, Error, Kept, Level, LinkError, Output, Pin, Refresh, Speed,
};
use x10_microcode::test_support::db9;

type Link = RecordingLink<64>;
type Motor<'a> = Kept<DcMotor<&'a Link>>;

/// A kept motor on DB 9 actuator port 1, re-sent every `steps` steps, nothing sent yet.
fn motor(link: &Link, steps: u16) -> Motor<'_> {
    Kept::new(
        DcMotor::new(link, db9(), 1).unwrap(),
        Refresh::every(steps).unwrap(),
    )
}

/// The same, already set to full speed forward (frames `forward(0x00)`, checked).
fn running(link: &Link, steps: u16) -> Motor<'_> {
    let mut m = motor(link, steps);
    sends(&mut m, link, Speed::FULL_FORWARD, forward(0x00), true);
    m
}

/// The three frames of the stopped state (coast) on DB 9 A1, from sequence `seq`.
fn coast(seq: u8) -> [Vec<u8>; 3] {
    [
        vec![0x20, 0x09, 0x00, seq, 0x00],
        vec![0x11, 0x09, 0x00, seq + 1],
        vec![0x11, 0x09, 0x01, seq + 2],
    ]
}

/// The three frames of full speed forward on DB 9 A1, from sequence `seq`.
fn forward(seq: u8) -> [Vec<u8>; 3] {
    [
        vec![0x11, 0x09, 0x01, seq],
        vec![0x20, 0x09, 0x00, seq + 1, 0xff],
        vec![0x12, 0x09, 0x00, seq + 2],
    ]
}

/// `set` (or `keep`) of `speed`, all acknowledged, sends exactly `frames`.
fn sends(m: &mut Motor<'_>, link: &Link, speed: Speed, frames: [Vec<u8>; 3], set: bool) {
    link.acks(3);
    if set {
        block_on(m.set(speed)).unwrap();
    } else {
        block_on(m.keep(speed)).unwrap();
    }
    let sent: Vec<Vec<u8>> = link.take_sent().iter().map(|f| f.to_vec()).collect();
    assert_eq!(sent, frames);
    assert_eq!(m.state(), Some(speed));
}

/// `n` steps keeping `speed` send nothing.
fn quiet(m: &mut Motor<'_>, link: &Link, speed: Speed, n: usize) {
    for _ in 0..n {
        block_on(m.keep(speed)).unwrap();
    }
    link.assert_sent(&[]);
}

#[test]
fn a_kept_motor_is_re_sent_every_n_steps_and_at_once_on_a_change() {
    let link = Link::new();
    let mut m = motor(&link, 3);
    assert_eq!(m.state(), None);
    sends(&mut m, &link, Speed::STOP, coast(0x00), true);
    // Two steps without a change send nothing; the third re-sends the stopped state.
    quiet(&mut m, &link, Speed::STOP, 2);
    sends(&mut m, &link, Speed::STOP, coast(0x03), false);
    // One quiet step, then a change: sent at once, and the count starts again from it.
    quiet(&mut m, &link, Speed::STOP, 1);
    sends(&mut m, &link, Speed::FULL_FORWARD, forward(0x06), false);
    quiet(&mut m, &link, Speed::FULL_FORWARD, 2);
    sends(&mut m, &link, Speed::FULL_FORWARD, forward(0x09), false);
    assert_eq!(m.output().speed(), Some(Speed::FULL_FORWARD));
    link.finish();
}

#[test]
fn every_step_refresh_sends_on_every_keep() {
    let link = Link::new();
    let mut m = motor(&link, 1);
    sends(&mut m, &link, Speed::STOP, coast(0x00), true);
    sends(&mut m, &link, Speed::STOP, coast(0x03), false);
    sends(&mut m, &link, Speed::STOP, coast(0x06), false);
    link.finish();
}

#[test]
fn the_first_keep_sends_even_if_the_state_matches_the_boards_default() {
    // Nothing is known before the first command, so STOP is not assumed.
    let link = Link::new();
    let mut m = motor(&link, 25);
    sends(&mut m, &link, Speed::STOP, coast(0x00), false);
    quiet(&mut m, &link, Speed::STOP, 24);
    link.finish();
}

#[test]
fn a_failed_command_is_sent_again_at_the_next_keep_and_does_not_restart_the_count() {
    let link = Link::new();
    let mut m = running(&link, 3);
    quiet(&mut m, &link, Speed::FULL_FORWARD, 2);
    // The refresh's PWM write times out: the speed is unknown.
    link.acks(2).fail(LinkError::Timeout);
    assert_eq!(
        block_on(m.keep(Speed::FULL_FORWARD)),
        Err(Error::Link(LinkError::Timeout))
    );
    let [a, b, c] = forward(0x03);
    link.assert_sent(&[&a, &b, &c]);
    assert_eq!(m.state(), None);
    // The next step sends the whole command again, and that success starts the count: two
    // quiet steps, then the refresh.
    sends(&mut m, &link, Speed::FULL_FORWARD, forward(0x06), false);
    quiet(&mut m, &link, Speed::FULL_FORWARD, 2);
    sends(&mut m, &link, Speed::FULL_FORWARD, forward(0x09), false);
    link.finish();
}

#[test]
fn a_failed_set_leaves_the_state_unknown() {
    let link = Link::new();
    let mut m = motor(&link, 25);
    link.fail(LinkError::Nack);
    assert_eq!(
        block_on(m.set(Speed::STOP)),
        Err(Error::Link(LinkError::Nack))
    );
    link.assert_sent(&[&[0x20, 0x09, 0x00, 0x00, 0]]);
    assert_eq!(m.state(), None);
    sends(&mut m, &link, Speed::STOP, coast(0x01), false);
    link.finish();
}

#[test]
fn invalidate_sends_nothing_and_the_next_keep_sends_the_state() {
    let link = Link::new();
    let mut m = running(&link, 25);
    quiet(&mut m, &link, Speed::FULL_FORWARD, 1);
    m.invalidate();
    assert_eq!(m.state(), None);
    link.assert_sent(&[]);
    sends(&mut m, &link, Speed::FULL_FORWARD, forward(0x03), false);
    link.finish();
}

#[test]
fn keep_or_forget_forgets_on_an_error_and_keeps_otherwise() {
    let link = Link::new();
    let mut m = running(&link, 25);
    // Working out the wanted speed failed (a read from the same board): nothing is sent, the
    // error comes back, the speed is forgotten.
    let timeout = Error::Link(LinkError::Timeout);
    assert_eq!(block_on(m.keep_or_forget(Err(timeout))), Err(timeout));
    link.assert_sent(&[]);
    assert_eq!(m.state(), None);
    // The next step re-sends the unchanged speed, the one after sends nothing.
    link.acks(3);
    block_on(m.keep_or_forget(Ok(Speed::FULL_FORWARD))).unwrap();
    let [a, b, c] = forward(0x03);
    link.assert_sent(&[&a, &b, &c]);
    block_on(m.keep_or_forget(Ok(Speed::FULL_FORWARD))).unwrap();
    link.assert_sent(&[]);
    // A failed command through keep_or_forget is returned as it is.
    link.fail(LinkError::Nack);
    assert_eq!(
        block_on(m.keep_or_forget(Ok(Speed::STOP))),
        Err(Error::Link(LinkError::Nack))
    );
    link.assert_sent(&[&[0x20, 0x09, 0x00, 0x06, 0]]);
    assert_eq!(m.state(), None);
    link.finish();
}

#[test]
fn digital_output_writes_its_pin_and_remembers_the_level() {
    let link = Link::new();
    assert_eq!(
        DigitalOutput::new(&link, db9(), 0, Pin::A).map(|_| ()),
        Err(Error::BadPort(0))
    );
    let mut out = DigitalOutput::new(&link, db9(), 3, Pin::B).unwrap();
    assert_eq!((out.pin(), out.state()), (Pin::B, None));
    assert_eq!(out.actuator().db(), db9());
    link.acks(2).fail(LinkError::Nack).ack();
    block_on(out.set(Level::High)).unwrap();
    assert_eq!(out.state(), Some(Level::High));
    block_on(out.set(Level::Low)).unwrap();
    assert_eq!(out.state(), Some(Level::Low));
    let failed = block_on(out.set(Level::High));
    assert_eq!(
        (failed, out.state()),
        (Err(Error::Link(LinkError::Nack)), None)
    );
    block_on(out.set(Level::Low)).unwrap();
    out.invalidate();
    assert_eq!(out.state(), None);
    // IO HIGH / IO LOW on DB 9, actuator port 3 pin B (port byte 0x05).
    link.assert_sent(&[
        &[0x12, 0x09, 0x05, 0x00],
        &[0x11, 0x09, 0x05, 0x01],
        &[0x12, 0x09, 0x05, 0x02],
        &[0x11, 0x09, 0x05, 0x03],
    ]);
    link.finish();
}

#[test]
fn a_kept_digital_output_re_asserts_low_as_well_as_high() {
    let link = Link::new();
    let out = DigitalOutput::new(&link, db9(), 1, Pin::A).unwrap();
    let mut alarm = Kept::new(out, Refresh::every(2).unwrap());
    link.acks(5);
    block_on(alarm.set(Level::Low)).unwrap();
    for (level, what) in [
        (Level::Low, "quiet"),
        (Level::Low, "due: LOW again"),
        (Level::High, "a change"),
        (Level::High, "quiet"),
        (Level::High, "due: HIGH again"),
        (Level::Low, "a change"),
    ] {
        block_on(alarm.keep(level)).unwrap_or_else(|e| panic!("{what}: {e}"));
    }
    link.assert_sent(&[
        &[0x11, 0x09, 0x00, 0x00],
        &[0x11, 0x09, 0x00, 0x01],
        &[0x12, 0x09, 0x00, 0x02],
        &[0x12, 0x09, 0x00, 0x03],
        &[0x11, 0x09, 0x00, 0x04],
    ]);
    assert_eq!(alarm.state(), Some(Level::Low));
    link.finish();
}
