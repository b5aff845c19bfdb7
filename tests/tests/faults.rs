//! The Figure 4.4 robot on a faulty bus (injected NACKs and corrupted bytes): the runtimes
//! retry, reject and count, and the robot still does its job.

use x10_microcode::Pin;
use x10_sim::bus::FaultConfig;
use x10_sim::sim::SimConfig;
use x10_tests::{act, ms};

#[test]
fn fig4_4_survives_nacks_and_corrupted_bytes() {
    let config = SimConfig {
        seed: 42,
        faults: FaultConfig {
            nack_ppm: 30_000,
            corrupt_ppm: 20_000,
            ..FaultConfig::NONE
        },
        ..SimConfig::default()
    };
    let o = x10_sim::examples::sim("fig4_4", config)
        .expect("an example")
        .run()
        .unwrap();
    // Faults happened and were handled.
    assert!(o.bus.injected > 20, "{:?}", o.bus);
    assert!(o.mb.retries > 0);
    assert!(o.mb.nacked > 0);
    let db = o.board("db09").unwrap();
    assert!(
        o.mb.bad_replies
            + u32::from(db.bad_length)
            + u32::from(db.wrong_address)
            + u32::from(db.port_errors)
            + u32::from(db.unknown_function)
            + u32::from(db.unknown_operand)
            + u32::from(db.other_errors)
            > 0,
        "some corruption was caught: {:?} {:?}",
        o.mb,
        db
    );
    // The motor on db09 still follows the light: on while it is above 700, off after.
    let a1a = act(1, Pin::A);
    let level = |t| o.log.level_at("db09", a1a, t).map(|l| l.is_high());
    assert_eq!(level(ms(1_500)), Some(false));
    assert_eq!(level(ms(3_000)), Some(true));
    assert_eq!(level(ms(4_900)), Some(false));
    // The internal board is not on the bus: Figure 4.2's motor is untouched by bus faults.
    let mb = |t| o.log.level_at("mb", a1a, t).map(|l| l.is_high());
    assert_eq!(mb(ms(2_500)), Some(true));
    assert_eq!(mb(ms(3_300)), Some(false));
}
