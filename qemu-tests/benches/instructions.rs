//! Instructions per operation of the portable X10 cores on real Cortex-M instruction sets.
//!
//! Run by `bench.sh` (`cargo bench --target <t> --bench instructions`) under QEMU with
//! `-icount shift=0,sleep=off` (see `qemu-run.sh`): every instruction advances virtual time by
//! exactly 1 ns, and SysTick counts virtual time. So the virtual nanoseconds spent in `N`
//! repetitions of an operation, less those of the same loop with an empty body, divided by `N`,
//! are the instructions one operation executes, the same on every run. They are instruction
//! counts, not cycles: QEMU models neither flash wait states nor multi-cycle instructions.
//!
//! One defmt line per figure: `bench | <what> | <instructions>`. A first figure calibrates
//! the method: a block of 32 `nop`s must measure exactly 32, or the run fails. Before
//! timing, every operation is run once and its outcome checked (the exact reply bytes, an `Ok`
//! call), so the figures are those of the success path. A failed check exits with code 1.
#![no_std]
#![no_main]

use core::future::Future;
use core::hint::black_box;

use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use firmware_db::{Daughterboard, DbConfig, PortError, Ports};
use firmware_mb::{MbConfig, Motherboard, X10};
use x10_devices::LinkError;
use x10_hal::time::Clock;
use x10_microcode::{pec, Address, BoardKind, Edge, Level, Op, Payload, PinRef, Port, Request};
use x10_qemu_tests::clock::{ms_and_ticks, TICKS_PER_MS};
use x10_qemu_tests::{block_on, QemuClock};

/// Repetitions per figure.
const N: u32 = 10_000;

/// The external daughterboard's address in the interpreter figures.
const DB: Address = match Address::external(0x09) {
    Ok(a) => a,
    Err(_) => panic!("0x09 is an external address"),
};
/// The motherboard's own address (its internal daughterboard is at 0).
const MB: Address = match Address::external(0x08) {
    Ok(a) => a,
    Err(_) => panic!("0x08 is an external address"),
};

/// Sensor port 1 (S1) and its pin A; actuator port 1 (A1) pin A.
const S1: Port = Port::from_byte(0x80);
const S1_A: PinRef = PinRef::from_byte(0x80);
const A1_A: PinRef = PinRef::from_byte(0x00);

/// The thesis's four measured operations (Table 4.2), as the simulator's latency report
/// runs them: `io high A1.A`, `io input S1.A`, `pwm duty A1.A 128`, `analog read S1`.
struct Case {
    name: &'static str,
    op: Op<'static>,
    /// The request to board 0x09 with sequence number 0x2A.
    frame: &'static [u8],
    /// The reply bytes read back; `None`: an output, written without a read.
    reply: Option<&'static [u8]>,
}

const CASES: [Case; 4] = [
    Case {
        name: "digitalOut",
        op: Op::DigitalWrite(A1_A, Level::High),
        frame: &[0x12, 0x09, 0x00, 0x2A],
        reply: None,
    },
    Case {
        name: "digitalIn",
        op: Op::DigitalRead(S1_A),
        frame: &[0x10, 0x09, 0x80, 0x2A],
        reply: Some(&[0x2A, 0x00, 0x01, 0x01]),
    },
    Case {
        name: "pwm",
        op: Op::PwmDuty(A1_A, 128),
        frame: &[0x20, 0x09, 0x00, 0x2A, 128],
        reply: None,
    },
    Case {
        name: "analog",
        op: Op::AnalogRead(S1),
        frame: &[0x30, 0x09, 0x80, 0x2A],
        reply: Some(&[0x2A, 0x00, 0x02, 0x23, 0x01]),
    },
];

/// What the fake digital input reads (high) and the fake ADC converts (0x0123).
const LEVEL: bool = true;
const ANALOG: u16 = 0x0123;

/// Ports that do nothing: writes only hand their value to [`black_box`] (so the compiler
/// must compute it, as it must for a register write), reads return a constant through it.
struct NoopPorts;

impl Ports for NoopPorts {
    fn sensor_ports(&self) -> u8 {
        2
    }

    fn actuator_ports(&self) -> u8 {
        2
    }

    fn adc_bits(&self) -> u8 {
        12
    }

    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        black_box(pin);
        Ok(Level::from_bool(black_box(LEVEL)))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        black_box((pin, level));
        Ok(())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        black_box((pin, duty));
        Ok(())
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        black_box((port, hz));
        Ok(())
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        black_box((pin, us));
        Ok(())
    }

    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        black_box(port);
        Ok(black_box(ANALOG))
    }

    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        black_box((pin, edge, timeout_ms));
        Err(PortError::Unsupported)
    }
}

type Db = Daughterboard<NoopRawMutex, NoopPorts>;
type Mb = Motherboard<NoopPorts>;

/// Virtual time in ns, to one SysTick tick (62.5 ns on the micro:bit, 40 ns on the MPS2):
/// the clock's milliseconds and the SysTick ticks into the current one, read together
/// ([`ms_and_ticks`], which also reads them right near a reload). Not inlined, so that it
/// takes no registers from the timed loops around it (inlined, it once made the 32-nop loop
/// reload `N` in every iteration, and the calibration read 33).
#[inline(never)]
fn now_ns() -> u64 {
    let (ms, ticks) = ms_and_ticks();
    ms * 1_000_000 + u64::from(ticks) * 1_000_000 / u64::from(TICKS_PER_MS)
}

/// Virtual ns of `N` calls of `f`.
#[inline(always)]
fn measure(mut f: impl FnMut(u32)) -> u64 {
    let t0 = now_ns();
    for i in 0..N {
        f(black_box(i));
    }
    now_ns().wrapping_sub(t0)
}

/// Virtual ns of `N` awaits of `f`, in one task (one poll: nothing here waits).
#[inline(always)]
fn measure_async(mut f: impl AsyncFnMut(u32)) -> u64 {
    block_on(async {
        let t0 = now_ns();
        for i in 0..N {
            f(black_box(i)).await;
        }
        now_ns().wrapping_sub(t0)
    })
}

/// Runs `f` to completion while `mb`'s worker for its internal daughterboard runs beside it,
/// in one `select` under the suites' executor, as the runtime's task and a robot task share
/// an executor on a board.
#[inline(always)]
fn with_worker<F: Future>(mb: &'static Mb, f: F) -> F::Output {
    match block_on(select(mb.run_internal_requests(), f)) {
        Either::First(never) => never,
        Either::Second(out) => out,
    }
}

/// The motherboard, in a static. Not inlined: the value is built on the stack before it is
/// moved into its static, and a place for it in `main`'s frame (6 KiB and more) would stay
/// taken for the whole run; here it is freed on return.
#[inline(never)]
fn motherboard() -> &'static Mb {
    match cortex_m::singleton!(: Mb = Mb::new(MbConfig::new(MB), NoopPorts)) {
        Some(mb) => mb,
        None => {
            check(false, "the motherboard is created once");
            semihosting::process::exit(1)
        }
    }
}

/// One call to `mb`'s internal daughterboard through the robot programs' handle, its
/// worker running beside it (the direct path does not need it; it is there to show that).
#[inline(always)]
fn internal_call(x10: X10, mb: &'static Mb, op: Op<'static>) -> Result<Payload, LinkError> {
    with_worker(mb, x10.call(Address::INTERNAL, op))
}

/// Virtual ns of `N` calls of `op` to the internal daughterboard through `x10` (the robot
/// programs' handle), awaited one after the other in one task: each call yields once
/// (`block_on` polls it again at once) and runs the internal board in the caller. The
/// runtime's worker is not polled beside it: it takes no part in these calls, and an
/// executor polls only the tasks that were woken.
#[inline(always)]
fn measure_internal_calls(x10: X10, op: Op<'static>) -> u64 {
    block_on(async {
        let t0 = now_ns();
        for i in 0..N {
            black_box(i);
            // The operation by reference through `black_box`, then copied as a program
            // copies one (an `Op` by value through it costs a byte-wise `memmove` on the M0).
            let op = *black_box(&op);
            black_box(x10.call(Address::INTERNAL, op).await.is_ok());
        }
        now_ns().wrapping_sub(t0)
    })
}

/// Instructions per repetition: (`total` − `empty`) / `N`, rounded.
fn per_op(total: u64, empty: u64) -> u32 {
    let n = u64::from(N);
    let per = (total.saturating_sub(empty) + n / 2) / n;
    u32::try_from(per).unwrap_or(u32::MAX)
}

fn report(what: &str, instructions: u32) {
    defmt::info!("bench | {=str} | {=u32}", what, instructions);
}

/// Ends the run with exit code 1 when a check fails.
fn check(ok: bool, what: &str) {
    if !ok {
        defmt::error!("bench: check failed: {=str}", what);
        semihosting::process::exit(1);
    }
}

/// Formats "`prefix`: `name`" into `buf` (labels are short; a longer one is cut).
fn label<'a>(buf: &'a mut heapless::String<64>, prefix: &str, name: &str) -> &'a str {
    buf.clear();
    for part in [prefix, ": ", name] {
        for c in part.chars() {
            if buf.push(c).is_err() {
                return buf.as_str();
            }
        }
    }
    buf.as_str()
}

#[entry]
fn main() -> ! {
    QemuClock::start();
    // Right after the start the counter reads 0 until its first reload, one tick later:
    // that reading would be taken for the end of a millisecond.
    while SYST::get_current() == 0 {}
    let mut text = heapless::String::<64>::new();

    // The method: an empty loop, and 32 nops in the same loop (written out: an assembler
    // `.rept` would hide their size from the compiler's branch-range estimate).
    let empty = measure(|i| {
        black_box(i);
    });
    let nops = measure(|i| {
        black_box(i);
        // SAFETY: 32 nops: no memory, no stack, no flags touched.
        unsafe {
            core::arch::asm!(
                concat!(
                    "nop\nnop\nnop\nnop\nnop\nnop\nnop\nnop\n",
                    "nop\nnop\nnop\nnop\nnop\nnop\nnop\nnop\n",
                    "nop\nnop\nnop\nnop\nnop\nnop\nnop\nnop\n",
                    "nop\nnop\nnop\nnop\nnop\nnop\nnop\nnop",
                ),
                options(nomem, nostack, preserves_flags)
            )
        };
    });
    let calibration = per_op(nops, empty);
    if calibration != 32 {
        defmt::error!(
            "bench: {=u32} nops measured {=u64} ns, the empty loop {=u64} ns",
            N,
            nops,
            empty
        );
    }
    report("calibration: 32 nop", calibration);
    check(
        calibration == 32,
        "32 nops must measure 32 instructions (is QEMU running with -icount shift=0?)",
    );

    // The wire protocol: parse and emit of each request, PEC over a 5-byte frame.
    for case in &CASES {
        let parsed = Request::parse(case.frame);
        let expected = Request {
            db: DB,
            seq: 0x2A,
            op: case.op,
        };
        check(parsed == Ok(expected), "parse gives the request");
        let t = measure(|_| {
            black_box(Request::parse(black_box(case.frame)).is_ok());
        });
        report(
            label(&mut text, "parse request", case.name),
            per_op(t, empty),
        );
    }
    for case in &CASES {
        let req = Request {
            db: DB,
            seq: 0x2A,
            op: case.op,
        };
        let mut buf = [0u8; 8];
        let n = req.emit(&mut buf).unwrap_or(0);
        check(buf.get(..n) == Some(case.frame), "emit gives the frame");
        let t = measure(|_| {
            let req = black_box(&req);
            black_box(req.emit(black_box(&mut buf)).is_ok());
        });
        report(
            label(&mut text, "emit request", case.name),
            per_op(t, empty),
        );
    }
    let pwm_frame = CASES[2].frame;
    let addr = DB.addr_byte(false);
    check(
        pec::compute(addr, pwm_frame) == crc8_smbus(addr, pwm_frame),
        "PEC is the SMBus CRC-8",
    );
    let t = measure(|_| {
        black_box(pec::compute(black_box(addr), black_box(pwm_frame)));
    });
    report("PEC compute, 5-byte frame", per_op(t, empty));

    // The clock the motherboard reads twice per call (SysTick here; a board's differs).
    let t = measure(|_| {
        black_box(QemuClock.now());
    });
    report("clock read (QemuClock::now)", per_op(t, empty));

    // The daughterboard interpreter at 0x09 on no-op ports: what its bus listener does for
    // one transaction (a write; for a read also the reply it answers with).
    let db: &'static Db = match cortex_m::singleton!(
        : Db = Db::new(NoopPorts, DbConfig::new(DB, BoardKind::SIMULATED))
    ) {
        Some(db) => db,
        None => {
            check(false, "the daughterboard is created once");
            semihosting::process::exit(1)
        }
    };
    let empty_async = measure_async(async |i| {
        black_box(i);
    });
    for case in &CASES {
        let mut buf = [0u8; 8];
        let before = db.diagnostics().frames_ok;
        db.handle_write(case.frame, case.reply.is_some());
        check(
            db.diagnostics().frames_ok == before + 1,
            "the DB executes it",
        );
        if let Some(reply) = case.reply {
            let n = db.take_reply(&mut buf);
            check(
                buf.get(..n) == Some(reply),
                "the DB replies the exact bytes",
            );
        }
        check(db.events_queued() == 0, "the DB rejects nothing");
        let t = measure_async(async |_| {
            db.handle_write(black_box(case.frame), case.reply.is_some());
            if case.reply.is_some() {
                black_box(db.take_reply(black_box(&mut buf)));
            }
        });
        report(
            label(&mut text, "DB interpreter", case.name),
            per_op(t, empty_async),
        );
    }

    // One call through the motherboard runtime to its internal daughterboard (address 0):
    // slot and sequence number, encode, the request queued for the runtime's worker and its
    // deadline timer set, the caller suspended, the worker polled (the interpreter, the reply
    // parsed, the result signalled), the caller polled again, the slot freed. The worker
    // (`Motherboard::run_internal_requests`) runs beside the caller in one `select`, as it
    // runs beside robot tasks on a board: since robot programs take a concrete `X10` handle,
    // the runtime's worker task serves every internal request, and no call runs the
    // interpreter in the caller's own future any more. Subtracted: the empty async loop,
    // as for the interpreter rows. Not counted: an executor's own work to wake and switch
    // tasks (the suites' executor polls in a loop and ignores wakers).
    let mb = motherboard();
    mb.serve_internal_directly();
    let x10 = mb.handle();
    for case in &CASES {
        let want: &[u8] = match case.reply {
            Some(reply) => reply.get(3..).unwrap_or(&[]),
            None => &[],
        };
        let got = internal_call(x10, mb, case.op);
        check(
            got.as_ref().map(|p| &p[..]) == Ok(want),
            "the internal call succeeds with the value",
        );
        let t = measure_internal_calls(x10, case.op);
        report(
            label(&mut text, "MB call, internal DB", case.name),
            per_op(t, empty_async),
        );
    }
    let d = mb.diagnostics();
    check(
        d.requests == d.completed && d.timeouts == 0,
        "every internal call completed",
    );

    // What the loops themselves cost (subtracted above).
    report("empty loop (subtracted)", per_op(empty, 0));
    report("empty async loop (subtracted)", per_op(empty_async, 0));
    semihosting::process::exit(0)
}

/// CRC-8/SMBUS bit by bit (polynomial 0x07, initial 0), independent of the `crc` crate.
fn crc8_smbus(addr: u8, frame: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in core::iter::once(&addr).chain(frame) {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}
