//! Sensitivities of an equilibrium by the implicit function theorem on its
//! factored Jacobian: O(n) a column.
//!
//! With friction an equilibrium is the end of a step of its loading
//! history, and its sensitivities are that step's: each contact (and port)
//! keeps its state, a sticking one held at its anchor, a sliding one sliding
//! on against its move since the step's start with its friction at `mu`
//! times its normal force. That is the derivative of a solve warm from a
//! `Solution` (`Solver::solve_after`) in the parameters it ends at, the
//! Jacobian the inverse kinematics steps with; it is one-sided where a
//! contact is at its cone's edge or a slide would reverse.

use super::{Solver, Status};
use crate::disc::{Interior, Loading};
use crate::error::{Error, Result};
use crate::model::RodModel;
use crate::quat::Quat;
use crate::scene::Scene;
use nalgebra::Vector3;

/// The parameters a robot's drive moves, whose loading derivatives a solver
/// keeps (they enter the equations linearly).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveParameters {
    /// The rest curvature `[kappa_x, kappa_y]` of each of this many equal sections.
    SectionCurvature(usize),
    /// The tendons' tensions, one a tendon of the scene.
    Tensions,
    /// The uniform field's three components, world frame.
    Field,
}

/// Derivatives of the tip of an equilibrium with respect to the actuation.
#[derive(Debug, Clone)]
pub struct TipSensitivity {
    /// `d r_tip / d kappa` [m^2], 3 x 2m.
    pub position: nalgebra::Matrix3xX<f64>,
    /// `d T_tip / d kappa` (tip tangent) [m], 3 x 2m.
    pub tangent: nalgebra::Matrix3xX<f64>,
    /// `d phi_tip / d kappa`: the tip frame's turn, a world rotation vector [m].
    pub rotation: nalgebra::Matrix3xX<f64>,
}

impl TipSensitivity {
    /// `columns` columns of zeros.
    fn zeros(columns: usize) -> TipSensitivity {
        TipSensitivity {
            position: nalgebra::Matrix3xX::zeros(columns),
            tangent: nalgebra::Matrix3xX::zeros(columns),
            rotation: nalgebra::Matrix3xX::zeros(columns),
        }
    }
}

impl Solver {
    /// `f` of this solver with every sticking contact and port of its last
    /// equilibrium released (free to slide, its friction held at its value;
    /// a sliding one keeps its own), then its state put back: the inverse
    /// kinematics' Jacobian with friction. The exact one holds a stuck
    /// contact where it is (a tip stuck on a wall has no derivative along
    /// it), where the descent needs the way friction lets the robot go once
    /// it moves on. Without friction, `f`.
    pub fn with_sticking_released<T>(&mut self, f: impl FnOnce(&mut Solver) -> T) -> T {
        if !self.model.has_friction() {
            return f(self);
        }
        let kept = super::friction::release_sticking(&mut self.work);
        let out = f(self);
        super::friction::restore_sticking(&mut self.work, kept);
        super::constrained::evaluate(&self.model, &mut self.work, 1.0, true);
        self.jacobian_at_solution = false;
        out
    }

    /// Sensitivity of the tip of the last (converged, free-tip) equilibrium to the
    /// rest curvature of each of `sections` equal sections: columns `2s` and
    /// `2s + 1` are `d/d kappa_x` and `d/d kappa_y` of section `s`. Costs two
    /// O(n) back-substitutions a column with the Jacobian already factored.
    pub fn tip_sensitivity(&mut self, sections: usize) -> Result<TipSensitivity> {
        self.drive_sensitivity(DriveParameters::SectionCurvature(sections))
    }

    /// Sensitivity of the tip of the last (converged, free-tip)
    /// equilibrium to the tendons' tensions, one column a tendon of the scene.
    pub fn tension_sensitivity(&mut self) -> Result<TipSensitivity> {
        self.drive_sensitivity(DriveParameters::Tensions)
    }

    /// Sensitivity of the tip of the last (converged, free-tip) equilibrium
    /// to the uniform field's three components, world frame. The field
    /// enters the equations linearly, so its tangents are drawn once.
    pub fn field_sensitivity(&mut self) -> Result<TipSensitivity> {
        self.drive_sensitivity(DriveParameters::Field)
    }

    /// The tip's sensitivity to `parameters`.
    fn drive_sensitivity(&mut self, parameters: DriveParameters) -> Result<TipSensitivity> {
        self.with_drive_tangents(parameters, |solver, tangents| {
            solver.tip_sensitivity_with(tangents)
        })?
    }

    /// `f` of the loading's derivatives in `parameters`, drawn once and
    /// kept: the drives enter the equations linearly (a section's rest
    /// curvature, a tension, the field), so they do not change with them.
    pub(crate) fn with_drive_tangents<T>(
        &mut self,
        parameters: DriveParameters,
        f: impl FnOnce(&mut Solver, &[Loading]) -> T,
    ) -> Result<T> {
        let kept = match parameters {
            DriveParameters::SectionCurvature(sections) => {
                let n = self.model.n();
                if sections == 0 || n % sections != 0 {
                    return Err(Error::argument(
                        "sections",
                        format!("{sections} sections do not divide {n} elements"),
                    ));
                }
                let per = n / sections;
                if self.curvature_tangents.len() != 2 * sections {
                    self.curvature_tangents = (0..2 * sections)
                        .map(|column| {
                            // The rest curvature's component of one section's elements.
                            let (s, c) = (column / 2, column % 2);
                            let mut rest = vec![Vector3::zeros(); n];
                            for k in &mut rest[s * per..(s + 1) * per] {
                                k[c] = 1.0;
                            }
                            Loading {
                                rest_curvature: rest,
                                support: Some((s * per + 1, (s + 1) * per)),
                                ..Loading::empty()
                            }
                        })
                        .collect();
                }
                &mut self.curvature_tangents
            }
            DriveParameters::Tensions => {
                let tendons = self.scene.tendons.len();
                if self.tension_tangents.len() != tendons {
                    let names = (0..tendons).map(|j| format!("tendons[{j}].tension"));
                    self.tension_tangents = term_tangents(&self.model, names)?;
                }
                &mut self.tension_tangents
            }
            DriveParameters::Field => {
                if self.field_tangents.len() != 3 {
                    let names = (0..3).map(|j| format!("magnetic_field[{j}]"));
                    self.field_tangents = term_tangents(&self.model, names)?;
                }
                &mut self.field_tangents
            }
        };
        let tangents = std::mem::take(kept);
        let out = f(self, &tangents);
        *match parameters {
            DriveParameters::SectionCurvature(_) => &mut self.curvature_tangents,
            DriveParameters::Tensions => &mut self.tension_tangents,
            DriveParameters::Field => &mut self.field_tangents,
        } = tangents;
        Ok(out)
    }

    /// The tip's sensitivity to the parameters of which `tangents` are the
    /// loading's derivatives, by the implicit function theorem on the
    /// factored Jacobian (free tip).
    fn tip_sensitivity_with(&mut self, tangents: &[Loading]) -> Result<TipSensitivity> {
        let columns = tangents.len();
        let n = self.model.n();
        if self.model.is_constrained() && !self.model.has_contact() {
            return Err(Error::argument("tip_sensitivity", "needs a free tip"));
        }
        if self.model.has_contact() {
            return self.tip_sensitivity_in_contact(tangents);
        }
        let (model, w) = (&self.model, &mut self.work);
        self.state_tangents_at.clear();
        self.state_tangents.clear();
        // After an IK's forward solve the Jacobian at its equilibrium is
        // usually there, and factored: a third of a step's assembly saved.
        let factored = self.jacobian_at_solution && w.lu.is_factor_of(&w.jac);
        if !self.jacobian_at_solution {
            model.residual_jacobian(&w.q, 1.0, &mut w.interior, &mut w.g, &mut w.jac);
            self.jacobian_at_solution = true;
        }
        if !factored && w.lu.factor(&w.jac, 0.0).is_err() {
            return Err(singular_jacobian(model, w));
        }
        let frame = TipFrame::new(model, w);
        let mut out = TipSensitivity::zeros(columns);
        let mut shift = Vec::new();
        let mut moved = vec![Vector3::zeros(); n + 1];
        // The columns dg/dp in one pass, then d theta / dp = -A^{-1} dg/dp
        // in their place; the tip also moves with the interior at fixed
        // nodes (fe4).
        self.state_tangents.resize(columns * n, Vector3::zeros());
        model.residual_derivatives(
            &w.q,
            tangents,
            &mut w.interior,
            &mut self.state_tangents,
            &mut shift,
        );
        for (column, tangent) in self.state_tangents.chunks_exact_mut(n).enumerate() {
            if !shift.is_empty() {
                let at = &shift[column * n..(column + 1) * n];
                model.position_derivative(&w.q, &mut w.interior, at, &mut moved);
            }
            w.lu.solve_in_place(tangent);
            tangent.iter_mut().for_each(|x| *x = -*x);
            frame.fill(&mut out, column, tangent, moved[n]);
        }
        self.state_tangents_at.extend_from_slice(&w.q);
        Ok(out)
    }

    /// [`Solver::tip_sensitivity_with`] of an equilibrium in contact: the
    /// contacts held stay on their obstacles (their rows in the KKT system,
    /// the obstacles fixed) and the others stay free, so the columns are
    /// one-sided where a contact is about to open or close. Held points
    /// (a pinned or clamped tip, guides) are refused as for a free rod.
    fn tip_sensitivity_in_contact(&mut self, tangents: &[Loading]) -> Result<TipSensitivity> {
        use super::constrained;
        let (model, w) = (&self.model, &mut self.work);
        if !model.constraints().is_empty() || model.clamped_tip().is_some() {
            return Err(Error::argument("tip_sensitivity", "needs a free tip"));
        }
        self.state_tangents_at.clear();
        self.state_tangents.clear();
        self.jacobian_at_solution = false;
        constrained::evaluate(model, w, 1.0, true);
        constrained::load_constraint_jacobian(model, w);
        if w.lu.factor(&w.jac, 0.0).is_err() {
            return Err(singular_jacobian(model, w));
        }
        let frame = TipFrame::new(model, w);
        let mut out = TipSensitivity::zeros(tangents.len());
        let mut shift = Vec::new();
        let mut solved = true;
        for (column, t) in tangents.iter().enumerate() {
            model.residual_derivative(&w.q, &[], t, &mut w.interior, &mut w.g, &mut shift);
            // d theta / dp: the KKT system's step for the residual dg/dp.
            if !constrained::kkt_solve(w) {
                solved = false;
                break;
            }
            self.state_tangents.extend_from_slice(&w.step);
            frame.fill(&mut out, column, &w.step, Vector3::zeros());
        }
        // The residual and Jacobian of the equilibrium again, for the caller.
        constrained::evaluate(model, w, 1.0, true);
        if !solved {
            self.state_tangents.clear();
            return Err(Error::argument("tip_sensitivity", "singular KKT system"));
        }
        self.state_tangents_at.extend_from_slice(&w.q);
        Ok(out)
    }

    /// The tip's sensitivity to a translation of the clamped base along
    /// `direction` (one column; a robot's insertion): the whole rod moves
    /// with it, less what the surroundings hold back. Without ports or
    /// obstacles the tip translates with the base; with them, the KKT
    /// system's step for the rows' motion relative to the rod (a port's
    /// `d_i . direction`, a held contact's `nu . direction`), the contacts
    /// held. The last solve's equilibrium, free tip.
    pub fn base_sensitivity(&mut self, direction: Vector3<f64>) -> Result<TipSensitivity> {
        use super::constrained;
        let model = &self.model;
        if !model.constraints().is_empty() || model.clamped_tip().is_some() {
            return Err(Error::argument("base_sensitivity", "needs a free tip"));
        }
        let mut out = TipSensitivity::zeros(1);
        if !model.has_contact() {
            out.position.set_column(0, &direction);
            return Ok(out);
        }
        let w = &mut self.work;
        refuse_moving_what_sticks(model, w, "base_sensitivity")?;
        self.state_tangents_at.clear();
        self.state_tangents.clear();
        self.jacobian_at_solution = false;
        // The equations change too: the forces' shares move along their
        // chords, and a curved surface's normal turns, as the rod moves
        // against its surroundings. Central differences of the exact
        // residual, the multipliers and the contact set held.
        let step = BASE_STEP * model.length();
        let mut moved = model.clone();
        let mut residual_at = |sign: f64| {
            moved.set_base_position(model.base_position() + sign * step * direction);
            constrained::evaluate(&moved, w, 1.0, false);
            w.g.clone()
        };
        let (plus, minus) = (residual_at(1.0), residual_at(-1.0));
        constrained::evaluate(model, w, 1.0, true);
        constrained::load_constraint_jacobian(model, w);
        if w.lu.factor(&w.jac, 0.0).is_err() {
            return Err(singular_jacobian(model, w));
        }
        let frame = TipFrame::new(model, w);
        let contact = &w.kkt.contact;
        let ports: Vec<[f64; 2]> = contact
            .ports
            .iter()
            .map(|p| p.directions.map(|d| d.dot(&direction)))
            .collect();
        let gaps: Vec<f64> = contact
            .active
            .iter()
            .map(|&i| contact.sites[i].normal.dot(&direction))
            .collect();
        for ((g, p), m) in w.g.iter_mut().zip(&plus).zip(&minus) {
            *g = (p - m) / (2.0 * step);
        }
        if model.clamped_tip().is_some() {
            let n = model.n();
            w.g[n - 1] = Vector3::zeros();
        }
        let solved = constrained::kkt_solve_moving(w, &ports, &gaps);
        if solved {
            frame.fill(&mut out, 0, &w.step, direction);
        }
        constrained::evaluate(model, w, 1.0, true);
        if !solved {
            return Err(Error::argument("base_sensitivity", "singular KKT system"));
        }
        Ok(out)
    }

    /// The equilibrium predicted to first order when the parameters of the
    /// last tip sensitivity (its columns) move by `dp` from the state `q`:
    /// `q` turned by `sum_j d theta / d p_j dp_j` ([`Solver::tip_sensitivity`],
    /// [`Solver::tension_sensitivity`], [`Solver::field_sensitivity`]).
    /// `None` unless that sensitivity was taken at `q` with `dp.len()`
    /// columns. A warm start from it saves a Newton iteration or two of an
    /// inverse solve's every forward solve.
    pub fn predicted_state(&self, q: &[Quat], dp: &[f64]) -> Option<Vec<Quat>> {
        let n = self.model.n();
        if q != self.state_tangents_at.as_slice() || dp.len() * n != self.state_tangents.len() {
            return None;
        }
        let mut turn = vec![Vector3::zeros(); n];
        for (column, d) in self.state_tangents.chunks_exact(n).zip(dp) {
            for (t, c) in turn.iter_mut().zip(column) {
                *t += *d * c;
            }
        }
        let mut out = q.to_vec();
        super::newton::retract_along_chain(q, &turn, 1.0, &mut out);
        Some(out)
    }
}

/// Relative step of the base's differences in [`Solver::base_sensitivity`]:
/// a millionth of the rod.
const BASE_STEP: f64 = 1e-6;

/// What the tip's outputs are of a state tangent `d theta / dp`: the tip's
/// position Jacobian, `d T_n / d theta_n = -R [e3]x` and the tip's turn `R`.
pub(crate) struct TipFrame {
    d_tip: Vec<nalgebra::Matrix3<f64>>,
    d_tangent: nalgebra::Matrix3<f64>,
    turn: nalgebra::Matrix3<f64>,
}

impl TipFrame {
    pub(crate) fn new(model: &RodModel, w: &super::Workspace) -> TipFrame {
        let n = model.n();
        let mut d_tip = vec![nalgebra::Matrix3::zeros(); n];
        model.position_jacobian(&w.q, n, &w.interior, &mut d_tip);
        let turn = w.q[n].rotation();
        TipFrame {
            d_tip,
            d_tangent: -(turn * crate::quat::skew(&Vector3::z())),
            turn,
        }
    }

    /// Column `column` of `out` from the state tangent `dtheta`, the tip
    /// also moved by `moved_tip` at fixed nodes (fe4's interior).
    pub(crate) fn fill(
        &self,
        out: &mut TipSensitivity,
        column: usize,
        dtheta: &[Vector3<f64>],
        moved_tip: Vector3<f64>,
    ) {
        let (position, rotation) = self.moves(dtheta, moved_tip);
        out.position.set_column(column, &position);
        let last = dtheta[dtheta.len() - 1];
        out.tangent.set_column(column, &(self.d_tangent * last));
        out.rotation.set_column(column, &rotation);
    }

    /// The tip's move and turn (a world rotation vector) for the state
    /// tangent `dtheta`, the tip also moved by `moved_tip` at fixed nodes.
    pub(crate) fn moves(
        &self,
        dtheta: &[Vector3<f64>],
        moved_tip: Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let dr: Vector3<f64> = self.d_tip.iter().zip(dtheta).map(|(b, x)| b * x).sum();
        // The tip turns by R d theta_n (body to world).
        (dr + moved_tip, self.turn * dtheta[dtheta.len() - 1])
    }

    /// The tip position's derivative in each node's turn (nodes 1 to n).
    pub(crate) fn position_rows(&self) -> &[nalgebra::Matrix3<f64>] {
        &self.d_tip
    }

    /// The tip's rotation, body to world: its turn's derivative in the last node's.
    pub(crate) fn turn(&self) -> nalgebra::Matrix3<f64> {
        self.turn
    }
}

/// The error of a singular Jacobian at an equilibrium.
fn singular_jacobian(model: &RodModel, w: &super::Workspace) -> Error {
    Error::NotConverged {
        status: Status::NotConverged,
        iterations: 0,
        residual: model.residual_norm(&w.g),
        reason: "singular Jacobian: the equilibrium is at a bifurcation".into(),
    }
}

/// Derivatives of the tip of an equilibrium with respect to named
/// parameters (one column each), by the implicit function theorem.
#[derive(Debug, Clone)]
pub struct Sensitivity {
    /// The parameters, one a column.
    pub parameters: Vec<String>,
    /// `d r_tip / d p` [m per unit of p].
    pub tip_position: nalgebra::Matrix3xX<f64>,
    /// `d phi_tip / d p`: the tip frame's turn, a rotation vector in the
    /// world frame [rad per unit of p].
    pub tip_rotation: nalgebra::Matrix3xX<f64>,
    /// `d (tip reaction force) / d p` of a pinned or clamped tip [N per unit].
    pub tip_reaction_force: Option<nalgebra::Matrix3xX<f64>>,
    /// `d (tip reaction moment) / d p` of a clamped tip [N m per unit].
    pub tip_reaction_moment: Option<nalgebra::Matrix3xX<f64>>,
    /// Per column, whether the equations' derivative is the terms' analytic
    /// one (false: for a parameter that moves the mesh or the base,
    /// differences of the discrete equations and of the tip's outputs at one
    /// and two unit-free steps, extrapolated; about 1e-12 relative).
    pub exact: Vec<bool>,
}

/// Largest node turn [rad] of the state's move along a sensitivity column in
/// the directional differences of the tip's outputs (at one and two steps,
/// extrapolated): their truncation error is about its fourth power
/// (1e-16 relative; at 1e-3 a section's length had 2e-10), their round-off
/// 1e-16 over it (1e-12).
const OUTPUT_TURN: f64 = 1e-4;

/// Relative change of the discrete equations (of their residual's own scale,
/// and of a held point's position over `L`) by which a parameter's step moves
/// them in the differences of `dF/dp` (central at one and two steps,
/// extrapolated): truncation about its fourth power where they are not
/// linear in the parameter (1e-16, but a section's length had 2e-10 at a
/// response of 1e-3), round-off about `eps` over it (1e-12).
/// A step in the parameter's own units instead lost every digit on a rod in
/// centimetres (a tip force step of 1e-9 N against a force scale of 1e9 N).
const PARAMETER_RESPONSE: f64 = 1e-4;

/// Rescalings of a parameter's step before the response is taken as it is
/// (a parameter that moves nothing has a zero column), and the most one
/// rescaling grows it.
const STEP_TRIES: usize = 8;
const MAX_STEP_GROWTH: f64 = 1e8;

/// What the tip reports at a state, as a `Solution` does.
struct TipReport {
    position: Vector3<f64>,
    orientation: crate::quat::Quat,
    reaction_force: Option<Vector3<f64>>,
    reaction_moment: Option<Vector3<f64>>,
}

/// The residual of `model` at `q` with `reactions`, its Jacobian in
/// `scratch`: with the fourth-order scheme the evaluation with the Jacobian
/// leaves the internal nodes (loaded by the reactions) in `interior`, where
/// the positions and the held points' rows then find them.
fn evaluate_at(
    model: &RodModel,
    q: &[crate::quat::Quat],
    reactions: &[Vector3<f64>],
    interior: &mut Interior,
    g: &mut [Vector3<f64>],
    scratch: &mut crate::blocktri::BlockTridiagonal,
) {
    model.residual_with_reactions(q, 1.0, reactions, interior, g, Some(scratch));
}

fn tip_report(
    model: &RodModel,
    q: &[crate::quat::Quat],
    reactions: &[Vector3<f64>],
    scratch: &mut crate::blocktri::BlockTridiagonal,
) -> TipReport {
    let n = model.n();
    // The residual serves a clamped tip's reaction moment and, with `fe4`,
    // the internal nodes the positions are drawn through.
    let mut interior = model.new_interior();
    let mut g = Vec::new();
    if model.clamped_tip().is_some() || !interior.is_none() {
        g = vec![Vector3::zeros(); n];
        evaluate_at(model, q, reactions, &mut interior, &mut g, scratch);
    }
    let mut positions = vec![Vector3::zeros(); n + 1];
    model.positions(q, &mut interior, &mut positions);
    let tip_held = model.constraints().last().is_some_and(|c| c.node == n);
    let reaction_moment = model.clamped_tip().map(|_| q[n].rotate(g[n - 1]));
    TipReport {
        position: positions[n],
        orientation: q[n],
        reaction_force: tip_held.then(|| reactions[reactions.len() - 1]),
        reaction_moment,
    }
}

/// The section `i` of a parameter `sections[i].length`.
fn section_index(name: &str) -> Option<usize> {
    name.strip_prefix("sections[")
        .and_then(|rest| rest.strip_suffix("].length"))
        .and_then(|i| i.parse().ok())
}

/// Lengthen section `i` of the scene's value `v` by `delta`: the rod with
/// it, and every located input with the section it lies in (in proportion
/// inside section `i`, shifted beyond it), as the nodes move: an input on a
/// node stays on one, a tendon anchored at the tip stays there.
fn stretch_section(v: &mut crate::value::Value, scene: &Scene, i: usize, delta: f64) -> Result<()> {
    let lengths = scene.section_lengths();
    let Some(&length) = lengths.get(i) else {
        return Err(Error::argument(
            format!("sections[{i}].length"),
            "no such section length",
        ));
    };
    let start: f64 = lengths[..i].iter().sum();
    let end = start + length;
    let moved = |s: f64| {
        if s <= start {
            s
        } else if s <= end {
            start + (s - start) * (length + delta) / length
        } else {
            s + delta
        }
    };
    for (key, _) in scene.located_inputs() {
        if let Ok(s) = v.number_at_mut(&key) {
            *s = moved(*s);
        }
    }
    *v.number_at_mut(&format!("sections[{i}].length"))? += delta;
    *v.number_at_mut("length")? += delta;
    Ok(())
}

/// Refuse a parameter the discrete equations are not differentiable in: a
/// located input's arc length (it sits on a node and moves between them),
/// and the rod's length when the sections' lengths make it.
fn differentiable(name: &str, scene: &Scene) -> Result<()> {
    if scene.located_inputs().iter().any(|(key, _)| key == name) {
        return Err(Error::argument(
            name,
            "an arc length on the rod: the input sits on a node of the discrete rod, \
             and its equations are not differentiable in where it sits",
        ));
    }
    if name == "length" && !scene.section_lengths().is_empty() {
        return Err(Error::argument(
            name,
            "the sections' lengths make the rod's: take sections[i].length",
        ));
    }
    Ok(())
}

/// The first step of a parameter's differences, in its own units (then
/// rescaled by the response it gives).
fn first_step(value: f64) -> f64 {
    if value == 0.0 {
        1e-6
    } else {
        1e-6 * value.abs()
    }
}

/// The models of a parameter's differences: at `±step` and, where the
/// scene allows them, at `±2 step`.
struct Stencil {
    step: f64,
    near: (RodModel, RodModel),
    far: Option<(RodModel, RodModel)>,
}

/// `(4 d(h) - d(2h)) / 3` of central differences `d` at one and two steps:
/// the fourth-order derivative (Richardson), from `near = (f(h) - f(-h)) / 2`
/// and `far = (f(2h) - f(-2h)) / 2`, in units of `h`.
#[inline]
fn extrapolated(near: Vector3<f64>, far: Vector3<f64>) -> Vector3<f64> {
    (4.0 * near - 0.5 * far) / 3.0
}

/// Half differences `(f(+) - f(-)) / 2` of the discrete equations between
/// two models at a fixed state: the residual, the held points' rows and,
/// in contact, the ports' and the contact candidates' rows.
#[derive(Debug, Clone, Default)]
struct Differences {
    g: Vec<Vector3<f64>>,
    h: Vec<Vector3<f64>>,
    ports: Vec<[f64; 2]>,
    gaps: Vec<f64>,
}

impl Differences {
    /// How far they move the equations, over their scales (the rows over `L`).
    fn response(&self, model: &RodModel) -> f64 {
        let rows = self
            .h
            .iter()
            .map(|h| h.amax())
            .chain(self.ports.iter().flatten().map(|x| x.abs()))
            .chain(self.gaps.iter().map(|x| x.abs()))
            .fold(0.0, f64::max);
        model.residual_norm(&self.g).max(rows / model.length())
    }

    /// `(4 near - far / 2) / 3`, entry by entry (see [`extrapolated`]).
    fn extrapolate(&mut self, far: &Differences) {
        let scalar = |a: f64, b: f64| (4.0 * a - 0.5 * b) / 3.0;
        for (d, f) in self.g.iter_mut().zip(&far.g) {
            *d = extrapolated(*d, *f);
        }
        for (d, f) in self.h.iter_mut().zip(&far.h) {
            *d = extrapolated(*d, *f);
        }
        for (d, f) in self.ports.iter_mut().zip(&far.ports) {
            *d = [scalar(d[0], f[0]), scalar(d[1], f[1])];
        }
        for (d, f) in self.gaps.iter_mut().zip(&far.gaps) {
            *d = scalar(*d, *f);
        }
    }
}

/// The discrete equations' derivative in parameter `j` (now `value`) at a
/// fixed state by central differences at one and two steps (extrapolated),
/// with the step that moves them by [`PARAMETER_RESPONSE`] of their own
/// scale whatever the parameter's units: the `half` differences of the
/// stencil's models times the step, and the models.
fn differenced(
    model: &RodModel,
    model_at: &impl Fn(usize, f64) -> Result<RodModel>,
    j: usize,
    value: f64,
    half: &mut dyn FnMut(&RodModel, &RodModel) -> Differences,
) -> Result<(Stencil, Differences)> {
    let mut step = first_step(value);
    let mut models = None;
    let mut refusal = None;
    for _ in 0..STEP_TRIES {
        let (plus, minus) = match (model_at(j, step), model_at(j, -step)) {
            (Ok(plus), Ok(minus)) => (plus, minus),
            // A grown step the scene refuses: the last one serves.
            (Err(_), _) | (_, Err(_)) if models.is_some() => break,
            // A first guess it refuses (a parameter at zero that
            // may not be negative, a load beyond any rod's): smaller.
            (Err(e), _) | (_, Err(e)) => {
                refusal = Some(e);
                step *= 1e-6;
                continue;
            }
        };
        let differences = half(&plus, &minus);
        let response = differences.response(model);
        models = Some((plus, minus, step, differences));
        let factor = if !response.is_finite() {
            1e-3
        } else if response > 0.0 {
            (PARAMETER_RESPONSE / response).min(MAX_STEP_GROWTH)
        } else {
            MAX_STEP_GROWTH
        };
        if (0.25..=4.0).contains(&factor) {
            break;
        }
        step *= factor;
    }
    let Some((plus, minus, step, mut differences)) = models else {
        return Err(refusal.expect("an attempt without models was refused"));
    };
    // The far pair: where the scene refuses it, the near pair alone serves
    // (second order).
    let far = match (model_at(j, 2.0 * step), model_at(j, -2.0 * step)) {
        (Ok(a), Ok(b)) => Some((a, b)),
        _ => None,
    };
    if let Some((far_plus, far_minus)) = &far {
        differences.extrapolate(&half(far_plus, far_minus));
    }
    let stencil = Stencil {
        step,
        near: (plus, minus),
        far,
    };
    Ok((stencil, differences))
}

/// The half differences of the free or held equations (no contact): the
/// residual with the held points' reactions and their rows.
fn held_differences<'a>(
    (q, reactions): (&'a [crate::quat::Quat], &'a [Vector3<f64>]),
    held: bool,
) -> impl FnMut(&RodModel, &RodModel) -> Differences + 'a {
    move |plus, minus| {
        let n = q.len() - 1;
        let m = reactions.len();
        let mut scratch = crate::blocktri::BlockTridiagonal::zeros(n);
        let mut positions = vec![Vector3::zeros(); n + 1];
        let mut side = |at: &RodModel| {
            // Each model's interior (fe4) loaded by the reactions, for its
            // held points' positions.
            let mut interior = at.new_interior();
            let mut g = vec![Vector3::zeros(); n];
            evaluate_at(at, q, reactions, &mut interior, &mut g, &mut scratch);
            let mut h = Vec::new();
            if held {
                h = vec![Vector3::zeros(); m];
                at.constraint_residual(q, 1.0, &mut interior, &mut positions, &mut h);
            }
            (g, h)
        };
        let ((ga, ha), (gb, hb)) = (side(plus), side(minus));
        Differences {
            g: ga.iter().zip(&gb).map(|(a, b)| 0.5 * (a - b)).collect(),
            h: ha.iter().zip(&hb).map(|(a, b)| 0.5 * (a - b)).collect(),
            ..Differences::default()
        }
    }
}

/// In contact: the half differences of the whole constrained residual at
/// the fixed state `(q, r)` (the ports' and contacts' forces in it, the
/// contact set held), evaluated in the workspace `w`.
fn contact_differences<'a>(
    w: &'a mut super::Workspace,
    (q, r): (&'a [crate::quat::Quat], &'a [Vector3<f64>]),
) -> impl FnMut(&RodModel, &RodModel) -> Differences + 'a {
    use super::constrained;
    move |plus, minus| {
        let mut side = |at: &RodModel| {
            w.q.copy_from_slice(q);
            w.kkt.reactions.copy_from_slice(r);
            constrained::evaluate(at, w, 1.0, false);
            let ports: Vec<[f64; 2]> = w.kkt.contact.ports.iter().map(|p| p.residual).collect();
            (
                w.g.clone(),
                w.kkt.h.clone(),
                ports,
                w.kkt.contact.gaps.clone(),
            )
        };
        let (a, b) = (side(plus), side(minus));
        Differences {
            g: a.0.iter().zip(&b.0).map(|(x, y)| 0.5 * (x - y)).collect(),
            h: a.1.iter().zip(&b.1).map(|(x, y)| 0.5 * (x - y)).collect(),
            ports: a
                .2
                .iter()
                .zip(&b.2)
                .map(|(x, y)| [0.5 * (x[0] - y[0]), 0.5 * (x[1] - y[1])])
                .collect(),
            gaps: a.3.iter().zip(&b.3).map(|(x, y)| 0.5 * (x - y)).collect(),
        }
    }
}

/// The loading's derivative in the scene path `path` (and each held point's
/// target's): a term's own parameter, or a held point's target; `None`
/// when neither (the equations are differenced).
fn path_tangent(model: &RodModel, path: &str) -> Option<(Loading, Vec<Vector3<f64>>)> {
    let mut moves = vec![Vector3::zeros(); model.constraints().len()];
    if let Some((c, axis)) = held_target(model, path) {
        moves[c][axis] = 1.0;
        return Some((Loading::empty(), moves));
    }
    let tangent = model.terms().derivative(path, model.mesh()).ok()??;
    Some((tangent, moves))
}

/// The held point and axis whose target the scene path `path` is
/// (`guides[i].position[c]`, a held tip's `tip.position[c]`).
fn held_target(model: &RodModel, path: &str) -> Option<(usize, usize)> {
    let constraints = model.constraints();
    let tip_held = constraints.last().is_some_and(|c| c.node == model.n());
    match crate::terms::split_index(path, "guides") {
        Some((g, rest)) => crate::terms::component(rest, ".position").map(|c| (g, c)),
        None if tip_held => {
            crate::terms::component(path, "tip.position").map(|c| (constraints.len() - 1, c))
        }
        None => None,
    }
}

/// Relative step of a parameter in the map to the scene's values: the
/// values it moves, and by how much, by central differences at one and two
/// steps, extrapolated (exact where the map is linear, as every scene
/// parameter's is; a robot's parameters map to the scene's through its own
/// models, smooth: truncation about the step's fourth power, round-off
/// `eps` over the step, 1e-12).
const VALUE_STEP: f64 = 1e-4;

/// The loading's derivative in parameter `j` (now `value`) and each held
/// point's target's, when every scene value it moves belongs to a term or
/// is a held point's target (else `None`: the mesh and the base,
/// whose equations are differenced as a whole). Each value's rate
/// goes through its term's analytic derivative.
fn loading_tangent(
    model: &RodModel,
    scene_at: &impl Fn(usize, f64) -> Result<Scene>,
    j: usize,
    value: f64,
) -> Option<(Loading, Vec<Vector3<f64>>)> {
    let delta = match value {
        0.0 => 1e-6,
        v => VALUE_STEP * v.abs(),
    };
    let values = |k: f64| Some(scene_at(j, k * delta).ok()?.to_value().numbers());
    let (plus, minus) = (values(1.0)?, values(-1.0)?);
    // The far pair where the scene allows it (else the near pair alone).
    let far = values(2.0).zip(values(-2.0));
    let same_paths = |a: &[(String, f64)], b: &[(String, f64)]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.0 == y.0)
    };
    if !same_paths(&plus, &minus)
        || far
            .as_ref()
            .is_some_and(|(a, b)| !same_paths(&plus, a) || !same_paths(&plus, b))
    {
        return None;
    }
    let mut moves = vec![Vector3::zeros(); model.constraints().len()];
    let mut tangent = Loading::empty();
    for (i, ((path, a), (_, b))) in plus.iter().zip(&minus).enumerate() {
        if a == b {
            continue;
        }
        let near = 0.5 * (a - b);
        let half = match &far {
            Some((fp, fm)) => (4.0 * near - 0.25 * (fp[i].1 - fm[i].1)) / 3.0,
            None => near,
        };
        let rate = half / delta;
        // A held point's target: its row moves, no term does.
        if let Some((c, axis)) = held_target(model, path) {
            moves.get_mut(c)?[axis] += rate;
            continue;
        }
        let part = model.terms().derivative(path, model.mesh()).ok()??;
        tangent.add_scaled(&part, rate);
    }
    Some((tangent, moves))
}

impl Solver {
    /// Sensitivity of the last solve's equilibrium to numeric fields of the
    /// scene, named by their path in the scene's dict (`"tip_force[0]"`,
    /// `"stiffness.kx"`, `"rest_curvature[2][1]"`, `"gravity.linear_density"`);
    /// `"rest_curvature"` stands for every section's two components and
    /// `"tip_wrench"` for the tip force and moment (the columns of the 6x6
    /// tip compliance).
    pub fn sensitivity(&mut self, parameters: &[&str]) -> Result<Sensitivity> {
        let mut base = self.scene.to_value();
        // The base's position is written only where it is not the origin;
        // as a parameter it is there at its value.
        if let crate::value::Value::Map(entries) = &mut base {
            if !entries.iter().any(|(k, _)| k == "base_position") {
                let origin = (0..3).map(|_| crate::value::Value::Number(0.0)).collect();
                entries.push(("base_position".into(), crate::value::Value::List(origin)));
            }
        }
        let mut names = Vec::new();
        let mut values = Vec::new();
        for (i, p) in parameters.iter().enumerate() {
            let first = names.len();
            match *p {
                "rest_curvature" => {
                    for s in 0..self.scene.rest_curvature.len() {
                        names.extend([0, 1].map(|c| format!("rest_curvature[{s}][{c}]")));
                    }
                }
                "tip_wrench" => {
                    names.extend((0..3).map(|c| format!("tip_force[{c}]")));
                    names.extend((0..3).map(|c| format!("tip_moment[{c}]")));
                }
                other => names.push(other.to_string()),
            }
            for name in &names[first..] {
                let value = differentiable(name, &self.scene)
                    .and_then(|()| base.clone().number_at_mut(name).map(|x| *x));
                values.push(value.map_err(|e| e.of_parameter(i, p))?);
            }
        }
        // A tension is differenced through zero (a slack tendon: the
        // equations are linear in it), past what a scene may be given.
        let tensions: Vec<Option<usize>> = names
            .iter()
            .map(|name| {
                name.strip_prefix("tendons[")
                    .and_then(|rest| rest.strip_suffix("].tension"))
                    .and_then(|i| i.parse().ok())
            })
            .collect();
        let scene = self.scene.clone();
        self.sensitivity_of_paths(names.clone(), &values, |j, delta| {
            if let Some(i) = tensions[j] {
                let mut moved = scene.clone();
                moved.tendons[i].tension += delta;
                return Ok(moved);
            }
            let mut v = base.clone();
            if section_index(&names[j]).is_none() {
                *v.number_at_mut(&names[j])? += delta;
            }
            if let Some(i) = section_index(&names[j]) {
                stretch_section(&mut v, &scene, i, delta)?;
            }
            Scene::from_value(&v)
        })
    }

    /// Sensitivity of the last solve's equilibrium to parameters given by
    /// the scene they make: `scene_at(j, delta)` is the scene with parameter
    /// `j` (now `values[j]`) moved by `delta`. `dF/dp` comes from central
    /// differences of the discrete equations at the fixed equilibrium, with
    /// the step that moves them by [`PARAMETER_RESPONSE`] of their own scale
    /// whatever the parameter's units (exact for the parameters the
    /// equations are linear in: loads, stiffness, rest curvature); one O(n)
    /// solve with the factored Jacobian a column.
    pub fn sensitivity_with(
        &mut self,
        parameters: Vec<String>,
        values: &[f64],
        scene_at: impl Fn(usize, f64) -> Result<Scene>,
    ) -> Result<Sensitivity> {
        let tangent_of =
            |model: &RodModel, j: usize, value: f64| loading_tangent(model, &scene_at, j, value);
        self.sensitivity_core(parameters, values, tangent_of, &scene_at)
    }

    /// [`Solver::sensitivity_with`] of parameters that are the scene's own
    /// values, named by their paths (`"tendons[0].tension"`): each goes
    /// straight through its term's derivative.
    pub(crate) fn sensitivity_of_paths(
        &mut self,
        paths: Vec<String>,
        values: &[f64],
        scene_at: impl Fn(usize, f64) -> Result<Scene>,
    ) -> Result<Sensitivity> {
        let names = paths.clone();
        let tangent_of = |model: &RodModel, j: usize, _: f64| path_tangent(model, &paths[j]);
        self.sensitivity_core(names, values, tangent_of, scene_at)
    }

    /// [`Solver::sensitivity_with`] with the loading's tangent of each
    /// parameter from `tangent_of` (`None`: the equations are differenced).
    fn sensitivity_core(
        &mut self,
        parameters: Vec<String>,
        values: &[f64],
        tangent_of: impl Fn(&RodModel, usize, f64) -> Option<(Loading, Vec<Vector3<f64>>)>,
        scene_at: impl Fn(usize, f64) -> Result<Scene>,
    ) -> Result<Sensitivity> {
        use super::constrained;
        if !self.settings.method.on_the_potential() {
            return Err(Error::argument(
                "sensitivity",
                "needs the equilibrium of method 'newton' or 'lm'",
            ));
        }
        // The differences below may leave other Jacobians in the workspace.
        self.jacobian_at_solution = false;
        let (model, w) = (&self.model, &mut self.work);
        let (n, scheme) = (model.n(), model.scheme());
        let held = model.is_constrained();
        if held {
            constrained::evaluate(model, w, 1.0, true);
            constrained::load_constraint_jacobian(model, w);
        } else {
            model.residual_jacobian(&w.q, 1.0, &mut w.interior, &mut w.g, &mut w.jac);
        }
        let residual = super::residual_norm(model, w);
        let tol = model.effective_tol(self.settings.residual_tol);
        // NaN fails too.
        if residual.is_nan() || residual > 1e3 * tol.max(1e-12) {
            return Err(Error::argument(
                "sensitivity",
                format!("needs a converged equilibrium: solve first (residual {residual:.1e})"),
            ));
        }
        if w.lu.factor(&w.jac, 0.0).is_err() {
            return Err(Error::NotConverged {
                status: Status::NotConverged,
                iterations: 0,
                residual,
                reason: "singular Jacobian: the equilibrium is at a bifurcation".into(),
            });
        }
        let q0 = w.q.clone();
        let r0 = w.kkt.reactions.clone();
        let clamped = model.clamped_tip().is_some();
        let k = parameters.len();
        let mut out = Sensitivity {
            parameters,
            tip_position: nalgebra::Matrix3xX::zeros(k),
            tip_rotation: nalgebra::Matrix3xX::zeros(k),
            tip_reaction_force: (held
                && !model.constraints().is_empty()
                && model.constraints().last().is_some_and(|c| c.node == n))
            .then(|| nalgebra::Matrix3xX::zeros(k)),
            // In contact the clamp's moment takes the contacts' forces too,
            // which the differences along the tangent do not move: not given.
            tip_reaction_moment: (clamped && !model.has_contact())
                .then(|| nalgebra::Matrix3xX::zeros(k)),
            exact: vec![false; k],
        };
        // The held points' reactions (the ports' and contacts' multipliers
        // follow them in `r0`; the step's rows are the held points' first).
        let m = model.constraints().len();
        let mut scratch = crate::blocktri::BlockTridiagonal::zeros(n);
        let model_at = |j: usize, delta: f64| -> Result<RodModel> {
            let scene = scene_at(j, delta)?;
            scene.check_derived()?;
            Ok(RodModel::new(&scene, n).with_scheme(scheme))
        };
        let mut shift = Vec::new();
        // The tip's position Jacobian in the rotations and (fe4, through the
        // internal nodes the reactions load) in the reactions, for the
        // outputs of an analytic column.
        let mut d_tip = vec![nalgebra::Matrix3::zeros(); n];
        model.position_jacobian(&q0, n, &w.interior, &mut d_tip);
        let with_tip: Vec<usize> = model
            .constraints()
            .iter()
            .map(|c| c.node)
            .chain([n])
            .collect();
        let tip_compliance =
            model
                .discretisation()
                .held_point_compliance(model.rod(), &q0, &with_tip, &w.interior);
        let mut moved_nodes = vec![Vector3::zeros(); n + 1];
        for (j, &value) in values.iter().enumerate() {
            // dF/dp at the fixed state (rotations and reactions): from the
            // terms' analytic derivatives where every scene value the
            // parameter moves belongs to a term or a held point's target,
            // else by central differences of the discrete equations.
            let analytic = tangent_of(model, j, value);
            out.exact[j] = analytic.is_some();
            let mut models = None;
            // In contact, a differenced parameter may move the rod against its
            // surroundings: the ports' and contacts' rows move too.
            let mut moving: Option<(Vec<[f64; 2]>, Vec<f64>)> = None;
            if let Some((tangent, target_moves)) = &analytic {
                model.residual_derivative(&q0, &r0, tangent, &mut w.interior, &mut w.g, &mut shift);
                model.position_derivative(&q0, &mut w.interior, &shift, &mut moved_nodes);
                if held {
                    for ((h, c), moved) in w
                        .kkt
                        .h
                        .iter_mut()
                        .zip(model.constraints())
                        .zip(target_moves)
                    {
                        *h = moved_nodes[c.node] - moved;
                    }
                }
            } else {
                if model.has_contact() {
                    refuse_moving_what_sticks(model, w, &out.parameters[j])?;
                }
                let (stencil, d) = if model.has_contact() {
                    let found = differenced(
                        model,
                        &model_at,
                        j,
                        value,
                        &mut contact_differences(w, (&q0, &r0)),
                    );
                    // The workspace's state and sites are the model's again.
                    w.q.copy_from_slice(&q0);
                    w.kkt.reactions.copy_from_slice(&r0);
                    constrained::evaluate(model, w, 1.0, false);
                    found?
                } else {
                    let mut half = held_differences((&q0, &r0[..m]), held);
                    differenced(model, &model_at, j, value, &mut half)?
                };
                w.g.copy_from_slice(&d.g);
                for (h, x) in w.kkt.h.iter_mut().zip(&d.h) {
                    *h = *x;
                }
                if model.has_contact() {
                    moving = Some((d.ports, d.gaps));
                }
                models = Some(stencil);
            }
            // The step that moves the equations by PARAMETER_RESPONSE of
            // their scale: the differences' own, or an analytic column's
            // (which bounds the outputs' step below, whatever the units).
            let (step, response_step) = match &models {
                Some(stencil) => (stencil.step, stencil.step),
                None => {
                    let mut response = model.residual_norm(&w.g);
                    if held {
                        let moved = w.kkt.h.iter().map(|h| h.amax()).fold(0.0, f64::max);
                        response = response.max(moved / model.length());
                    }
                    let bound = match response > 0.0 && response.is_finite() {
                        true => PARAMETER_RESPONSE / response,
                        false => first_step(value),
                    };
                    (1.0, bound)
                }
            };
            w.g.iter_mut().for_each(|g| *g /= step);
            if held {
                w.kkt.h.iter_mut().for_each(|h| *h /= step);
                if clamped {
                    w.g[n - 1] = Vector3::zeros();
                }
                let solved = match &moving {
                    Some((ports, gaps)) => {
                        let ports: Vec<[f64; 2]> =
                            ports.iter().map(|p| p.map(|x| x / step)).collect();
                        let gaps: Vec<f64> = gaps.iter().map(|x| x / step).collect();
                        constrained::kkt_solve_moving(w, &ports, &gaps)
                    }
                    None => constrained::kkt_solve(w),
                };
                if !solved {
                    return Err(Error::argument("sensitivity", "singular KKT system"));
                }
            } else {
                w.step.copy_from_slice(&w.g);
                w.lu.solve_in_place(&mut w.step);
                w.step.iter_mut().for_each(|x| *x = -*x);
            }
            // The state's tangent: d theta / dp = w.step (node i at index i - 1),
            // d R / dp = w.kkt.rhs. An analytic column's outputs from it
            // (but a clamped tip's reaction moment); the others' by central
            // differences along it.
            let reaction_step = |c: usize| {
                Vector3::new(w.kkt.rhs[3 * c], w.kkt.rhs[3 * c + 1], w.kkt.rhs[3 * c + 2])
            };
            if analytic.is_some() && !clamped {
                let mut dr = d_tip
                    .iter()
                    .zip(&w.step)
                    .map(|(b, x)| b * x)
                    .sum::<Vector3<f64>>()
                    + moved_nodes[n];
                if let Some(e) = &tip_compliance {
                    // The tip is the last of `with_tip`: E dR over the held points.
                    for c in 0..m {
                        dr += e.fixed_view::<3, 3>(3 * m, 3 * c) * reaction_step(c);
                    }
                }
                out.tip_position.set_column(j, &dr);
                out.tip_rotation.set_column(j, &q0[n].rotate(w.step[n - 1]));
                if let Some(col) = out.tip_reaction_force.as_mut() {
                    col.set_column(j, &reaction_step(m - 1));
                }
                continue;
            }
            let turn = w.step.iter().map(|x| x.amax()).fold(0.0, f64::max);
            let eps = match turn > 0.0 {
                true => (OUTPUT_TURN / turn).min(response_step),
                false => response_step,
            };
            // The stencil's models serve when the step keeps the state's move
            // small enough (the common case).
            let (near, far) = match models {
                Some(stencil) if eps == stencil.step => (stencil.near, stencil.far),
                _ => {
                    let far = match (model_at(j, 2.0 * eps), model_at(j, -2.0 * eps)) {
                        (Ok(a), Ok(b)) => Some((a, b)),
                        _ => None,
                    };
                    ((model_at(j, eps)?, model_at(j, -eps)?), far)
                }
            };
            // The tip's report at the state moved by `k eps` along the column
            // with the model at `k eps`.
            let mut report = |at: &RodModel, k: f64| -> TipReport {
                let mut q = q0.clone();
                for (i, x) in w.step.iter().enumerate() {
                    q[i + 1] = q0[i + 1].perturbed(k * eps * x);
                }
                let r: Vec<Vector3<f64>> =
                    (0..m).map(|c| r0[c] + k * eps * reaction_step(c)).collect();
                tip_report(at, &q, &r, &mut scratch)
            };
            // `(f(+) - f(-)) / 2` of every output of a pair of reports: the
            // position, the world-frame turn from the minus to the plus
            // orientation (`2 v` of the relative rotation, odd in the step as
            // the difference), the reactions.
            let half = |a: &TipReport, b: &TipReport| -> [Option<Vector3<f64>>; 4] {
                let turn = a.orientation * b.orientation.conj();
                let turn = if turn.w < 0.0 { -turn } else { turn };
                let pair = |x: Option<Vector3<f64>>, y: Option<Vector3<f64>>| {
                    x.zip(y).map(|(x, y)| 0.5 * (x - y))
                };
                [
                    Some(0.5 * (a.position - b.position)),
                    Some(turn.v),
                    pair(a.reaction_force, b.reaction_force),
                    pair(a.reaction_moment, b.reaction_moment),
                ]
            };
            let mut outputs = half(&report(&near.0, 1.0), &report(&near.1, -1.0));
            if let Some((far_plus, far_minus)) = &far {
                let wide = half(&report(far_plus, 2.0), &report(far_minus, -2.0));
                for (o, f) in outputs.iter_mut().zip(wide) {
                    *o = o.zip(f).map(|(o, f)| extrapolated(o, f));
                }
            }
            let [position, turn, force, moment] = outputs.map(|o| o.map(|v| v / eps));
            out.tip_position.set_column(j, &position.expect("always"));
            out.tip_rotation.set_column(j, &turn.expect("always"));
            if let (Some(col), Some(x)) = (out.tip_reaction_force.as_mut(), force) {
                col.set_column(j, &x);
            }
            if let (Some(col), Some(x)) = (out.tip_reaction_moment.as_mut(), moment) {
                col.set_column(j, &x);
            }
        }
        Ok(out)
    }
}

/// A parameter that moves the rod against its surroundings (the base, a
/// differenced one) while a contact or port sticks is refused by name: the
/// sticking rows' own motion is not differenced (the IK's Jacobian, which
/// lets what sticks go, has none).
fn refuse_moving_what_sticks(model: &RodModel, w: &super::Workspace, name: &str) -> Result<()> {
    if !super::friction::sticks_anywhere(model, w) {
        return Ok(());
    }
    Err(Error::argument(
        name,
        "not given while a contact or port sticks: it moves the rod against what holds it",
    ))
}

/// The loading's derivatives in the named parameters, each from its term.
fn term_tangents(model: &RodModel, names: impl Iterator<Item = String>) -> Result<Vec<Loading>> {
    names
        .map(|name| {
            model
                .terms()
                .derivative(&name, model.mesh())?
                .ok_or_else(|| Error::argument(name, "no such parameter"))
        })
        .collect()
}
