//! Byte-vector tests: every request operation, reply and event kind as a static byte array,
//! checked four ways (view getters, setters into a dirty buffer, parse, emit), plus every
//! truncated prefix, plus the same frames with SMBus PEC.
//!
//! The expected field values are written out by hand next to each vector, never read back from
//! the bytes, so a vector and its meaning cannot drift together.

use x10_microcode::test_support::{a, s};
use x10_microcode::{
    pec, Address, Batch, BatchItem, BatchResults, BatchWriter, BoardKind, Capabilities,
    Diagnostics, Edge, Error, Event, EventConfig, EventFrame, EventKind, Function, Identity, Level,
    Op, Pin, PinRef, Reply, ReplyFrame, Request, RequestFrame, ScanResult, Status, MAX_FRAME_LEN,
    MAX_REQUEST_DATA,
};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn req(db: u8, seq: u8, op: Op<'_>) -> Request<'_> {
    Request {
        db: Address::new(db).unwrap(),
        seq,
        op,
    }
}

/// Scratch space a vector's representation may borrow (batches are built into it).
type Scratch = [u8; MAX_REQUEST_DATA];

// ---------------------------------------------------------------------------------------------
// Requests
// ---------------------------------------------------------------------------------------------

struct RequestVector {
    name: &'static str,
    bytes: &'static [u8],
    // What the view getters must return.
    fn_op: u8,
    function: Function,
    operand: u8,
    db: u8,
    port_byte: u8,
    seq: u8,
    data: &'static [u8],
    // What the operation says about itself.
    op_name: &'static str,
    expects_reply: bool,
    reply_capacity: usize,
    /// Strict prefixes that are themselves valid requests (a request carries no length field:
    /// the transfer length frames it, so dropping whole optional data can leave a valid frame).
    ok_prefixes: &'static [usize],
    repr: for<'b> fn(&'b mut Scratch) -> Request<'b>,
}

static PING: [u8; 4] = [0x00, 0x09, 0x00, 0x01];
static IDENTIFY: [u8; 4] = [0x01, 0x09, 0x00, 0x02];
static HEARTBEAT: [u8; 4] = [0x02, 0x09, 0x00, 0x03];
static SET_FAILSAFE: [u8; 6] = [0x03, 0x09, 0x00, 0x04, 0xf4, 0x01];
static EVENT_ENABLE: [u8; 9] = [0x04, 0x09, 0x82, 0x05, 0x07, 0x64, 0x00, 0x84, 0x03];
static READ_DIAGNOSTICS: [u8; 4] = [0x05, 0x09, 0x00, 0x06];
static CLEAR_DIAGNOSTICS: [u8; 4] = [0x06, 0x09, 0x00, 0x07];
static SET_PEC: [u8; 5] = [0x07, 0x09, 0x00, 0x08, 0x01];
static IO_INPUT: [u8; 4] = [0x10, 0x09, 0x80, 0x09];
static IO_LOW: [u8; 4] = [0x11, 0x09, 0x02, 0x0a];
/// The example: digitalOut HIGH to DB 9, actuator port 1, pin B, sequence 2.
static IO_HIGH: [u8; 4] = [0x12, 0x09, 0x01, 0x02];
static PULSE_IN_RISING: [u8; 4] = [0x13, 0x09, 0x85, 0x0b];
static PULSE_IN_FALLING: [u8; 6] = [0x14, 0x09, 0x85, 0x0c, 0xe8, 0x03];
/// Thesis `pwm(B, 9, 1, 128)`: `{FN_PWM, db, ((port-1)<<1)+pin, seq, duty}`.
static PWM_DUTY: [u8; 5] = [0x20, 0x09, 0x01, 0x03, 0x80];
static PWM_FREQUENCY: [u8; 6] = [0x21, 0x09, 0x00, 0x0d, 0x20, 0x4e];
static PWM_PULSE_WIDTH: [u8; 6] = [0x22, 0x09, 0x02, 0x0e, 0xdc, 0x05];
/// Thesis `analog(9, 1)` in the Table 3.2 layout (port kind bit set: a sensor port).
static ANALOG_READ: [u8; 4] = [0x30, 0x09, 0x80, 0x04];
static ANALOG_READ_INTERNAL: [u8; 4] = [0x30, 0x00, 0x82, 0x10];
static SERIAL_WRITE: [u8; 6] = [0x40, 0x09, 0x86, 0x0f, b'h', b'i'];
static SERIAL_READ: [u8; 5] = [0x41, 0x09, 0x86, 0x10, 0x08];
static SERIAL_CONFIG: [u8; 8] = [0x42, 0x09, 0x86, 0x11, 0x80, 0x25, 0x00, 0x00];
/// Batch: HIGH on A1.B; duty 200 on A1.A; analog read of S1.
static BATCH: [u8; 14] = [
    0x50, 0x09, 0x00, 0x12, // header
    0x12, 0x01, 0x00, // io high, A1.B, no data
    0x20, 0x00, 0x01, 0xc8, // pwm duty, A1.A, 1 byte: 200
    0x30, 0x80, 0x00, // analog read, S1, no data
];
static SCAN: [u8; 4] = [0x60, 0x09, 0x00, 0x13];

fn batch_repr(buf: &mut Scratch) -> Request<'_> {
    let mut w = BatchWriter::new(buf);
    w.push(&Op::DigitalWrite(a(1).pin(Pin::B), Level::High))
        .unwrap();
    w.push(&Op::PwmDuty(a(1).pin(Pin::A), 200)).unwrap();
    w.push(&Op::AnalogRead(s(1))).unwrap();
    req(0x09, 0x12, Op::Batch(w.finish().unwrap()))
}

fn request_vectors() -> Vec<RequestVector> {
    vec![
        RequestVector {
            name: "ping",
            bytes: &PING,
            fn_op: 0x00,
            function: Function::System,
            operand: 0,
            db: 0x09,
            port_byte: 0,
            seq: 1,
            data: &[],
            op_name: "ping",
            expects_reply: true,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 1, Op::Ping),
        },
        RequestVector {
            name: "identify",
            bytes: &IDENTIFY,
            fn_op: 0x01,
            function: Function::System,
            operand: 1,
            db: 0x09,
            port_byte: 0,
            seq: 2,
            data: &[],
            op_name: "identify",
            expects_reply: true,
            reply_capacity: 10,
            ok_prefixes: &[],
            repr: |_| req(0x09, 2, Op::Identify),
        },
        RequestVector {
            name: "heartbeat",
            bytes: &HEARTBEAT,
            fn_op: 0x02,
            function: Function::System,
            operand: 2,
            db: 0x09,
            port_byte: 0,
            seq: 3,
            data: &[],
            op_name: "heartbeat",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 3, Op::Heartbeat),
        },
        RequestVector {
            name: "set_failsafe",
            bytes: &SET_FAILSAFE,
            fn_op: 0x03,
            function: Function::System,
            operand: 3,
            db: 0x09,
            port_byte: 0,
            seq: 4,
            data: &[0xf4, 0x01],
            op_name: "set_failsafe",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 4, Op::SetFailsafe { timeout_ms: 500 }),
        },
        RequestVector {
            name: "event_enable",
            bytes: &EVENT_ENABLE,
            fn_op: 0x04,
            function: Function::System,
            operand: 4,
            db: 0x09,
            port_byte: 0x82,
            seq: 5,
            data: &[0x07, 0x64, 0x00, 0x84, 0x03],
            op_name: "event_enable",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| {
                req(
                    0x09,
                    5,
                    Op::EventEnable(
                        s(2).pin(Pin::A),
                        EventConfig {
                            rising: true,
                            falling: true,
                            analog_window: true,
                            low: 100,
                            high: 900,
                        },
                    ),
                )
            },
        },
        RequestVector {
            name: "read_diagnostics",
            bytes: &READ_DIAGNOSTICS,
            fn_op: 0x05,
            function: Function::System,
            operand: 5,
            db: 0x09,
            port_byte: 0,
            seq: 6,
            data: &[],
            op_name: "read_diagnostics",
            expects_reply: true,
            reply_capacity: 28,
            ok_prefixes: &[],
            repr: |_| req(0x09, 6, Op::ReadDiagnostics),
        },
        RequestVector {
            name: "clear_diagnostics",
            bytes: &CLEAR_DIAGNOSTICS,
            fn_op: 0x06,
            function: Function::System,
            operand: 6,
            db: 0x09,
            port_byte: 0,
            seq: 7,
            data: &[],
            op_name: "clear_diagnostics",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 7, Op::ClearDiagnostics),
        },
        RequestVector {
            name: "set_pec",
            bytes: &SET_PEC,
            fn_op: 0x07,
            function: Function::System,
            operand: 7,
            db: 0x09,
            port_byte: 0,
            seq: 8,
            data: &[0x01],
            op_name: "set_pec",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 8, Op::SetPec(true)),
        },
        RequestVector {
            name: "io_input",
            bytes: &IO_INPUT,
            fn_op: 0x10,
            function: Function::Io,
            operand: 0,
            db: 0x09,
            port_byte: 0x80,
            seq: 9,
            data: &[],
            op_name: "input",
            expects_reply: true,
            reply_capacity: 1,
            ok_prefixes: &[],
            repr: |_| req(0x09, 9, Op::DigitalRead(s(1).pin(Pin::A))),
        },
        RequestVector {
            name: "io_low",
            bytes: &IO_LOW,
            fn_op: 0x11,
            function: Function::Io,
            operand: 1,
            db: 0x09,
            port_byte: 0x02,
            seq: 10,
            data: &[],
            op_name: "low",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 10, Op::DigitalWrite(a(2).pin(Pin::A), Level::Low)),
        },
        RequestVector {
            name: "io_high (issue example 12 09 01 02)",
            bytes: &IO_HIGH,
            fn_op: 0x12,
            function: Function::Io,
            operand: 2,
            db: 0x09,
            port_byte: 0x01,
            seq: 2,
            data: &[],
            op_name: "high",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 2, Op::DigitalWrite(a(1).pin(Pin::B), Level::High)),
        },
        RequestVector {
            name: "pulse_in_rising, default timeout",
            bytes: &PULSE_IN_RISING,
            fn_op: 0x13,
            function: Function::Io,
            operand: 3,
            db: 0x09,
            port_byte: 0x85,
            seq: 11,
            data: &[],
            op_name: "pulse_in_rising",
            expects_reply: true,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| {
                req(
                    0x09,
                    11,
                    Op::PulseIn {
                        pin: s(3).pin(Pin::B),
                        edge: Edge::Rising,
                        timeout_ms: None,
                    },
                )
            },
        },
        RequestVector {
            name: "pulse_in_falling, 1000 ms timeout",
            bytes: &PULSE_IN_FALLING,
            fn_op: 0x14,
            function: Function::Io,
            operand: 4,
            db: 0x09,
            port_byte: 0x85,
            seq: 12,
            data: &[0xe8, 0x03],
            op_name: "pulse_in_falling",
            expects_reply: true,
            reply_capacity: 0,
            // Without its two data bytes it is a pulse-in with the default timeout.
            ok_prefixes: &[4],
            repr: |_| {
                req(
                    0x09,
                    12,
                    Op::PulseIn {
                        pin: s(3).pin(Pin::B),
                        edge: Edge::Falling,
                        timeout_ms: Some(1000),
                    },
                )
            },
        },
        RequestVector {
            name: "pwm duty (thesis pwm)",
            bytes: &PWM_DUTY,
            fn_op: 0x20,
            function: Function::Pwm,
            operand: 0,
            db: 0x09,
            port_byte: 0x01,
            seq: 3,
            data: &[0x80],
            op_name: "duty",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 3, Op::PwmDuty(a(1).pin(Pin::B), 128)),
        },
        RequestVector {
            name: "pwm frequency",
            bytes: &PWM_FREQUENCY,
            fn_op: 0x21,
            function: Function::Pwm,
            operand: 1,
            db: 0x09,
            port_byte: 0x00,
            seq: 13,
            data: &[0x20, 0x4e],
            op_name: "frequency",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 13, Op::PwmFrequency(a(1), 20_000)),
        },
        RequestVector {
            name: "pwm pulse width",
            bytes: &PWM_PULSE_WIDTH,
            fn_op: 0x22,
            function: Function::Pwm,
            operand: 2,
            db: 0x09,
            port_byte: 0x02,
            seq: 14,
            data: &[0xdc, 0x05],
            op_name: "pulse_width",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 14, Op::PwmPulseWidth(a(2).pin(Pin::A), 1500)),
        },
        RequestVector {
            name: "analog read (thesis analog, Table 3.2 layout)",
            bytes: &ANALOG_READ,
            fn_op: 0x30,
            function: Function::Analog,
            operand: 0,
            db: 0x09,
            port_byte: 0x80,
            seq: 4,
            data: &[],
            op_name: "read",
            expects_reply: true,
            reply_capacity: 2,
            ok_prefixes: &[],
            repr: |_| req(0x09, 4, Op::AnalogRead(s(1))),
        },
        RequestVector {
            name: "analog read on the internal DB",
            bytes: &ANALOG_READ_INTERNAL,
            fn_op: 0x30,
            function: Function::Analog,
            operand: 0,
            db: 0x00,
            port_byte: 0x82,
            seq: 16,
            data: &[],
            op_name: "read",
            expects_reply: true,
            reply_capacity: 2,
            ok_prefixes: &[],
            repr: |_| req(0x00, 16, Op::AnalogRead(s(2))),
        },
        RequestVector {
            name: "serial write",
            bytes: &SERIAL_WRITE,
            fn_op: 0x40,
            function: Function::Serial,
            operand: 0,
            db: 0x09,
            port_byte: 0x86,
            seq: 15,
            data: b"hi",
            op_name: "write",
            expects_reply: false,
            reply_capacity: 0,
            // Serial data is framed by the transfer: "h" alone is a valid write.
            ok_prefixes: &[5],
            repr: |_| req(0x09, 15, Op::SerialWrite(s(4), b"hi")),
        },
        RequestVector {
            name: "serial read",
            bytes: &SERIAL_READ,
            fn_op: 0x41,
            function: Function::Serial,
            operand: 1,
            db: 0x09,
            port_byte: 0x86,
            seq: 16,
            data: &[8],
            op_name: "read",
            expects_reply: true,
            reply_capacity: 8,
            ok_prefixes: &[],
            repr: |_| req(0x09, 16, Op::SerialRead(s(4), 8)),
        },
        RequestVector {
            name: "serial config",
            bytes: &SERIAL_CONFIG,
            fn_op: 0x42,
            function: Function::Serial,
            operand: 2,
            db: 0x09,
            port_byte: 0x86,
            seq: 17,
            data: &[0x80, 0x25, 0x00, 0x00],
            op_name: "config",
            expects_reply: false,
            reply_capacity: 0,
            ok_prefixes: &[],
            repr: |_| req(0x09, 17, Op::SerialConfig(s(4), 9600)),
        },
        RequestVector {
            name: "batch",
            bytes: &BATCH,
            fn_op: 0x50,
            function: Function::Batch,
            operand: 0,
            db: 0x09,
            port_byte: 0x00,
            seq: 0x12,
            data: &[0x12, 0x01, 0x00, 0x20, 0x00, 0x01, 0xc8, 0x30, 0x80, 0x00],
            op_name: "batch",
            expects_reply: true,
            // status+len per item, plus 2 bytes of analog value
            reply_capacity: 8,
            // Cut at an item boundary, the rest is a shorter valid batch.
            ok_prefixes: &[7, 11],
            repr: batch_repr,
        },
        RequestVector {
            name: "scan",
            bytes: &SCAN,
            fn_op: 0x60,
            function: Function::Scan,
            operand: 0,
            db: 0x09,
            port_byte: 0x00,
            seq: 0x13,
            data: &[],
            op_name: "scan",
            expects_reply: true,
            // 3 + 2 × 8 ports
            reply_capacity: 19,
            ok_prefixes: &[],
            repr: |_| req(0x09, 0x13, Op::Scan),
        },
    ]
}

#[test]
fn request_vectors_cover_every_op_variant() {
    // One vector per operation name within its function, so a new Op variant without a vector
    // fails here.
    let mut seen: Vec<(Function, &str)> = request_vectors()
        .iter()
        .map(|v| (v.function, v.op_name))
        .collect();
    seen.sort_by_key(|(f, n)| (f.code(), *n));
    seen.dedup();
    assert_eq!(seen.len(), 22, "{seen:?}");
}

#[test]
fn request_view_getters() {
    for v in request_vectors() {
        let f = RequestFrame::new_checked(v.bytes).unwrap();
        assert_eq!(f.fn_op(), v.fn_op, "{}", v.name);
        assert_eq!(f.function(), v.function, "{}", v.name);
        assert_eq!(f.operand(), v.operand, "{}", v.name);
        assert_eq!(f.db(), v.db, "{}", v.name);
        assert_eq!(f.port_byte(), v.port_byte, "{}", v.name);
        assert_eq!(f.pin_ref().to_byte(), v.port_byte, "{}", v.name);
        assert_eq!(f.seq(), v.seq, "{}", v.name);
        assert_eq!(f.data(), v.data, "{}", v.name);
        assert_eq!(f.into_inner(), v.bytes, "{}", v.name);
    }
}

#[test]
fn request_view_setters_into_dirty_buffer() {
    for v in request_vectors() {
        // Whole byte 0 at once.
        let mut buf = vec![0xffu8; v.bytes.len()];
        let mut f = RequestFrame::new_unchecked(&mut buf[..]);
        f.set_fn_op(v.fn_op);
        f.set_db(v.db);
        f.set_port_byte(v.port_byte);
        f.set_seq(v.seq);
        f.data_mut().copy_from_slice(v.data);
        assert_eq!(buf, v.bytes, "{}", v.name);

        // Function and operand nibbles separately.
        let mut buf = vec![0xffu8; v.bytes.len()];
        let mut f = RequestFrame::new_unchecked(&mut buf[..]);
        f.set_function(v.function);
        f.set_operand(v.operand);
        f.set_db(v.db);
        f.set_port_byte(v.port_byte);
        f.set_seq(v.seq);
        f.data_mut().copy_from_slice(v.data);
        assert_eq!(buf, v.bytes, "{}", v.name);
    }
}

#[test]
fn request_parse() {
    for v in request_vectors() {
        let mut scratch = [0u8; MAX_REQUEST_DATA];
        let expected = (v.repr)(&mut scratch);
        let got = Request::parse(v.bytes).unwrap();
        assert_eq!(got, expected, "{}", v.name);
        assert_eq!(got.op.name(), v.op_name, "{}", v.name);
        assert_eq!(got.op.function(), v.function, "{}", v.name);
        assert_eq!(got.op.operand(), v.operand, "{}", v.name);
        assert_eq!(got.op.expects_reply(), v.expects_reply, "{}", v.name);
        assert_eq!(got.op.reply_capacity(), v.reply_capacity, "{}", v.name);
        assert_eq!(got.op.validate(), Ok(()), "{}", v.name);
        // The operation alone parses from bytes 0, 2 and the data.
        assert_eq!(
            Op::parse(v.fn_op, v.port_byte, v.data),
            Ok(expected.op),
            "{}",
            v.name
        );
        // Through an explicit view as well.
        let view = RequestFrame::new_checked(v.bytes).unwrap();
        assert_eq!(Request::parse_frame(&view), Ok(expected), "{}", v.name);
    }
}

#[test]
fn request_emit() {
    for v in request_vectors() {
        let mut scratch = [0u8; MAX_REQUEST_DATA];
        let r = (v.repr)(&mut scratch);
        assert_eq!(r.buffer_len(), v.bytes.len(), "{}", v.name);
        assert_eq!(r.op.fn_op_byte(), v.fn_op, "{}", v.name);
        assert_eq!(r.op.port_byte(), v.port_byte, "{}", v.name);
        assert_eq!(r.op.data_len(), v.data.len(), "{}", v.name);

        let mut buf = [0xffu8; MAX_FRAME_LEN + 8];
        assert_eq!(r.emit(&mut buf), Ok(v.bytes.len()), "{}", v.name);
        assert_eq!(&buf[..v.bytes.len()], v.bytes, "{}", v.name);
        assert!(
            buf[v.bytes.len()..].iter().all(|&b| b == 0xff),
            "{}: wrote past buffer_len",
            v.name
        );

        // Into a view over a dirty buffer of exactly buffer_len bytes.
        let mut exact = vec![0xffu8; v.bytes.len()];
        r.emit_frame(&mut RequestFrame::new_unchecked(&mut exact[..]))
            .unwrap();
        assert_eq!(exact, v.bytes, "{}", v.name);

        // Data alone.
        let mut data = [0xffu8; MAX_REQUEST_DATA];
        assert_eq!(r.op.emit_data(&mut data), Ok(v.data.len()), "{}", v.name);
        assert_eq!(&data[..v.data.len()], v.data, "{}", v.name);

        // One byte short.
        let mut short = vec![0u8; v.bytes.len() - 1];
        assert_eq!(r.emit(&mut short), Err(Error::BufferTooShort), "{}", v.name);
        assert_eq!(
            r.emit_frame(&mut RequestFrame::new_unchecked(&mut short[..])),
            Err(Error::BufferTooShort),
            "{}",
            v.name
        );
        if !v.data.is_empty() {
            let mut short = vec![0u8; v.data.len() - 1];
            assert_eq!(
                r.op.emit_data(&mut short),
                Err(Error::BufferTooShort),
                "{}",
                v.name
            );
        }
    }
}

#[test]
fn request_truncated_prefixes() {
    for v in request_vectors() {
        let mut scratch = [0u8; MAX_REQUEST_DATA];
        let full = (v.repr)(&mut scratch);
        for n in 0..v.bytes.len() {
            let prefix = &v.bytes[..n];
            let got = Request::parse(prefix);
            if v.ok_prefixes.contains(&n) {
                let got = got.unwrap_or_else(|e| panic!("{}: prefix {n}: {e:?}", v.name));
                assert_ne!(got, full, "{}: prefix {n}", v.name);
            } else {
                assert!(got.is_err(), "{}: prefix {n} parsed: {got:?}", v.name);
            }
            if n < 4 {
                assert_eq!(got, Err(Error::Truncated), "{}: prefix {n}", v.name);
                assert!(RequestFrame::new_checked(prefix).is_err());
            }
        }
    }
}

/// Request vectors with their PEC byte, computed independently (CRC-8/SMBus, address byte
/// `db << 1` first).
static PEC_REQUESTS: &[(&[u8], u8)] = &[
    (&[0x12, 0x09, 0x01, 0x02], 0x9c),
    (&[0x00, 0x09, 0x00, 0x01], 0xcb),
    (&[0x30, 0x09, 0x80, 0x04], 0xcf),
    (&[0x20, 0x09, 0x01, 0x03, 0x80], 0xd3),
    (&[0x07, 0x09, 0x00, 0x08, 0x01], 0xec),
];

/// A 14-byte request (a batch) ends in a CRC-16/IBM-3740 over its address byte and frame, low
/// byte first (0x96ad, computed independently by `emu/run.mjs`'s bitwise CRC); its CRC-8 would
/// have been 0xcd.
#[test]
fn a_request_over_13_bytes_ends_in_a_crc16() {
    let db = Address::new(0x09).unwrap();
    let frame = [
        0x50, 0x09, 0x00, 0x12, 0x12, 0x01, 0x00, 0x20, 0x00, 0x01, 0xc8, 0x30, 0x80, 0x00,
    ];
    assert_eq!(pec::compute(0x12, &frame), 0xcd);
    assert_eq!(pec::compute16(0x12, &frame), 0x96ad);
    let r = Request::parse(&frame).unwrap();
    let mut buf = [0xffu8; MAX_FRAME_LEN];
    let n = r.emit_with_pec(&mut buf).unwrap();
    assert_eq!(n, frame.len() + 2);
    assert_eq!(&buf[..frame.len()], &frame);
    assert_eq!(&buf[frame.len()..n], &[0xad, 0x96]);
    assert_eq!(Request::parse_with_pec(db, &buf[..n]), Ok(r));
    // The frame with a CRC-8 byte instead is refused: 15 bytes is no valid length.
    let mut old = frame.to_vec();
    old.push(0xcd);
    assert_eq!(Request::parse_with_pec(db, &old), Err(Error::BadLength));
    // No room for the second byte.
    let mut short = vec![0u8; frame.len() + 1];
    assert_eq!(r.emit_with_pec(&mut short), Err(Error::BufferTooShort));
}

#[test]
fn request_pec_bytes() {
    let db = Address::new(0x09).unwrap();
    for &(frame, pec_byte) in PEC_REQUESTS {
        assert_eq!(pec::compute(0x12, frame), pec_byte, "{frame:02x?}");
        let r = Request::parse(frame).unwrap();
        let mut buf = [0xffu8; MAX_FRAME_LEN];
        let n = r.emit_with_pec(&mut buf).unwrap();
        assert_eq!(n, frame.len() + 1);
        assert_eq!(&buf[..frame.len()], frame);
        assert_eq!(buf[frame.len()], pec_byte);
        assert_eq!(Request::parse_with_pec(db, &buf[..n]), Ok(r));
        // No room for the PEC byte.
        let mut short = vec![0u8; frame.len()];
        assert_eq!(r.emit_with_pec(&mut short), Err(Error::BufferTooShort));
    }
    // The internal DB (address 0) is covered by address byte 0x00.
    let mut buf = [0u8; 8];
    let r = Request::parse(&ANALOG_READ_INTERNAL).unwrap();
    assert_eq!(r.emit_with_pec(&mut buf), Ok(5));
    assert_eq!(buf[..5], [0x30, 0x00, 0x82, 0x10, 0x45]);
}

#[test]
fn request_pec_every_vector_and_prefix() {
    for v in request_vectors() {
        let mut scratch = [0u8; MAX_REQUEST_DATA];
        let r = (v.repr)(&mut scratch);
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = r.emit_with_pec(&mut buf).unwrap();
        let framed = &buf[..n];
        assert_eq!(
            &framed[v.bytes.len()..],
            &check_bytes(v.db << 1, v.bytes)[..],
            "{}",
            v.name
        );
        assert_eq!(Request::parse_with_pec(r.db, framed), Ok(r), "{}", v.name);
        for k in 0..n {
            let got = Request::parse_with_pec(r.db, &framed[..k]);
            assert!(got.is_err(), "{}: PEC prefix {k} parsed: {got:?}", v.name);
        }
        // A flipped bit anywhere is caught.
        for i in 0..n {
            let mut bad = framed.to_vec();
            bad[i] ^= 0x10;
            assert!(
                matches!(
                    Request::parse_with_pec(r.db, &bad),
                    Err(Error::PecMismatch { .. } | Error::CrcMismatch)
                ),
                "{}: flipped byte {i}",
                v.name
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Replies
// ---------------------------------------------------------------------------------------------

struct ReplyVector {
    name: &'static str,
    bytes: &'static [u8],
    seq: u8,
    status: Status,
    status_byte: u8,
    payload: &'static [u8],
}

static REPLY_PING: [u8; 3] = [0x01, 0x00, 0x00];
static REPLY_INPUT: [u8; 4] = [0x09, 0x00, 0x01, 0x01];
static REPLY_ANALOG: [u8; 5] = [0x04, 0x00, 0x02, 0x00, 0x02];
static REPLY_PENDING: [u8; 3] = [0x0b, 0x01, 0x00];
static IDENTITY_BYTES: [u8; 10] = [0x01, 0x00, 0x01, 0x00, 0x03, 0x04, 0x04, 0xff, 0x01, 0x0c];
static REPLY_IDENTIFY: [u8; 13] = [
    0x02, 0x00, 0x0a, 0x01, 0x00, 0x01, 0x00, 0x03, 0x04, 0x04, 0xff, 0x01, 0x0c,
];
static DIAGNOSTICS_BYTES: [u8; 28] = [
    0xe8, 0x03, // frames_ok 1000
    0x02, 0x00, // bad_length 2
    0x01, 0x00, // unknown_function 1
    0x00, 0x00, // unknown_operand 0
    0x03, 0x00, // port_errors 3
    0x00, 0x00, // wrong_address 0
    0x05, 0x00, // pec_errors 5
    0x00, 0x00, // other_errors 0
    0x2a, 0x00, // events_sent 42
    0x07, 0x00, // event_retries 7
    0x00, 0x00, // events_dropped 0
    0x04, 0x00, // arbitration_lost 4
    0x01, 0x00, // failsafe_trips 1
    0x02, 0x01, // no_request_reads 258
];
static REPLY_DIAGNOSTICS: [u8; 31] = [
    0x06, 0x00, 0x1c, 0xe8, 0x03, 0x02, 0x00, 0x01, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x05,
    0x00, 0x00, 0x00, 0x2a, 0x00, 0x07, 0x00, 0x00, 0x00, 0x04, 0x00, 0x01, 0x00, 0x02, 0x01,
];
static SCAN_BYTES: [u8; 11] = [
    0x04, 0x96, 0x00, 0x64, 0x00, 0xc8, 0x00, 0x2c, 0x01, 0x90, 0x01,
];
static REPLY_SCAN: [u8; 14] = [
    0x13, 0x00, 0x0b, 0x04, 0x96, 0x00, 0x64, 0x00, 0xc8, 0x00, 0x2c, 0x01, 0x90, 0x01,
];
static BATCH_RESULTS: [u8; 8] = [0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x02];
static REPLY_BATCH: [u8; 11] = [
    0x12, 0x00, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x02,
];
static REPLY_SERIAL: [u8; 5] = [0x10, 0x00, 0x02, b'h', b'i'];
static REPLY_UNKNOWN_FUNCTION: [u8; 3] = [0x07, 0x03, 0x00];
static REPLY_UNKNOWN_STATUS: [u8; 3] = [0x07, 0x42, 0x00];
static REPLY_NO_REQUEST: [u8; 3] = [0x00, 0x0d, 0x00];

fn reply_vectors() -> Vec<ReplyVector> {
    vec![
        ReplyVector {
            name: "ping ok",
            bytes: &REPLY_PING,
            seq: 1,
            status: Status::Ok,
            status_byte: 0,
            payload: &[],
        },
        ReplyVector {
            name: "digital input 1",
            bytes: &REPLY_INPUT,
            seq: 9,
            status: Status::Ok,
            status_byte: 0,
            payload: &[1],
        },
        ReplyVector {
            name: "analog 512",
            bytes: &REPLY_ANALOG,
            seq: 4,
            status: Status::Ok,
            status_byte: 0,
            payload: &[0x00, 0x02],
        },
        ReplyVector {
            name: "pulse-in pending",
            bytes: &REPLY_PENDING,
            seq: 11,
            status: Status::Pending,
            status_byte: 1,
            payload: &[],
        },
        ReplyVector {
            name: "identify",
            bytes: &REPLY_IDENTIFY,
            seq: 2,
            status: Status::Ok,
            status_byte: 0,
            payload: &IDENTITY_BYTES,
        },
        ReplyVector {
            name: "read_diagnostics",
            bytes: &REPLY_DIAGNOSTICS,
            seq: 6,
            status: Status::Ok,
            status_byte: 0,
            payload: &DIAGNOSTICS_BYTES,
        },
        ReplyVector {
            name: "scan",
            bytes: &REPLY_SCAN,
            seq: 0x13,
            status: Status::Ok,
            status_byte: 0,
            payload: &SCAN_BYTES,
        },
        ReplyVector {
            name: "batch",
            bytes: &REPLY_BATCH,
            seq: 0x12,
            status: Status::Ok,
            status_byte: 0,
            payload: &BATCH_RESULTS,
        },
        ReplyVector {
            name: "serial read",
            bytes: &REPLY_SERIAL,
            seq: 0x10,
            status: Status::Ok,
            status_byte: 0,
            payload: b"hi",
        },
        ReplyVector {
            name: "unknown function",
            bytes: &REPLY_UNKNOWN_FUNCTION,
            seq: 7,
            status: Status::UnknownFunction,
            status_byte: 3,
            payload: &[],
        },
        ReplyVector {
            name: "status code this version does not know",
            bytes: &REPLY_UNKNOWN_STATUS,
            seq: 7,
            status: Status::Unknown(0x42),
            status_byte: 0x42,
            payload: &[],
        },
        ReplyVector {
            name: "no request",
            bytes: &REPLY_NO_REQUEST,
            seq: 0,
            status: Status::NoRequest,
            status_byte: 0x0d,
            payload: &[],
        },
    ]
}

fn reply_repr(v: &ReplyVector) -> Reply<'static> {
    Reply {
        seq: v.seq,
        status: v.status,
        payload: v.payload,
    }
}

#[test]
fn reply_view_getters() {
    for v in reply_vectors() {
        let f = ReplyFrame::new_checked(v.bytes).unwrap();
        assert_eq!(f.seq(), v.seq, "{}", v.name);
        assert_eq!(f.status(), v.status, "{}", v.name);
        assert_eq!(f.status().to_byte(), v.status_byte, "{}", v.name);
        assert_eq!(f.payload_len() as usize, v.payload.len(), "{}", v.name);
        assert_eq!(f.frame_len(), v.bytes.len(), "{}", v.name);
        assert_eq!(f.payload(), v.payload, "{}", v.name);
        assert_eq!(f.into_inner(), v.bytes, "{}", v.name);
    }
}

#[test]
fn reply_view_setters_into_dirty_buffer() {
    for v in reply_vectors() {
        let mut buf = vec![0xffu8; v.bytes.len()];
        let mut f = ReplyFrame::new_unchecked(&mut buf[..]);
        f.set_seq(v.seq);
        f.set_status(v.status);
        f.set_payload_len(v.payload.len() as u8);
        f.payload_mut().copy_from_slice(v.payload);
        assert_eq!(buf, v.bytes, "{}", v.name);
    }
}

#[test]
fn reply_parse() {
    for v in reply_vectors() {
        assert_eq!(Reply::parse(v.bytes), Ok(reply_repr(&v)), "{}", v.name);
        let view = ReplyFrame::new_checked(v.bytes).unwrap();
        assert_eq!(Reply::parse_frame(&view), Ok(reply_repr(&v)), "{}", v.name);
        // A fixed-size read: the frame followed by padding.
        let mut read = v.bytes.to_vec();
        read.extend_from_slice(&[0xff; 6]);
        let db = Address::new(0x09).unwrap();
        assert_eq!(
            Reply::parse_read(db, false, &read),
            Ok(reply_repr(&v)),
            "{}",
            v.name
        );
        // parse_frame ignores the padding too; parse does not.
        let view = ReplyFrame::new_checked(&read[..]).unwrap();
        assert_eq!(Reply::parse_frame(&view), Ok(reply_repr(&v)), "{}", v.name);
        assert_eq!(Reply::parse(&read), Err(Error::BadLength), "{}", v.name);
    }
}

#[test]
fn reply_emit() {
    for v in reply_vectors() {
        let r = reply_repr(&v);
        assert_eq!(r.buffer_len(), v.bytes.len(), "{}", v.name);
        let mut buf = [0xffu8; MAX_FRAME_LEN + 4];
        assert_eq!(r.emit(&mut buf), Ok(v.bytes.len()), "{}", v.name);
        assert_eq!(&buf[..v.bytes.len()], v.bytes, "{}", v.name);
        assert!(
            buf[v.bytes.len()..].iter().all(|&b| b == 0xff),
            "{}",
            v.name
        );
        let mut short = vec![0u8; v.bytes.len() - 1];
        assert_eq!(r.emit(&mut short), Err(Error::BufferTooShort), "{}", v.name);
    }
}

#[test]
fn reply_truncated_prefixes() {
    for v in reply_vectors() {
        let db = Address::new(0x09).unwrap();
        for n in 0..v.bytes.len() {
            let p = &v.bytes[..n];
            assert_eq!(Reply::parse(p), Err(Error::Truncated), "{}: {n}", v.name);
            assert_eq!(
                Reply::parse_read(db, false, p),
                Err(Error::Truncated),
                "{}: {n}",
                v.name
            );
            assert!(ReplyFrame::new_checked(p).is_err(), "{}: {n}", v.name);
        }
    }
}

#[test]
fn reply_value_accessors() {
    assert_eq!(Reply::parse(&REPLY_INPUT).unwrap().value_u8(), Ok(1));
    assert_eq!(Reply::parse(&REPLY_ANALOG).unwrap().value_u16(), Ok(512));
    assert_eq!(
        Reply::parse(&REPLY_ANALOG).unwrap().value_u8(),
        Err(Error::BadLength)
    );
    assert_eq!(
        Reply::parse(&REPLY_INPUT).unwrap().value_u16(),
        Err(Error::BadLength)
    );
    assert_eq!(
        Reply::parse(&REPLY_PING).unwrap().value_u32(),
        Err(Error::BadLength)
    );
    let width = Reply {
        seq: 0,
        status: Status::Ok,
        payload: &[0xf0, 0x05, 0x00, 0x00],
    };
    assert_eq!(width.value_u32(), Ok(1520));
    assert_eq!(
        Reply::status_only(5, Status::Busy),
        Reply {
            seq: 5,
            status: Status::Busy,
            payload: &[]
        }
    );
}

/// Reply vectors with PEC over `db << 1 | 1` (DB 0x09: address byte 0x13).
static PEC_REPLIES: &[(&[u8], u8)] = &[
    (&[0x09, 0x00, 0x01, 0x01], 0x20),
    (
        &[
            0x02, 0x00, 0x0a, 0x01, 0x00, 0x01, 0x00, 0x03, 0x04, 0x04, 0xff, 0x01, 0x0c,
        ],
        0x76,
    ),
];

#[test]
fn reply_pec() {
    let db = Address::new(0x09).unwrap();
    for &(frame, pec_byte) in PEC_REPLIES {
        assert_eq!(pec::compute(0x13, frame), pec_byte);
        let r = Reply::parse(frame).unwrap();
        let mut buf = [0xffu8; MAX_FRAME_LEN];
        let n = r.emit_with_pec(db, &mut buf).unwrap();
        assert_eq!(&buf[..n - 1], frame);
        assert_eq!(buf[n - 1], pec_byte);
        // The read is longer than the frame: padding after the PEC is ignored.
        assert_eq!(Reply::parse_read(db, true, &buf), Ok(r));
        // The PEC byte itself missing.
        assert_eq!(Reply::parse_read(db, true, frame), Err(Error::Truncated));
        // A read from another board's address does not check.
        let other = Address::new(0x0a).unwrap();
        assert!(matches!(
            Reply::parse_read(other, true, &buf[..n]),
            Err(Error::PecMismatch { .. })
        ));
    }
    for v in reply_vectors() {
        let r = reply_repr(&v);
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = r.emit_with_pec(db, &mut buf).unwrap();
        assert_eq!(
            &buf[v.bytes.len()..n],
            &check_bytes(0x13, v.bytes)[..],
            "{}",
            v.name
        );
        assert_eq!(Reply::parse_read(db, true, &buf[..n]), Ok(r), "{}", v.name);
        for k in 0..n {
            assert!(
                Reply::parse_read(db, true, &buf[..k]).is_err(),
                "{}: {k}",
                v.name
            );
        }
        let mut bad = buf;
        bad[n - 1] ^= 1;
        let want = if pec::check_len(v.bytes.len()) == 1 {
            Error::PecMismatch {
                received: buf[n - 1] ^ 1,
                computed: buf[n - 1],
            }
        } else {
            Error::CrcMismatch
        };
        assert_eq!(
            Reply::parse_read(db, true, &bad[..n]),
            Err(want),
            "{}",
            v.name
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Events
// ---------------------------------------------------------------------------------------------

struct EventVector {
    name: &'static str,
    bytes: &'static [u8],
    source: u8,
    kind: EventKind,
    kind_byte: u8,
    port_byte: u8,
    seq: u8,
    status: Status,
    payload: &'static [u8],
}

static EV_PIN_CHANGE: [u8; 7] = [0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01];
static EV_ANALOG_THRESHOLD: [u8; 9] = [0x09, 0x02, 0x82, 0x08, 0x00, 0x03, 0x89, 0x03, 0x00];
static EV_DEFERRED_REPLY: [u8; 10] = [0x09, 0x03, 0x85, 0x0b, 0x00, 0x04, 0xf0, 0x05, 0x00, 0x00];
static EV_DEFERRED_TIMEOUT: [u8; 6] = [0x09, 0x03, 0x85, 0x0c, 0x0c, 0x00];
static EV_FAILSAFE: [u8; 8] = [0x09, 0x04, 0x00, 0x09, 0x00, 0x02, 0xf4, 0x01];
static EV_REJECTED: [u8; 6] = [0x09, 0x05, 0x80, 0x14, 0x06, 0x00];
static EV_OVERFLOW: [u8; 8] = [0x09, 0x06, 0x00, 0x0a, 0x00, 0x02, 0x03, 0x00];
static EV_BOOT: [u8; 16] = [
    0x09, 0x07, 0x00, 0x00, 0x00, 0x0a, 0x01, 0x00, 0x01, 0x00, 0x03, 0x04, 0x04, 0xff, 0x01, 0x0c,
];
static EV_UNKNOWN_KIND: [u8; 6] = [0x09, 0x20, 0x00, 0x0b, 0x00, 0x00];
static EV_INTERNAL: [u8; 7] = [0x00, 0x01, 0x81, 0x0c, 0x00, 0x01, 0x00];

fn event_vectors() -> Vec<EventVector> {
    vec![
        EventVector {
            name: "pin change",
            bytes: &EV_PIN_CHANGE,
            source: 0x09,
            kind: EventKind::PinChange,
            kind_byte: 1,
            port_byte: 0x80,
            seq: 7,
            status: Status::Ok,
            payload: &[1],
        },
        EventVector {
            name: "analog threshold",
            bytes: &EV_ANALOG_THRESHOLD,
            source: 0x09,
            kind: EventKind::AnalogThreshold,
            kind_byte: 2,
            port_byte: 0x82,
            seq: 8,
            status: Status::Ok,
            payload: &[0x89, 0x03, 0x00],
        },
        EventVector {
            name: "deferred reply (pulse width 1520 us)",
            bytes: &EV_DEFERRED_REPLY,
            source: 0x09,
            kind: EventKind::DeferredReply,
            kind_byte: 3,
            port_byte: 0x85,
            seq: 0x0b,
            status: Status::Ok,
            payload: &[0xf0, 0x05, 0x00, 0x00],
        },
        EventVector {
            name: "deferred reply, timeout",
            bytes: &EV_DEFERRED_TIMEOUT,
            source: 0x09,
            kind: EventKind::DeferredReply,
            kind_byte: 3,
            port_byte: 0x85,
            seq: 0x0c,
            status: Status::Timeout,
            payload: &[],
        },
        EventVector {
            name: "failsafe tripped",
            bytes: &EV_FAILSAFE,
            source: 0x09,
            kind: EventKind::FailsafeTripped,
            kind_byte: 4,
            port_byte: 0,
            seq: 9,
            status: Status::Ok,
            payload: &[0xf4, 0x01],
        },
        EventVector {
            name: "rejected output",
            bytes: &EV_REJECTED,
            source: 0x09,
            kind: EventKind::Rejected,
            kind_byte: 5,
            port_byte: 0x80,
            seq: 0x14,
            status: Status::WrongPortKind,
            payload: &[],
        },
        EventVector {
            name: "overflow",
            bytes: &EV_OVERFLOW,
            source: 0x09,
            kind: EventKind::Overflow,
            kind_byte: 6,
            port_byte: 0,
            seq: 0x0a,
            status: Status::Ok,
            payload: &[0x03, 0x00],
        },
        EventVector {
            name: "boot",
            bytes: &EV_BOOT,
            source: 0x09,
            kind: EventKind::Boot,
            kind_byte: 7,
            port_byte: 0,
            seq: 0,
            status: Status::Ok,
            payload: &IDENTITY_BYTES,
        },
        EventVector {
            name: "unknown kind",
            bytes: &EV_UNKNOWN_KIND,
            source: 0x09,
            kind: EventKind::Unknown(0x20),
            kind_byte: 0x20,
            port_byte: 0,
            seq: 0x0b,
            status: Status::Ok,
            payload: &[],
        },
        EventVector {
            name: "pin change from the internal DB",
            bytes: &EV_INTERNAL,
            source: 0x00,
            kind: EventKind::PinChange,
            kind_byte: 1,
            port_byte: 0x81,
            seq: 0x0c,
            status: Status::Ok,
            payload: &[0],
        },
    ]
}

fn event_repr(v: &EventVector) -> Event<'static> {
    Event {
        source: Address::new(v.source).unwrap(),
        kind: v.kind,
        pin: x10_microcode::PinRef::from_byte(v.port_byte),
        seq: v.seq,
        status: v.status,
        payload: v.payload,
    }
}

#[test]
fn event_vectors_cover_every_kind() {
    let mut kinds: Vec<u8> = event_vectors().iter().map(|v| v.kind_byte).collect();
    kinds.sort();
    kinds.dedup();
    assert_eq!(kinds, [1, 2, 3, 4, 5, 6, 7, 0x20]);
}

#[test]
fn event_view_getters() {
    for v in event_vectors() {
        let f = EventFrame::new_checked(v.bytes).unwrap();
        assert_eq!(f.source(), v.source, "{}", v.name);
        assert_eq!(f.kind(), v.kind, "{}", v.name);
        assert_eq!(f.kind().to_byte(), v.kind_byte, "{}", v.name);
        assert_eq!(f.pin_ref().to_byte(), v.port_byte, "{}", v.name);
        assert_eq!(f.seq(), v.seq, "{}", v.name);
        assert_eq!(f.status(), v.status, "{}", v.name);
        assert_eq!(f.payload_len() as usize, v.payload.len(), "{}", v.name);
        assert_eq!(f.frame_len(), v.bytes.len(), "{}", v.name);
        assert_eq!(f.payload(), v.payload, "{}", v.name);
        assert_eq!(f.into_inner(), v.bytes, "{}", v.name);
    }
}

#[test]
fn event_view_setters_into_dirty_buffer() {
    for v in event_vectors() {
        let mut buf = vec![0xffu8; v.bytes.len()];
        let mut f = EventFrame::new_unchecked(&mut buf[..]);
        f.set_source(v.source);
        f.set_kind(v.kind);
        f.set_pin_ref(x10_microcode::PinRef::from_byte(v.port_byte));
        f.set_seq(v.seq);
        f.set_status(v.status);
        f.set_payload_len(v.payload.len() as u8);
        f.payload_mut().copy_from_slice(v.payload);
        assert_eq!(buf, v.bytes, "{}", v.name);
    }
}

#[test]
fn event_parse_and_emit() {
    for v in event_vectors() {
        let e = event_repr(&v);
        assert_eq!(Event::parse(v.bytes), Ok(e), "{}", v.name);
        assert_eq!(e.buffer_len(), v.bytes.len(), "{}", v.name);
        let mut buf = [0xffu8; MAX_FRAME_LEN + 4];
        assert_eq!(e.emit(&mut buf), Ok(v.bytes.len()), "{}", v.name);
        assert_eq!(&buf[..v.bytes.len()], v.bytes, "{}", v.name);
        assert!(
            buf[v.bytes.len()..].iter().all(|&b| b == 0xff),
            "{}",
            v.name
        );
        let mut short = vec![0u8; v.bytes.len() - 1];
        assert_eq!(e.emit(&mut short), Err(Error::BufferTooShort), "{}", v.name);
        // Trailing bytes are not part of an event.
        let mut long = v.bytes.to_vec();
        long.push(0);
        assert_eq!(Event::parse(&long), Err(Error::BadLength), "{}", v.name);
    }
}

#[test]
fn event_truncated_prefixes() {
    for v in event_vectors() {
        for n in 0..v.bytes.len() {
            let p = &v.bytes[..n];
            assert_eq!(Event::parse(p), Err(Error::Truncated), "{}: {n}", v.name);
            assert!(EventFrame::new_checked(p).is_err(), "{}: {n}", v.name);
        }
    }
}

/// Event vectors with PEC over `mb << 1` (MB at 0x10: address byte 0x20).
static PEC_EVENTS: &[(&[u8], u8)] = &[
    (&[0x09, 0x01, 0x80, 0x07, 0x00, 0x01, 0x01], 0x95),
    (
        &[0x09, 0x03, 0x85, 0x0b, 0x00, 0x04, 0xf0, 0x05, 0x00, 0x00],
        0x63,
    ),
];

#[test]
fn event_pec() {
    let mb = Address::new(0x10).unwrap();
    for &(frame, pec_byte) in PEC_EVENTS {
        assert_eq!(pec::compute(0x20, frame), pec_byte);
        let e = Event::parse(frame).unwrap();
        let mut buf = [0xffu8; MAX_FRAME_LEN];
        let n = e.emit_with_pec(mb, &mut buf).unwrap();
        assert_eq!(&buf[..n - 1], frame);
        assert_eq!(buf[n - 1], pec_byte);
        assert_eq!(Event::parse_with_pec(mb, &buf[..n]), Ok(e));
    }
    for v in event_vectors() {
        let e = event_repr(&v);
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = e.emit_with_pec(mb, &mut buf).unwrap();
        assert_eq!(
            &buf[v.bytes.len()..n],
            &check_bytes(0x20, v.bytes)[..],
            "{}",
            v.name
        );
        assert_eq!(Event::parse_with_pec(mb, &buf[..n]), Ok(e), "{}", v.name);
        for k in 0..n {
            assert!(
                Event::parse_with_pec(mb, &buf[..k]).is_err(),
                "{}: {k}",
                v.name
            );
        }
        // Sent to another MB address, the PEC does not check.
        let other = Address::new(0x11).unwrap();
        assert!(matches!(
            Event::parse_with_pec(other, &buf[..n]),
            Err(Error::PecMismatch { .. } | Error::CrcMismatch)
        ));
    }
}

// ---------------------------------------------------------------------------------------------
// Payloads: batch items and results, identify, diagnostics, event_enable, scan
// ---------------------------------------------------------------------------------------------

#[test]
fn batch_items() {
    let data = &BATCH[4..];
    let b = Batch::new_checked(data).unwrap();
    assert_eq!(b.as_bytes(), data);
    assert_eq!(b.len(), 3);
    assert!(!b.is_empty());
    assert_eq!(b.reply_capacity(), 8);
    let items: Vec<Op<'_>> = b.iter().collect();
    assert_eq!(
        items,
        [
            Op::DigitalWrite(a(1).pin(Pin::B), Level::High),
            Op::PwmDuty(a(1).pin(Pin::A), 200),
            Op::AnalogRead(s(1)),
        ]
    );
    // The writer produces the same bytes, into a dirty buffer.
    let mut buf = [0xffu8; 40];
    let mut w = BatchWriter::new(&mut buf);
    for op in &items {
        w.push(op).unwrap();
    }
    assert_eq!(w.finish().unwrap().as_bytes(), data);
    // Every cut inside an item is an error; cuts at item boundaries are shorter batches.
    for n in 0..data.len() {
        let got = Batch::new_checked(&data[..n]);
        match n {
            0 => assert_eq!(got, Err(Error::BadLength)),
            3 => assert_eq!(got.unwrap().len(), 1),
            7 => assert_eq!(got.unwrap().len(), 2),
            _ => assert_eq!(got, Err(Error::Truncated), "cut at {n}"),
        }
    }
}

#[test]
fn batch_results() {
    let got: Vec<_> = BatchResults::new(&BATCH_RESULTS).collect();
    assert_eq!(
        got,
        [
            Ok(BatchItem {
                status: Status::Ok,
                value: &[]
            }),
            Ok(BatchItem {
                status: Status::Ok,
                value: &[]
            }),
            Ok(BatchItem {
                status: Status::Ok,
                value: &[0x00, 0x02]
            }),
        ]
    );
    // Emitting the same results into a dirty buffer.
    let mut buf = [0xffu8; 8];
    let mut n = 0;
    n += BatchResults::emit(&mut buf[n..], Status::Ok, &[]).unwrap();
    n += BatchResults::emit(&mut buf[n..], Status::Ok, &[]).unwrap();
    n += BatchResults::emit(&mut buf[n..], Status::Ok, &[0x00, 0x02]).unwrap();
    assert_eq!(n, 8);
    assert_eq!(buf, BATCH_RESULTS);
    assert_eq!(
        BatchResults::emit(&mut [0u8; 3], Status::Ok, &[1, 2]),
        Err(Error::BufferTooShort)
    );
    assert_eq!(
        BatchResults::emit(&mut [0u8; 300], Status::Ok, &[0u8; 256]),
        Err(Error::TooLong)
    );
    // A result with a failed item: status bad_argument, no value.
    let mixed = [0x09, 0x00, 0x00, 0x01, 0x01];
    let got: Vec<_> = BatchResults::new(&mixed).collect();
    assert_eq!(
        got,
        [
            Ok(BatchItem {
                status: Status::BadArgument,
                value: &[]
            }),
            Ok(BatchItem {
                status: Status::Ok,
                value: &[1]
            }),
        ]
    );
    // Every cut inside a result ends the iteration with one error.
    for n in 1..BATCH_RESULTS.len() {
        let got: Vec<_> = BatchResults::new(&BATCH_RESULTS[..n]).collect();
        let complete = matches!(n, 2 | 4);
        if complete {
            assert!(got.iter().all(Result::is_ok), "cut at {n}");
        } else {
            assert_eq!(got.last(), Some(&Err(Error::Truncated)), "cut at {n}");
            assert_eq!(got.iter().filter(|r| r.is_err()).count(), 1);
        }
    }
}

fn identity() -> Identity {
    Identity {
        protocol_version: 1,
        firmware: [0, 1, 0],
        board: BoardKind::PICO,
        sensor_ports: 4,
        actuator_ports: 4,
        capabilities: Capabilities(0x01ff),
        adc_bits: 12,
    }
}

#[test]
fn identity_payload() {
    let id = identity();
    assert_eq!(Identity::parse(&IDENTITY_BYTES), Ok(id));
    assert_eq!(id.to_bytes(), IDENTITY_BYTES);
    assert_eq!(id.board.name(), "pico");
    assert!(id
        .capabilities
        .has(Capabilities::PULSE_IN | Capabilities::PWM_PULSE_WIDTH));
    assert!(!Capabilities(0x0004).has(Capabilities::PEC));
    for n in 0..IDENTITY_BYTES.len() {
        assert_eq!(Identity::parse(&IDENTITY_BYTES[..n]), Err(Error::BadLength));
    }
    assert_eq!(Identity::parse(&[0u8; 11]), Err(Error::BadLength));
    // The identify reply and the boot event carry exactly these bytes.
    assert_eq!(
        Reply::parse(&REPLY_IDENTIFY).unwrap().payload,
        IDENTITY_BYTES
    );
    assert_eq!(Event::parse(&EV_BOOT).unwrap().payload, IDENTITY_BYTES);
    for (code, name) in [
        (0, "unknown"),
        (1, "simulated"),
        (2, "internal"),
        (3, "pico"),
        (4, "g431"),
        (5, "c011"),
        (6, "unknown"),
    ] {
        assert_eq!(BoardKind(code).name(), name);
    }
}

#[test]
fn diagnostics_payload() {
    let d = Diagnostics {
        frames_ok: 1000,
        bad_length: 2,
        unknown_function: 1,
        unknown_operand: 0,
        port_errors: 3,
        wrong_address: 0,
        pec_errors: 5,
        other_errors: 0,
        events_sent: 42,
        event_retries: 7,
        events_dropped: 0,
        arbitration_lost: 4,
        failsafe_trips: 1,
        no_request_reads: 258,
    };
    assert_eq!(Diagnostics::LEN, 28);
    assert_eq!(Diagnostics::parse(&DIAGNOSTICS_BYTES), Ok(d));
    assert_eq!(d.to_bytes(), DIAGNOSTICS_BYTES);
    assert_eq!(d.values(), [1000, 2, 1, 0, 3, 0, 5, 0, 42, 7, 0, 4, 1, 258]);
    assert_eq!(Diagnostics::from_values(d.values()), d);
    assert_eq!(x10_microcode::DIAGNOSTIC_NAMES.len(), 14);
    assert_eq!(x10_microcode::DIAGNOSTIC_NAMES[0], "frames_ok");
    assert_eq!(x10_microcode::DIAGNOSTIC_NAMES[13], "no_request_reads");
    for n in 0..DIAGNOSTICS_BYTES.len() {
        assert_eq!(
            Diagnostics::parse(&DIAGNOSTICS_BYTES[..n]),
            Err(Error::BadLength)
        );
    }
}

#[test]
fn event_config_payload() {
    let data = &EVENT_ENABLE[4..];
    let cfg = EventConfig {
        rising: true,
        falling: true,
        analog_window: true,
        low: 100,
        high: 900,
    };
    assert_eq!(EventConfig::parse(data), Ok(cfg));
    assert_eq!(cfg.to_bytes(), *data);
    assert_eq!(EventConfig::OFF.to_bytes(), [0, 0, 0, 0, 0]);
    assert_eq!(EventConfig::parse(&[0; 5]), Ok(EventConfig::OFF));
    let rising_only = EventConfig {
        rising: true,
        ..EventConfig::OFF
    };
    assert_eq!(rising_only.to_bytes(), [0x01, 0, 0, 0, 0]);
    let falling_only = EventConfig {
        falling: true,
        ..EventConfig::OFF
    };
    assert_eq!(falling_only.to_bytes(), [0x02, 0, 0, 0, 0]);
    for n in 0..data.len() {
        assert_eq!(EventConfig::parse(&data[..n]), Err(Error::BadLength));
    }
}

#[test]
fn scan_payload() {
    let mut analog = [0u16; ScanResult::MAX_PORTS];
    analog[..4].copy_from_slice(&[100, 200, 300, 400]);
    let scan = ScanResult {
        ports: 4,
        digital: 0x0096,
        analog,
    };
    assert_eq!(ScanResult::parse(&SCAN_BYTES), Ok(scan));
    assert_eq!(scan.len(), SCAN_BYTES.len());
    assert!(!scan.is_empty());
    let mut buf = [0xffu8; 28];
    assert_eq!(scan.emit(&mut buf), Ok(11));
    assert_eq!(buf[..11], SCAN_BYTES);
    assert!(buf[11..].iter().all(|&b| b == 0xff));
    assert_eq!(scan.emit(&mut [0u8; 10]), Err(Error::BufferTooShort));
    // 0x96 = 0b1001_0110: S1 A0 B1, S2 A1 B0, S3 A1 B0, S4 A0 B1.
    let levels: Vec<_> = (1..=4)
        .flat_map(|p| [scan.digital(p, 0), scan.digital(p, 1)])
        .collect();
    assert_eq!(
        levels,
        [
            Some(false),
            Some(true),
            Some(true),
            Some(false),
            Some(true),
            Some(false),
            Some(false),
            Some(true)
        ]
    );
    assert_eq!(scan.digital(0, 0), None);
    assert_eq!(scan.digital(5, 0), None);
    assert_eq!(scan.digital(1, 2), None);
    assert_eq!(scan.analog(1), Some(100));
    assert_eq!(scan.analog(4), Some(400));
    assert_eq!(scan.analog(0), None);
    assert_eq!(scan.analog(5), None);
    for n in 0..SCAN_BYTES.len() {
        assert_eq!(ScanResult::parse(&SCAN_BYTES[..n]), Err(Error::BadLength));
    }
    // No sensor ports at all: just the count and the (zero) digital word.
    let empty = ScanResult::default();
    assert!(empty.is_empty());
    let mut buf = [0xffu8; 3];
    assert_eq!(empty.emit(&mut buf), Ok(3));
    assert_eq!(buf, [0, 0, 0]);
    assert_eq!(ScanResult::parse(&[0, 0, 0]), Ok(empty));
}

/// The check bytes after `frame` on the wire: its PEC byte, or its CRC-16 (little-endian) when
/// the frame is longer than 13 bytes.
fn check_bytes(addr_byte: u8, frame: &[u8]) -> Vec<u8> {
    let c = pec::check(addr_byte, frame).to_le_bytes();
    c[..pec::check_len(frame.len())].to_vec()
}

/// `Op::validate` checks the port operations and the data-less system operations without
/// encoding them (issue 27); here it gives the round trip's answer (`validate_encoded`: the
/// data emitted and parsed back) for every port byte and the edge values of each argument.
#[test]
fn validate_without_encoding_agrees_with_the_round_trip() {
    let mut checked = 0;
    let mut refused = 0;
    for byte in 0..=255u8 {
        let pin = PinRef::from_byte(byte);
        let port = pin.port;
        let mut ops = vec![
            Op::Ping,
            Op::Heartbeat,
            Op::Scan,
            Op::DigitalRead(pin),
            Op::DigitalWrite(pin, Level::Low),
            Op::DigitalWrite(pin, Level::High),
            Op::AnalogRead(port),
        ];
        for duty in [0, 1, 128, 255] {
            ops.push(Op::PwmDuty(pin, duty));
        }
        for v in [0, 1, 50, 1500, u16::MAX] {
            ops.push(Op::PwmPulseWidth(pin, v));
            ops.push(Op::PwmFrequency(port, v));
        }
        for op in ops {
            assert_eq!(op.validate(), op.validate_encoded(), "{op:?}");
            checked += 1;
            refused += usize::from(op.validate().is_err());
        }
    }
    // Both answers occur: wrong port kinds and a zero frequency are refused.
    assert_eq!(checked, 256 * 21);
    assert!(refused > 256 * 4, "{refused}");
}
