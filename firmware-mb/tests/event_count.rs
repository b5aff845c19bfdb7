//! Events never lost silently, as the MB counts them: a gap in a board's event counter is
//! counted in `event_gaps`, the drops the board reports in `events_lost`, from the cumulative
//! count of its `overflow` events, so a lost report loses no count.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use common::{Db, World};
use x10_microcode::{Pin, Port};

/// A pin-change event from DB 9 on S1A with the board's event counter at `seq`: level 1, one
/// rising edge.
fn pin_change(seq: u8) -> Vec<u8> {
    let pin = Port::sensor(1).unwrap().pin(Pin::A).to_byte();
    vec![
        0x09, 0x01, pin, seq, 0x00, 0x05, 0x01, 0x01, 0x00, 0x00, 0x00,
    ]
}

/// An overflow event from DB 9: `since_report` dropped since its last report, `total` since
/// its boot.
fn overflow(seq: u8, since_report: u16, total: u32) -> Vec<u8> {
    let mut f = vec![0x09, 0x06, 0x00, seq, 0x00, 0x06];
    f.extend_from_slice(&since_report.to_le_bytes());
    f.extend_from_slice(&total.to_le_bytes());
    f
}

/// DB 9's boot event (event counter 0).
fn boot(db9: &Db) -> Vec<u8> {
    common::boot_event(9, &db9.identity())
}

/// Writes `frames` to the MB as DB 9 would, 1 ms apart from 1 ms on (DB 9's own boot event,
/// counter 0, has gone out at 0); returns the MB's (event_gaps, events_lost, overflows,
/// events) once they have been routed.
fn deliver(w: &World, frames: Vec<Vec<u8>>) -> (u32, u32, u32, u32) {
    w.sim(async {
        let mut t = 0;
        for f in frames {
            t += 1_000;
            w.at(t).await;
            w.bus.to_mb(f);
        }
        w.at(t + 1_000).await;
        let d = w.mb.diagnostics();
        (d.event_gaps, d.events_lost, d.overflows, d.events)
    })
}

#[test]
fn gaps_in_a_boards_event_counter_are_counted() {
    let w = World::new();
    let rejected = vec![0x09, 0x05, 0x00, 0x42, 0x03, 0x00];
    let deferred = vec![0x09, 0x03, 0x80, 0x17, 0x00, 0x04, 0x10, 0x27, 0x00, 0x00];
    let frames = vec![
        pin_change(1),
        // 2 and 3 missing: 2 events the MB never heard of
        pin_change(4),
        // replies and refusals carry a request's sequence number: no gap, no restart
        rejected,
        deferred,
        pin_change(5),
        // a retransmission of 5 (its delivery was not seen by the board): no gap
        pin_change(5),
        // the board rebooted: its counter starts again at 0, no gap
        boot(&w.db9),
        pin_change(1),
        // 2 missing
        pin_change(3),
    ];
    let (gaps, lost, overflows, events) = deliver(&w, frames);
    assert_eq!(
        events,
        2 + 9,
        "the boot events of the MB's internal board and DB 9, 9 written"
    );
    assert_eq!((gaps, lost, overflows), (2 + 1, 0, 0));
}

#[test]
fn a_lost_overflow_report_loses_no_count() {
    let w = World::new();
    // The board's story (counter: 0 = its boot, at 0): event 1 delivered; 2 and 3 dropped,
    // reported by overflow 4 (2 since the last report, 2 since boot); 5..=7 dropped, reported
    // by overflow 8 (3, 5), which is itself lost on the bus; 9..=12 dropped, reported by
    // overflow 13 (4, 9); event 14 delivered.
    let frames = vec![
        pin_change(1),
        overflow(4, 2, 2),
        overflow(13, 4, 9),
        pin_change(14),
    ];
    let (gaps, lost, overflows, events) = deliver(&w, frames);
    // 9 events the board dropped, all reported (the lost report's 3 come with the next one),
    // and 10 numbers missing: the 9 drops and the lost report itself, which the MB counts as
    // a gap but cannot know more of. Lost silently: none.
    assert_eq!((lost, gaps, overflows, events), (9, 10, 2, 2 + 4));
}

#[test]
fn a_reboot_restarts_the_cumulative_count_and_old_firmware_reports_count_as_they_come() {
    let w = World::new();
    let frames = vec![
        overflow(2, 1, 1),
        // a report seen twice (retransmitted) adds nothing
        overflow(2, 1, 1),
        // after a reboot the board counts from 0 again: its first report counts whole
        boot(&w.db9),
        overflow(3, 2, 2),
        // a board of an earlier firmware reports only the drops since its last report (u16)
        vec![0x09, 0x06, 0x00, 0x06, 0x00, 0x02, 0x02, 0x00],
    ];
    let (gaps, lost, overflows, events) = deliver(&w, frames);
    assert_eq!((lost, overflows, events), (1 + 2 + 2, 4, 2 + 5));
    // missing numbers: 1 before the first report, 1 and 2 after the reboot, then 4 and 5
    assert_eq!(gaps, 1 + 2 + 2);
}
