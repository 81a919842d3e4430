//! Unit quaternions, scalar first `(w, x, y, z)`, rotating material to world.
//!
//! A small explicit type rather than nalgebra's `Quaternion`, whose storage order
//! is `(x, y, z, w)`: the formulas of docs/model.md read one-to-one here.

use nalgebra::{Matrix3, Vector3};
use std::ops::Mul;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quat {
    pub w: f64,
    pub v: Vector3<f64>,
}

impl Quat {
    pub const IDENTITY: Quat = Quat {
        w: 1.0,
        v: Vector3::new(0.0, 0.0, 0.0),
    };

    pub fn new(w: f64, x: f64, y: f64, z: f64) -> Self {
        Quat {
            w,
            v: Vector3::new(x, y, z),
        }
    }

    pub fn from_array(a: [f64; 4]) -> Self {
        Quat::new(a[0], a[1], a[2], a[3])
    }

    pub fn to_array(self) -> [f64; 4] {
        [self.w, self.v.x, self.v.y, self.v.z]
    }

    pub fn pure(v: Vector3<f64>) -> Self {
        Quat { w: 0.0, v }
    }

    /// `q (0, e_k)` for the three axes `e_k`: the columns of `G(q)^T`,
    /// written out (built from `Vector3::ith` in a loop, the axis went
    /// through memory and stalled the fd2 kernel's store forwarding).
    #[inline(always)]
    pub fn times_axes(self) -> [Quat; 3] {
        let (w, v) = (self.w, self.v);
        [
            Quat::new(-v.x, w, v.z, -v.y),
            Quat::new(-v.y, -v.z, w, v.x),
            Quat::new(-v.z, v.y, -v.x, w),
        ]
    }

    pub fn conj(self) -> Self {
        Quat {
            w: self.w,
            v: -self.v,
        }
    }

    pub fn norm(self) -> f64 {
        (self.w * self.w + self.v.norm_squared()).sqrt()
    }

    pub fn normalized(self) -> Self {
        let n = self.norm();
        Quat {
            w: self.w / n,
            v: self.v / n,
        }
    }

    pub fn dot(self, o: Quat) -> f64 {
        self.w * o.w + self.v.dot(&o.v)
    }

    /// `exp(theta / 2)`: the unit quaternion of the rotation vector `theta`.
    pub fn from_rotation_vector(theta: Vector3<f64>) -> Self {
        let angle = theta.norm();
        let half = 0.5 * angle;
        // sin(half)/angle, with its series near zero (no division by zero).
        let s = if angle < 1e-4 {
            0.5 - angle * angle / 48.0
        } else {
            half.sin() / angle
        };
        Quat {
            w: half.cos(),
            v: theta * s,
        }
    }

    /// Body-frame update `q * exp(theta / 2)`, renormalised against round-off.
    pub fn perturbed(self, theta: Vector3<f64>) -> Self {
        (self * Quat::from_rotation_vector(theta)).normalized()
    }

    /// Rotation matrix `R(q)` (exact for unit `q`).
    pub fn rotation(self) -> Matrix3<f64> {
        let (w, x, y, z) = (self.w, self.v.x, self.v.y, self.v.z);
        Matrix3::new(
            w * w + x * x - y * y - z * z,
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            w * w - x * x + y * y - z * z,
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            w * w - x * x - y * y + z * z,
        )
    }

    /// `R(q) v` for unit `q`.
    pub fn rotate(self, v: Vector3<f64>) -> Vector3<f64> {
        let t = 2.0 * self.v.cross(&v);
        v + self.w * t + self.v.cross(&t)
    }

    /// `R(q)^T v` for unit `q`.
    pub fn inverse_rotate(self, v: Vector3<f64>) -> Vector3<f64> {
        self.conj().rotate(v)
    }

    /// Tangent `T(q)`: the third column of `R(q)`, a quadratic form in `q` (seed Eq. 29).
    pub fn tangent(self) -> Vector3<f64> {
        tangent_bilinear(self, self)
    }
}

/// Symmetric bilinear form `T(a, b)` of the tangent, `T(q, q) = T(q)` (seed Eq. 30).
pub fn tangent_bilinear(a: Quat, b: Quat) -> Vector3<f64> {
    let (aw, ax, ay, az) = (a.w, a.v.x, a.v.y, a.v.z);
    let (bw, bx, by, bz) = (b.w, b.v.x, b.v.y, b.v.z);
    Vector3::new(
        aw * by + ay * bw + ax * bz + az * bx,
        ay * bz + az * by - aw * bx - ax * bw,
        aw * bw + az * bz - ax * bx - ay * by,
    )
}

/// `S_F q`, with `S_F` the symmetric 4x4 matrix of `F . T(a, b) = a^T S_F b`.
pub fn tangent_form_apply(f: &Vector3<f64>, q: Quat) -> Quat {
    let (w, x, y, z) = (q.w, q.v.x, q.v.y, q.v.z);
    Quat::new(
        f.z * w - f.y * x + f.x * y,
        -f.y * w - f.z * x + f.x * z,
        f.x * w - f.z * y + f.y * z,
        f.x * x + f.y * y + f.z * z,
    )
}

/// `S q`, with `S` the symmetric 4x4 matrix of `q^T S q = c . R(q) m` (a
/// world vector `c` against a body vector `m`; `m = e3` is
/// [`tangent_form_apply`]): from `R(q) = (w^2 - |v|^2) I + 2 v v^T + 2 w [v]x`.
pub fn rotation_form_apply(c: &Vector3<f64>, m: &Vector3<f64>, q: Quat) -> Quat {
    let (w, v) = (q.w, q.v);
    let cm = c.dot(m);
    let mc = m.cross(c);
    Quat {
        w: cm * w + mc.dot(&v),
        v: mc * w - cm * v + c * m.dot(&v) + m * c.dot(&v),
    }
}

/// Cross-product matrix `[v]x`, `[v]x u = v x u`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

impl std::ops::Neg for Quat {
    type Output = Quat;
    fn neg(self) -> Quat {
        Quat {
            w: -self.w,
            v: -self.v,
        }
    }
}

impl Mul for Quat {
    type Output = Quat;
    fn mul(self, o: Quat) -> Quat {
        Quat {
            w: self.w * o.w - self.v.dot(&o.v),
            v: self.w * o.v + o.w * self.v + self.v.cross(&o.v),
        }
    }
}

/// The potential `c . R(x) m` of a world vector `c` against a body vector
/// `m` at a unit node `x`: its value, gradient in the body-frame rotation
/// (`R(x exp(theta/2)) m = R(x) (m + theta x m + ...)`) and that gradient's
/// derivative under the same update (as the schemes' other node terms).
pub(crate) fn body_vector_terms(
    x: Quat,
    c: &Vector3<f64>,
    m: &Vector3<f64>,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let f = x.inverse_rotate(*c);
    (f.dot(m), m.cross(&f), skew(m) * skew(&f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_axes_is_the_product_with_each_pure_axis() {
        let q = Quat::new(0.3, -0.5, 0.7, 0.2);
        for (k, got) in q.times_axes().into_iter().enumerate() {
            let want = q * Quat::pure(Vector3::ith(k, 1.0));
            assert_eq!(got.to_array(), want.to_array(), "axis {k}");
        }
    }

    #[test]
    fn rotation_matches_rotate_and_tangent() {
        let q = Quat::new(0.3, -0.5, 0.7, 0.2).normalized();
        let v = Vector3::new(0.1, -2.0, 0.4);
        assert!((q.rotation() * v - q.rotate(v)).norm() < 1e-14);
        assert!((q.rotation().column(2) - q.tangent()).norm() < 1e-14);
        assert!((q.inverse_rotate(q.rotate(v)) - v).norm() < 1e-14);
    }

    #[test]
    fn tangent_form_matches_bilinear() {
        let a = Quat::new(0.3, -0.5, 0.7, 0.2);
        let b = Quat::new(-0.1, 0.4, 0.9, -0.3);
        let f = Vector3::new(1.5, -0.7, 0.25);
        assert!((a.dot(tangent_form_apply(&f, b)) - f.dot(&tangent_bilinear(a, b))).abs() < 1e-14);
        // The general form: its quadratic value is c . R(q) m, and m = e3 is the tangent's.
        let (c, m) = (Vector3::new(0.3, -1.2, 0.7), Vector3::new(-0.4, 0.9, 0.2));
        let unit = a.normalized();
        let value = unit.dot(rotation_form_apply(&c, &m, unit));
        assert!((value - c.dot(&unit.rotate(m))).abs() < 1e-14);
        let z = rotation_form_apply(&f, &Vector3::z(), b);
        assert!((z.to_array()[0] - tangent_form_apply(&f, b).to_array()[0]).abs() < 1e-14);
        assert!((z.v - tangent_form_apply(&f, b).v).norm() < 1e-14);
    }

    #[test]
    fn exp_map_rotates_by_angle() {
        let theta = Vector3::new(0.0, 0.0, 1.0);
        let q = Quat::from_rotation_vector(theta);
        let x = q.rotate(Vector3::x());
        assert!((x - Vector3::new(1.0f64.cos(), 1.0f64.sin(), 0.0)).norm() < 1e-14);
    }
}
