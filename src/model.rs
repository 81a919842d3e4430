//! The discrete equations of MODEL.md: residual (body-frame torque balance per
//! node), its analytic Jacobian (block-tridiagonal), positions and energy.
//!
//! Unknowns are the node quaternions `q_1..q_n` (`q_0` is the clamped base).
//! A node is moved by the body-frame update `q_j <- q_j * exp(theta_j / 2)`, which
//! keeps `|q_j| = 1` exactly; the residual of node `j` is `dPi/dtheta_j` (plus the
//! tip moment at node `n`) and the Jacobian is its derivative under the same
//! update, so it is exact and can be checked by finite differences.
//!
//! Every load and the rest curvature are scaled by `lambda`, the load
//! continuation parameter: `lambda = 0` is the straight, unloaded rod, whose
//! equilibrium is exact, and `lambda = 1` is the scene.

use crate::blocktri::BlockTridiagonal;
use crate::quat::{skew, tangent_bilinear, tangent_form_apply, Quat};
use crate::scene::Scene;
use nalgebra::{Matrix3, Vector3};

/// A scene discretised by `n` elements of length `ds`.
#[derive(Debug, Clone)]
pub struct RodModel {
    pub n: usize,
    pub length: f64,
    pub ds: f64,
    /// Diagonal stiffness `(kx, ky, kz)` [N m^2].
    pub stiffness: Vector3<f64>,
    pub base: Quat,
    /// Rest curvature of element `i` (index `i - 1`), material frame [1/m].
    pub rest_curvature: Vec<Vector3<f64>>,
    /// Mean internal force `Fbar_i` of element `i` (index `i - 1`), world frame [N].
    pub mean_force: Vec<Vector3<f64>>,
    /// `Fbar_j + Fbar_{j+1}` of node `j` (index `j - 1`), the weight of `T(q_j)`.
    node_force_weight: Vec<Vector3<f64>>,
    /// Internal force `F_j` at node `j = 0..n`, world frame [N].
    pub node_force: Vec<Vector3<f64>>,
    pub tip_moment: Vector3<f64>,
    /// Moment scale `max(k) / L` that makes residuals dimensionless.
    pub residual_scale: f64,
}

impl RodModel {
    /// Discretise `scene` with `n` elements (validated by the caller: `n` is a
    /// positive multiple of the number of sections).
    pub fn new(scene: &Scene, n: usize) -> Self {
        let length = scene.length;
        let ds = length / n as f64;
        let sections = scene.rest_curvature.len().max(1);
        let rest_curvature = (0..n)
            .map(|i| match scene.rest_curvature.get(i * sections / n) {
                Some(k) => Vector3::new(k[0], k[1], 0.0),
                None => Vector3::zeros(),
            })
            .collect();
        let f = scene.distributed_force();
        let node_force: Vec<Vector3<f64>> = (0..=n)
            .map(|j| scene.tip_force + f * (length - j as f64 * ds))
            .collect();
        let mean_force: Vec<Vector3<f64>> = (1..=n)
            .map(|i| 0.5 * (node_force[i - 1] + node_force[i]))
            .collect();
        let node_force_weight = (1..=n)
            .map(|j| mean_force[j - 1] + mean_force.get(j).copied().unwrap_or_else(Vector3::zeros))
            .collect();
        let stiffness = scene.stiffness();
        RodModel {
            n,
            length,
            ds,
            stiffness,
            base: scene.base_quaternion,
            rest_curvature,
            mean_force,
            node_force_weight,
            node_force,
            tip_moment: scene.tip_moment,
            residual_scale: stiffness.max() / length,
        }
    }

    /// True when nothing bends the rod: the straight rod is the exact equilibrium.
    pub fn is_trivial(&self) -> bool {
        self.rest_curvature.iter().all(|k| k.norm() == 0.0)
            && self.mean_force.iter().all(|f| f.norm() == 0.0)
            && self.tip_moment.norm() == 0.0
    }

    /// The straight rod along the base tangent.
    pub fn straight(&self) -> Vec<Quat> {
        vec![self.base; self.n + 1]
    }

    /// Residual `g` (node `j` at index `j - 1`) at load scale `lambda`.
    pub fn residual(&self, q: &[Quat], lambda: f64, g: &mut [Vector3<f64>]) {
        self.assemble(q, lambda, g, None);
    }

    /// Residual and its exact Jacobian at load scale `lambda`.
    pub fn residual_jacobian(
        &self,
        q: &[Quat],
        lambda: f64,
        g: &mut [Vector3<f64>],
        jac: &mut BlockTridiagonal,
    ) {
        self.assemble(q, lambda, g, Some(jac));
    }

    fn assemble(
        &self,
        q: &[Quat],
        lambda: f64,
        g: &mut [Vector3<f64>],
        mut jac: Option<&mut BlockTridiagonal>,
    ) {
        debug_assert_eq!(q.len(), self.n + 1);
        debug_assert_eq!(g.len(), self.n);
        let (ds, k) = (self.ds, self.stiffness);
        let kmat = Matrix3::from_diagonal(&k);
        g.iter_mut().for_each(|x| *x = Vector3::zeros());
        if let Some(j) = jac.as_deref_mut() {
            j.clear();
        }
        // Elements: elastic energy and the bilinear part of the load potential.
        for i in 1..=self.n {
            let (a, b) = (q[i - 1], q[i]);
            let c = a.conj() * b;
            let (c0, cv) = (c.w, c.v);
            let e = (2.0 / ds) * cv - lambda * self.rest_curvature[i - 1];
            let w = k.component_mul(&e); // bending/twisting moment, body frame
            let amat = Matrix3::identity() * c0 + skew(&cv);
            let ga = -(amat * w);
            let gb = amat.transpose() * w;
            // Load potential kappa * a^T S b with kappa = -ds/3 (F . T(a,b) term).
            let kappa = -ds / 3.0;
            let fbar = lambda * self.mean_force[i - 1];
            let sb = tangent_form_apply(&fbar, b);
            let sa = tangent_form_apply(&fbar, a);
            let gax = 0.5 * kappa * (a.conj() * sb).v;
            let gbx = 0.5 * kappa * (b.conj() * sa).v;
            if i >= 2 {
                g[i - 2] += ga + gax;
            }
            g[i - 1] += gb + gbx;

            if let Some(jac) = jac.as_deref_mut() {
                let cw = cv.dot(&w);
                let psi = kappa * a.dot(sb);
                let radial = (-0.5 * cw - 0.25 * psi) * Matrix3::identity();
                let jbb = amat.transpose() * kmat * amat / ds + radial + 0.5 * skew(&(gb + gbx));
                jac.diag[i - 1] += jbb;
                if i >= 2 {
                    let jaa =
                        amat * kmat * amat.transpose() / ds + radial + 0.5 * skew(&(ga + gax));
                    jac.diag[i - 2] += jaa;
                    let mut jab = -(amat * kmat * amat) / ds
                        - 0.5
                            * (Matrix3::identity() * cw
                                - c0 * skew(&w)
                                - cv * w.transpose()
                                - w * cv.transpose());
                    // 1/4 kappa G(a) S G(b)^T, column by column: G(b)^T e_k = b * (0, e_k).
                    for col in 0..3 {
                        let bek = b * Quat::pure(Vector3::ith(col, 1.0));
                        let v = (a.conj() * tangent_form_apply(&fbar, bek)).v;
                        jab.set_column(col, &(jab.column(col) + 0.25 * kappa * v));
                    }
                    jac.upper[i - 2] += jab;
                    jac.lower[i - 2] += jab.transpose();
                }
            }
        }
        // Nodes: the quadratic part of the load potential, h . T(q_j).
        for j in 1..=self.n {
            let h = (-ds / 3.0 * lambda) * self.node_force_weight[j - 1];
            let f = q[j].inverse_rotate(h);
            g[j - 1] += Vector3::new(-f.y, f.x, 0.0);
            if let Some(jac) = jac.as_deref_mut() {
                jac.diag[j - 1] += f * Vector3::z().transpose() - f.z * Matrix3::identity();
            }
        }
        // Tip moment (a dead load in the world frame, no potential in 3D).
        if self.tip_moment.norm() > 0.0 {
            let m = q[self.n].inverse_rotate(lambda * self.tip_moment);
            g[self.n - 1] -= m;
            if let Some(jac) = jac {
                jac.diag[self.n - 1] -= skew(&m);
            }
        }
    }

    /// `d g / d lambda`: the residual is affine in the load scale.
    pub fn residual_lambda_derivative(
        &self,
        q: &[Quat],
        out: &mut [Vector3<f64>],
        scratch: &mut [Vector3<f64>],
    ) {
        self.residual(q, 1.0, out);
        self.residual(q, 0.0, scratch);
        for (o, s) in out.iter_mut().zip(scratch.iter()) {
            *o -= s;
        }
    }

    /// Dimensionless residual norm: largest torque imbalance over `max(k) / L`.
    pub fn residual_norm(&self, g: &[Vector3<f64>]) -> f64 {
        g.iter().map(|x| x.amax()).fold(0.0, f64::max) / self.residual_scale
    }

    /// Node positions `r_0 = 0`, `r_i = r_{i-1} + ds T_i` with the exact mean tangent.
    pub fn positions(&self, q: &[Quat], out: &mut [Vector3<f64>]) {
        out[0] = Vector3::zeros();
        for i in 1..=self.n {
            out[i] = out[i - 1] + self.ds * mean_tangent(q[i - 1], q[i]);
        }
    }

    /// Total potential `Pi` (elastic energy minus the work of the dead forces) [J].
    /// A dead tip moment has no potential in 3D and is not included.
    pub fn energy(&self, q: &[Quat]) -> f64 {
        let mut total = 0.0;
        for i in 1..=self.n {
            let (a, b) = (q[i - 1], q[i]);
            let e = (2.0 / self.ds) * (a.conj() * b).v - self.rest_curvature[i - 1];
            let elastic = 0.5 * e.dot(&self.stiffness.component_mul(&e));
            total += self.ds * (elastic - self.mean_force[i - 1].dot(&mean_tangent(a, b)));
        }
        total
    }
}

/// Mean tangent of an element: the exact mean of `T` under linear interpolation of `q`.
pub fn mean_tangent(a: Quat, b: Quat) -> Vector3<f64> {
    (a.tangent() + tangent_bilinear(a, b) + b.tangent()) / 3.0
}
