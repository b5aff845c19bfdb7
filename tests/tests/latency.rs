//! The latency table's figures: simulated end-to-end times against the wire-time minimum.

use x10_cli::report::{latency_table, measure};
use x10_sim::timing::Speed;

#[test]
fn external_calls_cost_their_wire_time_plus_bus_free_time() {
    for speed in Speed::ALL {
        let t = speed.timing();
        let rows = measure(speed, 10).unwrap();
        assert_eq!(rows.len(), 8);
        for r in &rows {
            assert_eq!(r.failures, 0, "{speed} {}", r.op);
            if r.internal {
                // No bus, and port calls take no virtual time (synchronous, as on the
                // boards; the boards' 2 µs ADC conversion is not simulated).
                assert_eq!((r.min_ns, r.max_ns), (0, 0), "{speed} {}", r.op);
                assert_eq!(r.wire_ns, None);
            } else {
                let wire = r.wire_ns.unwrap();
                let expected_wire = match r.op {
                    "digitalOut" => t.write_ns(4),
                    "pwm" => t.write_ns(5),
                    "digitalIn" => t.write_read_ns(4, 4),
                    "analog" => t.write_read_ns(4, 5),
                    other => panic!("{other}"),
                };
                assert_eq!(wire, expected_wire, "{speed} {}", r.op);
                // Back to back: each call waits t_BUF after the previous STOP (the first
                // one after a switch of operation may start at once).
                assert_eq!(r.max_ns, wire + t.buf_ns, "{speed} {}", r.op);
                assert!(r.min_ns >= wire, "{speed} {}", r.op);
            }
        }
    }
}

#[test]
fn the_table_lists_every_operation_board_and_the_thesis_figures() {
    let table = latency_table(20).unwrap();
    for needle in [
        "| digitalOut | external db09 |",
        "| digitalOut | internal SELF |",
        "| digitalIn  | external db09 |",
        "| pwm        | internal SELF |",
        "| analog     | external db09 |",
        "261.4",
        "554.8",
        "215.58",
    ] {
        assert!(table.contains(needle), "{needle} missing in\n{table}");
    }
    assert!(!table.contains("WARNING"));
    assert!(!table.contains('?'));
    // 400 kHz digitalOut to db09: 115 µs on the wire, 116.3 µs back to back (mean of 20: the
    // first call starts on an idle bus).
    assert!(table.contains("| digitalOut | external db09 |    467.8 |     463.3 |    116.3 |       115 |   46.5 |    46.1 |  261.4 |"), "{table}");
}
