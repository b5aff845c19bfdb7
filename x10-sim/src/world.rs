//! The world a robot program runs against: its boards, the devices on their ports and the
//! signals its sensors see over virtual time, described once in Rust ([`World`], a builder)
//! or in a small TOML file ([`World::from_toml`], [`World::load`]; the format is in
//! `docs/world.md`), then turned into a [`Sim`] ([`World::sim`]). After the run,
//! [`crate::timeline`] says per device what happened, in device words.
//!
//! ```
//! use x10_sim::sim::SimConfig;
//! use x10_sim::world::{Board, Device, Pin, Signal, World, SELF};
//!
//! let world = World::new()
//!     .board(Board::internal(2, 2))
//!     .board(Board::new(9, 2, 2))
//!     .device(Device::dc_motor("drive", SELF, 1))
//!     .device(Device::button("bumper", SELF, 2, Pin::B).pressed_at_ms(1_000, 50))
//!     .device(Device::light_sensor("light", SELF, 1).counts(Signal::linear([(0, 100.0), (4_000, 800.0)])))
//!     .device(Device::led("heartbeat", 9, 1, Pin::A));
//! let sim = world.sim(SimConfig::default()).unwrap();
//! // Add the robot program or test tasks to `sim`, then run it:
//! let outcome = sim.run().unwrap();
//! let timeline = x10_sim::timeline::Timeline::new(&world, &outcome);
//! assert!(!timeline.led("heartbeat").unwrap().last_state());
//! ```
//!
//! The device models:
//!
//! * **inputs** follow their scripts exactly: a button's pin is at its pressed level during
//!   each press; an analog sensor's ADC reading is its counts profile; a thermistor's reading
//!   is the raw value whose temperature, through the driver's own divider and Steinhart–Hart
//!   arithmetic, is closest to the scripted temperature ([`thermistor_raw`]); an ultrasonic
//!   ranger's echo pin answers a pulse-in after a trigger pulse with the echo width of the
//!   scripted distance ([`echo_width_us`], [`crate::ports::Digital::Echo`]);
//! * **outputs** are whatever the runtime drove, as the board's ports recorded it; the
//!   timeline decodes them (an H-bridge's direction and duty, an LED's level or brightness, a
//!   servo's angle).

mod arena;
mod board;
mod device;
mod error;
mod file;
mod model;
mod signal;

use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;

use x10_microcode::{Address, Port, PortKind};

pub use board::{Board, BoardKind, BoardRef, INTERNAL_NAME};
pub use device::{Device, DeviceKind, Ranger};
pub use error::{WorldError, WorldErrorKind};
pub use model::{echo_width_us, thermistor_raw};
pub use signal::{DigitalSignal, Signal};
pub use x10_devices::SELF;
pub use x10_microcode::Pin;

use self::device::{pin_letter, Use};
use self::error::bad;
pub(crate) use self::signal::seconds;
use crate::board::board_name;
use crate::ports::{Analog, Digital, SensorScript, SimPorts};
use crate::sim::{Sim, SimConfig};

/// Where in a world file a thing was written (for error messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Item {
    Board(usize),
    Device(usize),
    Physics,
    Chassis,
    Arena,
    Sensor(usize),
    Thermal(usize),
    Servo(usize),
    Image(usize),
}

/// A daughterboard image the motherboard carries (`[[image]]`): its board kind (the port
/// counts of a `simulated` kind do not matter) and its version. In the simulator it is a fake
/// of the right length and CRC (`x10_sim::firmware::fake_image`): the board model runs
/// whatever its flash says, the image only carries the version.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CarriedImage {
    /// The board kind it is built for.
    pub kind: BoardKind,
    /// Its version.
    pub version: x10_microcode::Version,
}

/// The boards and devices a robot program runs against.
#[derive(Clone, Debug, Default)]
pub struct World {
    boards: Vec<Board>,
    devices: Vec<Device>,
    /// The physical models (`[chassis]`, `[arena]`, …): [`crate::physics`].
    physics: crate::physics::Physics,
    /// Line of each (item, field) in the file the world came from.
    lines: HashMap<(Item, &'static str), usize>,
    /// The daughterboard images the motherboard carries (`[[image]]`).
    images: Vec<CarriedImage>,
}

/// Two worlds are equal when they have the same boards and the same devices on the same
/// boards (named by address or by name alike), wherever they came from.
impl PartialEq for World {
    fn eq(&self, other: &Self) -> bool {
        let resolved = |w: &World| -> Vec<(Device, Option<u8>)> {
            w.devices
                .iter()
                .map(|d| {
                    let address = w.board_of(d).map(|b| b.address);
                    let mut d = d.clone();
                    if let Some(a) = address {
                        d.board = BoardRef::Address(a);
                    }
                    (d, address)
                })
                .collect()
        };
        self.boards() == other.boards()
            && resolved(self) == resolved(other)
            && self.physics == other.physics
            && self.images == other.images
    }
}

impl World {
    /// An empty world: the internal board with 2 sensor and 2 actuator ports, no devices.
    pub fn new() -> World {
        World::default()
    }

    /// Adds a board (an internal one replaces the default).
    pub fn board(mut self, board: Board) -> World {
        self.push_board(board);
        self
    }

    /// Adds a board; one without an address gets the next key of its own.
    fn push_board(&mut self, mut board: Board) {
        if board.unaddressed {
            let k = self.boards.iter().filter(|b| b.unaddressed).count();
            board.address = board::UNADDRESSED_KEY.saturating_add(u8::try_from(k).unwrap_or(0x7f));
        }
        self.boards.push(board);
    }

    /// Adds an image the motherboard carries.
    pub fn carries(mut self, image: CarriedImage) -> World {
        self.images.push(image);
        self
    }

    /// The images the motherboard carries.
    pub fn images(&self) -> &[CarriedImage] {
        &self.images
    }

    /// Adds a device.
    pub fn device(mut self, device: Device) -> World {
        self.devices.push(device);
        self
    }

    /// Reads a world file's text.
    ///
    /// # Errors
    /// [`WorldError`] with the line: TOML syntax, wrong types and unknown fields
    /// ([`WorldErrorKind::Syntax`]), then everything [`World::check`] finds.
    pub fn from_toml(text: &str) -> Result<World, WorldError> {
        let world = file::parse(text)?;
        world.check()?;
        Ok(world)
    }

    /// Reads a world file.
    ///
    /// # Errors
    /// [`WorldErrorKind::Io`] when it cannot be read; otherwise as [`World::from_toml`], the
    /// message prefixed by the path.
    pub fn load(path: impl AsRef<Path>) -> Result<World, WorldError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| {
            WorldError::new(WorldErrorKind::Io {
                path: path.display().to_string(),
                message: e.to_string(),
            })
        })?;
        World::from_toml(&text)
    }

    /// The boards, the internal one first (the default one when none was declared), then the
    /// others in the order given.
    pub fn boards(&self) -> Vec<Board> {
        let mut v = Vec::new();
        match self.boards.iter().find(|b| b.is_internal()) {
            Some(b) => v.push(b.clone()),
            None => v.push(Board::internal(2, 2)),
        }
        v.extend(self.boards.iter().filter(|b| !b.is_internal()).cloned());
        v
    }

    /// The devices in the order given.
    pub fn devices(&self) -> &[Device] {
        &self.devices
    }

    /// The device called `name`.
    pub fn device_named(&self, name: &str) -> Option<&Device> {
        self.devices.iter().find(|d| d.name == name)
    }

    /// The board `r` names.
    pub fn find_board(&self, r: &BoardRef) -> Option<Board> {
        self.boards().into_iter().find(|b| b.answers_to(r))
    }

    /// The board a device is on.
    pub fn board_of(&self, device: &Device) -> Option<Board> {
        self.find_board(&device.board)
    }

    fn at(&self, item: Item, field: &'static str, kind: WorldErrorKind) -> WorldError {
        let line = self
            .lines
            .get(&(item, field))
            .or_else(|| self.lines.get(&(item, "")))
            .copied();
        WorldError { line, kind }
    }

    /// Checks the world: boards (addresses, names, port counts), devices (names, boards,
    /// ports, pins, scripts).
    ///
    /// # Errors
    /// The first [`WorldError`] found, in file order.
    pub fn check(&self) -> Result<(), WorldError> {
        self.check_boards()?;
        self.check_devices()?;
        self.check_physics()
    }

    fn check_boards(&self) -> Result<(), WorldError> {
        let mut addresses: Vec<u8> = Vec::new();
        let mut names: Vec<String> = Vec::new();
        for (i, b) in self.boards.iter().enumerate() {
            let item = Item::Board(i);
            if b.unaddressed && b.alias.as_deref().is_none_or(str::is_empty) {
                return Err(self.at(
                    item,
                    "name",
                    bad(
                        "a board without an address".to_string(),
                        "name",
                        "is needed: devices and the trace name the board by it",
                    ),
                ));
            }
            if !b.unaddressed && b.address != 0 && Address::assignable(b.address).is_err() {
                return Err(self.at(
                    item,
                    "address",
                    WorldErrorKind::BadAddress {
                        address: i64::from(b.address),
                    },
                ));
            }
            if !b.unaddressed && addresses.contains(&b.address) {
                return Err(self.at(
                    item,
                    "address",
                    WorldErrorKind::DuplicateAddress { address: b.address },
                ));
            }
            addresses.push(b.address);
            let (s, a) = b.ports();
            if s > Port::MAX_PORTS || a > Port::MAX_PORTS {
                return Err(self.at(
                    item,
                    "sensor_ports",
                    WorldErrorKind::BoardPorts {
                        board: b.log_name(),
                        reason: format!(
                            "{s} sensor and {a} actuator ports: at most {} of each",
                            Port::MAX_PORTS
                        ),
                    },
                ));
            }
            if let Some(bits) = b.adc_bits.filter(|b| !(1..=16).contains(b)) {
                return Err(self.at(
                    item,
                    "adc_bits",
                    bad(b.log_name(), "adc_bits", format!("is {bits}: 1 to 16 bits")),
                ));
            }
            let mut own = vec![b.log_name()];
            if b.is_internal() {
                own.push("SELF".to_string());
            }
            if let Some(alias) = &b.alias {
                if alias.is_empty() {
                    return Err(self.at(item, "name", bad(b.log_name(), "name", "is empty")));
                }
                if !own.contains(alias) {
                    own.push(alias.clone());
                }
            }
            for n in own {
                if names.contains(&n) {
                    let field = if b.alias.as_ref() == Some(&n) {
                        "name"
                    } else {
                        "address"
                    };
                    return Err(self.at(
                        item,
                        field,
                        WorldErrorKind::DuplicateBoardName { name: n },
                    ));
                }
                names.push(n);
            }
        }
        Ok(())
    }

    fn check_devices(&self) -> Result<(), WorldError> {
        // (board address, port, use) → device name
        let mut taken: Vec<(u8, Port, Use, String)> = Vec::new();
        for (i, d) in self.devices.iter().enumerate() {
            let item = Item::Device(i);
            let at = |field, kind| self.at(item, field, kind);
            if d.name.is_empty() {
                return Err(at("name", bad("a device".to_string(), "name", "is empty")));
            }
            if self.devices[..i].iter().any(|o| o.name == d.name) {
                return Err(at(
                    "name",
                    WorldErrorKind::DuplicateDeviceName {
                        name: d.name.clone(),
                    },
                ));
            }
            if let Some(setting) = d.misuse.first() {
                return Err(at(
                    "",
                    WorldErrorKind::NotApplicable {
                        device: d.name.clone(),
                        field: setting.clone(),
                        kind: d.kind.name(),
                    },
                ));
            }
            let Some(board) = self.board_of(d) else {
                return Err(at(
                    "board",
                    WorldErrorKind::UnknownBoard {
                        device: d.name.clone(),
                        board: d.board.to_string(),
                    },
                ));
            };
            let (sensors, actuators) = board.ports();
            let available = match d.kind.port_kind() {
                PortKind::Sensor => sensors,
                PortKind::Actuator => actuators,
            };
            let Some(port) = d.port().filter(|_| d.port <= available) else {
                return Err(at(
                    "port",
                    WorldErrorKind::PortOutOfRange {
                        device: d.name.clone(),
                        port: d.port_label(),
                        board: board.log_name(),
                        available,
                    },
                ));
            };
            self.check_scripts(i, d, &board)?;
            for u in d.kind.uses() {
                if let Some((_, _, _, by)) = taken
                    .iter()
                    .find(|(a, p, used, _)| *a == board.address && *p == port && *used == u)
                {
                    let what = match u {
                        Use::Digital(p) => format!("{}.{}", d.port_label(), pin_letter(p)),
                        Use::Pwm(p) => format!("{} PWM {}", d.port_label(), pin_letter(p)),
                        Use::Analog => format!("{} analog input", d.port_label()),
                    };
                    return Err(at(
                        "port",
                        WorldErrorKind::PinTaken {
                            device: d.name.clone(),
                            pin: format!("{} {what}", board.log_name()),
                            by: by.clone(),
                        },
                    ));
                }
            }
            // A servo sets the port's PWM frequency: no other PWM user on that port but servos.
            let is_servo = matches!(d.kind, DeviceKind::Servo { .. });
            let uses_pwm = d.kind.uses().iter().any(|u| matches!(u, Use::Pwm(_)));
            if uses_pwm {
                for (a, p, u, by) in &taken {
                    if *a != board.address || *p != port || !matches!(u, Use::Pwm(_)) {
                        continue;
                    }
                    let other_is_servo = self
                        .device_named(by)
                        .is_some_and(|o| matches!(o.kind, DeviceKind::Servo { .. }));
                    if is_servo != other_is_servo {
                        let (servo, other) = if is_servo {
                            (d.name.clone(), by.clone())
                        } else {
                            (by.clone(), d.name.clone())
                        };
                        return Err(at(
                            "port",
                            WorldErrorKind::SharedPwmFrequency {
                                device: servo,
                                other,
                            },
                        ));
                    }
                }
            }
            for u in d.kind.uses() {
                taken.push((board.address, port, u, d.name.clone()));
            }
        }
        Ok(())
    }

    fn check_scripts(&self, i: usize, d: &Device, board: &Board) -> Result<(), WorldError> {
        let item = Item::Device(i);
        let who = format!("device `{}`", d.name);
        let err = |field: &'static str, reason: String| {
            Err(self.at(item, field, bad(who.clone(), field, reason)))
        };
        let check_signal = |field: &'static str, s: &Signal, min: f64, max: f64, whole: bool| {
            let pts = s.points();
            if matches!(s, Signal::Steps(_) | Signal::Linear(_)) && pts.is_empty() {
                return err(field, "has no points".to_string());
            }
            if pts.windows(2).any(|w| w[1].0 < w[0].0) {
                return err(field, "has times that go backwards".to_string());
            }
            let values: Vec<f64> = match s {
                Signal::Const(v) => vec![*v],
                _ => pts.iter().map(|p| p.1).collect(),
            };
            for v in values {
                if !v.is_finite() || v < min || v > max {
                    return err(field, format!("has {v}, outside {min} to {max}"));
                }
                if whole && v.fract() != 0.0 {
                    return err(field, format!("has {v}: ADC counts are whole numbers"));
                }
            }
            Ok(())
        };
        let check_digital = |field: &'static str, s: &DigitalSignal, active_low: bool| match s {
            DigitalSignal::Const(_) => Ok(()),
            DigitalSignal::Toggles { at_ms, .. } => {
                if at_ms.windows(2).any(|w| w[1] <= w[0]) {
                    err(field, "needs strictly increasing times".to_string())
                } else {
                    Ok(())
                }
            }
            DigitalSignal::Presses(p) => {
                if p.iter().any(|(_, d)| *d == 0) {
                    return err(field, "has a press of 0 ms".to_string());
                }
                if p.windows(2)
                    .any(|w| w[1].0 <= w[0].0.saturating_add(w[0].1))
                {
                    return err(
                        field,
                        "has presses out of time order, overlapping or touching".to_string(),
                    );
                }
                Ok(())
            }
            DigitalSignal::Pulses {
                period_us,
                width_us,
                ..
            } => {
                if active_low {
                    err(
                        field,
                        "cannot be a pulse train on an active-low input".to_string(),
                    )
                } else if *width_us == 0 || *width_us >= *period_us {
                    err(field, "needs 0 < width < period".to_string())
                } else {
                    Ok(())
                }
            }
        };
        let adc_max = f64::from(board.adc_max());
        match &d.kind {
            DeviceKind::LightSensor { counts }
            | DeviceKind::ForceSensor { counts }
            | DeviceKind::AnalogInput { counts } => {
                check_signal("counts", counts, 0.0, adc_max, true)
            }
            DeviceKind::Thermistor { config, celsius } => {
                if config.adc_bits() != board.adc_resolution() {
                    return err(
                        "adc_bits",
                        format!(
                            "is {} but board {} has a {}-bit ADC",
                            config.adc_bits(),
                            board.log_name(),
                            board.adc_resolution()
                        ),
                    );
                }
                check_signal("celsius", celsius, -273.15, 1_000.0, false)
            }
            DeviceKind::Ultrasonic {
                ranger,
                distance_mm,
            } => {
                if ranger.speed_of_sound_m_s == 0 {
                    return err("speed_of_sound", "is 0".to_string());
                }
                check_signal("distance_mm", distance_mm, 0.0, 100_000.0, false)
            }
            DeviceKind::Button {
                pressed: s,
                active_low,
                ..
            } => check_digital("presses", s, *active_low),
            DeviceKind::Switch {
                on: s, active_low, ..
            } => check_digital("level", s, *active_low),
            DeviceKind::DigitalInput { level, .. } => check_digital("level", level, false),
            _ => Ok(()),
        }
    }

    /// What sensor port `port` of `board` sees: the scripts of every device on it (pins and
    /// analog input nobody uses stay low and 0). `None` when the world has no such board or
    /// port.
    pub fn sensor_script(&self, board: impl Into<BoardRef>, port: u8) -> Option<SensorScript> {
        let board = self.find_board(&board.into())?;
        if port == 0 || port > board.kind.sensor_ports() {
            return None;
        }
        let mut script = SensorScript::default();
        for d in self
            .devices
            .iter()
            .filter(|d| d.port == port && board.answers_to(&d.board))
        {
            let pin_of = |script: &mut SensorScript, pin: Pin, s: Digital| match pin {
                Pin::A => script.a = s,
                Pin::B => script.b = s,
            };
            match &d.kind {
                DeviceKind::Button {
                    pin,
                    active_low,
                    pressed: s,
                }
                | DeviceKind::Switch {
                    pin,
                    active_low,
                    on: s,
                } => pin_of(&mut script, *pin, s.to_digital(*active_low)),
                DeviceKind::DigitalInput { pin, level } => {
                    pin_of(&mut script, *pin, level.to_digital(false));
                }
                DeviceKind::LightSensor { counts }
                | DeviceKind::ForceSensor { counts }
                | DeviceKind::AnalogInput { counts } => {
                    script.analog = match counts {
                        Signal::Const(_) => Analog::Const(counts.counts_at_us(0)),
                        _ => {
                            let c = counts.clone();
                            Analog::Func(Rc::new(move |t_us| c.counts_at_us(t_us)))
                        }
                    };
                }
                DeviceKind::Thermistor { config, celsius } => {
                    let config = *config;
                    script.analog = match celsius {
                        Signal::Const(c) => Analog::Const(thermistor_raw(&config, *c as f32)),
                        _ => {
                            let c = celsius.clone();
                            Analog::Func(Rc::new(move |t_us| {
                                thermistor_raw(&config, c.value_at_us_f32(t_us))
                            }))
                        }
                    };
                }
                DeviceKind::Ultrasonic {
                    ranger,
                    distance_mm,
                } => {
                    let speed = ranger.speed_of_sound_m_s;
                    let c = distance_mm.clone();
                    let echo = Digital::Echo {
                        trigger: ranger.trigger.filter(|t| *t != ranger.echo),
                        delay_us: u64::from(ranger.echo_delay_us),
                        min_interval_us: u64::from(ranger.min_interval_ms) * 1_000,
                        width_us: Analog::Func(Rc::new(move |t_us| {
                            echo_width_us(c.value_at_us(t_us), speed)
                        })),
                    };
                    pin_of(&mut script, ranger.echo, echo);
                }
                DeviceKind::DcMotor
                | DeviceKind::Led { .. }
                | DeviceKind::DigitalOutput { .. }
                | DeviceKind::PwmOutput { .. }
                | DeviceKind::Servo { .. } => {}
            }
        }
        Some(script)
    }

    fn ports_for(
        &self,
        sim: &Sim,
        board: &Board,
        engine: Option<&Rc<std::cell::RefCell<crate::physics::Engine>>>,
    ) -> SimPorts {
        let (s, a) = board.ports();
        let mut ports = sim
            .ports(&board_name_of(board), s, a)
            .with_adc_bits(board.adc_resolution());
        for n in 1..=s {
            if let Some(mut script) = self.sensor_script(board.self_ref(), n) {
                if let Some(e) = engine {
                    self.model_scripts(e, board, n, &mut script);
                }
                ports = ports.with_sensor(n, script);
            }
        }
        ports
    }

    /// A simulation of this world: the internal board's ports and every other board with its
    /// ports and scripts. No robot program: add it, or test tasks, to the returned [`Sim`].
    ///
    /// # Errors
    /// As [`World::check`]; [`WorldErrorKind::MotherboardAddress`] for a board at
    /// `config.mb_address`.
    pub fn sim(&self, config: SimConfig) -> Result<Sim, WorldError> {
        self.check()?;
        let mb = config.mb_address.get();
        if let Some(i) = self
            .boards
            .iter()
            .position(|b| !b.unaddressed && b.address == mb)
        {
            return Err(self.at(
                Item::Board(i),
                "address",
                WorldErrorKind::MotherboardAddress { address: mb },
            ));
        }
        let sim = Sim::new(config);
        let engine = self.physics_spec().map(|spec| {
            crate::physics::Engine::new(spec, sim.log().clone(), Some(sim.clock().clone()))
                .into_shared()
        });
        let engine = engine.as_ref();
        let boards = self.boards();
        let mut sim = match boards.iter().find(|b| b.is_internal()) {
            Some(b) => {
                let ports = self.ports_for(&sim, b, engine);
                sim.with_internal_ports(ports)
            }
            None => sim,
        };
        for b in boards.iter().filter(|b| !b.is_internal()) {
            if b.unaddressed {
                let ports = self.ports_for(&sim, b, engine);
                sim = sim.with_unaddressed_board(&b.log_name(), b.uid, ports);
                continue;
            }
            let address = Address::external(b.address).map_err(|_| {
                WorldError::new(WorldErrorKind::BadAddress {
                    address: i64::from(b.address),
                })
            })?;
            let ports = self.ports_for(&sim, b, engine);
            sim = sim.with_board(address, ports);
        }
        // Boards whose firmware version the world gives run it (a flash of A/B slots holding
        // a fake image of that version: `crate::firmware`).
        for b in boards
            .iter()
            .filter(|b| !b.is_internal() && b.has_firmware())
        {
            let fw = crate::firmware::SimFirmware::new(b.firmware_version());
            sim = sim.with_firmware(&b.log_name(), fw);
        }
        Ok(sim)
    }
}

/// The simulator's name of a board (`mb`, `db09`): the one its log and trace use.
fn board_name_of(board: &Board) -> String {
    if board.unaddressed {
        return board.log_name();
    }
    match Address::external(board.address) {
        Ok(a) => board_name(a),
        Err(_) => INTERNAL_NAME.to_string(),
    }
}

/// `docs/world.md`: its Rust examples run as doctests (its TOML examples are read by
/// `tests/world.rs`).
#[cfg(doctest)]
#[doc = include_str!("../../docs/world.md")]
pub struct WorldGuide;

#[cfg(test)]
mod tests;
