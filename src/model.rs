//! The discrete equations of docs/model.md: residual (body-frame torque balance per
//! node), its analytic Jacobian (block-tridiagonal), positions and energy.
//!
//! Unknowns are the node quaternions `q_1..q_n` (`q_0` is the clamped base).
//! A node is moved by the body-frame update `q_j <- q_j * exp(theta_j / 2)`, which
//! keeps `|q_j| = 1` exactly; the residual of node `j` is `dPi/dtheta_j` (plus the
//! tip moment at node `n`) and the Jacobian is its derivative under the same
//! update, so it is exact and can be checked by finite differences.
//!
//! Every load and the rest curvature are scaled by `lambda`, the load
//! continuation parameter: `lambda = 0` is the unloaded rod in its rest shape
//! (a chain of arcs, exact), so that continuation follows the loading of the
//! rod from rest, as an experiment would; the rest curvature is not scaled.
//! equilibrium is exact, and `lambda = 1` is the scene.

use crate::blocktri::BlockTridiagonal;
use crate::fe4;
use crate::mesh::Mesh;
use crate::quat::{
    body_vector_terms, rotation_form_apply, skew, tangent_bilinear, tangent_form_apply, Quat,
};
pub use crate::scene::reach::clamped_end_deficit;
use crate::scene::{Scene, TipCondition};
use nalgebra::{Matrix3, Vector3};

/// Elements per chunk of the parallel assembly (about 10 ms of work with the
/// Jacobian); a rod of one chunk, every ordinary one, is assembled in place.
const ASSEMBLY_CHUNK: usize = 1 << 16;

/// The terms of one element (see `RodModel::element_terms`).
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

/// A node held at a position (a pinned tip or a guide). Its reaction force is
/// an unknown that acts on the rod like a point force at the node.
#[derive(Debug, Clone, PartialEq)]
pub struct PointConstraint {
    pub node: usize,
    /// Prescribed position [m].
    pub target: Vector3<f64>,
    /// Where the unloaded rest shape puts the node: the start of the load path.
    pub rest: Vector3<f64>,
}

impl PointConstraint {
    /// The target at load scale `lambda`, moved linearly from the rest shape.
    /// Both ends are within reach, and so is every point between (convexity).
    pub fn target_at(&self, lambda: f64) -> Vector3<f64> {
        self.rest + lambda * (self.target - self.rest)
    }
}

/// The discretisation of the backbone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scheme {
    /// The seed's finite differences: one rotation a node, the curvature of
    /// each element from its two nodes, the exact mean tangent. Second order.
    #[default]
    Fd2,
    /// Quadratic elements of the rotation (an internal node at each element's
    /// middle, condensed out), the elastic energy by two-point Gauss
    /// quadrature and the loads by Simpson: fourth order at the nodes (see
    /// `fe4.rs`).
    Fe4,
}

impl Scheme {
    /// The name [`Scheme::from_str`](std::str::FromStr) reads.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Fd2 => "fd2",
            Scheme::Fe4 => "fe4",
        }
    }

    /// The order of convergence of the node positions as `n` grows.
    pub fn order(self) -> i32 {
        match self {
            Scheme::Fd2 => 2,
            Scheme::Fe4 => 4,
        }
    }
}

impl std::str::FromStr for Scheme {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        match s {
            "fd2" => Ok(Scheme::Fd2),
            "fe4" => Ok(Scheme::Fe4),
            other => Err(crate::error::Error::argument(
                "scheme",
                format!("unknown scheme '{other}' (expected 'fd2' or 'fe4')"),
            )),
        }
    }
}

/// A scene discretised by `n` elements (see [`Mesh`]: equal within a section).
#[derive(Debug, Clone)]
pub struct RodModel {
    pub n: usize,
    /// The discretisation (set by [`RodModel::with_scheme`]).
    pub scheme: Scheme,
    /// Distributed dead force [N/m], world frame (gravity included).
    pub distributed_force: Vector3<f64>,
    /// The unloaded rest shape (see [`RodModel::rest_shape`]).
    rest_nodes: Vec<Quat>,
    /// Fourth-order scheme: the internal nodes of the last evaluation.
    mids: fe4::MidCache,
    pub length: f64,
    /// The mean element length `L / n` [m]: every element's unless the
    /// sections have lengths of their own (see [`RodModel::h`]).
    pub ds: f64,
    /// Where the nodes sit.
    mesh: Mesh,
    /// Diagonal stiffness `(kx, ky, kz)` [N m^2]; with per-section
    /// stiffness, the softest section's in each component (it sets the
    /// residual's scale).
    pub stiffness: Vector3<f64>,
    /// Per-section stiffness, element `i` at index `i - 1`; empty: `stiffness`.
    element_stiffness: Vec<Vector3<f64>>,
    /// Per-section distributed force [N/m], element `i` at index `i - 1`;
    /// empty: `distributed_force`.
    element_force: Vec<Vector3<f64>>,
    pub base: Quat,
    /// Position of node 0 [m], world frame.
    pub base_position: Vector3<f64>,
    /// Rest curvature of element `i` (index `i - 1`), material frame [1/m].
    pub rest_curvature: Vec<Vector3<f64>>,
    /// Magnetisation of element `i` (index `i - 1`), material frame
    /// [A m^2 / m]; empty without a field or magnetisation.
    magnetization: Vec<Vector3<f64>>,
    /// The tip magnet's dipole moment, material frame [A m^2].
    tip_magnet: Vector3<f64>,
    /// Uniform external field, world frame [T].
    magnetic_field: Vector3<f64>,
    /// The tip force and where it acts from the tip (material frame): its
    /// potential `-F . R(q_n) c` beyond the tip's own `-F . r_n`.
    tip_force_at: (Vector3<f64>, Vector3<f64>),
    /// Tendons, longest first (an element's tendons are a prefix).
    tendons: Vec<crate::scene::Tendon>,
    /// The scene's index of each of `tendons`.
    tendon_order: Vec<usize>,
    /// The moment scale of the loads other than the tendons and the field
    /// [N m], and the magnets' moment per tesla [N m / T]: with the
    /// tensions and the field, [`RodModel::load_parameter`].
    other_moment: f64,
    magnet_moment: f64,
    /// How many tendons (a prefix of `tendons`) run through element `i`
    /// (index `i - 1`).
    tendons_through: Vec<usize>,
    /// Fourth-order scheme: the rest curvature each element is given at its
    /// Gauss points (`fe4::gauss_rest_curvature`; empty with `fd2`).
    gauss_rest: Vec<Vector3<f64>>,
    /// Mean internal force `Fbar_i` of element `i` (index `i - 1`), world frame [N].
    pub mean_force: Vec<Vector3<f64>>,
    /// `h_j Fbar_j + h_{j+1} Fbar_{j+1}` of node `j` (index `j - 1`), the
    /// weight of `T(q_j)` [N m].
    node_force_weight: Vec<Vector3<f64>>,
    /// Internal force `F_j` at node `j = 0..n`, world frame [N].
    pub node_force: Vec<Vector3<f64>>,
    pub tip_moment: Vector3<f64>,
    /// Held nodes, by increasing node (guides, then a pinned or clamped tip).
    pub constraints: Vec<PointConstraint>,
    /// Orientation of a clamped tip, on the rest tip's side of the quaternion sphere.
    pub clamped_tip: Option<Quat>,
    /// Tip orientation of the unloaded rest shape.
    pub rest_tip: Quat,
    /// Moment scale of each body-frame torque row, `k_c / L` [N m]: a residual
    /// row over its own stiffness is the angle-like error that row leaves, so
    /// a stiffness ratio of 1e10 neither hides a soft row's imbalance nor
    /// demands round-off from a stiff one.
    pub residual_scale: Vector3<f64>,
    /// The second leg of a held scene's load path (see `solver::load_path`):
    /// the loads stay at full scale and `lambda` moves only the held points
    /// and a clamped tip's orientation, from where the loaded free rod put them.
    pub loads_held_fixed: bool,
    /// Largest bending moment the applied loads can exert, times `L` over the
    /// smallest stiffness (dimensionless): the curvature scale `kappa L` of
    /// the loaded rod, which sets the round-off floor of the residual.
    pub load_parameter: f64,
}

impl RodModel {
    /// Discretise `scene` with `n` elements (validated by the caller: `n` is a
    /// positive multiple of the number of sections).
    pub fn new(scene: &Scene, n: usize) -> Self {
        let length = scene.length;
        let ds = length / n as f64;
        let mesh = scene.mesh(n);
        let h = |i: usize| mesh.element_lengths()[i - 1];
        let sections = scene.rest_curvature.len().max(1);
        let rest_curvature = (0..n)
            .map(
                |i| match scene.rest_curvature.get(section_of(i, sections, n)) {
                    Some(k) => Vector3::new(k[0], k[1], 0.0),
                    None => Vector3::zeros(),
                },
            )
            .collect();
        let f = scene.distributed_force();
        let sections = scene.sections();
        // Each element's value of a section property (none without sections).
        let per_element = |of: &dyn Fn(usize) -> Vector3<f64>| -> Vec<Vector3<f64>> {
            match scene.sections.is_empty() {
                true => Vec::new(),
                false => (0..n).map(|i| of(section_of(i, sections, n))).collect(),
            }
        };
        let element_stiffness = per_element(&|s| scene.section_stiffness(s));
        let element_force = per_element(&|s| scene.section_force(s));
        let force_of = |i: usize| element_force.get(i - 1).copied().unwrap_or(f);
        let largest_force = element_force
            .iter()
            .map(|x| x.norm())
            .fold(f.norm(), f64::max);
        // The distributed force beyond node j: sum over the elements past it.
        let mut beyond = vec![Vector3::zeros(); n + 1];
        for j in (0..n).rev() {
            beyond[j] = beyond[j + 1] + force_of(j + 1) * h(j + 1);
        }
        // Point loads by node: a load at node k acts on every element i <= k.
        let point_loads: Vec<(usize, Vector3<f64>)> = scene
            .point_loads
            .iter()
            .map(|p| (mesh.nearest_node(p.s), p.force))
            .collect();
        let point_loads_from = |node: usize, strictly_distal: bool| -> Vector3<f64> {
            point_loads
                .iter()
                .filter(|(k, _)| {
                    if strictly_distal {
                        *k > node || *k == n
                    } else {
                        *k >= node
                    }
                })
                .map(|(_, q)| *q)
                .sum()
        };
        let node_force: Vec<Vector3<f64>> = (0..=n)
            .map(|j| scene.tip_force + beyond[j] + point_loads_from(j, true))
            .collect();
        let mean_force: Vec<Vector3<f64>> = (1..=n)
            .map(|i| {
                let to_mid = beyond[i] + force_of(i) * (0.5 * h(i));
                scene.tip_force + to_mid + point_loads_from(i, false)
            })
            .collect();
        let node_force_weight = (1..=n)
            .map(|j| {
                let next = match j < n {
                    true => h(j + 1) * mean_force[j],
                    false => Vector3::zeros(),
                };
                h(j) * mean_force[j - 1] + next
            })
            .collect();
        let stiffness = scene.stiffness();
        let magnetized =
            scene.magnetic_field != Vector3::zeros() && !scene.magnetization.is_empty();
        let magnetization = if magnetized {
            let k = scene.magnetization.len();
            (0..n)
                .map(|i| scene.magnetization[section_of(i, k, n)])
                .collect()
        } else {
            Vec::new()
        };
        // Longest first (a stable sort: equal ends keep the scene's order).
        let mut tendon_order: Vec<usize> = (0..scene.tendons.len()).collect();
        tendon_order.sort_by(|a, b| scene.tendons[*b].end.total_cmp(&scene.tendons[*a].end));
        let tendons: Vec<crate::scene::Tendon> = tendon_order
            .iter()
            .map(|i| scene.tendons[*i].clone())
            .collect();
        let last_element = |t: &crate::scene::Tendon| mesh.nearest_node(t.end);
        let tendons_through = (1..=n)
            .map(|i| tendons.iter().take_while(|t| last_element(t) >= i).count())
            .collect();
        let base = scene.base_quaternion;
        let mut constraints: Vec<PointConstraint> = scene
            .guides
            .iter()
            .map(|g| {
                let node = mesh.nearest_node(g.s);
                PointConstraint {
                    node,
                    target: g.position,
                    rest: Vector3::zeros(),
                }
            })
            .collect();
        let (tip_target, clamped_tip) = match &scene.tip {
            TipCondition::Free => (None, None),
            TipCondition::Pinned { position } => (Some(*position), None),
            TipCondition::Clamped {
                position,
                quaternion,
            } => (Some(*position), Some(*quaternion)),
        };
        if let Some(target) = tip_target {
            constraints.push(PointConstraint {
                node: n,
                target,
                rest: Vector3::zeros(),
            });
        }
        let mut model = RodModel {
            n,
            scheme: Scheme::Fd2,
            distributed_force: f,
            rest_nodes: Vec::new(),
            mids: fe4::MidCache::default(),
            length,
            ds,
            mesh,
            stiffness,
            element_stiffness,
            element_force,
            base: scene.base_quaternion,
            base_position: scene.base_position,
            rest_curvature,
            magnetization,
            tip_magnet: scene.tip_magnet,
            magnetic_field: scene.magnetic_field,
            tip_force_at: (scene.tip_force, scene.tip_force_offset),
            tendons,
            tendon_order,
            tendons_through,
            gauss_rest: Vec::new(),
            mean_force,
            node_force_weight,
            node_force,
            tip_moment: scene.tip_moment,
            constraints,
            clamped_tip,
            rest_tip: base,
            residual_scale: stiffness / length,
            loads_held_fixed: false,
            load_parameter: 0.0,
            other_moment: 0.0,
            magnet_moment: 0.0,
        };
        let point_moment: f64 = scene.point_loads.iter().map(|p| p.force.norm() * p.s).sum();
        model.magnet_moment = scene.tip_magnet.norm()
            + length
                * scene
                    .magnetization
                    .iter()
                    .map(|m| m.norm())
                    .fold(0.0, f64::max);
        model.other_moment = scene.tip_moment.norm()
            + scene.tip_force.norm() * scene.tip_force_offset.norm()
            + length * scene.tip_force.norm()
            + 0.5 * length * length * largest_force
            + point_moment;
        model.refresh_load_parameter();
        model.refresh_rest();
        model
    }

    /// `load_parameter` from the loads' moments, the tensions and the field.
    fn refresh_load_parameter(&mut self) {
        let tendon_moment: f64 = self
            .tendons
            .iter()
            .map(|t| t.tension * t.largest_offset())
            .sum();
        let moment =
            self.other_moment + self.magnetic_field.norm() * self.magnet_moment + tendon_moment;
        self.load_parameter = moment * self.length / self.stiffness.min();
    }

    /// How much stiffer than the residual's scale ([`RodModel::residual_scale`],
    /// the softest section's stiffness) any element is about the same axis:
    /// at least 1. A row's round-off is that of the elastic moments meeting
    /// there, so a section 100 times stiffer than the scale rounds 100 times
    /// larger relative to it.
    fn stiffness_spread(&self) -> f64 {
        self.element_stiffness
            .iter()
            .map(|k| k.component_div(&self.stiffness).max())
            .fold(1.0, f64::max)
    }

    /// Set the tendons' tensions in place, in the scene's order (checked by
    /// the caller): nothing else of the discretisation depends on them.
    pub(crate) fn set_tensions(&mut self, tensions: &[f64]) {
        assert_eq!(tensions.len(), self.tendons.len(), "one tension a tendon");
        for (t, i) in self.tendons.iter_mut().zip(&self.tendon_order) {
            t.tension = tensions[*i];
        }
        self.drives_changed();
    }

    /// After new drives: the load parameter, and the fourth-order scheme's
    /// internal nodes (which belonged to the old ones) forgotten.
    fn drives_changed(&mut self) {
        self.refresh_load_parameter();
        if self.scheme == Scheme::Fe4 {
            self.mids = fe4::MidCache::new(self.n);
        }
    }

    /// Set the field in place where the discretisation keeps its shape
    /// (the magnetised elements are kept only under a field); false when the
    /// model must be rebuilt for it.
    pub(crate) fn set_magnetic_field(&mut self, field: Vector3<f64>, magnetized: bool) -> bool {
        let kept = !self.magnetization.is_empty();
        if magnetized && kept != (field != Vector3::zeros()) {
            return false;
        }
        self.magnetic_field = field;
        self.drives_changed();
        true
    }

    /// Fourth-order scheme: whether every internal node of the last
    /// evaluation with the Jacobian is a minimum of its element's potential
    /// (the condensed Hessian then decides stability); true for `fd2`.
    pub fn internal_nodes_at_minima(&self) -> bool {
        self.scheme != Scheme::Fe4 || self.mids.all_minima()
    }

    /// The same rod in another discretisation.
    pub fn with_scheme(mut self, scheme: Scheme) -> Self {
        if scheme != self.scheme {
            self.scheme = scheme;
            self.mids = fe4::MidCache::new(self.n);
            self.refresh_rest();
        }
        self
    }

    /// Length of element `i` (from 1) [m].
    #[inline(always)]
    pub fn h(&self, i: usize) -> f64 {
        self.mesh.element_lengths()[i - 1]
    }

    /// Arc length of node `i` [m].
    #[inline(always)]
    pub fn arc(&self, i: usize) -> f64 {
        self.mesh.arcs()[i]
    }

    /// Arc length of the middle of element `i` [m].
    #[inline(always)]
    fn mid_arc(&self, i: usize) -> f64 {
        0.5 * (self.arc(i - 1) + self.arc(i))
    }

    /// Where the nodes sit.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Stiffness of element `i`.
    #[inline]
    fn stiffness_of(&self, i: usize) -> Vector3<f64> {
        self.element_stiffness
            .get(i - 1)
            .copied()
            .unwrap_or(self.stiffness)
    }

    /// Distributed force on element `i` (unscaled).
    #[inline]
    fn force_of(&self, i: usize) -> Vector3<f64> {
        self.element_force
            .get(i - 1)
            .copied()
            .unwrap_or(self.distributed_force)
    }

    /// The tendons that run through element `i` (from 1).
    #[inline(always)]
    fn element_tendons(&self, i: usize) -> &[crate::scene::Tendon] {
        if self.tendons.is_empty() {
            return &[];
        }
        &self.tendons[..self.tendons_through[i - 1]]
    }

    /// Element `i`'s data for the fourth-order scheme at load scale `load`.
    /// The reactions of held points act on it as point forces beyond it.
    fn fe4_element(&self, i: usize, load: f64, reactions: &[Vector3<f64>]) -> fe4::Element<'_> {
        // The internal force changes by the distributed force along the element.
        let h = self.h(i);
        let half = load * self.force_of(i) * (0.5 * h);
        let mut mean = load * self.mean_force[i - 1];
        if !reactions.is_empty() {
            mean += self.reactions_from(reactions, i);
        }
        fe4::Element {
            h,
            stiffness: self.stiffness_of(i),
            rest: self.gauss_rest[i - 1],
            force: [mean + half, mean, mean - half],
            tendons: self.element_tendons(i),
            start: self.arc(i - 1),
            tension_scale: load,
            magnet: self
                .magnetization
                .get(i - 1)
                .map(|m| (load * self.magnetic_field, *m)),
        }
    }

    /// The unloaded rod in its rest shape: each element turns by exactly its
    /// rest curvature, `(2/ds) vec(conj(q_{i-1}) q_i) = kappa0_i` (with the
    /// fourth-order scheme: at both Gauss points), so the elastic energy and
    /// the residual vanish (the load path starts exactly).
    pub fn rest_shape(&self) -> Vec<Quat> {
        self.rest_nodes.clone()
    }

    fn compute_rest_shape(&self) -> Vec<Quat> {
        if self.scheme == Scheme::Fe4 {
            return fe4::rest_chain(
                self.base,
                (1..=self.n).map(|i| self.fe4_element(i, 0.0, &[])),
            );
        }
        let mut q = Vec::with_capacity(self.n + 1);
        q.push(self.base);
        for (i, k) in self.rest_curvature.iter().enumerate() {
            let v = 0.5 * self.h(i + 1) * k;
            // Beyond ds |kappa0| = 2 no element reaches its rest curvature (the
            // solve reports it underresolved); the nearest is a half turn.
            let w = (1.0 - v.norm_squared()).max(0.0).sqrt();
            q.push((q[i] * Quat::new(w, v.x, v.y, v.z)).normalized());
        }
        q
    }

    /// Recompute what depends on the rest shape: where it puts the held
    /// nodes (the load path's start) and its tip orientation (a clamped tip's
    /// start, whose quaternion is taken on the same side of the sphere).
    fn refresh_rest(&mut self) {
        self.gauss_rest = match self.scheme {
            Scheme::Fe4 => self
                .rest_curvature
                .iter()
                .enumerate()
                .map(|(i, k)| fe4::gauss_rest_curvature(*k, self.h(i + 1)))
                .collect(),
            Scheme::Fd2 => Vec::new(),
        };
        let rest = self.compute_rest_shape();
        self.rest_nodes = rest.clone();
        if !self.constraints.is_empty() {
            let mut positions = vec![Vector3::zeros(); self.n + 1];
            self.unloaded_positions(&rest, &mut positions);
            for c in &mut self.constraints {
                c.rest = positions[c.node];
            }
        }
        self.rest_tip = rest[self.n];
        if let Some(q) = self.clamped_tip.as_mut() {
            if q.dot(self.rest_tip) < 0.0 {
                *q = -*q;
            }
        }
    }

    /// Node positions of the chain `q` without loads: with the fourth-order
    /// scheme, the internal nodes of the unloaded elements (the rest shape's).
    fn unloaded_positions(&self, q: &[Quat], out: &mut [Vector3<f64>]) {
        if self.scheme != Scheme::Fe4 {
            return self.positions(q, out);
        }
        out[0] = self.base_position;
        for i in 1..=self.n {
            let el = self.fe4_element(i, 0.0, &[]);
            let m = fe4::solve_mid(q[i - 1], q[i], &el, None, None);
            out[i] = out[i - 1] + fe4::chord([q[i - 1], m, q[i]], el.h);
        }
    }

    /// Replace the rest curvature, one `[kappa_x, kappa_y]` per equal section
    /// (the number of sections must divide `n`).
    pub fn set_section_curvature(&mut self, sections: &[[f64; 2]]) {
        let m = sections.len().max(1);
        debug_assert_eq!(self.n % m, 0);
        for (i, k) in self.rest_curvature.iter_mut().enumerate() {
            *k = sections
                .get(i * m / self.n)
                .map_or(Vector3::zeros(), |s| Vector3::new(s[0], s[1], 0.0));
        }
        self.refresh_rest();
    }

    /// `d g / d kappa_c` of one section's rest curvature component `c` (0: x, 1: y),
    /// the section covering elements `first..=last`: the residual depends on the
    /// rest curvature through the elastic moment `K (omega - omega0)`.
    pub fn rest_curvature_gradient(
        &self,
        q: &[Quat],
        first: usize,
        last: usize,
        component: usize,
        out: &mut [Vector3<f64>],
    ) {
        out.iter_mut().for_each(|x| *x = Vector3::zeros());
        for i in first..=last {
            let dk = Vector3::ith(component, self.stiffness_of(i)[component]);
            let c = q[i - 1].conj() * q[i];
            let amat = Matrix3::identity() * c.w + skew(&c.v);
            out[i - 1] -= amat.transpose() * dk;
            if i >= 2 {
                out[i - 2] += amat * dk;
            }
        }
    }

    /// `d g / d tension` of one tendon (`fd2`): the elements it runs through,
    /// with its moment per unit tension in place of the elastic moment (the
    /// equations are linear in a tension).
    pub fn tension_gradient(
        &self,
        q: &[Quat],
        tendon: &crate::scene::Tendon,
        out: &mut [Vector3<f64>],
    ) {
        debug_assert_eq!(self.scheme, Scheme::Fd2);
        out.iter_mut().for_each(|x| *x = Vector3::zeros());
        let unit = [crate::scene::Tendon {
            tension: 1.0,
            ..tendon.clone()
        }];
        let last = self.mesh.nearest_node(tendon.end);
        for i in 1..=last {
            let c = q[i - 1].conj() * q[i];
            let omega = (2.0 / self.h(i)) * c.v;
            let (_, moment, _) = crate::tendon::density(&unit, 1.0, self.mid_arc(i), &omega);
            let amat = Matrix3::identity() * c.w + skew(&c.v);
            out[i - 1] += amat.transpose() * moment;
            if i >= 2 {
                out[i - 2] -= amat * moment;
            }
        }
    }

    /// True when nothing loads the rod: the rest shape is the exact equilibrium.
    pub fn is_trivial(&self) -> bool {
        self.mean_force.iter().all(|f| f.norm() == 0.0)
            && self.tendons.iter().all(|t| t.tension == 0.0)
            && self.magnetization.is_empty()
            && (self.tip_magnet == Vector3::zeros() || self.magnetic_field == Vector3::zeros())
            && (self.tip_force_at.0 == Vector3::zeros() || self.tip_force_at.1 == Vector3::zeros())
            && self.tip_moment.norm() == 0.0
            && self.constraints.iter().all(|c| c.target == c.rest)
            && self.clamped_tip.is_none_or(|q| q == self.rest_tip)
    }

    /// The largest ratio of the distance between consecutive held points (the
    /// base first) to the rod between them: 1 is full reach.
    pub fn tightest_reach(&self) -> f64 {
        let mut from = (0usize, self.base_position);
        let mut ratio: f64 = 0.0;
        for c in &self.constraints {
            let arc = self.arc(c.node) - self.arc(from.0);
            ratio = ratio.max((c.target - from.1).norm() / arc);
            from = (c.node, c.target);
        }
        ratio
    }

    /// Whether the scene has unknown reactions (held nodes or a clamped tip).
    pub fn is_constrained(&self) -> bool {
        !self.constraints.is_empty() || self.clamped_tip.is_some()
    }

    /// The scale of the applied loads at path parameter `lambda`.
    pub fn load_scale(&self, lambda: f64) -> f64 {
        if self.loads_held_fixed {
            1.0
        } else {
            lambda
        }
    }

    /// The same rod and loads with every held point and a clamped tip
    /// released: the first leg of a held scene's load path.
    pub fn released(&self) -> RodModel {
        RodModel {
            constraints: Vec::new(),
            clamped_tip: None,
            ..self.clone()
        }
    }

    /// The second leg of a held scene's load path: the loads at full scale,
    /// the held points (and a clamped tip's orientation) moved by `lambda`
    /// from where the chain `q` (the loaded free rod) puts them.
    pub fn holding_from(&self, q: &[Quat]) -> RodModel {
        let mut model = self.clone();
        let mut positions = vec![Vector3::zeros(); self.n + 1];
        self.positions(q, &mut positions);
        for c in &mut model.constraints {
            c.rest = positions[c.node];
        }
        model.rest_tip = q[self.n];
        if let Some(target) = model.clamped_tip.as_mut() {
            if target.dot(model.rest_tip) < 0.0 {
                *target = -*target;
            }
        }
        model.loads_held_fixed = true;
        model
    }

    /// Orientation of a clamped tip at load scale `lambda` (slerp from the
    /// rest shape's tip).
    pub fn clamped_tip_at(&self, lambda: f64) -> Option<Quat> {
        self.clamped_tip
            .map(|target| slerp(self.rest_tip, target, lambda))
    }

    /// The initial guess of a solve without one: the rest shape, or for a
    /// clamped tip the rod turning uniformly from the base to the tip orientation.
    pub fn initial_guess(&self) -> Vec<Quat> {
        match self.clamped_tip {
            None => self.rest_shape(),
            Some(target) => (0..=self.n)
                .map(|j| slerp(self.base, target, j as f64 / self.n as f64))
                .collect(),
        }
    }

    /// The straight rod along the base tangent.
    pub fn straight(&self) -> Vec<Quat> {
        vec![self.base; self.n + 1]
    }

    /// Residual `g` (node `j` at index `j - 1`) at load scale `lambda`.
    pub fn residual(&self, q: &[Quat], lambda: f64, g: &mut [Vector3<f64>]) {
        self.assemble(q, lambda, &[], g, None);
    }

    /// Residual and its exact Jacobian at load scale `lambda`.
    pub fn residual_jacobian(
        &self,
        q: &[Quat],
        lambda: f64,
        g: &mut [Vector3<f64>],
        jac: &mut BlockTridiagonal,
    ) {
        self.assemble(q, lambda, &[], g, Some(jac));
    }

    /// Residual with the constraint reactions (one per constraint, world frame)
    /// acting as point forces, and optionally its Jacobian in the rotations.
    pub fn residual_with_reactions(
        &self,
        q: &[Quat],
        lambda: f64,
        reactions: &[Vector3<f64>],
        g: &mut [Vector3<f64>],
        jac: Option<&mut BlockTridiagonal>,
    ) {
        self.assemble(q, lambda, reactions, g, jac);
    }

    /// Sum of the reactions at nodes `>= node`: their share of the internal force there.
    fn reactions_from(&self, reactions: &[Vector3<f64>], node: usize) -> Vector3<f64> {
        self.constraints
            .iter()
            .zip(reactions)
            .filter(|(c, _)| c.node >= node)
            .map(|(_, r)| *r)
            .sum()
    }

    /// The element terms of node `i - 1` (`gb`, `jbb`) and node `i - 2`
    /// (`ga`, `jaa`), and the coupling block `jab` of element `i`.
    fn element_terms(
        &self,
        i: usize,
        q: &[Quat],
        load: f64,
        reactions: &[Vector3<f64>],
        with_jacobian: bool,
    ) -> ElementTerms {
        let (ds, k) = (self.h(i), self.stiffness_of(i));
        let (a, b) = (q[i - 1], q[i]);
        let c = a.conj() * b;
        let (c0, cv) = (c.w, c.v);
        let e = (2.0 / ds) * cv - self.rest_curvature[i - 1];
        // Bending/twisting moment, body frame, and its derivative in the
        // curvature: the elastic law, plus the tendons' (at the midpoint).
        let mut w = k.component_mul(&e);
        let tendons = self.element_tendons(i);
        let mut tendon_stiffness = None;
        if !tendons.is_empty() {
            let omega = (2.0 / ds) * cv;
            let (_, moment, stiffness) =
                crate::tendon::density(tendons, load, self.mid_arc(i), &omega);
            w += moment;
            tendon_stiffness = Some(stiffness);
        }
        let amat = Matrix3::identity() * c0 + skew(&cv);
        let ga = -(amat * w);
        let gb = amat.transpose() * w;
        // Load potential kappa * a^T S b with kappa = -ds/3 (F . T(a,b) term).
        let kappa = -ds / 3.0;
        let mut fbar = load * self.mean_force[i - 1];
        if !reactions.is_empty() {
            fbar += self.reactions_from(reactions, i);
        }
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
        let mut kmat = Matrix3::from_diagonal(&k);
        if let Some(stiffness) = tendon_stiffness {
            kmat += stiffness;
        }
        let cw = cv.dot(&w);
        let psi = kappa * a.dot(sb);
        let radial = (-0.5 * cw - 0.25 * psi) * Matrix3::identity();
        terms.jbb = amat.transpose() * kmat * amat / ds + radial + 0.5 * skew(&terms.gb);
        if i >= 2 {
            terms.jaa = amat * kmat * amat.transpose() / ds + radial + 0.5 * skew(&terms.ga);
            let mut jab = -(amat * kmat * amat) / ds
                - 0.5
                    * (Matrix3::identity() * cw
                        - c0 * skew(&w)
                        - cv * w.transpose()
                        - w * cv.transpose());
            // 1/4 kappa G(a) S G(b)^T, column by column: G(b)^T e_k = b * (0, e_k).
            for col in 0..3 {
                let bek = b * Quat::pure(Vector3::ith(col, 1.0));
                let v = (a.conj() * tangent_form_apply(&fbar, bek)).v;
                jab.set_column(col, &(jab.column(col) + 0.25 * kappa * v));
            }
            terms.jab = jab;
        }
        terms
    }

    /// The field's terms of element `i` on its magnetisation `m`: the
    /// bilinear part `kappa a^T S b` of `-B . R m` by the tangent's rule
    /// (the nodes' parts are node terms), entering the gradient and the
    /// Jacobian as the dead loads' part does in [`RodModel::element_terms`].
    /// Apart from it so that the common element, without a field, stays lean.
    fn magnetic_terms(
        &self,
        i: usize,
        q: &[Quat],
        load: f64,
        m: &Vector3<f64>,
        with_jacobian: bool,
    ) -> ElementTerms {
        let (a, b) = (q[i - 1], q[i]);
        let kappa = -self.h(i) / 3.0;
        let field = load * self.magnetic_field;
        let (sa, sb) = (
            rotation_form_apply(&field, m, a),
            rotation_form_apply(&field, m, b),
        );
        let mut terms = ElementTerms {
            ga: 0.5 * kappa * (a.conj() * sb).v,
            gb: 0.5 * kappa * (b.conj() * sa).v,
            jaa: Matrix3::zeros(),
            jbb: Matrix3::zeros(),
            jab: Matrix3::zeros(),
        };
        if !with_jacobian {
            return terms;
        }
        let radial = (-0.25 * kappa * a.dot(sb)) * Matrix3::identity();
        terms.jbb = radial + 0.5 * skew(&terms.gb);
        if i >= 2 {
            terms.jaa = radial + 0.5 * skew(&terms.ga);
            for col in 0..3 {
                let bek = b * Quat::pure(Vector3::ith(col, 1.0));
                let v = (a.conj() * rotation_form_apply(&field, m, bek)).v;
                terms.jab.set_column(col, &(0.25 * kappa * v));
            }
        }
        terms
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
        load: f64,
        reactions: &[Vector3<f64>],
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
            self.fill_slab(&mut slab, q, load, reactions);
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
                .for_each(|slab| self.fill_slab(slab, q, load, reactions));
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

    /// The terms of the elements of one chunk into its rows.
    fn fill_slab(&self, slab: &mut Slab, q: &[Quat], load: f64, reactions: &[Vector3<f64>]) {
        let with_jacobian = slab.blocks.is_some();
        for i in slab.first..slab.end {
            // A huge n takes long here: an interrupt leaves the residual
            // unfinished, and the solver's loops stop on the same flag.
            if i % crate::interrupt::POLL_STRIDE == 0 && crate::interrupt::requested() {
                return;
            }
            let mut t = self.element_terms(i, q, load, reactions, with_jacobian);
            if let Some(m) = self.magnetization.get(i - 1) {
                let f = self.magnetic_terms(i, q, load, m, with_jacobian);
                t.ga += f.ga;
                t.gb += f.gb;
                t.jaa += f.jaa;
                t.jbb += f.jbb;
                t.jab += f.jab;
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

    fn assemble(
        &self,
        q: &[Quat],
        lambda: f64,
        reactions: &[Vector3<f64>],
        g: &mut [Vector3<f64>],
        mut jac: Option<&mut BlockTridiagonal>,
    ) {
        debug_assert_eq!(q.len(), self.n + 1);
        debug_assert_eq!(g.len(), self.n);
        let load = self.load_scale(lambda);
        if self.scheme == Scheme::Fe4 {
            let mut mids = self.mids.lock();
            fe4::assemble(
                q,
                |i| self.fe4_element(i, load, reactions),
                &mut mids,
                g,
                jac.as_deref_mut(),
            );
        } else {
            // Elements: elastic energy and the bilinear part of the load potential.
            // They write every entry of `g` and `jac`: no clearing pass.
            self.assemble_elements(q, load, reactions, g, jac.as_deref_mut(), ASSEMBLY_CHUNK);
        }
        // Nodes: the quadratic part of the load potential, h . T(q_j).
        for j in (1..=self.n).filter(|_| self.scheme == Scheme::Fd2) {
            let mut weight = load * self.node_force_weight[j - 1];
            if !reactions.is_empty() {
                weight += self.h(j) * self.reactions_from(reactions, j);
                if j < self.n {
                    weight += self.h(j + 1) * self.reactions_from(reactions, j + 1);
                }
            }
            let h = (-1.0 / 3.0) * weight;
            let f = q[j].inverse_rotate(h);
            g[j - 1] += Vector3::new(-f.y, f.x, 0.0);
            if let Some(jac) = jac.as_deref_mut() {
                jac.diag[j - 1] += f * Vector3::z().transpose() - f.z * Matrix3::identity();
            }
            // The field on the magnetisation of the elements that meet here.
            for e in [j, j + 1] {
                if let Some(m) = self.magnetization.get(e - 1) {
                    let c = (-self.h(e) / 3.0) * load * self.magnetic_field;
                    let (_, grad, block) = body_vector_terms(q[j], &c, m);
                    g[j - 1] += grad;
                    if let Some(jac) = jac.as_deref_mut() {
                        jac.diag[j - 1] += block;
                    }
                }
            }
        }
        // A tip magnet, -B . R(q_n) mu, and a tip force off the tip, -F . R(q_n) c:
        // the same form.
        let (force, offset) = self.tip_force_at;
        for (world, body) in [(self.magnetic_field, self.tip_magnet), (force, offset)] {
            if world != Vector3::zeros() && body != Vector3::zeros() {
                let c = -load * world;
                let (_, grad, block) = body_vector_terms(q[self.n], &c, &body);
                g[self.n - 1] += grad;
                if let Some(jac) = jac.as_deref_mut() {
                    jac.diag[self.n - 1] += block;
                }
            }
        }
        // Tip moment (a dead load in the world frame, no potential in 3D).
        if self.tip_moment.norm() > 0.0 {
            let m = q[self.n].inverse_rotate(load * self.tip_moment);
            g[self.n - 1] -= m;
            if let Some(jac) = jac {
                jac.diag[self.n - 1] -= skew(&m);
            }
        }
    }

    /// `d g / d lambda`: the residual is affine in the load scale.
    pub fn residual_lambda_derivative(
        &self,
        q: &[Quat],
        out: &mut [Vector3<f64>],
        scratch: &mut [Vector3<f64>],
    ) {
        self.residual(q, 1.0, out);
        self.residual(q, 0.0, scratch);
        for (o, s) in out.iter_mut().zip(scratch.iter()) {
            *o -= s;
        }
    }

    /// `h_c = r_{node_c} - target_c(lambda)` for every constraint; `r` is scratch
    /// of `n + 1` positions.
    pub fn constraint_residual(
        &self,
        q: &[Quat],
        lambda: f64,
        r: &mut [Vector3<f64>],
        h: &mut [Vector3<f64>],
    ) {
        self.positions(q, r);
        for (c, hc) in self.constraints.iter().zip(h.iter_mut()) {
            *hc = r[c.node] - c.target_at(lambda);
        }
    }

    /// `d r_k / d theta_j` for every node `j` (index `j - 1`; zero beyond `k`):
    /// the Jacobian of a held node's position. The residual depends on that
    /// node's reaction `R` through `-(d r_k / d theta)^T R`.
    pub fn position_jacobian(&self, q: &[Quat], k: usize, out: &mut [Matrix3<f64>]) {
        if self.scheme == Scheme::Fe4 {
            return self.fe4_position_jacobian(q, k, out);
        }
        for j in 1..=self.n {
            if j > k {
                out[j - 1] = Matrix3::zeros();
                continue;
            }
            // Row c: gradient of e_c . r_k. T(q_j) counts once per element of node
            // j inside [1, k] (element `i` weighted by `h_i / 3`); the bilinear
            // terms pair it with its neighbours.
            let before = self.h(j) / 3.0;
            let after = if j < k { self.h(j + 1) / 3.0 } else { 0.0 };
            let mut block = Matrix3::zeros();
            for c in 0..3 {
                let e = Vector3::ith(c, 1.0);
                let f = q[j].inverse_rotate(e);
                let mut row = (before + after) * Vector3::new(-f.y, f.x, 0.0);
                row += (0.5 * before) * (q[j].conj() * tangent_form_apply(&e, q[j - 1])).v;
                if j < k {
                    row += (0.5 * after) * (q[j].conj() * tangent_form_apply(&e, q[j + 1])).v;
                }
                block.set_row(c, &row.transpose());
            }
            out[j - 1] = block;
        }
    }

    /// [`RodModel::position_jacobian`] of the fourth-order scheme: the total
    /// derivative, the internal nodes following the ends as the last
    /// evaluation with the Jacobian (at `q`) linearised them.
    fn fe4_position_jacobian(&self, q: &[Quat], k: usize, out: &mut [Matrix3<f64>]) {
        out.iter_mut().for_each(|b| *b = Matrix3::zeros());
        let mids = self.mids.lock();
        for e in 1..=k {
            let Some(state) = mids[e - 1] else { continue };
            let c = fe4::chord_jacobian([q[e - 1], state.node(), q[e]], self.h(e));
            let (ma, mb, _) = state.response();
            if e >= 2 {
                out[e - 2] += c[0] - c[1] * ma;
            }
            out[e - 1] += c[2] - c[1] * mb;
        }
    }

    /// Fourth-order scheme: how the held points move with their reactions at
    /// fixed node rotations (`dh_c / dR_c'`, 3x3 blocks of a 3m x 3m matrix),
    /// through the internal nodes, which the reactions load: `sum over the
    /// elements before both of C_m J_mm^-1 C_m^T` with `C_m = d chord / d
    /// theta_m`. Zero for the finite-difference scheme (None).
    pub fn held_point_compliance(&self, q: &[Quat]) -> Option<nalgebra::DMatrix<f64>> {
        if self.scheme != Scheme::Fe4 {
            return None;
        }
        let m = self.constraints.len();
        let mids = self.mids.lock();
        let last = self.constraints.iter().map(|c| c.node).max().unwrap_or(0);
        // Running sum over the elements, read off at each held node.
        let mut running = Matrix3::zeros();
        let mut at_node = vec![Matrix3::zeros(); last + 1];
        for e in 1..=last {
            if let Some(state) = mids[e - 1] {
                let c = fe4::chord_jacobian([q[e - 1], state.node(), q[e]], self.h(e));
                let (_, _, inverse) = state.response();
                running += c[1] * inverse * c[1].transpose();
            }
            at_node[e] = running;
        }
        let mut out = nalgebra::DMatrix::zeros(3 * m, 3 * m);
        for (i, a) in self.constraints.iter().enumerate() {
            for (j, b) in self.constraints.iter().enumerate() {
                let block = at_node[a.node.min(b.node)];
                out.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&block);
            }
        }
        Some(out)
    }

    /// Internal force at the nodes with the reactions: the force that the distal
    /// part exerts on the proximal one (a held node's reaction counts distal).
    pub fn node_forces(&self, reactions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        (0..=self.n)
            .map(|j| {
                let held: Vector3<f64> = self
                    .constraints
                    .iter()
                    .zip(reactions)
                    .filter(|(c, _)| c.node > j || c.node == self.n)
                    .map(|(_, r)| *r)
                    .sum();
                self.node_force[j] + held
            })
            .collect()
    }

    /// Dimensionless residual norm: the largest torque imbalance of a row over
    /// its own scale `k_c / L`. Not finite if any row is not (NaN is never
    /// dropped, so a broken state can never pass a tolerance).
    pub fn residual_norm(&self, g: &[Vector3<f64>]) -> f64 {
        let mut largest = 0.0f64;
        for x in g {
            let r = x.component_div(&self.residual_scale).amax();
            if !r.is_finite() {
                return f64::INFINITY;
            }
            largest = largest.max(r);
        }
        largest
    }

    /// The residual tolerance in effect: `tol`, but never below the
    /// residual's round-off floor ([`RodModel::roundoff_floor`]). The
    /// equilibrium is not less accurate for it: the rounding is a torque noise
    /// of zero mean whose effect on the shape is of order `eps`.
    pub fn effective_tol(&self, tol: f64) -> f64 {
        tol.max(self.roundoff_floor())
    }

    /// The round-off floor of the relative residual, `8 eps (n + kappa L)`.
    /// A node's torque comes from the curvature `(2/ds) vec(conj(a) b)` of
    /// unit quaternions stored to `eps`, so its rounding is about
    /// `2 eps k / ds`, that is `2 eps n` relative to `k / L` (measured: 1.8 eps
    /// n on the cantilever from n = 1e4 to 1e5). The elastic moments `K omega`
    /// themselves, which balance the loads' moment and the rest curvature, are
    /// of order `kappa L` relative to `k / L` and round to `eps` of that (a tip
    /// force of 1e8 `EI/L^2` leaves a residual noise of about 1e-8).
    ///
    /// Sections of their own stiffness round as their own: the floor is
    /// that of the stiffest relative to the residual's scale
    /// ([`RodModel::stiffness_spread`]); a section 100 times stiffer than
    /// the softest left residuals that a `residual_tol` of 1e-13 could never
    /// meet.
    pub fn roundoff_floor(&self) -> f64 {
        // `L / h` of the shortest element: `n` when the elements are equal.
        let shortest = self
            .mesh
            .element_lengths()
            .iter()
            .fold(self.ds, |a, b| a.min(*b));
        let per_length = self.n as f64 * self.ds / shortest;
        let curvature = self.load_parameter + self.max_rest_turn() * per_length;
        8.0 * f64::EPSILON * (per_length + curvature) * self.stiffness_spread()
    }

    /// The line-search merit: the sum of squares of the scaled torque rows.
    /// Newton's step is a descent direction of any fixed row weighting; this
    /// one keeps a stiff row from drowning the soft ones.
    pub fn merit(&self, g: &[Vector3<f64>]) -> f64 {
        g.iter()
            .map(|x| x.component_div(&self.residual_scale).norm_squared())
            .sum()
    }

    /// Largest turning angle of one element [rad] (the angle of `conj(a) b`).
    pub fn max_element_turn(&self, q: &[Quat]) -> f64 {
        q.windows(2)
            .map(|p| element_turn(p[0], p[1]))
            .fold(0.0, f64::max)
    }

    /// Largest turning of one element at rest, `h_i |kappa0_i|` [rad].
    pub fn max_rest_turn(&self) -> f64 {
        self.rest_curvature
            .iter()
            .enumerate()
            .map(|(i, k)| self.h(i + 1) * k.norm())
            .fold(0.0, f64::max)
    }

    /// Node positions `r_0` (the base position), `r_i = r_{i-1} + h_i T_i`
    /// with the exact mean tangent.
    /// (Fourth-order scheme: by Simpson's rule on each element's tangents,
    /// with the internal nodes of the full loads.)
    pub fn positions(&self, q: &[Quat], out: &mut [Vector3<f64>]) {
        out[0] = self.base_position;
        if self.scheme == Scheme::Fe4 {
            let mut mids = self.mids.lock();
            for i in 1..=self.n {
                let el = self.fe4_element(i, 1.0, &[]);
                let m = fe4::mid_for(&mut mids, i, q[i - 1], q[i], &el);
                out[i] = out[i - 1] + fe4::chord([q[i - 1], m, q[i]], el.h);
            }
            return;
        }
        for i in 1..=self.n {
            out[i] = out[i - 1] + self.h(i) * mean_tangent(q[i - 1], q[i]);
        }
    }

    /// The internal nodes of the fourth-order scheme's elements at `q` (as
    /// [`RodModel::positions`] draws them); empty for the second-order one.
    pub fn internal_nodes(&self, q: &[Quat]) -> Vec<Quat> {
        if self.scheme != Scheme::Fe4 {
            return Vec::new();
        }
        let mut mids = self.mids.lock();
        (1..=self.n)
            .map(|i| {
                let el = self.fe4_element(i, 1.0, &[]);
                fe4::mid_for(&mut mids, i, q[i - 1], q[i], &el)
            })
            .collect()
    }

    /// Total potential `Pi` (elastic energy minus the work of the dead forces) [J].
    /// A dead tip moment has no potential in 3D and is not included.
    pub fn energy(&self, q: &[Quat]) -> f64 {
        self.energy_at(q, 1.0)
    }

    /// `Pi` at load scale `lambda` (the applied loads scaled).
    pub fn energy_at(&self, q: &[Quat], lambda: f64) -> f64 {
        let load = self.load_scale(lambda);
        // A tip magnet, -B . R(q_n) mu, and a tip force off the tip, -F . R(q_n) c.
        let (force, offset) = self.tip_force_at;
        let mut total =
            body_vector_terms(q[self.n], &(-load * self.magnetic_field), &self.tip_magnet).0
                + body_vector_terms(q[self.n], &(-load * force), &offset).0;
        if self.scheme == Scheme::Fe4 {
            let mut mids = self.mids.lock();
            return total
                + (1..=self.n)
                    .map(|i| {
                        let el = self.fe4_element(i, load, &[]);
                        let m = fe4::mid_for(&mut mids, i, q[i - 1], q[i], &el);
                        fe4::energy([q[i - 1], m, q[i]], &el)
                    })
                    .sum::<f64>();
        }
        for i in 1..=self.n {
            let (a, b) = (q[i - 1], q[i]);
            let (cv, h) = ((a.conj() * b).v, self.h(i));
            let e = (2.0 / h) * cv - self.rest_curvature[i - 1];
            let mut elastic = 0.5 * e.dot(&self.stiffness_of(i).component_mul(&e));
            let tendons = self.element_tendons(i);
            if !tendons.is_empty() {
                let omega = (2.0 / h) * cv;
                elastic += crate::tendon::density(tendons, load, self.mid_arc(i), &omega).0;
            }
            let mut work = load * self.mean_force[i - 1].dot(&mean_tangent(a, b));
            if let Some(m) = self.magnetization.get(i - 1) {
                // B . (R(a) m + R(a, b) m + R(b) m) / 3, the tangent's rule.
                let field = load * self.magnetic_field;
                let form = |x: Quat| rotation_form_apply(&field, m, x);
                work += (a.dot(form(a)) + a.dot(form(b)) + b.dot(form(b))) / 3.0;
            }
            total += h * (elastic - work);
        }
        total
    }
}

/// The section of element `i` (from 0) of a rod of `n` elements in `sections`
/// equal sections.
pub(crate) fn section_of(i: usize, sections: usize, n: usize) -> usize {
    i * sections / n
}

/// Spherical interpolation from `a` (t = 0) to `b` (t = 1) along the short arc
/// when `a . b >= 0` (the caller chooses the sign of `b`).
pub fn slerp(a: Quat, b: Quat, t: f64) -> Quat {
    let rel = a.conj() * b;
    let angle = 2.0 * rel.v.norm().atan2(rel.w);
    let axis = if rel.v.norm() > 0.0 {
        rel.v / rel.v.norm()
    } else {
        Vector3::zeros()
    };
    (a * Quat::from_rotation_vector(axis * (angle * t))).normalized()
}

/// Turning angle of the element from `a` to `b` [rad], in `[0, 2 pi]`: the
/// angle of `conj(a) b` on the quaternions' own branch (beyond `pi` the
/// discrete curvature folds back).
pub fn element_turn(a: Quat, b: Quat) -> f64 {
    let c = a.conj() * b;
    2.0 * c.v.norm().atan2(c.w)
}

/// Mean tangent of an element: the exact mean of `T` under linear interpolation of `q`.
pub fn mean_tangent(a: Quat, b: Quat) -> Vector3<f64> {
    (a.tangent() + tangent_bilinear(a, b) + b.tangent()) / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// The chunked (parallel) assembly adds the same terms in the same order
    /// as the one-chunk loop: equal to the last bit, with and without
    /// reactions, whatever the chunk size, and whatever the buffers held.
    #[test]
    fn chunked_assembly_is_bitwise_the_one_thread_assembly() {
        let scene = Scene::from_json_str(
            r#"{"length": 1.3, "stiffness": {"kx": 1, "ky": 2, "kz": 0.5},
                "rest_curvature": [[1, -2], [0.5, 3]], "tip_force": [1, -2, 0.5],
                "gravity": {"linear_density": 0.3, "vector": [0, 1, -9.81]},
                "tip_moment": [0.2, 0.1, -0.3],
                "tip": {"type": "pinned", "position": [0.3, 0.2, 1.0]}}"#,
        )
        .unwrap();
        let n = 37;
        let model = RodModel::new(&scene, n);
        // A bent, twisted state.
        let q: Vec<Quat> = (0..=n)
            .map(|j| {
                let s = j as f64 / n as f64;
                Quat::from_rotation_vector(Vector3::new(0.9 * s, -0.4 * s * s, 1.7 * s))
            })
            .collect();
        let reactions = [Vector3::new(0.3, -1.2, 2.0)];
        for reactions in [&[][..], &reactions[..]] {
            let run = |chunk: usize| {
                // Every entry is written: what was there before does not matter.
                let mut g = vec![Vector3::repeat(f64::NAN); n];
                let mut jac = BlockTridiagonal::zeros(n);
                jac.diag.fill(Matrix3::repeat(f64::NAN));
                jac.upper.fill(Matrix3::repeat(f64::NAN));
                jac.lower.fill(Matrix3::repeat(f64::NAN));
                model.assemble_elements(&q, 0.8, reactions, &mut g, Some(&mut jac), chunk);
                (g, jac)
            };
            let (g1, j1) = run(n + 1);
            for chunk in [1, 2, 3, 5, 16, 36, 37] {
                let (g2, j2) = run(chunk);
                assert_eq!(g1, g2, "chunk {chunk}");
                assert_eq!(j1.diag, j2.diag, "chunk {chunk}");
                assert_eq!(j1.upper, j2.upper, "chunk {chunk}");
                assert_eq!(j1.lower, j2.lower, "chunk {chunk}");
            }
        }
    }
}
