//! Accuracy on demand: the solver chooses the discretisation. The scheme is
//! second order, so the error of a node of the solve at 2n is about a third
//! of the difference between that node at n and 2n; n doubles until the
//! largest such estimate over the backbone is below the tolerance. Richardson extrapolation `(4 r_2n - r_n) / 3` removes
//! the leading error term and typically gains two to four digits.

use super::{check_tolerance, Settings, Solution, Solver, Status, MAX_ELEMENTS};
use crate::error::{Error, Result};
use crate::model::{element_turn, slerp};
use crate::quat::Quat;
use crate::read::{as_argument, count, finite, Table};
use crate::scene::Scene;
use crate::value::Value;

/// What accuracy to reach and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Accuracy {
    /// Tip error tolerance, relative to the length `L`.
    pub tol: f64,
    /// Return the Richardson-extrapolated tip (marked in the Solution).
    pub richardson: bool,
    /// Largest number of elements tried (default 10 240).
    pub max_elements: usize,
}

impl Accuracy {
    /// An accuracy of `tol` with the defaults: no extrapolation, at most 10 240 elements.
    pub fn new(tol: f64) -> Self {
        Accuracy {
            tol,
            richardson: false,
            max_elements: 10_240,
        }
    }
}

/// A value as the user wrote it, for a refusal.
fn shown_value(v: &Value) -> String {
    match v {
        Value::String(s) => format!("'{s}'"),
        other => other.kind().to_string(),
    }
}

/// Range of the relative tip tolerance: 1e-12 L is about what double
/// precision leaves of a tip at the largest n; above 0.1 L is no accuracy.
pub const ACCURACY_TOL_RANGE: (f64, f64) = (1e-12, 1e-1);

/// Largest turning of one element [rad] at which the error estimate from the
/// solves at n and 2n is trusted (the error is then in its asymptotic,
/// second-order regime); coarser solves only lead to finer ones.
pub const ASYMPTOTIC_TURN: f64 = 0.25;

impl Accuracy {
    /// Whether one pass of this solve may outlast the interrupt poll (see
    /// [`Settings::has_long_passes`]): it may end at any n up to
    /// `max_elements`.
    pub fn has_long_passes(&self, settings: &Settings) -> bool {
        Settings {
            n_elements: Some(self.max_elements),
            ..settings.clone()
        }
        .has_long_passes()
    }

    /// Every key of [`Accuracy::set`].
    pub const KEYS: [&'static str; 3] = ["tol", "refine", "max_elements"];

    /// Set one field from a value: `tol` a number, `refine` `"richardson"`
    /// or null (none), `max_elements` a count; ranges are
    /// [`validate`](Accuracy::validate)'s.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        match key {
            "tol" => self.tol = finite(value, key).map_err(as_argument)?,
            "refine" => {
                self.richardson = match value {
                    Value::Null => false,
                    Value::String(s) if s == "richardson" => true,
                    other => {
                        return Err(Error::argument(
                            key,
                            format!("expected 'richardson' or None, got {}", shown_value(other)),
                        ))
                    }
                }
            }
            "max_elements" => {
                self.max_elements = count(value, key, MAX_ELEMENTS).map_err(as_argument)?
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

    /// An accuracy from a table of [`Accuracy::KEYS`] (`tol` required), validated.
    pub fn from_value(v: &Value) -> Result<Accuracy> {
        let table = Table::top(v, "accuracy").map_err(as_argument)?;
        let Some(tol) = table.get("tol") else {
            // Named by what was given without it.
            let given = table.entries.first().map_or("tol", |(k, _)| k.as_str());
            return Err(Error::argument(
                given,
                "needs tol (accuracy on demand: refine and max_elements apply to it)",
            ));
        };
        let mut accuracy = Accuracy::new(f64::NAN);
        accuracy.set("tol", tol)?;
        for (k, x) in table.entries {
            accuracy.set(k, x)?;
        }
        accuracy.validate()?;
        Ok(accuracy)
    }

    /// Every field as a table ([`Accuracy::from_value`] reads it back).
    pub fn to_value(&self) -> Value {
        let refine = if self.richardson {
            Value::String("richardson".into())
        } else {
            Value::Null
        };
        Value::Map(vec![
            ("tol".into(), Value::Number(self.tol)),
            ("refine".into(), refine),
            (
                "max_elements".into(),
                Value::Number(self.max_elements as f64),
            ),
        ])
    }

    /// Refuse an accuracy out of range, naming the field.
    pub fn validate(&self) -> Result<()> {
        check_tolerance("tol", self.tol, ACCURACY_TOL_RANGE)?;
        if self.max_elements == 0 || self.max_elements > MAX_ELEMENTS {
            return Err(Error::argument(
                "max_elements",
                format!("must lie in [1, {MAX_ELEMENTS}], got {}", self.max_elements),
            ));
        }
        Ok(())
    }
}

/// The first n of accuracy on demand: at least `requested`, a multiple of the
/// sections, and fine enough that no element turns by more than
/// [`ASYMPTOTIC_TURN`] at rest (a coiled rod needs many elements before any
/// estimate means anything).
pub fn starting_elements(scene: &Scene, requested: usize) -> usize {
    let m = scene.sections();
    let rest_turn = scene
        .rest_curvature
        .iter()
        .map(|k| k[0].hypot(k[1]))
        .fold(0.0, f64::max)
        * scene.length;
    let resolving = (rest_turn / ASYMPTOTIC_TURN)
        .ceil()
        .min(MAX_ELEMENTS as f64) as usize;
    requested.max(resolving).max(1).div_ceil(m) * m
}

/// Solve `scene` to a tip accuracy of `accuracy.tol * L`, starting at
/// [`starting_elements`] and doubling.
pub fn solve_to_accuracy(
    scene: &Scene,
    settings: Settings,
    accuracy: &Accuracy,
) -> Result<Solution> {
    let started = std::time::Instant::now();
    let mut solution = refine_until_met(scene, settings, accuracy)?;
    solution.solve_time = started.elapsed().as_secs_f64();
    Ok(solution)
}

/// The doubling of [`solve_to_accuracy`].
fn refine_until_met(scene: &Scene, settings: Settings, accuracy: &Accuracy) -> Result<Solution> {
    accuracy.validate()?;
    let length = scene.length;
    let mut n = starting_elements(scene, settings.elements_for(scene));
    let mut solver = Solver::new(
        scene,
        Settings {
            n_elements: Some(n),
            ..settings.clone()
        },
    )?;
    let mut coarse = solver.solve(None)?;
    let straight = scene
        .rest_curvature
        .iter()
        .all(|k| k[0] == 0.0 && k[1] == 0.0);
    if straight && solver.model().is_trivial() {
        // The unloaded straight rod is exact at any n: nothing to refine.
        coarse.error_estimate = Some(0.0);
        return Ok(coarse);
    }
    let mut iterations = coarse.iterations;
    // An underresolved equilibrium is no answer yet, but a finer n may resolve it.
    let usable = |s: &Solution| s.converged() || s.status == Status::Underresolved;
    loop {
        if !usable(&coarse) {
            coarse.iterations = iterations;
            return Ok(coarse);
        }
        if 2 * n > accuracy.max_elements {
            coarse.iterations = iterations;
            if coarse.converged() {
                coarse.status = Status::ToleranceNotMet;
                coarse.message = format!(
                    "tolerance not met: no error estimate, the first resolving n = {n} leaves no finer n within max_elements {}",
                    accuracy.max_elements
                );
            }
            return Ok(coarse);
        }
        crate::interrupt::check()?;
        let warm = refine(&coarse.quaternions);
        let mut fine = Solver::new(
            scene,
            Settings {
                n_elements: Some(2 * n),
                ..settings.clone()
            },
        )?
        .solve(Some(&warm))?;
        iterations += fine.iterations;
        if !usable(&fine) {
            fine.iterations = iterations;
            return Ok(fine);
        }
        let (r_n, r_2n) = (coarse.tip_position(), fine.tip_position());
        // The whole backbone: a held tip never moves, so the tip alone would
        // estimate the error of a pinned rod as zero.
        let estimate = backbone_difference(&coarse, &fine) / 3.0;
        let asymptotic = coarse.converged() && max_turn(scene, &coarse) <= ASYMPTOTIC_TURN;
        let met = asymptotic && estimate <= accuracy.tol * length;
        if met || 4 * n > accuracy.max_elements {
            fine.iterations = iterations;
            fine.error_estimate = asymptotic.then_some(estimate);
            if accuracy.richardson && asymptotic {
                fine.extrapolated_tip = Some((4.0 * r_2n - r_n) / 3.0);
            }
            if !met && fine.converged() {
                fine.status = Status::ToleranceNotMet;
                fine.message = format!(
                    "tolerance not met: {} elements reached the limit (max_elements {}), error estimate {estimate:.2e} m > tol * L = {:.2e} m",
                    2 * n,
                    accuracy.max_elements,
                    accuracy.tol * length
                );
            }
            return Ok(fine);
        }
        coarse = fine;
        n *= 2;
    }
}

/// Largest distance between the nodes of `coarse` and the same nodes of the
/// twice finer `fine` [m].
fn backbone_difference(coarse: &Solution, fine: &Solution) -> f64 {
    coarse
        .positions
        .iter()
        .zip(fine.positions.iter().step_by(2))
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
}

/// Largest element turning of a solution [rad], rest turning included.
fn max_turn(scene: &Scene, sol: &Solution) -> f64 {
    let ds = scene.length / sol.n_elements as f64;
    let rest = scene
        .rest_curvature
        .iter()
        .map(|k| ds * k[0].hypot(k[1]))
        .fold(0.0, f64::max);
    sol.quaternions
        .windows(2)
        .map(|p| element_turn(p[0], p[1]))
        .fold(rest, f64::max)
}

/// The nodes of a twice finer discretisation: every node kept, a midpoint
/// (half-way rotation) between neighbours.
fn refine(q: &[Quat]) -> Vec<Quat> {
    let mut out = Vec::with_capacity(2 * q.len() - 1);
    for pair in q.windows(2) {
        out.push(pair[0]);
        out.push(slerp(pair[0], pair[1], 0.5));
    }
    out.push(q[q.len() - 1]);
    out
}
