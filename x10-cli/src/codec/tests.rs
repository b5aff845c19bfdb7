//! The codec's own cases: the operation table against the protocol crate, hex forms, encode
//! errors, reply context and PEC, and decode → encode round trips of generated frames.

use serde_json::json;
use x10_microcode::{Level, Port};

use super::words::{EVENT_VALUE_KEYS, REPLY_VALUE_KEYS};
use super::*;

fn op_info_of(op: &Op<'_>) -> Option<&'static OpInfo> {
    op_info(op.function().name(), op.name())
}

fn req_json(hex: &str) -> Value {
    decode(
        &parse_hex(hex).unwrap(),
        &DecodeOptions::new(FrameKind::Request),
    )
    .unwrap()
}

#[test]
fn op_table_agrees_with_the_protocol_crate() {
    let s1 = Port::sensor(1).unwrap();
    let a1 = Port::actuator(1).unwrap();
    let (mut b1, mut b2, mut b3) = ([0u8; 28], [0u8; 28], [0u8; 28]);
    let (mut b4, mut b5) = ([0u8; 28], [0u8; 28]);
    let ops = [
        Op::Ping,
        Op::Identify,
        Op::Heartbeat,
        Op::SetFailsafe { timeout_ms: 1 },
        Op::EventEnable(s1.pin(Pin::A), EventConfig::OFF),
        Op::ReadDiagnostics,
        Op::ClearDiagnostics,
        Op::SetPec(true),
        Op::Assign {
            uid: x10_microcode::Uid([1, 2, 3, 4, 5, 6, 7, 8]),
            address: x10_microcode::Address::new(0x20).unwrap(),
        },
        Op::SetAddress(x10_microcode::Address::new(0x21).unwrap()),
        Op::Blink(3),
        Op::WhoIsThere,
        Op::DigitalRead(s1.pin(Pin::A)),
        Op::DigitalWrite(a1.pin(Pin::A), Level::Low),
        Op::DigitalWrite(a1.pin(Pin::A), Level::High),
        Op::PulseIn {
            pin: s1.pin(Pin::A),
            edge: Edge::Rising,
            timeout_ms: None,
        },
        Op::PulseIn {
            pin: s1.pin(Pin::A),
            edge: Edge::Falling,
            timeout_ms: None,
        },
        Op::PwmDuty(a1.pin(Pin::A), 1),
        Op::PwmFrequency(a1, 1),
        Op::PwmPulseWidth(a1.pin(Pin::A), 1),
        Op::AnalogRead(s1),
        Op::SerialWrite(s1, b"x"),
        Op::SerialRead(s1, 1),
        Op::SerialConfig(s1, 1),
        Op::Scan,
        Op::EnterUpdate,
        Op::ConfirmFirmware,
        x10_microcode::UpdateOp::Begin(x10_microcode::ImageInfo {
            len: 1,
            crc32: 2,
            board: x10_microcode::BoardKind::PICO,
            version: [0, 1, 0],
        })
        .to_op(&mut b1),
        x10_microcode::UpdateOp::Chunk {
            offset: 0,
            data: b"x",
        }
        .to_op(&mut b2),
        x10_microcode::UpdateOp::Commit.to_op(&mut b3),
        x10_microcode::UpdateOp::Status.to_op(&mut b4),
        x10_microcode::UpdateOp::Leave.to_op(&mut b5),
        Op::Sample,
        Op::Apply,
    ];
    assert_eq!(ops.len() + 2, OPS.len()); // + batch and stage, checked below
    for op in ops {
        let info = op_info_of(&op).unwrap();
        assert_eq!(info.fn_op, op.fn_op_byte(), "{}", info.operation);
        assert_eq!(info.reply, op.expects_reply(), "{}", info.operation);
        let port = match op.pin_ref() {
            None => PortUse::Board,
            Some(_)
                if matches!(
                    op,
                    Op::PwmFrequency(..)
                        | Op::AnalogRead(_)
                        | Op::SerialWrite(..)
                        | Op::SerialRead(..)
                        | Op::SerialConfig(..)
                ) =>
            {
                PortUse::Port
            }
            Some(_) => PortUse::Pin,
        };
        assert_eq!(info.port, port, "{}", info.operation);
        // Every field the table names is in the decoded object.
        let m = object(op);
        for f in info.fields {
            assert!(m.contains_key(*f), "{} lacks {f}", info.operation);
        }
    }
    let batch = op_info("batch", "batch").unwrap();
    assert_eq!(batch.fn_op, 0x50);
    let stage = op_info("stage", "stage").unwrap();
    assert_eq!(stage.fn_op, 0x90);
    assert!(!stage.reply);
}

#[test]
fn hex_forms() {
    let want = vec![0x12, 0x09, 0x01, 0x02];
    for s in [
        "12090102",
        "12 09 01 02",
        "12:09:01:02",
        "0x12,0x09,0x01,0x02",
        " 1209 0102 ",
        "12-09-01-02",
        "12_09_01_02",
        "0X12 0X09 01 02",
    ] {
        assert_eq!(parse_hex(s), Ok(want.clone()), "{s}");
    }
    assert_eq!(to_hex(&want), "12 09 01 02");
    assert_eq!(
        parse_hex("12 9 01 02").unwrap_err().to_string(),
        "`9` has an odd number of hex digits"
    );
    assert_eq!(
        parse_hex("12 0g").unwrap_err().to_string(),
        "`g` is not a hex digit (in `0g`)"
    );
    assert_eq!(parse_hex("").unwrap_err().to_string(), "no bytes given");
    assert_eq!(
        parse_hex("0x").unwrap_err().to_string(),
        "`0x` has an odd number of hex digits"
    );
    assert_eq!(
        split_prefix("reply:01 00 00"),
        (Some(FrameKind::Reply), "01 00 00")
    );
    assert_eq!(split_prefix("event: 09"), (Some(FrameKind::Event), " 09"));
    assert_eq!(split_prefix("12:09"), (None, "12:09"));
    let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    // Single bytes are one frame; anything else is one frame per argument.
    assert_eq!(
        frames_of_args(args(&["12", "09", "0x1", "0X02"])),
        ["12 09 01 02"]
    );
    assert_eq!(
        frames_of_args(args(&["reply:04", "00", "02", "00", "02"])),
        ["reply:04 00 02 00 02"]
    );
    for unchanged in [
        &["12"][..],
        &["12090102", "30098004"],
        &["12", "09", "01", "0102"],
        &["12", "09", "01", "zz"],
        &["12", "reply:09"],
        &["12", "0x"],
    ] {
        assert_eq!(frames_of_args(args(unchanged)), args(unchanged));
    }
    assert!(frames_of_args(Vec::new()).is_empty());
    assert_eq!(parse_address("0x09").unwrap().get(), 9);
    assert_eq!(parse_address("16").unwrap().get(), 16);
    assert!(parse_address("0x78").is_err());
    assert!(parse_address("x").is_err());
}

#[test]
fn decode_issue_example() {
    let v = req_json("12 09 01 02");
    assert_eq!(
        v,
        json!({"kind": "request", "function": "io", "operation": "high", "db": 9,
               "port_kind": "actuator", "port": 1, "pin": "B", "seq": 2, "data": []})
    );
    assert_eq!(
        describe(&v),
        "request to DB 0x09 seq 2: io high on actuator port 1 pin B"
    );
    assert_eq!(encode(&v), Ok(vec![0x12, 0x09, 0x01, 0x02]));
}

#[test]
fn encode_from_fields_without_data() {
    let v = json!({"kind": "request", "function": "pwm", "operation": "duty", "db": "0x09",
                   "port_kind": "actuator", "port": 1, "pin": "B", "seq": 3, "duty": 128});
    assert_eq!(encode(&v), Ok(vec![0x20, 0x09, 0x01, 0x03, 0x80]));
    // `kind` defaults to request, `pin` to A.
    let v = json!({"function": "analog", "operation": "read", "db": 9,
                   "port_kind": "sensor", "port": 1, "seq": 4});
    assert_eq!(encode(&v), Ok(vec![0x30, 0x09, 0x80, 0x04]));
    let v = json!({"function": "batch", "operation": "batch", "db": 9, "seq": 0x12,
    "items": [
        {"function": "io", "operation": "high", "port_kind": "actuator", "port": 1, "pin": "B"},
        {"function": "pwm", "operation": "duty", "port_kind": "actuator", "port": 1, "duty": 200},
        {"function": "analog", "operation": "read", "port_kind": "sensor", "port": 1}
    ]});
    assert_eq!(
        encode(&v).map(|b| to_hex(&b)),
        Ok("50 09 00 12 12 01 00 20 00 01 c8 30 80 00".to_string())
    );
}

#[test]
fn encode_errors() {
    let cases = [
        (json!([1]), "expected a JSON object, got [1]"),
        (json!({"kind": "frame"}), "unknown kind `frame` (request, reply or event)"),
        (json!({"function": "io"}), "`operation` is required"),
        (
            json!({"function": "io", "operation": "toggle"}),
            "unknown operation `toggle` of io (known: input, low, high, pulse_in_rising, pulse_in_falling)",
        ),
        (json!({"function": "gpio", "operation": "x"}), "unknown function `gpio`"),
        (
            json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                   "port_kind": "actuator", "port": 1, "colour": "red"}),
            "unknown key `colour` for io high",
        ),
        (
            json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                   "port_kind": "actuator", "port": 1, "duty": 3}),
            "unknown key `duty` for io high",
        ),
        (
            json!({"function": "io", "operation": "high", "db": 300, "seq": 1,
                   "port_kind": "actuator", "port": 1}),
            "`db` must be an integer 0..=255, got 300",
        ),
        (
            json!({"function": "io", "operation": "high", "db": 5, "seq": 1,
                   "port_kind": "actuator", "port": 1}),
            "invalid request: bad daughterboard address 0x05 (a board answers status wrong_address)",
        ),
        (
            json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                   "port_kind": "actuator", "port": 65}),
            "`port` must be 1..=64, got 65",
        ),
        (
            json!({"function": "io", "operation": "high", "db": 9, "seq": 1,
                   "port_kind": "motor", "port": 1}),
            "`port_kind` must be \"actuator\" or \"sensor\", got \"motor\"",
        ),
        (
            json!({"function": "io", "operation": "high", "db": 9, "seq": -1,
                   "port_kind": "actuator", "port": 1}),
            "`seq` must be an integer 0..=255, got -1",
        ),
        (
            json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                   "port_kind": "actuator", "port": 1, "duty": 256}),
            "`duty` must be an integer 0..=255, got 256",
        ),
        (
            json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                   "port_kind": "actuator", "port": 1}),
            "`duty` is required for pwm duty",
        ),
        (
            json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                   "port_kind": "sensor", "port": 1, "duty": 3}),
            "invalid request: operation not available on this kind of port (a board answers status wrong_port_kind)",
        ),
        (
            json!({"function": "pwm", "operation": "duty", "db": 9, "seq": 1,
                   "port_kind": "actuator", "port": 1, "duty": 3, "data": [4]}),
            "`duty` is 3 but the frame says 4",
        ),
        (
            json!({"function": "system", "operation": "ping", "db": 9, "seq": 1, "port": 2}),
            "system ping is addressed to the whole board: `port_kind`, `port` and `pin` must be null or absent",
        ),
        (
            json!({"kind": "reply", "seq": 1, "status": "fine"}),
            "unknown status `fine`",
        ),
        (
            json!({"kind": "reply", "seq": 1, "payload": vec![0u8; 29]}),
            "invalid reply: data or payload too long (a board answers status bad_length)",
        ),
        (
            json!({"kind": "reply", "seq": 1, "answers": "io.high"}),
            "io.high has no reply",
        ),
        (
            json!({"kind": "reply", "seq": 1, "answers": "io.input", "payload": [1, 2], "level": 1}),
            "unknown key `level`",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "pin_change", "seq": 1, "pec": 3}),
            "`pec` needs `pec_addr` (the address it covers)",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "boom", "seq": 1}),
            "unknown event kind `boom`",
        ),
        (
            json!({"kind": "event", "source": 3, "event": "boot", "seq": 0}),
            "bad daughterboard address 0x03",
        ),
        (
            json!({"kind": "request", "function": "io", "operation": "high", "db": 9, "seq": 2,
                   "port_kind": "actuator", "port": 1, "pin": "B", "pec_addr": 9, "pec": 1}),
            "`pec` is 1 but the frame says 156",
        ),
    ];
    for (v, msg) in cases {
        assert_eq!(encode(&v).unwrap_err().to_string(), msg, "{v}");
    }
}

#[test]
fn reply_context_and_pec() {
    let mut opts = DecodeOptions::new(FrameKind::Reply);
    opts.answers = Some(Answers::parse("analog.read").unwrap());
    opts.pec = Some(Address::new(9).unwrap());
    let bytes = parse_hex("04 00 02 00 02").unwrap();
    let mut framed = bytes.clone();
    framed.push(pec::compute(0x13, &bytes));
    let v = decode(&framed, &opts).unwrap();
    assert_eq!(v["value"], json!(512));
    assert_eq!(v["pec_addr"], json!(9));
    assert_eq!(encode(&v), Ok(framed.clone()));
    assert_eq!(
        describe(&v),
        format!(
            "reply seq 4 to analog.read: ok, value 512 [PEC {:#04x} ok, address 0x09]",
            framed[5]
        )
    );
    // The context of a decoded batch request carries its items.
    let req = req_json("50 09 00 12 12 01 00 20 00 01 c8 30 80 00");
    let a = Answers::of_request(&req).unwrap();
    assert_eq!(a.name, "batch.batch");
    assert_eq!(
        a.items,
        ["io.high", "pwm.duty", "analog.read"].map(|s| Some(s.to_string()))
    );
    let mut opts = DecodeOptions::new(FrameKind::Reply);
    opts.answers = Some(a);
    let v = decode(
        &parse_hex("12 00 08 00 00 00 00 00 02 00 02").unwrap(),
        &opts,
    )
    .unwrap();
    assert_eq!(v["results"][2]["value"], json!(512));
    assert_eq!(v["results"][2]["answers"], json!("analog.read"));
    assert_eq!(
        encode(&v).map(|b| to_hex(&b)),
        Ok("12 00 08 00 00 00 00 00 02 00 02".into())
    );
    // Requests without a reply give no context.
    assert_eq!(Answers::of_request(&req_json("12 09 01 02")), None);
    // A wrong PEC is refused.
    let mut bad = framed;
    bad[5] ^= 1;
    let mut opts = DecodeOptions::new(FrameKind::Reply);
    opts.pec = Some(Address::new(9).unwrap());
    assert!(decode(&bad, &opts)
        .unwrap_err()
        .to_string()
        .starts_with("invalid reply: PEC mismatch"));
}

/// Removes `data` / `payload` wherever the decoded fields say the same, so that `encode`
/// has to rebuild them.
fn strip_raw(v: &mut Value) {
    let Some(o) = v.as_object_mut() else { return };
    let is_serial_write =
        o.get("function") == Some(&json!("serial")) && o.get("operation") == Some(&json!("write"));
    if o.contains_key("function") && !is_serial_write {
        o.remove("data");
    }
    if let Some(Value::Array(items)) = o.get_mut("items") {
        items.iter_mut().for_each(strip_raw);
    }
    if let Some(Value::Array(results)) = o.get_mut("results") {
        for r in results.iter_mut() {
            let decoded = REPLY_VALUE_KEYS.iter().any(|k| r.get(*k).is_some());
            if let Some(ro) = r.as_object_mut() {
                if decoded || ro.get("payload") == Some(&json!([])) {
                    ro.remove("payload");
                }
            }
        }
    }
    let decoded = REPLY_VALUE_KEYS
        .iter()
        .chain(EVENT_VALUE_KEYS)
        .chain(&["results"])
        .any(|k| o.contains_key(*k));
    if decoded || o.get("payload") == Some(&json!([])) {
        o.remove("payload");
    }
}

fn frame_strategy(
) -> impl proptest::strategy::Strategy<Value = (FrameKind, Vec<u8>, Option<String>)> {
    use proptest::prelude::*;
    let request = (
        proptest::sample::select(OPS.iter().map(|o| o.fn_op).collect::<Vec<_>>()),
        prop_oneof![Just(9u8), Just(0u8), any::<u8>()],
        prop_oneof![Just(0u8), any::<u8>()],
        any::<u8>(),
        proptest::collection::vec(any::<u8>(), 0..8),
    )
        .prop_map(|(f, db, port, seq, data)| {
            let mut v = vec![f, db, port, seq];
            v.extend(data);
            (FrameKind::Request, v, None)
        });
    let names: Vec<String> = OPS
        .iter()
        .filter(|o| o.reply)
        .map(|o| format!("{}.{}", o.function, o.operation))
        .collect();
    let reply = (
        any::<u8>(),
        prop_oneof![4 => Just(0u8), 1 => any::<u8>()],
        prop_oneof![
            Just(vec![1u8]),
            Just(vec![0u8, 2]),
            proptest::collection::vec(any::<u8>(), 10..=10),
            proptest::collection::vec(any::<u8>(), 28..=28),
            proptest::collection::vec(any::<u8>(), 0..=28),
            Just(vec![0u8, 0, 0, 0, 0, 2, 7, 1]),
            Just(vec![4u8, 0x96, 0, 1, 0, 2, 0, 3, 0, 4, 0]),
        ],
        proptest::option::of(proptest::sample::select(names)),
    )
        .prop_map(|(seq, status, payload, answers)| {
            let mut v = vec![seq, status, payload.len() as u8];
            v.extend(payload);
            (FrameKind::Reply, v, answers)
        });
    let event = (
        prop_oneof![Just(9u8), Just(0u8), any::<u8>()],
        prop_oneof![4 => 1u8..=7, 1 => any::<u8>()],
        prop_oneof![Just(0u8), any::<u8>()],
        any::<u8>(),
        prop_oneof![4 => Just(0u8), 1 => any::<u8>()],
        prop_oneof![
            proptest::collection::vec(any::<u8>(), 0..=4),
            Just(vec![0x89u8, 3, 1]),
            proptest::collection::vec(any::<u8>(), 10..=10),
        ],
    )
        .prop_map(|(src, kind, port, seq, status, payload)| {
            let mut v = vec![src, kind, port, seq, status, payload.len() as u8];
            v.extend(payload);
            (FrameKind::Event, v, None)
        });
    prop_oneof![request, reply, event]
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(3000))]

    /// decode → encode gives the same bytes, with and without PEC, and so does encoding
    /// from the decoded fields alone (raw `data`/`payload` removed).
    #[test]
    fn decode_encode_roundtrip((kind, bytes, answers) in frame_strategy(),
                               with_pec in proptest::prelude::any::<bool>()) {
        let mut opts = DecodeOptions::new(kind);
        opts.answers = answers.map(|a| Answers::parse(&a).unwrap());
        let mut framed = bytes.clone();
        if with_pec {
            let addr = Address::new(0x09).unwrap();
            framed.push(pec::compute(addr.addr_byte(kind == FrameKind::Reply), &bytes));
            opts.pec = Some(addr);
        }
        if let Ok(v) = decode(&framed, &opts) {
            proptest::prop_assert_eq!(encode(&v), Ok(framed.clone()), "{}", v);
            let mut stripped = v.clone();
            strip_raw(&mut stripped);
            proptest::prop_assert_eq!(encode(&stripped), Ok(framed.clone()), "{}", stripped);
            // Words never fail.
            proptest::prop_assert!(!describe(&v).is_empty());
        }
    }

    /// Arbitrary JSON-ish objects never panic the encoder.
    #[test]
    fn encode_arbitrary_objects(keys in proptest::collection::vec(
        (proptest::sample::select(vec!["kind", "function", "operation", "db", "port_kind",
            "port", "pin", "seq", "data", "payload", "status", "answers", "results", "items",
            "event", "source", "identity", "scan", "pec_addr", "pec", "duty", "level"]),
         0u8..8), 0..10)) {
        let samples = [json!(null), json!(9), json!("io"), json!([1, 2]), json!({}),
                       json!(-1), json!("reply"), json!([{"function": "io"}])];
        let mut o = Map::new();
        for (k, i) in keys {
            o.insert(k.to_string(), samples[i as usize].clone());
        }
        let _ = encode(&Value::Object(o));
    }
}

#[test]
fn encode_replies_and_events_from_fields() {
    let cases = [
        (
            json!({"kind": "reply", "seq": 18, "answers": "batch.batch", "results": [
                {"status": "ok"}, {"status": "ok"},
                {"status": "ok", "answers": "analog.read", "value": 512}]}),
            "12 00 08 00 00 00 00 00 02 00 02",
        ),
        (
            json!({"kind": "reply", "seq": 2, "answers": "system.identify", "identity": {
                "protocol_version": 1, "firmware": [0, 1, 0], "board": "pico",
                "sensor_ports": 4, "actuator_ports": 4, "capabilities": 511, "adc_bits": 12}}),
            "02 00 0a 01 00 01 00 03 04 04 ff 01 0c",
        ),
        (
            json!({"kind": "reply", "seq": 19, "answers": "scan.scan",
                   "scan": {"ports": 2, "digital": 6, "analog": [100, 200]}}),
            "13 00 07 02 06 00 64 00 c8 00",
        ),
        (
            json!({"kind": "reply", "seq": 6, "answers": "system.read_diagnostics",
                   "diagnostics": {"frames_ok": 1000, "pec_errors": 5}}),
            "06 00 1c e8 03 00 00 00 00 00 00 00 00 00 00 05 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00",
        ),
        (json!({"kind": "reply", "seq": 11, "status": "pending"}), "0b 01 00"),
        (json!({"kind": "reply", "seq": 7, "status": 66}), "07 42 00"),
        (
            json!({"kind": "event", "source": 9, "event": "pin_change", "port_kind": "sensor",
                   "port": 1, "pin": "A", "seq": 7, "level": 1}),
            "09 01 80 07 00 01 01",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "analog_threshold",
                   "port_kind": "sensor", "port": 2, "seq": 8, "value": 905, "inside": false}),
            "09 02 82 08 00 03 89 03 00",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "deferred_reply",
                   "port_kind": "sensor", "port": 3, "pin": "B", "seq": 11, "width_us": 1520}),
            "09 03 85 0b 00 04 f0 05 00 00",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "failsafe_tripped", "seq": 9,
                   "timeout_ms": 500}),
            "09 04 00 09 00 02 f4 01",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "overflow", "seq": 10, "dropped": 3}),
            "09 06 00 0a 00 02 03 00",
        ),
        (
            json!({"kind": "event", "source": 0, "event": 32, "seq": 11}),
            "00 20 00 0b 00 00",
        ),
        (
            json!({"kind": "event", "source": 9, "event": "pin_change", "port_kind": "sensor",
                   "port": 1, "seq": 7, "level": 1, "pec_addr": 16}),
            "09 01 80 07 00 01 01 95",
        ),
    ];
    for (v, hex) in cases {
        assert_eq!(encode(&v).map(|b| to_hex(&b)), Ok(hex.to_string()), "{v}");
    }
}
