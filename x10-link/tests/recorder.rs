//! The motherboard's recorder and request server: records kept in order only while a laptop
//! listens, whole frames or nothing, drops counted exactly; requests answered through
//! `X10::call` on the simulated motherboard.

use x10_devices::LinkError;
use x10_link::recorder::{serve, Identity, Recorder};
use x10_link::{Feed, FrameReader, ToDevice, ToHost, WireOp, MAX_FRAME};
use x10_microcode::test_support::{a, s};
use x10_microcode::{Event, EventKind, Level, Op, Payload, Pin, PinRef, Status};
use x10_sim::ports::Change;
use x10_sim::sim::{Sim, SimConfig, X10};

/// Everything waiting, decoded (Rust's `Debug` form, one per frame).
fn drain<const N: usize>(rec: &Recorder<N>) -> Vec<String> {
    let mut out = Vec::new();
    let mut reader: FrameReader<{ MAX_FRAME }> = FrameReader::new();
    let mut buf = [0u8; 64];
    loop {
        let n = rec.take(&mut buf);
        if n == 0 {
            return out;
        }
        for &b in &buf[..n] {
            if reader.feed(b) == Feed::Frame {
                out.push(format!("{:?}", reader.decode::<ToHost>().unwrap()));
            }
        }
    }
}

fn duty() -> Op<'static> {
    Op::PwmDuty(a(1).pin(Pin::A), 127)
}

fn ok() -> Result<Payload, LinkError> {
    Ok(Payload::new())
}

#[test]
fn nothing_is_kept_while_nobody_listens_only_counted() {
    let rec: Recorder<256> = Recorder::new();
    rec.call(0, &duty(), &ok(), 10, 20);
    rec.call(9, &Op::AnalogRead(s(1)), &Err(LinkError::Nack), 30, 40);
    rec.log(b"hello");
    assert_eq!(rec.pending(), 0);
    let seen = rec.seen();
    assert_eq!((seen.calls, seen.events, seen.outputs), (2, 0, 1));
    assert_eq!(rec.boards().as_slice(), &[0, 9]);
    assert!(drain(&rec).is_empty());
}

#[test]
fn records_come_in_order_with_the_output_after_its_call() {
    let rec: Recorder<512> = Recorder::new();
    rec.set_listening(true);
    rec.call(0, &duty(), &ok(), 1_000_000, 1_000_450);
    let mut value = Payload::new();
    value.extend_from_slice(&[0x34, 0x12]).unwrap();
    rec.call(9, &Op::AnalogRead(s(1)), &Ok(value), 2_000, 2_900);
    rec.call(
        9,
        &Op::DigitalWrite(a(2).pin(Pin::B), Level::High),
        &Err(LinkError::Status(Status::PortOutOfRange)),
        3_000,
        3_100,
    );
    let ev = Event {
        source: x10_microcode::Address::new(9).unwrap(),
        kind: EventKind::PinChange,
        pin: PinRef::from_byte(0x80),
        seq: 4,
        status: Status::Ok,
        payload: &[1],
    };
    rec.event(&ev, 1_500_000);
    rec.log(&[0x01, 0x02]);
    assert_eq!(
        drain(&rec),
        [
            "Call(CallRec { db: 0, op: WireOp { fn_op: 32, port: 0, data: [127] }, outcome: Ok([]), start_us: 1000000, end_us: 1000450 })",
            "Output(OutputRec { db: 0, port: 0, value: Duty(127), at_us: 1000450 })",
            "Call(CallRec { db: 9, op: WireOp { fn_op: 48, port: 128, data: [] }, outcome: Ok([52, 18]), start_us: 2000, end_us: 2900 })",
            // A refused output is a call, not an output change.
            "Call(CallRec { db: 9, op: WireOp { fn_op: 18, port: 3, data: [] }, outcome: Err(Status(5)), start_us: 3000, end_us: 3100 })",
            "Event(EventRec { db: 9, kind: 1, port: 128, seq: 4, status: 0, payload: [1], at_us: 1500000 })",
            "Log([1, 2])",
        ]
    );
    assert_eq!(rec.dropped(), x10_link::Dropped::default());
}

#[test]
fn a_full_ring_drops_whole_records_and_reports_the_count_when_there_is_room() {
    // One pwm-duty call is an 18-byte call frame and a 12-byte output frame (docs/usb-link.md):
    // 64 bytes hold two calls and 4 bytes; the third call and its output are dropped whole.
    let rec: Recorder<64> = Recorder::new();
    rec.set_listening(true);
    for _ in 0..3 {
        rec.call(0, &duty(), &ok(), 1_000_000, 1_000_450);
    }
    assert_eq!(rec.pending(), 60);
    let d = rec.dropped();
    assert_eq!((d.calls, d.outputs, d.events, d.log_bytes), (1, 1, 0, 0));
    let frames = drain(&rec);
    assert_eq!(frames.len(), 5, "{frames:#?}");
    assert!(frames[0].starts_with("Call(") && frames[1].starts_with("Output("));
    assert!(frames[2].starts_with("Call(") && frames[3].starts_with("Output("));
    assert_eq!(
        frames[4],
        "Dropped(Dropped { calls: 1, events: 0, outputs: 1, log_bytes: 0, bad_frames: 0 })"
    );
    // Reported once: nothing more until the counters move again.
    assert!(drain(&rec).is_empty());
    rec.log(&[7u8; 100]);
    assert_eq!(rec.dropped().log_bytes, 100);
    assert_eq!(
        drain(&rec),
        ["Dropped(Dropped { calls: 1, events: 0, outputs: 1, log_bytes: 100, bad_frames: 0 })"]
    );
}

#[test]
fn bye_stops_the_records_and_empties_the_ring() {
    let rec: Recorder<256> = Recorder::new();
    rec.set_listening(true);
    rec.call(0, &duty(), &ok(), 1, 2);
    rec.set_listening(false);
    assert_eq!(rec.pending(), 0);
    rec.call(0, &duty(), &ok(), 3, 4);
    assert_eq!(rec.pending(), 0);
    assert_eq!(rec.seen().calls, 2);
}

static SERVED: Recorder<1024> = Recorder::new();

#[test]
fn laptop_requests_are_served_through_x10_call_on_the_motherboard() {
    let who = Identity {
        address: 8,
        board: "sim",
        robot: "test",
    };
    let config = SimConfig {
        duration_ms: 100,
        ..SimConfig::default()
    };
    let a1b = a(1).pin(Pin::B);
    let outcome = Sim::new(config)
        .with_robot("link", move |x10: X10| async move {
            let hello = x10_link::Hello {
                version: 1,
                address: 0,
                board: "x10",
                robot: "",
            };
            serve(&SERVED, x10, who, ToDevice::Hello(hello)).await;
            let high = Op::DigitalWrite(a1b, Level::High);
            let mut data = [0u8; 4];
            let n = high.emit_data(&mut data).unwrap();
            let op = WireOp {
                fn_op: high.fn_op_byte(),
                port: high.port_byte(),
                data: &data[..n],
            };
            serve(&SERVED, x10, who, ToDevice::Call { id: 7, db: 0, op }).await;
            // A board that does not exist, an address out of range, an op that does not parse.
            serve(&SERVED, x10, who, ToDevice::Call { id: 8, db: 200, op }).await;
            let bad = WireOp {
                fn_op: 0xff,
                port: 0,
                data: &[],
            };
            serve(
                &SERVED,
                x10,
                who,
                ToDevice::Call {
                    id: 9,
                    db: 0,
                    op: bad,
                },
            )
            .await;
            serve(&SERVED, x10, who, ToDevice::ListBoards { id: 10 }).await;
            serve(&SERVED, x10, who, ToDevice::Diagnostics { id: 11 }).await;
            Ok::<(), x10_devices::Error>(())
        })
        .run()
        .unwrap();
    let frames = drain(&SERVED);
    assert_eq!(frames.len(), 6, "{frames:#?}");
    assert_eq!(
        frames[..5],
        [
            "Hello(Hello { version: 2, address: 8, board: \"sim\", robot: \"test\" })",
            "Reply { id: 7, outcome: Ok([]) }",
            "Reply { id: 8, outcome: Err(BadAddress) }",
            "Reply { id: 9, outcome: Err(Invalid) }",
            // The simulator's observer is its tracer, so this recorder saw no call: board 0 only.
            "Boards { id: 10, addresses: [0] }",
        ]
    );
    // requests 1, completed 1, then zeros: the one call that reached the runtime.
    assert!(
        frames[5].starts_with("Diagnostics { id: 11, counters: [1, 1, 0, 0,"),
        "{}",
        frames[5]
    );
    // The call drove the pin.
    let levels: Vec<Change> = outcome.log.of("mb", a1b).iter().map(|c| c.change).collect();
    assert_eq!(levels.last(), Some(&Change::Digital(Level::High)));
}

#[test]
fn the_diagnostics_names_are_the_motherboards_counters_in_order() {
    // `MbDiagnostics`'s Debug lists its fields in declaration order.
    let d = firmware_mb::MbDiagnostics::default();
    let text = format!("{d:?}");
    let names: Vec<&str> = text
        .trim_start_matches("MbDiagnostics { ")
        .trim_end_matches(" }")
        .split(", ")
        .map(|f| f.split(':').next().unwrap())
        .collect();
    assert_eq!(names, x10_link::DIAG_NAMES);
    // And diag_counters gives one value per name.
    let counters = x10_link::recorder::diag_counters(&d);
    assert_eq!(counters.len(), x10_link::DIAG_NAMES.len());
}
