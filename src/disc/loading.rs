//! What a scheme integrates: the kinds of effect on a rod, element by
//! element and node by node, filled in by the terms (the `terms` module).
//!
//! A kind is what a scheme knows how to integrate at its own quadrature:
//!
//! * the elastic law `1/2 (omega - omega0)^T K (omega - omega0)` per length,
//!   from the curvature (every scheme's rest shape is its zero);
//! * curvature densities `W(omega, s)` per length beyond it (tendons);
//! * the internal force `F(s)` that the dead forces beyond `s` exert, whose
//!   potential is `-F . T` per length (`T` the tangent): piecewise linear,
//!   given by its value at each element's middle and its drop along it;
//! * body-vector potentials `-c . R(s) b(s)` per length with a uniform world
//!   vector `c` and a body vector `b` per element (a magnetisation in a
//!   field), and the same at single nodes (a tip magnet, a force at an
//!   offset from the tip);
//! * dead moments, per length or at nodes (no potential in 3D).
//!
//! Everything but the elastic law is scaled by the load scale of the load
//! path. The same struct holds a term's derivative in one of its parameters
//! (a "tangent" loading, empty where the term has no entry), which the
//! schemes turn into the residual's derivative.

use crate::quat::Quat;
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// A potential `-world . R(s) body_i` per length along every element `i`
/// (index `i - 1`): a uniform world vector paired with a body vector an element.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyLoad {
    pub world: Vector3<f64>,
    pub body: Vec<Vector3<f64>>,
}

/// A potential `-world . R(q_node) body` at one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodePair {
    pub node: usize,
    pub world: Vector3<f64>,
    pub body: Vector3<f64>,
}

/// A dead moment at one node, world frame [N m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeMoment {
    pub node: usize,
    pub moment: Vector3<f64>,
}

/// A potential per length that depends on the curvature (and the arc
/// length): it enters a scheme where the elastic energy does, through its
/// gradient (a moment) and Hessian (a stiffness), so the system stays banded
/// and symmetric.
pub trait CurvatureDensity: std::fmt::Debug + Send + Sync {
    /// Whether it acts along element `i` (from 1).
    fn acts_on(&self, element: usize) -> bool;

    /// Its value [N], gradient in `omega` [N m] and Hessian [N m^2] at arc
    /// length `s` of element `element`, curvature `omega` (material frame),
    /// scaled by `scale` (the load scale); `None` where it does not act.
    fn density(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<(f64, Vector3<f64>, Matrix3<f64>)>;

    /// Its gradient alone (a moment), for the residual's derivatives, which
    /// need no value and no stiffness.
    fn moment(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<Vector3<f64>> {
        self.density(element, s, omega, scale).map(|(_, m, _)| m)
    }

    /// Its value alone, for the energy, which needs no moment and no stiffness.
    fn value(&self, element: usize, s: f64, omega: &Vector3<f64>, scale: f64) -> Option<f64> {
        self.density(element, s, omega, scale).map(|(v, _, _)| v)
    }
}

/// What the terms put on a rod of `n` elements (see the module's
/// documentation); per-element entries at index `i - 1`, an empty list
/// where nothing of that kind acts.
#[derive(Debug, Clone, Default)]
pub struct Loading {
    /// Diagonal stiffness `(kx, ky, kz)` of each element [N m^2], or one
    /// entry for a rod of one stiffness (the kernels then read no array).
    pub stiffness: Vec<Vector3<f64>>,
    /// Rest curvature of each element, material frame [1/m].
    pub rest_curvature: Vec<Vector3<f64>>,
    /// The internal force at the middle of each element from the dead
    /// forces beyond it, world frame [N].
    pub mean_force: Vec<Vector3<f64>>,
    /// Its drop along the element, start minus end (the distributed force
    /// on it) [N].
    pub force_drop: Vec<Vector3<f64>>,
    /// The internal force at each node `0..=n` (the distal part on the
    /// proximal one; a point load at a node counts distal), world frame [N].
    pub node_force: Vec<Vector3<f64>>,
    /// Body-vector potentials along the rod.
    pub body_loads: Vec<BodyLoad>,
    /// Dead moment per length on each element, world frame [N m / m].
    pub distributed_moment: Vec<Vector3<f64>>,
    /// Body-vector potentials at nodes.
    pub node_pairs: Vec<NodePair>,
    /// Dead moments at nodes.
    pub node_moments: Vec<NodeMoment>,
    /// Curvature densities beyond the elastic law.
    pub densities: Vec<Arc<dyn CurvatureDensity>>,
    /// A tangent's elements (from 1, both ends included) outside of which
    /// its per-element entries and densities are zero (a section's rest
    /// curvature, a tendon's tension): where a scheme need look. `None`:
    /// anywhere (and always for a rod's own loading).
    pub support: Option<(usize, usize)>,
}

impl Loading {
    /// An unloaded rod of `n` elements (no stiffness yet: the elastic term
    /// sets it).
    pub fn zeros(n: usize) -> Self {
        Loading {
            stiffness: vec![Vector3::zeros(); n],
            rest_curvature: vec![Vector3::zeros(); n],
            mean_force: vec![Vector3::zeros(); n],
            force_drop: vec![Vector3::zeros(); n],
            node_force: vec![Vector3::zeros(); n + 1],
            ..Loading::default()
        }
    }

    /// A loading with nothing in it: the start of a tangent.
    pub fn empty() -> Self {
        Loading::default()
    }

    /// Stiffness of element `i` (zero where none is given: a tangent).
    #[inline(always)]
    pub fn stiffness_of(&self, i: usize) -> Vector3<f64> {
        match self.stiffness.len() {
            0 => Vector3::zeros(),
            1 => self.stiffness[0],
            _ => self.stiffness[i - 1],
        }
    }

    /// Rest curvature of element `i`.
    #[inline(always)]
    pub fn rest_of(&self, i: usize) -> Vector3<f64> {
        self.rest_curvature
            .get(i - 1)
            .copied()
            .unwrap_or_else(Vector3::zeros)
    }

    /// The dead forces' internal force at the middle of element `i`.
    #[inline(always)]
    pub fn mean_force_of(&self, i: usize) -> Vector3<f64> {
        self.mean_force
            .get(i - 1)
            .copied()
            .unwrap_or_else(Vector3::zeros)
    }

    /// Its drop along element `i`.
    #[inline(always)]
    pub fn force_drop_of(&self, i: usize) -> Vector3<f64> {
        self.force_drop
            .get(i - 1)
            .copied()
            .unwrap_or_else(Vector3::zeros)
    }

    /// The dead moment per length on element `i`.
    #[inline(always)]
    pub fn distributed_moment_of(&self, i: usize) -> Vector3<f64> {
        self.distributed_moment
            .get(i - 1)
            .copied()
            .unwrap_or_else(Vector3::zeros)
    }

    /// Whether a curvature density acts along element `i`.
    #[inline(always)]
    pub fn has_density(&self, i: usize) -> bool {
        !self.densities.is_empty() && self.densities.iter().any(|d| d.acts_on(i))
    }

    /// The curvature densities' sum at arc length `s` of element `i`;
    /// `None` where none acts (the common element: no call).
    #[inline(always)]
    pub fn density(
        &self,
        i: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<(f64, Vector3<f64>, Matrix3<f64>)> {
        match self.densities.as_slice() {
            [] => None,
            [one] => one.density(i, s, omega, scale),
            many => many
                .iter()
                .filter_map(|d| d.density(i, s, omega, scale))
                .reduce(|a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2)),
        }
    }

    // The three sums are written out: one generic over the part asked for
    // cost the tendon robot's IK 2 to 4 % of its instructions (measured).

    /// The curvature densities' values alone ([`Loading::density`]'s first).
    #[inline(always)]
    pub fn density_value(&self, i: usize, s: f64, omega: &Vector3<f64>, scale: f64) -> Option<f64> {
        match self.densities.as_slice() {
            [] => None,
            [one] => one.value(i, s, omega, scale),
            many => many
                .iter()
                .filter_map(|d| d.value(i, s, omega, scale))
                .reduce(|a, b| a + b),
        }
    }

    /// The curvature densities' moments alone ([`Loading::density`]'s second).
    #[inline(always)]
    pub fn density_moment(
        &self,
        i: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<Vector3<f64>> {
        match self.densities.as_slice() {
            [] => None,
            [one] => one.moment(i, s, omega, scale),
            many => many
                .iter()
                .filter_map(|d| d.moment(i, s, omega, scale))
                .reduce(|a, b| a + b),
        }
    }

    /// The elements `(first, last)` (from 1, both included) outside of which
    /// it is zero on a rod of `n`: its `support`, else all of them.
    #[inline(always)]
    pub fn elements(&self, n: usize) -> (usize, usize) {
        self.support.unwrap_or((1, n))
    }

    /// Whether it holds nothing at all (a tangent before a term's part).
    pub fn is_empty(&self) -> bool {
        self.stiffness.is_empty()
            && self.rest_curvature.is_empty()
            && self.densities.is_empty()
            && self.only_moments()
    }

    /// Whether it holds only kinds that act through the curvature (the
    /// elastic law, curvature densities): a tangent of such a parameter.
    pub fn only_moments(&self) -> bool {
        self.mean_force.is_empty()
            && self.force_drop.is_empty()
            && self.body_loads.is_empty()
            && self.distributed_moment.is_empty()
            && self.node_pairs.is_empty()
            && self.node_moments.is_empty()
    }

    /// Whether the rest shape is the exact equilibrium: nothing but the
    /// elastic law acts (every load-like entry is zero).
    pub fn is_unloaded(&self, zero_density: bool) -> bool {
        let zero = |v: &Vector3<f64>| *v == Vector3::zeros();
        self.mean_force.iter().all(zero)
            && self.force_drop.iter().all(zero)
            && self
                .body_loads
                .iter()
                .all(|b| zero(&b.world) || b.body.iter().all(zero))
            && self.distributed_moment.iter().all(zero)
            && self
                .node_pairs
                .iter()
                .all(|p| zero(&p.world) || zero(&p.body))
            && self.node_moments.iter().all(|m| zero(&m.moment))
            && (self.densities.is_empty() || zero_density)
    }

    /// Add `factor` times `other` (a tangent's parts: a combination of
    /// terms' derivatives), entry by entry.
    pub fn add_scaled(&mut self, other: &Loading, factor: f64) {
        // The union of the supports (anywhere if either is anywhere).
        self.support = match (self.is_empty(), self.support, other.support) {
            (true, _, support) => support,
            (false, Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
            _ => None,
        };
        fn add(to: &mut Vec<Vector3<f64>>, from: &[Vector3<f64>], factor: f64) {
            if from.is_empty() {
                return;
            }
            to.resize(to.len().max(from.len()), Vector3::zeros());
            for (t, f) in to.iter_mut().zip(from) {
                *t += factor * f;
            }
        }
        add(&mut self.stiffness, &other.stiffness, factor);
        add(&mut self.rest_curvature, &other.rest_curvature, factor);
        add(&mut self.mean_force, &other.mean_force, factor);
        add(&mut self.force_drop, &other.force_drop, factor);
        add(&mut self.node_force, &other.node_force, factor);
        add(
            &mut self.distributed_moment,
            &other.distributed_moment,
            factor,
        );
        self.body_loads
            .extend(other.body_loads.iter().map(|b| BodyLoad {
                world: factor * b.world,
                body: b.body.clone(),
            }));
        self.node_pairs
            .extend(other.node_pairs.iter().map(|p| NodePair {
                world: factor * p.world,
                ..*p
            }));
        self.node_moments
            .extend(other.node_moments.iter().map(|m| NodeMoment {
                moment: factor * m.moment,
                ..*m
            }));
        self.densities.extend(other.densities.iter().map(|d| {
            Arc::new(Scaled {
                factor,
                density: d.clone(),
            }) as Arc<dyn CurvatureDensity>
        }));
    }

    /// Add the node terms (body-vector potentials and dead moments at
    /// nodes, scaled by `load`) to the residual and its Jacobian.
    #[inline]
    pub fn add_node_terms(
        &self,
        q: &[Quat],
        load: f64,
        g: &mut [Vector3<f64>],
        mut jac: Option<&mut crate::blocktri::BlockTridiagonal>,
    ) {
        for p in &self.node_pairs {
            if p.world != Vector3::zeros() && p.body != Vector3::zeros() {
                let (_, grad, block) =
                    crate::quat::body_vector_terms(q[p.node], &(-load * p.world), &p.body);
                g[p.node - 1] += grad;
                if let Some(jac) = jac.as_deref_mut() {
                    jac.diag[p.node - 1] += block;
                }
            }
        }
        for m in &self.node_moments {
            if m.moment != Vector3::zeros() {
                let (grad, block) = super::dead_moment(q[m.node], &(load * m.moment));
                g[m.node - 1] += grad;
                if let Some(jac) = jac.as_deref_mut() {
                    jac.diag[m.node - 1] += block;
                }
            }
        }
    }

    /// The node terms' potential at load scale `load` [J] (dead moments have none).
    pub fn node_energy(&self, q: &[Quat], load: f64) -> f64 {
        self.node_pairs
            .iter()
            .map(|p| crate::quat::body_vector_terms(q[p.node], &(-load * p.world), &p.body).0)
            .sum()
    }
}

/// A curvature density times a factor.
#[derive(Debug)]
struct Scaled {
    factor: f64,
    density: Arc<dyn CurvatureDensity>,
}

impl CurvatureDensity for Scaled {
    fn acts_on(&self, element: usize) -> bool {
        self.density.acts_on(element)
    }

    fn density(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<(f64, Vector3<f64>, Matrix3<f64>)> {
        let (v, m, k) = self.density.density(element, s, omega, scale)?;
        Some((self.factor * v, self.factor * m, self.factor * k))
    }

    fn moment(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<Vector3<f64>> {
        Some(self.factor * self.density.moment(element, s, omega, scale)?)
    }

    fn value(&self, element: usize, s: f64, omega: &Vector3<f64>, scale: f64) -> Option<f64> {
        Some(self.factor * self.density.value(element, s, omega, scale)?)
    }
}
