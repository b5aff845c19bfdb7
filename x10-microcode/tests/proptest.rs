//! Property tests: emit → parse is the identity for every representation; parse never panics on
//! arbitrary bytes, and whatever parses re-emits to exactly the same bytes (the encoding is
//! canonical).

use proptest::prelude::*;
use x10_microcode::{
    Address, Batch, BatchResults, BatchWriter, BoardKind, Capabilities, Diagnostics, Edge, Error,
    Event, EventConfig, EventFrame, EventKind, Identity, Level, Op, Pin, PinRef, Port, PortKind,
    Reply, ReplyFrame, Request, RequestFrame, ScanResult, Status, MAX_FRAME_LEN, MAX_PAYLOAD,
    MAX_REQUEST_DATA,
};

// ---------------------------------------------------------------------------------------------
// Strategies
// ---------------------------------------------------------------------------------------------

fn address() -> impl Strategy<Value = Address> {
    prop_oneof![Just(0u8), 0x08u8..=0x77].prop_map(|a| Address::new(a).unwrap())
}

fn external_address() -> impl Strategy<Value = Address> {
    (0x08u8..=0x77).prop_map(|a| Address::new(a).unwrap())
}

fn port_of(kind: PortKind) -> impl Strategy<Value = Port> {
    (1u8..=Port::MAX_PORTS).prop_map(move |n| Port::new(kind, n).unwrap())
}

fn any_port() -> impl Strategy<Value = Port> {
    prop_oneof![port_of(PortKind::Sensor), port_of(PortKind::Actuator)]
}

fn pin() -> impl Strategy<Value = Pin> {
    prop_oneof![Just(Pin::A), Just(Pin::B)]
}

fn pin_of(kind: PortKind) -> impl Strategy<Value = PinRef> {
    (port_of(kind), pin()).prop_map(|(p, pin)| p.pin(pin))
}

fn any_pin() -> impl Strategy<Value = PinRef> {
    (any_port(), pin()).prop_map(|(p, pin)| p.pin(pin))
}

fn event_config() -> impl Strategy<Value = EventConfig> {
    (
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<u16>(),
        any::<u16>(),
    )
        .prop_map(|(rising, falling, analog_window, a, b)| {
            let (low, high) = if analog_window && a > b {
                (b, a)
            } else {
                (a, b)
            };
            EventConfig {
                rising,
                falling,
                analog_window,
                low,
                high,
            }
        })
}

/// An operation that owns its data, so that a strategy can produce it; [`OwnedOp::op`] borrows
/// it as an [`Op`].
#[derive(Clone, Debug)]
enum OwnedOp {
    Plain(Op<'static>),
    SerialWrite(Port, Vec<u8>),
    Batch(Vec<OwnedOp>),
}

fn plain_op() -> impl Strategy<Value = Op<'static>> {
    prop_oneof![
        Just(Op::Ping),
        Just(Op::Identify),
        Just(Op::Heartbeat),
        any::<u16>().prop_map(|timeout_ms| Op::SetFailsafe { timeout_ms }),
        // The analog window exists only on sensor ports (actuator ports have no analog input).
        (any_pin(), event_config()).prop_map(|(p, mut c)| {
            if p.port.kind() == PortKind::Actuator {
                c.analog_window = false;
            }
            Op::EventEnable(p, c)
        }),
        Just(Op::ReadDiagnostics),
        Just(Op::ClearDiagnostics),
        any::<bool>().prop_map(Op::SetPec),
        any_pin().prop_map(Op::DigitalRead),
        (any_pin(), any::<bool>()).prop_map(|(p, h)| Op::DigitalWrite(p, Level::from_bool(h))),
        (
            any_pin(),
            prop_oneof![Just(Edge::Rising), Just(Edge::Falling)],
            proptest::option::of(any::<u16>())
        )
            .prop_map(|(pin, edge, timeout_ms)| Op::PulseIn {
                pin,
                edge,
                timeout_ms
            }),
        (pin_of(PortKind::Actuator), any::<u8>()).prop_map(|(p, d)| Op::PwmDuty(p, d)),
        (port_of(PortKind::Actuator), 1u16..).prop_map(|(p, hz)| Op::PwmFrequency(p, hz)),
        (pin_of(PortKind::Actuator), any::<u16>()).prop_map(|(p, us)| Op::PwmPulseWidth(p, us)),
        port_of(PortKind::Sensor).prop_map(Op::AnalogRead),
        (any_port(), 1u8..=MAX_PAYLOAD as u8).prop_map(|(p, n)| Op::SerialRead(p, n)),
        (any_port(), 1u32..).prop_map(|(p, baud)| Op::SerialConfig(p, baud)),
        Just(Op::Scan),
    ]
}

/// Operations allowed in a batch (not deferred, not a batch), owned.
fn batch_item() -> impl Strategy<Value = OwnedOp> {
    prop_oneof![
        4 => plain_op()
            .prop_filter("deferred operations cannot be batched", |op| !op.is_deferred())
            .prop_map(OwnedOp::Plain),
        1 => (any_port(), proptest::collection::vec(any::<u8>(), 1..=8))
            .prop_map(|(p, d)| OwnedOp::SerialWrite(p, d)),
    ]
}

fn owned_op() -> impl Strategy<Value = OwnedOp> {
    prop_oneof![
        6 => plain_op().prop_map(OwnedOp::Plain),
        1 => (any_port(), proptest::collection::vec(any::<u8>(), 1..=MAX_REQUEST_DATA))
            .prop_map(|(p, d)| OwnedOp::SerialWrite(p, d)),
        2 => proptest::collection::vec(batch_item(), 1..10).prop_map(OwnedOp::Batch),
    ]
}

impl OwnedOp {
    /// Builds the operation; batch items are written with [`BatchWriter`] into `buf`, keeping
    /// only the leading items that fit one request and one reply.
    fn op<'a>(&'a self, buf: &'a mut [u8; MAX_REQUEST_DATA]) -> Op<'a> {
        match self {
            OwnedOp::Plain(op) => *op,
            OwnedOp::SerialWrite(p, d) => Op::SerialWrite(*p, d),
            OwnedOp::Batch(items) => {
                let mut w = BatchWriter::new(buf);
                let (mut data, mut reply) = (0usize, 0usize);
                let mut pushed = 0;
                let mut scratch = [0u8; MAX_REQUEST_DATA];
                for item in items {
                    let op = item.op(&mut scratch);
                    let d = 3 + op.data_len();
                    let r = 2 + op.reply_capacity();
                    if data + d > MAX_REQUEST_DATA || reply + r > MAX_PAYLOAD {
                        // This item would not fit: the writer must say so (data), or accept
                        // it now and refuse at finish (reply); either way skip it.
                        continue;
                    }
                    w.push(&op).unwrap();
                    data += d;
                    reply += r;
                    pushed += 1;
                }
                if pushed == 0 {
                    w.push(&Op::Ping).unwrap();
                }
                Op::Batch(w.finish().unwrap())
            }
        }
    }
}

fn status() -> impl Strategy<Value = Status> {
    any::<u8>().prop_map(Status::from_byte)
}

fn identity() -> impl Strategy<Value = Identity> {
    (
        any::<u8>(),
        any::<[u8; 3]>(),
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        any::<u16>(),
        any::<u8>(),
    )
        .prop_map(|(v, fw, board, s, a, caps, adc)| Identity {
            protocol_version: v,
            firmware: fw,
            board: BoardKind(board),
            sensor_ports: s,
            actuator_ports: a,
            capabilities: Capabilities(caps),
            adc_bits: adc,
        })
}

fn scan_result() -> impl Strategy<Value = ScanResult> {
    (
        0u8..=ScanResult::MAX_PORTS as u8,
        any::<u16>(),
        any::<[u16; ScanResult::MAX_PORTS]>(),
    )
        .prop_map(|(ports, digital, mut analog)| {
            for v in analog.iter_mut().skip(ports as usize) {
                *v = 0;
            }
            ScanResult {
                ports,
                digital,
                analog,
            }
        })
}

fn payload() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), 0..=MAX_PAYLOAD)
}

fn bytes() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), 0..48)
}

/// Arbitrary bytes biased towards well-formed headers, so that the deeper parsers are reached.
fn request_like() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        bytes(),
        (
            0u8..0x70,
            prop_oneof![Just(9u8), any::<u8>()],
            any::<u8>(),
            any::<u8>(),
            proptest::collection::vec(any::<u8>(), 0..30)
        )
            .prop_map(|(f, db, port, seq, data)| {
                let mut v = vec![f, db, port, seq];
                v.extend(data);
                v
            }),
    ]
}

// ---------------------------------------------------------------------------------------------
// emit → parse
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn request_roundtrip(db in address(), seq in any::<u8>(), op in owned_op()) {
        let mut scratch = [0u8; MAX_REQUEST_DATA];
        let r = Request { db, seq, op: op.op(&mut scratch) };
        prop_assert_eq!(r.op.validate(), Ok(()));
        let mut buf = [0xa5u8; MAX_FRAME_LEN + 4];
        let n = r.emit(&mut buf).unwrap();
        prop_assert_eq!(n, r.buffer_len());
        prop_assert!(buf[n..].iter().all(|&b| b == 0xa5));
        prop_assert_eq!(Request::parse(&buf[..n]), Ok(r));
        // The view agrees with the representation.
        let f = RequestFrame::new_checked(&buf[..n]).unwrap();
        prop_assert_eq!(f.fn_op(), r.op.fn_op_byte());
        prop_assert_eq!(f.db(), db.get());
        prop_assert_eq!(f.port_byte(), r.op.port_byte());
        prop_assert_eq!(f.seq(), seq);
        prop_assert_eq!(f.data().len(), r.op.data_len());
        // With PEC.
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = r.emit_with_pec(&mut buf).unwrap();
        prop_assert_eq!(Request::parse_with_pec(db, &buf[..n]), Ok(r));
        // A batch item list read back equals what was written.
        if let Op::Batch(b) = r.op {
            let again = Batch::new_checked(b.as_bytes()).unwrap();
            prop_assert_eq!(again.iter().count(), b.len());
            prop_assert!(b.reply_capacity() <= MAX_PAYLOAD);
        }
    }

    #[test]
    fn reply_roundtrip(seq in any::<u8>(), status in status(), payload in payload(),
                       db in address(), padding in 0usize..8) {
        let r = Reply { seq, status, payload: &payload };
        let mut buf = [0xa5u8; MAX_FRAME_LEN + 8];
        let n = r.emit(&mut buf).unwrap();
        prop_assert_eq!(n, r.buffer_len());
        prop_assert_eq!(Reply::parse(&buf[..n]), Ok(r));
        prop_assert_eq!(Reply::parse_read(db, false, &buf[..n + padding]), Ok(r));
        let n = r.emit_with_pec(db, &mut buf).unwrap();
        prop_assert_eq!(Reply::parse_read(db, true, &buf[..n + padding]), Ok(r));
    }

    #[test]
    fn event_roundtrip(source in address(), kind in any::<u8>(), port in any::<u8>(),
                       seq in any::<u8>(), status in status(), payload in payload(),
                       mb in external_address()) {
        let e = Event {
            source,
            kind: EventKind::from_byte(kind),
            pin: PinRef::from_byte(port),
            seq,
            status,
            payload: &payload,
        };
        let mut buf = [0xa5u8; MAX_FRAME_LEN + 4];
        let n = e.emit(&mut buf).unwrap();
        prop_assert_eq!(n, e.buffer_len());
        prop_assert!(buf[n..].iter().all(|&b| b == 0xa5));
        prop_assert_eq!(Event::parse(&buf[..n]), Ok(e));
        let n = e.emit_with_pec(mb, &mut buf).unwrap();
        prop_assert_eq!(Event::parse_with_pec(mb, &buf[..n]), Ok(e));
    }

    #[test]
    fn identity_roundtrip(id in identity()) {
        prop_assert_eq!(Identity::parse(&id.to_bytes()), Ok(id));
    }

    #[test]
    fn diagnostics_roundtrip(values in any::<[u16; 14]>()) {
        let d = Diagnostics::from_values(values);
        prop_assert_eq!(d.values(), values);
        prop_assert_eq!(Diagnostics::parse(&d.to_bytes()), Ok(d));
    }

    #[test]
    fn event_config_roundtrip(cfg in event_config()) {
        prop_assert_eq!(EventConfig::parse(&cfg.to_bytes()), Ok(cfg));
    }

    #[test]
    fn scan_result_roundtrip(scan in scan_result()) {
        let mut buf = [0xa5u8; MAX_PAYLOAD];
        let n = scan.emit(&mut buf).unwrap();
        prop_assert_eq!(n, scan.len());
        prop_assert!(n <= MAX_PAYLOAD);
        prop_assert_eq!(ScanResult::parse(&buf[..n]), Ok(scan));
    }

    #[test]
    fn pin_ref_byte_roundtrip(b in any::<u8>()) {
        let p = PinRef::from_byte(b);
        prop_assert_eq!(p.to_byte(), b);
        prop_assert_eq!(Port::from_byte(b), p.port);
        prop_assert_eq!(p.port.number(), (b >> 1 & 0x3f) + 1);
    }

    #[test]
    fn batch_results_roundtrip(items in proptest::collection::vec((status(), payload()), 0..6)) {
        let mut buf = [0u8; 6 * (2 + MAX_PAYLOAD)];
        let mut n = 0;
        for (s, v) in &items {
            n += BatchResults::emit(&mut buf[n..], *s, v).unwrap();
        }
        let got: Vec<_> = BatchResults::new(&buf[..n]).collect::<Result<_, _>>().unwrap();
        prop_assert_eq!(got.len(), items.len());
        for (g, (s, v)) in got.iter().zip(&items) {
            prop_assert_eq!(g.status, *s);
            prop_assert_eq!(g.value, &v[..]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// parse of arbitrary bytes: never panics; what parses is canonical
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(5000))]

    #[test]
    fn request_parse_arbitrary(b in request_like(), db in address()) {
        match Request::parse(&b) {
            Ok(r) => {
                let mut out = [0u8; MAX_FRAME_LEN];
                let n = r.emit(&mut out).unwrap();
                prop_assert_eq!(&out[..n], &b[..]);
                prop_assert_eq!(r.op.validate(), Ok(()));
            }
            Err(e) => {
                // Every parse error maps to a refusal status.
                prop_assert!(!e.status().is_ok());
                prop_assert!(e != Error::BufferTooShort);
            }
        }
        let _ = Request::parse_with_pec(db, &b);
        if let Ok(f) = RequestFrame::new_checked(&b[..]) {
            let _ = (f.fn_op(), f.function(), f.operand(), f.db(), f.port_byte(),
                     f.pin_ref(), f.seq(), f.data());
        }
        // The view never panics even unchecked.
        let f = RequestFrame::new_unchecked(&b[..]);
        let _ = (f.fn_op(), f.db(), f.port_byte(), f.seq(), f.data());
        if b.len() >= 2 {
            let _ = Op::parse(b[0], b[1], &b[2..]);
        }
        let _ = Batch::new_checked(&b);
    }

    #[test]
    fn reply_parse_arbitrary(b in bytes(), db in address(), pec_on in any::<bool>()) {
        if let Ok(r) = Reply::parse(&b) {
            let mut out = [0u8; MAX_FRAME_LEN];
            let n = r.emit(&mut out).unwrap();
            prop_assert_eq!(&out[..n], &b[..]);
        }
        if let Ok(r) = Reply::parse_read(db, pec_on, &b) {
            let mut out = [0u8; MAX_FRAME_LEN];
            let n = if pec_on { r.emit_with_pec(db, &mut out) } else { r.emit(&mut out) }.unwrap();
            prop_assert_eq!(&out[..n], &b[..n]);
        }
        if let Ok(f) = ReplyFrame::new_checked(&b[..]) {
            let _ = (f.seq(), f.status(), f.payload_len(), f.frame_len(), f.payload());
        }
        let f = ReplyFrame::new_unchecked(&b[..]);
        let _ = (f.seq(), f.status(), f.payload_len(), f.frame_len(), f.payload());
        for item in BatchResults::new(&b) {
            let _ = item;
        }
        let _ = (Identity::parse(&b), Diagnostics::parse(&b), ScanResult::parse(&b),
                 EventConfig::parse(&b));
    }

    #[test]
    fn event_parse_arbitrary(b in bytes(), mb in address()) {
        if let Ok(e) = Event::parse(&b) {
            let mut out = [0u8; MAX_FRAME_LEN];
            let n = e.emit(&mut out).unwrap();
            prop_assert_eq!(&out[..n], &b[..]);
        }
        if let Ok(e) = Event::parse_with_pec(mb, &b) {
            let mut out = [0u8; MAX_FRAME_LEN];
            let n = e.emit_with_pec(mb, &mut out).unwrap();
            prop_assert_eq!(&out[..n], &b[..]);
        }
        if let Ok(f) = EventFrame::new_checked(&b[..]) {
            let _ = (f.source(), f.kind(), f.pin_ref(), f.seq(), f.status(), f.payload_len(),
                     f.frame_len(), f.payload());
        }
        let f = EventFrame::new_unchecked(&b[..]);
        let _ = (f.source(), f.kind(), f.pin_ref(), f.seq(), f.status(), f.payload());
    }

    #[test]
    fn payload_parsers_arbitrary(b in proptest::collection::vec(any::<u8>(), 0..=MAX_PAYLOAD)) {
        if let Ok(id) = Identity::parse(&b) {
            prop_assert_eq!(&id.to_bytes()[..], &b[..]);
        }
        if let Ok(d) = Diagnostics::parse(&b) {
            prop_assert_eq!(&d.to_bytes()[..], &b[..]);
        }
        if let Ok(c) = EventConfig::parse(&b) {
            prop_assert_eq!(&c.to_bytes()[..], &b[..]);
        }
        if let Ok(s) = ScanResult::parse(&b) {
            let mut out = [0u8; MAX_PAYLOAD];
            let n = s.emit(&mut out).unwrap();
            prop_assert_eq!(&out[..n], &b[..]);
        }
    }

    #[test]
    fn sweep_pack_unpack_roundtrip(scan in scan_result()) {
        let mut scan = scan;
        for v in scan.analog.iter_mut() {
            *v &= 0x0fff;
        }
        // A board has two pins per port: the levels above them are 0.
        scan.digital &= u16::MAX.checked_shr(16 - 2 * u32::from(scan.ports)).unwrap_or(0);
        let mut out = [0u8; x10_microcode::sweep::MAX_PAYLOAD_LEN];
        let n = x10_microcode::sweep::pack(&scan, &mut out).unwrap();
        prop_assert_eq!(n, x10_microcode::sweep::payload_len(scan.ports));
        prop_assert_eq!(x10_microcode::sweep::unpack(scan.ports, &out[..n]).unwrap(), scan);
    }

    #[test]
    fn sweep_unpack_arbitrary(ports in 0u8..12, b in proptest::collection::vec(any::<u8>(), 0..20)) {
        // Whatever unpacks packs again to exactly the same bytes: no two payloads give the
        // same values.
        if let Ok(scan) = x10_microcode::sweep::unpack(ports, &b) {
            let mut out = [0u8; x10_microcode::sweep::MAX_PAYLOAD_LEN];
            let n = x10_microcode::sweep::pack(&scan, &mut out).unwrap();
            prop_assert_eq!(&out[..n], &b[..]);
        }
    }

    #[test]
    fn update_op_parse_arbitrary(operand in any::<u8>(), port in any::<u8>(),
                                 b in proptest::collection::vec(any::<u8>(), 0..=MAX_REQUEST_DATA)) {
        if let Ok(op) = x10_microcode::UpdateOp::parse(operand, port, &b) {
            let mut out = [0u8; MAX_REQUEST_DATA];
            let n = op.emit_data(&mut out).unwrap();
            prop_assert_eq!(&out[..n], &b[..]);
        }
        let _ = x10_microcode::UpdateReport::parse(&b);
    }
}
