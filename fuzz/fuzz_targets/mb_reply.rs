//! The motherboard runtime's reply and event path on a fake bus answered by the input, checked
//! by an oracle of its own (see `src/lib.rs` for the input format, `src/oracle.rs` for what is
//! checked). A panic of the runtime, a call that never ends or ends late, an `Ok` or a status
//! that no valid reply gave, or a pin event that was not sent aborts the run. With
//! `X10_FUZZ_TRACE=1` in the environment every case prints its transactions, events and calls;
//! `X10_FUZZ_ALLOW=class,...` lets violations of those classes pass (long runs looking past
//! known defects; never in ./test-all).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let (record, verdict) = x10_fuzz::run(input);
    if std::env::var_os("X10_FUZZ_TRACE").is_some() {
        eprintln!("{}", record.dump());
    }
    if let Err(v) = verdict {
        // Long runs may let known classes pass to look for others (docs/reliability.md).
        let allowed = std::env::var("X10_FUZZ_ALLOW").unwrap_or_default();
        if allowed.split(',').any(|c| c == v.class) {
            return;
        }
        eprintln!("{}", record.dump());
        panic!("oracle violation: {v}");
    }
});
