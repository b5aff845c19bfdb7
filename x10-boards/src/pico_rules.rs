//! The decisions [`pico`](crate::pico)'s adapters make about the RP2040's I2C block
//! (DW_apb_i2c) and its GPIO edge latches, as pure functions on register snapshots: tested on
//! the host, no HAL.
//!
//! Register and bit names are the RP2040 datasheet's (§4.3 I2C, §2.19 GPIO); the HAL lines
//! each rule works around are embassy-rp 0.10.0's (`i2c_slave.rs`, `i2c.rs`, `gpio.rs`).

use x10_hal::bus::BusError;
use x10_hal::ports::EdgeCount;

/// Depth of the block's TX FIFO (`IC_TXFLR` counts up to it).
pub const TX_FIFO: u8 = 16;

/// How many of `remaining` reply bytes may be handed to embassy-rp's `respond_to_read` now,
/// with `txflr` bytes (`IC_TXFLR`) still in the TX FIFO.
///
/// `respond_to_read` splits its buffer into 16-byte chunks and writes a chunk to
/// `IC_DATA_CMD` on every poll without looking at the FIFO level (`i2c_slave.rs` 322-327):
/// a second chunk polled before the first has gone out falls into a full FIFO and is lost
/// (issue 16 defect 1). Given at most the free space, it writes only on its first poll.
#[must_use]
pub fn tx_chunk(remaining: usize, txflr: u8) -> usize {
    remaining.min(usize::from(TX_FIFO.saturating_sub(txflr)))
}

/// What the target side shows, read from `IC_STATUS` and `IC_RAW_INTR_STAT`, and whether the
/// adapter holds the first byte of a transfer not drained yet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Target {
    /// `IC_STATUS.SLV_ACTIVITY`: the target state machine is not idle.
    pub slv_activity: bool,
    /// `IC_STATUS.RFNE`: received bytes wait in the RX FIFO.
    pub rfne: bool,
    /// `IC_RAW_INTR_STAT.RD_REQ`: a controller reads from this node (SCL held low).
    pub rd_req: bool,
    /// The adapter took a transfer's first byte out of the RX FIFO while draining the one
    /// before it, and keeps it for the next `listen` (see [`heard`]).
    pub kept: bool,
}

/// True when a transfer to this node's own address has reached the block: a received byte
/// (in the RX FIFO or kept by the adapter) or a read request. Both arise only after this
/// node's address matched (`IC_SAR`).
///
/// `SLV_ACTIVITY` is not used: it stays set from a read's last byte until its STOP (so after
/// a reply it would make `listen` wait for the next transfer, issue 16 defect 2), it stays
/// set when a controller vanishes without a STOP, and the datasheet does not say that it
/// stays clear during other nodes' address phases (issue 11 item 6).
#[must_use]
pub fn addressed(t: Target) -> bool {
    t.rfne || t.rd_req || t.kept
}

/// Whether the target may be dropped (the block reset) to become a controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Switch {
    /// Nothing in the block: switch.
    Now,
    /// Something for this node is in the block, or a transfer is still active: answer
    /// `ArbitrationLost` (the runtime listens and retries).
    Refuse,
    /// `SLV_ACTIVITY` alone has lasted longer than [`stale_activity_us`]: the controller went
    /// away without a STOP (issue 11 item 5). Reset the block and switch.
    Stale,
}

/// Time of one byte with its ACK (9 SCL periods) at `frequency_hz`, in µs, rounded up.
#[must_use]
pub fn byte_us(frequency_hz: u32) -> u64 {
    // In 32 bits: no 64-bit division in the image (issue 12).
    u64::from(9_000_000u32.div_ceil(frequency_hz.max(1)))
}

/// How long `SLV_ACTIVITY` with nothing received and no read request means a transfer that
/// was abandoned: four byte times. After its address matched, a transfer to this node shows a
/// received byte or a read request within one byte time (the block ACKs and fills its FIFO by
/// itself), unless its controller stalls or went away without a STOP.
#[must_use]
pub fn stale_activity_us(frequency_hz: u32) -> u64 {
    4 * byte_us(frequency_hz)
}

/// Tracks how long the target has shown `SLV_ACTIVITY` with nothing else, to tell an active
/// transfer from one abandoned without a STOP.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Activity {
    since_us: Option<u64>,
    last_us: u64,
}

impl Activity {
    /// Decides a switch to controller at `now_us`, given the target's state and
    /// [`stale_activity_us`].
    ///
    /// Only an unbroken run of observations counts: one more than `stale_us` after the
    /// previous starts the count again (the activity seen then may have been another transfer).
    pub fn switch(&mut self, now_us: u64, t: Target, stale_us: u64) -> Switch {
        if now_us.saturating_sub(self.last_us) > stale_us {
            self.since_us = None;
        }
        self.last_us = now_us;
        if addressed(t) {
            // Bytes or a read request for us: never thrown away.
            self.since_us = None;
            return Switch::Refuse;
        }
        if !t.slv_activity {
            self.since_us = None;
            return Switch::Now;
        }
        let since = *self.since_us.get_or_insert(now_us);
        if now_us.saturating_sub(since) >= stale_us {
            self.since_us = None;
            Switch::Stale
        } else {
            Switch::Refuse
        }
    }
}

/// After a reply's last byte (embassy-rp's `respond_to_read` returned): true once the read is
/// over, looking at the block while waiting for its STOP. It is over when the target state
/// machine is idle (`SLV_ACTIVITY` stays set from a read's last byte until its STOP), or when
/// a later transfer has reached the block (a byte or a read request: the read ended before
/// it, with a STOP or a repeated START).
///
/// `STOP_DET` is not used: it is one flag for the read's STOP and any later one, so a look
/// at the block that comes late (the executor busy, issue 21 item 5) cannot tell "the read's
/// STOP, then a write under way" from "the read's STOP, a whole write with its STOP, then the
/// next transfer". The rule that cleared it in the first case cleared the second write's STOP
/// too, and embassy-rp's `listen` then dropped that write (an output the MB saw ACKed) or
/// merged it with the next one. Transfers are now told apart by [`heard`].
#[must_use]
pub fn read_over(t: Target) -> bool {
    addressed(t) || !t.slv_activity
}

/// What `listen` has seen of the write it drains, after taking every byte from the RX FIFO.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Listen {
    /// Bytes of the transfer taken so far (a kept first byte included).
    pub len: usize,
    /// A byte flagged `IC_DATA_CMD.FIRST_DATA_BYTE` came after them: it starts the next
    /// transfer (the adapter keeps it), so this one is over.
    pub next: bool,
    /// `IC_RAW_INTR_STAT.RD_REQ`, read before the RX FIFO was drained.
    pub rd_req: bool,
    /// `IC_RAW_INTR_STAT.RESTART_DET`, read with `rd_req`.
    pub restart_det: bool,
    /// `IC_STATUS.SLV_ACTIVITY`, from the `IC_STATUS` read that found the RX FIFO empty.
    pub slv_activity: bool,
}

/// The transfer `listen` reports, or [`Heard::Wait`] to look again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heard {
    /// Not over yet.
    Wait,
    /// A write of `len` bytes, ended (STOP, or the next transfer began).
    Write,
    /// A write of `len` bytes, then a repeated START into a read.
    WriteRead,
    /// A read with no write before it.
    Read,
}

/// The rule for [`Heard`]: transfer boundaries from the block's own marks, never from
/// `STOP_DET` (one flag for any number of STOPs, see [`read_over`]).
///
/// * The RX FIFO marks each transfer's first byte (`FIRST_DATA_BYTE`): a marked byte after
///   the ones taken ends their write, however many STOPs the adapter missed.
/// * A read request found before the FIFO was drained follows every byte in it: the write
///   taken is over, and was the write of a write-read if `RESTART_DET` says so.
/// * The state machine idle in the same `IC_STATUS` read that found the FIFO empty: the
///   write's STOP has come and every byte of it was taken.
///
/// embassy-rp's `listen` ended a write on `STOP_DET` and cleared it, so of two writes
/// received before it looked, the second waited for the next transfer's STOP, and was
/// dropped when that transfer was a read (`i2c_slave.rs` 241-301).
#[must_use]
pub fn heard(l: Listen) -> Heard {
    if l.len == 0 {
        if l.rd_req {
            Heard::Read
        } else {
            Heard::Wait
        }
    } else if l.next || (!l.rd_req && !l.slv_activity) {
        Heard::Write
    } else if l.rd_req {
        if l.restart_det {
            Heard::WriteRead
        } else {
            Heard::Write
        }
    } else {
        Heard::Wait
    }
}

/// How a reply ended, read once the read is over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReplyEnd {
    /// `IC_TXFLR`: bytes still in the TX FIFO (the controller read fewer than were queued).
    pub txflr: u8,
    /// `IC_RAW_INTR_STAT.TX_ABRT`: the block flushed the FIFO or aborted.
    pub tx_abrt: bool,
}

/// True when the block must be reset after a reply: anything left in the TX FIFO would be
/// flushed with `TX_ABRT` on the next read request, and embassy-rp's `respond_to_read` then
/// returns `LeftoverBytes` without queuing a byte while SCL stays low (`i2c_slave.rs` 311-320,
/// issue 11 item 1); an abort leaves the block in an unknown state. (A read that never ends
/// is cut by `respond`'s timeout, which resets the block too.)
#[must_use]
pub fn reset_after_reply(e: ReplyEnd) -> bool {
    e.txflr > 0 || e.tx_abrt
}

/// `IC_SDA_HOLD.IC_SDA_TX_HOLD` for a bus at `bus_hz`, the block clocked at `clk_hz`
/// (`clk_peri`): how long, in block clocks, this node holds SDA after SCL falls when it sends.
///
/// UM10204 Table 10 note 3: a device must provide at least 300 ns of data hold time inside
/// itself (Standard and Fast mode) to bridge the undefined region of SCL's falling edge;
/// 120 ns in Fast-mode Plus (the value embassy-rp uses there). The count is embassy-rp 0.10's
/// for its controller (`i2c.rs` 443-458: `clk * 3 / 10_000_000 + 1`, `clk * 3 / 25_000_000 +
/// 1` at 1 MHz; here one division, never less), so both roles hold SDA alike; its target
/// (`i2c_slave.rs` 126-170) resets the block and leaves the reset value, one clock, which the
/// block raises to its slave minimum of seven (56 ns at 125 MHz; RP2040 datasheet,
/// `IC_SDA_HOLD`). At least eight, the datasheet's least for slave mode; for `clk_hz` from
/// 20 MHz it is also at most the mode's shortest SCL low time (4.7 / 1.3 / 0.5 µs) less two
/// clocks, the datasheet's other bound (host-tested).
#[must_use]
pub fn sda_tx_hold(clk_hz: u32, bus_hz: u32) -> u16 {
    // clk_hz * 300 ns = clk_hz / 3_333_333 (120 ns: / 8_333_333), in 32 bits.
    let per = if bus_hz < 1_000_000 {
        3_333_333
    } else {
        8_333_333
    };
    let n = (clk_hz / per + 1).max(SLAVE_MIN_HOLD + 1);
    u16::try_from(n).unwrap_or(u16::MAX)
}

/// `IC_SDA_TX_HOLD` for the bootloader's target (`boot-pico`), which is flashed once and
/// then serves daughterboard images built for any bus clock (`X10_BUS_HZ`: 100 kHz, 400 kHz or
/// 1 MHz), so it cannot take the clock's own value: 300 ns ([`sda_tx_hold`] below 1 MHz). That
/// meets all three modes for `clk_hz` from 100 to 200 MHz (the Pico's `clk_peri` is 125 MHz):
/// at least t_HD;DAT (300 / 300 / 120 ns, UM10204 Table 10 note 3), with the output's fall
/// time (at most 120 ns in Fast-mode Plus) within the shortest data valid time t_VD;DAT
/// (3.45 / 0.9 / 0.45 µs, Table 10), and within the shortest SCL low time less two clocks
/// (the RP2040 datasheet's bound, `IC_SDA_HOLD`). Without it the bootloader's target kept
/// the reset value, the block's slave minimum of seven clocks (56 ns), less than Standard
/// and Fast mode's 300 ns (host-tested; the emulator does not model the hold time).
#[must_use]
pub fn bootloader_sda_tx_hold(clk_hz: u32) -> u16 {
    sda_tx_hold(clk_hz, 100_000)
}

/// The shortest `IC_SDA_TX_HOLD` the block takes in slave mode (datasheet, `IC_SDA_HOLD`).
pub const SLAVE_MIN_HOLD: u32 = 7;

/// `IC_TX_ABRT_SOURCE.ABRT_7B_ADDR_NOACK`.
pub const ABRT_7B_ADDR_NOACK: u32 = 1 << 0;
/// `IC_TX_ABRT_SOURCE.ABRT_10ADDR1_NOACK`.
pub const ABRT_10ADDR1_NOACK: u32 = 1 << 1;
/// `IC_TX_ABRT_SOURCE.ABRT_10ADDR2_NOACK`.
pub const ABRT_10ADDR2_NOACK: u32 = 1 << 2;
/// `IC_TX_ABRT_SOURCE.ABRT_TXDATA_NOACK`: a data byte of a write was not acknowledged.
pub const ABRT_TXDATA_NOACK: u32 = 1 << 3;
/// `IC_TX_ABRT_SOURCE.ARB_LOST`.
pub const ARB_LOST: u32 = 1 << 12;

/// The bus error for a controller abort with `IC_TX_ABRT_SOURCE` = `source`.
///
/// embassy-rp 0.10 decodes only the address NACKs and `ARB_LOST` and hands every other
/// source over as `AbortReason::Other(source)` (`i2c.rs` 514-523), so a data-byte NACK would
/// become `Bus`, which the MB never retries. A NACK of a data byte is `Nack` as on the STM32
/// (issue 11 item 7): the target was there but could not take the byte (its RX FIFO full, or
/// it reset), and a retry is right.
#[must_use]
pub fn abort_error(source: u32) -> BusError {
    if source & ARB_LOST != 0 {
        BusError::ArbitrationLost
    } else if source
        & (ABRT_7B_ADDR_NOACK | ABRT_10ADDR1_NOACK | ABRT_10ADDR2_NOACK | ABRT_TXDATA_NOACK)
        != 0
    {
        BusError::Nack
    } else {
        BusError::Bus
    }
}

/// The controller side, read from `IC_STATUS` and `IC_RAW_INTR_STAT` after embassy-rp's
/// `write_async` or `write_read_async` returned `Ok`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Controller {
    /// `IC_STATUS.MST_ACTIVITY`: the controller state machine is not idle.
    pub mst_activity: bool,
    /// `IC_STATUS.TFE`: the TX FIFO (this node's commands) is empty.
    pub tfe: bool,
    /// `IC_RAW_INTR_STAT.TX_ABRT`.
    pub tx_abrt: bool,
}

/// What a controller transfer that embassy-rp reported as done really did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControllerEnd {
    /// Sent whole, its own STOP seen.
    Done,
    /// Ended by an abort after all (read `IC_TX_ABRT_SOURCE`, then clear it).
    Aborted,
    /// Not over: commands still queued or the state machine busy. Look again.
    Wait,
}

/// The rule for [`ControllerEnd`].
///
/// embassy-rp ends a transfer on `IC_RAW_INTR_STAT.STOP_DET` (`i2c.rs` 296-322) and never
/// clears that flag before it starts one. With `IC_CON.STOP_DET_IF_MASTER_ACTIVE` at 0 (its
/// reset value) the block raises it for every STOP on the bus, another controller's too, and
/// its own target side's transfers leave it set: a write queued behind such a STOP returns
/// `Ok` at once, while its bytes still sit in the TX FIFO. The role switch that follows
/// resets the block and cuts the transfer without a STOP (found on the emulated pair:
/// db-pico's boot event cut after 14 bytes). Done means: nothing queued, the state machine
/// idle, and no abort.
#[must_use]
pub fn controller_end(c: Controller) -> ControllerEnd {
    if c.tx_abrt {
        ControllerEnd::Aborted
    } else if c.mst_activity || !c.tfe {
        ControllerEnd::Wait
    } else {
        ControllerEnd::Done
    }
}

/// The GPIO number of a pin named as in the pin table (`"PIN_4"` → 4); `None` for any other
/// name or a number past the RP2040's 30 user GPIOs.
/// A `const fn`, so that the adapter's GPIO table is computed at compile time.
#[must_use]
pub const fn gpio_number(name: &str) -> Option<u8> {
    let b = name.as_bytes();
    if b.len() < 5 || b.len() > 6 || b[0] != b'P' || b[1] != b'I' || b[2] != b'N' || b[3] != b'_' {
        return None;
    }
    let mut n: u8 = 0;
    let mut i = 4;
    while i < b.len() {
        if !b[i].is_ascii_digit() {
            return None;
        }
        n = n * 10 + (b[i] - b'0');
        i += 1;
    }
    if n < 30 {
        Some(n)
    } else {
        None
    }
}

/// `IO_BANK0.INTRn` holds eight GPIOs' raw interrupt bits, four each (LEVEL_LOW, LEVEL_HIGH,
/// EDGE_LOW, EDGE_HIGH, from bit 0): the register index and the shift of `gpio`'s four bits.
#[must_use]
pub const fn intr_slot(gpio: u8) -> (usize, u32) {
    ((gpio / 8) as usize, 4 * (gpio % 8) as u32)
}

/// `EDGE_LOW` within a GPIO's four bits.
pub const EDGE_LOW: u32 = 1 << 2;
/// `EDGE_HIGH` within a GPIO's four bits.
pub const EDGE_HIGH: u32 = 1 << 3;

/// The edges `gpio` latched, from its `INTRn` register's value `intr`, and the mask to write
/// back to clear exactly those (the edge bits are write-1-to-clear; an edge latched after the
/// read keeps its bit). The raw bits latch whether or not an interrupt is enabled, so no edge
/// is missed, but they say "at least one": several edges of one direction between two reads
/// count as one.
#[must_use]
pub fn latched_edges(intr: u32, gpio: u8) -> (EdgeCount, u32) {
    let (_, shift) = intr_slot(gpio);
    let bits = (intr >> shift) & (EDGE_LOW | EDGE_HIGH);
    let count = EdgeCount {
        rising: u16::from(bits & EDGE_HIGH != 0),
        falling: u16::from(bits & EDGE_LOW != 0),
    };
    (count, bits << shift)
}

/// The edge bits of the GPIOs in `pins` (bit n = GPIO n) within register `INTR{reg}`: a
/// latched edge of any of them is `intr & edge_mask(pins, reg) != 0`.
#[must_use]
pub fn edge_mask(pins: u32, reg: usize) -> u32 {
    (0..8u32)
        .filter(|i| {
            let gpio = reg as u32 * 8 + i;
            gpio < 32 && pins & (1 << gpio) != 0
        })
        .fold(0, |m, i| m | (EDGE_LOW | EDGE_HIGH) << (4 * i))
}

/// What the bus lines showed while [`LineWatch`] sampled them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lines {
    /// SCL and SDA high, unchanged, for the whole window: no transfer under way. Start.
    Free,
    /// A line changed: another master's transfer is under way (its START came while this
    /// node's block was being reset, so the block never saw it). Do not start: answer
    /// `ArbitrationLost` (the runtime listens, then retries).
    Active,
    /// A line low and unchanged for the stuck time: a held bus (a target holding SDA, a
    /// controller gone mid-byte), not a transfer. Start: the transfer fails or times out and
    /// the bus clear runs, as before this watch.
    Stuck,
}

/// Watches SCL and SDA (samples of the pins) before a block that was just reset, or is about
/// to be, starts a transfer (issue 21 item 3). Every Pico role switch rebuilds the I2C block
/// (RESETS), and the rebuilt block takes the bus for free: a START of another master during
/// the reset is not seen, and a START of its own in the middle of that transfer breaks it (an
/// STM32 master answers BERR, `Bus`, which the MB does not retry). The node starts only after
/// both lines stayed high for two SCL periods (no transfer can leave both high that long:
/// SCL is low for part of every period, and a STOP's SDA-high comes with SCL high only
/// between transfers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LineWatch {
    start_us: u32,
    first: (bool, bool),
}

impl LineWatch {
    /// Starts a watch with the first sample (`scl_high`, `sda_high`) at `now_us` (a µs
    /// clock that may wrap: only differences are used, in 32 bits, as the image has no
    /// 64-bit arithmetic to spare).
    #[must_use]
    pub fn new(now_us: u32, scl_high: bool, sda_high: bool) -> LineWatch {
        LineWatch {
            start_us: now_us,
            first: (scl_high, sda_high),
        }
    }

    /// Takes one more sample at `now_us`. `None`: sample again (as fast as possible, so that
    /// no SCL pulse goes unseen); otherwise the verdict. `window_us` is two SCL periods
    /// ([`idle_window_us`]), `stuck_us` the time after which an unchanged low line is a held
    /// bus (four byte times, [`stale_activity_us`]).
    pub fn sample(
        &mut self,
        now_us: u32,
        scl_high: bool,
        sda_high: bool,
        window_us: u32,
        stuck_us: u32,
    ) -> Option<Lines> {
        if (scl_high, sda_high) != self.first {
            return Some(Lines::Active);
        }
        let held = now_us.wrapping_sub(self.start_us);
        if scl_high && sda_high {
            (held >= window_us).then_some(Lines::Free)
        } else {
            (held >= stuck_us).then_some(Lines::Stuck)
        }
    }
}

/// Two SCL periods at `frequency_hz`, in µs, rounded up: how long both lines must stay high
/// before a reset block starts a transfer ([`LineWatch`]).
#[must_use]
pub fn idle_window_us(frequency_hz: u32) -> u32 {
    2_000_000u32.div_ceil(frequency_hz.max(1))
}

/// Clock pulses of the bus-clear procedure (UM10204 §3.1.16): a target holding SDA low
/// releases it within nine clocks.
pub const RECOVERY_CLOCKS: u8 = 9;

/// One step of the bus-clear procedure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recovery {
    /// SDA is high: send a STOP (SDA low then high while SCL is high) and stop.
    Stop,
    /// SDA still low: send one more SCL pulse.
    Clock,
    /// SDA still low after nine pulses: give up with `BusError::Bus`.
    GiveUp,
}

/// The step after `clocks` pulses with SDA read as `sda_high`.
#[must_use]
pub fn recovery(sda_high: bool, clocks: u8) -> Recovery {
    if sda_high {
        Recovery::Stop
    } else if clocks < RECOVERY_CLOCKS {
        Recovery::Clock
    } else {
        Recovery::GiveUp
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn gpio_numbers_come_from_the_pin_table() {
        assert_eq!(gpio_number("PIN_0"), Some(0));
        assert_eq!(gpio_number("PIN_29"), Some(29));
        assert_eq!(gpio_number("PIN_30"), None);
        assert_eq!(gpio_number("PIN_"), None);
        assert_eq!(gpio_number("PA4"), None);
        assert_eq!(gpio_number("PIN_4x"), None);
        assert_eq!(gpio_number("PIN_999"), None);
        // Every digital pin of the Pico's map has one, and no two share it.
        let map = crate::pins::PICO;
        let mut seen = 0u32;
        for name in map
            .sensors
            .iter()
            .flat_map(|s| [s.a, s.b])
            .chain(map.actuators.iter().flat_map(|a| [a.a, a.b]))
        {
            let g = gpio_number(name).expect(name);
            assert_eq!(seen & (1 << g), 0, "{name} twice");
            seen |= 1 << g;
        }
    }

    #[test]
    fn edges_are_read_from_their_gpio_and_cleared_alone() {
        assert_eq!(intr_slot(0), (0, 0));
        assert_eq!(intr_slot(7), (0, 28));
        assert_eq!(intr_slot(8), (1, 0));
        assert_eq!(intr_slot(29), (3, 20));
        // GPIO 12 (INTR1, bits 16-19): EDGE_HIGH only; level bits and other GPIOs ignored.
        let intr = (EDGE_HIGH | 0b0011) << 16 | (EDGE_LOW << 20) | EDGE_HIGH;
        let (n, clear) = latched_edges(intr, 12);
        assert_eq!(
            n,
            EdgeCount {
                rising: 1,
                falling: 0
            }
        );
        assert_eq!(clear, EDGE_HIGH << 16);
        // Both directions (a pulse): one each, both bits cleared.
        let (n, clear) = latched_edges((EDGE_LOW | EDGE_HIGH) << 28, 7);
        assert_eq!(
            n,
            EdgeCount {
                rising: 1,
                falling: 1
            }
        );
        assert_eq!(clear, (EDGE_LOW | EDGE_HIGH) << 28);
        // Nothing latched: nothing to clear.
        assert_eq!(latched_edges(0b0011 << 4, 9), (EdgeCount::NONE, 0));
    }

    #[test]
    fn edge_masks_cover_the_latched_gpios_of_each_register() {
        let pins = (1 << 2) | (1 << 14) | (1 << 15) | (1 << 29);
        assert_eq!(edge_mask(pins, 0), 0xc << 8);
        assert_eq!(edge_mask(pins, 1), (0xc << 24) | (0xc << 28));
        assert_eq!(edge_mask(pins, 2), 0);
        assert_eq!(edge_mask(pins, 3), 0xc << 20);
        assert_eq!(edge_mask(0, 1), 0);
        // Consistent with latched_edges: a pin's edge bits are inside its register's mask.
        for gpio in 0..30u8 {
            let (reg, _) = intr_slot(gpio);
            let (_, clear) = latched_edges(u32::MAX, gpio);
            assert_eq!(edge_mask(1 << gpio, reg), clear);
        }
    }

    #[test]
    fn a_transfer_is_over_only_when_idle_and_empty() {
        let c = |mst_activity, tfe, tx_abrt| Controller {
            mst_activity,
            tfe,
            tx_abrt,
        };
        assert_eq!(controller_end(c(false, true, false)), ControllerEnd::Done);
        // Another controller's STOP ended embassy-rp's wait: our bytes are still queued.
        assert_eq!(controller_end(c(false, false, false)), ControllerEnd::Wait);
        assert_eq!(controller_end(c(true, false, false)), ControllerEnd::Wait);
        // The last byte on the wire, the STOP not sent yet.
        assert_eq!(controller_end(c(true, true, false)), ControllerEnd::Wait);
        // An abort (a NACK, or arbitration lost once the transfer really ran) wins.
        for (m, t) in [(false, true), (true, true), (false, false), (true, false)] {
            assert_eq!(controller_end(c(m, t, true)), ControllerEnd::Aborted);
        }
    }

    #[test]
    fn chunks_never_exceed_free_space() {
        assert_eq!(tx_chunk(31, 0), 16);
        assert_eq!(tx_chunk(31, 5), 11);
        assert_eq!(tx_chunk(3, 0), 3);
        assert_eq!(tx_chunk(3, 15), 1);
        assert_eq!(tx_chunk(3, 16), 0);
        assert_eq!(tx_chunk(0, 0), 0);
        // A bogus level above the depth gives nothing, not an overflow.
        assert_eq!(tx_chunk(3, 200), 0);
        for level in 0..=TX_FIFO {
            for n in 0..64 {
                assert!(usize::from(level) + tx_chunk(n, level) <= usize::from(TX_FIFO));
            }
        }
    }

    const IDLE: Target = Target {
        slv_activity: false,
        rfne: false,
        rd_req: false,
        kept: false,
    };

    #[test]
    fn addressed_only_on_own_match() {
        assert!(!addressed(IDLE));
        // Activity alone (a read waiting for its STOP, an abandoned transfer, maybe another
        // node's address phase) is not a transfer to us.
        assert!(!addressed(Target {
            slv_activity: true,
            ..IDLE
        }));
        assert!(addressed(Target { rfne: true, ..IDLE }));
        // A first byte the adapter kept while draining the write before it.
        assert!(addressed(Target { kept: true, ..IDLE }));
        assert!(addressed(Target {
            slv_activity: true,
            rd_req: true,
            ..IDLE
        }));
    }

    #[test]
    fn switch_refuses_while_addressed_and_resets_stale_activity() {
        let mut a = Activity::default();
        assert_eq!(a.switch(0, IDLE, 20_000), Switch::Now);
        assert_eq!(a.switch(1, IDLE, 20_000), Switch::Now);
        assert_eq!(
            a.switch(0, Target { rfne: true, ..IDLE }, 20_000),
            Switch::Refuse
        );
        let act = Target {
            slv_activity: true,
            ..IDLE
        };
        assert_eq!(a.switch(100, act, 20_000), Switch::Refuse);
        assert_eq!(a.switch(10_000, act, 20_000), Switch::Refuse);
        assert_eq!(a.switch(20_099, act, 20_000), Switch::Refuse);
        assert_eq!(a.switch(20_100, act, 20_000), Switch::Stale);
        // Starts over after the stale reset.
        assert_eq!(a.switch(20_200, act, 20_000), Switch::Refuse);
        // Any other state restarts the count.
        assert_eq!(a.switch(30_000, IDLE, 20_000), Switch::Now);
        assert_eq!(a.switch(45_000, act, 20_000), Switch::Refuse);
        assert_eq!(
            a.switch(
                60_000,
                Target {
                    rd_req: true,
                    slv_activity: true,
                    ..IDLE
                },
                20_000
            ),
            Switch::Refuse
        );
        assert_eq!(a.switch(70_000, act, 20_000), Switch::Refuse);
        assert_eq!(a.switch(90_000, act, 20_000), Switch::Stale);
    }

    #[test]
    fn sparse_observations_start_over() {
        // Activity seen once, then again long after (another transfer): not stale.
        let act = Target {
            slv_activity: true,
            ..IDLE
        };
        let mut a = Activity::default();
        assert_eq!(a.switch(1_000, act, 360), Switch::Refuse);
        assert_eq!(a.switch(50_000, act, 360), Switch::Refuse);
        assert_eq!(a.switch(50_300, act, 360), Switch::Refuse);
        assert_eq!(a.switch(50_400, act, 360), Switch::Stale);
        // Retries 100, 200 µs apart keep the run unbroken.
        let mut a = Activity::default();
        let mut t = 90_000;
        assert_eq!(a.switch(t, act, 360), Switch::Refuse);
        for step in [100, 200] {
            t += step;
            assert_eq!(a.switch(t, act, 360), Switch::Refuse);
        }
        t += 300; // 600 after the first look, each gap within 360
        assert_eq!(a.switch(t, act, 360), Switch::Stale);
    }

    #[test]
    fn stale_after_four_byte_times() {
        assert_eq!(byte_us(100_000), 90);
        assert_eq!(byte_us(400_000), 23);
        assert_eq!(byte_us(1_000_000), 9);
        assert_eq!(stale_activity_us(100_000), 360);
        assert_eq!(stale_activity_us(0), 36_000_000);
    }

    #[test]
    fn a_read_is_over_when_idle_or_followed() {
        // The last byte sent, the STOP not yet seen.
        assert!(!read_over(Target {
            slv_activity: true,
            ..IDLE
        }));
        // Its STOP (and any number after it).
        assert!(read_over(IDLE));
        // A later transfer reached the block, however late this look is.
        for t in [
            Target {
                rfne: true,
                slv_activity: true,
                ..IDLE
            },
            Target { rfne: true, ..IDLE },
            Target {
                rd_req: true,
                rfne: true,
                slv_activity: true,
                ..IDLE
            },
            Target {
                rd_req: true,
                slv_activity: true,
                ..IDLE
            },
        ] {
            assert!(read_over(t), "{t:?}");
        }
    }

    const NOTHING: Listen = Listen {
        len: 0,
        next: false,
        rd_req: false,
        restart_det: false,
        slv_activity: false,
    };

    #[test]
    fn heard_waits_for_a_transfer() {
        assert_eq!(heard(NOTHING), Heard::Wait);
        // Matched, no byte yet.
        assert_eq!(
            heard(Listen {
                slv_activity: true,
                ..NOTHING
            }),
            Heard::Wait
        );
        // Bytes, the write still under way.
        assert_eq!(
            heard(Listen {
                len: 3,
                slv_activity: true,
                ..NOTHING
            }),
            Heard::Wait
        );
    }

    #[test]
    fn heard_ends_a_write_at_its_stop_or_at_the_next_transfer() {
        // Its STOP: idle, every byte taken.
        assert_eq!(heard(Listen { len: 4, ..NOTHING }), Heard::Write);
        // A write-read's write: the read request after a repeated START.
        let wr = Listen {
            len: 4,
            rd_req: true,
            restart_det: true,
            slv_activity: true,
            ..NOTHING
        };
        assert_eq!(heard(wr), Heard::WriteRead);
        // A plain read after this write's STOP: the write alone, the read next time.
        assert_eq!(
            heard(Listen {
                restart_det: false,
                ..wr
            }),
            Heard::Write
        );
        assert_eq!(
            heard(Listen {
                rd_req: true,
                slv_activity: true,
                ..NOTHING
            }),
            Heard::Read
        );
        // Another transfer's first byte after it: over, whatever else is seen.
        for rd_req in [false, true] {
            for restart_det in [false, true] {
                for slv_activity in [false, true] {
                    let l = Listen {
                        len: 4,
                        next: true,
                        rd_req,
                        restart_det,
                        slv_activity,
                    };
                    assert_eq!(heard(l), Heard::Write, "{l:?}");
                }
            }
        }
    }

    /// Issue 21 item 5: the adapter looks late, after a reply's STOP, a whole write (an output)
    /// with its STOP, and the start of the next transfer. Each write is reported whole and in
    /// order, the way the adapter's `listen` feeds the rule: the kept first byte of the next
    /// transfer starts the next `listen`.
    #[test]
    fn a_late_look_loses_no_write() {
        // The write (4 bytes), then a plain read waiting (SCL held).
        let rd = Listen {
            rd_req: true,
            slv_activity: true,
            ..NOTHING
        };
        assert_eq!(heard(Listen { len: 4, ..rd }), Heard::Write);
        assert_eq!(heard(rd), Heard::Read);
        // The write, then a write-read whose read waits: the first write ends at the marked
        // byte; the second is the write of the write-read.
        let wr = Listen {
            rd_req: true,
            restart_det: true,
            slv_activity: true,
            ..NOTHING
        };
        assert_eq!(
            heard(Listen {
                len: 4,
                next: true,
                ..wr
            }),
            Heard::Write
        );
        assert_eq!(heard(Listen { len: 4, ..wr }), Heard::WriteRead);
        // Two writes, the second still under way, then over.
        let busy = Listen {
            slv_activity: true,
            ..NOTHING
        };
        assert_eq!(
            heard(Listen {
                len: 4,
                next: true,
                ..busy
            }),
            Heard::Write
        );
        assert_eq!(heard(Listen { len: 2, ..busy }), Heard::Wait);
        assert_eq!(heard(Listen { len: 4, ..NOTHING }), Heard::Write);
    }

    #[test]
    fn reset_when_anything_is_left() {
        assert!(!reset_after_reply(ReplyEnd {
            txflr: 0,
            tx_abrt: false,
        }));
        assert!(reset_after_reply(ReplyEnd {
            txflr: 2,
            tx_abrt: false,
        }));
        assert!(reset_after_reply(ReplyEnd {
            txflr: 0,
            tx_abrt: true,
        }));
    }

    #[test]
    fn sda_hold_meets_the_spec_at_every_speed() {
        // The Pico's 125 MHz: 38 clocks (304 ns) below 1 MHz, 16 (128 ns) at 1 MHz, as
        // embassy-rp's controller sets; the target had 1.
        assert_eq!(sda_tx_hold(125_000_000, 100_000), 38);
        assert_eq!(sda_tx_hold(125_000_000, 400_000), 38);
        assert_eq!(sda_tx_hold(125_000_000, 1_000_000), 16);
        assert_eq!(sda_tx_hold(133_000_000, 400_000), 40);
        // Every clock from 20 MHz: at least t_HD;DAT (300 / 120 ns), above the slave minimum,
        // within the shortest SCL low time less two clocks.
        for mhz in 20..=200u32 {
            let clk = mhz * 1_000_000;
            for (bus, t_ns, low_ns) in [
                (100_000u32, 300u64, 4_700u64),
                (400_000, 300, 1_300),
                (1_000_000, 120, 500),
            ] {
                let n = u64::from(sda_tx_hold(clk, bus));
                let ns = n * 1_000_000_000 / u64::from(clk);
                assert!(ns >= t_ns, "{mhz} MHz, {bus} Hz: {n} clocks = {ns} ns");
                assert!(n > u64::from(SLAVE_MIN_HOLD));
                assert!(
                    n + 2 <= u64::from(clk) * low_ns / 1_000_000_000,
                    "{mhz} {bus}"
                );
            }
        }
        // The bootloader's one value serves every bus clock: 38 clocks at 125 MHz.
        assert_eq!(bootloader_sda_tx_hold(125_000_000), 38);
        for mhz in 100..=200u32 {
            let clk = mhz * 1_000_000;
            let n = u64::from(bootloader_sda_tx_hold(clk));
            let ns = n * 1_000_000_000 / u64::from(clk);
            for (t_ns, valid_ns, low_ns) in [
                (300u64, 3_450u64, 4_700u64),
                (300, 900, 1_300),
                (120, 450, 500),
            ] {
                assert!(ns >= t_ns, "{mhz} MHz: {n} clocks = {ns} ns");
                assert!(ns + 120 <= valid_ns, "{mhz} MHz: {ns} ns");
                assert!(
                    n + 2 <= u64::from(clk) * low_ns / 1_000_000_000,
                    "{mhz} MHz"
                );
            }
        }
        // A slow clock: the slave minimum; the fastest: no overflow.
        assert_eq!(sda_tx_hold(10_000_000, 1_000_000), 8);
        assert_eq!(sda_tx_hold(u32::MAX, 100_000), 1_289);
    }

    #[test]
    fn abort_sources_map_like_the_stm32() {
        assert_eq!(abort_error(ABRT_7B_ADDR_NOACK), BusError::Nack);
        assert_eq!(abort_error(ABRT_TXDATA_NOACK), BusError::Nack);
        // TX_FLUSH_CNT (bits 23..31) rides along with the data NACK.
        assert_eq!(abort_error(ABRT_TXDATA_NOACK | (3 << 23)), BusError::Nack);
        assert_eq!(abort_error(ARB_LOST), BusError::ArbitrationLost);
        assert_eq!(
            abort_error(ARB_LOST | ABRT_TXDATA_NOACK),
            BusError::ArbitrationLost
        );
        // ABRT_USER_ABRT, ABRT_SBYTE_ACKDET and the rest are bus faults.
        assert_eq!(abort_error(1 << 16), BusError::Bus);
        assert_eq!(abort_error(1 << 7), BusError::Bus);
        assert_eq!(abort_error(0), BusError::Bus);
    }

    /// Runs a watch over (time, SCL, SDA) samples, as the adapter's loop does.
    fn watch(samples: &[(u32, bool, bool)], window: u32, stuck: u32) -> Option<Lines> {
        let (&(t0, c0, d0), rest) = samples.split_first()?;
        let mut w = LineWatch::new(t0, c0, d0);
        rest.iter()
            .find_map(|&(t, c, d)| w.sample(t, c, d, window, stuck))
    }

    #[test]
    fn lines_free_after_two_periods_high() {
        assert_eq!(idle_window_us(100_000), 20);
        assert_eq!(idle_window_us(400_000), 5);
        assert_eq!(idle_window_us(1_000_000), 2);
        assert_eq!(idle_window_us(0), 2_000_000);
        let high: std::vec::Vec<_> = (0..=20).map(|t| (t, true, true)).collect();
        assert_eq!(watch(&high, 20, 360), Some(Lines::Free));
        // Not before the window is over.
        assert_eq!(watch(&high[..20], 20, 360), None);
    }

    /// Issue 21 item 3: a transfer that began while the block was in reset. Both lines high
    /// at the first sample (SCL's high phase), then SCL falls: the node must not start.
    #[test]
    fn a_transfer_under_way_is_seen_in_any_phase() {
        // 100 kHz: SCL high 5 us, low 5 us; SDA moves while SCL is low.
        let transfer = |t: u32| {
            let scl = t % 10 < 5;
            let sda = scl || (t / 10).is_multiple_of(2);
            (t, scl, sda)
        };
        for phase in 0..10 {
            let s: std::vec::Vec<_> = (phase..phase + 25).map(transfer).collect();
            assert_eq!(watch(&s, 20, 360), Some(Lines::Active), "phase {phase}");
        }
        // A START alone (SDA falls, SCL high) and a STOP (SDA rises) are changes too.
        assert_eq!(
            watch(&[(0, true, true), (3, true, false)], 20, 360),
            Some(Lines::Active)
        );
        assert_eq!(
            watch(&[(0, true, false), (3, true, true)], 20, 360),
            Some(Lines::Active)
        );
    }

    #[test]
    fn the_watch_spans_a_clock_wrap() {
        let t0 = u32::MAX - 5;
        assert_eq!(
            watch(
                &[(t0, true, true), (t0.wrapping_add(19), true, true)],
                20,
                360
            ),
            None
        );
        assert_eq!(
            watch(
                &[(t0, true, true), (t0.wrapping_add(20), true, true)],
                20,
                360
            ),
            Some(Lines::Free)
        );
    }

    #[test]
    fn a_held_line_is_stuck_after_the_stuck_time() {
        // SDA held low by a target, SCL high: no change for 360 us.
        let held: std::vec::Vec<_> = (0..=360).map(|t| (t, true, false)).collect();
        assert_eq!(watch(&held[..360], 20, 360), None);
        assert_eq!(watch(&held, 20, 360), Some(Lines::Stuck));
        // SCL held low (a long stretch) the same.
        let stretch: std::vec::Vec<_> = (0..=360).map(|t| (t, false, true)).collect();
        assert_eq!(watch(&stretch, 20, 360), Some(Lines::Stuck));
        // A stretch that ends is a transfer under way.
        assert_eq!(
            watch(
                &[(0, false, true), (100, false, true), (101, true, true)],
                20,
                360
            ),
            Some(Lines::Active)
        );
    }

    #[test]
    fn recovery_gives_nine_clocks_then_up() {
        assert_eq!(recovery(true, 0), Recovery::Stop);
        for c in 0..RECOVERY_CLOCKS {
            assert_eq!(recovery(false, c), Recovery::Clock);
        }
        assert_eq!(recovery(false, 9), Recovery::GiveUp);
        assert_eq!(recovery(true, 9), Recovery::Stop);
        // The loop the adapter runs: SDA freed after k pulses.
        for k in 0..=12u8 {
            let mut clocks = 0;
            let end = loop {
                match recovery(clocks >= k, clocks) {
                    Recovery::Clock => clocks += 1,
                    other => break other,
                }
            };
            assert_eq!(
                end,
                if k <= 9 {
                    Recovery::Stop
                } else {
                    Recovery::GiveUp
                }
            );
            assert!(clocks <= RECOVERY_CLOCKS);
        }
    }
}
