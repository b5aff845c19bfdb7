//! Issue 22 item 11: a driver on a port the board does not have fails at its first call with
//! a clear error; before, every write of a `DcMotor` on actuator port 3 of a 2-port board
//! returned `Ok` and the board's refusals came later as `rejected` events.

use std::cell::RefCell;
use std::rc::Rc;
use x10_devices::{DcMotor, Error, LinkError};
use x10_microcode::{Address, Status};
use x10_sim::sim::{SimConfig, X10};
use x10_sim::world::{Board, World};

#[test]
fn a_motor_on_a_port_the_board_lacks_fails_at_its_first_call() {
    let results: Rc<RefCell<Vec<Result<(), Error>>>> = Rc::default();
    let r = results.clone();
    let config = SimConfig {
        duration_ms: 200,
        ..SimConfig::default()
    };
    let outcome = World::new()
        .board(Board::new(9, 2, 2))
        .sim(config)
        .unwrap()
        .with_robot("drive", move |x10: X10| async move {
            let mut motor = DcMotor::new(x10, Address::new(9).unwrap(), 3)?;
            let first = motor.set_percent(50).await;
            r.borrow_mut().push(first);
            let second = motor.stop().await;
            r.borrow_mut().push(second);
            Ok::<(), Error>(())
        })
        .run()
        .unwrap();
    let refused = Err(Error::Link(LinkError::Status(Status::PortOutOfRange)));
    assert_eq!(*results.borrow(), [refused, refused]);
    // Nothing reached the board: no refusal, no rejected event.
    assert_eq!(outcome.mb.rejected, 0);
    assert!(outcome.boards.iter().all(|(_, d)| d.port_errors == 0));
}
