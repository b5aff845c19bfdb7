//! A doorbell: a push button on daughterboard 9 rings a chime on the motherboard's own port.
//! The task sleeps until the button's pin-change event comes in from board 9 (no polling on
//! the bus) and mirrors the button on the chime. It is the shortest program in which a
//! daughterboard's event wakes a motherboard task, so the emulated Pico pair measures that
//! path with it (`cargo xtask emu doorbell`).
//!
//! Wiring:
//!
//! | device | board | port | pin |
//! |---|---|---|---|
//! | doorbell button (HIGH when pressed) | 9 | sensor port 1 | digital A |
//! | chime (a buzzer or an LED with its driver) | SELF | actuator port 1 | digital A |

use x10::{Address, Button, ButtonState, DigitalOutput, Error, Pin, SELF, X10};

/// The board with the button.
pub const BUTTON_BOARD: Address = match Address::new(9) {
    Ok(a) => a,
    // Evaluated at compile time.
    Err(_) => panic!("9 is a valid daughterboard address"),
};

/// Rings the chime (SELF actuator port 1, pin A) while the button (board 9, sensor port 1,
/// pin A) is held: enables the button's events, then waits for each change.
///
/// # Errors
/// The first failed call (board 9 absent or gone: the image logs it and the task ends).
pub async fn doorbell(x10: X10) -> Result<(), Error> {
    let mut button = Button::new(x10, BUTTON_BOARD, 1, Pin::A)?;
    let mut chime = DigitalOutput::new(x10, SELF, 1, Pin::A)?;
    chime.low().await?;
    button.enable_events().await?;
    loop {
        match button.wait_change().await? {
            ButtonState::Pressed => chime.high().await?,
            ButtonState::Released => chime.low().await?,
        }
    }
}
