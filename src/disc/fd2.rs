//! The seed's finite differences (`Scheme::Fd2`, docs/model.md "The discrete
//! model"): one rotation a node, second order.
//!
//! Element `i` joins `a = q_{i-1}` and `b = q_i`; its curvature is `omega_i =
//! (2/h_i) vec(conj(a) b)` and its tangent the exact mean `T_i = (T(a) + T(a,
//! b) + T(b)) / 3` of the tangent of the linearly interpolated quaternion,
//! so `r_i = r_{i-1} + h_i T_i`. The potential of an element is
//! `h_i [W(omega_i) - Fbar_i . T_i - c . (R(a) + R(a, b) + R(b)) b_i / 3]`
//! (the elastic law and the curvature densities at the element's middle, the
//! internal force and the body-vector potentials by the tangent's rule); a
//! dead moment per length is lumped to the nodes by the trapezoid rule.
//!
//! The quadratic parts of the rule (`T(q_j)`, `R(q_j)`) are node terms; the
//! bilinear parts and the curvature are element terms: every element adds
//! to the rows of its two nodes and their coupling block.

use super::{derivatives_one_by_one, Discretisation, Interior, Loading, NodeForces, Rod, Scheme};
use crate::blocktri::BlockTridiagonal;
use crate::quat::{rotation_form_apply, skew, tangent_bilinear, tangent_form_apply, Quat};
use nalgebra::{Matrix3, Vector3};

/// The second-order scheme (it keeps nothing of the rod).
#[derive(Debug, Clone, Copy, Default)]
pub struct Fd2;

/// Elements per chunk of the parallel assembly (about 10 ms of work with the
/// Jacobian); a rod of one chunk, every ordinary one, is assembled in place.
const ASSEMBLY_CHUNK: usize = 1 << 16;

/// The terms of one element (see [`Source::element_terms`]).
struct ElementTerms {
    ga: Vector3<f64>,
    gb: Vector3<f64>,
    jaa: Matrix3<f64>,
    jbb: Matrix3<f64>,
    jab: Matrix3<f64>,
}

/// A chunk's diagonal, upper and lower blocks of the Jacobian.
type JacobianRows<'a> = (
    &'a mut [Matrix3<f64>],
    &'a mut [Matrix3<f64>],
    &'a mut [Matrix3<f64>],
);

fn jacobian_rows(j: &mut BlockTridiagonal) -> JacobianRows<'_> {
    (&mut j.diag[..], &mut j.upper[..], &mut j.lower[..])
}

/// One chunk of the parallel assembly: its elements `first..end`, its rows
/// of `g` and blocks of the Jacobian, and its first element's terms on the
/// row before the chunk.
struct Slab<'a> {
    first: usize,
    end: usize,
    g: &'a mut [Vector3<f64>],
    blocks: Option<JacobianRows<'a>>,
    boundary: (Vector3<f64>, Matrix3<f64>),
}

/// What the kernel integrates: the rod's loading at a load scale with the
/// held points' forces, or (`TANGENT`) a tangent of the rod's loading,
/// whose entries may be absent (zero) and whose elastic law is the
/// derivative of the rod's (`rod_stiffness`, `rod_rest`).
/// Its lists are kept as slices: the element loop reads them without
/// going through the loading (measured: 8 % of the kernel's time).
#[derive(Clone, Copy)]
struct Source<'a, const TANGENT: bool> {
    n: usize,
    h: &'a [f64],
    arcs: &'a [f64],
    stiffness: &'a [Vector3<f64>],
    rest: &'a [Vector3<f64>],
    mean_force: &'a [Vector3<f64>],
    distributed_moment: &'a [Vector3<f64>],
    rod_stiffness: &'a [Vector3<f64>],
    rod_rest: &'a [Vector3<f64>],
    loading: &'a Loading,
    load: f64,
    held: NodeForces<'a>,
    /// Whether the loading has an elastic law and an internal force: a
    /// tangent may have neither (a tension's), and then skips them.
    elastic: bool,
    forces: bool,
}

impl<'a, const TANGENT: bool> Source<'a, TANGENT> {
    /// `loading` (the rod's, or a tangent of it) on `rod` at load scale
    /// `load` with the forces `held`.
    fn new(rod: &'a Rod, loading: &'a Loading, load: f64, held: NodeForces<'a>) -> Self {
        Source {
            n: rod.n(),
            h: rod.mesh.element_lengths(),
            arcs: rod.mesh.arcs(),
            stiffness: &loading.stiffness,
            rest: &loading.rest_curvature,
            mean_force: &loading.mean_force,
            distributed_moment: &loading.distributed_moment,
            rod_stiffness: &rod.loading.stiffness,
            rod_rest: &rod.loading.rest_curvature,
            loading,
            load,
            held,
            elastic: !loading.stiffness.is_empty() || !loading.rest_curvature.is_empty(),
            forces: !loading.mean_force.is_empty() || !held.is_empty(),
        }
    }

    /// Whether anything of the loading acts on element `i` (always, but
    /// along a tangent of one term's parameter).
    #[inline(always)]
    fn acts_on(&self, i: usize) -> bool {
        let nonzero = |list: &[Vector3<f64>]| Self::entry(list, i) != Vector3::zeros();
        !TANGENT
            || (self.elastic && (nonzero(self.stiffness) || nonzero(self.rest)))
            || self.forces
            || !self.loading.body_loads.is_empty()
            || self.loading.densities.iter().any(|d| d.acts_on(i))
    }

    /// A stiffness of element `i` from a list of one a rod or one an element.
    #[inline(always)]
    fn stiffness_in(list: &[Vector3<f64>], i: usize) -> Vector3<f64> {
        match list.len() {
            1 => list[0],
            _ => list[i - 1],
        }
    }

    /// Element `i`'s entry of a per-element list: the rod's loading has
    /// every entry; a tangent only those it changes.
    #[inline(always)]
    fn entry(list: &[Vector3<f64>], i: usize) -> Vector3<f64> {
        match TANGENT {
            true => list.get(i - 1).copied().unwrap_or_else(Vector3::zeros),
            false => list[i - 1],
        }
    }

    /// The elastic moment of element `i` is `k (omega - rest) + shift`:
    /// the elastic law, or along a tangent `dK (omega - omega0) - K domega0`.
    #[inline(always)]
    fn elastic(&self, i: usize) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        match TANGENT {
            false => (
                Self::stiffness_in(self.stiffness, i),
                self.rest[i - 1],
                Vector3::zeros(),
            ),
            true => (
                Self::entry(self.stiffness, i),
                self.rod_rest[i - 1],
                -Self::stiffness_in(self.rod_stiffness, i)
                    .component_mul(&Self::entry(self.rest, i)),
            ),
        }
    }

    /// The internal force at the middle of element `i` (held points included).
    #[inline(always)]
    fn mean_force(&self, i: usize) -> Vector3<f64> {
        let mut f = self.load * Self::entry(self.mean_force, i);
        if !self.held.is_empty() {
            f += self.held.from_node(i);
        }
        f
    }

    /// The terms of element `i` on node `i - 1` (`gb`, `jbb`) and node `i -
    /// 2` (`ga`, `jaa`), and the coupling block `jab`.
    fn element_terms(&self, i: usize, q: &[Quat], with_jacobian: bool) -> ElementTerms {
        let ds = self.h[i - 1];
        let (k, rest, shift) = self.elastic(i);
        let (a, b) = (q[i - 1], q[i]);
        let c = a.conj() * b;
        let (c0, cv) = (c.w, c.v);
        let e = (2.0 / ds) * cv - rest;
        // Bending/twisting moment, body frame, and its derivative in the
        // curvature: the elastic law, plus the curvature densities (at the
        // element's middle).
        let mut w = k.component_mul(&e);
        if TANGENT {
            w += shift;
        }
        let mut density_stiffness = None;
        if !self.loading.densities.is_empty() {
            let omega = (2.0 / ds) * cv;
            let middle = 0.5 * (self.arcs[i - 1] + self.arcs[i]);
            if !with_jacobian {
                // A residual alone (a line search's trial) needs the moment alone.
                if let Some(moment) = self.loading.density_moment(i, middle, &omega, self.load) {
                    w += moment;
                }
            } else if let Some((_, moment, stiffness)) =
                self.loading.density(i, middle, &omega, self.load)
            {
                w += moment;
                density_stiffness = Some(stiffness);
            }
        }
        let amat = Matrix3::identity() * c0 + skew(&cv);
        let ga = -(amat * w);
        let gb = amat.transpose() * w;
        if TANGENT && !self.forces {
            // A tangent without forces (a tension's): its moment alone.
            return ElementTerms {
                ga,
                gb,
                jaa: Matrix3::zeros(),
                jbb: Matrix3::zeros(),
                jab: Matrix3::zeros(),
            };
        }
        // Load potential kappa * a^T S b with kappa = -ds/3 (F . T(a,b) term).
        let kappa = -ds / 3.0;
        let fbar = self.mean_force(i);
        let sb = tangent_form_apply(&fbar, b);
        let sa = tangent_form_apply(&fbar, a);
        let gax = 0.5 * kappa * (a.conj() * sb).v;
        let gbx = 0.5 * kappa * (b.conj() * sa).v;
        let mut terms = ElementTerms {
            ga: ga + gax,
            gb: gb + gbx,
            jaa: Matrix3::zeros(),
            jbb: Matrix3::zeros(),
            jab: Matrix3::zeros(),
        };
        if !with_jacobian {
            return terms;
        }
        // `K A` and `K A^T`: rows scaled for the elastic law's diagonal `K`
        // (the common element), products with a density's full stiffness.
        let scale_rows = |m: Matrix3<f64>| Matrix3::from_fn(|r, c| k[r] * m[(r, c)]);
        let (ka, kat) = match density_stiffness {
            None => (scale_rows(amat), scale_rows(amat.transpose())),
            Some(stiffness) => {
                let kmat = Matrix3::from_diagonal(&k) + stiffness;
                (kmat * amat, kmat * amat.transpose())
            }
        };
        let inv_ds = 1.0 / ds;
        let cw = cv.dot(&w);
        let psi = kappa * a.dot(sb);
        let radial = (-0.5 * cw - 0.25 * psi) * Matrix3::identity();
        terms.jbb = (amat.transpose() * ka) * inv_ds + radial + 0.5 * skew(&terms.gb);
        if i >= 2 {
            terms.jaa = (amat * kat) * inv_ds + radial + 0.5 * skew(&terms.ga);
            let mut jab = -(amat * ka) * inv_ds
                - 0.5
                    * (Matrix3::identity() * cw
                        - c0 * skew(&w)
                        - cv * w.transpose()
                        - w * cv.transpose());
            // 1/4 kappa G(a) S G(b)^T, column by column: G(b)^T e_k = b * (0, e_k).
            for (col, bek) in b.times_axes().into_iter().enumerate() {
                let v = (a.conj() * tangent_form_apply(&fbar, bek)).v;
                jab.set_column(col, &(jab.column(col) + 0.25 * kappa * v));
            }
            terms.jab = jab;
        }
        terms
    }

    /// A body-vector potential's terms of element `i` (world vector `field`
    /// at the load scale, body vector `m`): the bilinear part `kappa a^T S b`
    /// of `-c . R b` by the tangent's rule (the nodes' parts are node
    /// terms), entering as the dead loads' part does in `element_terms`.
    /// Apart from it so that the common element stays lean.
    #[inline(never)]
    fn body_terms(
        &self,
        i: usize,
        q: &[Quat],
        field: &Vector3<f64>,
        m: &Vector3<f64>,
        t: &mut ElementTerms,
        with_jacobian: bool,
    ) {
        let (a, b) = (q[i - 1], q[i]);
        let kappa = -self.h[i - 1] / 3.0;
        let (sa, sb) = (
            rotation_form_apply(field, m, a),
            rotation_form_apply(field, m, b),
        );
        let ga = 0.5 * kappa * (a.conj() * sb).v;
        let gb = 0.5 * kappa * (b.conj() * sa).v;
        t.ga += ga;
        t.gb += gb;
        if !with_jacobian {
            return;
        }
        let radial = (-0.25 * kappa * a.dot(sb)) * Matrix3::identity();
        t.jbb += radial + 0.5 * skew(&gb);
        if i >= 2 {
            t.jaa += radial + 0.5 * skew(&ga);
            for (col, bek) in b.times_axes().into_iter().enumerate() {
                let v = (a.conj() * rotation_form_apply(field, m, bek)).v;
                t.jab
                    .set_column(col, &(t.jab.column(col) + 0.25 * kappa * v));
            }
        }
    }

    /// The terms of the elements of one chunk into its rows.
    fn fill_slab(&self, slab: &mut Slab, q: &[Quat]) {
        let with_jacobian = slab.blocks.is_some();
        for i in slab.first..slab.end {
            // A huge n takes long here: an interrupt leaves the residual
            // unfinished, and the solver's loops stop on the same flag.
            if i % crate::interrupt::POLL_STRIDE == 0 && crate::interrupt::requested() {
                return;
            }
            let mut t = match self.acts_on(i) {
                true => self.element_terms(i, q, with_jacobian),
                false => ElementTerms {
                    ga: Vector3::zeros(),
                    gb: Vector3::zeros(),
                    jaa: Matrix3::zeros(),
                    jbb: Matrix3::zeros(),
                    jab: Matrix3::zeros(),
                },
            };
            for body in &self.loading.body_loads {
                let field = self.load * body.world;
                self.body_terms(i, q, &field, &body.body[i - 1], &mut t, with_jacobian);
            }
            let row = i - slab.first;
            if i >= 2 {
                if i == slab.first {
                    slab.boundary.0 = t.ga;
                } else {
                    slab.g[row - 1] += t.ga;
                }
            }
            // Row `i - 1`'s first term (its second comes from element i + 1).
            slab.g[row] = t.gb;
            if let Some((diag, upper, lower)) = slab.blocks.as_mut() {
                diag[row] = t.jbb;
                if i >= 2 {
                    if i == slab.first {
                        slab.boundary.1 = t.jaa;
                    } else {
                        diag[row - 1] += t.jaa;
                    }
                    let coupling = i - slab.first.max(2);
                    upper[coupling] = t.jab;
                    lower[coupling] = t.jab.transpose();
                }
            }
        }
    }

    /// Set `g` and `jac` to the sum of every element's terms (each row's
    /// first term is written, the second added: no clearing pass). A rod of
    /// one chunk, every ordinary one, is assembled in place without
    /// allocating. A longer rod is cut into chunks assembled on all cores: a
    /// chunk owns the rows of its elements' distal nodes, and the one term of
    /// its first element on the node before it is added after the join, in
    /// the order of the one-thread loop, so that the sum is the same to the
    /// last bit whatever the number of threads.
    fn assemble_elements(
        &self,
        q: &[Quat],
        g: &mut [Vector3<f64>],
        mut jac: Option<&mut BlockTridiagonal>,
        chunk: usize,
    ) {
        let n = self.n;
        if n <= chunk {
            let mut slab = Slab {
                first: 1,
                end: n + 1,
                g,
                blocks: jac.map(jacobian_rows),
                boundary: (Vector3::zeros(), Matrix3::zeros()),
            };
            self.fill_slab(&mut slab, q);
            return;
        }
        let boundaries: Vec<(usize, Vector3<f64>, Matrix3<f64>)> = {
            // Chunk c: elements [first, end), rows g[first - 1 .. end - 1],
            // coupling blocks [max(first, 2) - 2 .. end - 2].
            let mut slabs = Vec::with_capacity(n.div_ceil(chunk));
            let mut g_rest = &mut g[..];
            let mut jac_rest = jac.as_deref_mut().map(jacobian_rows);
            let mut first = 1;
            while first <= n {
                let end = (first + chunk).min(n + 1);
                let rows = end - first;
                let couplings = end.saturating_sub(first.max(2));
                let (g_own, g_next) = std::mem::take(&mut g_rest).split_at_mut(rows);
                g_rest = g_next;
                let blocks = jac_rest.take().map(|(diag, upper, lower)| {
                    let (d, d_next) = diag.split_at_mut(rows);
                    let (u, u_next) = upper.split_at_mut(couplings);
                    let (l, l_next) = lower.split_at_mut(couplings);
                    jac_rest = Some((d_next, u_next, l_next));
                    (d, u, l)
                });
                slabs.push(Slab {
                    first,
                    end,
                    g: g_own,
                    blocks,
                    boundary: (Vector3::zeros(), Matrix3::zeros()),
                });
                first = end;
            }
            use rayon::prelude::*;
            slabs
                .par_iter_mut()
                .for_each(|slab| self.fill_slab(slab, q));
            slabs
                .iter()
                .skip(1)
                .map(|s| (s.first, s.boundary.0, s.boundary.1))
                .collect()
        };
        // The first element of a chunk on the last row of the chunk before,
        // added after that row's own term as in the one-thread loop.
        for (first, ga, jaa) in boundaries {
            g[first - 2] += ga;
            if let Some(j) = jac.as_deref_mut() {
                j.diag[first - 2] += jaa;
            }
        }
    }

    /// The whole residual: elements, then the nodes' quadratic parts of
    /// the tangent's rule and the lumped moments, then the node terms.
    fn assemble(
        &self,
        q: &[Quat],
        g: &mut [Vector3<f64>],
        mut jac: Option<&mut BlockTridiagonal>,
        chunk: usize,
    ) {
        let (loading, load, h_of) = (self.loading, self.load, self.h);
        let n = self.n;
        debug_assert_eq!(q.len(), n + 1);
        debug_assert_eq!(g.len(), n);
        // They write every entry of `g` and `jac`: no clearing pass.
        self.assemble_elements(q, g, jac.as_deref_mut(), chunk);
        let moments = !self.distributed_moment.is_empty();
        // The internal force's node weights `h_j Fbar_j + h_{j+1} Fbar_{j+1}`,
        // each element's term computed once, the load scale applied to their
        // sum (the held points' forces are not scaled).
        let weighted = |i: usize| h_of[i - 1] * Self::entry(self.mean_force, i);
        let held = |i: usize| h_of[i - 1] * self.held.from_node(i);
        let forces = !TANGENT || self.forces;
        let mut next = match forces {
            true => weighted(1),
            false => Vector3::zeros(),
        };
        for j in 1..=n {
            if forces {
                let this = next;
                next = match j < n {
                    true => weighted(j + 1),
                    false => Vector3::zeros(),
                };
                let mut weight = load * (this + next);
                if !self.held.is_empty() {
                    weight += held(j);
                    if j < n {
                        weight += held(j + 1);
                    }
                }
                let h = (-1.0 / 3.0) * weight;
                let f = q[j].inverse_rotate(h);
                g[j - 1] += Vector3::new(-f.y, f.x, 0.0);
                if let Some(jac) = jac.as_deref_mut() {
                    jac.diag[j - 1] += f * Vector3::z().transpose() - f.z * Matrix3::identity();
                }
            }
            // The body-vector potentials of the elements that meet here.
            for body in &loading.body_loads {
                for e in (j..=j + 1).filter(|e| *e <= n) {
                    let c = (-h_of[e - 1] / 3.0) * load * body.world;
                    let (_, grad, block) =
                        crate::quat::body_vector_terms(q[j], &c, &body.body[e - 1]);
                    g[j - 1] += grad;
                    if let Some(jac) = jac.as_deref_mut() {
                        jac.diag[j - 1] += block;
                    }
                }
            }
            // A distributed dead moment, by the trapezoid rule.
            if moments {
                let mut moment = 0.5 * h_of[j - 1] * Self::entry(self.distributed_moment, j);
                if j < n {
                    moment += 0.5 * h_of[j] * Self::entry(self.distributed_moment, j + 1);
                }
                let (grad, block) = super::dead_moment(q[j], &(load * moment));
                g[j - 1] += grad;
                if let Some(jac) = jac.as_deref_mut() {
                    jac.diag[j - 1] += block;
                }
            }
        }
        loading.add_node_terms(q, load, g, jac);
    }
}

/// `dg` along tangents of the elastic law or of curvature densities (a
/// section's rest curvature, a tension), one column of `n` each: the
/// moment's derivative on the elements each moves, `dK (omega - omega0) -
/// K domega0 + dW/domega`, the rest of the assembly skipped. Where the
/// columns overlap (a drive's tensions share most elements) each element's
/// relative rotation is formed once for all of them; where they lie apart
/// (the sections' curvatures) each column walks its own elements. The same
/// numbers either way.
fn moment_columns(rod: &Rod, q: &[Quat], tangents: &[Loading], dg: &mut [Vector3<f64>]) {
    let n = rod.n();
    dg.iter_mut().for_each(|x| *x = Vector3::zeros());
    let walked: usize = tangents
        .iter()
        .map(|t| 1 + t.elements(n).1 - t.elements(n).0)
        .sum();
    if walked <= 2 * n {
        for (tangent, column) in tangents.iter().zip(dg.chunks_exact_mut(n)) {
            add_moment_columns(rod, q, std::slice::from_ref(tangent), column);
        }
    } else {
        add_moment_columns(rod, q, tangents, dg);
    }
}

/// [`moment_columns`] added to `dg`, element after element over the
/// tangents' supports.
fn add_moment_columns(rod: &Rod, q: &[Quat], tangents: &[Loading], dg: &mut [Vector3<f64>]) {
    let n = rod.n();
    let entry = Source::<true>::entry;
    let supports = tangents.iter().map(|t| t.elements(n));
    let first = supports.clone().map(|s| s.0).min().unwrap_or(1);
    let last = supports.map(|s| s.1).max().unwrap_or(0);
    for i in first..=last {
        let h = rod.h(i);
        let c = q[i - 1].conj() * q[i];
        let omega = (2.0 / h) * c.v;
        let middle = 0.5 * (rod.arc(i - 1) + rod.arc(i));
        let amat = Matrix3::identity() * c.w + skew(&c.v);
        for (tangent, column) in tangents.iter().zip(dg.chunks_exact_mut(n)) {
            let (lo, hi) = tangent.elements(n);
            if i < lo || i > hi {
                continue;
            }
            // A tension's column has no elastic part: skipped, not formed as
            // zero (the same moment, to the last bit).
            let elastic = (!tangent.stiffness.is_empty() || !tangent.rest_curvature.is_empty())
                .then(|| {
                    let (dk, drest) = (
                        entry(&tangent.stiffness, i),
                        entry(&tangent.rest_curvature, i),
                    );
                    (dk != Vector3::zeros() || drest != Vector3::zeros()).then(|| {
                        dk.component_mul(&(omega - rod.loading.rest_of(i)))
                            - rod.loading.stiffness_of(i).component_mul(&drest)
                    })
                })
                .flatten();
            // None where no density acts on the element (a tendon short of it).
            let density = tangent.density_moment(i, middle, &omega, 1.0);
            let moment = match (elastic, density) {
                (None, None) => continue,
                (Some(m), None) | (None, Some(m)) => m,
                (Some(e), Some(m)) => e + m,
            };
            column[i - 1] += amat.transpose() * moment;
            if i >= 2 {
                column[i - 2] -= amat * moment;
            }
        }
    }
}

impl Discretisation for Fd2 {
    fn scheme(&self) -> Scheme {
        Scheme::Fd2
    }

    fn boxed(&self) -> Box<dyn Discretisation> {
        Box::new(*self)
    }

    fn prepare(&mut self, _rod: &Rod) {}

    fn evaluate(
        &self,
        rod: &Rod,
        q: &[Quat],
        load: f64,
        held: NodeForces,
        _interior: &mut Interior,
        g: &mut [Vector3<f64>],
        jac: Option<&mut BlockTridiagonal>,
    ) {
        let source = Source::<false>::new(rod, &rod.loading, load, held);
        source.assemble(q, g, jac, ASSEMBLY_CHUNK);
    }

    fn residual_derivative(
        &self,
        rod: &Rod,
        q: &[Quat],
        _held: NodeForces,
        tangent: &Loading,
        _interior: &mut Interior,
        dg: &mut [Vector3<f64>],
        interior_shift: &mut Vec<Vector3<f64>>,
    ) {
        interior_shift.clear();
        if tangent.only_moments() {
            moment_columns(rod, q, std::slice::from_ref(tangent), dg);
            return;
        }
        let source = Source::<true>::new(rod, tangent, 1.0, NodeForces::NONE);
        source.assemble(q, dg, None, ASSEMBLY_CHUNK);
    }

    fn residual_derivatives(
        &self,
        rod: &Rod,
        q: &[Quat],
        held: NodeForces,
        tangents: &[Loading],
        interior: &mut Interior,
        dg: &mut [Vector3<f64>],
        interior_shift: &mut Vec<Vector3<f64>>,
    ) {
        if tangents.iter().all(Loading::only_moments) {
            interior_shift.clear();
            moment_columns(rod, q, tangents, dg);
        } else {
            derivatives_one_by_one(self, rod, q, held, tangents, interior, dg, interior_shift);
        }
    }

    fn positions(&self, rod: &Rod, q: &[Quat], _interior: &mut Interior, out: &mut [Vector3<f64>]) {
        out[0] = rod.base_position;
        for i in 1..=rod.n() {
            out[i] = out[i - 1] + rod.h(i) * mean_tangent(q[i - 1], q[i]);
        }
    }

    fn unloaded_positions(&self, rod: &Rod, q: &[Quat], out: &mut [Vector3<f64>]) {
        self.positions(rod, q, &mut Interior::none(), out);
    }

    fn energy(&self, rod: &Rod, q: &[Quat], load: f64, _interior: &mut Interior) -> f64 {
        let loading = &rod.loading;
        let mut total = loading.node_energy(q, load);
        for i in 1..=rod.n() {
            let (a, b) = (q[i - 1], q[i]);
            let (cv, h) = ((a.conj() * b).v, rod.h(i));
            let e = (2.0 / h) * cv - loading.rest_of(i);
            let mut elastic = 0.5 * e.dot(&loading.stiffness_of(i).component_mul(&e));
            if !loading.densities.is_empty() {
                let omega = (2.0 / h) * cv;
                let middle = 0.5 * (rod.arc(i - 1) + rod.arc(i));
                if let Some(value) = loading.density_value(i, middle, &omega, load) {
                    elastic += value;
                }
            }
            let mut work = load * loading.mean_force_of(i).dot(&mean_tangent(a, b));
            for body in &loading.body_loads {
                // c . (R(a) m + R(a, b) m + R(b) m) / 3, the tangent's rule.
                let field = load * body.world;
                let form = |x: Quat| rotation_form_apply(&field, &body.body[i - 1], x);
                work += (a.dot(form(a)) + a.dot(form(b)) + b.dot(form(b))) / 3.0;
            }
            total += h * (elastic - work);
        }
        total
    }

    fn rest_shape(&self, rod: &Rod) -> Vec<Quat> {
        let n = rod.n();
        let mut q = Vec::with_capacity(n + 1);
        q.push(rod.base);
        for i in 1..=n {
            let v = 0.5 * rod.h(i) * rod.loading.rest_of(i);
            // Beyond ds |kappa0| = 2 no element reaches its rest curvature (the
            // solve reports it underresolved); the nearest is a half turn.
            let w = (1.0 - v.norm_squared()).max(0.0).sqrt();
            q.push((q[i - 1] * Quat::new(w, v.x, v.y, v.z)).normalized());
        }
        q
    }

    fn position_jacobian(
        &self,
        rod: &Rod,
        q: &[Quat],
        k: usize,
        _interior: &Interior,
        out: &mut [Matrix3<f64>],
    ) {
        // r_k is the sum of the chords up to k: node j moves its two
        // elements' chords, the second only inside [1, k]. Each chord's
        // blocks once (the end node's first, as the sum always was).
        for block in out.iter_mut().take(rod.n()).skip(k) {
            *block = Matrix3::zeros();
        }
        for i in 1..=k {
            let (start, end) = chord_jacobian(rod, q, i);
            out[i - 1] = end;
            if i >= 2 {
                out[i - 2] += start;
            }
        }
    }

    fn chord_jacobians(
        &self,
        rod: &Rod,
        q: &[Quat],
        out: &mut [(Matrix3<f64>, Matrix3<f64>)],
    ) -> bool {
        for (i, blocks) in out.iter_mut().enumerate() {
            *blocks = chord_jacobian(rod, q, i + 1);
        }
        true
    }
}

/// `d (r_i - r_(i-1)) / d theta` of element `i`'s chord `h_i mean_tangent(q_(i-1),
/// q_i)`: the blocks of its start node and its end node. Row c is the gradient
/// of `e_c . chord`: `T(q)` counts `h_i / 3` at each node, the bilinear term
/// `h_i / 3` shared between them.
#[inline(always)]
pub(crate) fn chord_jacobian(rod: &Rod, q: &[Quat], i: usize) -> (Matrix3<f64>, Matrix3<f64>) {
    let third = rod.h(i) / 3.0;
    (
        chord_block(q[i - 1], q[i], third),
        chord_block(q[i], q[i - 1], third),
    )
}

/// One node's block of [`chord_jacobian`], `at` the node and `other` the
/// element's other node. Row c is `third (-f_y, f_x, 0) + (third / 2) (at^*
/// S_(e_c) other)_v` with `f = R(at)^T e_c`, row c of `R(at)`. Spelt out per
/// axis because this runs for every chord at every contact step: `S_(e_c)
/// other` is a signed permutation of `other` ([`tangent_form_apply`] with a
/// unit axis), and only the first two columns of `R(at)` are needed.
#[inline(always)]
fn chord_block(at: Quat, other: Quat, third: f64) -> Matrix3<f64> {
    let (w, x, y, z) = (at.w, at.v.x, at.v.y, at.v.z);
    // Columns 0 and 1 of R(at): entry c of each is f_x, f_y of row c.
    let first = Vector3::new(
        w * w + x * x - y * y - z * z,
        2.0 * (x * y + w * z),
        2.0 * (x * z - w * y),
    );
    let second = Vector3::new(
        2.0 * (x * y - w * z),
        w * w - x * x + y * y - z * z,
        2.0 * (y * z + w * x),
    );
    let (ow, ox, oy, oz) = (other.w, other.v.x, other.v.y, other.v.z);
    let forms = [
        (oy, Vector3::new(oz, ow, ox)),
        (-ox, Vector3::new(-ow, oz, oy)),
        (ow, Vector3::new(-ox, -oy, oz)),
    ];
    let half = 0.5 * third;
    let mut block = Matrix3::zeros();
    for (c, (sw, sv)) in forms.into_iter().enumerate() {
        // The vector part of at^* (sw, sv).
        let turned = w * sv - sw * at.v - at.v.cross(&sv);
        block[(c, 0)] = -third * second[c] + half * turned.x;
        block[(c, 1)] = third * first[c] + half * turned.y;
        block[(c, 2)] = half * turned.z;
    }
    block
}

/// The block of [`chord_jacobian`] as the formula reads, axis by axis: the
/// reference its spelt-out form is tested against.
#[cfg(test)]
fn chord_block_as_written(at: Quat, other: Quat, third: f64) -> Matrix3<f64> {
    let mut block = Matrix3::zeros();
    for c in 0..3 {
        let e = Vector3::ith(c, 1.0);
        let f = at.inverse_rotate(e);
        let row = third * Vector3::new(-f.y, f.x, 0.0)
            + (0.5 * third) * (at.conj() * tangent_form_apply(&e, other)).v;
        block.set_row(c, &row.transpose());
    }
    block
}

/// Mean tangent of an element: the exact mean of `T` under linear interpolation of `q`.
pub fn mean_tangent(a: Quat, b: Quat) -> Vector3<f64> {
    (a.tangent() + tangent_bilinear(a, b) + b.tangent()) / 3.0
}

/// [`Fd2`]'s residual and Jacobian assembled in chunks of `chunk` elements
/// (the parallel assembly's unit), for the test that it is the one-thread sum.
#[cfg(test)]
pub(crate) fn evaluate_in_chunks(
    rod: &Rod,
    q: &[Quat],
    load: f64,
    held: NodeForces,
    g: &mut [Vector3<f64>],
    jac: Option<&mut BlockTridiagonal>,
    chunk: usize,
) {
    let source = Source::<false>::new(rod, &rod.loading, load, held);
    source.assemble(q, g, jac, chunk);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The spelt-out chord block is the formula's, to round-off of the
    /// rotation's entries, at unit quaternions of every kind of turn.
    #[test]
    fn the_spelt_out_chord_block_is_the_formulas() {
        let mut at = Quat::IDENTITY;
        let mut other = Quat::new(0.5, -0.5, 0.5, 0.5);
        for k in 0..200 {
            let t = k as f64;
            at = at.perturbed(Vector3::new(0.7 * t.sin(), 0.3 + 0.2 * t.cos(), -0.4));
            other = other.perturbed(Vector3::new(-0.2, 0.5 * (1.3 * t).cos(), 0.9 * t.sin()));
            let third = 0.01 + 0.001 * t;
            let fast = chord_block(at, other, third);
            let slow = chord_block_as_written(at, other, third);
            assert!(
                (fast - slow).amax() <= 8.0 * f64::EPSILON * third,
                "{k}: {fast} against {slow}"
            );
        }
    }
}
