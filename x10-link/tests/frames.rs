//! The frames of docs/usb-link.md: every example there decodes to its message and encodes
//! back to the same bytes, every message kind has an example, and no bytes make a decoder
//! panic.

use proptest::prelude::*;
use x10_link::{
    decode, encode, encode_host, read_to_device, write_to_host, AssignStatus, BoardEntry,
    BoardState, CallError, CallRec, DiagCounters, Dropped, EventRec, Feed, FrameError, FrameReader,
    Hello, Outcome, OutputRec, OutputValue, ToDevice, ToHost, UpdateFailure, UpdatePhase,
    UpdateRec, UpdateStatus, WireOp, MAX_FRAME,
};
use x10_microcode::test_support::{a, s};
use x10_microcode::{EventKind, Level, Op, Pin};

const DOC: &str = include_str!("../../docs/usb-link.md");

fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn unhex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|h| u8::from_str_radix(h, 16).unwrap())
        .collect()
}

fn frame<T: serde::Serialize>(m: &T) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode(m, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// `op` as the link carries it: its byte 0, byte 2 and data (`buf` holds the data).
fn wire<'a>(op: &Op<'_>, buf: &'a mut [u8; 8]) -> WireOp<'a> {
    let n = op.emit_data(buf).unwrap();
    WireOp {
        fn_op: op.fn_op_byte(),
        port: op.port_byte(),
        data: &buf[..n],
    }
}

/// A board's unique ID in the examples (docs/protocol.md's).
const UID: [u8; 8] = [0xe6, 0x61, 0x38, 0x52, 0x83, 0x3f, 0x5c, 0x2a];

/// One message of each kind, each way.
fn examples() -> Vec<(&'static str, String, Vec<u8>)> {
    // pwm duty A1.A 127 on the motherboard's own ports; io high A1.B; analog read S1.
    let (mut b1, mut b2, mut b3) = ([0u8; 8], [0u8; 8], [0u8; 8]);
    let duty = wire(&Op::PwmDuty(a(1).pin(Pin::A), 127), &mut b1);
    let high = wire(&Op::DigitalWrite(a(1).pin(Pin::B), Level::High), &mut b2);
    let analog = wire(&Op::AnalogRead(s(1)), &mut b3);
    let mut counters = DiagCounters::new();
    for c in [12, 12, 0, 0] {
        counters.push(c).unwrap();
    }
    let to_host = [
        ToHost::Hello(Hello {
            version: 2,
            address: 8,
            board: "Pico",
            robot: "fig4_4",
        }),
        ToHost::Log(&[0x01, 0x02, 0x00, 0x03]),
        ToHost::Call(CallRec {
            db: 0,
            op: duty,
            outcome: Outcome::Ok(&[]),
            start_us: 1_000_000,
            end_us: 1_000_450,
        }),
        ToHost::Call(CallRec {
            db: 9,
            op: analog,
            outcome: Outcome::Err(CallError::Status(5)),
            start_us: 2_000,
            end_us: 2_900,
        }),
        ToHost::Event(EventRec {
            db: 9,
            kind: EventKind::PinChange.to_byte(),
            port: s(1).pin(Pin::A).to_byte(),
            seq: 4,
            status: 0,
            payload: &[1],
            at_us: 1_500_000,
        }),
        ToHost::Output(OutputRec {
            db: 0,
            port: duty.port,
            value: OutputValue::Duty(127),
            at_us: 1_000_450,
        }),
        ToHost::Output(OutputRec {
            db: 0,
            port: high.port,
            value: OutputValue::Level(true),
            at_us: 1_000_900,
        }),
        ToHost::Dropped(Dropped {
            calls: 3,
            events: 0,
            outputs: 2,
            log_bytes: 0,
            bad_frames: 1,
        }),
        ToHost::Reply {
            id: 7,
            outcome: Outcome::Ok(&[0x02, 0x00]),
        },
        ToHost::Diagnostics { id: 8, counters },
        ToHost::Boards {
            id: 9,
            addresses: heapless::Vec::from_slice(&[0, 9]).unwrap(),
        },
        ToHost::Refused { id: 10 },
        ToHost::BoardList {
            id: 11,
            total: 2,
            first: 0,
            boards: heapless::Vec::from_slice(&[
                BoardEntry {
                    address: 0x20,
                    uid: UID,
                    kind: 3,
                    firmware: [0, 1, 0],
                    state: BoardState::Present,
                },
                BoardEntry {
                    address: 0x31,
                    uid: [9, 8, 7, 6, 5, 4, 3, 2],
                    kind: 5,
                    firmware: [2, 0, 0],
                    state: BoardState::Lost,
                },
            ])
            .unwrap(),
        },
        ToHost::Assigned {
            id: 12,
            status: AssignStatus::Done,
        },
        ToHost::Assigned {
            id: 13,
            status: AssignStatus::NotConfirmed(CallError::Timeout),
        },
        ToHost::UpdateAnswer {
            id: 14,
            status: UpdateStatus::Started(1),
        },
        ToHost::UpdateAnswer {
            id: 15,
            status: UpdateStatus::Busy(0x20),
        },
        ToHost::Update(UpdateRec {
            db: 0x20,
            from: [0, 1, 0],
            to: [2, 0, 0],
            phase: UpdatePhase::Started,
            at_us: 2_000_000,
        }),
        ToHost::Update(UpdateRec {
            db: 0x20,
            from: [0, 1, 0],
            to: [2, 0, 0],
            phase: UpdatePhase::Failed(UpdateFailure::RolledBack),
            at_us: 17_000_000,
        }),
    ];
    let to_device = [
        ToDevice::Hello(Hello {
            version: 2,
            address: 0,
            board: "x10",
            robot: "",
        }),
        ToDevice::Bye,
        ToDevice::Call {
            id: 7,
            db: 0,
            op: high,
        },
        ToDevice::Diagnostics { id: 8 },
        ToDevice::ListBoards { id: 9 },
        ToDevice::Boards { id: 11, first: 0 },
        ToDevice::Assign {
            id: 12,
            uid: UID,
            address: 0x40,
        },
        ToDevice::Update {
            id: 14,
            uid: Some(UID),
        },
        ToDevice::Update { id: 16, uid: None },
    ];
    let mut v = Vec::new();
    for m in &to_host {
        v.push(("ToHost", format!("{m:?}"), frame(m)));
    }
    for m in &to_device {
        v.push(("ToDevice", format!("{m:?}"), frame(m)));
    }
    v
}

/// The doc's example rows: `| ToHost | `Debug` | `bytes` |`.
fn doc_rows() -> Vec<(String, String, Vec<u8>)> {
    DOC.lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            if cells.len() < 5 || !(cells[1] == "ToHost" || cells[1] == "ToDevice") {
                return None;
            }
            let debug = cells[2].trim_matches('`').to_string();
            let bytes = unhex(cells[3].trim_matches('`'));
            Some((cells[1].to_string(), debug, bytes))
        })
        .collect()
}

#[test]
fn every_example_is_in_the_doc() {
    let rows = doc_rows();
    let missing: Vec<String> = examples()
        .into_iter()
        .filter(|(dir, debug, bytes)| {
            !rows
                .iter()
                .any(|(d, m, b)| d == dir && m == debug && b == bytes)
        })
        .map(|(dir, debug, bytes)| format!("| {dir} | `{debug}` | `{}` |", hex(&bytes)))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/usb-link.md lacks the rows\n{}",
        missing.join("\n")
    );
}

#[test]
fn every_doc_row_decodes_exactly_and_encodes_back() {
    let rows = doc_rows();
    assert_eq!(rows.len(), examples().len());
    for (dir, debug, bytes) in rows {
        let mut copy = bytes.clone();
        let got = if dir == "ToHost" {
            let m: ToHost = decode(&mut copy).unwrap();
            assert_eq!(frame(&m), bytes);
            format!("{m:?}")
        } else {
            let m: ToDevice = decode(&mut copy).unwrap();
            assert_eq!(frame(&m), bytes);
            format!("{m:?}")
        };
        assert_eq!(got, debug);
        assert_eq!(*bytes.last().unwrap(), 0);
        assert!(!bytes[..bytes.len() - 1].contains(&0));
    }
}

/// The motherboard's hand-written encoder and decoder (no serde) against serde's postcard.
#[test]
fn the_motherboards_own_codec_gives_every_doc_row_exactly() {
    for (dir, debug, bytes) in doc_rows() {
        let mut copy = bytes.clone();
        if dir == "ToHost" {
            let m: ToHost = decode(&mut copy).unwrap();
            let mut buf = [0u8; MAX_FRAME];
            let n = encode_host(&m, &mut buf).unwrap();
            assert_eq!(&buf[..n], &bytes[..], "{debug}");
        } else {
            let mut r: FrameReader<{ MAX_FRAME }> = FrameReader::new();
            let mut got = None;
            for &b in &bytes {
                if r.feed(b) == Feed::Frame {
                    got = Some(format!("{:?}", r.decode_device().unwrap()));
                }
            }
            // The hello's names are skipped, not read (`read_to_device`).
            let want = debug.replace("board: \"x10\"", "board: \"\"");
            assert_eq!(got.as_deref(), Some(want.as_str()));
        }
    }
    // Too long for the buffer: refused, as postcard refuses it.
    let mut short = [0u8; 3];
    assert_eq!(write_to_host(&ToHost::Log(&[1, 2, 3]), &mut short), None);
    assert_eq!(
        write_to_host(&ToHost::Refused { id: 10 }, &mut short),
        Some(2)
    );
}

/// `ToDevice::Hello` with its names as any bytes (postcard writes a `str` as a byte slice).
#[derive(serde::Deserialize)]
enum HelloBytes<'a> {
    Hello {
        version: u16,
        address: u8,
        #[allow(dead_code)]
        #[serde(borrow)]
        board: &'a [u8],
        #[allow(dead_code)]
        #[serde(borrow)]
        robot: &'a [u8],
    },
}

/// The messages proptest draws for the codec's comparison.
fn to_host_of(k: u8, a: u8, n: u64, bytes: &[u8], text: &str) -> ToHost<'static> {
    let bytes: &'static [u8] = Vec::leak(bytes.to_vec());
    let text: &'static str = String::leak(text.to_string());
    let errors = [
        CallError::Nack,
        CallError::Timeout,
        CallError::ArbitrationLost,
        CallError::Bus,
        CallError::BadReply,
        CallError::Status(a),
        CallError::Invalid,
        CallError::Busy,
        CallError::Unsupported,
        CallError::BadAddress,
        CallError::Updating,
    ];
    let outcome = if n % 12 == 11 {
        Outcome::Ok(bytes)
    } else {
        Outcome::Err(errors[(n % 12) as usize])
    };
    let small = (n & 0xffff) as u16;
    let mut counters = DiagCounters::new();
    let mut addresses = heapless::Vec::new();
    for (i, &b) in bytes.iter().enumerate() {
        let _ = counters.push(u32::from(b) << (i % 25));
        let _ = addresses.push(b);
    }
    match k % 14 {
        0 => ToHost::Hello(Hello {
            version: small,
            address: a,
            board: text,
            robot: text,
        }),
        1 => ToHost::Log(bytes),
        2 => ToHost::Call(CallRec {
            db: a,
            op: WireOp {
                fn_op: a ^ 0x55,
                port: a.wrapping_add(3),
                data: bytes,
            },
            outcome,
            start_us: n,
            end_us: n.rotate_left(17),
        }),
        3 => ToHost::Event(EventRec {
            db: a,
            kind: a ^ 1,
            port: a ^ 2,
            seq: a ^ 3,
            status: a ^ 4,
            payload: bytes,
            at_us: n,
        }),
        4 => ToHost::Output(OutputRec {
            db: a,
            port: a ^ 7,
            value: match n % 4 {
                0 => OutputValue::Level(a & 1 == 1),
                1 => OutputValue::Duty(a),
                2 => OutputValue::FrequencyHz((n >> 8) as u32),
                _ => OutputValue::PulseWidthUs(small),
            },
            at_us: n >> 3,
        }),
        5 => ToHost::Dropped(Dropped {
            calls: n as u32,
            events: (n >> 7) as u32,
            outputs: (n >> 14) as u32,
            log_bytes: (n >> 21) as u32,
            bad_frames: (n >> 32) as u32,
        }),
        6 => ToHost::Reply { id: small, outcome },
        7 => ToHost::Diagnostics {
            id: small,
            counters,
        },
        8 => ToHost::Boards {
            id: small,
            addresses,
        },
        9 => ToHost::Refused { id: small },
        10 => ToHost::BoardList {
            id: small,
            total: a,
            first: a ^ 3,
            boards: bytes
                .chunks(8)
                .take(8)
                .map(|c| BoardEntry {
                    address: c[0],
                    uid: [c[0], a, 1, 2, 3, 4, 5, c[c.len() - 1]],
                    kind: a,
                    firmware: [c[0], a, (n >> 8) as u8],
                    state: [
                        BoardState::Present,
                        BoardState::Lost,
                        BoardState::Updating,
                        BoardState::Collided,
                    ][usize::from(c[0] % 4)],
                })
                .collect(),
        },
        11 => ToHost::Assigned {
            id: small,
            status: match a % 6 {
                0 => AssignStatus::Done,
                1 => AssignStatus::UnknownUid,
                2 => AssignStatus::Reserved,
                3 => AssignStatus::Taken,
                4 => AssignStatus::Collided,
                _ => AssignStatus::NotConfirmed(errors[(n % 11) as usize]),
            },
        },
        12 => ToHost::UpdateAnswer {
            id: small,
            status: match n % 7 {
                0 => UpdateStatus::Started(a),
                1 => UpdateStatus::NoImages,
                2 => UpdateStatus::UnknownUid,
                3 => UpdateStatus::NotPresent,
                4 => UpdateStatus::NoImage,
                5 => UpdateStatus::UpToDate,
                _ => UpdateStatus::Busy(a),
            },
        },
        _ => ToHost::Update(UpdateRec {
            db: a,
            from: [a, 1, 2],
            to: [(n >> 8) as u8, 0, a ^ 9],
            phase: match n % 11 {
                0 => UpdatePhase::Started,
                1 => UpdatePhase::Done,
                2 => UpdatePhase::Failed(UpdateFailure::NoMethod),
                3 => UpdatePhase::Failed(UpdateFailure::Enter),
                4 => UpdatePhase::Failed(UpdateFailure::NoBootloader),
                5 => UpdatePhase::Failed(UpdateFailure::Refused),
                6 => UpdatePhase::Failed(UpdateFailure::Link),
                7 => UpdatePhase::Failed(UpdateFailure::NotBack),
                8 => UpdatePhase::Failed(UpdateFailure::RolledBack),
                _ => UpdatePhase::Failed(UpdateFailure::Rom),
            },
            at_us: n,
        }),
    }
}

#[test]
fn a_reader_in_the_middle_of_a_stream_resyncs_at_the_next_zero() {
    let a = frame(&ToDevice::Diagnostics { id: 1 });
    let b = frame(&ToDevice::ListBoards { id: 2 });
    let mut stream = a[2..].to_vec(); // the tail of a frame
    stream.extend_from_slice(&b);
    let mut r: FrameReader<64> = FrameReader::new();
    let mut got = Vec::new();
    for &x in &stream {
        if r.feed(x) == Feed::Frame {
            got.push(r.decode::<ToDevice>().map(|m| format!("{m:?}")));
        }
    }
    assert_eq!(
        got,
        vec![
            Err(FrameError::Cobs),
            Ok("ListBoards { id: 2 }".to_string())
        ]
    );
}

#[test]
fn a_flipped_bit_is_a_crc_error() {
    let mut f = frame(&ToDevice::Diagnostics { id: 0x1234 });
    f[3] ^= 0x04;
    assert_eq!(decode::<ToDevice>(&mut f), Err(FrameError::Crc));
}

#[test]
fn a_frame_longer_than_the_reader_is_skipped_and_reported() {
    let mut r: FrameReader<4> = FrameReader::new();
    let mut seen = Vec::new();
    for &x in &[1u8, 2, 3, 4, 5, 6, 0] {
        seen.push(r.feed(x));
    }
    assert_eq!(seen.last(), Some(&Feed::TooLong));
    let f = frame(&ToDevice::Bye);
    assert_eq!(f.len(), 5);
    let mut last = Feed::Pending;
    for &x in &f {
        last = r.feed(x);
    }
    assert_eq!(last, Feed::Frame);
    assert_eq!(r.decode::<ToDevice>(), Ok(ToDevice::Bye));
}

#[test]
fn an_unknown_variant_of_a_newer_peer_is_a_message_error() {
    // Variant 8 of ToDevice does not exist in version 2: postcard bytes [08], CRC, COBS.
    let mut f = frame(&ToDevice::ListBoards { id: 0 });
    let mut raw = [8u8, 0, 0];
    let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(&raw[..1]);
    raw[1..].copy_from_slice(&crc.to_le_bytes());
    f.clear();
    let mut enc = [0u8; 8];
    let n = cobs::encode(&raw, &mut enc);
    f.extend_from_slice(&enc[..n]);
    f.push(0);
    assert_eq!(decode::<ToDevice>(&mut f), Err(FrameError::Message));
}

#[test]
fn a_message_too_long_for_a_frame_is_refused_when_written() {
    let long = [0u8; 300];
    let mut buf = [0u8; 1024];
    assert_eq!(
        encode(&ToHost::Log(&long), &mut buf),
        Err(FrameError::TooLong)
    );
    let mut short = [0u8; 4];
    assert_eq!(
        encode(&ToDevice::ListBoards { id: 1 }, &mut short),
        Err(FrameError::TooLong)
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn no_bytes_make_a_decoder_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut host: FrameReader<{ MAX_FRAME }> = FrameReader::new();
        let mut dev: FrameReader<64> = FrameReader::new();
        for &b in &bytes {
            if host.feed(b) == Feed::Frame {
                let _ = host.decode::<ToHost>();
            }
            if dev.feed(b) == Feed::Frame {
                let _ = dev.decode::<ToDevice>();
            }
        }
        let mut copy = bytes.clone();
        let _ = decode::<ToHost>(&mut copy);
        let mut copy = bytes;
        let _ = decode::<ToDevice>(&mut copy);
    }

    #[test]
    fn valid_postcard_with_any_bytes_never_panics(tail in proptest::collection::vec(any::<u8>(), 0..60), v in 0u8..12) {
        // A correct frame around arbitrary message bytes: only postcard judges them.
        let mut raw = vec![v];
        raw.extend_from_slice(&tail);
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(&raw);
        raw.extend_from_slice(&crc.to_le_bytes());
        let mut enc = vec![0u8; raw.len() + 4];
        let n = cobs::encode(&raw, &mut enc);
        enc.truncate(n);
        let mut a = enc.clone();
        let _ = decode::<ToHost>(&mut a);
        let mut b = enc;
        let _ = decode::<ToDevice>(&mut b);
    }

    #[test]
    fn the_motherboards_encoder_writes_what_postcard_writes(k in any::<u8>(), a in any::<u8>(), n in any::<u64>(),
        bytes in proptest::collection::vec(any::<u8>(), 0..60), text in "\\PC{0,12}") {
        let m = to_host_of(k, a, n, &bytes, &text);
        let mut want = [0u8; 400];
        let mut got = [0u8; 400];
        let w = postcard::to_slice(&m, &mut want).map(|s| s.len()).ok();
        prop_assert_eq!(write_to_host(&m, &mut got), w);
        let w = w.unwrap();
        prop_assert_eq!(&got[..w], &want[..w]);
        // And the whole frame, when it fits one.
        let mut fa = [0u8; MAX_FRAME];
        let mut fb = [0u8; MAX_FRAME];
        prop_assert_eq!(encode_host(&m, &mut fa), encode(&m, &mut fb));
        prop_assert_eq!(fa, fb);
    }

    #[test]
    fn the_motherboards_decoder_reads_what_postcard_reads(bytes in proptest::collection::vec(any::<u8>(), 0..40),
        v in 0u8..10, id in any::<u16>(), db in any::<u8>(), text in "\\PC{0,6}") {
        // Random bytes behind a variant tag, and well-formed requests, some with bytes left over.
        let mut raw = vec![v];
        raw.extend_from_slice(&bytes);
        let good = [
            ToDevice::Hello(Hello { version: id, address: db, board: &text, robot: &text }),
            ToDevice::Bye,
            ToDevice::Call { id, db, op: WireOp { fn_op: db, port: !db, data: &bytes } },
            ToDevice::Diagnostics { id },
            ToDevice::ListBoards { id },
            ToDevice::Boards { id, first: db },
            ToDevice::Assign { id, uid: [db, 1, 2, 3, 4, 5, 6, !db], address: db },
            ToDevice::Update { id, uid: None },
            ToDevice::Update { id, uid: Some([!db, 9, 8, 7, 6, 5, 4, db]) },
        ];
        let mut cases = vec![raw];
        for m in &good {
            let mut buf = [0u8; 200];
            let n = postcard::to_slice(m, &mut buf).unwrap().len();
            cases.push(buf[..n].to_vec());
            let mut longer = buf[..n].to_vec();
            longer.push(db);
            cases.push(longer);
            cases.push(buf[..n.saturating_sub(1)].to_vec());
        }
        for c in &cases {
            // The motherboard skips the hello's names (any bytes; read back empty).
            let want = match postcard::take_from_bytes::<ToDevice>(c) {
                Ok((ToDevice::Hello(h), [])) => Some(ToDevice::Hello(Hello { board: "", robot: "", ..h })),
                Ok((m, [])) => Some(m),
                _ => match postcard::take_from_bytes::<HelloBytes>(c) {
                    Ok((HelloBytes::Hello { version, address, .. }, [])) => Some(ToDevice::Hello(Hello { version, address, board: "", robot: "" })),
                    _ => None,
                },
            };
            prop_assert_eq!(read_to_device(c), want, "{:02x?}", c);
        }
    }

    #[test]
    fn any_call_record_round_trips(db in any::<u8>(), fn_op in any::<u8>(), port in any::<u8>(),
        data in proptest::collection::vec(any::<u8>(), 0..30), s in any::<u64>(), e in any::<u64>()) {
        let m = ToHost::Call(CallRec { db, op: WireOp { fn_op, port, data: &data }, outcome: Outcome::Ok(&data), start_us: s, end_us: e });
        let mut f = frame(&m);
        prop_assert_eq!(decode::<ToHost>(&mut f), Ok(m.clone()));
    }
}
