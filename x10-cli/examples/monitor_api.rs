//! A laptop program driving a robot over the USB link (docs/usb-link.md): switches the
//! motherboard's A1.B on and prints its counters and the boards it knows. Needs a motherboard
//! on USB: `cargo run -p x10-cli --example monitor_api`.

use x10_cli::monitor::Robot;
use x10_microcode::{Address, Level, Op, Pin, Port};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut robot = Robot::open_first()?; // finds the port, says hello
    let a1b = Port::actuator(1).map_err(|e| format!("{e:?}"))?.pin(Pin::B);
    robot.call(Address::INTERNAL, &Op::DigitalWrite(a1b, Level::High))?; // as a robot task would
    let counters = robot.diagnostics()?; // (name, value) pairs
    let boards = robot.boards()?; // [0, 9, ...]
    println!("{counters:?}\n{boards:?}");
    Ok(())
}
