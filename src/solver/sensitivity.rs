//! Sensitivities of an equilibrium by the implicit function theorem on its
//! factored Jacobian: O(n) a column.

use super::{Solver, Status};
use crate::error::{Error, Result};
use nalgebra::Vector3;

/// Derivatives of the tip of an equilibrium with respect to the actuation.
#[derive(Debug, Clone)]
pub struct TipSensitivity {
    /// `d r_tip / d kappa` [m^2], 3 x 2m.
    pub position: nalgebra::Matrix3xX<f64>,
    /// `d T_tip / d kappa` (tip tangent) [m], 3 x 2m.
    pub tangent: nalgebra::Matrix3xX<f64>,
}

impl Solver {
    /// Sensitivity of the tip of the last (converged, free-tip) equilibrium to the
    /// rest curvature of each of `sections` equal sections: columns `2s` and
    /// `2s + 1` are `d/d kappa_x` and `d/d kappa_y` of section `s`. Costs two
    /// O(n) back-substitutions a column with the Jacobian already factored.
    pub fn tip_sensitivity(&mut self, sections: usize) -> Result<TipSensitivity> {
        let n = self.model.n;
        if self.model.is_constrained() {
            return Err(Error::argument("tip_sensitivity", "needs a free tip"));
        }
        if self.model.scheme != crate::model::Scheme::Fd2 {
            return Err(Error::argument(
                "tip_sensitivity",
                "available for scheme 'fd2' only, for now",
            ));
        }
        if sections == 0 || n % sections != 0 {
            return Err(Error::argument(
                "sections",
                format!("{sections} sections do not divide {n} elements"),
            ));
        }
        let (model, w) = (&self.model, &mut self.work);
        model.residual_jacobian(&w.q, 1.0, &mut w.g, &mut w.jac);
        if w.lu.factor(&w.jac, 0.0).is_err() {
            return Err(Error::NotConverged {
                status: Status::NotConverged,
                iterations: 0,
                residual: model.residual_norm(&w.g),
                reason: "singular Jacobian: the equilibrium is at a bifurcation".into(),
            });
        }
        let mut d_tip = vec![nalgebra::Matrix3::zeros(); n];
        model.position_jacobian(&w.q, n, &mut d_tip);
        let tip = w.q[n];
        // d T_n / d theta_n = -R [e3]x
        let d_tangent = -(tip.rotation() * crate::quat::skew(&Vector3::z()));
        let per = n / sections;
        let mut out = TipSensitivity {
            position: nalgebra::Matrix3xX::zeros(2 * sections),
            tangent: nalgebra::Matrix3xX::zeros(2 * sections),
        };
        for s in 0..sections {
            for c in 0..2 {
                model.rest_curvature_gradient(&w.q, s * per + 1, (s + 1) * per, c, &mut w.step);
                w.lu.solve_in_place(&mut w.step);
                // d theta / d kappa = -A^{-1} dg/dkappa
                let dr: Vector3<f64> = d_tip.iter().zip(&w.step).map(|(b, x)| -(b * x)).sum();
                let dt = -(d_tangent * w.step[n - 1]);
                out.position.set_column(2 * s + c, &dr);
                out.tangent.set_column(2 * s + c, &dt);
            }
        }
        Ok(out)
    }
}
