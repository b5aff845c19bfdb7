//! A world that answers back: physical models whose state the robot's own outputs drive, and
//! whose sensors read that state (issue 28). A differential-drive chassis in an arena of walls,
//! boxes and floor lines; an ultrasonic ranger, a bumper, line and light sensors and wheel
//! encoders derived from the chassis's pose; thermal bodies (a heater, a freezer with a door)
//! read by thermistors.
//!
//! The models step on a fixed grid of virtual time ([`Physics::step_us`], 1 ms by default).
//! Step `k` (from `k·dt` to `(k+1)·dt`) takes its inputs (H-bridge pins and duties, heater
//! outputs, door switches) as they were at its start, from the board's
//! [`crate::ports::ActuatorLog`]; a sensor read at `t` sees the state at the last grid instant
//! at or before `t`, whose inputs all lie strictly before `t`. The state is integrated lazily,
//! up to the instant a sensor is read, and never past the simulator's "now": the same run
//! whatever the order or number of reads, and the same trajectory when the timeline replays
//! the log after the run ([`crate::timeline::Timeline::pose_at_ms`] and the rest).
//!
//! The models, their parameters, units and equations are in `docs/world.md` ("Physics").

mod engine;
pub(crate) mod geom;
mod view;

pub(crate) use engine::{slewed, Engine, InputPin, PinModel, RangerWiring, Spec};
pub use engine::{Contact, ModelPin, Motion, PoseSample, RangerReading};
pub(crate) use view::top_view_section;
pub use view::{top_view_svg, TOP_VIEW_SAMPLE_NS, TOP_VIEW_WIDTH};

/// Where a chassis is and which way it points: millimetres in the arena's plane (x to the
/// right, y up), heading in degrees counter-clockwise from the x axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// x, mm.
    pub x_mm: f64,
    /// y, mm.
    pub y_mm: f64,
    /// Heading, degrees (0: along +x, 90: along +y).
    pub heading_deg: f64,
}

impl Pose {
    /// A pose.
    pub fn new(x_mm: f64, y_mm: f64, heading_deg: f64) -> Pose {
        Pose {
            x_mm,
            y_mm,
            heading_deg,
        }
    }
}

/// A differential-drive chassis: two DC motors (world devices of kind `dc_motor`, driven
/// through their H-bridges) each turning a wheel, a round outline.
///
/// Each wheel's surface speed follows its motor's command with a first-order response:
/// `dv/dt = (v* − v) / τ`, where `v* = sign · top · (p − dead) / (100 − dead)` for a duty of
/// `p` % above the dead band, 0 otherwise (braking and coasting too); `top` is
/// `top_speed_rpm / 60 · 2π · wheel_radius_mm` mm/s.
#[derive(Clone, Debug, PartialEq)]
pub struct Chassis {
    /// The left motor's device name.
    pub left: String,
    /// The right motor's device name.
    pub right: String,
    /// Distance between the wheels, mm.
    pub wheel_base_mm: f64,
    /// Wheel radius, mm.
    pub wheel_radius_mm: f64,
    /// Wheel speed at 100 % duty, revolutions per minute.
    pub top_speed_rpm: f64,
    /// The motors' time constant, ms (0: the speed follows the command at once).
    pub time_constant_ms: f64,
    /// Duties at or below this percentage do not turn the wheel.
    pub dead_band_percent: f64,
    /// The chassis outline: a circle of this radius around the point between the wheels.
    pub radius_mm: f64,
    /// Where the run starts.
    pub start: Pose,
    /// Wheel encoder resolution: level changes per wheel revolution (a sensor with
    /// `source = "left_encoder"` or `"right_encoder"`).
    pub encoder_edges_per_rev: u32,
}

impl Chassis {
    /// A chassis on motors `left` and `right` with the defaults: wheel base 120 mm, wheels of
    /// 30 mm radius at 120 rpm at full duty (377 mm/s), time constant 100 ms, dead band 10 %,
    /// outline radius 80 mm, starting at (0, 0) heading 0°, 40 encoder edges per revolution.
    pub fn new(left: impl Into<String>, right: impl Into<String>) -> Chassis {
        Chassis {
            left: left.into(),
            right: right.into(),
            wheel_base_mm: 120.0,
            wheel_radius_mm: 30.0,
            top_speed_rpm: 120.0,
            time_constant_ms: 100.0,
            dead_band_percent: 10.0,
            radius_mm: 80.0,
            start: Pose::new(0.0, 0.0, 0.0),
            encoder_edges_per_rev: 40,
        }
    }

    /// Starts at `(x_mm, y_mm)` heading `heading_deg`.
    pub fn start(mut self, x_mm: f64, y_mm: f64, heading_deg: f64) -> Chassis {
        self.start = Pose::new(x_mm, y_mm, heading_deg);
        self
    }

    /// The wheel base and wheel radius, mm.
    pub fn wheels(mut self, wheel_base_mm: f64, wheel_radius_mm: f64) -> Chassis {
        self.wheel_base_mm = wheel_base_mm;
        self.wheel_radius_mm = wheel_radius_mm;
        self
    }

    /// Wheel speed at full duty (rpm), the time constant (ms) and the dead band (%).
    pub fn motors(mut self, top_speed_rpm: f64, time_constant_ms: f64, dead_band: f64) -> Chassis {
        self.top_speed_rpm = top_speed_rpm;
        self.time_constant_ms = time_constant_ms;
        self.dead_band_percent = dead_band;
        self
    }

    /// The outline's radius, mm.
    pub fn radius(mut self, radius_mm: f64) -> Chassis {
        self.radius_mm = radius_mm;
        self
    }

    /// Wheel surface speed at 100 % duty, mm/s.
    pub fn top_speed_mm_s(&self) -> f64 {
        self.top_speed_rpm / 60.0 * std::f64::consts::TAU * self.wheel_radius_mm
    }
}

/// A straight wall from `from` to `to` (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// One end.
    pub from: (f64, f64),
    /// The other end.
    pub to: (f64, f64),
}

/// An obstacle: an axis-aligned box from `min` to `max` (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obstacle {
    /// Lower-left corner.
    pub min: (f64, f64),
    /// Upper-right corner.
    pub max: (f64, f64),
}

/// A line on the floor (tape): a polyline of a width, of a reflectance (0 black to 1 white).
#[derive(Clone, Debug, PartialEq)]
pub struct FloorLine {
    /// Its points, mm.
    pub points: Vec<(f64, f64)>,
    /// Its width, mm.
    pub width_mm: f64,
    /// Its reflectance, 0 to 1.
    pub reflectance: f64,
}

/// A lamp: a light sensor at `d` mm from it reads `ambient + at_1m · (1000 / d)²` counts
/// (inverse square; `d` at least 50 mm), capped at the ADC's full scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lamp {
    /// Where it is, mm.
    pub at: (f64, f64),
    /// Counts its light adds at 1 m.
    pub counts_at_1m: f64,
    /// Counts without the lamp.
    pub ambient_counts: f64,
}

/// The plane a chassis drives in: walls, obstacles, the floor and its lines, a lamp.
#[derive(Clone, Debug, PartialEq)]
pub struct Arena {
    /// Walls.
    pub walls: Vec<Wall>,
    /// Obstacles (boxes).
    pub boxes: Vec<Obstacle>,
    /// Lines on the floor, drawn in order (a later one covers an earlier one).
    pub lines: Vec<FloorLine>,
    /// The floor's reflectance where there is no line, 0 to 1.
    pub floor_reflectance: f64,
    /// A lamp, if any.
    pub lamp: Option<Lamp>,
}

impl Default for Arena {
    fn default() -> Self {
        Arena {
            walls: Vec::new(),
            boxes: Vec::new(),
            lines: Vec::new(),
            floor_reflectance: 0.8,
            lamp: None,
        }
    }
}

impl Arena {
    /// An arena of `width_mm` × `height_mm` with a wall on each side, corners at (0, 0) and
    /// (width, height).
    pub fn walled(width_mm: f64, height_mm: f64) -> Arena {
        let (w, h) = (width_mm, height_mm);
        Arena {
            walls: vec![
                Wall {
                    from: (0.0, 0.0),
                    to: (w, 0.0),
                },
                Wall {
                    from: (w, 0.0),
                    to: (w, h),
                },
                Wall {
                    from: (w, h),
                    to: (0.0, h),
                },
                Wall {
                    from: (0.0, h),
                    to: (0.0, 0.0),
                },
            ],
            ..Arena::default()
        }
    }

    /// Adds a wall.
    pub fn wall(mut self, from: (f64, f64), to: (f64, f64)) -> Arena {
        self.walls.push(Wall { from, to });
        self
    }

    /// Adds a box from `min` to `max`.
    pub fn obstacle(mut self, min: (f64, f64), max: (f64, f64)) -> Arena {
        self.boxes.push(Obstacle { min, max });
        self
    }

    /// Adds a floor line.
    pub fn line(mut self, points: Vec<(f64, f64)>, width_mm: f64, reflectance: f64) -> Arena {
        self.lines.push(FloorLine {
            points,
            width_mm,
            reflectance,
        });
        self
    }

    /// Sets the lamp.
    pub fn lamp(mut self, lamp: Lamp) -> Arena {
        self.lamp = Some(lamp);
        self
    }

    /// What a contact touched, by index over walls then boxes: `wall 2`, `box 1` (from 1).
    pub fn obstacle_name(&self, index: usize) -> String {
        if index < self.walls.len() {
            format!("wall {}", index + 1)
        } else {
            format!("box {}", index - self.walls.len() + 1)
        }
    }
}

/// Which wheel an encoder watches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wheel {
    /// The left one.
    Left,
    /// The right one.
    Right,
}

/// Where a sensor takes its value from, instead of a script.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// An ultrasonic ranger on the chassis: at `at` (mm, in the chassis's frame: x forward, y
    /// left), pointing `angle_deg` from the heading; the nearest wall or box along any of 5
    /// rays spread over `beam_deg`, within `range_mm` (beyond: no echo).
    Ranger {
        /// Mounting point, chassis frame, mm.
        at: (f64, f64),
        /// Direction from the heading, degrees (counter-clockwise: 90 looks left).
        angle_deg: f64,
        /// Full beam width, degrees.
        beam_deg: f64,
        /// Farthest echo, mm.
        range_mm: f64,
    },
    /// A bumper: pressed while the outline touches (within 1 mm) a wall or box whose nearest
    /// point is within `arc_deg / 2` of the heading.
    Bumper {
        /// Width of the bumper's arc at the front, degrees.
        arc_deg: f64,
    },
    /// A line sensor at `at` (chassis frame) reads the floor's reflectance under it times the
    /// ADC's full scale.
    Line {
        /// Mounting point, chassis frame, mm.
        at: (f64, f64),
    },
    /// A light sensor at `at` (chassis frame) reads the lamp ([`Lamp`]).
    Light {
        /// Mounting point, chassis frame, mm.
        at: (f64, f64),
    },
    /// A wheel encoder: its level toggles [`Chassis::encoder_edges_per_rev`] times per
    /// revolution of the wheel.
    Encoder(Wheel),
    /// A thermistor in thermal body `body` ([`Thermal`]).
    Thermal {
        /// The body's name.
        body: String,
    },
}

impl Source {
    /// The name a world file uses.
    pub fn name(&self) -> &'static str {
        match self {
            Source::Ranger { .. } => "ranger",
            Source::Bumper { .. } => "bumper",
            Source::Line { .. } => "line",
            Source::Light { .. } => "light",
            Source::Encoder(Wheel::Left) => "left_encoder",
            Source::Encoder(Wheel::Right) => "right_encoder",
            Source::Thermal { .. } => "thermal",
        }
    }

    /// A ranger at the front of a chassis of radius `radius_mm`, looking ahead with the
    /// HC-SR04's 15° beam and 4 m range.
    pub fn front_ranger(radius_mm: f64) -> Source {
        Source::Ranger {
            at: (radius_mm, 0.0),
            angle_deg: 0.0,
            beam_deg: 15.0,
            range_mm: 4_000.0,
        }
    }
}

/// A device whose value comes from a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSensor {
    /// The device's name.
    pub device: String,
    /// Its model.
    pub source: Source,
}

/// A thermal body (an oven, a tank, a freezer): one temperature `T` with a first-order
/// response, `dT/dt = (T* − T) / τ`, towards `T* = base + heater_c · power`, where `base` is
/// `ambient_c` while the door (a switch or input device) is open and `idle_c` otherwise, and
/// `power` is the heater output's level (1 when driven HIGH) or duty (0–1).
#[derive(Clone, Debug, PartialEq)]
pub struct Thermal {
    /// Its name (what thermistors name as their `body`).
    pub name: String,
    /// Temperature at the start, °C.
    pub start_c: f64,
    /// Where it settles with the door shut and the heater off, °C.
    pub idle_c: f64,
    /// Where it settles with the door open, °C.
    pub ambient_c: f64,
    /// Time constant, s.
    pub time_constant_s: f64,
    /// The heater: an output device (digital output, LED, PWM output), if any.
    pub heater: Option<String>,
    /// How much warmer it settles with the heater at full power, °C.
    pub heater_c: f64,
    /// The door: an input device (switch, button, digital input), if any.
    pub door: Option<String>,
}

impl Thermal {
    /// A body called `name` at `start_c`, settling at `idle_c` with a time constant of
    /// `time_constant_s`; ambient 20 °C; no heater, no door.
    pub fn new(
        name: impl Into<String>,
        start_c: f64,
        idle_c: f64,
        time_constant_s: f64,
    ) -> Thermal {
        Thermal {
            name: name.into(),
            start_c,
            idle_c,
            ambient_c: 20.0,
            time_constant_s,
            heater: None,
            heater_c: 0.0,
            door: None,
        }
    }

    /// Heated by output device `device`, `rise_c` warmer at full power.
    pub fn heater(mut self, device: impl Into<String>, rise_c: f64) -> Thermal {
        self.heater = Some(device.into());
        self.heater_c = rise_c;
        self
    }

    /// A door (input device `device`): open, the body settles at `ambient_c`.
    pub fn door(mut self, device: impl Into<String>, ambient_c: f64) -> Thermal {
        self.door = Some(device.into());
        self.ambient_c = ambient_c;
        self
    }
}

/// A servo that travels: the timeline's angle moves towards each commanded angle at
/// `deg_per_s` (a hobby servo's rated speed: an SG90's 0.1 s per 60° is 600°/s) instead of
/// jumping to it. It starts at its first commanded angle.
#[derive(Clone, Debug, PartialEq)]
pub struct ServoSlew {
    /// The servo's device name.
    pub device: String,
    /// Its rated speed, degrees per second.
    pub deg_per_s: f64,
}

/// Every physical model of a world.
#[derive(Clone, Debug, PartialEq)]
pub struct Physics {
    /// The integration step, µs (1 000 by default).
    pub step_us: u64,
    /// The chassis, if any.
    pub chassis: Option<Chassis>,
    /// The arena.
    pub arena: Arena,
    /// Devices whose values come from the models.
    pub sensors: Vec<ModelSensor>,
    /// Thermal bodies.
    pub thermals: Vec<Thermal>,
    /// Servos that travel at their rated speed.
    pub servos: Vec<ServoSlew>,
}

impl Default for Physics {
    fn default() -> Self {
        Physics {
            step_us: 1_000,
            chassis: None,
            arena: Arena::default(),
            sensors: Vec::new(),
            thermals: Vec::new(),
            servos: Vec::new(),
        }
    }
}

impl Physics {
    /// True when there is nothing to simulate.
    pub fn is_empty(&self) -> bool {
        self.chassis.is_none()
            && self.sensors.is_empty()
            && self.thermals.is_empty()
            && self.servos.is_empty()
    }

    /// The model of device `name`, if it has one.
    pub fn source_of(&self, name: &str) -> Option<&Source> {
        self.sensors
            .iter()
            .find(|s| s.device == name)
            .map(|s| &s.source)
    }
}

#[cfg(test)]
mod tests;
