//! The programs keep their actuators driven: the state is re-sent every `REFRESH_STEPS` steps
//! without a change (a board that reset and fell back to its safe state is driven again), and
//! at the next step after a failed call. Exact microcode against the recording double.

use embassy_futures::block_on;
use x10_devices::testing::RecordingLink;
use x10_devices::{LinkError, Robot, Speed};
use x10_robots::{LightMotor, SingleBoard, TemperatureAlarm, REFRESH_STEPS};

type Link = RecordingLink<256>;

#[test]
fn the_interval_is_25_steps() {
    assert_eq!(REFRESH_STEPS, 25);
}

/// Runs one Figure 4.2 step with the button released and force `force`, expecting success.
fn fig4_2_step(robot: &mut SingleBoard<&Link>, link: &Link, force: u16) {
    link.reply(&[0]).reply(&force.to_le_bytes());
    block_on(robot.step()).unwrap();
}

/// The two reads of a Figure 4.2 step (button SELF S2.B, force SELF S1), sequence `seq`.
fn fig4_2_reads(seq: u8) -> [Vec<u8>; 2] {
    [vec![0x10, 0x00, 0x83, seq], vec![0x30, 0x00, 0x80, seq + 1]]
}

/// `n` steps that change nothing send the reads only; returns the next sequence number.
fn fig4_2_quiet_steps(
    robot: &mut SingleBoard<&Link>,
    link: &Link,
    force: u16,
    n: u16,
    seq: u8,
) -> u8 {
    let mut want = Vec::new();
    let mut seq = seq;
    for _ in 0..n {
        fig4_2_step(robot, link, force);
        want.extend(fig4_2_reads(seq));
        seq += 2;
    }
    let sent: Vec<Vec<u8>> = link.take_sent().iter().map(|f| f.to_vec()).collect();
    assert_eq!(sent, want);
    seq
}

#[test]
fn fig4_2_re_sends_the_stopped_state_every_25_steps() {
    let link = Link::new();
    let mut robot = SingleBoard::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.assert_sent(&[
        &[0x11, 0x00, 0x00, 0x00],
        &[0x11, 0x00, 0x01, 0x01],
        &[0x20, 0x00, 0x00, 0x02, 0x00],
    ]);
    // Steps 1..=24 after the setup's command: reads only.
    let seq = fig4_2_quiet_steps(&mut robot, &link, 50, REFRESH_STEPS - 1, 0x03);
    assert_eq!(seq, 0x33);
    // Step 25: the reads, then the stopped state again (coast: A LOW, B LOW, PWM 0).
    link.reply(&[0]).reply(&50u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x33],
        &[0x30, 0x00, 0x80, 0x34],
        &[0x11, 0x00, 0x00, 0x35],
        &[0x11, 0x00, 0x01, 0x36],
        &[0x20, 0x00, 0x00, 0x37, 0x00],
    ]);
    assert_eq!(robot.motor_speed(), Some(Speed::STOP));
    // The count starts again: 24 quiet steps, then the next refresh.
    let seq = fig4_2_quiet_steps(&mut robot, &link, 50, REFRESH_STEPS - 1, 0x38);
    link.reply(&[0]).reply(&50u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, seq],
        &[0x30, 0x00, 0x80, seq + 1],
        &[0x11, 0x00, 0x00, seq + 2],
        &[0x11, 0x00, 0x01, seq + 3],
        &[0x20, 0x00, 0x00, seq + 4, 0x00],
    ]);
    link.finish();
}

#[test]
fn fig4_2_re_asserts_a_running_motor_25_steps_after_the_last_command() {
    let link = Link::new();
    let mut robot = SingleBoard::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.take_sent();
    // Two quiet steps, then force 500: full speed (a change restarts the count).
    let seq = fig4_2_quiet_steps(&mut robot, &link, 50, 2, 0x03);
    link.reply(&[0]).reply(&500u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x07],
        &[0x30, 0x00, 0x80, 0x08],
        &[0x11, 0x00, 0x01, 0x09],
        &[0x12, 0x00, 0x00, 0x0a],
        &[0x20, 0x00, 0x00, 0x0b, 0xff],
    ]);
    assert_eq!(seq, 0x07);
    // 24 steps still pressing: reads only (step 27 after setup would have been the setup's
    // refresh; the change moved it).
    let seq = fig4_2_quiet_steps(&mut robot, &link, 500, REFRESH_STEPS - 1, 0x0c);
    assert_eq!(seq, 0x3c);
    // The 25th: forward at full speed again, B LOW first, then A HIGH, then the duty.
    link.reply(&[0]).reply(&500u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x3c],
        &[0x30, 0x00, 0x80, 0x3d],
        &[0x11, 0x00, 0x01, 0x3e],
        &[0x12, 0x00, 0x00, 0x3f],
        &[0x20, 0x00, 0x00, 0x40, 0xff],
    ]);
    assert_eq!(robot.motor_speed(), Some(Speed::FULL_FORWARD));
    link.finish();
}

#[test]
fn fig4_2_re_sends_the_motor_command_after_a_failed_read() {
    let link = Link::new();
    let mut robot = SingleBoard::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.take_sent();
    link.reply(&[0]).reply(&500u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    assert_eq!(link.take_sent().len(), 5);
    assert_eq!(robot.motor_speed(), Some(Speed::FULL_FORWARD));

    // The board resets: its button read is not acknowledged. The motor command is forgotten.
    link.fail(LinkError::Nack);
    assert_eq!(block_on(robot.step()), Err(LinkError::Nack));
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x08]]);
    assert_eq!(robot.motor_speed(), None);

    // The board is back (in its safe state, coasting). The wanted speed did not change, yet
    // the next step drives the motor again.
    link.reply(&[0]).reply(&500u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x09],
        &[0x30, 0x00, 0x80, 0x0a],
        &[0x11, 0x00, 0x01, 0x0b],
        &[0x12, 0x00, 0x00, 0x0c],
        &[0x20, 0x00, 0x00, 0x0d, 0xff],
    ]);
    assert_eq!(robot.motor_speed(), Some(Speed::FULL_FORWARD));

    // A failed force read (the button not pressed) forgets it too.
    link.reply(&[0]).fail(LinkError::Timeout);
    assert_eq!(block_on(robot.step()), Err(LinkError::Timeout));
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x0e], &[0x30, 0x00, 0x80, 0x0f]]);
    assert_eq!(robot.motor_speed(), None);
    link.reply(&[0]).reply(&500u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x10],
        &[0x30, 0x00, 0x80, 0x11],
        &[0x11, 0x00, 0x01, 0x12],
        &[0x12, 0x00, 0x00, 0x13],
        &[0x20, 0x00, 0x00, 0x14, 0xff],
    ]);
    // And then only the reads again.
    fig4_2_quiet_steps(&mut robot, &link, 500, 1, 0x15);
    link.finish();
}

#[test]
fn fig4_2_a_failed_refresh_is_sent_again_at_the_next_step() {
    let link = Link::new();
    let mut robot = SingleBoard::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.take_sent();
    fig4_2_quiet_steps(&mut robot, &link, 50, REFRESH_STEPS - 1, 0x03);
    // The refresh's PWM write times out.
    link.reply(&[0])
        .reply(&50u16.to_le_bytes())
        .acks(2)
        .fail(LinkError::Timeout);
    assert_eq!(block_on(robot.step()), Err(LinkError::Timeout));
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x33],
        &[0x30, 0x00, 0x80, 0x34],
        &[0x11, 0x00, 0x00, 0x35],
        &[0x11, 0x00, 0x01, 0x36],
        &[0x20, 0x00, 0x00, 0x37, 0x00],
    ]);
    assert_eq!(robot.motor_speed(), None);
    // Next step: the whole command again.
    link.reply(&[0]).reply(&50u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x38],
        &[0x30, 0x00, 0x80, 0x39],
        &[0x11, 0x00, 0x00, 0x3a],
        &[0x11, 0x00, 0x01, 0x3b],
        &[0x20, 0x00, 0x00, 0x3c, 0x00],
    ]);
    // Then quiet for another 24 steps.
    fig4_2_quiet_steps(&mut robot, &link, 50, REFRESH_STEPS - 1, 0x3d);
    link.finish();
}

// ------------------------------------------------------------------ Figure 4.4's module

#[test]
fn light_motor_refresh_and_re_send_after_a_failed_read() {
    let link = Link::new();
    let mut robot = LightMotor::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.take_sent();
    // Bright: forward at 50 % (duty 127) on DB 9 A1.
    link.reply(&800u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x09, 0x80, 0x03],
        &[0x11, 0x09, 0x01, 0x04],
        &[0x12, 0x09, 0x00, 0x05],
        &[0x20, 0x09, 0x00, 0x06, 0x7f],
    ]);
    // 24 bright steps: the light reading only.
    let mut want = Vec::new();
    for seq in 0x07..0x07 + (REFRESH_STEPS as u8 - 1) {
        link.reply(&800u16.to_le_bytes());
        block_on(robot.step()).unwrap();
        want.push(vec![0x30, 0x09, 0x80, seq]);
    }
    let sent: Vec<Vec<u8>> = link.take_sent().iter().map(|f| f.to_vec()).collect();
    assert_eq!(sent, want);
    // The 25th: the reading and the 50 % command again.
    link.reply(&800u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x09, 0x80, 0x1f],
        &[0x11, 0x09, 0x01, 0x20],
        &[0x12, 0x09, 0x00, 0x21],
        &[0x20, 0x09, 0x00, 0x22, 0x7f],
    ]);
    // DB 9 resets: the reading times out; the command is sent at the next step.
    link.fail(LinkError::Timeout);
    assert_eq!(block_on(robot.step()), Err(LinkError::Timeout));
    assert_eq!(robot.motor_speed(), None);
    link.reply(&800u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x09, 0x80, 0x23],
        &[0x30, 0x09, 0x80, 0x24],
        &[0x11, 0x09, 0x01, 0x25],
        &[0x12, 0x09, 0x00, 0x26],
        &[0x20, 0x09, 0x00, 0x27, 0x7f],
    ]);
    assert_eq!(
        robot.motor_speed(),
        Some(x10_robots::light_motor::RUN_SPEED)
    );
    link.finish();
}

// ------------------------------------------------------------------ Figure 4.6

// Raw thermistor readings (see programs.rs): 100 → −19.16 °C, 256 → 1.67 °C, 1000 → 282.07 °F.
const FREEZING: u16 = 100;
const FREEZER_WARM: u16 = 256;
const OVEN_HOT: u16 = 1000;

#[test]
fn fig4_6_re_asserts_the_alarm_level_every_25_steps() {
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.ack();
    block_on(robot.setup()).unwrap();
    link.assert_sent(&[&[0x11, 0x0a, 0x04, 0x00]]);
    // Quiet (freezer −19 °C, oven 282 °F): 24 steps read both thermistors, nothing else.
    let mut want = Vec::new();
    for i in 0..REFRESH_STEPS as u8 - 1 {
        link.reply(&FREEZING.to_le_bytes())
            .reply(&OVEN_HOT.to_le_bytes());
        block_on(robot.step()).unwrap();
        want.push(vec![0x30, 0x11, 0x80, 1 + 2 * i]);
        want.push(vec![0x30, 0x6c, 0x8a, 2 + 2 * i]);
    }
    let sent: Vec<Vec<u8>> = link.take_sent().iter().map(|f| f.to_vec()).collect();
    assert_eq!(sent, want);
    // The 25th: LOW again (a reset board would be LOW anyway; the write costs one frame).
    link.reply(&FREEZING.to_le_bytes())
        .reply(&OVEN_HOT.to_le_bytes())
        .ack();
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x31],
        &[0x30, 0x6c, 0x8a, 0x32],
        &[0x11, 0x0a, 0x04, 0x33],
    ]);
    // Freezer warm: alarm HIGH.
    link.reply(&FREEZER_WARM.to_le_bytes()).ack();
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x34], &[0x12, 0x0a, 0x04, 0x35]]);
    assert!(robot.alarm_on());
    // Latched, freezer cold again: 24 steps of reads only...
    let mut want = Vec::new();
    for i in 0..REFRESH_STEPS as u8 - 1 {
        link.reply(&FREEZING.to_le_bytes())
            .reply(&OVEN_HOT.to_le_bytes());
        block_on(robot.step()).unwrap();
        want.push(vec![0x30, 0x11, 0x80, 0x36 + 2 * i]);
        want.push(vec![0x30, 0x6c, 0x8a, 0x37 + 2 * i]);
    }
    let sent: Vec<Vec<u8>> = link.take_sent().iter().map(|f| f.to_vec()).collect();
    assert_eq!(sent, want);
    // ...then HIGH again: board 10 may have reset and dropped the alarm to LOW.
    link.reply(&FREEZING.to_le_bytes())
        .reply(&OVEN_HOT.to_le_bytes())
        .ack();
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x66],
        &[0x30, 0x6c, 0x8a, 0x67],
        &[0x12, 0x0a, 0x04, 0x68],
    ]);
    assert!(robot.alarm_on() && robot.alarm_raised());
    link.finish();
}

#[test]
fn fig4_6_a_failed_alarm_write_is_sent_again_and_the_latch_holds() {
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.ack();
    block_on(robot.setup()).unwrap();
    link.take_sent();
    // Freezer warm, but board 10 does not answer the alarm write.
    link.reply(&FREEZER_WARM.to_le_bytes())
        .fail(LinkError::Nack);
    assert_eq!(block_on(robot.step()), Err(LinkError::Nack));
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x01], &[0x12, 0x0a, 0x04, 0x02]]);
    assert!(robot.alarm_raised());
    assert!(!robot.alarm_on());
    // The freezer is cold again, the oven hot: the condition is gone, but the alarm was
    // raised, so the next step writes HIGH.
    link.reply(&FREEZING.to_le_bytes())
        .reply(&OVEN_HOT.to_le_bytes())
        .ack();
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x03],
        &[0x30, 0x6c, 0x8a, 0x04],
        &[0x12, 0x0a, 0x04, 0x05],
    ]);
    assert!(robot.alarm_on());
    // Then nothing more until the refresh.
    link.reply(&FREEZING.to_le_bytes())
        .reply(&OVEN_HOT.to_le_bytes());
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x06], &[0x30, 0x6c, 0x8a, 0x07]]);
    // A thermistor board failing is not the alarm's board: no re-send for it.
    link.fail(LinkError::Timeout);
    assert_eq!(block_on(robot.step()), Err(LinkError::Timeout));
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x08]]);
    assert!(robot.alarm_on());
    link.finish();
}
