//! A bounded run ([`Keep::Summary`]): what it keeps does not grow with its length, its
//! counters and bus load are those of the full record, and the summary says what it kept.

use x10_sim::examples;
use x10_sim::sim::{Keep, SimConfig, SimOutcome, KEEP_CAP};
use x10_sim::timeline;

fn run(name: &str, duration_ms: u64, keep: Keep) -> SimOutcome {
    let config = SimConfig {
        duration_ms,
        keep,
        ..SimConfig::default()
    };
    match examples::sim(name, config).map(x10_sim::sim::Sim::run) {
        Some(Ok(o)) => o,
        None => panic!("no example {name}"),
        Some(Err(e)) => panic!("{name}: {e}"),
    }
}

/// What a run keeps in its lists, in entries.
fn kept_entries(o: &SimOutcome) -> [usize; 5] {
    [
        o.records.len(),
        o.calls.len(),
        o.trace.lines().len(),
        o.log.len(),
        o.device_warnings.len(),
    ]
}

#[test]
fn a_bounded_run_keeps_the_same_whatever_its_length() {
    x10_sim::isolated(|| {
        let short = run("fig4_4", 10_000, Keep::Summary);
        let long = run("fig4_4", 40_000, Keep::Summary);
        // Figure 4.4's outputs all change in its first 5 s (its world's scripts end at
        // 4.2 s): the 10 s and the 40 s runs keep exactly the same entries.
        assert_eq!(kept_entries(&short), kept_entries(&long));
        assert_eq!(kept_entries(&long), [0, 0, 0, long.log.len(), 0]);
        assert_eq!(short.log.changes(), long.log.changes());
        // What they counted grows with the run.
        assert!(long.bus.transactions > 3 * short.bus.transactions);
        assert!(long.kept.calls.0 > 3 * short.kept.calls.0);
        assert_eq!((long.kept.calls.1, long.kept.dropped()), (0, 0));
    });
}

#[test]
fn a_bounded_run_counts_what_the_full_record_holds() {
    x10_sim::isolated(|| {
        let world = examples::find("fig4_4").and_then(|e| e.world().ok());
        let Some(world) = world else {
            panic!("fig4_4 has a world")
        };
        let all = run("fig4_4", 8_000, Keep::All);
        let summary = run("fig4_4", 8_000, Keep::Summary);
        assert_eq!(all.bus, summary.bus);
        assert_eq!(all.mb, summary.mb);
        assert_eq!(all.boards, summary.boards);
        assert_eq!(all.log.changes(), summary.log.changes());
        let busy: u64 = all.records.iter().map(|r| r.duration_ns()).sum();
        assert_eq!(summary.bus.busy_ns, busy);
        assert_eq!(summary.kept.calls.0, all.calls.len() as u64);
        // The summaries are the same but for the line that says what the bounded one kept.
        let full = timeline::summary(&world, &all);
        let bounded = timeline::summary(&world, &summary);
        assert_eq!(
            bounded,
            format!(
                "{full}record: a summary (a long run): the counts and the bus load cover the whole run ({} calls, 0 failed); kept of the lists only the first {KEEP_CAP} of each (failed bus transactions, failed calls, warnings, output changes): nothing was past that\n",
                all.calls.len()
            )
        );
        assert_eq!(all.kept.summary_line(), None);
    });
}

/// A writer whose bytes the test reads afterwards.
#[derive(Clone, Default)]
struct Shared(std::rc::Rc<std::cell::RefCell<Vec<u8>>>);

impl std::io::Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_bounded_run_streams_the_whole_bus_record_when_asked() {
    x10_sim::isolated(|| {
        let all = run("fig4_4", 3_000, Keep::All);
        let out = Shared::default();
        let config = SimConfig {
            duration_ms: 3_000,
            keep: Keep::Summary,
            ..SimConfig::default()
        };
        let streamed =
            examples::sim("fig4_4", config).map(|s| s.record_to(Box::new(out.clone())).run());
        let Some(Ok(streamed)) = streamed else {
            panic!("fig4_4 runs")
        };
        assert_eq!(streamed.record_errors, 0);
        assert!(streamed.records.is_empty());
        // The lines --trace prints for each transaction of the full record, in order.
        let names = ["mb".to_string(), "db09".to_string()];
        let bus_names = x10_sim::trace::BusNames {
            names: &names,
            mb_address: Some(0x08),
        };
        let mut want = String::new();
        for r in &all.records {
            let mut lines = x10_sim::trace::bus_lines(r, &bus_names);
            lines.sort_by_key(|l| l.t_ns);
            for l in lines {
                want.push_str(&format!("{l}\n"));
            }
        }
        let got = String::from_utf8(out.0.borrow().clone()).unwrap_or_default();
        assert!(got.lines().count() >= all.records.len());
        assert_eq!(got, want);
        // And they are the trace's own lines.
        let trace = all.trace.render();
        assert!(got.lines().all(|l| trace.contains(l)));
    });
}
