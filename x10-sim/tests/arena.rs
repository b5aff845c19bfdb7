//! Worlds that answer back (issue 28): the example robots in their arenas, checked on what the
//! robot did in the world (where it went, what it touched, what its sensors saw), not only on
//! the commands it sent; the same run byte for byte; the world file's mistakes with their line.

use x10_sim::examples;
use x10_sim::physics::{top_view_svg, Contact};
use x10_sim::sim::{SimConfig, SimOutcome};
use x10_sim::timeline::{summary, MotorState, Timeline};
use x10_sim::world::World;

fn run(name: &str, ms: u64) -> (World, SimOutcome) {
    let e = examples::find(name).expect("an example");
    let world = e.world().expect("its world");
    let config = SimConfig {
        duration_ms: ms,
        ..SimConfig::default()
    };
    let outcome = examples::sim(name, config)
        .expect("its simulation")
        .run()
        .expect("the simulation runs");
    (world, outcome)
}

fn contacts(tl: &Timeline) -> Vec<(String, u64)> {
    tl.contacts()
        .iter()
        .map(|c: &Contact| (c.obstacle.clone(), c.t_ns / 1_000_000))
        .collect()
}

#[test]
fn the_explorer_hits_backs_off_turns_and_goes_on() {
    let (world, outcome) = run("explorer", 20_000);
    let tl = Timeline::new(&world, &outcome);
    let hits = contacts(&tl);
    assert_eq!(
        hits,
        [
            ("box 1".to_string(), 4_064),
            ("box 1".to_string(), 6_056),
            ("wall 1".to_string(), 11_762),
            ("wall 4".to_string(), 15_707),
        ]
    );
    let (left, right) = (tl.motor("left").unwrap(), tl.motor("right").unwrap());
    let bumper = tl.level("bumper").unwrap();
    for (_, at) in &hits {
        // The bumper is pressed at the contact; the robot stops, backs off, spins, cruises.
        assert!(!bumper.at_ms(at - 1) && bumper.at_ms(*at));
        assert_eq!(left.at_ms(at + 50), MotorState::STOPPED);
        assert_eq!(
            (left.at_ms(at + 300), right.at_ms(at + 300)),
            (MotorState::reverse(50), MotorState::reverse(50))
        );
        assert_eq!(
            (left.at_ms(at + 1_000), right.at_ms(at + 1_000)),
            (MotorState::forward(60), MotorState::reverse(50))
        );
        assert_eq!(
            (left.at_ms(at + 1_500), right.at_ms(at + 1_500)),
            (MotorState::forward(60), MotorState::forward(60))
        );
    }
    // Against a wall, never through one: the outline's gap is never negative.
    let (_, gap) = tl.closest_to_wall().unwrap();
    assert!((0.0..0.001).contains(&gap), "{gap}");
    let end = tl.pose_at_ms(20_000).unwrap();
    assert_eq!(
        format!("{:.0} {:.0} {:.0}", end.x_mm, end.y_mm, end.heading_deg),
        "397 933 66"
    );
    assert!(summary(&world, &outcome).contains(
        "chassis: ended at (397, 933) mm heading 66°; 4 contacts: box 1 at 4.064 s, box 1 at 6.056 s, wall 1 at 11.762 s, wall 4 at 15.707 s; closest to a wall 0 mm at 15.834 s\n"
    ));
}

#[test]
fn the_wall_follower_never_comes_within_5_cm_of_a_wall_in_60_s() {
    let (world, outcome) = run("wall_follower", 60_000);
    let tl = Timeline::new(&world, &outcome);
    assert!(tl.contacts().is_empty());
    let (t, gap) = tl.closest_to_wall().unwrap();
    assert!(gap > 50.0, "{gap} mm at {t} ns");
    // It goes round the arena: up the left wall, along the top, down the right, along the
    // bottom, and back up the left.
    let at = |ms| tl.pose_at_ms(ms).unwrap();
    assert!(at(6_000).x_mm < 400.0 && at(6_000).y_mm > 900.0);
    assert!(at(14_000).y_mm > 1_100.0 && at(14_000).x_mm > 900.0);
    assert!(at(24_000).x_mm > 1_600.0 && at(24_000).y_mm < 900.0);
    assert!(at(36_000).y_mm < 400.0 && at(36_000).x_mm < 1_200.0);
    assert!(at(46_000).x_mm < 400.0 && at(46_000).y_mm > 900.0);
    // Each reading the program got is the one the arena gives: its steering follows the
    // replayed distance, floor(mm) as the driver converts the echo.
    let left = tl.motor("left").unwrap();
    let readings = tl.motion().unwrap().ranger_readings();
    assert!(readings.len() > 800, "{}", readings.len());
    for r in readings {
        let steer = match r.distance_mm {
            Some(d) => ((d.floor() as i32 - 300) / 6).clamp(-25, 25),
            None => 25,
        };
        let t_ms = r.t_ns / 1_000_000 + 10;
        if t_ms < 60_000 {
            assert_eq!(
                left.at_ms(t_ms).signed_percent(),
                (40 - steer) as i16,
                "{r:?}"
            );
        }
    }
}

#[test]
fn the_line_follower_stays_on_the_circle() {
    let (world, outcome) = run("line_follower", 30_000);
    let tl = Timeline::new(&world, &outcome);
    assert_eq!(tl.time_on_line_ns("eye"), Some(13_191_000_000));
    let m = tl.motion().unwrap();
    let mut swept = 0.0;
    let mut last = None;
    for s in m.samples(20_000_000) {
        let (dx, dy) = (s.pose.x_mm - 1_000.0, s.pose.y_mm - 750.0);
        let r = dx.hypot(dy);
        assert!(
            (420.0..520.0).contains(&r),
            "{r} mm from the centre at {} ns",
            s.t_ns
        );
        let a = dy.atan2(dx).to_degrees();
        if let Some(l) = last {
            swept += (a - l + 540.0) % 360.0 - 180.0;
        }
        last = Some(a);
    }
    assert_eq!(format!("{swept:.0}"), "214");
    assert!(tl.contacts().is_empty());
}

#[test]
fn the_freezer_alarm_goes_on_after_the_door_has_been_open_for_a_while() {
    let (world, outcome) = run("freezer", 12_000);
    let tl = Timeline::new(&world, &outcome);
    let alarm = tl.led("alarm").unwrap();
    // The door opens at 2 s; 20 − 38 e^(−t/10 s) passes 1 °C 6.931 s later; the alarm goes on
    // at the next of the program's readings (every 20 ms).
    assert_eq!(alarm.first_ns(|on| *on).map(|t| t / 1_000_000), Some(8_943));
    let m = tl.motion().unwrap();
    let c = |ms: u64| m.celsius_at_ns("cabinet", ms * 1_000_000).unwrap();
    assert_eq!(c(2_000), -18.0);
    assert!(
        c(8_920) < 1.0 && c(8_940) > 1.0,
        "{} {}",
        c(8_920),
        c(8_940)
    );
    assert_eq!(
        tl.device("freezer").unwrap().at_ms(8_940),
        x10_sim::timeline::DeviceState::Celsius(1.0)
    );
}

#[test]
fn the_same_world_and_seed_give_the_same_run_byte_for_byte() {
    let (w1, o1) = run("explorer", 8_000);
    let (w2, o2) = run("explorer", 8_000);
    assert_eq!(o1.log.changes(), o2.log.changes());
    let (t1, t2) = (Timeline::new(&w1, &o1), Timeline::new(&w2, &o2));
    assert_eq!(
        t1.motion().unwrap().samples(1_000_000),
        t2.motion().unwrap().samples(1_000_000)
    );
    assert_eq!(summary(&w1, &o1), summary(&w2, &o2));
    assert_eq!(
        top_view_svg(t1.motion().unwrap()),
        top_view_svg(t2.motion().unwrap())
    );
}

#[test]
fn the_page_has_the_arena_and_its_slider() {
    let (world, outcome) = run("wall_follower", 3_000);
    let page = x10_sim::timeline::timeline_html(&world, &outcome, "wall follower");
    for needle in [
        "<h2>Arena</h2>",
        r#"id="x10-scrub""#,
        r#"id="x10-arena""#,
        r#"id="x10-robot""#,
        r#"class="beam""#,
        r#"class="wall""#,
        "sonar 0.000 s: 391 mm",
    ] {
        assert!(page.contains(needle), "{needle}");
    }
    assert!(!page.contains("http://") || !page.contains("src=\"http"));
    let svg = top_view_svg(Timeline::new(&world, &outcome).motion().unwrap());
    roxmltree::Document::parse(&svg).expect("well-formed SVG");
}

#[test]
fn the_lanes_of_model_sensors_show_what_they_read() {
    for (name, ms) in [
        ("explorer", 8_000),
        ("wall_follower", 3_000),
        ("line_follower", 3_000),
        ("freezer", 10_000),
    ] {
        let (world, outcome) = run(name, ms);
        let svg = x10_sim::timeline::timeline_svg(&world, &outcome);
        roxmltree::Document::parse(&svg).expect("well-formed SVG");
        let page = x10_sim::timeline::timeline_html(&world, &outcome, name);
        for bad in [
            "NaN",
            "inf",
            "constant 1000 mm",
            "constant 0 counts",
            "constant 20 °C",
        ] {
            assert!(!page.contains(bad), "{name}: {bad}");
        }
    }
}

/// The picture in docs/world.md: `cargo run -p x10-sim --example arena -- explorer 20000
/// docs/arena-explorer.svg` writes it; regenerating gives the same bytes.
#[test]
fn the_top_view_in_the_docs_is_what_the_command_writes() {
    let (world, outcome) = run("explorer", 20_000);
    let svg = top_view_svg(Timeline::new(&world, &outcome).motion().unwrap());
    assert_eq!(svg, include_str!("../../docs/arena-explorer.svg"));
}

fn error(text: &str) -> String {
    World::from_toml(text).expect_err("a mistake").to_string()
}

const BOARD: &str = "[[board]]\naddress = 0\nsensor_ports = 2\nactuator_ports = 2\n\n[[device]]\nname = \"left\"\nkind = \"dc_motor\"\nport = \"A1\"\n\n[[device]]\nname = \"right\"\nkind = \"led\"\nport = \"A2\"\npin = \"A\"\n\n[[device]]\nname = \"bumper\"\nkind = \"button\"\nport = \"S2\"\npin = \"B\"\n";

#[test]
fn inconsistent_worlds_are_refused_with_their_line() {
    assert_eq!(
        error(&format!("{BOARD}\n[chassis]\nleft = \"left\"\nright = \"right\"\n")),
        "line 25: chassis: `right` names `right`, a led: the chassis's wheels are dc_motor devices (H-bridges)"
    );
    let two_motors = BOARD.replace(
        "kind = \"led\"\nport = \"A2\"\npin = \"A\"",
        "kind = \"dc_motor\"\nport = \"A2\"",
    );
    let chassis = format!("{two_motors}\n[chassis]\nleft = \"left\"\nright = \"right\"\nstart = [50, 500, 0]\n\n[arena]\nsize_mm = [1000, 1000]\n");
    assert_eq!(
        error(&chassis),
        "line 25: chassis: `start` puts the outline into wall 4 (50 mm from its centre, radius 80 mm)"
    );
    let fine = chassis.replace("[50, 500, 0]", "[500, 500, 0]");
    assert!(World::from_toml(&fine).is_ok());
    assert_eq!(
        error(&format!("{fine}\n[[sensor]]\ndevice = \"bumper\"\nsource = \"laser\"\n")),
        "line 32: sensor `bumper`: `source` is `laser`: one of ranger, bumper, line, light, left_encoder, right_encoder, thermal"
    );
    assert_eq!(
        error(&format!(
            "{fine}\n[[sensor]]\ndevice = \"bumper\"\nsource = \"bumper\"\nrange_mm = 4\n"
        )),
        "line 33: sensor `bumper`: `range_mm` does not apply to `source = \"bumper\"`"
    );
    let scripted = fine.replace("pin = \"B\"\n", "pin = \"B\"\npresses = [[1000, 50]]\n");
    assert_eq!(
        error(&format!("{scripted}\n[[sensor]]\ndevice = \"bumper\"\nsource = \"bumper\"\n")),
        "line 33: sensor `bumper`: `source` `bumper` is a model, but `bumper` also has a script: keep one"
    );
    assert_eq!(
        error(&format!("{two_motors}\n[[sensor]]\ndevice = \"bumper\"\nsource = \"bumper\"\n")),
        "line 24: sensor `bumper`: `source` `bumper` reads the chassis, but the world has no [chassis]"
    );
    assert_eq!(
        error(&format!(
            "{fine}\n[[sensor]]\ndevice = \"left\"\nsource = \"line\"\n"
        )),
        "line 32: sensor `left`: `source` `line` does not fit a dc_motor"
    );
    assert_eq!(
        error(&format!("{fine}\n[[thermal]]\nname = \"oven\"\nstart_c = 20\nidle_c = 20\ntime_constant_s = 60\nheater = \"bumper\"\n")),
        "line 35: thermal `oven`: `heater` names `bumper`, a button: a heater is a digital_output, led or pwm_output"
    );
    assert!(error(&format!("{fine}\nwheel_count = 3\n"))
        .starts_with("line 30: unknown field `wheel_count`, expected one of `size_mm`"));
}
