//! The timeline plot and its page (issue 23 item 8): every change has its tooltip, no label is
//! dropped without saying so, the devices, the bus and the tasks' calls share one time axis,
//! and the page is self-contained.

use embassy_time::Timer;
use x10_devices::{Actuator, DcMotor, Duty, Error, Pin};
use x10_microcode::Address;
use x10_sim::sim::{SimConfig, SimOutcome, X10};
use x10_sim::timeline::{
    timeline_html, timeline_svg, DeviceState, MotorState, Timeline, LABEL_ROWS,
};
use x10_sim::trace::timestamp;
use x10_sim::world::{Board, Device, World, SELF};

/// The plot's geometry: the plot runs from x = 230 to x = 976 over the whole run.
const LEFT: f64 = 230.0;
const RIGHT: f64 = 976.0;

fn world() -> World {
    World::new()
        .board(Board::internal(2, 2))
        .board(Board::new(0x0a, 1, 2))
        .device(Device::dc_motor("left", 0x0a, 1))
        .device(Device::dc_motor("right", 0x0a, 2))
        .device(Device::dimmable_led("lamp", SELF, 1, Pin::A))
}

fn db0a() -> Address {
    Address::external(0x0a).unwrap_or(Address::INTERNAL)
}

/// A bumper manoeuvre: forward, reverse 30 ms later, stop 300 ms after that; the user's run in
/// which "reverse 50 %" was missing on both motor lanes.
async fn drive(x10: X10) -> Result<(), Error> {
    let mut left = DcMotor::new(x10, db0a(), 1)?;
    let mut right = DcMotor::new(x10, db0a(), 2)?;
    Timer::after_millis(1_000).await;
    left.set_percent(50).await?;
    right.set_percent(50).await?;
    Timer::after_millis(30).await;
    left.set_percent(-50).await?;
    right.set_percent(-50).await?;
    Timer::after_millis(300).await;
    left.stop().await?;
    right.stop().await?;
    Ok(())
}

/// A lamp fading up in 40 steps of 10 ms: more labels than three rows hold.
async fn fade(x10: X10) -> Result<(), Error> {
    let lamp = Actuator::new(x10, SELF, 1)?;
    Timer::after_millis(2_000).await;
    for step in 1..=40u8 {
        lamp.pwm(Pin::A, Duty(step * 6)).await?;
        Timer::after_millis(10).await;
    }
    Ok(())
}

fn run() -> (World, SimOutcome) {
    let world = world();
    let config = SimConfig {
        duration_ms: 5_000,
        ..SimConfig::default()
    };
    let outcome = world
        .sim(config)
        .unwrap()
        .with_robot("drive", drive)
        .with_robot("fade", fade)
        .run()
        .unwrap();
    (world, outcome)
}

fn x_of(t_ns: u64, end_ns: u64) -> f64 {
    LEFT + (RIGHT - LEFT) * (t_ns as f64 / end_ns as f64)
}

fn attr(n: roxmltree::Node<'_, '_>, name: &str) -> f64 {
    n.attribute(name).unwrap().parse().unwrap()
}

fn title(n: roxmltree::Node<'_, '_>) -> String {
    n.children()
        .find(|c| c.has_tag_name("title"))
        .and_then(|t| t.text())
        .unwrap_or_default()
        .to_string()
}

fn class(n: roxmltree::Node<'_, '_>, c: &str) -> bool {
    n.attribute("class") == Some(c)
}

#[test]
fn every_change_has_its_tooltip_and_its_label() {
    let (world, o) = run();
    let tl = Timeline::new(&world, &o);
    let svg = timeline_svg(&world, &o);
    let doc = match roxmltree::Document::parse(&svg) {
        Ok(d) => d,
        Err(e) => panic!("{e}\n{svg}"),
    };
    let root = doc.root_element();
    // One dot per change, in lane order, each with its tooltip.
    let dots: Vec<String> = root
        .descendants()
        .filter(|n| class(*n, "change"))
        .map(title)
        .collect();
    let want: Vec<String> = tl
        .devices
        .iter()
        .flat_map(|d| d.track.changes().iter().map(|(t, s)| d.change_text(*t, s)))
        .collect();
    assert_eq!(dots, want);
    // The first motor's three changes, as the tooltips word them.
    let left = tl.get("left").unwrap();
    let changes = left.track.changes();
    assert_eq!(
        changes.iter().map(|(_, s)| *s).collect::<Vec<_>>(),
        [
            DeviceState::Motor(MotorState::forward(50)),
            DeviceState::Motor(MotorState::reverse(50)),
            DeviceState::Motor(MotorState::STOPPED)
        ]
    );
    let at = |i: usize| timestamp(changes[i].0);
    assert_eq!(
        want[..3],
        [
            format!("left {} s: forward 50 %", at(0)),
            format!("left {} s: reverse 50 %", at(1)),
            format!("left {} s: stopped", at(2))
        ]
    );
    assert!(
        at(0).starts_with("1.00") && at(1).starts_with("1.03"),
        "{want:?}"
    );
    // Per lane, its labels in time order; which are visible.
    let lanes: Vec<Vec<(String, bool)>> = root
        .descendants()
        .filter(|n| class(*n, "labels"))
        .map(|g| {
            g.children()
                .filter(|n| class(*n, "label"))
                .map(|n| {
                    (
                        n.text().unwrap_or_default().to_string(),
                        n.attribute("visibility") != Some("hidden"),
                    )
                })
                .collect()
        })
        .collect();
    let shown = |v: &[(String, bool)]| -> Vec<String> {
        v.iter()
            .filter(|(_, s)| *s)
            .map(|(t, _)| t.clone())
            .collect()
    };
    // Both motors: every change labelled, "rev 50 %" among them.
    for lane in &lanes[..2] {
        assert_eq!(shown(lane), ["fwd 50 %", "rev 50 %", "stop"]);
    }
    // The lamp: 40 changes, every one with its label in the picture; those without room are
    // hidden until a zoom makes room, and the lane says how many.
    let lamp = tl.get("lamp").unwrap();
    let labels: Vec<String> = lamp
        .track
        .changes()
        .iter()
        .map(|(_, s)| lamp.label(s))
        .collect();
    assert_eq!(labels.len(), 40);
    assert_eq!(
        lanes[2].iter().map(|(t, _)| t.clone()).collect::<Vec<_>>(),
        labels
    );
    let hidden = lanes[2].iter().filter(|(_, s)| !s).count();
    assert!(hidden > 0 && hidden < 40, "{hidden}");
    let notes: Vec<&str> = root
        .descendants()
        .filter(|n| {
            n.attribute("id")
                .is_some_and(|i| i.starts_with("x10-note-"))
        })
        .map(|n| n.text().unwrap_or_default())
        .collect();
    assert_eq!(
        notes,
        [
            "",
            "",
            &*format!("{hidden} labels without room: zoom in or hover")
        ]
    );
    // The visible labels of one row never overlap (6 px per character, 6 px apart).
    let mut rows: Vec<Vec<(f64, f64)>> = vec![Vec::new(); LABEL_ROWS];
    let lamp_group = root
        .descendants()
        .filter(|n| class(*n, "labels"))
        .nth(2)
        .unwrap();
    let y0 = attr(lamp_group, "data-y");
    for n in lamp_group.children().filter(|n| class(*n, "label")) {
        if n.attribute("visibility") == Some("hidden") {
            continue;
        }
        let row = ((attr(n, "y") - y0) / 12.0).round() as usize;
        let (x, w) = (attr(n, "x"), attr(n, "data-w"));
        let span = if n.attribute("text-anchor") == Some("end") {
            (x - w, x)
        } else {
            (x, x + w)
        };
        for (a, b) in &rows[row] {
            assert!(span.0 >= b + 6.0 || span.1 + 6.0 <= *a, "{span:?} {a} {b}");
        }
        rows[row].push(span);
    }
    assert_eq!(
        rows.iter().map(Vec::len).sum::<usize>() + hidden,
        40,
        "{rows:?}"
    );
}

#[test]
fn devices_bus_and_calls_share_one_time_axis() {
    let (world, o) = run();
    let svg = timeline_svg(&world, &o);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let root = doc.root_element();
    let end = o.end_ns;
    // Every bus transaction and every call is a bar from its start to its end, with its
    // tooltip, at the same x as a device change at that instant.
    let txns: Vec<_> = root.descendants().filter(|n| class(*n, "txn")).collect();
    assert_eq!(txns.len(), o.records.len());
    for (n, r) in txns.iter().zip(&o.records) {
        assert!((attr(*n, "x") - x_of(r.start_ns, end)).abs() < 0.001);
        let w = x_of(r.end_ns, end) - x_of(r.start_ns, end);
        assert!((attr(*n, "width") - w).abs() < 0.002);
    }
    assert!(
        title(txns[0]).starts_with("bus 0.000"),
        "{}",
        title(txns[0])
    );
    let calls: Vec<_> = root.descendants().filter(|n| class(*n, "call")).collect();
    // drive: 2 motors × 3 commands × 3 writes; fade: 40 duties.
    assert_eq!(o.calls.len(), 58);
    assert_eq!(calls.len(), o.calls.len());
    // The lamp is on the internal board: its calls take no virtual time, drawn as lines.
    assert_eq!(calls.iter().filter(|n| n.has_tag_name("line")).count(), 40);
    let mut by_lane: Vec<&str> = Vec::new();
    for c in &o.calls {
        if !by_lane.contains(&c.task.as_str()) {
            by_lane.push(&c.task);
        }
    }
    assert_eq!(by_lane, ["drive", "fade"]);
    let ordered: Vec<_> = by_lane
        .iter()
        .flat_map(|t| o.calls.iter().filter(move |c| c.task == *t))
        .collect();
    for (n, c) in calls.iter().zip(&ordered) {
        assert_eq!(
            title(*n),
            format!("{} {} s: {}", c.task, timestamp(c.start_ns), c.text)
        );
        let x = if n.has_tag_name("line") {
            assert_eq!(c.start_ns, c.end_ns);
            attr(*n, "x1")
        } else {
            assert!(c.end_ns > c.start_ns);
            let w = x_of(c.end_ns, end) - x_of(c.start_ns, end);
            assert!((attr(*n, "width") - w).abs() < 0.002);
            attr(*n, "x")
        };
        assert!((x - x_of(c.start_ns, end)).abs() < 0.001);
    }
    // The first call: the left motor's first direction pin, at 1 s.
    assert_eq!(
        title(calls[0]),
        format!("drive 1.000000 s: {}", o.calls[0].text)
    );
    assert!(
        o.calls[0].text.starts_with("db0a io low A1.B -> ok in "),
        "{}",
        o.calls[0].text
    );
    // The change dots on the same axis.
    let tl = Timeline::new(&world, &o);
    let dots: Vec<_> = root.descendants().filter(|n| class(*n, "change")).collect();
    let times: Vec<u64> = tl
        .devices
        .iter()
        .flat_map(|d| d.track.changes().iter().map(|(t, _)| *t))
        .collect();
    for (n, t) in dots.iter().zip(&times) {
        assert!((attr(*n, "data-x") - x_of(*t, end)).abs() < 0.001);
    }
    // The lane names: devices, then the bus, then the tasks.
    let names: Vec<&str> = root
        .descendants()
        .filter(|n| n.has_tag_name("text") && n.attribute("font-size") == Some("13"))
        .filter_map(|n| n.text())
        .collect();
    assert_eq!(
        names,
        ["left", "right", "lamp", "bus", "task drive", "task fade"]
    );
}

#[test]
fn the_page_is_self_contained_and_lists_every_change() {
    let (world, o) = run();
    let tl = Timeline::new(&world, &o);
    let page = timeline_html(&world, &o, "Two motors & a lamp");
    assert!(!page.contains("http://") && !page.contains("https://"));
    for attribute in [
        " src=",
        " href=",
        "@import",
        "url(http",
        "fetch(",
        "XMLHttpRequest",
    ] {
        assert!(!page.contains(attribute), "{attribute}");
    }
    // The only url() references are the picture's own clip path.
    assert_eq!(
        page.matches("url(").count(),
        page.matches("url(#x10-plot-area)").count()
    );
    assert_eq!(page.matches("<script>").count(), 1);
    assert!(page.contains(include_str!("../src/timeline/zoom.js")));
    assert!(page.contains("<title>Two motors &amp; a lamp</title>"));
    // Every change: its tooltip in the picture and its row in the table.
    let mut rows = 0;
    for d in &tl.devices {
        for (t, s) in d.track.changes() {
            let text = d.change_text(*t, s);
            assert!(page.contains(&format!("<title>{text}</title>")), "{text}");
            let row = format!(
                "<tr><td>{} s</td><td>{}</td><td>{}</td></tr>",
                timestamp(*t),
                d.device.name(),
                d.words(s)
            );
            assert!(page.contains(&row), "{row}");
            rows += 1;
        }
    }
    assert_eq!(rows, 46);
    assert!(page.contains("<h2>Changes (46)</h2>"));
    assert_eq!(page.matches("<tr><td>").count(), 46);
    // The inline picture is the SVG file's without its namespace URL.
    let svg = timeline_svg(&world, &o).replace(r#" xmlns="http://www.w3.org/2000/svg""#, "");
    assert!(page.contains(&svg));
}
