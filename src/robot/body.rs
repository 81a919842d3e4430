//! The robot's body: what every robot has whatever drives it. A backbone of
//! `m` sections (their lengths, stiffness, mass per length and the disk at
//! each section's end), its base pose, its weight and a tool at the tip.

use super::positive;
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::read::{count, finite, table_list, vec3};
use crate::scene::{
    check_lengths_add_up, prefixed, read_stiffness, section_entries, stiffness_value, Stiffness,
};
use crate::value::Value;
use nalgebra::Vector3;

/// Standard gravity [m/s^2].
pub const STANDARD_GRAVITY: f64 = 9.81;

/// Most sections a robot may have (the IK's dense Jacobian has `2 m` columns).
pub const MAX_SECTIONS: usize = 10_000;

/// The passive structure of a robot (see the module docs); the default is
/// the seed's prototype: 1 m, 10 sections, hanging from its base.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Backbone length [m] (default 1).
    pub length: f64,
    /// Backbone stiffness (default: spring steel, 3 mm: E 200 GPa, G 77 GPa).
    pub stiffness: Stiffness,
    /// Mass per length of backbone, muscles and tubing [kg/m] (default 0.2).
    pub linear_density: f64,
    /// Number of sections `m` (default 10).
    pub sections: usize,
    /// Mass of each constraint disk at a section end [kg] (default 0.01).
    pub disk_mass: f64,
    /// Gravitational acceleration, world frame [m/s^2] (default `[0, 0, -9.81]`).
    pub gravity: Vector3<f64>,
    /// Base orientation (default `[0, 1, 0, 0]`: hanging, tangent `-z`).
    pub base_quaternion: Quat,
    /// Base position [m], world frame (default the origin).
    pub base_position: Vector3<f64>,
    /// Per section, its own length, stiffness, linear density or disk mass
    /// (default none: the body's everywhere; else one entry a section).
    pub section_properties: Vec<SectionSpec>,
    /// Mass of a tool at the tip [kg] (default 0).
    pub tool_mass: f64,
    /// Where the tool's weight, and the payload it holds (the `load`), act:
    /// from the tip in its material frame [m] (default the tip itself).
    pub tool_offset: Vector3<f64>,
    /// Outer radius of the body for contact [m] (default `None`: the
    /// drive's, see [`super::Robot::contact_radius`]).
    pub radius: Option<f64>,
}

/// What one section changes of the body's own properties (each `None`:
/// the body's).
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

impl Default for Body {
    fn default() -> Self {
        Body {
            length: 1.0,
            stiffness: Stiffness::RoundRod {
                e: 200e9,
                g: 77e9,
                diameter: 0.003,
            },
            linear_density: 0.2,
            sections: 10,
            disk_mass: 0.01,
            gravity: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
            base_quaternion: Quat::new(0.0, 1.0, 0.0, 0.0),
            base_position: Vector3::zeros(),
            section_properties: Vec::new(),
            tool_mass: 0.0,
            tool_offset: Vector3::zeros(),
            radius: None,
        }
    }
}

impl Body {
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

    /// Whether every section has the same length.
    pub fn has_equal_sections(&self) -> bool {
        let lengths = self.section_lengths();
        lengths.iter().all(|l| (l - lengths[0]).abs() <= 1e-12 * l)
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

    /// The body's own mass [kg]: its backbone, disks and tool.
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

    /// Refuse a section count out of range.
    pub(super) fn check_sections(&self) -> Result<()> {
        if !(1..=MAX_SECTIONS).contains(&self.sections) {
            return Err(Error::scene(
                "sections",
                format!(
                    "must be an integer in [1, {MAX_SECTIONS}], got {}",
                    self.sections
                ),
            ));
        }
        Ok(())
    }

    /// Refuse a field out of range, naming it (the sections counted first).
    pub(super) fn check_fields(&self) -> Result<()> {
        positive("length", self.length)?;
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
        self.check_section_properties()
    }

    /// One entry a section or none, lengths adding up to the body's, masses
    /// non-negative.
    fn check_section_properties(&self) -> Result<()> {
        let p = self.section_properties.len();
        if p > 0 && p != self.sections {
            return Err(Error::scene(
                "section_properties",
                format!("expected one entry a section ({}), got {p}", self.sections),
            ));
        }
        let given: Vec<Option<f64>> = self.section_properties.iter().map(|p| p.length).collect();
        check_lengths_add_up(&given, self.length, "section_properties")?;
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
        Ok(())
    }

    /// The body's derived quantities as `(key, quantity, value, whether an
    /// exact zero is what the fields say)` at `n_elements` (see
    /// [`super::Robot::validate`]).
    pub(super) fn derived(
        &self,
        n_elements: usize,
    ) -> Vec<(&'static str, &'static str, f64, bool)> {
        let ds = self.length / n_elements as f64;
        let g = self.gravity.norm();
        let weight = self.linear_density * g;
        let disks = self.disk_mass * g;
        vec![
            ("length", "section length", self.section_length(), false),
            ("length", "element length", ds, false),
            ("length", "element length squared", ds * ds, false),
            ("length", "length squared", self.length * self.length, false),
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
        ]
    }
}

/// The keys of a robot's body (see [`Body`]).
pub(super) const BODY_KEYS: [&str; 12] = [
    "length",
    "stiffness",
    "linear_density",
    "sections",
    "disk_mass",
    "gravity",
    "base_quaternion",
    "base_position",
    "section_properties",
    "tool_mass",
    "tool_offset",
    "radius",
];

impl Body {
    /// Set the field `key` (one of [`BODY_KEYS`]) from the value tree.
    pub(super) fn read_key(&mut self, key: &str, value: &Value) -> Result<()> {
        let num = |v: &Value| finite(v, key);
        match key {
            "length" => self.length = num(value)?,
            "stiffness" => self.stiffness = read_stiffness(value)?,
            "linear_density" => self.linear_density = num(value)?,
            "sections" => self.sections = count(value, key, MAX_SECTIONS)?,
            "disk_mass" => self.disk_mass = num(value)?,
            "gravity" => self.gravity = vec3(value, key)?,
            "base_quaternion" => self.base_quaternion = crate::scene::orientation(value, key)?,
            "base_position" => self.base_position = vec3(value, key)?,
            "section_properties" => self.section_properties = section_specs(value)?,
            "tool_mass" => self.tool_mass = num(value)?,
            "tool_offset" => self.tool_offset = vec3(value, key)?,
            "radius" => {
                let r = num(value)?;
                if r < 0.0 {
                    return Err(Error::scene(key, format!("must not be negative, got {r}")));
                }
                self.radius = Some(r);
            }
            other => unreachable!("{other} is not a body key"),
        }
        Ok(())
    }

    /// The body's fields as value-tree entries (tool and per-section
    /// properties only where given).
    pub(super) fn entries(&self) -> Vec<(String, Value)> {
        let num = Value::Number;
        let list = |xs: &[f64]| Value::List(xs.iter().map(|x| num(*x)).collect());
        let mut entries = vec![
            ("length".into(), num(self.length)),
            ("stiffness".into(), stiffness_value(&self.stiffness)),
            ("linear_density".into(), num(self.linear_density)),
            ("sections".into(), num(self.sections as f64)),
            ("disk_mass".into(), num(self.disk_mass)),
            ("gravity".into(), list(self.gravity.as_slice())),
            (
                "base_quaternion".into(),
                list(&self.base_quaternion.to_array()),
            ),
            ("base_position".into(), list(self.base_position.as_slice())),
        ];
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
        if let Some(r) = self.radius {
            entries.push(("radius".into(), num(r)));
        }
        entries
    }
}

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
