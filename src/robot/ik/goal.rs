//! What one inverse solve aims at, and the error rows it drives to zero.
//!
//! The rows are the same for every drive: the aimed point's miss (3 rows,
//! metres), then, with a direction, the turn that takes the tip's tangent to
//! it, across the tangent (2 rows, radians times the robot's length `L`). So
//! `tol` is a distance for the point and an angle of `tol / L` for the
//! direction, whatever moves the tip.

use crate::quat::skew;
use crate::solver::Solution;
use nalgebra::{DMatrix, DVector, Matrix3xX, Vector3};

/// Target tolerance of the intermediate targets of a continuation [relative to L].
const CONTINUATION_TOL: f64 = 1e-4;

/// The point an inverse solve aims: `offset` from the tip in its frame (a
/// tool's point), the tip itself for a zero offset.
pub(crate) fn tool_point(sol: &Solution, offset: Vector3<f64>) -> Vector3<f64> {
    sol.tip_position() + sol.tip_quaternion().rotate(offset)
}

/// An orthonormal pair across the unit vector `t`.
fn across(t: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if t.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = t.cross(&helper).normalize();
    (u, t.cross(&u))
}

/// What one inverse solve aims at.
#[derive(Debug, Clone)]
pub(super) struct Goal {
    pub target: Vector3<f64>,
    /// A unit vector, world frame.
    pub direction: Option<Vector3<f64>>,
    /// The actuation the answer stays closest to, in the drive's coordinates.
    pub reference: DVector<f64>,
    pub tol: f64,
    /// Robot length: the weight of the direction rows.
    pub length: f64,
    /// The point aimed, from the tip in its frame (the tool's; zero: the tip).
    pub offset: Vector3<f64>,
}

impl Goal {
    /// Rows of the error: 3, or 5 with a direction.
    pub fn rows(&self) -> usize {
        if self.direction.is_some() {
            5
        } else {
            3
        }
    }

    /// The error of an equilibrium: the aimed point's miss, then the turn
    /// toward the direction across the tangent, times `L`.
    pub fn error(&self, sol: &Solution) -> DVector<f64> {
        let mut e = DVector::zeros(self.rows());
        e.rows_mut(0, 3)
            .copy_from(&(self.target - tool_point(sol, self.offset)));
        if let Some(d) = self.direction {
            let t = sol.tip_quaternion().tangent();
            let (u, v) = across(t);
            // The turn that takes t toward d, as a small rotation across t.
            let turn = t.cross(&d);
            let turn = if t.dot(&d) < 0.0 {
                // More than a right angle off: aim along the sine's direction
                // at full length (or any axis if antiparallel).
                turn.try_normalize(1e-12).unwrap_or(u)
            } else {
                turn
            };
            e[3] = turn.dot(&u) * self.length;
            e[4] = turn.dot(&v) * self.length;
        }
        e
    }

    /// Within `tol` of the point and `tol / L` of the direction.
    pub fn reached(&self, e: &DVector<f64>) -> bool {
        e.rows(0, 3).norm() <= self.tol && (e.len() == 3 || e.rows(3, 2).norm() <= self.tol)
    }

    /// The rows of [`Goal::error`] differentiated (negated) from the tip's
    /// sensitivities: its position and its turn (a world rotation vector),
    /// one column a drive coordinate. The aimed point moves with the turn
    /// too, `phi x (R c)`; the direction's rows are the turn across the tangent.
    pub fn jacobian(
        &self,
        sol: &Solution,
        position: &Matrix3xX<f64>,
        rotation: &Matrix3xX<f64>,
    ) -> DMatrix<f64> {
        let k = position.ncols();
        let mut jac = DMatrix::zeros(self.rows(), k);
        if self.offset == Vector3::zeros() {
            jac.rows_mut(0, 3).copy_from(position);
        } else {
            let arm = sol.tip_quaternion().rotate(self.offset);
            jac.rows_mut(0, 3)
                .copy_from(&(position - skew(&arm) * rotation));
        }
        if self.direction.is_some() {
            let (u, v) = across(sol.tip_quaternion().tangent());
            for c in 0..k {
                let phi: Vector3<f64> = rotation.column(c).into();
                jac[(3, c)] = phi.dot(&u) * self.length;
                jac[(4, c)] = phi.dot(&v) * self.length;
            }
        }
        jac
    }

    /// The goal a fraction `t` of the way from the aimed point (and
    /// direction) of `from` to this one, reached loosely short of the end.
    pub fn partway(&self, from: &Solution, t: f64) -> Goal {
        let direction = self.direction.map(|d| {
            let d0 = from.tip_quaternion().tangent();
            let mid = d0 + (d - d0) * t;
            // Antiparallel directions: turn through a perpendicular.
            if mid.norm() > 1e-3 {
                mid.normalize()
            } else {
                d0.cross(&Vector3::x())
                    .try_normalize(1e-6)
                    .unwrap_or(Vector3::y())
            }
        });
        let start = tool_point(from, self.offset);
        Goal {
            target: start + (self.target - start) * t,
            direction,
            tol: if t < 1.0 {
                CONTINUATION_TOL * self.length
            } else {
                self.tol
            },
            ..self.clone()
        }
    }

    /// Farther from the base than an inextensible backbone (and the tool) reach.
    pub fn beyond_length(&self, base: Vector3<f64>) -> bool {
        (self.target - base).norm() > self.length + self.offset.norm() + self.tol
    }
}
