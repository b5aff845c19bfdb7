//! The thesis programs against the recording double: setup and steps, exact microcode.

use embassy_futures::{block_on, join::join};
use x10_devices::testing::{Frame, RecordingLink};
use x10_devices::{Address, LinkError, Robot, Speed, SELF};
use x10_robots::fig4_6::{CONTROL_BOARD, FREEZER, OVEN};
use x10_robots::{
    names, AnyRobot, LightMotor, Program, SingleBoard, TemperatureAlarm, UnknownProgram,
};

type Link = RecordingLink<64>;

const COAST_SELF: [&[u8]; 3] = [
    &[0x11, 0x00, 0x00],
    &[0x11, 0x00, 0x01],
    &[0x20, 0x00, 0x00],
];
const FULL_SELF: [&[u8]; 3] = [
    &[0x11, 0x00, 0x01],
    &[0x12, 0x00, 0x00],
    &[0x20, 0x00, 0x00],
];

/// Frames with the sequence number byte (index 3) left out, for comparing sequences that are
/// numbered differently.
fn unnumbered(frames: &[Frame]) -> Vec<Vec<u8>> {
    frames
        .iter()
        .map(|f| {
            f.iter()
                .enumerate()
                .filter(|(i, _)| *i != 3)
                .map(|(_, b)| *b)
                .collect()
        })
        .collect()
}

fn three(frames: [&[u8]; 3], duty: u8) -> Vec<Vec<u8>> {
    let mut v: Vec<Vec<u8>> = frames.iter().map(|f| f.to_vec()).collect();
    v[2].push(duty);
    v
}

// ------------------------------------------------------------------ Figure 4.2

#[test]
fn fig4_2_button_or_force_drives_the_motor() {
    let link = Link::new();
    let mut robot = SingleBoard::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.assert_sent(&[
        &[0x11, 0x00, 0x00, 0x00],
        &[0x11, 0x00, 0x01, 0x01],
        &[0x20, 0x00, 0x00, 0x02, 0x00],
    ]);
    assert_eq!(robot.motor_speed(), Some(Speed::STOP));

    // Released, force 50: stays stopped, nothing written.
    link.reply(&[0]).reply(&50u16.to_le_bytes());
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x03], &[0x30, 0x00, 0x80, 0x04]]);

    // Force 101 > 100: full speed forward.
    link.reply(&[0]).reply(&101u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x05],
        &[0x30, 0x00, 0x80, 0x06],
        &[0x11, 0x00, 0x01, 0x07],
        &[0x12, 0x00, 0x00, 0x08],
        &[0x20, 0x00, 0x00, 0x09, 0xff],
    ]);
    assert_eq!(robot.motor_speed(), Some(Speed::FULL_FORWARD));

    // Force exactly 100 is not above the threshold: stop.
    link.reply(&[0]).reply(&100u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x0a],
        &[0x30, 0x00, 0x80, 0x0b],
        &[0x11, 0x00, 0x00, 0x0c],
        &[0x11, 0x00, 0x01, 0x0d],
        &[0x20, 0x00, 0x00, 0x0e, 0x00],
    ]);

    // Button HIGH once: not yet a press (debounce), force read, still stopped.
    link.reply(&[1]).reply(&0u16.to_le_bytes());
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x0f], &[0x30, 0x00, 0x80, 0x10]]);

    // Button HIGH again: pressed; the force sensor is not read (C `||`); full speed.
    link.reply(&[1]).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x11],
        &[0x11, 0x00, 0x01, 0x12],
        &[0x12, 0x00, 0x00, 0x13],
        &[0x20, 0x00, 0x00, 0x14, 0xff],
    ]);

    // One LOW read is a bounce: still pressed, nothing else sent.
    link.reply(&[0]);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x10, 0x00, 0x83, 0x15]]);

    // Second LOW: released, force low: stop (coast, PWM 0).
    link.reply(&[0]).reply(&3u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x10, 0x00, 0x83, 0x16],
        &[0x30, 0x00, 0x80, 0x17],
        &[0x11, 0x00, 0x00, 0x18],
        &[0x11, 0x00, 0x01, 0x19],
        &[0x20, 0x00, 0x00, 0x1a, 0x00],
    ]);
    link.finish();
}

#[test]
fn fig4_2_errors_are_reported_and_a_failed_command_is_retried() {
    let link = Link::new();
    let mut robot = SingleBoard::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.take_sent();

    // The button read is not acknowledged: the step fails, nothing else is sent.
    link.fail(LinkError::Nack);
    assert_eq!(block_on(robot.step()), Err(LinkError::Nack));
    assert_eq!(link.take_sent().len(), 1);

    // The motor command fails half-way: the speed is unknown...
    link.reply(&[0])
        .reply(&500u16.to_le_bytes())
        .ack()
        .fail(LinkError::Timeout);
    assert_eq!(block_on(robot.step()), Err(LinkError::Timeout));
    assert_eq!(link.take_sent().len(), 4);
    assert_eq!(robot.motor_speed(), None);

    // ...so the next step sends the whole command again.
    link.reply(&[0]).reply(&500u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    let frames = link.take_sent();
    assert_eq!(unnumbered(&frames[2..]), three(FULL_SELF, 0xff));
    assert_eq!(robot.motor_speed(), Some(Speed::FULL_FORWARD));

    // A bad status from the board.
    link.reply(&[0])
        .fail(LinkError::Status(x10_devices::Status::PortOutOfRange));
    assert_eq!(
        block_on(robot.step()),
        Err(LinkError::Status(x10_devices::Status::PortOutOfRange))
    );
    assert_eq!(link.take_sent().len(), 2);
    link.finish();
}

// ------------------------------------------------------------------ Figure 4.4

#[test]
fn fig4_4_light_motor_alone() {
    let link = Link::new();
    let mut robot = LightMotor::new(&link).unwrap();
    link.acks(3);
    block_on(robot.setup()).unwrap();
    link.reply(&701u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.reply(&900u16.to_le_bytes());
    block_on(robot.step()).unwrap();
    link.reply(&700u16.to_le_bytes()).acks(3);
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        // setup: stop motor 2 (DB 9, actuator port 1)
        &[0x11, 0x09, 0x00, 0x00],
        &[0x11, 0x09, 0x01, 0x01],
        &[0x20, 0x09, 0x00, 0x02, 0x00],
        // light 701 > 700: forward at 50 % (duty 127)
        &[0x30, 0x09, 0x80, 0x03],
        &[0x11, 0x09, 0x01, 0x04],
        &[0x12, 0x09, 0x00, 0x05],
        &[0x20, 0x09, 0x00, 0x06, 0x7f],
        // still bright: only the reading
        &[0x30, 0x09, 0x80, 0x07],
        // 700 is not above: stop
        &[0x30, 0x09, 0x80, 0x08],
        &[0x11, 0x09, 0x00, 0x09],
        &[0x11, 0x09, 0x01, 0x0a],
        &[0x20, 0x09, 0x00, 0x0b, 0x00],
    ]);
    assert_eq!(robot.motor_speed(), Some(Speed::STOP));
    link.finish();
}

/// Scripts one step of each robot of Figure 4.4 and runs them as two concurrent tasks would.
fn fig4_4_run(link: &Link) -> Vec<Frame> {
    let robots = Program::Fig4_4.build(link).unwrap();
    let [mut single, mut light]: [AnyRobot<&Link>; 2] = robots.into_array().ok().unwrap();
    // setups: single board first, then the light module (join polls in order).
    link.acks(3).acks(3);
    let (a, b) = block_on(join(single.setup(), light.setup()));
    a.unwrap();
    b.unwrap();
    // step: button 0, force 300 -> full; light 800 -> half.
    link.reply(&[0]).reply(&300u16.to_le_bytes()).acks(3);
    link.reply(&800u16.to_le_bytes()).acks(3);
    let (a, b) = block_on(join(single.step(), light.step()));
    a.unwrap();
    b.unwrap();
    link.take_sent().into_iter().collect()
}

#[test]
fn fig4_4_runs_beside_fig4_2_without_changing_it() {
    let link = Link::new();
    let frames = fig4_4_run(&link);
    link.finish();

    // What the Figure 4.2 robot sends alone, given the same replies.
    let alone = Link::new();
    let mut single = SingleBoard::new(&alone).unwrap();
    alone.acks(3);
    block_on(single.setup()).unwrap();
    alone.reply(&[0]).reply(&300u16.to_le_bytes()).acks(3);
    block_on(single.step()).unwrap();
    let alone_frames = alone.take_sent();
    alone.finish();

    let on = |db: u8| -> Vec<Frame> { frames.iter().filter(|f| f[1] == db).cloned().collect() };
    // Board SELF: exactly what Figure 4.2 sends alone.
    assert_eq!(unnumbered(&on(0x00)), unnumbered(&alone_frames));
    // Board 9: the module's own frames.
    let mut want = three(
        [
            &[0x11, 0x09, 0x00],
            &[0x11, 0x09, 0x01],
            &[0x20, 0x09, 0x00],
        ],
        0,
    );
    want.push(vec![0x30, 0x09, 0x80]);
    want.extend(three(
        [
            &[0x11, 0x09, 0x01],
            &[0x12, 0x09, 0x00],
            &[0x20, 0x09, 0x00],
        ],
        0x7f,
    ));
    assert_eq!(unnumbered(&on(0x09)), want);
    assert_eq!(frames.len(), alone_frames.len() + want.len());
    // And the exact interleaving: one link, one sequence.
    let seqs: Vec<u8> = frames.iter().map(|f| f[3]).collect();
    assert_eq!(seqs, (0..frames.len() as u8).collect::<Vec<_>>());
    assert_eq!(unnumbered(&frames[..3]), three(COAST_SELF, 0));
}

// ------------------------------------------------------------------ Figure 4.6

// Raw readings (thesis thermistor, 10-bit ADC; values from python3, see
// x10-devices/tests/math.rs): 100 → −19.16 °C, 256 → 1.67 °C, 700 → 110.33 °F,
// 1000 → 282.07 °F.
const FREEZING: u16 = 100;
const FREEZER_WARM: u16 = 256;
const OVEN_COOL: u16 = 700;
const OVEN_HOT: u16 = 1000;

fn raw(v: u16) -> [u8; 2] {
    v.to_le_bytes()
}

#[test]
fn fig4_6_alarm_when_oven_cools_and_it_latches() {
    assert_eq!(
        (FREEZER.get(), OVEN.get(), CONTROL_BOARD.get()),
        (17, 108, 10)
    );
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.ack();
    block_on(robot.setup()).unwrap();
    link.assert_sent(&[&[0x11, 0x0a, 0x04, 0x00]]); // alarm (DB 10, A3.A) LOW

    // Freezer −19 °C, oven 282 °F: quiet.
    link.reply(&raw(FREEZING)).reply(&raw(OVEN_HOT));
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x01], &[0x30, 0x6c, 0x8a, 0x02]]);
    assert!(!robot.alarm_on());

    // Oven 110 °F < 200 °F: alarm HIGH.
    link.reply(&raw(FREEZING)).reply(&raw(OVEN_COOL)).ack();
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x03],
        &[0x30, 0x6c, 0x8a, 0x04],
        &[0x12, 0x0a, 0x04, 0x05],
    ]);
    assert!(robot.alarm_on());

    // Back to normal: the alarm stays on (no off branch in the thesis), nothing written.
    link.reply(&raw(FREEZING)).reply(&raw(OVEN_HOT));
    block_on(robot.step()).unwrap();
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x06], &[0x30, 0x6c, 0x8a, 0x07]]);
    assert!(robot.alarm_on());

    // A restart (setup) silences it.
    link.ack();
    block_on(robot.setup()).unwrap();
    link.assert_sent(&[&[0x11, 0x0a, 0x04, 0x08]]);
    assert!(!robot.alarm_on());
    link.finish();
}

#[test]
fn fig4_6_warm_freezer_alarms_without_reading_the_oven() {
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.reply(&raw(FREEZER_WARM)).ack();
    block_on(robot.step()).unwrap();
    link.reply(&raw(FREEZER_WARM));
    block_on(robot.step()).unwrap();
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x00],
        &[0x12, 0x0a, 0x04, 0x01],
        &[0x30, 0x11, 0x80, 0x02],
    ]);
    link.finish();
}

#[test]
fn fig4_6_an_unreadable_thermistor_raises_the_alarm_and_is_reported() {
    // Freezer thermistor open (raw 0).
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.reply(&raw(0)).ack();
    assert_eq!(block_on(robot.step()), Err(LinkError::BadReply));
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x00], &[0x12, 0x0a, 0x04, 0x01]]);
    assert!(robot.alarm_on());
    link.finish();

    // Oven board absent.
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.reply(&raw(FREEZING)).fail(LinkError::Nack).ack();
    assert_eq!(block_on(robot.step()), Err(LinkError::Nack));
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x00],
        &[0x30, 0x6c, 0x8a, 0x01],
        &[0x12, 0x0a, 0x04, 0x02],
    ]);
    assert!(robot.alarm_on());
    link.finish();

    // The alarm board does not answer: reported, and tried again on the next step.
    let link = Link::new();
    let mut robot = TemperatureAlarm::new(&link).unwrap();
    link.reply(&raw(FREEZER_WARM)).fail(LinkError::Timeout);
    assert_eq!(block_on(robot.step()), Err(LinkError::Timeout));
    assert!(!robot.alarm_on());
    link.reply(&raw(FREEZER_WARM)).ack();
    block_on(robot.step()).unwrap();
    assert!(robot.alarm_on());
    link.assert_sent(&[
        &[0x30, 0x11, 0x80, 0x00],
        &[0x12, 0x0a, 0x04, 0x01],
        &[0x30, 0x11, 0x80, 0x02],
        &[0x12, 0x0a, 0x04, 0x03],
    ]);
    link.finish();
}

// ------------------------------------------------------------------ registry

#[test]
fn registry_names_and_boards() {
    assert_eq!(names(), ["fig4_2", "fig4_4", "fig4_6"]);
    for (name, program) in names().iter().zip(Program::ALL) {
        assert_eq!(Program::from_name(name), Some(program));
        assert_eq!(name.parse::<Program>(), Ok(program));
        assert_eq!(program.to_string(), *name);
        assert!(!program.description().is_empty());
    }
    assert_eq!(Program::from_name("fig4_3"), None);
    assert_eq!("FIG4_2".parse::<Program>(), Err(UnknownProgram));
    let a = |n: u8| Address::new(n).unwrap();
    assert_eq!(Program::Fig4_2.boards(), [SELF]);
    assert_eq!(Program::Fig4_4.boards(), [SELF, a(9)]);
    assert_eq!(Program::Fig4_6.boards(), [a(17), a(108), a(10)]);
}

#[test]
fn registry_builds_each_program_and_the_robots_run() {
    for program in Program::ALL {
        let link = Link::new();
        let robots = program.build(&link).unwrap();
        let built: Vec<&str> = robots.iter().map(AnyRobot::name).collect();
        assert_eq!(built, program.robot_names());
        assert!(robots.len() <= x10_robots::MAX_ROBOTS);
        // Each robot's setup through AnyRobot sends its own setup frames.
        for mut robot in robots {
            let n = match robot {
                AnyRobot::TemperatureAlarm(_) => 1,
                _ => 3,
            };
            link.acks(n);
            block_on(robot.setup()).unwrap();
        }
        let frames = link.take_sent();
        let want: Vec<Vec<u8>> = match program {
            Program::Fig4_2 => three(COAST_SELF, 0),
            Program::Fig4_4 => {
                let mut v = three(COAST_SELF, 0);
                v.extend(three(
                    [
                        &[0x11, 0x09, 0x00],
                        &[0x11, 0x09, 0x01],
                        &[0x20, 0x09, 0x00],
                    ],
                    0,
                ));
                v
            }
            Program::Fig4_6 => vec![vec![0x11, 0x0a, 0x04]],
        };
        assert_eq!(unnumbered(&frames), want, "{program}");
        link.finish();
    }
}

#[test]
fn any_robot_steps_dispatch() {
    let link = Link::new();
    let mut robots = Program::Fig4_6.build(&link).unwrap();
    link.reply(&raw(FREEZER_WARM)).ack();
    block_on(robots[0].step()).unwrap();
    link.assert_sent(&[&[0x30, 0x11, 0x80, 0x00], &[0x12, 0x0a, 0x04, 0x01]]);
    link.finish();
}
