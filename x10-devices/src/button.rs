//! A push button on a digital pin, debounced, with optional change events.

use x10_microcode::{Address, EventConfig, EventKind, Level, Pin};

use crate::error::Error;
use crate::math::Debouncer;
use crate::port::Sensor;
use crate::{Link, LinkError, Result};

/// A debounced button state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ButtonState {
    /// Not pressed.
    Released,
    /// Pressed.
    Pressed,
}

impl ButtonState {
    fn from_pressed(pressed: bool) -> ButtonState {
        if pressed {
            ButtonState::Pressed
        } else {
            ButtonState::Released
        }
    }
}

/// A push button on digital pin `pin` of a sensor port, debounced by counting: the state
/// changes after `samples` consecutive reads agree (default 2), so the debounce window is
/// `samples` times the interval between reads. Starts released.
///
/// Polling: call [`Button::is_pressed`] (one `IO INPUT` per call). Events: call
/// [`Button::enable_events`] once (`SYSTEM EVENT-ENABLE`, both edges), then
/// [`Button::wait_change`], which wakes on the board's pin-change events and confirms each
/// with `samples − 1` reads.
#[derive(Clone, Debug)]
pub struct Button<L> {
    sensor: Sensor<L>,
    pin: Pin,
    pressed_level: Level,
    debouncer: Debouncer,
}

impl<L: Link> Button<L> {
    /// Default number of agreeing samples.
    pub const DEFAULT_SAMPLES: u8 = 2;

    /// A button that reads HIGH when pressed, on pin `pin` of sensor port `number` (from 1) of
    /// board `db`, debounced over [`Button::DEFAULT_SAMPLES`].
    ///
    /// # Errors
    /// [`Error::BadPort`] for 0 or above 64.
    pub fn new(link: L, db: Address, number: u8, pin: Pin) -> Result<Self> {
        Ok(Button {
            sensor: Sensor::new(link, db, number)?,
            pin,
            pressed_level: Level::High,
            debouncer: Debouncer::new(Self::DEFAULT_SAMPLES, false)?,
        })
    }

    /// The same button reading LOW when pressed (a switch to ground with a pull-up).
    pub fn active_low(mut self) -> Self {
        self.pressed_level = Level::Low;
        self
    }

    /// The same button debounced over `samples` agreeing reads (1 = no debouncing).
    ///
    /// # Errors
    /// [`Error::Range`] unless `1 <= samples <= 32`.
    pub fn debounce(mut self, samples: u8) -> Result<Self> {
        self.debouncer = Debouncer::new(samples, self.debouncer.state())?;
        Ok(self)
    }

    /// The sensor port.
    pub fn sensor(&self) -> &Sensor<L> {
        &self.sensor
    }

    /// The debounced state, without reading.
    pub fn state(&self) -> ButtonState {
        ButtonState::from_pressed(self.debouncer.state())
    }

    /// One read of the pin, without debouncing: true when it is at the pressed level.
    ///
    /// # Errors
    /// [`Error::Link`].
    pub async fn read_raw(&self) -> Result<bool> {
        Ok(self.sensor.read_digital(self.pin).await? == self.pressed_level)
    }

    /// Reads the pin once, feeds the debouncer, returns the debounced state (thesis
    /// `pushbutton.readDigitalB()`).
    ///
    /// # Errors
    /// [`Error::Link`]; the debouncer is then unchanged.
    pub async fn is_pressed(&mut self) -> Result<bool> {
        let raw = self.read_raw().await?;
        Ok(self.debouncer.update(raw))
    }

    /// Asks the board for an event on every edge of the pin.
    ///
    /// # Errors
    /// [`Error::Link`].
    pub async fn enable_events(&self) -> Result<()> {
        let config = EventConfig {
            rising: true,
            falling: true,
            ..EventConfig::OFF
        };
        self.sensor.enable_events(self.pin, config).await
    }

    /// Turns the pin's events off.
    ///
    /// # Errors
    /// [`Error::Link`].
    pub async fn disable_events(&self) -> Result<()> {
        self.sensor.enable_events(self.pin, EventConfig::OFF).await
    }

    /// Waits until the debounced state changes and returns the new state. Each pin-change
    /// event counts as one sample; `samples − 1` reads confirm it; a bounce that does not
    /// last goes back to waiting. Events of other kinds are ignored.
    ///
    /// # Errors
    /// [`Error::Link`] (`Link(Unsupported)` when the link has no events); `Link(BadReply)` for
    /// a pin-change event whose payload is not one byte 0 or 1.
    pub async fn wait_change(&mut self) -> Result<ButtonState> {
        let before = self.debouncer.state();
        loop {
            let event = self.sensor.wait_event(self.pin).await?;
            if event.kind != EventKind::PinChange {
                continue;
            }
            // The level, then the edge counts (protocol: pin_change payload).
            let level = match *event.value {
                [0, ..] => Level::Low,
                [1, ..] => Level::High,
                _ => return Err(Error::Link(LinkError::BadReply)),
            };
            let mut state = self.debouncer.update(level == self.pressed_level);
            for _ in 1..self.debouncer.samples() {
                if state != before {
                    break;
                }
                state = self.is_pressed().await?;
            }
            if state != before {
                return Ok(ButtonState::from_pressed(state));
            }
        }
    }
}
