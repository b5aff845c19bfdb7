//! docs/performance.md's latency table is the one `x10 report` prints, byte for byte (issue 23
//! item 9: a figure in the docs comes from one place that a command regenerates). Paste the
//! new table from `cargo x10 report` when this fails.

/// The default number of calls per operation (`x10 report` without `--samples`).
const SAMPLES: u32 = 20;

#[test]
fn the_latency_table_in_the_docs_is_the_one_x10_report_prints() {
    let doc = include_str!("../../docs/performance.md");
    let start = doc
        .find("\nX10 latency per call")
        .expect("the table in docs/performance.md")
        + 1;
    let end = start
        + doc[start..]
            .find("\n```")
            .expect("the end of the table's block")
        + 1;
    let table = x10_cli::report::latency_table(SAMPLES).expect("the report runs");
    assert_eq!(&doc[start..end], table);
}
