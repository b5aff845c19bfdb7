//! A ROM bootloader that answers anything: whatever bytes the reads return (and however the
//! writes fail), the client ends, with an error, after a bounded number of bus operations,
//! and never reports an update done.

use embassy_futures::block_on;
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::{ErrorKind, ErrorType, I2c, Operation};
use proptest::prelude::*;
use x10_stmboot::{update, Client, C011};

/// Reads return the next bytes of `answers` (then the bus fails); writes fail where `fails`
/// says.
struct Noise {
    answers: Vec<u8>,
    at: usize,
    fails: Vec<bool>,
    writes: usize,
    ops: usize,
}

impl ErrorType for Noise {
    type Error = ErrorKind;
}

impl I2c for Noise {
    async fn transaction(
        &mut self,
        _address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), ErrorKind> {
        for op in operations {
            self.ops += 1;
            assert!(self.ops < 100_000, "the client does not end");
            match op {
                Operation::Read(buf) => {
                    for b in buf.iter_mut() {
                        *b = *self.answers.get(self.at).ok_or(ErrorKind::Other)?;
                        self.at += 1;
                    }
                }
                Operation::Write(_) => {
                    let fail = self.fails.get(self.writes).copied().unwrap_or(false);
                    self.writes += 1;
                    if fail {
                        return Err(ErrorKind::Other);
                    }
                }
            }
        }
        Ok(())
    }
}

struct NoDelay;

impl DelayNs for NoDelay {
    async fn delay_ns(&mut self, _ns: u32) {}
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    #[test]
    fn any_answers_end_in_an_error(
        answers in proptest::collection::vec(
            prop_oneof![Just(0x79u8), Just(0x1f), Just(0x76), Just(0x12), Just(0x04), Just(0x43), any::<u8>()],
            0..400,
        ),
        fails in proptest::collection::vec(proptest::bool::weighted(0.05), 0..200),
        len in 1usize..3000,
    ) {
        let image: Vec<u8> = (0..len).map(|i| (i * 13 + 1) as u8).collect();
        let bus = Noise { answers, at: 0, fails, writes: 0, ops: 0 };
        let mut c = Client::new(bus, NoDelay);
        let r = block_on(update(&mut c, &C011, &image));
        prop_assert!(r.is_err(), "an update reported done: {:?}", r);
    }
}
