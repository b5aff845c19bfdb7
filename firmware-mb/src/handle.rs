//! [`X10`]: the handle robot programs use, a `&'static` reference to the [`MbCore`] (and
//! the [`Link`] implementations through which the drivers reach it).

use core::future::Future;

use x10_devices::{Link, LinkError, PinEvent};
use x10_microcode::{Address, Op, Payload, PinRef, Uid};

use crate::config::MbConfig;
use crate::diag::MbDiagnostics;
use crate::directory::{AssignError, AssignPlan, BoardQuery, KnownBoard};
use crate::mb_core::MbCore;
use crate::mb_core::{now, sleep_until};
use crate::together::{NotTogether, SweepResult, SweepSummary, Together};
use crate::update::UpdateRefusal;

/// How often [`X10::wait_for_board`] looks (5 ms).
pub const WAIT_FOR_BOARD_POLL_US: u64 = 5_000;

/// How long [`X10::assign`] waits for the board's `boot` from its new address (1 s: a board
/// restarts in a few ms; an unaddressed one's `assign` is sent again at its next announce).
pub const ASSIGN_WAIT_US: u64 = 1_000_000;

/// The robot programs' handle on the running motherboard: one concrete, `Copy` type, the same
/// on every board and in the simulator, so a robot program is a plain `async fn` that takes
/// an `X10`:
///
/// ```ignore
/// pub async fn blink(x10: X10) -> Result<(), x10::Error> {
///     let mut led = DigitalOutput::new(x10, SELF, 1, Pin::A)?;
///     loop {
///         led.toggle().await?;
///         Timer::after_millis(500).await;
///     }
/// }
/// ```
///
/// It implements [`x10_devices::Link`], so every driver works through it; copy it into as
/// many tasks as needed: each call gets its own sequence number and its own reply, and the
/// runtime's tasks (dispatcher, internal daughterboard, keepalive) serve them all. A firmware
/// image gets it from `Motherboard::handle` (the board crate's `start_motherboard`), the
/// simulator hands one to every robot task.
#[derive(Clone, Copy)]
pub struct X10 {
    core: &'static MbCore,
}

impl X10 {
    pub(crate) fn new(core: &'static MbCore) -> X10 {
        X10 { core }
    }

    /// Sends `op` to board `db` (0 = [`x10_devices::SELF`], the motherboard's own ports) and
    /// waits for its outcome, with the default timeout (`MbConfig::request_timeout_us`, plus
    /// the pulse-in timeout for a pulse-in). Drivers call this; programs rarely need it.
    ///
    /// # Errors
    /// As [`MbCore::call_with_timeout`].
    pub fn call<'a>(
        &'a self,
        db: Address,
        op: Op<'a>,
    ) -> impl Future<Output = Result<Payload, LinkError>> + 'a {
        // The core's future itself, not one wrapped in another state machine (issue 27).
        crate::mb_core::call_with(self.core, db, op, None)
    }

    /// [`X10::call`] with an explicit timeout in µs.
    ///
    /// # Errors
    /// As [`MbCore::call_with_timeout`].
    pub fn call_with_timeout<'a>(
        &'a self,
        db: Address,
        op: Op<'a>,
        timeout_us: u64,
    ) -> impl Future<Output = Result<Payload, LinkError>> + 'a {
        crate::mb_core::call_with(self.core, db, op, Some(timeout_us))
    }

    /// Waits for the next pin-change or analog-threshold event from `pin` on board `db`
    /// (enable it first; drivers such as `Button::wait_change` do).
    ///
    /// # Errors
    /// As [`MbCore::wait_event`].
    pub async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        self.core.wait_event(db, pin).await
    }

    /// The boards the motherboard knows by their unique ID (plug and play; present or not,
    /// see [`KnownBoard::present`]), copied into `out` in the order they were first heard;
    /// returns how many were copied (at most `out.len()`).
    pub fn boards(&self, out: &mut [KnownBoard]) -> usize {
        self.boards_from(0, out).0
    }

    /// As [`X10::boards`], from the `first`-th board on; also returns how many boards are
    /// known in all, and the board being updated ([`X10::updating`]).
    pub fn boards_from(
        &self,
        first: usize,
        out: &mut [KnownBoard],
    ) -> (usize, usize, Option<Address>) {
        self.core.with(|t| {
            let known = t.directory.known();
            let copied = out
                .iter_mut()
                .zip(known.iter().skip(first))
                .map(|(o, b)| *o = *b)
                .count();
            (copied, known.len(), t.updating)
        })
    }

    /// The known board that `q` names (present or not), if any.
    pub fn board(&self, q: BoardQuery) -> Option<KnownBoard> {
        self.core.with(|t| t.directory.find(q))
    }

    /// Waits until a board that `q` names is present (its `boot` or `announce` came in), at
    /// most `timeout_us`; looks every [`WAIT_FOR_BOARD_POLL_US`].
    ///
    /// # Errors
    /// [`LinkError::Timeout`] when none is present by then.
    pub async fn wait_for_board(
        &self,
        q: BoardQuery,
        timeout_us: u64,
    ) -> Result<KnownBoard, LinkError> {
        let deadline = now().plus_us(timeout_us);
        loop {
            if let Some(b) = self.board(q).filter(|b| b.present) {
                return Ok(b);
            }
            let t = now();
            if t >= deadline {
                return Err(LinkError::Timeout);
            }
            sleep_until(t.plus_us(WAIT_FOR_BOARD_POLL_US).min(deadline)).await;
        }
    }

    /// Moves the board at `old` to `new` (`set_address`, Dynamixel's ID write): the board
    /// keeps `new` in its record, answers, and starts again there; the motherboard then
    /// finds it at `new` by its `boot` event.
    ///
    /// # Errors
    /// As [`X10::call`]; `LinkError::Status(unsupported)` from a board that keeps no
    /// address (a build-time override), `busy` when its record could not be written.
    pub async fn set_address(&self, old: Address, new: Address) -> Result<(), LinkError> {
        self.core.call(old, Op::SetAddress(new)).await?;
        self.core.with(|t| t.directory.moved(old, new));
        Ok(())
    }

    /// Gives the board with unique ID `uid` the address `to` (a person fixing addresses, the
    /// USB link's assign), through plug and play's own operations: a board that answers at an
    /// address is sent `set_address` there ([`X10::set_address`]); one that does not
    /// (unaddressed) an `assign` with its ID at `0x77`, sent by the dispatcher. Either way it
    /// starts again at `to`, and this returns once its `boot` came from there (within
    /// [`ASSIGN_WAIT_US`]): robot calls to `to` then reach it.
    ///
    /// # Errors
    /// [`AssignError`]: the refusals before anything is sent (unknown ID, reserved address,
    /// address taken, a board in a collision), or the board did not confirm.
    pub async fn assign(&self, uid: Uid, to: Address) -> Result<(), AssignError> {
        if let Some(old) = self.assign_step(uid, to)? {
            self.call(old, Op::SetAddress(to))
                .await
                .map_err(AssignError::NotConfirmed)?;
            self.moved(old, to);
        }
        self.assign_wait(uid, to).await
    }

    /// [`X10::assign`]'s first step, for a caller that sends the `set_address` itself (the
    /// USB link, through its one call site): refuses, or queues the `assign` of a board that
    /// does not answer (`None`), or names the address the board answers at (`Some`: send it
    /// `Op::SetAddress(to)` there, then [`X10::moved`]). Then [`X10::assign_wait`].
    ///
    /// # Errors
    /// As [`X10::assign`], before anything is sent.
    pub fn assign_step(&self, uid: Uid, to: Address) -> Result<Option<Address>, AssignError> {
        let mb = self.core.config.address;
        let pinned = self.core.config.pinned;
        let plan = self.core.with(|t| {
            let plan = {
                let boards = &t.boards;
                t.directory
                    .assign_plan(uid, to, mb, pinned, |a| boards.ports_known(a))?
            };
            if plan == AssignPlan::Assign {
                t.directory.reassign(uid, to);
            }
            Ok(plan)
        })?;
        Ok(match plan {
            AssignPlan::SetAddress(old) => Some(old),
            AssignPlan::Assign => {
                // The dispatcher looks at its plug-and-play work again.
                self.core.keepalive_changed.signal(());
                None
            }
            AssignPlan::Already => None,
        })
    }

    /// The board at `from` confirmed `set_address(to)`: the directory has it at `to`, present
    /// again once its `boot` comes from there.
    pub fn moved(&self, from: Address, to: Address) {
        self.core.with(|t| t.directory.moved(from, to));
    }

    /// Waits until the board `uid` answers at `to` (its `boot` came from there), at most
    /// [`ASSIGN_WAIT_US`].
    ///
    /// # Errors
    /// [`AssignError::NotConfirmed`] with `Timeout`.
    pub async fn assign_wait(&self, uid: Uid, to: Address) -> Result<(), AssignError> {
        match self
            .wait_for_board(BoardQuery::Uid(uid), ASSIGN_WAIT_US)
            .await
        {
            Ok(b) if b.address == to => Ok(()),
            _ => Err(AssignError::NotConfirmed(LinkError::Timeout)),
        }
    }

    /// Starts the update of the board `uid` now (whatever the image's `UpdatePolicy`), or of
    /// every present board out of date (`None`; a `Never` policy overridden, pins kept), with
    /// the images the updater carries (`update::run_updates`). Answers at once: how many boards
    /// the updater will bring to the carried version at its next look (within
    /// `update::UPDATE_POLL_US`); the progress reaches the call observer
    /// (`CallObserver::update`: the USB link's records).
    ///
    /// # Errors
    /// [`UpdateRefusal`], as `update::start_decision` decides.
    pub fn start_update(&self, uid: Option<Uid>) -> Result<u8, UpdateRefusal> {
        self.core.with(|t| {
            let n = crate::update::start_decision(
                t.carried,
                t.update_policy,
                t.directory.known(),
                t.updating,
                t.update_now.is_some(),
                uid,
            )?;
            t.update_now = Some(uid);
            Ok(n)
        })
    }

    /// The board whose firmware is being updated, if any.
    pub fn updating(&self) -> Option<Address> {
        self.core.with(|t| t.updating)
    }

    /// Blinks the status LED of the board at `db` for `secs` seconds (0 stops), to find it
    /// by eye.
    ///
    /// # Errors
    /// As [`X10::call`]; `LinkError::Status(unsupported)` from a board without one.
    pub async fn blink(&self, db: Address, secs: u8) -> Result<(), LinkError> {
        self.core.call(db, Op::Blink(secs)).await.map(|_| ())
    }

    /// Every sensor port of every board in `boards`, read from one moment: one `sample` to
    /// every board at once (the I2C general call), then one short read per board; a board
    /// that missed it is read with a `scan` of its own, one that is gone gets its error, and
    /// no board's error fails another's. See [`MbCore::sweep`].
    ///
    /// ```ignore
    /// let mut values = [Ok(ScanResult::default()); 3];
    /// x10.sweep(&[LEFT, RIGHT, HEAD], &mut values).await;
    /// ```
    pub async fn sweep(&self, boards: &[Address], out: &mut [SweepResult]) -> SweepSummary {
        self.core.sweep(boards, out).await
    }

    /// Outputs on several boards that change at once: set them in `set`, then they are
    /// applied together (one `apply` written to every board at once). See
    /// [`MbCore::together`].
    ///
    /// ```ignore
    /// x10.together(|t| {
    ///     t.set(LEFT, Op::PwmDuty(motor_a, 200))?;
    ///     t.set(RIGHT, Op::PwmDuty(motor_a, 200))
    /// })
    /// .await?;
    /// ```
    ///
    /// # Errors
    /// The first board that did not apply with the others ([`NotTogether`]).
    pub async fn together(
        &self,
        set: impl FnOnce(&mut Together) -> Result<(), LinkError>,
    ) -> Result<(), NotTogether> {
        self.core.together(set).await
    }

    /// The motherboard's counters.
    pub fn diagnostics(&self) -> MbDiagnostics {
        self.core.diagnostics()
    }

    /// The motherboard's configuration.
    pub fn config(&self) -> &'static MbConfig {
        &self.core.config
    }

    /// True when PEC is negotiated with `db`.
    pub fn pec_enabled(&self, db: Address) -> bool {
        self.core.pec_enabled(db)
    }

    /// The shared runtime state behind the handle.
    pub fn core(&self) -> &'static MbCore {
        self.core
    }
}

impl core::fmt::Debug for X10 {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("X10")
            .field("address", &self.core.config.address)
            .finish()
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for X10 {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "X10 {{ address: {} }}", self.core.config.address)
    }
}

impl Link for X10 {
    fn call(&self, db: Address, op: Op<'_>) -> impl Future<Output = Result<Payload, LinkError>> {
        crate::mb_core::call_with(self.core, db, op, None)
    }

    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        self.core.wait_event(db, pin).await
    }
}

impl Link for MbCore {
    fn call(&self, db: Address, op: Op<'_>) -> impl Future<Output = Result<Payload, LinkError>> {
        crate::mb_core::call_with(self, db, op, None)
    }

    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        MbCore::wait_event(self, db, pin).await
    }
}
