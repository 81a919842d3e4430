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
use super::dense;
use super::friction;
use super::mixed::{self, Mixed, MixedWork};
use super::port;
use super::{step_limit, Workspace};
use crate::blocktri::BlockLu;
use crate::disc::NodeForces;
use crate::interrupt;
use crate::model::RodModel;
use crate::quat::Quat;
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
    /// The held points' rows among them, `3 m` of the model that loaded
    /// them: a load path's first leg solves the released model (no held
    /// point) in the whole scene's workspace, whose `h` has `m` entries.
    pub held_rows: usize,
    /// How many leading entries of each row may be nonzero: a position
    /// depends on the rotations up to its node only.
    pub row_len: Vec<usize>,
    /// What a row's multiplier adds to the equations beyond its own row
    /// (`D^T` times a sliding contact's `mu d`, see `friction.rs`), by row:
    /// the KKT system is unsymmetric where there are any.
    pub force_extra: Vec<(usize, Vec<Vector3<f64>>)>,
    /// The contact rows' sites, active set and forces (see `contact.rs`).
    pub contact: ContactWork,
    /// The step in mixed form, for many rows (see `mixed.rs`).
    pub mixed: MixedWork,
    /// Where the rows (and the contacts' curvature) stand loaded at a
    /// converged Newton's answer, so that the stability verdict there
    /// needs no second load; cleared by every load.
    pub rows_at_answer: Option<RowsAt>,
}

/// The state a load of the constraint rows was made at (see
/// [`KktWorkspace::rows_at_answer`]): the model, rotations, multipliers
/// and candidates, on which the rows and the curvature depend.
#[derive(Debug, Clone)]
pub(crate) struct RowsAt {
    /// The model's address (a workspace serves a released model too).
    model: usize,
    q: Vec<Quat>,
    reactions: Vec<Vector3<f64>>,
    active: Vec<usize>,
}

impl RowsAt {
    fn of(model: &RodModel, w: &Workspace) -> Self {
        RowsAt {
            model: std::ptr::from_ref(model) as usize,
            q: w.q.clone(),
            reactions: w.kkt.reactions.clone(),
            active: w.kkt.contact.active.clone(),
        }
    }

    fn is_of(&self, model: &RodModel, w: &Workspace) -> bool {
        self.model == std::ptr::from_ref(model) as usize
            && self.q == w.q
            && self.reactions == w.kkt.reactions
            && self.active == w.kkt.contact.active
    }
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
        self.contact.friction.clear();
        self.contact.free_evaluation.clear();
    }

    /// Keep the multipliers and the contact set as the last equilibrium
    /// (a contact's force acts only while its slot is a candidate, so the
    /// multipliers alone do not say which act).
    pub fn save(&mut self) {
        self.reactions_saved.copy_from_slice(&self.reactions);
        self.contact.saved_active.clone_from(&self.contact.active);
        self.contact.saved_held.clone_from(&self.contact.held);
        self.contact.friction.save();
    }

    /// Go back to the kept multipliers and contact set.
    pub fn restore_saved(&mut self) {
        self.reactions.copy_from_slice(&self.reactions_saved);
        self.contact.active.clone_from(&self.contact.saved_active);
        self.contact.held.clone_from(&self.contact.saved_held);
        self.contact.friction.restore_saved();
    }

    /// Keep the rest shape's: no multiplier, no contact.
    pub fn clear_saved(&mut self) {
        self.reactions_saved
            .iter_mut()
            .for_each(|r| *r = Vector3::zeros());
        self.contact.saved_active.clear();
        self.contact.saved_held.clear();
        self.contact.friction.clear_saved();
    }

    pub fn new(model: &RodModel) -> Self {
        let (n, m) = (model.n(), model.constraints().len());
        let positions = if model.is_constrained() { n + 1 } else { 0 };
        // The ports' multipliers follow the held points' reactions, the
        // contact slots' the ports'.
        let multipliers = m + model.ports().len() + contact::slot_count(model);
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
            held_rows: 3 * m,
            row_len: Vec::new(),
            force_extra: Vec::new(),
            contact: ContactWork::new(model),
            mixed: MixedWork::default(),
            rows_at_answer: None,
        }
    }
}

/// A state of a solve to come back to: the unknowns, the multipliers and
/// the contact set they go with (see [`KktWorkspace::save`]).
pub(crate) struct Snapshot {
    q: Vec<Quat>,
    reactions: Vec<Vector3<f64>>,
    active: Vec<usize>,
    held: Vec<bool>,
    friction: super::friction::FrictionWork,
}

impl Snapshot {
    pub fn take(w: &Workspace) -> Snapshot {
        Snapshot {
            q: w.q.clone(),
            reactions: w.kkt.reactions.clone(),
            active: w.kkt.contact.active.clone(),
            held: w.kkt.contact.held.clone(),
            friction: w.kkt.contact.friction.clone(),
        }
    }

    /// Put the state back (the snapshot stays, to go back to again).
    pub fn restore(&self, w: &mut Workspace) {
        w.q.copy_from_slice(&self.q);
        w.kkt.reactions.copy_from_slice(&self.reactions);
        w.kkt.contact.active.clone_from(&self.active);
        w.kkt.contact.held.clone_from(&self.held);
        w.kkt.contact.friction.clone_from(&self.friction);
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
    if model.has_contact() {
        // The contact and port forces act where the backbone is: positions
        // first (the second-order scheme's need no interior).
        model.positions(&w.q, &mut w.interior, &mut w.kkt.positions);
        contact::locate(model, &w.kkt.positions, &mut w.kkt.contact.sites);
        port::locate(model, &w.kkt.positions, lambda, &mut w.kkt.contact.ports);
        friction::gather_sticks(model, w);
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
    evaluated_merit(model, w)
}

/// The merit of the last evaluation with the present candidates' gaps.
fn evaluated_merit(model: &RodModel, w: &Workspace) -> f64 {
    let contact = &w.kkt.contact;
    let gaps = contact.gaps.iter().zip(&contact.held);
    let contact_rows: f64 = gaps.map(|(x, held)| contact_error(*x, *held).powi(2)).sum();
    let port_rows: f64 = port_residuals(w).map(|x| x * x).sum();
    merit(
        model,
        &w.g,
        held_residuals(model, w),
        contact_rows + port_rows,
    )
}

/// The held points' residuals of `model` (the workspace's are sized for the
/// scene: on a load path's released leg the entries past the model's are
/// another evaluation's, which once made that leg's residual never fall
/// below a held tip's miss when it touched an obstacle).
fn held_residuals<'a>(model: &RodModel, w: &'a Workspace) -> &'a [Vector3<f64>] {
    &w.kkt.h[..model.constraints().len()]
}

/// The ports' rows' residuals (their friction's too) and the sticking
/// contacts' [m].
fn port_residuals(w: &Workspace) -> impl Iterator<Item = f64> + '_ {
    let c = &w.kkt.contact;
    let sticks = c.friction.sticks.iter().flat_map(|s| s.residual);
    let axial = c.friction.ports.iter().map(|p| p.residual);
    c.ports
        .iter()
        .flat_map(|p| p.residual)
        .chain(axial)
        .chain(sticks)
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
    for x in held_residuals(model, w) {
        let r = x.amax() * position_weight(model);
        if !r.is_finite() {
            return f64::INFINITY;
        }
        h = h.max(r);
    }
    let contact = &w.kkt.contact;
    let errors = contact.gaps.iter().zip(&contact.held);
    let errors = errors.map(|(x, held)| contact_error(*x, *held));
    for x in errors.chain(port_residuals(w)) {
        let r = x.abs() * position_weight(model);
        if !r.is_finite() {
            return f64::INFINITY;
        }
        h = h.max(r);
    }
    model.residual_norm(&w.g).max(h)
}

/// Load the KKT rows at `w.q`: the held points' `D_c` (zero on a clamped tip
/// node, which does not move) and the contact candidates' rows, dense, or in
/// mixed form where there are many (see `mixed.rs`; the dense rows then
/// come from it on demand, [`mixed::densify`]).
pub(crate) fn load_constraint_jacobian(model: &RodModel, w: &mut Workspace) {
    w.kkt.rows_at_answer = None;
    w.kkt.compliance = model.held_point_compliance(&w.q, &w.interior);
    let held = model.constraints().len();
    let ports = port::row_count(model);
    let sticks = w.kkt.contact.friction.row_count();
    w.kkt.row_count = 3 * held + ports + sticks + w.kkt.contact.active.len();
    w.kkt.held_rows = 3 * held;
    let n = model.n();
    w.kkt.row_len.clear();
    for c in model.constraints() {
        w.kkt.row_len.extend([c.node.min(n); 3]);
    }
    for site in &w.kkt.contact.ports {
        w.kkt.row_len.extend([port::last_node(site).min(n); 2]);
    }
    for j in model.frictional_ports() {
        let site = &w.kkt.contact.ports[j];
        w.kkt.row_len.push(port::last_node(site).min(n));
    }
    for stick in &w.kkt.contact.friction.sticks {
        w.kkt
            .row_len
            .extend([contact::last_node(model, stick.slot).min(n); 2]);
    }
    for &i in &w.kkt.contact.active {
        w.kkt.row_len.push(contact::last_node(model, i).min(n));
    }
    if model.has_contact() {
        w.kkt.contact.load_chords(model, &w.q);
    }
    mixed::load(model, w);
    let dense = !w.kkt.mixed.in_use;
    if dense {
        for (c, d) in model.constraints().iter().zip(w.kkt.d.iter_mut()) {
            model.position_jacobian(&w.q, c.node, &w.interior, d);
            if model.clamped_tip().is_some() {
                d[model.n() - 1] = Matrix3::zeros();
            }
        }
        for (c, d) in w.kkt.d[..held].iter().enumerate() {
            for e in 0..3 {
                for (x, b) in w.kkt.rows[3 * c + e].iter_mut().zip(d) {
                    *x = b.row(e).transpose();
                }
            }
        }
        port::load_rows(model, w, 3 * held);
        friction::load_rows(model, w, 3 * held + ports);
        contact::load_rows(model, w, 3 * held + ports + sticks);
    }
    load_slide_forces(model, w, 3 * held + ports + sticks);
    if model.has_contact() {
        contact::curvature(model, w, dense);
    }
    // The chords are this step's: no row loaded later may take them.
    w.kkt.contact.chords_loaded = false;
}

/// The sliding contacts' extra columns (see `KktWorkspace::force_extra`),
/// dense, and in the mixed form's rows; `first` the first candidate's row.
fn load_slide_forces(model: &RodModel, w: &mut Workspace, first: usize) {
    w.kkt.force_extra.clear();
    w.kkt.mixed.force_extra.clear();
    let slides = friction::slide_forces(model, w, first);
    let scratch = w.kkt.row_count;
    let n = model.n();
    while !slides.is_empty() && w.kkt.rows.len() <= scratch {
        w.kkt.rows.push(vec![Vector3::zeros(); n]);
    }
    for slide in slides {
        let (row, force) = (slide.row, slide.force);
        contact::load_row(model, w, scratch, slide.shares, &force);
        let extra = w.kkt.rows[scratch].clone();
        w.kkt.force_extra.push((row, extra));
        let [(na, wa), (nb, wb)] = slide.shares;
        let directions = [(na, wa * force), (nb, wb * force)];
        w.kkt.mixed.force_extra.push((row, directions));
    }
}

/// `x . y` over the nodes.
fn dot(x: &[Vector3<f64>], y: &[Vector3<f64>]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a.dot(b)).sum()
}

/// Row `r`'s residual: a held point's position error, a port's, a
/// sticking contact's, then an active contact's gap.
fn row_residual(w: &Workspace, r: usize) -> f64 {
    let held = w.kkt.held_rows;
    let ports = held + 2 * w.kkt.contact.ports.len();
    let frictional = &w.kkt.contact.friction.frictional_ports;
    let axial = ports + frictional.len();
    let equalities = w.kkt.row_count - w.kkt.contact.gaps.len();
    if r < held {
        w.kkt.h[r / 3][r % 3]
    } else if r < ports {
        let p = r - held;
        w.kkt.contact.ports[p / 2].residual[p % 2]
    } else if r < axial {
        w.kkt.contact.friction.ports[frictional[r - ports]].residual
    } else if r < equalities {
        let p = r - axial;
        w.kkt.contact.friction.sticks[p / 2].residual[p % 2]
    } else {
        w.kkt.contact.gaps[r - equalities]
    }
}

/// Solve the KKT system at the current state (Jacobian and `D` loaded, `lu`
/// factored): the rotation step goes to `w.step`, the reaction step to `w.kkt.rhs`.
/// [`kkt_step`] with `w.lu` factored, for the sensitivities: `w.step` and
/// `w.kkt.rhs` (the reactions' step) from `w.g` and `w.kkt.h`. The contacts
/// held stay on their obstacles, which do not move (their rows' residuals
/// zero), and the others stay free: a derivative along the active set.
pub(crate) fn kkt_solve(w: &mut Workspace) -> bool {
    let (ports, gaps) = (w.kkt.contact.ports.len(), w.kkt.contact.gaps.len());
    kkt_solve_moving(w, &vec![[0.0; 2]; ports], &vec![0.0; gaps])
}

/// [`kkt_solve`] with the rows' residuals given: the ports' (`moved_ports`)
/// and the candidates' gaps (`moved_gaps`), for a derivative along which
/// the surroundings move relative to the rod (the base translated).
pub(crate) fn kkt_solve_moving(
    w: &mut Workspace,
    moved_ports: &[[f64; 2]],
    moved_gaps: &[f64],
) -> bool {
    let lu = std::mem::replace(&mut w.lu, BlockLu::new(0));
    let gaps = std::mem::replace(&mut w.kkt.contact.gaps, moved_gaps.to_vec());
    let ports: Vec<[f64; 2]> = w.kkt.contact.ports.iter().map(|p| p.residual).collect();
    for (p, r) in w.kkt.contact.ports.iter_mut().zip(moved_ports) {
        p.residual = *r;
    }
    w.kkt.contact.choose = false;
    let ok = kkt_step(&lu, w);
    w.kkt.contact.choose = true;
    w.kkt.contact.gaps = gaps;
    for (p, r) in w.kkt.contact.ports.iter_mut().zip(ports) {
        p.residual = r;
    }
    w.lu = lu;
    ok
}

fn kkt_step(lu: &BlockLu, w: &mut Workspace) -> bool {
    // Many contacts: the banded mixed form. Where its matrix is singular
    // (a held point that cannot move to first order) the Schur
    // complement's pseudo-inverse takes the step.
    if w.kkt.mixed.in_use {
        if mixed_step(lu.shift(), w) {
            return true;
        }
        mixed::densify(w);
    }
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
    }
    for (r, extra) in &w.kkt.force_extra {
        for (x, e) in w.kkt.columns[*r].iter_mut().zip(extra) {
            *x += e;
        }
    }
    lu.solve_columns_in_place(&mut w.kkt.columns[..rows]);
    // The contacts' curvature: the Jacobian is `A + U M U^T`, whose inverse
    // the Woodbury identity applies from `A`'s.
    if !w.kkt.contact.curvature_blocks.is_empty() {
        let Some(curvature) = CurvatureInverse::for_step(lu, w) else {
            return false;
        };
        curvature.correct(&mut w.scratch);
        for col in &mut w.kkt.columns[..rows] {
            curvature.correct(col);
        }
    }
    // Each on its own: a mixed step leaves `rhs` its size.
    if w.kkt.schur.nrows() != rows {
        w.kkt.schur = DMatrix::zeros(rows, rows);
    }
    if w.kkt.rhs.len() != rows {
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
    // The sticking contacts' and ports' rows give with their forces, a
    // sliding port's keeps its multiplier at zero (see `friction.rs`).
    let friction = &w.kkt.contact.friction;
    let first_axial = w.kkt.held_rows + 2 * w.kkt.contact.ports.len();
    for (a, &j) in friction.frictional_ports.iter().enumerate() {
        w.kkt.schur[(first_axial + a, first_axial + a)] += friction.ports[j].diagonal;
    }
    let first_stick = first_axial + friction.frictional_ports.len();
    for r in first_stick..first_stick + friction.row_count() {
        w.kkt.schur[(r, r)] += friction.compliance;
    }
    let candidates = w.kkt.contact.gaps.len();
    if candidates == 0 {
        if !dense::pseudo_inverse_solve_in_place(&mut w.kkt.schur, &mut w.kkt.rhs) {
            return false;
        }
    } else {
        let lower = contact_lower_bounds(w);
        let choose = w.kkt.contact.choose;
        let mut schur = Schur {
            s: &w.kkt.schur,
            b: &w.kkt.rhs,
            symmetric: w.kkt.force_extra.is_empty(),
            free_rows: Vec::with_capacity(rows),
            fixed_rows: Vec::with_capacity(rows),
        };
        let Some(x) = bounded_qp(
            &mut schur,
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

/// The contact forces stay >= 0: each candidate's step is bounded below
/// by minus its force.
fn contact_lower_bounds(w: &Workspace) -> Vec<f64> {
    let first = w.kkt.reactions.len() - w.kkt.contact.sites.len();
    w.kkt
        .contact
        .active
        .iter()
        .map(|&i| friction::lower_bound(w, i, -w.kkt.reactions[first + i].x.max(0.0)))
        .collect()
}

/// [`kkt_step`] in mixed form (see `mixed.rs`); `false`, the held set
/// untouched, where its matrix is singular.
fn mixed_step(shift: f64, w: &mut Workspace) -> bool {
    let rows = w.kkt.row_count;
    let candidates = w.kkt.contact.gaps.len();
    w.kkt.mixed.residuals = (0..rows).map(|r| row_residual(w, r)).collect();
    w.kkt.mixed.begin();
    let lower = contact_lower_bounds(w);
    let mut held = w.kkt.contact.held.clone();
    let mut mixed = Mixed {
        work: &mut w.kkt.mixed,
        jac: &w.jac,
        g: &w.g,
        shift,
        curvature: (
            &w.kkt.contact.curvature_blocks,
            &w.kkt.contact.curvature_nodes,
        ),
    };
    let equalities = rows - candidates;
    let x = if w.kkt.contact.choose {
        let Some(scale) = row_scale(&mut mixed, rows) else {
            return false;
        };
        primal_dual_active_set(&mut mixed, equalities, &lower, &mut held, scale)
    } else {
        solve_held(&mut mixed, equalities, &lower, &held)
    };
    let Some(x) = x else {
        return false;
    };
    w.kkt.contact.held = held;
    w.kkt.rhs = x;
    w.kkt.mixed.take_step(&mut w.step);
    true
}

/// The equality-constrained subproblem of [`bounded_qp`], in whichever form
/// the KKT system is solved.
pub(crate) trait Subproblem {
    /// Solve for the multipliers of the rows `free` marks, the others held
    /// at their values in `x`; the solved ones go into `x`.
    fn solve(&mut self, free: &[bool], x: &mut DVector<f64>) -> bool;
    /// Each row's linearised value after the last solve's step (`S x - b`
    /// for `x` that solve's): a held row's is zero, a free contact's is its
    /// gap after the step.
    fn rows_after(&self, x: &DVector<f64>) -> DVector<f64>;
    /// `S x - b` for any multipliers `x` (the QP's gradient); the step of
    /// `x` becomes the last solve's.
    fn rows_at(&mut self, x: &DVector<f64>) -> Option<DVector<f64>>;
    /// Whether `S` is known to be symmetric and positive semidefinite, to
    /// round-off (false where that is not known): the QP convex, its gaps
    /// `S x - b` at the minimum unique whatever path the active set takes
    /// to it (only the split of a force between dependent rows is not).
    fn is_convex(&self) -> bool;
    /// Whether `x`, the last solve's multiplier of row `r`, is round-off of
    /// a singular subproblem (dependent rows freed together): its row's own
    /// action `|x| S_rr` beyond [`ROUND_OFF_FORCE`] times `scale`, the
    /// rows' (no gap the step closes asks for a force near it). False where
    /// the form cannot tell.
    fn is_round_off_force(&self, _r: usize, _x: f64, _scale: f64) -> bool {
        false
    }
}

/// See [`Subproblem::is_round_off_force`]: about `1 / sqrt(eps)`. The seed's
/// robot bent into a wall in front of a ball frees 16 rows at once, five of
/// them on four coordinates, and the solve gives forces of 1e5 to 2.5e15 N
/// (`|x| S_rr` up to 4e15 against gaps of 0.16 m); a rod's stretch settling
/// on a floor, 1e2 to 6e2 N of both signs at its edge.
const ROUND_OFF_FORCE: f64 = 1e8;

/// The shift of [`Subproblem::is_convex`]'s factorisation, relative to the
/// largest diagonal entry of `S`: round-off of its entries.
const CONVEX_SHIFT: f64 = 1e-10;

/// The subproblem over the Schur complement: `S x = b` on the free rows.
struct Schur<'a> {
    s: &'a DMatrix<f64>,
    b: &'a DVector<f64>,
    /// Whether `S` is symmetric (no sliding contact's friction in it).
    symmetric: bool,
    /// Scratch of [`Subproblem::solve`]: the rows solved for, and the
    /// others (held at their bounds).
    free_rows: Vec<usize>,
    fixed_rows: Vec<usize>,
}

impl Subproblem for Schur<'_> {
    fn solve(&mut self, free: &[bool], x: &mut DVector<f64>) -> bool {
        let (s, b) = (self.s, self.b);
        // The QP solves a few working sets a step: the index lists are
        // reused, and the fixed rows' part of the right-hand side is summed
        // over them alone.
        self.free_rows.clear();
        self.fixed_rows.clear();
        for (i, &f) in free.iter().enumerate() {
            if f {
                self.free_rows.push(i);
            } else {
                self.fixed_rows.push(i);
            }
        }
        let (rows, fixed) = (&self.free_rows, &self.fixed_rows);
        if rows.is_empty() {
            return true;
        }
        let mut sub = DMatrix::from_fn(rows.len(), rows.len(), |r, c| s[(rows[r], rows[c])]);
        let mut rhs = DVector::from_fn(rows.len(), |r, _| {
            let i = rows[r];
            b[i] - fixed.iter().map(|&j| s[(i, j)] * x[j]).sum::<f64>()
        });
        let solved = if self.symmetric {
            dense::solve_symmetric_in_place(&mut sub, &mut rhs)
        } else {
            dense::solve_general_in_place(&mut sub, &mut rhs)
        };
        if !solved {
            return false;
        }
        for (r, &i) in rows.iter().enumerate() {
            x[i] = rhs[r];
        }
        true
    }

    fn rows_after(&self, x: &DVector<f64>) -> DVector<f64> {
        self.s * x - self.b
    }

    fn rows_at(&mut self, x: &DVector<f64>) -> Option<DVector<f64>> {
        Some(self.s * x - self.b)
    }

    fn is_convex(&self) -> bool {
        // The Cholesky factorisation reads one triangle: the other is the
        // same to round-off where no sliding contact's friction is in `S`.
        // Shifted by round-off of its largest entry, it passes where `S` is
        // semidefinite, singular to round-off or exactly: where rows repeat
        // (a contact on a node and on the element beside it) or are
        // dependent (the seed's robot bent into a wall in front of a ball:
        // nodes 15 and 16 held by the wall and the ball, five rows on their
        // four in-plane coordinates, the least eigenvalue 2e-18 of the
        // largest). There the minimisers differ only in how the forces
        // split between the dependent rows: `S x`, the gaps, the same (and
        // `D^T x`, the rod's step, where `A^-1` is definite on the range of
        // `D^T`, as near a stable equilibrium). An indefinite `S` (a rod
        // curled into a wall away from an equilibrium) fails, unless its
        // negative eigenvalues are within the shift (round-off).
        if !self.symmetric {
            return false;
        }
        let shift = CONVEX_SHIFT * self.s.diagonal().amax();
        let mut shifted = self.s.clone();
        for i in 0..shifted.nrows() {
            shifted[(i, i)] += shift;
        }
        shifted.cholesky().is_some()
    }

    fn is_round_off_force(&self, r: usize, x: f64, scale: f64) -> bool {
        x.abs() * self.s[(r, r)] > ROUND_OFF_FORCE * scale
    }
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
    let ports = model.ports().len();
    let first_port = port::first_row(model);
    let port_multiplier = port::offset(model, w.kkt.reaction_step.len());
    for (j, d) in w.kkt.reaction_step[port_multiplier..port_multiplier + ports]
        .iter_mut()
        .enumerate()
    {
        *d = Vector3::new(rhs[first_port + 2 * j], rhs[first_port + 2 * j + 1], 0.0);
    }
    for (a, j) in model.frictional_ports().enumerate() {
        w.kkt.reaction_step[port_multiplier + j].z = rhs[port::first_axial_row(model) + a];
    }
    if model.has_obstacles() {
        let first = contact::offset(model, w);
        let sticks = &w.kkt.contact.friction.sticks;
        let first_stick = 3 * held + port::row_count(model);
        let first_row = first_stick + 2 * sticks.len();
        w.kkt.reaction_step[first..]
            .iter_mut()
            .for_each(|d| *d = Vector3::zeros());
        for (a, &i) in w.kkt.contact.active.iter().enumerate() {
            w.kkt.reaction_step[first + i].x = w.kkt.rhs[first_row + a];
        }
        for (j, stick) in sticks.iter().enumerate() {
            let d = &mut w.kkt.reaction_step[first + stick.slot];
            d.y = w.kkt.rhs[first_stick + 2 * j];
            d.z = w.kkt.rhs[first_stick + 2 * j + 1];
        }
    }
}

/// The step of the multipliers where some are bounded below: the QP
/// `min q(x) = 1/2 x^T S x - b^T x` with `x_i >= lower_i` for the rows from
/// `equalities` on (the contact candidates; `held` says which are free of
/// their bound). Its optimality conditions are the linearised contact's:
/// the gap after the step, `w = S x - b`, vanishes where a force is free
/// and is `>= 0` where it is at its bound (zero force). With `choose` false
/// the held set is kept and solved as it is (a tangent).
///
/// A primal active set from the held candidates, feasible throughout (`x =
/// 0` is: the forces are `>= 0`): finite for `S` positive definite.
fn bounded_qp(
    sub: &mut impl Subproblem,
    equalities: usize,
    lower: &[f64],
    held: &mut [bool],
    choose: bool,
) -> Option<DVector<f64>> {
    if !choose {
        return solve_held(sub, equalities, lower, held);
    }
    let scale = row_scale(sub, equalities + lower.len())?;
    primal_active_set(sub, equalities, lower, held, scale, true)
}

/// The scale of the QP's rows, for its round-off tolerance: the gaps of
/// the step with the forces kept.
fn row_scale(sub: &mut impl Subproblem, rows: usize) -> Option<f64> {
    Some(
        sub.rows_at(&DVector::zeros(rows))?
            .amax()
            .max(f64::MIN_POSITIVE),
    )
}

/// The subproblem with the held set as it is (a tangent's).
fn solve_held(
    sub: &mut impl Subproblem,
    equalities: usize,
    lower: &[f64],
    held: &[bool],
) -> Option<DVector<f64>> {
    let m = equalities + lower.len();
    let free: Vec<bool> = (0..m)
        .map(|i| i < equalities || held[i - equalities])
        .collect();
    let mut x = DVector::zeros(m);
    for i in (equalities..m).filter(|&i| !free[i]) {
        x[i] = lower[i - equalities];
    }
    sub.solve(&free, &mut x).then_some(x)
}

/// Passes of the primal-dual active set before the step is left to the
/// Schur complement: a rod settling onto a floor takes 2 or 3; the QP of a
/// rod 5 cm above a floor, stepping far through it, cycles.
const ACTIVE_SET_PASSES: usize = 4;

/// [`bounded_qp`]'s QP by a primal-dual active set (a semismooth Newton
/// on the complementarity): each pass solves with the held rows free and
/// the others at their bounds, then drops every held row whose force went
/// below its bound and holds every row whose gap went negative, all at
/// once, so that a rod settling onto a surface along a stretch costs a few
/// solves, not one a row (in mixed form each factors a band). It can cycle
/// (the rod's fourth-order operator makes the forces at a stretch's edge
/// alternate in sign): `None` after [`ACTIVE_SET_PASSES`].
fn primal_dual_active_set(
    sub: &mut impl Subproblem,
    equalities: usize,
    lower: &[f64],
    held: &mut [bool],
    scale: f64,
) -> Option<DVector<f64>> {
    let m = equalities + lower.len();
    let negative = -1e-12 * scale;
    for _ in 0..ACTIVE_SET_PASSES {
        let x = solve_held(sub, equalities, lower, held)?;
        let gaps = sub.rows_after(&x);
        let mut changed = false;
        for i in equalities..m {
            let keep = if held[i - equalities] {
                x[i] >= lower[i - equalities]
            } else {
                gaps[i] < negative
            };
            changed |= keep != held[i - equalities];
            held[i - equalities] = keep;
        }
        if !changed {
            return Some(x);
        }
    }
    None
}

/// A batch of rows [`primal_active_set`] freed at once: the multipliers and
/// held set before it, its rows, and its row of the most negative gap.
struct Batch {
    before: DVector<f64>,
    held_before: Vec<bool>,
    rows: Vec<usize>,
    worst: usize,
}

/// [`bounded_qp`]'s primal active set, feasible throughout (`x = 0` is: the
/// forces are `>= 0`), from the held set `held`.
///
/// It frees every zero force whose gap the step would close at once, which
/// settles a rod onto a surface along a stretch in a solve or two. From a
/// start deep in obstacles the step then leaves most of them again, each
/// blocking row a solve of the subproblem (16 candidates freed on the
/// seed's robot bent into a wall in front of a ball, one contact at the
/// end). With `undo_failed_batches`, where the solve after a batch freed
/// at once takes half the batch or more below its bounds, the QP goes back to
/// where it freed them and from there frees one row a pass, the one whose
/// gap the step closes most: one solve wasted. A batch that the step
/// leaves by a row or two (a stretch's edge) drops them as before. So is a
/// batch whose solve gives any force of round-off
/// ([`Subproblem::is_round_off_force`]: dependent rows freed together,
/// whose count below the bounds is chance). That changes the cost and at
/// most the split of a force between dependent rows where `S` is
/// semidefinite ([`Subproblem::is_convex`], asked at the first such
/// batch): the gaps at the minimum are unique (a split changes the
/// reported forces and so the next step's start, not this step's gaps).
/// Where `S` is indefinite (a rod curled into a wall, away from an
/// equilibrium) or unsymmetric (a sliding contact's friction) the path
/// decides which answer the QP returns, and the batches' is kept.
/// The subproblem's solves in a whole forward solve: 24 before, 6 after on
/// that robot; 22 and 5 on a heavy rod clamped 5 cm above a table (n =
/// 40); unchanged on a rod lying on it (3).
fn primal_active_set(
    sub: &mut impl Subproblem,
    equalities: usize,
    lower: &[f64],
    held: &mut [bool],
    scale: f64,
    undo_failed_batches: bool,
) -> Option<DVector<f64>> {
    let m = equalities + lower.len();
    let mut x: DVector<f64> = DVector::zeros(m);
    // Rows freed and blocked again at once, with no step: a round-off
    // choice (degenerate), never freed again in this QP, so that it ends.
    let mut freed = vec![false; m];
    let mut frozen = vec![false; m];
    let mut batch: Option<Batch> = None;
    let mut one_at_a_time = false;
    let mut convex = None;
    for _ in 0..4 * m + 8 {
        // The subproblem: the bounded rows at their bounds, the rest solved.
        let trial = solve_held(sub, equalities, lower, held)?;
        // A free force that would go below its bound stops the step there.
        let mut step = 1.0;
        let mut blocking = None;
        for i in (equalities..m).filter(|&i| held[i - equalities]) {
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
            let undone = batch.take().filter(|b| {
                let below = b.rows.iter().filter(|&&r| trial[r] < lower[r - equalities]);
                let failed = 2 * below.count() >= b.rows.len()
                    || b.rows
                        .iter()
                        .any(|&r| sub.is_round_off_force(r, trial[r], scale));
                failed && *convex.get_or_insert_with(|| sub.is_convex())
            });
            if let Some(b) = undone {
                x = b.before;
                held.copy_from_slice(&b.held_before);
                held[b.worst - equalities] = true;
                freed.iter_mut().for_each(|f| *f = false);
                freed[b.worst] = true;
                one_at_a_time = true;
                continue;
            }
            if freed[i] && step <= 1e-12 {
                frozen[i] = true;
            }
            freed.iter_mut().for_each(|f| *f = false);
            x += step * (&trial - &x);
            x[i] = lower[i - equalities];
            held[i - equalities] = false;
            continue;
        }
        batch = None;
        x = trial;
        // Every zero force whose gap would go negative is freed (the most
        // negative alone, once a batch has failed).
        let gap = sub.rows_after(&x);
        let closing: Vec<usize> = (equalities..m)
            .filter(|&i| !held[i - equalities] && !frozen[i] && gap[i] < -1e-12 * scale)
            .collect();
        let Some(&worst) = closing.iter().min_by(|&&i, &&j| gap[i].total_cmp(&gap[j])) else {
            return Some(x);
        };
        freed.iter_mut().for_each(|f| *f = false);
        if one_at_a_time || closing.len() == 1 {
            held[worst - equalities] = true;
            freed[worst] = true;
            continue;
        }
        let saved = undo_failed_batches.then(|| (x.clone(), held.to_vec()));
        for &i in &closing {
            held[i - equalities] = true;
            freed[i] = true;
        }
        batch = saved.map(|(before, held_before)| Batch {
            before,
            held_before,
            rows: closing,
            worst,
        });
    }
    None
}

/// The path's tangent at the equilibrium in `w.q` (reactions in
/// `w.kkt.reactions`) at `lambda`: `-dtheta/dlambda` into `w.step` (the sign
/// of the free scenes' predictor) and `dR/dlambda` into `w.kkt.reaction_step`.
/// It is the Newton step of the KKT system for the residuals' derivatives
/// `[dg/dlambda; dh/dlambda]`: the loads' (nothing on a leg whose loads stay
/// fixed) and the targets' motion. Near a held point's full reach the tangent
/// is large and points along the buckling mode, which is what the predictor
/// needs there. A clamped tip's orientation is left to the corrector.
///
/// With friction every held contact counts as sticking (see [`is_stable`]):
/// the frictionless tangent of a contact sliding along a surface is the
/// free slide, far off where friction lets it go.
pub(crate) fn tangent(model: &RodModel, w: &mut Workspace, lambda: f64) -> bool {
    if !model.has_friction() {
        return tangent_of_path(model, w, lambda);
    }
    let kept = friction::stick_all(model, w);
    let predicted = tangent_of_path(model, w, lambda);
    friction::unstick(w, kept);
    predicted
}

fn tangent_of_path(model: &RodModel, w: &mut Workspace, lambda: f64) -> bool {
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
    // A port's rows move with its point: `-b_i . dp/dlambda`.
    for (site, p) in w.kkt.contact.ports.iter_mut().zip(model.ports()) {
        let moved = p.target_at(0.0) - p.target_at(1.0);
        site.residual = p.port.frame().map(|b| b.dot(&moved));
    }
    // The obstacles stay: the active contacts keep their gaps, the
    // sticking ones their anchors.
    w.kkt.contact.gaps.iter_mut().for_each(|x| *x = 0.0);
    for stick in &mut w.kkt.contact.friction.sticks {
        stick.residual = [0.0; 2];
    }
    for port in &mut w.kkt.contact.friction.ports {
        port.residual = 0.0;
    }
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
///
/// With friction, where the sticking rows' own compliance does not settle
/// (a stretch of sticking contacts whose end carries a moment: its forces
/// alternate above their cones and the contacts slide and stick in turn),
/// the step is solved again from its start with the rows relaxed: a
/// compliance as soft as the rod's, taken down level by level, each level
/// from the last one's equilibrium (see [`relaxed_friction`]); where that
/// fails too, at the rows' own compliance with the whole budget.
pub(crate) fn newton(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    (max_iter, tol): (usize, f64),
) -> (bool, usize) {
    if !model.has_friction() {
        return newton_at(model, w, lambda, (max_iter, tol));
    }
    let exact = friction::compliance(model);
    let start = Snapshot::take(w);
    // The rows' own compliance first, until a step of this solve has
    // needed the levels.
    let direct = if w.kkt.contact.friction.relax {
        0
    } else {
        max_iter.min(friction::DIRECT_ITERATIONS)
    };
    let mut iterations = 0;
    if direct > 0 {
        w.kkt.contact.friction.compliance = exact;
        let (converged, spent) = newton_at(model, w, lambda, (direct, tol));
        if converged || interrupt::requested() {
            return (converged, spent);
        }
        iterations = spent;
        start.restore(w);
    }
    let (converged, spent) = relaxed_friction(model, w, lambda, (max_iter, tol));
    iterations += spent;
    if converged || interrupt::requested() || direct >= max_iter {
        return (converged, iterations);
    }
    // Neither: the rows' own compliance with the whole budget (contacts
    // that settle after many iterations).
    start.restore(w);
    w.kkt.contact.friction.compliance = exact;
    let (converged, spent) = newton_at(model, w, lambda, (max_iter, tol));
    (converged, iterations + spent)
}

/// Friction's homotopy: Newton with the sticking rows' compliance `c` from
/// [`friction::relaxed_compliance`] (softer than the whole rod) down level by
/// level, each level from the last one's equilibrium. While relaxed, a
/// sliding contact whose slip the rows' spring would hold sticks, and the
/// others slide against their slip (`friction::update`): a spring that
/// yields at `mu lambda`, whose contact set changes little from one level
/// to the next. The levels part by [`friction::RELAXED_FACTOR`], by its
/// square after a level that took at most [`friction::EASY_LEVEL`]
/// iterations, by its square root after
/// one that failed (from the last level's answer again). It ends at the
/// first level whose sticking contacts creep by at most
/// [`friction::STICK_CREEP`] of the length (`c |f|`), or at the rows' own
/// compliance (below which round-off in the positions, divided by `c`,
/// would be the friction forces); where a level fails from a last one
/// whose sticking contacts creep by at most [`friction::ACCEPTED_CREEP`],
/// at that one.
fn relaxed_friction(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    (max_iter, tol): (usize, f64),
) -> (bool, usize) {
    let exact = friction::compliance(model);
    w.kkt.contact.friction.relax = true;
    let top = friction::relaxed_compliance(model).max(exact);
    // A level above the last relaxed solve's end, from the top where that
    // fails (see `FrictionWork::last_level`).
    let last_level = w.kkt.contact.friction.last_level;
    let mut compliance = if last_level > 0.0 {
        (last_level / friction::RELAXED_FACTOR).min(top)
    } else {
        top
    };
    let mut resumed = (compliance < top).then(|| Snapshot::take(w));
    let mut factor = friction::RELAXED_FACTOR;
    // The last level that converged, its compliance and creep.
    let mut last: Option<(Snapshot, f64, f64)> = None;
    let mut iterations = 0;
    loop {
        w.kkt.contact.friction.compliance = compliance.max(exact);
        // The top level starts from the step's predictor, as an unrelaxed
        // solve would (from a bump, far from it): the step's budget. Each
        // level below starts from the one above, a few iterations away.
        let budget = if last.is_none() && compliance >= top {
            max_iter
        } else {
            max_iter.min(friction::LEVEL_ITERATIONS)
        };
        let (converged, spent) = newton_at(model, w, lambda, (budget, tol));
        iterations += spent;
        if interrupt::requested() || iterations > max_iter * friction::RELAXED_LEVELS {
            return (false, iterations);
        }
        if !converged {
            // Back to the last level: its answer where its sticking
            // contacts creep little enough, else a shorter way down.
            let Some((kept, at, creep)) = &last else {
                if let Some(start) = resumed.take() {
                    start.restore(w);
                    compliance = top;
                    continue;
                }
                return (false, iterations);
            };
            let (at, creep) = (*at, *creep);
            kept.restore(w);
            if creep <= friction::ACCEPTED_CREEP * model.length() {
                evaluate(model, w, lambda, true);
                w.kkt.contact.friction.last_level = at;
                return (true, iterations);
            }
            factor = factor.sqrt();
            if factor > friction::SLOWEST_FACTOR {
                return (false, iterations);
            }
            compliance = at * factor;
            continue;
        }
        let creep = friction::creep(model, w);
        if compliance <= exact || creep <= friction::STICK_CREEP * model.length() {
            w.kkt.contact.friction.last_level = compliance.max(exact);
            return (true, iterations);
        }
        last = Some((Snapshot::take(w), compliance, creep));
        if spent <= friction::EASY_LEVEL {
            factor = (factor * factor).max(friction::FASTEST_FACTOR);
        }
        compliance *= factor;
    }
}

/// [`newton`] at the sticking rows' present compliance.
fn newton_at(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    (max_iter, tol): (usize, f64),
) -> (bool, usize) {
    let n = model.n();
    if let Some(tip) = model.clamped_tip_at(lambda) {
        w.q[n] = tip;
    }
    // With obstacles or friction each pass evaluates again once it has
    // chosen its candidates, Jacobian and all: the start and the end of
    // the pass before need not.
    let reevaluated = model.has_obstacles() || model.has_friction();
    // Whether `w` holds the evaluation of its state, Jacobian and all (a
    // step's first trial, accepted): where the candidates then chosen move
    // no force (no friction to update), it stands. So does the free start's
    // last evaluation (`contact::start_from_free_equilibrium`, made only
    // where nothing is held, no port, no friction): at full load, with no
    // contact force yet, the free solve's Jacobian is this one's.
    let free_start = std::mem::take(&mut w.kkt.contact.free_evaluation);
    let mut evaluated_with_jacobian = lambda == 1.0
        && !model.has_friction()
        && free_start == w.q
        && w.kkt.reactions.iter().all(|r| *r == Vector3::zeros());
    let mut merit_now = evaluate(model, w, lambda, !reevaluated);
    // One pass more than the budget: the last one only certifies.
    for it in 0..=max_iter {
        // The contact candidates of this step (see `contact.rs`); a step
        // whose QP changes which are held certifies nothing.
        let mut held_before = Vec::new();
        if reevaluated {
            let mut forces_moved = true;
            if model.has_obstacles() {
                forces_moved = contact::select_candidates(model, w, contact_margin(model));
            }
            friction::update(model, w);
            if evaluated_with_jacobian && !forces_moved && !model.has_friction() {
                contact::gather_forces(model, w);
                contact::gather_gaps(w);
                merit_now = evaluated_merit(model, w);
            } else {
                merit_now = evaluate(model, w, lambda, true);
            }
            held_before = contact::held_slots(w);
        }
        evaluated_with_jacobian = false;
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
            // Sliding contacts that did not slide stick, those whose
            // direction is not against their move turn, and the solve goes
            // on (see `friction.rs`).
            if it == max_iter || !friction::settle(model, w) {
                // The rows stand loaded at the answer (without friction,
                // whose verdict loads them sticking).
                if !model.has_friction() {
                    w.kkt.rows_at_answer = Some(RowsAt::of(model, w));
                }
                return (true, it);
            }
            if !reevaluated {
                merit_now = evaluate(model, w, lambda, true);
            }
            continue;
        }
        if it == max_iter {
            return (false, it);
        }
        match search_along_step(model, w, lambda, merit_now, tol) {
            Ok((merit, with_jacobian)) => {
                evaluated_with_jacobian = with_jacobian;
                merit_now = merit;
            }
            Err(merit_back) => {
                // A step whose QP changed the held set and that the merit
                // refuses: the contact set has cycled into a bad guess. Step
                // once with the held set the iteration began with, unchosen.
                if settled || !hold_and_step(model, w, lambda, &held_before, merit_back) {
                    return (false, it + 1);
                }
            }
        }
        // The line search left `w` evaluated at the step's end (its
        // residual, its Jacobian too where the whole step was taken); the
        // next pass loads the Jacobian after its candidates.
        if !reevaluated && !evaluated_with_jacobian {
            merit_now = evaluate(model, w, lambda, true);
        }
    }
    unreachable!("the loop returns at its last pass")
}

/// Take the step in `w.step` (the multipliers' too) from `w.q` by
/// backtracking on the merit from `merit_now`, or, refused, go back to the
/// start (evaluated, its Jacobian loaded) and return its merit as the error.
/// Taken, its merit and whether the step's end was evaluated with its
/// Jacobian (the first trial is, the whole step; the others are not).
fn search_along_step(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    merit_now: f64,
    tol: f64,
) -> Result<(f64, bool), f64> {
    let n = model.n();
    take_multiplier_step(model, w);
    // The start is kept in `w.trial` and `reactions_start`; trials go in place.
    w.trial.copy_from_slice(&w.q);
    w.kkt.reactions_start.copy_from_slice(&w.kkt.reactions);
    let alpha = step_limit(&w.step, 1.0, 0.3);
    let mut with_jacobian = false;
    let accepted = super::newton::backtrack(
        w,
        alpha,
        merit_now,
        |w, alpha, first| {
            with_jacobian = first && !model.has_friction();
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
            // With friction the next pass evaluates again whatever it
            // chooses: no Jacobian here for it to throw away.
            evaluate(model, w, lambda, first && !model.has_friction())
        },
        |w| residual_norm(model, w) <= tol,
    );
    let Some(accepted) = accepted else {
        w.q.copy_from_slice(&w.trial);
        w.kkt.reactions.copy_from_slice(&w.kkt.reactions_start);
        return Err(evaluate(model, w, lambda, true));
    };
    Ok((accepted, with_jacobian))
}

/// A Newton step with the contacts `held` held and the other candidates
/// free (no QP choosing), searched on the merit from `merit_now`: whether
/// it was taken.
fn hold_and_step(
    model: &RodModel,
    w: &mut Workspace,
    lambda: f64,
    held: &[usize],
    merit_now: f64,
) -> bool {
    let c = &mut w.kkt.contact;
    for (i, h) in c.active.iter().zip(c.held.iter_mut()) {
        *h = held.binary_search(i).is_ok();
    }
    load_constraint_jacobian(model, w);
    w.kkt.contact.choose = false;
    let solved = super::newton::damped_solve(model, w, kkt_step);
    w.kkt.contact.choose = true;
    // No tolerance to meet early: the next iteration certifies.
    solved && search_along_step(model, w, lambda, merit_now, 0.0).is_ok()
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
/// curvature, see `contact::curvature`; `M` block-diagonal, one block a
/// contact), by Woodbury's identity: `(A + U M U^T)^{-1} = A^{-1} - Y W U^T
/// A^{-1}` with `Y = A^{-1} U` and `W = M (I + U^T Y M)^{-1}`, which needs no
/// inverse of `M` (singular: a sphere turns its force in two directions of
/// three) and holds for a block that is not symmetric (a port's sliding
/// friction, which is no potential's). For the stability verdict it also
/// counts the inertia it adds: see [`CurvatureInverse::with_inertia`].
struct CurvatureInverse {
    /// The columns of `U` (or `U'`, see `with_inertia`) and `Y = A^{-1} U`.
    columns: Vec<Vec<Vector3<f64>>>,
    y: Vec<Vec<Vector3<f64>>>,
    /// `W`.
    inverse: DMatrix<f64>,
    negative_schur: usize,
    positive_blocks: usize,
}

impl CurvatureInverse {
    /// For a Newton step, from `lu`, the factorisation of `A`. A symmetric
    /// block (a contact's: a Hessian) is reduced to its range first, `M = V
    /// L V^T`, `U' = U V` (a sphere's element contact: 3 columns of 6, each a
    /// banded solve less); another keeps its columns.
    fn for_step(lu: &BlockLu, w: &Workspace) -> Option<CurvatureInverse> {
        let contact = &w.kkt.contact;
        if contact.curvature_blocks.is_empty() {
            return None;
        }
        let n = w.g.len();
        let mut columns = Vec::new();
        // The blocks of `M'` (diagonal where reduced), at their columns.
        let mut blocks: Vec<(usize, DMatrix<f64>)> = Vec::new();
        let mut at = 0;
        for block in &contact.curvature_blocks {
            let size = block.nrows();
            let raw = &contact.curvature_columns[at..at + size];
            if is_symmetric(block) {
                for (value, vector) in range_of(block) {
                    blocks.push((columns.len(), DMatrix::from_element(1, 1, value)));
                    columns.push(combined(raw, &vector, n));
                }
            } else {
                blocks.push((columns.len(), block.clone()));
                columns.extend(raw.iter().cloned());
            }
            at += size;
        }
        let k = columns.len();
        let mut m = DMatrix::zeros(k, k);
        for (first, block) in &blocks {
            let size = block.nrows();
            m.view_mut((*first, *first), (size, size)).copy_from(block);
        }
        let y = solved_columns(lu, columns.clone());
        let g = DMatrix::from_fn(k, k, |a, b| dot(&columns[a], &y[b]));
        let kernel = (DMatrix::identity(k, k) + g * &m).try_inverse()?;
        Some(CurvatureInverse {
            columns,
            y,
            inverse: m * kernel,
            negative_schur: 0,
            positive_blocks: 0,
        })
    }

    /// For the stability verdict, from `lu`, the factorisation of the
    /// symmetric part of `A`, with the blocks' symmetric parts, each
    /// reduced to its range: `W = (L^{-1} + U'^T A^{-1} U')^{-1}`. Then
    /// (Haynsworth, twice) the negative eigenvalues of `H = A + U' L U'^T`
    /// are those of `A`, plus those of `-L^{-1} - U'^T A^{-1} U'`, less the
    /// positive ones of `L`.
    fn with_inertia(lu: &BlockLu, w: &Workspace) -> Option<CurvatureInverse> {
        let contact = &w.kkt.contact;
        if contact.curvature_blocks.is_empty() {
            return None;
        }
        let n = w.g.len();
        let (mut columns, mut values) = (Vec::new(), Vec::new());
        let mut at = 0;
        for block in &contact.curvature_blocks {
            let size = block.nrows();
            let raw = &contact.curvature_columns[at..at + size];
            for (value, vector) in range_of(&(0.5 * (block + block.transpose()))) {
                columns.push(combined(raw, &vector, n));
                values.push(value);
            }
            at += size;
        }
        let y = solved_columns(lu, columns.clone());
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

/// Asymmetry of a curvature block, relative to its size, below which it
/// counts as symmetric (a Hessian's, to round-off).
const SYMMETRIC_BLOCK: f64 = 1e-13;

/// Whether a curvature block is symmetric (see [`SYMMETRIC_BLOCK`]), read in
/// place (this runs at every Newton step).
fn is_symmetric(block: &DMatrix<f64>) -> bool {
    let size = block.nrows();
    let skew = (0..size)
        .flat_map(|a| (0..a).map(move |b| (a, b)))
        .fold(0.0f64, |m, (a, b)| {
            m.max((block[(a, b)] - block[(b, a)]).abs())
        });
    skew <= SYMMETRIC_BLOCK * block.amax()
}

/// The eigenpairs of a symmetric block whose values are not nil (beside
/// its largest): its range. A contact's block is 3 x 3 or 6 x 6, whose
/// decompositions are on the stack.
fn range_of(block: &DMatrix<f64>) -> Vec<(f64, DVector<f64>)> {
    // The eigenpairs of a fixed-size copy (nalgebra's decomposition needs
    // its dimension spelt out).
    macro_rules! kept {
        ($d:literal) => {{
            let fixed = nalgebra::SMatrix::<f64, $d, $d>::from_fn(|a, b| block[(a, b)]);
            let eig = fixed.symmetric_eigen();
            let largest = eig.eigenvalues.amax();
            (0..$d)
                .filter(|&k| eig.eigenvalues[k].abs() > 1e-12 * largest)
                .map(|k| {
                    let column = eig.eigenvectors.column(k);
                    (
                        eig.eigenvalues[k],
                        DVector::from_iterator($d, column.iter().copied()),
                    )
                })
                .collect()
        }};
    }
    match block.nrows() {
        3 => kept!(3),
        6 => kept!(6),
        _ => {
            let eig = SymmetricEigen::new(block.clone());
            let largest = eig.eigenvalues.amax();
            (0..block.nrows())
                .filter(|&k| eig.eigenvalues[k].abs() > 1e-12 * largest)
                .map(|k| (eig.eigenvalues[k], eig.eigenvectors.column(k).into_owned()))
                .collect()
        }
    }
}

/// `sum_a weights_a columns_a` (`n` blocks).
fn combined(columns: &[Vec<Vector3<f64>>], weights: &DVector<f64>, n: usize) -> Vec<Vector3<f64>> {
    let mut out = vec![Vector3::zeros(); n];
    for (column, weight) in columns.iter().zip(weights.iter()) {
        for (x, u) in out.iter_mut().zip(column) {
            *x += *weight * u;
        }
    }
    out
}

/// `A^{-1}` applied to each of `columns`.
fn solved_columns(lu: &BlockLu, mut columns: Vec<Vec<Vector3<f64>>>) -> Vec<Vec<Vector3<f64>>> {
    lu.solve_columns_in_place(&mut columns);
    columns
}

/// Stability of a constrained equilibrium: the reduced Hessian `Z^T A Z` on the
/// null space of `D` is positive definite iff the KKT matrix has exactly 3m
/// negative eigenvalues; by Haynsworth's inertia formula that number is
/// `neg(A) + pos(D A^{-1} D^T)` (symmetric parts, `A` nonsingular).
///
/// With friction, the sliding contacts count as sticking: a small move of
/// the rod along the obstacle meets their friction, which the frictionless
/// Hessian leaves out (a robot leaning on a wall would count as unstable,
/// free to slide down it).
pub(crate) fn is_stable(model: &RodModel, w: &mut Workspace) -> bool {
    if !model.has_friction() {
        return reduced_hessian_is_positive(model, w);
    }
    let kept = friction::stick_all(model, w);
    let stable = reduced_hessian_is_positive(model, w);
    friction::unstick(w, kept);
    stable
}

fn reduced_hessian_is_positive(model: &RodModel, w: &mut Workspace) -> bool {
    let loaded = (w.kkt.rows_at_answer.take()).is_some_and(|at| at.is_of(model, w));
    if !loaded {
        load_constraint_jacobian(model, w);
    }
    mixed::densify(w);
    // The workspace's factorisation is free (every use refactors first) and
    // takes that of the symmetric part; `w.scratch` holds the columns.
    let mut lu = std::mem::replace(&mut w.lu, BlockLu::new(0));
    let negative = lu.factor_symmetric_part(&w.jac);
    // The contacts' curvature: the Hessian is `A + U M U^T`.
    let curvature = negative.and_then(|_| CurvatureInverse::with_inertia(&lu, w));
    let negative = match (&curvature, negative) {
        (_, None) => None,
        (None, Some(k)) if w.kkt.contact.curvature_blocks.is_empty() => Some(k),
        (None, Some(_)) => None,
        (Some(c), Some(k)) => (k + c.negative_schur).checked_sub(c.positive_blocks),
    };
    if negative == Some(0) && model.has_contact() {
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
    // A sliding port's friction row holds nothing (its direction zero).
    let first_axial = w.kkt.held_rows + 2 * contact.ports.len();
    let friction = &contact.friction;
    let idle = |r: usize| {
        r.checked_sub(first_axial)
            .and_then(|a| friction.frictional_ports.get(a))
            .is_some_and(|&j| friction.ports[j].direction == Vector3::zeros())
    };
    let kept: Vec<usize> = (0..held_rows)
        .filter(|&r| !idle(r))
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
    let stable = match (negative, s) {
        (Some(negative), Some(s)) => {
            schur_verdict(model, w, (&lu, curvature.as_ref()), negative, s, &kept)
        }
        _ => false,
    };
    w.lu = lu;
    stable
}

/// Whether the Hessian with `negative` negative eigenvalues is positive on
/// the rows `kept` (the reduced Hessian's test by inertia), `s` their Schur
/// complement `R A^{-1} R^T` and `A^{-1}` from `lu` and `curvature`.
fn schur_verdict(
    model: &RodModel,
    w: &Workspace,
    (lu, curvature): (&BlockLu, Option<&CurvatureInverse>),
    negative: usize,
    s: DMatrix<f64>,
    kept: &[usize],
) -> bool {
    let rows = kept.len();
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
    // An eigenvalue near zero is either rows that repeat others (`R^T v =
    // 0`: no direction at all, left out of the count), a neutral direction
    // (not stable), or a small one of its sign. Sticking contacts repeat:
    // where every node of a stretch sticks, each chord's length is held
    // twice over (a rod pushed along a frictional floor read as unstable,
    // and its path crawled); a long stuck stretch also has directions of
    // small `R^T v`, whose eigenvalues are small but far above round-off
    // (the repeated ones' are ~1e-19 of the largest).
    let largest = eig.eigenvalues.amax().max(f64::MIN_POSITIVE);
    let scale = kept
        .iter()
        .map(|&r| w.kkt.rows[r].iter().map(|v| v.norm_squared()).sum::<f64>())
        .fold(0.0, f64::max)
        .sqrt();
    let (mut positive, mut repeated) = (0, 0);
    for (e, &value) in eig.eigenvalues.iter().enumerate() {
        if value.abs() <= SMALL_EIGENVALUE * largest {
            let v = eig.eigenvectors.column(e);
            let mut combination = vec![Vector3::zeros(); model.n()];
            for (c, &r) in kept.iter().enumerate() {
                let len = w.kkt.row_len[r];
                for (x, row) in combination.iter_mut().zip(&w.kkt.rows[r][..len]) {
                    *x += v[c] * row;
                }
            }
            let size = combination
                .iter()
                .map(|x| x.norm_squared())
                .sum::<f64>()
                .sqrt();
            if size <= REPEATED_ROWS * scale {
                repeated += 1;
                continue;
            }
            // `v^T S v` again as `x^T A^{-1} x` (`x = R^T v`), whose error
            // is round-off of `|x|^2 |A^{-1}|`, not of the largest.
            let mut solved = combination.clone();
            lu.solve_in_place(&mut solved);
            if let Some(c) = curvature {
                c.correct(&mut solved);
            }
            let mut value = dot(&combination, &solved);
            if let Some(e) = &w.kkt.compliance {
                let held = e.nrows();
                let part = v.rows(0, held);
                value += part.dot(&(e * part));
            }
            let inverse = largest / (scale * scale);
            if value.abs() <= NEUTRAL_EIGENVALUE * size * size * inverse {
                return false;
            }
            positive += usize::from(value > 0.0);
            continue;
        }
        positive += usize::from(value > 0.0);
    }
    negative + positive + repeated == rows
}

/// An eigenvalue of the rows' Schur complement this small (of the largest)
/// is looked at: repeated rows, neutral, or small.
const SMALL_EIGENVALUE: f64 = 1e-12;

/// How small `R^T v` is, of the largest row, where rows repeat others.
const REPEATED_ROWS: f64 = 1e-6;

/// A direction that is no repeat is neutral where `x^T A^{-1} x` is this
/// small of `|x|^2` times an estimate of `|A^{-1}|` (the largest eigenvalue
/// over the largest row's square): round-off's, with a margin.
const NEUTRAL_EIGENVALUE: f64 = 1e-12;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::Obstacle;
    use crate::quat::Quat;
    use crate::scene::{Gravity, Scene};

    /// A heavy rod of 40 elements (60 lying) bent down onto a floor and a ball, every
    /// slot a candidate, every other one held with a force; or (`lying`)
    /// straight on the floor, no slot held.
    fn pressed_rod(lying: bool) -> (RodModel, Workspace) {
        let mut scene = Scene::new(1.0, 1.0, 1.0, 1.0);
        scene.gravity = Some(Gravity {
            linear_density: 1.0,
            vector: Vector3::new(0.0, 0.0, -1.0),
        });
        let half = std::f64::consts::FRAC_1_SQRT_2;
        scene.base_quaternion = Quat::new(half, 0.0, half, 0.0);
        scene.radius = Some(0.005);
        scene.obstacles = vec![
            Obstacle::HalfSpace {
                point: Vector3::new(0.0, 0.0, -0.05),
                normal: Vector3::z(),
            },
            Obstacle::Sphere {
                centre: Vector3::new(0.5, 0.03, -0.06),
                radius: 0.03,
            },
        ];
        if lying {
            scene.obstacles.truncate(1);
            scene.base_position = Vector3::new(0.0, 0.0, -0.045);
        }
        let model = RodModel::new(&scene, if lying { 60 } else { 40 });
        let mut w = Workspace::new(&model).unwrap();
        let n = model.n();
        for j in (1..=n).filter(|_| !lying) {
            // Down about y, and a little about x: a rod out of plane.
            let s = j as f64 / n as f64;
            let (pitch, roll) = (0.15 * s * s, 0.05 * s);
            let turn = Quat::new((0.5 * pitch).cos(), 0.0, (0.5 * pitch).sin(), 0.0)
                * Quat::new((0.5 * roll).cos(), (0.5 * roll).sin(), 0.0, 0.0);
            w.q[j] = (turn * w.q[0]).normalized();
        }
        evaluate(&model, &mut w, 1.0, true);
        contact::select_candidates(&model, &mut w, 10.0);
        let first = contact::offset(&model, &w);
        let active = w.kkt.contact.active.clone();
        for (a, &i) in active.iter().enumerate().filter(|_| !lying) {
            w.kkt.contact.held[a] = a % 2 == 0;
            w.kkt.reactions[first + i].x = if a % 2 == 0 { 0.1 } else { 0.0 };
        }
        evaluate(&model, &mut w, 1.0, true);
        (model, w)
    }

    /// The step in mixed form is the Schur complement's: the rows built from
    /// the chords against those from `position_jacobian`, and the step and
    /// the multipliers with the held set kept (the ball's curvature in them).
    #[test]
    fn the_mixed_step_is_the_schur_complements() {
        let (model, mut w) = pressed_rod(false);
        load_constraint_jacobian(&model, &mut w);
        let rows = w.kkt.row_count;
        assert!(w.kkt.mixed.in_use, "{rows} rows");
        assert!(!w.kkt.contact.curvature_blocks.is_empty());
        mixed::densify(&mut w);
        let from_chords = w.kkt.rows[..rows].to_vec();
        let columns = w.kkt.contact.curvature_columns.clone();
        contact::load_rows(&model, &mut w, 0);
        contact::curvature(&model, &mut w, true);
        let largest = from_chords
            .iter()
            .flatten()
            .fold(0.0f64, |a, v| a.max(v.amax()));
        let pairs = from_chords.iter().zip(&w.kkt.rows);
        for (a, b) in pairs.chain(columns.iter().zip(&w.kkt.contact.curvature_columns)) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).amax() <= 1e-13 * largest, "{x} against {y}");
            }
        }
        w.kkt.contact.choose = false;
        compare_steps(&mut w, 1e-9);
    }

    /// A contact's row from the chords' Jacobians, loaded once a step, is
    /// the one from its node's position Jacobian.
    #[test]
    fn a_row_from_the_loaded_chords_is_the_position_jacobians() {
        let (model, mut w) = pressed_rod(false);
        let rows = w.kkt.contact.active.len();
        assert!(rows > 1, "{rows} rows");
        contact::load_rows(&model, &mut w, 0);
        let direct = w.kkt.rows[..rows].to_vec();
        w.kkt.contact.load_chords(&model, &w.q);
        assert!(w.kkt.contact.chords_loaded);
        contact::load_rows(&model, &mut w, 0);
        let largest = direct.iter().flatten().fold(0.0f64, |a, v| a.max(v.amax()));
        for (a, b) in direct.iter().zip(&w.kkt.rows[..rows]) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).amax() <= 1e-14 * largest, "{x} against {y}");
            }
        }
    }

    /// A rod lying straight on a floor under its weight: the QP in mixed
    /// form (primal-dual) holds every node, as the Schur complement's
    /// (primal) does, with the same forces.
    #[test]
    fn the_mixed_qp_settles_a_rod_on_a_floor_as_the_schur_qp() {
        let (model, mut w) = pressed_rod(true);
        load_constraint_jacobian(&model, &mut w);
        assert!(w.kkt.mixed.in_use && w.kkt.contact.held.iter().all(|h| !h));
        mixed::densify(&mut w);
        w.kkt.contact.choose = true;
        // The floor carries each node's weight w h = 1/60 N (the tip's half).
        // The Schur complement squares the rod's condition (~n^4): its
        // forces are off by 2e-6 of it, the mixed form's by 1e-7.
        let forces = compare_steps(&mut w, 1e-5);
        assert!(w.kkt.contact.held.iter().all(|h| *h));
        for (k, f) in forces.iter().enumerate() {
            let weight = if k + 1 == 60 { 0.5 / 60.0 } else { 1.0 / 60.0 };
            assert!((f - weight).abs() <= 1e-6 * weight, "node {}: {f}", k + 1);
        }
    }

    /// Solve the step at `w`'s state in mixed form and by the Schur
    /// complement (the rows dense in `w`) from the same held set: the same
    /// held set, step and multipliers (to `tol`); the mixed multipliers.
    fn compare_steps(w: &mut Workspace, tol: f64) -> DVector<f64> {
        assert!(w.lu.factor(&w.jac, 0.0).is_ok());
        let lu = std::mem::replace(&mut w.lu, BlockLu::new(0));
        let held = w.kkt.contact.held.clone();
        assert!(mixed_step(0.0, w));
        let (step, x, chosen) = (
            w.step.clone(),
            w.kkt.rhs.clone(),
            w.kkt.contact.held.clone(),
        );
        w.kkt.contact.held.copy_from_slice(&held);
        w.kkt.mixed.in_use = false;
        assert!(kkt_step(&lu, w));
        w.kkt.mixed.in_use = true;
        assert_eq!(chosen, w.kkt.contact.held);
        // (A rod held flat on the floor does not turn: its step is round-off.)
        let scale = step.iter().fold(0.0f64, |a, v| a.max(v.amax()));
        for (a, b) in step.iter().zip(&w.step) {
            assert!((a - b).amax() <= 1e-9 * scale + 1e-12, "{a} against {b}");
        }
        let error = (&x - &w.kkt.rhs).amax();
        assert!(
            x.amax() > 0.0 && error <= tol * x.amax(),
            "{error:e} of {:e}",
            x.amax()
        );
        x
    }

    /// [`Schur`] counting its solves.
    struct Counted<'a>(Schur<'a>, usize);

    impl Subproblem for Counted<'_> {
        fn solve(&mut self, free: &[bool], x: &mut DVector<f64>) -> bool {
            self.1 += 1;
            self.0.solve(free, x)
        }
        fn rows_after(&self, x: &DVector<f64>) -> DVector<f64> {
            self.0.rows_after(x)
        }
        fn rows_at(&mut self, x: &DVector<f64>) -> Option<DVector<f64>> {
            self.0.rows_at(x)
        }
        fn is_convex(&self) -> bool {
            self.0.is_convex()
        }
        fn is_round_off_force(&self, r: usize, x: f64, scale: f64) -> bool {
            self.0.is_round_off_force(r, x, scale)
        }
    }

    /// The compliance of `m` contacts along a stretch: the inverse of a
    /// chain of springs, each to the ground and to its neighbours (positive
    /// definite, every row coupled).
    fn chain_compliance(m: usize) -> DMatrix<f64> {
        let stiffness = DMatrix::from_fn(m, m, |i, j| match i.abs_diff(j) {
            0 => 2.1,
            1 => -1.0,
            _ => 0.0,
        });
        stiffness.try_inverse().unwrap()
    }

    /// [`primal_active_set`] on `S x = b` (`equalities` rows unbounded, the
    /// rest at least `lower`) from no row held: its answer, held set and
    /// subproblem solves.
    fn run_qp(
        s: &DMatrix<f64>,
        b: &DVector<f64>,
        (equalities, lower): (usize, &[f64]),
        symmetric: bool,
        undo: bool,
    ) -> (DVector<f64>, Vec<bool>, usize) {
        let mut sub = Counted(
            Schur {
                s,
                b,
                symmetric,
                free_rows: vec![],
                fixed_rows: vec![],
            },
            0,
        );
        let mut held = vec![false; lower.len()];
        let scale = row_scale(&mut sub, s.nrows()).unwrap();
        let x = primal_active_set(&mut sub, equalities, lower, &mut held, scale, undo).unwrap();
        (x, held, sub.1)
    }

    #[test]
    fn freeing_one_row_at_a_time_after_a_failed_batch_finds_the_same_minimum() {
        // 16 contacts whose gaps all close at first (`b > 0`), deepest at
        // one end: a start deep in an obstacle that the step leaves along
        // most of the stretch.
        let m = 16;
        let s = chain_compliance(m);
        let b = DVector::from_fn(m, |i, _| (0.5 * i as f64).exp());
        let lower = vec![0.0; m];
        let (batch, batch_held, batch_solves) = run_qp(&s, &b, (0, &lower), true, false);
        let (single, single_held, single_solves) = run_qp(&s, &b, (0, &lower), true, true);
        // The minimum: forces >= 0, gaps >= 0, one or the other zero.
        let gaps = &s * &single - &b;
        let (force, gap) = (single.amax(), b.amax());
        for i in 0..m {
            assert!(single[i] >= 0.0 && gaps[i] >= -1e-12 * gap, "row {i}");
            assert!(single[i] * gaps[i] <= 1e-12 * force * gap, "row {i}");
        }
        assert_eq!(batch_held, single_held);
        assert!((&batch - &single).amax() <= 1e-10 * batch.amax());
        // One contact left of 16 freed: 3 solves against 17.
        assert_eq!(single_held.iter().filter(|h| **h).count(), 1);
        assert!(
            single_solves < batch_solves / 4,
            "{single_solves} solves against {batch_solves}"
        );
    }

    #[test]
    fn with_a_held_row_and_forces_at_hand_the_minimum_is_the_batches() {
        // A held point's row (unbounded) beside 16 contacts with forces
        // (their steps bounded below by minus them), two deep places: one
        // at a time frees several rows, and steps are blocked on the way.
        let m = 17;
        let mut s = chain_compliance(m);
        s[(0, 0)] += 1.0;
        let b = DVector::from_fn(m, |i, _| {
            let (a, c) = (i as f64 - 5.0, i as f64 - 14.0);
            3.0 * (-0.5 * a * a).exp() + 4.0 * (-0.5 * c * c).exp() - 0.5
        });
        let lower: Vec<f64> = (1..m).map(|i| -0.02 * (i % 3) as f64).collect();
        let (batch, batch_held, _) = run_qp(&s, &b, (1, &lower), true, false);
        let (single, single_held, solves) = run_qp(&s, &b, (1, &lower), true, true);
        assert_eq!(batch_held, single_held);
        assert!((&batch - &single).amax() <= 1e-10 * batch.amax());
        let gaps = &s * &single - &b;
        assert!(gaps[0].abs() <= 1e-12 * b.amax());
        for (c, lo) in lower.iter().enumerate() {
            let i = c + 1;
            assert!(
                single[i] >= *lo - 1e-12 && gaps[i] >= -1e-12 * b.amax(),
                "row {i}"
            );
        }
        assert!(
            solves > 3,
            "{solves} solves: the case frees more than one row"
        );
    }

    #[test]
    fn a_batch_left_by_a_row_or_an_indefinite_or_unsymmetric_qp_keep_the_batches_path() {
        let m = 16;
        let lower = vec![0.0; m];
        // A stretch settling whole but for its first row: dropped as before.
        let b = DVector::from_fn(m, |i, _| if i == 0 { 0.3 } else { 1.0 });
        let s = chain_compliance(m);
        let same = |s: &DMatrix<f64>, b: &DVector<f64>, symmetric: bool| {
            let (x, held, solves) = run_qp(s, b, (0, &lower), symmetric, false);
            let (y, held_y, solves_y) = run_qp(s, b, (0, &lower), symmetric, true);
            assert_eq!((held, solves), (held_y, solves_y));
            assert_eq!(x, y);
            solves
        };
        assert_eq!(same(&s, &b, true), 3);
        // Deep at one end, which the first test undoes, on an `S` that is
        // indefinite or not symmetric: the batches' path.
        let deep = DVector::from_fn(m, |i, _| (0.5 * i as f64).exp());
        let schur = |s| Schur {
            s,
            b: &deep,
            symmetric: true,
            free_rows: vec![],
            fixed_rows: vec![],
        };
        let mut indefinite = s.clone();
        indefinite[(3, 3)] = -indefinite[(3, 3)];
        assert!(!schur(&indefinite).is_convex());
        same(&indefinite, &deep, true);
        same(&s, &deep, false);
    }

    /// `S` whose first two rows repeat exactly (a contact on a node and on
    /// the element beside it).
    fn repeated_rows(m: usize) -> DMatrix<f64> {
        let mut repeated = chain_compliance(m);
        for j in 0..m {
            repeated[(1, j)] = repeated[(0, j)];
        }
        for i in 0..m {
            repeated[(i, 1)] = repeated[(i, 0)];
        }
        repeated
    }

    #[test]
    fn a_semidefinite_qp_is_convex_and_its_failed_batch_undone_to_the_same_gaps() {
        // Rows that repeat make `S` singular, semidefinite: its minimisers
        // differ only in how a force splits between them, the gaps (and
        // the rod's step) the same. One at a time puts it on one row.
        let m = 16;
        let lower = vec![0.0; m];
        // (The repeated rows' gaps are the same: `b` repeats too.)
        let deep = DVector::from_fn(m, |i, _| (0.5 * (m - 1 - i.max(1)) as f64).exp());
        let repeated = repeated_rows(m);
        assert!(Schur {
            s: &repeated,
            b: &deep,
            symmetric: true,
            free_rows: vec![],
            fixed_rows: vec![],
        }
        .is_convex());
        let (batch, _, batch_solves) = run_qp(&repeated, &deep, (0, &lower), true, false);
        let (single, _, solves) = run_qp(&repeated, &deep, (0, &lower), true, true);
        assert!(solves < batch_solves, "{solves} against {batch_solves}");
        let (gaps, batch_gaps) = (&repeated * &single - &deep, &repeated * &batch - &deep);
        assert!((&gaps - &batch_gaps).amax() <= 1e-9 * deep.amax());
        assert!((single[0] + single[1] - batch[0] - batch[1]).abs() <= 1e-9 * batch.amax());
        assert!(single[0] == 0.0 || single[1] == 0.0, "{single}");
        for i in 0..m {
            assert!(
                single[i] >= 0.0 && gaps[i] >= -1e-12 * deep.amax(),
                "row {i}"
            );
        }
    }
    #[test]
    fn a_batch_of_dependent_rows_takes_one_path_whatever_the_round_off() {
        // 17 contacts on 16 coordinates (`S = R C R^T`, row 16 of `R` rows
        // 13 + 14 - 15: a point held by two obstacles at once), deepest at
        // one end. Freed together their subproblem is singular, its solve
        // round-off: whether the factorisations pass and which forces come
        // out below their bounds is chance. Perturbed by round-off, the QP
        // must take the same path to the same answer.
        let m = 17;
        let mut r = DMatrix::identity(m, m);
        r[(16, 13)] = 1.0;
        r[(16, 14)] = 1.0;
        r[(16, 15)] = -1.0;
        r[(16, 16)] = 0.0;
        let exact = &r * chain_compliance(m) * r.transpose();
        let b = DVector::from_fn(m, |i, _| (0.5 * i.min(15) as f64).exp());
        let lower = vec![0.0; m];
        let mut seen = Vec::new();
        for k in 0..24 {
            // A symmetric perturbation of a few ulps, different each time.
            let mut s = exact.clone();
            for i in 0..m {
                for j in 0..=i {
                    let t = ((k * 31 + i * 7 + j * 13) % 17) as f64 / 17.0 - 0.5;
                    let v = s[(i, j)] * (1.0 + 8.0 * f64::EPSILON * t);
                    s[(i, j)] = v;
                    s[(j, i)] = v;
                }
            }
            let (x, held, solves) = run_qp(&s, &b, (0, &lower), true, true);
            let gaps = &s * &x - &b;
            for i in 0..m {
                assert!(
                    x[i] >= 0.0 && gaps[i] >= -1e-9 * b.amax(),
                    "{k}, row {i}: {x}"
                );
            }
            seen.push((held, solves));
        }
        assert!(seen.iter().all(|v| *v == seen[0]), "{seen:?}");
    }

    #[test]
    fn the_verdict_at_a_newton_answer_reuses_its_rows_as_a_fresh_load_gives_them() {
        // A rod pressed onto a floor and a ball, solved: the verdict takes
        // the rows the last step loaded, the same to the bit as loading
        // them again; a moved state or another load drops them.
        let (model, mut w) = pressed_rod(false);
        let (converged, _) = newton(&model, &mut w, 1.0, (200, 1e-10));
        assert!(converged && !w.kkt.contact.held.iter().all(|h| !h));
        assert!(w.kkt.rows_at_answer.is_some());
        let loaded = |w: &Workspace| {
            let rows = w.kkt.rows[..w.kkt.row_count].to_vec();
            (rows, w.kkt.contact.curvature_blocks.clone())
        };
        let reused = reduced_hessian_is_positive(&model, &mut w);
        assert!(w.kkt.rows_at_answer.is_none());
        let kept = loaded(&w);
        let fresh = reduced_hessian_is_positive(&model, &mut w);
        assert_eq!(reused, fresh);
        assert_eq!(kept, loaded(&w));
        let record = RowsAt::of(&model, &w);
        w.q[5] = w.q[5].perturbed(Vector3::new(1e-9, 0.0, 0.0));
        assert!(!record.is_of(&model, &w));
        w.kkt.rows_at_answer = Some(record);
        load_constraint_jacobian(&model, &mut w);
        assert!(w.kkt.rows_at_answer.is_none());
    }
}
