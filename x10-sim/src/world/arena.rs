//! The world's physical models ([`crate::physics`]): the builder, the world file's
//! `[physics]`, `[chassis]`, `[arena]`, `[[sensor]]` and `[[thermal]]` tables, their checks,
//! and the sensor scripts that read the models.

use std::cell::RefCell;
use std::rc::Rc;

use serde::Deserialize;
use toml::Spanned;
use x10_microcode::{Pin, Port};

use super::error::bad;
use super::{
    board_name_of, thermistor_raw, Board, Device, DeviceKind, DigitalSignal, Item, Signal, World,
    WorldError,
};
use crate::physics::{
    Arena, Chassis, Engine, FloorLine, InputPin, Lamp, ModelPin, ModelSensor, Obstacle, Physics,
    PinModel, Pose, RangerWiring, ServoSlew, Source, Spec, Thermal, Wall, Wheel,
};
use crate::ports::{Analog, Digital, SensorScript};

impl World {
    /// Sets the chassis ([`Chassis`]).
    pub fn chassis(mut self, chassis: Chassis) -> World {
        self.physics.chassis = Some(chassis);
        self
    }

    /// Sets the arena ([`Arena`]).
    pub fn arena(mut self, arena: Arena) -> World {
        self.physics.arena = arena;
        self
    }

    /// Device `device` takes its value from a model ([`Source`]) instead of a script.
    pub fn model(mut self, device: impl Into<String>, source: Source) -> World {
        self.physics.sensors.push(ModelSensor {
            device: device.into(),
            source,
        });
        self
    }

    /// Adds a thermal body ([`Thermal`]).
    pub fn thermal(mut self, body: Thermal) -> World {
        self.physics.thermals.push(body);
        self
    }

    /// Servo `device` travels at `deg_per_s` towards each commanded angle
    /// ([`crate::physics::ServoSlew`]).
    pub fn servo_slew(mut self, device: impl Into<String>, deg_per_s: f64) -> World {
        self.physics.servos.push(ServoSlew {
            device: device.into(),
            deg_per_s,
        });
        self
    }

    /// Sets the models' integration step, µs (1 000 by default).
    pub fn physics_step_us(mut self, step_us: u64) -> World {
        self.physics.step_us = step_us;
        self
    }

    /// The physical models.
    pub fn physics(&self) -> &Physics {
        &self.physics
    }

    /// Checks the models: the chassis's motors, the sensors' devices and sources, the thermal
    /// bodies' heaters and doors, every number.
    pub(super) fn check_physics(&self) -> Result<(), WorldError> {
        let p = &self.physics;
        let err = |item: Item, who: &str, field: &'static str, reason: String| {
            Err(self.at(item, field, bad(who.to_string(), field, reason)))
        };
        if p.step_us == 0 || p.step_us > 1_000_000 {
            return err(
                Item::Physics,
                "physics",
                "step_ms",
                format!("is {} µs: 1 µs to 1 s", p.step_us),
            );
        }
        if let Some(c) = &p.chassis {
            let item = Item::Chassis;
            for (field, name) in [("left", &c.left), ("right", &c.right)] {
                match self.device_named(name) {
                    None => return err(item, "chassis", field, format!("names `{name}`, which is not a device")),
                    Some(d) if !matches!(d.kind, DeviceKind::DcMotor) => {
                        return err(
                            item,
                            "chassis",
                            field,
                            format!("names `{name}`, a {}: the chassis's wheels are dc_motor devices (H-bridges)", d.kind.name()),
                        )
                    }
                    Some(_) => {}
                }
            }
            if c.left == c.right {
                return err(
                    item,
                    "chassis",
                    "right",
                    "is the left motor too".to_string(),
                );
            }
            for (field, v, min) in [
                ("wheel_base_mm", c.wheel_base_mm, 1.0),
                ("wheel_radius_mm", c.wheel_radius_mm, 1.0),
                ("radius_mm", c.radius_mm, 1.0),
                ("top_speed_rpm", c.top_speed_rpm, 0.0),
                ("time_constant_ms", c.time_constant_ms, 0.0),
                ("dead_band_percent", c.dead_band_percent, 0.0),
            ] {
                if !v.is_finite() || v < min || v > 1e6 {
                    return err(item, "chassis", field, format!("is {v}: from {min} up"));
                }
            }
            if c.encoder_edges_per_rev == 0 {
                return err(
                    item,
                    "chassis",
                    "encoder_edges_per_rev",
                    "is 0: at least 1".to_string(),
                );
            }
            if c.dead_band_percent >= 100.0 {
                return err(
                    item,
                    "chassis",
                    "dead_band_percent",
                    format!("is {}: under 100", c.dead_band_percent),
                );
            }
            let s = c.start;
            if ![s.x_mm, s.y_mm, s.heading_deg]
                .iter()
                .all(|v| v.is_finite())
            {
                return err(item, "chassis", "start", "is not a finite pose".to_string());
            }
            let segs = arena_segments(&p.arena);
            if let Some((d, _, o)) = crate::physics::geom::nearest((s.x_mm, s.y_mm), &segs) {
                if d < c.radius_mm {
                    return err(
                        item,
                        "chassis",
                        "start",
                        format!(
                            "puts the outline into {} ({d:.0} mm from its centre, radius {} mm)",
                            p.arena.obstacle_name(o),
                            c.radius_mm
                        ),
                    );
                }
            }
        }
        let a = &p.arena;
        let finite = |pts: &[(f64, f64)]| pts.iter().all(|(x, y)| x.is_finite() && y.is_finite());
        if !finite(
            &a.walls
                .iter()
                .flat_map(|w| [w.from, w.to])
                .collect::<Vec<_>>(),
        ) || !finite(
            &a.boxes
                .iter()
                .flat_map(|b| [b.min, b.max])
                .collect::<Vec<_>>(),
        ) {
            return err(
                Item::Arena,
                "arena",
                "walls",
                "has a coordinate that is not a number".to_string(),
            );
        }
        if a.boxes
            .iter()
            .any(|b| b.min.0 >= b.max.0 || b.min.1 >= b.max.1)
        {
            return err(
                Item::Arena,
                "arena",
                "boxes",
                "has a box whose first corner is not below and left of its second".to_string(),
            );
        }
        let unit = |v: f64| (0.0..=1.0).contains(&v);
        if !unit(a.floor_reflectance) {
            return err(
                Item::Arena,
                "arena",
                "floor_reflectance",
                format!("is {}: 0 to 1", a.floor_reflectance),
            );
        }
        for l in &a.lines {
            let good = !l.points.is_empty()
                && finite(&l.points)
                && l.width_mm > 0.0
                && l.width_mm.is_finite()
                && unit(l.reflectance);
            if !good {
                return err(
                    Item::Arena,
                    "arena",
                    "lines",
                    "needs points, a width above 0 mm and a reflectance from 0 to 1".to_string(),
                );
            }
        }
        if let Some(l) = a.lamp {
            let good = finite(&[l.at])
                && (0.0..1e9).contains(&l.counts_at_1m)
                && (0.0..1e9).contains(&l.ambient_counts);
            if !good {
                return err(
                    Item::Arena,
                    "arena",
                    "lamp",
                    "needs a position and counts of 0 or more".to_string(),
                );
            }
        }
        for (i, t) in p.thermals.iter().enumerate() {
            let item = Item::Thermal(i);
            let who = format!("thermal `{}`", t.name);
            if t.name.is_empty() {
                return err(item, "a thermal body", "name", "is empty".to_string());
            }
            if p.thermals[..i].iter().any(|o| o.name == t.name) {
                return err(
                    item,
                    &who,
                    "name",
                    "is taken by another thermal body".to_string(),
                );
            }
            for (field, v) in [
                ("start_c", t.start_c),
                ("idle_c", t.idle_c),
                ("ambient_c", t.ambient_c),
                ("heater_c", t.heater_c),
            ] {
                if !v.is_finite() || !(-273.15..=1_000.0).contains(&v) {
                    return err(item, &who, field, format!("is {v}: −273.15 to 1000 °C"));
                }
            }
            if !t.time_constant_s.is_finite() || t.time_constant_s < 0.0 {
                return err(
                    item,
                    &who,
                    "time_constant_s",
                    format!("is {}: 0 or more", t.time_constant_s),
                );
            }
            if let Some(h) = &t.heater {
                match self.device_named(h).map(|d| &d.kind) {
                    Some(
                        DeviceKind::DigitalOutput { .. }
                        | DeviceKind::Led { .. }
                        | DeviceKind::PwmOutput { .. },
                    ) => {}
                    Some(k) => {
                        return err(
                            item,
                            &who,
                            "heater",
                            format!(
                            "names `{h}`, a {}: a heater is a digital_output, led or pwm_output",
                            k.name()
                        ),
                        )
                    }
                    None => {
                        return err(
                            item,
                            &who,
                            "heater",
                            format!("names `{h}`, which is not a device"),
                        )
                    }
                }
            }
            if let Some(h) = &t.door {
                match self.device_named(h).map(|d| &d.kind) {
                    Some(
                        DeviceKind::Switch { .. }
                        | DeviceKind::Button { .. }
                        | DeviceKind::DigitalInput { .. },
                    ) => {}
                    Some(k) => {
                        return err(
                            item,
                            &who,
                            "door",
                            format!(
                                "names `{h}`, a {}: a door is a switch, button or digital_input",
                                k.name()
                            ),
                        )
                    }
                    None => {
                        return err(
                            item,
                            &who,
                            "door",
                            format!("names `{h}`, which is not a device"),
                        )
                    }
                }
            }
        }
        for (i, s) in p.servos.iter().enumerate() {
            let item = Item::Servo(i);
            let who = format!("servo `{}`", s.device);
            match self.device_named(&s.device).map(|d| &d.kind) {
                Some(DeviceKind::Servo { .. }) => {}
                Some(k) => {
                    return err(
                        item,
                        &who,
                        "device",
                        format!("names `{}`, a {}: not a servo", s.device, k.name()),
                    )
                }
                None => {
                    return err(
                        item,
                        &who,
                        "device",
                        format!("names `{}`, which is not a device", s.device),
                    )
                }
            }
            if p.servos[..i].iter().any(|o| o.device == s.device) {
                return err(item, &who, "device", "already has a speed".to_string());
            }
            if !(s.deg_per_s > 0.0 && s.deg_per_s.is_finite()) {
                return err(
                    item,
                    &who,
                    "speed_deg_s",
                    format!("is {}: above 0", s.deg_per_s),
                );
            }
        }
        for (i, s) in p.sensors.iter().enumerate() {
            let item = Item::Sensor(i);
            let who = format!("sensor `{}`", s.device);
            let Some(d) = self.device_named(&s.device) else {
                return err(
                    item,
                    &who,
                    "device",
                    format!("names `{}`, which is not a device", s.device),
                );
            };
            if p.sensors[..i].iter().any(|o| o.device == s.device) {
                return err(
                    item,
                    &who,
                    "device",
                    "already takes its value from a model".to_string(),
                );
            }
            let fits = matches!(
                (&s.source, &d.kind),
                (Source::Ranger { .. }, DeviceKind::Ultrasonic { .. })
                    | (
                        Source::Bumper { .. } | Source::Encoder(_),
                        DeviceKind::Button { .. }
                            | DeviceKind::Switch { .. }
                            | DeviceKind::DigitalInput { .. },
                    )
                    | (
                        Source::Line { .. } | Source::Light { .. },
                        DeviceKind::LightSensor { .. } | DeviceKind::AnalogInput { .. },
                    )
                    | (Source::Thermal { .. }, DeviceKind::Thermistor { .. })
            );
            if !fits {
                return err(
                    item,
                    &who,
                    "source",
                    format!("`{}` does not fit a {}", s.source.name(), d.kind.name()),
                );
            }
            if has_script(&d.kind) {
                return err(
                    item,
                    &who,
                    "source",
                    format!(
                        "`{}` is a model, but `{}` also has a script: keep one",
                        s.source.name(),
                        s.device
                    ),
                );
            }
            let needs_chassis = !matches!(s.source, Source::Thermal { .. });
            if needs_chassis && p.chassis.is_none() {
                return err(
                    item,
                    &who,
                    "source",
                    format!(
                        "`{}` reads the chassis, but the world has no [chassis]",
                        s.source.name()
                    ),
                );
            }
            match &s.source {
                Source::Thermal { body } if !p.thermals.iter().any(|t| &t.name == body) => {
                    return err(
                        item,
                        &who,
                        "body",
                        format!("names `{body}`, which is not a thermal body"),
                    );
                }
                Source::Ranger {
                    at,
                    angle_deg,
                    beam_deg,
                    range_mm,
                } if !(finite(&[*at])
                    && angle_deg.is_finite()
                    && (0.0..=180.0).contains(beam_deg)
                    && *range_mm > 0.0
                    && range_mm.is_finite()) =>
                {
                    return err(
                        item,
                        &who,
                        "range_mm",
                        "needs a finite mount, a beam of 0 to 180° and a range above 0 mm"
                            .to_string(),
                    );
                }
                Source::Bumper { arc_deg } if !(0.0..=360.0).contains(arc_deg) => {
                    return err(item, &who, "arc_deg", format!("is {arc_deg}: 0 to 360°"));
                }
                Source::Line { at } | Source::Light { at } if !finite(&[*at]) => {
                    return err(item, &who, "at", "is not a finite point".to_string());
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The models with their devices resolved to pins; `None` when the world has none.
    pub(crate) fn physics_spec(&self) -> Option<Spec> {
        if self.physics.is_empty() {
            return None;
        }
        let mut inputs: Vec<InputPin> = Vec::new();
        let mut input = |board: String, port: Port, pin: Pin, duty: bool| {
            let i = InputPin {
                board,
                pin: port.pin(pin),
                duty,
            };
            match inputs.iter().position(|x| *x == i) {
                Some(n) => n,
                None => {
                    inputs.push(i);
                    inputs.len() - 1
                }
            }
        };
        let place = |name: &str| -> Option<(String, Port, &Device)> {
            let d = self.device_named(name)?;
            let b = self.board_of(d)?;
            Some((board_name_of(&b), d.port()?, d))
        };
        let motors = self.physics.chassis.as_ref().and_then(|c| {
            let mut pins = [[0usize; 3]; 2];
            for (w, name) in [&c.left, &c.right].into_iter().enumerate() {
                let (b, port, _) = place(name)?;
                let p = pins.get_mut(w)?;
                *p = [
                    input(b.clone(), port, Pin::A, false),
                    input(b.clone(), port, Pin::B, false),
                    input(b, port, Pin::A, true),
                ];
            }
            Some(pins)
        });
        let heaters = self
            .physics
            .thermals
            .iter()
            .map(|t| {
                let (b, port, d) = place(t.heater.as_deref()?)?;
                match d.kind {
                    DeviceKind::Led { pin, dimmable } => Some(input(b, port, pin, dimmable)),
                    DeviceKind::DigitalOutput { pin } => Some(input(b, port, pin, false)),
                    DeviceKind::PwmOutput { pin } => Some(input(b, port, pin, true)),
                    _ => None,
                }
            })
            .collect();
        let doors = self
            .physics
            .thermals
            .iter()
            .map(|t| match &self.device_named(t.door.as_deref()?)?.kind {
                DeviceKind::Switch { on: s, .. }
                | DeviceKind::Button { pressed: s, .. }
                | DeviceKind::DigitalInput { level: s, .. } => Some(s.clone()),
                _ => None,
            })
            .collect();
        let rangers = self
            .physics
            .sensors
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let (board, port, d) = place(&s.device)?;
                match (&s.source, &d.kind) {
                    (Source::Ranger { .. }, DeviceKind::Ultrasonic { ranger, .. }) => {
                        Some(RangerWiring {
                            sensor: i,
                            board,
                            trigger: ranger.trigger.map(|t| port.pin(t)),
                            delay_us: u64::from(ranger.echo_delay_us),
                        })
                    }
                    _ => None,
                }
            })
            .collect();
        Some(Spec {
            physics: self.physics.clone(),
            inputs,
            motors,
            heaters,
            doors,
            rangers,
        })
    }

    /// Replaces, in `script` (sensor port `port` of `board`), what the devices that take their
    /// value from a model see.
    pub(super) fn model_scripts(
        &self,
        engine: &Rc<RefCell<Engine>>,
        board: &Board,
        port: u8,
        script: &mut SensorScript,
    ) {
        for (i, s) in self.physics.sensors.iter().enumerate() {
            let Some(d) = self.device_named(&s.device) else {
                continue;
            };
            if d.port != port
                || !board.answers_to(&d.board)
                || !matches!(d.kind.port_kind(), x10_microcode::PortKind::Sensor)
            {
                continue;
            }
            let set = |script: &mut SensorScript, pin: Pin, v: Digital| match pin {
                Pin::A => script.a = v,
                Pin::B => script.b = v,
            };
            let e = engine.clone();
            match (&s.source, &d.kind) {
                (Source::Ranger { .. }, DeviceKind::Ultrasonic { ranger, .. }) => {
                    let (delay, speed) =
                        (u64::from(ranger.echo_delay_us), ranger.speed_of_sound_m_s);
                    let echo = Digital::Echo {
                        trigger: ranger.trigger.filter(|t| *t != ranger.echo),
                        delay_us: delay,
                        min_interval_us: u64::from(ranger.min_interval_ms) * 1_000,
                        width_us: Analog::Func(Rc::new(move |t_us| {
                            e.borrow_mut().echo_us(i, t_us, delay, speed)
                        })),
                    };
                    set(script, ranger.echo, echo);
                }
                (
                    Source::Bumper { .. } | Source::Encoder(_),
                    DeviceKind::Button {
                        pin, active_low, ..
                    }
                    | DeviceKind::Switch {
                        pin, active_low, ..
                    },
                ) => {
                    set(
                        script,
                        *pin,
                        Digital::Model(ModelPin::new(e, pin_model(&s.source), *active_low)),
                    );
                }
                (
                    Source::Bumper { .. } | Source::Encoder(_),
                    DeviceKind::DigitalInput { pin, .. },
                ) => {
                    set(
                        script,
                        *pin,
                        Digital::Model(ModelPin::new(e, pin_model(&s.source), false)),
                    );
                }
                (Source::Line { .. } | Source::Light { .. }, _) => {
                    let max = board.adc_max();
                    script.analog = Analog::Func(Rc::new(move |t_us| {
                        e.borrow_mut().counts(i, t_us.saturating_mul(1_000), max)
                    }));
                }
                (Source::Thermal { body }, DeviceKind::Thermistor { config, .. }) => {
                    let config = *config;
                    let b = self
                        .physics
                        .thermals
                        .iter()
                        .position(|t| &t.name == body)
                        .unwrap_or(usize::MAX);
                    script.analog = Analog::Func(Rc::new(move |t_us| {
                        let c = e.borrow_mut().celsius(b, t_us.saturating_mul(1_000));
                        thermistor_raw(&config, c as f32)
                    }));
                }
                _ => {}
            }
        }
    }
}

fn pin_model(s: &Source) -> PinModel {
    match s {
        Source::Encoder(w) => PinModel::Encoder(*w),
        _ => PinModel::Bumper,
    }
}

fn arena_segments(a: &Arena) -> Vec<crate::physics::geom::Seg> {
    let walls: Vec<_> = a.walls.iter().map(|w| (w.from, w.to)).collect();
    let boxes: Vec<_> = a.boxes.iter().map(|b| (b.min, b.max)).collect();
    crate::physics::geom::segments(&walls, &boxes)
}

/// Whether an input device has a script of its own (not the default "nothing happens").
fn has_script(k: &DeviceKind) -> bool {
    match k {
        DeviceKind::Button { pressed: s, .. }
        | DeviceKind::Switch { on: s, .. }
        | DeviceKind::DigitalInput { level: s, .. } => *s != DigitalSignal::Const(false),
        DeviceKind::LightSensor { counts }
        | DeviceKind::ForceSensor { counts }
        | DeviceKind::AnalogInput { counts } => *counts != Signal::Const(0.0),
        DeviceKind::Thermistor { celsius, .. } => *celsius != Signal::Const(20.0),
        DeviceKind::Ultrasonic { distance_mm, .. } => *distance_mm != Signal::Const(1_000.0),
        _ => false,
    }
}

// ---- The world file's tables ----

/// `[physics]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPhysics {
    step_ms: f64,
}

/// `[chassis]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawChassis {
    left: Spanned<String>,
    right: Spanned<String>,
    wheel_base_mm: Option<Spanned<f64>>,
    wheel_radius_mm: Option<Spanned<f64>>,
    top_speed_rpm: Option<Spanned<f64>>,
    time_constant_ms: Option<Spanned<f64>>,
    dead_band_percent: Option<Spanned<f64>>,
    radius_mm: Option<Spanned<f64>>,
    start: Option<Spanned<[f64; 3]>>,
    encoder_edges_per_rev: Option<Spanned<u32>>,
}

/// `lines = [{ points = …, width_mm = …, reflectance = … }]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLine {
    points: Vec<[f64; 2]>,
    width_mm: f64,
    reflectance: f64,
}

/// `lamp = { at = [x, y], counts_at_1m = …, ambient_counts = … }`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLamp {
    at: [f64; 2],
    counts_at_1m: f64,
    #[serde(default)]
    ambient_counts: f64,
}

/// `[arena]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawArena {
    size_mm: Option<Spanned<[f64; 2]>>,
    walls: Option<Spanned<Vec<[f64; 4]>>>,
    boxes: Option<Spanned<Vec<[f64; 4]>>>,
    lines: Option<Spanned<Vec<RawLine>>>,
    floor_reflectance: Option<Spanned<f64>>,
    lamp: Option<Spanned<RawLamp>>,
}

/// `[[sensor]]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSensor {
    device: Spanned<String>,
    source: Spanned<String>,
    at: Option<Spanned<[f64; 2]>>,
    angle_deg: Option<Spanned<f64>>,
    beam_deg: Option<Spanned<f64>>,
    range_mm: Option<Spanned<f64>>,
    arc_deg: Option<Spanned<f64>>,
    body: Option<Spanned<String>>,
}

/// `[[thermal]]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawThermal {
    name: Spanned<String>,
    start_c: Spanned<f64>,
    idle_c: Spanned<f64>,
    time_constant_s: Spanned<f64>,
    ambient_c: Option<Spanned<f64>>,
    heater: Option<Spanned<String>>,
    heater_c: Option<Spanned<f64>>,
    door: Option<Spanned<String>>,
}

/// `[[servo]]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawServo {
    device: Spanned<String>,
    speed_deg_s: Spanned<f64>,
}

/// The physics tables of a world file.
pub(super) struct RawModels<'a> {
    pub physics: Option<&'a Spanned<RawPhysics>>,
    pub chassis: Option<&'a Spanned<RawChassis>>,
    pub arena: Option<&'a Spanned<RawArena>>,
    pub sensors: &'a [Spanned<RawSensor>],
    pub thermals: &'a [Spanned<RawThermal>],
    pub servos: &'a [Spanned<RawServo>],
}

fn v<T: Copy>(s: &Option<Spanned<T>>, default: T) -> T {
    s.as_ref().map_or(default, |s| *s.get_ref())
}

/// Reads the physics tables into `world`, recording each field's line (`line` maps a byte
/// offset to a line).
pub(super) fn read(
    raw: RawModels<'_>,
    world: &mut World,
    line: &dyn Fn(usize) -> usize,
) -> Result<(), WorldError> {
    let mark = |world: &mut World,
                item: Item,
                field: &'static str,
                span: Option<std::ops::Range<usize>>| {
        if let Some(s) = span {
            world.lines.insert((item, field), line(s.start));
        }
    };
    if let Some(p) = raw.physics {
        mark(world, Item::Physics, "", Some(p.span()));
        let ms = p.get_ref().step_ms;
        world.physics.step_us = if ms.is_finite() && ms > 0.0 {
            (ms * 1_000.0).round() as u64
        } else {
            0
        };
    }
    if let Some(c) = raw.chassis {
        let item = Item::Chassis;
        mark(world, item, "", Some(c.span()));
        let c = c.get_ref();
        mark(world, item, "left", Some(c.left.span()));
        mark(world, item, "right", Some(c.right.span()));
        for (f, s) in [
            ("wheel_base_mm", &c.wheel_base_mm),
            ("wheel_radius_mm", &c.wheel_radius_mm),
            ("top_speed_rpm", &c.top_speed_rpm),
            ("time_constant_ms", &c.time_constant_ms),
            ("dead_band_percent", &c.dead_band_percent),
            ("radius_mm", &c.radius_mm),
        ] {
            mark(world, item, f, s.as_ref().map(Spanned::span));
        }
        mark(world, item, "start", c.start.as_ref().map(Spanned::span));
        mark(
            world,
            item,
            "encoder_edges_per_rev",
            c.encoder_edges_per_rev.as_ref().map(Spanned::span),
        );
        let d = Chassis::new(c.left.get_ref().clone(), c.right.get_ref().clone());
        let start = c.start.as_ref().map_or([0.0; 3], |s| *s.get_ref());
        world.physics.chassis = Some(Chassis {
            wheel_base_mm: v(&c.wheel_base_mm, d.wheel_base_mm),
            wheel_radius_mm: v(&c.wheel_radius_mm, d.wheel_radius_mm),
            top_speed_rpm: v(&c.top_speed_rpm, d.top_speed_rpm),
            time_constant_ms: v(&c.time_constant_ms, d.time_constant_ms),
            dead_band_percent: v(&c.dead_band_percent, d.dead_band_percent),
            radius_mm: v(&c.radius_mm, d.radius_mm),
            start: Pose::new(start[0], start[1], start[2]),
            encoder_edges_per_rev: v(&c.encoder_edges_per_rev, d.encoder_edges_per_rev),
            ..d
        });
    }
    if let Some(a) = raw.arena {
        let item = Item::Arena;
        mark(world, item, "", Some(a.span()));
        let a = a.get_ref();
        mark(world, item, "walls", a.walls.as_ref().map(Spanned::span));
        mark(world, item, "boxes", a.boxes.as_ref().map(Spanned::span));
        mark(world, item, "lines", a.lines.as_ref().map(Spanned::span));
        mark(
            world,
            item,
            "floor_reflectance",
            a.floor_reflectance.as_ref().map(Spanned::span),
        );
        mark(world, item, "lamp", a.lamp.as_ref().map(Spanned::span));
        let mut arena = match &a.size_mm {
            Some(s) => Arena::walled(s.get_ref()[0], s.get_ref()[1]),
            None => Arena::default(),
        };
        let none = Vec::new();
        arena.walls.extend(
            a.walls
                .as_ref()
                .map_or(&none, |w| w.get_ref())
                .iter()
                .map(|w| Wall {
                    from: (w[0], w[1]),
                    to: (w[2], w[3]),
                }),
        );
        arena.boxes.extend(
            a.boxes
                .as_ref()
                .map_or(&none, |b| b.get_ref())
                .iter()
                .map(|b| Obstacle {
                    min: (b[0], b[1]),
                    max: (b[2], b[3]),
                }),
        );
        let no_lines = Vec::new();
        arena.lines = a
            .lines
            .as_ref()
            .map_or(&no_lines, |l| l.get_ref())
            .iter()
            .map(|l| FloorLine {
                points: l.points.iter().map(|p| (p[0], p[1])).collect(),
                width_mm: l.width_mm,
                reflectance: l.reflectance,
            })
            .collect();
        arena.floor_reflectance = v(&a.floor_reflectance, arena.floor_reflectance);
        arena.lamp = a.lamp.as_ref().map(|l| {
            let l = l.get_ref();
            Lamp {
                at: (l.at[0], l.at[1]),
                counts_at_1m: l.counts_at_1m,
                ambient_counts: l.ambient_counts,
            }
        });
        world.physics.arena = arena;
    }
    for (i, t) in raw.thermals.iter().enumerate() {
        let item = Item::Thermal(i);
        mark(world, item, "", Some(t.span()));
        let t = t.get_ref();
        mark(world, item, "name", Some(t.name.span()));
        mark(world, item, "heater", t.heater.as_ref().map(Spanned::span));
        mark(world, item, "door", t.door.as_ref().map(Spanned::span));
        mark(
            world,
            item,
            "time_constant_s",
            Some(t.time_constant_s.span()),
        );
        world.physics.thermals.push(Thermal {
            name: t.name.get_ref().clone(),
            start_c: *t.start_c.get_ref(),
            idle_c: *t.idle_c.get_ref(),
            ambient_c: v(&t.ambient_c, 20.0),
            time_constant_s: *t.time_constant_s.get_ref(),
            heater: t.heater.as_ref().map(|h| h.get_ref().clone()),
            heater_c: v(&t.heater_c, 0.0),
            door: t.door.as_ref().map(|h| h.get_ref().clone()),
        });
    }
    for (i, s) in raw.servos.iter().enumerate() {
        let item = Item::Servo(i);
        mark(world, item, "", Some(s.span()));
        let s = s.get_ref();
        mark(world, item, "device", Some(s.device.span()));
        mark(world, item, "speed_deg_s", Some(s.speed_deg_s.span()));
        world.physics.servos.push(ServoSlew {
            device: s.device.get_ref().clone(),
            deg_per_s: *s.speed_deg_s.get_ref(),
        });
    }
    for (i, s) in raw.sensors.iter().enumerate() {
        let item = Item::Sensor(i);
        mark(world, item, "", Some(s.span()));
        let s = s.get_ref();
        mark(world, item, "device", Some(s.device.span()));
        mark(world, item, "source", Some(s.source.span()));
        mark(world, item, "body", s.body.as_ref().map(Spanned::span));
        mark(
            world,
            item,
            "range_mm",
            s.range_mm.as_ref().map(Spanned::span),
        );
        mark(
            world,
            item,
            "arc_deg",
            s.arc_deg.as_ref().map(Spanned::span),
        );
        mark(world, item, "at", s.at.as_ref().map(Spanned::span));
        let radius = world.physics.chassis.as_ref().map_or(80.0, |c| c.radius_mm);
        let at = s.at.as_ref().map(|a| (a.get_ref()[0], a.get_ref()[1]));
        let who = format!("sensor `{}`", s.device.get_ref());
        let fail = |field: &'static str, reason: String| {
            Err(world.at(item, field, bad(who.clone(), field, reason)))
        };
        let name = s.source.get_ref().as_str();
        let source = match name {
            "ranger" => Source::Ranger {
                at: at.unwrap_or((radius, 0.0)),
                angle_deg: v(&s.angle_deg, 0.0),
                beam_deg: v(&s.beam_deg, 15.0),
                range_mm: v(&s.range_mm, 4_000.0),
            },
            "bumper" => Source::Bumper {
                arc_deg: v(&s.arc_deg, 180.0),
            },
            "line" => Source::Line {
                at: at.unwrap_or((radius, 0.0)),
            },
            "light" => Source::Light {
                at: at.unwrap_or((0.0, 0.0)),
            },
            "left_encoder" => Source::Encoder(Wheel::Left),
            "right_encoder" => Source::Encoder(Wheel::Right),
            "thermal" => match &s.body {
                Some(b) => Source::Thermal {
                    body: b.get_ref().clone(),
                },
                None => return fail("body", "is missing: `source = \"thermal\"` names its body".to_string()),
            },
            other => {
                return fail(
                    "source",
                    format!("is `{other}`: one of ranger, bumper, line, light, left_encoder, right_encoder, thermal"),
                )
            }
        };
        // Fields that do not apply to the source.
        let applies: &[&str] = match source {
            Source::Ranger { .. } => &["at", "angle_deg", "beam_deg", "range_mm"],
            Source::Bumper { .. } => &["arc_deg"],
            Source::Line { .. } | Source::Light { .. } => &["at"],
            Source::Encoder(_) => &[],
            Source::Thermal { .. } => &["body"],
        };
        for (field, given) in [
            ("at", s.at.is_some()),
            ("angle_deg", s.angle_deg.is_some()),
            ("beam_deg", s.beam_deg.is_some()),
            ("range_mm", s.range_mm.is_some()),
            ("arc_deg", s.arc_deg.is_some()),
            ("body", s.body.is_some()),
        ] {
            if given && !applies.contains(&field) {
                return fail(field, format!("does not apply to `source = \"{name}\"`"));
            }
        }
        world.physics.sensors.push(ModelSensor {
            device: s.device.get_ref().clone(),
            source,
        });
    }
    Ok(())
}
