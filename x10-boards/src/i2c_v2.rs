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
//! stale ([`before_controller`], [`before_target`]), waits for the STOP that ends its own
//! transfers ([`after_controller`], [`stop_wait_us`]) and recovers a stuck bus
//! ([`recover_bus`], UM10204 §3.1.16).

use x10_hal::bus::BusError;

/// ISR bits (RM0440 §37.7.7, RM0490 §23.7.7: the same on the G4 and the C0).
pub mod isr {
    /// Address matched (target).
    pub const ADDR: u32 = 1 << 3;
    /// NACK received.
    pub const NACKF: u32 = 1 << 4;
    /// STOP detected.
    pub const STOPF: u32 = 1 << 5;
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
/// so every flag set belongs to an earlier one and is cleared. Otherwise the call must not
/// start: embassy-stm32 would spin synchronously on BUSY (`v2.rs` 207-210), so the adapter
/// answers [`BusError::ArbitrationLost`] and the runtime retries after its backoff.
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

/// What a controller call's outcome, as embassy-stm32 reports it, leaves to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum After {
    /// A STOP is on its way (set by the driver, by AUTOEND, or by the block after a NACK):
    /// wait for STOPF and clear it, then report the result.
    WaitStop,
    /// Nothing: the driver reset the block (PE toggled after ARLO or BERR, `v2.rs` 945-949,
    /// 1067-1071), which clears every flag.
    Done,
    /// The driver gave up in the middle (its timeout dropped the transfer, leaving the block
    /// as controller, maybe holding SCL): send STOP, wait for it, and recover the bus when it
    /// does not come.
    Abort,
}

/// The outcome of a controller call, as far as the adapter needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Done.
    Ok,
    /// Address or data byte not acknowledged (`Error::Nack`, either phase: `v2.rs` 957-959
    /// reads NACKF without telling them apart).
    Nack,
    /// Arbitration lost.
    Arbitration,
    /// Bus error.
    Bus,
    /// The driver's timeout.
    Timeout,
    /// Overrun, CRC or zero-length: errors of the driver's own bookkeeping.
    Other,
}

/// What to do after a controller call ended with `outcome`.
pub fn after_controller(outcome: Outcome) -> After {
    match outcome {
        Outcome::Ok | Outcome::Nack | Outcome::Other => After::WaitStop,
        Outcome::Arbitration | Outcome::Bus => After::Done,
        Outcome::Timeout => After::Abort,
    }
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
        assert_eq!(after_controller(Ok), After::WaitStop);
        assert_eq!(after_controller(Nack), After::WaitStop);
        assert_eq!(after_controller(Arbitration), After::Done);
        assert_eq!(after_controller(Bus), After::Done);
        assert_eq!(after_controller(Timeout), After::Abort);
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
