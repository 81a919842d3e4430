//! What a robot carries besides its own weight: a payload mass at the tip
//! (pulled along the robot's gravity), a wrench at the tip and wrenches at
//! points along it, all world frame. Every entry point that solves a robot
//! (forward, inverse, track, batches, sensitivity, calibration) takes one.
//!
//! A bare number is a payload mass [kg] (`Load::from(0.03)`); a table reads
//!
//! ```text
//! mass         kg, >= 0 (default 0)
//! tip_force    [Fx, Fy, Fz] N, world frame, at the tool's point (the tip without a tool)
//! tip_moment   [Mx, My, Mz] N m, world frame
//! point_loads  [{s, force, moment}, ...] m, N, N m: on the robot's nodes, world frame
//! ```
//!
//! The lateral tip force of the tendon-robot literature is
//! `{tip_force = [0.5, 0, 0]}`; no fake gravity and zeroed masses are needed.

use crate::error::{Error, Result};
use crate::read::{as_argument, finite, vec3, Table};
use crate::scene::PointLoad;
use crate::value::Value;
use nalgebra::Vector3;

/// What a robot carries (see the module docs).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Load {
    /// Payload at the tool's point (the tip without a tool) [kg], pulled along
    /// the robot's gravity.
    pub mass: f64,
    /// Force at the tool's point, world frame [N].
    pub tip_force: Vector3<f64>,
    /// Moment at the tip, world frame [N m].
    pub tip_moment: Vector3<f64>,
    /// Wrenches at arc lengths along the robot (each on a node), world frame.
    pub point_loads: Vec<PointLoad>,
}

impl From<f64> for Load {
    /// A payload mass [kg] and nothing else.
    fn from(mass: f64) -> Load {
        Load {
            mass,
            ..Load::default()
        }
    }
}

impl Load {
    /// Every key of a load's table.
    pub const KEYS: [&'static str; 4] = ["mass", "tip_force", "tip_moment", "point_loads"];

    /// A load from a number (a mass [kg]) or a table of [`Load::KEYS`],
    /// refused naming `load.<key>`.
    pub fn from_value(v: &Value) -> Result<Load> {
        if let Value::Number(mass) = v {
            let load = Load::from(*mass);
            load.validate()?;
            return Ok(load);
        }
        if !matches!(v, Value::Map(_)) {
            return Err(Error::argument(
                "load",
                format!(
                    "expected a mass [kg] or a table of {{{}}}, got {}",
                    Self::KEYS.join(", "),
                    v.kind()
                ),
            ));
        }
        let table = Table::new(v, "load").map_err(as_argument)?;
        table.only(&Self::KEYS).map_err(as_argument)?;
        let vector = |key: &str| {
            table
                .get(key)
                .map_or(Ok(Vector3::zeros()), |x| vec3(x, &table.key(key)))
                .map_err(as_argument)
        };
        let mass = match table.get("mass") {
            None => 0.0,
            Some(x) => finite(x, "load.mass").map_err(as_argument)?,
        };
        if mass < 0.0 {
            return Err(Error::argument(
                "load.mass",
                format!("must be a mass >= 0 kg, got {mass}"),
            ));
        }
        let load = Load {
            mass,
            tip_force: vector("tip_force")?,
            tip_moment: vector("tip_moment")?,
            point_loads: match table.get("point_loads") {
                None => Vec::new(),
                Some(x) => crate::scene::point_loads(x, "load.point_loads").map_err(as_argument)?,
            },
        };
        load.validate()?;
        Ok(load)
    }

    /// The load as a table ([`Load::from_value`] reads it back); a bare
    /// mass as a number.
    pub fn to_value(&self) -> Value {
        if self.is_mass_only() {
            return Value::Number(self.mass);
        }
        self.to_table()
    }

    /// The load as a table of every key, a bare mass too: the paths of its
    /// sensitivity parameters (`tip_force[0]`, `point_loads[1].moment[2]`).
    pub fn to_table(&self) -> Value {
        let vector = |v: &Vector3<f64>| Value::List(v.iter().map(|x| Value::Number(*x)).collect());
        Value::Map(vec![
            ("mass".into(), Value::Number(self.mass)),
            ("tip_force".into(), vector(&self.tip_force)),
            ("tip_moment".into(), vector(&self.tip_moment)),
            (
                "point_loads".into(),
                Value::List(
                    self.point_loads
                        .iter()
                        .map(|p| {
                            Value::Map(vec![
                                ("s".into(), Value::Number(p.s)),
                                ("force".into(), vector(&p.force)),
                                ("moment".into(), vector(&p.moment)),
                            ])
                        })
                        .collect(),
                ),
            ),
        ])
    }

    /// Only a payload mass (today's `load=` number).
    pub fn is_mass_only(&self) -> bool {
        self.tip_force == Vector3::zeros()
            && self.tip_moment == Vector3::zeros()
            && self.point_loads.is_empty()
    }

    /// Refuse a negative or non-finite mass and non-finite wrenches, naming them.
    pub fn validate(&self) -> Result<()> {
        if !(self.mass.is_finite() && self.mass >= 0.0) {
            return Err(Error::argument(
                if self.is_mass_only() {
                    "load"
                } else {
                    "load.mass"
                },
                format!("must be a mass >= 0 kg, got {}", self.mass),
            ));
        }
        let vectors = [
            ("load.tip_force", &self.tip_force),
            ("load.tip_moment", &self.tip_moment),
        ];
        for (name, v) in vectors {
            if v.iter().any(|x| !x.is_finite()) {
                return Err(Error::argument(name, "must be finite"));
            }
        }
        for (i, p) in self.point_loads.iter().enumerate() {
            if !(p.s.is_finite() && p.force.iter().chain(p.moment.iter()).all(|x| x.is_finite())) {
                return Err(Error::argument(
                    format!("load.point_loads[{i}]"),
                    "must be finite",
                ));
            }
        }
        Ok(())
    }

    /// The same load with another payload mass (a sensitivity's step).
    pub fn with_mass(&self, mass: f64) -> Load {
        Load {
            mass,
            ..self.clone()
        }
    }
}
