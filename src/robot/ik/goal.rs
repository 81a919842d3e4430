//! What one inverse solve aims at, and the error rows it drives to zero.
//!
//! The rows are the same for every drive: the aimed point's miss (3 rows,
//! metres), then, with a direction, the turn that takes the tip's tangent to
//! it, across the tangent (2 rows), or, with an orientation (a full pose),
//! the turn that takes the tip's frame to it (3 rows), each in radians times
//! the robot's length `L`. So `tol` is a distance for the point and an angle
//! of `tol / L` for the direction or the orientation, whatever moves the tip.

use crate::quat::{skew, Quat};
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

/// What an inverse solve aims the tip's frame at besides its point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Aim {
    /// The point alone.
    #[default]
    Point,
    /// The tip's tangent along a unit vector, world frame.
    Direction(Vector3<f64>),
    /// The tip's frame: a full pose (a unit quaternion, world frame).
    Orientation(Quat),
}

impl From<Option<Vector3<f64>>> for Aim {
    /// A direction, or the point alone.
    fn from(direction: Option<Vector3<f64>>) -> Aim {
        direction.map_or(Aim::Point, Aim::Direction)
    }
}

/// The rotation vector of a unit quaternion (the shorter way round).
fn rotation_vector(q: Quat) -> Vector3<f64> {
    let q = if q.w < 0.0 { -q } else { q };
    let v = q.v;
    let s = v.norm();
    if s < 1e-300 {
        return Vector3::zeros();
    }
    v * (2.0 * s.atan2(q.w) / s)
}

/// What one inverse solve aims at.
#[derive(Debug, Clone)]
pub(super) struct Goal {
    pub target: Vector3<f64>,
    /// A unit vector, world frame.
    pub direction: Option<Vector3<f64>>,
    /// The tip frame's orientation, world frame (a full pose).
    pub orientation: Option<Quat>,
    /// The actuation the answer stays closest to, in the drive's coordinates.
    pub reference: DVector<f64>,
    pub tol: f64,
    /// Robot length: the weight of the direction rows.
    pub length: f64,
    /// The point aimed, from the tip in its frame (the tool's; zero: the tip).
    pub offset: Vector3<f64>,
    /// The obstacle (its index and shape) the aimed tip lies in, where the
    /// backbone, kept its radius off every obstacle, cannot be.
    pub inside_obstacle: Option<(usize, &'static str)>,
}

impl Goal {
    /// Rows of the error: 3, 5 with a direction, 6 with an orientation.
    pub fn rows(&self) -> usize {
        3 + 2 * usize::from(self.direction.is_some()) + 3 * usize::from(self.orientation.is_some())
    }

    /// The error of an equilibrium: the aimed point's miss, then the turn
    /// toward the direction across the tangent, times `L`.
    pub fn error(&self, sol: &Solution) -> DVector<f64> {
        self.error_at(sol.tip_position(), sol.tip_quaternion())
    }

    /// [`Goal::error`] of a tip at `position` [m] in the frame `frame`.
    pub fn error_at(&self, position: Vector3<f64>, frame: Quat) -> DVector<f64> {
        let mut e = DVector::zeros(self.rows());
        e.rows_mut(0, 3)
            .copy_from(&(self.target - position - frame.rotate(self.offset)));
        if let Some(d) = self.direction {
            let t = frame.tangent();
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
        if let Some(q) = self.orientation {
            // The turn that takes the tip's frame to the aimed one, world frame.
            let turn = rotation_vector(q * frame.conj());
            e.rows_mut(3, 3).copy_from(&(turn * self.length));
        }
        e
    }

    /// Whether the error's rows depend on the tip's turn (a direction, an
    /// orientation, or a tool's point off the tip).
    pub fn turns(&self) -> bool {
        self.rows() > 3 || self.offset != Vector3::zeros()
    }

    /// Within `tol` of the point and `tol / L` of the direction or orientation.
    pub fn reached(&self, e: &DVector<f64>) -> bool {
        e.rows(0, 3).norm() <= self.tol
            && (e.len() == 3 || e.rows(3, e.len() - 3).norm() <= self.tol)
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
        self.jacobian_at(sol.tip_quaternion(), position, rotation)
    }

    /// [`Goal::jacobian`] of a tip in the frame `frame`.
    pub fn jacobian_at(
        &self,
        frame: Quat,
        position: &Matrix3xX<f64>,
        rotation: &Matrix3xX<f64>,
    ) -> DMatrix<f64> {
        let k = position.ncols();
        let mut jac = DMatrix::zeros(self.rows(), k);
        if self.offset == Vector3::zeros() {
            jac.rows_mut(0, 3).copy_from(position);
        } else {
            let arm = frame.rotate(self.offset);
            jac.rows_mut(0, 3)
                .copy_from(&(position - skew(&arm) * rotation));
        }
        if self.direction.is_some() {
            let (u, v) = across(frame.tangent());
            for c in 0..k {
                let phi: Vector3<f64> = rotation.column(c).into();
                jac[(3, c)] = phi.dot(&u) * self.length;
                jac[(4, c)] = phi.dot(&v) * self.length;
            }
        }
        if self.orientation.is_some() {
            // Near the aimed frame the turn left falls by the tip's own turn.
            jac.rows_mut(3, 3).copy_from(&(rotation * self.length));
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
        let orientation = self.orientation.map(|q| {
            let q0 = from.tip_quaternion();
            Quat::from_rotation_vector(rotation_vector(q * q0.conj()) * t) * q0
        });
        let start = tool_point(from, self.offset);
        Goal {
            target: start + (self.target - start) * t,
            direction,
            orientation,
            tol: if t < 1.0 {
                CONTINUATION_TOL * self.length
            } else {
                self.tol
            },
            inside_obstacle: if t < 1.0 { None } else { self.inside_obstacle },
            ..self.clone()
        }
    }

    /// Where no tip can be: beyond the robot's length or inside an obstacle.
    pub fn unreachable(&self, base: Vector3<f64>) -> bool {
        self.beyond_length(base) || self.inside_obstacle.is_some()
    }

    /// Farther from the base than an inextensible backbone (and the tool) reach.
    pub fn beyond_length(&self, base: Vector3<f64>) -> bool {
        (self.target - base).norm() > self.length + self.offset.norm() + self.tol
    }
}
