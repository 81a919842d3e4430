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

use super::{indexed, Term};
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
    let mut value = 0.0;
    let mut moment = Vector3::zeros();
    let mut hessian = Matrix3::zeros();
    for t in tendons {
        let tension = scale * t.tension;
        if tension == 0.0 {
            continue;
        }
        let (rho, drho) = t.routing(s);
        let v = Vector3::z() + omega.cross(&rho) + drho;
        let length = v.norm();
        let unit = v / length;
        value += tension * length;
        // d v / d omega = -[rho]x.
        moment += tension * rho.cross(&unit);
        let arm = skew(&rho);
        let across = Matrix3::identity() - unit * unit.transpose();
        hessian += (tension / length) * arm.transpose() * across * arm;
    }
    (value, moment, hessian)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let step = 1e-6;
        for c in 0..3 {
            let d = Vector3::ith(c, step);
            let (vp, mp, _) = density(&tendons, 1.0, 0.3, &(omega + d));
            let (vm, mm, _) = density(&tendons, 1.0, 0.3, &(omega - d));
            assert!(((vp - vm) / (2.0 * step) - m[c]).abs() < 1e-9);
            assert!(((mp - mm) / (2.0 * step) - h.column(c)).norm() < 1e-8);
        }
    }
}
