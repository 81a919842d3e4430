//! Frictionless tendons in the discrete potential (docs/model.md, "Tendons"):
//! a curvature density in the loading; its parameters are the tensions.
//!
//! A tendon at offset `rho(s)` from the backbone (material frame) runs along
//! `p = r + R rho`, so `|p'| = |e3 + omega x rho + rho'|`: its potential
//! `tension * length` is an integral of a function of the curvature alone.
//! It enters each scheme where the elastic energy does, as a density in
//! `omega` with its gradient (a moment) and Hessian (a stiffness), so the
//! system stays banded and `stable` keeps its meaning; the anchor's force and
//! moment come out of the tendon ending at a node.

use super::{indexed, split_index, BendingLoads, Term};
use crate::disc::{CurvatureDensity, Loading};
use crate::error::Result;
use crate::mesh::Mesh;
use crate::quat::skew;
use crate::scene::{Scene, Tendon};
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// The tendons of a rod, longest first (the tendons through an element are
/// a prefix), with the scene's index of each.
#[derive(Debug, Clone)]
pub struct Tendons {
    tendons: Vec<Tendon>,
    order: Vec<usize>,
    /// The last element each reaches (its anchor's node).
    last: Vec<usize>,
    n: usize,
}

/// The density of `tendons` (a prefix of them through each element:
/// `through[i - 1]` of them through element `i`).
#[derive(Debug)]
struct TendonDensity {
    tendons: Vec<Tendon>,
    through: Vec<usize>,
}

impl CurvatureDensity for TendonDensity {
    #[inline]
    fn acts_on(&self, element: usize) -> bool {
        self.through[element - 1] > 0
    }

    fn density(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<(f64, Vector3<f64>, Matrix3<f64>)> {
        match self.through[element - 1] {
            0 => None,
            k => Some(density(&self.tendons[..k], scale, s, omega)),
        }
    }

    fn moment(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<Vector3<f64>> {
        match self.through[element - 1] {
            0 => None,
            k => Some(moment(&self.tendons[..k], scale, s, omega)),
        }
    }

    fn value(&self, element: usize, s: f64, omega: &Vector3<f64>, scale: f64) -> Option<f64> {
        match self.through[element - 1] {
            0 => None,
            k => Some(value(&self.tendons[..k], scale, s, omega)),
        }
    }
}

/// Which number of a tendon's routing a parameter is: routing `routing`
/// (0 from the base, then one a change), its offset's `x` or `y` or its twist.
#[derive(Debug, Clone, Copy, PartialEq)]
enum RoutingNumber {
    Offset(usize),
    Twist,
}

/// The derivative of one tendon's density in one number of its routing,
/// at fixed curvature: a density of its own (value, moment and stiffness
/// differentiated), acting where that routing runs.
#[derive(Debug)]
struct RoutingTangent {
    tendon: Tendon,
    routing: usize,
    number: RoutingNumber,
    through: Vec<usize>,
}

impl CurvatureDensity for RoutingTangent {
    #[inline]
    fn acts_on(&self, element: usize) -> bool {
        self.through[element - 1] > 0
    }

    fn density(
        &self,
        element: usize,
        s: f64,
        omega: &Vector3<f64>,
        scale: f64,
    ) -> Option<(f64, Vector3<f64>, Matrix3<f64>)> {
        if self.through[element - 1] == 0 {
            return None;
        }
        let (rho, drho) = self.tendon.routing(s);
        let (d_rho, d_drho) = routing_derivative(&self.tendon, s, self.routing, self.number)?;
        Some(density_derivative(
            scale * self.tendon.tension,
            (rho, drho),
            (d_rho, d_drho),
            omega,
        ))
    }
}

/// `(d rho, d rho')` at arc length `s` in one number of routing `routing`
/// of `tendon`, `None` where another routing runs. With `theta = twist (s -
/// from)`, `rho = R(theta) (x, y)`, `rho' = twist J rho` (`J` a quarter turn).
fn routing_derivative(
    tendon: &Tendon,
    s: f64,
    routing: usize,
    number: RoutingNumber,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let running = tendon
        .reroutes
        .iter()
        .filter(|(start, _)| *start <= s)
        .count();
    if running != routing {
        return None;
    }
    let (twist, from) = match routing {
        0 => (tendon.twist, 0.0),
        r => (tendon.reroutes[r - 1].1.twist, tendon.reroutes[r - 1].0),
    };
    let quarter = |v: Vector3<f64>| Vector3::new(-v.y, v.x, 0.0);
    let (sin, cos) = (twist * (s - from)).sin_cos();
    Some(match number {
        RoutingNumber::Offset(c) => {
            let d_rho = match c {
                0 => Vector3::new(cos, sin, 0.0),
                _ => Vector3::new(-sin, cos, 0.0),
            };
            (d_rho, twist * quarter(d_rho))
        }
        RoutingNumber::Twist => {
            let (rho, _) = tendon.routing(s);
            let d_rho = (s - from) * quarter(rho);
            (d_rho, quarter(rho) + twist * quarter(d_rho))
        }
    })
}

/// One tendon's density (value, moment, stiffness; see [`density`])
/// differentiated along a change `(d rho, d rho')` of its routing at fixed
/// curvature `omega`: with `v = e3 + omega x rho + rho'`, `u = v / |v|`,
/// `P = I - u u^T` and `A = [rho]x`, the value `T |v|`, the moment
/// `T rho x u` and the stiffness `T / |v| A^T P A` have the derivatives
/// `T u . dv`, `T (d rho x u + rho x du)` and their product rule, where
/// `dv = omega x d rho + d rho'` and `du = P dv / |v|`.
fn density_derivative(
    tension: f64,
    (rho, drho): (Vector3<f64>, Vector3<f64>),
    (d_rho, d_drho): (Vector3<f64>, Vector3<f64>),
    omega: &Vector3<f64>,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    if tension == 0.0 {
        return (0.0, Vector3::zeros(), Matrix3::zeros());
    }
    let v = Vector3::z() + omega.cross(&rho) + drho;
    let length = v.norm();
    let unit = v / length;
    let across = Matrix3::identity() - unit * unit.transpose();
    let dv = omega.cross(&d_rho) + d_drho;
    let d_length = unit.dot(&dv);
    let d_unit = across * dv / length;
    let d_across = -(d_unit * unit.transpose() + unit * d_unit.transpose());
    let (arm, d_arm) = (skew(&rho), skew(&d_rho));
    let moment = tension * (d_rho.cross(&unit) + rho.cross(&d_unit));
    let stiffness = (tension / length)
        * (d_arm.transpose() * across * arm
            + arm.transpose() * d_across * arm
            + arm.transpose() * across * d_arm
            - (d_length / length) * arm.transpose() * across * arm);
    (tension * d_length, moment, stiffness)
}

/// The routing number a parameter names, relative to its tendon: `offset[c]`
/// or `twist` of a tendon of one routing, `offset[r][c]` or `twist[r]` of
/// one routed section by section (as the scene's dict names them).
fn routing_number(rest: &str, routings: usize) -> Option<(usize, RoutingNumber)> {
    let indices = |tail: &str| -> Option<Vec<usize>> {
        tail.split(']')
            .filter(|p| !p.is_empty())
            .map(|p| p.strip_prefix('[')?.parse().ok())
            .collect()
    };
    if let Some(tail) = rest.strip_prefix(".offset") {
        return match (indices(tail)?.as_slice(), routings) {
            (&[c], 1) if c < 2 => Some((0, RoutingNumber::Offset(c))),
            (&[r, c], m) if m > 1 && r < m && c < 2 => Some((r, RoutingNumber::Offset(c))),
            _ => None,
        };
    }
    let tail = rest.strip_prefix(".twist")?;
    match (indices(tail)?.as_slice(), routings) {
        (&[], 1) => Some((0, RoutingNumber::Twist)),
        (&[r], m) if m > 1 && r < m => Some((r, RoutingNumber::Twist)),
        _ => None,
    }
}

impl Tendons {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        // Longest first (a stable sort: equal ends keep the scene's order).
        let mut order: Vec<usize> = (0..scene.tendons.len()).collect();
        order.sort_by(|a, b| scene.tendons[*b].end.total_cmp(&scene.tendons[*a].end));
        let tendons: Vec<Tendon> = order.iter().map(|i| scene.tendons[*i].clone()).collect();
        let last = tendons.iter().map(|t| mesh.nearest_node(t.end)).collect();
        Tendons {
            tendons,
            order,
            last,
            n: mesh.n(),
        }
    }

    /// Set the tensions, in the scene's order (checked by the caller).
    pub fn set_tensions(&mut self, tensions: &[f64]) {
        assert_eq!(tensions.len(), self.tendons.len(), "one tension a tendon");
        for (t, i) in self.tendons.iter_mut().zip(&self.order) {
            t.tension = tensions[*i];
        }
    }

    /// How many of `last` (decreasing) reach element `i`, for every element.
    fn through(&self, last: &[usize]) -> Vec<usize> {
        (1..=self.n)
            .map(|i| last.iter().take_while(|l| **l >= i).count())
            .collect()
    }
}

impl Term for Tendons {
    fn apply(&self, mesh: &Mesh, loading: &mut Loading) {
        self.apply_densities(mesh, loading);
    }

    fn apply_densities(&self, _mesh: &Mesh, loading: &mut Loading) {
        if self.tendons.is_empty() {
            return;
        }
        loading.densities.push(Arc::new(TendonDensity {
            tendons: self.tendons.clone(),
            through: self.through(&self.last),
        }));
    }

    fn moment_scale(&self, _length: f64) -> f64 {
        self.tendons
            .iter()
            .map(|t| t.tension * t.largest_offset())
            .sum()
    }

    fn bending_loads(&self, length: f64) -> BendingLoads {
        BendingLoads {
            force: 0.0,
            moment: self.moment_scale(length),
        }
    }

    fn vanishes(&self) -> bool {
        self.tendons.iter().all(|t| t.tension == 0.0)
    }

    fn breaks(&self, mesh: &Mesh, out: &mut Vec<usize>) {
        // Anchors, and where a routing changes (the tendon crosses a disk).
        out.extend(&self.last);
        for t in &self.tendons {
            out.extend(
                t.reroutes
                    .iter()
                    .map(|(start, _)| mesh.nearest_node(*start)),
            );
        }
    }

    fn derivative(&self, parameter: &str, _mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        if let Some((k, rest)) = split_index(parameter, "tendons") {
            if let Some(at) = self.order.iter().position(|i| *i == k) {
                let tendon = &self.tendons[at];
                if let Some((routing, number)) = routing_number(rest, tendon.routings().count()) {
                    // Its own density's derivative, on the elements it runs by.
                    tangent.support = match tangent.is_empty() {
                        true => Some((1, self.last[at].max(1))),
                        false => None,
                    };
                    tangent.densities.push(Arc::new(RoutingTangent {
                        tendon: tendon.clone(),
                        routing,
                        number,
                        through: self.through(&self.last[at..=at]),
                    }));
                    return Ok(true);
                }
            }
        }
        let Some(k) = indexed(parameter, "tendons", ".tension") else {
            return Ok(false);
        };
        let Some(at) = self.order.iter().position(|i| *i == k) else {
            return Ok(false);
        };
        // The equations are linear in a tension: its unit tension alone.
        let unit = Tendon {
            tension: 1.0,
            ..self.tendons[at].clone()
        };
        tangent.support = match tangent.is_empty() {
            true => Some((1, self.last[at].max(1))),
            false => None,
        };
        tangent.densities.push(Arc::new(TendonDensity {
            tendons: vec![unit],
            through: self.through(&self.last[at..=at]),
        }));
        Ok(true)
    }
}

/// The tendons' potential density at curvature `omega` (material frame) at
/// arc length `s`, tensions times `scale`: its value [N], gradient in
/// `omega` (a moment [N m]) and Hessian [N m^2]. `tendons` are those that
/// reach past `s`. Called from the tendons' curvature density, out of the
/// schemes' line.
#[inline]
pub fn density(
    tendons: &[Tendon],
    scale: f64,
    s: f64,
    omega: &Vector3<f64>,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    density_of(paths(tendons, scale, s, s, omega))
}

/// [`density`] at `s` with the routings of the stretch at `stretch_at`
/// ([`Tendon::routing_on`]): shooting's stages at an element's end.
#[inline]
pub fn density_on(
    tendons: &[Tendon],
    scale: f64,
    (s, stretch_at): (f64, f64),
    omega: &Vector3<f64>,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    density_of(paths(tendons, scale, s, stretch_at, omega))
}

/// The value, moment and stiffness of the `(tension, rho, v)` paths.
#[inline]
fn density_of(
    paths: impl Iterator<Item = (f64, Vector3<f64>, Vector3<f64>)>,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let mut value = 0.0;
    let mut moment = Vector3::zeros();
    let mut hessian = Matrix3::zeros();
    for (tension, rho, v) in paths {
        let length = v.norm();
        // One division (this loop is the tendon robot's hottest).
        let inverse = 1.0 / length;
        let unit = v * inverse;
        value += tension * length;
        // d v / d omega = -[rho]x.
        let arm = rho.cross(&unit);
        moment += tension * arm;
        // The stiffness A^T (I - u u^T) A with A = [rho]x, without the 3 x 3
        // products: A^T A = |rho|^2 I - rho rho^T and A^T u = -rho x u.
        let c = tension * inverse;
        let r = c * rho;
        let w = c * arm;
        hessian +=
            Matrix3::from_diagonal_element(r.dot(&rho)) - r * rho.transpose() - w * arm.transpose();
    }
    (value, moment, hessian)
}

/// [`density`]'s value alone: `sum tension |v|`.
fn value(tendons: &[Tendon], scale: f64, s: f64, omega: &Vector3<f64>) -> f64 {
    // As [`density`] sums it, to the last bit.
    paths(tendons, scale, s, s, omega)
        .fold(0.0, |value, (tension, _, v)| value + tension * v.norm())
}

/// [`density`]'s moment alone: `sum tension rho x v / |v|`.
#[inline]
pub fn moment(tendons: &[Tendon], scale: f64, s: f64, omega: &Vector3<f64>) -> Vector3<f64> {
    paths(tendons, scale, s, s, omega).fold(Vector3::zeros(), |moment, (tension, rho, v)| {
        // As [`density`] computes it, to the last bit.
        moment + tension * rho.cross(&(v * (1.0 / v.norm())))
    })
}

/// Each pulled tendon's tension, offset `rho` and path tangent
/// `v = e3 + omega x rho + rho'` at `s` with the routing of the stretch at
/// `stretch_at` (the slack ones skipped).
#[inline]
fn paths<'a>(
    tendons: &'a [Tendon],
    scale: f64,
    s: f64,
    stretch_at: f64,
    omega: &'a Vector3<f64>,
) -> impl Iterator<Item = (f64, Vector3<f64>, Vector3<f64>)> + 'a {
    tendons.iter().filter_map(move |t| {
        let tension = scale * t.tension;
        if tension == 0.0 {
            return None;
        }
        let (rho, drho) = t.routing_on(s, stretch_at);
        Some((tension, rho, Vector3::z() + omega.cross(&rho) + drho))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Routing;

    #[test]
    fn the_moment_and_stiffness_are_the_derivatives_of_the_density() {
        let tendons = [
            Tendon {
                tension: 2.0,
                offset: [0.02, -0.01],
                twist: 3.0,
                end: 1.0,
                ..Tendon::default()
            },
            Tendon {
                tension: 0.7,
                offset: [-0.015, 0.005],
                twist: 0.0,
                end: 1.0,
                ..Tendon::default()
            },
        ];
        let omega = Vector3::new(1.3, -2.1, 0.4);
        let (_, m, h) = density(&tendons, 1.0, 0.3, &omega);
        assert_eq!(
            moment(&tendons, 1.0, 0.3, &omega),
            m,
            "the moment alone is the same"
        );
        let step = 1e-6;
        for c in 0..3 {
            let d = Vector3::ith(c, step);
            let (vp, mp, _) = density(&tendons, 1.0, 0.3, &(omega + d));
            let (vm, mm, _) = density(&tendons, 1.0, 0.3, &(omega - d));
            assert!(((vp - vm) / (2.0 * step) - m[c]).abs() < 1e-9);
            assert!(((mp - mm) / (2.0 * step) - h.column(c)).norm() < 1e-8);
        }
    }

    /// A density's value, moment and stiffness.
    type Density = (f64, Vector3<f64>, Matrix3<f64>);

    /// A tendon routed section by section: two routings, the second from 0.4.
    fn rerouted() -> Tendon {
        Tendon {
            tension: 1.7,
            offset: [0.02, -0.01],
            twist: 3.0,
            reroutes: vec![(
                0.4,
                Routing {
                    offset: [-0.015, 0.012],
                    twist: -2.0,
                },
            )],
            end: 1.0,
        }
    }

    #[test]
    fn a_routing_tangent_is_the_derivative_of_the_density() {
        let omega = Vector3::new(1.3, -2.1, 0.4);
        let numbers = [
            RoutingNumber::Offset(0),
            RoutingNumber::Offset(1),
            RoutingNumber::Twist,
        ];
        // Stations in the first routing and in the second.
        for (s, routing) in [(0.3, 0usize), (0.7, 1)] {
            for number in numbers {
                let tangent = RoutingTangent {
                    tendon: rerouted(),
                    routing,
                    number,
                    through: vec![1],
                };
                let (dv, dm, dk) = tangent.density(1, s, &omega, 1.0).unwrap();
                // Five-point differences of the density in that number.
                let at = |delta: f64| {
                    let mut t = rerouted();
                    let r = match routing {
                        0 => &mut t.offset,
                        _ => &mut t.reroutes[0].1.offset,
                    };
                    match number {
                        RoutingNumber::Offset(c) => r[c] += delta,
                        RoutingNumber::Twist => match routing {
                            0 => t.twist += delta,
                            _ => t.reroutes[0].1.twist += delta,
                        },
                    }
                    density(&[t], 1.0, s, &omega)
                };
                let h = 1e-4;
                let (p2, p1, m1, m2) = (at(2.0 * h), at(h), at(-h), at(-2.0 * h));
                let five = |f: &dyn Fn(&Density) -> nalgebra::DMatrix<f64>| {
                    (f(&m2) - 8.0 * f(&m1) + 8.0 * f(&p1) - f(&p2)) / (12.0 * h)
                };
                let value = five(&|d| nalgebra::DMatrix::from_element(1, 1, d.0));
                let moment = five(&|d| nalgebra::DMatrix::from_column_slice(3, 1, d.1.as_slice()));
                let stiffness =
                    five(&|d| nalgebra::DMatrix::from_column_slice(3, 3, d.2.as_slice()));
                let label = format!("s = {s}, {number:?}");
                assert!(
                    (value[(0, 0)] - dv).abs() < 1e-9 * dv.abs().max(1e-3),
                    "{label}"
                );
                assert!(
                    (moment - nalgebra::DMatrix::from_column_slice(3, 1, dm.as_slice())).norm()
                        < 1e-9,
                    "{label}"
                );
                assert!(
                    (stiffness - nalgebra::DMatrix::from_column_slice(3, 3, dk.as_slice())).norm()
                        < 1e-9,
                    "{label}"
                );
                // The other routing's numbers do not act here.
                let other = RoutingTangent {
                    routing: 1 - routing,
                    ..tangent
                };
                assert!(other.density(1, s, &omega, 1.0).is_none());
            }
        }
    }

    #[test]
    fn routing_numbers_are_read_as_the_scene_names_them() {
        assert_eq!(
            routing_number(".offset[1]", 1),
            Some((0, RoutingNumber::Offset(1)))
        );
        assert_eq!(routing_number(".twist", 1), Some((0, RoutingNumber::Twist)));
        assert_eq!(
            routing_number(".offset[1][0]", 2),
            Some((1, RoutingNumber::Offset(0)))
        );
        assert_eq!(
            routing_number(".twist[1]", 2),
            Some((1, RoutingNumber::Twist))
        );
        for (rest, routings) in [
            (".offset[2]", 1),
            (".offset[0]", 2),
            (".twist", 2),
            (".twist[2]", 2),
            (".end", 1),
        ] {
            assert_eq!(routing_number(rest, routings), None, "{rest}");
        }
    }
}
