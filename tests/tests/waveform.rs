//! The VCD file: a valid header, time only moving forward, and SDA changing while SCL is high
//! exactly at every START, repeated START and STOP of the recorded transactions.

use x10_sim::bus::WireSym;
use x10_sim::sim::SimConfig;
use x10_sim::timing::Speed;

#[test]
fn vcd_encodes_every_start_and_stop() {
    for speed in Speed::ALL {
        let config = SimConfig {
            speed,
            duration_ms: 600,
            ..SimConfig::default()
        };
        let o = x10_sim::examples::sim("fig4_4", config)
            .expect("an example")
            .run()
            .unwrap();
        let vcd = o.vcd();
        let (header, body) = vcd.split_once("$enddefinitions $end\n").unwrap();
        assert!(header.contains("$timescale 1ns $end"));
        assert!(header.contains("$var wire 1 ! SCL $end"));
        assert!(header.contains("$var wire 1 \" SDA $end"));
        let (mut scl, mut sda) = (true, true);
        let (mut t, mut starts, mut stops) = (0u64, 0usize, 0usize);
        let mut in_dumpvars = false;
        for line in body.lines() {
            if line == "$dumpvars" {
                in_dumpvars = true;
                continue;
            }
            if line == "$end" {
                in_dumpvars = false;
                continue;
            }
            if let Some(ts) = line.strip_prefix('#') {
                let now: u64 = ts.parse().unwrap();
                assert!(now >= t, "{speed}: time went back at {line}");
                t = now;
                continue;
            }
            let (v, id) = line.split_at(1);
            let v = match v {
                "0" => false,
                "1" => true,
                other => panic!("{speed}: bad value {other:?}"),
            };
            match id {
                "!" => scl = v,
                "\"" => {
                    if scl && !in_dumpvars && v != sda {
                        if v {
                            stops += 1;
                        } else {
                            starts += 1;
                        }
                    }
                    sda = v;
                }
                other => panic!("{speed}: unknown id {other:?}"),
            }
        }
        let wire_starts = o
            .records
            .iter()
            .flat_map(|r| r.wire.iter())
            .filter(|(_, s)| matches!(s, WireSym::Start | WireSym::RepeatedStart))
            .count();
        let wire_stops = o
            .records
            .iter()
            .flat_map(|r| r.wire.iter())
            .filter(|(_, s)| matches!(s, WireSym::Stop))
            .count();
        assert!(o.records.len() > 20);
        assert_eq!(starts, wire_starts, "{speed}");
        assert_eq!(stops, wire_stops, "{speed}");
        assert_eq!(stops, o.records.len(), "{speed}");
        // Bus idle (both high) at the end.
        assert!(scl && sda, "{speed}");
    }
}
