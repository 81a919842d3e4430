//! Damped Newton with a backtracking line search on the residual norm.
//!
//! The step solves `J d = -g` by the O(n) block-tridiagonal factorisation. `J` is
//! the exact Jacobian of `g`, so `d` is a descent direction of `|g|^2` and the
//! Armijo backtracking always terminates near a regular solution.

use super::{step_limit, LocalOutcome, LocalSolver, Workspace};
use crate::blocktri::BlockLu;
use crate::interrupt;
use crate::model::RodModel;
use crate::quat::Quat;
use nalgebra::Vector3;

pub(crate) struct Newton;

/// Largest node rotation and element rotation of one update [rad].
pub(crate) const MAX_NODE_TURN: f64 = 1.0;
pub(crate) const MAX_ELEMENT_TURN: f64 = 0.3;

/// Iterations over which a run must reduce its merit by `STALL_FACTOR`.
const STALL_WINDOW: usize = 8;
const STALL_FACTOR: f64 = 0.9;

/// Detects a stalled direct attempt of a free rod: the merit (half the squared residual)
/// has not dropped below `STALL_FACTOR` of its value `STALL_WINDOW`
/// iterations ago. From the initial guess, Newton often ends near a local
/// minimum of the merit that is no equilibrium (the Jacobian nearly
/// singular), where the line search keeps accepting steps of a few percent
/// that lower the merit by a hair: the attempt wandered until its budget was
/// spent (12 iterations at n = 24, 48 to 65 at n = 192 and above), and load
/// continuation started later the finer the rod. A continuation step is not
/// judged this way: it starts next to the path, and a slow step there is
/// genuine progress towards a strained equilibrium (a held tip just inside
/// its reach creeps in for hundreds of iterations).
pub(crate) struct Progress {
    recent: [f64; STALL_WINDOW],
    seen: usize,
}

impl Progress {
    pub(crate) fn new() -> Self {
        Progress {
            recent: [f64::INFINITY; STALL_WINDOW],
            seen: 0,
        }
    }

    /// Record the merit at the start of an iteration; true if the run stalls.
    pub(crate) fn stalled(&mut self, merit: f64) -> bool {
        let slot = self.seen % STALL_WINDOW;
        let before = self.recent[slot];
        self.recent[slot] = merit;
        self.seen += 1;
        self.seen > STALL_WINDOW && merit > STALL_FACTOR * before
    }
}

impl LocalSolver for Newton {
    fn for_model(&self, _model: &RodModel) -> Box<dyn LocalSolver + Send + Sync> {
        Box::new(Newton)
    }

    fn run(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome {
        iterate(model, w, lambda, (max_iter, tol), false)
    }

    fn attempt(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome {
        iterate(model, w, lambda, (max_iter, tol), true)
    }
}

/// Newton from `w.q` within `max_iter` iterations; with `give_up_when_stalled`
/// a free rod's run stops once the merit stalls (see [`Progress`]).
fn iterate(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    (max_iter, tol): (usize, f64),
    give_up_when_stalled: bool,
) -> LocalOutcome {
    if model.is_constrained() {
        // Not judged by its merit: a held rod's Newton often rests on a
        // plateau for ten iterations and then converges (a guided scene went
        // from 18 iterations to none, or to another equilibrium by the fallback).
        let (converged, iterations) = super::constrained::newton(model, w, lambda, (max_iter, tol));
        return LocalOutcome {
            converged,
            iterations,
        };
    }
    iterate_free(model, w, lambda, (max_iter, tol), give_up_when_stalled)
}

/// [`iterate`] on the rod's own equations (its loads, nothing held or
/// touched): a free rod's Newton, and the start among obstacles that
/// `contact::start_from_free_equilibrium` tries.
pub(crate) fn iterate_free(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    (max_iter, tol): (usize, f64),
    give_up_when_stalled: bool,
) -> LocalOutcome {
    model.residual_jacobian(&w.q, lambda, &mut w.interior, &mut w.g, &mut w.jac);
    let mut merit = model.merit(&w.g);
    let mut progress = Progress::new();
    // One pass more than the budget: the last one only certifies.
    for it in 0..=max_iter {
        let norm = model.residual_norm(&w.g);
        let stop = |converged| LocalOutcome {
            converged,
            iterations: it,
        };
        if !norm.is_finite() || interrupt::requested() {
            return stop(false);
        }
        if !newton_step(model, w) {
            return stop(false);
        }
        if certified(norm, &w.step, tol) {
            return stop(true);
        }
        // Within the tolerance the merit is round-off: only the step is
        // still being certified.
        let stalled = give_up_when_stalled && norm > tol && progress.stalled(merit);
        if it == max_iter || stalled {
            return stop(false);
        }
        let alpha = step_limit(&w.step, MAX_NODE_TURN, MAX_ELEMENT_TURN);
        // The first trial, usually accepted, is evaluated with its
        // Jacobian: the factorisation no longer needs `w.jac`, and the
        // next iteration then needs no second pass over the rod.
        let mut jacobian_at_trial = true;
        let accepted = backtrack(
            w,
            alpha,
            merit,
            |w, alpha, first| {
                jacobian_at_trial = first;
                retract_along_chain(&w.q, &w.step, alpha, &mut w.trial);
                if first {
                    model.residual_jacobian(
                        &w.trial,
                        lambda,
                        &mut w.interior,
                        &mut w.g_trial,
                        &mut w.jac,
                    );
                } else {
                    model.residual(&w.trial, lambda, &mut w.interior, &mut w.g_trial);
                }
                model.merit(&w.g_trial)
            },
            |w| model.residual_norm(&w.g_trial) <= tol,
        );
        let Some(accepted_merit) = accepted else {
            // The contract: `w.g` and `w.jac` at `w.q`.
            model.residual_jacobian(&w.q, lambda, &mut w.interior, &mut w.g, &mut w.jac);
            return LocalOutcome {
                converged: false,
                iterations: it + 1,
            };
        };
        merit = accepted_merit;
        std::mem::swap(&mut w.q, &mut w.trial);
        std::mem::swap(&mut w.g, &mut w.g_trial);
        if !jacobian_at_trial {
            model.residual_jacobian(&w.q, lambda, &mut w.interior, &mut w.g, &mut w.jac);
        }
    }
    unreachable!("the loop returns at its last pass")
}

/// The Newton step `-J^{-1} g` at the workspace state into `w.step` (`w.lu`
/// keeps the factorisation). A singular pivot (a bifurcation, a neutral
/// direction) is damped by a growing diagonal shift; false if even a shift of
/// the Jacobian's own scale does not make it regular.
fn newton_step(model: &RodModel, w: &mut Workspace) -> bool {
    damped_solve(model, w, |lu, w| {
        for (s, g) in w.step.iter_mut().zip(&w.g) {
            *s = -g;
        }
        lu.solve_in_place(&mut w.step);
        true
    })
}

/// Smallest fraction of a step that a line search tries before it gives up.
pub(crate) const MIN_STEP_FRACTION: f64 = 1e-4;

/// Armijo backtracking, shared by every Newton variant. `trial(state, alpha,
/// first)` puts the step `alpha` (of the direction the caller holds) in
/// `state` and returns its merit; `alpha` halves from `alpha` until the merit
/// drops by `1e-4 alpha` of `merit`, or `within_tol(state)` says the trial's
/// residual is within the tolerance (at the round-off floor the merit is noise
/// and need not decrease; asked only when the merit did not drop). Returns the
/// accepted merit, or None once `alpha` is below [`MIN_STEP_FRACTION`] or an
/// interrupt is requested (the trial residuals are then unfinished).
pub(crate) fn backtrack<S>(
    state: &mut S,
    mut alpha: f64,
    merit: f64,
    mut trial: impl FnMut(&mut S, f64, bool) -> f64,
    mut within_tol: impl FnMut(&S) -> bool,
) -> Option<f64> {
    let mut first = true;
    loop {
        let trial_merit = trial(state, alpha, first);
        let decreased = trial_merit <= (1.0 - 1e-4 * alpha) * merit;
        if trial_merit.is_finite() && (decreased || within_tol(state)) {
            return Some(trial_merit);
        }
        first = false;
        alpha *= 0.5;
        if alpha < MIN_STEP_FRACTION || interrupt::requested() {
            return None;
        }
    }
}

/// Factor `J + shift I` (the workspace's Jacobian) and run `solve` with the
/// factorisation, the shift growing from 0 (by 1e-10 of the Jacobian's scale,
/// then a hundredfold) while the factorisation or `solve` fails: a singular
/// pivot is a bifurcation or a neutral direction. False if even a shift of
/// the Jacobian's own scale does not help. Shared by every Newton variant.
pub(crate) fn damped_solve(
    model: &RodModel,
    w: &mut Workspace,
    mut solve: impl FnMut(&BlockLu, &mut Workspace) -> bool,
) -> bool {
    let scale = w
        .jac
        .max_diagonal()
        .max(model.residual_scale().max() * model.ds());
    if !scale.is_finite() {
        // No shift is of this scale: counting up to an infinite one never
        // ended (kz = 1e308 N m^2 ran for minutes).
        return false;
    }
    // The factorisation leaves the workspace while `solve` borrows it.
    let mut lu = std::mem::replace(&mut w.lu, BlockLu::new(0));
    // A fixed number of trials whatever the scale: 0, then 1e-10 to 1 of it.
    let shifts = std::iter::once(0.0).chain((0..=5).map(|k| scale * 100f64.powi(k - 5)));
    let mut solved = false;
    for shift in shifts {
        if lu.factor(&w.jac, shift).is_ok() && solve(&lu, w) {
            solved = true;
            break;
        }
    }
    w.lu = lu;
    solved
}

/// Convergence: the scaled residual is within `tol` (the tolerance in effect,
/// round-off floor included) and the Newton step from the state, the estimate
/// of its distance from the equilibrium, turns no node by more than `tol`
/// [rad]. The residual alone would not do: a smooth error `e` of the node
/// rotations leaves a nodal residual of only about `e / n`, so at large n it
/// hides under the round-off floor while the shape is visibly off.
pub(crate) fn certified(norm: f64, step: &[Vector3<f64>], tol: f64) -> bool {
    norm <= tol && step.iter().all(|d| d.amax() <= tol)
}

/// Apply the step `alpha d` to the chain through its relative rotations: element
/// `i` turns by its linearised increment `d_i - R(c_i)^T d_{i-1}`, and the nodes
/// are rebuilt from the base. To first order this is `q_j exp(alpha d_j / 2)`,
/// but a finite step no longer composes the nodes' rotations into spurious
/// relative twist (a second-order term that a torsion much stiffer than bending,
/// kz = 1000 kx, turns into a residual that stalls the line search).
pub(crate) fn retract_along_chain(q: &[Quat], step: &[Vector3<f64>], alpha: f64, out: &mut [Quat]) {
    out[0] = q[0];
    let mut previous = Vector3::zeros();
    for j in 1..q.len() {
        let relative = q[j - 1].conj() * q[j];
        let d = alpha * step[j - 1];
        let increment = d - relative.inverse_rotate(previous);
        out[j] = (out[j - 1] * relative.perturbed(increment)).normalized();
        previous = d;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_stalls_on_a_flat_merit_only() {
        // Newton-like progress, and damped progress by 5 % an iteration, go on.
        let mut fast = Progress::new();
        assert!((0..30).all(|k| !fast.stalled(0.5f64.powi(k))));
        let mut damped = Progress::new();
        assert!((0..30).all(|k| !damped.stalled(0.95f64.powi(k))));
        // A merit lowered by a hair an iteration stalls after the window.
        let mut flat = Progress::new();
        let stalled: Vec<bool> = (0..12)
            .map(|k| flat.stalled(1.0 - 1e-3 * k as f64))
            .collect();
        assert_eq!(stalled.iter().position(|&s| s), Some(STALL_WINDOW));
    }
}
