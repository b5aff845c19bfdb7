//! The models' integration on the grid of virtual time, its recorded history, and what the
//! sensors read from it.

use std::cell::RefCell;
use std::fmt;
use std::rc::Rc;

use firmware_db::EdgeCount;
use x10_microcode::{Level, PinRef};

use super::geom::{self, Seg, P};
use super::{Arena, Physics, Pose, Source, Wheel};
use crate::exec::{Nanos, SimClock};
use crate::ports::{ActuatorLog, Change, OutputChange};
use crate::timeline::{DeviceState, MotorState, Track};
use crate::world::{echo_width_us, Device, DigitalSignal};

/// A model sensor's timeline samples its value this often (line, light, thermal), ns.
pub const MODEL_SAMPLE_NS: Nanos = 10_000_000;

/// An output pin the models read: a digital level or a PWM duty.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct InputPin {
    pub board: String,
    pub pin: PinRef,
    pub duty: bool,
}

/// A ranger's wiring, for the readings the timeline lists.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RangerWiring {
    /// Index in `Physics::sensors`.
    pub sensor: usize,
    pub board: String,
    pub trigger: Option<PinRef>,
    pub delay_us: u64,
}

/// The models with every name resolved to pins (the world builds it: `World::physics_spec`).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Spec {
    pub physics: Physics,
    pub inputs: Vec<InputPin>,
    /// Left and right motor: indices in `inputs` of IN1, IN2 and the enable duty.
    pub motors: Option<[[usize; 3]; 2]>,
    /// Per thermal body: the heater's index in `inputs`.
    pub heaters: Vec<Option<usize>>,
    /// Per thermal body: the door's logical level.
    pub doors: Vec<Option<DigitalSignal>>,
    pub rangers: Vec<RangerWiring>,
}

/// The recorded levels of a digital model pin.
#[derive(Clone, Debug, Default)]
pub(super) struct Levels {
    initial: bool,
    level: bool,
    /// Each change: when, and the new level.
    pub(super) edges: Vec<(Nanos, bool)>,
}

impl Levels {
    fn set(&mut self, t: Nanos, level: bool) {
        if level != self.level {
            self.level = level;
            self.edges.push((t, level));
        }
    }

    pub(super) fn at(&self, t: Nanos) -> bool {
        let n = self.edges.partition_point(|(at, _)| *at <= t);
        n.checked_sub(1)
            .and_then(|i| self.edges.get(i))
            .map_or(self.initial, |(_, l)| *l)
    }

    fn count(&self, from: Nanos, to: Nanos) -> EdgeCount {
        let mut n = EdgeCount::NONE;
        for (_, l) in self.edges.iter().filter(|(at, _)| *at > from && *at <= to) {
            if *l {
                n.rising = n.rising.saturating_add(1);
            } else {
                n.falling = n.falling.saturating_add(1);
            }
        }
        n
    }
}

/// A time the outline touched a wall or box.
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    /// When the contact began, ns.
    pub t_ns: Nanos,
    /// What it touched: `wall 2`, `box 1` ([`Arena::obstacle_name`]).
    pub obstacle: String,
    /// The point touched, mm.
    pub at: (f64, f64),
}

/// The pose at one grid instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSample {
    /// When, ns.
    pub t_ns: Nanos,
    /// Where.
    pub pose: Pose,
}

/// One ranger measurement (a trigger pulse's end): where the sensor was and what its beam met.
#[derive(Clone, Debug, PartialEq)]
pub struct RangerReading {
    /// The ranger's device name.
    pub device: String,
    /// The end of the trigger pulse, ns.
    pub t_ns: Nanos,
    /// The sensor's position, mm.
    pub from: (f64, f64),
    /// The beam's direction, degrees.
    pub angle_deg: f64,
    /// The distance to the nearest hit, mm (`None`: nothing within range).
    pub distance_mm: Option<f64>,
}

/// The chassis's numbers the steps use, worked out once.
#[derive(Clone, Copy, Debug)]
struct WheelParams {
    /// Surface speed at 100 %, mm/s.
    top: f64,
    /// The motor's response per step, `1 − e^(−dt/τ)`.
    alpha: f64,
    /// Dead band, %.
    dead: f64,
    /// Wheel base, mm.
    base: f64,
    /// Surface travel per encoder edge, mm.
    mm_per_edge: f64,
}

/// The models' state over virtual time.
pub(crate) struct Engine {
    spec: Spec,
    wheels: Option<WheelParams>,
    segs: Vec<Seg>,
    log: ActuatorLog,
    cursor: usize,
    clock: Option<SimClock>,
    values: Vec<u8>,
    dt: Nanos,
    /// The state is at `k · dt`.
    k: u64,
    v: [f64; 2],
    pub(super) turned: [f64; 2],
    /// The pose (x, y, heading in radians) at each grid instant so far.
    pub(super) path: Vec<(f64, f64, f64)>,
    /// Per thermal body, the temperature at each grid instant so far.
    temps: Vec<Vec<f64>>,
    bumper: Levels,
    encoders: [Levels; 2],
    pub(super) contacts: Vec<Contact>,
    touching: bool,
    /// How far the chassis may still move before it could touch anything, mm (0: check at
    /// the next step).
    slack: f64,
}

impl fmt::Debug for Engine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Engine(t = {} steps)", self.k)
    }
}

fn rad(deg: f64) -> f64 {
    deg.to_radians()
}

/// A point of the chassis frame (`at`: x forward, y left) in the arena, for pose `p`.
fn on_chassis(p: (f64, f64, f64), at: P) -> P {
    let (s, c) = p.2.sin_cos();
    (p.0 + at.0 * c - at.1 * s, p.1 + at.0 * s + at.1 * c)
}

impl Engine {
    pub(crate) fn new(spec: Spec, log: ActuatorLog, clock: Option<SimClock>) -> Engine {
        // It reads the changes as the run goes: a bounded run keeps them all.
        log.follow();
        let a = &spec.physics.arena;
        let walls: Vec<(P, P)> = a.walls.iter().map(|w| (w.from, w.to)).collect();
        let boxes: Vec<(P, P)> = a.boxes.iter().map(|b| (b.min, b.max)).collect();
        let segs = geom::segments(&walls, &boxes);
        let start = spec.physics.chassis.as_ref().map_or((0.0, 0.0, 0.0), |c| {
            (c.start.x_mm, c.start.y_mm, rad(c.start.heading_deg))
        });
        let temps = spec
            .physics
            .thermals
            .iter()
            .map(|t| vec![t.start_c])
            .collect();
        let dt = spec.physics.step_us.max(1).saturating_mul(1_000);
        let wheels = spec.physics.chassis.as_ref().map(|c| WheelParams {
            top: c.top_speed_mm_s(),
            alpha: if c.time_constant_ms <= 0.0 {
                1.0
            } else {
                1.0 - (-(dt as f64) / 1e6 / c.time_constant_ms).exp()
            },
            dead: c.dead_band_percent,
            base: c.wheel_base_mm.max(1e-9),
            mm_per_edge: std::f64::consts::TAU * c.wheel_radius_mm.max(1e-9)
                / f64::from(c.encoder_edges_per_rev.max(1)),
        });
        let mut e = Engine {
            wheels,
            values: vec![0; spec.inputs.len()],
            segs,
            log,
            cursor: 0,
            clock,
            dt,
            k: 0,
            v: [0.0; 2],
            turned: [0.0; 2],
            path: vec![start],
            temps,
            bumper: Levels::default(),
            encoders: [Levels::default(), Levels::default()],
            contacts: Vec::new(),
            touching: false,
            slack: 0.0,
            spec,
        };
        e.touching = e.gap().is_some_and(|(g, _, _)| g <= Self::TOUCH_MM);
        let level = e.bumper_level();
        e.bumper.level = level;
        e.bumper.initial = level;
        e
    }

    /// A gap this small counts as touching, mm.
    const TOUCH_MM: f64 = 1.0;

    pub(crate) fn into_shared(self) -> Rc<RefCell<Engine>> {
        Rc::new(RefCell::new(self))
    }

    pub(crate) fn step_ns(&self) -> Nanos {
        self.dt
    }

    fn pose(&self) -> (f64, f64, f64) {
        self.path.last().copied().unwrap_or((0.0, 0.0, 0.0))
    }

    /// Integrates up to the last grid instant at or before `t_ns` (never past the clock's now).
    pub(crate) fn advance_to(&mut self, t_ns: Nanos) -> u64 {
        let t = match &self.clock {
            Some(c) => t_ns.min(c.now_ns()),
            None => t_ns,
        };
        let target = t / self.dt;
        while self.k < target {
            self.step();
        }
        target
    }

    /// Takes the log's changes up to `s` (the start of the step) into the input values.
    fn take_inputs(&mut self, s: Nanos) {
        let inputs = &self.spec.inputs;
        let values = &mut self.values;
        let mut cursor = self.cursor;
        self.log.with_changes(|changes: &[OutputChange]| {
            while let Some(c) = changes.get(cursor).filter(|c| c.t_ns <= s) {
                for (i, input) in inputs.iter().enumerate() {
                    if input.pin != c.pin || input.board != c.board {
                        continue;
                    }
                    match (c.change, input.duty) {
                        (Change::Digital(l), false) => values[i] = u8::from(l == Level::High),
                        (Change::Duty(d), true) => values[i] = d,
                        _ => {}
                    }
                }
                cursor += 1;
            }
        });
        self.cursor = cursor;
    }

    fn motor_target(&self, pins: [usize; 3], top: f64, dead: f64) -> f64 {
        let level = |i: usize| self.values.get(i).map(|v| Level::from_bool(*v != 0));
        let duty = self.values.get(pins[2]).copied().unwrap_or(0);
        let state = MotorState::decode(level(pins[0]), level(pins[1]), duty);
        let p = f64::from(state.signed_percent());
        if p.abs() <= dead || dead >= 100.0 {
            0.0
        } else {
            p.signum() * top * (p.abs() - dead) / (100.0 - dead)
        }
    }

    /// The gap between the outline and the nearest obstacle, its point and obstacle.
    fn gap_at(&self, p: (f64, f64, f64)) -> Option<(f64, P, usize)> {
        let r = self.spec.physics.chassis.as_ref()?.radius_mm;
        geom::nearest((p.0, p.1), &self.segs).map(|(d, q, o)| (d - r, q, o))
    }

    fn gap(&self) -> Option<(f64, P, usize)> {
        self.gap_at(self.pose())
    }

    /// Whether the outline at `p` would overlap an obstacle (squared distances: no root).
    fn blocked(&self, p: (f64, f64, f64)) -> bool {
        let Some(r) = self.spec.physics.chassis.as_ref().map(|c| c.radius_mm) else {
            return false;
        };
        let r2 = r * r;
        self.segs.iter().any(|s| {
            let q = geom::nearest_on((p.0, p.1), s.a, s.b);
            let (dx, dy) = (p.0 - q.0, p.1 - q.1);
            dx * dx + dy * dy < r2
        })
    }

    /// When the bumper's level may next change, at the earliest, from now (`None`: at the
    /// next step): while the outline is more than the touching distance away, it must first
    /// travel the difference, at no more than the wheels' top speed.
    pub(crate) fn bumper_quiet_ns(&self) -> Option<Nanos> {
        let c = self.spec.physics.chassis.as_ref()?;
        let (gap, _, _) = self.gap()?;
        let top = c.top_speed_mm_s();
        let room = gap - Self::TOUCH_MM;
        if room <= 0.0 || top <= 0.0 {
            return (top <= 0.0 && room > 0.0).then_some(Nanos::MAX / 2);
        }
        let ns = (room / top * 1e9).floor();
        (ns >= self.dt as f64).then(|| ns.min(1e15) as Nanos)
    }

    fn bumper_level(&self) -> bool {
        let Some(arc) = self
            .spec
            .physics
            .sensors
            .iter()
            .find_map(|s| match s.source {
                Source::Bumper { arc_deg } => Some(arc_deg),
                _ => None,
            })
        else {
            return false;
        };
        let Some(r) = self.spec.physics.chassis.as_ref().map(|c| c.radius_mm) else {
            return false;
        };
        let p = self.pose();
        let half = rad(arc) / 2.0;
        self.segs.iter().any(|s| {
            let q = geom::nearest_on((p.0, p.1), s.a, s.b);
            if geom::dist((p.0, p.1), q) > r + Self::TOUCH_MM {
                return false;
            }
            let bearing = (q.1 - p.1).atan2(q.0 - p.0) - p.2;
            let off = (bearing + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            off.abs() <= half + 1e-9
        })
    }

    /// One step: from `k·dt` to `(k+1)·dt`, the inputs as they were at `k·dt`.
    fn step(&mut self) {
        let s = self.k * self.dt;
        let end = s + self.dt;
        let dt_s = self.dt as f64 / 1e9;
        self.take_inputs(s);
        if let (Some(c), Some(pins)) = (self.wheels, self.spec.motors) {
            for (w, p) in pins.iter().enumerate() {
                let target = self.motor_target(*p, c.top, c.dead);
                self.v[w] += (target - self.v[w]) * c.alpha;
            }
            let (x, y, th) = self.pose();
            let v = (self.v[0] + self.v[1]) / 2.0;
            let omega = (self.v[1] - self.v[0]) / c.base;
            let mid = th + omega * dt_s / 2.0;
            let (dx, dy) = (v * mid.cos() * dt_s, v * mid.sin() * dt_s);
            let th2 = th + omega * dt_s;
            // Translation as far as the outline goes without entering an obstacle (the robot
            // stops against a wall; the wheels slip); turning in place always works.
            let mut f = 1.0;
            let moved = (dx * dx + dy * dy).sqrt();
            // Far from every obstacle (the gap last measured, less the way travelled since,
            // still above the touching distance): nothing to check.
            let clear = moved < self.slack;
            if clear {
                self.slack -= moved;
            } else if self.blocked((x + dx, y + dy, th2)) {
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..16 {
                    let m = (lo + hi) / 2.0;
                    if self.blocked((x + dx * m, y + dy * m, th2)) {
                        hi = m;
                    } else {
                        lo = m;
                    }
                }
                f = lo;
            }
            self.path.push((x + dx * f, y + dy * f, th2));
            for w in 0..2 {
                let old = self.turned[w];
                self.turned[w] += self.v[w] * dt_s;
                let count = |d: f64| (d / c.mm_per_edge).floor();
                let before = count(old);
                let after = count(self.turned[w]);
                let n = (after - before).abs().min(1e6) as u64;
                if let Some(e) = self.encoders.get_mut(w) {
                    for _ in 0..n {
                        let l = !e.level;
                        e.set(end, l);
                    }
                }
            }
            let gap = if clear { None } else { self.gap() };
            if let Some((g, _, _)) = gap {
                // A margin far above the rounding of the sums.
                self.slack = (g - Self::TOUCH_MM - 1e-6).max(0.0);
            }
            let touching = gap.is_some_and(|(g, _, _)| g <= Self::TOUCH_MM);
            if touching && !self.touching {
                if let Some((_, q, o)) = gap {
                    self.contacts.push(Contact {
                        t_ns: end,
                        obstacle: self.spec.physics.arena.obstacle_name(o),
                        at: q,
                    });
                }
            }
            self.touching = touching;
            // Only a touching outline can press the bumper.
            let b = touching && self.bumper_level();
            self.bumper.set(end, b);
        }
        for i in 0..self.temps.len() {
            let Some(body) = self.spec.physics.thermals.get(i) else {
                continue;
            };
            let open = self
                .spec
                .doors
                .get(i)
                .and_then(Option::as_ref)
                .is_some_and(|d| d.level_at_ns(s));
            let power = match self.spec.heaters.get(i).copied().flatten() {
                Some(h) => {
                    let v = f64::from(self.values.get(h).copied().unwrap_or(0));
                    let duty = self.spec.inputs.get(h).is_some_and(|p| p.duty);
                    if duty {
                        v / 255.0
                    } else {
                        v
                    }
                }
                None => 0.0,
            };
            let base = if open { body.ambient_c } else { body.idle_c };
            let target = base + body.heater_c * power;
            let alpha = if body.time_constant_s <= 0.0 {
                1.0
            } else {
                1.0 - (-dt_s / body.time_constant_s).exp()
            };
            if let Some(series) = self.temps.get_mut(i) {
                let t = series.last().copied().unwrap_or(body.start_c);
                series.push(t + (target - t) * alpha);
            }
        }
        self.k += 1;
    }

    /// The pose (radians) at grid instant `t / dt`, integrating as needed.
    pub(super) fn pose_at(&mut self, t: Nanos) -> (f64, f64, f64) {
        let j = self.advance_to(t).min(self.k);
        let i = usize::try_from(j).unwrap_or(usize::MAX);
        self.path
            .get(i)
            .or(self.path.last())
            .copied()
            .unwrap_or((0.0, 0.0, 0.0))
    }

    /// The distance a ranger sees at `t` (mm), `None` when nothing is within its range.
    pub(super) fn range(&mut self, sensor: usize, t: Nanos) -> Option<(f64, P, f64)> {
        let Source::Ranger {
            at,
            angle_deg,
            beam_deg,
            range_mm,
        } = self.spec.physics.sensors.get(sensor)?.source.clone()
        else {
            return None;
        };
        let p = self.pose_at(t);
        Some(self.cast(p, at, angle_deg, beam_deg, range_mm))
            .and_then(|(d, o, a)| d.map(|d| (d, o, a)))
    }

    /// The nearest hit of a ranger's 5 rays from pose `p`: distance (within range), the
    /// sensor's position, the beam's middle direction (degrees).
    fn cast(
        &self,
        p: (f64, f64, f64),
        at: P,
        angle_deg: f64,
        beam_deg: f64,
        range_mm: f64,
    ) -> (Option<f64>, P, f64) {
        let o = on_chassis(p, at);
        let mid = p.2 + rad(angle_deg);
        let mut best: Option<f64> = None;
        for k in [-2.0, -1.0, 0.0, 1.0, 2.0] {
            let a = mid + rad(beam_deg) / 4.0 * k;
            let d = (a.cos(), a.sin());
            for s in &self.segs {
                if let Some(h) = geom::ray_hit(o, d, s.a, s.b) {
                    if h <= range_mm && best.is_none_or(|b| h < b) {
                        best = Some(h);
                    }
                }
            }
        }
        (best, o, mid.to_degrees())
    }

    /// The echo width (µs) of ranger `sensor` whose echo starts at `start_us`: the distance at
    /// the trigger's end (`start − delay`), 0 (no echo) when nothing is within range.
    pub(crate) fn echo_us(
        &mut self,
        sensor: usize,
        start_us: u64,
        delay_us: u64,
        speed: u16,
    ) -> u16 {
        let t = start_us.saturating_sub(delay_us).saturating_mul(1_000);
        match self.range(sensor, t) {
            Some((d, _, _)) => echo_width_us(d, speed),
            None => 0,
        }
    }

    /// What the floor reflects at a point of the chassis at `t`, 0 to 1.
    fn reflectance(&mut self, at: P, t: Nanos) -> f64 {
        let p = self.pose_at(t);
        floor_reflectance(&self.spec.physics.arena, on_chassis(p, at))
    }

    /// An analog model sensor's counts at `t` on an ADC whose full scale is `max`.
    pub(crate) fn counts(&mut self, sensor: usize, t: Nanos, max: u16) -> u16 {
        let full = f64::from(max);
        let v = match self
            .spec
            .physics
            .sensors
            .get(sensor)
            .map(|s| s.source.clone())
        {
            Some(Source::Line { at }) => self.reflectance(at, t) * full,
            Some(Source::Light { at }) => {
                let p = self.pose_at(t);
                match self.spec.physics.arena.lamp {
                    Some(l) => {
                        let d = geom::dist(on_chassis(p, at), l.at).max(50.0);
                        l.ambient_counts + l.counts_at_1m * (1_000.0 / d).powi(2)
                    }
                    None => 0.0,
                }
            }
            _ => 0.0,
        };
        v.round().clamp(0.0, full) as u16
    }

    /// Thermal body `body`'s temperature at `t`, °C.
    pub(crate) fn celsius(&mut self, body: usize, t: Nanos) -> f64 {
        let j = self.advance_to(t).min(self.k);
        let i = usize::try_from(j).unwrap_or(usize::MAX);
        self.temps
            .get(body)
            .and_then(|s| s.get(i).or(s.last()))
            .copied()
            .unwrap_or(0.0)
    }

    pub(super) fn levels(&self, pin: PinModel) -> &Levels {
        match pin {
            PinModel::Bumper => &self.bumper,
            PinModel::Encoder(Wheel::Left) => &self.encoders[0],
            PinModel::Encoder(Wheel::Right) => &self.encoders[1],
        }
    }
}

/// The floor's reflectance at `p`: the last line that covers it, or the floor's.
pub(crate) fn floor_reflectance(arena: &Arena, p: P) -> f64 {
    arena
        .lines
        .iter()
        .rev()
        .find(|l| geom::dist_to_polyline(p, &l.points) <= l.width_mm / 2.0)
        .map_or(arena.floor_reflectance, |l| l.reflectance)
}

/// Which model a digital pin follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PinModel {
    Bumper,
    Encoder(Wheel),
}

/// A digital input whose level comes from a model (a bumper, a wheel encoder): see
/// [`crate::ports::Digital::Model`].
#[derive(Clone)]
pub struct ModelPin {
    engine: Rc<RefCell<Engine>>,
    pin: PinModel,
    invert: bool,
}

impl fmt::Debug for ModelPin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "Model({:?}{})",
            self.pin,
            if self.invert { ", inverted" } else { "" }
        )
    }
}

impl ModelPin {
    pub(crate) fn new(engine: Rc<RefCell<Engine>>, pin: PinModel, invert: bool) -> ModelPin {
        ModelPin {
            engine,
            pin,
            invert,
        }
    }

    /// The level at `t_ns` (integrating up to it).
    pub fn level_at(&self, t_ns: Nanos) -> bool {
        let mut e = self.engine.borrow_mut();
        e.advance_to(t_ns);
        e.levels(self.pin).at(t_ns) ^ self.invert
    }

    /// The first change after `t_ns` among those integrated so far (up to the clock's now):
    /// the model cannot know the commands to come.
    pub fn next_change_after(&self, t_ns: Nanos) -> Option<Nanos> {
        let mut e = self.engine.borrow_mut();
        e.advance_to(Nanos::MAX);
        let levels = e.levels(self.pin);
        let i = levels.edges.partition_point(|(at, _)| *at <= t_ns);
        levels.edges.get(i).map(|(at, _)| *at)
    }

    /// The edges in `(from_ns, to_ns]`, exactly as the integration recorded them.
    pub fn edges_between(&self, from_ns: Nanos, to_ns: Nanos) -> EdgeCount {
        let mut e = self.engine.borrow_mut();
        e.advance_to(to_ns);
        let n = e.levels(self.pin).count(from_ns, to_ns);
        if self.invert {
            EdgeCount {
                rising: n.falling,
                falling: n.rising,
            }
        } else {
            n
        }
    }

    /// When a task waiting for this pin's edges should look again: `now` when an edge came
    /// after `since`, else the next grid instant after `now`.
    pub fn wake_after(&self, since: Nanos, now: Nanos) -> Nanos {
        let n = self.edges_between(since, now);
        if n != EdgeCount::NONE {
            return now;
        }
        let e = self.engine.borrow();
        let dt = e.step_ns();
        let next = (now / dt + 1) * dt;
        match self.pin {
            // Far from any wall: no contact before the chassis could have crossed the gap.
            PinModel::Bumper => e
                .bumper_quiet_ns()
                .map_or(next, |q| (now.saturating_add(q) / dt * dt).max(next)),
            PinModel::Encoder(_) => next,
        }
    }
}

/// The models replayed over a finished run, for the timeline: the path, the contacts, the
/// ranger readings.
#[derive(Clone, Debug)]
pub struct Motion {
    physics: Physics,
    dt: Nanos,
    end_ns: Nanos,
    path: Vec<(f64, f64, f64)>,
    temps: Vec<Vec<f64>>,
    contacts: Vec<Contact>,
    readings: Vec<RangerReading>,
    bumper: Vec<(Nanos, bool)>,
    bumper_initial: bool,
    encoders: [Vec<(Nanos, bool)>; 2],
}

fn pose_of(p: (f64, f64, f64)) -> Pose {
    let deg = p.2.to_degrees();
    let deg = (deg + 180.0).rem_euclid(360.0) - 180.0;
    Pose::new(p.0, p.1, deg)
}

impl Motion {
    /// Replays the models of `spec` over `changes` up to `end_ns`.
    pub(crate) fn replay(spec: Spec, changes: &[OutputChange], end_ns: Nanos) -> Motion {
        let log = ActuatorLog::from_changes(changes.to_vec());
        let rangers = spec.rangers.clone();
        let mut e = Engine::new(spec, log, None);
        e.advance_to(end_ns);
        let mut readings = Vec::new();
        for r in &rangers {
            let Some(trigger) = r.trigger else { continue };
            let Some(sensor) = e.spec.physics.sensors.get(r.sensor).cloned() else {
                continue;
            };
            let Source::Ranger {
                at,
                angle_deg,
                beam_deg,
                range_mm,
            } = sensor.source
            else {
                continue;
            };
            let mut previous = None;
            for c in changes
                .iter()
                .filter(|c| c.board == r.board && c.pin == trigger && c.t_ns <= end_ns)
            {
                if let Change::Digital(l) = c.change {
                    if previous == Some(Level::High) && l == Level::Low {
                        let p = e.pose_at(c.t_ns);
                        let (d, from, angle) = e.cast(p, at, angle_deg, beam_deg, range_mm);
                        readings.push(RangerReading {
                            device: sensor.device.clone(),
                            t_ns: c.t_ns,
                            from,
                            angle_deg: angle,
                            distance_mm: d,
                        });
                    }
                    previous = Some(l);
                }
            }
        }
        readings.sort_by_key(|r| r.t_ns);
        Motion {
            dt: e.dt,
            end_ns,
            path: std::mem::take(&mut e.path),
            temps: std::mem::take(&mut e.temps),
            contacts: std::mem::take(&mut e.contacts),
            readings,
            bumper: std::mem::take(&mut e.bumper.edges),
            bumper_initial: e.bumper.initial,
            encoders: [
                std::mem::take(&mut e.encoders[0].edges),
                std::mem::take(&mut e.encoders[1].edges),
            ],
            physics: e.spec.physics,
        }
    }

    /// The rated speed of servo `name` if it travels ([`super::ServoSlew`]), °/s.
    pub fn slew_of(&self, name: &str) -> Option<f64> {
        self.physics
            .servos
            .iter()
            .find(|s| s.device == name)
            .map(|s| s.deg_per_s)
    }

    /// The models.
    pub fn physics(&self) -> &Physics {
        &self.physics
    }

    /// The end of the run, ns.
    pub fn end_ns(&self) -> Nanos {
        self.end_ns
    }

    /// The integration step, ns.
    pub fn step_ns(&self) -> Nanos {
        self.dt
    }

    /// The chassis's pose at `t_ns` (the grid instant at or before it), heading in
    /// (−180°, 180°].
    pub fn pose_at_ns(&self, t_ns: Nanos) -> Pose {
        let i = usize::try_from(t_ns / self.dt).unwrap_or(usize::MAX);
        pose_of(
            self.path
                .get(i)
                .or(self.path.last())
                .copied()
                .unwrap_or((0.0, 0.0, 0.0)),
        )
    }

    /// The chassis's pose at `t_ms`.
    pub fn pose_at_ms(&self, t_ms: u64) -> Pose {
        self.pose_at_ns(t_ms.saturating_mul(1_000_000))
    }

    /// Where the run ended.
    pub fn end_pose(&self) -> Pose {
        self.pose_at_ns(self.end_ns)
    }

    /// The pose every `every_ns` (at least the step) from 0 to the end.
    pub fn samples(&self, every_ns: Nanos) -> Vec<PoseSample> {
        let every = (every_ns / self.dt).max(1);
        let n = self
            .path
            .len()
            .min(usize::try_from(self.end_ns / self.dt + 1).unwrap_or(usize::MAX));
        (0..n)
            .step_by(usize::try_from(every).unwrap_or(usize::MAX))
            .filter_map(|i| {
                let p = self.path.get(i)?;
                Some(PoseSample {
                    t_ns: i as u64 * self.dt,
                    pose: pose_of(*p),
                })
            })
            .collect()
    }

    /// Every time the outline touched a wall or box, in time order.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// Every ranger measurement (trigger pulse), in time order.
    pub fn ranger_readings(&self) -> &[RangerReading] {
        &self.readings
    }

    /// The bumper's changes (time, pressed).
    pub fn bumper_changes(&self) -> &[(Nanos, bool)] {
        &self.bumper
    }

    /// The closest the outline came to a wall or box: the gap in mm and when (the first
    /// instant of the smallest gap). `None` without a chassis or obstacles.
    pub fn closest_to_wall(&self) -> Option<(Nanos, f64)> {
        let r = self.physics.chassis.as_ref()?.radius_mm;
        let e = Engine::segments_of(&self.physics.arena);
        let mut best: Option<(Nanos, f64)> = None;
        for (i, p) in self.path.iter().enumerate() {
            let t = i as u64 * self.dt;
            if t > self.end_ns {
                break;
            }
            if let Some((d, _, _)) = geom::nearest((p.0, p.1), &e) {
                let g = d - r;
                if best.is_none_or(|(_, b)| g < b) {
                    best = Some((t, g));
                }
            }
        }
        best
    }

    /// How long a point of the chassis (`at`, chassis frame, mm) was over a floor line, ns.
    pub fn time_on_line_ns(&self, at: (f64, f64)) -> Nanos {
        let on = self
            .path
            .iter()
            .take(usize::try_from(self.end_ns / self.dt).unwrap_or(usize::MAX))
            .filter(|p| {
                let q = on_chassis(**p, at);
                self.physics
                    .arena
                    .lines
                    .iter()
                    .any(|l| geom::dist_to_polyline(q, &l.points) <= l.width_mm / 2.0)
            })
            .count();
        on as u64 * self.dt
    }

    /// The timeline track of device `d` when it reads a model (its source's name and its
    /// states: a bumper's or encoder's level, a ranger's distance at each reading, a line or
    /// light sensor's counts and a thermistor's °C every [`MODEL_SAMPLE_NS`], when they
    /// change); `adc_max` is its board's ADC full scale.
    pub(crate) fn track_of(
        &self,
        d: &Device,
        adc_max: u16,
    ) -> Option<(&'static str, Track<DeviceState>)> {
        let source = self.physics.source_of(d.name())?;
        let levels = |initial: bool, edges: &[(Nanos, bool)]| {
            Track::new(
                DeviceState::Level(initial),
                edges
                    .iter()
                    .filter(|(t, _)| *t <= self.end_ns)
                    .map(|(t, l)| (*t, DeviceState::Level(*l)))
                    .collect(),
            )
        };
        let sampled = |f: &dyn Fn(Nanos) -> DeviceState| {
            let initial = f(0);
            let mut last = initial;
            let mut changes = Vec::new();
            let mut t = MODEL_SAMPLE_NS;
            while t <= self.end_ns {
                let v = f(t);
                if v != last {
                    changes.push((t, v));
                    last = v;
                }
                t += MODEL_SAMPLE_NS;
            }
            Track::new(initial, changes)
        };
        let track = match source {
            Source::Bumper { .. } => levels(self.bumper_initial, &self.bumper),
            Source::Encoder(Wheel::Left) => levels(false, &self.encoders[0]),
            Source::Encoder(Wheel::Right) => levels(false, &self.encoders[1]),
            Source::Ranger { .. } => Track::new(
                DeviceState::Distance(f64::INFINITY),
                self.readings
                    .iter()
                    .filter(|r| r.device == d.name())
                    .map(|r| {
                        (
                            r.t_ns,
                            DeviceState::Distance(r.distance_mm.unwrap_or(f64::INFINITY)),
                        )
                    })
                    .collect(),
            ),
            Source::Line { at } => {
                let at = *at;
                sampled(&|t| {
                    let p = self.raw_pose(t);
                    let r = floor_reflectance(&self.physics.arena, on_chassis(p, at));
                    DeviceState::Counts(
                        (r * f64::from(adc_max))
                            .round()
                            .clamp(0.0, f64::from(adc_max)) as u16,
                    )
                })
            }
            Source::Light { at } => {
                let at = *at;
                sampled(&|t| {
                    let p = self.raw_pose(t);
                    let v = self.physics.arena.lamp.map_or(0.0, |l| {
                        let dd = geom::dist(on_chassis(p, at), l.at).max(50.0);
                        l.ambient_counts + l.counts_at_1m * (1_000.0 / dd).powi(2)
                    });
                    DeviceState::Counts(v.round().clamp(0.0, f64::from(adc_max)) as u16)
                })
            }
            Source::Thermal { body } => {
                let body = body.clone();
                sampled(&|t| {
                    let c = self.celsius_at_ns(&body, t).unwrap_or(0.0);
                    DeviceState::Celsius(((c * 10.0).round() / 10.0) as f32)
                })
            }
        };
        Some((source.name(), track))
    }

    fn raw_pose(&self, t: Nanos) -> (f64, f64, f64) {
        let i = usize::try_from(t / self.dt).unwrap_or(usize::MAX);
        self.path
            .get(i)
            .or(self.path.last())
            .copied()
            .unwrap_or((0.0, 0.0, 0.0))
    }

    /// Thermal body `name`'s temperature at `t_ns`, °C.
    pub fn celsius_at_ns(&self, name: &str, t_ns: Nanos) -> Option<f64> {
        let b = self.physics.thermals.iter().position(|t| t.name == name)?;
        let s = self.temps.get(b)?;
        let i = usize::try_from(t_ns / self.dt).unwrap_or(usize::MAX);
        s.get(i).or(s.last()).copied()
    }

    /// A line of the summary: where the chassis ended and what it touched.
    pub fn summary_line(&self) -> Option<String> {
        self.physics.chassis.as_ref()?;
        let p = self.end_pose();
        let mut s = format!(
            "chassis: ended at ({:.0}, {:.0}) mm heading {:.0}°",
            p.x_mm, p.y_mm, p.heading_deg
        );
        match self.contacts.len() {
            0 => s.push_str("; no contact"),
            n => {
                let list: Vec<String> = self
                    .contacts
                    .iter()
                    .take(5)
                    .map(|c| format!("{} at {}", c.obstacle, crate::world::seconds(c.t_ns)))
                    .collect();
                s.push_str(&format!(
                    "; {n} contact{}: {}{}",
                    if n == 1 { "" } else { "s" },
                    list.join(", "),
                    if n > 5 { ", …" } else { "" }
                ));
            }
        }
        if let Some((t, g)) = self.closest_to_wall() {
            s.push_str(&format!(
                "; closest to a wall {:.0} mm at {}",
                g.max(0.0),
                crate::world::seconds(t)
            ));
        }
        Some(s)
    }
}

impl Engine {
    fn segments_of(arena: &Arena) -> Vec<Seg> {
        let walls: Vec<(P, P)> = arena.walls.iter().map(|w| (w.from, w.to)).collect();
        let boxes: Vec<(P, P)> = arena.boxes.iter().map(|b| (b.min, b.max)).collect();
        geom::segments(&walls, &boxes)
    }
}

/// A servo's commanded angles (`commanded`, a timeline track) as the servo reaches them at
/// `deg_per_s`: from its first commanded angle on, each later command is approached at the
/// rated speed, sampled every [`MODEL_SAMPLE_NS`] (a change when the whole degree changes); a
/// release (no pulses) is immediate, the servo holding where it was.
pub(crate) fn slewed(
    commanded: &Track<DeviceState>,
    deg_per_s: f64,
    end_ns: Nanos,
) -> Track<DeviceState> {
    let angle = |s: DeviceState| match s {
        DeviceState::Servo(a) => a,
        _ => None,
    };
    let initial = commanded.initial();
    let mut changes: Vec<(Nanos, DeviceState)> = Vec::new();
    let mut at: Option<f64> = angle(initial).map(f64::from);
    let mut shown = initial;
    let per_step = deg_per_s.max(0.0) * MODEL_SAMPLE_NS as f64 / 1e9;
    let mut t = 0;
    let cmds = commanded.changes();
    let mut next = 0;
    let mut target = angle(initial);
    while t <= end_ns {
        while let Some((_, s)) = cmds.get(next).filter(|(ct, _)| *ct <= t) {
            let a = angle(*s);
            if at.is_none() {
                at = a.map(f64::from);
            }
            target = a;
            next += 1;
        }
        let state = match (target, at) {
            (Some(goal), Some(now)) => {
                let goal = f64::from(goal);
                let moved = if (goal - now).abs() <= per_step {
                    goal
                } else {
                    now + per_step.copysign(goal - now)
                };
                at = Some(moved);
                DeviceState::Servo(Some(moved.round().clamp(0.0, f64::from(u16::MAX)) as u16))
            }
            _ => DeviceState::Servo(None),
        };
        if state != shown {
            changes.push((t, state));
            shown = state;
        }
        t += MODEL_SAMPLE_NS;
    }
    Track::new(initial, changes)
}
