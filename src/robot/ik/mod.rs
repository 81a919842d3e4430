//! Load-aware inverse kinematics, one engine for every drive: the actuation
//! (muscle curvatures, tendon tensions or a uniform field) whose *loaded*
//! equilibrium puts the tip, or the tool's point, at the target, and
//! optionally along a direction; among the many that do, the one closest to a
//! reference.
//!
//! * `goal.rs`: what a solve aims at, its error rows and their derivative
//!   from the tip's sensitivities; one meaning of `tol` for every drive.
//! * `drive.rs`: the drive's coordinates, their admissible set (the muscles'
//!   length range, the tensions' box, the field's ball), how they enter the
//!   forward solver and the tip's Jacobian in them, and the starts a missed
//!   target is tried from.
//! * `engine.rs`: the descent ([`InverseSolver`]), which names no drive.
//!
//! Here: the settings, options, endings and results, and [`Robot::inverse`]
//! and [`Robot::track`].

mod drive;
mod engine;
mod goal;

pub use drive::ActuationSpace;
pub use engine::InverseSolver;
pub use goal::Aim;

use super::{Load, Robot};
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::read::{as_argument, count, finite, string, Table};
use crate::solver::Solution;
use crate::value::Value;
use nalgebra::Vector3;

/// How the actuation is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// The loaded equilibrium reaches the target (default).
    Equilibrium,
    /// The seed's way: fit the sections to the target ignoring weight and load,
    /// then apply that actuation to the loaded robot (it misses under load).
    Geometric,
}

impl std::str::FromStr for Strategy {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "equilibrium" => Ok(Strategy::Equilibrium),
            "geometric" => Ok(Strategy::Geometric),
            other => Err(Error::argument(
                "strategy",
                format!("unknown strategy '{other}' (expected 'equilibrium' or 'geometric')"),
            )),
        }
    }
}

impl Strategy {
    /// The name [`Strategy::from_str`](std::str::FromStr) reads.
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Equilibrium => "equilibrium",
            Strategy::Geometric => "geometric",
        }
    }
}

/// Settings of inverse kinematics; every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSettings {
    /// How the actuation is found (default [`Strategy::Equilibrium`]).
    pub strategy: Strategy,
    /// Tip position tolerance [m] (default 1e-9, in [1e-12 L, 1e-2 L]); a
    /// direction's tolerance is tol / L.
    pub tol: f64,
    /// Iteration limit of one descent (default 60). A missed target is retried
    /// by a continuation and from at most 12 other starts (see `engine.rs`),
    /// then settled on its closest tip, each with this limit.
    pub max_iterations: usize,
}

impl Default for IkSettings {
    fn default() -> Self {
        IkSettings {
            strategy: Strategy::Equilibrium,
            tol: 1e-9,
            max_iterations: 60,
        }
    }
}

/// Largest iteration limit of one descent a setting accepts.
const MAX_IK_ITERATIONS: usize = 1_000_000;

impl IkSettings {
    /// Every key of [`IkSettings::set`].
    pub const KEYS: [&'static str; 3] = ["strategy", "tol", "max_iterations"];

    /// Set one field from a value, named by [`IkSettings::KEYS`]; the range
    /// of `tol` is [`validate`](IkSettings::validate)'s.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        match key {
            "strategy" => self.strategy = string(value, key).map_err(as_argument)?.parse()?,
            "tol" => self.tol = finite(value, key).map_err(as_argument)?,
            "max_iterations" => {
                self.max_iterations = count(value, key, MAX_IK_ITERATIONS).map_err(as_argument)?
            }
            other => {
                return Err(Error::argument(
                    other,
                    format!(
                        "unknown setting (expected one of: {})",
                        Self::KEYS.join(", ")
                    ),
                ))
            }
        }
        Ok(())
    }

    /// Settings from a table of [`IkSettings::KEYS`] over the defaults.
    pub fn from_value(v: &Value) -> Result<IkSettings> {
        let mut settings = IkSettings::default();
        for (k, x) in Table::top(v, "settings").map_err(as_argument)?.entries {
            settings.set(k, x)?;
        }
        settings.validate()?;
        Ok(settings)
    }

    /// Every field as a table ([`IkSettings::from_value`] reads it back).
    pub fn to_value(&self) -> Value {
        Value::Map(vec![
            (
                "strategy".into(),
                Value::String(self.strategy.name().into()),
            ),
            ("tol".into(), Value::Number(self.tol)),
            (
                "max_iterations".into(),
                Value::Number(self.max_iterations as f64),
            ),
        ])
    }

    /// Refuse a tolerance that is not positive and finite (its range relative
    /// to a robot's length is checked by the inverse solve).
    pub fn validate(&self) -> Result<()> {
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(Error::argument(
                "tol",
                format!("must be positive, got {}", self.tol),
            ));
        }
        Ok(())
    }
}

/// Options of one inverse solve: what it aims at, under which load, and the
/// settings of the solver.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IkOptions {
    /// What the robot carries (default nothing): a payload mass, wrenches.
    pub load: Load,
    /// Actuation to stay closest to (default: zero curvature).
    pub reference: Option<Vec<[f64; 2]>>,
    /// Also reach this tip direction (unit vector, world frame).
    pub direction: Option<Vector3<f64>>,
    /// Also reach this orientation of the tip's frame (a full pose; unit
    /// quaternion, world frame). Not with `direction`.
    pub orientation: Option<Quat>,
    pub settings: IkSettings,
    /// Tendon-driven robots: the tensions to stay closest to [N] (default
    /// zero: the least tension, in norm, that reaches the target).
    pub pretension: Option<Vec<f64>>,
    /// A warm start: an earlier answer's equilibrium (node quaternions) and
    /// actuation. The forward solves start from the equilibrium, and the
    /// actuation is the reference when none is given (the search starts at
    /// the reference).
    pub initial: Option<IkStart>,
}

impl IkOptions {
    /// What the tip's frame aims at besides its point: the direction or
    /// the orientation, refused when both are given.
    pub fn aim(&self) -> Result<Aim> {
        match (self.direction, self.orientation) {
            (Some(_), Some(_)) => Err(Error::argument(
                "orientation",
                "give a direction or an orientation, not both (an orientation fixes the \
                 direction)",
            )),
            (Some(d), None) => Ok(Aim::Direction(d)),
            (None, Some(q)) => Ok(Aim::Orientation(q)),
            (None, None) => Ok(Aim::Point),
        }
    }
}

/// A warm start of an inverse solve (see [`IkOptions::initial`]).
#[derive(Debug, Clone, PartialEq)]
pub struct IkStart {
    pub quaternions: Vec<Quat>,
    pub rest_curvature: Option<Vec<[f64; 2]>>,
    /// A tendon-driven or magnetic robot's actuation: its tensions [N] or
    /// its field [T] (`None`: from slack, or zero field).
    pub actuation: Option<Vec<f64>>,
    /// A robot's insertion [m] (`None`: zero).
    pub insertion: Option<f64>,
}

crate::status::named_enum! {
    /// Why an inverse solve ended.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum IkEnding {
        /// The tip (and direction) is within the tolerance, on a stable
        /// equilibrium.
        Reached => "reached",
        /// The closest tip found is limited by the robot, not by its drives'
        /// limits: farther than the robot is long, or a local minimum of the
        /// miss with no drive at a limit holding it back.
        OutOfReach => "out_of_reach",
        /// Drives at their limits hold the closest tip found back: muscles at
        /// their length limits, tendons slack or at `max_tension`, the field at
        /// `max_field`.
        BoundsActive => "bounds_active",
        /// No stable equilibrium was found where the descent had to go.
        SolverFailure => "solver_failure",
        /// The iteration budget ran out while the miss was still shrinking.
        IterationLimit => "iteration_limit",
        /// The geometric strategy's fit, applied to the loaded robot, misses.
        LoadIgnored => "load_ignored",
    }
}

impl std::str::FromStr for IkEnding {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        IkEnding::ALL
            .into_iter()
            .find(|ending| ending.name() == s)
            .ok_or_else(|| Error::argument("ending", format!("unknown ending '{s}'")))
    }
}

/// The actuation found, in every space, with the equilibrium it produces.
#[derive(Debug, Clone)]
pub struct IkResult {
    /// `[kappa_x, kappa_y]` per section [1/m].
    pub rest_curvature: Vec<[f64; 2]>,
    /// Three muscle lengths per section [m].
    pub muscle_lengths: Vec<[f64; 3]>,
    /// Three inflation times per section [s].
    pub inflation_times: Vec<[f64; 3]>,
    /// Tendon tensions [N] (a tendon-driven robot; empty otherwise).
    pub tensions: Vec<f64>,
    /// Uniform magnetic field, world frame [T] (a magnetic robot; zero otherwise).
    pub field: Vector3<f64>,
    /// How far the base was moved along its tangent [m] (a robot with an
    /// `insertion_range`; zero otherwise).
    pub insertion: f64,
    /// The loaded equilibrium with this actuation.
    pub solution: Solution,
    /// The point aimed at the target: the tool's, or the tip without a tool [m].
    pub tip_position: Vector3<f64>,
    /// Distance from the aimed point (the tool's, or the tip) to the target [m].
    pub tip_miss: f64,
    /// Whether the target (and direction) was reached within the tolerance on
    /// a stable equilibrium.
    pub reached: bool,
    pub ending: IkEnding,
    pub message: String,
    /// Gauss-Newton and Levenberg-Marquardt iterations, all starts included.
    pub iterations: usize,
    /// Starting actuations tried (1: the fast path from the reference).
    pub starts: usize,
    /// Wall-clock time of this inverse solve [s].
    pub seconds: f64,
}

impl IkResult {
    /// Refuse a stored result (`IkResult.from_dict`) that no inverse solve
    /// returns: a NaN anywhere, a negative miss or time, a reached target
    /// with a non-finite answer or an equilibrium that did not converge.
    pub fn check_stored(&self) -> Result<()> {
        let rows = self
            .rest_curvature
            .iter()
            .enumerate()
            .map(|(i, k)| (format!("rest_curvature[{i}]"), k.to_vec()))
            .chain(
                self.muscle_lengths
                    .iter()
                    .enumerate()
                    .map(|(i, l)| (format!("muscle_lengths[{i}]"), l.to_vec())),
            )
            .chain(
                self.inflation_times
                    .iter()
                    .enumerate()
                    .map(|(i, t)| (format!("inflation_times[{i}]"), t.to_vec())),
            )
            .chain([
                ("tensions".to_string(), self.tensions.clone()),
                ("field".to_string(), self.field.iter().copied().collect()),
                (
                    "tip_position".to_string(),
                    self.tip_position.iter().copied().collect(),
                ),
            ]);
        for (name, values) in rows {
            let bad = values
                .iter()
                .find(|x| x.is_nan() || (self.reached && !x.is_finite()));
            if let Some(x) = bad {
                return Err(Error::argument(
                    format!("ik_result.{name}"),
                    format!("an inverse solve never answers {x}"),
                ));
            }
        }
        if self.tip_miss.is_nan()
            || self.tip_miss < 0.0
            || (self.reached && self.tip_miss.is_infinite())
        {
            return Err(Error::argument(
                "ik_result.tip_miss",
                format!("a distance: finite and >= 0, got {}", self.tip_miss),
            ));
        }
        if !(self.seconds.is_finite() && self.seconds >= 0.0) {
            return Err(Error::argument(
                "ik_result.time",
                format!("a duration: finite and >= 0 s, got {}", self.seconds),
            ));
        }
        if self.reached && !self.solution.converged() {
            return Err(Error::argument(
                "ik_result.reached",
                "a target is reached only on a converged equilibrium",
            ));
        }
        Ok(())
    }
}

impl IkResult {
    /// The answer in its drive's coordinates, as [`InverseSolver::solve`]
    /// takes a reference: the curvatures section by section, the tensions,
    /// or the field.
    pub fn drive(&self, space: ActuationSpace) -> Vec<f64> {
        match space {
            ActuationSpace::Curvature => self.rest_curvature.iter().flatten().copied().collect(),
            ActuationSpace::Tensions => self.tensions.clone(),
            ActuationSpace::Field => self.field.iter().copied().collect(),
        }
    }
}

/// Refuse a warm start that does not fit the robot's discretisation.
fn check_initial(start: &IkStart, n_elements: usize) -> Result<()> {
    if start.quaternions.len() != n_elements + 1 {
        return Err(Error::argument(
            "initial",
            format!(
                "has {} nodes, the robot's discretisation {}",
                start.quaternions.len(),
                n_elements + 1
            ),
        ));
    }
    if start
        .quaternions
        .iter()
        .any(|q| !q.to_array().iter().all(|x| x.is_finite()) || q.norm() < 1e-6)
    {
        return Err(Error::argument(
            "initial",
            "quaternions must be finite and non-zero",
        ));
    }
    Ok(())
}

impl Robot {
    /// The reference (or pretension) of `options` in this robot's drive
    /// coordinates, checked, as [`InverseSolver::solve`] takes it.
    pub(crate) fn ik_reference(&self, options: &IkOptions) -> Result<Option<Vec<f64>>> {
        engine::reference_of(self, &drive::DriveSpace::of(self)?, options)
    }

    /// Load-aware inverse kinematics of one target (see [`IkOptions`]).
    pub fn inverse(&self, target: Vector3<f64>, options: &IkOptions) -> Result<IkResult> {
        Ok(self.track(&[target], options)?.remove(0))
    }

    /// Inverse kinematics of a sequence of targets, each warm-started from
    /// the previous one. Muscles choose the actuation closest to the last
    /// answer (smooth motion); tendons the least tension (or the closest to
    /// the pretension), a field the smallest.
    pub fn track(&self, targets: &[Vector3<f64>], options: &IkOptions) -> Result<Vec<IkResult>> {
        options.settings.validate()?;
        let mut loaded = InverseSolver::new(self, &options.load)?;
        let mut reference = loaded.reference_of(options)?;
        if let Some(start) = &options.initial {
            check_initial(start, self.n_elements)?;
            loaded.warm_start(start)?;
            if reference.is_none() && loaded.follows_path() {
                reference = Some(loaded.last_answer().to_vec());
            }
        }
        let mut weightless = match options.settings.strategy {
            Strategy::Equilibrium => None,
            Strategy::Geometric => Some(InverseSolver::new(&self.weightless(), &Load::default())?),
        };
        let (tol, budget) = (options.settings.tol, options.settings.max_iterations);
        let aim = options.aim()?;
        let mut out = Vec::with_capacity(targets.len());
        for target in targets {
            let result = match weightless.as_mut() {
                None => loaded.solve(*target, aim, reference.as_deref(), tol, budget)?,
                Some(geometric) => {
                    let fit = geometric.solve(*target, aim, reference.as_deref(), tol, budget)?;
                    loaded.apply_geometric_fit(fit, *target, tol)?
                }
            };
            if loaded.follows_path() {
                reference = Some(loaded.coordinates_of(&result).as_slice().to_vec());
            }
            out.push(result);
        }
        Ok(out)
    }
}
