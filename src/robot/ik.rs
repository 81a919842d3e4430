//! Load-aware inverse kinematics: the section curvatures whose *loaded*
//! equilibrium puts the tip at the target, the one closest to a reference among
//! the many that do.
//!
//! Each iteration solves the forward statics (warm), takes the tip's sensitivity
//! to the curvatures from the factored equilibrium Jacobian (O(n) a column), and
//! steps by the minimum-norm Gauss-Newton rule
//! `delta = r + J^T (J J^T)^{-1} (e - J r)`, `r = kappa_ref - kappa`, with a
//! backtracking line search on the tip error. At a solution, `kappa - kappa_ref`
//! is orthogonal to the directions that keep the tip in place: the first-order
//! condition of the minimum-norm choice. A target out of reach ends in
//! Levenberg-Marquardt on the tip error alone, which finds the closest tip.

use super::Robot;
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::solver::{Settings, Solution, Solver};
use nalgebra::{DMatrix, DVector, Vector3};

/// Relative accuracy to which the actuation is the one closest to the reference.
const MIN_NORM_ACCURACY: f64 = 1e-5;

/// How the actuation is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// The loaded equilibrium reaches the target (default).
    Equilibrium,
    /// The seed's way: fit the sections to the target ignoring weight and load,
    /// then apply that actuation to the loaded robot (it misses under load).
    Geometric,
}

/// Options of one inverse solve.
#[derive(Debug, Clone, PartialEq)]
pub struct IkOptions {
    /// Tip mass [kg] (default 0).
    pub tip_mass: f64,
    /// Actuation to stay closest to (default: zero curvature).
    pub reference: Option<Vec<[f64; 2]>>,
    /// Also reach this tip direction (unit vector, world frame).
    pub direction: Option<Vector3<f64>>,
    pub strategy: Strategy,
    /// Tip position tolerance [m] (default 1e-9); a direction's tolerance is tol / L.
    pub tol: f64,
    /// Iteration limit (default 60).
    pub max_iterations: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            tip_mass: 0.0,
            reference: None,
            direction: None,
            strategy: Strategy::Equilibrium,
            tol: 1e-9,
            max_iterations: 60,
        }
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
    /// The loaded equilibrium with this actuation.
    pub solution: Solution,
    pub tip_position: Vector3<f64>,
    /// Distance from the tip to the target [m].
    pub tip_miss: f64,
    /// Whether the target (and direction) was reached within the tolerance.
    pub reached: bool,
    pub message: String,
    pub iterations: usize,
    /// Wall-clock time of this inverse solve [s].
    pub seconds: f64,
}

/// Inverse kinematics of one robot under one tip mass, reusing its forward
/// solver and the last answer as the warm start of the next (trajectories).
pub struct InverseSolver {
    robot: Robot,
    solver: Solver,
    kappa: Vec<[f64; 2]>,
    q: Option<Vec<Quat>>,
}

impl InverseSolver {
    pub fn new(robot: &Robot, tip_mass: f64) -> Result<Self> {
        let zero = vec![[0.0; 2]; robot.sections];
        let scene = robot.scene(&zero, tip_mass)?;
        let settings = Settings {
            n_elements: robot.n_elements,
            residual_tol: 1e-12,
            ..Settings::default()
        };
        Ok(InverseSolver {
            robot: robot.clone(),
            solver: Solver::new(&scene, settings)?,
            kappa: zero,
            q: None,
        })
    }

    /// Forward statics at `kappa`, warm from the last state.
    fn forward(&mut self, kappa: &[[f64; 2]]) -> Result<Solution> {
        self.solver.set_rest_curvature(kappa)?;
        let sol = self.solver.solve(self.q.as_deref())?;
        if !sol.converged() {
            // A far warm start can fail where the straight rod succeeds.
            return self.solver.solve(None);
        }
        Ok(sol)
    }

    /// Tip error (and weighted direction error) of an equilibrium.
    fn error(
        &self,
        sol: &Solution,
        target: &Vector3<f64>,
        direction: Option<&Vector3<f64>>,
    ) -> DVector<f64> {
        let mut e = DVector::zeros(if direction.is_some() { 6 } else { 3 });
        let d = target - sol.tip_position();
        e.rows_mut(0, 3).copy_from(&d);
        if let Some(dir) = direction {
            let t = sol.tip_quaternion().tangent();
            e.rows_mut(3, 3).copy_from(&((dir - t) * self.robot.length));
        }
        e
    }

    fn jacobian(&mut self, direction: bool) -> Result<DMatrix<f64>> {
        let sens = self.solver.tip_sensitivity(self.robot.sections)?;
        let cols = 2 * self.robot.sections;
        let mut j = DMatrix::zeros(if direction { 6 } else { 3 }, cols);
        j.rows_mut(0, 3).copy_from(&sens.position);
        if direction {
            j.rows_mut(3, 3)
                .copy_from(&(sens.tangent * self.robot.length));
        }
        Ok(j)
    }

    /// The actuation whose loaded equilibrium puts the tip at `target`.
    pub fn solve(
        &mut self,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        reference: Option<&[[f64; 2]]>,
        tol: f64,
        max_iterations: usize,
    ) -> Result<IkResult> {
        let started = std::time::Instant::now();
        let m = self.robot.sections;
        if target.iter().any(|x| !x.is_finite()) {
            return Err(Error::argument("target", "must be finite"));
        }
        let direction = match direction {
            Some(d) if d.iter().all(|x| x.is_finite()) && d.norm() > 0.0 => Some(d.normalize()),
            Some(_) => {
                return Err(Error::argument(
                    "direction",
                    "must be a finite non-zero vector",
                ))
            }
            None => None,
        };
        let reference: Vec<[f64; 2]> = match reference {
            Some(r) if r.len() == m => r.to_vec(),
            Some(r) => {
                return Err(Error::argument(
                    "reference",
                    format!("expected {m} sections, got {}", r.len()),
                ))
            }
            None => vec![[0.0; 2]; m],
        };
        // Direction rows are weighted by L: tol on them is an angle of tol / L.
        let dir_tol = tol;
        // Start at the reference: the Gauss-Newton path from there to the nearest
        // solution is short, while sliding along the solution set from elsewhere
        // converges only linearly (for tracking, the reference is the last answer).
        let mut kappa = reference.clone();
        let mut sol = self.forward(&kappa)?;
        let mut e = self.error(&sol, &target, direction.as_ref());
        let mut iterations = 0;
        let mut clamped = false;
        let reached = |e: &DVector<f64>| {
            e.rows(0, 3).norm() <= tol && (e.len() == 3 || e.rows(3, 3).norm() <= dir_tol)
        };
        // Phase 1: minimum-norm Gauss-Newton with backtracking.
        let mut stalled = false;
        while iterations < max_iterations {
            iterations += 1;
            let j = self.jacobian(direction.is_some())?;
            let r = flatten(&reference) - flatten(&kappa);
            let jjt = &j * j.transpose();
            let eps = 1e-14 * jjt.trace().max(f64::MIN_POSITIVE);
            let Some(inv) = (jjt + DMatrix::identity(e.len(), e.len()) * eps).try_inverse() else {
                stalled = true;
                break;
            };
            let step = &r + j.transpose() * (inv * (&e - &j * &r));
            let size = 1.0 + flatten(&kappa).norm();
            if reached(&e) && step.norm() <= 1e-12 * size {
                break;
            }
            let mut alpha = 1.0;
            let mut accepted = false;
            while alpha > 1e-3 {
                let mut trial = unflatten(&(flatten(&kappa) + &step * alpha));
                let was_clamped = self.robot.clamp_to_bounds(&mut trial);
                let trial_sol = self.forward(&trial)?;
                if trial_sol.converged() {
                    let trial_e = self.error(&trial_sol, &target, direction.as_ref());
                    // Decrease the error, or keep it within tolerance while moving
                    // toward the reference (the minimum-norm part of the step).
                    if trial_e.norm() < (1.0 - 1e-4 * alpha) * e.norm()
                        || (reached(&trial_e) && reached(&e))
                    {
                        kappa = trial;
                        clamped = was_clamped;
                        self.q = Some(trial_sol.quaternions.clone());
                        sol = trial_sol;
                        e = trial_e;
                        accepted = true;
                        break;
                    }
                }
                alpha *= 0.5;
            }
            if !accepted {
                // Re-establish the solver's state at the current point.
                sol = self.forward(&kappa)?;
                stalled = true;
                break;
            }
            // The tip is on target and the last full step, which moves along
            // the solution set toward the reference, changed the actuation by
            // less than 1e-5 of its size: the minimum-norm choice is settled to
            // that accuracy (Gauss-Newton converges only linearly along the set;
            // the tip itself converges quadratically and is at tol).
            if reached(&e) && alpha == 1.0 && step.norm() <= MIN_NORM_ACCURACY * size {
                break;
            }
        }
        // Phase 2 (out of reach or limited by the muscles): closest tip by LM on the error alone.
        if !reached(&e) && stalled {
            let mut mu = 1e-6;
            while iterations < max_iterations {
                iterations += 1;
                let j = self.jacobian(direction.is_some())?;
                let jtj = j.transpose() * &j;
                let scale = jtj.trace() / jtj.nrows() as f64;
                let Some(inv) =
                    (jtj + DMatrix::identity(2 * m, 2 * m) * (mu * scale)).try_inverse()
                else {
                    break;
                };
                let step = inv * (j.transpose() * &e);
                let mut trial = unflatten(&(flatten(&kappa) + step));
                let was_clamped = self.robot.clamp_to_bounds(&mut trial);
                let trial_sol = self.forward(&trial)?;
                let trial_e = self.error(&trial_sol, &target, direction.as_ref());
                if trial_sol.converged() && trial_e.norm() < e.norm() {
                    let gain = e.norm() - trial_e.norm();
                    kappa = trial;
                    clamped = was_clamped;
                    self.q = Some(trial_sol.quaternions.clone());
                    sol = trial_sol;
                    e = trial_e;
                    mu = (mu / 3.0).max(1e-12);
                    if gain <= 1e-12 * (1.0 + e.norm()) || reached(&e) {
                        break;
                    }
                } else {
                    sol = self.forward(&kappa)?;
                    mu *= 4.0;
                    if mu > 1e8 {
                        break;
                    }
                }
            }
        }
        self.kappa = kappa.clone();
        self.q = Some(sol.quaternions.clone());
        let ok = reached(&e);
        let miss = e.rows(0, 3).norm();
        let message = if ok {
            "reached".to_string()
        } else if clamped {
            format!("not reached: the muscles' length range limits the actuation; the closest tip found misses by {miss:.3e} m")
        } else if stalled {
            format!("not reached: the target is out of reach; the closest tip found misses by {miss:.3e} m")
        } else {
            format!("not reached after {iterations} iterations: the tip misses by {miss:.3e} m")
        };
        let mut result = self.result(kappa, sol, miss, ok, message, iterations);
        result.seconds = started.elapsed().as_secs_f64();
        Ok(result)
    }

    fn result(
        &self,
        kappa: Vec<[f64; 2]>,
        sol: Solution,
        miss: f64,
        reached: bool,
        message: String,
        iterations: usize,
    ) -> IkResult {
        let lengths = self.robot.muscle_lengths(&kappa);
        IkResult {
            inflation_times: self.robot.inflation_times(&lengths),
            muscle_lengths: lengths,
            rest_curvature: kappa,
            tip_position: sol.tip_position(),
            solution: sol,
            tip_miss: miss,
            reached,
            message,
            iterations,
            seconds: 0.0,
        }
    }
}

fn flatten(k: &[[f64; 2]]) -> DVector<f64> {
    DVector::from_iterator(2 * k.len(), k.iter().flat_map(|x| x.iter().copied()))
}

fn unflatten(v: &DVector<f64>) -> Vec<[f64; 2]> {
    v.as_slice().chunks(2).map(|c| [c[0], c[1]]).collect()
}

impl Robot {
    /// Load-aware inverse kinematics of one target (see [`IkOptions`]).
    pub fn inverse(&self, target: Vector3<f64>, options: &IkOptions) -> Result<IkResult> {
        Ok(self.track(&[target], options)?.remove(0))
    }

    /// Inverse kinematics of a sequence of targets, each warm-started from the
    /// previous one and choosing the actuation closest to it (smooth motion).
    pub fn track(&self, targets: &[Vector3<f64>], options: &IkOptions) -> Result<Vec<IkResult>> {
        if !(options.tol.is_finite() && options.tol > 0.0) {
            return Err(Error::argument("tol", "must be positive"));
        }
        let mut loaded = InverseSolver::new(self, options.tip_mass)?;
        let mut weightless = match options.strategy {
            Strategy::Equilibrium => None,
            Strategy::Geometric => Some(InverseSolver::new(&self.weightless(), 0.0)?),
        };
        let mut reference = options.reference.clone();
        let mut out = Vec::with_capacity(targets.len());
        for target in targets {
            let result = match weightless.as_mut() {
                None => loaded.solve(
                    *target,
                    options.direction,
                    reference.as_deref(),
                    options.tol,
                    options.max_iterations,
                )?,
                Some(geometric) => {
                    let started = std::time::Instant::now();
                    let fit = geometric.solve(
                        *target,
                        options.direction,
                        reference.as_deref(),
                        options.tol,
                        options.max_iterations,
                    )?;
                    let sol = loaded.forward(&fit.rest_curvature)?;
                    loaded.q = Some(sol.quaternions.clone());
                    let miss = (sol.tip_position() - target).norm();
                    let message = format!(
                        "geometric fit (load ignored): the loaded tip misses by {miss:.3e} m"
                    );
                    let mut r = loaded.result(
                        fit.rest_curvature,
                        sol,
                        miss,
                        miss <= options.tol,
                        message,
                        fit.iterations,
                    );
                    r.seconds = started.elapsed().as_secs_f64();
                    r
                }
            };
            reference = Some(result.rest_curvature.clone());
            out.push(result);
        }
        Ok(out)
    }
}
