//! The seed paper's method as a `Solver` method: its answer reported with the
//! model's residual, stability and reactions (see `crate::paper_method`).

use super::solution::judge;
use super::workspace::{evaluate, is_stable};
use super::{Solution, Solver, Status};
use crate::error::{Error, Result};
use crate::paper_method::solve_paper;
use crate::scene::ReachLimit;

impl Solver {
    /// The seed paper's method (see `paper_method`); its answer is reported with
    /// the model's residual and stability at the renormalised quaternions.
    pub(super) fn solve_paper(&mut self, literal: bool) -> Result<Solution> {
        if let Some(ReachLimit::FullReach(reason) | ReachLimit::BeyondDiscreteReach(reason)) =
            &self.reach_limit
        {
            return Err(Error::argument("tip", reason.clone()));
        }
        let out = solve_paper(&self.scene, self.model.n(), &self.settings.paper, literal)?;
        let (model, w) = (&self.model, &mut self.work);
        for (dst, src) in w.q.iter_mut().zip(&out.quaternions) {
            *dst = src.normalized();
        }
        w.q[0] = model.base();
        let n = model.n();
        if let Some(r) = w.kkt.reactions.last_mut() {
            *r = out.forces[n] - self.scene.tip_force;
        }
        evaluate(model, w, 1.0);
        // The literal system is solved when its rows vanish, but a drifted |q| is
        // no equilibrium of the rod: never report that as converged.
        let drifted = out.max_norm_deviation > 1e-8;
        let converged = out.converged && !drifted;
        let message = if out.converged && drifted {
            format!(
                "not an equilibrium: the literal system's rows vanish (largest {:.1e}) but |q| drifted from 1 by up to {:.3}",
                out.residual_norm, out.max_norm_deviation
            )
        } else {
            format!(
                "{}; max | |q| - 1 | = {:.2e}",
                out.message, out.max_norm_deviation
            )
        };
        // The method's verdict covers its own residual (the paper's rows).
        let verdict = if converged {
            Ok(())
        } else {
            Err(Status::NotConverged)
        };
        let (status, note) = judge(
            model,
            &out.quaternions,
            &out.positions,
            out.residual_norm,
            verdict,
            f64::INFINITY,
        );
        let message = note.unwrap_or(message);
        let stable = status == Status::Converged && is_stable(model, w);
        let tip_held = model.constraints().last().is_some_and(|c| c.node == n);
        let tip_reaction_moment = model.clamped_tip().map(|_| w.q[n].rotate(w.kkt.tip_torque));
        Ok(Solution {
            n_elements: n,
            scheme: crate::disc::Scheme::Fd2,
            length: model.length(),
            section_lengths: Vec::new(),
            quaternions: out.quaternions.clone(),
            positions: out.positions,
            internal_quaternions: Vec::new(),
            breaks: Some(model.breaks().to_vec()),
            forces: out.forces.clone(),
            stiffness: model.stiffness(),
            section_stiffness: Vec::new(),
            rest_curvature: self.scene.rest_curvature.clone(),
            tip_moment: model.tip_moment(),
            tip_reaction_force: tip_held.then(|| out.forces[n] - self.scene.tip_force),
            tip_reaction_moment,
            guide_reactions: Vec::new(),
            status,
            iterations: out.pso_iterations + out.lm_iterations,
            continuation_steps: 0,
            residual_norm: out.residual_norm,
            energy: model.energy(&out.quaternions, &mut model.new_interior()),
            stable,
            message,
            error_estimate: None,
            extrapolated_tip: None,
            solve_time: 0.0,
        })
    }
}
