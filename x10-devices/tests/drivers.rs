//! Every device driver against the recording double: exact frames, replies, error paths.

use embassy_futures::block_on;
use embedded_hal_async::delay::DelayNs;
use x10_devices::testing::RecordingLink;
use x10_devices::{
    Address, AnalogSensor, Button, ButtonState, Calibration, Celsius, DcMotor, Degrees, Divider,
    Duty, Error, EventKind, HBridge, LinkError, Millimetres, Pin, PinEvent, Quantity, Ramp,
    RangeError, Refresh, Servo, ServoConfig, Speed, Status, SteinhartHart, Thermistor,
    ThermistorConfig, Ultrasonic, UltrasonicConfig, SELF,
};

fn db(n: u8) -> Address {
    Address::new(n).unwrap()
}

// ---------------------------------------------------------------- H-bridge

#[test]
fn hbridge_states() {
    let link = RecordingLink::<16>::new();
    let h = HBridge::new(&link, db(9), 1).unwrap();
    link.acks(12);
    block_on(async {
        h.forward(Duty(200)).await.unwrap();
        h.reverse(Duty(100)).await.unwrap();
        h.brake().await.unwrap();
        h.coast().await.unwrap();
    });
    link.assert_sent(&[
        // forward: B LOW, PWM A 200, A HIGH
        &[0x11, 0x09, 0x01, 0x00],
        &[0x20, 0x09, 0x00, 0x01, 200],
        &[0x12, 0x09, 0x00, 0x02],
        // reverse: A LOW, PWM A 100, B HIGH
        &[0x11, 0x09, 0x00, 0x03],
        &[0x20, 0x09, 0x00, 0x04, 100],
        &[0x12, 0x09, 0x01, 0x05],
        // brake: A HIGH, B HIGH, PWM A 255
        &[0x12, 0x09, 0x00, 0x06],
        &[0x12, 0x09, 0x01, 0x07],
        &[0x20, 0x09, 0x00, 0x08, 255],
        // coast (stopped): PWM A 0, A LOW, B LOW
        &[0x20, 0x09, 0x00, 0x09, 0],
        &[0x11, 0x09, 0x00, 0x0a],
        &[0x11, 0x09, 0x01, 0x0b],
    ]);
    link.finish();
}

#[test]
fn hbridge_stop_is_coast_and_drive_picks_direction() {
    let link = RecordingLink::<16>::new();
    let h = HBridge::new(&link, SELF, 2).unwrap();
    link.acks(9);
    block_on(async {
        h.stop().await.unwrap();
        h.drive(x10_devices::Direction::Forward, Duty::FULL)
            .await
            .unwrap();
        h.drive(x10_devices::Direction::Reverse, Duty(1))
            .await
            .unwrap();
    });
    link.assert_sent(&[
        &[0x20, 0x00, 0x02, 0x00, 0],
        &[0x11, 0x00, 0x02, 0x01],
        &[0x11, 0x00, 0x03, 0x02],
        &[0x11, 0x00, 0x03, 0x03],
        &[0x20, 0x00, 0x02, 0x04, 255],
        &[0x12, 0x00, 0x02, 0x05],
        &[0x11, 0x00, 0x02, 0x06],
        &[0x20, 0x00, 0x02, 0x07, 1],
        &[0x12, 0x00, 0x03, 0x08],
    ]);
    link.finish();
}

#[test]
fn hbridge_stops_sending_at_the_first_failure() {
    let link = RecordingLink::<8>::new();
    let h = HBridge::new(&link, db(9), 1).unwrap();
    link.ack().fail(LinkError::Nack);
    assert_eq!(
        block_on(h.forward(Duty(10))),
        Err(Error::Link(LinkError::Nack))
    );
    // B LOW, then the duty (NACKed): A is never raised.
    link.assert_sent(&[&[0x11, 0x09, 0x01, 0x00], &[0x20, 0x09, 0x00, 0x01, 10]]);
    link.finish();
}

/// Issue 10: a reversal must never drive the new direction at the old duty. Forward at 200,
/// then reverse at 100: A goes LOW (coast), the duty becomes 100, and only then B goes HIGH.
/// (The duty used to come last: B HIGH drove reverse at 200 until the third frame.)
#[test]
fn hbridge_reversal_never_drives_the_new_direction_at_the_old_duty() {
    let link = RecordingLink::<8>::new();
    let h = HBridge::new(&link, db(9), 1).unwrap();
    link.acks(6);
    block_on(async {
        h.forward(Duty(200)).await.unwrap();
        h.reverse(Duty(100)).await.unwrap();
    });
    let frames = link.take_sent();
    // The bridge's state after each frame: (A, B, duty).
    let (mut a, mut b, mut duty) = (false, false, 0u8);
    let mut states = Vec::new();
    for f in &frames {
        match (f[0], f[2]) {
            (0x11, 0x00) => a = false,
            (0x12, 0x00) => a = true,
            (0x11, 0x01) => b = false,
            (0x12, 0x01) => b = true,
            (0x20, _) => duty = f[4],
            other => panic!("unexpected frame {other:?}"),
        }
        states.push((a, b, duty));
    }
    // Reverse (A LOW, B HIGH) is only ever driven at 100.
    assert!(
        states.iter().all(|&(a, b, d)| a || !b || d == 100),
        "{states:?}"
    );
    assert_eq!(states.last(), Some(&(false, true, 100)));
    link.finish();
}

// ---------------------------------------------------------------- DC motor

#[test]
fn motor_speed_forward_reverse_stop() {
    let link = RecordingLink::<16>::new();
    let mut m = DcMotor::new(&link, db(9), 1).unwrap();
    assert_eq!(m.speed(), None);
    link.acks(9);
    block_on(async {
        m.set_speed(Speed::FULL_FORWARD).await.unwrap();
        assert_eq!(m.speed(), Some(Speed::FULL_FORWARD));
        m.set_percent(-50).await.unwrap();
        assert_eq!(m.speed(), Some(Speed::new(-50).unwrap()));
        m.stop().await.unwrap();
        assert_eq!(m.speed(), Some(Speed::STOP));
    });
    link.assert_sent(&[
        &[0x11, 0x09, 0x01, 0x00],
        &[0x20, 0x09, 0x00, 0x01, 255],
        // really reverse: the direction pins swap (the thesis's run() could not)
        &[0x12, 0x09, 0x00, 0x02],
        &[0x11, 0x09, 0x00, 0x03],
        &[0x20, 0x09, 0x00, 0x04, 127],
        &[0x12, 0x09, 0x01, 0x05],
        &[0x20, 0x09, 0x00, 0x06, 0],
        &[0x11, 0x09, 0x00, 0x07],
        &[0x11, 0x09, 0x01, 0x08],
    ]);
    link.finish();
}

#[test]
fn motor_out_of_range_speed_sends_nothing() {
    let link = RecordingLink::<4>::new();
    let mut m = DcMotor::new(&link, SELF, 1).unwrap();
    for bad in [101i8, -101, 127, -128] {
        assert_eq!(
            block_on(m.set_percent(bad)),
            Err(Error::Range(RangeError {
                quantity: Quantity::Speed,
                value: bad as i32,
                min: -100,
                max: 100
            }))
        );
    }
    assert_eq!(link.calls(), 0);
    assert_eq!(DcMotor::new(&link, SELF, 0).err(), Some(Error::BadPort(0)));
    link.finish();
}

#[test]
fn motor_failure_leaves_speed_unknown_and_brake_is_not_a_speed() {
    let link = RecordingLink::<16>::new();
    let mut m = DcMotor::new(&link, SELF, 1).unwrap();
    link.acks(3)
        .ack()
        .ack()
        .fail(LinkError::Status(Status::Busy))
        .acks(3);
    block_on(async {
        m.set_speed(Speed::FULL_FORWARD).await.unwrap();
        assert_eq!(
            m.set_speed(Speed::FULL_REVERSE).await,
            Err(Error::Link(LinkError::Status(Status::Busy)))
        );
        assert_eq!(m.speed(), None);
        m.brake().await.unwrap();
        assert_eq!(m.speed(), None);
    });
    link.assert_sent(&[
        &[0x11, 0x00, 0x01, 0x00],
        &[0x20, 0x00, 0x00, 0x01, 255],
        &[0x12, 0x00, 0x00, 0x02],
        &[0x11, 0x00, 0x00, 0x03],
        &[0x20, 0x00, 0x00, 0x04, 255],
        &[0x12, 0x00, 0x01, 0x05],
        &[0x12, 0x00, 0x00, 0x06],
        &[0x12, 0x00, 0x01, 0x07],
        &[0x20, 0x00, 0x00, 0x08, 255],
    ]);
    link.finish();
}

/// A delay that logs (frames sent so far, ns asked) and returns at once.
struct LogDelay<'a> {
    link: &'a RecordingLink<32>,
    log: Vec<(usize, u32)>,
}

impl DelayNs for LogDelay<'_> {
    async fn delay_ns(&mut self, ns: u32) {
        self.log.push((self.link.sent().len(), ns));
    }
}

#[test]
fn motor_ramp_steps_through_zero() {
    let link = RecordingLink::<32>::new();
    let mut m = DcMotor::new(&link, db(9), 1).unwrap();
    let mut delay = LogDelay {
        link: &link,
        log: Vec::new(),
    };
    let ramp = Ramp::new(40, 20).unwrap();
    link.acks(3 * 3);
    // From unknown (taken as 0) to 100: 40, 80, 100.
    block_on(m.ramp_to(Speed::FULL_FORWARD, ramp, &mut delay)).unwrap();
    link.assert_sent(&[
        &[0x11, 0x09, 0x01, 0x00],
        &[0x20, 0x09, 0x00, 0x01, 102],
        &[0x12, 0x09, 0x00, 0x02],
        &[0x11, 0x09, 0x01, 0x03],
        &[0x20, 0x09, 0x00, 0x04, 204],
        &[0x12, 0x09, 0x00, 0x05],
        &[0x11, 0x09, 0x01, 0x06],
        &[0x20, 0x09, 0x00, 0x07, 255],
        &[0x12, 0x09, 0x00, 0x08],
    ]);
    // 20 ms between steps, none after the last.
    assert_eq!(delay.log, vec![(3, 20_000_000), (6, 20_000_000)]);
    delay.log.clear();
    // From 100 to -50 in steps of 40: 60, 20, 0 (stop on the way), -40, -50.
    link.acks(5 * 3);
    block_on(m.ramp_to(Speed::new(-50).unwrap(), ramp, &mut delay)).unwrap();
    let frames = link.take_sent();
    let duties: Vec<(u8, u8)> = frames
        .chunks(3)
        // (last pin written: 0x12 HIGH / 0x11 LOW, duty); a stop writes its duty first
        .map(|c| match c[0][0] {
            0x20 => (c[2][0], c[0][4]),
            _ => (c[2][0], c[1][4]),
        })
        .collect();
    assert_eq!(
        duties,
        vec![(0x12, 153), (0x12, 51), (0x11, 0), (0x12, 102), (0x12, 127)]
    );
    // The reverse steps raise pin B (port byte 0x01).
    assert_eq!(frames[11][2], 0x01);
    assert_eq!(delay.log.len(), 4);
    // Already there: nothing sent, no delay.
    block_on(m.ramp_to(Speed::new(-50).unwrap(), ramp, &mut delay)).unwrap();
    assert_eq!(delay.log.len(), 4);
    assert_eq!(m.speed(), Some(Speed::new(-50).unwrap()));
    link.finish();
}

#[test]
fn motor_ramp_stops_at_a_failure() {
    let link = RecordingLink::<32>::new();
    let mut m = DcMotor::new(&link, SELF, 1).unwrap();
    let mut delay = LogDelay {
        link: &link,
        log: Vec::new(),
    };
    link.acks(3).fail(LinkError::Timeout);
    assert_eq!(
        block_on(m.ramp_to(Speed::FULL_FORWARD, Ramp::new(50, 5).unwrap(), &mut delay)),
        Err(Error::Link(LinkError::Timeout))
    );
    assert_eq!(link.take_sent().len(), 4);
    assert_eq!(delay.log, vec![(3, 5_000_000)]);
    assert_eq!(m.speed(), None);
    link.finish();
}

#[test]
fn motor_invalidate_forgets_the_speed_so_it_is_sent_again() {
    let link = RecordingLink::<32>::new();
    let mut m = DcMotor::new(&link, db(9), 1).unwrap();
    let ramp = Ramp::new(100, 0).unwrap();
    let mut delay = LogDelay {
        link: &link,
        log: Vec::new(),
    };
    link.acks(3);
    block_on(m.set_speed(Speed::new(-50).unwrap())).unwrap();
    link.assert_sent(&[
        &[0x11, 0x09, 0x00, 0x00],
        &[0x20, 0x09, 0x00, 0x01, 127],
        &[0x12, 0x09, 0x01, 0x02],
    ]);
    // Known: a ramp to the same speed sends nothing.
    block_on(m.ramp_to(Speed::new(-50).unwrap(), ramp, &mut delay)).unwrap();
    link.assert_sent(&[]);
    // Forgotten (the board may have reset): nothing is sent by invalidate itself...
    m.invalidate();
    assert_eq!(m.speed(), None);
    link.assert_sent(&[]);
    // ...and the same ramp now drives the bridge again, from 0 in one step of 100 %.
    link.acks(3);
    block_on(m.ramp_to(Speed::new(-50).unwrap(), ramp, &mut delay)).unwrap();
    link.assert_sent(&[
        &[0x11, 0x09, 0x00, 0x03],
        &[0x20, 0x09, 0x00, 0x04, 127],
        &[0x12, 0x09, 0x01, 0x05],
    ]);
    assert_eq!(m.speed(), Some(Speed::new(-50).unwrap()));
    assert!(delay.log.is_empty());
    link.finish();
}

#[test]
fn refresh_is_due_every_n_steps_until_restarted() {
    assert_eq!(
        Refresh::every(0),
        Err(RangeError {
            quantity: Quantity::RefreshSteps,
            value: 0,
            min: 1,
            max: 65_535
        })
    );
    let mut every_step = Refresh::every(1).unwrap();
    assert_eq!(every_step.steps(), 1);
    assert!(every_step.tick());
    every_step.restart();
    assert!(every_step.tick());

    let mut r = Refresh::every(4).unwrap();
    let due: Vec<bool> = (0..6).map(|_| r.tick()).collect();
    assert_eq!(due, [false, false, false, true, true, true]);
    r.restart();
    let due: Vec<bool> = (0..4).map(|_| r.tick()).collect();
    assert_eq!(due, [false, false, false, true]);

    // The count saturates: never wraps back to "not due".
    let mut longest = Refresh::every(u16::MAX).unwrap();
    assert_eq!((1..u16::MAX).filter(|_| longest.tick()).count(), 0);
    assert!(longest.tick());
    assert!(longest.tick());
    assert!(longest.tick());
}

#[test]
fn ramp_step_must_be_1_to_100() {
    assert_eq!(
        Ramp::new(0, 10),
        Err(RangeError {
            quantity: Quantity::RampStep,
            value: 0,
            min: 1,
            max: 100
        })
    );
    assert!(Ramp::new(101, 10).is_err());
    let r = Ramp::new(100, 7).unwrap();
    assert_eq!((r.step().get(), r.interval_ms()), (100, 7));
}

// ---------------------------------------------------------------- thermistor

#[test]
fn thermistor_reads_celsius_and_fahrenheit() {
    let link = RecordingLink::<8>::new();
    let t = Thermistor::new(&link, db(17), 1).unwrap();
    // 512 → 10 kΩ → 24.999668 °C; 700 → 110.333638 °F (python3, see tests/math.rs).
    link.reply(&512u16.to_le_bytes())
        .reply(&700u16.to_le_bytes())
        .reply(&[0x00, 0x02]);
    block_on(async {
        let c = t.celsius().await.unwrap();
        assert!((f64::from(c.0) - 24.999668).abs() < 0.005, "{c:?}");
        let f = t.fahrenheit().await.unwrap();
        assert!((f64::from(f.0) - 110.333638).abs() < 0.01, "{f:?}");
        assert_eq!(t.read_raw().await, Ok(512));
    });
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x00],
        &[0x30, 0x11, 0x80, 0x01],
        &[0x30, 0x11, 0x80, 0x02],
    ]);
    link.finish();
}

#[test]
fn thermistor_rail_readings_and_link_errors() {
    let link = RecordingLink::<8>::new();
    let t = Thermistor::new(&link, db(108), 6).unwrap();
    link.reply(&[0, 0])
        .reply(&1023u16.to_le_bytes())
        .reply(&4095u16.to_le_bytes())
        .fail(LinkError::Nack)
        .reply(&[1]);
    block_on(async {
        assert_eq!(
            t.celsius().await,
            Err(Error::ReadingOutOfRange {
                raw: 0,
                min: 1,
                max: 1022
            })
        );
        assert_eq!(
            t.fahrenheit().await,
            Err(Error::ReadingOutOfRange {
                raw: 1023,
                min: 1,
                max: 1022
            })
        );
        assert_eq!(
            t.kelvin().await,
            Err(Error::ReadingOutOfRange {
                raw: 4095,
                min: 1,
                max: 1022
            })
        );
        assert_eq!(t.celsius().await, Err(Error::Link(LinkError::Nack)));
        assert_eq!(t.celsius().await, Err(Error::Link(LinkError::BadReply)));
    });
    // DB 108 = 0x6c, sensor port 6 = 0x80 | 5 << 1 = 0x8a.
    link.assert_sent(&[
        &[0x30, 0x6c, 0x8a, 0x00],
        &[0x30, 0x6c, 0x8a, 0x01],
        &[0x30, 0x6c, 0x8a, 0x02],
        &[0x30, 0x6c, 0x8a, 0x03],
        &[0x30, 0x6c, 0x8a, 0x04],
    ]);
    assert_eq!(
        Thermistor::new(&link, SELF, 0).err(),
        Some(Error::BadPort(0))
    );
    link.finish();
}

#[test]
fn thermistor_with_its_own_configuration() {
    let link = RecordingLink::<4>::new();
    let cfg =
        ThermistorConfig::new(SteinhartHart::THESIS, 4_700, 12, Divider::ThermistorHigh).unwrap();
    let t = Thermistor::with_config(&link, SELF, 3, cfg).unwrap();
    assert_eq!(t.config().adc_bits(), 12);
    link.reply(&2048u16.to_le_bytes())
        .reply(&4094u16.to_le_bytes());
    block_on(async {
        let c: Celsius = t.celsius().await.unwrap();
        assert!((f64::from(c.0) - 43.130793).abs() < 0.005, "{c:?}");
        // 4094 is usable at 12 bits.
        assert!(t.celsius().await.is_ok());
    });
    link.assert_sent(&[&[0x30, 0x00, 0x84, 0x00], &[0x30, 0x00, 0x84, 0x01]]);
    link.finish();
}

// ---------------------------------------------------------------- servo

#[test]
fn servo_init_angles_release() {
    let link = RecordingLink::<8>::new();
    let s = Servo::new(&link, db(9), 2, Pin::B).unwrap();
    link.acks(5);
    block_on(async {
        s.init().await.unwrap();
        s.set_angle(Degrees(0)).await.unwrap();
        s.set_angle(Degrees(90)).await.unwrap();
        s.set_pulse_us(2000).await.unwrap();
        s.release().await.unwrap();
    });
    link.assert_sent(&[
        &[0x21, 0x09, 0x02, 0x00, 50, 0],      // 50 Hz on actuator port 2
        &[0x22, 0x09, 0x03, 0x01, 0xe8, 0x03], // 1000 µs on PWM B
        &[0x22, 0x09, 0x03, 0x02, 0xdc, 0x05], // 1500 µs
        &[0x22, 0x09, 0x03, 0x03, 0xd0, 0x07], // 2000 µs
        &[0x22, 0x09, 0x03, 0x04, 0x00, 0x00], // no pulses
    ]);
    link.finish();
}

#[test]
fn servo_ranges() {
    let link = RecordingLink::<4>::new();
    let cfg = ServoConfig::new(500, 2500, 270).unwrap();
    let s = Servo::with_config(&link, SELF, 1, Pin::A, cfg).unwrap();
    link.ack().fail(LinkError::Status(Status::Unsupported));
    block_on(async {
        assert_eq!(
            s.set_angle(Degrees(271)).await,
            Err(Error::Range(RangeError {
                quantity: Quantity::Angle,
                value: 271,
                min: 0,
                max: 270
            }))
        );
        assert_eq!(
            s.set_pulse_us(499).await,
            Err(Error::Range(RangeError {
                quantity: Quantity::PulseWidth,
                value: 499,
                min: 500,
                max: 2500
            }))
        );
        s.set_angle(Degrees(270)).await.unwrap();
        assert_eq!(
            s.init().await,
            Err(Error::Link(LinkError::Status(Status::Unsupported)))
        );
    });
    link.assert_sent(&[
        &[0x22, 0x00, 0x00, 0x00, 0xc4, 0x09],
        &[0x21, 0x00, 0x00, 0x01, 50, 0],
    ]);
    assert!(ServoConfig::new(2000, 1000, 180).is_err());
    assert!(ServoConfig::new(0, 1000, 180).is_err());
    assert!(ServoConfig::new(1000, 20_001, 180).is_err());
    assert!(ServoConfig::new(1000, 2000, 0).is_err());
    assert_eq!(
        Servo::new(&link, SELF, 0, Pin::A).err(),
        Some(Error::BadPort(0))
    );
    link.finish();
}

// ---------------------------------------------------------------- button

fn pin_change(source: Address, pin: x10_devices::PinRef, value: &[u8]) -> PinEvent {
    PinEvent {
        source,
        kind: EventKind::PinChange,
        pin,
        value: heapless::Vec::from_slice(value).unwrap(),
    }
}

#[test]
fn button_polling_is_debounced() {
    let link = RecordingLink::<16>::new();
    let mut b = Button::new(&link, SELF, 2, Pin::B).unwrap();
    assert_eq!(b.state(), ButtonState::Released);
    // HIGH, LOW (bounce), HIGH, HIGH, LOW, LOW
    for v in [1u8, 0, 1, 1, 0, 0] {
        link.reply(&[v]);
    }
    let mut seen = Vec::new();
    block_on(async {
        for _ in 0..6 {
            seen.push(b.is_pressed().await.unwrap());
        }
    });
    assert_eq!(seen, vec![false, false, false, true, true, false]);
    let frames = link.take_sent();
    assert!(frames
        .iter()
        .enumerate()
        .all(|(i, f)| f.as_slice() == [0x10, 0x00, 0x83, i as u8]));
    assert_eq!(frames.len(), 6);
    link.finish();
}

#[test]
fn button_active_low_and_single_sample() {
    let link = RecordingLink::<8>::new();
    let mut b = Button::new(&link, db(9), 1, Pin::A)
        .unwrap()
        .active_low()
        .debounce(1)
        .unwrap();
    link.reply(&[0])
        .reply(&[1])
        .reply(&[0])
        .fail(LinkError::Nack);
    block_on(async {
        assert_eq!(b.is_pressed().await, Ok(true));
        assert_eq!(b.is_pressed().await, Ok(false));
        assert_eq!(b.read_raw().await, Ok(true));
        assert_eq!(b.is_pressed().await, Err(Error::Link(LinkError::Nack)));
    });
    assert_eq!(b.state(), ButtonState::Released);
    assert_eq!(link.take_sent().len(), 4);
    assert!(Button::new(&link, SELF, 1, Pin::A)
        .unwrap()
        .debounce(0)
        .is_err());
    link.finish();
}

#[test]
fn button_events() {
    let link = RecordingLink::<16>::new();
    let mut b = Button::new(&link, SELF, 2, Pin::B).unwrap();
    let pin = b.sensor().pin(Pin::B);
    link.ack();
    block_on(b.enable_events()).unwrap();
    link.assert_sent(&[&[0x04, 0x00, 0x83, 0x00, 0x03, 0, 0, 0, 0]]);

    // A bounce: event HIGH, confirming read LOW -> no change; then an analog event (ignored);
    // then event HIGH, read HIGH -> pressed.
    let analog = PinEvent {
        kind: EventKind::AnalogThreshold,
        ..pin_change(SELF, pin, &[0, 0, 1])
    };
    link.event(pin_change(SELF, pin, &[1]))
        .event(analog)
        .event(pin_change(SELF, pin, &[1]));
    link.reply(&[0]).reply(&[1]);
    assert_eq!(block_on(b.wait_change()), Ok(ButtonState::Pressed));
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x01], &[0x10, 0x00, 0x83, 0x02]]);

    // Release.
    link.event(pin_change(SELF, pin, &[0])).reply(&[0]);
    assert_eq!(block_on(b.wait_change()), Ok(ButtonState::Released));
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x03]]);

    // Malformed event, link error, and off.
    link.event(pin_change(SELF, pin, &[7]));
    assert_eq!(
        block_on(b.wait_change()),
        Err(Error::Link(LinkError::BadReply))
    );
    link.event_error(SELF, pin, LinkError::Unsupported);
    assert_eq!(
        block_on(b.wait_change()),
        Err(Error::Link(LinkError::Unsupported))
    );
    link.ack();
    block_on(b.disable_events()).unwrap();
    link.assert_sent(&[&[0x04, 0x00, 0x83, 0x04, 0x00, 0, 0, 0, 0]]);
    link.finish();
}

// ---------------------------------------------------------------- analog sensor

#[test]
fn analog_sensor_raw_and_calibrated() {
    let link = RecordingLink::<8>::new();
    let light = AnalogSensor::new(&link, db(9), 1).unwrap();
    let force = AnalogSensor::with_calibration(
        &link,
        SELF,
        1,
        Calibration::two_point((100, 0.0), (900, 20.0)).unwrap(),
    )
    .unwrap();
    link.reply(&701u16.to_le_bytes())
        .reply(&701u16.to_le_bytes())
        .reply(&500u16.to_le_bytes())
        .fail(LinkError::ArbitrationLost);
    block_on(async {
        assert_eq!(light.read_raw().await, Ok(701));
        assert_eq!(light.read().await, Ok(701.0));
        assert_eq!(force.read().await, Ok(10.0));
        assert_eq!(
            force.read_raw().await,
            Err(Error::Link(LinkError::ArbitrationLost))
        );
    });
    link.assert_sent(&[
        &[0x30, 0x09, 0x80, 0x00],
        &[0x30, 0x09, 0x80, 0x01],
        &[0x30, 0x00, 0x80, 0x02],
        &[0x30, 0x00, 0x80, 0x03],
    ]);
    assert_eq!(
        AnalogSensor::new(&link, SELF, 0).err(),
        Some(Error::BadPort(0))
    );
    link.finish();
}

// ---------------------------------------------------------------- ultrasonic

#[test]
fn ultrasonic_hc_sr04() {
    let link = RecordingLink::<16>::new();
    let u = Ultrasonic::new(&link, db(9), 4).unwrap();
    link.acks(2).reply(&1000u32.to_le_bytes());
    link.acks(2).fail(LinkError::Status(Status::Timeout));
    link.acks(2).reply(&30_000u32.to_le_bytes());
    link.acks(2).fail(LinkError::Timeout);
    block_on(async {
        assert_eq!(u.distance().await, Ok(Some(Millimetres(171))));
        assert_eq!(u.distance().await, Ok(None)); // no echo before the timeout
        assert_eq!(u.distance().await, Ok(None)); // 5.1 m: beyond 4 m
        assert_eq!(u.distance().await, Err(Error::Link(LinkError::Timeout)));
    });
    // Sensor port 4 = 0x86: trigger A HIGH, LOW, pulse-in rising on B, timeout 30 ms.
    let one: [&[u8]; 3] = [
        &[0x12, 0x09, 0x86, 0],
        &[0x11, 0x09, 0x86, 0],
        &[0x13, 0x09, 0x87, 0, 30, 0],
    ];
    let frames = link.take_sent();
    assert_eq!(frames.len(), 12);
    for (i, f) in frames.iter().enumerate() {
        let mut want = one[i % 3].to_vec();
        want[3] = i as u8;
        assert_eq!(f.as_slice(), want.as_slice(), "frame {i}");
    }
    link.finish();
}

#[test]
fn ultrasonic_free_running_and_one_pin() {
    let link = RecordingLink::<8>::new();
    let free = UltrasonicConfig::new(None, Pin::A, 50, Millimetres(6000), 340).unwrap();
    let u = Ultrasonic::with_config(&link, SELF, 1, free).unwrap();
    let ping = UltrasonicConfig::new(Some(Pin::B), Pin::B, 20, Millimetres(3000), 343).unwrap();
    let p = Ultrasonic::with_config(&link, SELF, 2, ping).unwrap();
    link.reply(&2000u32.to_le_bytes()).acks(2).reply(&[1, 2, 3]);
    block_on(async {
        assert_eq!(u.echo_us().await, Ok(Some(2000)));
        assert_eq!(p.distance().await, Err(Error::Link(LinkError::BadReply)));
    });
    link.assert_sent(&[
        &[0x13, 0x00, 0x80, 0x00, 50, 0],
        &[0x12, 0x00, 0x83, 0x01],
        &[0x11, 0x00, 0x83, 0x02],
        &[0x13, 0x00, 0x83, 0x03, 20, 0],
    ]);
    assert_eq!(
        UltrasonicConfig::new(None, Pin::A, 50, Millimetres(1), 0),
        Err(RangeError {
            quantity: Quantity::SpeedOfSound,
            value: 0,
            min: 1,
            max: 65535
        })
    );
    assert_eq!(
        UltrasonicConfig::HC_SR04.distance(23_324),
        Some(Millimetres(4000))
    );
    assert_eq!(UltrasonicConfig::HC_SR04.distance(23_330), None);
    link.finish();
}

// ---------------------------------------------------------------- the link is all drivers see

#[test]
fn drivers_share_one_link_and_its_sequence() {
    let link = RecordingLink::<8>::new();
    let t = Thermistor::new(&link, db(17), 1).unwrap();
    let h = HBridge::new(&link, db(10), 3).unwrap();
    link.reply(&512u16.to_le_bytes()).acks(3);
    block_on(async {
        t.celsius().await.unwrap();
        h.stop().await.unwrap();
    });
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x00],
        &[0x20, 0x0a, 0x04, 0x01, 0],
        &[0x11, 0x0a, 0x04, 0x02],
        &[0x11, 0x0a, 0x05, 0x03],
    ]);
    assert_eq!(link.calls(), 4);
    link.finish();
}

/// Leaving a brake (both inputs HIGH, enable 255) for a drive: the motor coasts first, so the
/// new direction is never driven at the brake's full enable.
#[test]
fn motor_leaving_a_brake_coasts_first() {
    let link = RecordingLink::<16>::new();
    let mut m = DcMotor::new(&link, db(9), 1).unwrap();
    link.acks(9);
    block_on(async {
        m.brake().await.unwrap();
        m.set_percent(40).await.unwrap();
    });
    let frames = link.take_sent();
    assert_eq!(frames.len(), 9, "brake, coast, forward");
    let (mut a, mut b, mut duty) = (false, false, 0u8);
    for f in &frames {
        match (f[0], f[2]) {
            (0x11, 0x00) => a = false,
            (0x12, 0x00) => a = true,
            (0x11, 0x01) => b = false,
            (0x12, 0x01) => b = true,
            (0x20, _) => duty = f[4],
            other => panic!("unexpected frame {other:?}"),
        }
        // Driving one way (exactly one input HIGH) only ever at 40 % (duty 102), or not at
        // all (enable 0).
        assert!(
            a == b || duty == 0 || duty == 102,
            "{f:02x?}: A {a} B {b} duty {duty}"
        );
    }
    assert_eq!((a, b, duty), (true, false, 102));
    link.finish();
}
