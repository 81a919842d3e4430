//! The discretisation of the backbone: how a scheme turns the rod and what
//! the terms put on it ([`Loading`]) into unknowns, a residual with its
//! banded Jacobian, positions, an energy and the shape between the nodes.
//!
//! ```text
//! loading.rs   what a scheme integrates: the kinds of effect the terms fill in
//! fd2.rs       the seed's finite differences, second order
//! fe4.rs       quadratic elements with condensed internal nodes, fourth order
//! ```
//!
//! A scheme never names a term: it integrates the kinds of [`Loading`] (an
//! elastic law, curvature densities, the internal force, body-vector
//! potentials, dead moments). The solvers call it only through the
//! [`Discretisation`] trait; the one choice of a scheme is [`for_scheme`].
//!
//! The unknowns of every scheme are the node rotations `q_1..q_n` (`q_0` is
//! the clamped base), moved by the body-frame update `q_j <- q_j exp(theta_j
//! / 2)`; the residual of node `j` is `dPi/dtheta_j` plus the dead moments'
//! virtual work, and the Jacobian its exact derivative under the same update
//! (block-tridiagonal). A scheme with interior unknowns condenses them and
//! keeps their last values in an [`Interior`] that the caller owns (the
//! solver's workspace): the discretisation itself holds no state.

pub mod fd2;
pub mod fe4;
mod loading;

pub use loading::{BodyLoad, CurvatureDensity, Loading, NodeMoment, NodePair};

use crate::blocktri::BlockTridiagonal;
use crate::mesh::Mesh;
use crate::quat::Quat;
use nalgebra::{DMatrix, Matrix3, Vector3};

crate::status::named_enum! {
    /// How a solution's nodes were computed: its discretisation.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Scheme {
        /// The seed's finite differences: one rotation a node, the curvature
        /// of each element from its two nodes, the exact mean tangent. Second
        /// order.
        Fd2 => "fd2",
        /// Quadratic elements of the rotation (an internal node at each
        /// element's middle, condensed out), the elastic energy by two-point
        /// Gauss quadrature and the loads by Simpson: fourth order at the nodes.
        Fe4 => "fe4",
        /// Shooting's integrator (classic Runge-Kutta on the rod's equations,
        /// `method = "shooting"`): the scheme of its solutions, not a setting.
        Rk4 => "rk4",
    }
}

impl Default for Scheme {
    /// The seed's finite differences.
    fn default() -> Self {
        Scheme::Fd2
    }
}

impl Scheme {
    /// The order of convergence of the node positions as `n` grows.
    pub fn order(self) -> i32 {
        match self {
            Scheme::Fd2 => 2,
            Scheme::Fe4 | Scheme::Rk4 => 4,
        }
    }

    /// Whether its solutions have internal nodes (one an element), without
    /// which they have no shape between their nodes.
    pub fn has_internal_nodes(self) -> bool {
        self == Scheme::Fe4
    }
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Scheme {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        Scheme::ALL
            .into_iter()
            .find(|scheme| scheme.name() == s)
            .ok_or_else(|| {
                crate::error::Error::argument(
                    "scheme",
                    format!("unknown scheme '{s}' (expected 'fd2' or 'fe4')"),
                )
            })
    }
}

/// The discretisation of `scheme` (shooting's solutions are judged on the
/// finite differences' nodes): the one place a scheme is chosen.
pub fn for_scheme(scheme: Scheme) -> Box<dyn Discretisation> {
    match scheme {
        Scheme::Fd2 | Scheme::Rk4 => Box::new(fd2::Fd2),
        Scheme::Fe4 => Box::new(fe4::Fe4::default()),
    }
}

/// The rod a scheme discretises: where its nodes sit, what the terms put on
/// it, and its clamped base.
#[derive(Debug, Clone)]
pub struct Rod {
    pub mesh: Mesh,
    pub loading: Loading,
    /// Orientation of the clamped base, `q_0`.
    pub base: Quat,
    /// Position of node 0 [m], world frame.
    pub base_position: Vector3<f64>,
}

impl Rod {
    /// Number of elements.
    #[inline(always)]
    pub fn n(&self) -> usize {
        self.mesh.n()
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
}

/// Forces that act at nodes besides the loading's (the reactions of held
/// points, which are unknowns of the solve): `forces[c]` at `nodes[c]`, world
/// frame [N]. Each counts in the internal force of every element before it.
#[derive(Debug, Clone, Copy, Default)]
pub struct NodeForces<'a> {
    pub nodes: &'a [usize],
    pub forces: &'a [Vector3<f64>],
}

impl NodeForces<'_> {
    /// No forces.
    pub const NONE: NodeForces<'static> = NodeForces {
        nodes: &[],
        forces: &[],
    };

    /// Whether there are none.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.forces.is_empty()
    }

    /// The sum of the forces at nodes `>= node`: their share of the internal
    /// force of element `node` (and of every node before it).
    #[inline]
    pub fn from_node(&self, node: usize) -> Vector3<f64> {
        self.nodes
            .iter()
            .zip(self.forces)
            .filter(|(k, _)| **k >= node)
            .map(|(_, f)| *f)
            .sum()
    }
}

/// The interior unknowns of each element at their last evaluation, condensed
/// out of the scheme's equations (fourth order: the internal nodes, with
/// their linear response to the element's ends). A cache owned by the caller
/// (the solver's workspace): it starts the next evaluation's inner Newton
/// iteration and lets the positions and the held points' rows reuse the
/// interior of the residual just evaluated. Empty for a scheme without
/// interior unknowns; the answer never depends on what it held.
#[derive(Debug, Clone, Default)]
pub struct Interior {
    pub(crate) mids: Vec<Option<fe4::MidState>>,
}

impl Interior {
    /// A cache of `n` elements, empty.
    pub fn new(n: usize) -> Self {
        Interior {
            mids: vec![None; n],
        }
    }

    /// A cache without elements: for a scheme that has no interior unknowns.
    pub fn none() -> Self {
        Interior::default()
    }

    /// Whether it has no elements (a scheme without interior unknowns).
    pub fn is_none(&self) -> bool {
        self.mids.is_empty()
    }

    /// Forget every element's interior (after the loads changed: they
    /// belonged to the old ones), keeping the buffer.
    pub fn forget(&mut self) {
        self.mids.iter_mut().for_each(|m| *m = None);
    }
}

/// A discretisation of the backbone (see the module's documentation). Every
/// method takes the rod it discretises; the methods with an [`Interior`]
/// read and update the caller's cache of the interior unknowns.
pub trait Discretisation: std::fmt::Debug + Send + Sync {
    /// Which scheme this is.
    fn scheme(&self) -> Scheme;

    /// The order of convergence of the node positions as `n` grows.
    fn order(&self) -> i32 {
        self.scheme().order()
    }

    /// A copy of this discretisation.
    fn boxed(&self) -> Box<dyn Discretisation>;

    /// Derive what the scheme keeps of the rod (its rest curvature at the
    /// quadrature points): after the rod's elastic law changed.
    fn prepare(&mut self, rod: &Rod);

    /// An empty cache of the interior unknowns of `n` elements.
    fn interior(&self, n: usize) -> Interior {
        let _ = n;
        Interior::none()
    }

    /// Residual `g` (node `j` at index `j - 1`) at `q`, the loading scaled
    /// by `load` (not the elastic law) with the forces `held` added, and
    /// with `jac` its exact Jacobian. Every entry of `g` and `jac` is written.
    #[allow(clippy::too_many_arguments)]
    fn evaluate(
        &self,
        rod: &Rod,
        q: &[Quat],
        load: f64,
        held: NodeForces,
        interior: &mut Interior,
        g: &mut [Vector3<f64>],
        jac: Option<&mut BlockTridiagonal>,
    );

    /// `dg` along a change of the loading: `tangent` holds the derivatives
    /// of the loading's entries (a term's derivative in one of its
    /// parameters); the residual is linear in every kind but the elastic law,
    /// whose moment `K (omega - omega0)` changes by `dK (omega - omega0) - K
    /// domega0` (`tangent.stiffness`, `tangent.rest_curvature`). At the
    /// interior of the last evaluation with the Jacobian at `q` (the forces
    /// `held` on it): with interior unknowns, the total derivative, the
    /// interior following the change; `interior_shift` then receives each
    /// element's interior move (empty without interior unknowns).
    #[allow(clippy::too_many_arguments)]
    fn residual_derivative(
        &self,
        rod: &Rod,
        q: &[Quat],
        held: NodeForces,
        tangent: &Loading,
        interior: &mut Interior,
        dg: &mut [Vector3<f64>],
        interior_shift: &mut Vec<Vector3<f64>>,
    );

    /// [`Discretisation::residual_derivative`] along each of `tangents`:
    /// `dg` holds their columns one after another (`n` entries each) and
    /// `interior_shift` their interiors' moves likewise (empty without
    /// interior unknowns). A drive's columns (a sensitivity, the coupled
    /// iteration) come so in one pass; a scheme whose columns share each
    /// element's kinematics overrides it.
    #[allow(clippy::too_many_arguments)]
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
        derivatives_one_by_one(self, rod, q, held, tangents, interior, dg, interior_shift);
    }

    /// `d r_k / dp` of the node positions `k = 0..=n` at fixed node
    /// rotations, from the interior's move `interior_shift` (zero without
    /// interior unknowns).
    fn position_derivative(
        &self,
        rod: &Rod,
        q: &[Quat],
        interior: &mut Interior,
        interior_shift: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        let _ = (rod, q, interior, interior_shift);
        out.iter_mut().for_each(|x| *x = Vector3::zeros());
    }

    /// Node positions `r_0..r_n` (the interior of the full loads).
    fn positions(&self, rod: &Rod, q: &[Quat], interior: &mut Interior, out: &mut [Vector3<f64>]);

    /// Node positions of the chain `q` without loads (the load path's start).
    fn unloaded_positions(&self, rod: &Rod, q: &[Quat], out: &mut [Vector3<f64>]);

    /// The interior nodes of the elements at `q`, one an element (as
    /// [`Discretisation::positions`] draws them); empty without them.
    fn internal_nodes(&self, rod: &Rod, q: &[Quat], interior: &mut Interior) -> Vec<Quat> {
        let _ = (rod, q, interior);
        Vec::new()
    }

    /// Whether every interior unknown of the last evaluation with the
    /// Jacobian sits at a minimum of its element's potential (the condensed
    /// Hessian then decides stability); true without interior unknowns.
    fn interior_at_minima(&self, interior: &Interior) -> bool {
        let _ = interior;
        true
    }

    /// Total potential at load scale `load` [J] (dead moments have none).
    fn energy(&self, rod: &Rod, q: &[Quat], load: f64, interior: &mut Interior) -> f64;

    /// The unloaded rod at rest from its base: every element at its rest
    /// curvature, so that the elastic energy and the residual vanish.
    fn rest_shape(&self, rod: &Rod) -> Vec<Quat>;

    /// `d r_k / d theta_j` for every node `j` (index `j - 1`; zero beyond
    /// `k`): the Jacobian of node `k`'s position, the interior following the
    /// nodes as the last evaluation with the Jacobian linearised it.
    fn position_jacobian(
        &self,
        rod: &Rod,
        q: &[Quat],
        k: usize,
        interior: &Interior,
        out: &mut [Matrix3<f64>],
    );

    /// `d (r_i - r_(i-1)) / d theta` of every element's chord, the blocks
    /// of its start node and of its end node (element `i` at index `i - 1`):
    /// the banded form of the positions' Jacobian, for the KKT step with
    /// many contacts. `false` where a chord is not a function of its two
    /// nodes alone (interior unknowns).
    fn chord_jacobians(
        &self,
        _rod: &Rod,
        _q: &[Quat],
        _out: &mut [(Matrix3<f64>, Matrix3<f64>)],
    ) -> bool {
        false
    }

    /// How the held nodes `nodes` move with their reactions at fixed node
    /// rotations (`dh_c / dR_c'`, 3x3 blocks of a 3m x 3m matrix), through
    /// the interior unknowns the reactions load; `None` where they do not
    /// move (no interior unknowns).
    fn held_point_compliance(
        &self,
        rod: &Rod,
        q: &[Quat],
        nodes: &[usize],
        interior: &Interior,
    ) -> Option<DMatrix<f64>> {
        let _ = (rod, q, nodes, interior);
        None
    }
}

/// [`Discretisation::residual_derivatives`] column by column.
#[allow(clippy::too_many_arguments)]
pub(crate) fn derivatives_one_by_one<D: Discretisation + ?Sized>(
    disc: &D,
    rod: &Rod,
    q: &[Quat],
    held: NodeForces,
    tangents: &[Loading],
    interior: &mut Interior,
    dg: &mut [Vector3<f64>],
    interior_shift: &mut Vec<Vector3<f64>>,
) {
    interior_shift.clear();
    // Allocates only for a scheme with interior unknowns.
    let mut one = Vec::new();
    for (tangent, column) in tangents.iter().zip(dg.chunks_exact_mut(rod.n())) {
        disc.residual_derivative(rod, q, held, tangent, interior, column, &mut one);
        interior_shift.extend_from_slice(&one);
    }
}

impl Clone for Box<dyn Discretisation> {
    fn clone(&self) -> Self {
        self.boxed()
    }
}

/// The residual `-R(q)^T M` of a dead moment `M` (world frame) at a node and
/// its block under the body-frame update: a dead moment has no potential in
/// 3D, so the block is not symmetric.
#[inline(always)]
pub(crate) fn dead_moment(q: Quat, moment: &Vector3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
    let m = q.inverse_rotate(*moment);
    (-m, -crate::quat::skew(&m))
}
