//! The recording double itself: it must catch what tests rely on it to catch.

use embassy_futures::block_on;
use x10_devices::testing::{Hex, RecordingLink};
use x10_devices::{Address, Link, LinkError, Pin, Port, SELF};
use x10_microcode::{Level, Op};

fn high(port: u8) -> Op<'static> {
    Op::DigitalWrite(Port::actuator(port).unwrap().pin(Pin::A), Level::High)
}

#[test]
fn sequence_numbers_count_from_zero_and_wrap() {
    let link = RecordingLink::<8>::new();
    link.acks(2);
    block_on(link.call(SELF, high(1))).unwrap();
    block_on(link.call(SELF, high(2))).unwrap();
    link.assert_sent(&[&[0x12, 0x00, 0x00, 0x00], &[0x12, 0x00, 0x02, 0x01]]);
    link.set_next_seq(255).acks(2);
    block_on(link.call(SELF, high(1))).unwrap();
    block_on(link.call(SELF, high(1))).unwrap();
    link.assert_sent(&[&[0x12, 0x00, 0x00, 0xff], &[0x12, 0x00, 0x00, 0x00]]);
    link.finish();
}

#[test]
fn scripted_outcomes_come_back_in_order() {
    let link = RecordingLink::<8>::new();
    link.reply(&[7]).fail(LinkError::Busy).ack();
    let db = Address::new(0x10).unwrap();
    assert_eq!(block_on(link.call(db, high(1))).unwrap().as_slice(), &[7]);
    assert_eq!(block_on(link.call(db, high(1))), Err(LinkError::Busy));
    assert!(block_on(link.call(db, high(1))).unwrap().is_empty());
    assert_eq!(link.take_sent().len(), 3);
    link.finish();
}

#[test]
fn invalid_operations_are_refused_unsent() {
    let link = RecordingLink::<8>::new();
    // PWM on a sensor port does not exist.
    let op = Op::PwmDuty(Port::sensor(1).unwrap().pin(Pin::A), 9);
    assert_eq!(
        block_on(link.call(SELF, op)),
        Err(LinkError::Invalid(x10_microcode::Error::WrongPortKind))
    );
    link.assert_sent(&[]);
    link.finish();
}

#[test]
fn events_are_matched_by_board_and_pin() {
    let link = RecordingLink::<8>::new();
    let a = Port::sensor(1).unwrap().pin(Pin::A);
    let b = Port::sensor(1).unwrap().pin(Pin::B);
    link.event_error(SELF, a, LinkError::Nack)
        .event_error(SELF, b, LinkError::Bus);
    assert_eq!(block_on(link.wait_event(SELF, b)), Err(LinkError::Bus));
    assert_eq!(block_on(link.wait_event(SELF, a)), Err(LinkError::Nack));
    link.finish();
}

#[test]
#[should_panic(expected = "frames differ")]
fn a_wrong_byte_fails() {
    let link = RecordingLink::<8>::new();
    link.ack();
    block_on(link.call(SELF, high(1))).unwrap();
    link.assert_sent(&[&[0x12, 0x00, 0x00, 0x01]]);
}

#[test]
#[should_panic(expected = "frames differ")]
fn a_missing_frame_fails() {
    let link = RecordingLink::<8>::new();
    link.ack();
    block_on(link.call(SELF, high(1))).unwrap();
    link.assert_sent(&[&[0x12, 0x00, 0x00, 0x00], &[0x12, 0x00, 0x00, 0x01]]);
}

#[test]
#[should_panic(expected = "never consumed")]
fn an_unconsumed_reply_fails() {
    let link = RecordingLink::<8>::new();
    link.ack();
    link.finish();
}

#[test]
#[should_panic(expected = "event(s) never consumed")]
fn an_unconsumed_event_fails() {
    let link = RecordingLink::<8>::new();
    link.event_error(SELF, Port::sensor(1).unwrap().pin(Pin::A), LinkError::Nack);
    link.finish();
}

#[test]
#[should_panic(expected = "found no scripted outcome")]
fn an_unscripted_call_fails() {
    let link = RecordingLink::<8>::new();
    assert_eq!(
        block_on(link.call(SELF, high(1))),
        Err(LinkError::Unsupported)
    );
    link.take_sent();
    link.finish();
}

#[test]
#[should_panic(expected = "found no scripted outcome")]
fn an_unscripted_wait_fails() {
    let link = RecordingLink::<8>::new();
    let pin = Port::sensor(1).unwrap().pin(Pin::A);
    assert_eq!(
        block_on(link.wait_event(SELF, pin)),
        Err(LinkError::Unsupported)
    );
    link.finish();
}

#[test]
#[should_panic(expected = "frames never checked")]
fn an_unchecked_frame_fails() {
    let link = RecordingLink::<8>::new();
    link.ack();
    block_on(link.call(SELF, high(1))).unwrap();
    link.finish();
}

#[test]
#[should_panic(expected = "more than 2 frames")]
fn overflow_fails() {
    let link = RecordingLink::<2>::new();
    for _ in 0..2 {
        link.ack();
    }
    block_on(link.call(SELF, high(1))).unwrap();
    block_on(link.call(SELF, high(1))).unwrap();
    let _ = block_on(link.call(SELF, high(1)));
    link.take_sent();
    link.finish();
}

#[test]
fn hex_formats_spaced_lowercase() {
    assert_eq!(format!("{}", Hex(&[0x12, 0x0a, 0xff])), "12 0a ff");
}
