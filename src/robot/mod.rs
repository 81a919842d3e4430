//! The robot: a [`Body`] (sections, base pose, weight, tool) bent by one
//! [`Drive`] (pneumatic muscles, tendons or a magnetic field), and the maps
//! between its spaces (seed Fig. 2c):
//!
//! ```text
//! actuation (drive) -> configuration (loaded equilibrium) -> task (tip pose)
//! ```
//!
//! One set of entry points serves every drive: [`Robot::forward`],
//! [`Robot::inverse`], [`Robot::forward_batch`], [`Robot::workspace`],
//! [`Robot::sensitivity`] and [`Robot::calibrate`] dispatch on the drive here.

mod batch;
mod body;
mod bounds;
mod calibrate;
mod drive;
mod ik;
mod load;
pub mod trajectory;

pub use batch::{IkSample, WARM_TURN};
use body::BODY_KEYS;
pub use body::{Body, SectionSpec, MAX_SECTIONS, STANDARD_GRAVITY};
pub use calibrate::{Calibration, CalibrationSettings};
pub use drive::{Drive, Magnets, Muscles, TendonRoute, Tendons};
use drive::{FIELD_KEYS, MUSCLE_KEYS, TENDON_KEYS};
pub use ik::{
    ActuationSpace, IkEnding, IkOptions, IkResult, IkSettings, IkStart, InverseSolver, Strategy,
};
pub use load::Load;

use crate::contact::{Obstacle, Port};
use crate::error::{Error, Result};
use crate::read::count;
use crate::scene::{Gravity, PointLoad, Scene, Tendon};
use crate::value::Value;
use nalgebra::Vector3;

/// Sections from which one IK iteration (dense over `2 m` columns) may
/// outlast an interrupt poll.
const LONG_IK_PASS_SECTIONS: usize = 200;

/// Most elements of a robot's discretisation (about 0.5 GB of solver workspace).
pub const MAX_ROBOT_ELEMENTS: usize = 1_000_000;

/// A payload this many times the robot's own mass or more is warned about
/// (a mass in grams given as kilograms is a thousand times too heavy; soft
/// robots carry a few times their own mass at most).
pub const PAYLOAD_WARNING: f64 = 20.0;

/// A continuum robot: a body and the drive that bends it, discretised by
/// `n_elements` elements. `Robot::default()` resembles the seed's
/// prototype: 1 m, 10 sections of three pneumatic muscles, hanging from its
/// base.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Sections, base pose, weight and tool.
    pub body: Body,
    /// Muscles, tendons or a field.
    pub drive: Drive,
    /// Rigid obstacles around the robot, world frame (default none).
    pub obstacles: Vec<Obstacle>,
    /// Each obstacle's Coulomb friction coefficient, as
    /// [`Scene::friction`] (default none: frictionless).
    pub friction: Vec<f64>,
    /// Ports the robot slides through without friction, world frame (a
    /// trocar, a guide tube's exit; default none).
    pub ports: Vec<Port>,
    /// The range of the insertion, `[min, max]` [m]: how far the base may
    /// move along its tangent (a linear stage feeding the robot through a
    /// port). Given, the inverse kinematics has the insertion as one more
    /// coordinate; `None`: the base stays (insertion 0).
    pub insertion_range: Option<[f64; 2]>,
    /// Elements of the discretisation used by every solve (default: the
    /// smallest multiple of the sections that is at least 20, see
    /// [`crate::solver::default_elements`]).
    pub n_elements: usize,
}

/// What drives a robot at one instant: the muscles' rest curvature, the
/// tendons' tensions and the external magnetic field. Each left empty (or
/// zero) does not act.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Actuation {
    /// `[kappa_x, kappa_y]` per section [1/m]; empty: straight.
    pub rest_curvature: Vec<[f64; 2]>,
    /// One tension per tendon of the robot [N], each >= 0; empty: all slack.
    pub tensions: Vec<f64>,
    /// Uniform external field, world frame [T].
    pub field: Vector3<f64>,
    /// How far the base is moved along its tangent [m] (see
    /// [`Robot::insertion_range`]); 0: where the body puts it.
    pub insertion: f64,
}

impl Actuation {
    /// The muscles' rest curvature alone (tendons slack, no field).
    pub fn muscles(rest_curvature: Vec<[f64; 2]>) -> Actuation {
        Actuation {
            rest_curvature,
            ..Actuation::default()
        }
    }
}

/// Which drives a batch's result reports, a column each: the rest curvature
/// where the muscles drive the robot or it was given, the tensions of a
/// robot with tendons, the field of a magnetic one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveColumns {
    pub rest_curvature: bool,
    pub tensions: bool,
    pub field: bool,
    /// The insertion, where the robot has an insertion range.
    pub insertion: bool,
}

fn positive(name: &str, x: f64) -> Result<()> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(Error::scene(
            name,
            format!("must be positive and finite, got {x}"),
        ))
    }
}

/// Refuse derived quantities `(key, quantity, value, whether an exact zero
/// is what the fields say)` that are not finite normal numbers, each blamed
/// on the key that sets it (see [`Robot::validate`]).
fn check_normal(quantities: &[(&str, &str, f64, bool)]) -> Result<()> {
    for &(key, what, x, zero) in quantities {
        if !(x.is_normal() || (zero && x == 0.0)) {
            return Err(Error::scene(
                key,
                format!("{what} = {x:e} is beyond double precision (overflow or underflow); rescale the robot"),
            ));
        }
    }
    Ok(())
}

impl Default for Robot {
    fn default() -> Self {
        let body = Body::default();
        Robot {
            drive: Drive::Muscles(Muscles::for_sections_of(body.section_length())),
            n_elements: crate::solver::default_elements(body.sections),
            body,
            obstacles: Vec::new(),
            friction: Vec::new(),
            ports: Vec::new(),
            insertion_range: None,
        }
    }
}

impl Robot {
    /// A body bent by a drive, discretised by the default elements
    /// ([`crate::solver::default_elements`]).
    pub fn new(body: Body, drive: Drive) -> Robot {
        Robot {
            n_elements: crate::solver::default_elements(body.sections),
            body,
            drive,
            obstacles: Vec::new(),
            friction: Vec::new(),
            ports: Vec::new(),
            insertion_range: None,
        }
    }

    /// The robot's outer radius for contact [m]: the body's `radius`, else
    /// the drive's reach from the backbone (the muscles' distance, the
    /// farthest tendon's offset), else half a round backbone's diameter.
    pub fn contact_radius(&self) -> f64 {
        if let Some(r) = self.body.radius {
            return r;
        }
        let backbone = match self.body.stiffness {
            crate::scene::Stiffness::RoundRod { diameter, .. } => 0.5 * diameter,
            crate::scene::Stiffness::Diagonal { .. } => 0.0,
        };
        let drive = match &self.drive {
            Drive::Muscles(m) => m.radius,
            Drive::Tendons(t) => t
                .routes
                .iter()
                .map(|r| r.offset[0].hypot(r.offset[1]))
                .fold(0.0, f64::max),
            Drive::Field(_) => 0.0,
        };
        backbone.max(drive)
    }

    /// The muscles, or why the robot has none (`what` needs them).
    pub fn muscles(&self, what: &str) -> Result<&Muscles> {
        self.drive.muscles().ok_or_else(|| {
            Error::argument(
                what,
                format!(
                    "the robot has no muscles: it is driven by its {}",
                    self.drive.name()
                ),
            )
        })
    }

    /// Joint space from rest curvature: the three muscle lengths of each
    /// section (see [`Muscles::lengths`]).
    pub fn muscle_lengths(&self, rest_curvature: &[[f64; 2]]) -> Result<Vec<[f64; 3]>> {
        let m = self.muscles("rest_curvature")?;
        Ok(m.lengths(self.body.section_length(), rest_curvature))
    }

    /// Rest curvature from joint space (see [`Muscles::rest_curvature`]).
    pub fn rest_curvature(&self, muscle_lengths: &[[f64; 3]]) -> Result<Vec<[f64; 2]>> {
        self.muscles("muscle_lengths")?
            .rest_curvature(self.body.section_length(), muscle_lengths)
    }

    /// Actuator space from joint space: inflation time of each muscle [s].
    pub fn inflation_times(&self, muscle_lengths: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
        Ok(self
            .muscles("muscle_lengths")?
            .inflation_times(muscle_lengths))
    }

    /// Joint space from actuator space.
    pub fn muscle_lengths_from_times(&self, times: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
        Ok(self.muscles("times")?.lengths_from_times(times))
    }

    /// Whether every muscle length of every section lies in the range.
    pub fn within_bounds(&self, rest_curvature: &[[f64; 2]]) -> Result<bool> {
        let m = self.muscles("rest_curvature")?;
        Ok(m.within_bounds(self.body.section_length(), rest_curvature))
    }

    /// Whether one pass of a solve of this robot (a sweep over its elements,
    /// the IK's dense factorisation over its sections) may outlast an
    /// interrupt poll: see [`crate::Settings::has_long_passes`].
    pub fn has_long_passes(&self) -> bool {
        let forward = crate::Settings {
            n_elements: Some(self.n_elements),
            ..crate::Settings::default()
        };
        forward.has_long_passes() || self.body.sections >= LONG_IK_PASS_SECTIONS
    }

    /// The scene of the robot under an actuation (muscles, tendons and
    /// field; each left empty does not act) and `load`: own weight, the disks
    /// as point loads at the section ends, the payload's weight and the
    /// load's wrenches.
    pub fn scene(&self, actuation: &Actuation, load: &Load) -> Result<Scene> {
        let mut scene = if actuation.rest_curvature.is_empty() {
            let straight = vec![[0.0; 2]; self.body.sections];
            self.scene_of(&straight, &actuation.tensions, actuation.field, load)
        } else {
            self.scene_of(
                &actuation.rest_curvature,
                &actuation.tensions,
                actuation.field,
                load,
            )
        }?;
        self.check_insertion(actuation.insertion)?;
        scene.base_position = self.base_at(actuation.insertion);
        Ok(scene)
    }

    /// Whether an obstacle or a port has friction: an equilibrium is then
    /// the end of a loading history.
    pub fn has_friction(&self) -> bool {
        self.friction.iter().any(|mu| *mu > 0.0) || self.ports.iter().any(|p| p.friction > 0.0)
    }

    /// Where an insertion [m] puts the base: moved along its tangent.
    pub fn base_at(&self, insertion: f64) -> Vector3<f64> {
        self.body.base_position + insertion * self.insertion_axis()
    }

    /// The direction the insertion moves the base: its tangent.
    pub fn insertion_axis(&self) -> Vector3<f64> {
        self.body.base_quaternion.rotate(Vector3::z())
    }

    /// Refuse an insertion that is not finite or outside the robot's range
    /// (without a range, any finite insertion moves the base).
    pub fn check_insertion(&self, insertion: f64) -> Result<()> {
        if !insertion.is_finite() {
            return Err(Error::argument(
                "insertion",
                format!("must be finite, got {insertion}"),
            ));
        }
        if let Some([lo, hi]) = self.insertion_range {
            if !(lo..=hi).contains(&insertion) {
                return Err(Error::argument(
                    "insertion",
                    format!("{insertion} m is outside insertion_range [{lo}, {hi}]"),
                ));
            }
        }
        Ok(())
    }

    /// Forward statics: the loaded equilibrium of an actuation (see
    /// [`Robot::scene`]) at the robot's `n_elements`, from the straight rod
    /// or warm from `initial` (the quaternions of an equilibrium).
    pub fn forward(
        &self,
        actuation: &Actuation,
        load: &Load,
        initial: Option<&[crate::Quat]>,
    ) -> Result<crate::Solution> {
        let settings = crate::Settings {
            n_elements: Some(self.n_elements),
            ..crate::Settings::default()
        };
        crate::solve(&self.scene(actuation, load)?, settings, initial)
    }

    /// [`Robot::forward`] as the next equilibrium of a history from
    /// `previous` (see [`crate::Solver::solve_after`]): with friction, the
    /// step starts from the robot where it stood, at its insertion then.
    pub fn forward_after(
        &self,
        actuation: &Actuation,
        load: &Load,
        previous: &crate::Solution,
    ) -> Result<crate::Solution> {
        let settings = crate::Settings {
            n_elements: Some(self.n_elements),
            ..crate::Settings::default()
        };
        crate::solver::solve_after(&self.scene(actuation, load)?, settings, previous)
    }

    /// Refuse tensions (`name` "tensions") or a field (`name` "field")
    /// given to a robot that has no tendons or no magnets: it would move
    /// nothing.
    pub fn check_drive_given(&self, name: &str) -> Result<()> {
        let has = match name {
            "tensions" => !self.drive.tendon_routes().is_empty(),
            "field" => self.drive.magnets().is_some(),
            _ => true,
        };
        if has {
            return Ok(());
        }
        let what = if name == "field" {
            "magnetised material"
        } else {
            "tendons"
        };
        Err(Error::argument(
            name,
            format!(
                "this robot has no {what}: it is driven by {}",
                self.drive.description()
            ),
        ))
    }

    /// Refuse tensions or a field the robot's drives cannot apply, naming them.
    pub fn check_actuation(&self, tensions: &[f64], field: Vector3<f64>) -> Result<()> {
        let routes = self.drive.tendon_routes();
        if !tensions.is_empty() {
            self.check_drive_given("tensions")?;
        }
        if field != Vector3::zeros() {
            self.check_drive_given("field")?;
        }
        if !tensions.is_empty() && tensions.len() != routes.len() {
            return Err(Error::argument(
                "tensions",
                format!(
                    "expected {} tensions, one a tendon, got {}",
                    routes.len(),
                    tensions.len()
                ),
            ));
        }
        let most = self.drive.max_tension().unwrap_or(f64::INFINITY);
        for (i, t) in tensions.iter().enumerate() {
            if !(t.is_finite() && *t >= 0.0) {
                return Err(Error::argument(
                    format!("tensions[{i}]"),
                    format!("a tendon pulls, it cannot push: must be finite and >= 0 N, got {t}"),
                ));
            }
            if *t > most {
                return Err(Error::argument(
                    format!("tensions[{i}]"),
                    format!("{t} N is more than the robot's max_tension ({most} N)"),
                ));
            }
        }
        if let Some(c) = field.iter().position(|b| !b.is_finite()) {
            return Err(Error::argument(
                format!("field[{c}]"),
                format!("must be finite, got {}", field[c]),
            ));
        }
        if let Some(limit) = self.drive.max_field() {
            // Round-off of a field the inverse solve put on the limit passes.
            if field.norm() > limit * (1.0 + 1e-12) {
                return Err(Error::argument(
                    "field",
                    format!(
                        "|B| = {} T is more than the robot's max_field ({limit} T)",
                        field.norm()
                    ),
                ));
            }
        }
        Ok(())
    }

    fn scene_of(
        &self,
        rest_curvature: &[[f64; 2]],
        tensions: &[f64],
        field: Vector3<f64>,
        load: &Load,
    ) -> Result<Scene> {
        self.validate()?;
        self.check_sample_drives(rest_curvature, tensions, field)?;
        load.validate()?;
        let tip_mass = load.mass;
        // The payload's weight and the wrenches are the scene's loads: refused
        // as the argument the caller gave, not as the scene's keys.
        let softest = self.body.stiffness.diagonal().min();
        let radian = softest / (self.body.length * self.body.length);
        let weight = tip_mass * self.body.gravity.norm();
        let wrenches = [
            ("load", weight),
            ("load.tip_force", load.tip_force.norm()),
            ("load.tip_moment", load.tip_moment.norm() / self.body.length),
        ];
        for (name, force) in wrenches {
            let parameter = force / radian;
            if parameter > crate::scene::MAX_LOAD_PARAMETER {
                let what = match name {
                    "load" => format!("{tip_mass} kg weighs"),
                    "load.tip_force" => "the tip force is".into(),
                    _ => "the tip moment is".into(),
                };
                return Err(Error::argument(
                    if name == "load" && !load.is_mass_only() {
                        "load.mass"
                    } else {
                        name
                    },
                    format!(
                        "{what} {parameter:.1e} times what bends the robot by a radian \
                         ({radian:.1e} N): beyond what any solve resolves{}",
                        if name == "load" {
                            " (the load is a mass in kg)"
                        } else {
                            ""
                        }
                    ),
                ));
            }
        }
        let mut s = Scene::new(self.body.length, 1.0, 1.0, 1.0);
        s.name = Some(format!(
            "robot, {} sections, {:.0} g at the tip",
            self.body.sections,
            tip_mass * 1e3
        ));
        s.stiffness_spec = self.body.stiffness.clone();
        s.rest_curvature = rest_curvature.to_vec();
        s.gravity = Some(Gravity {
            linear_density: self.body.linear_density,
            vector: self.body.gravity,
        });
        s.base_quaternion = self.body.base_quaternion;
        s.base_position = self.body.base_position;
        s.tip_force = (tip_mass + self.body.tool_mass) * self.body.gravity + load.tip_force;
        s.tip_moment = load.tip_moment;
        s.tip_force_offset = self.body.tool_offset;
        s.sections = self
            .body
            .section_properties
            .iter()
            .map(|p| crate::scene::SectionProperties {
                length: p.length,
                stiffness: p.stiffness.clone(),
                linear_density: p.linear_density,
                distributed_moment: None,
            })
            .collect();
        s.point_loads = (1..=self.body.sections)
            .map(|k| PointLoad {
                s: self.body.section_end(k),
                force: self.body.disk_mass_of(k) * self.body.gravity,
                moment: Vector3::zeros(),
            })
            .filter(|p| p.force.norm() > 0.0)
            .chain(load.point_loads.iter().cloned())
            .collect();
        s.tendons = self
            .drive
            .tendon_routes()
            .iter()
            .enumerate()
            .map(|(i, route)| Tendon {
                tension: tensions.get(i).copied().unwrap_or(0.0),
                offset: route.offset,
                twist: route.twist,
                reroutes: route
                    .reroutes
                    .iter()
                    .enumerate()
                    .map(|(k, r)| (self.body.section_end(k + 1), *r))
                    .collect(),
                end: self.body.section_end(route.section),
            })
            .collect();
        if let Some(m) = self.drive.magnets() {
            s.magnetization.clone_from(&m.magnetization);
            s.tip_magnet = m.tip_magnet;
        }
        s.magnetic_field = field;
        if !self.obstacles.is_empty() {
            s.obstacles.clone_from(&self.obstacles);
            s.friction.clone_from(&self.friction);
            s.radius = Some(self.contact_radius());
        }
        s.ports.clone_from(&self.ports);
        Ok(s)
    }

    /// Refuse a whole actuation that this (valid) robot cannot take: a rest
    /// curvature not one a section or not finite, tensions or a field its
    /// drives cannot apply.
    pub fn check_sample_drives(
        &self,
        rest_curvature: &[[f64; 2]],
        tensions: &[f64],
        field: Vector3<f64>,
    ) -> Result<()> {
        self.check_actuation(tensions, field)?;
        self.check_rows("rest_curvature", rest_curvature.len())?;
        if rest_curvature.iter().flatten().any(|k| !k.is_finite()) {
            return Err(Error::argument("rest_curvature", "must be finite"));
        }
        Ok(())
    }

    /// Refuse `rows` rows of a per-section array (rest curvature, muscle
    /// lengths, inflation times) named `name` unless there is one a section.
    pub fn check_rows(&self, name: &str, rows: usize) -> Result<()> {
        if rows != self.body.sections {
            return Err(Error::argument(
                name,
                format!("expected {} sections, got {rows}", self.body.sections),
            ));
        }
        Ok(())
    }

    /// What a robot may carry but is more likely a unit mistake: a payload
    /// of [`PAYLOAD_WARNING`] times its own mass or more (30 given for 30 g).
    /// One message each; a caller shows them (Python: `UserWarning`).
    pub fn load_warnings(&self, load: &Load) -> Vec<String> {
        let tip_mass = load.mass;
        let own = self.body.own_mass();
        if own > 0.0 && tip_mass >= PAYLOAD_WARNING * own {
            vec![format!(
                "load = {tip_mass} kg is {:.0} times the robot's own mass ({own:.3} kg): grams \
                 meant? (the load is a mass in kg)",
                tip_mass / own
            )]
        } else {
            Vec::new()
        }
    }

    /// The warnings of the robot itself: its scene's (its moduli, how
    /// slender it is, its tendons), see [`Scene::warnings`].
    pub fn warnings(&self) -> Vec<String> {
        let straight = vec![[0.0; 2]; self.body.sections];
        self.scene(&Actuation::muscles(straight), &Load::default())
            .map(|s| s.warnings())
            .unwrap_or_default()
    }

    /// The drives a batch of this robot reports (see [`DriveColumns`]);
    /// `rest_curvature_given`: the batch was given the muscles' curvature.
    pub fn drive_columns(&self, rest_curvature_given: bool) -> DriveColumns {
        DriveColumns {
            rest_curvature: rest_curvature_given
                || self.actuation_space() == ActuationSpace::Curvature,
            tensions: self.actuation_space() == ActuationSpace::Tensions,
            field: self.actuation_space() == ActuationSpace::Field,
            insertion: self.insertion_range.is_some(),
        }
    }

    /// What the inverse kinematics searches: the drive's coordinates.
    pub fn actuation_space(&self) -> ActuationSpace {
        self.drive.space()
    }

    /// The sensitivity parameter of the robot's drive (the default of
    /// [`Robot::sensitivity`]): `"rest_curvature"`, `"tensions"` or `"field"`.
    pub fn drive_parameter(&self) -> &'static str {
        match self.actuation_space() {
            ActuationSpace::Curvature => "rest_curvature",
            ActuationSpace::Tensions => "tensions",
            ActuationSpace::Field => "field",
        }
    }

    /// The same robot without weight or load: what a purely geometric model sees.
    pub fn weightless(&self) -> Robot {
        let mut robot = self.clone();
        robot.body.gravity = Vector3::zeros();
        robot
    }

    /// Refuse a robot that cannot be solved as given, naming the field: a
    /// field out of range, muscles that do not span the cross-section, or a
    /// derived quantity that overflows or underflows (the element and
    /// section lengths and their squares, the weights and their moment; the
    /// muscles' lever `l_s d` and its square, rest length, range and the
    /// inflation times at its ends), each blamed on the field that sets it.
    pub fn validate(&self) -> Result<()> {
        let body = &self.body;
        body.check_sections()?;
        if !(1..=MAX_ROBOT_ELEMENTS).contains(&self.n_elements)
            || self.n_elements % body.sections != 0
        {
            return Err(Error::scene(
                "n_elements",
                format!(
                    "must be a multiple of sections ({}) in [1, {MAX_ROBOT_ELEMENTS}], got {}",
                    body.sections, self.n_elements
                ),
            ));
        }
        body.check_fields()?;
        check_normal(&body.derived(self.n_elements))?;
        self.drive.check(
            body.sections,
            body.section_length(),
            body.has_equal_sections(),
        )?;
        self.check_ports()
    }

    /// Refuse ports the base does not stay behind at every insertion of its
    /// range (at its place without one): the rod must cross each port's
    /// plane ahead of its clamp.
    fn check_ports(&self) -> Result<()> {
        let [lo, hi] = self.insertion_range.unwrap_or([0.0, 0.0]);
        for (i, port) in self.ports.iter().enumerate() {
            for d in [lo, hi] {
                let base = self.base_at(d);
                if port.axis.dot(&(port.position - base)) <= 0.0 {
                    let key = match self.insertion_range {
                        Some(_) => "insertion_range".to_string(),
                        None => format!("ports[{i}]"),
                    };
                    return Err(Error::scene(
                        key,
                        format!(
                            "at an insertion of {d} m the base is not behind ports[{i}] \
                             (the rod must cross the port's plane ahead of its clamp)"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Read a robot from JSON text (the fields of [`Robot::from_value`]).
    pub fn from_json_str(text: &str) -> Result<Self> {
        Robot::from_value(&Value::from_json_str(text)?)
    }

    /// Read a robot from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Self> {
        Robot::from_value(&Value::from_toml_str(text)?)
    }

    /// The robot as JSON or TOML text (`from_json_str` / `from_toml_str`
    /// of it is the same robot).
    pub fn to_text(&self, format: crate::value::Format) -> Result<String> {
        self.to_value().to_text(format)
    }

    /// Write the robot to a `.json` or `.toml` file (by its extension),
    /// which `from_file` reads back to the same robot.
    pub fn write_file(&self, path: &std::path::Path) -> Result<()> {
        self.to_value().write_file(path)
    }

    /// Read a `.json` or `.toml` file.
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        let mut value = Value::from_file(path)?;
        if let Some(dir) = path.parent() {
            crate::contact::files_beside(&mut value, dir);
        }
        Robot::from_value(&value)
    }

    /// Every field as a value tree (`Robot::from_value` of it is the same
    /// robot): the body's keys, `n_elements` and the drive's keys.
    pub fn to_value(&self) -> Value {
        let mut entries = self.body.entries();
        entries.push(("n_elements".into(), Value::Number(self.n_elements as f64)));
        entries.extend(self.drive.entries());
        if !self.obstacles.is_empty() {
            let list = crate::scene::obstacles_value(&self.obstacles, &self.friction);
            entries.push(("obstacles".into(), list));
        }
        if !self.ports.is_empty() {
            let list = self.ports.iter().map(Port::to_value).collect();
            entries.push(("ports".into(), Value::List(list)));
        }
        if let Some(range) = self.insertion_range {
            let pair = range.iter().map(|x| Value::Number(*x)).collect();
            entries.push(("insertion_range".into(), Value::List(pair)));
        }
        Value::Map(entries)
    }

    /// Read a robot from a value tree: every field optional, defaults as
    /// `Robot::default()`. The body's keys ([`Body`]), `n_elements` and the
    /// keys of one drive ([`Drive`]: muscles unless tendons or magnets are
    /// given).
    pub fn from_value(v: &Value) -> Result<Self> {
        let entries = match v {
            Value::Map(entries) => entries,
            other => {
                return Err(Error::scene(
                    "robot",
                    format!("expected a table, got {}", other.kind()),
                ))
            }
        };
        let mut body = Body::default();
        let mut n_elements = None;
        let mut obstacles = Vec::new();
        let mut friction = Vec::new();
        let mut ports = None;
        let mut insertion_range = None;
        let mut drive_entries = Vec::new();
        for (key, value) in entries {
            let key = key.as_str();
            if BODY_KEYS.contains(&key) {
                body.read_key(key, value)?;
            } else if key == "n_elements" {
                n_elements = Some(count(value, key, MAX_ROBOT_ELEMENTS)?);
            } else if key == "obstacles" {
                obstacles = crate::scene::obstacles(value)?;
                friction = crate::scene::obstacle_friction(value)?;
            } else if key == "ports" {
                ports = Some(value);
            } else if key == "insertion_range" {
                let [lo, hi] = crate::read::numbers::<2>(value, key)?;
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    return Err(Error::scene(
                        key,
                        format!("expected finite [min, max] with min <= max, got [{lo}, {hi}]"),
                    ));
                }
                insertion_range = Some([lo, hi]);
            } else if [&MUSCLE_KEYS[..], &TENDON_KEYS, &FIELD_KEYS]
                .iter()
                .any(|keys| keys.contains(&key))
            {
                drive_entries.push((key, value));
            } else {
                let known: Vec<&str> = BODY_KEYS
                    .iter()
                    .chain(["n_elements", "obstacles", "ports", "insertion_range"].iter())
                    .chain(MUSCLE_KEYS.iter())
                    .chain(TENDON_KEYS.iter())
                    .chain(FIELD_KEYS.iter())
                    .copied()
                    .collect();
                return Err(Error::scene(
                    key,
                    format!("unknown key (expected one of: {})", known.join(", ")),
                ));
            }
        }
        let given = |name: &str| entries.iter().any(|(k, _)| k == name);
        // Sections given their lengths give the robot its own.
        if !given("length") && !body.section_lengths().is_empty() {
            body.length = body.section_lengths().iter().sum();
        }
        body.check_sections()?;
        let drive = Drive::read(&drive_entries, body.sections, body.section_length())?;
        // A port's axis defaults to the base's tangent (the body read first).
        let ports = match ports {
            Some(v) => crate::scene::ports(v, body.base_quaternion.rotate(Vector3::z()))?,
            None => Vec::new(),
        };
        let r = Robot {
            n_elements: n_elements.unwrap_or(crate::solver::default_elements(body.sections)),
            body,
            drive,
            obstacles,
            friction,
            ports,
            insertion_range,
        };
        // A field defaulted from another is blamed on the one given.
        let rest_key = if given("muscle_rest_length") {
            "muscle_rest_length"
        } else {
            "length"
        };
        let range_key = if given("muscle_length_range") {
            "muscle_length_range"
        } else {
            rest_key
        };
        r.validate().map_err(|e| match e {
            Error::InvalidScene { key, reason } if key == "muscle_rest_length" => {
                Error::scene(rest_key, reason)
            }
            Error::InvalidScene { key, reason } if key == "muscle_length_range" => {
                Error::scene(range_key, reason)
            }
            other => other,
        })?;
        Ok(r)
    }
}
