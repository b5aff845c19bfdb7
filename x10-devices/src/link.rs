//! The one trait every driver talks through.

use core::fmt;

use x10_microcode::{Address, EventKind, Op, Payload, PinRef, Status};

/// Why an operation sent through a [`Link`] failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkError {
    /// The board did not acknowledge (absent, unpowered, or deaf while it was a master) after
    /// every retry.
    Nack,
    /// No reply (or deferred reply) arrived in time.
    Timeout,
    /// Arbitration was lost on every retry.
    ArbitrationLost,
    /// A bus fault (stuck line, misplaced START/STOP).
    Bus,
    /// A reply arrived but was malformed (bad length, PEC mismatch).
    BadReply,
    /// The board answered with this non-`ok` status.
    Status(Status),
    /// The operation could not be encoded (a value out of range): nothing was sent.
    Invalid(x10_microcode::Error),
    /// The runtime has no room for another outstanding request right now.
    Busy,
    /// The link does not offer this (e.g. events on a test double that has none).
    Unsupported,
    /// The board is having its firmware updated by the motherboard (issue 25): nothing was
    /// sent; it answers again once the update has ended.
    Updating,
}

impl From<x10_microcode::Error> for LinkError {
    fn from(e: x10_microcode::Error) -> Self {
        LinkError::Invalid(e)
    }
}

impl fmt::Display for LinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkError::Nack => f.write_str("not acknowledged"),
            LinkError::Timeout => f.write_str("timed out"),
            LinkError::ArbitrationLost => f.write_str("arbitration lost on every retry"),
            LinkError::Bus => f.write_str("bus fault"),
            LinkError::BadReply => f.write_str("malformed reply"),
            LinkError::Status(s) => write!(f, "board answered {s}"),
            LinkError::Invalid(e) => write!(f, "invalid operation: {e}"),
            LinkError::Busy => f.write_str("too many requests outstanding"),
            LinkError::Unsupported => f.write_str("not supported by this link"),
            LinkError::Updating => f.write_str("the board's firmware is being updated"),
        }
    }
}

impl core::error::Error for LinkError {}

/// An event delivered to a robot program (pin change or analog threshold).
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PinEvent {
    /// Board that sent it.
    pub source: Address,
    /// [`EventKind::PinChange`] or [`EventKind::AnalogThreshold`].
    pub kind: EventKind,
    /// Port and pin.
    pub pin: PinRef,
    /// Payload as sent (new level; or analog value u16 LE and inside flag).
    pub value: Payload,
}

/// How drivers reach daughterboards: send one operation to one board, await its outcome.
///
/// The motherboard runtime, the internal daughterboard, the simulator and test doubles all
/// implement it; drivers never see I2C. The implementation assigns sequence numbers, routes
/// address 0 to the internal board, retries, and matches replies.
///
/// `call` resolves:
/// * for outputs (digital write, PWM, configuration): once the board acknowledged the write,
///   with an empty payload;
/// * for reads: with the reply payload, when the status is `ok`;
/// * for deferred operations (pulse-in): with the payload of the deferred reply.
///
/// Any other status is `Err(LinkError::Status(..))`.
#[allow(async_fn_in_trait)]
pub trait Link {
    /// Sends `op` to board `db` and waits for its outcome.
    ///
    /// # Errors
    /// Every [`LinkError`] variant but `Unsupported`.
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError>;

    /// Waits for the next pin-change or analog-threshold event from `pin` on board `db`
    /// (enable it first with `Op::EventEnable`).
    ///
    /// # Errors
    /// [`LinkError::Unsupported`] when the link delivers no events (the default).
    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        let _ = (db, pin);
        Err(LinkError::Unsupported)
    }
}

impl<L: Link + ?Sized> Link for &L {
    async fn call(&self, db: Address, op: Op<'_>) -> Result<Payload, LinkError> {
        (**self).call(db, op).await
    }

    async fn wait_event(&self, db: Address, pin: PinRef) -> Result<PinEvent, LinkError> {
        (**self).wait_event(db, pin).await
    }
}
