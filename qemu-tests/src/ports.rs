//! A recording [`Ports`] with set levels, analog values and scripted pulses.

use core::cell::{Cell, RefCell};

use firmware_db::{PortError, Ports};
use x10_hal::time::Clock;
use x10_microcode::{Edge, Level, PinRef, Port, PortKind};

use crate::QemuClock;

/// One call the runtime made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum PortOp {
    /// `digital_read`.
    DigitalRead(PinRef),
    /// `digital_write`.
    DigitalWrite(PinRef, Level),
    /// `pwm_duty`.
    PwmDuty(PinRef, u8),
    /// `pwm_frequency`.
    PwmFrequency(Port, u16),
    /// `pwm_pulse_width`.
    PwmPulseWidth(PinRef, u16),
    /// `analog_read`.
    AnalogRead(Port),
    /// `pulse_in`.
    PulseIn(PinRef, Edge, u16),
}

/// Most calls kept in the log (later ones are counted, not kept).
pub const LOG_LEN: usize = 24;

/// Sensor ports and actuator ports of the fake board.
pub const PORTS: u8 = 2;

/// A board with [`PORTS`] ports of each kind: digital inputs read what [`FakePorts::set_level`]
/// set, analog inputs what [`FakePorts::set_analog`] set, a pulse-in waits and answers what
/// [`FakePorts::set_pulse`] scripted. Every call is logged.
pub struct FakePorts {
    levels: RefCell<[[bool; 2]; PORTS as usize]>,
    analog: RefCell<[u16; PORTS as usize]>,
    pulse: Cell<Option<(u64, Result<u32, PortError>)>>,
    log: RefCell<heapless::Vec<PortOp, LOG_LEN>>,
    dropped: Cell<usize>,
}

impl Default for FakePorts {
    fn default() -> Self {
        Self::new()
    }
}

impl FakePorts {
    /// All inputs low, analog 0, no pulse.
    pub const fn new() -> FakePorts {
        FakePorts {
            levels: RefCell::new([[false; 2]; PORTS as usize]),
            analog: RefCell::new([0; PORTS as usize]),
            pulse: Cell::new(None),
            log: RefCell::new(heapless::Vec::new()),
            dropped: Cell::new(0),
        }
    }

    /// Sets the level a sensor pin reads.
    pub fn set_level(&self, pin: PinRef, high: bool) {
        if let Some(p) = self
            .levels
            .borrow_mut()
            .get_mut(usize::from(pin.port.index()))
        {
            p[pin.pin.index()] = high;
        }
    }

    /// Sets what a sensor port's analog input reads.
    pub fn set_analog(&self, port: Port, value: u16) {
        if let Some(v) = self.analog.borrow_mut().get_mut(usize::from(port.index())) {
            *v = value;
        }
    }

    /// The next pulse-in waits `after_us`, then answers `result`.
    pub fn set_pulse(&self, after_us: u64, result: Result<u32, PortError>) {
        self.pulse.set(Some((after_us, result)));
    }

    /// The calls so far (emptied).
    pub fn take_log(&self) -> heapless::Vec<PortOp, LOG_LEN> {
        core::mem::take(&mut *self.log.borrow_mut())
    }

    fn record(&self, op: PortOp) {
        if self.log.borrow_mut().push(op).is_err() {
            self.dropped.set(self.dropped.get() + 1);
        }
    }

    fn check(&self, port: Port) -> Result<usize, PortError> {
        let i = usize::from(port.index());
        if i < usize::from(PORTS) {
            Ok(i)
        } else {
            Err(PortError::NoSuchPin)
        }
    }
}

impl Ports for FakePorts {
    fn sensor_ports(&self) -> u8 {
        PORTS
    }

    fn actuator_ports(&self) -> u8 {
        PORTS
    }

    fn adc_bits(&self) -> u8 {
        12
    }

    fn digital_read(&self, pin: PinRef) -> Result<Level, PortError> {
        self.record(PortOp::DigitalRead(pin));
        let i = self.check(pin.port)?;
        let high = match pin.port.kind() {
            PortKind::Sensor => self.levels.borrow()[i][pin.pin.index()],
            PortKind::Actuator => false,
        };
        Ok(Level::from_bool(high))
    }

    fn digital_write(&self, pin: PinRef, level: Level) -> Result<(), PortError> {
        self.record(PortOp::DigitalWrite(pin, level));
        self.check(pin.port).map(|_| ())
    }

    fn pwm_duty(&self, pin: PinRef, duty: u8) -> Result<(), PortError> {
        self.record(PortOp::PwmDuty(pin, duty));
        self.check(pin.port).map(|_| ())
    }

    fn pwm_frequency(&self, port: Port, hz: u16) -> Result<(), PortError> {
        self.record(PortOp::PwmFrequency(port, hz));
        self.check(port).map(|_| ())
    }

    fn pwm_pulse_width(&self, pin: PinRef, us: u16) -> Result<(), PortError> {
        self.record(PortOp::PwmPulseWidth(pin, us));
        self.check(pin.port).map(|_| ())
    }

    fn analog_read(&self, port: Port) -> Result<u16, PortError> {
        self.record(PortOp::AnalogRead(port));
        let i = self.check(port)?;
        Ok(self.analog.borrow()[i])
    }

    async fn pulse_in(&self, pin: PinRef, edge: Edge, timeout_ms: u16) -> Result<u32, PortError> {
        self.record(PortOp::PulseIn(pin, edge, timeout_ms));
        self.check(pin.port)?;
        let Some((after_us, result)) = self.pulse.take() else {
            return Err(PortError::Timeout);
        };
        let clock = QemuClock;
        clock.sleep_us(after_us).await;
        result
    }
}
