//! A Newton step of the equilibrium and of the drive that moves it,
//! together: the inverse kinematics' coupled iteration near its target,
//! which solves the equilibrium once, at the end, instead of at every step
//! of the drive (`robot/ik/engine.rs`, `InverseSolver::coupled`).
//!
//! At a state `q` that need not be an equilibrium, the equations `g(q, p)`
//! linearise to `A dq + G dp = -g`, so the state moves by
//! `dq = delta - A^{-1} G dp`, `delta = -A^{-1} g` being Newton's step. The
//! caller picks `dp` from the tip's linearisation: where `delta` takes the
//! tip, and the tip's derivative in the drive, `-P A^{-1} G` (`P` the tip's
//! derivative in the state). The latter comes by the adjoint: three solves
//! with `A^T` (the tip's position rows; six with its turn's) instead of one solve a drive
//! coordinate (20 for the seed's robot), then a dot product a column of `G`.
//! The drives enter the equations linearly ([`DriveParameters`]), so `G`'s
//! columns are the loading's kept derivatives. A free rod only: nothing held,
//! no contact.

use super::newton::{certified, retract_along_chain, MAX_ELEMENT_TURN, MAX_NODE_TURN};
use super::sensitivity::{DriveParameters, TipFrame};
use super::{step_limit, Solver, Status};
use crate::disc::Loading;
use crate::error::{Error, Result};
use crate::quat::Quat;
use nalgebra::{Matrix3xX, Vector3};

/// The equations and the tip linearised at a state, in the state and a drive.
#[derive(Debug, Clone)]
pub struct CoupledLinearisation {
    /// Whether the state is an equilibrium to the solver's tolerance (its
    /// residual and Newton's step, as a solve certifies one).
    pub certified: bool,
    /// The tip's position [m] and frame at the state.
    pub tip_position: Vector3<f64>,
    pub tip_quaternion: Quat,
    /// Where Newton's step takes the tip: its move [m] and turn (a world
    /// rotation vector [rad]).
    pub newton_position: Vector3<f64>,
    pub newton_rotation: Vector3<f64>,
    /// The tip's move and turn along each drive coordinate with the state
    /// following to first order (`-P A^{-1} G`), one column a coordinate
    /// (the turn's zero where not asked for).
    pub position: Matrix3xX<f64>,
    pub rotation: Matrix3xX<f64>,
}

/// The buffers of a coupled iteration, kept by the solver.
#[derive(Debug, Clone, Default)]
pub(crate) struct CoupledWork {
    /// The state linearised, Newton's step there and `G`'s columns (`n` a
    /// column), for [`Solver::move_state`].
    at: Vec<Quat>,
    newton: Vec<Vector3<f64>>,
    columns: Vec<Vector3<f64>>,
    /// The tip's rows through `A^{-T}`: its position's, then its turn's.
    adjoint: Vec<Vec<Vector3<f64>>>,
    /// Scratch of each linearisation: the interior's shift along a column
    /// (fe4), the positions it moves, the state's positions.
    shift: Vec<Vector3<f64>>,
    moved: Vec<Vector3<f64>>,
    positions: Vec<Vector3<f64>>,
}

impl Solver {
    /// The current state: the node rotations `q_0..q_n`.
    pub fn state(&self) -> &[Quat] {
        &self.work.q
    }

    /// Put the solver at the rotations `q` (`q_0` replaced by the base's)
    /// without solving: the start of a coupled iteration.
    pub fn set_state(&mut self, q: &[Quat]) -> Result<()> {
        let n = self.model.n();
        if q.len() != n + 1 {
            return Err(Error::argument(
                "state",
                format!("has {} nodes, the discretisation has {}", q.len(), n + 1),
            ));
        }
        let w = &mut self.work;
        w.q[0] = self.model.base();
        for (dst, src) in w.q.iter_mut().zip(q).skip(1) {
            *dst = src.normalized();
        }
        self.jacobian_at_solution = false;
        Ok(())
    }

    /// The equations and the tip linearised at the state in the state and
    /// `parameters` (see the module docs); the tip's turn only if `turn`
    /// (else its rows are zero: three solves saved). A free rod only.
    pub fn linearise_coupled(
        &mut self,
        parameters: DriveParameters,
        turn: bool,
    ) -> Result<CoupledLinearisation> {
        if self.model.is_constrained() || self.model.has_contact() {
            return Err(Error::argument("linearise_coupled", "needs a free rod"));
        }
        self.with_drive_tangents(parameters, |solver, tangents| {
            solver.linearise_with(tangents, turn)
        })?
    }

    fn linearise_with(&mut self, tangents: &[Loading], turn: bool) -> Result<CoupledLinearisation> {
        let (model, w, c) = (&self.model, &mut self.work, &mut self.coupled);
        let n = model.n();
        model.residual_jacobian(&w.q, 1.0, &mut w.interior, &mut w.g, &mut w.jac);
        self.jacobian_at_solution = true;
        let residual = model.residual_norm(&w.g);
        if !residual.is_finite() || w.lu.factor(&w.jac, 0.0).is_err() {
            return Err(Error::NotConverged {
                status: Status::NotConverged,
                iterations: 0,
                residual,
                reason: "the coupled iteration's Jacobian is singular".into(),
            });
        }
        c.at.clone_from(&w.q);
        c.newton.clear();
        c.newton.extend(w.g.iter().map(|g| -g));
        w.lu.solve_in_place(&mut c.newton);
        let frame = TipFrame::new(model, w);
        let (newton_position, newton_rotation) = frame.moves(&c.newton, Vector3::zeros());
        // The tip's rows: its position's in every node's turn, its frame's
        // turn in the last node's.
        let rows = if turn { 6 } else { 3 };
        c.adjoint.resize(rows, Vec::new());
        for (a, row) in c.adjoint.iter_mut().enumerate() {
            row.clear();
            row.resize(n, Vector3::zeros());
            if a < 3 {
                for (r, d) in row.iter_mut().zip(frame.position_rows()) {
                    *r = d.row(a).transpose();
                }
            } else {
                row[n - 1] = frame.turn().row(a - 3).transpose();
            }
            w.lu.solve_transposed_in_place(row);
        }
        let m = tangents.len();
        let (mut position, mut rotation) = (Matrix3xX::zeros(m), Matrix3xX::zeros(m));
        c.columns.clear();
        c.columns.resize(m * n, Vector3::zeros());
        model.residual_derivatives(
            &w.q,
            tangents,
            &mut w.interior,
            &mut c.columns,
            &mut c.shift,
        );
        c.moved.resize(n + 1, Vector3::zeros());
        c.positions.resize(n + 1, Vector3::zeros());
        for (k, column) in c.columns.chunks_exact(n).enumerate() {
            // fe4: the tip also moves with the interior at fixed nodes.
            let at_fixed_nodes = if c.shift.is_empty() {
                Vector3::zeros()
            } else {
                let shift = &c.shift[k * n..(k + 1) * n];
                model.position_derivative(&w.q, &mut w.interior, shift, &mut c.moved);
                c.moved[n]
            };
            // A section's or a tendon's column is nonzero on its elements only.
            let zero = Vector3::zeros();
            let lo = column.iter().position(|g| *g != zero).unwrap_or(n);
            let hi = column
                .iter()
                .rposition(|g| *g != zero)
                .map_or(lo, |i| i + 1);
            for a in 0..3 {
                let dot = |row: &[Vector3<f64>]| -> f64 {
                    -row[lo..hi]
                        .iter()
                        .zip(&column[lo..hi])
                        .map(|(l, g)| l.dot(g))
                        .sum::<f64>()
                };
                position[(a, k)] = dot(&c.adjoint[a]) + at_fixed_nodes[a];
                if turn {
                    rotation[(a, k)] = dot(&c.adjoint[3 + a]);
                }
            }
        }
        model.positions(&w.q, &mut w.interior, &mut c.positions);
        let tol = model.effective_tol(self.settings.residual_tol);
        Ok(CoupledLinearisation {
            certified: certified(residual, &c.newton, tol),
            tip_position: c.positions[n],
            tip_quaternion: w.q[n],
            newton_position,
            newton_rotation,
            position,
            rotation,
        })
    }

    /// Move the state by `delta - A^{-1} G dp` of the last
    /// [`Solver::linearise_coupled`]. False, the state unchanged, where that
    /// was not at this state, of this model (a change of the drive, the
    /// loads or the base since, a solve or a sensitivity in between) or for
    /// as many coordinates, or where the move turns a node or an element
    /// farther than a Newton step may (a longer move is no step of a
    /// converging Newton iteration).
    pub fn move_state(&mut self, dp: &[f64]) -> bool {
        let (w, c) = (&mut self.work, &self.coupled);
        let n = self.model.n();
        // Every change of the model and every solve clear the flag; the
        // linearisation set it with its Jacobian and factors.
        let current = self.jacobian_at_solution && w.lu.is_factor_of(&w.jac);
        if !current || c.at != w.q || c.columns.len() != dp.len() * n || c.newton.len() != n {
            return false;
        }
        w.step.iter_mut().for_each(|s| *s = Vector3::zeros());
        for (column, d) in c.columns.chunks_exact(n).zip(dp) {
            for (s, g) in w.step.iter_mut().zip(column) {
                *s += *d * g;
            }
        }
        w.lu.solve_in_place(&mut w.step);
        for (s, delta) in w.step.iter_mut().zip(&c.newton) {
            *s = delta - *s;
        }
        if step_limit(&w.step, MAX_NODE_TURN, MAX_ELEMENT_TURN) < 1.0 {
            return false;
        }
        retract_along_chain(&w.q, &w.step, 1.0, &mut w.trial);
        std::mem::swap(&mut w.q, &mut w.trial);
        self.jacobian_at_solution = false;
        true
    }
}
