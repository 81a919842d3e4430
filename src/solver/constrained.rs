//! Held nodes (a pinned tip, guides) and a clamped tip: the KKT system.
//!
//! Each held node `k` adds its reaction `R_c` (3 unknowns) and the rows
//! `h_c = r_k(q) - p_c = 0`. The reactions act on the rod as point forces, so the
//! residual is `g(theta, R) = g_0(theta) - sum_c D_c^T R_c` with `D_c = dr_k/dtheta`,
//! and a Newton step solves
//!
//! ```text
//! [ A   -D^T ] [dtheta]   [-g]
//! [ D    0   ] [dR    ] = [-h]
//! ```
//!
//! (with the fourth-order scheme the lower right block is `E = dh/dR`, the
//! held points' motion through the internal nodes the reactions load, and
//! `S` gains it) by the Schur complement `S = D A^{-1} D^T` (3m x 3m, m held nodes): two sweeps
//! of the O(n) block-tridiagonal factorisation per column of `D^T`, so the cost
//! stays linear in n. A clamped tip fixes `q_n` (a Dirichlet row); its reaction
//! moment is what the torque balance of node n leaves over. Nothing here runs
//! for a free tip without guides.

use super::contact::{self, ContactWork};
use super::{step_limit, Workspace};
use crate::blocktri::BlockLu;
use crate::disc::NodeForces;
use crate::interrupt;
use crate::model::RodModel;
use nalgebra::{DMatrix, DVector, Matrix3, SymmetricEigen, Vector3};

/// Buffers of the constrained solve, sized once (empty for free scenes).
#[derive(Debug, Clone)]
pub(crate) struct KktWorkspace {
    pub reactions: Vec<Vector3<f64>>,
    pub reactions_start: Vec<Vector3<f64>>,
    pub reaction_step: Vec<Vector3<f64>>,
    pub reactions_saved: Vec<Vector3<f64>>,
    /// Constraint residuals `h_c` (m).
    pub h: Vec<Vector3<f64>>,
    /// `D_c` blocks per constraint, per node.
    pub d: Vec<Vec<Matrix3<f64>>>,
    /// `A^{-1} D^T e` per constraint component (3m columns of n blocks).
    pub columns: Vec<Vec<Vector3<f64>>>,
    pub positions: Vec<Vector3<f64>>,
    pub schur: DMatrix<f64>,
    pub rhs: DVector<f64>,
    /// Torque balance of a clamped tip node before it is replaced by the
    /// Dirichlet row: the reaction moment in the body frame.
    pub tip_torque: Vector3<f64>,
    /// `dh / dR` at fixed rotations (the fourth-order scheme's internal nodes
    /// move with the reactions; see `RodModel::held_point_compliance`).
    pub compliance: Option<DMatrix<f64>>,
    /// The KKT system's rows as `n` vectors each (`D^T e`): three a held
    /// point, then one an active contact; `row_count` of them in use.
    pub rows: Vec<Vec<Vector3<f64>>>,
    pub row_count: usize,
    /// How many leading entries of each row may be nonzero: a position
    /// depends on the rotations up to its node only.
    pub row_len: Vec<usize>,
    /// The contact rows' sites, active set and forces (see `contact.rs`).
    pub contact: ContactWork,
}

impl KktWorkspace {
    /// Forget the multipliers of the last solve: every reaction and
    /// contact force zero, no contact held (a solve's answer and its path
    /// never depend on the one before).
    pub fn clear_multipliers(&mut self) {
        self.reactions
            .iter_mut()
            .for_each(|r| *r = Vector3::zeros());
        self.contact.active.clear();
        self.contact.held.clear();
    }

    pub fn new(model: &RodModel) -> Self {
        let (n, m) = (model.n(), model.constraints().len());
        let positions = if model.is_constrained() { n + 1 } else { 0 };
        // The contact slots' multipliers follow the held points' reactions.
        let multipliers = m + contact::slot_count(model);
        KktWorkspace {
            reactions: vec![Vector3::zeros(); multipliers],
            reactions_start: vec![Vector3::zeros(); multipliers],
            reaction_step: vec![Vector3::zeros(); multipliers],
            reactions_saved: vec![Vector3::zeros(); multipliers],
            h: vec![Vector3::zeros(); m],
            d: vec![vec![Matrix3::zeros(); n]; m],
            columns: vec![vec![Vector3::zeros(); n]; 3 * m],
            positions: vec![Vector3::zeros(); positions],
            schur: DMatrix::zeros(3 * m, 3 * m),
            rhs: DVector::zeros(3 * m),
            tip_torque: Vector3::zeros(),
            compliance: None,
            rows: vec![vec![Vector3::zeros(); n]; 3 * m],
            row_count: 3 * m,
            row_len: Vec::new(),
            contact: ContactWork::new(model),
        }
    }
}

/// Weight of a held point's position rows in the scaled merit, `1 / L`: the
/// torque rows count over their own scales (see `RodModel::residual_norm`), so
/// `tol` bounds `|h| / L` alike.
pub(crate) fn position_weight(model: &RodModel) -> f64 {
    1.0 / model.length()
}

/// Residual (and Jacobian) at `w.q` with the reactions `w.kkt.reactions`;
/// applies the clamped tip's Dirichlet row. Returns the merit `|g|^2 + |W h|^2`.
pub(crate) fn evaluate(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    with_jacobian: bool,
) -> f64 {
    let n = model.n();
    let jac = if with_jacobian {
        Some(&mut w.jac)
    } else {
        None
    };
    if model.has_obstacles() {
        // The contact forces act where the backbone is: positions first
        // (the second-order scheme's need no interior).
        model.positions(&w.q, &mut w.interior, &mut w.kkt.positions);
        contact::locate(model, &w.kkt.positions, &mut w.kkt.contact.sites);
        contact::gather_forces(model, w);
        contact::gather_gaps(w);
        let held = NodeForces {
            nodes: &w.kkt.contact.force_nodes,
            forces: &w.kkt.contact.force_vectors,
        };
        let jac = if with_jacobian {
            Some(&mut w.jac)
        } else {
            None
        };
        model.residual_with_forces(&w.q, lambda, held, &mut w.interior, &mut w.g, jac);
        model.held_point_residual(&w.kkt.positions, lambda, &mut w.kkt.h);
    } else {
        model.residual_with_reactions(
            &w.q,
            lambda,
            &w.kkt.reactions,
            &mut w.interior,
            &mut w.g,
            jac,
        );
        model.constraint_residual(
            &w.q,
            lambda,
            &mut w.interior,
            &mut w.kkt.positions,
            &mut w.kkt.h,
        );
    }
    if model.clamped_tip().is_some() {
        w.kkt.tip_torque = w.g[n - 1];
        w.g[n - 1] = Vector3::zeros();
        if with_jacobian {
            let scale = w.jac.max_diagonal().max(f64::MIN_POSITIVE);
            w.jac.diag[n - 1] = Matrix3::identity() * scale;
            if n >= 2 {
                w.jac.upper[n - 2] = Matrix3::zeros();
                w.jac.lower[n - 2] = Matrix3::zeros();
            }
        }
    }
    let contact = &w.kkt.contact;
    let gaps = contact.gaps.iter().zip(&contact.held);
    let contact_rows = gaps.map(|(x, held)| contact_error(*x, *held).powi(2)).sum();
    merit(model, &w.g, &w.kkt.h, contact_rows)
}

/// A candidate contact's error: a held one's gap, a free one's penetration.
fn contact_error(gap: f64, held: bool) -> f64 {
    if held {
        gap
    } else {
        gap.min(0.0)
    }
}

fn merit(model: &RodModel, g: &[Vector3<f64>], h: &[Vector3<f64>], contact_rows: f64) -> f64 {
    let wt = position_weight(model);
    let rows = h.iter().map(|x| x.norm_squared()).sum::<f64>() + contact_rows;
    model.merit(g) + wt * wt * rows
}

/// Dimensionless residual: torque rows and weighted constraint rows together.
pub(crate) fn residual_norm(model: &RodModel, w: &Workspace) -> f64 {
    let mut h = 0.0f64;
    for x in &w.kkt.h {
        let r = x.amax() * position_weight(model);
        if !r.is_finite() {
            return f64::INFINITY;
        }
        h = h.max(r);
    }
    let contact = &w.kkt.contact;
    for (x, held) in contact.gaps.iter().zip(&contact.held) {
        let r = contact_error(*x, *held).abs() * position_weight(model);
        if !r.is_finite() {
            return f64::INFINITY;
        }
        h = h.max(r);
    }
    model.residual_norm(&w.g).max(h)
}

/// Fill `D_c` at `w.q` (zero on a clamped tip node, which does not move).
pub(crate) fn load_constraint_jacobian(model: &RodModel, w: &mut Workspace) {
    w.kkt.compliance = model.held_point_compliance(&w.q, &w.interior);
    for (c, d) in model.constraints().iter().zip(w.kkt.d.iter_mut()) {
        model.position_jacobian(&w.q, c.node, &w.interior, d);
        if model.clamped_tip().is_some() {
            d[model.n() - 1] = Matrix3::zeros();
        }
    }
    let held = model.constraints().len();
    for (c, d) in w.kkt.d[..held].iter().enumerate() {
        for e in 0..3 {
            for (x, b) in w.kkt.rows[3 * c + e].iter_mut().zip(d) {
                *x = b.row(e).transpose();
            }
        }
    }
    contact::load_rows(model, w, 3 * held);
    w.kkt.row_count = 3 * held + w.kkt.contact.active.len();
    let n = model.n();
    w.kkt.row_len.clear();
    for c in model.constraints() {
        w.kkt.row_len.extend([c.node.min(n); 3]);
    }
    for &i in &w.kkt.contact.active {
        w.kkt.row_len.push(contact::last_node(model, i).min(n));
    }
    if model.has_obstacles() {
        contact::curvature(model, w);
    }
}

/// `x . y` over the nodes.
fn dot(x: &[Vector3<f64>], y: &[Vector3<f64>]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a.dot(b)).sum()
}

/// Row `r`'s residual: a held point's position error, then an active
/// contact's gap.
fn row_residual(w: &Workspace, r: usize) -> f64 {
    let held = w.kkt.row_count - w.kkt.contact.gaps.len();
    if r < held {
        w.kkt.h[r / 3][r % 3]
    } else {
        w.kkt.contact.gaps[r - held]
    }
}

/// Solve the KKT system at the current state (Jacobian and `D` loaded, `lu`
/// factored): the rotation step goes to `w.step`, the reaction step to `w.kkt.rhs`.
/// [`kkt_step`] with `w.lu` factored, for the sensitivities: `w.step` and
/// `w.kkt.rhs` (the reactions' step) from `w.g` and `w.kkt.h`. The contacts
/// held stay on their obstacles, which do not move (their rows' residuals
/// zero), and the others stay free: a derivative along the active set.
pub(crate) fn kkt_solve(w: &mut Workspace) -> bool {
    let lu = std::mem::replace(&mut w.lu, BlockLu::new(0));
    let gaps = std::mem::take(&mut w.kkt.contact.gaps);
    w.kkt.contact.gaps = vec![0.0; gaps.len()];
    w.kkt.contact.choose = false;
    let ok = kkt_step(&lu, w);
    w.kkt.contact.choose = true;
    w.kkt.contact.gaps = gaps;
    w.lu = lu;
    ok
}

fn kkt_step(lu: &BlockLu, w: &mut Workspace) -> bool {
    let rows = w.kkt.row_count;
    // y = A^{-1} g  (in w.scratch)
    w.scratch.copy_from_slice(&w.g);
    lu.solve_in_place(&mut w.scratch);
    // columns = A^{-1} D^T e_r
    let n = w.g.len();
    while w.kkt.columns.len() < rows {
        w.kkt.columns.push(vec![Vector3::zeros(); n]);
    }
    for (col, row) in w.kkt.columns.iter_mut().zip(&w.kkt.rows[..rows]) {
        col.copy_from_slice(row);
        lu.solve_in_place(col);
    }
    // The contacts' curvature: the Jacobian is `A + U M U^T`, whose inverse
    // the Woodbury identity applies from `A`'s.
    if !w.kkt.contact.curvature_blocks.is_empty() {
        let Some(curvature) = CurvatureInverse::new(lu, w) else {
            return false;
        };
        curvature.correct(&mut w.scratch);
        for col in &mut w.kkt.columns[..rows] {
            curvature.correct(col);
        }
    }
    if w.kkt.schur.nrows() != rows {
        w.kkt.schur = DMatrix::zeros(rows, rows);
        w.kkt.rhs = DVector::zeros(rows);
    }
    for r in 0..rows {
        for k in 0..rows {
            let len = w.kkt.row_len[r];
            w.kkt.schur[(r, k)] = dot(&w.kkt.rows[r][..len], &w.kkt.columns[k][..len]);
        }
        w.kkt.rhs[r] = dot(&w.kkt.rows[r], &w.scratch) - row_residual(w, r);
    }
    if let Some(e) = &w.kkt.compliance {
        let held = e.nrows();
        let mut block = w.kkt.schur.view_mut((0, 0), (held, held));
        block += e;
    }
    let candidates = w.kkt.contact.gaps.len();
    if candidates == 0 {
        if !solve_small_in_place(&mut w.kkt.schur, &mut w.kkt.rhs) {
            return false;
        }
    } else {
        // The contact forces stay >= 0: a candidate's step is bounded below
        // by minus its force, and the QP decides which are held.
        let first = w.kkt.reactions.len() - w.kkt.contact.sites.len();
        let lower: Vec<f64> = w
            .kkt
            .contact
            .active
            .iter()
            .map(|&i| -w.kkt.reactions[first + i].x.max(0.0))
            .collect();
        let choose = w.kkt.contact.choose;
        let Some(x) = bounded_qp(
            &w.kkt.schur,
            &w.kkt.rhs,
            rows - candidates,
            &lower,
            &mut w.kkt.contact.held,
            choose,
        ) else {
            return false;
        };
        w.kkt.rhs.copy_from(&x);
    }
    for (j, s) in w.step.iter_mut().enumerate() {
        let mut v = -w.scratch[j];
        for (k, col) in w.kkt.columns[..rows].iter().enumerate() {
            v += col[j] * w.kkt.rhs[k];
        }
        *s = v;
    }
    true
}

/// The multipliers' step from the last KKT solve into `reaction_step`:
/// the held points' reactions, then the active contacts' forces (a free
/// contact's stays zero).
fn take_multiplier_step(model: &RodModel, w: &mut Workspace) {
    let held = model.constraints().len();
    let rhs = &w.kkt.rhs;
    for (i, d) in w.kkt.reaction_step[..held].iter_mut().enumerate() {
        *d = Vector3::new(rhs[3 * i], rhs[3 * i + 1], rhs[3 * i + 2]);
    }
    if model.has_obstacles() {
        let first = contact::offset(model, w);
        w.kkt.reaction_step[first..]
            .iter_mut()
            .for_each(|d| *d = Vector3::zeros());
        for (a, &i) in w.kkt.contact.active.iter().enumerate() {
            w.kkt.reaction_step[first + i] = Vector3::new(w.kkt.rhs[3 * held + a], 0.0, 0.0);
        }
    }
}

/// The step of the multipliers where some are bounded below: the QP
/// `min 1/2 x^T S x - b^T x` with `x_i >= lower_i` for the rows from
/// `equalities` on (the contact candidates; `held` says which are free of
/// their bound). Its optimality conditions are the linearised contact's:
/// the gap after the step, `w = S x - b`, vanishes where a force is free
/// and is `>= 0` where it is at its bound (zero force). A primal active set
/// from the held candidates, feasible throughout (`x = 0` is: the forces are
/// `>= 0`): finite for `S` positive definite. With `choose` false the held
/// set is kept and solved as it is (a tangent).
fn bounded_qp(
    s: &DMatrix<f64>,
    b: &DVector<f64>,
    equalities: usize,
    lower: &[f64],
    held: &mut [bool],
    choose: bool,
) -> Option<DVector<f64>> {
    let m = b.len();
    let bounded = |i: usize| i >= equalities;
    let mut x = DVector::zeros(m);
    let scale = b.amax().max(f64::MIN_POSITIVE);
    // Rows freed and blocked again at once, with no step: a round-off
    // choice (degenerate), never freed again in this QP, so that it ends.
    let mut freed = vec![false; m];
    let mut frozen = vec![false; m];
    for _ in 0..4 * m + 8 {
        let free: Vec<usize> = (0..m)
            .filter(|&i| !bounded(i) || held[i - equalities])
            .collect();
        // The subproblem: the bounded rows at their bounds, the rest solved.
        let mut trial = x.clone();
        for i in (equalities..m).filter(|&i| !held[i - equalities]) {
            trial[i] = lower[i - equalities];
        }
        let mut sub = DMatrix::from_fn(free.len(), free.len(), |r, c| s[(free[r], free[c])]);
        let mut rhs = DVector::from_fn(free.len(), |r, _| {
            let i = free[r];
            b[i] - (equalities..m)
                .filter(|&j| !held[j - equalities])
                .map(|j| s[(i, j)] * trial[j])
                .sum::<f64>()
        });
        if !free.is_empty() && !solve_positive_in_place(&mut sub, &mut rhs) {
            return None;
        }
        for (r, &i) in free.iter().enumerate() {
            trial[i] = rhs[r];
        }
        if !choose {
            return Some(trial);
        }
        // A free force that would go below its bound stops the step there.
        let mut step = 1.0;
        let mut blocking = None;
        for &i in free.iter().filter(|&&i| bounded(i)) {
            let (lo, from, to) = (lower[i - equalities], x[i], trial[i]);
            if to < lo && from > to {
                let t = ((from - lo) / (from - to)).clamp(0.0, 1.0);
                if t < step {
                    step = t;
                    blocking = Some(i);
                }
            }
        }
        if let Some(i) = blocking {
            if freed[i] && step <= 1e-12 {
                frozen[i] = true;
            }
            freed.iter_mut().for_each(|f| *f = false);
            x += step * (&trial - &x);
            x[i] = lower[i - equalities];
            held[i - equalities] = false;
            continue;
        }
        x = trial;
        // Every zero force whose gap would go negative is freed.
        let gap = s * &x - b;
        freed.iter_mut().for_each(|f| *f = false);
        let mut any = false;
        for i in equalities..m {
            if !held[i - equalities] && !frozen[i] && gap[i] < -1e-12 * scale {
                held[i - equalities] = true;
                freed[i] = true;
                any = true;
            }
        }
        if !any {
            return Some(x);
        }
    }
    None
}

/// Solve `a x = b` for a positive definite `a` by Cholesky, or by the
/// pseudo-inverse where it is not (a redundant row).
fn solve_positive_in_place(a: &mut DMatrix<f64>, b: &mut DVector<f64>) -> bool {
    if let Some(chol) = a.clone().cholesky() {
        let x = chol.solve(b);
        if x.iter().all(|v| v.is_finite()) {
            b.copy_from(&x);
            return true;
        }
    }
    solve_small_in_place(a, b)
}

/// Minimum-norm solution of the small Schur system by SVD. `S` is singular where
/// a held point cannot move to first order: at the straight rod, along its axis
/// (the rod is inextensible). The pseudo-inverse leaves that reaction component
/// alone for this step; the loads bend the rod and the next step sees it.
fn solve_small_in_place(a: &mut DMatrix<f64>, b: &mut DVector<f64>) -> bool {
    if a.nrows() == 0 {
        // No row held (obstacles, none touched): the free step.
        return true;
    }
    let svd = a.clone().svd(true, true);
    let cutoff = 1e-11 * svd.singular_values.max();
    if cutoff.is_nan() || cutoff <= 0.0 {
        return false;
    }
    match svd.solve(b, cutoff) {
        Ok(x) if x.iter().all(|v| v.is_finite()) => {
            b.copy_from(&x);
            true
        }
        _ => false,
    }
}

/// The path's tangent at the equilibrium in `w.q` (reactions in
/// `w.kkt.reactions`) at `lambda`: `-dtheta/dlambda` into `w.step` (the sign
/// of the free scenes' predictor) and `dR/dlambda` into `w.kkt.reaction_step`.
/// It is the Newton step of the KKT system for the residuals' derivatives
/// `[dg/dlambda; dh/dlambda]`: the loads' (nothing on a leg whose loads stay
/// fixed) and the targets' motion. Near a held point's full reach the tangent
/// is large and points along the buckling mode, which is what the predictor
/// needs there. A clamped tip's orientation is left to the corrector.
pub(crate) fn tangent(model: &RodModel, w: &mut Workspace, lambda: f64) -> bool {
    let n = model.n();
    let m = model.constraints().len();
    evaluate(model, w, lambda, true);
    load_constraint_jacobian(model, w);
    if model.loads_held_fixed() {
        w.g.iter_mut().for_each(|x| *x = Vector3::zeros());
    } else {
        model.residual_lambda_derivative(&w.q, &mut w.interior, &mut w.g, &mut w.scratch);
    }
    if model.clamped_tip().is_some() {
        w.g[n - 1] = Vector3::zeros();
    }
    for (h, c) in w.kkt.h[..m].iter_mut().zip(model.constraints()) {
        *h = c.rest - c.target;
    }
    // The obstacles stay: the active contacts keep their gaps.
    w.kkt.contact.gaps.iter_mut().for_each(|x| *x = 0.0);
    w.kkt.contact.choose = false;
    let solved = super::newton::damped_solve(model, w, kkt_step);
    w.kkt.contact.choose = true;
    if !solved {
        return false;
    }
    w.step.iter_mut().for_each(|x| *x = -*x);
    take_multiplier_step(model, w);
    true
}

/// Newton on the KKT system with a backtracking line search on the merit.
pub(crate) fn newton(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    (max_iter, tol): (usize, f64),
) -> (bool, usize) {
    let n = model.n();
    if let Some(tip) = model.clamped_tip_at(lambda) {
        w.q[n] = tip;
    }
    let mut merit_now = evaluate(model, w, lambda, true);
    // One pass more than the budget: the last one only certifies.
    for it in 0..=max_iter {
        // The contact candidates of this step (see `contact.rs`); a step
        // whose QP changes which are held certifies nothing.
        let mut held_before = Vec::new();
        if model.has_obstacles() {
            contact::select_candidates(model, w, contact_margin(model));
            merit_now = evaluate(model, w, lambda, true);
            held_before = contact::held_slots(w);
        }
        let norm = residual_norm(model, w);
        if !norm.is_finite() || interrupt::requested() {
            return (false, it);
        }
        load_constraint_jacobian(model, w);
        let mut solved = super::newton::damped_solve(model, w, kkt_step);
        // A step that would carry the rod through an obstacle it is not
        // yet near (a thin one, a large step) holds those slots too.
        for _ in 0..CROSSING_PASSES {
            if !solved || !model.has_obstacles() {
                break;
            }
            let crossed = crossing_of_step(model, w);
            if crossed.is_empty() {
                break;
            }
            contact::add_candidates(w, &crossed);
            contact::gather_gaps(w);
            load_constraint_jacobian(model, w);
            solved = super::newton::damped_solve(model, w, kkt_step);
        }
        if !solved {
            return (false, it);
        }
        let settled = !model.has_obstacles() || contact::held_slots(w) == held_before;
        if settled && super::newton::certified(norm, &w.step, tol) {
            return (true, it);
        }
        if it == max_iter {
            return (false, it);
        }
        take_multiplier_step(model, w);
        // The start is kept in `w.trial` and `reactions_start`; trials go in place.
        w.trial.copy_from_slice(&w.q);
        w.kkt.reactions_start.copy_from_slice(&w.kkt.reactions);
        let alpha = step_limit(&w.step, 1.0, 0.3);
        let accepted = super::newton::backtrack(
            w,
            alpha,
            merit_now,
            |w, alpha, _| {
                for j in 1..=n {
                    w.q[j] = w.trial[j].perturbed(alpha * w.step[j - 1]);
                }
                for ((r, r0), d) in w
                    .kkt
                    .reactions
                    .iter_mut()
                    .zip(&w.kkt.reactions_start)
                    .zip(&w.kkt.reaction_step)
                {
                    *r = r0 + alpha * d;
                }
                evaluate(model, w, lambda, false)
            },
            |w| residual_norm(model, w) <= tol,
        );
        if accepted.is_none() {
            w.q.copy_from_slice(&w.trial);
            w.kkt.reactions.copy_from_slice(&w.kkt.reactions_start);
            evaluate(model, w, lambda, true);
            return (false, it + 1);
        }
        merit_now = evaluate(model, w, lambda, true);
    }
    unreachable!("the loop returns at its last pass")
}

/// How often a Newton step is solved again with the slots it would carry
/// through their obstacles.
const CROSSING_PASSES: usize = 4;

/// The slots that the step in `w.step` (from `w.q`) carries across their
/// obstacles (see [`contact::crossing`]). `w.trial` holds the stepped chain
/// (scratch here: the line search sets it afterwards).
pub(crate) fn crossing_of_step(model: &RodModel, w: &mut Workspace) -> Vec<usize> {
    for ((moved, start), step) in w.trial[1..].iter_mut().zip(&w.q[1..]).zip(&w.step) {
        *moved = start.perturbed(*step);
    }
    w.trial[0] = w.q[0];
    let mut moved = std::mem::take(&mut w.kkt.contact.moved);
    model.positions(&w.trial, &mut w.interior, &mut moved);
    let crossed = contact::crossing(model, w, &moved, true);
    w.kkt.contact.moved = moved;
    crossed
}

/// How near its obstacle a slot is a candidate of the next step [m]: a
/// tenth of the longest element. Measured on the lifted rod: as many Newton
/// steps as with a whole element (5 to 7 at n = 60 and 240) at a third of
/// the cost for n = 80 (fewer rows in the Schur complement); none at all
/// (only the slots held and inside) takes 16 to 59.
fn contact_margin(model: &RodModel) -> f64 {
    let longest = model
        .mesh()
        .element_lengths()
        .iter()
        .fold(0.0f64, |a, b| a.max(*b));
    0.1 * longest
}

/// The inverse of `A + U M U^T` from `A`'s factorisation (the contacts'
/// curvature, see `contact::curvature`), and the inertia it adds. Each block
/// of `M` is reduced to its range, `M = V L V^T`, so that `U' = U V` and
/// `H = A + U' L U'^T` with `L` invertible; then (Haynsworth, twice) the
/// negative eigenvalues of `H` are those of `A`, plus those of `-L^{-1} -
/// U'^T A^{-1} U'`, less the positive ones of `L`.
struct CurvatureInverse {
    /// `U'` and `A^{-1} U'` (one column a kept direction).
    columns: Vec<Vec<Vector3<f64>>>,
    y: Vec<Vec<Vector3<f64>>>,
    /// `(L^{-1} + U'^T A^{-1} U')^{-1}`.
    inverse: DMatrix<f64>,
    negative_schur: usize,
    positive_blocks: usize,
}

impl CurvatureInverse {
    fn new(lu: &BlockLu, w: &Workspace) -> Option<CurvatureInverse> {
        let contact = &w.kkt.contact;
        if contact.curvature_blocks.is_empty() {
            return None;
        }
        let n = w.g.len();
        let (mut columns, mut values) = (Vec::new(), Vec::new());
        let mut at = 0;
        for block in &contact.curvature_blocks {
            let size = block.nrows();
            let eig = SymmetricEigen::new(block.clone());
            let largest = eig.eigenvalues.amax();
            for (k, value) in eig.eigenvalues.iter().enumerate() {
                if value.abs() <= 1e-12 * largest {
                    continue;
                }
                let mut column = vec![Vector3::zeros(); n];
                for a in 0..size {
                    let weight = eig.eigenvectors[(a, k)];
                    for (x, u) in column.iter_mut().zip(&contact.curvature_columns[at + a]) {
                        *x += weight * u;
                    }
                }
                columns.push(column);
                values.push(*value);
            }
            at += size;
        }
        let y: Vec<Vec<Vector3<f64>>> = columns
            .iter()
            .map(|c| {
                let mut solved = c.clone();
                lu.solve_in_place(&mut solved);
                solved
            })
            .collect();
        let k = values.len();
        let kernel = DMatrix::from_fn(k, k, |a, b| {
            let diagonal = if a == b { 1.0 / values[a] } else { 0.0 };
            diagonal + dot(&columns[a], &y[b])
        });
        let kernel = 0.5 * (&kernel + kernel.transpose());
        let negative_schur = SymmetricEigen::new(-kernel.clone())
            .eigenvalues
            .iter()
            .filter(|v| **v < 0.0)
            .count();
        let positive_blocks = values.iter().filter(|v| **v > 0.0).count();
        Some(CurvatureInverse {
            columns,
            y,
            inverse: kernel.try_inverse()?,
            negative_schur,
            positive_blocks,
        })
    }

    /// `v = A^{-1} d` becomes `(A + U M U^T)^{-1} d`.
    fn correct(&self, v: &mut [Vector3<f64>]) {
        let k = self.y.len();
        let r = DVector::from_fn(k, |a, _| dot(&self.columns[a], v));
        let t = &self.inverse * r;
        for (column, coefficient) in self.y.iter().zip(t.iter()) {
            for (x, c) in v.iter_mut().zip(column) {
                *x -= *coefficient * c;
            }
        }
    }
}

/// Stability of a constrained equilibrium: the reduced Hessian `Z^T A Z` on the
/// null space of `D` is positive definite iff the KKT matrix has exactly 3m
/// negative eigenvalues; by Haynsworth's inertia formula that number is
/// `neg(A) + pos(D A^{-1} D^T)` (symmetric parts, `A` nonsingular).
pub(crate) fn is_stable(model: &RodModel, w: &mut Workspace) -> bool {
    load_constraint_jacobian(model, w);
    // The workspace's factorisation is free (every use refactors first) and
    // takes that of the symmetric part; `w.scratch` holds the columns.
    let mut lu = std::mem::replace(&mut w.lu, BlockLu::new(0));
    let negative = lu.factor_symmetric_part(&w.jac);
    // The contacts' curvature: the Hessian is `A + U M U^T`.
    let curvature = negative.and_then(|_| CurvatureInverse::new(&lu, w));
    let negative = match (&curvature, negative) {
        (_, None) => None,
        (None, Some(k)) if w.kkt.contact.curvature_blocks.is_empty() => Some(k),
        (None, Some(_)) => None,
        (Some(c), Some(k)) => (k + c.negative_schur).checked_sub(c.positive_blocks),
    };
    if negative == Some(0) && model.has_obstacles() {
        // A positive definite Hessian is so on every subspace: however
        // many contacts hold (their Schur complement, stiff for a long
        // stretch on a surface, is then not needed).
        w.lu = lu;
        return true;
    }
    // The rows that hold: the held points' and the contacts held on their
    // obstacles (a free candidate constrains nothing).
    let contact = &w.kkt.contact;
    let held_rows = w.kkt.row_count - contact.gaps.len();
    let kept: Vec<usize> = (0..held_rows)
        .chain(
            contact
                .held
                .iter()
                .enumerate()
                .filter_map(|(a, h)| h.then_some(held_rows + a)),
        )
        .collect();
    let rows = kept.len();
    let s = negative.map(|_| {
        let mut s = DMatrix::zeros(rows, rows);
        let col = &mut w.scratch;
        for (c2, &r2) in kept.iter().enumerate() {
            col.copy_from_slice(&w.kkt.rows[r2]);
            lu.solve_in_place(col);
            if let Some(c) = &curvature {
                c.correct(col);
            }
            for (c, &r) in kept.iter().enumerate() {
                let len = w.kkt.row_len[r];
                s[(c, c2)] = dot(&w.kkt.rows[r][..len], &col[..len]);
            }
        }
        s
    });
    w.lu = lu;
    let (Some(negative), Some(s)) = (negative, s) else {
        return false;
    };
    let s = match &w.kkt.compliance {
        Some(e) => {
            let mut s = s;
            let held = e.nrows();
            let mut block = s.view_mut((0, 0), (held, held));
            block += e;
            s
        }
        None => s,
    };
    if rows == 0 {
        return negative == 0;
    }
    let s = 0.5 * (&s + s.transpose());
    let eig = SymmetricEigen::new(s);
    let tiny = 1e-12 * eig.eigenvalues.amax().max(f64::MIN_POSITIVE);
    if eig.eigenvalues.iter().any(|v| v.abs() <= tiny) {
        return false;
    }
    let positive = eig.eigenvalues.iter().filter(|v| **v > 0.0).count();
    negative + positive == rows
}
