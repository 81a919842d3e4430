//! The fourth-order scheme (`Scheme::Fe4`, docs/model.md "A fourth-order
//! backbone"): quadratic finite elements of the rotation, the elastic energy
//! by two-point Gauss quadrature and the loads by Simpson's rule.
//!
//! Element `i` joins the nodes `a = q_{i-1}` and `b = q_i` through an internal
//! node `m` at its middle. Along the element (`tau` in `[0, 1]`) the quaternion
//! is the quadratic interpolant `q = N_a a + N_m m + N_b b`, normalised; with
//! `p = dq/ds` the curvature at a point is
//!
//! ```text
//! omega = 2 vec(conj(q) p) / |q|^2
//! ```
//!
//! and the element's potential is the elastic energy `h/2 sum_g 1/2 (omega -
//! omega0_g)^T K (omega - omega0_g)` over the Gauss points `tau = 1/2 -+
//! sqrt(3)/6` minus the loads' work by Simpson at the nodes,
//! `h/6 (F_a . T(a) + 4 F_m . T(m) + F_b . T(b))`. Both rules are exact for cubics: order 4 at the nodes (a
//! Galerkin discretisation of degree 2). Positions follow from the same rule,
//! `r_b = r_a + h/6 (T(a) + 4 T(m) + T(b))`. `omega0_g` is the curvature the
//! exact arc of the rest curvature has at the Gauss points, so the rest
//! shape is exactly the arcs ([`gauss_rest_curvature`]).
//!
//! The internal node is condensed out exactly: for given element ends it
//! minimises the element's potential (a three-unknown Newton iteration), so
//! the scheme's unknowns are the `n + 1` node rotations, its residual is the
//! gradient of the reduced potential (the envelope theorem) and its Jacobian
//! the Schur complement: block-tridiagonal, as for the second-order scheme.

use super::{Discretisation, Interior, Loading, NodeForces, Rod, Scheme};
use crate::blocktri::BlockTridiagonal;
use crate::quat::{skew, Quat};
use nalgebra::{DMatrix, Matrix3, Matrix3x4, Matrix4, SMatrix, Vector3, Vector4};

type Matrix4x3 = SMatrix<f64, 4, 3>;

/// `sqrt(3) / 6`: the Gauss points sit at `1/2 -+` this.
pub(crate) const GAUSS_OFFSET: f64 = 0.288_675_134_594_812_9;
/// Gauss points on `[0, 1]`.
pub(crate) const GAUSS: [f64; 2] = [0.5 - GAUSS_OFFSET, 0.5 + GAUSS_OFFSET];

/// Newton iterations of the internal node, and when to stop them: Newton
/// converges quadratically, so after a step below `MID_STEP_TOL` radians the
/// node is within about its square of the optimum (at round-off); the rest
/// chain, solved once, iterates until its steps are themselves at round-off.
const MID_ITERATIONS: usize = 12;
const MID_STEP_TOL: f64 = 1e-8;
const REST_STEP_TOL: f64 = 1e-13;
/// A chord iteration whose step shrinks by less than this factor switches to
/// Newton (its error after a step is about this factor times the step).
const CHORD_CONTRACTION: f64 = 0.01;

/// What one element needs besides its nodes, at a load scale.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Element<'a> {
    /// Length [m].
    pub h: f64,
    /// Diagonal stiffness [N m^2].
    pub stiffness: Vector3<f64>,
    /// Rest curvature at the Gauss points, material frame [1/m].
    pub rest: Vector3<f64>,
    /// Added to the elastic moment `K (omega - rest)`: zero, or along a
    /// tangent of the loading `-K domega0` (see `Discretisation::residual_derivative`).
    pub shift: Vector3<f64>,
    /// Internal force at the element's start, middle and end (`tau = 0,
    /// 1/2, 1`, just inside the element), world frame [N].
    pub force: [Vector3<f64>; 3],
    /// Dead moment per length, world frame [N m / m].
    pub moment: Vector3<f64>,
    /// The loading whose curvature densities and body-vector potentials act
    /// on the element, its index (from 1) and their scale (the load scale).
    pub loading: &'a Loading,
    pub index: usize,
    pub scale: f64,
    /// Whether a curvature density acts on it.
    pub density: bool,
    /// Arc length of the element's start [m] (where the densities are evaluated).
    pub start: f64,
}
/// Gradient and Jacobian of an element in the body-frame rotations of its
/// nodes `(a, m, b)` (see `model.rs` for the update and the residual).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Derivatives {
    pub grad: [Vector3<f64>; 3],
    pub jac: [[Matrix3<f64>; 3]; 3],
}

/// The quadratic basis on `tau = 0, 1/2, 1` and its derivative in `tau`.
fn basis(tau: f64) -> ([f64; 3], [f64; 3]) {
    (
        [
            (1.0 - tau) * (1.0 - 2.0 * tau),
            4.0 * tau * (1.0 - tau),
            tau * (2.0 * tau - 1.0),
        ],
        [4.0 * tau - 3.0, 4.0 - 8.0 * tau, 4.0 * tau - 1.0],
    )
}

fn v4(q: Quat) -> Vector4<f64> {
    Vector4::new(q.w, q.v.x, q.v.y, q.v.z)
}

fn vec_part(x: &Vector4<f64>) -> Vector3<f64> {
    Vector3::new(x[1], x[2], x[3])
}

/// `x (0, mu)`, the quaternion product with a pure quaternion.
fn times_pure(x: &Vector4<f64>, mu: &Vector3<f64>) -> Vector4<f64> {
    let xv = vec_part(x);
    let v = x[0] * mu + xv.cross(mu);
    Vector4::new(-xv.dot(mu), v.x, v.y, v.z)
}

/// `B(x)`, the 3x4 matrix of `y -> vec(conj(x) y)`; `B(x)^T mu = x (0, mu)`.
fn conj_product(x: &Vector4<f64>) -> Matrix3x4<f64> {
    let xv = vec_part(x);
    let m = Matrix3::identity() * x[0] - skew(&xv);
    Matrix3x4::from_columns(&[
        -xv,
        m.column(0).into(),
        m.column(1).into(),
        m.column(2).into(),
    ])
}

/// `E = d (x exp(theta/2)) / d theta` at 0: the columns `x (0, e_c) / 2`.
#[inline(always)]
fn update_basis(x: &Vector4<f64>) -> Matrix4x3 {
    let h = 0.5 * x;
    Matrix4x3::new(
        -h[1], -h[2], -h[3], //
        h[0], -h[3], h[2], //
        h[3], h[0], -h[1], //
        -h[2], h[1], h[0],
    )
}

/// The 4x4 matrix of `x -> x (0, mu)` (antisymmetric).
fn right_pure(mu: &Vector3<f64>) -> Matrix4<f64> {
    Matrix4::new(
        0.0, -mu.x, -mu.y, -mu.z, //
        mu.x, 0.0, mu.z, -mu.y, //
        mu.y, -mu.z, 0.0, mu.x, //
        mu.z, mu.y, -mu.x, 0.0,
    )
}

/// The elastic energy density at one point and its derivatives in
/// `(q, p)`, the interpolated quaternion and its arc-length derivative.
struct PointTerms {
    value: f64,
    grad_q: Vector4<f64>,
    grad_p: Vector4<f64>,
    hqq: Matrix4<f64>,
    /// Rows `q`, columns `p`.
    hqp: Matrix4<f64>,
    hpp: Matrix4<f64>,
}

#[inline(always)]
fn point_terms(
    q: &Vector4<f64>,
    p: &Vector4<f64>,
    el: &Element,
    tau: f64,
    hessian: bool,
) -> PointTerms {
    let inv = 1.0 / q.norm_squared();
    let bq = conj_product(q);
    let omega = 2.0 * inv * (bq * p);
    let delta = omega - el.rest;
    let mut mu = el.stiffness.component_mul(&delta);
    let mut k = Matrix3::from_diagonal(&el.stiffness);
    let mut value = 0.5 * delta.dot(&mu);
    mu += el.shift;
    if el.density {
        // The curvature densities add to the elastic one: their gradient to
        // the moment, their Hessian to the stiffness.
        let s = el.start + tau * el.h;
        let (v, moment, stiffness) = el
            .loading
            .density(el.index, s, &omega, el.scale)
            .unwrap_or_default();
        value += v;
        mu += moment;
        k += stiffness;
    }
    let g = mu.dot(&omega);
    let p_mu = times_pure(p, &mu);
    let q_mu = times_pure(q, &mu);
    let mut terms = PointTerms {
        value,
        grad_q: -2.0 * inv * (p_mu + g * q),
        grad_p: 2.0 * inv * q_mu,
        hqq: Matrix4::zeros(),
        hqp: Matrix4::zeros(),
        hpp: Matrix4::zeros(),
    };
    if !hessian {
        return terms;
    }
    let jq = -2.0 * inv * (conj_product(p) + omega * q.transpose());
    let jp = 2.0 * inv * bq;
    // Without a curvature density the stiffness is diagonal: scale rows.
    let (kjq, kjp) = if el.density {
        (k * jq, k * jp)
    } else {
        let rows = |m: &Matrix3x4<f64>| {
            let mut out = *m;
            for (r, kr) in el.stiffness.iter().enumerate() {
                out.row_mut(r).scale_mut(*kr);
            }
            out
        };
        (rows(&jq), rows(&jp))
    };
    let inv2 = inv * inv;
    // mu . omega as a function of (q, p) with mu fixed: 2 q^T M p / |q|^2,
    // M = -right_pure(mu), so M p = -p (0, mu) and M^T q = q (0, mu).
    let m = -right_pure(&mu);
    let mp = -p_mu;
    let curvature_qq = -4.0 * inv2 * (mp * q.transpose() + q * mp.transpose())
        + 8.0 * inv2 * g * q * q.transpose()
        - 2.0 * inv * g * Matrix4::identity();
    let curvature_qp = 2.0 * inv * m - 4.0 * inv2 * q * q_mu.transpose();
    terms.hqq = jq.transpose() * kjq + curvature_qq;
    terms.hqp = jq.transpose() * kjp + curvature_qp;
    terms.hpp = jp.transpose() * kjp;
    terms
}

/// Simpson's weights of the element's nodes `(a, m, b)` in units of `h`.
const SIMPSON: [f64; 3] = [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0];

/// The node terms of node `k` of an element (value, gradient, block): the
/// internal force's `-h w_k F_k . T(x_k)`, the body-vector potentials' `-h
/// w_k c . R(x_k) b` (`quat::body_vector_terms`, the second-order scheme's
/// node rule) and the dead moment's virtual work `h w_k m . R(x_k) dtheta`.
#[inline(always)]
fn node_terms(x: Quat, el: &Element, k: usize) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let (mut value, mut grad, mut block) =
        crate::quat::body_vector_terms(x, &load_weight(el, k), &Vector3::z());
    for body in &el.loading.body_loads {
        let c = (-el.h * SIMPSON[k] * el.scale) * body.world;
        let (v, g, b) = crate::quat::body_vector_terms(x, &c, &body.body[el.index - 1]);
        value += v;
        grad += g;
        block += b;
    }
    if el.moment != Vector3::zeros() {
        let (g, b) = super::dead_moment(x, &((el.h * SIMPSON[k]) * el.moment));
        grad += g;
        block += b;
    }
    (value, grad, block)
}

/// `-h w_k F_k`: the weight `c` of node `k`'s load potential `c . T(x_k)`.
#[inline(always)]
fn load_weight(el: &Element, k: usize) -> Vector3<f64> {
    (-el.h * SIMPSON[k]) * el.force[k]
}

/// The rest curvature the fourth-order element is given at its Gauss points
/// for a rest curvature `kappa0` [1/m] over an element of length `h`: the
/// curvature that the exact arc of `kappa0` has there in the quadratic
/// interpolation, so that the arc is an exact zero of the element's energy
/// (the rest shape is then the exact arcs, not an O(h^4) approximation).
/// `beta = h |kappa0| / 4`; it is `kappa0 (1 + beta^4 / 45 + ...)`.
pub(crate) fn gauss_rest_curvature(kappa0: Vector3<f64>, h: f64) -> Vector3<f64> {
    let size = kappa0.norm();
    let beta = 0.25 * h * size;
    if beta < 1e-4 {
        // The series, to round-off (the closed form cancels here).
        return kappa0 * (1.0 + beta.powi(4) / 45.0);
    }
    let numerator = (8.0 / 3.0) * beta.sin() - (1.0 / 3.0) * (2.0 * beta).sin();
    let denominator = 2.0 / 3.0 + (4.0 / 9.0) * beta.cos() - (1.0 / 9.0) * (2.0 * beta).cos();
    (2.0 / (h * size)) * (numerator / denominator) * kappa0
}

/// The derivative of [`gauss_rest_curvature`] along `dkappa0`: `phi(beta)
/// kappa0` with `phi = N / (2 beta D)` (its closed form's numerator and
/// denominator), so `d = phi dkappa0 + phi'(beta) (h/4) (kappa0 . dkappa0 /
/// |kappa0|) kappa0`.
pub(crate) fn gauss_rest_derivative(
    kappa0: Vector3<f64>,
    h: f64,
    dkappa0: Vector3<f64>,
) -> Vector3<f64> {
    let size = kappa0.norm();
    let beta = 0.25 * h * size;
    if size == 0.0 {
        return dkappa0;
    }
    let (phi, dphi) = if beta < 1e-4 {
        (1.0 + beta.powi(4) / 45.0, 4.0 * beta.powi(3) / 45.0)
    } else {
        let (s1, c1) = beta.sin_cos();
        let (s2, c2) = (2.0 * beta).sin_cos();
        let n = (8.0 / 3.0) * s1 - (1.0 / 3.0) * s2;
        let dn = (8.0 / 3.0) * c1 - (2.0 / 3.0) * c2;
        let d = 2.0 / 3.0 + (4.0 / 9.0) * c1 - (1.0 / 9.0) * c2;
        let dd = -(4.0 / 9.0) * s1 + (2.0 / 9.0) * s2;
        let phi = n / (2.0 * beta * d);
        (
            phi,
            dn / (2.0 * beta * d) - n * (d + beta * dd) / (2.0 * beta * beta * d * d),
        )
    };
    let dbeta = 0.25 * h * kappa0.dot(&dkappa0) / size;
    phi * dkappa0 + dphi * dbeta * kappa0
}

/// The element's nodes on one side of the quaternion sphere: the quadratic
/// interpolant of `a`, `-m` and `b` would pass near zero.
fn aligned(nodes: [Quat; 3]) -> [Vector4<f64>; 3] {
    let a = v4(nodes[0]);
    let mut m = v4(nodes[1]);
    if a.dot(&m) < 0.0 {
        m = -m;
    }
    let mut b = v4(nodes[2]);
    if m.dot(&b) < 0.0 {
        b = -b;
    }
    [a, m, b]
}

/// The interpolated quaternion and its arc-length derivative at Gauss point `g`.
#[inline(always)]
fn interpolate(
    x: &[Vector4<f64>; 3],
    h: f64,
    g: usize,
) -> (Vector4<f64>, Vector4<f64>, [f64; 3], [f64; 3]) {
    let (n, dn) = basis(GAUSS[g]);
    let q = n[0] * x[0] + n[1] * x[1] + n[2] * x[2];
    let p = (dn[0] * x[0] + dn[1] * x[1] + dn[2] * x[2]) / h;
    (q, p, n, dn)
}

/// The element's potential [J]: the elastic energy by Gauss, the loads'
/// potential by Simpson at the nodes.
pub(crate) fn energy(nodes: [Quat; 3], el: &Element) -> f64 {
    let x = aligned(nodes);
    let elastic: f64 = (0..2)
        .map(|g| {
            let (q, p, _, _) = interpolate(&x, el.h, g);
            0.5 * el.h * point_terms(&q, &p, el, GAUSS[g], false).value
        })
        .sum();
    let loads: f64 = (0..3).map(|k| node_terms(nodes[k], el, k).0).sum();
    elastic + loads
}

/// The element's chord `r_b - r_a = h/6 (T(a) + 4 T(m) + T(b))` [m] (Simpson).
pub(crate) fn chord(nodes: [Quat; 3], h: f64) -> Vector3<f64> {
    (0..3).map(|k| (h * SIMPSON[k]) * nodes[k].tangent()).sum()
}

/// Gradient of the element in its nodes' rotations; with `jacobian`, the
/// exact derivative of that gradient under the same updates (its diagonal
/// blocks carry the update's second-order terms, as in `model.rs`). With
/// `mid_only`, only the internal node's gradient and block.
pub(crate) fn derivatives(
    nodes: [Quat; 3],
    el: &Element,
    jacobian: bool,
    mid_only: bool,
) -> Derivatives {
    let x = aligned(nodes);
    let h = el.h;
    let weight = 0.5 * h;
    let mut euclid = [Vector4::zeros(); 3];
    let mut hess = [[Matrix4::zeros(); 3]; 3];
    // The blocks integrated: the ends' alone for the whole Jacobian (the
    // internal node's follow from the energy's invariance, see
    // `internal_blocks`), the internal node's alone with `mid_only`.
    let blocks: &[(usize, usize)] = if mid_only {
        &[(1, 1)]
    } else {
        &[(0, 0), (0, 2), (2, 2)]
    };
    for (g, tau) in GAUSS.iter().enumerate() {
        let (q, p, n, dn) = interpolate(&x, h, g);
        let t = point_terms(&q, &p, el, *tau, jacobian);
        let d = [dn[0] / h, dn[1] / h, dn[2] / h];
        for k in 0..3 {
            euclid[k] += weight * (n[k] * t.grad_q + d[k] * t.grad_p);
        }
        if jacobian {
            let hpq = t.hqp.transpose();
            for &(k, l) in blocks {
                hess[k][l] += weight
                    * (n[k] * n[l] * t.hqq
                        + n[k] * d[l] * t.hqp
                        + d[k] * n[l] * hpq
                        + d[k] * d[l] * t.hpp);
            }
        }
    }
    // d x_k / d theta_k = E_k = B(x_k)^T / 2 (columns x_k (0, e_c) / 2).
    let e = [
        update_basis(&x[0]),
        update_basis(&x[1]),
        update_basis(&x[2]),
    ];
    let mut out = Derivatives {
        grad: [Vector3::zeros(); 3],
        jac: [[Matrix3::zeros(); 3]; 3],
    };
    for k in 0..3 {
        out.grad[k] = e[k].transpose() * euclid[k];
    }
    if jacobian {
        for &(k, l) in blocks {
            out.jac[k][l] = e[k].transpose() * hess[k][l] * e[l];
            out.jac[l][k] = out.jac[k][l].transpose();
            if k == l {
                let radial = -0.25 * x[k].dot(&euclid[k]);
                out.jac[k][k] += radial * Matrix3::identity() + 0.5 * skew(&out.grad[k]);
            }
        }
        if !mid_only {
            internal_blocks(&x, &mut out);
        }
    }
    // The loads, node by node (their exact rule, added after the elastic
    // part's conversion above).
    for (k, node) in nodes.iter().enumerate() {
        if mid_only && k != 1 {
            continue;
        }
        let (_, grad, jac) = node_terms(*node, el, k);
        out.grad[k] += grad;
        if jacobian {
            out.jac[k][k] += jac;
        }
    }
    out
}

/// The elastic Jacobian's blocks of the internal node from the ends'. The
/// energy is the same for every node turned by one rotation `g` (the
/// curvature `2 vec(conj(q) p) / |q|^2` is), and `g x_k = x_k exp(R_k^T phi
/// / 2)`: so `sum_k R_k g_k = 0` in every state, and its derivative along node
/// `l`'s update gives `sum_k R_k J_kl = R_l [g_l]x`. With `P_k = R_m^T R_k`
/// (the rotations of the nodes normalised: a node given off the unit sphere,
/// as `residual` and `jacobian` take it from Python, turns as its direction):
///
/// ```text
/// J_ma = P_a ([g_a]x - J_aa) - P_b J_ba
/// J_mb = P_b ([g_b]x - J_bb) - P_a J_ab
/// J_mm = [g_m]x - P_a J_am - P_b J_bm        (J_am = J_ma^T, J_bm = J_mb^T)
/// ```
///
/// three 3 x 3 blocks instead of three integrated 4 x 4 ones. (The loads,
/// which turn with no rotation, are added after.)
fn internal_blocks(x: &[Vector4<f64>; 3], out: &mut Derivatives) {
    let quat = |v: &Vector4<f64>| Quat::new(v[0], v[1], v[2], v[3]);
    let mid = quat(&x[1]).conj();
    let relative = |k: usize| (mid * quat(&x[k])).normalized().rotation();
    let (pa, pb) = (relative(0), relative(2));
    let j = &mut out.jac;
    let g = &out.grad;
    j[1][0] = pa * (skew(&g[0]) - j[0][0]) - pb * j[2][0];
    j[1][2] = pb * (skew(&g[2]) - j[2][2]) - pa * j[0][2];
    j[0][1] = j[1][0].transpose();
    j[2][1] = j[1][2].transpose();
    j[1][1] = skew(&g[1]) - pa * j[0][1] - pb * j[2][1];
}

/// The internal node's gradient alone (the chord iteration's evaluation).
fn mid_gradient(nodes: [Quat; 3], el: &Element) -> Vector3<f64> {
    let x = aligned(nodes);
    let h = el.h;
    let mut euclid = Vector4::zeros();
    for (g, tau) in GAUSS.iter().enumerate() {
        let (q, p, n, dn) = interpolate(&x, h, g);
        let t = point_terms(&q, &p, el, *tau, false);
        euclid += (0.5 * h) * (n[1] * t.grad_q + (dn[1] / h) * t.grad_p);
    }
    0.5 * conj_product(&x[1]) * euclid + node_terms(nodes[1], el, 1).1
}

/// `q (1, theta / 2)`, normalised: the update of an internal node. It agrees
/// with `q exp(theta / 2)` to second order, which is all the iteration needs
/// (its fixed point, the optimum, does not depend on the update), and costs
/// no trigonometry.
#[inline]
fn nudged(q: Quat, theta: Vector3<f64>) -> Quat {
    (q * Quat {
        w: 1.0,
        v: 0.5 * theta,
    })
    .normalized()
}

/// The internal node that minimises the element's potential for its ends
/// (Newton from `start`; the slerp midpoint of the ends if `None`).
/// With `chord`, the inverse of the node's block from a nearby evaluation:
/// the iteration then only evaluates gradients (a chord iteration) while its
/// steps keep shrinking fast, and goes on with Newton if they do not.
pub(crate) fn solve_mid(
    a: Quat,
    b: Quat,
    el: &Element,
    start: Option<Quat>,
    mut chord: Option<Matrix3<f64>>,
) -> Quat {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    let mut m = start.unwrap_or_else(|| {
        Quat {
            w: a.w + b.w,
            v: a.v + b.v,
        }
        .normalized()
    });
    let mut last = f64::INFINITY;
    for _ in 0..MID_ITERATIONS {
        let (grad, inverse) = match chord {
            Some(inverse) => (mid_gradient([a, m, b], el), inverse),
            None => {
                let d = derivatives([a, m, b], el, true, true);
                let Some(inverse) = d.jac[1][1].try_inverse() else {
                    break;
                };
                (d.grad[1], inverse)
            }
        };
        let step = -(inverse * grad);
        let size = step.norm();
        m = nudged(m, step);
        if size < MID_STEP_TOL {
            break;
        }
        if size > CHORD_CONTRACTION * last {
            chord = None;
        }
        last = size;
    }
    m
}

/// The condensed terms of one element on its end nodes: gradient and
/// Jacobian blocks of the reduced potential (the internal node at its optimum).
pub(crate) struct Condensed {
    /// The internal node at its optimum and its linear response to the ends.
    pub mid: MidState,
    pub ga: Vector3<f64>,
    pub gb: Vector3<f64>,
    pub jaa: Matrix3<f64>,
    pub jab: Matrix3<f64>,
    pub jba: Matrix3<f64>,
    pub jbb: Matrix3<f64>,
}

#[inline(always)]
pub(crate) fn condensed(
    a: Quat,
    b: Quat,
    el: &Element,
    last: Option<&MidState>,
    jacobian: bool,
) -> Condensed {
    let m = solve_mid(
        a,
        b,
        el,
        last.map(|s| s.predict(a, b)),
        last.map(|s| s.inverse),
    );
    let d = derivatives([a, m, b], el, jacobian, false);
    let mut out = Condensed {
        mid: MidState {
            a,
            b,
            m,
            ma: Matrix3::zeros(),
            mb: Matrix3::zeros(),
            inverse: Matrix3::zeros(),
            minimum: false,
        },
        ga: d.grad[0],
        gb: d.grad[2],
        jaa: Matrix3::zeros(),
        jab: Matrix3::zeros(),
        jba: Matrix3::zeros(),
        jbb: Matrix3::zeros(),
    };
    if !jacobian {
        return out;
    }
    let j = &d.jac;
    let inverse = j[1][1].try_inverse().unwrap_or_else(Matrix3::zeros);
    // Eliminating the internal node's step, -J_mm^-1 (g_m + J_ma x_a + J_mb x_b).
    let ma = inverse * j[1][0];
    let mb = inverse * j[1][2];
    let gm = inverse * d.grad[1];
    (out.mid.ma, out.mid.mb, out.mid.inverse) = (ma, mb, inverse);
    out.mid.minimum = (0.5 * (j[1][1] + j[1][1].transpose())).cholesky().is_some();
    out.ga -= j[0][1] * gm;
    out.gb -= j[2][1] * gm;
    out.jaa = j[0][0] - j[0][1] * ma;
    out.jab = j[0][2] - j[0][1] * mb;
    out.jba = j[2][0] - j[2][1] * ma;
    out.jbb = j[2][2] - j[2][1] * mb;
    out
}

/// Add the condensed element terms of a rod to `g` and `jac` (node `j` at
/// index `j - 1`; both cleared first). `element(i)` gives element `i = 1..=n`;
/// `mids` holds each element's state of the last evaluation (the start of
/// its internal node's Newton iteration) and receives the new ones.
pub(crate) fn assemble<'a>(
    q: &[Quat],
    element: impl Fn(usize) -> Element<'a>,
    mids: &mut [Option<MidState>],
    g: &mut [Vector3<f64>],
    mut jac: Option<&mut BlockTridiagonal>,
) {
    let n = g.len();
    g.iter_mut().for_each(|x| *x = Vector3::zeros());
    if let Some(j) = jac.as_deref_mut() {
        j.diag.iter_mut().for_each(|x| *x = Matrix3::zeros());
    }
    for i in 1..=n {
        // A huge n takes long here: an interrupt leaves the residual
        // unfinished, and the solver's loops stop on the same flag.
        if i % crate::interrupt::POLL_STRIDE == 0 && crate::interrupt::requested() {
            return;
        }
        let c = condensed(
            q[i - 1],
            q[i],
            &element(i),
            mids[i - 1].as_ref(),
            jac.is_some(),
        );
        if jac.is_some() {
            mids[i - 1] = Some(c.mid);
        } else if let Some(s) = mids[i - 1].as_mut() {
            // Without the Jacobian the response is not new: keep the last one.
            (s.a, s.b, s.m) = (c.mid.a, c.mid.b, c.mid.m);
        }
        g[i - 1] += c.gb;
        if i >= 2 {
            g[i - 2] += c.ga;
        }
        if let Some(j) = jac.as_deref_mut() {
            j.diag[i - 1] += c.jbb;
            if i >= 2 {
                j.diag[i - 2] += c.jaa;
                j.upper[i - 2] = c.jab;
                j.lower[i - 2] = c.jba;
            }
        }
    }
}

/// What an element's last evaluation leaves for the next: its ends, its
/// internal node and that node's linear response to the ends, `dm = -(M_a da
/// + M_b db)` (`M = J_mm^-1 J_m.`, the back-substitution of the condensation).
#[derive(Debug, Clone, Copy)]
pub(crate) struct MidState {
    a: Quat,
    b: Quat,
    m: Quat,
    ma: Matrix3<f64>,
    mb: Matrix3<f64>,
    /// `J_mm^-1`, for a chord iteration of the next evaluation.
    inverse: Matrix3<f64>,
    /// Whether `J_mm` is positive definite: the internal node sits at a
    /// minimum of its element's potential. The reduced Hessian's definiteness
    /// says the equilibrium is stable only where every one is.
    pub minimum: bool,
}

impl MidState {
    /// Whether this state was evaluated at exactly these ends.
    pub(crate) fn at(&self, a: Quat, b: Quat) -> bool {
        self.a == a && self.b == b
    }

    /// The internal node.
    pub(crate) fn node(&self) -> Quat {
        self.m
    }

    /// `(J_mm^-1 J_ma, J_mm^-1 J_mb, J_mm^-1)` of the last evaluation with the Jacobian.
    pub(crate) fn response(&self) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
        (self.ma, self.mb, self.inverse)
    }

    /// The internal node predicted for the ends `a`, `b`: a start of its
    /// Newton iteration within about the square of the ends' move.
    pub(crate) fn predict(&self, a: Quat, b: Quat) -> Quat {
        let da = rotation_from(self.a, a);
        let db = rotation_from(self.b, b);
        nudged(self.m, -(self.ma * da + self.mb * db))
    }
}

/// The body-frame rotation vector from `from` to `to` (to first order: a
/// predictor's input), on the short arc.
fn rotation_from(from: Quat, to: Quat) -> Vector3<f64> {
    let rel = from.conj() * to;
    if rel.w < 0.0 {
        -2.0 * rel.v
    } else {
        2.0 * rel.v
    }
}

/// The internal node of element `i` (from 1) for the ends `a`, `b`: the last
/// evaluation's if it was at these ends (it then includes the reactions of
/// held points), else the optimum for `el`, from the cache's prediction.
pub(crate) fn mid_for(
    cache: &mut [Option<MidState>],
    i: usize,
    a: Quat,
    b: Quat,
    el: &Element,
) -> Quat {
    match cache[i - 1] {
        Some(s) if s.at(a, b) => s.m,
        _ => cached_mid(cache, i, a, b, el),
    }
}

/// `d chord / d theta` of the element's nodes `(a, m, b)` (3x3 each):
/// `T(x exp(theta/2)) = R(x) (e_z + theta x e_z + ...)`, so node `k`'s block
/// is `h w_k R(x_k) [e_z]x^T` with Simpson's weights `w`.
pub(crate) fn chord_jacobian(nodes: [Quat; 3], h: f64) -> [Matrix3<f64>; 3] {
    let turn = -skew(&Vector3::z());
    let mut out = [Matrix3::zeros(); 3];
    for k in 0..3 {
        out[k] = (h * SIMPSON[k]) * nodes[k].rotation() * turn;
    }
    out
}

/// The optimal internal node of element `i` (from 1) for the ends `a`, `b`,
/// from the cache's prediction; the cache keeps the node.
pub(crate) fn cached_mid(
    cache: &mut [Option<MidState>],
    i: usize,
    a: Quat,
    b: Quat,
    el: &Element,
) -> Quat {
    let slot = &mut cache[i - 1];
    let m = solve_mid(
        a,
        b,
        el,
        slot.map(|s| s.predict(a, b)),
        slot.map(|s| s.inverse),
    );
    if let Some(s) = slot.as_mut() {
        (s.a, s.b, s.m) = (a, b, m);
    }
    m
}

/// The node quaternions of a chain whose every element is at rest
/// (`omega = omega0` at both Gauss points, so its potential is zero) from
/// `base`, each element by Newton on its internal node and end.
///
/// An unloaded element's potential depends only on its nodes' relative
/// rotations, so an element at rest turns by the same `conj(a) b` wherever it
/// is: solved once for each run of equal elements (a section).
pub(crate) fn rest_chain<'a>(base: Quat, elements: impl Iterator<Item = Element<'a>>) -> Vec<Quat> {
    let mut out = vec![base];
    // A run of equal elements: the same rest curvature and length.
    let mut last: Option<(Vector3<f64>, f64, Quat)> = None;
    for el in elements {
        let a = *out.last().expect("starts with the base");
        if let Some((_, _, turn)) = last.filter(|(rest, h, _)| *rest == el.rest && *h == el.h) {
            out.push((a * turn).normalized());
            continue;
        }
        let b = rest_element(a, &el);
        last = Some((el.rest, el.h, a.conj() * b));
        out.push(b);
    }
    out
}

/// The end `b` of an unloaded element at rest from `a` (Newton on its
/// internal node and end).
fn rest_element(a: Quat, el: &Element) -> Quat {
    // The arc of constant curvature: exact to the scheme's order.
    let mut m = a.perturbed(0.5 * el.h * el.rest);
    let mut b = a.perturbed(el.h * el.rest);
    for _ in 0..MID_ITERATIONS {
        let d = derivatives([a, m, b], el, true, false);
        let mut jac = SMatrix::<f64, 6, 6>::zeros();
        let mut rhs = SMatrix::<f64, 6, 1>::zeros();
        for (r, k) in [1usize, 2].iter().enumerate() {
            rhs.fixed_rows_mut::<3>(3 * r).copy_from(&(-d.grad[*k]));
            for (c, l) in [1usize, 2].iter().enumerate() {
                jac.fixed_view_mut::<3, 3>(3 * r, 3 * c)
                    .copy_from(&d.jac[*k][*l]);
            }
        }
        let Some(step) = jac.lu().solve(&rhs) else {
            break;
        };
        m = m.perturbed(step.fixed_rows::<3>(0).into_owned());
        b = b.perturbed(step.fixed_rows::<3>(3).into_owned());
        if step.norm() < REST_STEP_TOL {
            break;
        }
    }
    b
}

/// The fourth-order scheme: the rest curvature it gives each element at its
/// Gauss points ([`gauss_rest_curvature`]).
#[derive(Debug, Clone, Default)]
pub struct Fe4 {
    gauss_rest: Vec<Vector3<f64>>,
}

impl Fe4 {
    /// Element `i`'s data at load scale `load`; the forces `held` act on it
    /// as point forces beyond it.
    #[inline(always)]
    fn element<'a>(&self, rod: &'a Rod, i: usize, load: f64, held: NodeForces) -> Element<'a> {
        let loading = &rod.loading;
        let mut mean = load * loading.mean_force_of(i);
        if !held.is_empty() {
            mean += held.from_node(i);
        }
        // The internal force changes by the distributed force along the element.
        let half = (0.5 * load) * loading.force_drop_of(i);
        Element {
            h: rod.h(i),
            stiffness: loading.stiffness_of(i),
            rest: self.gauss_rest[i - 1],
            shift: Vector3::zeros(),
            force: [mean + half, mean, mean - half],
            moment: load * loading.distributed_moment_of(i),
            loading,
            index: i,
            scale: load,
            density: loading.has_density(i),
            start: rod.arc(i - 1),
        }
    }

    /// Element `i` along the tangent `tangent` of the rod's loading: the
    /// entries' derivatives, the elastic law's `dK (omega - omega0) - K domega0`.
    fn tangent_element<'a>(&self, rod: &Rod, tangent: &'a Loading, i: usize) -> Element<'a> {
        let h = rod.h(i);
        let half = 0.5 * tangent.force_drop_of(i);
        let mean = tangent.mean_force_of(i);
        let domega0 = gauss_rest_derivative(rod.loading.rest_of(i), h, tangent.rest_of(i));
        Element {
            h,
            stiffness: tangent.stiffness_of(i),
            rest: self.gauss_rest[i - 1],
            shift: -rod.loading.stiffness_of(i).component_mul(&domega0),
            force: [mean + half, mean, mean - half],
            moment: tangent.distributed_moment_of(i),
            loading: tangent,
            index: i,
            scale: 1.0,
            density: tangent.has_density(i),
            start: rod.arc(i - 1),
        }
    }

    /// The interior sized for the rod (a caller's fresh cache).
    fn sized(interior: &mut Interior, n: usize) {
        if interior.mids.len() != n {
            *interior = Interior::new(n);
        }
    }
}

impl Discretisation for Fe4 {
    fn scheme(&self) -> Scheme {
        Scheme::Fe4
    }

    fn boxed(&self) -> Box<dyn Discretisation> {
        Box::new(self.clone())
    }

    fn prepare(&mut self, rod: &Rod) {
        self.gauss_rest = (1..=rod.n())
            .map(|i| gauss_rest_curvature(rod.loading.rest_of(i), rod.h(i)))
            .collect();
    }

    fn interior(&self, n: usize) -> Interior {
        Interior::new(n)
    }

    fn evaluate(
        &self,
        rod: &Rod,
        q: &[Quat],
        load: f64,
        held: NodeForces,
        interior: &mut Interior,
        g: &mut [Vector3<f64>],
        mut jac: Option<&mut BlockTridiagonal>,
    ) {
        Fe4::sized(interior, rod.n());
        assemble(
            q,
            |i| self.element(rod, i, load, held),
            &mut interior.mids,
            g,
            jac.as_deref_mut(),
        );
        rod.loading.add_node_terms(q, load, g, jac);
    }

    fn residual_derivative(
        &self,
        rod: &Rod,
        q: &[Quat],
        held: NodeForces,
        tangent: &Loading,
        interior: &mut Interior,
        dg: &mut [Vector3<f64>],
        interior_shift: &mut Vec<Vector3<f64>>,
    ) {
        let n = rod.n();
        Fe4::sized(interior, n);
        dg.iter_mut().for_each(|x| *x = Vector3::zeros());
        interior_shift.clear();
        interior_shift.resize(n, Vector3::zeros());
        for i in 1..=n {
            let el = self.element(rod, i, 1.0, held);
            let m = mid_for(&mut interior.mids, i, q[i - 1], q[i], &el);
            let nodes = [q[i - 1], m, q[i]];
            // The element's Jacobian at its interior, and the tangent's
            // gradient at fixed nodes: the interior follows the change.
            let j = derivatives(nodes, &el, true, false).jac;
            let d = derivatives(nodes, &self.tangent_element(rod, tangent, i), false, false);
            let inverse = j[1][1].try_inverse().unwrap_or_else(Matrix3::zeros);
            let shift = -(inverse * d.grad[1]);
            interior_shift[i - 1] = shift;
            if i >= 2 {
                dg[i - 2] += d.grad[0] + j[0][1] * shift;
            }
            dg[i - 1] += d.grad[2] + j[2][1] * shift;
        }
        tangent.add_node_terms(q, 1.0, dg, None);
    }

    fn position_derivative(
        &self,
        rod: &Rod,
        q: &[Quat],
        interior: &mut Interior,
        interior_shift: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) {
        out[0] = Vector3::zeros();
        for i in 1..=rod.n() {
            let el = self.element(rod, i, 1.0, NodeForces::NONE);
            let m = mid_for(&mut interior.mids, i, q[i - 1], q[i], &el);
            let shift = interior_shift
                .get(i - 1)
                .copied()
                .unwrap_or_else(Vector3::zeros);
            out[i] = out[i - 1] + chord_jacobian([q[i - 1], m, q[i]], el.h)[1] * shift;
        }
    }

    fn positions(&self, rod: &Rod, q: &[Quat], interior: &mut Interior, out: &mut [Vector3<f64>]) {
        Fe4::sized(interior, rod.n());
        out[0] = rod.base_position;
        for i in 1..=rod.n() {
            let el = self.element(rod, i, 1.0, NodeForces::NONE);
            let m = mid_for(&mut interior.mids, i, q[i - 1], q[i], &el);
            out[i] = out[i - 1] + chord([q[i - 1], m, q[i]], el.h);
        }
    }

    fn unloaded_positions(&self, rod: &Rod, q: &[Quat], out: &mut [Vector3<f64>]) {
        out[0] = rod.base_position;
        for i in 1..=rod.n() {
            let el = self.element(rod, i, 0.0, NodeForces::NONE);
            let m = solve_mid(q[i - 1], q[i], &el, None, None);
            out[i] = out[i - 1] + chord([q[i - 1], m, q[i]], el.h);
        }
    }

    fn internal_nodes(&self, rod: &Rod, q: &[Quat], interior: &mut Interior) -> Vec<Quat> {
        Fe4::sized(interior, rod.n());
        (1..=rod.n())
            .map(|i| {
                let el = self.element(rod, i, 1.0, NodeForces::NONE);
                mid_for(&mut interior.mids, i, q[i - 1], q[i], &el)
            })
            .collect()
    }

    fn interior_at_minima(&self, interior: &Interior) -> bool {
        interior.mids.iter().all(|s| s.is_some_and(|s| s.minimum))
    }

    fn energy(&self, rod: &Rod, q: &[Quat], load: f64, interior: &mut Interior) -> f64 {
        Fe4::sized(interior, rod.n());
        let elements: f64 = (1..=rod.n())
            .map(|i| {
                let el = self.element(rod, i, load, NodeForces::NONE);
                let m = mid_for(&mut interior.mids, i, q[i - 1], q[i], &el);
                energy([q[i - 1], m, q[i]], &el)
            })
            .sum();
        rod.loading.node_energy(q, load) + elements
    }

    fn rest_shape(&self, rod: &Rod) -> Vec<Quat> {
        rest_chain(
            rod.base,
            (1..=rod.n()).map(|i| self.element(rod, i, 0.0, NodeForces::NONE)),
        )
    }

    fn position_jacobian(
        &self,
        rod: &Rod,
        q: &[Quat],
        k: usize,
        interior: &Interior,
        out: &mut [Matrix3<f64>],
    ) {
        out.iter_mut().for_each(|b| *b = Matrix3::zeros());
        for e in 1..=k {
            let Some(state) = interior.mids.get(e - 1).copied().flatten() else {
                continue;
            };
            let c = chord_jacobian([q[e - 1], state.node(), q[e]], rod.h(e));
            let (ma, mb, _) = state.response();
            if e >= 2 {
                out[e - 2] += c[0] - c[1] * ma;
            }
            out[e - 1] += c[2] - c[1] * mb;
        }
    }

    fn held_point_compliance(
        &self,
        rod: &Rod,
        q: &[Quat],
        nodes: &[usize],
        interior: &Interior,
    ) -> Option<DMatrix<f64>> {
        let m = nodes.len();
        let last = nodes.iter().copied().max().unwrap_or(0);
        // Running sum over the elements, read off at each held node:
        // `sum over the elements before both of C_m J_mm^-1 C_m^T`.
        let mut running = Matrix3::zeros();
        let mut at_node = vec![Matrix3::zeros(); last + 1];
        for e in 1..=last {
            if let Some(state) = interior.mids.get(e - 1).copied().flatten() {
                let c = chord_jacobian([q[e - 1], state.node(), q[e]], rod.h(e));
                let (_, _, inverse) = state.response();
                running += c[1] * inverse * c[1].transpose();
            }
            at_node[e] = running;
        }
        let mut out = DMatrix::zeros(3 * m, 3 * m);
        for (i, a) in nodes.iter().enumerate() {
            for (j, b) in nodes.iter().enumerate() {
                let block = at_node[(*a).min(*b)];
                out.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&block);
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A loaded element with a magnetisation in a field (index 1 of its loading).
    fn element() -> Element<'static> {
        let loading: &'static Loading = Box::leak(Box::new(Loading {
            body_loads: vec![super::super::BodyLoad {
                world: Vector3::new(0.3, -0.2, 0.5),
                body: vec![Vector3::new(0.4, 0.1, -0.7)],
            }],
            ..Loading::empty()
        }));
        Element {
            h: 0.13,
            stiffness: Vector3::new(0.9, 1.3, 0.7),
            rest: Vector3::new(1.2, -0.8, 0.0),
            shift: Vector3::zeros(),
            force: [
                Vector3::new(0.4, -1.1, 2.0),
                Vector3::new(0.35, -1.05, 1.85),
                Vector3::new(0.3, -1.0, 1.7),
            ],
            moment: Vector3::zeros(),
            loading,
            index: 1,
            scale: 1.0,
            density: false,
            start: 0.0,
        }
    }

    /// The same without the magnetisation (an unloaded element at rest).
    fn bare_element() -> Element<'static> {
        let empty: &'static Loading = Box::leak(Box::new(Loading::empty()));
        Element {
            loading: empty,
            ..element()
        }
    }

    fn nodes() -> [Quat; 3] {
        let a = Quat::new(0.9, 0.2, -0.3, 0.1).normalized();
        let m = a.perturbed(Vector3::new(0.05, -0.08, 0.03));
        let b = m.perturbed(Vector3::new(0.07, -0.02, 0.06));
        [a, m, b]
    }

    #[test]
    fn gradient_matches_central_differences_of_the_energy() {
        let (el, x) = (element(), nodes());
        let d = derivatives(x, &el, false, false);
        assert!((mid_gradient(x, &el) - d.grad[1]).norm() < 1e-13);
        let h = 1e-6;
        for k in 0..3 {
            for c in 0..3 {
                let step = Vector3::ith(c, h);
                let (mut p, mut m) = (x, x);
                p[k] = x[k].perturbed(step);
                m[k] = x[k].perturbed(-step);
                let fd = (energy(p, &el) - energy(m, &el)) / (2.0 * h);
                assert!(
                    (fd - d.grad[k][c]).abs() < 1e-8,
                    "node {k} row {c}: {fd} vs {}",
                    d.grad[k][c]
                );
            }
        }
    }

    #[test]
    fn jacobian_matches_central_differences_of_the_gradient() {
        // A dead moment too: its block is not symmetric.
        let el = Element {
            moment: Vector3::new(0.7, -0.4, 1.1),
            ..element()
        };
        let x = nodes();
        let d = derivatives(x, &el, true, false);
        let h = 1e-6;
        for l in 0..3 {
            for c in 0..3 {
                let step = Vector3::ith(c, h);
                let (mut p, mut m) = (x, x);
                p[l] = x[l].perturbed(step);
                m[l] = x[l].perturbed(-step);
                let (gp, gm) = (
                    derivatives(p, &el, false, false),
                    derivatives(m, &el, false, false),
                );
                for k in 0..3 {
                    let fd = (gp.grad[k] - gm.grad[k]) / (2.0 * h);
                    let column = d.jac[k][l].column(c);
                    assert!(
                        (fd - column).norm() < 1e-6,
                        "block ({k}, {l}) column {c}: {fd} vs {column}"
                    );
                }
            }
        }
    }

    /// A curvature density `exp(w . omega) + s |omega|^2 / 2`: not quadratic,
    /// and not the same along the element.
    #[derive(Debug)]
    struct Curved;

    impl super::super::CurvatureDensity for Curved {
        fn acts_on(&self, _: usize) -> bool {
            true
        }

        fn density(
            &self,
            _: usize,
            s: f64,
            omega: &Vector3<f64>,
            scale: f64,
        ) -> Option<(f64, Vector3<f64>, Matrix3<f64>)> {
            let w = Vector3::new(0.3, -0.2, 0.1);
            let e = (w.dot(omega)).exp();
            Some((
                scale * (e + 0.5 * s * omega.norm_squared()),
                scale * (e * w + s * omega),
                scale * (e * w * w.transpose() + s * Matrix3::identity()),
            ))
        }
    }

    #[test]
    fn the_internal_nodes_block_from_the_invariance_is_the_integrated_one() {
        // `internal_blocks` derives the internal node's blocks from the
        // ends'; with `mid_only` its block is integrated directly. A shifted
        // moment, a curvature density, a dead moment and body loads (added
        // after), turned nodes, on and off the unit sphere: the two agree to
        // round-off (the other blocks agree with central differences,
        // `jacobian_matches_central_differences_of_the_gradient`).
        let loading: &'static Loading = Box::leak(Box::new(Loading {
            densities: vec![std::sync::Arc::new(Curved)],
            ..element().loading.clone()
        }));
        let el = Element {
            moment: Vector3::new(0.7, -0.4, 1.1),
            shift: Vector3::new(0.2, 0.1, -0.3),
            loading,
            density: true,
            start: 0.4,
            ..element()
        };
        let a = Quat::new(0.3, -0.6, 0.2, 0.7).normalized();
        let unit = [
            a,
            a.perturbed(Vector3::new(0.4, -0.3, 0.2)),
            a.perturbed(Vector3::new(0.7, -0.5, 0.5)),
        ];
        let scaled = |q: Quat, f: f64| Quat {
            w: f * q.w,
            v: f * q.v,
        };
        let off = [
            scaled(unit[0], 1.0 + 1e-3),
            unit[1],
            scaled(unit[2], 1.0 - 1e-3),
        ];
        for x in [unit, off] {
            let full = derivatives(x, &el, true, false).jac;
            let direct = derivatives(x, &el, true, true).jac[1][1];
            let scale = direct.amax();
            let miss = (full[1][1] - direct).amax() / scale;
            assert!(miss < 1e-13, "{miss:e}: {} vs {direct}", full[1][1]);
            assert!((full[0][1] - full[1][0].transpose()).amax() == 0.0);
        }
    }

    #[test]
    fn the_condensed_gradient_is_that_of_the_reduced_energy() {
        let el = element();
        let [a, _, b] = nodes();
        let reduced = |a: Quat, b: Quat| energy([a, solve_mid(a, b, &el, None, None), b], &el);
        let c = condensed(a, b, &el, None, true);
        let h = 1e-5;
        for col in 0..3 {
            let step = Vector3::ith(col, h);
            let fd_a = (reduced(a.perturbed(step), b) - reduced(a.perturbed(-step), b)) / (2.0 * h);
            let fd_b = (reduced(a, b.perturbed(step)) - reduced(a, b.perturbed(-step))) / (2.0 * h);
            assert!((fd_a - c.ga[col]).abs() < 1e-8);
            assert!((fd_b - c.gb[col]).abs() < 1e-8);
            // The Schur complement is the derivative of the reduced gradient.
            let ga = |a: Quat| condensed(a, b, &el, None, false).ga;
            let gb = |b: Quat| condensed(a, b, &el, None, false).gb;
            let dga = (ga(a.perturbed(step)) - ga(a.perturbed(-step))) / (2.0 * h);
            let dgb = (gb(b.perturbed(step)) - gb(b.perturbed(-step))) / (2.0 * h);
            assert!(
                (dga - c.jaa.column(col)).norm() < 1e-6,
                "{dga} {}",
                c.jaa.column(col)
            );
            assert!(
                (dgb - c.jbb.column(col)).norm() < 1e-6,
                "{dgb} {}",
                c.jbb.column(col)
            );
            let gab = |bb: Quat| condensed(a, bb, &el, None, false).ga;
            let dab = (gab(b.perturbed(step)) - gab(b.perturbed(-step))) / (2.0 * h);
            assert!(
                (dab - c.jab.column(col)).norm() < 1e-6,
                "{dab} {}",
                c.jab.column(col)
            );
            let gba = |aa: Quat| condensed(aa, b, &el, None, false).gb;
            let dba = (gba(a.perturbed(step)) - gba(a.perturbed(-step))) / (2.0 * h);
            assert!(
                (dba - c.jba.column(col)).norm() < 1e-6,
                "{dba} {}",
                c.jba.column(col)
            );
        }
    }

    #[test]
    fn a_rest_chain_is_the_exact_arc() {
        let mut el = bare_element();
        el.force = [Vector3::zeros(); 3];
        let kappa0 = Vector3::new(2.0, -1.0, 0.0);
        el.rest = gauss_rest_curvature(kappa0, el.h);
        let chain = rest_chain(Quat::IDENTITY, std::iter::repeat_n(el, 4));
        for w in chain.windows(2) {
            let m = solve_mid(w[0], w[1], &el, None, None);
            assert!(energy([w[0], m, w[1]], &el).abs() < 1e-24);
        }
        // The exact arc turns by h |kappa0| an element; uncorrected, the
        // chain would be off by about 1e-7 here.
        let exact = Quat::from_rotation_vector(4.0 * el.h * kappa0);
        let rel = exact.conj() * chain[4];
        assert!(rel.v.norm() < 1e-14, "{}", rel.v.norm());
    }

    #[test]
    fn gauss_rest_curvature_is_the_arc_at_the_gauss_points_and_smooth_at_zero() {
        let h = 0.3;
        for kappa0 in [Vector3::new(2.0, -1.0, 0.0), Vector3::new(1e-3, 0.0, 0.0)] {
            // The arc's nodes, and its curvature in the interpolation at a
            // Gauss point (by differences of the interpolated quaternion).
            let arc = |s: f64| Quat::from_rotation_vector(s * kappa0);
            let x = aligned([arc(0.0), arc(0.5 * h), arc(h)]);
            let omega = |tau: f64| {
                let (n, dn) = basis(tau);
                let q = n[0] * x[0] + n[1] * x[1] + n[2] * x[2];
                let p = (dn[0] * x[0] + dn[1] * x[1] + dn[2] * x[2]) / h;
                2.0 * (conj_product(&q) * p) / q.norm_squared()
            };
            let corrected = gauss_rest_curvature(kappa0, h);
            for tau in GAUSS {
                assert!((omega(tau) - corrected).norm() < 1e-13 * kappa0.norm().max(1.0));
            }
        }
        // Near the switch to the series the correction is below round-off:
        // the closed form just above it must give kappa0 to round-off too.
        for beta in [0.999e-4, 1.001e-4, 1e-3] {
            let k = Vector3::new(0.6, 0.8, 0.0) * (4.0 * beta);
            let ratio = gauss_rest_curvature(k, 1.0).norm() / k.norm();
            assert!(
                (ratio - 1.0 - beta.powi(4) / 45.0).abs() < 1e-14,
                "{beta}: {ratio}"
            );
        }
    }

    #[test]
    fn the_gauss_rest_derivative_matches_central_differences() {
        let h = 0.3;
        let curvatures: [Vector3<f64>; 3] = [
            Vector3::new(2.0, -1.0, 0.0),
            Vector3::new(1e-4, 2e-4, 0.0),
            Vector3::new(6.0, 3.0, 0.0),
        ];
        for kappa0 in curvatures {
            for d in [Vector3::x(), Vector3::y(), Vector3::new(0.3, -0.7, 0.0)] {
                let step = 1e-6 * kappa0.norm().max(1.0);
                let fd = (gauss_rest_curvature(kappa0 + step * d, h)
                    - gauss_rest_curvature(kappa0 - step * d, h))
                    / (2.0 * step);
                let exact = gauss_rest_derivative(kappa0, h, d);
                assert!((fd - exact).norm() < 1e-8, "{kappa0} {d}: {fd} vs {exact}");
            }
        }
        // At zero curvature the map is the identity to first order.
        let d = Vector3::new(0.4, -0.2, 0.0);
        assert_eq!(gauss_rest_derivative(Vector3::zeros(), h, d), d);
    }

    #[test]
    fn chord_jacobian_matches_central_differences() {
        let x = nodes();
        let h = 0.13;
        let jac = chord_jacobian(x, h);
        let step = 1e-6;
        for k in 0..3 {
            for c in 0..3 {
                let (mut p, mut m) = (x, x);
                p[k] = x[k].perturbed(Vector3::ith(c, step));
                m[k] = x[k].perturbed(Vector3::ith(c, -step));
                let fd = (chord(p, h) - chord(m, h)) / (2.0 * step);
                assert!((fd - jac[k].column(c)).norm() < 1e-9, "node {k} column {c}");
            }
        }
    }
}
