//! Levenberg-Marquardt on the same residual and minimal update as Newton, with
//! the damped normal equations `(J^T J + mu I) d = -J^T r` solved densely by
//! faer's Cholesky. It is the general-purpose least-squares baseline (and the
//! finishing stage of the paper's method): robust, but O(n^3) per iteration.
//!
//! For a constrained scene the unknowns are the rotations and the reactions,
//! the residual is the torque balance and the weighted held-point rows, and `J`
//! is the whole KKT matrix `[[A, -D^T], [W D, 0]]`.

use super::constrained::{self, load_constraint_jacobian, position_weight};
use super::{step_limit, LocalOutcome, LocalSolver, Workspace};
use crate::interrupt;
use crate::model::RodModel;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::{
    factor::cholesky_in_place, factor::cholesky_in_place_scratch, solve::solve_in_place,
};
use faer::{Accum, Mat, Par};
use nalgebra::Vector3;

pub(crate) struct LevenbergMarquardt {
    jac: Mat<f64>,
    normal: Mat<f64>,
    factor: Mat<f64>,
    residual: Mat<f64>,
    rhs: Mat<f64>,
    predicted: Mat<f64>,
    buffer: MemBuffer,
}

/// Gain-ratio thresholds of the damping update: shrink `mu` above the first,
/// grow it below the second (the seed's Algorithm 1).
const GAIN_SHRINK: f64 = 0.75;
const GAIN_GROW: f64 = 0.45;

impl LevenbergMarquardt {
    pub(crate) fn new(model: &RodModel) -> Self {
        let dim = 3 * (model.n() + model.constraints().len());
        LevenbergMarquardt {
            jac: Mat::zeros(dim, dim),
            normal: Mat::zeros(dim, dim),
            factor: Mat::zeros(dim, dim),
            residual: Mat::zeros(dim, 1),
            rhs: Mat::zeros(dim, 1),
            predicted: Mat::zeros(dim, 1),
            buffer: MemBuffer::new(cholesky_in_place_scratch::<f64>(
                dim,
                Par::Seq,
                Default::default(),
            )),
        }
    }

    /// Residual and Jacobian at the workspace state into the dense buffers,
    /// then `J^T J`. Returns the merit `|r|^2`.
    fn load(&mut self, model: &RodModel, w: &mut Workspace, lambda: f64) -> f64 {
        let n = model.n();
        let merit = evaluate(model, w, lambda, true);
        self.jac.fill(0.0);
        // Torque rows over their own scales, as in the residual norm and merit.
        let row_scale = model.residual_scale();
        w.jac
            .for_each_entry(|r, c, v| self.jac[(r, c)] = v / row_scale[r % 3]);
        if model.is_constrained() {
            load_constraint_jacobian(model, w);
            let wt = position_weight(model);
            for (ci, d) in w.kkt.d[..model.constraints().len()].iter().enumerate() {
                for (j, block) in d.iter().enumerate() {
                    for a in 0..3 {
                        for b in 0..3 {
                            // g depends on R through -D^T R; h on theta through D.
                            self.jac[(3 * j + b, 3 * (n + ci) + a)] = -block[(a, b)] / row_scale[b];
                            self.jac[(3 * (n + ci) + a, 3 * j + b)] = wt * block[(a, b)];
                        }
                    }
                }
            }
        }
        self.load_residual(model, w);
        faer::linalg::matmul::matmul(
            self.normal.as_mut(),
            Accum::Replace,
            self.jac.transpose(),
            self.jac.as_ref(),
            1.0,
            Par::Seq,
        );
        merit
    }

    fn load_residual(&mut self, model: &RodModel, w: &Workspace) {
        let n = model.n();
        let wt = position_weight(model);
        for (j, g) in w.g.iter().enumerate() {
            for r in 0..3 {
                self.residual[(3 * j + r, 0)] = g[r] / model.residual_scale()[r];
            }
        }
        // The workspace is sized for the scene; a released leg holds nothing.
        for (c, h) in w.kkt.h[..model.constraints().len()].iter().enumerate() {
            for r in 0..3 {
                self.residual[(3 * (n + c) + r, 0)] = wt * h[r];
            }
        }
    }
}

/// Residual (and Jacobian) of a free or constrained scene; the merit `|r|^2`.
fn evaluate(model: &RodModel, w: &mut Workspace, lambda: f64, with_jacobian: bool) -> f64 {
    if model.is_constrained() {
        constrained::evaluate(model, w, lambda, with_jacobian)
    } else {
        if with_jacobian {
            model.residual_jacobian(&w.q, lambda, &mut w.interior, &mut w.g, &mut w.jac);
        } else {
            model.residual(&w.q, lambda, &mut w.interior, &mut w.g);
        }
        model.merit(&w.g)
    }
}

/// Convergence as Newton certifies it: the residual within `tol` and the
/// Newton step from the state (its distance from the equilibrium) below
/// `tol` rad. The residual alone let an iteration limit's last state pass as
/// converged (8 of 326 random scenes, all of them unstable).
fn certified(model: &RodModel, w: &mut Workspace, lambda: f64, tol: f64) -> bool {
    let mut newton = super::newton::Newton;
    newton.run(model, w, lambda, 0, tol).converged
}

fn norm(model: &RodModel, w: &Workspace) -> f64 {
    if model.is_constrained() {
        constrained::residual_norm(model, w)
    } else {
        model.residual_norm(&w.g)
    }
}

impl LocalSolver for LevenbergMarquardt {
    fn for_model(&self, model: &RodModel) -> Box<dyn LocalSolver + Send + Sync> {
        Box::new(LevenbergMarquardt::new(model))
    }

    fn run(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome {
        let n = model.n();
        let m = model.constraints().len();
        let dim = 3 * (n + m);
        if let Some(tip) = model.clamped_tip_at(lambda) {
            w.q[n] = tip;
        }
        let mut merit = self.load(model, w, lambda);
        let max_diag = (0..dim).map(|i| self.normal[(i, i)]).fold(0.0, f64::max);
        let mut mu = 1e-6 * max_diag.max(f64::MIN_POSITIVE);
        for it in 0..max_iter {
            let residual = norm(model, w);
            if !residual.is_finite() || interrupt::requested() {
                return LocalOutcome {
                    converged: false,
                    iterations: it,
                };
            }
            if residual <= tol && certified(model, w, lambda, tol) {
                return LocalOutcome {
                    converged: true,
                    iterations: it,
                };
            }
            self.factor.copy_from(&self.normal);
            for i in 0..dim {
                self.factor[(i, i)] += mu;
            }
            let stack = MemStack::new(&mut self.buffer);
            let factored = cholesky_in_place(
                self.factor.as_mut(),
                Default::default(),
                Par::Seq,
                stack,
                Default::default(),
            );
            if factored.is_err() {
                mu *= 4.0;
                continue;
            }
            // rhs = -J^T r
            faer::linalg::matmul::matmul(
                self.rhs.as_mut(),
                Accum::Replace,
                self.jac.transpose(),
                self.residual.as_ref(),
                -1.0,
                Par::Seq,
            );
            solve_in_place(
                self.factor.as_ref(),
                self.rhs.as_mut(),
                Par::Seq,
                MemStack::new(&mut self.buffer),
            );
            for (j, s) in w.step.iter_mut().enumerate() {
                *s = Vector3::new(
                    self.rhs[(3 * j, 0)],
                    self.rhs[(3 * j + 1, 0)],
                    self.rhs[(3 * j + 2, 0)],
                );
            }
            let limit = step_limit(&w.step, 1.0, 0.3);
            w.step.iter_mut().for_each(|s| *s *= limit);
            for i in 0..dim {
                self.rhs[(i, 0)] *= limit;
            }
            // Gain ratio: actual over predicted decrease of |r|^2.
            self.predicted.copy_from(&self.residual);
            faer::linalg::matmul::matmul(
                self.predicted.as_mut(),
                Accum::Add,
                self.jac.as_ref(),
                self.rhs.as_ref(),
                1.0,
                Par::Seq,
            );
            let predicted_merit: f64 = (0..dim).map(|i| self.predicted[(i, 0)].powi(2)).sum();
            w.trial.copy_from_slice(&w.q);
            w.kkt.reactions_start.copy_from_slice(&w.kkt.reactions);
            for j in 1..=n {
                w.q[j] = w.trial[j].perturbed(w.step[j - 1]);
            }
            for (c, r) in w.kkt.reactions[..model.constraints().len()]
                .iter_mut()
                .enumerate()
            {
                *r += Vector3::new(
                    self.rhs[(3 * (n + c), 0)],
                    self.rhs[(3 * (n + c) + 1, 0)],
                    self.rhs[(3 * (n + c) + 2, 0)],
                );
            }
            let trial_merit = evaluate(model, w, lambda, false);
            let gain = (merit - trial_merit) / (merit - predicted_merit).max(f64::MIN_POSITIVE);
            if trial_merit.is_finite() && gain > 0.0 {
                merit = self.load(model, w, lambda);
            } else {
                w.q.copy_from_slice(&w.trial);
                w.kkt.reactions.copy_from_slice(&w.kkt.reactions_start);
                evaluate(model, w, lambda, false);
            }
            if gain > GAIN_SHRINK {
                mu /= 3.0;
            } else if gain < GAIN_GROW {
                mu *= 2.0;
            }
            if !mu.is_finite() || mu > 1e20 * max_diag.max(1.0) {
                break;
            }
        }
        // Leave the Jacobian current for the caller's stability test.
        evaluate(model, w, lambda, true);
        let converged = norm(model, w) <= tol && certified(model, w, lambda, tol);
        evaluate(model, w, lambda, true);
        LocalOutcome {
            converged,
            iterations: max_iter,
        }
    }
}
