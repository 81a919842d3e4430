//! The KKT step in mixed form, banded whatever the number of contacts.
//!
//! The Schur complement of `constrained.rs` eliminates the positions: a
//! row of `D = dr/dtheta` reaches back to the base, so with m rows the step
//! costs O(m n) to build the columns, O(m^2 n) to form `S` and O(m^3) to
//! factor it. A rod lying along a surface has m ~ n, and that is O(n^3).
//! Here the positions `dr_k` and the elements' internal forces `dN_i` stay
//! unknowns beside the rotations (the chords' equations `dr_i - dr_(i-1) =
//! E_i dtheta_(i-1) + F_i dtheta_i` the rows whose multipliers are the
//! internal forces), so every row is local:
//!
//! ```text
//! theta_k:  A dtheta - F_k^T dN_k - E_(k+1)^T dN_(k+1)           = -g_k
//! N_k:      -E_k dtheta_(k-1) - F_k dtheta_k + dr_k - dr_(k-1)    = 0
//! r_k:      dN_k - dN_(k+1) + (M dr)_k - sum_rows v_(row,k) x_row = 0
//! row:      sum_k v_(row,k)^T dr_k                                = -residual
//! ```
//!
//! (`v` a row's direction at a node: a held point's axis, or a contact's
//! share of its normal; `M` the contacts' curvature). Eliminating `dr` and
//! `dN` gives back `(A + U M U^T) dtheta - D^T x = -g`, `D dtheta =
//! -residual`: the same step. Ordered node by node the matrix is banded with
//! a width of about ten, and a band LU with partial pivoting solves it in
//! O(n) (it is indefinite). The bounded QP of the contact forces runs over it
//! as over the Schur complement (`constrained::bounded_qp`): one band
//! factorisation per working set.

use super::constrained::Subproblem;
use super::{contact, Workspace};
use crate::banded::BandLu;
use crate::blocktri::BlockTridiagonal;
use crate::model::RodModel;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// How many KKT rows make the mixed form the cheaper: measured on the rod
/// on a floor and the seed's robot against a wall (`cargo bench --bench
/// contact`). Below it the Schur complement's few banded solves win.
pub(crate) const MIXED_ROWS: usize = 48;

/// Unknowns of a node before its rows: `dtheta`, `dN`, `dr`.
const THETA: usize = 0;
const FORCE: usize = 3;
const POSITION: usize = 6;
const NODE_UNKNOWNS: usize = 9;

/// A row's directions at its (up to two) nodes.
pub(crate) type RowDirections = [(usize, Vector3<f64>); 2];

/// The mixed form's buffers, sized by the first use.
#[derive(Debug, Clone, Default)]
pub(crate) struct MixedWork {
    /// Whether this step is solved in mixed form (set with the rows).
    pub in_use: bool,
    /// `(E_i, F_i)`: element `i`'s chord Jacobian (index `i - 1`).
    pub chords: Vec<(Matrix3<f64>, Matrix3<f64>)>,
    /// Each KKT row's directions at its (up to two) nodes; node 0, the
    /// clamped base, does not move.
    pub rows: Vec<[(usize, Vector3<f64>); 2]>,
    /// Each row's residual for this step.
    pub residuals: Vec<f64>,
    /// Each row's compliance (its diagonal entry: a sticking contact's, see
    /// `friction.rs`; zero for the others).
    pub compliance: Vec<f64>,
    /// What a row's multiplier adds to the nodes' balance beyond its own
    /// directions (a sliding contact's `mu d`), by row.
    pub force_extra: Vec<(usize, RowDirections)>,
    band: BandLu,
    /// First unknown of each node's group (`n + 1` entries) and each row's
    /// unknown (`None` while its multiplier is fixed).
    start: Vec<usize>,
    unknown: Vec<Option<usize>>,
    solution: Vec<f64>,
    /// The system with every multiplier given (the QP's gradients), and
    /// whether it is factored for this step.
    fixed_band: BandLu,
    fixed_factored: bool,
    /// Whether the dense rows and curvature columns are loaded too.
    dense: bool,
}

impl MixedWork {
    /// The node whose group holds a row's unknown: its last.
    fn owner(&self, row: usize) -> usize {
        let [(a, _), (b, _)] = self.rows[row];
        a.max(b)
    }
}

/// The step's data borrowed from the workspace.
pub(crate) struct Mixed<'a> {
    pub work: &'a mut MixedWork,
    pub jac: &'a BlockTridiagonal,
    pub g: &'a [Vector3<f64>],
    pub shift: f64,
    pub curvature: (&'a [DMatrix<f64>], &'a [Vec<usize>]),
}

impl Mixed<'_> {
    /// Each entry of the matrix, and the right-hand side, of the rows in
    /// `free` solved and the others' multipliers at `x`.
    fn assemble(
        &self,
        x: &DVector<f64>,
        emit: &mut impl FnMut(usize, usize, f64),
        rhs: &mut [f64],
    ) {
        let w = &*self.work;
        let n = self.g.len();
        let at = |k: usize, part: usize| w.start[k - 1] + part;
        let identity = Matrix3::identity();
        for k in 1..=n {
            let (theta, force, position) = (at(k, THETA), at(k, FORCE), at(k, POSITION));
            let (e, f) = &w.chords[k - 1];
            // Node k's rotation: the Jacobian, and the internal forces' torques.
            put(
                emit,
                theta,
                theta,
                &(self.jac.diag[k - 1] + identity * self.shift),
            );
            if k < n {
                put(emit, theta, at(k + 1, THETA), &self.jac.upper[k - 1]);
                put(emit, theta, at(k + 1, FORCE), &-w.chords[k].0.transpose());
            }
            if k > 1 {
                put(emit, theta, at(k - 1, THETA), &self.jac.lower[k - 2]);
            }
            put(emit, theta, force, &-f.transpose());
            for a in 0..3 {
                rhs[theta + a] = -self.g[k - 1][a];
            }
            // Element k's chord.
            put(emit, force, theta, &-f);
            put(emit, force, position, &identity);
            if k > 1 {
                put(emit, force, at(k - 1, THETA), &-e);
                put(emit, force, at(k - 1, POSITION), &-identity);
            }
            // Node k's force balance.
            put(emit, position, force, &identity);
            if k < n {
                put(emit, position, at(k + 1, FORCE), &-identity);
            }
        }
        for (m, nodes) in self.curvature.0.iter().zip(self.curvature.1) {
            for (a, &na) in nodes.iter().enumerate() {
                for (b, &nb) in nodes.iter().enumerate() {
                    let part: Matrix3<f64> = m.fixed_view::<3, 3>(3 * a, 3 * b).into();
                    put(emit, at(na, POSITION), at(nb, POSITION), &part);
                }
            }
        }
        for (row, directions) in w.rows.iter().enumerate() {
            let unknown = w.unknown[row];
            for &(node, v) in directions.iter().filter(|(node, _)| *node > 0) {
                let position = at(node, POSITION);
                for a in 0..3 {
                    match unknown {
                        Some(u) => {
                            emit(position + a, u, -v[a]);
                            emit(u, position + a, v[a]);
                        }
                        None => rhs[position + a] += v[a] * x[row],
                    }
                }
            }
            for (_, extra) in w.force_extra.iter().filter(|(r, _)| *r == row) {
                for &(node, v) in extra.iter().filter(|(node, _)| *node > 0) {
                    let position = at(node, POSITION);
                    for a in 0..3 {
                        match unknown {
                            Some(u) => emit(position + a, u, -v[a]),
                            None => rhs[position + a] += v[a] * x[row],
                        }
                    }
                }
            }
            if let Some(u) = unknown {
                rhs[u] = -w.residuals[row];
                if w.compliance[row] != 0.0 {
                    emit(u, u, w.compliance[row]);
                }
            }
        }
    }
}

/// A 3x3 block's nonzero entries at `(i, j)`.
fn put(emit: &mut impl FnMut(usize, usize, f64), i: usize, j: usize, m: &Matrix3<f64>) {
    for a in 0..3 {
        for b in 0..3 {
            if m[(a, b)] != 0.0 {
                emit(i + a, j + b, m[(a, b)]);
            }
        }
    }
}

impl Mixed<'_> {
    /// Number the unknowns node by node: `dtheta`, `dN`, `dr`, then the
    /// free rows that end at the node. Returns their count.
    fn layout(&mut self, free: &[bool]) -> usize {
        let n = self.g.len();
        let w = &mut *self.work;
        let mut owned = vec![0usize; n + 1];
        for (row, &f) in free.iter().enumerate() {
            if f {
                owned[w.owner(row)] += 1;
            }
        }
        w.start.clear();
        let mut next = 0;
        for &rows in &owned[1..] {
            w.start.push(next);
            next += NODE_UNKNOWNS + rows;
        }
        w.start.push(next);
        let mut filled = vec![0usize; n + 1];
        w.unknown.clear();
        for (row, &f) in free.iter().enumerate() {
            w.unknown.push(if f {
                let k = w.owner(row);
                filled[k] += 1;
                Some(w.start[k - 1] + NODE_UNKNOWNS + filled[k] - 1)
            } else {
                None
            });
        }
        next
    }

    /// Assemble and factor into `band` the system of the current layout.
    fn factor(&self, band: &mut BandLu, size: usize, x: &DVector<f64>) -> bool {
        let mut rhs = vec![0.0; size];
        let (mut below, mut above) = (0usize, 0usize);
        self.assemble(
            x,
            &mut |i, j, _| {
                below = below.max(i.saturating_sub(j));
                above = above.max(j.saturating_sub(i));
            },
            &mut rhs,
        );
        band.reset(size, below, above);
        self.assemble(x, &mut |i, j, v| band.add(i, j, v), &mut rhs);
        band.factor()
    }

    /// Solve the factored system of the current layout for the multipliers
    /// `x` of the fixed rows into `solution`.
    fn solve_factored(&mut self, band: &BandLu, size: usize, x: &DVector<f64>) -> bool {
        let mut rhs = vec![0.0; size];
        self.assemble(x, &mut |_, _, _| {}, &mut rhs);
        band.solve(&mut rhs);
        if rhs.iter().any(|v| !v.is_finite()) {
            return false;
        }
        self.work.solution = rhs;
        true
    }
}

impl Subproblem for Mixed<'_> {
    fn solve(&mut self, free: &[bool], x: &mut DVector<f64>) -> bool {
        let size = self.layout(free);
        let mut band = std::mem::take(&mut self.work.band);
        let solved = self.factor(&mut band, size, x) && self.solve_factored(&band, size, x);
        self.work.band = band;
        if !solved {
            return false;
        }
        for (row, unknown) in self.work.unknown.iter().enumerate() {
            if let Some(u) = unknown {
                x[row] = self.work.solution[*u];
            }
        }
        true
    }

    fn rows_at(&mut self, x: &DVector<f64>) -> Option<DVector<f64>> {
        // Every multiplier given: the system of the rod alone (its matrix
        // the same for the whole QP, factored once).
        let size = self.layout(&vec![false; x.len()]);
        let mut band = std::mem::take(&mut self.work.fixed_band);
        let factored = self.work.fixed_factored || self.factor(&mut band, size, x);
        self.work.fixed_factored = factored;
        let solved = factored && self.solve_factored(&band, size, x);
        self.work.fixed_band = band;
        solved.then(|| self.rows_after(x))
    }

    fn is_convex(&self) -> bool {
        // Not known without the Schur complement this form avoids; its QP
        // is the primal-dual active set's, which needs no such choice.
        false
    }

    fn rows_after(&self, _x: &DVector<f64>) -> DVector<f64> {
        let w = &*self.work;
        DVector::from_fn(w.rows.len(), |row, _| {
            let moved: f64 = w.rows[row]
                .iter()
                .filter(|(node, _)| *node > 0)
                .map(|(node, v)| {
                    let p = w.start[node - 1] + POSITION;
                    v.dot(&Vector3::new(
                        w.solution[p],
                        w.solution[p + 1],
                        w.solution[p + 2],
                    ))
                })
                .sum();
            moved + w.residuals[row]
        })
    }
}

impl MixedWork {
    /// The rotation step of the last solve into `step`.
    pub fn take_step(&self, step: &mut [Vector3<f64>]) {
        for (k, s) in step.iter_mut().enumerate() {
            let t = self.start[k] + THETA;
            *s = Vector3::new(self.solution[t], self.solution[t + 1], self.solution[t + 2]);
        }
    }

    /// A new QP: the rod's own system is factored again.
    pub fn begin(&mut self) {
        self.fixed_factored = false;
    }
}

/// Choose the form of this step's KKT solves and, for the mixed one, load
/// its rows and chords (after `constrained::load_constraint_jacobian` has
/// chosen the rows).
pub(crate) fn load(model: &RodModel, w: &mut Workspace) {
    let work = &mut w.kkt.mixed;
    work.in_use = false;
    work.dense = false;
    if !model.has_contact() || w.kkt.row_count <= MIXED_ROWS || w.kkt.compliance.is_some() {
        return;
    }
    let n = model.n();
    if w.kkt.contact.chords_loaded {
        // This step's, loaded once for every row.
        work.chords.clone_from(&w.kkt.contact.chords);
    } else {
        work.chords.resize(n, (Matrix3::zeros(), Matrix3::zeros()));
        if !model.chord_jacobians(&w.q, &mut work.chords) {
            return;
        }
    }
    if model.clamped_tip().is_some() {
        // The tip's rotation is held: it moves no chord.
        work.chords[n - 1].1 = Matrix3::zeros();
    }
    work.rows.clear();
    for c in model.constraints() {
        for axis in 0..3 {
            work.rows
                .push([(c.node, Vector3::ith(axis, 1.0)), (0, Vector3::zeros())]);
        }
    }
    let contact = &w.kkt.contact;
    for site in &contact.ports {
        let [(a, wa), (b, wb)] = super::port::shares(site);
        for d in site.directions {
            work.rows.push([(a, wa * d), (b, wb * d)]);
        }
    }
    work.compliance.clear();
    work.compliance.resize(work.rows.len(), 0.0);
    for &j in &contact.friction.frictional_ports {
        let [(a, wa), (b, wb)] = super::port::shares(&contact.ports[j]);
        let state = &contact.friction.ports[j];
        let d = state.direction;
        work.rows.push([(a, wa * d), (b, wb * d)]);
        work.compliance.push(state.diagonal);
    }
    for stick in &contact.friction.sticks {
        let [(a, wa), (b, wb)] = super::friction::stick_shares(model, contact, stick.slot);
        for d in stick.directions {
            work.rows.push([(a, wa * d), (b, wb * d)]);
            work.compliance.push(contact.friction.compliance);
        }
    }
    for &i in &contact.active {
        let site = &contact.sites[i];
        let [(a, wa), (b, wb)] = contact::shares(model, i, site);
        work.rows
            .push([(a, wa * site.normal), (b, wb * site.normal)]);
    }
    work.compliance.resize(work.rows.len(), 0.0);
    work.in_use = true;
}

/// The dense rows `D^T v` of this step and the curvature's columns `U`
/// from the mixed form's chords (for the Schur complement where the mixed
/// matrix is singular, and for the stability verdict); nothing where the
/// rows are dense already.
pub(crate) fn densify(w: &mut Workspace) {
    let kkt = &mut w.kkt;
    let work = &mut kkt.mixed;
    if !work.in_use || work.dense {
        return;
    }
    let n = work.chords.len();
    for (r, directions) in work.rows.iter().enumerate() {
        if kkt.rows.len() <= r {
            kkt.rows.push(vec![Vector3::zeros(); n]);
        }
        dense_row(&work.chords, directions, &mut kkt.rows[r]);
    }
    let contact = &mut kkt.contact;
    let mut used = 0;
    for nodes in &contact.curvature_nodes {
        for &k in nodes {
            for axis in 0..3 {
                if contact.curvature_columns.len() <= used {
                    contact.curvature_columns.push(vec![Vector3::zeros(); n]);
                }
                let directions = [(k, Vector3::ith(axis, 1.0)), (0, Vector3::zeros())];
                dense_row(
                    &work.chords,
                    &directions,
                    &mut contact.curvature_columns[used],
                );
                used += 1;
            }
        }
    }
    contact.curvature_columns.truncate(used);
    work.dense = true;
}

/// `D^T v` of a row with directions `v` at its nodes: `dr_k / dtheta_j` is
/// `F_j + E_(j+1)` below `k`, `F_k` at it.
fn dense_row(
    chords: &[(Matrix3<f64>, Matrix3<f64>)],
    directions: &[(usize, Vector3<f64>); 2],
    out: &mut [Vector3<f64>],
) {
    out.iter_mut().for_each(|x| *x = Vector3::zeros());
    for &(k, v) in directions.iter().filter(|(k, _)| *k > 0) {
        for j in 1..=k {
            out[j - 1] += chords[j - 1].1.transpose() * v;
            if j < k {
                out[j - 1] += chords[j].0.transpose() * v;
            }
        }
    }
}
