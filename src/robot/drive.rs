//! What drives a robot: one of pneumatic muscles, tendons or an external
//! magnetic field, with the drive's own geometry and limits. The inverse
//! kinematics searches the drive's coordinates ([`ActuationSpace`]).
//!
//! Muscle `i` of a section sits at angle `phi_i` in the cross-section; bending
//! the section (backbone length `l_s`, fixed) with curvature `(kx, ky)` changes
//! its length by `l_s d (kx sin phi_i - ky cos phi_i)` (the fibre at offset `p`
//! stretches by `kappa . (p x e3)`). What the three lengths share (their common
//! mode) does not bend the backbone; it is chosen to centre the lengths in the
//! muscles' range, which leaves the most room for the next move.

use super::{positive, ActuationSpace, MAX_SECTIONS};
use crate::error::{Error, Result};
use crate::read::{count, finite, numbers, table_list, vec3};
use crate::scene::{read_routings, routing_values, Routing};
use crate::value::Value;
use nalgebra::{Matrix3, Vector3};

/// Smallest `|det [1, sin phi_i, -cos phi_i]|` of the muscle angles: 2.6 for
/// three muscles 120 degrees apart, 0 for muscles on one line (which cannot
/// bend a section in every direction) or two at one angle.
const MIN_ANGLE_SPREAD: f64 = 1e-6;

/// Why muscle angles are refused.
pub(super) const SPAN_MESSAGE: &str =
    "the three muscles must sit at distinct angles that span the cross-section's plane (the map from curvature to length changes must have rank 2)";

/// A robot's drive (see the module docs). A robot without tendons or
/// magnets is driven by its muscles.
#[derive(Debug, Clone, PartialEq)]
pub enum Drive {
    /// Three pneumatic muscles a section set its rest curvature.
    Muscles(Muscles),
    /// Tendons pulled at the base.
    Tendons(Tendons),
    /// A uniform external field acting on magnetised material.
    Field(Magnets),
}

/// Three pneumatic artificial muscles in every section, at radius `d` from
/// the backbone, and their calibration (seed Fig. 2c):
///
/// ```text
/// actuator (inflation time) <-> joint (muscle length) <-> rest curvature
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Muscles {
    /// Distance of the muscles from the backbone `d` [m] (default 0.02).
    pub radius: f64,
    /// Angles of the three muscles in the cross-section [deg] (default 90, 210, 330).
    pub angles: [f64; 3],
    /// Muscle length at zero inflation time [m] (default: the section length).
    pub rest_length: f64,
    /// Calibration `length = rest_length + rate * time` [m/s] (default -0.01:
    /// inflation shortens a muscle by 1 cm a second).
    pub inflation_rate: f64,
    /// Shortest and longest muscle length [m] (default 0.8 and 1.05 times the
    /// rest length): the contraction range.
    pub length_range: [f64; 2],
}

/// Tendons routed along the backbone, pulled at the base.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tendons {
    /// The routes; their tensions are the actuation's
    /// [`super::Actuation::tensions`].
    pub routes: Vec<TendonRoute>,
    /// Largest tension a tendon's drive can pull [N] (default none: unbounded).
    pub max_tension: Option<f64>,
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

/// Magnetised material steered by a uniform external field.
#[derive(Debug, Clone, PartialEq)]
pub struct Magnets {
    /// Magnetisation per section, material frame [A m^2 / m] (default none;
    /// one entry magnetises every section).
    pub magnetization: Vec<Vector3<f64>>,
    /// A magnet at the tip, material frame [A m^2] (default none).
    pub tip_magnet: Vector3<f64>,
    /// Largest field the magnetic system makes, |B| [T] (default none: unbounded).
    pub max_field: Option<f64>,
}

impl Default for Drive {
    fn default() -> Self {
        Drive::Muscles(Muscles::for_sections_of(0.1))
    }
}

impl Drive {
    /// What the inverse kinematics searches with this drive.
    pub fn space(&self) -> ActuationSpace {
        match self {
            Drive::Muscles(_) => ActuationSpace::Curvature,
            Drive::Tendons(_) => ActuationSpace::Tensions,
            Drive::Field(_) => ActuationSpace::Field,
        }
    }

    /// The drive's name in messages: `"muscles"`, `"tendons"`, `"field"`.
    pub fn name(&self) -> &'static str {
        match self {
            Drive::Muscles(_) => "muscles",
            Drive::Tendons(_) => "tendons",
            Drive::Field(_) => "field",
        }
    }

    /// What drives the robot, in a sentence: "pneumatic muscles", ...
    pub fn description(&self) -> &'static str {
        match self {
            Drive::Muscles(_) => "its pneumatic muscles (rest_curvature)",
            Drive::Tendons(_) => "its tendons (tensions)",
            Drive::Field(_) => "a magnetic field acting on its magnetised material (field)",
        }
    }

    /// The muscles, if they drive the robot.
    pub fn muscles(&self) -> Option<&Muscles> {
        match self {
            Drive::Muscles(m) => Some(m),
            _ => None,
        }
    }

    /// The tendons' routes (none unless tendons drive the robot).
    pub fn tendon_routes(&self) -> &[TendonRoute] {
        match self {
            Drive::Tendons(t) => &t.routes,
            _ => &[],
        }
    }

    /// The largest tension (none: unbounded, or no tendons).
    pub fn max_tension(&self) -> Option<f64> {
        match self {
            Drive::Tendons(t) => t.max_tension,
            _ => None,
        }
    }

    /// The magnets, if a field drives the robot.
    pub fn magnets(&self) -> Option<&Magnets> {
        match self {
            Drive::Field(m) => Some(m),
            _ => None,
        }
    }

    /// The largest field (none: unbounded, or not magnetic).
    pub fn max_field(&self) -> Option<f64> {
        self.magnets().and_then(|m| m.max_field)
    }
}

impl Muscles {
    /// The default muscles of sections `section_length` long: rest length
    /// the section's, range 0.8 to 1.05 of it.
    pub fn for_sections_of(section_length: f64) -> Muscles {
        Muscles {
            radius: 0.02,
            angles: [90.0, 210.0, 330.0],
            rest_length: section_length,
            inflation_rate: -0.01,
            length_range: [0.8 * section_length, 1.05 * section_length],
        }
    }

    /// Length change of each muscle per unit curvature in a section
    /// `section_length` long: row `i` is `l_s d (sin phi_i, -cos phi_i)`.
    pub(crate) fn lever(&self, section_length: f64) -> [[f64; 2]; 3] {
        let ld = section_length * self.radius;
        self.unit_lever().map(|[a, b]| [ld * a, ld * b])
    }

    /// The lever per `l_s d`: `(sin phi_i, -cos phi_i)`.
    fn unit_lever(&self) -> [[f64; 2]; 3] {
        self.angles.map(|a| {
            let phi = a.to_radians();
            [phi.sin(), -phi.cos()]
        })
    }

    /// `[1, sin phi_i, -cos phi_i]`: common mode and curvature per `l_s d` to lengths.
    fn joint_map(&self) -> Matrix3<f64> {
        let u = self.unit_lever();
        Matrix3::from_fn(|r, c| if c == 0 { 1.0 } else { u[r][c - 1] })
    }

    /// Joint space from rest curvature: the three muscle lengths of each
    /// section, their common mode centred in the muscles' range.
    pub fn lengths(&self, section_length: f64, rest_curvature: &[[f64; 2]]) -> Vec<[f64; 3]> {
        let lever = self.lever(section_length);
        let centre = 0.5 * (self.length_range[0] + self.length_range[1]);
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
    pub fn rest_curvature(
        &self,
        section_length: f64,
        muscle_lengths: &[[f64; 3]],
    ) -> Result<Vec<[f64; 2]>> {
        // [1, unit_lever_i] [common, l_s d kx, l_s d ky]^T = l_i, solved
        // without the scale l_s d, which only divides the answer.
        let inv = self
            .joint_map()
            .try_inverse()
            .ok_or_else(|| Error::argument("muscle_angles", SPAN_MESSAGE))?;
        let ld = section_length * self.radius;
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
            .map(|l| l.map(|x| (x - self.rest_length) / self.inflation_rate))
            .collect()
    }

    /// Joint space from actuator space.
    pub fn lengths_from_times(&self, times: &[[f64; 3]]) -> Vec<[f64; 3]> {
        times
            .iter()
            .map(|t| t.map(|x| self.rest_length + self.inflation_rate * x))
            .collect()
    }

    /// Whether every muscle length of every section lies in the range.
    pub fn within_bounds(&self, section_length: f64, rest_curvature: &[[f64; 2]]) -> bool {
        let [lo, hi] = self.length_range;
        let tol = 1e-12 * hi;
        self.lengths(section_length, rest_curvature)
            .iter()
            .all(|l| l.iter().all(|x| *x >= lo - tol && *x <= hi + tol))
    }

    /// Scale each section's curvature back into the muscles' range (the
    /// largest difference between two muscle lengths must fit in the range);
    /// whether any was.
    pub fn clamp_to_bounds(&self, section_length: f64, rest_curvature: &mut [[f64; 2]]) -> bool {
        let lever = self.lever(section_length);
        let span = self.length_range[1] - self.length_range[0];
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

    /// Refuse a field out of range or angles that do not span the
    /// cross-section, naming the robot's key.
    fn check(&self) -> Result<()> {
        positive("muscle_radius", self.radius)?;
        positive("muscle_rest_length", self.rest_length)?;
        if !(self.inflation_rate.is_finite() && self.inflation_rate != 0.0) {
            return Err(Error::scene(
                "inflation_rate",
                "must be finite and non-zero",
            ));
        }
        let [lo, hi] = self.length_range;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
            return Err(Error::scene(
                "muscle_length_range",
                format!("must be [min, max] with 0 < min < max, got [{lo}, {hi}]"),
            ));
        }
        if self.angles.iter().any(|a| !a.is_finite()) {
            return Err(Error::scene("muscle_angles", "must be finite"));
        }
        // The 2 x 3 map from curvature to length changes has rank 2 and, with
        // the common mode, is invertible (three distinct angles, not on one line).
        if self.joint_map().determinant().abs() < MIN_ANGLE_SPREAD {
            let [a, b, c] = self.angles;
            return Err(Error::scene(
                "muscle_angles",
                format!("{SPAN_MESSAGE}, got [{a}, {b}, {c}]"),
            ));
        }
        Ok(())
    }

    /// The muscles' derived quantities in sections `section_length` long, as
    /// [`super::body::Body::derived`]'s.
    fn derived(&self, section_length: f64) -> Vec<(&'static str, &'static str, f64, bool)> {
        let ld = section_length * self.radius;
        let [lo, hi] = self.length_range;
        let rest = self.rest_length;
        vec![
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
        ]
    }
}

impl Tendons {
    /// Refuse a route or limit out of range on a body of `sections`.
    fn check(&self, sections: usize) -> Result<()> {
        if let Some(x) = self.max_tension {
            positive("max_tension", x)?;
        }
        if self.routes.is_empty() {
            return Err(Error::scene(
                "tendons",
                "a tendon-driven robot needs at least one tendon",
            ));
        }
        for (i, t) in self.routes.iter().enumerate() {
            let offsets = std::iter::once(&t.offset).chain(t.reroutes.iter().map(|r| &r.offset));
            if offsets.flatten().any(|x| !x.is_finite()) {
                return Err(Error::scene(
                    format!("tendons[{i}].offset"),
                    "must be finite",
                ));
            }
            if !(1..=sections).contains(&t.section) {
                return Err(Error::scene(
                    format!("tendons[{i}].section"),
                    format!("must be a section in [1, {sections}], got {}", t.section),
                ));
            }
            if !t.reroutes.is_empty() && t.reroutes.len() + 1 != t.section {
                return Err(Error::scene(
                    format!("tendons[{i}].offset"),
                    format!(
                        "{} routings, but the tendon runs through {} sections: one [x, y] \
                         for all, or one for each",
                        t.reroutes.len() + 1,
                        t.section
                    ),
                ));
            }
            if !t.twist.is_finite() || t.reroutes.iter().any(|r| !r.twist.is_finite()) {
                return Err(Error::scene(
                    format!("tendons[{i}].twist"),
                    "must be finite",
                ));
            }
        }
        Ok(())
    }
}

impl Magnets {
    /// Refuse magnetisation or a limit out of range on a body of `sections`.
    fn check(&self, sections: usize) -> Result<()> {
        if let Some(x) = self.max_field {
            positive("max_field", x)?;
        }
        let k = self.magnetization.len();
        if k > 1 && k != sections {
            return Err(Error::scene(
                "magnetization",
                format!("expected one entry or one a section ({sections}), got {k}"),
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
        if self.magnetization.iter().all(|m| *m == Vector3::zeros())
            && self.tip_magnet == Vector3::zeros()
        {
            return Err(Error::scene(
                "magnetization",
                "a magnetic robot needs magnetised sections or a tip_magnet; both are zero",
            ));
        }
        Ok(())
    }
}

impl Drive {
    /// Refuse a drive that cannot act on a body of `sections` sections
    /// `section_length` long (equal, unless `equal_sections` is false).
    pub(super) fn check(
        &self,
        sections: usize,
        section_length: f64,
        equal_sections: bool,
    ) -> Result<()> {
        match self {
            Drive::Muscles(m) => {
                if !equal_sections {
                    return Err(Error::scene(
                        "section_properties",
                        "sections of different lengths are modelled for tendon and magnetic \
                         robots; the pneumatic muscle model takes equal sections (one lever \
                         l_s d for all)",
                    ));
                }
                m.check()?;
                super::check_normal(&m.derived(section_length))
            }
            Drive::Tendons(t) => t.check(sections),
            Drive::Field(f) => f.check(sections),
        }
    }
}

/// The keys of each drive, in the order [`Drive::entries`] writes them.
pub(super) const MUSCLE_KEYS: [&str; 5] = [
    "muscle_radius",
    "muscle_angles",
    "muscle_rest_length",
    "inflation_rate",
    "muscle_length_range",
];
pub(super) const TENDON_KEYS: [&str; 2] = ["tendons", "max_tension"];
pub(super) const FIELD_KEYS: [&str; 3] = ["magnetization", "tip_magnet", "max_field"];

impl Drive {
    /// The drive a robot's table gives by its keys (`entries`: those of
    /// [`MUSCLE_KEYS`], [`TENDON_KEYS`] and [`FIELD_KEYS`] given; none:
    /// the default muscles), on a body of `sections` sections
    /// `section_length` long. Keys of two drives are refused: a robot has one.
    pub(super) fn read(
        entries: &[(&str, &Value)],
        sections: usize,
        section_length: f64,
    ) -> Result<Drive> {
        let kind = |key: &str| {
            if TENDON_KEYS.contains(&key) {
                "tendons"
            } else if FIELD_KEYS.contains(&key) {
                "field"
            } else {
                "muscles"
            }
        };
        let Some(&(first, _)) = entries.first() else {
            return Ok(Drive::Muscles(Muscles::for_sections_of(section_length)));
        };
        if let Some(&(other, _)) = entries.iter().find(|(k, _)| kind(k) != kind(first)) {
            return Err(Error::scene(
                other,
                format!(
                    "a robot has one drive: `{first}` makes it {}-driven, and `{other}` belongs \
                     to the {} drive",
                    kind(first).trim_end_matches('s'),
                    kind(other)
                ),
            ));
        }
        let given = |name: &str| entries.iter().find(|(k, _)| *k == name).map(|(_, v)| *v);
        match kind(first) {
            "tendons" => Ok(Drive::Tendons(Tendons {
                routes: match given("tendons") {
                    Some(v) => tendon_routes(v, sections)?,
                    None => Vec::new(),
                },
                max_tension: given("max_tension")
                    .map(|v| finite(v, "max_tension"))
                    .transpose()?,
            })),
            "field" => Ok(Drive::Field(Magnets {
                magnetization: match given("magnetization") {
                    Some(Value::List(items))
                        if items.iter().all(|x| matches!(x, Value::List(_))) =>
                    {
                        items
                            .iter()
                            .enumerate()
                            .map(|(i, x)| vec3(x, &format!("magnetization[{i}]")))
                            .collect::<Result<_>>()?
                    }
                    Some(other) => vec![vec3(other, "magnetization")?],
                    None => Vec::new(),
                },
                tip_magnet: given("tip_magnet")
                    .map(|v| vec3(v, "tip_magnet"))
                    .transpose()?
                    .unwrap_or_else(Vector3::zeros),
                max_field: given("max_field")
                    .map(|v| finite(v, "max_field"))
                    .transpose()?,
            })),
            _ => {
                let mut m = Muscles::for_sections_of(section_length);
                let number = |name: &str| given(name).map(|v| finite(v, name)).transpose();
                m.radius = number("muscle_radius")?.unwrap_or(m.radius);
                if let Some(v) = given("muscle_angles") {
                    m.angles = numbers::<3>(v, "muscle_angles")?;
                }
                m.inflation_rate = number("inflation_rate")?.unwrap_or(m.inflation_rate);
                // The range follows the rest length unless given.
                if let Some(rest) = number("muscle_rest_length")? {
                    m = Muscles {
                        rest_length: rest,
                        length_range: [0.8 * rest, 1.05 * rest],
                        ..m
                    };
                }
                if let Some(v) = given("muscle_length_range") {
                    m.length_range = numbers::<2>(v, "muscle_length_range")?;
                }
                Ok(Drive::Muscles(m))
            }
        }
    }

    /// The drive's fields as value-tree entries ([`Drive::read`] of them is
    /// the same drive).
    pub(super) fn entries(&self) -> Vec<(String, Value)> {
        let num = Value::Number;
        let list = |xs: &[f64]| Value::List(xs.iter().map(|x| num(*x)).collect());
        let mut entries: Vec<(String, Value)> = Vec::new();
        match self {
            Drive::Muscles(m) => {
                entries.push(("muscle_radius".into(), num(m.radius)));
                entries.push(("muscle_angles".into(), list(&m.angles)));
                entries.push(("muscle_rest_length".into(), num(m.rest_length)));
                entries.push(("inflation_rate".into(), num(m.inflation_rate)));
                entries.push(("muscle_length_range".into(), list(&m.length_range)));
            }
            Drive::Tendons(t) => {
                let routes = t
                    .routes
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
                if let Some(x) = t.max_tension {
                    entries.push(("max_tension".into(), num(x)));
                }
            }
            Drive::Field(f) => {
                if !f.magnetization.is_empty() {
                    let per_section = f.magnetization.iter().map(|m| list(m.as_slice())).collect();
                    entries.push(("magnetization".into(), Value::List(per_section)));
                }
                if f.tip_magnet != Vector3::zeros() {
                    entries.push(("tip_magnet".into(), list(f.tip_magnet.as_slice())));
                }
                if let Some(x) = f.max_field {
                    entries.push(("max_field".into(), num(x)));
                }
            }
        }
        entries
    }
}

/// Tendon routes from a list of `{offset, twist, section}` tables (a route
/// without `section` is anchored at the end of the last of `sections`).
fn tendon_routes(v: &Value, sections: usize) -> Result<Vec<TendonRoute>> {
    table_list(v, "tendons", &["offset", "twist", "section"], "", |t| {
        let routings = read_routings(t)?;
        Ok(TendonRoute {
            offset: routings[0].offset,
            twist: routings[0].twist,
            reroutes: routings[1..].to_vec(),
            section: match t.get("section") {
                None => sections,
                Some(x) => count(x, &t.key("section"), MAX_SECTIONS)?,
            },
        })
    })
}
