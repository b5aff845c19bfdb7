//! The handle robot programs use.

use embassy_sync::blocking_mutex::raw::RawMutex;
use firmware_db::Ports;
use x10_devices::{Link, LinkError, PinEvent};
use x10_hal::time::Clock;
use x10_microcode::{Address, Op, Payload, PinRef};

use crate::motherboard::Motherboard;

/// A cheap, `Copy` handle on a [`Motherboard`] for robot tasks: implements
/// [`x10_devices::Link`], so every driver works through it. Clone it into as many tasks as
/// needed; each call gets its own sequence number and its own reply.
pub struct MbHandle<'a, M: RawMutex, P: Ports, C: Clock> {
    mb: &'a Motherboard<M, P, C>,
}

impl<'a, M: RawMutex, P: Ports, C: Clock> MbHandle<'a, M, P, C> {
    /// A handle on `mb`.
    pub fn new(mb: &'a Motherboard<M, P, C>) -> Self {
        MbHandle { mb }
    }

    /// The motherboard behind the handle.
    pub fn motherboard(&self) -> &'a Motherboard<M, P, C> {
        self.mb
    }

    /// [`Link::call`] with an explicit timeout in µs.
    ///
    /// # Errors
    /// As [`Motherboard::call_with_timeout`].
    pub async fn call_with_timeout(
        &self,
        db: Address,
        op: Op<'_>,
        timeout_us: u64,
    ) -> Result<Payload, LinkError> {
        self.mb.call_with_timeout(db, op, timeout_us).await
    }
}

impl<M: RawMutex, P: Ports, C: Clock> Clone for MbHandle<'_, M, P, C> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<M: RawMutex, P: Ports, C: Clock> Copy for MbHandle<'_, M, P, C> {}

impl<M: RawMutex, P: Ports, C: Clock> Link for MbHandle<'_, M, P, C> {
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        self.mb.call(db, op).await
    }

    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        self.mb.wait_event(db, pin).await
    }
}

impl<M: RawMutex, P: Ports, C: Clock> Link for Motherboard<M, P, C> {
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        Motherboard::call(self, db, op).await
    }

    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        Motherboard::wait_event(self, db, pin).await
    }
}
