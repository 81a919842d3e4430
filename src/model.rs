//! The discrete rod a solver works on: a scene's terms on a mesh, discretised
//! by a scheme (`crate::disc`), with its held points and the load path.
//!
//! Unknowns are the node quaternions `q_1..q_n` (`q_0` is the clamped base),
//! moved by the body-frame update `q_j <- q_j * exp(theta_j / 2)`, which
//! keeps `|q_j| = 1` exactly; the residual of node `j` is `dPi/dtheta_j` plus
//! the dead moments' virtual work, and the Jacobian its exact derivative
//! under the same update (see `crate::disc`).
//!
//! Every load is scaled by `lambda`, the load continuation parameter;
//! `lambda = 0` is the unloaded rod in its rest shape (a chain of arcs, an
//! exact equilibrium), so that continuation follows the loading of the rod
//! from rest, as an experiment would; the rest curvature is not scaled.
//! `lambda = 1` is the scene.
//!
//! The schemes' interior unknowns (fe4's internal nodes) live in an
//! [`Interior`] that the caller owns (a solver's workspace): every method
//! that evaluates the scheme takes it.

use crate::blocktri::BlockTridiagonal;
use crate::contact::{Crossing, Obstacle, Port};
pub use crate::disc::Scheme;
use crate::disc::{for_scheme, Discretisation, Interior, NodeForces, Rod};
use crate::mesh::Mesh;
use crate::quat::Quat;
pub use crate::scene::reach::clamped_end_deficit;
use crate::scene::{Scene, TipCondition};
use crate::terms::Terms;
use nalgebra::{Matrix3, Vector3};

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

/// A port the backbone slides through (see `contact::Port`), with the
/// start of its load path: where the rest shape crosses its plane.
#[derive(Debug, Clone, PartialEq)]
pub struct PortConstraint {
    pub port: Port,
    /// Where the unloaded rest shape crosses the port's plane; `None` where
    /// it does not (the scene is refused).
    pub rest: Option<Vector3<f64>>,
}

impl PortConstraint {
    /// The point the backbone passes through at load scale `lambda`, moved
    /// linearly from the rest shape's crossing.
    pub fn target_at(&self, lambda: f64) -> Vector3<f64> {
        let p = self.port.position;
        self.rest.map_or(p, |rest| rest + lambda * (p - rest))
    }

    /// The rows' residuals `b_i . (c - p(lambda))` at the crossing `c`.
    pub fn residual(&self, crossing: &Crossing, lambda: f64) -> [f64; 2] {
        let off = crossing.point - self.target_at(lambda);
        self.port.frame().map(|b| b.dot(&off))
    }
}

/// A scene discretised by `n` elements (see [`Mesh`]: equal within a section).
#[derive(Debug, Clone)]
pub struct RodModel {
    /// The rod: mesh, loading and base.
    rod: Rod,
    /// Its discretisation.
    disc: Box<dyn Discretisation>,
    /// The scene's effects, from which the loading is made.
    terms: Terms,
    /// The unloaded rest shape (see [`RodModel::rest_shape`]).
    rest_nodes: Vec<Quat>,
    /// Smallest stiffness about each axis `(kx, ky, kz)` [N m^2]: it sets
    /// the residual's scale.
    stiffness: Vector3<f64>,
    /// Held nodes, by increasing node (guides, then a pinned or clamped tip),
    /// and their nodes alone.
    constraints: Vec<PointConstraint>,
    held_nodes: Vec<usize>,
    /// Orientation of a clamped tip, on the rest tip's side of the quaternion sphere.
    clamped_tip: Option<Quat>,
    /// Tip orientation of the start of the load path.
    rest_tip: Quat,
    /// The second leg of a held scene's load path (see `solver::load_path`):
    /// the loads stay at full scale and `lambda` moves only the held points
    /// and a clamped tip's orientation, from where the loaded free rod put them.
    loads_held_fixed: bool,
    /// Largest bending moment the applied loads can exert, times `L` over the
    /// smallest stiffness (dimensionless): the curvature scale `kappa L` of
    /// the loaded rod, which sets the round-off floor of the residual.
    load_parameter: f64,
    /// What the solves read often, kept: the residual's scale (see
    /// [`RodModel::residual_scale`]), the round-off floor's factors of the
    /// mesh and the stiffness (see [`RodModel::roundoff_floor`]), the largest
    /// rest turn of an element and the nodes where the shape is not smooth.
    residual_scale: Vector3<f64>,
    per_length: f64,
    stiffness_spread: f64,
    max_rest_turn: f64,
    breaks: Vec<usize>,
    /// Rigid obstacles the rod may touch, and the rod's radius [m]: the
    /// contact rows of the constrained solve (see `solver::contact`).
    obstacles: Vec<Obstacle>,
    contact_radius: f64,
    /// Each obstacle's Coulomb coefficient (one an obstacle).
    friction: Vec<f64>,
    /// Ports the backbone slides through: two rows each (see `solver::port`).
    ports: Vec<PortConstraint>,
}

impl RodModel {
    /// Discretise `scene` with `n` elements by the second-order scheme
    /// (validated by the caller: `n` is a positive multiple of the number of
    /// sections that puts every located input on a node).
    pub fn new(scene: &Scene, n: usize) -> Self {
        let mesh = scene.mesh(n);
        let terms = Terms::new(scene, &mesh);
        let loading = terms.loading(&mesh);
        let rod = Rod {
            mesh,
            loading,
            base: scene.base_quaternion,
            base_position: scene.base_position,
        };
        let mut constraints: Vec<PointConstraint> = scene
            .guides
            .iter()
            .map(|g| PointConstraint {
                node: rod.mesh.nearest_node(g.s),
                target: g.position,
                rest: Vector3::zeros(),
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
        let held_nodes = constraints.iter().map(|c| c.node).collect();
        let mut model = RodModel {
            disc: for_scheme(Scheme::default()),
            terms,
            rest_nodes: Vec::new(),
            stiffness: scene.stiffness(),
            constraints,
            held_nodes,
            clamped_tip,
            rest_tip: rod.base,
            loads_held_fixed: false,
            load_parameter: 0.0,
            residual_scale: Vector3::zeros(),
            per_length: 0.0,
            stiffness_spread: 1.0,
            max_rest_turn: 0.0,
            breaks: Vec::new(),
            obstacles: scene.obstacles.clone(),
            contact_radius: scene.contact_radius(),
            friction: (0..scene.obstacles.len())
                .map(|i| scene.friction.get(i).copied().unwrap_or(0.0))
                .collect(),
            ports: scene
                .ports
                .iter()
                .map(|port| PortConstraint {
                    port: port.clone(),
                    rest: None,
                })
                .collect(),
            rod,
        };
        model.residual_scale = model.stiffness / model.length();
        // `L / h` of the shortest element: `n` when the elements are equal.
        let ds = model.ds();
        let shortest = model
            .mesh()
            .element_lengths()
            .iter()
            .fold(ds, |a, b| a.min(*b));
        model.per_length = n as f64 * ds / shortest;
        model.stiffness_spread = model
            .rod
            .loading
            .stiffness
            .iter()
            .map(|k| k.component_div(&model.stiffness).max())
            .fold(1.0, f64::max);
        model.refresh_load_parameter();
        model.refresh_rest();
        model
    }

    /// The same rod in another discretisation.
    pub fn with_scheme(mut self, scheme: Scheme) -> Self {
        if scheme != self.disc.scheme() {
            self.disc = for_scheme(scheme);
            self.refresh_rest();
        }
        self
    }

    /// Number of elements.
    #[inline(always)]
    pub fn n(&self) -> usize {
        self.rod.n()
    }

    /// Length `L` of the rod [m].
    #[inline(always)]
    pub fn length(&self) -> f64 {
        self.rod.arc(self.n())
    }

    /// The mean element length `L / n` [m]: every element's unless the
    /// sections have lengths of their own (see [`RodModel::h`]).
    #[inline(always)]
    pub fn ds(&self) -> f64 {
        self.length() / self.n() as f64
    }

    /// The scheme.
    pub fn scheme(&self) -> Scheme {
        self.disc.scheme()
    }

    /// Its discretisation.
    pub fn discretisation(&self) -> &dyn Discretisation {
        self.disc.as_ref()
    }

    /// The rod: mesh, loading and base.
    pub fn rod(&self) -> &Rod {
        &self.rod
    }

    /// The scene's effects.
    pub fn terms(&self) -> &Terms {
        &self.terms
    }

    /// Orientation of the clamped base, `q_0`.
    pub fn base(&self) -> Quat {
        self.rod.base
    }

    /// Position of node 0 [m], world frame.
    pub fn base_position(&self) -> Vector3<f64> {
        self.rod.base_position
    }

    /// Smallest stiffness `(kx, ky, kz)` about each axis [N m^2].
    pub fn stiffness(&self) -> Vector3<f64> {
        self.stiffness
    }

    /// Moment scale of each body-frame torque row, `k_c / L` [N m]: a residual
    /// row over its own stiffness is the angle-like error that row leaves, so
    /// a stiffness ratio of 1e10 neither hides a soft row's imbalance nor
    /// demands round-off from a stiff one.
    pub fn residual_scale(&self) -> Vector3<f64> {
        self.residual_scale
    }

    /// The loads' curvature scale `kappa L` (see the field).
    pub fn load_parameter(&self) -> f64 {
        self.load_parameter
    }

    /// The dead moment at the tip node, world frame [N m]: the tip moment
    /// and point loads' moments there.
    pub fn tip_moment(&self) -> Vector3<f64> {
        let n = self.n();
        let points = &self.terms.moments.points;
        self.terms.moments.tip
            + points
                .iter()
                .filter(|(node, _)| *node == n)
                .map(|(_, m)| *m)
                .sum::<Vector3<f64>>()
    }

    /// Held nodes, by increasing node.
    pub fn constraints(&self) -> &[PointConstraint] {
        &self.constraints
    }

    /// Orientation of a clamped tip.
    pub fn clamped_tip(&self) -> Option<Quat> {
        self.clamped_tip
    }

    /// Whether the loads stay at full scale along the path (its second leg).
    pub fn loads_held_fixed(&self) -> bool {
        self.loads_held_fixed
    }

    /// Length of element `i` (from 1) [m].
    #[inline(always)]
    pub fn h(&self, i: usize) -> f64 {
        self.rod.h(i)
    }

    /// Arc length of node `i` [m].
    #[inline(always)]
    pub fn arc(&self, i: usize) -> f64 {
        self.rod.arc(i)
    }

    /// Where the nodes sit.
    pub fn mesh(&self) -> &Mesh {
        &self.rod.mesh
    }

    /// A cache of the scheme's interior unknowns for this rod (empty for
    /// `fd2`), for the evaluations of a caller without a workspace.
    pub fn new_interior(&self) -> Interior {
        self.disc.interior(self.n())
    }

    /// `load_parameter` from the terms' moments.
    fn refresh_load_parameter(&mut self) {
        let length = self.length();
        self.load_parameter = self.terms.moment_scale(length) * length / self.stiffness.min();
    }

    /// The loading again from the terms (after a drive changed), and the
    /// load parameter.
    fn reload(&mut self) {
        self.rod.loading = self.terms.loading(&self.rod.mesh);
        self.refresh_load_parameter();
        self.refresh_breaks();
    }

    /// How much stiffer than the residual's scale ([`RodModel::residual_scale`],
    /// the softest section's stiffness) any element is about the same axis:
    /// at least 1. A row's round-off is that of the elastic moments meeting
    /// there, so a section 100 times stiffer than the scale rounds 100 times
    /// larger relative to it.
    fn stiffness_spread(&self) -> f64 {
        self.stiffness_spread
    }

    /// Set the tendons' tensions in place, in the scene's order (checked by
    /// the caller): nothing else of the discretisation depends on them. The
    /// interiors a caller keeps belonged to the old ones: forget them.
    /// Move the clamped base to `p` [m] (the rest shape, and so where the
    /// held points and ports start their load paths, with it).
    pub(crate) fn set_base_position(&mut self, p: Vector3<f64>) {
        self.rod.base_position = p;
        self.refresh_rest();
    }

    pub(crate) fn set_tensions(&mut self, tensions: &[f64]) {
        self.terms.tendons.set_tensions(tensions);
        // Only their curvature density changes (the IK in tension space sets
        // them at every trial): the rest of the loading and the breaks stay.
        self.terms
            .refresh_densities(&self.rod.mesh, &mut self.rod.loading);
        self.refresh_load_parameter();
    }

    /// Set the field in place.
    pub(crate) fn set_magnetic_field(&mut self, field: Vector3<f64>) {
        self.terms.magnets.field = field;
        self.reload();
    }

    /// Set the tip force and moment in place.
    pub(crate) fn set_tip_load(&mut self, force: Vector3<f64>, moment: Vector3<f64>) {
        self.terms.tip_force.force = force;
        self.terms.moments.set_tip(moment);
        self.reload();
    }

    /// Replace the rest curvature, one `[kappa_x, kappa_y]` per equal section
    /// (the number of sections must divide `n`).
    pub fn set_section_curvature(&mut self, sections: &[[f64; 2]]) {
        debug_assert_eq!(self.n() % sections.len().max(1), 0);
        self.terms.elastic.set_rest_curvature(sections, self.n());
        self.terms
            .elastic
            .rest_curvature
            .expand_into(&mut self.rod.loading.rest_curvature);
        self.refresh_rest();
    }

    /// Whether every interior unknown of the last evaluation with the
    /// Jacobian sits at a minimum of its element's potential (the condensed
    /// Hessian then decides stability); true for `fd2`.
    pub fn interior_at_minima(&self, interior: &Interior) -> bool {
        self.disc.interior_at_minima(interior)
    }

    /// The unloaded rod in its rest shape: each element at exactly its rest
    /// curvature (with the fourth-order scheme: at both Gauss points), so the
    /// elastic energy and the residual vanish (the load path starts exactly).
    pub fn rest_shape(&self) -> Vec<Quat> {
        self.rest_nodes.clone()
    }

    /// Recompute what depends on the rest shape: the scheme's own rest
    /// curvature, where the rest shape puts the held nodes (the load path's
    /// start) and its tip orientation (a clamped tip's start, whose
    /// quaternion is taken on the same side of the sphere).
    fn refresh_rest(&mut self) {
        self.disc.prepare(&self.rod);
        let rest = self.disc.rest_shape(&self.rod);
        if !self.constraints.is_empty() || !self.ports.is_empty() {
            let mut positions = vec![Vector3::zeros(); self.n() + 1];
            self.disc
                .unloaded_positions(&self.rod, &rest, &mut positions);
            for c in &mut self.constraints {
                c.rest = positions[c.node];
            }
            for p in &mut self.ports {
                p.rest = p.port.crossing(&positions).map(|c| c.point);
            }
        }
        self.rest_tip = rest[self.n()];
        self.max_rest_turn = self
            .rod
            .loading
            .rest_curvature
            .iter()
            .enumerate()
            .map(|(i, k)| self.h(i + 1) * k.norm())
            .fold(0.0, f64::max);
        self.refresh_breaks();
        if let Some(q) = self.clamped_tip.as_mut() {
            if q.dot(self.rest_tip) < 0.0 {
                *q = -*q;
            }
        }
        self.rest_nodes = rest;
    }

    /// The interior nodes where the shape is not smooth (see
    /// `Term::breaks`; also where the element length changes and at held
    /// points, whose reactions are point forces).
    pub fn breaks(&self) -> &[usize] {
        &self.breaks
    }

    fn refresh_breaks(&mut self) {
        let n = self.n();
        let mut out = std::mem::take(&mut self.breaks);
        out.clear();
        self.terms.breaks(self.mesh(), &mut out);
        crate::terms::jumps(self.mesh().element_lengths(), &mut out);
        out.extend(&self.held_nodes);
        out.retain(|j| (1..n).contains(j));
        out.sort_unstable();
        out.dedup();
        self.breaks = out;
    }

    /// True when nothing loads the rod: the rest shape is the exact equilibrium.
    pub fn is_trivial(&self) -> bool {
        self.terms.vanish()
            && self.obstacles.is_empty()
            && self.ports.is_empty()
            && self.constraints.iter().all(|c| c.target == c.rest)
            && self.clamped_tip.is_none_or(|q| q == self.rest_tip)
    }

    /// The largest ratio of the distance between consecutive held points (the
    /// base first) to the rod between them: 1 is full reach.
    pub fn tightest_reach(&self) -> f64 {
        let mut from = (0usize, self.base_position());
        let mut ratio: f64 = 0.0;
        for c in &self.constraints {
            let arc = self.arc(c.node) - self.arc(from.0);
            ratio = ratio.max((c.target - from.1).norm() / arc);
            from = (c.node, c.target);
        }
        ratio
    }

    /// Whether the scene has unknown reactions (held nodes, a clamped tip or
    /// obstacles, whose contact forces are unknowns).
    pub fn is_constrained(&self) -> bool {
        !self.constraints.is_empty() || self.clamped_tip.is_some() || self.has_contact()
    }

    /// Whether the rod meets its surroundings (obstacles or ports): rows
    /// whose place on the rod moves, so that the forces are gathered at
    /// the positions of each evaluation (see `solver::contact`).
    pub fn has_contact(&self) -> bool {
        self.has_obstacles() || !self.ports.is_empty()
    }

    /// The ports the backbone slides through.
    pub fn ports(&self) -> &[PortConstraint] {
        &self.ports
    }

    /// The obstacles the rod may touch.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Whether there are obstacles.
    pub fn has_obstacles(&self) -> bool {
        !self.obstacles.is_empty()
    }

    /// Obstacle `o`'s Coulomb friction coefficient.
    pub fn friction(&self, o: usize) -> f64 {
        self.friction[o]
    }

    /// Whether any obstacle or port has friction: the answer then depends
    /// on the loading history (see `solver::friction`).
    pub fn has_friction(&self) -> bool {
        self.friction.iter().any(|mu| *mu > 0.0) || self.frictional_ports().next().is_some()
    }

    /// The ports with friction, by index: each has a third row, its
    /// friction along the rod (see `solver::port`).
    pub fn frictional_ports(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.ports.len()).filter(|&j| self.ports[j].port.friction > 0.0)
    }

    /// The first obstacle the unloaded rest shape passes into (a node
    /// deeper than a nanometre a metre): the load path cannot start there.
    pub fn obstacle_at_rest(&self) -> Option<usize> {
        if self.obstacles.is_empty() {
            return None;
        }
        let mut nodes = vec![Vector3::zeros(); self.n() + 1];
        self.positions(&self.rest_nodes, &mut self.new_interior(), &mut nodes);
        let depth = 1e-9 * self.length();
        (0..self.obstacles.len()).find(|&o| {
            let obstacle = &self.obstacles[o];
            let gap = |p: &Vector3<f64>| obstacle.proximity(p).gap - self.contact_radius;
            nodes.iter().any(|p| gap(p) < -depth)
        })
    }

    /// The rod's radius for contact [m].
    pub fn contact_radius(&self) -> f64 {
        self.contact_radius
    }

    /// Another radius for contact [m], of either sign: every gap offset by
    /// the change (the approach of `solver/homotopy.rs` moves the obstacles
    /// in by growing it from below the rod's own).
    pub(crate) fn set_contact_radius(&mut self, radius: f64) {
        self.contact_radius = radius;
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
            held_nodes: Vec::new(),
            clamped_tip: None,
            ..self.clone()
        }
    }

    /// The second leg of a held scene's load path: the loads at full scale,
    /// the held points (and a clamped tip's orientation) moved by `lambda`
    /// from where the chain `q` (the loaded free rod) puts them.
    pub fn holding_from(&self, q: &[Quat], interior: &mut Interior) -> RodModel {
        let mut model = self.clone();
        let mut positions = vec![Vector3::zeros(); self.n() + 1];
        self.positions(q, interior, &mut positions);
        for c in &mut model.constraints {
            c.rest = positions[c.node];
        }
        // A port holds the rod on both legs: at its place already.
        for p in &mut model.ports {
            p.rest = Some(p.port.position);
        }
        model.rest_tip = q[self.n()];
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
            Some(target) => (0..=self.n())
                .map(|j| slerp(self.base(), target, j as f64 / self.n() as f64))
                .collect(),
        }
    }

    /// The straight rod along the base tangent.
    pub fn straight(&self) -> Vec<Quat> {
        vec![self.base(); self.n() + 1]
    }

    /// The held points' reactions as forces at their nodes.
    fn held<'a>(&'a self, reactions: &'a [Vector3<f64>]) -> NodeForces<'a> {
        NodeForces {
            nodes: &self.held_nodes[..reactions.len().min(self.held_nodes.len())],
            forces: &reactions[..reactions.len().min(self.held_nodes.len())],
        }
    }

    /// Residual `g` (node `j` at index `j - 1`) at load scale `lambda`.
    pub fn residual(
        &self,
        q: &[Quat],
        lambda: f64,
        interior: &mut Interior,
        g: &mut [Vector3<f64>],
    ) {
        self.residual_with_reactions(q, lambda, &[], interior, g, None);
    }

    /// Residual and its exact Jacobian at load scale `lambda`.
    pub fn residual_jacobian(
        &self,
        q: &[Quat],
        lambda: f64,
        interior: &mut Interior,
        g: &mut [Vector3<f64>],
        jac: &mut BlockTridiagonal,
    ) {
        self.residual_with_reactions(q, lambda, &[], interior, g, Some(jac));
    }

    /// Residual with the constraint reactions (one per constraint, world frame)
    /// acting as point forces, and optionally its Jacobian in the rotations.
    pub fn residual_with_reactions(
        &self,
        q: &[Quat],
        lambda: f64,
        reactions: &[Vector3<f64>],
        interior: &mut Interior,
        g: &mut [Vector3<f64>],
        jac: Option<&mut BlockTridiagonal>,
    ) {
        let load = self.load_scale(lambda);
        let held = self.held(reactions);
        self.disc
            .evaluate(&self.rod, q, load, held, interior, g, jac);
    }

    /// Residual with the forces `held` at nodes besides the loads (the held
    /// points' reactions and the contact forces), and optionally its Jacobian.
    pub(crate) fn residual_with_forces(
        &self,
        q: &[Quat],
        lambda: f64,
        held: NodeForces,
        interior: &mut Interior,
        g: &mut [Vector3<f64>],
        jac: Option<&mut BlockTridiagonal>,
    ) {
        let load = self.load_scale(lambda);
        self.disc
            .evaluate(&self.rod, q, load, held, interior, g, jac);
    }

    /// `d g / d lambda`: the residual is affine in the load scale.
    pub fn residual_lambda_derivative(
        &self,
        q: &[Quat],
        interior: &mut Interior,
        out: &mut [Vector3<f64>],
        scratch: &mut [Vector3<f64>],
    ) {
        self.residual(q, 1.0, interior, out);
        self.residual(q, 0.0, interior, scratch);
        for (o, s) in out.iter_mut().zip(scratch.iter()) {
            *o -= s;
        }
    }

    /// `d g / d p` at the state `q` (reactions `reactions`) along the
    /// loading's tangent `tangent` (a term's derivative in a parameter, see
    /// [`Terms::derivative`]), and the interior's move with it.
    pub fn residual_derivative(
        &self,
        q: &[Quat],
        reactions: &[Vector3<f64>],
        tangent: &crate::disc::Loading,
        interior: &mut Interior,
        dg: &mut [Vector3<f64>],
        interior_shift: &mut Vec<Vector3<f64>>,
    ) {
        let held = self.held(reactions);
        self.disc
            .residual_derivative(&self.rod, q, held, tangent, interior, dg, interior_shift);
    }

    /// [`RodModel::residual_derivative`] along each of `tangents` at a free
    /// state, their columns one after another in `dg` (`n` each), their
    /// interiors' moves likewise in `interior_shift` (empty for `fd2`).
    pub fn residual_derivatives(
        &self,
        q: &[Quat],
        tangents: &[crate::disc::Loading],
        interior: &mut Interior,
        dg: &mut [Vector3<f64>],
        interior_shift: &mut Vec<Vector3<f64>>,
    ) {
        let held = self.held(&[]);
        self.disc
            .residual_derivatives(&self.rod, q, held, tangents, interior, dg, interior_shift);
    }

    /// `d r / d p` of the node positions at fixed rotations from the
    /// interior's move `interior_shift` (zero for `fd2`).
    pub fn position_derivative(
        &self,
        q: &[Quat],
        interior: &mut Interior,
        interior_shift: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        self.disc
            .position_derivative(&self.rod, q, interior, interior_shift, out);
    }

    /// `h_c = r_{node_c} - target_c(lambda)` for every constraint; `r` is scratch
    /// of `n + 1` positions.
    pub fn constraint_residual(
        &self,
        q: &[Quat],
        lambda: f64,
        interior: &mut Interior,
        r: &mut [Vector3<f64>],
        h: &mut [Vector3<f64>],
    ) {
        self.positions(q, interior, r);
        self.held_point_residual(r, lambda, h);
    }

    /// `h_c = r_{node_c} - target_c(lambda)` from the node positions `r`.
    pub fn held_point_residual(&self, r: &[Vector3<f64>], lambda: f64, h: &mut [Vector3<f64>]) {
        for (c, hc) in self.constraints.iter().zip(h.iter_mut()) {
            *hc = r[c.node] - c.target_at(lambda);
        }
    }

    /// `d r_k / d theta_j` for every node `j` (index `j - 1`; zero beyond `k`):
    /// the Jacobian of a held node's position (the interior following the
    /// nodes as the last evaluation with the Jacobian linearised it). The
    /// residual depends on that node's reaction `R` through `-(d r_k / d theta)^T R`.
    pub fn position_jacobian(
        &self,
        q: &[Quat],
        k: usize,
        interior: &Interior,
        out: &mut [Matrix3<f64>],
    ) {
        self.disc.position_jacobian(&self.rod, q, k, interior, out);
    }

    /// Every element's chord Jacobian, `(d/dtheta_(i-1), d/dtheta_i)` of
    /// `r_i - r_(i-1)` (see `Discretisation::chord_jacobians`); `false` for
    /// a scheme with interior unknowns.
    pub fn chord_jacobians(&self, q: &[Quat], out: &mut [(Matrix3<f64>, Matrix3<f64>)]) -> bool {
        self.disc.chord_jacobians(&self.rod, q, out)
    }

    /// How the held points move with their reactions at fixed node
    /// rotations (`dh_c / dR_c'`, 3x3 blocks of a 3m x 3m matrix), through
    /// the interior unknowns the reactions load; `None` for `fd2`.
    pub fn held_point_compliance(
        &self,
        q: &[Quat],
        interior: &Interior,
    ) -> Option<nalgebra::DMatrix<f64>> {
        self.disc
            .held_point_compliance(&self.rod, q, &self.held_nodes, interior)
    }

    /// Internal force at the nodes with the forces `held` at nodes (held
    /// points' reactions and contact forces): the force that the distal part
    /// exerts on the proximal one (a force at the tip node counts there).
    pub(crate) fn internal_forces(&self, held: NodeForces) -> Vec<Vector3<f64>> {
        let n = self.n();
        let mut distal = vec![Vector3::zeros(); n + 1];
        for (&k, f) in held.nodes.iter().zip(held.forces) {
            // Counted at every node before it, and at the tip's own.
            distal[k] += f;
        }
        let mut out = vec![Vector3::zeros(); n + 1];
        let mut sum = distal[n];
        out[n] = self.rod.loading.node_force[n] + sum;
        for j in (0..n).rev() {
            out[j] = self.rod.loading.node_force[j] + sum;
            sum += distal[j];
        }
        out
    }

    /// Internal force at the nodes with the reactions: the force that the distal
    /// part exerts on the proximal one (a held node's reaction counts distal).
    pub fn node_forces(&self, reactions: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let n = self.n();
        (0..=n)
            .map(|j| {
                let held: Vector3<f64> = self
                    .constraints
                    .iter()
                    .zip(reactions)
                    .filter(|(c, _)| c.node > j || c.node == n)
                    .map(|(_, r)| *r)
                    .sum();
                self.rod.loading.node_force[j] + held
            })
            .collect()
    }

    /// Dimensionless residual norm: the largest torque imbalance of a row over
    /// its own scale `k_c / L`. Not finite if any row is not (NaN is never
    /// dropped, so a broken state can never pass a tolerance).
    pub fn residual_norm(&self, g: &[Vector3<f64>]) -> f64 {
        let scale = self.residual_scale();
        let mut largest = 0.0f64;
        for x in g {
            let r = x.component_div(&scale).amax();
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
        let curvature = self.load_parameter + self.max_rest_turn * self.per_length;
        8.0 * f64::EPSILON * (self.per_length + curvature) * self.stiffness_spread()
    }

    /// The line-search merit: the sum of squares of the scaled torque rows.
    /// Newton's step is a descent direction of any fixed row weighting; this
    /// one keeps a stiff row from drowning the soft ones.
    pub fn merit(&self, g: &[Vector3<f64>]) -> f64 {
        let scale = self.residual_scale();
        g.iter()
            .map(|x| x.component_div(&scale).norm_squared())
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
        self.max_rest_turn
    }

    /// Node positions `r_0` (the base position), `r_i = r_{i-1} + h_i T_i`
    /// by the scheme's rule (fe4: with the interior of the full loads).
    pub fn positions(&self, q: &[Quat], interior: &mut Interior, out: &mut [Vector3<f64>]) {
        self.disc.positions(&self.rod, q, interior, out);
    }

    /// The internal nodes of the fourth-order scheme's elements at `q` (as
    /// [`RodModel::positions`] draws them); empty for the second-order one.
    pub fn internal_nodes(&self, q: &[Quat], interior: &mut Interior) -> Vec<Quat> {
        self.disc.internal_nodes(&self.rod, q, interior)
    }

    /// Total potential `Pi` (elastic energy minus the work of the dead forces) [J].
    /// A dead moment has no potential in 3D and is not included.
    pub fn energy(&self, q: &[Quat], interior: &mut Interior) -> f64 {
        self.energy_at(q, 1.0, interior)
    }

    /// `Pi` at load scale `lambda` (the applied loads scaled).
    pub fn energy_at(&self, q: &[Quat], lambda: f64, interior: &mut Interior) -> f64 {
        self.disc
            .energy(&self.rod, q, self.load_scale(lambda), interior)
    }
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
                "tip_moment": [0.2, 0.1, -0.3], "distributed_moment": [0.1, -0.4, 0.2],
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
                crate::disc::fd2::evaluate_in_chunks(
                    model.rod(),
                    &q,
                    0.8,
                    model.held(reactions),
                    &mut g,
                    Some(&mut jac),
                    chunk,
                );
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
