//! Levenberg-Marquardt on the same residual and minimal update as Newton, with
//! the damped normal equations `(J^T J + mu I) d = -J^T g` solved densely by
//! faer's Cholesky. It is the general-purpose least-squares baseline (and the
//! finishing stage of the paper's method): robust, but O(n^3) per iteration.

use super::{step_limit, sum_squares, LocalOutcome, LocalSolver, Workspace};
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
    rhs: Mat<f64>,
    buffer: MemBuffer,
    predicted: Vec<Vector3<f64>>,
}

/// Gain-ratio thresholds of the damping update: shrink `mu` above the first,
/// grow it below the second (the seed's Algorithm 1).
const GAIN_SHRINK: f64 = 0.75;
const GAIN_GROW: f64 = 0.45;

impl LevenbergMarquardt {
    pub(crate) fn new(model: &RodModel) -> Self {
        let n = model.n;
        let dim = 3 * n;
        LevenbergMarquardt {
            jac: Mat::zeros(dim, dim),
            normal: Mat::zeros(dim, dim),
            factor: Mat::zeros(dim, dim),
            rhs: Mat::zeros(dim, 1),
            buffer: MemBuffer::new(cholesky_in_place_scratch::<f64>(
                dim,
                Par::Seq,
                Default::default(),
            )),
            predicted: vec![Vector3::zeros(); n],
        }
    }

    /// Dense copy of the block-tridiagonal Jacobian, then `J^T J` and `J^T g`.
    fn load_normal_equations(&mut self, w: &Workspace) {
        self.jac.fill(0.0);
        w.jac.for_each_entry(|r, c, v| self.jac[(r, c)] = v);
        faer::linalg::matmul::matmul(
            self.normal.as_mut(),
            Accum::Replace,
            self.jac.transpose(),
            self.jac.as_ref(),
            1.0,
            Par::Seq,
        );
    }
}

impl LocalSolver for LevenbergMarquardt {
    fn run(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome {
        let n = model.n;
        let dim = 3 * n;
        model.residual_jacobian(&w.q, lambda, &mut w.g, &mut w.jac);
        self.load_normal_equations(w);
        let mut merit = sum_squares(&w.g);
        let max_diag = (0..dim).map(|i| self.normal[(i, i)]).fold(0.0, f64::max);
        let mut mu = 1e-6 * max_diag.max(f64::MIN_POSITIVE);
        for it in 0..max_iter {
            if model.residual_norm(&w.g) <= tol {
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
            if cholesky_in_place(
                self.factor.as_mut(),
                Default::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .is_err()
            {
                mu *= 4.0;
                continue;
            }
            // rhs = -J^T g
            for j in 0..n {
                for r in 0..3 {
                    self.rhs[(3 * j + r, 0)] = w.g[j][r];
                }
            }
            let g_col = self.rhs.clone();
            faer::linalg::matmul::matmul(
                self.rhs.as_mut(),
                Accum::Replace,
                self.jac.transpose(),
                g_col.as_ref(),
                -1.0,
                Par::Seq,
            );
            solve_in_place(
                self.factor.as_ref(),
                self.rhs.as_mut(),
                Par::Seq,
                MemStack::new(&mut self.buffer),
            );
            for j in 0..n {
                w.step[j] = Vector3::new(
                    self.rhs[(3 * j, 0)],
                    self.rhs[(3 * j + 1, 0)],
                    self.rhs[(3 * j + 2, 0)],
                );
            }
            let limit = step_limit(&w.step, 1.0, 0.3);
            w.step.iter_mut().for_each(|s| *s *= limit);
            // Gain ratio: actual over predicted decrease of |g|^2.
            w.jac.mul_vec(&w.step, &mut self.predicted);
            let predicted_merit: f64 = self
                .predicted
                .iter()
                .zip(&w.g)
                .map(|(p, g)| (p + g).norm_squared())
                .sum();
            w.trial[0] = w.q[0];
            for j in 1..=n {
                w.trial[j] = w.q[j].perturbed(w.step[j - 1]);
            }
            model.residual(&w.trial, lambda, &mut w.g_trial);
            let trial_merit = sum_squares(&w.g_trial);
            let gain = (merit - trial_merit) / (merit - predicted_merit).max(f64::MIN_POSITIVE);
            if trial_merit.is_finite() && gain > 0.0 {
                std::mem::swap(&mut w.q, &mut w.trial);
                model.residual_jacobian(&w.q, lambda, &mut w.g, &mut w.jac);
                self.load_normal_equations(w);
                merit = trial_merit;
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
        let converged = model.residual_norm(&w.g) <= tol;
        LocalOutcome {
            converged,
            iterations: max_iter,
        }
    }
}
