//! Sliding ports in the constrained solve: two equality rows a port, after
//! the held points' and before the contacts' (see `contact::Port` for the
//! geometry, `constrained.rs` for the KKT system).
//!
//! A port's rows are `b_i . (c - p) = 0` at the crossing `c` of the
//! backbone's chord with the port's plane. With `c = (1 - s) r_(k-1) + s
//! r_k` and `s` sliding so that `c` stays on the plane, the rows' gradients
//! are `(1 - s) d_i` at node `k - 1` and `s d_i` at node `k`, `d_i = P^T
//! b_i` (exact: the slide is in them), and the port's force `sum lambda_i
//! d_i` is shared between the two nodes like a contact's. The multipliers
//! live after the held points' reactions in the workspace's `reactions`
//! (`x` and `y` of one vector a port).
//!
//! A port with friction has a third row, after every port's two: while it
//! sticks, the arc length of the material in it is held (`friction.rs`),
//! its multiplier the `z` of the port's vector; while it slides, its
//! friction `mu N` along the chord (`N` the lateral force's size) is a
//! force that moves with the lateral multipliers, and its row only keeps
//! its multiplier at zero.

use super::Workspace;
use crate::contact::{Crossing, Port};
use crate::model::RodModel;
use nalgebra::{DMatrix, Vector3};

/// One port's crossing at the last evaluation.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PortSite {
    /// Where the backbone crosses the port's plane; `None` where it does
    /// not (the rows' residuals are then infinite: no such step is taken).
    pub crossing: Option<Crossing>,
    /// The force directions of the two multipliers, `P^T b_i`.
    pub directions: [Vector3<f64>; 2],
    /// The rows' residuals `b_i . (c - p(lambda))` [m].
    pub residual: [f64; 2],
    /// The chord it crosses [m] and that element's rest length [m].
    pub chord: Vector3<f64>,
    pub h: f64,
    /// The arc length of the rod's material in the port [m].
    pub arc: f64,
}

/// A port's force along the rod beside the lateral one (see `friction.rs`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) enum Axial {
    /// Frictionless (or not crossed).
    #[default]
    Free,
    /// Sticking: its row's multiplier `f`, the force `f g` (`g` the row's
    /// direction, [`Port::axial_direction`]).
    Stick(f64),
    /// Sliding: `mu s`, the force `mu s N t` (`t` the chord's unit, `N` the
    /// size of the lateral force, `s = +-1`).
    Slide(f64),
}

/// A port's force on the rod with its multipliers `lambda` (lateral `x`,
/// `y`) and its friction `axial`, where it crosses `chord` of an element of
/// rest length `h` [N].
pub(crate) fn port_force(
    port: &Port,
    lambda: &Vector3<f64>,
    axial: Axial,
    chord: &Vector3<f64>,
    h: f64,
) -> Vector3<f64> {
    let [d1, d2] = port.force_directions(chord);
    let lateral = lambda.x * d1 + lambda.y * d2;
    match axial {
        Axial::Free => lateral,
        Axial::Stick(f) => lateral + f * port.axial_direction(chord, h),
        Axial::Slide(mu_s) => lateral + (mu_s * lateral.norm() / chord.norm()) * chord,
    }
}

/// The index of the first port's multiplier in `reactions` of length
/// `multipliers`: before the contact slots', counted from the end, so that
/// it stays in place whichever leg of a load path (released or holding,
/// with fewer or more held points' reactions first) is solved.
pub(crate) fn offset(model: &RodModel, multipliers: usize) -> usize {
    multipliers - model.ports().len() - super::contact::slot_count(model)
}

/// The first KKT row of the ports (after the held points').
pub(crate) fn first_row(model: &RodModel) -> usize {
    3 * model.constraints().len()
}

/// The number of port rows: two a port, and one more a port with friction.
pub(crate) fn row_count(model: &RodModel) -> usize {
    2 * model.ports().len() + model.frictional_ports().count()
}

/// The first row of the ports' friction (after every port's two).
pub(crate) fn first_axial_row(model: &RodModel) -> usize {
    first_row(model) + 2 * model.ports().len()
}

/// Every port's site at the node positions `r` and load scale `lambda`.
pub(crate) fn locate(model: &RodModel, r: &[Vector3<f64>], lambda: f64, sites: &mut [PortSite]) {
    for (p, site) in model.ports().iter().zip(sites.iter_mut()) {
        *site = match p.port.crossing(r) {
            Some(c) => {
                let chord = r[c.element] - r[c.element - 1];
                let h = model.h(c.element);
                PortSite {
                    crossing: Some(c),
                    directions: p.port.force_directions(&chord),
                    residual: p.residual(&c, lambda),
                    chord,
                    h,
                    arc: model.arc(c.element - 1) + c.s * h,
                }
            }
            None => PortSite {
                residual: [f64::INFINITY; 2],
                ..PortSite::default()
            },
        };
    }
}

/// The nodes and weights of a port's force: `(1 - s)` at node `k - 1`, `s`
/// at node `k`.
pub(crate) fn shares(site: &PortSite) -> [(usize, f64); 2] {
    match site.crossing {
        Some(c) => [(c.element - 1, 1.0 - c.s), (c.element, c.s)],
        None => [(0, 0.0), (0, 0.0)],
    }
}

/// A port's force on the rod from its multipliers `lambda` and its
/// friction `axial` [N].
pub(crate) fn force(
    port: &Port,
    site: &PortSite,
    lambda: &Vector3<f64>,
    axial: Axial,
) -> Vector3<f64> {
    if site.crossing.is_none() {
        return Vector3::zeros();
    }
    port_force(port, lambda, axial, &site.chord, site.h)
}

/// The last node a port's rows depend on.
pub(crate) fn last_node(site: &PortSite) -> usize {
    site.crossing.map_or(1, |c| c.element)
}

/// The ports' rows `d_i^T ((1 - s) D_(k-1) + s D_k)` as `n` vectors each
/// into `rows` from index `from`, then the friction rows (`friction.rs`
/// gives their directions).
pub(crate) fn load_rows(model: &RodModel, w: &mut Workspace, from: usize) {
    let ports = w.kkt.contact.ports.len();
    for j in 0..ports {
        let site = w.kkt.contact.ports[j];
        for (i, direction) in site.directions.iter().enumerate() {
            super::contact::load_row(model, w, from + 2 * j + i, shares(&site), direction);
        }
    }
    for a in 0..w.kkt.contact.friction.frictional_ports.len() {
        let j = w.kkt.contact.friction.frictional_ports[a];
        let site = w.kkt.contact.ports[j];
        let direction = w.kkt.contact.friction.ports[j].direction;
        super::contact::load_row(model, w, from + 2 * ports + a, shares(&site), &direction);
    }
}

/// Relative step of the differences of a port's force: a millionth of
/// the element.
const CURVATURE_STEP: f64 = 1e-6;

/// A port's curvature block (see `contact::curvature`): its force `sum
/// lambda_i d_i` (and its friction, `axial`) turns with the chord it
/// crosses, and its shares move with the crossing; `M = -dF/dr` over the
/// moving nodes of its element, by central differences, made symmetric
/// where it is the Hessian of `-lambda . h` (unsymmetric while the rod
/// slides through the port: its friction's turn with the chord). `None`
/// where there is no force or nothing moves.
pub(crate) fn curvature_block(
    model: &RodModel,
    index: usize,
    site: &PortSite,
    lambda: &Vector3<f64>,
    axial: Axial,
    r: &[Vector3<f64>],
) -> Option<(DMatrix<f64>, Vec<usize>)> {
    let c = site.crossing?;
    if lambda.x == 0.0 && lambda.y == 0.0 && matches!(axial, Axial::Free | Axial::Slide(_)) {
        return None;
    }
    let n = model.n();
    let clamped = model.clamped_tip().is_some();
    let port = &model.ports()[index].port;
    let (a, b) = (c.element - 1, c.element);
    let moving: Vec<usize> = [a, b]
        .into_iter()
        .filter(|&k| k > 0 && !(clamped && k == n))
        .collect();
    if moving.is_empty() {
        return None;
    }
    let step = CURVATURE_STEP * model.h(b);
    // The shares of the force at nodes a and b for the chord a-b.
    let shares = |ra: &Vector3<f64>, rb: &Vector3<f64>| -> Option<[Vector3<f64>; 2]> {
        let chord = rb - ra;
        let along = port.axis.dot(&chord);
        if along <= 0.0 {
            return None;
        }
        let s = port.axis.dot(&(port.position - ra)) / along;
        let f = port_force(port, lambda, axial, &chord, site.h);
        Some([(1.0 - s) * f, s * f])
    };
    let mut jac = DMatrix::zeros(6, 3 * moving.len());
    for (m, &k) in moving.iter().enumerate() {
        for axis in 0..3 {
            let shifted = |sign: f64| {
                let (mut ra, mut rb) = (r[a], r[b]);
                if k == a {
                    ra[axis] += sign * step;
                } else {
                    rb[axis] += sign * step;
                }
                shares(&ra, &rb)
            };
            let (plus, minus) = (shifted(1.0)?, shifted(-1.0)?);
            for share in 0..2 {
                let d = (plus[share] - minus[share]) / (2.0 * step);
                jac.view_mut((3 * share, 3 * m + axis), (3, 1))
                    .copy_from(&d);
            }
        }
    }
    let mut block = DMatrix::zeros(3 * moving.len(), 3 * moving.len());
    for (row, &k) in moving.iter().enumerate() {
        let share = usize::from(k == b);
        let part = jac.view((3 * share, 0), (3, 3 * moving.len()));
        block
            .view_mut((3 * row, 0), (3, 3 * moving.len()))
            .copy_from(&part);
    }
    // Without friction (or sticking) it is a Hessian, symmetric but for the
    // differences' round-off; a sliding port's friction is no potential's.
    let block = match axial {
        Axial::Slide(_) => -block,
        _ => -0.5 * (&block + block.transpose()),
    };
    (block.amax() > 0.0).then_some((block, moving))
}

/// A port's answer: where the rod passes it and the force it takes.
#[derive(Debug, Clone, PartialEq)]
pub struct PortReaction {
    /// Index of the port in the scene's list.
    pub port: usize,
    /// Arc length of the backbone point in the port [m].
    pub arc_length: f64,
    /// The backbone point in the port [m], world frame (the port's
    /// position, to the solve's tolerance).
    pub point: Vector3<f64>,
    /// The port's force on the rod [N], world frame: across the rod, and
    /// along it with friction.
    pub force: Vector3<f64>,
    /// The part of `force` along the rod: its friction [N] (zero without).
    pub friction: Vector3<f64>,
    /// Whether the rod slides through the port (its friction at `mu` times
    /// the rest of its force; false without friction).
    pub sliding: bool,
}

/// The ports' answers at the last evaluation.
pub(crate) fn reactions(model: &RodModel, w: &Workspace) -> Vec<PortReaction> {
    let first = offset(model, w.kkt.reactions.len());
    w.kkt
        .contact
        .ports
        .iter()
        .enumerate()
        .filter_map(|(j, site)| {
            let c = site.crossing?;
            let axial = super::friction::port_axial(model, w, j);
            let port = &model.ports()[j].port;
            let force = force(port, site, &w.kkt.reactions[first + j], axial);
            let t = site.chord.normalize();
            Some(PortReaction {
                port: j,
                arc_length: site.arc,
                point: c.point,
                force,
                friction: match axial {
                    Axial::Free => Vector3::zeros(),
                    _ => t * t.dot(&force),
                },
                sliding: matches!(axial, Axial::Slide(_)),
            })
        })
        .collect()
}
