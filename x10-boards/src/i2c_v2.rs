//! The decisions of the STM32 I2C v2 adapter ([`crate::stm32`]), as pure functions of the
//! block's status register, tested on the host.
//!
//! embassy-stm32 0.6 leaves flags behind that its next call misreads (the line numbers are of
//! `embassy-stm32-0.6.0/src/i2c/v2.rs`):
//!
//! * STOPF after its own controller transfers: `write` sets CR2.STOP after TC and returns
//!   (1017-1023), a read ends with AUTOEND and returns when the DMA has the last byte, before
//!   the STOP (1128-1131), and after a NACK the block sends STOP on its own; nobody clears
//!   STOPF. The next `respond_to_write` checks STOPF before `slave_start` (1983-1987) and
//!   returns `total_len - 2 * total_len`; `respond_to_read` returns `LeftoverBytes` at once.
//! * NACKF/BERR/ARLO/OVR raised while nobody polls are read by the first poll of the next
//!   controller call (957-968): a stale BERR becomes `Error::Bus`.
//!
//! So the adapter clears the stale flags at the two moments where every flag set is known to be
//! stale ([`before_controller`], [`before_target`]) and recovers a stuck bus ([`recover_bus`],
//! UM10204 §3.1.16).
//!
//! The controller side is the adapter's own, on the registers (issue 11 item 8): the driver's
//! `write` spins synchronously on BUSY before its START (207-210, up to its 20 ms timeout when
//! a master starts in the window after the adapter's BUSY check), waits synchronously for TC
//! after a DMA write (1017), and its reads return before their STOP (1128-1131). The adapter
//! instead polls ISR with a yield between polls and decides each move with
//! [`controller_step`]; a transfer ends on its own STOP (AUTOEND), and what a failure leaves to
//! do is [`after_controller`]. The register sequence is the driver's own blocking one
//! (`master_write`, `write_internal`, `read_internal`, 151-227 and 450-572) without its spins.
//!
//! Issue 21: BUSY, set by a START and cleared only by a STOP or PE=0, no longer refuses every
//! transfer for ever after one START without its STOP ([`before_controller`], [`Hold`]); the
//! first START after a block reset waits for quiet lines; the target side is the adapter's own
//! too ([`receive_step`], [`transmit_step`]): the driver's `respond_to_write` and
//! `respond_to_read` held the bus for their 20 ms timeout on a write of 39 bytes or more and on
//! a read past their buffer (1946-2157: once the DMA is done nothing wakes their poll); the bus
//! clear waits at least t_LOW per phase ([`clear_half_period_us`]).

use x10_hal::bus::BusError;

/// ISR bits (RM0440 §37.7.7, RM0490 §23.7.7: the same on the G4 and the C0).
pub mod isr {
    /// Transmit interrupt status: TXDR wants the next byte.
    pub const TXIS: u32 = 1 << 1;
    /// Receive data register not empty.
    pub const RXNE: u32 = 1 << 2;
    /// Address matched (target).
    pub const ADDR: u32 = 1 << 3;
    /// NACK received.
    pub const NACKF: u32 = 1 << 4;
    /// STOP detected.
    pub const STOPF: u32 = 1 << 5;
    /// Transfer complete (controller, NBYTES done with AUTOEND and RELOAD off).
    pub const TC: u32 = 1 << 6;
    /// Transfer complete reload: NBYTES done with RELOAD on, SCL stretched (as a target
    /// receiver: before the last byte's ACK bit, RM0440 §39.4.8 "Target byte control mode").
    pub const TCR: u32 = 1 << 7;
    /// Bus error (misplaced START or STOP).
    pub const BERR: u32 = 1 << 8;
    /// Arbitration lost.
    pub const ARLO: u32 = 1 << 9;
    /// Overrun/underrun (target, NOSTRETCH only).
    pub const OVR: u32 = 1 << 10;
    /// Bus busy (START seen, no STOP yet).
    pub const BUSY: u32 = 1 << 15;
    /// Transfer direction of the address match: set when the controller reads.
    pub const DIR: u32 = 1 << 16;
}

/// ICR bits: each clears the ISR flag at the same position.
pub mod icr {
    /// Clears ADDR (and ends the clock stretching of an address match).
    pub const ADDRCF: u32 = 1 << 3;
    /// Clears NACKF.
    pub const NACKCF: u32 = 1 << 4;
    /// Clears STOPF.
    pub const STOPCF: u32 = 1 << 5;
    /// Clears BERR.
    pub const BERRCF: u32 = 1 << 8;
    /// Clears ARLO.
    pub const ARLOCF: u32 = 1 << 9;
    /// Clears OVR.
    pub const OVRCF: u32 = 1 << 10;
}

/// Every flag a previous transfer can leave behind (never ADDR: that one belongs to the
/// transfer that is stretching the clock now).
pub const STALE: u32 = icr::STOPCF | icr::NACKCF | icr::BERRCF | icr::ARLOCF | icr::OVRCF;

/// What to do before a controller transfer's START (see [`before_controller`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Before {
    /// The ICR bits to write: the flags earlier transfers left.
    pub icr: u32,
    /// When not 0: start only if SCL and SDA are both seen high, without a break, for this
    /// many µs ([`Hold`]); otherwise answer [`BusError::ArbitrationLost`].
    pub quiet_us: u32,
    /// After the quiet lines: reset the block (PE off and on) first, its BUSY is stale.
    pub reset: bool,
}

/// An SCL period at `frequency_hz`, in µs, rounded up (at least 1).
pub fn scl_period_us(frequency_hz: u32) -> u32 {
    1_000_000_u32.div_ceil(frequency_hz.max(1)).max(1)
}

/// How long SCL and SDA must both stay high before the first START after a block reset: two
/// SCL periods, and at least four of the longest sample gaps ([`max_gap_us`]) so that the
/// window holds several samples (20 µs at 100 kHz, 12 µs at 400 kHz). No master in the middle
/// of a transfer leaves SCL high that long (it drives SCL low once per bit, and a stretching
/// target holds it low), so a transfer that began before the reset, whose START the block has
/// not seen, shows within the window.
pub fn quiet_us(frequency_hz: u32) -> u32 {
    (2 * scl_period_us(frequency_hz)).max(4 * max_gap_us(frequency_hz))
}

/// How long SCL and SDA must both stay high, with BUSY set, for BUSY to count as stale (a
/// START whose STOP never came: a master reset or unplugged mid-transfer, a glitch on SDA
/// while SCL was high): two byte times of 9 SCL periods each.
pub fn stale_us(frequency_hz: u32) -> u32 {
    18 * scl_period_us(frequency_hz)
}

/// Before a controller call: what to clear and check, or why not to start.
///
/// * This node addressed (ADDR, SCL held): it must answer first;
///   [`BusError::ArbitrationLost`], the runtime listens and retries after its backoff.
/// * BUSY: another master's transfer, or a stale BUSY (BUSY clears only on a STOP or PE=0,
///   RM0440 §37.7.7, so one START without its STOP would refuse every transfer for ever,
///   issue 21 item 1). Start only when both lines stay high for [`stale_us`], after a block
///   reset; a line seen low is a live transfer: `ArbitrationLost` (unless SDA stays low under
///   a high SCL as long: a stuck target, which the adapter clocks free first).
/// * The block reset since its last START (`fresh`: PE off and on clears BUSY without the
///   block having seen a START already on the wire, issue 21 item 3): start only when both
///   lines stay high for [`quiet_us`].
/// * Otherwise no transfer is under way: every flag set belongs to an earlier one and is
///   cleared.
///
/// # Errors
/// [`BusError::ArbitrationLost`] while this node is addressed.
pub fn before_controller(isr: u32, fresh: bool, frequency_hz: u32) -> Result<Before, BusError> {
    if isr & isr::ADDR != 0 {
        return Err(BusError::ArbitrationLost);
    }
    let busy = isr & isr::BUSY != 0;
    Ok(Before {
        icr: isr & STALE,
        quiet_us: if busy {
            stale_us(frequency_hz)
        } else if fresh {
            quiet_us(frequency_hz)
        } else {
            0
        },
        reset: busy,
    })
}

/// The answer of one [`Hold`] sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Held {
    /// The lines held the wanted levels, without a break, for the whole window.
    Yes,
    /// A line left the wanted level, or the window could not complete in time.
    No,
    /// Not decided yet: sample again at once.
    Wait,
}

/// Watches SCL and SDA for a wanted pair of levels held without a break for a window, from
/// samples of the pins taken in a tight loop with their time in µs (a 1 MHz clock).
///
/// Every sample must show the wanted levels. Two samples more than `max_gap_us` apart (an
/// interrupt ran in between) restart the window, since a change could hide in the gap; the
/// window is only as good as the samples are dense, which [`max_gap_us`] bounds. With a 1 µs
/// clock a window of `need` µs is complete when the last sample is at least `need + 1` µs
/// after the first (the first may have been taken at the very end of its tick). When the
/// window has not completed within four windows (samples keep being interrupted), the
/// answer is [`Held::No`].
#[derive(Clone, Copy, Debug)]
pub struct Hold {
    scl: bool,
    sda: bool,
    need: u64,
    max_gap: u64,
    start: u64,
    since: u64,
    last: u64,
}

impl Hold {
    /// Wants SCL at `scl` and SDA at `sda` (true: high) for `need_us`, samples at most
    /// `max_gap_us` apart, starting at `now_us`.
    pub fn new(scl: bool, sda: bool, need_us: u32, max_gap_us: u32, now_us: u64) -> Hold {
        Hold {
            scl,
            sda,
            need: u64::from(need_us) + 1,
            max_gap: u64::from(max_gap_us),
            start: now_us,
            since: now_us,
            last: now_us,
        }
    }

    /// One sample: the levels of SCL and SDA read at `now_us`.
    pub fn sample(&mut self, now_us: u64, scl: bool, sda: bool) -> Held {
        if (scl, sda) != (self.scl, self.sda) {
            return Held::No;
        }
        if now_us.saturating_sub(self.last) > self.max_gap {
            self.since = now_us;
        }
        self.last = now_us;
        if now_us.saturating_sub(self.since) >= self.need {
            Held::Yes
        } else if now_us.saturating_sub(self.start) > 4 * self.need {
            Held::No
        } else {
            Held::Wait
        }
    }
}

/// The longest gap between two pin samples of a [`Hold`] at `frequency_hz`, in µs of a 1 MHz
/// clock: the whole µs of the shortest low phase of SCL (t_LOW of UM10204 Table 10: 4.7 µs
/// at 100 kHz, 1.3 µs at 400 kHz, 0.5 µs at 1 MHz), at least 3. A measured gap of `g` µs is
/// under `g + 1` µs, so at 100 kHz (4 µs) no SCL low phase fits between two samples. The floor
/// of 3 µs is one pass of the sampling loop (two GPIO reads, a read of the time driver and
/// the 64-bit compares: estimated at up to about 2 µs on the C011 at 48 MHz, not measured),
/// whose own gaps must not restart the window for ever; at 400 kHz such a gap could hide one
/// low phase, but a window holds several SCL periods and their lows, and a START misplaced
/// all the same ends as a bus error before any data byte, which is retried
/// ([`transfer_error`]) and followed by another reset and quiet window.
pub fn max_gap_us(frequency_hz: u32) -> u32 {
    (t_low_ns(frequency_hz) / 1000).max(3)
}

/// UM10204 Table 10: the shortest SCL low phase (t_LOW) at `frequency_hz`, in ns.
pub fn t_low_ns(frequency_hz: u32) -> u32 {
    match frequency_hz {
        0..=100_000 => 4_700,
        100_001..=400_000 => 1_300,
        _ => 500,
    }
}

/// UM10204 Table 10: the shortest SCL high phase (t_HIGH) at `frequency_hz`, in ns.
pub fn t_high_ns(frequency_hz: u32) -> u32 {
    match frequency_hz {
        0..=100_000 => 4_000,
        100_001..=400_000 => 600,
        _ => 260,
    }
}

/// Half an SCL period of the bus clear, in µs, as passed to `embassy_time::block_for` on a
/// 1 MHz tick: that wait lasts more than `d - 1` µs, never `d`, so `d` is one more than the
/// longer of half an SCL period and t_LOW (t_HIGH is shorter) rounded up: 6 µs at 100 kHz,
/// 3 µs at 400 kHz, 2 µs at 1 MHz.
pub fn clear_half_period_us(frequency_hz: u32) -> u32 {
    let half = 500_000_u32.div_ceil(frequency_hz.max(1));
    let t = t_low_ns(frequency_hz)
        .max(t_high_ns(frequency_hz))
        .div_ceil(1000);
    half.max(t) + 1
}

/// The half periods [`recover_bus`] waits at most: one to settle, two per clock pulse (nine),
/// four for the STOP.
pub const CLEAR_HALF_PERIODS: u32 = 1 + 2 * 9 + 4;

/// Before answering an address match (ADDR set, SCL stretched): the ICR bits to write. No STOP
/// and no error of this transfer can have happened yet (the clock is held), so STOPF, NACKF,
/// BERR, ARLO and OVR are all from before.
pub fn before_target(isr: u32) -> u32 {
    if isr & isr::ADDR != 0 {
        isr & STALE
    } else {
        0
    }
}

/// What a controller transfer's outcome leaves to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum After {
    /// A STOP is on its way (the block sends it by itself after a NACK, RM0440 §37.4.9): wait
    /// for STOPF and clear it, then report the result.
    WaitStop,
    /// Nothing: the transfer ended with its STOP (seen and cleared), or arbitration was lost
    /// (the block is a target again and the bus belongs to the winner; ARLO cleared and TXDR
    /// flushed).
    Done,
    /// Reset the block (PE off and on): a bus error (misplaced START or STOP) leaves its state
    /// machine where it struck.
    Reset,
    /// The transfer did not end in time (a target stretching SCL for ever, or a flag that never
    /// came): send STOP, wait for it, and recover the bus when it does not come.
    Abort,
}

/// The outcome of a controller transfer, or of a target-side call of the driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Done.
    Ok,
    /// Address or data byte not acknowledged (NACKF, either phase).
    Nack,
    /// Arbitration lost.
    Arbitration,
    /// Bus error.
    Bus,
    /// Timeout.
    Timeout,
    /// Overrun, CRC or zero-length: errors of the driver's own bookkeeping (target side).
    Other,
}

/// What to do after a controller transfer ended with `outcome`, and the ICR bits to write
/// first (the flag that ended it).
pub fn after_controller(outcome: Outcome) -> (u32, After) {
    match outcome {
        // STOPF was cleared when it ended the transfer.
        Outcome::Ok => (0, After::Done),
        Outcome::Nack => (icr::NACKCF, After::WaitStop),
        Outcome::Arbitration => (icr::ARLOCF, After::Done),
        Outcome::Bus | Outcome::Other => (icr::BERRCF, After::Reset),
        Outcome::Timeout => (0, After::Abort),
    }
}

/// How far a controller transfer has come: `write` bytes out, then (when `read` > 0) a
/// repeated START and `read` bytes in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// Bytes to write.
    pub write: usize,
    /// Bytes written to TXDR so far.
    pub sent: usize,
    /// Bytes to read after the repeated START (0: a plain write).
    pub read: usize,
    /// Bytes taken from RXDR so far.
    pub received: usize,
    /// The read phase has been started.
    pub restarted: bool,
}

impl Progress {
    /// A write of `write` bytes followed by a read of `read` bytes (0: none).
    pub fn new(write: usize, read: usize) -> Progress {
        Progress {
            write,
            read,
            ..Progress::default()
        }
    }

    /// Everything written and read.
    pub fn complete(&self) -> bool {
        self.sent == self.write && self.received == self.read
    }

    /// Counts a step once the adapter has carried it out (a byte written or read, the read
    /// phase started).
    pub fn advance(&mut self, step: Step) {
        match step {
            Step::Send => self.sent += 1,
            Step::Receive => self.received += 1,
            Step::Restart => self.restarted = true,
            Step::Wait | Step::Finished | Step::Failed(_) => {}
        }
    }
}

/// The next move of a controller transfer, decided from ISR (see [`controller_step`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Nothing to do yet: poll again (after a yield).
    Wait,
    /// Write the next byte to TXDR.
    Send,
    /// Take the next byte from RXDR.
    Receive,
    /// The write phase is complete (TC): start the read phase with a repeated START.
    Restart,
    /// STOPF after every byte: clear it; the transfer succeeded.
    Finished,
    /// The transfer failed; see [`after_controller`].
    Failed(Outcome),
}

/// The CR2 value that starts a phase of a controller transfer (RM0440 §37.7.2): 7-bit address
/// `addr` in SADD[7:1], `len` bytes (NBYTES), reading or writing (RD_WRN), START, and AUTOEND
/// when the phase ends the transfer (the block then sends STOP after the last byte by itself).
/// `None` for a phase longer than NBYTES holds (255; X10 frames are at most 36 bytes).
pub fn cr2_start(addr: u8, len: usize, read: bool, autoend: bool) -> Option<u32> {
    let n = u8::try_from(len).ok()?;
    let mut v = (u32::from(addr & 0x7F) << 1) | (u32::from(n) << 16) | (1 << 13);
    if read {
        v |= 1 << 10;
    }
    if autoend {
        v |= 1 << 25;
    }
    Some(v)
}

/// The CR2 values that start both phases of a controller transfer of `write` bytes to `addr`
/// and then `read` bytes back (the read phase's value is 0 when `read` is 0), all checked
/// before the START: `None` when a phase is longer than NBYTES holds (255), so that nothing
/// goes out (a read phase refused after the write phase would leave the block with SCL held
/// after TC and no STOP).
pub fn cr2_phases(addr: u8, write: usize, read: usize) -> Option<(u32, u32)> {
    let first = cr2_start(addr, write, false, read == 0)?;
    let second = if read == 0 {
        0
    } else {
        cr2_start(addr, read, true, true)?
    };
    Some((first, second))
}

/// CR2 bits of the target side (RM0440 §37.7.2).
pub mod cr2 {
    /// START (controller only; never written by the target side).
    pub const START: u32 = 1 << 13;
    /// STOP (controller only).
    pub const STOP: u32 = 1 << 14;
    /// NACK the current received byte (target receiver).
    pub const NACK: u32 = 1 << 15;
    /// NBYTES, bits 16 to 23.
    pub const NBYTES: u32 = 0xFF << 16;
    /// RELOAD: TCR after NBYTES bytes, SCL stretched until NBYTES is written again.
    pub const RELOAD: u32 = 1 << 24;
    /// AUTOEND (controller only).
    pub const AUTOEND: u32 = 1 << 25;
    /// PECBYTE.
    pub const PECBYTE: u32 = 1 << 26;
}

/// The CR2 value, from its value `old`, that arms the target side for `nbytes` bytes with
/// RELOAD on (TCR after them, SCL stretched: RM0440 §39.4.8 "Target byte control mode" and
/// "Target with clock stretching", the same paragraphs in RM0490; the driver sets SBC) and, when `nack`, NACKs the byte received last. Writing NBYTES ends a
/// TCR stretch. START, STOP, AUTOEND and PECBYTE are written 0 (writing 1 to START or STOP
/// would act as a controller).
pub fn target_cr2(old: u32, nbytes: u8, nack: bool) -> u32 {
    let keep =
        old & !(cr2::START | cr2::STOP | cr2::NACK | cr2::NBYTES | cr2::AUTOEND | cr2::PECBYTE);
    let nack = if nack { cr2::NACK } else { 0 };
    keep | cr2::RELOAD | (u32::from(nbytes) << 16) | nack
}

/// The next move of the target side receiving a write (see [`receive_step`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RxStep {
    /// Nothing yet: poll again after a yield (the block stretches SCL while RXDR is full).
    Wait,
    /// Take the byte in RXDR.
    Take,
    /// TCR: the receive count (NBYTES, [`crate::RX_LEN`]: one byte more than the longest
    /// frame) is reached, SCL is stretched before that byte's ACK: NACK it, so that the
    /// controller stops at once ([`BusError::Overrun`] after the STOP).
    Refuse,
    /// STOPF: the write is over; clear STOPF.
    Stop,
    /// ADDR: a repeated START addressed this node again (left set for what follows).
    Restart,
    /// A bus error, lost arbitration or overrun: the block is reset.
    Failed,
}

/// Decides the target receiver's next move from ISR: errors first, then a byte (before
/// STOPF: the last byte and the STOP can show together), then TCR, then the end.
pub fn receive_step(isr: u32) -> RxStep {
    if isr & (isr::BERR | isr::ARLO | isr::OVR) != 0 {
        RxStep::Failed
    } else if isr & isr::RXNE != 0 {
        RxStep::Take
    } else if isr & isr::TCR != 0 {
        RxStep::Refuse
    } else if isr & isr::STOPF != 0 {
        RxStep::Stop
    } else if isr & isr::ADDR != 0 {
        RxStep::Restart
    } else {
        RxStep::Wait
    }
}

/// What a received write was, from its byte count `n` and ISR at its end (`restart`: ended by
/// an address match instead of a STOP): `Some(true)` a write-read (the read follows),
/// `Some(false)` a write, `None` an over-long write (`n` reached `cap`: a byte past the longest
/// frame came, and was refused).
pub fn received(n: usize, cap: usize, isr: u32, restart: bool) -> Option<bool> {
    if n >= cap {
        None
    } else {
        Some(restart && isr & isr::DIR != 0)
    }
}

/// The next move of the target side answering a read (see [`transmit_step`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TxStep {
    /// Nothing yet: poll again after a yield.
    Wait,
    /// TXIS: write the next byte (the reply's, then 0xFF for as long as the controller reads).
    Send,
    /// TCR: 255 bytes went out, SCL is stretched: arm NBYTES again.
    Reload,
    /// NACKF: the controller's last byte; clear NACKF, flush TXDR and wait for the end.
    Nacked,
    /// STOPF (cleared) or a new address match (ADDR, left set): the read is over.
    Done,
    /// A bus error, lost arbitration or underrun: the block is reset.
    Failed,
}

/// Decides the target transmitter's next move from ISR; `nacked` once the controller's NACK
/// was seen (nothing more is sent after it).
pub fn transmit_step(isr: u32, nacked: bool) -> TxStep {
    if isr & (isr::BERR | isr::ARLO | isr::OVR) != 0 {
        TxStep::Failed
    } else if isr & isr::NACKF != 0 {
        TxStep::Nacked
    } else if isr & (isr::STOPF | isr::ADDR) != 0 {
        TxStep::Done
    } else if nacked {
        TxStep::Wait
    } else if isr & isr::TXIS != 0 {
        TxStep::Send
    } else if isr & isr::TCR != 0 {
        TxStep::Reload
    } else {
        TxStep::Wait
    }
}

/// Byte `i` of a reply: the reply's own, then 0xFF (the trait's padding, for any length).
pub fn reply_byte(reply: &[u8], i: usize) -> u8 {
    reply.get(i).copied().unwrap_or(0xFF)
}

/// Decides a controller transfer's next move from ISR.
///
/// Errors first (ARLO or ADDR, then BERR, then NACKF: after a lost arbitration nothing else of
/// this transfer counts), then data (RXNE before STOPF: the last byte read and the STOP can
/// show together), then TC of the write phase of a write-read, then STOPF. A STOP before every
/// byte moved (another master's STOP, or ours cut short) is a bus error. ADDR means another
/// master won the bus (it started first, or won arbitration) and addresses this node, which is
/// a target now: arbitration lost too; ADDR is left set for the target side, whose answer
/// (ADDRCF) also clears a START still pending (RM0440 §37.7.2, START).
pub fn controller_step(isr: u32, p: &Progress) -> Step {
    if isr & (isr::ARLO | isr::ADDR) != 0 {
        return Step::Failed(Outcome::Arbitration);
    }
    if isr & isr::BERR != 0 {
        return Step::Failed(Outcome::Bus);
    }
    if isr & isr::NACKF != 0 {
        return Step::Failed(Outcome::Nack);
    }
    if isr & isr::RXNE != 0 && p.restarted && p.received < p.read {
        return Step::Receive;
    }
    if isr & isr::TXIS != 0 && p.sent < p.write {
        return Step::Send;
    }
    if isr & isr::TC != 0 && p.sent == p.write && p.read > 0 && !p.restarted {
        return Step::Restart;
    }
    if isr & isr::STOPF != 0 {
        return if p.complete() {
            Step::Finished
        } else {
            Step::Failed(Outcome::Bus)
        };
    }
    Step::Wait
}

/// The error the runtimes see for a controller outcome. A NACK is [`BusError::Nack`] in the
/// address phase and in a data byte alike (the runtime retries it); this is the mapping the
/// RP2040 adapter should use too (issue 11 item 7).
///
/// # Errors
/// The [`BusError`] of every outcome but [`Outcome::Ok`].
pub fn controller_error(outcome: Outcome) -> Result<(), BusError> {
    match outcome {
        Outcome::Ok => Ok(()),
        Outcome::Nack => Err(BusError::Nack),
        Outcome::Arbitration => Err(BusError::ArbitrationLost),
        Outcome::Timeout => Err(BusError::Timeout),
        Outcome::Bus | Outcome::Other => Err(BusError::Bus),
    }
}

/// The error the runtimes see for a controller transfer that ended with `outcome` after
/// `progress`: [`controller_error`], except that a bus error (a misplaced START or STOP, BERR,
/// or a STOP before every byte moved) before any data byte was written or read is
/// [`BusError::ArbitrationLost`]. Then nothing of the transfer was delivered: another master's
/// START or STOP collided with this node's address phase, which is what a lost arbitration
/// is, and the runtime retries it after its backoff (firmware-mb does not retry `Bus`). The
/// block is still reset ([`after_controller`]).
///
/// # Errors
/// The [`BusError`] of every outcome but [`Outcome::Ok`].
pub fn transfer_error(outcome: Outcome, progress: &Progress) -> Result<(), BusError> {
    if outcome == Outcome::Bus && progress.sent == 0 && progress.received == 0 {
        Err(BusError::ArbitrationLost)
    } else {
        controller_error(outcome)
    }
}

/// Whether a failed target-side call of the driver (`listen`, `respond_to_write`,
/// `respond_to_read`) leaves the block to be reset. Its timeout drops the transfer in the
/// middle (`v2.rs` 1929-1940) with SCL maybe stretched and ADDR or NBYTES half done, and its
/// errors leave the state machine where they struck: all but a NACK (the normal end of a read,
/// which the driver handles itself) reset the block.
pub fn target_needs_reset(outcome: Outcome) -> bool {
    !matches!(outcome, Outcome::Ok | Outcome::Nack)
}

/// The longest wait for the STOP that ends this node's own transfer, in µs: two byte times
/// (18 SCL periods each) at `frequency_hz`, at least 10 µs. After a write the STOP follows TC
/// within a bit time; after a read, the NACK and the STOP follow the last byte. The wait is
/// polled with yields, never a synchronous spin.
pub fn stop_wait_us(frequency_hz: u32) -> u32 {
    (36_000_000 / frequency_hz.max(1)).max(10)
}

/// A bus's two lines, driven open-drain by hand (the recovery of UM10204 §3.1.16).
pub trait Lines {
    /// Releases (true) or pulls low (false) SCL.
    fn scl(&mut self, release: bool);
    /// Releases (true) or pulls low (false) SDA.
    fn sda(&mut self, release: bool);
    /// SDA's level.
    fn sda_high(&mut self) -> bool;
    /// Waits half an SCL period.
    fn half_period(&mut self);
}

/// UM10204 §3.1.16 "Bus clear": while a target holds SDA low, send up to nine clock pulses on
/// SCL (the target finishes the byte it thinks it is sending, sees no ACK and releases SDA),
/// then a STOP (SDA low → high while SCL is high). Returns whether SDA is free at the end;
/// when it is not, the caller gives up with [`BusError::Bus`].
pub fn recover_bus(l: &mut impl Lines) -> bool {
    l.sda(true);
    l.scl(true);
    l.half_period();
    let mut pulses = 0;
    while !l.sda_high() && pulses < 9 {
        l.scl(false);
        l.half_period();
        l.scl(true);
        l.half_period();
        pulses += 1;
    }
    // STOP: SDA low while SCL is low, SCL high, then SDA high.
    l.scl(false);
    l.half_period();
    l.sda(false);
    l.half_period();
    l.scl(true);
    l.half_period();
    l.sda(true);
    l.half_period();
    l.sda_high()
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;

    #[test]
    fn stale_flags_are_cleared_only_on_an_idle_bus_before_a_controller_call() {
        let all = isr::STOPF | isr::NACKF | isr::BERR | isr::ARLO | isr::OVR;
        let go = |icr| Before {
            icr,
            quiet_us: 0,
            reset: false,
        };
        assert_eq!(before_controller(all, false, 100_000), Ok(go(STALE)));
        assert_eq!(
            before_controller(isr::STOPF, false, 100_000),
            Ok(go(icr::STOPCF))
        );
        assert_eq!(before_controller(0, false, 100_000), Ok(go(0)));
        // This node addressed (ADDR): it answers first; retry.
        assert_eq!(
            before_controller(isr::ADDR | isr::BUSY, false, 100_000),
            Err(BusError::ArbitrationLost)
        );
        assert_eq!(
            before_controller(isr::ADDR, true, 100_000),
            Err(BusError::ArbitrationLost)
        );
    }

    /// Issue 21 item 1: BUSY set is no longer a refusal for ever. Before, every call with BUSY
    /// answered `ArbitrationLost`, and a START without its STOP (BUSY clears only on a STOP
    /// or PE=0) stopped every transfer of the node until a power cycle. Now BUSY asks for two
    /// byte times of quiet lines, then a block reset.
    #[test]
    fn a_busy_bus_is_checked_for_a_stale_busy_not_refused_for_ever() {
        let b = before_controller(isr::BUSY | isr::STOPF, false, 100_000);
        assert_eq!(
            b,
            Ok(Before {
                icr: icr::STOPCF,
                quiet_us: 180,
                reset: true
            })
        );
        assert_eq!(stale_us(400_000), 54);
        assert_eq!(stale_us(1_000_000), 18);
        // A live transfer pulls SCL low within an SCL period: the check answers No at once.
        let mut h = Hold::new(true, true, 180, max_gap_us(100_000), 1_000);
        assert_eq!(h.sample(1_000, true, true), Held::Wait);
        assert_eq!(h.sample(1_004, true, false), Held::No);
        // Stuck high for 180 µs: stale.
        let mut h = Hold::new(true, true, 180, max_gap_us(100_000), 1_000);
        let mut t = 1_000;
        let mut last = Held::Wait;
        while last == Held::Wait {
            last = h.sample(t, true, true);
            t += 1;
        }
        assert_eq!((last, t - 1), (Held::Yes, 1_181));
    }

    /// Issue 21 item 3: after a block reset (BUSY cleared without the block having seen a
    /// START already on the wire), the first START waits for two SCL periods of quiet lines.
    #[test]
    fn the_first_start_after_a_reset_wants_two_quiet_scl_periods() {
        assert_eq!(
            before_controller(0, true, 100_000),
            Ok(Before {
                icr: 0,
                quiet_us: 20,
                reset: false
            })
        );
        assert_eq!(
            before_controller(0, true, 400_000).map(|b| b.quiet_us),
            Ok(12)
        );
        assert_eq!(quiet_us(1_000_000), 12);
        // Another master's transfer under way: SCL is low once per bit.
        let mut h = Hold::new(true, true, 20, max_gap_us(100_000), 0);
        assert_eq!(h.sample(0, true, true), Held::Wait);
        assert_eq!(h.sample(2, true, true), Held::Wait);
        assert_eq!(h.sample(5, false, true), Held::No);
        // Quiet: Yes after 21 µs of a 1 MHz clock (20 µs at least).
        let mut h = Hold::new(true, true, 20, max_gap_us(100_000), 0);
        for t in 0..21 {
            assert_eq!(h.sample(t, true, true), Held::Wait);
        }
        assert_eq!(h.sample(21, true, true), Held::Yes);
    }

    #[test]
    fn a_gap_between_samples_restarts_the_window_and_too_many_give_up() {
        // 100 kHz: samples at most 4 µs apart.
        assert_eq!(max_gap_us(100_000), 4);
        assert_eq!(max_gap_us(400_000), 3);
        assert_eq!(max_gap_us(1_000_000), 3);
        let mut h = Hold::new(true, true, 20, 4, 0);
        assert_eq!(h.sample(0, true, true), Held::Wait);
        assert_eq!(h.sample(15, true, true), Held::Wait); // gap of 15: restart at 15
        assert_eq!(h.sample(35, true, true), Held::Wait); // gap again: restart at 35
        for t in 36..=55 {
            assert_eq!(h.sample(t, true, true), Held::Wait, "{t}");
        }
        assert_eq!(h.sample(56, true, true), Held::Yes);
        // Interrupted again and again: no answer after four windows is No.
        let mut h = Hold::new(true, true, 20, 4, 0);
        let mut t = 0;
        let mut last = Held::Wait;
        while last == Held::Wait {
            last = h.sample(t, true, true);
            t += 10;
        }
        assert_eq!((last, t - 10), (Held::No, 90));
        // Wanted levels other than both high: SDA stuck low under a high SCL.
        let mut h = Hold::new(true, false, 3, 1, 0);
        for t in 0..4 {
            assert_eq!(h.sample(t, true, false), Held::Wait);
        }
        assert_eq!(h.sample(4, true, false), Held::Yes);
        let mut h = Hold::new(true, false, 3, 1, 0);
        assert_eq!(h.sample(1, true, true), Held::No);
    }

    /// Issue 21 item 6: `block_for(d)` on a 1 MHz tick lasts more than `d - 1` µs only, so the
    /// bus clear's half period was 4-5 µs at 100 kHz (t_LOW 4.7 µs) and 0-1 µs at 400 kHz
    /// (t_LOW 1.3 µs) with `(500_000 / hz).max(1)`.
    #[test]
    fn bus_clear_phases_last_at_least_t_low() {
        for hz in crate::BUS_FREQUENCIES {
            let d = clear_half_period_us(hz);
            assert!((d - 1) * 1000 >= t_low_ns(hz), "{hz} Hz: {d}");
            assert!((d - 1) * 1000 >= t_high_ns(hz), "{hz} Hz: {d}");
            assert!((d - 1) * 2 >= 1_000_000 / hz, "{hz} Hz: {d}");
        }
        assert_eq!(clear_half_period_us(100_000), 6);
        assert_eq!(clear_half_period_us(400_000), 3);
        assert_eq!(clear_half_period_us(1_000_000), 2);
        assert_eq!(CLEAR_HALF_PERIODS, 23);
    }

    #[test]
    fn stale_flags_are_cleared_while_an_address_match_holds_the_clock() {
        // The case: STOPF left by our own write, then a master writes to this node.
        assert_eq!(before_target(isr::ADDR | isr::STOPF), icr::STOPCF);
        assert_eq!(
            before_target(isr::ADDR | isr::BUSY | isr::NACKF | isr::BERR),
            icr::NACKCF | icr::BERRCF
        );
        // No address match: no clearing (a transfer may be running).
        assert_eq!(before_target(isr::STOPF | isr::BUSY), 0);
        // ADDR itself is never cleared here: the driver clears it when it answers.
        assert_eq!(before_target(isr::ADDR) & isr::ADDR, 0);
    }

    #[test]
    fn outcomes() {
        use Outcome::*;
        assert_eq!(after_controller(Ok), (0, After::Done));
        assert_eq!(after_controller(Nack), (icr::NACKCF, After::WaitStop));
        assert_eq!(after_controller(Arbitration), (icr::ARLOCF, After::Done));
        assert_eq!(after_controller(Bus), (icr::BERRCF, After::Reset));
        assert_eq!(after_controller(Timeout), (0, After::Abort));
        assert_eq!(controller_error(Nack), Err(BusError::Nack));
        assert_eq!(
            controller_error(Arbitration),
            Err(BusError::ArbitrationLost)
        );
        assert_eq!(controller_error(Timeout), Err(BusError::Timeout));
        assert_eq!(controller_error(Bus), Err(BusError::Bus));
        assert_eq!(controller_error(Ok), Result::Ok(()));
        assert!(target_needs_reset(Timeout));
        assert!(target_needs_reset(Bus));
        assert!(target_needs_reset(Other));
        assert!(!target_needs_reset(Nack));
        assert!(!target_needs_reset(Ok));
    }

    /// Issue 21 item 3: a misplaced START or STOP during the address phase (another master's
    /// transfer colliding) was `Bus`, which firmware-mb does not retry; nothing was delivered,
    /// so it is a lost arbitration now. After a data byte it stays `Bus`.
    #[test]
    fn a_bus_error_before_any_data_byte_is_a_lost_arbitration() {
        let mut p = Progress::new(3, 2);
        assert_eq!(
            transfer_error(Outcome::Bus, &p),
            Err(BusError::ArbitrationLost)
        );
        assert_eq!(transfer_error(Outcome::Nack, &p), Err(BusError::Nack));
        assert_eq!(transfer_error(Outcome::Timeout, &p), Err(BusError::Timeout));
        p.advance(Step::Send);
        assert_eq!(transfer_error(Outcome::Bus, &p), Err(BusError::Bus));
        let mut p = Progress::new(0, 2);
        p.advance(Step::Restart);
        p.advance(Step::Receive);
        assert_eq!(transfer_error(Outcome::Bus, &p), Err(BusError::Bus));
        assert_eq!(transfer_error(Outcome::Ok, &p), Ok(()));
        assert_eq!(after_controller(Outcome::Bus).1, After::Reset);
    }

    #[test]
    fn cr2_starts_a_phase() {
        // 0x08, 5 bytes, write, AUTOEND: SADD 0x10, NBYTES 5, START, AUTOEND.
        assert_eq!(cr2_start(0x08, 5, false, true), Some(0x0205_2010));
        // Write phase of a write-read: no AUTOEND (TC then holds SCL for the restart).
        assert_eq!(cr2_start(0x11, 36, false, false), Some(0x0024_2022));
        // Read phase: RD_WRN.
        assert_eq!(cr2_start(0x11, 4, true, true), Some(0x0204_2422));
        assert_eq!(cr2_start(0x77, 255, true, true), Some(0x02FF_24EE));
        assert_eq!(cr2_start(0x08, 256, false, true), None);
    }

    /// Issue 21 item 6: a read phase over 255 bytes was refused only at TC, after the write
    /// phase had gone out (SCL held, no STOP, then a block reset). Now both are checked first.
    #[test]
    fn both_phases_are_checked_before_the_start() {
        assert_eq!(cr2_phases(0x08, 5, 0), Some((0x0205_2010, 0)));
        assert_eq!(cr2_phases(0x11, 2, 4), Some((0x0002_2022, 0x0204_2422)));
        assert_eq!(cr2_phases(0x11, 2, 256), None);
        assert_eq!(cr2_phases(0x11, 256, 1), None);
        assert_eq!(cr2_phases(0x11, 255, 255).map(|p| p.1), Some(0x02FF_2422));
    }

    #[test]
    fn target_cr2_arms_nbytes_with_reload_and_never_start_or_stop() {
        // ADD10 (bit 11) and SADD bits kept; START, STOP, AUTOEND, PECBYTE, old NBYTES dropped.
        let old = 0x0000_0810 | cr2::START | cr2::STOP | cr2::AUTOEND | cr2::PECBYTE | (5 << 16);
        assert_eq!(
            target_cr2(old, 37, false),
            0x0000_0810 | cr2::RELOAD | (37 << 16)
        );
        assert_eq!(target_cr2(0, 1, true), cr2::RELOAD | (1 << 16) | cr2::NACK);
        assert_eq!(target_cr2(cr2::NACK, 255, false), cr2::RELOAD | (255 << 16));
    }

    /// Runs a target receive of a write against ISR readings as the adapter does; returns the
    /// steps and the outcome (`received`) when it ended.
    fn receive(readings: &[u32]) -> (Vec<RxStep>, usize, Option<Option<bool>>) {
        let mut steps = Vec::new();
        let mut n = 0;
        for &r in readings {
            let step = receive_step(r);
            steps.push(step);
            match step {
                RxStep::Take => n += 1,
                RxStep::Stop => return (steps, n, Some(received(n, 37, r, false))),
                RxStep::Restart => return (steps, n, Some(received(n, 37, r, true))),
                _ => {}
            }
        }
        (steps, n, None)
    }

    #[test]
    fn a_target_receives_a_write_and_tells_a_write_read() {
        use isr::*;
        use RxStep::*;
        let (steps, n, end) = receive(&[BUSY, BUSY | RXNE, BUSY, BUSY | RXNE, RXNE | STOPF]);
        assert_eq!(steps, [Wait, Take, Wait, Take, Take]);
        assert_eq!((n, end), (3, None));
        let (_, n, end) = receive(&[BUSY | RXNE, BUSY | RXNE, STOPF]);
        assert_eq!((n, end), (2, Some(Some(false))));
        // Repeated START, read direction: a write-read.
        let (steps, n, end) = receive(&[BUSY | RXNE, BUSY | ADDR | DIR]);
        assert_eq!(steps, [Take, Restart]);
        assert_eq!((n, end), (1, Some(Some(true))));
        // Errors first.
        assert_eq!(receive_step(BERR | RXNE | STOPF), Failed);
        assert_eq!(receive_step(OVR), Failed);
    }

    /// Issue 21 item 6: a write of 39 bytes or more stalled the bus for the 20 ms timeout
    /// (the driver's DMA had its 37 bytes and nothing woke it while the block stretched SCL)
    /// and ended `Timeout`. Now NBYTES = 37 with RELOAD: TCR after the 37th byte, which is
    /// NACKed, the controller stops, and the write is over-long (`Overrun`).
    #[test]
    fn an_over_long_write_is_refused_at_its_37th_byte() {
        use isr::*;
        let mut readings = std::vec![BUSY | RXNE; 37];
        readings.push(BUSY | TCR);
        readings.push(STOPF);
        let (steps, n, end) = receive(&readings);
        assert_eq!(steps[37], RxStep::Refuse);
        assert_eq!((n, end), (37, Some(None)));
        assert_eq!(received(36, 37, 0, false), Some(false));
    }

    #[test]
    fn a_target_answers_a_read_of_any_length_with_0xff_after_the_reply() {
        use isr::*;
        use TxStep::*;
        // Reply of 2 bytes, the controller reads 300: TXIS each byte, TCR after 255.
        let reply = [0x11, 0x22];
        let mut sent = Vec::new();
        let mut nacked = false;
        let mut readings = std::vec![];
        for i in 0..300 {
            if i == 255 {
                readings.push(BUSY | TCR);
            }
            readings.push(BUSY | TXIS);
        }
        readings.push(BUSY | NACKF);
        readings.push(BUSY);
        readings.push(STOPF);
        let mut steps = Vec::new();
        for r in readings {
            let s = transmit_step(r, nacked);
            steps.push(s);
            match s {
                Send => sent.push(reply_byte(&reply, sent.len())),
                Nacked => nacked = true,
                _ => {}
            }
        }
        assert_eq!(sent.len(), 300);
        assert_eq!(&sent[..3], &[0x11, 0x22, 0xFF]);
        assert!(sent[2..].iter().all(|&b| b == 0xFF));
        assert_eq!(steps[255], Reload);
        assert_eq!(&steps[301..], &[Nacked, Wait, Done]);
        // After the NACK nothing more is sent; a new address match ends it too.
        assert_eq!(transmit_step(BUSY | TXIS, true), Wait);
        assert_eq!(transmit_step(BUSY | ADDR, true), Done);
        assert_eq!(transmit_step(ARLO | TXIS, false), Failed);
    }

    /// Runs a transfer against a list of ISR readings, advancing the progress by each step
    /// as the adapter does; returns the steps taken.
    fn run(mut p: Progress, readings: &[u32]) -> (Vec<Step>, Progress) {
        let mut steps = Vec::new();
        for &r in readings {
            let step = controller_step(r, &p);
            p.advance(step);
            steps.push(step);
        }
        (steps, p)
    }

    #[test]
    fn a_write_sends_every_byte_and_ends_on_its_stop() {
        use isr::*;
        let (steps, p) = run(
            Progress::new(3, 0),
            &[
                BUSY,
                BUSY | TXIS,
                BUSY,
                BUSY | TXIS,
                BUSY | TXIS,
                BUSY,
                STOPF,
            ],
        );
        use Step::*;
        assert_eq!(steps, [Wait, Send, Wait, Send, Send, Wait, Finished]);
        assert!(p.complete());
    }

    #[test]
    fn a_write_read_restarts_on_tc_and_reads_the_last_byte_before_its_stop() {
        use isr::*;
        let (steps, p) = run(
            Progress::new(2, 2),
            &[
                BUSY | TXIS,
                BUSY | TXIS,
                BUSY | TC,
                BUSY,
                BUSY | RXNE,
                // The last byte and the STOP together: the byte first.
                RXNE | STOPF,
                STOPF,
            ],
        );
        use Step::*;
        assert_eq!(
            steps,
            [Send, Send, Restart, Wait, Receive, Receive, Finished]
        );
        assert!(p.complete());
    }

    #[test]
    fn tc_of_a_plain_write_and_stray_data_flags_are_not_acted_on() {
        use isr::*;
        let mut p = Progress::new(1, 0);
        p.sent = 1;
        assert_eq!(controller_step(BUSY | TC | TXIS, &p), Step::Wait);
        // RXNE before the read phase started (a target-side byte): not ours.
        let p = Progress::new(1, 2);
        assert_eq!(controller_step(BUSY | RXNE, &p), Step::Wait);
    }

    #[test]
    fn failures_come_first_arbitration_before_everything() {
        use isr::*;
        let p = Progress::new(4, 0);
        assert_eq!(
            controller_step(ARLO | ADDR | TXIS | NACKF | BERR, &p),
            Step::Failed(Outcome::Arbitration)
        );
        assert_eq!(
            controller_step(BERR | NACKF | TXIS, &p),
            Step::Failed(Outcome::Bus)
        );
        // Addressed by the master that took the bus before our START went out.
        assert_eq!(
            controller_step(ADDR | BUSY, &Progress::new(4, 0)),
            Step::Failed(Outcome::Arbitration)
        );
        // The address refused: NACKF (the block sends STOP itself).
        assert_eq!(
            controller_step(NACKF | TXIS, &p),
            Step::Failed(Outcome::Nack)
        );
        assert_eq!(
            controller_step(NACKF | STOPF, &p),
            Step::Failed(Outcome::Nack)
        );
    }

    #[test]
    fn a_stop_before_every_byte_moved_is_a_bus_error() {
        use isr::*;
        let mut p = Progress::new(4, 0);
        p.sent = 2;
        assert_eq!(controller_step(STOPF, &p), Step::Failed(Outcome::Bus));
        let mut p = Progress::new(1, 3);
        p.sent = 1;
        p.restarted = true;
        p.received = 1;
        assert_eq!(controller_step(STOPF, &p), Step::Failed(Outcome::Bus));
    }

    #[test]
    fn stop_waits_two_byte_times() {
        assert_eq!(stop_wait_us(100_000), 360);
        assert_eq!(stop_wait_us(400_000), 90);
        assert_eq!(stop_wait_us(1_000_000), 36);
        assert_eq!(stop_wait_us(0), 36_000_000);
        assert_eq!(stop_wait_us(10_000_000), 10);
    }

    /// A target that holds SDA low for `held` more falling SCL edges (it is in the middle of a
    /// byte), or for ever (`None`).
    struct Stuck {
        held: Option<u32>,
        scl: bool,
        sda_out: bool,
        log: Vec<(bool, bool)>,
        halves: u32,
    }

    impl Lines for Stuck {
        fn scl(&mut self, release: bool) {
            if self.scl && !release {
                if let Some(h) = self.held.as_mut() {
                    *h = h.saturating_sub(1);
                }
            }
            self.scl = release;
            let sda = self.sda_high();
            self.log.push((self.scl, sda));
        }
        fn sda(&mut self, release: bool) {
            self.sda_out = release;
            let sda = self.sda_high();
            self.log.push((self.scl, sda));
        }
        fn sda_high(&mut self) -> bool {
            self.sda_out && self.held == Some(0)
        }
        fn half_period(&mut self) {
            self.halves += 1;
        }
    }

    fn stuck(held: Option<u32>) -> Stuck {
        Stuck {
            held,
            scl: true,
            sda_out: true,
            log: Vec::new(),
            halves: 0,
        }
    }

    fn falling_edges(s: &Stuck) -> usize {
        s.log.windows(2).filter(|w| w[0].0 && !w[1].0).count()
    }

    #[test]
    fn nine_clocks_free_a_target_in_the_middle_of_a_byte() {
        for held in 0..=8 {
            let mut s = stuck(Some(held));
            assert!(recover_bus(&mut s), "held for {held} clocks");
            // `held` pulses, then the STOP's own falling edge.
            assert_eq!(falling_edges(&s), held as usize + 1);
            // Ends with a STOP: SDA rises while SCL is high.
            let n = s.log.len();
            assert_eq!(s.log[n - 2], (true, false));
            assert_eq!(s.log[n - 1], (true, true));
        }
    }

    #[test]
    fn a_target_that_never_lets_go_is_given_up_after_nine_clocks() {
        let mut s = stuck(None);
        assert!(!recover_bus(&mut s));
        assert_eq!(falling_edges(&s), 10);
        // The longest bus clear: 23 half periods (138 µs at 100 kHz, 69 µs at 400 kHz).
        assert_eq!(s.halves, CLEAR_HALF_PERIODS);
        assert_eq!(CLEAR_HALF_PERIODS * clear_half_period_us(100_000), 138);
        assert_eq!(CLEAR_HALF_PERIODS * clear_half_period_us(400_000), 69);
    }
}
