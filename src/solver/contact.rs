//! Frictionless contact with rigid obstacles: the contact rows of the
//! constrained solve (see `constrained.rs`) and their active set.
//!
//! Where a rod of radius `r` may touch an obstacle, its backbone keeps
//! `g(p) - r >= 0`, and a contact force `lambda nu` (`nu` the obstacle's
//! normal, `lambda >= 0`) acts only where the gap vanishes. The backbone of
//! the discrete rod is the polygon of its nodes (`fd2`: `r_k - r_(k-1) = h
//! t_k`), so the condition is enforced on every chord, not only at the
//! nodes: each obstacle has a *slot* at every free node and one inside every
//! element, at the point of the chord nearest the obstacle when it lies
//! strictly between the nodes (a sphere, a cylinder's edge, a box's corner
//! between two nodes). Every obstacle's gap is convex along a chord (a
//! signed distance to a convex set; a lumen's is concave, so its nearest
//! point is a node), so that point is the root of the gap's slope, bracketed.
//!
//! A force `lambda nu` at the point `(1 - s) r_(k-1) + s r_k` does the
//! virtual work of `(1 - s) lambda nu` at node `k - 1` and `s lambda nu` at
//! node `k`: the contacts act on the rod as point forces at nodes, like the
//! held points' reactions, and the row of a slot is `nu^T ((1 - s) D_(k-1) +
//! s D_k)` with `D_k = dr_k / dtheta`. The normal and the point are those of
//! the current state (their own change is left out of the Jacobian: exact
//! for a plane, a quasi-Newton step on a curved surface; the residual is
//! exact, so is the answer).
//!
//! The active set is primal-dual (a semismooth Newton on `min(lambda, g - r)
//! = 0`): at each step a slot is held on its obstacle if its force is not
//! negative and it was held, or if it penetrates; its row then asks the
//! linearised gap to vanish, and a free slot's force is zero. The solve has
//! converged only when the set no longer changes, so no held force is
//! negative and no free slot penetrates.
//!
//! The multipliers `lambda` live after the held points' reactions in the
//! workspace's `reactions` (the `x` entry of one vector a slot), so that
//! every save and restore of a solve's state keeps them.

use super::friction::{self, FrictionWork};
use super::port::{self, PortSite};
use super::Workspace;
use crate::contact::{Obstacle, Proximity};
use crate::disc::NodeForces;
use crate::model::RodModel;
use crate::quat::Quat;
use nalgebra::{Matrix3, Vector3};

/// How closely the nearest point of a chord is found: `2^-48` of its length.
const NEAREST_WIDTH: f64 = 3.552713678800501e-15;

/// One slot's geometry at the last evaluation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Site {
    /// `g(p) - r` at the slot's point [m] (`+inf` for an element whose
    /// nearest point is one of its nodes: the node's slot holds it).
    pub gap: f64,
    /// The obstacle's normal there (into free space).
    pub normal: Vector3<f64>,
    /// The point's place along its element's chord, `0..=1` (1 at a node).
    pub s: f64,
    /// The backbone point [m].
    pub point: Vector3<f64>,
    /// An element's: whether its chord's nearest point lies strictly inside
    /// it (else the site is the nearer node's, a held slot's continuation
    /// until the node's slot takes its force over).
    pub inside: bool,
}

impl Default for Site {
    fn default() -> Self {
        Site {
            gap: f64::INFINITY,
            normal: Vector3::zeros(),
            s: 1.0,
            point: Vector3::zeros(),
            inside: false,
        }
    }
}

/// Buffers of the contact rows, sized once (empty without obstacles).
#[derive(Debug, Clone, Default)]
pub(crate) struct ContactWork {
    /// Every slot's site at the last evaluation.
    pub sites: Vec<Site>,
    /// The candidate slots, increasing: the rows of the step's QP (those
    /// held on their obstacles and those near one).
    pub active: Vec<usize>,
    /// Whether each candidate is held on its obstacle (its gap a row of
    /// the merit, its force free); the others' forces are zero.
    pub held: Vec<bool>,
    /// The candidates and their held flags at the continuation's last
    /// equilibrium (with `reactions_saved`).
    pub saved_active: Vec<usize>,
    pub saved_held: Vec<bool>,
    /// The candidates' gaps (zero for a tangent).
    pub gaps: Vec<f64>,
    /// Whether the step chooses which candidates are held (the QP); a
    /// tangent keeps them.
    pub choose: bool,
    /// The nodes and forces that act on the rod besides the loads: the held
    /// points' reactions, then the contacts' shares at nodes.
    pub force_nodes: Vec<usize>,
    pub force_vectors: Vec<Vector3<f64>>,
    /// Scratch for one node's `D_k` (n blocks) and for the node positions
    /// a step or a prediction moves the rod to (n + 1).
    pub position_jacobian: Vec<Matrix3<f64>>,
    /// Every chord's Jacobian at the step's rotations (see
    /// `Discretisation::chord_jacobians`), while `chords_loaded`: during
    /// `constrained::load_constraint_jacobian`, for a scheme that has them.
    /// A row then costs its nodes' additions, not a position Jacobian each
    /// (which computes every chord's before it).
    pub chords: Vec<(Matrix3<f64>, Matrix3<f64>)>,
    pub chords_loaded: bool,
    /// The chords' terms along one direction `nu`, for the rows that share
    /// it (every contact on a plane): `E_i^T nu` at rotation `i - 1` and
    /// `F_i^T nu` at `i - 2`, of the loaded chords (`None` where not yet),
    /// as far along the rod as a row has needed.
    pub along: Option<Vector3<f64>>,
    pub along_ends: Vec<Vector3<f64>>,
    pub along_starts: Vec<Vector3<f64>>,
    pub moved: Vec<Vector3<f64>>,
    /// The held contacts' curvature terms (see [`curvature`]): the columns
    /// `U` (`D_k^T e_a` of each node and axis, `n` vectors each) and the
    /// block-diagonal `M` (one block a contact), so that the Jacobian of the
    /// equations is `A + U M U^T`.
    pub curvature_columns: Vec<Vec<Vector3<f64>>>,
    pub curvature_blocks: Vec<nalgebra::DMatrix<f64>>,
    /// The nodes each block of `M` moves (its rows: 3 a node).
    pub curvature_nodes: Vec<Vec<usize>>,
    /// Every port's crossing at the last evaluation (see `port.rs`).
    pub ports: Vec<PortSite>,
    /// The contacts' friction: anchors, sticking or sliding, the sticking
    /// ones' rows (see `friction.rs`).
    pub friction: FrictionWork,
    /// The state at which the workspace's residual and Jacobian are the
    /// free rod's at full load, no contact force on it: the free start's
    /// last evaluation (see [`start_from_free_equilibrium`]), which the
    /// contact Newton's first step then uses. Empty where there is none.
    pub free_evaluation: Vec<Quat>,
}

impl ContactWork {
    /// Load every chord's Jacobian at `q` (see `chords`), where the scheme
    /// has them; the terms along a direction are then computed again.
    pub fn load_chords(&mut self, model: &RodModel, q: &[Quat]) {
        self.chords
            .resize(model.n(), (Matrix3::zeros(), Matrix3::zeros()));
        self.chords_loaded = model.chord_jacobians(q, &mut self.chords);
        self.along = None;
    }

    /// The forces at nodes of the last evaluation (held points and contacts).
    pub fn node_forces(&self) -> NodeForces<'_> {
        NodeForces {
            nodes: &self.force_nodes,
            forces: &self.force_vectors,
        }
    }

    pub fn new(model: &RodModel) -> Self {
        if !model.has_contact() {
            return ContactWork::default();
        }
        ContactWork {
            sites: vec![Site::default(); slot_count(model)],
            ports: vec![PortSite::default(); model.ports().len()],
            position_jacobian: vec![Matrix3::zeros(); model.n()],
            moved: vec![Vector3::zeros(); model.n() + 1],
            friction: FrictionWork::new(model),
            choose: true,
            ..ContactWork::default()
        }
    }
}

/// Which place a slot stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Place {
    /// Node `k` (1..=n).
    Node(usize),
    /// The inside of element `k` (1..=n), between nodes `k - 1` and `k`.
    Element(usize),
}

/// The number of slots: a node and an element slot per element and obstacle.
pub(crate) fn slot_count(model: &RodModel) -> usize {
    2 * model.n() * model.obstacles().len()
}

/// The obstacle and place of slot `i`.
pub(crate) fn slot(model: &RodModel, i: usize) -> (usize, Place) {
    let n = model.n();
    let (obstacle, r) = (i / (2 * n), i % (2 * n));
    if r < n {
        (obstacle, Place::Node(r + 1))
    } else {
        (obstacle, Place::Element(r - n + 1))
    }
}

/// The slots of the elements either side of node slot `i` (same obstacle;
/// none past the tip). An element's point at that node is the node's contact.
pub(crate) fn elements_beside(model: &RodModel, i: usize) -> impl Iterator<Item = usize> {
    let n = model.n();
    let (o, place) = slot(model, i);
    let node = match place {
        Place::Node(k) => Some(k),
        Place::Element(_) => None,
    };
    node.into_iter()
        .flat_map(move |k| k..=(k + 1).min(n))
        .map(move |e| 2 * n * o + n + e - 1)
}

/// The index of the first slot's multiplier in `reactions` (after the held
/// points', whichever leg of a load path is solved).
pub(crate) fn offset(model: &RodModel, w: &Workspace) -> usize {
    w.kkt.reactions.len() - slot_count(model)
}

/// Slot `i`'s contact force `lambda` [N].
pub(crate) fn force(model: &RodModel, w: &Workspace, i: usize) -> f64 {
    w.kkt.reactions[offset(model, w) + i].x
}

/// How far off the contact Newton's linearised gaps are at the rod in
/// `w.q` (its slots located afresh): the largest depth into an obstacle
/// times the rate its normal turns there (nil in a plane, whose gap is
/// linear; zero where nothing penetrates).
fn curved_depth(model: &RodModel, w: &mut Workspace) -> f64 {
    model.positions(&w.q, &mut w.interior, &mut w.kkt.positions);
    locate(model, &w.kkt.positions, &mut w.kkt.contact.sites);
    let step = CURVATURE_STEP * model.length();
    let sites = w.kkt.contact.sites.iter().enumerate();
    sites
        .filter(|(_, site)| site.gap < 0.0)
        .map(|(i, site)| {
            let obstacle = &model.obstacles()[slot(model, i).0];
            -site.gap * obstacle.normal_jacobian(&site.point, step).norm()
        })
        .fold(0.0, f64::max)
}

/// The start of a direct solve among obstacles: from the start in `w.q`
/// (the rest shape), the loaded rod's equilibrium without them, where the
/// rest shape runs deep into a curved obstacle (its [`curved_depth`] above
/// [`CURVED_DEPTH`]) and the free equilibrium converges, is less so and has
/// not passed through any obstacle (see [`passed_through`]). Deep inside a
/// curved obstacle the linearised gaps of the contact Newton are far off:
/// the seed's robot whose rest shape runs through a ball takes 5 contact
/// iterations from it and 3 from its free equilibrium, whose own iterations
/// cost a third as much each; beside a wall the direct solve failed from
/// the rest shape (61 iterations on the load path). A rest shape on or into
/// a plane stays (a rod resting on a floor, which its loads would carry
/// through). Returns the free solve's iterations.
pub(crate) fn start_from_free_equilibrium(
    model: &RodModel,
    w: &mut Workspace,
    (max_iter, tol): (usize, f64),
) -> usize {
    let at_rest = curved_depth(model, w);
    if at_rest < CURVED_DEPTH {
        return 0;
    }
    let (rest, rest_sites) = (w.q.clone(), w.kkt.contact.sites.clone());
    let free =
        super::newton::iterate_free(model, w, 1.0, (max_iter, tol.max(START_TOLERANCE)), true);
    let kept = free.converged
        && curved_depth(model, w) < at_rest
        && !passed_through(&rest_sites, &w.kkt.contact.sites);
    if kept {
        // `iterate_free` leaves `w.g` and `w.jac` at its answer.
        w.kkt.contact.free_evaluation.clone_from(&w.q);
    } else {
        w.q.copy_from_slice(&rest);
    }
    free.iterations
}

/// How near the free equilibrium a start is solved (its residual and last
/// step, see `newton::certified`): the contact Newton goes on from it. The
/// seed's robot through a ball: 110 us from a start within 1e-2, 120 us
/// from one to round-off.
const START_TOLERANCE: f64 = 1e-2;

/// The [`curved_depth`] from which a direct solve starts at the free
/// equilibrium: the linearised gap is then off by an eighth of the depth.
const CURVED_DEPTH: f64 = 0.25;

/// Whether any slot moved from its site in `before` through its obstacle to
/// its site in `after`: its normal reversed, and it moved beyond the
/// tangent plane it had (a thin edge the free rod sagged through, which
/// the contact Newton would then hold from the wrong side).
fn passed_through(before: &[Site], after: &[Site]) -> bool {
    before.iter().zip(after).any(|(b, a)| {
        b.gap.is_finite()
            && a.gap.is_finite()
            && a.normal.dot(&b.normal) < 0.0
            && b.gap + b.normal.dot(&(a.point - b.point)) < 0.0
    })
}

/// The point of the chord `a`-`b` nearest the obstacle and its gap, when it
/// lies strictly inside; `None` when it is an end. The root of the gap's
/// slope along the chord (the gap is convex along it, see the module),
/// to [`NEAREST_WIDTH`].
fn nearest_inside(
    obstacle: &Obstacle,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    at_a: &Proximity,
    at_b: &Proximity,
) -> Option<(f64, Proximity)> {
    let chord = b - a;
    if at_a.normal.dot(&chord) >= 0.0 || at_b.normal.dot(&chord) <= 0.0 {
        return None;
    }
    // Regula falsi with the Illinois halving, which brings both ends in;
    // a bisection where the bracket did not halve over the last two steps
    // (a kinked gap: a box's edge), so that the bracket halves at least
    // every three slopes.
    let slope = |t: f64| obstacle.proximity(&(a + t * chord)).normal.dot(&chord);
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let (mut slope_lo, mut slope_hi) = (at_a.normal.dot(&chord), at_b.normal.dot(&chord));
    // The bracket's widths one and two steps back.
    let mut widths = [2.0f64; 2];
    let mut last_side = 0i8;
    while hi - lo > NEAREST_WIDTH {
        let t = if hi - lo > 0.5 * widths[0] {
            0.5 * (lo + hi)
        } else {
            (lo * slope_hi - hi * slope_lo) / (slope_hi - slope_lo)
        };
        let t = if t > lo && t < hi { t } else { 0.5 * (lo + hi) };
        widths = [widths[1], hi - lo];
        let at = slope(t);
        if at < 0.0 {
            (lo, slope_lo) = (t, at);
            if last_side < 0 {
                slope_hi *= 0.5;
            }
            last_side = -1;
        } else if at == 0.0 {
            (lo, hi) = (t, t);
        } else {
            // Positive, or not a number (a degenerate obstacle): the bracket
            // closes from above, as bisection's did.
            (hi, slope_hi) = (t, at);
            if last_side > 0 {
                slope_lo *= 0.5;
            }
            last_side = 1;
        }
    }
    let s = 0.5 * (lo + hi);
    // At a node to round-off: the node's slot holds it (not twice).
    if !(NODE_SHARE..1.0 - NODE_SHARE).contains(&s) {
        return None;
    }
    Some((s, obstacle.proximity(&(a + s * chord))))
}

/// How near a node, as a share of its element, a chord's nearest point is
/// that node's.
const NODE_SHARE: f64 = 1e-9;

/// The slots that the move of the backbone from the last evaluation's
/// positions to `moved` (n + 1) carries across their obstacle's tangent
/// plane (the plane at the slot's nearest point, which separates it from a
/// convex obstacle): a move that ends beyond it passed through the obstacle
/// or into it, however thin the obstacle is, and a step must hold those
/// slots. With `skip_candidates` the step's candidates are left out (its
/// QP keeps their linearised gaps >= 0).
pub(crate) fn crossing(
    model: &RodModel,
    w: &Workspace,
    moved: &[Vector3<f64>],
    skip_candidates: bool,
) -> Vec<usize> {
    let c = &w.kkt.contact;
    let before = &w.kkt.positions;
    let mut k = 0;
    let mut out = Vec::new();
    for (i, site) in c.sites.iter().enumerate() {
        let candidate = k < c.active.len() && c.active[k] == i;
        if candidate {
            k += 1;
            if skip_candidates {
                continue;
            }
        }
        let place = slot(model, i).1;
        let ineligible = match place {
            Place::Node(k) => is_held_node(model, k),
            Place::Element(_) => !site.inside,
        };
        if !site.gap.is_finite() || ineligible {
            continue;
        }
        let shift = match place {
            Place::Node(j) => moved[j] - before[j],
            Place::Element(j) => {
                (1.0 - site.s) * (moved[j - 1] - before[j - 1]) + site.s * (moved[j] - before[j])
            }
        };
        if site.gap + site.normal.dot(&shift) < 0.0 {
            out.push(i);
        }
    }
    out
}

/// Whether node `k` is held (a pinned or clamped tip, a guide): it touches
/// nothing, its reaction carries whatever an obstacle would push it with
/// (a contact row there would repeat the held point's: on a tip pinned on
/// a floor's surface the two were parallel and the KKT system singular).
fn is_held_node(model: &RodModel, k: usize) -> bool {
    model.constraints().iter().any(|c| c.node == k)
}

/// Make `slots` candidates (free: the next step's QP decides).
pub(crate) fn add_candidates(w: &mut Workspace, slots: &[usize]) {
    let c = &mut w.kkt.contact;
    for &i in slots {
        let at = c.active.partition_point(|&j| j < i);
        if c.active.get(at) != Some(&i) {
            c.active.insert(at, i);
            c.held.insert(at, false);
        }
    }
}

/// Every slot's site at the node positions `r` (`n + 1`).
pub(crate) fn locate(model: &RodModel, r: &[Vector3<f64>], sites: &mut [Site]) {
    let n = model.n();
    let radius = model.contact_radius();
    for (o, obstacle) in model.obstacles().iter().enumerate() {
        let (nodes, elements) = sites[2 * n * o..2 * n * (o + 1)].split_at_mut(n);
        let mut before = obstacle.proximity(&r[0]);
        for k in 1..=n {
            let here = obstacle.proximity(&r[k]);
            nodes[k - 1] = Site {
                gap: here.gap - radius,
                normal: here.normal,
                s: 1.0,
                point: r[k],
                inside: false,
            };
            // Far from the obstacle no point of the chord can touch: the
            // gap changes by at most the distance moved along it.
            let length = (r[k] - r[k - 1]).norm();
            let reachable = 0.5 * (before.gap + here.gap - length) <= radius + length;
            elements[k - 1] = match reachable
                .then(|| nearest_inside(obstacle, &r[k - 1], &r[k], &before, &here))
                .flatten()
            {
                Some((s, p)) => Site {
                    gap: p.gap - radius,
                    normal: p.normal,
                    s,
                    point: r[k - 1] + s * (r[k] - r[k - 1]),
                    inside: true,
                },
                // The nearer node: what the chord's nearest point becomes
                // as it leaves the element (continuous while it is held).
                None => {
                    let (s, p) = if before.gap <= here.gap {
                        (0.0, &before)
                    } else {
                        (1.0, &here)
                    };
                    Site {
                        gap: p.gap - radius,
                        normal: p.normal,
                        s,
                        point: r[k - 1] + s * (r[k] - r[k - 1]),
                        inside: false,
                    }
                }
            };
            before = here;
        }
    }
}

/// The last node a slot's point depends on (its row's support).
pub(crate) fn last_node(model: &RodModel, i: usize) -> usize {
    match slot(model, i).1 {
        Place::Node(k) | Place::Element(k) => k,
    }
}

/// The nodes and weights a slot's force acts at.
pub(crate) fn shares(model: &RodModel, i: usize, site: &Site) -> [(usize, f64); 2] {
    match slot(model, i).1 {
        Place::Node(k) => [(k, 1.0), (k, 0.0)],
        Place::Element(k) => [(k - 1, 1.0 - site.s), (k, site.s)],
    }
}

/// Fill the forces on the rod besides the loads: the held points'
/// reactions, the ports' forces, then each active slot's `lambda nu` at
/// its nodes.
pub(crate) fn gather_forces(model: &RodModel, w: &mut Workspace) {
    let held = model.constraints().len();
    let c = &mut w.kkt.contact;
    c.force_nodes.clear();
    c.force_vectors.clear();
    c.force_nodes
        .extend(model.constraints().iter().map(|constraint| constraint.node));
    c.force_vectors.extend(&w.kkt.reactions[..held]);
    let first_port = port::offset(model, w.kkt.reactions.len());
    for (j, site) in c.ports.iter().enumerate() {
        let axial = friction::port_axial_of(model, &c.friction, &w.kkt.reactions, j);
        let lambda = &w.kkt.reactions[first_port + j];
        let force = port::force(&model.ports()[j].port, site, lambda, axial);
        for (node, weight) in port::shares(site) {
            if weight != 0.0 {
                c.force_nodes.push(node);
                c.force_vectors.push(weight * force);
            }
        }
    }
    let first = w.kkt.reactions.len() - c.sites.len();
    for &i in &c.active {
        let site = &c.sites[i];
        let lambda = w.kkt.reactions[first + i].x;
        for (node, weight) in shares(model, i, site) {
            if weight != 0.0 {
                c.force_nodes.push(node);
                c.force_vectors.push(weight * lambda * site.normal);
            }
        }
    }
    friction::gather_forces(model, w);
}

/// The candidates' gaps into `gaps`.
pub(crate) fn gather_gaps(w: &mut Workspace) {
    let c = &mut w.kkt.contact;
    c.gaps.clear();
    c.gaps.extend(c.active.iter().map(|&i| c.sites[i].gap));
}

/// Choose the candidates for the next step from the last evaluation's
/// sites: every slot held, and every slot closer to its obstacle than
/// `margin` [m] (a step moves the rod by less near the answer; one that
/// goes farther finds the slots it pushed in at the next step). A slot that
/// is no candidate has its force zeroed. Returns whether any contact force
/// on the rod changed (a held element's handed to its node, a candidate's
/// dropped): else the last evaluation's residual and Jacobian stand.
pub(crate) fn select_candidates(model: &RodModel, w: &mut Workspace, margin: f64) -> bool {
    let n = model.n();
    let first = offset(model, w);
    let c = &mut w.kkt.contact;
    let (old_active, old_held) = (std::mem::take(&mut c.active), std::mem::take(&mut c.held));
    let mut moved = false;
    let mut held_before: Vec<usize> = old_active
        .iter()
        .zip(&old_held)
        .filter_map(|(i, h)| h.then_some(*i))
        .collect();
    // A held element whose chord's nearest point reached a node hands its
    // force to that node's slot (the base's goes into the clamp).
    for i in held_before.clone() {
        let (o, place) = slot(model, i);
        let site = c.sites[i];
        if let Place::Element(k) = place {
            if !site.inside {
                let lambda = w.kkt.reactions[first + i].x;
                moved |= lambda != 0.0;
                w.kkt.reactions[first + i] = Vector3::zeros();
                held_before.retain(|&j| j != i);
                let node = if site.s < 0.5 { k - 1 } else { k };
                // A sliding contact slides on from the node (a sticking
                // one sticks where the node stands).
                let sliding = c.friction.sliding.get_mut(i).and_then(|d| d.take());
                if let Some(a) = c.friction.anchors.get_mut(i) {
                    *a = None;
                }
                if node > 0 {
                    let j = 2 * n * o + node - 1;
                    if let Some(d) = c.friction.sliding.get_mut(j) {
                        *d = d.or(sliding);
                    }
                    w.kkt.reactions[first + j].x += lambda;
                    if !held_before.contains(&j) {
                        held_before.push(j);
                    }
                }
            }
        }
    }
    held_before.sort_unstable();
    for i in 0..c.sites.len() {
        let acted =
            old_active.binary_search(&i).is_ok() && w.kkt.reactions[first + i] != Vector3::zeros();
        let was_held = held_before.binary_search(&i).is_ok();
        let site = &c.sites[i];
        let eligible = match slot(model, i).1 {
            Place::Node(k) => site.gap.is_finite() && !is_held_node(model, k),
            Place::Element(_) => site.inside,
        };
        if eligible && (was_held || site.gap < margin) {
            c.active.push(i);
            c.held.push(was_held);
        } else {
            moved |= acted;
            w.kkt.reactions[first + i] = Vector3::zeros();
        }
    }
    moved
}

/// The held candidates, to see whether a step changed them.
pub(crate) fn held_slots(w: &Workspace) -> Vec<usize> {
    let c = &w.kkt.contact;
    c.active
        .iter()
        .zip(&c.held)
        .filter_map(|(i, h)| h.then_some(*i))
        .collect()
}

/// The active rows of the KKT system, `nu^T ((1 - s) D_(k-1) + s D_k)` as
/// `n` vectors each, appended to `rows` from index `from` (grown as needed).
pub(crate) fn load_rows(model: &RodModel, w: &mut Workspace, from: usize) {
    let active = std::mem::take(&mut w.kkt.contact.active);
    for (a, &i) in active.iter().enumerate() {
        let site = w.kkt.contact.sites[i];
        load_row(model, w, from + a, shares(model, i, &site), &site.normal);
    }
    w.kkt.contact.active = active;
}

/// `D_k = dr_k / dtheta` (n blocks) into the contacts' `position_jacobian`:
/// from the step's chords where they are loaded (`r_k` is the sum of the
/// chords up to it), else from the scheme.
fn node_position_jacobian(model: &RodModel, w: &mut Workspace, k: usize) {
    let c = &mut w.kkt.contact;
    if !c.chords_loaded {
        model.position_jacobian(&w.q, k, &w.interior, &mut c.position_jacobian);
        return;
    }
    let d = &mut c.position_jacobian;
    d.iter_mut().for_each(|x| *x = Matrix3::zeros());
    for i in 1..=k {
        let (start, end) = &c.chords[i - 1];
        d[i - 1] += end;
        if i >= 2 {
            d[i - 2] += start;
        }
    }
}

/// KKT row `r` of a force along `direction` shared between nodes as
/// `shares` (a contact's, a port's): `sum weight D_k^T direction` as `n`
/// vectors (zero on a clamped tip's node; node 0, the base, moves nothing).
pub(crate) fn load_row(
    model: &RodModel,
    w: &mut Workspace,
    r: usize,
    shares: [(usize, f64); 2],
    direction: &Vector3<f64>,
) {
    let n = model.n();
    if w.kkt.rows.len() <= r {
        w.kkt.rows.push(vec![Vector3::zeros(); n]);
    }
    w.kkt.rows[r].iter_mut().for_each(|x| *x = Vector3::zeros());
    for (node, weight) in shares {
        if weight == 0.0 || node == 0 {
            continue;
        }
        if w.kkt.contact.chords_loaded {
            // r_node is the sum of the chords up to it: its row the chords'
            // terms along the direction, up to the node.
            let c = &mut w.kkt.contact;
            if c.along != Some(*direction) {
                // Another direction (a port's, a tangent, a curved
                // obstacle's normal): computed again from the base.
                c.along_ends.clear();
                c.along_starts.clear();
                c.along = Some(*direction);
            }
            // Up to the node only: rows that turn their direction each time
            // cost what they did without the terms kept.
            let computed = c.along_ends.len();
            c.along_ends.extend(
                c.chords[computed..node.max(computed)]
                    .iter()
                    .map(|(_, end)| end.transpose() * direction),
            );
            let computed = c.along_starts.len();
            let needed = node.saturating_sub(1).max(computed);
            c.along_starts.extend(
                c.chords[computed + 1..needed + 1]
                    .iter()
                    .map(|(start, _)| start.transpose() * direction),
            );
            let row = &mut w.kkt.rows[r];
            for (x, e) in row[..node].iter_mut().zip(&c.along_ends) {
                *x += weight * e;
            }
            for (x, s) in row[..node.saturating_sub(1)]
                .iter_mut()
                .zip(&c.along_starts)
            {
                *x += weight * s;
            }
        } else {
            node_position_jacobian(model, w, node);
            let (d, row) = (&w.kkt.contact.position_jacobian, &mut w.kkt.rows[r]);
            let v = weight * direction;
            for (x, b) in row.iter_mut().zip(d.iter()) {
                *x += b.transpose() * v;
            }
        }
    }
    if model.clamped_tip().is_some() {
        w.kkt.rows[r][n - 1] = Vector3::zeros();
    }
}

/// The derivative of a slot's unit shares of its force (`nu` at a node;
/// `(1 - s) nu` and `s nu` at an element's nodes `a`, `b`) with its nodes'
/// positions, from the normal's derivative `turn` at its point: 3 x 3 at a
/// node, 6 x 6 at an element, where the point also slides along the chord
/// to stay the nearest, `nu . (r_b - r_a) = 0`, so that
/// `ds/dr_a = (nu - (1 - s) turn^T d) / c`, `ds/dr_b = -(s turn^T d + nu) / c`
/// with `d = r_b - r_a` and `c = d^T turn d` (> 0: the gap is convex along
/// the chord).
fn share_jacobian(
    place: Place,
    site: &Site,
    turn: &Matrix3<f64>,
    ra: &Vector3<f64>,
    rb: &Vector3<f64>,
) -> nalgebra::DMatrix<f64> {
    if let Place::Node(_) = place {
        return nalgebra::DMatrix::from_iterator(3, 3, turn.iter().copied());
    }
    let (s, nu) = (site.s, site.normal);
    let d = rb - ra;
    let c = d.dot(&(turn * d));
    let along = turn.transpose() * d;
    // The weights of the shares and of the point's motion, node a then b.
    let weights = [1.0 - s, s];
    let slide = if c > 0.0 {
        [(nu - (1.0 - s) * along) / c, -(s * along + nu) / c]
    } else {
        [Vector3::zeros(); 2]
    };
    let mut jac = nalgebra::DMatrix::zeros(6, 6);
    for (i, (wi, sign)) in weights.iter().zip([-1.0, 1.0]).enumerate() {
        for (j, (wj, ds)) in weights.iter().zip(&slide).enumerate() {
            // d(w_i nu)/dr_j = (dw_i/ds) nu ds^T + w_i turn (w_j I + d ds^T)
            let part = sign * nu * ds.transpose()
                + *wi * turn * (Matrix3::identity() * *wj + d * ds.transpose());
            jac.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&part);
        }
    }
    jac
}

/// Relative step of the differences of a contact's force directions: a
/// millionth of the element.
const CURVATURE_STEP: f64 = 1e-6;

/// The curvature terms of the contacts at the last evaluation: a
/// contact force `lambda nu` turns with the obstacle's normal where the rod
/// moves along a curved surface (and, inside an element, slides along the
/// chord), which the Jacobian of point forces of fixed direction leaves out.
/// Each candidate with a force adds `D^T M D` to the Jacobian, `D` the
/// positions of its nodes (3 or 6 rows) and `M = -lambda dF/dr` the change
/// of its nodes' shares of the force with their positions, by central
/// differences (`CURVATURE_STEP` of the element), made symmetric (it is the
/// Hessian of `-lambda` times the gap at the nearest point). Zero for a
/// plane, and left out there. Fills the columns `U = D^T` and blocks `M`.
pub(crate) fn curvature(model: &RodModel, w: &mut Workspace, with_columns: bool) {
    let n = model.n();
    let first = offset(model, w);
    let clamped = model.clamped_tip().is_some();
    let mut used = 0;
    w.kkt.contact.curvature_blocks.clear();
    w.kkt.contact.curvature_nodes.clear();
    // Every candidate with a force, held or on its way out (its force
    // still acts on the rod).
    for candidate in 0..w.kkt.contact.active.len() {
        let i = w.kkt.contact.active[candidate];
        let lambda = w.kkt.reactions[first + i].x;
        if lambda <= 0.0 {
            continue;
        }
        let (o, place) = slot(model, i);
        let obstacle = &model.obstacles()[o];
        let (a, b) = match place {
            Place::Node(k) => (k, k),
            Place::Element(k) => (k - 1, k),
        };
        let site = &w.kkt.contact.sites[i];
        // The nodes that move: a clamped base (node 0) and a clamped tip
        // do not.
        let moving: Vec<usize> = match place {
            Place::Node(_) => vec![b],
            Place::Element(_) => vec![a, b],
        }
        .into_iter()
        .filter(|&k| k > 0 && !(clamped && k == n))
        .collect();
        // An element's point at one of its nodes is that node's (it has no
        // slide along the chord to differentiate).
        if moving.is_empty() || (matches!(place, Place::Element(_)) && !site.inside) {
            continue;
        }
        let step = CURVATURE_STEP * model.h(b.max(1));
        let turn = obstacle.normal_jacobian(&site.point, step);
        let jac = share_jacobian(place, site, &turn, &w.kkt.positions[a], &w.kkt.positions[b]);
        // dF/dr, rows the nodes' shares and columns their coordinates (3
        // each); a base node's share goes into the clamp: keep the moving
        // nodes' rows and columns.
        let mut kept = [0; 2];
        let mut count = 0;
        for (k, share) in [(a, 0), (b, 1)] {
            if matches!(place, Place::Element(_)) && moving.contains(&k) {
                kept[count] = share;
                count += 1;
            }
        }
        let kept = if matches!(place, Place::Node(_)) {
            &[0][..]
        } else {
            &kept[..count]
        };
        // `-lambda` times the symmetric part, filled in place (this runs
        // for every contact at every step).
        let mut block = nalgebra::DMatrix::zeros(3 * kept.len(), 3 * kept.len());
        for (row, &r) in kept.iter().enumerate() {
            for (column, &c) in kept.iter().enumerate() {
                for i in 0..3 {
                    for j in 0..3 {
                        let (u, v) = (3 * r + i, 3 * c + j);
                        block[(3 * row + i, 3 * column + j)] =
                            -lambda * 0.5 * (jac[(u, v)] + jac[(v, u)]);
                    }
                }
            }
        }
        if block.amax() == 0.0 {
            continue;
        }
        push_curvature(model, w, block, moving, with_columns, &mut used);
    }
    for (block, moving) in friction::slip_blocks(model, w) {
        push_curvature(model, w, block, moving, with_columns, &mut used);
    }
    let first = port::offset(model, w.kkt.reactions.len());
    for j in 0..w.kkt.contact.ports.len() {
        let (site, lambda) = (&w.kkt.contact.ports[j], &w.kkt.reactions[first + j]);
        let axial = friction::port_axial(model, w, j);
        let block = port::curvature_block(model, j, site, lambda, axial, &w.kkt.positions);
        if let Some((block, moving)) = block {
            push_curvature(model, w, block, moving, with_columns, &mut used);
        }
    }
    w.kkt.contact.curvature_columns.truncate(used);
}

/// Add a curvature block `M` on the nodes `moving` and, `with_columns`,
/// their columns `U` (`D_k^T e_a`) from index `used` on.
fn push_curvature(
    model: &RodModel,
    w: &mut Workspace,
    block: nalgebra::DMatrix<f64>,
    moving: Vec<usize>,
    with_columns: bool,
    used: &mut usize,
) {
    let n = model.n();
    let clamped = model.clamped_tip().is_some();
    for &k in moving.iter().filter(|_| with_columns) {
        node_position_jacobian(model, w, k);
        let c = &mut w.kkt.contact;
        for axis in 0..3 {
            if c.curvature_columns.len() <= *used {
                c.curvature_columns.push(vec![Vector3::zeros(); n]);
            }
            for (x, d) in c.curvature_columns[*used]
                .iter_mut()
                .zip(&c.position_jacobian)
            {
                *x = d.row(axis).transpose();
            }
            if clamped {
                c.curvature_columns[*used][n - 1] = Vector3::zeros();
            }
            *used += 1;
        }
    }
    let c = &mut w.kkt.contact;
    c.curvature_blocks.push(block);
    c.curvature_nodes.push(moving);
}

/// A contact of a solution: where the rod touches an obstacle and how hard.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// Index of the obstacle in the scene's list.
    pub obstacle: usize,
    /// Arc length of the backbone point in contact [m].
    pub arc_length: f64,
    /// The point of the obstacle's surface the rod touches [m], world frame.
    pub point: Vector3<f64>,
    /// The obstacle's normal there (into free space): the force's direction.
    pub normal: Vector3<f64>,
    /// The contact force's magnitude [N] (`>= 0`).
    pub force: f64,
    /// The friction force on the rod [N], along the obstacle's surface
    /// (zero on a frictionless obstacle).
    pub friction: Vector3<f64>,
    /// Whether the contact slides (its friction at the cone's edge,
    /// against its motion); else it sticks.
    pub sliding: bool,
}

/// The contacts at the last evaluation: the held slots, by arc length.
pub(crate) fn contacts(model: &RodModel, w: &Workspace) -> Vec<Contact> {
    let c = &w.kkt.contact;
    let mut out: Vec<Contact> = held_slots(w)
        .into_iter()
        .map(|i| {
            let site = &c.sites[i];
            let (obstacle, place) = slot(model, i);
            let arc_length = match place {
                Place::Node(k) => model.arc(k),
                Place::Element(k) => model.arc(k - 1) + site.s * model.h(k),
            };
            let distance = site.gap + model.contact_radius();
            let (friction, sliding) = friction::force(model, w, i);
            Contact {
                obstacle,
                arc_length,
                point: site.point - distance * site.normal,
                normal: site.normal,
                force: force(model, w, i),
                friction,
                sliding,
            }
        })
        .collect();
    out.sort_by(|a, b| a.arc_length.total_cmp(&b.arc_length));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::obstacle::tests::{points, shapes};

    /// A slot's unit shares with its chord at `ra`, `rb` (an element's), or
    /// `None` where the chord's nearest point is an end.
    fn shares(
        obstacle: &Obstacle,
        ra: &Vector3<f64>,
        rb: &Vector3<f64>,
    ) -> Option<[Vector3<f64>; 2]> {
        let (pa, pb) = (obstacle.proximity(ra), obstacle.proximity(rb));
        let (s, p) = nearest_inside(obstacle, ra, rb, &pa, &pb)?;
        Some([(1.0 - s) * p.normal, s * p.normal])
    }

    #[test]
    fn the_shares_derivative_is_their_difference() {
        // `share_jacobian` (the normal's turn and the point's slide along the
        // chord) against central differences of the shares, each with its
        // chord's nearest point found again, for chords whose nearest point
        // lies inside them on every curved shape (a lumen's is a node).
        let h = 1e-6;
        let points = points();
        let curved = shapes().into_iter().skip(1);
        for shape in curved.filter(|o| !matches!(o, Obstacle::Lumen { .. })) {
            let mut checked = 0;
            for pair in points.chunks(2) {
                let (ra, rb) = (pair[0], pair[0] + 0.2 * (pair[1] - pair[0]));
                let (pa, pb) = (shape.proximity(&ra), shape.proximity(&rb));
                let Some((s, p)) = nearest_inside(&shape, &ra, &rb, &pa, &pb) else {
                    continue;
                };
                let site = Site {
                    gap: p.gap,
                    normal: p.normal,
                    s,
                    point: ra + s * (rb - ra),
                    inside: true,
                };
                let turn = shape.normal_jacobian(&site.point, 1e-7);
                let exact = share_jacobian(Place::Element(1), &site, &turn, &ra, &rb);
                let mut differenced = nalgebra::DMatrix::zeros(6, 6);
                let mut smooth = true;
                for column in 0..6 {
                    let d = Vector3::ith(column % 3, h);
                    let moved = |sign: f64| {
                        let (mut a, mut b) = (ra, rb);
                        if column < 3 {
                            a += sign * d;
                        } else {
                            b += sign * d;
                        }
                        shares(&shape, &a, &b)
                    };
                    let (Some(plus), Some(minus)) = (moved(1.0), moved(-1.0)) else {
                        smooth = false;
                        break;
                    };
                    for share in 0..2 {
                        let change = (plus[share] - minus[share]) / (2.0 * h);
                        differenced
                            .fixed_view_mut::<3, 1>(3 * share, column)
                            .copy_from(&change);
                    }
                }
                // Away from a box's or a mesh's edges, where the normal jumps.
                if !smooth || differenced.norm() > 1e3 {
                    continue;
                }
                let scale = 1.0 + differenced.norm();
                if shape.has_edges() && (&exact - &differenced).norm() > 1e-3 * scale {
                    continue;
                }
                assert!(
                    (&exact - &differenced).norm() < 1e-5 * scale,
                    "{}: chord {ra} to {rb}, {exact} against {differenced}",
                    shape.shape()
                );
                checked += 1;
            }
            assert!(checked > 5, "{}: {checked} chords", shape.shape());
        }
    }
}
