//! `x10 monitor`'s view of a robot equals the simulator's: the Figure 4.4 robot runs in the
//! simulator with the motherboard's USB-link recorder as an extra observer (the recorder of
//! the board images, `x10_link::recorder::Recorder`); its frames, fed to the monitor's
//! `LinkRun`, give every device the same states in the same order as the simulator's timeline,
//! each within 5 ms (the link stamps an output when its call ends, the simulator when the
//! board's pin changed), and the same summary lines once the times are set aside.

use x10_cli::monitor::LinkRun;
use x10_link::recorder::Recorder;
use x10_sim::sim::SimConfig;
use x10_sim::timeline::Timeline;
use x10_sim::world::World;

static REC: Recorder<{ 256 * 1024 }> = Recorder::new();

/// A device line of a summary without its time column.
fn untimed(line: &str) -> String {
    line.trim_start()
        .split_once("  ")
        .map_or(line.to_string(), |(_, rest)| rest.trim_start().to_string())
}

#[test]
fn the_monitor_sees_fig4_4_as_the_simulator_does() {
    let example = x10_sim::examples::find("fig4_4").unwrap();
    let world = World::from_toml(example.world).unwrap();
    let config = SimConfig::default();
    REC.set_listening(true);
    let sim = world.sim(config).unwrap().also_observe(&REC);
    let outcome = (example.add_tasks)(sim).run().unwrap();
    assert_eq!(REC.dropped(), x10_link::Dropped::default());

    let mut stream = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let n = REC.take(&mut buf);
        if n == 0 {
            break;
        }
        stream.extend_from_slice(&buf[..n]);
    }
    let mut run = LinkRun::new();
    run.feed(&stream);
    assert_eq!(run.bad_frames, 0);
    assert!(!run.calls.is_empty());
    let sim_tl = Timeline::new(&world, &outcome);
    let link_tl = run.timeline(&world);
    let mut compared = 0;
    for (s, l) in sim_tl.devices.iter().zip(&link_tl.devices) {
        if s.script().is_some() {
            continue; // inputs: scripted, not driven
        }
        let (sc, lc) = (s.track.changes(), l.track.changes());
        let states = |c: &[(u64, _)]| c.iter().map(|(_, st)| s.words(st)).collect::<Vec<_>>();
        assert_eq!(states(sc), states(lc), "{}", s.device.name());
        for ((ts, _), (tl, _)) in sc.iter().zip(lc) {
            assert!(
                ts.abs_diff(*tl) <= 5_000_000,
                "{}: {ts} ns in the simulator, {tl} ns over the link",
                s.device.name()
            );
            compared += 1;
        }
    }
    // fig4_4: motor on at the button (2 s) and off, motor2 at the light: at least 4 changes.
    assert!(compared >= 4, "{compared}");
    // The summaries' device lines say the same, times aside.
    let sim_summary = x10_sim::timeline::summary(&world, &outcome);
    let link_summary = run.summary(&world);
    let devices = |s: &str| {
        s.lines()
            .skip(1)
            .take_while(|l| l.starts_with("  "))
            .map(untimed)
            .collect::<Vec<_>>()
    };
    assert_eq!(devices(&sim_summary), devices(&link_summary));
    assert!(
        link_summary.contains("warnings and errors: none"),
        "{link_summary}"
    );
    // The page is the simulator's page.
    let html = run.html(&world, "x10 monitor");
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.contains("<svg"));

    // `x10 monitor --from FILE` prints the same summary and writes the page.
    let dir = std::env::temp_dir().join(format!("x10-monitor-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("fig4_4.x10link");
    let page = dir.join("fig4_4.html");
    std::fs::write(&file, &stream).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_x10"))
        .args(["monitor", "--quiet", "--example", "fig4_4", "--from"])
        .arg(&file)
        .arg("--html")
        .arg(&page)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with(&link_summary), "{text}");
    assert_eq!(std::fs::read_to_string(&page).unwrap(), {
        let title = format!(
            "x10 monitor: {}, against robots/worlds/fig4_4.toml",
            file.display()
        );
        run.html(&world, &title)
    });
    std::fs::remove_dir_all(&dir).unwrap();
}
