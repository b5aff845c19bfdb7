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
    /// Bus error (misplaced START or STOP).
    pub const BERR: u32 = 1 << 8;
    /// Arbitration lost.
    pub const ARLO: u32 = 1 << 9;
    /// Overrun/underrun (target, NOSTRETCH only).
    pub const OVR: u32 = 1 << 10;
    /// Bus busy (START seen, no STOP yet).
    pub const BUSY: u32 = 1 << 15;
}

/// ICR bits: each clears the ISR flag at the same position.
pub mod icr {
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

/// Before a controller call: the ICR bits to write, or why not to start.
///
/// With the bus idle (no BUSY) and this node not addressed (no ADDR), no transfer is under way,
/// so every flag set belongs to an earlier one and is cleared. Otherwise the transfer does not
/// start: the bus belongs to another master, or this node must first answer its own address
/// match (ADDR holds SCL), so the adapter answers [`BusError::ArbitrationLost`] and the
/// runtime listens and retries after its backoff.
///
/// # Errors
/// [`BusError::ArbitrationLost`] while the bus is busy or this node is addressed.
pub fn before_controller(isr: u32) -> Result<u32, BusError> {
    if isr & (isr::BUSY | isr::ADDR) != 0 {
        Err(BusError::ArbitrationLost)
    } else {
        Ok(isr & STALE)
    }
}

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
        assert_eq!(before_controller(all), Ok(STALE));
        assert_eq!(before_controller(isr::STOPF), Ok(icr::STOPCF));
        assert_eq!(before_controller(0), Ok(0));
        // Taken: another master (BUSY) or this node addressed (ADDR): no clearing, retry.
        assert_eq!(
            before_controller(all | isr::BUSY),
            Err(BusError::ArbitrationLost)
        );
        assert_eq!(before_controller(isr::ADDR), Err(BusError::ArbitrationLost));
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
        fn half_period(&mut self) {}
    }

    fn stuck(held: Option<u32>) -> Stuck {
        Stuck {
            held,
            scl: true,
            sda_out: true,
            log: Vec::new(),
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
    }
}
