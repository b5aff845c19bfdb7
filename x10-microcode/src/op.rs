//! Operations: what a request (or one item of a batch) asks a daughterboard to do.
//!
//! An operation is encoded in three places: byte 0 (function in the high nibble, operand in the
//! low nibble), byte 2 (port kind, port index, pin) and the data bytes. [`Op::parse`] and
//! [`Op::emit_data`] translate between those bytes and [`Op`]; [`crate::Request`] and
//! [`crate::Batch`] add the framing around them.

use crate::system::EventConfig;
use crate::types::{Edge, Level, PinRef, Port, PortKind};
use crate::{Batch, Error, Result, MAX_PAYLOAD, MAX_REQUEST_DATA};

/// Function codes: the high nibble of byte 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Function {
    /// 0x0, new: ping, identify, heartbeat, failsafe, event enables, diagnostics, PEC.
    System,
    /// 0x1, thesis `FN_IO`: digital input, low, high, pulse-in.
    Io,
    /// 0x2, thesis `FN_PWM`: duty cycle (and, new, frequency and pulse width).
    Pwm,
    /// 0x3, thesis `FN_ANALOG`: analog read of a sensor port.
    Analog,
    /// 0x4, thesis `FN_SERIAL` (defined, never implemented there): serial on a port's two pins.
    Serial,
    /// 0x5, new: several operations in one transfer.
    Batch,
    /// 0x6, new: every sensor port of the board in one reply.
    Scan,
    /// 0x7, new: the frames a board's bootloader answers during a firmware update.
    Update,
    /// 0x8, new: requests to every board at once, written to the I2C general call address
    /// (`sample` for a sweep, `apply` for staged outputs).
    Sweep,
    /// 0x9, new: outputs held by the board until an `apply`.
    Stage,
    /// Any other code.
    Unknown(u8),
}

impl Function {
    /// Decodes a 4-bit function code.
    pub const fn from_code(code: u8) -> Function {
        match code {
            0 => Function::System,
            1 => Function::Io,
            2 => Function::Pwm,
            3 => Function::Analog,
            4 => Function::Serial,
            5 => Function::Batch,
            6 => Function::Scan,
            7 => Function::Update,
            8 => Function::Sweep,
            9 => Function::Stage,
            x => Function::Unknown(x),
        }
    }

    /// The 4-bit function code.
    pub const fn code(self) -> u8 {
        match self {
            Function::System => 0,
            Function::Io => 1,
            Function::Pwm => 2,
            Function::Analog => 3,
            Function::Serial => 4,
            Function::Batch => 5,
            Function::Scan => 6,
            Function::Update => 7,
            Function::Sweep => 8,
            Function::Stage => 9,
            Function::Unknown(x) => x,
        }
    }

    /// Name used by the `x10` tool and the docs.
    pub const fn name(self) -> &'static str {
        match self {
            Function::System => "system",
            Function::Io => "io",
            Function::Pwm => "pwm",
            Function::Analog => "analog",
            Function::Serial => "serial",
            Function::Batch => "batch",
            Function::Scan => "scan",
            Function::Update => "update",
            Function::Sweep => "sweep",
            Function::Stage => "stage",
            Function::Unknown(_) => "unknown",
        }
    }
}

/// Operand codes, named as in `docs/protocol.md`. (Used by [`Op::operand`].)
pub struct Operand;

#[allow(missing_docs)]
impl Operand {
    pub const SYS_PING: u8 = 0;
    pub const SYS_IDENTIFY: u8 = 1;
    pub const SYS_HEARTBEAT: u8 = 2;
    pub const SYS_SET_FAILSAFE: u8 = 3;
    pub const SYS_EVENT_ENABLE: u8 = 4;
    pub const SYS_READ_DIAGNOSTICS: u8 = 5;
    pub const SYS_CLEAR_DIAGNOSTICS: u8 = 6;
    pub const SYS_SET_PEC: u8 = 7;
    pub const SYS_ASSIGN: u8 = 8;
    pub const SYS_SET_ADDRESS: u8 = 9;
    pub const SYS_BLINK: u8 = 10;
    pub const SYS_WHO_IS_THERE: u8 = 11;
    pub const SYS_ENTER_UPDATE: u8 = 12;
    pub const SYS_CONFIRM_FIRMWARE: u8 = 13;
    pub const IO_INPUT: u8 = 0;
    pub const IO_LOW: u8 = 1;
    pub const IO_HIGH: u8 = 2;
    pub const IO_PULSE_IN_RISING: u8 = 3;
    pub const IO_PULSE_IN_FALLING: u8 = 4;
    pub const PWM_DUTY: u8 = 0;
    pub const PWM_FREQUENCY: u8 = 1;
    pub const PWM_PULSE_WIDTH: u8 = 2;
    pub const ANALOG_READ: u8 = 0;
    pub const SERIAL_WRITE: u8 = 0;
    pub const SERIAL_READ: u8 = 1;
    pub const SERIAL_CONFIG: u8 = 2;
    pub const BATCH: u8 = 0;
    pub const SCAN: u8 = 0;
    pub const SWEEP_SAMPLE: u8 = 0;
    pub const SWEEP_APPLY: u8 = 1;
    pub const STAGE: u8 = 0;
}

/// One operation on a daughterboard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Op<'a> {
    /// System 0, ping: reply with status `ok` and no payload.
    Ping,
    /// System 1, identify: reply with an [`crate::Identity`].
    Identify,
    /// System 2, heartbeat: keeps the failsafe from tripping. No reply.
    Heartbeat,
    /// System 3, failsafe timeout in milliseconds (data: u16 LE; 0 turns the failsafe off).
    /// No reply.
    SetFailsafe {
        /// Milliseconds of MB silence after which every actuator goes to its safe state.
        timeout_ms: u16,
    },
    /// System 4, events for one pin (data: [`EventConfig`], 5 bytes). No reply.
    EventEnable(PinRef, EventConfig),
    /// System 5, read the diagnostics counters: reply with [`crate::Diagnostics`].
    ReadDiagnostics,
    /// System 6, clear the diagnostics counters. No reply.
    ClearDiagnostics,
    /// System 7, PEC on (1) or off (0) from the next frame on (data: 1 byte). No reply.
    SetPec(bool),
    /// System 8, plug and play: the board whose unique ID is `uid` takes `address` (data:
    /// the ID, 8 bytes, then the address, 1 byte in `0x08..=0x76`). Written to
    /// [`crate::Address::UNADDRESSED`], always with its check; every other board ignores it.
    /// No reply (nothing is ever read at that address).
    Assign {
        /// The board meant.
        uid: crate::Uid,
        /// Its new address.
        address: crate::Address,
    },
    /// System 9, the board keeps a new address (data: 1 byte in `0x08..=0x76`) and moves
    /// there once its reply (`ok`, empty) has been read.
    SetAddress(crate::Address),
    /// System 10, blink the status LED for this many seconds (data: 1 byte; 0 stops), to
    /// find the board by eye. No reply; a board without an LED refuses it (`unsupported`).
    Blink(u8),
    /// System 11, every board at the address queues an `announce` event from that address
    /// (two IDs for one address: a collision). No reply.
    WhoIsThere,
    /// System 12, firmware update: the board answers `ok` and, once the reply has been read,
    /// resets into its bootloader, which then answers [`Op::Update`] (a board without one
    /// answers `unsupported`). Its outputs go to their safe state by the reset.
    EnterUpdate,
    /// System 13, the running image marks itself good (it is kept at the next reset instead
    /// of being rolled back); `ok` also when there was nothing to confirm.
    ConfirmFirmware,
    /// Function 7, answered by a board's bootloader only ([`crate::UpdateFrame`]; build it
    /// with [`crate::UpdateOp::to_op`]).
    Update(crate::UpdateFrame<'a>),
    /// IO 0, read a digital pin (thesis `digitalIn`): reply payload 1 byte, 0 or 1.
    DigitalRead(PinRef),
    /// IO 1 / IO 2, drive a digital pin (thesis `digitalOut`). No reply.
    DigitalWrite(PinRef, Level),
    /// IO 3 / IO 4, measure a pulse (data: none, or u16 LE timeout in ms). The reply is
    /// `pending`; the width in µs (u32 LE) follows in a deferred-reply event.
    PulseIn {
        /// Pin to measure.
        pin: PinRef,
        /// Edge that starts the pulse.
        edge: Edge,
        /// Timeout in ms; `None` is the board's default (and no data bytes on the wire).
        timeout_ms: Option<u16>,
    },
    /// PWM 0, duty cycle 0–255 on a PWM pin of an actuator port (thesis `pwm`). No reply.
    PwmDuty(PinRef, u8),
    /// PWM 1, PWM frequency in Hz of both PWM pins of an actuator port (data: u16 LE, > 0).
    /// No reply.
    PwmFrequency(Port, u16),
    /// PWM 2, high time of each period in µs (data: u16 LE), for servos. No reply.
    PwmPulseWidth(PinRef, u16),
    /// ANALOG 0, read the analog input of a sensor port (thesis `analog`): reply payload u16 LE.
    AnalogRead(Port),
    /// SERIAL 0, send bytes on a port's pins (A = TX, B = RX). No reply.
    SerialWrite(Port, &'a [u8]),
    /// SERIAL 1, read up to n received bytes (data: 1 byte, n ≤ 28): reply payload the bytes.
    SerialRead(Port, u8),
    /// SERIAL 2, baud rate (data: u32 LE). No reply.
    SerialConfig(Port, u32),
    /// BATCH 0: several operations in one transfer; reply payload one result per item.
    Batch(Batch<'a>),
    /// SCAN 0: every sensor port at once; reply with a [`crate::ScanResult`].
    Scan,
    /// SWEEP 0, written to the general call address (byte 1 = 0), always with its check:
    /// every board samples its sensor ports at once and holds the reply (levels and values
    /// packed, [`crate::sweep::pack`], always with a CRC-16) for the motherboard's plain read.
    Sample,
    /// SWEEP 1, written to the general call address (or to one board), always with its
    /// check: every board applies what it holds staged, at once, and holds its status reply
    /// for a plain read (`ok` with nothing staged: nothing done).
    Apply,
    /// STAGE 0: outputs (batch items: io low/high, pwm duty, frequency, pulse width),
    /// checked now and held until an [`Op::Apply`] (or dropped after
    /// [`crate::sweep::STAGE_TIMEOUT_MS`]). No reply.
    Stage(Batch<'a>),
}

fn u16_le(data: &[u8]) -> Result<u16> {
    match *data {
        [a, b] => Ok(u16::from_le_bytes([a, b])),
        _ => Err(Error::BadLength),
    }
}

fn u32_le(data: &[u8]) -> Result<u32> {
    match *data {
        [a, b, c, d] => Ok(u32::from_le_bytes([a, b, c, d])),
        _ => Err(Error::BadLength),
    }
}

fn no_data(data: &[u8]) -> Result<()> {
    if data.is_empty() {
        Ok(())
    } else {
        Err(Error::BadLength)
    }
}

/// Port byte that must be zero (operations addressed to the board, not a port).
fn no_port(port: u8) -> Result<()> {
    if port == 0 {
        Ok(())
    } else {
        Err(Error::BadArgument)
    }
}

/// A port operation that takes no pin: bit 0 must be clear.
fn port_only(port: u8) -> Result<Port> {
    let p = PinRef::from_byte(port);
    if port & 1 != 0 {
        Err(Error::BadArgument)
    } else {
        Ok(p.port)
    }
}

fn require_kind(port: Port, kind: PortKind) -> Result<()> {
    if port.kind() == kind {
        Ok(())
    } else {
        Err(Error::WrongPortKind)
    }
}

fn copy_into(buf: &mut [u8], bytes: &[u8]) -> Result<usize> {
    buf.get_mut(..bytes.len())
        .ok_or(Error::BufferTooShort)?
        .copy_from_slice(bytes);
    Ok(bytes.len())
}

impl<'a> Op<'a> {
    /// Parses an operation from byte 0, byte 2 and the data bytes of a request (or a batch item).
    ///
    /// # Errors
    /// [`Error::UnknownFunction`], [`Error::UnknownOperand`], [`Error::BadLength`] (wrong data
    /// length), [`Error::BadArgument`] (reserved bits set, value out of range),
    /// [`Error::WrongPortKind`], [`Error::TooLong`], or a batch's item errors.
    pub fn parse(fn_op: u8, port: u8, data: &'a [u8]) -> Result<Op<'a>> {
        let function = fn_op >> 4;
        let operand = fn_op & 0x0f;
        let unknown = Error::UnknownOperand { function, operand };
        let pin = PinRef::from_byte(port);
        match Function::from_code(function) {
            Function::System => {
                let op = match operand {
                    Operand::SYS_PING => no_data(data).map(|_| Op::Ping),
                    Operand::SYS_IDENTIFY => no_data(data).map(|_| Op::Identify),
                    Operand::SYS_HEARTBEAT => no_data(data).map(|_| Op::Heartbeat),
                    Operand::SYS_SET_FAILSAFE => {
                        u16_le(data).map(|timeout_ms| Op::SetFailsafe { timeout_ms })
                    }
                    Operand::SYS_EVENT_ENABLE => {
                        let cfg = EventConfig::parse(data)?;
                        if cfg.analog_window {
                            // Only sensor ports have an analog input.
                            require_kind(pin.port, PortKind::Sensor)?;
                        }
                        return Ok(Op::EventEnable(pin, cfg));
                    }
                    Operand::SYS_READ_DIAGNOSTICS => no_data(data).map(|_| Op::ReadDiagnostics),
                    Operand::SYS_CLEAR_DIAGNOSTICS => no_data(data).map(|_| Op::ClearDiagnostics),
                    Operand::SYS_SET_PEC => match *data {
                        [0] => Ok(Op::SetPec(false)),
                        [1] => Ok(Op::SetPec(true)),
                        [_] => Err(Error::BadArgument),
                        _ => Err(Error::BadLength),
                    },
                    Operand::SYS_ASSIGN => match data {
                        [uid @ .., a] if uid.len() == crate::Uid::LEN => {
                            crate::Address::assignable(*a).and_then(|address| {
                                Ok(Op::Assign {
                                    uid: crate::Uid::parse(uid)?,
                                    address,
                                })
                            })
                        }
                        _ => Err(Error::BadLength),
                    },
                    Operand::SYS_SET_ADDRESS => match *data {
                        [a] => crate::Address::assignable(a).map(Op::SetAddress),
                        _ => Err(Error::BadLength),
                    },
                    Operand::SYS_BLINK => match *data {
                        [secs] => Ok(Op::Blink(secs)),
                        _ => Err(Error::BadLength),
                    },
                    Operand::SYS_WHO_IS_THERE => no_data(data).map(|_| Op::WhoIsThere),
                    Operand::SYS_ENTER_UPDATE => no_data(data).map(|_| Op::EnterUpdate),
                    Operand::SYS_CONFIRM_FIRMWARE => no_data(data).map(|_| Op::ConfirmFirmware),
                    _ => Err(unknown),
                }?;
                no_port(port)?;
                Ok(op)
            }
            Function::Io => match operand {
                Operand::IO_INPUT => no_data(data).map(|_| Op::DigitalRead(pin)),
                Operand::IO_LOW => no_data(data).map(|_| Op::DigitalWrite(pin, Level::Low)),
                Operand::IO_HIGH => no_data(data).map(|_| Op::DigitalWrite(pin, Level::High)),
                Operand::IO_PULSE_IN_RISING | Operand::IO_PULSE_IN_FALLING => {
                    let edge = if operand == Operand::IO_PULSE_IN_RISING {
                        Edge::Rising
                    } else {
                        Edge::Falling
                    };
                    let timeout_ms = if data.is_empty() {
                        None
                    } else {
                        Some(u16_le(data)?)
                    };
                    Ok(Op::PulseIn {
                        pin,
                        edge,
                        timeout_ms,
                    })
                }
                _ => Err(unknown),
            },
            Function::Pwm => {
                let op = match operand {
                    Operand::PWM_DUTY => match *data {
                        [duty] => Ok(Op::PwmDuty(pin, duty)),
                        _ => Err(Error::BadLength),
                    },
                    Operand::PWM_FREQUENCY => {
                        let hz = u16_le(data)?;
                        if hz == 0 {
                            return Err(Error::BadArgument);
                        }
                        Ok(Op::PwmFrequency(port_only(port)?, hz))
                    }
                    Operand::PWM_PULSE_WIDTH => u16_le(data).map(|us| Op::PwmPulseWidth(pin, us)),
                    _ => Err(unknown),
                }?;
                require_kind(pin.port, PortKind::Actuator)?;
                Ok(op)
            }
            Function::Analog => match operand {
                Operand::ANALOG_READ => {
                    no_data(data)?;
                    let p = port_only(port)?;
                    require_kind(p, PortKind::Sensor)?;
                    Ok(Op::AnalogRead(p))
                }
                _ => Err(unknown),
            },
            Function::Serial => {
                let op = match operand {
                    Operand::SERIAL_WRITE => {
                        if data.is_empty() {
                            Err(Error::BadLength)
                        } else {
                            Ok(Op::SerialWrite(pin.port, data))
                        }
                    }
                    Operand::SERIAL_READ => match *data {
                        [n] if n as usize <= MAX_PAYLOAD && n > 0 => {
                            Ok(Op::SerialRead(pin.port, n))
                        }
                        [_] => Err(Error::BadArgument),
                        _ => Err(Error::BadLength),
                    },
                    Operand::SERIAL_CONFIG => {
                        let baud = u32_le(data)?;
                        if baud == 0 {
                            return Err(Error::BadArgument);
                        }
                        Ok(Op::SerialConfig(pin.port, baud))
                    }
                    _ => Err(unknown),
                }?;
                port_only(port)?;
                Ok(op)
            }
            // One path for both (one call of `Batch::new_checked`: smaller images).
            f @ (Function::Batch | Function::Stage) => {
                if operand != Operand::BATCH {
                    return Err(unknown);
                }
                no_port(port)?;
                let b = Batch::checked(data, f == Function::Stage)?;
                Ok(if f == Function::Batch {
                    Op::Batch(b)
                } else {
                    Op::Stage(b)
                })
            }
            Function::Scan => {
                if operand != Operand::SCAN {
                    return Err(unknown);
                }
                no_data(data)?;
                no_port(port)?;
                Ok(Op::Scan)
            }
            Function::Update => crate::UpdateFrame::parse(operand, port, data).map(Op::Update),
            Function::Sweep => {
                let op = match operand {
                    Operand::SWEEP_SAMPLE => Op::Sample,
                    Operand::SWEEP_APPLY => Op::Apply,
                    _ => return Err(unknown),
                };
                no_data(data)?;
                no_port(port)?;
                Ok(op)
            }

            Function::Unknown(f) => Err(Error::UnknownFunction(f)),
        }
    }

    /// The function of this operation.
    pub const fn function(&self) -> Function {
        match self {
            Op::Ping
            | Op::Identify
            | Op::Heartbeat
            | Op::SetFailsafe { .. }
            | Op::EventEnable(..)
            | Op::ReadDiagnostics
            | Op::ClearDiagnostics
            | Op::SetPec(_)
            | Op::Assign { .. }
            | Op::SetAddress(_)
            | Op::Blink(_)
            | Op::WhoIsThere
            | Op::EnterUpdate
            | Op::ConfirmFirmware => Function::System,
            Op::DigitalRead(_) | Op::DigitalWrite(..) | Op::PulseIn { .. } => Function::Io,
            Op::PwmDuty(..) | Op::PwmFrequency(..) | Op::PwmPulseWidth(..) => Function::Pwm,
            Op::AnalogRead(_) => Function::Analog,
            Op::SerialWrite(..) | Op::SerialRead(..) | Op::SerialConfig(..) => Function::Serial,
            Op::Batch(_) => Function::Batch,
            Op::Scan => Function::Scan,
            Op::Update(_) => Function::Update,
            Op::Sample | Op::Apply => Function::Sweep,
            Op::Stage(_) => Function::Stage,
        }
    }

    /// The 4-bit operand code.
    pub const fn operand(&self) -> u8 {
        match self {
            Op::Ping => Operand::SYS_PING,
            Op::Identify => Operand::SYS_IDENTIFY,
            Op::Heartbeat => Operand::SYS_HEARTBEAT,
            Op::SetFailsafe { .. } => Operand::SYS_SET_FAILSAFE,
            Op::EventEnable(..) => Operand::SYS_EVENT_ENABLE,
            Op::ReadDiagnostics => Operand::SYS_READ_DIAGNOSTICS,
            Op::ClearDiagnostics => Operand::SYS_CLEAR_DIAGNOSTICS,
            Op::SetPec(_) => Operand::SYS_SET_PEC,
            Op::Assign { .. } => Operand::SYS_ASSIGN,
            Op::SetAddress(_) => Operand::SYS_SET_ADDRESS,
            Op::Blink(_) => Operand::SYS_BLINK,
            Op::WhoIsThere => Operand::SYS_WHO_IS_THERE,
            Op::EnterUpdate => Operand::SYS_ENTER_UPDATE,
            Op::ConfirmFirmware => Operand::SYS_CONFIRM_FIRMWARE,
            Op::Update(u) => u.operand(),
            Op::DigitalRead(_) => Operand::IO_INPUT,
            Op::DigitalWrite(_, Level::Low) => Operand::IO_LOW,
            Op::DigitalWrite(_, Level::High) => Operand::IO_HIGH,
            Op::PulseIn {
                edge: Edge::Rising, ..
            } => Operand::IO_PULSE_IN_RISING,
            Op::PulseIn {
                edge: Edge::Falling,
                ..
            } => Operand::IO_PULSE_IN_FALLING,
            Op::PwmDuty(..) => Operand::PWM_DUTY,
            Op::PwmFrequency(..) => Operand::PWM_FREQUENCY,
            Op::PwmPulseWidth(..) => Operand::PWM_PULSE_WIDTH,
            Op::AnalogRead(_) => Operand::ANALOG_READ,
            Op::SerialWrite(..) => Operand::SERIAL_WRITE,
            Op::SerialRead(..) => Operand::SERIAL_READ,
            Op::SerialConfig(..) => Operand::SERIAL_CONFIG,
            Op::Batch(_) => Operand::BATCH,
            Op::Scan => Operand::SCAN,
            Op::Sample => Operand::SWEEP_SAMPLE,
            Op::Apply => Operand::SWEEP_APPLY,
            Op::Stage(_) => Operand::STAGE,
        }
    }

    /// Byte 0: function in the high nibble, operand in the low nibble.
    pub const fn fn_op_byte(&self) -> u8 {
        (self.function().code() << 4) | self.operand()
    }

    /// The pin this operation names, if any (port-only operations give pin A).
    pub fn pin_ref(&self) -> Option<PinRef> {
        match *self {
            Op::EventEnable(p, _)
            | Op::DigitalRead(p)
            | Op::DigitalWrite(p, _)
            | Op::PulseIn { pin: p, .. }
            | Op::PwmDuty(p, _)
            | Op::PwmPulseWidth(p, _) => Some(p),
            Op::PwmFrequency(p, _)
            | Op::AnalogRead(p)
            | Op::SerialWrite(p, _)
            | Op::SerialRead(p, _)
            | Op::SerialConfig(p, _) => Some(p.into()),
            Op::Ping
            | Op::Identify
            | Op::Heartbeat
            | Op::SetFailsafe { .. }
            | Op::ReadDiagnostics
            | Op::ClearDiagnostics
            | Op::SetPec(_)
            | Op::Assign { .. }
            | Op::SetAddress(_)
            | Op::Blink(_)
            | Op::WhoIsThere
            | Op::EnterUpdate
            | Op::ConfirmFirmware
            | Op::Update(_)
            | Op::Batch(_)
            | Op::Scan
            | Op::Sample
            | Op::Apply
            | Op::Stage(_) => None,
        }
    }

    /// Byte 2: port kind, port index, pin (0 for operations addressed to the whole board).
    pub fn port_byte(&self) -> u8 {
        self.pin_ref().map_or(0, PinRef::to_byte)
    }

    /// Name of the operation within its function, as the `x10` tool prints it
    /// (`input`, `low`, `high`, `pulse_in_rising`, `pulse_in_falling`, `duty`, `read`, …).
    pub const fn name(&self) -> &'static str {
        match self {
            Op::Ping => "ping",
            Op::Identify => "identify",
            Op::Heartbeat => "heartbeat",
            Op::SetFailsafe { .. } => "set_failsafe",
            Op::EventEnable(..) => "event_enable",
            Op::ReadDiagnostics => "read_diagnostics",
            Op::ClearDiagnostics => "clear_diagnostics",
            Op::SetPec(_) => "set_pec",
            Op::Assign { .. } => "assign",
            Op::SetAddress(_) => "set_address",
            Op::Blink(_) => "blink",
            Op::WhoIsThere => "who_is_there",
            Op::EnterUpdate => "enter_update",
            Op::ConfirmFirmware => "confirm_firmware",
            Op::Update(u) => u.name(),
            Op::DigitalRead(_) => "input",
            Op::DigitalWrite(_, Level::Low) => "low",
            Op::DigitalWrite(_, Level::High) => "high",
            Op::PulseIn {
                edge: Edge::Rising, ..
            } => "pulse_in_rising",
            Op::PulseIn {
                edge: Edge::Falling,
                ..
            } => "pulse_in_falling",
            Op::PwmDuty(..) => "duty",
            Op::PwmFrequency(..) => "frequency",
            Op::PwmPulseWidth(..) => "pulse_width",
            Op::AnalogRead(_) => "read",
            Op::SerialWrite(..) => "write",
            Op::SerialRead(..) => "read",
            Op::SerialConfig(..) => "config",
            Op::Batch(_) => "batch",
            Op::Scan => "scan",
            Op::Sample => "sample",
            Op::Apply => "apply",
            Op::Stage(_) => "stage",
        }
    }

    /// Number of data bytes this operation puts on the wire.
    pub fn data_len(&self) -> usize {
        match self {
            Op::Ping
            | Op::Identify
            | Op::Heartbeat
            | Op::ReadDiagnostics
            | Op::ClearDiagnostics
            | Op::DigitalRead(_)
            | Op::DigitalWrite(..)
            | Op::AnalogRead(_)
            | Op::WhoIsThere
            | Op::EnterUpdate
            | Op::ConfirmFirmware
            | Op::Scan
            | Op::Sample
            | Op::Apply => 0,
            Op::SetPec(_)
            | Op::SetAddress(_)
            | Op::Blink(_)
            | Op::PwmDuty(..)
            | Op::SerialRead(..) => 1,
            Op::Assign { .. } => crate::Uid::LEN + 1,
            Op::SetFailsafe { .. } | Op::PwmFrequency(..) | Op::PwmPulseWidth(..) => 2,
            Op::PulseIn { timeout_ms, .. } => {
                if timeout_ms.is_some() {
                    2
                } else {
                    0
                }
            }
            Op::SerialConfig(..) => 4,
            Op::EventEnable(..) => EventConfig::LEN,
            Op::SerialWrite(_, data) => data.len(),
            Op::Batch(b) | Op::Stage(b) => b.as_bytes().len(),
            Op::Update(u) => u.data().len(),
        }
    }

    /// Writes the data bytes into `buf` and returns how many were written.
    ///
    /// # Errors
    /// [`Error::BufferTooShort`] when `buf` is shorter than [`Op::data_len`].
    pub fn emit_data(&self, buf: &mut [u8]) -> Result<usize> {
        match *self {
            Op::SetPec(on) => copy_into(buf, &[on as u8]),
            Op::SetAddress(a) => copy_into(buf, &[a.get()]),
            Op::Blink(secs) => copy_into(buf, &[secs]),
            Op::Assign { uid, address } => {
                let mut b = [0u8; crate::Uid::LEN + 1];
                let (u, a) = b.split_at_mut(crate::Uid::LEN);
                u.copy_from_slice(&uid.0);
                a.fill(address.get());
                copy_into(buf, &b)
            }
            Op::PwmDuty(_, d) => copy_into(buf, &[d]),
            Op::SerialRead(_, n) => copy_into(buf, &[n]),
            Op::SetFailsafe { timeout_ms: v }
            | Op::PwmFrequency(_, v)
            | Op::PwmPulseWidth(_, v)
            | Op::PulseIn {
                timeout_ms: Some(v),
                ..
            } => copy_into(buf, &v.to_le_bytes()),
            Op::SerialConfig(_, baud) => copy_into(buf, &baud.to_le_bytes()),
            Op::EventEnable(_, cfg) => copy_into(buf, &cfg.to_bytes()),
            Op::SerialWrite(_, data) => copy_into(buf, data),
            Op::Batch(b) | Op::Stage(b) => copy_into(buf, b.as_bytes()),
            Op::Update(u) => copy_into(buf, u.data()),
            // The operations without data: those whose `data_len` is 0 (which of them carry
            // data is `data_len`'s to say; tests/vectors.rs `request_emit` checks that the two
            // agree for every operation).
            _ => Ok(0),
        }
    }

    /// Checks what `parse` would check, for an operation built in code: data length within
    /// [`MAX_REQUEST_DATA`], values in range, port kinds right.
    ///
    /// # Errors
    /// The error `parse` would return for the emitted bytes.
    pub fn validate(&self) -> Result<()> {
        // The port operations and the system operations without data: what `parse` checks of
        // their bytes, without encoding them (the round trip costs about 170 instructions on
        // the Cortex-M0, a third of the motherboard's whole direct call to its own ports,
        // issue 27). `tests/vectors.rs` holds the two ways to the same answers for
        // every port byte.
        match *self {
            // No port byte: 0, which `parse` wants of them.
            Op::Ping | Op::Heartbeat | Op::Scan => return Ok(()),
            Op::DigitalRead(_) | Op::DigitalWrite(..) => return Ok(()),
            // The port's kind survives its byte (bit 7), and a port operation's byte has
            // pin A, so `port_only` never refuses it.
            Op::PwmDuty(pin, _) | Op::PwmPulseWidth(pin, _) => {
                return require_kind(pin.port, PortKind::Actuator)
            }
            Op::PwmFrequency(port, hz) => {
                if hz == 0 {
                    return Err(Error::BadArgument);
                }
                return require_kind(port, PortKind::Actuator);
            }
            Op::AnalogRead(port) => return require_kind(port, PortKind::Sensor),
            _ => {}
        }
        self.validate_encoded()
    }

    /// [`Op::validate`] the long way, for every operation: its data encoded and parsed back.
    ///
    /// # Errors
    /// As [`Op::validate`].
    pub fn validate_encoded(&self) -> Result<()> {
        if self.data_len() > MAX_REQUEST_DATA {
            return Err(Error::TooLong);
        }
        let mut data = [0u8; MAX_REQUEST_DATA];
        let n = self.emit_data(&mut data)?;
        let data = data.get(..n).ok_or(Error::BufferTooShort)?;
        Op::parse(self.fn_op_byte(), self.port_byte(), data).map(|_| ())
    }

    /// True when the MB must read a reply (a write-then-read transaction); false for outputs,
    /// which are a single write.
    pub const fn expects_reply(&self) -> bool {
        matches!(
            self,
            Op::Ping
                | Op::Identify
                | Op::SetAddress(_)
                | Op::ReadDiagnostics
                | Op::DigitalRead(_)
                | Op::PulseIn { .. }
                | Op::AnalogRead(_)
                | Op::SerialRead(..)
                | Op::Batch(_)
                | Op::Scan
                | Op::EnterUpdate
                | Op::ConfirmFirmware
                | Op::Update(_)
                | Op::Sample
                | Op::Apply
        )
    }

    /// True when the length of this operation's `ok` reply varies (scan, sample, serial
    /// read, batch): [`Op::reply_len`] is not [`ReplyLen::Exact`], and its reply always ends
    /// in a CRC-16 when checked. What `!self.reply_len().is_exact()` says, without building
    /// the [`ReplyLen`] (a batch's capacity is worked out for it): the daughterboard asks it
    /// of every request (`tests/reply_len.rs` holds the two together).
    pub const fn reply_len_varies(&self) -> bool {
        matches!(
            self,
            Op::SerialRead(..) | Op::Scan | Op::Batch(_) | Op::Sample
        )
    }

    /// Largest payload the reply to this operation can carry: how many bytes the MB reads
    /// (plus the reply header and PEC).
    pub fn reply_capacity(&self) -> usize {
        match self {
            Op::DigitalRead(_) => 1,
            Op::AnalogRead(_) => 2,
            Op::PulseIn { .. } => 0,
            Op::Identify => crate::Identity::LEN,
            Op::ReadDiagnostics => crate::Diagnostics::LEN,
            Op::SerialRead(_, n) => *n as usize,
            Op::Scan => crate::ScanResult::MAX_LEN,
            Op::Sample => crate::sweep::MAX_PAYLOAD_LEN,
            Op::Batch(b) => b.reply_capacity(),
            Op::Update(u) => u.reply_len(),
            _ => 0,
        }
    }

    /// True for the plug-and-play operations that change or report where a board is
    /// (`assign`, `set_address`, `who_is_there`): never in a batch (`bad_argument`), each is
    /// a transaction of its own.
    /// The firmware-update operations (`enter_update`, `confirm_firmware`, function 7) are
    /// counted here too: never in a batch.
    pub const fn moves_board(&self) -> bool {
        matches!(
            self,
            Op::Assign { .. }
                | Op::SetAddress(_)
                | Op::WhoIsThere
                | Op::EnterUpdate
                | Op::ConfirmFirmware
                | Op::Update(_)
        )
    }

    /// True for the operations of boards that act together (`sample`, `apply`, `stage`):
    /// never in a batch (`bad_argument`).
    pub const fn is_together(&self) -> bool {
        matches!(self, Op::Sample | Op::Apply | Op::Stage(_))
    }

    /// True for the outputs a `stage` may hold: io low/high, pwm duty, frequency and pulse
    /// width.
    pub const fn is_stageable(&self) -> bool {
        matches!(
            self,
            Op::DigitalWrite(..) | Op::PwmDuty(..) | Op::PwmFrequency(..) | Op::PwmPulseWidth(..)
        )
    }

    /// True for long operations whose value arrives later in a deferred-reply event.
    pub const fn is_deferred(&self) -> bool {
        matches!(self, Op::PulseIn { .. })
    }

    /// The payload lengths a reply with status `ok` to this operation may have (a reply with
    /// any other status, `pending` included, has an empty payload). An output read back in a
    /// write-then-read (as the motherboard does for `set_pec`) is answered `ok` with an empty
    /// payload. The motherboard refuses any other length as a bad reply, and checks the LEN
    /// byte against this before it looks for the PEC byte.
    pub fn reply_len(&self) -> ReplyLen {
        match self {
            Op::DigitalRead(_) => ReplyLen::Exact(1),
            Op::AnalogRead(_) => ReplyLen::Exact(2),
            Op::Identify => ReplyLen::Exact(crate::Identity::LEN as u8),
            Op::ReadDiagnostics => ReplyLen::Exact(crate::Diagnostics::LEN as u8),
            Op::SerialRead(_, n) => ReplyLen::Range {
                min: 0,
                max: *n,
                step: 1,
            },
            Op::Scan => ReplyLen::Range {
                min: 3,
                max: crate::ScanResult::MAX_LEN as u8,
                step: 2,
            },
            Op::Batch(b) => ReplyLen::Batch {
                max: b.reply_capacity().min(MAX_PAYLOAD) as u8,
            },
            // The levels (2) and 0 to 8 values packed in 12 bits: its length follows from
            // the board's sensor ports (`sweep::payload_len`).
            Op::Sample => ReplyLen::Range {
                min: 2,
                max: crate::sweep::MAX_PAYLOAD_LEN as u8,
                step: 1,
            },
            // `pending` (empty) comes first; the width follows in the deferred reply.
            Op::PulseIn { .. } => ReplyLen::Exact(0),
            Op::Update(u) => ReplyLen::Exact(u.reply_len() as u8),
            Op::Ping
            | Op::Heartbeat
            | Op::SetFailsafe { .. }
            | Op::EventEnable(..)
            | Op::ClearDiagnostics
            | Op::SetPec(_)
            | Op::Assign { .. }
            | Op::SetAddress(_)
            | Op::Blink(_)
            | Op::WhoIsThere
            | Op::EnterUpdate
            | Op::ConfirmFirmware
            | Op::DigitalWrite(..)
            | Op::PwmDuty(..)
            | Op::PwmFrequency(..)
            | Op::PwmPulseWidth(..)
            | Op::SerialWrite(..)
            | Op::SerialConfig(..)
            | Op::Apply
            | Op::Stage(_) => ReplyLen::Exact(0),
        }
    }

    /// Length of the payload of a `deferred_reply` event with status `ok` for this operation
    /// (the pulse width, u32), `None` for operations that are never deferred.
    pub const fn deferred_len(&self) -> Option<usize> {
        match self {
            Op::PulseIn { .. } => Some(4),
            _ => None,
        }
    }

    /// Checks a reply payload against this operation: `ok` must carry a length
    /// [`Op::reply_len`] allows (for a batch: one well-formed result per item, each of a
    /// length its item allows), every other status an empty payload. A deferred operation is
    /// never answered `ok` at once (it answers `pending`; see [`Op::check_deferred`]); a
    /// digital level is 0 or 1; a scan is as long as the number of ports it reports says.
    ///
    /// # Errors
    /// [`Error::BadLength`] when the payload does not fit.
    pub fn check_reply(&self, status: crate::Status, payload: &[u8]) -> Result<()> {
        // A deferred operation is answered `pending` (or refused) at once, never `ok`: its
        // value comes in the deferred reply ([`Op::check_deferred`]).
        if status == crate::Status::Ok && self.is_deferred() {
            return Err(Error::BadLength);
        }
        if status != crate::Status::Ok {
            return if payload.is_empty() {
                Ok(())
            } else {
                Err(Error::BadLength)
            };
        }
        let Ok(len) = u8::try_from(payload.len()) else {
            return Err(Error::BadLength);
        };
        if !self.reply_len().allows(len) {
            return Err(Error::BadLength);
        }
        match (self, payload) {
            // A level is 0 or 1.
            (Op::DigitalRead(_), [level]) if *level > 1 => return Err(Error::BadArgument),
            // A scan's length follows from the number of ports it reports.
            (Op::Scan, [n, ..]) => {
                let ports = usize::from(*n);
                if ports > crate::ScanResult::MAX_PORTS || payload.len() != 3 + 2 * ports {
                    return Err(Error::BadLength);
                }
            }
            _ => {}
        }
        if let Op::Batch(b) = self {
            let mut results = crate::BatchResults::new(payload);
            for item in b.iter() {
                let r = results.next().ok_or(Error::BadLength)?;
                let r = r.map_err(|_| Error::BadLength)?;
                item.check_reply(r.status, r.value)?;
            }
            if results.next().is_some() {
                return Err(Error::BadLength);
            }
        }
        Ok(())
    }
}

impl Op<'_> {
    /// Checks a `deferred_reply` event's status and payload against this operation: `ok`
    /// with exactly [`Op::deferred_len`] bytes, or another status (never `pending`) with an
    /// empty payload.
    ///
    /// # Errors
    /// [`Error::BadLength`] for anything else, and for an operation that is never deferred.
    pub fn check_deferred(&self, status: crate::Status, payload: &[u8]) -> Result<()> {
        let Some(len) = self.deferred_len() else {
            return Err(Error::BadLength);
        };
        match status {
            crate::Status::Ok if payload.len() == len => Ok(()),
            crate::Status::Ok | crate::Status::Pending => Err(Error::BadLength),
            _ if payload.is_empty() => Ok(()),
            _ => Err(Error::BadLength),
        }
    }
}

/// The payload lengths an `ok` reply to an operation may have ([`Op::reply_len`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReplyLen {
    /// Exactly this many bytes: the reply's length, and so where its PEC byte is, is known
    /// before a byte of it is read.
    Exact(u8),
    /// `min`, `min + step`, … up to `max` bytes.
    Range {
        /// Shortest payload.
        min: u8,
        /// Longest payload.
        max: u8,
        /// Step between allowed lengths (1: every length).
        step: u8,
    },
    /// A batch's results: at most `max` bytes, checked item by item ([`Op::check_reply`]).
    Batch {
        /// The longest the results can be (the sum of `2 + capacity` over the items).
        max: u8,
    },
}

impl ReplyLen {
    /// True for one fixed length ([`ReplyLen::Exact`]); the replies of the others always end
    /// in a CRC-16 when checked ([`crate::pec::append16`]).
    pub const fn is_exact(self) -> bool {
        matches!(self, ReplyLen::Exact(_))
    }

    /// True when an `ok` payload of `len` bytes is allowed (for a batch: not longer than its
    /// capacity and at least one result header per item is for [`Op::check_reply`]).
    pub const fn allows(self, len: u8) -> bool {
        match self {
            ReplyLen::Exact(n) => len == n,
            ReplyLen::Range { min, max, step } => {
                len >= min && len <= max && (step <= 1 || (len - min).is_multiple_of(step))
            }
            ReplyLen::Batch { max } => len >= 2 && len <= max,
        }
    }

    /// The longest allowed payload.
    pub const fn max(self) -> u8 {
        match self {
            ReplyLen::Exact(n) => n,
            ReplyLen::Range { max, .. } | ReplyLen::Batch { max } => max,
        }
    }
}
