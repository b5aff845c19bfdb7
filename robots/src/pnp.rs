//! Plug and play: two daughterboards flashed with the same image and never given an address
//! by hand. The motherboard gives each one an address over the bus; this task waits until two
//! boards are known, then toggles pin A of actuator port 1 on each of them every 50 ms,
//! wherever they were put. It rides out a board that restarts (a call that fails is tried
//! again at the next step). The emulated Pico pair runs it (`cargo xtask emu plug-and-play`).
//!
//! Wiring: an LED (or anything on a digital output) on actuator port 1, pin A of each
//! daughterboard.

use embassy_time::Timer;
use x10::{Address, DigitalOutput, Error, KnownBoard, Pin, X10};

/// How often each board's output is toggled.
pub const STEP_MS: u64 = 50;

/// The first two present daughterboards the motherboard knows, by address.
fn two_present(x10: X10) -> Option<(Address, Address)> {
    let mut known = [KnownBoard::EMPTY; 8];
    let n = x10.boards(&mut known);
    let mut present = known
        .iter()
        .take(n)
        .filter(|b| b.present && !b.address.is_internal() && !b.address.is_unaddressed())
        .map(|b| b.address);
    Some((present.next()?, present.next()?))
}

/// Waits for two boards, then blinks actuator port 1, pin A on both.
///
/// # Errors
/// Never in practice: a port number out of range (it is 1) when building the outputs.
pub async fn two_boards(x10: X10) -> Result<(), Error> {
    let (a, b) = loop {
        if let Some(pair) = two_present(x10) {
            break pair;
        }
        Timer::after_millis(10).await;
    };
    let mut outputs = [
        DigitalOutput::new(x10, a, 1, Pin::A)?,
        DigitalOutput::new(x10, b, 1, Pin::A)?,
    ];
    loop {
        for o in outputs.iter_mut() {
            // A board that restarts misses a step: the next one drives it again.
            let _ = o.toggle().await;
        }
        Timer::after_millis(STEP_MS).await;
    }
}
