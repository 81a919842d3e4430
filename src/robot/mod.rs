//! The robot: a backbone with `m` equal sections, each bent by three pneumatic
//! artificial muscles at radius `d`, a constraint disk (a point mass) at each
//! section end and an optional tip load, and the maps between its four spaces
//! (seed Fig. 2c):
//!
//! ```text
//! actuator (inflation time) <-> joint (muscle length) <-> rest curvature
//!     -> configuration (loaded equilibrium) -> task (tip pose)
//! ```
//!
//! Muscle `i` of a section sits at angle `phi_i` in the cross-section; bending
//! the section (backbone length `l_s`, fixed) with curvature `(kx, ky)` changes
//! its length by `l_s d (kx sin phi_i - ky cos phi_i)` (the fibre at offset `p`
//! stretches by `kappa . (p x e3)`). What the three lengths share (their common
//! mode) does not bend the backbone; it is chosen to centre the lengths in the
//! muscles' range, which leaves the most room for the next move.

mod batch;
mod bounds;
mod calibrate;
mod ik;
mod load;
pub mod trajectory;

pub use batch::{IkSample, WARM_TURN};
pub use calibrate::{Calibration, CalibrationSettings};
pub use ik::{
    ActuationSpace, IkEnding, IkOptions, IkResult, IkSettings, IkStart, InverseSolver, Strategy,
};
pub use load::Load;

use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::read::{count, finite, table_list, vec3};
use crate::scene::{
    check_lengths_add_up, prefixed, read_routings, read_stiffness, routing_values, section_entries,
    stiffness_value, Gravity, PointLoad, Routing, Scene, Stiffness, Tendon,
};
use crate::value::Value;
use nalgebra::{Matrix3, Vector3};

/// Standard gravity [m/s^2].
pub const STANDARD_GRAVITY: f64 = 9.81;

/// Most sections a robot may have (the IK's dense Jacobian has `2 m` columns).
pub const MAX_SECTIONS: usize = 10_000;

/// Sections from which one IK iteration (dense over `2 m` columns) may
/// outlast an interrupt poll.
const LONG_IK_PASS_SECTIONS: usize = 200;

/// Most elements of a robot's discretisation (about 0.5 GB of solver workspace).
pub const MAX_ROBOT_ELEMENTS: usize = 1_000_000;

/// Smallest `|det [1, sin phi_i, -cos phi_i]|` of the muscle angles: 2.6 for
/// three muscles 120 degrees apart, 0 for muscles on one line (which cannot
/// bend a section in every direction) or two at one angle.
const MIN_ANGLE_SPREAD: f64 = 1e-6;

/// A payload this many times the robot's own mass or more is warned about
/// (a mass in grams given as kilograms is a thousand times too heavy; soft
/// robots carry a few times their own mass at most).
pub const PAYLOAD_WARNING: f64 = 20.0;

/// A multi-section pneumatic continuum robot. `Robot::default()` resembles the
/// seed's prototype: 1 m, 10 sections, hanging from its base.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Backbone length [m] (default 1).
    pub length: f64,
    /// Backbone stiffness (default: spring steel, 3 mm: E 200 GPa, G 77 GPa).
    pub stiffness: Stiffness,
    /// Mass per length of backbone, muscles and tubing [kg/m] (default 0.2).
    pub linear_density: f64,
    /// Number of equal sections `m` (default 10).
    pub sections: usize,
    /// Distance of the muscles from the backbone `d` [m] (default 0.02).
    pub muscle_radius: f64,
    /// Angles of the three muscles in the cross-section [deg] (default 90, 210, 330).
    pub muscle_angles: [f64; 3],
    /// Mass of each constraint disk at a section end [kg] (default 0.01).
    pub disk_mass: f64,
    /// Gravitational acceleration, world frame [m/s^2] (default `[0, 0, -9.81]`).
    pub gravity: Vector3<f64>,
    /// Base orientation (default `[0, 1, 0, 0]`: hanging, tangent `-z`).
    pub base_quaternion: Quat,
    /// Base position [m], world frame (default the origin).
    pub base_position: Vector3<f64>,
    /// Muscle length at zero inflation time [m] (default: the section length).
    pub muscle_rest_length: f64,
    /// Calibration `length = rest_length + rate * time` [m/s] (default -0.01:
    /// inflation shortens a muscle by 1 cm a second).
    pub inflation_rate: f64,
    /// Shortest and longest muscle length [m] (default 0.8 and 1.05 times the
    /// rest length): the contraction range.
    pub muscle_length_range: [f64; 2],
    /// Elements of the discretisation used by every solve (default: the
    /// smallest multiple of the sections that is at least 20, see
    /// [`crate::solver::default_elements`]).
    pub n_elements: usize,
    /// Tendons routed along the backbone (default none); their tensions are
    /// the actuation of [`Actuation::tensions`].
    pub tendons: Vec<TendonRoute>,
    /// Largest tension a tendon's drive can pull [N] (default none: unbounded).
    pub max_tension: Option<f64>,
    /// Magnetisation per section, material frame [A m^2 / m] (default none;
    /// one entry magnetises every section).
    pub magnetization: Vec<Vector3<f64>>,
    /// A magnet at the tip, material frame [A m^2] (default none).
    pub tip_magnet: Vector3<f64>,
    /// Largest field the magnetic system makes, |B| [T] (default none: unbounded).
    pub max_field: Option<f64>,
    /// Per section, its own stiffness, linear density or disk mass (default
    /// none: the robot's everywhere; else one entry a section).
    pub section_properties: Vec<SectionSpec>,
    /// Mass of a tool at the tip [kg] (default 0).
    pub tool_mass: f64,
    /// Where the tool's weight, and the payload it holds (the `load`), act:
    /// from the tip in its material frame [m] (default the tip itself).
    pub tool_offset: Vector3<f64>,
}

/// What one section changes of the robot's own properties (each `None`:
/// the robot's).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SectionSpec {
    /// Length of the section [m]; given for every section or for none
    /// (`None`: equal sections of `length / sections`).
    pub length: Option<f64>,
    pub stiffness: Option<Stiffness>,
    /// Mass per length [kg/m].
    pub linear_density: Option<f64>,
    /// Mass of the disk at the section's end [kg].
    pub disk_mass: Option<f64>,
}

/// How a tendon runs through the robot: routed at an offset from the
/// backbone in the cross-section (its angle may turn at a constant rate: a
/// helix), through holes of its own in each section if it is given one
/// routing a section, pulled at the base, anchored at the end of a section.
#[derive(Debug, Clone, PartialEq)]
pub struct TendonRoute {
    /// Offset `[x, y]` from the backbone at the base, material frame [m].
    pub offset: [f64; 2],
    /// Turn of the routing angle per length [rad/m] (default 0: straight).
    pub twist: f64,
    /// The routing through sections 2, 3, ... up to the anchor's, each from
    /// its section's start (empty: `offset` and `twist` all the way).
    pub reroutes: Vec<Routing>,
    /// The section at whose end the tendon is anchored, 1..=sections
    /// (default: the last).
    pub section: usize,
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
}

/// Why muscle angles are refused.
const SPAN_MESSAGE: &str =
    "the three muscles must sit at distinct angles that span the cross-section's plane (the map from curvature to length changes must have rank 2)";

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

impl Default for Robot {
    fn default() -> Self {
        let length = 1.0;
        let sections = 10;
        let rest = length / sections as f64;
        Robot {
            length,
            stiffness: Stiffness::RoundRod {
                e: 200e9,
                g: 77e9,
                diameter: 0.003,
            },
            linear_density: 0.2,
            sections,
            muscle_radius: 0.02,
            muscle_angles: [90.0, 210.0, 330.0],
            disk_mass: 0.01,
            gravity: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
            base_quaternion: Quat::new(0.0, 1.0, 0.0, 0.0),
            base_position: Vector3::zeros(),
            muscle_rest_length: rest,
            inflation_rate: -0.01,
            muscle_length_range: [0.8 * rest, 1.05 * rest],
            n_elements: 20,
            tendons: Vec::new(),
            max_tension: None,
            magnetization: Vec::new(),
            tip_magnet: Vector3::zeros(),
            max_field: None,
            section_properties: Vec::new(),
            tool_mass: 0.0,
            tool_offset: Vector3::zeros(),
        }
    }
}

impl Robot {
    /// Backbone length of one section [m] (the mean, if the sections have
    /// lengths of their own).
    pub fn section_length(&self) -> f64 {
        self.length / self.sections as f64
    }

    /// The sections' own lengths [m]; empty when the sections are equal.
    pub fn section_lengths(&self) -> Vec<f64> {
        self.section_properties
            .iter()
            .filter_map(|p| p.length)
            .collect()
    }

    /// Length change of each muscle per unit curvature: row `i` is
    /// `l_s d (sin phi_i, -cos phi_i)`.
    fn lever(&self) -> [[f64; 2]; 3] {
        let ld = self.section_length() * self.muscle_radius;
        self.unit_lever().map(|[a, b]| [ld * a, ld * b])
    }

    /// The lever per `l_s d`: `(sin phi_i, -cos phi_i)`.
    fn unit_lever(&self) -> [[f64; 2]; 3] {
        self.muscle_angles.map(|a| {
            let phi = a.to_radians();
            [phi.sin(), -phi.cos()]
        })
    }

    /// `[1, sin phi_i, -cos phi_i]`: common mode and curvature per `l_s d` to lengths.
    fn joint_map(&self) -> Matrix3<f64> {
        let u = self.unit_lever();
        Matrix3::from_fn(|r, c| if c == 0 { 1.0 } else { u[r][c - 1] })
    }

    /// Joint space from rest curvature: the three muscle lengths of each section,
    /// their common mode centred in the muscles' range.
    pub fn muscle_lengths(&self, rest_curvature: &[[f64; 2]]) -> Vec<[f64; 3]> {
        let lever = self.lever();
        let centre = 0.5 * (self.muscle_length_range[0] + self.muscle_length_range[1]);
        rest_curvature
            .iter()
            .map(|k| {
                let delta = lever.map(|l| l[0] * k[0] + l[1] * k[1]);
                let mid = 0.5
                    * (delta.iter().cloned().fold(f64::MIN, f64::max)
                        + delta.iter().cloned().fold(f64::MAX, f64::min));
                delta.map(|d| centre - mid + d)
            })
            .collect()
    }

    /// Rest curvature from joint space (the common mode of the lengths, which
    /// does not bend an inextensible backbone, drops out).
    pub fn rest_curvature(&self, muscle_lengths: &[[f64; 3]]) -> Result<Vec<[f64; 2]>> {
        // [1, unit_lever_i] [common, l_s d kx, l_s d ky]^T = l_i, solved
        // without the scale l_s d, which only divides the answer.
        let inv = self
            .joint_map()
            .try_inverse()
            .ok_or_else(|| Error::argument("muscle_angles", SPAN_MESSAGE))?;
        let ld = self.section_length() * self.muscle_radius;
        Ok(muscle_lengths
            .iter()
            .map(|l| {
                let x = inv * Vector3::from(*l);
                [x[1] / ld, x[2] / ld]
            })
            .collect())
    }

    /// Actuator space from joint space: inflation time of each muscle [s].
    pub fn inflation_times(&self, muscle_lengths: &[[f64; 3]]) -> Vec<[f64; 3]> {
        muscle_lengths
            .iter()
            .map(|l| l.map(|x| (x - self.muscle_rest_length) / self.inflation_rate))
            .collect()
    }

    /// Joint space from actuator space.
    pub fn muscle_lengths_from_times(&self, times: &[[f64; 3]]) -> Vec<[f64; 3]> {
        times
            .iter()
            .map(|t| t.map(|x| self.muscle_rest_length + self.inflation_rate * x))
            .collect()
    }

    /// Whether every muscle length of every section lies in the range.
    pub fn within_bounds(&self, rest_curvature: &[[f64; 2]]) -> bool {
        let [lo, hi] = self.muscle_length_range;
        let tol = 1e-12 * hi;
        self.muscle_lengths(rest_curvature)
            .iter()
            .all(|l| l.iter().all(|x| *x >= lo - tol && *x <= hi + tol))
    }

    /// Scale each section's curvature back into the muscles' range (the largest
    /// difference between two muscle lengths must fit in the range).
    pub fn clamp_to_bounds(&self, rest_curvature: &mut [[f64; 2]]) -> bool {
        let lever = self.lever();
        let span = self.muscle_length_range[1] - self.muscle_length_range[0];
        let mut clamped = false;
        for k in rest_curvature.iter_mut() {
            let delta = lever.map(|l| l[0] * k[0] + l[1] * k[1]);
            let spread = delta.iter().cloned().fold(f64::MIN, f64::max)
                - delta.iter().cloned().fold(f64::MAX, f64::min);
            if spread > span {
                let f = span / spread;
                *k = [k[0] * f, k[1] * f];
                clamped = true;
            }
        }
        clamped
    }

    /// Whether one pass of a solve of this robot (a sweep over its elements,
    /// the IK's dense factorisation over its sections) may outlast an
    /// interrupt poll: see [`crate::Settings::has_long_passes`].
    pub fn has_long_passes(&self) -> bool {
        let forward = crate::Settings {
            n_elements: Some(self.n_elements),
            ..crate::Settings::default()
        };
        forward.has_long_passes() || self.sections >= LONG_IK_PASS_SECTIONS
    }

    /// The scene of the robot under an actuation (muscles, tendons and
    /// field; each left empty does not act) and `load`: own weight, the disks
    /// as point loads at the section ends, the payload's weight and the
    /// load's wrenches.
    pub fn scene(&self, actuation: &Actuation, load: &Load) -> Result<Scene> {
        if actuation.rest_curvature.is_empty() {
            let straight = vec![[0.0; 2]; self.sections];
            self.scene_of(&straight, &actuation.tensions, actuation.field, load)
        } else {
            self.scene_of(
                &actuation.rest_curvature,
                &actuation.tensions,
                actuation.field,
                load,
            )
        }
    }

    /// Forward statics: the loaded equilibrium of an actuation (see
    /// [`Robot::scene`]) at the robot's `n_elements`, from the straight rod
    /// or warm from `initial` (the quaternions of an equilibrium).
    pub fn forward(
        &self,
        actuation: &Actuation,
        load: &Load,
        initial: Option<&[Quat]>,
    ) -> Result<crate::Solution> {
        let settings = crate::Settings {
            n_elements: Some(self.n_elements),
            ..crate::Settings::default()
        };
        crate::solve(&self.scene(actuation, load)?, settings, initial)
    }

    /// Refuse tensions or a field the robot's drives cannot apply, naming them.
    pub fn check_actuation(&self, tensions: &[f64], field: Vector3<f64>) -> Result<()> {
        if !tensions.is_empty() && tensions.len() != self.tendons.len() {
            return Err(Error::argument(
                "tensions",
                format!(
                    "expected one a tendon ({}), got {}",
                    self.tendons.len(),
                    tensions.len()
                ),
            ));
        }
        let most = self.max_tension.unwrap_or(f64::INFINITY);
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
        if let Some(limit) = self.max_field {
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
        let softest = self.stiffness.diagonal().min();
        let radian = softest / (self.length * self.length);
        let weight = tip_mass * self.gravity.norm();
        let wrenches = [
            ("load", weight),
            ("load.tip_force", load.tip_force.norm()),
            ("load.tip_moment", load.tip_moment.norm() / self.length),
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
        let mut s = Scene::new(self.length, 1.0, 1.0, 1.0);
        s.name = Some(format!(
            "robot, {} sections, {:.0} g at the tip",
            self.sections,
            tip_mass * 1e3
        ));
        s.stiffness_spec = self.stiffness.clone();
        s.rest_curvature = rest_curvature.to_vec();
        s.gravity = Some(Gravity {
            linear_density: self.linear_density,
            vector: self.gravity,
        });
        s.base_quaternion = self.base_quaternion;
        s.base_position = self.base_position;
        s.tip_force = (tip_mass + self.tool_mass) * self.gravity + load.tip_force;
        s.tip_moment = load.tip_moment;
        s.tip_force_offset = self.tool_offset;
        s.sections = self
            .section_properties
            .iter()
            .map(|p| crate::scene::SectionProperties {
                length: p.length,
                stiffness: p.stiffness.clone(),
                linear_density: p.linear_density,
                distributed_moment: None,
            })
            .collect();
        s.point_loads = (1..=self.sections)
            .map(|k| PointLoad {
                s: self.section_end(k),
                force: self.disk_mass_of(k) * self.gravity,
                moment: Vector3::zeros(),
            })
            .filter(|p| p.force.norm() > 0.0)
            .chain(load.point_loads.iter().cloned())
            .collect();
        s.tendons = self
            .tendons
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
                    .map(|(k, r)| (self.section_end(k + 1), *r))
                    .collect(),
                end: self.section_end(route.section),
            })
            .collect();
        s.magnetization.clone_from(&self.magnetization);
        s.tip_magnet = self.tip_magnet;
        s.magnetic_field = field;
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
        if rows != self.sections {
            return Err(Error::argument(
                name,
                format!("expected {} sections, got {rows}", self.sections),
            ));
        }
        Ok(())
    }

    /// The robot's own mass [kg]: its backbone, disks and tool.
    pub fn own_mass(&self) -> f64 {
        let lengths = self.section_lengths();
        (1..=self.sections)
            .map(|k| {
                let p = self.section_properties.get(k - 1);
                let density = p
                    .and_then(|p| p.linear_density)
                    .unwrap_or(self.linear_density);
                let length = lengths.get(k - 1).copied().unwrap_or(self.section_length());
                density * length + self.disk_mass_of(k)
            })
            .sum::<f64>()
            + self.tool_mass
    }

    /// What a robot may carry but is more likely a unit mistake: a payload
    /// of [`PAYLOAD_WARNING`] times its own mass or more (30 given for 30 g).
    /// One message each; a caller shows them (Python: `UserWarning`).
    pub fn load_warnings(&self, load: &Load) -> Vec<String> {
        let tip_mass = load.mass;
        let own = self.own_mass();
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
        let straight = vec![[0.0; 2]; self.sections];
        self.scene(&Actuation::muscles(straight), &Load::default())
            .map(|s| s.warnings())
            .unwrap_or_default()
    }

    /// Mass of the disk at the end of section `k` (1-based) [kg].
    pub fn disk_mass_of(&self, k: usize) -> f64 {
        self.section_properties
            .get(k - 1)
            .and_then(|p| p.disk_mass)
            .unwrap_or(self.disk_mass)
    }

    /// Arc length of the end of section `k` (1-based) [m].
    pub fn section_end(&self, k: usize) -> f64 {
        let lengths = self.section_lengths();
        if k >= self.sections {
            self.length
        } else if lengths.len() == self.sections {
            lengths[..k].iter().sum()
        } else {
            k as f64 * self.section_length()
        }
    }

    /// The drives a batch of this robot reports (see [`DriveColumns`]);
    /// `rest_curvature_given`: the batch was given the muscles' curvature.
    pub fn drive_columns(&self, rest_curvature_given: bool) -> DriveColumns {
        DriveColumns {
            rest_curvature: rest_curvature_given
                || self.actuation_space() == ActuationSpace::Curvature,
            tensions: !self.tendons.is_empty(),
            field: self.is_magnetic(),
        }
    }

    /// Whether the robot has magnetised material or a tip magnet.
    pub fn is_magnetic(&self) -> bool {
        !self.magnetization.is_empty() || self.tip_magnet != Vector3::zeros()
    }

    /// The space its inverse kinematics searches: tensions if it has
    /// tendons, else the field if it is magnetic, else the muscles' curvature.
    pub fn actuation_space(&self) -> ActuationSpace {
        if !self.tendons.is_empty() {
            ActuationSpace::Tensions
        } else if self.is_magnetic() {
            ActuationSpace::Field
        } else {
            ActuationSpace::Curvature
        }
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
        Robot {
            gravity: Vector3::zeros(),
            ..self.clone()
        }
    }

    /// Refuse a robot that cannot be solved as given, naming the field: a
    /// field out of range, muscles that do not span the cross-section, or a
    /// derived quantity that overflows or underflows (listed at `check_derived`).
    pub fn validate(&self) -> Result<()> {
        self.check_counts()?;
        self.check_fields()?;
        self.check_muscle_angles()?;
        self.check_drives()?;
        self.check_derived()
    }

    /// Tendon routes, magnets and the drives' limits.
    fn check_drives(&self) -> Result<()> {
        for (i, t) in self.tendons.iter().enumerate() {
            let offsets = std::iter::once(&t.offset).chain(t.reroutes.iter().map(|r| &r.offset));
            if offsets.flatten().any(|x| !x.is_finite()) {
                return Err(Error::scene(
                    format!("tendons[{i}].offset"),
                    "must be finite",
                ));
            }
            let runs = if t.section == LAST_SECTION {
                self.sections
            } else {
                t.section
            };
            if !t.reroutes.is_empty() && t.reroutes.len() + 1 != runs {
                return Err(Error::scene(
                    format!("tendons[{i}].offset"),
                    format!(
                        "{} routings, but the tendon runs through {runs} sections: one [x, y] \
                         for all, or one for each",
                        t.reroutes.len() + 1
                    ),
                ));
            }
            if !t.twist.is_finite() || t.reroutes.iter().any(|r| !r.twist.is_finite()) {
                return Err(Error::scene(
                    format!("tendons[{i}].twist"),
                    "must be finite",
                ));
            }
            if !(1..=self.sections).contains(&t.section) {
                return Err(Error::scene(
                    format!("tendons[{i}].section"),
                    format!(
                        "must be a section in [1, {}], got {}",
                        self.sections, t.section
                    ),
                ));
            }
        }
        let p = self.section_properties.len();
        if p > 0 && p != self.sections {
            return Err(Error::scene(
                "section_properties",
                format!("expected one entry a section ({}), got {p}", self.sections),
            ));
        }
        self.check_section_lengths()?;
        for (i, spec) in self.section_properties.iter().enumerate() {
            for (name, x) in [
                ("linear_density", spec.linear_density),
                ("disk_mass", spec.disk_mass),
            ] {
                if let Some(x) = x.filter(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(Error::scene(
                        format!("section_properties[{i}].{name}"),
                        format!("must be >= 0 and finite, got {x}"),
                    ));
                }
            }
        }
        let k = self.magnetization.len();
        if k > 1 && k != self.sections {
            return Err(Error::scene(
                "magnetization",
                format!(
                    "expected one entry or one a section ({}), got {k}",
                    self.sections
                ),
            ));
        }
        if self
            .magnetization
            .iter()
            .chain(std::iter::once(&self.tip_magnet))
            .any(|m| m.iter().any(|x| !x.is_finite()))
        {
            return Err(Error::scene("magnetization", "must be finite"));
        }
        for (name, limit) in [
            ("max_tension", self.max_tension),
            ("max_field", self.max_field),
        ] {
            if let Some(x) = limit {
                positive(name, x)?;
            }
        }
        Ok(())
    }

    /// Section lengths: for every section or none, positive, adding up to
    /// the robot's length; sections of different lengths need tendons or
    /// magnets (the muscle model has one lever for every section).
    fn check_section_lengths(&self) -> Result<()> {
        let given: Vec<Option<f64>> = self.section_properties.iter().map(|p| p.length).collect();
        check_lengths_add_up(&given, self.length, "section_properties")?;
        let lengths = self.section_lengths();
        let equal = lengths.iter().all(|l| (l - lengths[0]).abs() <= 1e-12 * l);
        if !equal && self.actuation_space() == ActuationSpace::Curvature {
            return Err(Error::scene(
                "section_properties",
                "sections of different lengths are modelled for tendon and magnetic robots; \
                 the pneumatic muscle model takes equal sections (one lever l_s d for all)",
            ));
        }
        Ok(())
    }

    fn check_counts(&self) -> Result<()> {
        if !(1..=MAX_SECTIONS).contains(&self.sections) {
            return Err(Error::scene(
                "sections",
                format!(
                    "must be an integer in [1, {MAX_SECTIONS}], got {}",
                    self.sections
                ),
            ));
        }
        if !(1..=MAX_ROBOT_ELEMENTS).contains(&self.n_elements)
            || self.n_elements % self.sections != 0
        {
            return Err(Error::scene(
                "n_elements",
                format!(
                    "must be a multiple of sections ({}) in [1, {MAX_ROBOT_ELEMENTS}], got {}",
                    self.sections, self.n_elements
                ),
            ));
        }
        Ok(())
    }

    fn check_fields(&self) -> Result<()> {
        positive("length", self.length)?;
        positive("muscle_radius", self.muscle_radius)?;
        positive("muscle_rest_length", self.muscle_rest_length)?;
        for (name, x) in [
            ("linear_density", self.linear_density),
            ("disk_mass", self.disk_mass),
            ("tool_mass", self.tool_mass),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(Error::scene(
                    name,
                    format!("must be >= 0 and finite, got {x}"),
                ));
            }
        }
        if !(self.inflation_rate.is_finite() && self.inflation_rate != 0.0) {
            return Err(Error::scene(
                "inflation_rate",
                "must be finite and non-zero",
            ));
        }
        let [lo, hi] = self.muscle_length_range;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
            return Err(Error::scene(
                "muscle_length_range",
                format!("must be [min, max] with 0 < min < max, got [{lo}, {hi}]"),
            ));
        }
        if self.muscle_angles.iter().any(|a| !a.is_finite()) {
            return Err(Error::scene("muscle_angles", "must be finite"));
        }
        if self.gravity.iter().any(|g| !g.is_finite()) {
            return Err(Error::scene("gravity", "must be finite"));
        }
        if self.tool_offset.iter().any(|x| !x.is_finite()) {
            return Err(Error::scene("tool_offset", "must be finite"));
        }
        if let Stiffness::RoundRod { e, g, diameter } = self.stiffness {
            positive("stiffness.E", e)?;
            positive("stiffness.G", g)?;
            positive("stiffness.diameter", diameter)?;
        }
        if let Stiffness::Diagonal { kx, ky, kz } = self.stiffness {
            positive("stiffness.kx", kx)?;
            positive("stiffness.ky", ky)?;
            positive("stiffness.kz", kz)?;
        }
        Ok(())
    }

    /// The muscles must span the cross-section's plane: the 2 x 3 map from
    /// curvature to length changes has rank 2 and, with the common mode, is
    /// invertible (three distinct angles, not on one line).
    fn check_muscle_angles(&self) -> Result<()> {
        let det = self.joint_map().determinant();
        if det.abs() >= MIN_ANGLE_SPREAD {
            return Ok(());
        }
        let [a, b, c] = self.muscle_angles;
        Err(Error::scene(
            "muscle_angles",
            format!("{SPAN_MESSAGE}, got [{a}, {b}, {c}]"),
        ))
    }

    /// Quantities derived from the fields must be finite normal numbers (no
    /// overflow, no underflow to zero or to the subnormal range), each blamed on
    /// the field that sets it: the section and element lengths and the
    /// element length squared (`length`), the length squared (`length`: moment
    /// arms), the lever `l_s d` and its square (`muscle_radius`), the muscle
    /// rest length (`muscle_rest_length`), the range's
    /// span and curvature range `span / (l_s d)` (`muscle_length_range`), the
    /// inflation times at the range's ends (`inflation_rate`), the weights and
    /// their moment (`linear_density`, `disk_mass`).
    fn check_derived(&self) -> Result<()> {
        let ls = self.section_length();
        let ds = self.length / self.n_elements as f64;
        let ld = ls * self.muscle_radius;
        let [lo, hi] = self.muscle_length_range;
        let rest = self.muscle_rest_length;
        let g = self.gravity.norm();
        let weight = self.linear_density * g;
        let disks = self.disk_mass * g;
        // (key, quantity, value, whether an exact zero is what the fields say)
        let quantities = [
            ("length", "section length", ls, false),
            ("length", "element length", ds, false),
            ("length", "element length squared", ds * ds, false),
            ("length", "length squared", self.length * self.length, false),
            ("muscle_radius", "lever l_s d", ld, false),
            ("muscle_radius", "lever squared", ld * ld, false),
            ("muscle_rest_length", "rest length", rest, false),
            ("muscle_length_range", "span max - min", hi - lo, false),
            (
                "muscle_length_range",
                "curvature range span / (l_s d)",
                (hi - lo) / ld,
                false,
            ),
            (
                "inflation_rate",
                "inflation time at the shortest length",
                (lo - rest) / self.inflation_rate,
                lo == rest,
            ),
            (
                "inflation_rate",
                "inflation time at the longest length",
                (hi - rest) / self.inflation_rate,
                hi == rest,
            ),
            (
                "linear_density",
                "weight",
                weight * self.length,
                weight == 0.0,
            ),
            (
                "linear_density",
                "weight's moment",
                weight * self.length * self.length,
                weight == 0.0,
            ),
            (
                "disk_mass",
                "disks' weight",
                disks * self.sections as f64,
                disks == 0.0,
            ),
        ];
        for (key, what, x, zero) in quantities {
            if !(x.is_normal() || (zero && x == 0.0)) {
                return Err(Error::scene(
                    key,
                    format!("{what} = {x:e} is beyond double precision (overflow or underflow); rescale the robot"),
                ));
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

    /// Read a `.json` or `.toml` file.
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        Robot::from_value(&Value::from_file(path)?)
    }

    /// Read a robot from a value tree: every field optional, defaults as `Robot::default()`.
    /// Every field as a value tree (`Robot::from_value` of it is the same robot).
    pub fn to_value(&self) -> Value {
        let num = Value::Number;
        let list = |xs: &[f64]| Value::List(xs.iter().map(|x| num(*x)).collect());
        let stiffness = stiffness_value(&self.stiffness);
        let mut value = Value::Map(vec![
            ("length".into(), num(self.length)),
            ("stiffness".into(), stiffness),
            ("linear_density".into(), num(self.linear_density)),
            ("sections".into(), num(self.sections as f64)),
            ("muscle_radius".into(), num(self.muscle_radius)),
            ("muscle_angles".into(), list(&self.muscle_angles)),
            ("disk_mass".into(), num(self.disk_mass)),
            ("gravity".into(), list(self.gravity.as_slice())),
            (
                "base_quaternion".into(),
                list(&self.base_quaternion.to_array()),
            ),
            ("base_position".into(), list(self.base_position.as_slice())),
            ("muscle_rest_length".into(), num(self.muscle_rest_length)),
            ("inflation_rate".into(), num(self.inflation_rate)),
            (
                "muscle_length_range".into(),
                list(&self.muscle_length_range),
            ),
            ("n_elements".into(), num(self.n_elements as f64)),
        ]);
        let Value::Map(entries) = &mut value else {
            unreachable!("built as a table")
        };
        if !self.tendons.is_empty() {
            let routes = self
                .tendons
                .iter()
                .map(|t| {
                    let first = Routing {
                        offset: t.offset,
                        twist: t.twist,
                    };
                    let routings: Vec<Routing> = std::iter::once(first)
                        .chain(t.reroutes.iter().copied())
                        .collect();
                    let [offset, twist] = routing_values(&routings);
                    Value::Map(vec![
                        offset,
                        twist,
                        ("section".into(), num(t.section as f64)),
                    ])
                })
                .collect();
            entries.push(("tendons".into(), Value::List(routes)));
        }
        if !self.magnetization.is_empty() {
            let per_section = self
                .magnetization
                .iter()
                .map(|m| list(m.as_slice()))
                .collect();
            entries.push(("magnetization".into(), Value::List(per_section)));
        }
        if self.tip_magnet != Vector3::zeros() {
            entries.push(("tip_magnet".into(), list(self.tip_magnet.as_slice())));
        }
        for (name, limit) in [
            ("max_tension", self.max_tension),
            ("max_field", self.max_field),
        ] {
            if let Some(x) = limit {
                entries.push((name.into(), num(x)));
            }
        }
        if !self.section_properties.is_empty() {
            let specs = self
                .section_properties
                .iter()
                .map(|p| {
                    let mut fields =
                        section_entries(p.length, p.stiffness.as_ref(), p.linear_density);
                    if let Some(x) = p.disk_mass {
                        fields.push(("disk_mass".to_string(), num(x)));
                    }
                    Value::Map(fields)
                })
                .collect();
            entries.push(("section_properties".into(), Value::List(specs)));
        }
        if self.tool_mass != 0.0 || self.tool_offset != Vector3::zeros() {
            entries.push(("tool_mass".into(), num(self.tool_mass)));
            entries.push(("tool_offset".into(), list(self.tool_offset.as_slice())));
        }
        value
    }

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
        let mut r = Robot::default();
        for (key, value) in entries {
            r.read_field(key, value)?;
        }
        let given = |name: &str| entries.iter().any(|(k, _)| k == name);
        // Sections given their lengths give the robot its own.
        if !given("length") && !r.section_lengths().is_empty() {
            r.length = r.section_lengths().iter().sum();
        }
        // Defaults that follow the section length.
        if !given("muscle_rest_length") {
            r.muscle_rest_length = r.section_length();
        }
        if !given("muscle_length_range") {
            r.muscle_length_range = [0.8 * r.muscle_rest_length, 1.05 * r.muscle_rest_length];
        }
        if !given("n_elements") {
            r.n_elements = crate::solver::default_elements(r.sections);
        }
        for t in r.tendons.iter_mut().filter(|t| t.section == LAST_SECTION) {
            t.section = r.sections;
        }
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

    /// Set one field from the value tree (counts checked before anything is sized by them).
    fn read_field(&mut self, key: &str, value: &Value) -> Result<()> {
        let num = |v: &Value| finite(v, key);
        let list = |v: &Value, len: usize| -> Result<Vec<f64>> {
            match v {
                Value::List(items) if items.len() == len => items.iter().map(num).collect(),
                _ => Err(Error::scene(
                    key,
                    format!("expected a list of {len} numbers"),
                )),
            }
        };
        match key {
            "length" => self.length = num(value)?,
            "stiffness" => self.stiffness = read_stiffness(value)?,
            "linear_density" => self.linear_density = num(value)?,
            "sections" => self.sections = count(value, key, MAX_SECTIONS)?,
            "muscle_radius" => self.muscle_radius = num(value)?,
            "muscle_angles" => {
                let a = list(value, 3)?;
                self.muscle_angles = [a[0], a[1], a[2]];
            }
            "disk_mass" => self.disk_mass = num(value)?,
            "gravity" => self.gravity = Vector3::from_vec(list(value, 3)?),
            "base_quaternion" => self.base_quaternion = crate::scene::orientation(value, key)?,
            "base_position" => self.base_position = Vector3::from_vec(list(value, 3)?),
            "muscle_rest_length" => self.muscle_rest_length = num(value)?,
            "inflation_rate" => self.inflation_rate = num(value)?,
            "muscle_length_range" => {
                let a = list(value, 2)?;
                self.muscle_length_range = [a[0], a[1]];
            }
            "n_elements" => self.n_elements = count(value, key, MAX_ROBOT_ELEMENTS)?,
            "tendons" => self.tendons = tendon_routes(value)?,
            "max_tension" => self.max_tension = Some(num(value)?),
            "magnetization" => {
                self.magnetization = match value {
                    Value::List(items) if items.iter().all(|x| matches!(x, Value::List(_))) => items
                        .iter()
                        .enumerate()
                        .map(|(i, x)| vec3(x, &format!("magnetization[{i}]")))
                        .collect::<Result<_>>()?,
                    other => vec![vec3(other, key)?],
                }
            }
            "tip_magnet" => self.tip_magnet = vec3(value, key)?,
            "max_field" => self.max_field = Some(num(value)?),
            "tool_mass" => self.tool_mass = num(value)?,
            "section_properties" => self.section_properties = section_specs(value)?,
            "tool_offset" => self.tool_offset = vec3(value, key)?,
            other => {
                return Err(Error::scene(other, "unknown key (expected one of: length, stiffness, linear_density, sections, muscle_radius, muscle_angles, disk_mass, gravity, base_quaternion, base_position, muscle_rest_length, inflation_rate, muscle_length_range, n_elements, tendons, max_tension, magnetization, tip_magnet, max_field, section_properties, tool_mass, tool_offset)"))
            }
        }
        Ok(())
    }
}

/// Tendon routes from a list of `{offset, twist, section}` tables (a route
/// without `section` gets `LAST_SECTION`, resolved by `Robot::from_value`).
fn tendon_routes(v: &Value) -> Result<Vec<TendonRoute>> {
    table_list(v, "tendons", &["offset", "twist", "section"], "", |t| {
        let routings = read_routings(t)?;
        Ok(TendonRoute {
            offset: routings[0].offset,
            twist: routings[0].twist,
            reroutes: routings[1..].to_vec(),
            section: match t.get("section") {
                None => LAST_SECTION,
                Some(x) => count(x, &t.key("section"), MAX_SECTIONS)?,
            },
        })
    })
}

/// Placeholder of a route read without `section`: the robot's last section,
/// set once the number of sections is known.
const LAST_SECTION: usize = usize::MAX;

/// Per-section properties from a list of `{length, stiffness,
/// linear_density, disk_mass}` tables (each key optional).
fn section_specs(v: &Value) -> Result<Vec<SectionSpec>> {
    let allowed = ["length", "stiffness", "linear_density", "disk_mass"];
    table_list(v, "section_properties", &allowed, ", one a section", |t| {
        let number = |name: &str| -> Result<Option<f64>> {
            t.get(name).map(|x| finite(x, &t.key(name))).transpose()
        };
        Ok(SectionSpec {
            length: number("length")?,
            stiffness: t
                .get("stiffness")
                .map(|k| read_stiffness(k).map_err(|e| prefixed(e, t.path())))
                .transpose()?,
            linear_density: number("linear_density")?,
            disk_mass: number("disk_mass")?,
        })
    })
}
