//! The motherboard runtime's reply and event path on a fake bus answered by the input, checked
//! by an oracle of its own (see `src/lib.rs` for the input format, `src/oracle.rs` for what is
//! checked). A panic of the runtime, a call that never ends or ends late, an `Ok` or a status
//! that no valid reply gave, or a pin event that was not sent aborts the run. With
//! `X10_FUZZ_TRACE=1` in the environment every case prints its transactions, events and calls;
//! `X10_FUZZ_ALLOW=class,...` lets violations of those classes pass (long runs looking past
//! known defects; never in ./test-all); `X10_FUZZ_EXPECT=class` makes an input pass only if
//! it breaks the oracle with that class (fuzz/regressions/open/).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    let (record, verdict) = x10_fuzz::run(input);
    if std::env::var_os("X10_FUZZ_TRACE").is_some() {
        eprintln!("{}", record.dump());
    }
    // Regression inputs of a defect still open must keep failing with their class
    // (fuzz/run.sh sets X10_FUZZ_EXPECT for fuzz/regressions/open/).
    if let Ok(class) = std::env::var("X10_FUZZ_EXPECT") {
        match verdict {
            Err(v) if v.class == class => return,
            Err(v) => {
                eprintln!("{}", record.dump());
                panic!("expected a violation of class {class}, got: {v}");
            }
            Ok(()) => panic!(
                "expected a violation of class {class}, but the input is clean: the defect is \
                 fixed; move the file from fuzz/regressions/open/ to fuzz/regressions/"
            ),
        }
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
