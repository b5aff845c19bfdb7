//! A full bus: 110 daughterboards (every address from 0x09 to 0x76; the motherboard is at
//! 0x08 and 0x77 is where unaddressed boards listen), each with 8 sensor ports, and one task
//! that scans every board once every 100 ms: one `scan` request per board, whose reply holds
//! the analog value and the two digital levels of every sensor port. Not a thesis figure: the
//! load test of the bus and of the simulator (`x10 sim full_bus --clock 1M`, and `x10 sim
//! --bench`, docs/performance.md).

use embassy_time::{Duration, Ticker};
use x10::{Address, Op, X10};

/// The first board's address.
pub const FIRST: u8 = 0x09;
/// The last board's address.
pub const LAST: u8 = 0x76;
/// How often every board is scanned.
pub const PERIOD: Duration = Duration::from_millis(100);

/// Scans boards [`FIRST`] to [`LAST`], one after the other, every [`PERIOD`] (a sweep that
/// takes longer starts the next one at once). A call that fails is not retried here: the
/// next sweep scans the board again, and the run's summary counts the failure. Runs for ever.
pub async fn scan_all(x10: X10) {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        for a in FIRST..=LAST {
            if let Ok(board) = Address::new(a) {
                let _ = x10.call(board, Op::Scan).await;
            }
        }
        ticker.next().await;
    }
}
