//! Coulomb friction at the contacts with obstacles (see `contact.rs` for
//! the normal part): each contact sticks or slides, and which depends on
//! the loading history.
//!
//! The history assumed is the load path's: the loads (and held points,
//! ports, insertion) go from the rest shape, or from a warm start's shape,
//! to their values in the continuation's steps, and each step starts from
//! the last equilibrium. A step is one backward-Euler increment of the
//! quasi-static problem. A contact's material point is the point of the rod
//! that touches when the step first holds it (a node, or a place on an
//! element's chord, kept), and its *anchor* the obstacle's point nearest
//! where that material point stood at the step's start; at the step's end
//! a held contact either
//!
//! * **sticks**: its material point has not moved along the obstacle, two
//!   equality rows `t_j . (p - a) + c f_j = 0` (`t_1`, `t_2` tangent to the
//!   obstacle, `a` the anchor, `c` a compliance far below the rod's, see
//!   [`compliance`]) whose multipliers are the friction force `f_t = f_1 t_1
//!   + f_2 t_2`, and `|f_t| <= mu lambda`; or
//! * **slides**: the friction force is `mu lambda d`, `d` against the
//!   material point's move along the obstacle since the anchor (`lambda`
//!   the normal force), and no row.
//!
//! Which is chosen like the normal contacts' set (`contact.rs`): a node
//! touching its obstacle at the step's start, and a contact first held in
//! the step, sticks; at each Newton step a sticking contact whose friction
//! left the cone slides, along it ([`update`]); when the solve converges a
//! sliding contact that did not move against its friction (which would have
//! to push it back) sticks, and one whose direction is off its move turns
//! ([`settle`]); once it has moved, its direction follows its move within
//! the solve ([`effective_direction`], [`slip_blocks`]). The solve has
//! converged only when none changed. A sliding
//! contact's force moves with its normal force: its multiplier's column in
//! the step carries `mu d` ([`slide_forces`]), which makes the KKT system
//! unsymmetric and keeps Newton quadratic while contacts slide.
//!
//! Where that does not settle (a sticking stretch whose end carries a
//! moment), the step is solved again with the rows relaxed, level by
//! level (`constrained::relaxed_friction`, docs/model.md "Relaxed levels").
//!
//! A port with friction (`port.rs`) is held the same way along the rod:
//! its anchor the arc length of the material in it at the step's start,
//! sticking while its friction, the part of its force along the chord, is
//! at most `mu` times the rest (across the rod), sliding otherwise with
//! `mu N` against the material's move through it ([`PortSlip`]).
//!
//! An increment finds the exact end of the history for loads under which
//! no contact that slid comes to rest within the step and none reverses
//! its sliding; otherwise the answer has the error of the step, which the
//! continuation's steps bound. The stick multipliers live in the `y` and
//! `z` of each slot's vector in `reactions` (its `x` the normal force).

use super::contact::{self, ContactWork, Place, Site};
use super::port::{self, Axial, PortSite};
use super::Workspace;
use crate::model::RodModel;
use nalgebra::Vector3;

/// A contact's material point and where it stood at the step's start.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Anchor {
    /// Its place along the element's chord, `0..=1` (1 for a node's slot).
    pub s: f64,
    /// Its obstacle's point nearest it at the step's start (offset by the
    /// rod's radius: where the backbone stands while the rod touches) [m].
    pub point: Vector3<f64>,
}

/// A sticking contact's rows at the last evaluation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stick {
    /// The slot.
    pub slot: usize,
    /// The tangents `t_1`, `t_2` of the obstacle there.
    pub directions: [Vector3<f64>; 2],
    /// `t_j . (p - a)` [m].
    pub residual: [f64; 2],
}

/// A port's friction state (see the module's comment; kept for every port,
/// used for those with friction).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PortSlip {
    /// The arc length of the material in the port at the step's start,
    /// offset by its row's spring (see [`anchor_at_saved`]) [m]; `None`
    /// until the step anchors it.
    pub anchor: Option<f64>,
    /// While it slides, the sign of its friction force on the rod along the
    /// chord (+1 towards the tip); `None` while it sticks.
    pub sliding: Option<f64>,
    /// Its row at the last evaluation: the direction at its crossing
    /// (zero while it slides), `sigma - anchor + c f` [m] (zero while it
    /// slides), and its diagonal: the compliance while it sticks, 1 while
    /// the row only keeps its multiplier at zero.
    pub direction: Vector3<f64>,
    pub residual: f64,
    pub diagonal: f64,
}

/// The friction state of a solve (empty without friction).
#[derive(Debug, Clone, Default)]
pub(crate) struct FrictionWork {
    /// The node positions at the step's start.
    pub start: Vec<Vector3<f64>>,
    /// Every slot's anchor while it is held in this step.
    pub anchors: Vec<Option<Anchor>>,
    /// Every slot's sliding direction: the unit direction of its friction
    /// force while it slides, `None` while it sticks (or touches nothing).
    pub sliding: Vec<Option<Vector3<f64>>>,
    /// The anchors, sliding directions and sticking contacts at the
    /// continuation's last equilibrium.
    pub saved_anchors: Vec<Option<Anchor>>,
    pub saved_sliding: Vec<Option<Vector3<f64>>>,
    pub saved_sticks: Vec<Stick>,
    /// The sticking contacts of this Newton step, by slot: two rows each,
    /// after the ports' and before the contact candidates'.
    pub sticks: Vec<Stick>,
    /// The sticking rows' compliance (see [`compliance`]; above it while
    /// `constrained::relaxed_friction` relaxes them) [m/N].
    pub compliance: f64,
    /// Whether a step of this solve has needed the relaxed levels: the
    /// next ones start there.
    pub relax: bool,
    /// The compliance of the relaxed level at which the last relaxed solve
    /// ended (0 before one): the next starts a level above it, not at the
    /// top (a rod sliding along a floor took ten levels a step to slide
    /// again from sticking).
    pub last_level: f64,
    /// Every port's friction state, and at the last equilibrium.
    pub ports: Vec<PortSlip>,
    pub saved_ports: Vec<PortSlip>,
    /// The ports with friction (`RodModel::frictional_ports`), in the order
    /// of their rows.
    pub frictional_ports: Vec<usize>,
}

impl FrictionWork {
    pub fn new(model: &RodModel) -> Self {
        if !model.has_friction() {
            return FrictionWork::default();
        }
        let slots = contact::slot_count(model);
        FrictionWork {
            start: vec![Vector3::zeros(); model.n() + 1],
            anchors: vec![None; slots],
            sliding: vec![None; slots],
            saved_anchors: vec![None; slots],
            saved_sliding: vec![None; slots],
            sticks: Vec::new(),
            saved_sticks: Vec::new(),
            compliance: compliance(model),
            relax: false,
            last_level: 0.0,
            ports: vec![PortSlip::default(); model.ports().len()],
            saved_ports: vec![PortSlip::default(); model.ports().len()],
            frictional_ports: model.frictional_ports().collect(),
        }
    }

    /// Forget the relaxed levels of past solves (see `relax` and
    /// `last_level`): a solve starts at the rows' own compliance.
    pub fn forget_levels(&mut self) {
        self.relax = false;
        self.last_level = 0.0;
    }

    /// Keep the state as the last equilibrium's (with the contact set).
    pub fn save(&mut self) {
        self.saved_anchors.clone_from(&self.anchors);
        self.saved_sliding.clone_from(&self.sliding);
        self.saved_sticks.clone_from(&self.sticks);
        self.saved_ports.clone_from(&self.ports);
    }

    /// Go back to the kept state.
    pub fn restore_saved(&mut self) {
        self.anchors.clone_from(&self.saved_anchors);
        self.sliding.clone_from(&self.saved_sliding);
        self.sticks.clone_from(&self.saved_sticks);
        self.ports.clone_from(&self.saved_ports);
    }

    /// No contact held: nothing anchored, sliding or sticking.
    pub fn clear(&mut self) {
        self.anchors.iter_mut().for_each(|a| *a = None);
        self.sliding.iter_mut().for_each(|d| *d = None);
        self.sticks.clear();
        self.ports.iter_mut().for_each(|p| *p = PortSlip::default());
    }

    /// The kept state is the rest shape's: nothing held.
    pub fn clear_saved(&mut self) {
        self.saved_anchors.iter_mut().for_each(|a| *a = None);
        self.saved_sliding.iter_mut().for_each(|d| *d = None);
        self.saved_sticks.clear();
        self.saved_ports
            .iter_mut()
            .for_each(|p| *p = PortSlip::default());
    }

    /// The rows of this step: two a sticking contact.
    pub fn row_count(&self) -> usize {
        2 * self.sticks.len()
    }
}

/// The nodes and weights of slot `i`'s material point (its anchor's place).
pub(crate) fn shares(model: &RodModel, i: usize, anchor: &Anchor) -> [(usize, f64); 2] {
    match contact::slot(model, i).1 {
        Place::Node(k) => [(k, 1.0), (k, 0.0)],
        Place::Element(k) => [(k - 1, 1.0 - anchor.s), (k, anchor.s)],
    }
}

/// Slot `i`'s material point at the node positions `r`.
fn material_point(model: &RodModel, i: usize, anchor: &Anchor, r: &[Vector3<f64>]) -> Vector3<f64> {
    let [(a, wa), (b, wb)] = shares(model, i, anchor);
    wa * r[a] + wb * r[b]
}

/// Two unit tangents of a surface with unit `normal`, orthogonal.
pub(crate) fn tangents(normal: &Vector3<f64>) -> [Vector3<f64>; 2] {
    // The axis least along the normal makes the first tangent well defined.
    let axis = if normal.x.abs() <= normal.y.abs() && normal.x.abs() <= normal.z.abs() {
        Vector3::x()
    } else if normal.y.abs() <= normal.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let t1 = (axis - normal * normal.dot(&axis)).normalize();
    [t1, normal.cross(&t1)]
}

/// A sliding direction `d` along the surface of unit `normal` (the surface
/// turns under a contact sliding on a curved obstacle), unit; `None` where
/// it is along the normal.
fn slide_direction(d: &Vector3<f64>, normal: &Vector3<f64>) -> Option<Vector3<f64>> {
    let d = along_surface(d, normal);
    let size = d.norm();
    (size > 0.0).then(|| d / size)
}

/// `v` along the surface of unit `normal`.
fn along_surface(v: &Vector3<f64>, normal: &Vector3<f64>) -> Vector3<f64> {
    v - normal * normal.dot(v)
}

/// Sliding slot `i`'s friction direction at the node positions `r`, and
/// the size of its slip when the direction follows it: against the material
/// point's move along the obstacle since its anchor, once that move is above
/// [`SLIP_FLOOR`] and against the direction it slides in (else that
/// direction; a move that turned back is [`settle`]'s to stick). Following
/// the slip within a Newton solve, with its derivative in the Jacobian
/// ([`slip_blocks`]), keeps a sideways slip from growing: turned only at
/// each solve's end, the direction chased the slip its own sideways part
/// made where the rod is softer across than along (a rod sliding over an
/// edge: the turns grew, and no solve converged). `None` while it sticks,
/// or where its direction is along the normal.
fn effective_direction(
    model: &RodModel,
    f: &FrictionWork,
    i: usize,
    site: &Site,
    r: &[Vector3<f64>],
) -> Option<(Vector3<f64>, Option<f64>)> {
    let d = slide_direction(&f.sliding[i]?, &site.normal)?;
    if let Some(anchor) = &f.anchors[i] {
        let moved = along_surface(
            &(material_point(model, i, anchor, r) - anchor.point),
            &site.normal,
        );
        let size = moved.norm();
        if size > SLIP_FLOOR * model.length() && moved.dot(&d) < 0.0 {
            return Some((-moved / size, Some(size)));
        }
    }
    Some((d, None))
}

/// The slip (of the length) above which a sliding contact's direction
/// follows it: far above the positions' round-off, below which the
/// direction's derivative, `mu lambda / |slip|`, would swamp the rod's
/// stiffness.
const SLIP_FLOOR: f64 = 1e-10;

/// The Jacobian blocks of the sliding contacts whose direction follows
/// their slip (see [`effective_direction`]): the force `mu lambda d` with
/// `d = -m / |m|`, `m` the material point's move along the obstacle, changes
/// with that point by `-(mu lambda / |m|) (P - d d^T)` (`P` the projection on
/// the surface; the obstacle's turn left out, as the contacts' normals),
/// a spring across the slip. Each block is on the moving nodes it acts at
/// (force at the contact's shares, slip at the material point's; made
/// symmetric) and is `M = -dF/dr`.
pub(crate) fn slip_blocks(
    model: &RodModel,
    w: &Workspace,
) -> Vec<(nalgebra::DMatrix<f64>, Vec<usize>)> {
    if !model.has_friction() {
        return Vec::new();
    }
    let n = model.n();
    let clamped = model.clamped_tip().is_some();
    let first = first(model, w);
    let c = &w.kkt.contact;
    let r = &w.kkt.positions;
    let mut blocks = Vec::new();
    for (&i, &held) in c.active.iter().zip(&c.held) {
        let (Some(anchor), true) = (&c.friction.anchors[i], held) else {
            continue;
        };
        let site = &c.sites[i];
        let Some((d, Some(size))) = effective_direction(model, &c.friction, i, site, r) else {
            continue;
        };
        let lambda = w.kkt.reactions[first + i].x.max(0.0);
        let mu = model.friction(contact::slot(model, i).0);
        if lambda == 0.0 {
            continue;
        }
        let nu = &site.normal;
        let across = (nalgebra::Matrix3::identity() - nu * nu.transpose() - d * d.transpose())
            * (mu * lambda / size);
        // Each moving node's share of the force and of the material point.
        let mut moving: Vec<(usize, f64, f64)> = Vec::new();
        let mut add = |node: usize, force: f64, slip: f64| {
            if node == 0 || (clamped && node == n) {
                return;
            }
            match moving.iter_mut().find(|(k, _, _)| *k == node) {
                Some(entry) => {
                    entry.1 += force;
                    entry.2 += slip;
                }
                None => moving.push((node, force, slip)),
            }
        };
        for (node, weight) in contact::shares(model, i, site) {
            add(node, weight, 0.0);
        }
        for (node, weight) in shares(model, i, anchor) {
            add(node, 0.0, weight);
        }
        if moving.is_empty() {
            continue;
        }
        let m = moving.len();
        let mut block = nalgebra::DMatrix::zeros(3 * m, 3 * m);
        for (a, &(_, force_a, slip_a)) in moving.iter().enumerate() {
            for (b, &(_, force_b, slip_b)) in moving.iter().enumerate() {
                let weight = 0.5 * (force_a * slip_b + slip_a * force_b);
                block
                    .view_mut((3 * a, 3 * b), (3, 3))
                    .copy_from(&(across * weight));
            }
        }
        blocks.push((block, moving.into_iter().map(|(k, _, _)| k).collect()));
    }
    blocks
}

/// Start a step of the history at the rod of rotations `w.saved` (its
/// last evaluation's): keep its positions, anchor each contact held there
/// where it stands (a sticking one at its material point, a sliding one at
/// its contact point), and let the others take theirs when the step first
/// holds them. A contact keeps sticking or sliding as it was, the Newton
/// step's first guess, and the forces at `w.saved` are unchanged.
pub(crate) fn anchor_at_saved(model: &RodModel, w: &mut Workspace) {
    anchor_at_saved_moved(model, w, Vector3::zeros());
}

/// [`anchor_at_saved`] for a rod that stood translated by `moved` from
/// where its rotations put it now (a warm start whose base was elsewhere:
/// `Solver::solve_after`): its material points stood there.
pub(crate) fn anchor_at_saved_moved(model: &RodModel, w: &mut Workspace, moved: Vector3<f64>) {
    if !model.has_friction() {
        return;
    }
    let held = contact::held_slots(w);
    let first = first(model, w);
    let f = &mut w.kkt.contact.friction;
    model.positions(&w.saved, &mut w.interior, &mut f.start);
    f.start.iter_mut().for_each(|p| *p += moved);
    let kept: Vec<(usize, Anchor)> = held
        .iter()
        .filter_map(|&i| {
            let site = &w.kkt.contact.sites[i];
            let s = match (f.sliding[i], f.anchors[i]) {
                (None, Some(anchor)) => anchor.s,
                _ => site.s,
            };
            let mut material = *site;
            material.s = s;
            (model.friction(contact::slot(model, i).0) > 0.0).then(|| {
                let mut anchor = anchor(model, i, &material, &f.start);
                if f.sliding[i].is_none() {
                    // Where its rows' spring rests: it keeps its friction
                    // (`c f` is round-off at the rows' own compliance).
                    let reaction = &w.kkt.reactions[first + i];
                    let t = tangents(&site.normal);
                    anchor.point += f.compliance * (reaction.y * t[0] + reaction.z * t[1]);
                }
                (i, anchor)
            })
        })
        .collect();
    f.anchors.iter_mut().for_each(|a| *a = None);
    for (i, anchor) in kept {
        f.anchors[i] = Some(anchor);
    }
    // Every sticking contact is anchored (its rows need its material point).
    let anchors = &f.anchors;
    f.sticks.retain(|s| anchors[s.slot].is_some());
    // A port's material where it stands, a sticking one's where its row's
    // spring rests (it keeps its friction, as a contact).
    let first_port = port::offset(model, w.kkt.reactions.len());
    for j in model.frictional_ports() {
        let slip = &mut f.ports[j];
        let spring = match slip.sliding {
            None => f.compliance * w.kkt.reactions[first_port + j].z,
            Some(_) => 0.0,
        };
        slip.anchor = port_arc(model, j, &f.start).map(|arc| arc + spring);
    }
    f.saved_anchors.clone_from(&f.anchors);
    f.saved_sticks.clone_from(&f.sticks);
    f.saved_ports.clone_from(&f.ports);
}

/// The arc length of the material in port `j` for node positions `r`.
fn port_arc(model: &RodModel, j: usize, r: &[Vector3<f64>]) -> Option<f64> {
    let c = model.ports()[j].port.crossing(r)?;
    Some(model.arc(c.element - 1) + c.s * model.h(c.element))
}

/// Port `j`'s friction at the last evaluation (its multipliers `reactions`).
pub(crate) fn port_axial_of(
    model: &RodModel,
    f: &FrictionWork,
    reactions: &[Vector3<f64>],
    j: usize,
) -> Axial {
    let mu = model.ports()[j].port.friction;
    if mu == 0.0 {
        return Axial::Free;
    }
    match f.ports[j].sliding {
        Some(sign) => Axial::Slide(mu * sign),
        None => Axial::Stick(reactions[port::offset(model, reactions.len()) + j].z),
    }
}

/// [`port_axial_of`] of the workspace's state.
pub(crate) fn port_axial(model: &RodModel, w: &Workspace, j: usize) -> Axial {
    port_axial_of(model, &w.kkt.contact.friction, &w.kkt.reactions, j)
}

/// A port's force split along its chord: `(N, F_t)`, the size of the part
/// across the rod and the part along it (towards the tip) [N].
fn port_parts(
    model: &RodModel,
    j: usize,
    site: &PortSite,
    lambda: &Vector3<f64>,
    axial: Axial,
) -> (f64, f64) {
    let force = port::force(&model.ports()[j].port, site, lambda, axial);
    let t = site.chord.normalize();
    let along = t.dot(&force);
    ((force - along * t).norm(), along)
}

/// Port `j` at a Newton step: anchored where the step first holds it
/// (sticking); while relaxed, a sliding port whose slip its spring would
/// hold sticks and the others slide against their slip; a sticking port
/// whose friction left its cone slides, along it.
fn update_port(model: &RodModel, w: &mut Workspace, j: usize, relaxed: bool) {
    let site = w.kkt.contact.ports[j];
    if site.crossing.is_none() {
        return;
    }
    let mu = model.ports()[j].port.friction;
    let index = port::offset(model, w.kkt.reactions.len()) + j;
    let f = &mut w.kkt.contact.friction;
    let Some(anchor) = f.ports[j].anchor else {
        f.ports[j].anchor = port_arc(model, j, &f.start);
        f.ports[j].sliding = None;
        return;
    };
    let reaction = w.kkt.reactions[index];
    let slip = site.arc - anchor;
    let (normal, along) = port_parts(
        model,
        j,
        &site,
        &reaction,
        port_axial_of(model, f, &w.kkt.reactions, j),
    );
    let state = &mut f.ports[j];
    let mut axial = reaction.z;
    if relaxed && state.sliding.is_some() {
        if slip.abs() <= f.compliance * mu * normal {
            state.sliding = None;
            axial = -slip / f.compliance;
        } else {
            state.sliding = Some(slip.signum());
        }
    } else if state.sliding.is_none() && along.abs() > mu * normal * (1.0 + CONE_SLACK) {
        state.sliding = Some(along.signum());
        axial = 0.0;
    }
    w.kkt.reactions[index].z = axial;
}

/// Port `j` at a Newton solve's end (see [`settle`]): a sticking port
/// whose friction left its cone slides; a sliding one that did not move
/// against its friction sticks, its friction as it was. Returns whether it
/// changed.
fn settle_port(model: &RodModel, w: &mut Workspace, j: usize) -> bool {
    let site = w.kkt.contact.ports[j];
    let f = &w.kkt.contact.friction;
    let (Some(_), Some(anchor)) = (site.crossing, f.ports[j].anchor) else {
        return false;
    };
    let mu = model.ports()[j].port.friction;
    let index = port::offset(model, w.kkt.reactions.len()) + j;
    let axial = port_axial_of(model, f, &w.kkt.reactions, j);
    let reaction = w.kkt.reactions[index];
    let (normal, along) = port_parts(model, j, &site, &reaction, axial);
    let state = &mut w.kkt.contact.friction.ports[j];
    match state.sliding {
        None if along.abs() > mu * normal * (1.0 + CONE_SLACK) => {
            state.sliding = Some(along.signum());
            w.kkt.reactions[index].z = 0.0;
            true
        }
        None => false,
        Some(sign) => {
            // The material moves through it by `-(sigma - anchor)` along
            // the chord, against a friction of sign `sign` where
            // `sign (sigma - anchor) > 0`.
            if sign * (site.arc - anchor) > MOVE_SLACK * model.length() {
                return false;
            }
            // The row's force along the chord is `-f h / |t|`.
            state.sliding = None;
            w.kkt.reactions[index].z = -along * site.chord.norm() / site.h;
            true
        }
    }
}

/// The anchor of slot `i` first held with its site `site`: its material
/// point the site's, where that stood at the step's start, onto the
/// obstacle's offset surface.
fn anchor(model: &RodModel, i: usize, site: &Site, start: &[Vector3<f64>]) -> Anchor {
    let (o, place) = contact::slot(model, i);
    let s = match place {
        Place::Node(_) => 1.0,
        Place::Element(_) => site.s,
    };
    let at_start = material_point(
        model,
        i,
        &Anchor {
            s,
            point: Vector3::zeros(),
        },
        start,
    );
    let near = model.obstacles()[o].proximity(&at_start);
    Anchor {
        s,
        point: at_start - (near.gap - model.contact_radius()) * near.normal,
    }
}

/// The lower bound of a contact candidate's force step in the step's QP
/// (`lower` for a frictionless or sliding one): none for a sticking contact,
/// whose friction rows hold its point, so that the QP cannot let go of its
/// normal force while its friction still acts; a sticking contact that
/// pulls is let go by [`update`] at the next step.
pub(crate) fn lower_bound(w: &Workspace, i: usize, lower: f64) -> f64 {
    let sticks = &w.kkt.contact.friction.sticks;
    if sticks.binary_search_by_key(&i, |s| s.slot).is_ok() {
        f64::NEG_INFINITY
    } else {
        lower
    }
}

/// The first multiplier of the slots in `reactions`.
fn first(model: &RodModel, w: &Workspace) -> usize {
    contact::offset(model, w)
}

/// At the start of a Newton step, after the candidates are chosen: hold the
/// candidates that touch, let go of sticking contacts that pull, anchor
/// the contacts first held (they stick), zero the friction of every other
/// slot, and list the sticking contacts (their rows are filled by
/// [`gather_sticks`]). Whether a contact sticks or slides is settled when
/// the Newton solve converges ([`settle`]).
pub(crate) fn update(model: &RodModel, w: &mut Workspace) {
    if !model.has_friction() {
        return;
    }
    let first = first(model, w);
    // A sticking contact's force is free of its bound within a step (its
    // rows are equalities, see `lower_bound`): one that pulls is let go
    // here, its friction with it.
    // A node that touches its obstacle is held with its friction: it sticks
    // from the step's start (left free, the step would slide it along the
    // obstacle before its friction acts). Not an element's point: touching
    // at a node, it would hold the node twice.
    // Nor a node whose contact an element beside it holds at its end (an
    // edge on the node that the rod slides over): two rows for one point
    // alternated, the node held then let go, and no step converged.
    let touching = TOUCHING * model.length();
    let held_before = contact::held_slots(w);
    let c = &mut w.kkt.contact;
    for (&i, held) in c.active.iter().zip(c.held.iter_mut()) {
        let reaction = &mut w.kkt.reactions[first + i];
        let mu = model.friction(contact::slot(model, i).0);
        if *held && c.friction.sliding[i].is_none() && reaction.x < 0.0 {
            *held = false;
            *reaction = Vector3::zeros();
        } else if !*held
            && mu > 0.0
            && c.sites[i].gap.abs() <= touching
            && matches!(contact::slot(model, i).1, Place::Node(_))
            && !contact::elements_beside(model, i).any(|j| held_before.binary_search(&j).is_ok())
        {
            *held = true;
        }
    }
    let held = contact::held_slots(w);
    let relaxed = w.kkt.contact.friction.compliance > compliance(model) * 1.5;
    let r = &w.kkt.positions;
    let c = &mut w.kkt.contact;
    let f = &mut c.friction;
    let mut is_held = vec![false; f.sliding.len()];
    for &i in &held {
        is_held[i] = true;
    }
    for (i, held) in is_held.iter().enumerate() {
        let mu = model.friction(contact::slot(model, i).0);
        let reaction = &mut w.kkt.reactions[first + i];
        if !held || mu == 0.0 {
            f.sliding[i] = None;
            f.anchors[i] = None;
            reaction.y = 0.0;
            reaction.z = 0.0;
            continue;
        }
        let site = &c.sites[i];
        // Relaxed (see `constrained::relaxed_friction`): a sliding contact
        // whose slip its spring would hold sticks, the others slide
        // against their slip.
        if let (Some(anchor), Some(_), true) = (f.anchors[i], f.sliding[i], relaxed) {
            let slip = along_surface(
                &(material_point(model, i, &anchor, r) - anchor.point),
                &site.normal,
            );
            let size = slip.norm();
            if size <= f.compliance * mu * reaction.x.max(0.0) {
                let t = tangents(&site.normal);
                let force = -slip / f.compliance;
                f.sliding[i] = None;
                reaction.y = force.dot(&t[0]);
                reaction.z = force.dot(&t[1]);
            } else {
                f.sliding[i] = Some(-slip / size);
            }
            continue;
        }
        // A sticking contact slides where its friction left the cone at the
        // last step, along it (a contact that cannot stick, which no Newton
        // step would settle, slides so); [`settle`] checks the others when
        // the solve converges.
        if f.anchors[i].is_some() && f.sliding[i].is_none() {
            let t = tangents(&site.normal);
            let force = reaction.y * t[0] + reaction.z * t[1];
            let size = force.norm();
            if size > mu * reaction.x.max(0.0) * (1.0 + CONE_SLACK) {
                f.sliding[i] = Some(force / size);
                reaction.y = 0.0;
                reaction.z = 0.0;
            }
        }
        if f.anchors[i].is_none() {
            // First held in this step: it sticks while the step finds its
            // friction (its move before it touched is no sliding).
            f.anchors[i] = Some(anchor(model, i, site, &f.start));
            f.sliding[i] = None;
            continue;
        }
    }
    f.sticks.clear();
    f.sticks.extend(
        held.iter()
            .filter(|&&i| model.friction(contact::slot(model, i).0) > 0.0 && f.sliding[i].is_none())
            .map(|&i| Stick {
                slot: i,
                directions: [Vector3::zeros(); 2],
                residual: [0.0; 2],
            }),
    );
    // By index: the list is the workspace's own (no allocation a step).
    for a in 0..w.kkt.contact.friction.frictional_ports.len() {
        let j = w.kkt.contact.friction.frictional_ports[a];
        update_port(model, w, j, relaxed);
    }
}

/// At a Newton solve's end, each sliding contact: one whose material point
/// did not move against its friction force since the anchor sticks (its
/// friction as it was, the solve finds it); one whose direction is more
/// than [`TURN_ANGLE`] from against its move turns. Returns whether any
/// changed (the solve goes on).
pub(crate) fn settle(model: &RodModel, w: &mut Workspace) -> bool {
    if !model.has_friction() {
        return false;
    }
    let mut changed = false;
    for a in 0..w.kkt.contact.friction.frictional_ports.len() {
        let j = w.kkt.contact.friction.frictional_ports[a];
        changed |= settle_port(model, w, j);
    }
    let first = first(model, w);
    let r = &w.kkt.positions;
    let c = &mut w.kkt.contact;
    let f = &mut c.friction;
    for (i, sliding) in f.sliding.iter_mut().enumerate() {
        let Some(anchor) = f.anchors[i] else {
            continue;
        };
        let Some(d) = *sliding else {
            // A sticking contact slides where its friction left the cone,
            // along it.
            let mu = model.friction(contact::slot(model, i).0);
            let reaction = &mut w.kkt.reactions[first + i];
            let t = tangents(&c.sites[i].normal);
            let force = reaction.y * t[0] + reaction.z * t[1];
            let size = force.norm();
            if size > mu * reaction.x.max(0.0) * (1.0 + CONE_SLACK) {
                *sliding = Some(force / size);
                reaction.y = 0.0;
                reaction.z = 0.0;
                changed = true;
            }
            continue;
        };
        let normal = &c.sites[i].normal;
        let moved = along_surface(
            &(material_point(model, i, &anchor, r) - anchor.point),
            normal,
        );
        let d = along_surface(&d, normal).normalize();
        let size = moved.norm();
        if size > SLIP_FLOOR * model.length() && moved.dot(&d) < 0.0 {
            // Its force followed the slip already (`effective_direction`).
            *sliding = Some(-moved / size);
            continue;
        }
        if moved.dot(&d) >= -MOVE_SLACK * model.length() {
            let mu = model.friction(contact::slot(model, i).0);
            let reaction = &mut w.kkt.reactions[first + i];
            let force = mu * reaction.x.max(0.0) * d;
            let t = tangents(normal);
            reaction.y = force.dot(&t[0]);
            reaction.z = force.dot(&t[1]);
            *sliding = None;
            changed = true;
        } else if d.dot(&(-moved / size)) < TURN_ANGLE.cos() {
            *sliding = Some(-moved / size);
            changed = true;
        }
    }
    changed
}

/// How far a sliding contact's direction may be from against its move.
const TURN_ANGLE: f64 = 1e-6;

/// How little a sliding contact must have moved against its friction force
/// to stay sliding (of the length): round-off.
const MOVE_SLACK: f64 = 1e-14;

/// How near its obstacle a candidate touches it (of the length).
const TOUCHING: f64 = 1e-12;

/// A sliding candidate's friction per unit normal force, or a sliding
/// port's per unit lateral multiplier (see [`slide_forces`]).
pub(crate) struct SlideForce {
    /// The KKT row of its multiplier.
    pub row: usize,
    /// Its nodes and weights.
    pub shares: [(usize, f64); 2],
    /// `mu d`.
    pub force: Vector3<f64>,
}

/// The sliding contacts' friction in the Newton step: each sliding
/// candidate's force `mu lambda d` moves with its normal force `lambda`, so
/// its multiplier's column carries `mu d` beside the normal (the KKT system
/// is then unsymmetric). A sliding port's `mu s N t` moves with its lateral
/// multipliers, `N = |lambda_1 d_1 + lambda_2 d_2|`: their columns carry
/// `mu s (n . d_i) t` (`n` the lateral force's unit; `N` is homogeneous in
/// the multipliers, so that is exact). The candidates' rows start at
/// `first_candidate`.
pub(crate) fn slide_forces(
    model: &RodModel,
    w: &Workspace,
    first_candidate: usize,
) -> Vec<SlideForce> {
    if !model.has_friction() {
        return Vec::new();
    }
    let c = &w.kkt.contact;
    let contacts = c
        .active
        .iter()
        .zip(&c.held)
        .enumerate()
        .filter_map(|(a, (&i, &held))| {
            c.friction.anchors[i]?;
            let site = &c.sites[i];
            let (d, _) = effective_direction(model, &c.friction, i, site, &w.kkt.positions)
                .filter(|_| held)?;
            Some(SlideForce {
                row: first_candidate + a,
                shares: contact::shares(model, i, site),
                force: model.friction(contact::slot(model, i).0) * d,
            })
        });
    let first_port = port::offset(model, w.kkt.reactions.len());
    let ports = model.frictional_ports().flat_map(move |j| {
        let site = &c.ports[j];
        let lambda = &w.kkt.reactions[first_port + j];
        let lateral = port::force(&model.ports()[j].port, site, lambda, Axial::Free);
        let size = lateral.norm();
        let slide = match (
            port_axial(model, w, j),
            site.crossing.is_some() && size > 0.0,
        ) {
            (Axial::Slide(mu_s), true) => Some(mu_s),
            _ => None,
        };
        (0..2).filter_map(move |i| {
            let mu_s = slide?;
            let t = site.chord.normalize();
            Some(SlideForce {
                row: port::first_row(model) + 2 * j + i,
                shares: port::shares(site),
                force: (mu_s * lateral.dot(&site.directions[i]) / size) * t,
            })
        })
    });
    contacts.chain(ports).collect()
}

/// Count every held, anchored contact with friction as sticking (its rows
/// in the step's), for the stability verdict and the path's tangent;
/// returns the state to put back with [`unstick`]. A port keeps its state:
/// the tangent of one that slides slides (measured: held, the predictor
/// missed by enough that every continuation step was taken twice).
pub(crate) fn stick_all(model: &RodModel, w: &mut Workspace) -> StuckState {
    let held = contact::held_slots(w);
    let f = &mut w.kkt.contact.friction;
    let kept = (f.sliding.clone(), f.sticks.clone());
    f.sticks.clear();
    for i in held {
        if model.friction(contact::slot(model, i).0) > 0.0 && f.anchors[i].is_some() {
            f.sliding[i] = None;
            f.sticks.push(Stick {
                slot: i,
                directions: [Vector3::zeros(); 2],
                residual: [0.0; 2],
            });
        }
    }
    gather_sticks(model, w);
    kept
}

/// What [`stick_all`] changed: the contacts' sliding and their sticking
/// rows.
pub(crate) type StuckState = (Vec<Option<Vector3<f64>>>, Vec<Stick>);

/// Put back what [`stick_all`] changed.
pub(crate) fn unstick(w: &mut Workspace, (sliding, sticks): StuckState) {
    let f = &mut w.kkt.contact.friction;
    f.sliding = sliding;
    f.sticks = sticks;
}

/// What [`release_sticking`] changed: the contacts' anchors and sticking
/// rows, and the ports' states.
pub(crate) type Released = (Vec<Option<Anchor>>, Vec<Stick>, Vec<PortSlip>);

/// Let every sticking contact and port go, free to slide with their
/// friction held at its value (a fixed force, no rows), a sliding one
/// keeping its own: the equations of a step in which what sticks starts to
/// slide, whichever way. The equilibrium is the same one. (A sticking
/// contact's own derivative holds it where it is: a tip stuck on a wall
/// does not move at all.)
pub(crate) fn release_sticking(w: &mut Workspace) -> Released {
    let f = &mut w.kkt.contact.friction;
    let kept = (
        f.anchors.clone(),
        std::mem::take(&mut f.sticks),
        f.ports.clone(),
    );
    // A port's row then keeps its multiplier, the friction, where it is.
    for port in f.ports.iter_mut().filter(|p| p.sliding.is_none()) {
        port.anchor = None;
    }
    kept
}

/// Whether a contact or a port sticks at the last evaluation (its rows
/// hold a material point where it is).
pub(crate) fn sticks_anywhere(model: &RodModel, w: &Workspace) -> bool {
    let f = &w.kkt.contact.friction;
    !f.sticks.is_empty()
        || model
            .frictional_ports()
            .any(|j| f.ports[j].anchor.is_some() && f.ports[j].sliding.is_none())
}

/// Put back what [`release_sticking`] changed.
pub(crate) fn restore_sticking(w: &mut Workspace, (anchors, sticks, ports): Released) {
    let f = &mut w.kkt.contact.friction;
    f.anchors = anchors;
    f.sticks = sticks;
    f.ports = ports;
}

/// How far outside its cone a sticking contact's friction goes before it
/// slides (relative): round-off.
const CONE_SLACK: f64 = 1e-9;

/// The compliance `c` of a sticking contact's rows [m/N]: the rows are
/// `t_j . (p - a) + c f_j = 0`, the material point held by a spring this
/// soft (it gives `c |f|`, below 1e-9 of an element's sag under that force).
/// Without it, contacts that all stick along a stretch are held twice over
/// (each chord's length is fixed already), their rows redundant and the
/// step's matrix singular; with it, the friction forces there are the
/// least that hold them.
pub(crate) fn compliance(model: &RodModel) -> f64 {
    let h = model.length() / model.n() as f64;
    STICK_COMPLIANCE * h * h * h / model.stiffness().max()
}

/// [`compliance`] over an element's bending compliance `h^3 / k`.
const STICK_COMPLIANCE: f64 = 1e-9;

/// Iterations of a step's Newton at the rows' own compliance before the
/// relaxed levels take over (`constrained::relaxed_friction`).
pub(crate) const DIRECT_ITERATIONS: usize = 40;

/// The first relaxed level's compliance over the whole rod's bending
/// compliance `L^3 / k`: a spring as soft as the rod, whatever `n`.
const RELAXED_COMPLIANCE: f64 = 1.0;

/// The first relaxed level's compliance [m/N] (see [`RELAXED_COMPLIANCE`]).
pub(crate) fn relaxed_compliance(model: &RodModel) -> f64 {
    RELAXED_COMPLIANCE * model.length().powi(3) / model.stiffness().max()
}

/// From one relaxed level to the next, at first; never less than
/// `FASTEST_FACTOR`, and the levels fail past `SLOWEST_FACTOR`.
pub(crate) const RELAXED_FACTOR: f64 = 0.5;
pub(crate) const FASTEST_FACTOR: f64 = 0.1;
pub(crate) const SLOWEST_FACTOR: f64 = 0.95;

/// Iterations of one relaxed level (they take one to four).
pub(crate) const LEVEL_ITERATIONS: usize = 8;

/// A relaxed level this quick lets the next one go further down.
pub(crate) const EASY_LEVEL: usize = 2;

/// The relaxed levels of a step stop after this many times its iterations.
pub(crate) const RELAXED_LEVELS: usize = 4;

/// How far a sticking contact may creep on its rows' spring at a relaxed
/// level's answer (of the length): `c |f|`, far below any discretisation
/// error and above the positions' round-off.
pub(crate) const STICK_CREEP: f64 = 1e-11;

/// The creep of a relaxed level kept where the next level fails (of the
/// length): a few nanometres a metre. Sticking contacts that creep turn
/// their stretch by about `creep / h`: on the rod pushed along a floor
/// (tests/test_friction.py) the tip moves by 0.1 % of its move at most,
/// below the discretisation's error.
pub(crate) const ACCEPTED_CREEP: f64 = 3e-9;

/// The most a sticking contact creeps on its rows' spring, `c |f|` [m].
pub(crate) fn creep(model: &RodModel, w: &Workspace) -> f64 {
    let first = first(model, w);
    let f = &w.kkt.contact.friction;
    let first_port = port::offset(model, w.kkt.reactions.len());
    let ports = model
        .frictional_ports()
        .filter(|&j| f.ports[j].sliding.is_none())
        .map(|j| f.compliance * w.kkt.reactions[first_port + j].z.abs());
    f.sticks
        .iter()
        .map(|s| {
            let r = &w.kkt.reactions[first + s.slot];
            f.compliance * r.y.hypot(r.z)
        })
        .chain(ports)
        .fold(0.0, f64::max)
}

/// The sticking contacts' directions and residuals at the last evaluation's
/// sites and positions.
pub(crate) fn gather_sticks(model: &RodModel, w: &mut Workspace) {
    if !model.has_friction() {
        return;
    }
    let first = first(model, w);
    let compliance = w.kkt.contact.friction.compliance;
    let r = &w.kkt.positions;
    let c = &mut w.kkt.contact;
    // A sticking port's row holds the arc length in it; a sliding one's
    // (or one not anchored) keeps its multiplier at zero.
    let first_port = port::offset(model, w.kkt.reactions.len());
    for j in model.frictional_ports() {
        let site = &c.ports[j];
        let state = &mut c.friction.ports[j];
        let axial = w.kkt.reactions[first_port + j].z;
        match (site.crossing, state.anchor, state.sliding) {
            (Some(_), Some(anchor), None) => {
                state.direction = model.ports()[j].port.axial_direction(&site.chord, site.h);
                state.residual = site.arc - anchor + compliance * axial;
                state.diagonal = compliance;
            }
            _ => {
                state.direction = Vector3::zeros();
                state.residual = 0.0;
                state.diagonal = 1.0;
            }
        }
    }
    for stick in &mut c.friction.sticks {
        let i = stick.slot;
        let Some(anchor) = &c.friction.anchors[i] else {
            continue;
        };
        let t = tangents(&c.sites[i].normal);
        let moved = material_point(model, i, anchor, r) - anchor.point;
        let f = &w.kkt.reactions[first + i];
        stick.directions = t;
        stick.residual = [
            t[0].dot(&moved) + compliance * f.y,
            t[1].dot(&moved) + compliance * f.z,
        ];
    }
}

/// The friction forces at nodes, after the contacts' (see
/// `contact::gather_forces`): a sticking contact's multipliers, a sliding
/// one's `mu lambda d`, at its material point.
pub(crate) fn gather_forces(model: &RodModel, w: &mut Workspace) {
    if !model.has_friction() {
        return;
    }
    let first = first(model, w);
    let r = &w.kkt.positions;
    let c = &mut w.kkt.contact;
    for &i in &c.active {
        let reaction = w.kkt.reactions[first + i];
        let site = &c.sites[i];
        let Some(anchor) = &c.friction.anchors[i] else {
            continue;
        };
        // A sliding contact's friction acts where its normal force does, a
        // sticking one's at its material point (its rows').
        let shares = match c.friction.sliding[i] {
            Some(_) => contact::shares(model, i, site),
            None => shares(model, i, anchor),
        };
        let force = match c.friction.sliding[i] {
            Some(_) => match effective_direction(model, &c.friction, i, site, r) {
                Some((d, _)) => model.friction(contact::slot(model, i).0) * reaction.x.max(0.0) * d,
                None => continue,
            },
            None => {
                if reaction.y == 0.0 && reaction.z == 0.0 {
                    continue;
                }
                let t = tangents(&site.normal);
                reaction.y * t[0] + reaction.z * t[1]
            }
        };
        for (node, weight) in shares {
            if weight != 0.0 {
                c.force_nodes.push(node);
                c.force_vectors.push(weight * force);
            }
        }
    }
}

/// The nodes and weights of a sticking contact's rows: its material
/// point's (every sticking contact is anchored; else its site's, so that
/// the rows keep their count).
pub(crate) fn stick_shares(model: &RodModel, c: &ContactWork, i: usize) -> [(usize, f64); 2] {
    match &c.friction.anchors[i] {
        Some(anchor) => shares(model, i, anchor),
        None => contact::shares(model, i, &c.sites[i]),
    }
}

/// The sticking contacts' rows into `rows` from index `from`.
pub(crate) fn load_rows(model: &RodModel, w: &mut Workspace, from: usize) {
    for j in 0..w.kkt.contact.friction.sticks.len() {
        let stick = w.kkt.contact.friction.sticks[j];
        let shares = stick_shares(model, &w.kkt.contact, stick.slot);
        for (e, direction) in stick.directions.iter().enumerate() {
            contact::load_row(model, w, from + 2 * j + e, shares, direction);
        }
    }
}

/// The friction force of slot `i` at the last evaluation [N], and whether
/// it slides.
pub(crate) fn force(model: &RodModel, w: &Workspace, i: usize) -> (Vector3<f64>, bool) {
    if !model.has_friction() {
        return (Vector3::zeros(), false);
    }
    let reaction = w.kkt.reactions[first(model, w) + i];
    let site = &w.kkt.contact.sites[i];
    match w.kkt.contact.friction.sliding[i] {
        Some(_) => {
            let mu = model.friction(contact::slot(model, i).0);
            let f = &w.kkt.contact.friction;
            let d = effective_direction(model, f, i, site, &w.kkt.positions)
                .map(|(d, _)| d)
                .unwrap_or_default();
            (mu * reaction.x.max(0.0) * d, true)
        }
        None => {
            let t = tangents(&site.normal);
            (reaction.y * t[0] + reaction.z * t[1], false)
        }
    }
}
