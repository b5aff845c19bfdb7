//! One multi-master I2C port.

/// Why a bus transaction failed. Boards map their driver errors onto these.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BusError {
    /// The address (or a data byte) was not acknowledged: nobody there, or the node is deaf
    /// (an RP2040 in its controller window).
    Nack,
    /// Another master won arbitration; nothing of ours was delivered. Retry after the bus is
    /// idle again.
    ArbitrationLost,
    /// The bus stayed busy, or a clock-stretching target held SCL, past the port's timeout.
    Timeout,
    /// Misplaced START/STOP, stuck line or another bus fault.
    Bus,
    /// Data was lost inside the port (overrun/underrun), or a received transfer did not fit the
    /// buffer.
    Overrun,
}

/// What a controller asked of this node while it listened as a target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Incoming {
    /// A write of `n` bytes (now in the listen buffer), ended by STOP.
    Write(usize),
    /// A read with nothing written first: call [`MultiMaster::respond`].
    Read,
    /// A write of `n` bytes followed by a repeated START and a read: call
    /// [`MultiMaster::respond`] with the reply.
    WriteRead(usize),
}

/// One multi-master I2C port: controller transactions and target listening on one bus.
///
/// Addresses are 7-bit. A port that cannot be controller and target at once (RP2040) switches
/// roles inside these calls, only while the bus is idle; a port that can (STM32 I2C v2
/// `MultiMaster`) just forwards them. Either way the caller sees one port and is the only one
/// using it.
///
/// # Contract the runtimes rely on
///
/// * **Waiting versus receiving.** [`MultiMaster::addressed`] is the cancel-safe wait (it
///   consumes nothing); [`MultiMaster::listen`] and [`MultiMaster::respond`] are never
///   cancelled once a transaction has been announced. A real port cannot give back bytes it
///   already took off the wire, so a `listen` dropped mid-transfer loses it (the simulator
///   counts such losses in its `BusStats::lost_transfers`).
/// * **Addressed while waiting to start.** If this port's own address is matched (another
///   controller addresses it: STM32 `ISR.ADDR`, RP2040 `IC_STATUS.SLV_ACTIVITY` or the
///   address-match interrupt) while a [`MultiMaster::write`] or [`MultiMaster::write_read`]
///   of this port is still waiting for the bus, that call must give up at once with
///   [`BusError::ArbitrationLost`] instead of waiting. The other controller's transaction is
///   held (SCL stretched) by this very port until someone calls [`MultiMaster::listen`], so
///   waiting for a free bus would deadlock the node against itself until the SMBus timeout
///   (25 ms) or the driver's own timeout (1 s by default on STM32). On `ArbitrationLost` the
///   runtimes wait on `addressed`, serve that transaction with `listen`, and retry right
///   after it without counting the attempt. The simulator (`x10-sim`, `bus.rs`) models ports this way.
/// * **Lost arbitration** ends the call with [`BusError::ArbitrationLost`] as soon as the
///   port notices it; nothing of ours was delivered.
/// * **Single-role ports** NACK their own address while they are controllers, and until
///   their target is armed again after the call returns. Keep that role switch shorter than
///   the daughterboards' first event retry (the `base_us` of their
///   [`crate::retry::RetryPolicy`], 100 µs by default): the event that beat the port in
///   arbitration is NACKed, and its first retry must find the port listening (the
///   motherboard listens at least `MbConfig::arbitration_wait_us`, 400 µs by default, before
///   it retries after a lost arbitration).
#[allow(async_fn_in_trait)]
pub trait MultiMaster {
    /// Writes `bytes` to `addr` (START, address+W, bytes, STOP).
    ///
    /// # Errors
    /// [`BusError::Nack`], [`BusError::ArbitrationLost`] (lost on the wire, or this port was
    /// addressed while the call waited for the bus: see the trait's contract),
    /// [`BusError::Timeout`], [`BusError::Bus`].
    async fn write(&mut self, addr: u8, bytes: &[u8]) -> Result<(), BusError>;

    /// Writes `bytes` to `addr`, then reads `read.len()` bytes after a repeated START.
    ///
    /// # Errors
    /// As [`MultiMaster::write`].
    async fn write_read(&mut self, addr: u8, bytes: &[u8], read: &mut [u8])
        -> Result<(), BusError>;

    /// Reads `read.len()` bytes from `addr` with nothing written first (START, address+R,
    /// bytes, STOP): how a motherboard collects what a general call left on each board
    /// (a sweep). The default is [`MultiMaster::write_read`] with no bytes written, for ports
    /// whose controller sends an empty write phase then a repeated START (10 bit times more);
    /// a daughterboard takes both forms alike.
    ///
    /// # Errors
    /// As [`MultiMaster::write`].
    async fn read(&mut self, addr: u8, read: &mut [u8]) -> Result<(), BusError> {
        self.write_read(addr, &[], read).await
    }

    /// Waits until a controller has addressed this node at its own address (address matched;
    /// the port holds the transaction, SCL stretched or bytes queued in its receive FIFO, until
    /// [`MultiMaster::listen`] takes it). Returns at once when such a transaction is already
    /// waiting.
    ///
    /// Consumes nothing. Cancel safety: the future may be dropped at any time and loses
    /// nothing; this is the call the runtimes race against their other work (a queued request,
    /// a timer, an event to send). Once it has returned `Ok`, the caller must go on with
    /// [`MultiMaster::listen`] (and [`MultiMaster::respond`] for a read) before anything else:
    /// the other controller's transaction is held until then.
    ///
    /// # Errors
    /// [`BusError::Bus`] when the port's target side failed.
    async fn addressed(&mut self) -> Result<(), BusError>;

    /// Receives the transaction [`MultiMaster::addressed`] announced (or, called without it,
    /// waits for the next one addressed to this node): the bytes written go into `buf`.
    ///
    /// Never race it: once a transaction addressed to this node has started, dropping this
    /// future loses the transfer (the bytes already received, and on some ports the bus
    /// itself, which stays stretched until the port is reset). Callers that must also wait
    /// for something else select on [`MultiMaster::addressed`] and, when it wins, await
    /// `listen` (and `respond`) to completion.
    ///
    /// # Errors
    /// [`BusError::Overrun`] when a write does not fit `buf`, [`BusError::Bus`],
    /// [`BusError::Timeout`] when the controller stopped clocking mid-transfer.
    async fn listen(&mut self, buf: &mut [u8]) -> Result<Incoming, BusError>;

    /// Answers the read part of the last [`Incoming::Read`] or [`Incoming::WriteRead`].
    /// If the controller reads more bytes than given, the port sends 0xFF.
    ///
    /// # Errors
    /// [`BusError::Bus`], [`BusError::Timeout`].
    async fn respond(&mut self, bytes: &[u8]) -> Result<(), BusError>;
}
