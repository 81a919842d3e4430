//! The seed paper's method, faithfully: the least-squares problem of its Eq. 50/51
//! over `X = [q_1..q_n, F_0..F_n]` (raw quaternions and nodal internal forces),
//! solved as its Algorithm 1: a particle swarm for the initial value (phase 1
//! plain, phase 2 with the global best moved by a damped Gauss-Newton step with
//! Armijo backtracking), then Levenberg-Marquardt with the gain-ratio update of
//! the damping.
//!
//! The rows are the published ones with docs/model.md's corrections: the torque
//! balance of every node from the variation of the discrete potential (with the
//! forces as unknowns), the force balance in the world frame
//! `(F_i - F_{i-1})/ds + f = 0`, the tip condition (`F_n = P`, or the tip held),
//! and a unit-norm row `|q_j|^2 - 1` per node. `literal` drops the unit-norm rows,
//! as printed: the system is then underdetermined and its least-squares solutions
//! let `|q|` drift (the collapse docs/model.md describes).
//!
//! The Jacobian is taken by central differences (the paper gives none), so this
//! method is slow by design; `newton` solves the same discrete equilibrium.

pub mod pso;

use crate::error::{Error, Result};
use crate::interrupt;
use crate::model::RodModel;
use crate::quat::{tangent_form_apply, Quat};
use crate::read::{as_argument, count, finite, whole};
use crate::scene::{Scene, TipCondition};
use crate::value::Value;
use nalgebra::{DMatrix, DVector, Vector3};
use pso::{Swarm, SwarmSettings};

/// Settings of the paper's method; every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct PaperSettings {
    /// The particle swarm (phase 1).
    pub swarm: SwarmSettings,
    /// Phase 2: swarm iterations, each followed by a Gauss-Newton step on the
    /// global best (default 20).
    pub gauss_newton_iterations: usize,
    /// Levenberg-Marquardt iteration limit (default 200).
    pub lm_iterations: usize,
    /// Tolerance on the largest scaled residual row (default 1e-10).
    pub tol: f64,
}

impl Default for PaperSettings {
    fn default() -> Self {
        PaperSettings {
            swarm: SwarmSettings::default(),
            gauss_newton_iterations: 20,
            lm_iterations: 200,
            tol: 1e-10,
        }
    }
}

impl PaperSettings {
    /// Every key of [`PaperSettings::set`]: the swarm's fields and the method's.
    pub const KEYS: [&'static str; 10] = [
        "particles",
        "iterations",
        "chi",
        "inertia",
        "c1",
        "c2",
        "seed",
        "gauss_newton_iterations",
        "lm_iterations",
        "tol",
    ];

    /// Set one field from a value, named by [`PaperSettings::KEYS`] (the
    /// swarm's fields flat); ranges are [`validate`](PaperSettings::validate)'s.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        self.set_field(key, value).map_err(as_argument)
    }

    fn set_field(&mut self, key: &str, value: &Value) -> Result<()> {
        let counted = |max: f64| whole(value, key, max).map(|x| x as usize);
        let sw = &mut self.swarm;
        match key {
            "particles" => sw.particles = count(value, key, 1_000_000_000)?,
            "iterations" => sw.iterations = counted(1e9)?,
            "chi" => sw.chi = finite(value, key)?,
            "inertia" => sw.inertia = finite(value, key)?,
            "c1" => sw.c1 = finite(value, key)?,
            "c2" => sw.c2 = finite(value, key)?,
            // Seeds up to 2^53: every one a double holds exactly.
            "seed" => sw.seed = whole(value, key, 9_007_199_254_740_992.0)? as u64,
            "gauss_newton_iterations" => self.gauss_newton_iterations = counted(1e9)?,
            "lm_iterations" => self.lm_iterations = counted(1e9)?,
            "tol" => self.tol = finite(value, key)?,
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

    /// Every field as a flat table of [`PaperSettings::KEYS`].
    pub fn to_value(&self) -> Value {
        let sw = &self.swarm;
        let numbers = [
            sw.particles as f64,
            sw.iterations as f64,
            sw.chi,
            sw.inertia,
            sw.c1,
            sw.c2,
            sw.seed as f64,
            self.gauss_newton_iterations as f64,
            self.lm_iterations as f64,
            self.tol,
        ];
        Value::Map(
            Self::KEYS
                .iter()
                .zip(numbers)
                .map(|(k, x)| (k.to_string(), Value::Number(x)))
                .collect(),
        )
    }

    /// Refuse settings that cannot run or cannot mean anything, naming the field.
    pub fn validate(&self) -> Result<()> {
        crate::read::check_tolerance("paper.tol", self.tol, (1e-14, 1e-4))?;
        let sw = &self.swarm;
        if sw.particles == 0 || sw.particles > 100_000 {
            return Err(Error::argument(
                "paper.particles",
                format!("must lie in [1, 100000], got {}", sw.particles),
            ));
        }
        for (name, v) in [
            ("paper.chi", sw.chi),
            ("paper.inertia", sw.inertia),
            ("paper.c1", sw.c1),
            ("paper.c2", sw.c2),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::argument(
                    name,
                    format!("must be finite and not negative, got {v}"),
                ));
            }
        }
        for (name, v) in [
            ("paper.iterations", sw.iterations),
            (
                "paper.gauss_newton_iterations",
                self.gauss_newton_iterations,
            ),
            ("paper.lm_iterations", self.lm_iterations),
        ] {
            if v > 1_000_000 {
                return Err(Error::argument(
                    name,
                    format!("must be at most 1000000, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// What the paper's method returns.
#[derive(Debug, Clone)]
pub struct PaperOutcome {
    /// Node quaternions `q_0..q_n` as solved (not renormalised: the literal
    /// system's drift shows here).
    pub quaternions: Vec<Quat>,
    /// Positions from those quaternions by the model's mean tangents [m].
    pub positions: Vec<Vector3<f64>>,
    /// Nodal internal forces `F_0..F_n`, world frame [N].
    pub forces: Vec<Vector3<f64>>,
    pub converged: bool,
    pub pso_iterations: usize,
    pub gauss_newton_iterations: usize,
    pub lm_iterations: usize,
    /// Largest scaled residual row.
    pub residual_norm: f64,
    /// `max_j | |q_j| - 1 |`.
    pub max_norm_deviation: f64,
    pub message: String,
}

/// The least-squares system of Eq. 50/51 for one scene and discretisation.
struct PaperSystem {
    model: RodModel,
    literal: bool,
    distributed: Vector3<f64>,
    tip_force: Vector3<f64>,
    tip: TipCondition,
    clamped: Option<Quat>,
    /// Row scales: torque, force balance, tip force.
    torque_scale: f64,
    force_scale: f64,
}

impl PaperSystem {
    fn new(scene: &Scene, n: usize, literal: bool) -> Result<Self> {
        if !scene.guides.is_empty() || !scene.point_loads.is_empty() {
            return Err(Error::argument(
                "method",
                "the paper's formulation has no guides or point loads: use 'newton' or 'lm'",
            ));
        }
        let model = RodModel::new(scene, n);
        let kmax = model.stiffness().max();
        let l = model.length();
        Ok(PaperSystem {
            clamped: model.clamped_tip(),
            literal,
            distributed: scene.distributed_force(),
            tip_force: scene.tip_force,
            tip: scene.tip.clone(),
            torque_scale: l / kmax,
            force_scale: l * l / kmax,
            model,
        })
    }

    fn n(&self) -> usize {
        self.model.n()
    }

    fn unknowns(&self) -> usize {
        4 * self.n() + 3 * (self.n() + 1)
    }

    fn rows(&self) -> usize {
        7 * self.n() + 3 - if self.literal { self.n() } else { 0 }
    }

    fn unpack(&self, x: &[f64]) -> (Vec<Quat>, Vec<Vector3<f64>>) {
        let n = self.n();
        let mut q = vec![self.model.base(); n + 1];
        for (qj, c) in q[1..].iter_mut().zip(x[..4 * n].chunks(4)) {
            *qj = Quat::new(c[0], c[1], c[2], c[3]);
        }
        let f = (0..=n)
            .map(|j| {
                let k = 4 * n + 3 * j;
                Vector3::new(x[k], x[k + 1], x[k + 2])
            })
            .collect();
        (q, f)
    }

    fn pack(&self, q: &[Quat], f: &[Vector3<f64>]) -> Vec<f64> {
        let mut x = Vec::with_capacity(self.unknowns());
        for qj in &q[1..] {
            x.extend_from_slice(&qj.to_array());
        }
        for fj in f {
            x.extend_from_slice(fj.as_slice());
        }
        x
    }

    /// The scaled residual rows at `x`.
    fn residual(&self, x: &[f64], out: &mut [f64]) {
        let n = self.n();
        let (q, f) = self.unpack(x);
        let m = &self.model;
        let ds = m.ds();
        // Gradient of the discrete potential with respect to each raw quaternion.
        let mut grad = vec![Quat::new(0.0, 0.0, 0.0, 0.0); n + 1];
        let add = |g: &mut Quat, d: Quat| {
            g.w += d.w;
            g.v += d.v;
        };
        for i in 1..=n {
            let (a, b) = (q[i - 1], q[i]);
            let e = (2.0 / ds) * (a.conj() * b).v - m.rod().loading.rest_curvature[i - 1];
            let w = m.stiffness().component_mul(&e);
            let ga = a * Quat::pure(w); // G(a)^T w
            let gb = b * Quat::pure(w); // G(b)^T w
            add(&mut grad[i], scale(ga, 2.0));
            add(&mut grad[i - 1], scale(gb, -2.0));
            let fbar = 0.5 * (f[i - 1] + f[i]);
            let (sa, sb) = (tangent_form_apply(&fbar, a), tangent_form_apply(&fbar, b));
            let kappa = -ds / 3.0;
            add(&mut grad[i - 1], scale(sum(scale(sa, 2.0), sb), kappa));
            add(&mut grad[i], scale(sum(sa, scale(sb, 2.0)), kappa));
        }
        let mut row = 0;
        let mut push = |out: &mut [f64], v: &[f64]| {
            for x in v {
                out[row] = *x;
                row += 1;
            }
        };
        // h1: torque balance of every free node (a clamped tip node has none).
        let last_torque_node = if self.clamped.is_some() { n - 1 } else { n };
        for j in 1..=last_torque_node {
            let mut t = 0.5 * (q[j].conj() * grad[j]).v;
            if j == n {
                t -= q[n].normalized().inverse_rotate(m.tip_moment());
            }
            push(out, (t * self.torque_scale).as_slice());
        }
        // h2: force balance of every element, world frame.
        for i in 1..=n {
            let r = ((f[i] - f[i - 1]) / ds + self.distributed) * (self.force_scale * m.length());
            push(out, r.as_slice());
        }
        // h3: the tip condition.
        match &self.tip {
            TipCondition::Free => {
                push(out, ((f[n] - self.tip_force) * self.force_scale).as_slice());
            }
            TipCondition::Pinned { position } | TipCondition::Clamped { position, .. } => {
                let mut r = vec![Vector3::zeros(); n + 1];
                m.positions(&q, &mut m.new_interior(), &mut r);
                push(out, ((r[n] - position) / m.length()).as_slice());
            }
        }
        if let Some(target) = self.clamped {
            push(out, (2.0 * (target.conj() * q[n]).v).as_slice());
        }
        // h4: unit norm (the correction; absent from the literal system).
        if !self.literal {
            for qj in &q[1..] {
                push(out, &[qj.dot(*qj) - 1.0]);
            }
        }
        debug_assert_eq!(row, self.rows());
    }

    fn sum_squares(&self, x: &[f64], scratch: &mut [f64]) -> f64 {
        self.residual(x, scratch);
        scratch.iter().map(|r| r * r).sum()
    }

    /// Central-difference Jacobian.
    fn jacobian(&self, x: &[f64]) -> DMatrix<f64> {
        let (rows, cols) = (self.rows(), self.unknowns());
        let mut j = DMatrix::zeros(rows, cols);
        let mut xp = x.to_vec();
        let (mut rp, mut rm) = (vec![0.0; rows], vec![0.0; rows]);
        for c in 0..cols {
            let h = 1e-6 * (1.0 + x[c].abs());
            xp[c] = x[c] + h;
            self.residual(&xp, &mut rp);
            xp[c] = x[c] - h;
            self.residual(&xp, &mut rm);
            xp[c] = x[c];
            for r in 0..rows {
                j[(r, c)] = (rp[r] - rm[r]) / (2.0 * h);
            }
        }
        j
    }

    /// The straight rod with the statics of its forces: one particle of the swarm.
    fn straight_guess(&self) -> Vec<f64> {
        let m = &self.model;
        let q = vec![m.base(); m.n() + 1];
        let f: Vec<Vector3<f64>> = m.rod().loading.node_force.clone();
        self.pack(&q, &f)
    }

    fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let m = &self.model;
        let load = self.tip_force.norm() + self.distributed.norm() * m.length();
        let bound = 2.0 * load + 10.0 * m.stiffness().max() / (m.length() * m.length());
        let n = m.n();
        let mut lower = vec![-1.0; 4 * n];
        let mut upper = vec![1.0; 4 * n];
        lower.extend(std::iter::repeat_n(-bound, 3 * (n + 1)));
        upper.extend(std::iter::repeat_n(bound, 3 * (n + 1)));
        (lower, upper)
    }
}

fn scale(q: Quat, s: f64) -> Quat {
    Quat {
        w: q.w * s,
        v: q.v * s,
    }
}

fn sum(a: Quat, b: Quat) -> Quat {
    Quat {
        w: a.w + b.w,
        v: a.v + b.v,
    }
}

/// Largest absolute row; infinite if any row is not finite (NaN is never dropped).
fn max_abs(r: &[f64]) -> f64 {
    r.iter().fold(0.0, |m, x| {
        if x.is_finite() {
            m.max(x.abs())
        } else {
            f64::INFINITY
        }
    })
}

/// Solve `scene` by the paper's method (`literal`: without the unit-norm rows).
pub fn solve_paper(
    scene: &Scene,
    n: usize,
    settings: &PaperSettings,
    literal: bool,
) -> Result<PaperOutcome> {
    scene.check_elements(n)?;
    if let Some(what) = scene.only_the_potential_models() {
        return Err(Error::argument(
            "method",
            format!("the paper's method does not model {what}; use 'newton' or 'lm'"),
        ));
    }
    if scene.check_constraints(n)?.is_some() {
        return Err(Error::argument(
            "tip",
            "a target at full reach has no well-defined reaction",
        ));
    }
    let system = PaperSystem::new(scene, n, literal)?;
    let rows = system.rows();
    let objective = |x: &[f64]| -> f64 {
        let mut r = vec![0.0; rows];
        system.sum_squares(x, &mut r)
    };
    // Phase 1: the plain swarm.
    let (lower, upper) = system.bounds();
    let swarm_settings = &settings.swarm;
    let mut swarm = Swarm::new(
        swarm_settings,
        lower,
        upper,
        &[system.straight_guess()],
        &objective,
    );
    for _ in 0..swarm_settings.iterations {
        if interrupt::requested() {
            break;
        }
        swarm.step(swarm_settings, &objective);
    }
    // Phase 2: the swarm with a damped Gauss-Newton step on its global best.
    let mut scratch = vec![0.0; rows];
    for _ in 0..settings.gauss_newton_iterations {
        if interrupt::requested() {
            break;
        }
        swarm.step(swarm_settings, &objective);
        let x = swarm.best.clone();
        if let Some((moved, value)) = gauss_newton_step(&system, &x, swarm.best_value, &mut scratch)
        {
            swarm.set_best(moved, value);
        }
    }
    // Phase 3: Levenberg-Marquardt with the gain-ratio update.
    let (x, lm_iterations) = levenberg_marquardt(&system, swarm.best.clone(), settings);
    interrupt::check()?;
    system.residual(&x, &mut scratch);
    let residual_norm = max_abs(&scratch);
    let (q, forces) = system.unpack(&x);
    let mut positions = vec![Vector3::zeros(); n + 1];
    system
        .model
        .positions(&q, &mut system.model.new_interior(), &mut positions);
    let max_norm_deviation = q[1..]
        .iter()
        .map(|qj| (qj.norm() - 1.0).abs())
        .fold(0.0, f64::max);
    let converged = residual_norm <= settings.tol;
    let message = if converged {
        format!(
            "converged (paper's method{})",
            if literal { ", literal" } else { "" }
        )
    } else {
        format!("not converged: largest residual row {residual_norm:.2e} after {lm_iterations} LM iterations")
    };
    Ok(PaperOutcome {
        quaternions: q,
        positions,
        forces,
        converged,
        pso_iterations: swarm_settings.iterations + settings.gauss_newton_iterations,
        gauss_newton_iterations: settings.gauss_newton_iterations,
        lm_iterations,
        residual_norm,
        max_norm_deviation,
        message,
    })
}

/// One damped Gauss-Newton step with Armijo backtracking on `|r|^2`.
fn gauss_newton_step(
    system: &PaperSystem,
    x: &[f64],
    value: f64,
    scratch: &mut [f64],
) -> Option<(Vec<f64>, f64)> {
    system.residual(x, scratch);
    let r = DVector::from_column_slice(scratch);
    let j = system.jacobian(x);
    let jtj = j.transpose() * &j;
    let damping = 1e-9 * jtj.trace() / jtj.nrows() as f64 + f64::MIN_POSITIVE;
    let step = (jtj + DMatrix::identity(x.len(), x.len()) * damping)
        .cholesky()?
        .solve(&(-(j.transpose() * &r)));
    let slope = -2.0 * (j.transpose() * &r).dot(&step).abs();
    let mut alpha = 1.0;
    while alpha > 1e-6 {
        let trial: Vec<f64> = x
            .iter()
            .zip(step.iter())
            .map(|(a, d)| a + alpha * d)
            .collect();
        let v = system.sum_squares(&trial, scratch);
        if v <= value + 1e-4 * alpha * slope {
            return Some((trial, v));
        }
        alpha *= 0.5;
    }
    None
}

/// Levenberg-Marquardt: shrink `mu` when the gain ratio exceeds 0.75, grow it
/// when it falls below 0.45 (the seed's thresholds).
fn levenberg_marquardt(
    system: &PaperSystem,
    mut x: Vec<f64>,
    settings: &PaperSettings,
) -> (Vec<f64>, usize) {
    let rows = system.rows();
    let mut r = vec![0.0; rows];
    let mut value = system.sum_squares(&x, &mut r);
    let mut j = system.jacobian(&x);
    let mut mu = 1e-3 * (j.transpose() * &j).diagonal().max();
    let mut trial_r = vec![0.0; rows];
    for it in 0..settings.lm_iterations {
        if max_abs(&r) <= settings.tol || interrupt::requested() {
            return (x, it);
        }
        let rv = DVector::from_column_slice(&r);
        let jtj = j.transpose() * &j;
        let g = j.transpose() * &rv;
        let Some(chol) = (jtj + DMatrix::identity(x.len(), x.len()) * mu).cholesky() else {
            mu *= 2.0;
            continue;
        };
        let step = chol.solve(&(-&g));
        let trial: Vec<f64> = x.iter().zip(step.iter()).map(|(a, d)| a + d).collect();
        let trial_value = system.sum_squares(&trial, &mut trial_r);
        let predicted = value - (&rv + &j * &step).norm_squared();
        let gain = (value - trial_value) / predicted.max(f64::MIN_POSITIVE);
        if gain > 0.0 && trial_value.is_finite() {
            x = trial;
            value = trial_value;
            r.copy_from_slice(&trial_r);
            j = system.jacobian(&x);
        }
        if gain > 0.75 {
            mu /= 3.0;
        } else if gain < 0.45 {
            mu *= 2.0;
        }
        if !mu.is_finite() || mu > 1e30 {
            return (x, it + 1);
        }
    }
    (x, settings.lm_iterations)
}
