//! `--mcap FILE` writes a run that Foxglove opens: the Figure 4.4 robot's file from `x10 sim`
//! and from `x10 monitor --replay` (its USB-link recording), read back with the `mcap`
//! crate's reader (the format's reference implementation), hold exactly the simulator's
//! (the link's) output changes, in values and order, on the documented topics.

use std::collections::BTreeMap;

use serde_json::Value;
use x10_cli::monitor::LinkRun;
use x10_link::recorder::Recorder;
use x10_sim::ports::OutputChange;
use x10_sim::sim::SimConfig;
use x10_sim::world::World;

static REC: Recorder<{ 256 * 1024 }> = Recorder::new();

/// A series of (ns, value).
type Series = Vec<(u64, u64)>;

/// One message read back: topic, log time (ns), JSON.
type Read = (String, u64, Value);

/// Every message of the MCAP file at `path`, in file order, after checking that each channel
/// is JSON with a JSON schema of the documented name.
fn read_mcap(path: &std::path::Path) -> Vec<Read> {
    let bytes = std::fs::read(path).unwrap();
    // The magic at both ends: a complete file.
    assert_eq!(&bytes[..8], b"\x89MCAP0\r\n");
    assert_eq!(&bytes[bytes.len() - 8..], b"\x89MCAP0\r\n");
    let mut out = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.channel.message_encoding, "json");
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "jsonschema");
        let want = match m.channel.topic.as_str() {
            "/x10/calls" => "x10.Call",
            "/x10/events" => "x10.Event",
            "/x10/log" => "foxglove.Log",
            t if t.starts_with("/x10/outputs/") => "x10.Output",
            t => panic!("unexpected topic {t}"),
        };
        assert_eq!(schema.name, want);
        // The schema is JSON.
        let _: Value = serde_json::from_slice(&schema.data).unwrap();
        assert_eq!(m.publish_time, m.log_time);
        out.push((
            m.channel.topic.clone(),
            m.log_time,
            serde_json::from_slice(&m.data).unwrap(),
        ));
    }
    // The summary's statistics agree.
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert_eq!(
        summary.stats.unwrap().message_count,
        u64::try_from(out.len()).unwrap()
    );
    out
}

/// An output change as the file should carry it: (topic, ns, value, text).
fn expected(c: &OutputChange) -> (String, u64, u64, String) {
    let (_, value) = x10_cli::foxglove::output_value(&c.change);
    (
        x10_cli::foxglove::output_topic(c),
        c.t_ns,
        u64::from(value),
        c.to_string(),
    )
}

/// The output messages of a file as (topic, ns, value, text).
fn outputs(msgs: &[Read]) -> Vec<(String, u64, u64, String)> {
    msgs.iter()
        .filter(|(t, _, _)| t.starts_with("/x10/outputs/"))
        .map(|(t, ns, v)| {
            (
                t.clone(),
                *ns,
                v["value"].as_u64().unwrap(),
                v["text"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

fn count(msgs: &[Read], topic: &str) -> usize {
    msgs.iter().filter(|(t, _, _)| t == topic).count()
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("x10-foxglove-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn x10_sim_writes_fig4_4_as_mcap() {
    x10_sim::isolated(|| {
        let file = temp("sim.mcap");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_x10"))
            .args(["sim", "fig4_4", "--mcap"])
            .arg(&file)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let msgs = read_mcap(&file);
        std::fs::remove_file(&file).unwrap();
        // The same run in this process: `x10 sim`'s defaults are the simulator's.
        let example = x10_sim::examples::find("fig4_4").unwrap();
        let world = World::from_toml(example.world).unwrap();
        let outcome = (example.add_tasks)(world.sim(SimConfig::default()).unwrap())
            .run()
            .unwrap();
        let changes = outcome.log.changes();
        assert_eq!(
            outputs(&msgs),
            changes.iter().map(expected).collect::<Vec<_>>()
        );
        // The motors as a student plots them: Figure 4.4's motor on the motherboard's A1
        // and light_motor on board 9's A1, each one series of duties.
        let series = |topic: &str| {
            msgs.iter()
                .filter(|(t, _, _)| t == topic)
                .map(|(_, ns, v)| (*ns, v["value"].as_u64().unwrap(), v["device"].clone()))
                .collect::<Vec<_>>()
        };
        let duties = |board: &str| {
            changes
                .iter()
                .filter(|c| c.board == board && c.pin.to_string() == "A1.A")
                .filter_map(|c| match c.change {
                    x10_sim::ports::Change::Duty(d) => Some((c.t_ns, u64::from(d))),
                    _ => None,
                })
                .collect::<Vec<_>>()
        };
        for (topic, board, device) in [
            ("/x10/outputs/mb/A1_A/pwm", "mb", "motor"),
            ("/x10/outputs/db09/A1_A/pwm", "db09", "light_motor"),
        ] {
            let s = series(topic);
            assert!(!s.is_empty(), "{topic}");
            assert_eq!(
                s.iter().map(|(t, v, _)| (*t, *v)).collect::<Vec<_>>(),
                duties(board),
                "{topic}"
            );
            assert!(s.iter().all(|(_, _, d)| d == device), "{topic}: {s:?}");
        }
        // Every call, event and trace line, in time order.
        assert_eq!(count(&msgs, "/x10/calls"), outcome.calls.len());
        assert_eq!(count(&msgs, "/x10/log"), outcome.trace.lines().len());
        let first_call = msgs.iter().find(|(t, _, _)| t == "/x10/calls").unwrap();
        let c = &outcome.calls[0];
        assert_eq!(first_call.1, c.end_ns);
        assert_eq!(first_call.2["text"], c.text.as_str());
        assert_eq!(first_call.2["task"], c.task.as_str());
        assert_eq!(first_call.2["start_ns"], c.start_ns);
        assert_eq!(first_call.2["ok"], true);
        // The first event: board 9's boot (the trace's first line says it).
        let (_, _, ev) = msgs.iter().find(|(t, _, _)| t == "/x10/events").unwrap();
        assert_eq!(ev["board"], "db09");
        assert_eq!(ev["kind"], "boot");
        assert_eq!(ev["seq"], 0);
        assert_eq!(ev["status"], "ok");
        assert!(msgs.windows(2).all(|w| w[0].1 <= w[1].1));
        // The series docs/usb-link.md tells to plot are topics of this file, with the field.
        let doc = include_str!("../../docs/usb-link.md");
        let section = doc
            .split("## Plotting in Foxglove")
            .nth(1)
            .and_then(|s| s.split("\n## ").next())
            .unwrap();
        let mut plotted = 0;
        for path in section.split('`').filter(|p| p.starts_with("/x10/")) {
            let Some((topic, field)) = path.split_once('.') else {
                continue;
            };
            let topic = topic.split('{').next().unwrap();
            let m = msgs.iter().find(|(t, _, _)| t == topic);
            let (_, _, v) = m.unwrap_or_else(|| panic!("{path}: no topic {topic}"));
            assert!(v.get(field).is_some(), "{path}: no field {field}");
            plotted += 1;
        }
        assert_eq!(plotted, 4);
    });
}

#[test]
fn x10_monitor_replay_converts_a_recording_to_mcap() {
    x10_sim::isolated(|| {
        // The Figure 4.4 robot with the motherboard's USB-link recorder (as tests/monitor.rs).
        let example = x10_sim::examples::find("fig4_4").unwrap();
        let world = World::from_toml(example.world).unwrap();
        REC.set_listening(true);
        let sim = world.sim(SimConfig::default()).unwrap().also_observe(&REC);
        let outcome = (example.add_tasks)(sim).run().unwrap();
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
        let lines = run.feed(&stream);
        assert!(run.events > 0);

        let recording = temp("fig4_4.x10link");
        let file = temp("link.mcap");
        std::fs::write(&recording, &stream).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_x10"))
            .args(["monitor", "--quiet", "--example", "fig4_4", "--replay"])
            .arg(&recording)
            .arg("--html")
            .arg(temp("link.html"))
            .arg("--mcap")
            .arg(&file)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let msgs = read_mcap(&file);
        std::fs::remove_dir_all(file.parent().unwrap()).unwrap();
        // The link's output changes, exactly, each named by the world's device.
        let mut want: Vec<_> = run.outputs.iter().map(expected).collect();
        want.sort_by_key(|w| w.1);
        assert_eq!(outputs(&msgs), want);
        let named = |topic: &str, device: &str| {
            let s: Vec<_> = msgs.iter().filter(|(t, _, _)| t == topic).collect();
            !s.is_empty() && s.iter().all(|(_, _, v)| v["device"] == device)
        };
        assert!(named("/x10/outputs/db09/A1_A/pwm", "light_motor"));
        assert!(named("/x10/outputs/mb/A1_A/pwm", "motor"));
        assert_eq!(count(&msgs, "/x10/calls"), run.calls.len());
        assert_eq!(count(&msgs, "/x10/events"), run.events);
        assert_eq!(count(&msgs, "/x10/log"), lines.len());
        // The motors' series over the link equal the simulator's in values and order, as
        // changes: the link carries every output call that ended well (the robot sets its
        // duty again and again), the simulator's log each change from the power-on 0. The
        // link stamps a change when its call ends, the simulator when the pin changed: within
        // 5 ms.
        let as_changes = |s: &[(u64, u64)]| {
            let mut last = 0;
            let mut out = Vec::new();
            for &(t, v) in s {
                if v != last {
                    out.push((t, v));
                    last = v;
                }
            }
            out
        };
        let sim_changes = outcome.log.changes();
        let mut per_topic: BTreeMap<String, (Series, Series)> = BTreeMap::new();
        for (topic, ns, v, _) in sim_changes.iter().map(expected) {
            per_topic.entry(topic).or_default().0.push((ns, v));
        }
        for (topic, ns, v, _) in outputs(&msgs) {
            per_topic.entry(topic).or_default().1.push((ns, v));
        }
        let mut compared = 0;
        for topic in ["/x10/outputs/mb/A1_A/pwm", "/x10/outputs/db09/A1_A/pwm"] {
            let (sim, link) = &per_topic[topic];
            assert_eq!(&as_changes(sim), sim, "{topic}");
            let link = as_changes(link);
            let values = |s: &[(u64, u64)]| s.iter().map(|(_, v)| *v).collect::<Vec<_>>();
            assert_eq!(values(sim), values(&link), "{topic}");
            for ((ts, _), (tl, _)) in sim.iter().zip(&link) {
                assert!(ts.abs_diff(*tl) <= 5_000_000, "{topic}: {ts} vs {tl}");
                compared += 1;
            }
        }
        // Figure 4.4: each motor on, then off.
        assert!(compared >= 4, "{compared}");
    });
}

/// `x10 monitor --foxglove-ws` serves the live run to a Foxglove client: the monitor reads a
/// pseudo-terminal standing for the motherboard's USB port, this test writes the Figure 4.4
/// robot's link recording into it, and as a client of the Foxglove WebSocket protocol
/// subscribes to the light motor's duty as soon as it is advertised: every later duty record
/// comes, in order, with its time.
#[cfg(all(unix, feature = "foxglove-live"))]
#[test]
fn x10_monitor_serves_the_live_run_to_foxglove() {
    use serialport::SerialPort as _;
    use std::io::{BufRead, Read as _, Write as _};
    use tungstenite::client::IntoClientRequest;
    use tungstenite::Message as Ws;
    use x10_link::{Feed, FrameReader, OutputValue, ToHost, MAX_FRAME};

    x10_sim::isolated(|| {
        let example = x10_sim::examples::find("fig4_4").unwrap();
        let world = World::from_toml(example.world).unwrap();
        REC.set_listening(true);
        let sim = world.sim(SimConfig::default()).unwrap().also_observe(&REC);
        (example.add_tasks)(sim).run().unwrap();
        let mut stream = Vec::new();
        let mut buf = [0u8; 4096];
        loop {
            let n = REC.take(&mut buf);
            if n == 0 {
                break;
            }
            stream.extend_from_slice(&buf[..n]);
        }
        // Where each frame ends, and the light motor's duty records: (frame index, µs, duty).
        let a1a = x10_microcode::Port::actuator(1)
            .unwrap()
            .pin(x10_microcode::Pin::A)
            .to_byte();
        let mut ends = Vec::new();
        let mut duties = Vec::new();
        let mut reader: Box<FrameReader<{ MAX_FRAME }>> = Box::default();
        for (i, &b) in stream.iter().enumerate() {
            if reader.feed(b) == Feed::Frame {
                if let Ok(ToHost::Output(o)) = reader.decode::<ToHost>() {
                    if let (9, true, OutputValue::Duty(d)) = (o.db, o.port == a1a, o.value) {
                        duties.push((ends.len(), o.at_us, d));
                    }
                }
                ends.push(i + 1);
            }
        }
        assert!(duties.len() >= 3, "{duties:?}");

        let (mut master, slave) = serialport::TTYPort::pair().unwrap();
        master
            .set_timeout(std::time::Duration::from_secs(10))
            .unwrap();
        let dir = temp("live");
        std::fs::create_dir_all(&dir).unwrap();
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_x10"))
            .args(["monitor", "--quiet", "--example", "fig4_4"])
            .args(["--foxglove-ws", "127.0.0.1:0", "--port"])
            .arg(slave.name().unwrap())
            .arg("--record")
            .arg(dir.join("run.x10link"))
            .arg("--html")
            .arg(dir.join("run.html"))
            .stdout(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
        let url = loop {
            let mut line = String::new();
            assert!(out.read_line(&mut line).unwrap() > 0, "no address printed");
            if let Some(u) = line
                .trim()
                .strip_prefix("x10 monitor: Foxglove's Open connection: ")
            {
                break u.to_string();
            }
        };
        let addr = url.strip_prefix("ws://").unwrap();
        let tcp = std::net::TcpStream::connect(addr).unwrap();
        tcp.set_read_timeout(Some(std::time::Duration::from_secs(10)))
            .unwrap();
        let mut req = url.as_str().into_client_request().unwrap();
        req.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            "foxglove.websocket.v1".parse().unwrap(),
        );
        let (mut ws, _) = tungstenite::client(req, tcp).unwrap();
        let text = |ws: &mut tungstenite::WebSocket<std::net::TcpStream>| loop {
            match ws.read().unwrap() {
                Ws::Text(t) => break serde_json::from_str::<Value>(t.as_str()).unwrap(),
                Ws::Binary(_) | Ws::Ping(_) | Ws::Pong(_) => {}
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(text(&mut ws)["op"], "serverInfo");
        // The monitor opened the port: its hello.
        let hello = x10_cli::monitor::frame(&x10_cli::monitor::laptop_hello());
        let mut got = vec![0u8; hello.len()];
        master.read_exact(&mut got).unwrap();
        assert_eq!(got, hello);
        // The records up to the light motor's first duty; its channel is advertised.
        let first = duties[0].0;
        master.write_all(&stream[..ends[first]]).unwrap();
        let topic = "/x10/outputs/db09/A1_A/pwm";
        let channel = loop {
            let v = text(&mut ws);
            if v["op"] != "advertise" {
                continue;
            }
            if let Some(c) = v["channels"]
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["topic"] == topic)
            {
                break c["id"].as_u64().unwrap();
            }
        };
        ws.send(Ws::text(format!(
            r#"{{"op":"subscribe","subscriptions":[{{"id":3,"channelId":{channel}}}]}}"#
        )))
        .unwrap();
        // The server reads requests in order and answers a ping after the subscription.
        ws.send(Ws::Ping(b"sub".to_vec().into())).unwrap();
        loop {
            match ws.read().unwrap() {
                Ws::Pong(p) if p.as_ref() == b"sub" => break,
                _ => {}
            }
        }
        master.write_all(&stream[ends[first]..]).unwrap();
        // Every later duty, in order, with its time, on subscription 3.
        for &(_, at_us, duty) in &duties[1..] {
            let frame = loop {
                if let Ws::Binary(b) = ws.read().unwrap() {
                    break b;
                }
            };
            assert_eq!(frame[0], 1);
            assert_eq!(frame[1..5], 3u32.to_le_bytes());
            assert_eq!(frame[5..13], (at_us * 1_000).to_le_bytes());
            let v: Value = serde_json::from_slice(&frame[13..]).unwrap();
            assert_eq!(v["value"], u64::from(duty));
            assert_eq!(v["device"], "light_motor");
        }
        child.kill().unwrap();
        child.wait().unwrap();
        drop(slave);
        std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
    });
}

/// `x10 sim --foxglove-ws` plays the simulated run to a Foxglove client: every topic is
/// advertised at once; once the client subscribes to the motherboard's motor duty, the run
/// plays (ten times its virtual pace here) and every duty change of the simulator's record
/// comes, in order, with its virtual time.
#[cfg(all(unix, feature = "foxglove-live"))]
#[test]
fn x10_sim_plays_the_run_to_foxglove() {
    use std::io::BufRead;
    use tungstenite::client::IntoClientRequest;
    use tungstenite::Message as Ws;

    x10_sim::isolated(|| {
        let example = x10_sim::examples::find("fig4_4").unwrap();
        let world = World::from_toml(example.world).unwrap();
        let config = SimConfig {
            duration_ms: 2_500,
            ..SimConfig::default()
        };
        let outcome = (example.add_tasks)(world.sim(config).unwrap())
            .run()
            .unwrap();
        let duties: Vec<(u64, u64)> = outcome
            .log
            .changes()
            .iter()
            .filter(|c| x10_cli::foxglove::output_topic(c) == "/x10/outputs/mb/A1_A/pwm")
            .map(|c| (c.t_ns, x10_cli::foxglove::output_value(&c.change).1.into()))
            .collect();
        // The button at 2 s starts the motor.
        assert!(!duties.is_empty());

        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_x10"))
            .args(["sim", "fig4_4", "--duration-ms", "2500"])
            .args(["--foxglove-ws", "127.0.0.1:0", "--foxglove-speed", "10"])
            .stdout(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
        let url = loop {
            let mut line = String::new();
            assert!(out.read_line(&mut line).unwrap() > 0, "no address printed");
            if let Some(rest) = line.strip_prefix("sim: Foxglove's Open connection: ") {
                break rest.split(' ').next().unwrap().to_string();
            }
        };
        let tcp = std::net::TcpStream::connect(url.strip_prefix("ws://").unwrap()).unwrap();
        tcp.set_read_timeout(Some(std::time::Duration::from_secs(10)))
            .unwrap();
        let mut req = url.as_str().into_client_request().unwrap();
        req.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            "foxglove.websocket.v1".parse().unwrap(),
        );
        let (mut ws, _) = tungstenite::client(req, tcp).unwrap();
        let mut text = || match ws.read().unwrap() {
            Ws::Text(t) => serde_json::from_str::<Value>(t.as_str()).unwrap(),
            other => panic!("{other:?}"),
        };
        assert_eq!(text()["op"], "serverInfo");
        // Every topic of the run, advertised before anything plays.
        let ads = text();
        assert_eq!(ads["op"], "advertise");
        let topics: Vec<(String, u64)> = ads["channels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                (
                    c["topic"].as_str().unwrap().to_string(),
                    c["id"].as_u64().unwrap(),
                )
            })
            .collect();
        let want: Vec<String> =
            x10_cli::foxglove::sim_messages(&world, &outcome, SimConfig::default().mb_address)
                .into_iter()
                .map(|m| m.topic)
                .collect();
        let mut unique = Vec::new();
        for t in want {
            if !unique.contains(&t) {
                unique.push(t);
            }
        }
        assert_eq!(
            topics.iter().map(|(t, _)| t.clone()).collect::<Vec<_>>(),
            unique
        );
        let channel = topics
            .iter()
            .find(|(t, _)| t == "/x10/outputs/mb/A1_A/pwm")
            .unwrap()
            .1;
        ws.send(Ws::text(format!(
            r#"{{"op":"subscribe","subscriptions":[{{"id":1,"channelId":{channel}}}]}}"#
        )))
        .unwrap();
        for &(t_ns, duty) in &duties {
            let frame = loop {
                match ws.read().unwrap() {
                    Ws::Binary(b) => break b,
                    Ws::Ping(_) | Ws::Pong(_) => {}
                    other => panic!("{other:?}"),
                }
            };
            assert_eq!(frame[..5], [1, 1, 0, 0, 0]);
            assert_eq!(frame[5..13], t_ns.to_le_bytes());
            let v: Value = serde_json::from_slice(&frame[13..]).unwrap();
            assert_eq!(v["value"], duty);
            assert_eq!(v["device"], "motor");
        }
        let mut line = String::new();
        while !line.starts_with("sim: played ") {
            line.clear();
            assert!(out.read_line(&mut line).unwrap() > 0, "no end of play");
        }
        child.kill().unwrap();
        child.wait().unwrap();
    });
}
