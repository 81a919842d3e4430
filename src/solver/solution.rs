//! What a solve returns: the [`Solution`] and its [`Status`], and the one
//! judgement of every method's end state.

use super::contact::Contact;
use super::port::PortReaction;
use crate::disc::Scheme;
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::model::RodModel;
use crate::quat::{tangent_bilinear, Quat};
use crate::terms::section_of;
use nalgebra::{Matrix3, Vector3};

pub use crate::status::Status;

impl std::str::FromStr for Status {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Status::ALL
            .into_iter()
            .find(|status| status.name() == s)
            .ok_or_else(|| Error::argument("status", format!("unknown status '{s}'")))
    }
}

/// Largest turning of one element [rad] that the scheme resolves. The discrete
/// curvature `2 sin(theta/2) / ds` then underestimates the element's turning
/// by at most 4 %, and the rest curvature stays representable (`ds |kappa0| < 2`
/// is a hard limit of the formula).
pub const MAX_RESOLVED_TURN: f64 = 1.0;

/// An equilibrium (or the best state reached) with its status.
#[derive(Debug, Clone)]
pub struct Solution {
    pub n_elements: usize,
    /// How the nodes were computed: `Fd2` or `Fe4`, or `Rk4` (shooting's
    /// integrator).
    pub scheme: Scheme,
    /// Length of the rod [m]: node `i` sits at arc length `i L / n`
    /// (sections of their own lengths: see `section_lengths`).
    pub length: f64,
    /// The sections' own lengths [m], each cut into `n / sections` equal
    /// elements; empty: equal elements `L / n`.
    pub section_lengths: Vec<f64>,
    /// Node quaternions `q_0..q_n`, `q_0` the base.
    pub quaternions: Vec<Quat>,
    /// Node positions `r_0..r_n` [m], `r_0` the scene's base position.
    pub positions: Vec<Vector3<f64>>,
    /// The fourth-order scheme's internal nodes, one an element at its
    /// middle (empty for the other schemes): with the nodes, the shape
    /// between them ([`Solution::positions_at`]).
    pub internal_quaternions: Vec<Quat>,
    /// The interior nodes where the shape is not smooth (a section's end,
    /// a point load, a tendon's anchor, a held point: see
    /// `RodModel::breaks`), which the shape between the nodes does not
    /// interpolate across; `None`: unknown (a stored solution of an earlier
    /// version), every node taken as one.
    pub breaks: Option<Vec<usize>>,
    /// Internal force at the nodes, world frame [N] (force the distal part exerts on the proximal one).
    pub forces: Vec<Vector3<f64>>,
    /// Stiffness `(kx, ky, kz)` [N m^2] and rest curvature `[kappa_x, kappa_y]`
    /// per equal section [1/m] of the rod: with the quaternions, what
    /// [`Solution::curvatures`] and [`Solution::moments`] are computed from
    /// (on demand: a control loop that never reads them never pays for them).
    pub stiffness: Vector3<f64>,
    pub rest_curvature: Vec<[f64; 2]>,
    /// Stiffness per equal section where the sections differ (empty: `stiffness`).
    pub section_stiffness: Vec<Vector3<f64>>,
    /// The moment applied at the tip, world frame [N m].
    pub tip_moment: Vector3<f64>,
    /// Force that a pinned or clamped tip's support exerts on the rod, world frame [N].
    pub tip_reaction_force: Option<Vector3<f64>>,
    /// Moment that a clamped tip's support exerts on the rod, world frame [N m].
    pub tip_reaction_moment: Option<Vector3<f64>>,
    /// Force of each guide on the rod, in the scene's order, world frame [N].
    pub guide_reactions: Vec<Vector3<f64>>,
    /// Where the rod touches the obstacles and how hard, by arc length
    /// (empty without obstacles).
    pub contacts: Vec<Contact>,
    /// Where the rod passes each port and the force the port takes, in the
    /// scene's order (empty without ports).
    pub ports: Vec<PortReaction>,
    pub status: Status,
    /// Newton or LM iterations, all continuation steps included.
    pub iterations: usize,
    /// Load-continuation steps taken (0: solved directly).
    pub continuation_steps: usize,
    /// Relative residual (see [`Settings::residual_tol`]).
    pub residual_norm: f64,
    /// Total potential: elastic energy minus the work of the dead forces [J].
    pub energy: f64,
    /// Whether the equilibrium is stable: the symmetric part of the reduced
    /// Hessian is positive definite. Always false when not converged.
    pub stable: bool,
    /// A short human-readable account of how the solve ended.
    pub message: String,
    /// Accuracy on demand: the estimated largest distance of a node from
    /// the continuous rod's [m], over the whole backbone: from the solves at
    /// n/k and n, their difference over `k^p - 1` (`p` the scheme's order);
    /// by shooting, from this shot and a finer one at 2n, their difference
    /// over `1 - 2^-p` (the shot's own error).
    pub error_estimate: Option<f64>,
    /// Accuracy on demand with Richardson extrapolation: the finer of the
    /// pair's tip `r_f + (r_f - r_c) / (k^p - 1)` (`k` the pair's ratio of n),
    /// returned by [`Solution::tip_position`] in place of the last node.
    pub extrapolated_tip: Option<Vector3<f64>>,
    /// Wall-clock time of the solve [s], the set-up of the discretisation
    /// included (every n of accuracy on demand).
    pub solve_time: f64,
}

/// `sum_k w_k q_k` (not normalised).
fn blend(terms: &[(f64, Quat)]) -> Quat {
    terms
        .iter()
        .fold(Quat::new(0.0, 0.0, 0.0, 0.0), |sum, &(w, q)| Quat {
            w: sum.w + w * q.w,
            v: sum.v + w * q.v,
        })
}

/// Where an arc length falls: its element (from 1) and the fraction `tau`
/// of the element's length from its start.
fn element_at(arcs: &[f64], s: f64) -> (usize, f64) {
    let n = arcs.len() - 1;
    let i = arcs.partition_point(|&a| a <= s).clamp(1, n);
    let h = arcs[i] - arcs[i - 1];
    (i, ((s - arcs[i - 1]) / h).clamp(0.0, 1.0))
}

impl Solution {
    /// Refuse arc lengths outside `[0, L]` (or not finite), naming them.
    /// `L` is a sum of section or element lengths, which rounds differently
    /// at another n: another solution's last arc length of the same rod may
    /// exceed it by an ulp or two, and is taken as the tip.
    fn check_stations(&self, s: &[f64]) -> Result<()> {
        let end = self.length * (1.0 + 8.0 * f64::EPSILON);
        if let Some((j, x)) = s
            .iter()
            .enumerate()
            .find(|(_, x)| !(x.is_finite() && (0.0..=end).contains(*x)))
        {
            return Err(Error::argument(
                format!("s[{j}]"),
                format!("must lie in [0, L] = [0, {}], got {x}", self.length),
            ));
        }
        if self.scheme.has_internal_nodes() && self.internal_quaternions.len() != self.n_elements {
            return Err(Error::argument(
                "s",
                "a fourth-order solution without its internal_quaternions has no shape \
                 between its nodes",
            ));
        }
        Ok(())
    }

    /// Whether the shape is smooth through interior node `j` (see
    /// [`Solution::breaks`]; the elements on both sides of equal length).
    fn smooth_at(&self, j: usize, mesh: &Mesh) -> bool {
        let h = mesh.element_lengths();
        (1..self.n_elements).contains(&j)
            && h[j - 1] == h[j]
            && self.breaks.as_ref().is_some_and(|b| !b.contains(&j))
    }

    /// The rotation at fraction `tau` of element `i`: the scheme's own
    /// interpolant of the quaternions, normalised. Linear between the nodes
    /// (second order); with the fourth-order scheme's internal nodes, the
    /// polynomial through the element's nodes, its internal node and the
    /// internal nodes of its neighbours where the shape is smooth through
    /// the node between (fourth order: the nodes and internal nodes are;
    /// the element's own quadratic alone would be third order).
    fn rotation_in(&self, i: usize, tau: f64, mesh: &Mesh) -> Quat {
        let (a, b) = (self.quaternions[i - 1], self.quaternions[i]);
        let Some(&m) = self.internal_quaternions.get(i - 1) else {
            return blend(&[(1.0 - tau, a), (tau, b)]).normalized();
        };
        // On the side of the sphere of `a`.
        let near = |q: Quat| if a.dot(q) < 0.0 { -q } else { q };
        let mut points = [(0.0, a); 5];
        let mut count = 0;
        let mut add = |t: f64, q: Quat| {
            points[count] = (t, near(q));
            count += 1;
        };
        if i >= 2 && self.smooth_at(i - 1, mesh) {
            add(-0.5, self.internal_quaternions[i - 2]);
        }
        add(0.0, a);
        add(0.5, m);
        add(1.0, b);
        if i < self.n_elements && self.smooth_at(i, mesh) {
            add(1.5, self.internal_quaternions[i]);
        }
        let points = &points[..count];
        // Lagrange's weights on the points' fractions.
        let terms: Vec<(f64, Quat)> = points
            .iter()
            .map(|&(tk, q)| {
                let w = points
                    .iter()
                    .filter(|(tl, _)| *tl != tk)
                    .map(|(tl, _)| (tau - tl) / (tk - tl))
                    .product::<f64>();
                (w, q)
            })
            .collect();
        blend(&terms).normalized()
    }

    /// Positions at the arc lengths `s` [m] (each in `[0, L]`), at the
    /// scheme's order between the nodes: the tangent integrated along the
    /// element as the scheme integrates it to the next node (the exact
    /// integral of the linear interpolant's tangent for `fd2`; for `fe4` the
    /// quadratic through the tangents at the ends and the internal node,
    /// whose integral is the scheme's Simpson rule). Node arc lengths give
    /// the nodes; any other method's nodes (shooting's) are met too, the
    /// element's chord mismatch spread along it.
    pub fn positions_at(&self, s: &[f64]) -> Result<Vec<Vector3<f64>>> {
        self.check_stations(s)?;
        let mesh = self.mesh();
        let arcs = mesh.arcs();
        Ok(s.iter()
            .map(|&x| {
                let (i, tau) = element_at(arcs, x);
                let h = arcs[i] - arcs[i - 1];
                let (a, b) = (self.quaternions[i - 1], self.quaternions[i]);
                let along = |t: f64| -> Vector3<f64> {
                    match self.internal_quaternions.get(i - 1) {
                        // The integrals of the Lagrange basis on {0, 1/2, 1}.
                        Some(m) => {
                            let (t2, t3) = (t * t, t * t * t);
                            a.tangent() * (2.0 / 3.0 * t3 - 1.5 * t2 + t)
                                + m.tangent() * (-4.0 / 3.0 * t3 + 2.0 * t2)
                                + b.tangent() * (2.0 / 3.0 * t3 - 0.5 * t2)
                        }
                        // T((1 - t) a + t b) is quadratic in t: (1 - t)^2 T(a)
                        // + 2 t (1 - t) T(a, b) + t^2 T(b).
                        None => {
                            let u = 1.0 - t;
                            a.tangent() * ((1.0 - u * u * u) / 3.0)
                                + tangent_bilinear(a, b) * (t * t - 2.0 / 3.0 * t * t * t)
                                + b.tangent() * (t * t * t / 3.0)
                        }
                    }
                };
                let chord = self.positions[i] - self.positions[i - 1];
                self.positions[i - 1] + h * along(tau) + tau * (chord - h * along(1.0))
            })
            .collect())
    }

    /// Rotations (unit quaternions, scalar first) at the arc lengths `s`
    /// [m] (each in `[0, L]`): the scheme's interpolant between the nodes.
    pub fn rotations_at(&self, s: &[f64]) -> Result<Vec<Quat>> {
        self.check_stations(s)?;
        let mesh = self.mesh();
        let arcs = mesh.arcs();
        Ok(s.iter()
            .map(|&x| {
                let (i, tau) = element_at(arcs, x);
                self.rotation_in(i, tau, &mesh)
            })
            .collect())
    }
    pub fn converged(&self) -> bool {
        self.status == Status::Converged
    }

    /// The tip: the last node, or the Richardson-extrapolated tip when asked for.
    pub fn tip_position(&self) -> Vector3<f64> {
        self.extrapolated_tip
            .unwrap_or(self.positions[self.positions.len() - 1])
    }

    pub fn tip_quaternion(&self) -> Quat {
        self.quaternions[self.quaternions.len() - 1]
    }

    /// Where the nodes sit along the rod.
    pub fn mesh(&self) -> Mesh {
        Mesh::new(self.length, &self.section_lengths, self.n_elements)
    }

    /// Arc length of the nodes [m]: `s_i = i L / n`, or each section's
    /// equal elements when the sections have lengths of their own.
    pub fn arc_length(&self) -> Vec<f64> {
        self.mesh().arcs().to_vec()
    }

    /// Curvature and twist of each element in its own (material) frame
    /// [1/m], `n` entries: `u_i = (2/ds) vec(c)`, `c = conj(q_{i-1}) q_i`, the
    /// finite-difference scheme's discrete curvature (for the other schemes,
    /// the same reading of their nodes: second order). It is the same in the
    /// frames of both nodes (the axis of the relative rotation).
    pub fn curvatures(&self) -> Vec<Vector3<f64>> {
        let mesh = self.mesh();
        self.quaternions
            .windows(2)
            .zip(mesh.element_lengths())
            .map(|(p, h)| (2.0 / h) * (p[0].conj() * p[1]).v)
            .collect()
    }

    /// Internal moment at the nodes, world frame [N m]: the moment the
    /// distal part exerts on the proximal one; `moments[0]` is the moment of
    /// the rod on its base support. Element `i` transmits the moment
    /// conjugate to its nodes' rotations, `R(q_{i-1}) A K (u - u0)` with `A =
    /// c_w I + [c_v]x`: the same from either node's side (`R(c) A^T = A`) and
    /// exact in the discrete balance (a tip moment alone is transmitted by
    /// every element). At the nodes: the mean of the two elements around an
    /// interior node, second order like the scheme; the tip's applied moment
    /// plus a clamp's reaction at the tip, where the boundary condition gives
    /// it exactly; linear extrapolation from the first two elements at the
    /// base (second order).
    pub fn moments(&self) -> Vec<Vector3<f64>> {
        let n = self.n_elements;
        let sections = self.rest_curvature.len().max(1);
        let stiffness_sections = self.section_stiffness.len().max(1);
        let element: Vec<Vector3<f64>> = self
            .curvatures()
            .iter()
            .enumerate()
            .map(|(i, u)| {
                let rest = self
                    .rest_curvature
                    .get(section_of(i, sections, n))
                    .map_or(Vector3::zeros(), |k| Vector3::new(k[0], k[1], 0.0));
                let k = self
                    .section_stiffness
                    .get(section_of(i, stiffness_sections, n))
                    .unwrap_or(&self.stiffness);
                let w = k.component_mul(&(u - rest));
                let (a, b) = (self.quaternions[i], self.quaternions[i + 1]);
                let c = a.conj() * b;
                a.rotate(c.w * w + c.v.cross(&w))
            })
            .collect();
        let mut moments = Vec::with_capacity(n + 1);
        moments.push(match n {
            1 => element[0],
            _ => 1.5 * element[0] - 0.5 * element[1],
        });
        moments.extend(element.windows(2).map(|m| 0.5 * (m[0] + m[1])));
        moments.push(self.tip_moment + self.tip_reaction_moment.unwrap_or_default());
        moments
    }

    /// The nodes' rotation matrices (material frame to world frame).
    pub fn rotation_matrices(&self) -> Vec<Matrix3<f64>> {
        self.quaternions.iter().map(|q| q.rotation()).collect()
    }

    /// Refuse a Solution whose arrays do not fit its `n_elements` (one
    /// rebuilt from stored fields), naming the field.
    pub fn check_layout(&self) -> Result<()> {
        let n = self.n_elements;
        if n == 0 {
            return Err(Error::argument("solution.n_elements", "must be positive"));
        }
        if !(self.length.is_finite() && self.length > 0.0) {
            return Err(Error::argument(
                "solution.length",
                format!("must be positive and finite, got {}", self.length),
            ));
        }
        for (name, len, expected) in [
            ("positions", self.positions.len(), n + 1),
            ("quaternions", self.quaternions.len(), n + 1),
            ("forces", self.forces.len(), n + 1),
        ] {
            if len != expected {
                return Err(Error::argument(
                    format!("solution.{name}"),
                    format!("has {len} rows, n_elements = {n} needs {expected}"),
                ));
            }
        }
        let internal = self.internal_quaternions.len();
        if internal != 0 && internal != n {
            return Err(Error::argument(
                "solution.internal_quaternions",
                format!("has {internal} rows, n_elements = {n} needs {n} (or none)"),
            ));
        }
        if let Some(j) = self.breaks.iter().flatten().find(|j| !(1..n).contains(*j)) {
            return Err(Error::argument(
                "solution.breaks",
                format!(
                    "node {j} is no interior node of {n} elements (1 to {})",
                    n - 1
                ),
            ));
        }
        let lengths = self.section_lengths.len();
        let total: f64 = self.section_lengths.iter().sum();
        let positive = self
            .section_lengths
            .iter()
            .all(|l| l.is_finite() && *l > 0.0);
        if lengths > 0
            && (n % lengths != 0 || !positive || (total - self.length).abs() > 1e-9 * self.length)
        {
            return Err(Error::argument(
                "solution.section_lengths",
                format!(
                    "{lengths} sections of positive length adding up to length = {} must divide \
                     n_elements = {n}",
                    self.length
                ),
            ));
        }
        let sections = self.rest_curvature.len();
        if sections > 0 && n % sections != 0 {
            return Err(Error::argument(
                "solution.rest_curvature",
                format!("{sections} sections do not divide n_elements = {n}"),
            ));
        }
        for (name, x) in [
            ("residual_norm", Some(self.residual_norm)),
            ("error_estimate", self.error_estimate),
            ("solve_time", Some(self.solve_time)),
        ] {
            // A norm, an error and a duration: never negative (a failure's
            // may be infinite or NaN).
            if x.is_some_and(|x| x < 0.0) {
                return Err(Error::argument(
                    format!("solution.{name}"),
                    format!("must not be negative, got {}", x.unwrap_or_default()),
                ));
            }
        }
        if self.converged() {
            self.check_converged_state()?;
        }
        Ok(())
    }

    /// What a converged answer is: a finite state of unit quaternions with
    /// finite reactions, residual and energy (a stored failure may hold the
    /// overflow that ended it; a converged one may not).
    fn check_converged_state(&self) -> Result<()> {
        let vectors: [(&str, &[Vector3<f64>]); 4] = [
            ("positions", &self.positions),
            ("forces", &self.forces),
            ("section_stiffness", &self.section_stiffness),
            ("guide_reactions", &self.guide_reactions),
        ];
        let single = [
            ("stiffness", Some(self.stiffness)),
            ("tip_moment", Some(self.tip_moment)),
            ("tip_reaction_force", self.tip_reaction_force),
            ("tip_reaction_moment", self.tip_reaction_moment),
            ("extrapolated_tip", self.extrapolated_tip),
        ];
        let rows = vectors.into_iter().flat_map(|(name, rows)| {
            rows.iter().enumerate().map(move |(i, v)| {
                (
                    format!("{name}[{i}]"),
                    v.iter().copied().collect::<Vec<_>>(),
                )
            })
        });
        let singles = single
            .into_iter()
            .filter_map(|(name, v)| v.map(|v| (name.to_string(), v.iter().copied().collect())));
        let curvature = self
            .rest_curvature
            .iter()
            .enumerate()
            .map(|(i, k)| (format!("rest_curvature[{i}]"), k.to_vec()));
        let scalars = [
            ("residual_norm", Some(self.residual_norm)),
            ("energy", Some(self.energy)),
            ("error_estimate", self.error_estimate),
        ]
        .into_iter()
        .filter_map(|(name, x)| x.map(|x| (name.to_string(), vec![x])));
        for (name, values) in rows.chain(singles).chain(curvature).chain(scalars) {
            if let Some(x) = values.iter().find(|x| !x.is_finite()) {
                return Err(Error::argument(
                    format!("solution.{name}"),
                    format!("a converged solution is finite, got {x}"),
                ));
            }
        }
        for (name, quaternions) in [
            ("quaternions", &self.quaternions),
            ("internal_quaternions", &self.internal_quaternions),
        ] {
            if let Some((i, q)) = quaternions.iter().enumerate().find(|(_, q)| {
                !q.to_array().iter().all(|x| x.is_finite()) || (q.norm() - 1.0).abs() > 1e-9
            }) {
                return Err(Error::argument(
                    format!("solution.{name}[{i}]"),
                    format!(
                        "a converged solution has unit quaternions, got norm {}",
                        q.norm()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The solution if it converged, otherwise [`Error::NotConverged`].
    pub fn check(self) -> Result<Self> {
        if self.converged() {
            Ok(self)
        } else {
            Err(Error::NotConverged {
                status: self.status,
                iterations: self.iterations,
                residual: self.residual_norm,
                reason: self.message,
            })
        }
    }
}

/// The one judgement of every method's end state: `solved` is the method's own
/// verdict (`Err` with the status of its failure). A converged answer must
/// also be finite, meet the residual tolerance and be resolved by the scheme.
/// Returns the status and, where the judgement overrules the method, the
/// message that says why.
pub(super) fn judge(
    model: &RodModel,
    q: &[Quat],
    positions: &[Vector3<f64>],
    residual_norm: f64,
    solved: std::result::Result<(), Status>,
    tol: f64,
) -> (Status, Option<String>) {
    let finite = residual_norm.is_finite()
        && q.iter().all(|x| x.to_array().iter().all(|v| v.is_finite()))
        && positions.iter().all(|p| p.iter().all(|v| v.is_finite()));
    if !finite {
        return (
            Status::NumericalError,
            Some("numerical error: the state or the residual is not finite (overflow)".into()),
        );
    }
    if let Err(status) = solved {
        return (status, None);
    }
    if residual_norm > tol {
        return (Status::NotConverged, None);
    }
    let turn = model.max_element_turn(q).max(model.max_rest_turn());
    if turn > MAX_RESOLVED_TURN {
        let needed = (model.n() as f64 * turn / MAX_RESOLVED_TURN).ceil();
        return (
            Status::Underresolved,
            Some(format!(
                "underresolved: an element turns by {turn:.2} rad, more than the {MAX_RESOLVED_TURN} rad \
                 the scheme resolves; use at least {needed} elements (or tol= for accuracy on demand)"
            )),
        );
    }
    (Status::Converged, None)
}
