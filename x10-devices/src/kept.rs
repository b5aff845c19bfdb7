//! Outputs kept asserted: the commanded state is sent when it changes, again every few steps
//! without a change, and again after it was forgotten.

use crate::refresh::Refresh;
use crate::Result;

/// An output whose driver remembers the state it last commanded successfully: what [`Kept`]
/// keeps asserted. [`crate::DcMotor`] (a [`crate::Speed`]) and [`crate::DigitalOutput`] (a
/// [`crate::Level`]) are outputs.
#[allow(async_fn_in_trait)]
pub trait Output {
    /// What is commanded.
    type State: Copy + PartialEq;

    /// The state last set successfully; `None` before the first, after a failed
    /// [`Output::set`] and after [`Output::invalidate`].
    fn state(&self) -> Option<Self::State>;

    /// Forgets the state; sends nothing.
    fn invalidate(&mut self);

    /// Sends `state`. Afterwards [`Output::state`] is `Some(state)`, or `None` if it failed.
    ///
    /// # Errors
    /// What the driver's command reports.
    async fn set(&mut self, state: Self::State) -> Result<()>;
}

/// An [`Output`] kept asserted by a control loop: [`Kept::keep`], once per step, sends the
/// wanted state when it differs from the last one sent successfully (a change, or a state
/// forgotten after a failure) and when the [`Refresh`] says it is due, so a board that reset
/// and fell back to its safe state without any call failing is driven again within
/// `refresh.steps()` steps.
///
/// ```
/// # use x10_devices::{testing::RecordingLink, DigitalOutput, Kept, Level, Pin, Refresh, SELF};
/// # use embassy_futures::block_on;
/// let link = RecordingLink::<8>::new();
/// let lamp = DigitalOutput::new(&link, SELF, 1, Pin::A).unwrap();
/// let mut lamp = Kept::new(lamp, Refresh::every(2).unwrap());
/// link.acks(3);
/// block_on(lamp.set(Level::High)).unwrap(); // sent; the count starts
/// block_on(lamp.keep(Level::High)).unwrap(); // no change, not due: nothing sent
/// block_on(lamp.keep(Level::High)).unwrap(); // due: HIGH again
/// block_on(lamp.keep(Level::Low)).unwrap(); // a change: sent at once
/// // IO HIGH, IO HIGH, IO LOW on SELF, actuator port 1 pin A, sequence numbers 0, 1, 2.
/// link.assert_sent(&[&[0x12, 0, 0, 0], &[0x12, 0, 0, 1], &[0x11, 0, 0, 2]]);
/// link.finish();
/// ```
#[derive(Clone, Debug)]
pub struct Kept<O> {
    output: O,
    refresh: Refresh,
}

impl<O: Output> Kept<O> {
    /// `output`, its state re-sent when `refresh` is due.
    pub const fn new(output: O, refresh: Refresh) -> Self {
        Kept { output, refresh }
    }

    /// The output.
    pub fn output(&self) -> &O {
        &self.output
    }

    /// The state last sent successfully; `None` when unknown (before the first, after a
    /// failure, after [`Kept::invalidate`]).
    pub fn state(&self) -> Option<O::State> {
        self.output.state()
    }

    /// Forgets the state (sends nothing), so the next [`Kept::keep`] sends it.
    ///
    /// Call it when the output's board may have lost the state although no command to the
    /// output failed: after any other failed call to that board (a NACK or timeout may be the
    /// board resetting) or when the board reports a boot.
    pub fn invalidate(&mut self) {
        self.output.invalidate();
    }

    /// Sends `state` now; on success the refresh count starts again (a program's `setup`).
    ///
    /// # Errors
    /// What [`Output::set`] reports; the state is then unknown and the next [`Kept::keep`]
    /// sends it.
    pub async fn set(&mut self, state: O::State) -> Result<()> {
        self.output.set(state).await?;
        self.refresh.restart();
        Ok(())
    }

    /// One step of the control loop wanting `state`: counts the step, and sends `state` (as
    /// [`Kept::set`]) if it differs from the state last sent or the refresh is due; otherwise
    /// sends nothing.
    ///
    /// # Errors
    /// As [`Kept::set`].
    pub async fn keep(&mut self, state: O::State) -> Result<()> {
        let due = self.refresh.tick();
        if due || self.output.state() != Some(state) {
            self.set(state).await?;
        }
        Ok(())
    }

    /// One step of a control loop whose every call goes to the output's board: with
    /// `Ok(state)`, as [`Kept::keep`]; with `Err(e)` (working out the wanted state failed),
    /// forgets the state as [`Kept::invalidate`] and sends nothing, so the next step sends it
    /// again: the failure may have been the board resetting.
    ///
    /// # Errors
    /// `e`, or as [`Kept::keep`].
    pub async fn keep_or_forget(&mut self, wanted: Result<O::State>) -> Result<()> {
        match wanted {
            Ok(state) => self.keep(state).await,
            Err(e) => {
                self.invalidate();
                Err(e)
            }
        }
    }
}
