//! The methods beside the schemes (`crate::methods`: shooting and the seed
//! paper's) as `Solver` methods: their answers reported like the local
//! solvers', with the model's residual, stability and reactions.

use super::solution::judge;
use super::workspace::{evaluate, is_stable};
use super::{Solution, Solver, Status};
use crate::error::{Error, Result};
use crate::methods::paper::solve_paper;
use crate::methods::shooting::{self, Candidate, Shot};
use crate::quat::Quat;
use crate::scene::ReachLimit;
use nalgebra::Vector3;

impl Solver {
    /// The seed paper's method (see `crate::methods::paper`); its answer is reported with
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
            contacts: Vec::new(),
            ports: Vec::new(),
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

    /// Solve by shooting (see `crate::methods::shooting`); the discrete
    /// model judges the stability of its candidates and of its answer.
    pub(super) fn solve_shooting(&mut self, initial: Option<&[Quat]>) -> Solution {
        let (model, w) = (&self.model, &mut self.work);
        let limits = shooting::Limits {
            tol: model.effective_tol(self.settings.residual_tol),
            max_iterations: self.settings.max_iterations,
            min_continuation_step: self.settings.min_continuation_step,
        };
        let mut stable = |candidate: &Candidate| {
            w.q.copy_from_slice(candidate.quaternions);
            // A free candidate leaves the reactions as they are: on a held
            // scene its free leg is judged with the tip's constraint in place
            // (only a change of stability along the leg matters there).
            if let Some((force, torque)) = candidate.held_tip {
                w.kkt
                    .reactions
                    .iter_mut()
                    .for_each(|r| *r = Vector3::zeros());
                if let Some(r) = w.kkt.reactions.last_mut() {
                    *r = force;
                }
                w.kkt.tip_torque = torque;
            }
            evaluate(model, w, candidate.load_scale);
            is_stable(model, w)
        };
        let warm = self.warm_shot.as_ref();
        let shot = shooting::shoot(model, &self.scene, limits, (initial, warm), &mut stable);
        self.last_shot = shot.warm;
        self.finish_shooting(shot)
    }

    fn finish_shooting(&mut self, shot: Shot) -> Solution {
        let (model, w) = (&self.model, &mut self.work);
        let mut positions = vec![Vector3::zeros(); model.n() + 1];
        let tip = shot.shape(model, &self.scene, &mut w.q, &mut positions);
        // The held tip's reactions: what the tip's support adds to the loads.
        w.kkt
            .reactions
            .iter_mut()
            .for_each(|r| *r = Vector3::zeros());
        if let (Some(force), Some(torque)) = (tip.reaction_force, tip.reaction_torque_body) {
            if let Some(r) = w.kkt.reactions.last_mut() {
                *r = force;
            }
            w.kkt.tip_torque = torque;
        }
        let solved = if shot.converged {
            Ok(())
        } else if shot.iterations >= self.settings.max_iterations {
            Err(Status::IterationLimit)
        } else {
            Err(Status::NotConverged)
        };
        let tol = model.effective_tol(self.settings.residual_tol);
        let (status, note) = judge(model, &w.q, &positions, shot.residual, solved, tol);
        // Stability from the finite-difference scheme's Hessian at the shot
        // shape (a second-order neighbour of its equilibrium), as shooting
        // judged its direct answer already.
        let stable = status == Status::Converged
            && shot.stable.unwrap_or_else(|| {
                evaluate(model, w, 1.0);
                is_stable(model, w)
            });
        let message = note.unwrap_or_else(|| match status {
            Status::Converged => format!(
                "converged by shooting (RK4, {} steps{})",
                model.n(),
                if shot.steps > 0 {
                    format!(", {} continuation steps", shot.steps)
                } else {
                    String::new()
                }
            ),
            _ => shot.note.clone().unwrap_or_else(|| {
                format!(
                    "shooting did not converge: tip mismatch {:.1e} after {} iterations",
                    shot.residual, shot.iterations
                )
            }),
        });
        let reactions = w.kkt.reactions.clone();
        Solution {
            n_elements: model.n(),
            scheme: crate::disc::Scheme::Rk4,
            length: model.length(),
            section_lengths: self.scene.section_lengths(),
            quaternions: w.q.clone(),
            positions,
            internal_quaternions: Vec::new(),
            breaks: Some(model.breaks().to_vec()),
            forces: model.node_forces(&reactions),
            stiffness: model.stiffness(),
            section_stiffness: (0..self.scene.sections.len())
                .map(|k| self.scene.section_stiffness(k))
                .collect(),
            rest_curvature: self.scene.rest_curvature.clone(),
            tip_moment: model.tip_moment(),
            tip_reaction_force: tip.reaction_force,
            tip_reaction_moment: model.clamped_tip().and(tip.reaction_moment),
            guide_reactions: Vec::new(),
            contacts: Vec::new(),
            ports: Vec::new(),
            status,
            iterations: shot.iterations,
            continuation_steps: shot.steps,
            residual_norm: shot.residual,
            energy: model.energy(&w.q, &mut w.interior),
            stable,
            message,
            error_estimate: None,
            extrapolated_tip: None,
            solve_time: 0.0,
        }
    }
}
