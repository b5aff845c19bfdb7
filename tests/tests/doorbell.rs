//! The doorbell example (`robots/src/doorbell.rs`): a button's events from daughterboard 9
//! wake the motherboard task, which mirrors the button on the chime. Checked against what the
//! simulated ports really held: the chime changes once per button change, in order, soon after.

use x10_sim::sim::SimConfig;
use x10_sim::timeline::Timeline;

const MS: u64 = 1_000_000;

#[test]
fn the_chime_follows_the_button_on_another_board() {
    let example = x10_sim::examples::find("doorbell").expect("the doorbell example");
    let world = example.world().expect("its world");
    let config = SimConfig {
        duration_ms: 3_000,
        ..SimConfig::default()
    };
    let sim = world.sim(config).expect("a valid world");
    let outcome = x10_sim::examples::with_tasks("doorbell", sim)
        .expect("its tasks")
        .run()
        .expect("it runs");
    let tl = Timeline::new(&world, &outcome);
    let chime = tl.led("chime").expect("the chime");
    let changes = chime.changes();
    // The world presses the button at 1.0 s for 500 ms and at 2.5 s for 100 ms.
    let button = [(1_000, true), (1_500, false), (2_500, true), (2_600, false)];
    // The chime was set low once at start (before the button's events were enabled).
    let after_start: Vec<_> = changes.iter().filter(|(t, _)| *t >= 500 * MS).collect();
    assert_eq!(after_start.len(), button.len(), "{changes:?}");
    for ((t, on), (pressed_ms, pressed)) in after_start.iter().zip(button) {
        assert_eq!(*on, pressed, "{changes:?}");
        let delay = t - pressed_ms * MS;
        // An event from board 9, the task, one confirming read of the button, the write: a
        // few bus transactions at 400 kHz.
        assert!(
            delay < 3 * MS,
            "chime {delay} ns after the button: {changes:?}"
        );
    }
    assert!(
        changes.iter().all(|(t, on)| *t >= 500 * MS || !on),
        "{changes:?}"
    );
}
