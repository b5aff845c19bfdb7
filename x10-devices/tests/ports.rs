//! `Sensor` and `Actuator` against the recording double: exact frames, replies, errors.

use embassy_futures::block_on;
use x10_devices::testing::RecordingLink;
use x10_devices::{
    Actuator, Duty, Edge, Error, EventConfig, EventKind, Level, LinkError, Pin, PinEvent, Quantity,
    RangeError, Sensor, Status, SELF,
};
use x10_microcode::test_support::db9;

#[test]
fn port_numbers_count_from_one() {
    let link = RecordingLink::<4>::new();
    assert_eq!(Sensor::new(&link, SELF, 0).err(), Some(Error::BadPort(0)));
    assert_eq!(Sensor::new(&link, SELF, 65).err(), Some(Error::BadPort(65)));
    assert_eq!(Actuator::new(&link, SELF, 0).err(), Some(Error::BadPort(0)));
    let s = Sensor::new(&link, SELF, 64).unwrap();
    assert_eq!(s.port().number(), 64);
    assert_eq!(s.port().index(), 63);
    let a = Actuator::new(&link, db9(), 1).unwrap();
    assert_eq!(a.db(), db9());
    // A port of the wrong kind is refused.
    assert_eq!(
        Sensor::at(&link, SELF, a.port()).err(),
        Some(Error::WrongPortKind)
    );
    assert_eq!(
        Actuator::at(&link, SELF, s.port()).err(),
        Some(Error::WrongPortKind)
    );
    assert!(Sensor::at(&link, SELF, s.port()).is_ok());
    assert_eq!(link.calls(), 0);
    link.finish();
}

#[test]
fn sensor_reads_and_writes() {
    let link = RecordingLink::<16>::new();
    let s = Sensor::new(&link, db9(), 2).unwrap();
    link.reply(&[0xbc, 0x02]) // 700
        .reply(&[1])
        .reply(&[0])
        .ack()
        .ack()
        .reply(&1234u32.to_le_bytes())
        .reply(&58u32.to_le_bytes())
        .ack()
        .ack();
    block_on(async {
        assert_eq!(s.read_analog().await, Ok(700));
        assert_eq!(s.read_digital(Pin::B).await, Ok(Level::High));
        assert_eq!(s.read_digital(Pin::A).await, Ok(Level::Low));
        assert_eq!(s.write_digital(Pin::A, Level::High).await, Ok(()));
        assert_eq!(s.write_digital(Pin::B, Level::Low).await, Ok(()));
        assert_eq!(s.pulse_in(Pin::B, Edge::Rising, Some(30)).await, Ok(1234));
        assert_eq!(s.pulse_in(Pin::A, Edge::Falling, None).await, Ok(58));
        let both = EventConfig {
            rising: true,
            falling: true,
            ..EventConfig::OFF
        };
        assert_eq!(s.enable_events(Pin::B, both).await, Ok(()));
        assert_eq!(s.enable_events(Pin::B, EventConfig::OFF).await, Ok(()));
    });
    link.assert_sent(&[
        &[0x30, 0x09, 0x82, 0x00],
        &[0x10, 0x09, 0x83, 0x01],
        &[0x10, 0x09, 0x82, 0x02],
        &[0x12, 0x09, 0x82, 0x03],
        &[0x11, 0x09, 0x83, 0x04],
        &[0x13, 0x09, 0x83, 0x05, 30, 0],
        &[0x14, 0x09, 0x82, 0x06],
        &[0x04, 0x09, 0x83, 0x07, 0x03, 0, 0, 0, 0],
        &[0x04, 0x09, 0x83, 0x08, 0x00, 0, 0, 0, 0],
    ]);
    link.finish();
}

#[test]
fn sensor_events_come_from_the_link() {
    let link = RecordingLink::<4>::new();
    let s = Sensor::new(&link, SELF, 2).unwrap();
    let ev = PinEvent {
        source: SELF,
        kind: EventKind::PinChange,
        pin: s.pin(Pin::B),
        value: heapless::Vec::from_slice(&[1]).unwrap(),
    };
    link.event(ev.clone())
        .event_error(SELF, s.pin(Pin::B), LinkError::Timeout);
    assert_eq!(block_on(s.wait_event(Pin::B)), Ok(ev));
    assert_eq!(
        block_on(s.wait_event(Pin::B)),
        Err(Error::Link(LinkError::Timeout))
    );
    link.assert_sent(&[]);
    link.finish();
}

#[test]
fn actuator_outputs() {
    let link = RecordingLink::<16>::new();
    let a = Actuator::new(&link, db9(), 3).unwrap();
    link.acks(7).reply(&[1]);
    block_on(async {
        assert_eq!(a.set_digital(Level::Low, Level::High).await, Ok(()));
        assert_eq!(a.write_digital(Pin::A, Level::High).await, Ok(()));
        assert_eq!(a.pwm(Pin::A, Duty(200)).await, Ok(()));
        assert_eq!(a.pwm(Pin::B, Duty::OFF).await, Ok(()));
        assert_eq!(a.pwm_frequency(50).await, Ok(()));
        assert_eq!(a.pulse_width(Pin::B, 1500).await, Ok(()));
        assert_eq!(a.read_digital(Pin::B).await, Ok(Level::High));
    });
    link.assert_sent(&[
        &[0x11, 0x09, 0x04, 0x00],
        &[0x12, 0x09, 0x05, 0x01],
        &[0x12, 0x09, 0x04, 0x02],
        &[0x20, 0x09, 0x04, 0x03, 200],
        &[0x20, 0x09, 0x05, 0x04, 0],
        &[0x21, 0x09, 0x04, 0x05, 50, 0],
        &[0x22, 0x09, 0x05, 0x06, 0xdc, 0x05],
        &[0x10, 0x09, 0x05, 0x07],
    ]);
    link.finish();
}

#[test]
fn zero_hertz_is_refused_before_sending() {
    let link = RecordingLink::<4>::new();
    let a = Actuator::new(&link, SELF, 1).unwrap();
    assert_eq!(
        block_on(a.pwm_frequency(0)),
        Err(Error::Range(RangeError {
            quantity: Quantity::PwmFrequency,
            value: 0,
            min: 1,
            max: 65535
        }))
    );
    assert_eq!(link.calls(), 0);
    link.finish();
}

#[test]
fn link_errors_pass_through() {
    let link = RecordingLink::<8>::new();
    let s = Sensor::new(&link, db9(), 1).unwrap();
    link.fail(LinkError::Nack)
        .fail(LinkError::Timeout)
        .fail(LinkError::Status(Status::PortOutOfRange))
        .fail(LinkError::Status(Status::Timeout));
    block_on(async {
        assert_eq!(s.read_analog().await, Err(Error::Link(LinkError::Nack)));
        assert_eq!(
            s.read_digital(Pin::A).await,
            Err(Error::Link(LinkError::Timeout))
        );
        assert_eq!(
            s.write_digital(Pin::A, Level::Low).await,
            Err(Error::Link(LinkError::Status(Status::PortOutOfRange)))
        );
        assert_eq!(
            s.pulse_in(Pin::B, Edge::Rising, None).await,
            Err(Error::Link(LinkError::Status(Status::Timeout)))
        );
    });
    // Failed requests were still sent.
    link.assert_sent(&[
        &[0x30, 0x09, 0x80, 0x00],
        &[0x10, 0x09, 0x80, 0x01],
        &[0x11, 0x09, 0x80, 0x02],
        &[0x13, 0x09, 0x81, 0x03],
    ]);
    link.finish();
}

#[test]
fn malformed_payloads_are_bad_replies() {
    let link = RecordingLink::<8>::new();
    let s = Sensor::new(&link, SELF, 1).unwrap();
    link.reply(&[1]) // analog needs 2 bytes
        .reply(&[1, 2, 3])
        .reply(&[2]) // a level is 0 or 1
        .reply(&[])
        .reply(&[1, 2]); // pulse width needs 4 bytes
    block_on(async {
        let bad = Err(Error::Link(LinkError::BadReply));
        assert_eq!(s.read_analog().await, bad);
        assert_eq!(s.read_analog().await, bad);
        assert_eq!(s.read_digital(Pin::A).await.map(|_| 0u16), bad);
        assert_eq!(s.read_digital(Pin::A).await.map(|_| 0u16), bad);
        assert_eq!(
            s.pulse_in(Pin::A, Edge::Rising, None).await.map(|_| 0u16),
            bad
        );
    });
    assert_eq!(link.take_sent().len(), 5);
    link.finish();
}

#[test]
fn errors_convert_for_robot_programs() {
    use x10_microcode::Error as Wire;
    assert_eq!(
        LinkError::from(Error::Link(LinkError::Nack)),
        LinkError::Nack
    );
    assert_eq!(
        LinkError::from(Error::BadPort(0)),
        LinkError::Invalid(Wire::BadPort(0))
    );
    assert_eq!(
        LinkError::from(Error::WrongPortKind),
        LinkError::Invalid(Wire::WrongPortKind)
    );
    let range = RangeError {
        quantity: Quantity::Speed,
        value: 101,
        min: -100,
        max: 100,
    };
    assert_eq!(
        LinkError::from(Error::Range(range)),
        LinkError::Invalid(Wire::BadArgument)
    );
    let reading = Error::ReadingOutOfRange {
        raw: 0,
        min: 1,
        max: 1022,
    };
    assert_eq!(LinkError::from(reading), LinkError::BadReply);
}
