//! Issue 10, finding "internal board never yields": calls to the motherboard's own ports
//! completed without an await point, so a loop of them starved every other task (the
//! dispatcher, and on the Pico everything else). Internal requests now go through the
//! internal board's worker task; a loop of them lets another task run at every call.

// `common` re-exports helpers this file does not use.
#[allow(unused_imports)]
mod common;

use std::cell::Cell;
use std::future::poll_fn;
use std::task::Poll;

use common::World;
use embassy_futures::join::join;
use x10_microcode::{Address, Op, Pin, Port};

#[test]
fn a_loop_of_internal_calls_lets_another_task_run() {
    let w = World::new();
    let a1a = Port::actuator(1).unwrap().pin(Pin::A);
    let done = Cell::new(false);
    let polls = Cell::new(0u32);
    let calls = 200u32;
    let polls_during = w.sim(async {
        let program = async {
            for _ in 0..calls {
                w.mb.call(Address::INTERNAL, Op::DigitalRead(a1a))
                    .await
                    .unwrap();
            }
            done.set(true);
            polls.get()
        };
        // Another task: counts how often it is polled until the program is done.
        let other = poll_fn(|cx| {
            if done.get() {
                return Poll::Ready(());
            }
            polls.set(polls.get() + 1);
            cx.waker().wake_by_ref();
            Poll::Pending
        });
        join(program, other).await.0
    });
    assert!(
        polls_during >= calls,
        "the other task ran {polls_during} times during {calls} internal calls"
    );
}
