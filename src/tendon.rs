//! Frictionless tendons in the discrete potential (docs/model.md, "Tendons").
//!
//! A tendon at offset `rho(s)` from the backbone (material frame) runs along
//! `p = r + R rho`, so `|p'| = |e3 + omega x rho + rho'|`: its potential
//! `tension * length` is an integral of a function of the curvature alone.
//! It enters each scheme where the elastic energy does, as a density in
//! `omega` with its gradient (a moment) and Hessian (a stiffness), so the
//! system stays banded and `stable` keeps its meaning; the anchor's force and
//! moment come out of the tendon ending at a node.

use crate::quat::skew;
use crate::scene::Tendon;
use nalgebra::{Matrix3, Vector3};

/// The tendons' potential density at curvature `omega` (material frame) at
/// arc length `s`, tensions times `scale`: its value [N], gradient in
/// `omega` (a moment [N m]) and Hessian [N m^2]. `tendons` are those that
/// reach past `s`. Kept out of line: the elements without tendons, the
/// common case, keep a small kernel.
#[inline(never)]
pub(crate) fn density(
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
