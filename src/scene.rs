//! The scene: what is being solved, in SI units and the conventions of docs/model.md.
//!
//! A scene is read from a [`Value`] tree (JSON, TOML or a Python dict) by one
//! validator, which refuses unknown keys, wrong shapes, non-finite numbers and
//! non-positive lengths or stiffnesses with an error that names the key.
//!
//! ```text
//! length            m
//! stiffness         {kx, ky, kz} N m^2  |  {E, G, diameter} of a round rod
//! rest_curvature    [[kappa_x, kappa_y], ...] 1/m, one per equal section
//! sections          [{length, stiffness, linear_density, distributed_moment}, ...] per section (each optional;
//!                   lengths for all sections or none: equal sections)
//! distributed_force [fx, fy, fz] N/m, world frame
//! distributed_moment [mx, my, mz] N m/m, world frame (a section's own replaces it)
//! point_loads       [{s, force, moment}, ...] m, N, N m: on nodes, world frame
//! gravity           {linear_density kg/m, vector [gx, gy, gz] m/s^2}
//! tip_force         [Px, Py, Pz] N, world frame
//! tip_moment        [Mx, My, Mz] N m, world frame
//! tip_force_offset  [x, y, z] m, the tip frame: where tip_force acts (a tool)
//! base_quaternion   [w, x, y, z], a 3x3 rotation matrix or (Python) a scipy Rotation, default identity (tangent +z)
//! base_position     [x, y, z] m, world frame, default the origin
//! obstacles         [{shape, ...}, ...] rigid obstacles (see `contact::Obstacle`)
//! ports             [{position, axis}, ...] m: points the rod slides through
//!                   without friction; axis default the base tangent
//! tip               {type: "free"}
//! name              free text
//! ```

mod plausible;
pub mod reach;
pub use plausible::{MAX_LOAD_PARAMETER, MODULUS_RANGE, ROUNDOFF_LOAD, SLENDER_LIMIT};

use crate::contact::{Obstacle, Port};
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::quat::Quat;
pub(crate) use crate::read::orientation;
use crate::read::{finite, numbers, positive, table_list, vec3, Table};
pub use crate::read::{QUATERNION_NORM_TOL, ROTATION_MATRIX_TOL};
use crate::value::Value;
use nalgebra::Vector3;
use reach::clamped_end_deficit;
use std::f64::consts::PI;

/// The key of a load parameter, written out only for a message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum LoadKey {
    Named(&'static str),
    /// `prefix[index]suffix`.
    Indexed(&'static str, usize, &'static str),
}

impl std::fmt::Display for LoadKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LoadKey::Named(key) => f.write_str(key),
            LoadKey::Indexed(prefix, i, suffix) => write!(f, "{prefix}[{i}]{suffix}"),
        }
    }
}

/// How the stiffness was given.
#[derive(Debug, Clone, PartialEq)]
pub enum Stiffness {
    /// Bending about local x, y and torsion about z [N m^2].
    Diagonal { kx: f64, ky: f64, kz: f64 },
    /// A round rod: Young's and shear moduli [Pa], diameter [m] (seed Eq. 8).
    RoundRod { e: f64, g: f64, diameter: f64 },
}

impl Stiffness {
    pub fn diagonal(&self) -> Vector3<f64> {
        match *self {
            Stiffness::Diagonal { kx, ky, kz } => Vector3::new(kx, ky, kz),
            Stiffness::RoundRod { e, g, diameter } => {
                let i = PI * diameter.powi(4) / 64.0;
                Vector3::new(e * i, e * i, 2.0 * g * i)
            }
        }
    }
}

/// Gravity acting on the rod's own mass.
#[derive(Debug, Clone, PartialEq)]
pub struct Gravity {
    /// Mass per length [kg/m].
    pub linear_density: f64,
    /// Gravitational acceleration, world frame [m/s^2].
    pub vector: Vector3<f64>,
}

/// The tip's boundary condition.
#[derive(Debug, Clone, PartialEq)]
pub enum TipCondition {
    /// Loaded by the given `tip_force` and `tip_moment`.
    Free,
    /// Held at a point by a ball joint: the tip force is an unknown reaction
    /// (an applied `tip_force` adds to it; a `tip_moment` still acts).
    Pinned { position: Vector3<f64> },
    /// Position and orientation held: force and moment are unknown reactions.
    Clamped {
        position: Vector3<f64>,
        quaternion: Quat,
    },
}

/// A dead force and moment applied at a node (a disk's weight, a hung
/// mass, a wrench at a point).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PointLoad {
    /// Arc length [m], in `(0, L]`; must fall on a node.
    pub s: f64,
    /// World frame [N].
    pub force: Vector3<f64>,
    /// World frame [N m] (a dead moment: its direction does not turn with the rod).
    pub moment: Vector3<f64>,
}

/// A frictionless tendon: pulled at the base with a constant tension, routed
/// at an offset from the backbone in the cross-section (the routing angle
/// may turn linearly along the rod: a helix; the routing may change at a
/// section's start, where the tendon crosses the disk to its new hole),
/// anchored at arc length `end`. Its potential is the tension times its path
/// length (a crossing's length is a constant of the configuration).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tendon {
    /// Tension [N], >= 0 (zero: slack).
    pub tension: f64,
    /// Offset `[x, y]` from the backbone at the base, material frame [m].
    pub offset: [f64; 2],
    /// Rate at which the routing angle turns about the backbone [rad/m]
    /// (0: straight routing).
    pub twist: f64,
    /// Where the routing changes, by increasing arc length: from `start` on
    /// (a section's start) the tendon runs at its own offset, its angle
    /// turning from there. Empty: one routing from the base to the anchor.
    pub reroutes: Vec<(f64, Routing)>,
    /// Arc length of the anchor [m], in `(0, L]`; must fall on a node.
    pub end: f64,
}

/// How a tendon runs through one stretch of the rod: its offset `[x, y]`
/// from the backbone at the stretch's start, material frame [m], and the rate
/// at which its angle turns about the backbone [rad/m].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Routing {
    pub offset: [f64; 2],
    pub twist: f64,
}

impl Tendon {
    /// The routing offset `rho(s)` and its derivative `rho'(s)`, material
    /// frame (at a change of routing, the one that starts there).
    pub fn routing(&self, s: f64) -> (Vector3<f64>, Vector3<f64>) {
        self.routing_on(s, s)
    }

    /// [`Tendon::routing`] at `s` of the stretch that runs at `stretch_at`
    /// (an element's end evaluated with the element's own routing where a
    /// change starts at that end).
    pub fn routing_on(&self, s: f64, stretch_at: f64) -> (Vector3<f64>, Vector3<f64>) {
        let stretch = self.reroutes.iter().rev().find(|(a, _)| *a <= stretch_at);
        let ([x, y], twist, from) = match stretch {
            None => (self.offset, self.twist, 0.0),
            Some((start, r)) => (r.offset, r.twist, *start),
        };
        if twist == 0.0 {
            // Straight routing, the common case: no trigonometry.
            return (Vector3::new(x, y, 0.0), Vector3::zeros());
        }
        let (sin, cos) = (twist * (s - from)).sin_cos();
        let rho = Vector3::new(cos * x - sin * y, sin * x + cos * y, 0.0);
        let drho = Vector3::new(-rho.y, rho.x, 0.0) * twist;
        (rho, drho)
    }

    /// The routings from the base: the first, then each change.
    pub fn routings(&self) -> impl Iterator<Item = Routing> + '_ {
        let first = Routing {
            offset: self.offset,
            twist: self.twist,
        };
        std::iter::once(first).chain(self.reroutes.iter().map(|(_, r)| *r))
    }

    /// Largest offset from the backbone [m]: the tendon's lever.
    pub fn largest_offset(&self) -> f64 {
        self.routings()
            .map(|r| r.offset[0].hypot(r.offset[1]))
            .fold(0.0, f64::max)
    }
}

/// A tendon's routing read from a table's `offset` (`[x, y]`, or one
/// `[x, y]` a section) and `twist` (a number, or one a section, as many as
/// the offsets).
pub(crate) fn read_routings(t: &Table) -> Result<Vec<Routing>> {
    let offset_key = t.key("offset");
    let offsets: Vec<[f64; 2]> = match t.require("offset")? {
        Value::List(items) if items.iter().all(|x| matches!(x, Value::List(_))) => {
            if items.is_empty() {
                return Err(Error::scene(offset_key, "must name at least one [x, y]"));
            }
            items
                .iter()
                .enumerate()
                .map(|(i, x)| numbers::<2>(x, &format!("{offset_key}[{i}]")))
                .collect::<Result<_>>()?
        }
        other => vec![numbers::<2>(other, &offset_key)?],
    };
    let twist_key = t.key("twist");
    let twists: Vec<f64> = match t.get("twist") {
        None => vec![0.0; offsets.len()],
        Some(Value::List(items)) => {
            if items.len() != offsets.len() {
                return Err(Error::scene(
                    twist_key,
                    format!(
                        "{} entries, but offset gives {}: one twist, or one for each offset",
                        items.len(),
                        offsets.len()
                    ),
                ));
            }
            items
                .iter()
                .enumerate()
                .map(|(i, x)| finite(x, &format!("{twist_key}[{i}]")))
                .collect::<Result<_>>()?
        }
        Some(x) => vec![finite(x, &twist_key)?; offsets.len()],
    };
    Ok(offsets
        .into_iter()
        .zip(twists)
        .map(|(offset, twist)| Routing { offset, twist })
        .collect())
}

/// The `offset` and `twist` entries of a tendon's routings: `[x, y]` and a
/// number for one routing, a list of each for one a section.
pub(crate) fn routing_values(routings: &[Routing]) -> [(String, Value); 2] {
    let pair = |o: &[f64; 2]| Value::List(vec![Value::Number(o[0]), Value::Number(o[1])]);
    match routings {
        [one] => [
            ("offset".into(), pair(&one.offset)),
            ("twist".into(), Value::Number(one.twist)),
        ],
        many => [
            (
                "offset".into(),
                Value::List(many.iter().map(|r| pair(&r.offset)).collect()),
            ),
            (
                "twist".into(),
                Value::List(many.iter().map(|r| Value::Number(r.twist)).collect()),
            ),
        ],
    }
}

/// What one of a rod's sections changes of the rod's own properties
/// (each `None`: the rod's).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SectionProperties {
    /// Length of the section [m]; given for every section or for none
    /// (`None`: the rod's sections are equal).
    pub length: Option<f64>,
    pub stiffness: Option<Stiffness>,
    /// Mass per length [kg/m] (weighs under the scene's gravity).
    pub linear_density: Option<f64>,
    /// Dead moment per length, world frame [N m / m], in place of the rod's.
    pub distributed_moment: Option<Vector3<f64>>,
}

/// A point of the backbone held at a position (a port or a ring the robot
/// passes through); the guide's force on the rod is an unknown reaction.
#[derive(Debug, Clone, PartialEq)]
pub struct Guide {
    /// Arc length of the held point [m]; must fall on a node.
    pub s: f64,
    /// World position of that point [m].
    pub position: Vector3<f64>,
}

/// A rod or robot backbone with its loads and boundary conditions.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub name: Option<String>,
    /// Length `L` [m].
    pub length: f64,
    pub stiffness_spec: Stiffness,
    /// Rest curvature `[kappa_x, kappa_y]` per section [1/m]; empty: straight.
    pub rest_curvature: Vec<[f64; 2]>,
    /// Per section, its own length, stiffness or linear density; empty: the
    /// rod's everywhere, in equal sections.
    pub sections: Vec<SectionProperties>,
    /// Distributed dead force [N/m], world frame, in addition to gravity.
    pub distributed_force: Vector3<f64>,
    /// Distributed dead moment [N m / m], world frame (a section's own
    /// replaces it there).
    pub distributed_moment: Vector3<f64>,
    pub gravity: Option<Gravity>,
    pub tip_force: Vector3<f64>,
    pub tip_moment: Vector3<f64>,
    /// Where `tip_force` acts, from the tip in its material frame [m] (a
    /// tool's weight): its moment turns with the tip.
    pub tip_force_offset: Vector3<f64>,
    /// Base orientation `Q0`, unit.
    pub base_quaternion: Quat,
    /// Base position `r_0` [m], world frame (default the origin): every node
    /// and held target is in the same world frame.
    pub base_position: Vector3<f64>,
    pub tip: TipCondition,
    /// Interior points held in place, by increasing `s`.
    pub guides: Vec<Guide>,
    /// Dead forces at nodes, in addition to the distributed and tip loads.
    pub point_loads: Vec<PointLoad>,
    /// Tendons, each with its tension (an actuation, scaled with the loads
    /// along a load path).
    pub tendons: Vec<Tendon>,
    /// Magnetisation per equal section (dipole moment per length, material
    /// frame) [A m^2 / m]; empty: none. One entry magnetises the whole rod.
    pub magnetization: Vec<Vector3<f64>>,
    /// A magnet at the tip: its dipole moment, material frame [A m^2].
    pub tip_magnet: Vector3<f64>,
    /// Uniform external magnetic field, world frame [T].
    pub magnetic_field: Vector3<f64>,
    /// Rigid obstacles the rod may touch.
    pub obstacles: Vec<Obstacle>,
    /// The Coulomb friction coefficient of each obstacle, in `obstacles`'
    /// order (`>= 0`; obstacles past its end are frictionless). With
    /// friction the answer depends on the loading history: see
    /// `solver::contact`.
    pub friction: Vec<f64>,
    /// Ports the backbone passes through and slides through without
    /// friction (a trocar, a guide tube's exit).
    pub ports: Vec<Port>,
    /// The rod's radius [m]: its surface, this far from the backbone, keeps
    /// out of the obstacles. `None`: half the diameter of a round rod's
    /// stiffness, else zero (see [`Scene::contact_radius`]).
    pub radius: Option<f64>,
}

impl Scene {
    /// A straight, unloaded rod with diagonal stiffness.
    pub fn new(length: f64, kx: f64, ky: f64, kz: f64) -> Self {
        Scene {
            name: None,
            length,
            stiffness_spec: Stiffness::Diagonal { kx, ky, kz },
            rest_curvature: Vec::new(),
            sections: Vec::new(),
            distributed_force: Vector3::zeros(),
            distributed_moment: Vector3::zeros(),
            gravity: None,
            tip_force: Vector3::zeros(),
            tip_moment: Vector3::zeros(),
            tip_force_offset: Vector3::zeros(),
            base_quaternion: Quat::IDENTITY,
            base_position: Vector3::zeros(),
            tip: TipCondition::Free,
            guides: Vec::new(),
            point_loads: Vec::new(),
            tendons: Vec::new(),
            magnetization: Vec::new(),
            tip_magnet: Vector3::zeros(),
            magnetic_field: Vector3::zeros(),
            obstacles: Vec::new(),
            friction: Vec::new(),
            ports: Vec::new(),
            radius: None,
        }
    }

    /// Whether the rod meets its surroundings: obstacles or ports, whose
    /// rows slide along it (solved by `fd2` and Newton so far).
    pub fn has_contact(&self) -> bool {
        !self.obstacles.is_empty() || !self.ports.is_empty()
    }

    /// The rod's radius for contact [m]: `radius`, else half a round rod's
    /// diameter, else zero (a line).
    pub fn contact_radius(&self) -> f64 {
        self.radius.unwrap_or(match self.stiffness_spec {
            Stiffness::RoundRod { diameter, .. } => 0.5 * diameter,
            Stiffness::Diagonal { .. } => 0.0,
        })
    }

    /// `(kx, ky, kz)` [N m^2]; with per-section stiffness, the softest
    /// section's in each component.
    pub fn stiffness(&self) -> Vector3<f64> {
        (0..self.sections.len()).fold(self.stiffness_spec.diagonal(), |k, s| {
            k.zip_map(&self.section_stiffness(s), f64::min)
        })
    }

    /// `(kx, ky, kz)` of section `s` of [`Scene::sections`] [N m^2].
    pub fn section_stiffness(&self, s: usize) -> Vector3<f64> {
        self.sections
            .get(s)
            .and_then(|p| p.stiffness.as_ref())
            .unwrap_or(&self.stiffness_spec)
            .diagonal()
    }

    /// The distributed force on section `s` [N/m], gravity on its own density included.
    pub fn section_force(&self, s: usize) -> Vector3<f64> {
        let own = self.sections.get(s).and_then(|p| p.linear_density);
        match (&self.gravity, own) {
            (Some(g), Some(density)) => self.distributed_force + density * g.vector,
            _ => self.distributed_force(),
        }
    }

    /// Section `s`'s own distributed moment [N m / m], if it gives one.
    pub fn section_moment(&self, s: usize) -> Option<Vector3<f64>> {
        self.sections.get(s).and_then(|p| p.distributed_moment)
    }

    /// Whether a distributed moment acts anywhere.
    pub fn has_distributed_moment(&self) -> bool {
        self.distributed_moment != Vector3::zeros()
            || (0..self.sections.len()).any(|s| {
                self.section_moment(s)
                    .is_some_and(|m| m != Vector3::zeros())
            })
    }

    /// Total distributed force, gravity included [N/m].
    pub fn distributed_force(&self) -> Vector3<f64> {
        let g = self
            .gravity
            .as_ref()
            .map_or(Vector3::zeros(), |g| g.linear_density * g.vector);
        self.distributed_force + g
    }

    /// Number of sections (1 for a rod without rest curvature or
    /// per-section properties).
    pub fn sections(&self) -> usize {
        self.rest_curvature.len().max(self.sections.len()).max(1)
    }

    /// What of the scene only the discrete potential models (the paper's
    /// system does not), if anything: everything of it, named.
    pub fn only_the_potential_models(&self) -> Option<String> {
        self.not_modelled(false)
    }

    /// What of the scene shooting does not model, if anything, named
    /// (moments and a tip force off the tip it does).
    pub fn beyond_shooting(&self) -> Option<String> {
        self.not_modelled(true)
    }

    /// What of the scene the paper's system (`shooting` false) or shooting
    /// does not model.
    fn not_modelled(&self, shooting: bool) -> Option<String> {
        let magnetic = !self.magnetization.is_empty() || self.tip_magnet != Vector3::zeros();
        let present = [
            (!shooting && !self.tendons.is_empty(), "tendons"),
            (!shooting && magnetic, "magnetic actuation"),
            (
                !shooting && !self.sections.is_empty(),
                "sections with their own length, stiffness or density",
            ),
            (
                !shooting && self.tip_force_offset != Vector3::zeros(),
                "a tip force off the tip (tip_force_offset)",
            ),
            (!self.obstacles.is_empty(), "contact with obstacles"),
            (!self.ports.is_empty(), "sliding ports"),
            (
                !shooting
                    && (self.has_distributed_moment()
                        || self
                            .point_loads
                            .iter()
                            .any(|p| p.moment != Vector3::zeros())),
                "point or distributed moments",
            ),
        ]
        .into_iter()
        .filter_map(|(present, what)| present.then_some(what))
        .collect::<Vec<_>>();
        (!present.is_empty()).then(|| present.join(", nor "))
    }

    /// The sections' own lengths [m]; empty when the sections are equal.
    pub fn section_lengths(&self) -> Vec<f64> {
        self.sections.iter().filter_map(|p| p.length).collect()
    }

    /// Where the nodes of `n` elements sit: `n / sections` equal elements in
    /// each section (see [`Mesh`]).
    pub fn mesh(&self, n: usize) -> Mesh {
        Mesh::new(self.length, &self.section_lengths(), n)
    }

    /// Read a scene from JSON text (duplicate keys refused, see [`Value::from_json_str`]).
    pub fn from_json_str(text: &str) -> Result<Self> {
        Scene::from_value(&Value::from_json_str(text)?)
    }

    pub fn from_toml_str(text: &str) -> Result<Self> {
        Scene::from_value(&Value::from_toml_str(text)?)
    }

    /// The scene as JSON or TOML text (`from_json_str` / `from_toml_str`
    /// of it is the same scene).
    pub fn to_text(&self, format: crate::value::Format) -> Result<String> {
        self.to_value().to_text(format)
    }

    /// Write the scene to a `.json` or `.toml` file (by its extension),
    /// which `from_file` reads back to the same scene.
    pub fn write_file(&self, path: &std::path::Path) -> Result<()> {
        self.to_value().write_file(path)
    }

    /// Read a `.json` or `.toml` file.
    pub fn from_file(path: &std::path::Path) -> Result<Self> {
        let mut value = Value::from_file(path)?;
        if let Some(dir) = path.parent() {
            crate::contact::files_beside(&mut value, dir);
        }
        Scene::from_value(&value)
    }

    /// Validate and build a scene from a value tree.
    pub fn from_value(v: &Value) -> Result<Self> {
        let top = Table::top(v, "scene")?;
        top.only(&[
            "name",
            "length",
            "stiffness",
            "rest_curvature",
            "sections",
            "distributed_force",
            "distributed_moment",
            "gravity",
            "tip_force",
            "tip_moment",
            "tip_force_offset",
            "base_quaternion",
            "base_position",
            "tip",
            "guides",
            "point_loads",
            "tendons",
            "magnetization",
            "tip_magnet",
            "magnetic_field",
            "obstacles",
            "ports",
            "radius",
        ])?;
        let name = match top.get("name") {
            None => None,
            Some(Value::String(s)) => Some(s.clone()),
            Some(other) => {
                return Err(Error::scene(
                    "name",
                    format!("expected a string, got {}", other.kind()),
                ))
            }
        };
        let stiffness_spec = read_stiffness(top.require("stiffness")?)?;
        let rest_curvature = match top.get("rest_curvature") {
            None => Vec::new(),
            Some(v) => rest_curvature(v)?,
        };
        let vec3_or_zero = |key: &str| top.get(key).map_or(Ok(Vector3::zeros()), |v| vec3(v, key));
        let gravity = match top.get("gravity") {
            None => None,
            Some(v) => Some(gravity(v)?),
        };
        let sections = match top.get("sections") {
            None => Vec::new(),
            Some(v) => section_properties(v, gravity.is_some())?,
        };
        let length = rod_length(top.get("length"), &sections)?;
        if !sections.is_empty()
            && !rest_curvature.is_empty()
            && sections.len() != rest_curvature.len()
        {
            return Err(Error::scene(
                "sections",
                format!(
                    "{} sections, but rest_curvature has {}: one entry a section in both",
                    sections.len(),
                    rest_curvature.len()
                ),
            ));
        }
        let base_quaternion = match top.get("base_quaternion") {
            None => Quat::IDENTITY,
            Some(v) => orientation(v, "base_quaternion")?,
        };
        let tip = match top.get("tip") {
            None => TipCondition::Free,
            Some(v) => tip(v)?,
        };
        let guides = match top.get("guides") {
            None => Vec::new(),
            Some(v) => guides(v)?,
        };
        let point_loads = match top.get("point_loads") {
            None => Vec::new(),
            Some(v) => point_loads(v, "point_loads")?,
        };
        let section_starts: Vec<f64> = {
            let count = rest_curvature.len().max(sections.len()).max(1);
            let lengths: Vec<f64> = sections.iter().filter_map(|p| p.length).collect();
            match lengths.is_empty() {
                true => (0..count)
                    .map(|k| length * k as f64 / count as f64)
                    .collect(),
                false => std::iter::once(0.0)
                    .chain(lengths.iter().scan(0.0, |a, l| {
                        *a += l;
                        Some(*a)
                    }))
                    .take(count)
                    .collect(),
            }
        };
        let tendons = match top.get("tendons") {
            None => Vec::new(),
            Some(v) => tendons(v, length, &section_starts)?,
        };
        let magnetization: Vec<Vector3<f64>> = match top.get("magnetization") {
            None => Vec::new(),
            Some(Value::List(items)) if items.iter().all(|x| matches!(x, Value::List(_))) => items
                .iter()
                .enumerate()
                .map(|(i, x)| vec3(x, &format!("magnetization[{i}]")))
                .collect::<Result<_>>()?,
            Some(v) => vec![vec3(v, "magnetization")?],
        };
        let scene = Scene {
            name,
            length,
            stiffness_spec,
            rest_curvature,
            sections,
            distributed_force: vec3_or_zero("distributed_force")?,
            distributed_moment: vec3_or_zero("distributed_moment")?,
            gravity,
            tip_force: vec3_or_zero("tip_force")?,
            tip_moment: vec3_or_zero("tip_moment")?,
            tip_force_offset: vec3_or_zero("tip_force_offset")?,
            base_quaternion,
            base_position: vec3_or_zero("base_position")?,
            tip,
            guides,
            point_loads,
            tendons,
            magnetization,
            tip_magnet: vec3_or_zero("tip_magnet")?,
            magnetic_field: vec3_or_zero("magnetic_field")?,
            obstacles: match top.get("obstacles") {
                None => Vec::new(),
                Some(v) => obstacles(v)?,
            },
            friction: match top.get("obstacles") {
                None => Vec::new(),
                Some(v) => obstacle_friction(v)?,
            },
            ports: match top.get("ports") {
                None => Vec::new(),
                Some(v) => ports(v, base_quaternion.rotate(Vector3::z()))?,
            },
            radius: match top.get("radius") {
                None => None,
                Some(v) => Some(non_negative_length(v, "radius")?),
            },
        };
        scene.check_section_lengths()?;
        scene.check_derived()?;
        Ok(scene)
    }

    /// Refuse a scene whose derived quantities overflow or underflow: the
    /// stiffness from `E`, `G` and the diameter, and the dimensionless load
    /// parameters (`|f| L^3 / k`, `|P| L^2 / k`, `|M| L / k`, `L |kappa0|`)
    /// that the solver works with. Each must be finite, the stiffness nonzero.
    pub fn check_derived(&self) -> Result<()> {
        if self.friction.len() > self.obstacles.len() {
            return Err(Error::scene(
                "friction",
                format!(
                    "{} coefficients for {} obstacles",
                    self.friction.len(),
                    self.obstacles.len()
                ),
            ));
        }
        for (i, mu) in self.friction.iter().enumerate() {
            check_friction(*mu, &format!("obstacles[{i}].friction"))?;
        }
        for (s, p) in self.sections.iter().enumerate() {
            let k = self.section_stiffness(s);
            if p.stiffness.is_some() && !k.iter().all(|v| v.is_finite() && *v >= f64::MIN_POSITIVE)
            {
                return Err(Error::scene(
                    format!("sections[{s}].stiffness"),
                    format!(
                        "(kx, ky, kz) = ({:e}, {:e}, {:e}) N m^2 overflows or underflows",
                        k.x, k.y, k.z
                    ),
                ));
            }
        }
        let k = self.stiffness();
        let stiffness_key = match self.stiffness_spec {
            Stiffness::Diagonal { .. } => "stiffness",
            Stiffness::RoundRod { .. } => "stiffness (from E, G and diameter)",
        };
        if !k.iter().all(|v| v.is_finite() && *v >= f64::MIN_POSITIVE) {
            return Err(Error::scene(
                stiffness_key,
                format!(
                    "(kx, ky, kz) = ({:e}, {:e}, {:e}) N m^2 overflows or underflows",
                    k.x, k.y, k.z
                ),
            ));
        }
        if !((k.max() / self.length).is_finite() && k.min() / self.length > 0.0) {
            return Err(Error::scene(
                stiffness_key,
                format!(
                    "the stiffness over the length overflows or underflows (length {:e} m, \
                     stiffness {:e} to {:e} N m^2)",
                    self.length,
                    k.min(),
                    k.max()
                ),
            ));
        }
        self.check_plausible()?;
        for (key, what, value) in self.load_parameters() {
            self.check_load(|| key.to_string(), what, value)?;
        }
        // No load: a rest shape too coiled for any n is underresolved, not refused.
        for (i, kappa) in self.rest_curvature.iter().enumerate() {
            let value = kappa[0].hypot(kappa[1]) * self.length;
            if !value.is_finite() {
                return Err(Error::scene(
                    format!("rest_curvature[{i}]"),
                    format!(
                        "L |kappa0| = {value:e} overflows (length {:e} m)",
                        self.length
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Every load's dimensionless parameter, by key (named only when a
    /// message needs it: the check runs at every solver's start): its bending moment over
    /// the softest stiffness and the length (the curvature scale `kappa L` it
    /// alone gives the rod), with its formula.
    fn load_parameters(&self) -> Vec<(LoadKey, &'static str, f64)> {
        let (l, k_min) = (self.length, self.stiffness().min());
        let f = (0..self.sections())
            .map(|k| self.section_force(k).norm())
            .fold(self.distributed_force().norm(), f64::max);
        let force_key = match self.gravity.is_some() {
            true => "gravity",
            false => "distributed_force",
        };
        let mut out = vec![
            (
                LoadKey::Named(force_key),
                "|f| L^3 / k",
                f * l / k_min * l * l,
            ),
            (
                LoadKey::Named("tip_force"),
                "|P| L^2 / k",
                self.tip_force.norm() * l / k_min * l,
            ),
            (
                LoadKey::Named("tip_moment"),
                "|M| L / k",
                self.tip_moment.norm() * l / k_min,
            ),
            (
                LoadKey::Named("tip_force_offset"),
                "|F| |c| L / k",
                self.tip_force.norm() * self.tip_force_offset.norm() * l / k_min,
            ),
        ];
        for (i, p) in self.point_loads.iter().enumerate() {
            let value = p.force.norm() * l / k_min * l;
            out.push((
                LoadKey::Indexed("point_loads", i, ".force"),
                "|F| L^2 / k",
                value,
            ));
            let value = p.moment.norm() * l / k_min;
            out.push((
                LoadKey::Indexed("point_loads", i, ".moment"),
                "|M| L / k",
                value,
            ));
        }
        let m = (0..self.sections.len())
            .filter_map(|s| self.section_moment(s))
            .map(|m| m.norm())
            .fold(self.distributed_moment.norm(), f64::max);
        out.push((
            LoadKey::Named("distributed_moment"),
            "|m| L^2 / k",
            m * l / k_min * l,
        ));
        out.extend(self.field_load_parameters(self.magnetic_field));
        let tensions: Vec<f64> = self.tendons.iter().map(|t| t.tension).collect();
        out.extend(self.tension_load_parameters(&tensions));
        out
    }

    /// Refuse a load parameter that overflows, or one so large that no
    /// solve resolves it (the likely unit mistake said), naming `key` (the
    /// scene's stiffness and length are valid).
    fn check_load(&self, key: impl FnOnce() -> String, what: &str, value: f64) -> Result<()> {
        let (l, k_min) = (self.length, self.stiffness().min());
        if !value.is_finite() {
            return Err(Error::scene(
                key(),
                format!("the load parameter {what} = {value:e} overflows (length {l:e} m, smallest stiffness {k_min:e} N m^2)"),
            ));
        }
        if value > MAX_LOAD_PARAMETER {
            return Err(Error::scene(
                key(),
                format!(
                    "the load parameter {what} = {value:.1e} is beyond what any solve resolves \
                     (a curvature scale kappa L above {MAX_LOAD_PARAMETER:.0e}; length {l:e} m, \
                     smallest stiffness {k_min:e} N m^2): check the units (SI: Pa, m, kg, N; E \
                     in GPa or a diameter in mm is a factor 1e9 or 1e12 off)"
                ),
            ));
        }
        Ok(())
    }

    /// The field's load parameters (on the magnetisation and the tip
    /// magnet) at `field`, without changing the scene.
    pub(crate) fn check_field_load(&self, field: Vector3<f64>) -> Result<()> {
        for (key, what, value) in self.field_load_parameters(field) {
            self.check_load(|| key.to_string(), what, value)?;
        }
        Ok(())
    }

    /// The field's load parameters at `field` (see [`Scene::load_parameters`]).
    fn field_load_parameters(&self, field: Vector3<f64>) -> Vec<(LoadKey, &'static str, f64)> {
        let (l, k_min, b) = (self.length, self.stiffness().min(), field.norm());
        let mut out: Vec<_> = self
            .magnetization
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let value = m.norm() * b * l / k_min * l;
                (
                    LoadKey::Indexed("magnetization", i, ""),
                    "|m| |B| L^2 / k",
                    value,
                )
            })
            .collect();
        let value = self.tip_magnet.norm() * b * l / k_min;
        out.push((LoadKey::Named("tip_magnet"), "|mu| |B| L / k", value));
        out
    }

    /// The tendons' load parameters at `tensions` (one a tendon), without
    /// changing the scene.
    pub(crate) fn check_tension_load(&self, tensions: &[f64]) -> Result<()> {
        for (key, what, value) in self.tension_load_parameters(tensions) {
            self.check_load(|| key.to_string(), what, value)?;
        }
        Ok(())
    }

    /// The tendons' load parameters at `tensions` (see [`Scene::load_parameters`]).
    fn tension_load_parameters(&self, tensions: &[f64]) -> Vec<(LoadKey, &'static str, f64)> {
        let (l, k_min) = (self.length, self.stiffness().min());
        self.tendons
            .iter()
            .zip(tensions)
            .enumerate()
            .map(|(i, (t, tension))| {
                let value = tension * t.largest_offset() * l / k_min;
                (
                    LoadKey::Indexed("tendons", i, ".tension"),
                    "|tension| |offset| L / k",
                    value,
                )
            })
            .collect()
    }

    /// The scene as a value tree (the inverse of [`Scene::from_value`]).
    pub fn to_value(&self) -> Value {
        let num = Value::Number;
        let v3 = |v: &Vector3<f64>| Value::List(v.iter().map(|x| Value::Number(*x)).collect());
        let mut m: Vec<(String, Value)> = Vec::new();
        if let Some(n) = &self.name {
            m.push(("name".into(), Value::String(n.clone())));
        }
        m.push(("length".into(), num(self.length)));
        m.push(("stiffness".into(), stiffness_value(&self.stiffness_spec)));
        if !self.sections.is_empty() {
            let sections = self
                .sections
                .iter()
                .map(|p| {
                    let mut entries =
                        section_entries(p.length, p.stiffness.as_ref(), p.linear_density);
                    if let Some(moment) = &p.distributed_moment {
                        entries.push(("distributed_moment".into(), v3(moment)));
                    }
                    Value::Map(entries)
                })
                .collect();
            m.push(("sections".into(), Value::List(sections)));
        }
        if !self.rest_curvature.is_empty() {
            let rc = self
                .rest_curvature
                .iter()
                .map(|k| Value::List(vec![num(k[0]), num(k[1])]))
                .collect();
            m.push(("rest_curvature".into(), Value::List(rc)));
        }
        m.push(("distributed_force".into(), v3(&self.distributed_force)));
        if self.distributed_moment != Vector3::zeros() {
            m.push(("distributed_moment".into(), v3(&self.distributed_moment)));
        }
        if let Some(g) = &self.gravity {
            m.push((
                "gravity".into(),
                Value::Map(vec![
                    ("linear_density".into(), num(g.linear_density)),
                    ("vector".into(), v3(&g.vector)),
                ]),
            ));
        }
        m.push(("tip_force".into(), v3(&self.tip_force)));
        m.push(("tip_moment".into(), v3(&self.tip_moment)));
        let q = self.base_quaternion.to_array();
        m.push((
            "base_quaternion".into(),
            Value::List(q.iter().map(|x| num(*x)).collect()),
        ));
        if self.base_position != Vector3::zeros() {
            m.push(("base_position".into(), v3(&self.base_position)));
        }
        let q4 = |q: &Quat| Value::List(q.to_array().iter().map(|x| num(*x)).collect());
        let kind = |k: &str| ("type".to_string(), Value::String(k.into()));
        let tip = match &self.tip {
            TipCondition::Free => vec![kind("free")],
            TipCondition::Pinned { position } => {
                vec![kind("pinned"), ("position".into(), v3(position))]
            }
            TipCondition::Clamped {
                position,
                quaternion,
            } => vec![
                kind("clamped"),
                ("position".into(), v3(position)),
                ("quaternion".into(), q4(quaternion)),
            ],
        };
        m.push(("tip".into(), Value::Map(tip)));
        if !self.guides.is_empty() {
            let g = self
                .guides
                .iter()
                .map(|g| {
                    Value::Map(vec![
                        ("s".into(), num(g.s)),
                        ("position".into(), v3(&g.position)),
                    ])
                })
                .collect();
            m.push(("guides".into(), Value::List(g)));
        }
        if !self.magnetization.is_empty() {
            m.push((
                "magnetization".into(),
                Value::List(self.magnetization.iter().map(v3).collect()),
            ));
        }
        if self.tip_force_offset != Vector3::zeros() {
            m.push(("tip_force_offset".into(), v3(&self.tip_force_offset)));
        }
        if self.tip_magnet != Vector3::zeros() {
            m.push(("tip_magnet".into(), v3(&self.tip_magnet)));
        }
        if !self.obstacles.is_empty() {
            m.push((
                "obstacles".into(),
                obstacles_value(&self.obstacles, &self.friction),
            ));
        }
        if !self.ports.is_empty() {
            let list = self.ports.iter().map(Port::to_value).collect();
            m.push(("ports".into(), Value::List(list)));
        }
        if let Some(radius) = self.radius {
            m.push(("radius".into(), num(radius)));
        }
        if self.magnetic_field != Vector3::zeros() {
            m.push(("magnetic_field".into(), v3(&self.magnetic_field)));
        }
        if !self.tendons.is_empty() {
            let t = self
                .tendons
                .iter()
                .map(|t| {
                    let routings: Vec<Routing> = t.routings().collect();
                    let [offset, twist] = routing_values(&routings);
                    Value::Map(vec![
                        ("tension".into(), num(t.tension)),
                        offset,
                        twist,
                        ("end".into(), num(t.end)),
                    ])
                })
                .collect();
            m.push(("tendons".into(), Value::List(t)));
        }
        if !self.point_loads.is_empty() {
            let p = self
                .point_loads
                .iter()
                .map(|p| {
                    let mut entries = vec![("s".into(), num(p.s)), ("force".into(), v3(&p.force))];
                    if p.moment != Vector3::zeros() {
                        entries.push(("moment".into(), v3(&p.moment)));
                    }
                    Value::Map(entries)
                })
                .collect();
            m.push(("point_loads".into(), Value::List(p)));
        }
        Value::Map(m)
    }

    /// Sections of their own lengths (as the reader checks them, for a scene
    /// built in Rust or changed since): every section or none given one,
    /// positive and finite, adding up to `length`, and the rest curvature
    /// and magnetisation one a section (or one for all).
    fn check_section_lengths(&self) -> Result<()> {
        let lengths = self.section_lengths();
        if lengths.is_empty() {
            return Ok(());
        }
        let given: Vec<Option<f64>> = self.sections.iter().map(|p| p.length).collect();
        check_lengths_add_up(&given, self.length, "sections")?;
        let k = lengths.len();
        for (key, count, one_allowed) in [
            ("rest_curvature", self.rest_curvature.len(), false),
            ("magnetization", self.magnetization.len(), true),
        ] {
            if count > 0 && count != k && !(one_allowed && count == 1) {
                return Err(Error::scene(
                    key,
                    format!("{count} entries, but the rod has {k} sections of their own lengths"),
                ));
            }
        }
        Ok(())
    }

    /// The inputs that sit at an arc length on the rod (each on a node of
    /// the mesh), by their key: point loads, tendon anchors, guides.
    pub(crate) fn located_inputs(&self) -> Vec<(String, f64)> {
        let loads = self.point_loads.iter().enumerate();
        let loads = loads.map(|(i, p)| (format!("point_loads[{i}].s"), p.s));
        let anchors = self.tendons.iter().enumerate();
        let anchors = anchors.map(|(i, t)| (format!("tendons[{i}].end"), t.end));
        let guides = self.guides.iter().enumerate();
        let guides = guides.map(|(i, g)| (format!("guides[{i}].s"), g.s));
        loads.chain(anchors).chain(guides).collect()
    }

    /// The element counts this scene can be solved with: every multiple of
    /// the count returned is a multiple of the sections and of the
    /// magnetised sections that puts every point load, tendon anchor and
    /// guide on a node ([`Scene::check_elements`] accepts it). A located
    /// input on a node of no count up to `limit` is refused by its key.
    pub fn node_multiple(&self, limit: usize) -> Result<usize> {
        let lengths = self.section_lengths();
        let m = self.sections();
        let mut multiple = crate::mesh::lcm(m, self.magnetization.len().max(1));
        for (key, s) in self.located_inputs() {
            let counts = crate::mesh::counts_with_node(self.length, &lengths, m, s, limit);
            multiple = counts
                .map(|c| crate::mesh::lcm(multiple, c))
                .filter(|g| *g <= limit)
                .ok_or_else(|| {
                    Error::scene(
                        key,
                        format!(
                            "must fall on a node: s = {s} and the other located inputs fall on \
                             the nodes of no n up to {limit}"
                        ),
                    )
                })?;
        }
        Ok(multiple)
    }

    /// Check a discretisation: `n` a positive multiple of the number of sections.
    pub fn check_elements(&self, n: usize) -> Result<()> {
        self.check_section_lengths()?;
        let m = self.sections();
        if n == 0 || n % m != 0 {
            return Err(Error::argument(
                "n_elements",
                format!("must be a positive multiple of the number of sections ({m}), got {n}"),
            ));
        }
        let mesh = self.mesh(n);
        for (i, p) in self.point_loads.iter().enumerate() {
            let key = format!("point_loads[{i}].s");
            if !in_rod(p.s, self.length) {
                return Err(Error::scene(
                    key,
                    format!("must lie in (0, L] = (0, {}], got {}", self.length, p.s),
                ));
            }
            check_on_node(&key, p.s, &mesh)?;
        }
        for (i, t) in self.tendons.iter().enumerate() {
            check_on_node(&format!("tendons[{i}].end"), t.end, &mesh)?;
        }
        let k = self.magnetization.len();
        if k > 0 && n % k != 0 {
            return Err(Error::argument(
                "n_elements",
                format!("must be a multiple of the magnetised sections ({k}), got {n}"),
            ));
        }
        Ok(())
    }
}

impl Scene {
    /// Check the held points against a discretisation of `n` elements: guides
    /// inside the rod, on nodes, in order; every target within reach of the
    /// previous held point (base included); a clamped tip without applied tip
    /// loads. Returns why a valid scene cannot be solved at this `n`: a target
    /// at full reach (only the straight rod reaches it: the reaction is
    /// indeterminate or unbounded), or beyond what the discrete rod reaches.
    pub fn check_constraints(&self, n: usize) -> Result<Option<ReachLimit>> {
        let mesh = self.mesh(n);
        if let TipCondition::Clamped { .. } = self.tip {
            if self.tip_force.norm() > 0.0 || self.tip_moment.norm() > 0.0 {
                return Err(Error::scene(
                    "tip",
                    "a clamped tip has prescribed position and orientation, so its force and moment \
                     are reactions: remove tip_force and tip_moment (prescribing all three \
                     over-determines an inextensible rod)",
                ));
            }
        }
        let mut previous = 0.0;
        for (i, g) in self.guides.iter().enumerate() {
            let key = format!("guides[{i}].s");
            if !(g.s > 0.0 && g.s < self.length) {
                return Err(Error::scene(
                    key,
                    format!(
                        "must lie inside (0, L) = (0, {}), got {} (the base is clamped; hold the tip with tip.type)",
                        self.length, g.s
                    ),
                ));
            }
            check_on_node(&key, g.s, &mesh)?;
            if i > 0 && g.s <= previous {
                return Err(Error::scene(key, "guides must be given by increasing s"));
            }
            previous = g.s;
        }
        // A held point inside an obstacle: no contact acts at a held node
        // (its reaction carries what the obstacle would), so the rod would
        // be held through it.
        let radius = self.contact_radius();
        for (key, _, position) in self.held_points() {
            for (o, obstacle) in self.obstacles.iter().enumerate() {
                let depth = radius - obstacle.proximity(&position).gap;
                if depth > HELD_INSIDE * self.length {
                    return Err(Error::scene(
                        key,
                        format!(
                            "lies inside obstacles[{o}] by {depth:.3e} m (the rod's surface \
                             there): the rod would be held through the obstacle"
                        ),
                    ));
                }
            }
        }
        let spans = self.held_spans(n)?;
        let limit = spans.into_iter().find_map(|span| {
            let HeldSpan {
                key,
                arc,
                distance,
                reach,
            } = span;
            if distance >= arc * (1.0 - FULL_REACH_BAND) {
                Some(ReachLimit::FullReach(format!(
                    "{key} is within {FULL_REACH_BAND:e} of full reach ({distance} m of {arc} m of \
                     rod): only a nearly straight rod reaches it, and its reaction (which grows \
                     without bound as the gap closes) is not determined to any useful accuracy"
                )))
            } else if distance >= reach - arc * FULL_REACH_BAND {
                let (gap, deficit) = (arc - distance, arc - reach);
                let needed = (n as f64 * deficit / gap).ceil();
                Some(ReachLimit::BeyondDiscreteReach(format!(
                    "{key} is {distance} m from the previous held point (or the base), beyond \
                     the {reach} m that the rod discretised by {n} elements reaches in that \
                     direction (its clamped end cannot straighten within an element; the \
                     continuous rod reaches {arc} m): use more than {needed} elements"
                )))
            } else {
                None
            }
        });
        Ok(limit)
    }

    /// The smallest slack of a held point to what the rod of `n` elements
    /// reaches, over the rod between it and the previous held point: 1 for a
    /// free tip, 0 at the discrete reach (see [`Scene::check_constraints`]).
    /// A valid scene's held points only; invalid ones count as no slack.
    pub fn reach_slack(&self, n: usize) -> f64 {
        match self.held_spans(n) {
            Ok(spans) => spans
                .iter()
                .map(|h| (h.reach - h.distance) / h.arc)
                .fold(1.0, f64::min),
            Err(_) => 0.0,
        }
    }

    /// The held points `(key of the position, s, position)`: the guides, then
    /// a pinned or clamped tip.
    fn held_points(&self) -> Vec<(String, f64, Vector3<f64>)> {
        let mut held: Vec<_> = self
            .guides
            .iter()
            .enumerate()
            .map(|(i, g)| (format!("guides[{i}].position"), g.s, g.position))
            .collect();
        if let TipCondition::Pinned { position } | TipCondition::Clamped { position, .. } =
            &self.tip
        {
            held.push(("tip.position".into(), self.length, *position));
        }
        held
    }

    /// The spans between consecutive [held points](Scene::held_points) (the
    /// base first), each with what the rod of `n` elements reaches along it.
    /// A clamped end (the base before the first held point, a clamped tip
    /// after the last) keeps the discrete rod from straightening at once:
    /// its reach falls short of the arc.
    fn held_spans(&self, n: usize) -> Result<Vec<HeldSpan>> {
        let mesh = self.mesh(n);
        let held = self.held_points();
        let held_count = held.len();
        let mut from = (0.0, self.base_position);
        let mut spans = Vec::with_capacity(held_count);
        for (index, (key, s, p)) in held.into_iter().enumerate() {
            let (arc, chord) = (s - from.0, p - from.1);
            let distance = chord.norm();
            if distance > arc * (1.0 + 1e-12) {
                return Err(Error::scene(
                    key,
                    format!(
                        "unreachable: {distance:.6} m from the previous held point (or the base), \
                         farther than the {arc:.6} m of rod between them"
                    ),
                ));
            }
            let (first, last) = (mesh.nearest_node(from.0), mesh.nearest_node(s));
            let elements = last.saturating_sub(first).max(1);
            let h = mesh.element_lengths();
            // The deficit is in units of the clamped end's element.
            let (base_h, tip_h) = (h[first.min(h.len() - 1)], h[last.max(1) - 1]);
            let angle_to = |tangent: Vector3<f64>| tangent.angle(&chord).min(PI);
            let mut deficit = 0.0f64;
            if index == 0 {
                let base_tangent = self.base_quaternion.rotate(Vector3::z());
                deficit = base_h * clamped_end_deficit(angle_to(base_tangent), elements);
            }
            if let (true, TipCondition::Clamped { quaternion, .. }) =
                (index + 1 == held_count, &self.tip)
            {
                let tip_tangent = quaternion.rotate(Vector3::z());
                deficit = deficit.max(tip_h * clamped_end_deficit(angle_to(tip_tangent), elements));
            }
            spans.push(HeldSpan {
                key,
                arc,
                distance,
                reach: arc - deficit,
            });
            from = (s, p);
        }
        Ok(spans)
    }
}

/// The rod between two consecutive held points (the base first).
struct HeldSpan {
    /// The key of the later held point's position.
    key: String,
    /// Rod between the two [m].
    arc: f64,
    /// Straight distance between the two [m].
    distance: f64,
    /// What the discrete rod reaches in that direction [m].
    reach: f64,
}

/// Why a valid scene with held points is not solved at a given `n`.
#[derive(Debug, Clone, PartialEq)]
pub enum ReachLimit {
    /// A held point within [`FULL_REACH_BAND`] of full reach: its reaction is
    /// indeterminate (the solve's status is `Indeterminate`).
    FullReach(String),
    /// A held point beyond the reach of the discrete rod, which a finer
    /// discretisation may reach (status `Underresolved`).
    BeyondDiscreteReach(String),
}

/// Relative gap to full reach under which a held point is refused as
/// indeterminate. Closer than this, the reaction of an inextensible rod is
/// ill-conditioned without bound, and a miss within the residual tolerance
/// (1e-10 L) is as large as the gap itself: the straight rod would pass as
/// "converged" with a reaction of 0.
pub const FULL_REACH_BAND: f64 = 1e-8;

/// How deep (of the length) a held point may lie inside an obstacle's
/// offset surface: round-off of a point given on it.
const HELD_INSIDE: f64 = 1e-9;

pub(crate) fn read_stiffness(v: &Value) -> Result<Stiffness> {
    let t = Table::new(v, "stiffness")?;
    t.only(&["kx", "ky", "kz", "E", "G", "diameter"])?;
    let diagonal = ["kx", "ky", "kz"].iter().any(|k| t.get(k).is_some());
    let round = ["E", "G", "diameter"].iter().any(|k| t.get(k).is_some());
    match (diagonal, round) {
        (true, false) => Ok(Stiffness::Diagonal {
            kx: t.positive("kx")?,
            ky: t.positive("ky")?,
            kz: t.positive("kz")?,
        }),
        (false, true) => {
            if t.get("G").is_none() {
                // The shear modulus is the one a user most often lacks.
                return Err(Error::scene(
                    t.key("G"),
                    "missing: the shear modulus [Pa] of the round rod {E, G, diameter} \
                     (isotropic: G = E / (2 (1 + nu)), E / 3 for a rubber with nu = 0.5); \
                     or give the stiffnesses {kx, ky, kz} [N m^2] instead",
                ));
            }
            Ok(Stiffness::RoundRod {
                e: t.positive("E")?,
                g: t.positive("G")?,
                diameter: t.positive("diameter")?,
            })
        }
        (true, true) => Err(Error::scene(
            "stiffness",
            "give either {kx, ky, kz} or {E, G, diameter}, not both",
        )),
        (false, false) => Err(Error::scene(
            "stiffness",
            "expected {kx, ky, kz} or {E, G, diameter}",
        )),
    }
}

/// The given entries of a section's table: `length`, `stiffness`,
/// `linear_density` (a robot's section adds its `disk_mass`).
pub(crate) fn section_entries(
    length: Option<f64>,
    stiffness: Option<&Stiffness>,
    linear_density: Option<f64>,
) -> Vec<(String, Value)> {
    let mut entries = Vec::new();
    if let Some(l) = length {
        entries.push(("length".to_string(), Value::Number(l)));
    }
    if let Some(k) = stiffness {
        entries.push(("stiffness".to_string(), stiffness_value(k)));
    }
    if let Some(d) = linear_density {
        entries.push(("linear_density".to_string(), Value::Number(d)));
    }
    entries
}

/// A stiffness as the table it is read from.
pub(crate) fn stiffness_value(k: &Stiffness) -> Value {
    let entries = match *k {
        Stiffness::Diagonal { kx, ky, kz } => vec![("kx", kx), ("ky", ky), ("kz", kz)],
        Stiffness::RoundRod { e, g, diameter } => {
            vec![("E", e), ("G", g), ("diameter", diameter)]
        }
    };
    Value::Map(
        entries
            .into_iter()
            .map(|(k, x)| (k.to_string(), Value::Number(x)))
            .collect(),
    )
}

/// Section lengths `given` under the list `key`: for every section or none,
/// positive and finite, adding up to the rod's `length`.
pub(crate) fn check_lengths_add_up(given: &[Option<f64>], length: f64, key: &str) -> Result<()> {
    if given.iter().all(Option::is_none) {
        return Ok(());
    }
    if let Some(i) = given
        .iter()
        .position(|l| !l.is_some_and(|l| l.is_finite() && l > 0.0))
    {
        return Err(Error::scene(
            format!("{key}[{i}].length"),
            "missing or not positive: give every section its length, or none (equal sections)",
        ));
    }
    let total: f64 = given.iter().flatten().sum();
    if (total - length).abs() > 1e-9 * length {
        return Err(Error::scene(
            "length",
            format!("{length} m, but the sections' lengths add up to {total} m"),
        ));
    }
    Ok(())
}

/// The rod's length: the `length` key, or else the sum of the sections'
/// lengths (checked with the scene: `Scene::check_section_lengths`).
fn rod_length(key: Option<&Value>, sections: &[SectionProperties]) -> Result<f64> {
    match key {
        Some(v) => positive(v, "length"),
        None if sections.iter().any(|p| p.length.is_some()) => {
            Ok(sections.iter().filter_map(|p| p.length).sum())
        }
        None => Err(Error::scene("length", "missing")),
    }
}

/// Per-section properties: a list of `{length, stiffness, linear_density}`
/// tables (each key optional; a density weighs only under the scene's gravity).
fn section_properties(v: &Value, has_gravity: bool) -> Result<Vec<SectionProperties>> {
    let allowed = [
        "length",
        "stiffness",
        "linear_density",
        "distributed_moment",
    ];
    table_list(v, "sections", &allowed, ", one a section", |t| {
        let length = t
            .get("length")
            .map(|x| positive(x, &t.key("length")))
            .transpose()?;
        let stiffness = t
            .get("stiffness")
            .map(|k| read_stiffness(k).map_err(|e| prefixed(e, t.path())))
            .transpose()?;
        let linear_density = match t.get("linear_density") {
            None => None,
            Some(x) => {
                let d = finite(x, &t.key("linear_density"))?;
                if d < 0.0 {
                    return Err(Error::scene(
                        t.key("linear_density"),
                        format!("must not be negative, got {d}"),
                    ));
                }
                if !has_gravity {
                    return Err(Error::scene(
                        t.key("linear_density"),
                        "weighs only under gravity: give the scene's gravity (its vector)",
                    ));
                }
                Some(d)
            }
        };
        let distributed_moment = t
            .get("distributed_moment")
            .map(|m| vec3(m, &t.key("distributed_moment")))
            .transpose()?;
        Ok(SectionProperties {
            length,
            stiffness,
            linear_density,
            distributed_moment,
        })
    })
}

/// An error of a nested table, its key under `path`.
pub(crate) fn prefixed(e: Error, path: &str) -> Error {
    match e {
        Error::InvalidScene { key, reason } => Error::scene(format!("{path}.{key}"), reason),
        other => other,
    }
}

fn rest_curvature(v: &Value) -> Result<Vec<[f64; 2]>> {
    let key = "rest_curvature";
    let items = match v {
        Value::List(items) => items,
        other => {
            return Err(Error::scene(
                key,
                format!(
                    "expected a list of [kappa_x, kappa_y] per section, got {}",
                    other.kind()
                ),
            ))
        }
    };
    if items.is_empty() {
        return Err(Error::scene(
            key,
            "must name at least one section (omit the key for a straight rod)",
        ));
    }
    items
        .iter()
        .enumerate()
        .map(|(i, item)| numbers::<2>(item, &format!("{key}[{i}]")))
        .collect()
}

fn gravity(v: &Value) -> Result<Gravity> {
    let t = Table::new(v, "gravity")?;
    t.only(&["linear_density", "vector"])?;
    let linear_density = finite(t.require("linear_density")?, &t.key("linear_density"))?;
    if linear_density < 0.0 {
        return Err(Error::scene(
            t.key("linear_density"),
            format!("must not be negative, got {linear_density}"),
        ));
    }
    Ok(Gravity {
        linear_density,
        vector: vec3(t.require("vector")?, &t.key("vector"))?,
    })
}

fn tip(v: &Value) -> Result<TipCondition> {
    let t = Table::new(v, "tip")?;
    let kind = match t.require("type")? {
        Value::String(s) => s.as_str(),
        other => {
            return Err(Error::scene(
                "tip.type",
                format!("expected a string, got {}", other.kind()),
            ))
        }
    };
    match kind {
        "free" => {
            t.only(&["type"])?;
            Ok(TipCondition::Free)
        }
        "pinned" => {
            t.only(&["type", "position"])?;
            Ok(TipCondition::Pinned {
                position: vec3(t.require("position")?, "tip.position")?,
            })
        }
        "clamped" => {
            t.only(&["type", "position", "quaternion"])?;
            Ok(TipCondition::Clamped {
                position: vec3(t.require("position")?, "tip.position")?,
                quaternion: orientation(t.require("quaternion")?, "tip.quaternion")?,
            })
        }
        other => Err(Error::scene(
            "tip.type",
            format!("unknown tip type '{other}' (expected 'free', 'pinned' or 'clamped')"),
        )),
    }
}

/// Whether arc length `s` lies in `(0, L]`, within the round-off of a sum
/// of section lengths (`3 * 0.1` is a little past `0.3`): the same relative
/// tolerance as [`check_on_node`].
fn in_rod(s: f64, length: f64) -> bool {
    s > 0.0 && s <= length * (1.0 + 1e-9)
}

/// Refuse an arc length `s` that does not fall on a node of `mesh` (up to
/// round-off): loads, guides and anchors act at nodes.
fn check_on_node(key: &str, s: f64, mesh: &Mesh) -> Result<()> {
    if mesh.node_at(s).is_some() {
        return Ok(());
    }
    let h = mesh.element_lengths();
    let spacing = if h.iter().all(|x| *x == h[0]) {
        format!("a multiple of L/n = {}", h[0])
    } else {
        let arcs = mesh.arcs();
        let after = arcs.partition_point(|a| *a < s).clamp(1, arcs.len() - 1);
        format!(
            "a node (each section has its own equal elements; the nearest nodes are at {} and {})",
            arcs[after - 1],
            arcs[after]
        )
    };
    Err(Error::scene(
        key,
        format!("must fall on a node: s = {s} is not {spacing}"),
    ))
}

/// A list of `{s, <vector key>}` tables: guides and point loads.
fn located_vectors(v: &Value, key: &str, vector_key: &str) -> Result<Vec<(f64, Vector3<f64>)>> {
    let items = match v {
        Value::List(items) => items,
        other => {
            return Err(Error::scene(
                key,
                format!(
                    "expected a list of {{s, {vector_key}}} tables, got {}",
                    other.kind()
                ),
            ))
        }
    };
    items
        .iter()
        .enumerate()
        .map(|(i, item)| {
            let path = format!("{key}[{i}]");
            let t = Table::new(item, &path)?;
            t.only(&["s", vector_key])?;
            Ok((
                finite(t.require("s")?, &t.key("s"))?,
                vec3(t.require(vector_key)?, &t.key(vector_key))?,
            ))
        })
        .collect()
}

/// Point loads: each a force, a moment or both at an arc length.
/// Point loads from a list of `{s, force, moment}` tables at `key`.
pub(crate) fn point_loads(v: &Value, key: &str) -> Result<Vec<PointLoad>> {
    table_list(v, key, &["s", "force", "moment"], "", |t| {
        let vector = |key: &str| {
            t.get(key)
                .map_or(Ok(Vector3::zeros()), |x| vec3(x, &t.key(key)))
        };
        if t.get("force").is_none() && t.get("moment").is_none() {
            return Err(Error::scene(
                t.path(),
                "give a force, a moment or both (world frame)",
            ));
        }
        Ok(PointLoad {
            s: finite(t.require("s")?, &t.key("s"))?,
            force: vector("force")?,
            moment: vector("moment")?,
        })
    })
}

/// Tendons; a tendon routed section by section (`section_starts`, the base's
/// 0 first) names one routing for each section it runs through.
fn tendons(v: &Value, length: f64, section_starts: &[f64]) -> Result<Vec<Tendon>> {
    table_list(
        v,
        "tendons",
        &["tension", "offset", "twist", "end"],
        "",
        |t| {
            let tension = finite(t.require("tension")?, &t.key("tension"))?;
            if tension < 0.0 {
                return Err(Error::scene(
                    t.key("tension"),
                    format!("a tendon pulls, it cannot push: must be >= 0 N, got {tension}"),
                ));
            }
            let routings = read_routings(t)?;
            let end = match t.get("end") {
                None => length,
                Some(v) => finite(v, &t.key("end"))?,
            };
            if !in_rod(end, length) {
                return Err(Error::scene(
                    t.key("end"),
                    format!("must lie in (0, L] = (0, {length}], got {end}"),
                ));
            }
            // The sections it runs through: those that start before its anchor.
            let through = section_starts
                .iter()
                .filter(|a| **a < end * (1.0 - 1e-9))
                .count();
            if routings.len() > 1 && routings.len() != through {
                return Err(Error::scene(
                    t.key("offset"),
                    format!(
                        "{} routings, but the tendon runs through {through} sections (to s = {end}): \
                         one [x, y] for all, or one for each",
                        routings.len()
                    ),
                ));
            }
            Ok(Tendon {
                tension,
                offset: routings[0].offset,
                twist: routings[0].twist,
                reroutes: section_starts[1..]
                    .iter()
                    .zip(&routings[1..])
                    .map(|(a, r)| (*a, *r))
                    .collect(),
                end: end.min(length),
            })
        },
    )
}

/// A list of obstacles (`obstacles[i]`), each a table with its `shape`.
pub(crate) fn obstacles(v: &Value) -> Result<Vec<Obstacle>> {
    match v {
        Value::List(items) => items
            .iter()
            .enumerate()
            .map(|(i, x)| Obstacle::from_value(x, &format!("obstacles[{i}]")))
            .collect(),
        other => Err(Error::scene(
            "obstacles",
            format!("expected a list of obstacles, got {}", other.kind()),
        )),
    }
}

/// The friction coefficient of each obstacle of a list (its `friction`
/// key, default 0), finite and non-negative.
pub(crate) fn obstacle_friction(v: &Value) -> Result<Vec<f64>> {
    let Value::List(items) = v else {
        return Ok(Vec::new());
    };
    items
        .iter()
        .enumerate()
        .map(|(i, x)| {
            let key = format!("obstacles[{i}].friction");
            match x {
                Value::Map(entries) => match entries.iter().find(|(k, _)| k == "friction") {
                    Some((_, v)) => check_friction(crate::read::finite(v, &key)?, &key),
                    None => Ok(0.0),
                },
                _ => Ok(0.0),
            }
        })
        .collect()
}

pub(crate) use crate::contact::check_friction;

/// Obstacles as a value-tree list, each with its `friction` where not zero.
pub(crate) fn obstacles_value(obstacles: &[Obstacle], friction: &[f64]) -> Value {
    let list = obstacles.iter().enumerate().map(|(i, o)| {
        let mut v = o.to_value();
        let mu = friction.get(i).copied().unwrap_or(0.0);
        if let (Value::Map(entries), true) = (&mut v, mu != 0.0) {
            entries.push(("friction".into(), Value::Number(mu)));
        }
        v
    });
    Value::List(list.collect())
}

/// A list of ports (`ports[i]`); a port's axis defaults to `base_tangent`.
pub(crate) fn ports(v: &Value, base_tangent: Vector3<f64>) -> Result<Vec<Port>> {
    match v {
        Value::List(items) => items
            .iter()
            .enumerate()
            .map(|(i, x)| Port::from_value(x, &format!("ports[{i}]"), base_tangent))
            .collect(),
        other => Err(Error::scene(
            "ports",
            format!("expected a list of ports, got {}", other.kind()),
        )),
    }
}

/// A length that may be zero (a rod's radius).
fn non_negative_length(v: &Value, key: &str) -> Result<f64> {
    let x = finite(v, key)?;
    if x < 0.0 {
        return Err(Error::scene(key, format!("must not be negative, got {x}")));
    }
    Ok(x)
}

fn guides(v: &Value) -> Result<Vec<Guide>> {
    Ok(located_vectors(v, "guides", "position")?
        .into_iter()
        .map(|(s, position)| Guide { s, position })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err_key(json: &str) -> String {
        match Scene::from_json_str(json) {
            Err(Error::InvalidScene { key, .. }) => key,
            other => panic!("expected an invalid scene, got {other:?}"),
        }
    }

    #[test]
    fn parses_and_round_trips() {
        let s = Scene::from_json_str(
            r#"{"length": 1, "stiffness": {"E": 2e9, "G": 8e8, "diameter": 0.01},
                "rest_curvature": [[1, 0], [0, 2]], "gravity": {"linear_density": 0.1, "vector": [0, 0, -9.81]},
                "tip_force": [0, 1, 0]}"#,
        )
        .unwrap();
        assert_eq!(s.sections(), 2);
        let back = Scene::from_value(&s.to_value()).unwrap();
        assert_eq!(s, back);
        let toml = "length = 0.5\n[stiffness]\nkx = 1\nky = 2\nkz = 3\n";
        assert_eq!(
            Scene::from_toml_str(toml).unwrap().stiffness(),
            Vector3::new(1.0, 2.0, 3.0)
        );
    }

    #[test]
    fn refusals_name_the_key() {
        let base = r#""stiffness": {"kx": 1, "ky": 1, "kz": 1}"#;
        assert_eq!(err_key(&format!(r#"{{"length": -1, {base}}}"#)), "length");
        assert_eq!(
            err_key(r#"{"length": 1, "stiffness": {"kx": 1, "ky": 0, "kz": 1}}"#),
            "stiffness.ky"
        );
        assert_eq!(
            err_key(&format!(r#"{{"length": 1, {base}, "tip_force": [1, 2]}}"#)),
            "tip_force"
        );
        assert_eq!(
            err_key(&format!(r#"{{"length": 1, {base}, "colour": 3}}"#)),
            "colour"
        );
        assert_eq!(
            err_key(r#"{"stiffness": {"kx": 1, "ky": 1, "kz": 1}}"#),
            "length"
        );
    }
}
