//! Shooting (`method = "shooting"`): the baseline most continuum-robot users
//! know. The Kirchhoff rod equations are integrated from the base by classic
//! fourth-order Runge-Kutta, one step an element (so the nodes are the step
//! points, point loads and section ends fall on them, and the rest curvature
//! is constant within a step), and Newton with a finite-difference Jacobian
//! finds the unknown base wrench that meets the tip's conditions (Broyden's
//! update of that Jacobian after a full step).
//!
//! ```text
//! r' = R e3        q' = q (0, u) / 2      u = u0 + K^-1 R^T m
//! n' = -f          m' = n x r' - l        (world frame; n, m: what the distal part exerts)
//! ```
//!
//! Dead loads: `f` and `l` per length, point forces and moments at nodes
//! (each jumps `n` or `m` as the integration passes it), and at the tip its
//! force, its moment and, for a tip force off the tip at `c` in the tip's
//! frame, `(R c) x F`. A magnetised rod in a uniform field `B` carries the
//! moment `(R mu) x B` per length of its magnetisation `mu` (material
//! frame, constant along a section), a tip magnet `(R mu_tip) x B` at the
//! tip: moments that turn with the rod, evaluated at each stage. A tendon
//! is part of the constitutive law, as in the discrete potential: its
//! potential `tension |e3 + u x rho + rho'|` is a function of the curvature,
//! so each stage solves `K (u - u0) + sum tension rho x v / |v| = R^T m` for
//! `u`; its anchor's and kinks' forces stay inside the internal wrench `n`,
//! `m` (the rod's with its tendons').
//!
//! For dead loads the internal force is explicit, `n(s) = n(0) - f s - (point
//! loads passed)`, so only `r`, `q` and `m` are integrated. A free tip's base
//! force is known (the sum of the loads): Newton has 3 unknowns, the base
//! moment. A pinned or clamped tip adds the base force (6 unknowns). Guides
//! (held interior points) are not supported by this method.
//!
//! A direct attempt from the rigid estimate of the base moment is followed,
//! if it fails, by load continuation from the rest shape (and for a held tip
//! by a second leg that moves the tip from where the loaded free rod puts it
//! to its target), the same strategy as the finite-element driver's.
//!
//! [`shoot`] returns the base wrench ([`Shot`]); [`Shot::shape`] integrates
//! it into the nodes. Whether a shape is a stable equilibrium is the
//! discrete model's judgement, asked of the caller through a closure.

use crate::interrupt;
use crate::interrupt::POLL_STRIDE;
use crate::model::{element_turn, slerp, RodModel};
use crate::quat::Quat;
use crate::scene::Scene;
use crate::scene::Tendon;
use crate::terms::section_of;
use crate::terms::tendons::density_on;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

type Vector6 = SVector<f64, 6>;
type Matrix6 = SMatrix<f64, 6, 6>;

/// What the tip must meet: its applied moment (free or pinned), its position
/// (pinned, clamped) and orientation (clamped).
#[derive(Debug, Clone, Copy)]
struct TipTarget {
    position: Option<Vector3<f64>>,
    orientation: Option<Quat>,
}

/// The loads at one load scale and the rod's fixed data, as the integration needs them.
struct Rod<'a> {
    model: &'a RodModel,
    /// Each element's (from 0) inverse stiffness [1 / N m^2], or one entry
    /// for a rod of one stiffness.
    inverse_stiffness: Vec<Vector3<f64>>,
    /// Each element's distributed force [N/m], world frame (its section's).
    distributed: Vec<Vector3<f64>>,
    /// Point load at each node (index = node), world frame [N]; the tip's
    /// counts in the tip condition.
    point: Vec<Vector3<f64>>,
    /// Point moment at each node (index = node), world frame [N m]; the
    /// tip's counts in the tip condition.
    point_moment: Vec<Vector3<f64>>,
    /// Each element's distributed moment [N m / m], world frame.
    distributed_moment: Vec<Vector3<f64>>,
    /// The free rod's base force (the sum of every load) [N].
    free_base_force: Vector3<f64>,
    tip_force: Vector3<f64>,
    /// Where the tip force acts, from the tip in its material frame [m].
    tip_force_offset: Vector3<f64>,
    tip_moment: Vector3<f64>,
    /// The uniform magnetic field [T, world], the magnetisation of each
    /// equal section [A m^2 / m, material frame] and the tip magnet [A m^2,
    /// material frame].
    field: Vector3<f64>,
    magnetization: Vec<Vector3<f64>>,
    tip_magnet: Vector3<f64>,
    /// The pulled tendons, longest first, their tensions times `tendon_scale`
    /// (the load scale), and how many of them run through each element.
    tendons: Vec<Tendon>,
    tendon_scale: f64,
    through: Vec<usize>,
}

/// A shape shooting asks its caller to judge: is it a stable equilibrium of
/// the discrete model at this load scale?
pub struct Candidate<'a> {
    /// The node quaternions of the shot.
    pub quaternions: &'a [Quat],
    /// The loads' scale along the continuation (1 at full load).
    pub load_scale: f64,
    /// A held tip's reaction force [N, world] and the moment its support
    /// exerts [N m, tip frame]; `None` on the free rod's leg.
    pub held_tip: Option<(Vector3<f64>, Vector3<f64>)>,
}

/// The limits of one shooting solve.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// The largest scaled tip mismatch accepted.
    pub tol: f64,
    /// Newton iterations in all.
    pub max_iterations: usize,
    /// The smallest continuation step before the path is given up.
    pub min_continuation_step: f64,
}

/// A solved shot's base wrench and the Jacobian of its tip mismatch: the
/// start of a finer solve of the same scene (accuracy on demand). There the
/// mismatch is of the coarse solve's error, and the coarse Jacobian differs
/// from the fine one by as little, so chord steps with it (one integration
/// each) converge where Newton would draw a new Jacobian (one integration
/// an unknown) at every iteration.
#[derive(Debug, Clone, Copy)]
pub struct WarmShot {
    x: Vector6,
    /// `None` where the start was the answer (no Jacobian drawn).
    jacobian: Option<Matrix6>,
    held: bool,
}

/// A chord step must shrink the mismatch at least this much; else the
/// Jacobian is drawn again.
const CHORD_CONTRACTION: f64 = 0.1;

/// The end state of one integration.
#[derive(Debug, Clone, Copy)]
struct TipState {
    position: Vector3<f64>,
    quaternion: Quat,
    moment: Vector3<f64>,
    force: Vector3<f64>,
}

impl<'a> Rod<'a> {
    fn new(model: &'a RodModel, scene: &Scene, lambda: f64) -> Self {
        let n = model.n();
        let mesh = model.mesh();
        let mut point = vec![Vector3::zeros(); n + 1];
        let mut point_moment = vec![Vector3::zeros(); n + 1];
        for p in &scene.point_loads {
            let node = mesh.nearest_node(p.s);
            point[node] += lambda * p.force;
            point_moment[node] += lambda * p.moment;
        }
        // Sections of their own: each element its section's density,
        // moment and stiffness (the elastic term's, one entry if uniform).
        let sections = scene.sections();
        let section = |i: usize| section_of(i, sections, n);
        let distributed: Vec<Vector3<f64>> = (0..n)
            .map(|i| lambda * scene.section_force(section(i)))
            .collect();
        let distributed_moment = (0..n)
            .map(|i| {
                lambda
                    * scene
                        .section_moment(section(i))
                        .unwrap_or(scene.distributed_moment)
            })
            .collect();
        let lengths = mesh.element_lengths();
        let total: Vector3<f64> = distributed.iter().zip(lengths).map(|(f, h)| f * *h).sum();
        // A tendon is part of the rod's constitutive law (its potential, a
        // function of the curvature): no load of its own, its anchor's force
        // and moment inside the internal wrench.
        let mut tendons: Vec<Tendon> = scene
            .tendons
            .iter()
            .filter(|t| t.tension != 0.0)
            .cloned()
            .collect();
        tendons.sort_by(|a, b| b.end.total_cmp(&a.end));
        Rod {
            model,
            inverse_stiffness: model
                .rod()
                .loading
                .stiffness
                .iter()
                .map(|k| k.map(|k| 1.0 / k))
                .collect(),
            free_base_force: lambda * scene.tip_force + total + point.iter().sum::<Vector3<f64>>(),
            distributed,
            point,
            point_moment,
            distributed_moment,
            tip_force: lambda * scene.tip_force,
            tip_force_offset: scene.tip_force_offset,
            tip_moment: lambda * scene.tip_moment,
            field: lambda * scene.magnetic_field,
            magnetization: scene.magnetization.clone(),
            tip_magnet: scene.tip_magnet,
            through: (1..=n)
                .map(|i| {
                    let middle = mesh.arcs()[i - 1] + 0.5 * lengths[i - 1];
                    tendons.iter().take_while(|t| t.end > middle).count()
                })
                .collect(),
            tendons,
            tendon_scale: lambda,
        }
    }

    /// The magnetic moment on element `i` of orientation `q`, per length
    /// [N m / m, world].
    fn magnetic_moment(&self, i: usize, q: Quat) -> Vector3<f64> {
        let sections = self.magnetization.len();
        if sections == 0 {
            return Vector3::zeros();
        }
        let mu = self.magnetization[section_of(i, sections, self.model.n())];
        q.rotate(mu).cross(&self.field)
    }

    /// The moment the loads apply at the tip of orientation `q` [N m,
    /// world]: the tip's own and a point load's there, and the tip force's
    /// about the tip where it acts off it.
    fn end_moment(&self, q: Quat) -> Vector3<f64> {
        self.tip_moment
            + self.point_moment[self.model.n()]
            + q.rotate(self.tip_force_offset).cross(&self.tip_force)
            + q.rotate(self.tip_magnet).cross(&self.field)
    }

    /// `(q', r', m')` at a state of element `i` at arc length `s` (its
    /// routings those of the element's middle `stretch_at`), with the
    /// internal force `force` and rest curvature `u0`.
    #[inline(always)]
    fn derivative(
        &self,
        (i, s, stretch_at): (usize, f64, f64),
        q: Quat,
        m: Vector3<f64>,
        force: Vector3<f64>,
        u0: Vector3<f64>,
    ) -> (Quat, Vector3<f64>, Vector3<f64>) {
        let compliance = match self.inverse_stiffness.as_slice() {
            [one] => one,
            each => &each[i],
        };
        let moment = q.inverse_rotate(m);
        let u = match self.through[i] {
            0 => u0 + compliance.component_mul(&moment),
            k => self.curvature_with_tendons(
                &self.tendons[..k],
                (i, s, stretch_at),
                u0,
                compliance,
                moment,
            ),
        };
        let dq = q * Quat::pure(0.5 * u);
        let t = q.tangent();
        let mut l = self.distributed_moment[i];
        if self.field != Vector3::zeros() {
            l += self.magnetic_moment(i, q);
        }
        (dq, t, force.cross(&t) - l)
    }

    /// The curvature whose moment, the elastic one and the tendons'
    /// `sum tension rho x v / |v|` (`v = e3 + u x rho + rho'`), is `moment`
    /// (material frame): Newton on a convex potential's gradient, from the
    /// tendon-free curvature.
    fn curvature_with_tendons(
        &self,
        tendons: &[Tendon],
        (i, s, stretch_at): (usize, f64, f64),
        u0: Vector3<f64>,
        compliance: &Vector3<f64>,
        moment: Vector3<f64>,
    ) -> Vector3<f64> {
        let at = (s, stretch_at);
        // Element i's stiffness, as the elastic term holds it.
        let stiffness = match self.model.rod().loading.stiffness.as_slice() {
            [one] => *one,
            each => each[i],
        };
        let mut u = u0 + compliance.component_mul(&moment);
        let scale = u0.amax() + 1.0 / self.model.length();
        for _ in 0..CURVATURE_ITERATIONS {
            let (_, pulled, hessian) = density_on(tendons, self.tendon_scale, at, &u);
            let residual = stiffness.component_mul(&(u - u0)) + pulled - moment;
            let jacobian = Matrix3::from_diagonal(&stiffness) + hessian;
            let Some(du) = jacobian.cholesky().map(|c| c.solve(&residual)) else {
                break;
            };
            u -= du;
            // Quadratic convergence: after a step of 1e-8 what remains is
            // at round-off.
            if du.amax() <= CURVATURE_STEP_TOL * (u.amax() + scale) {
                return u;
            }
        }
        // Not solved (a tendon path folded back on itself, |v| near 0): the
        // shot fails on its mismatch rather than going on with a curvature
        // that does not balance the moment.
        Vector3::repeat(f64::NAN)
    }

    /// Integrate from the base with base moment `m0` and force `n0`; with
    /// `quats` and `points`, store the node quaternions and positions.
    fn integrate(
        &self,
        m0: Vector3<f64>,
        n0: Vector3<f64>,
        mut quats: Option<&mut [Quat]>,
        mut points: Option<&mut [Vector3<f64>]>,
    ) -> TipState {
        let model = self.model;
        let (mut q, mut r, mut m) = (model.base(), model.base_position(), m0);
        let mut force = n0;
        if let Some(qs) = quats.as_mut() {
            qs[0] = q;
        }
        if let Some(rs) = points.as_mut() {
            rs[0] = r;
        }
        for i in 0..model.n() {
            // A huge n takes long here: an interrupt leaves the shot
            // unfinished, and the Newton loops stop on the same flag. (Not
            // at the first step: a short shot leaves the poll to the
            // Newton loop, which polls every iteration.)
            if (i + 1) % POLL_STRIDE == 0 && interrupt::requested() {
                break;
            }
            let u0 = model.rod().loading.rest_curvature[i];
            let h = model.h(i + 1);
            let s0 = model.arc(i);
            let middle = s0 + 0.5 * h;
            let f_mid = force - 0.5 * h * self.distributed[i];
            let f_end = force - h * self.distributed[i];
            let (dq1, dr1, dm1) = self.derivative((i, s0, middle), q, m, force, u0);
            let (dq2, dr2, dm2) = self.derivative(
                (i, middle, middle),
                add(q, dq1, 0.5 * h),
                m + 0.5 * h * dm1,
                f_mid,
                u0,
            );
            let (dq3, dr3, dm3) = self.derivative(
                (i, middle, middle),
                add(q, dq2, 0.5 * h),
                m + 0.5 * h * dm2,
                f_mid,
                u0,
            );
            let (dq4, dr4, dm4) =
                self.derivative((i, s0 + h, middle), add(q, dq3, h), m + h * dm3, f_end, u0);
            let sixth = h / 6.0;
            let dq = Quat {
                w: dq1.w + 2.0 * (dq2.w + dq3.w) + dq4.w,
                v: dq1.v + 2.0 * (dq2.v + dq3.v) + dq4.v,
            };
            // Renormalised each step: RK4 keeps |q| = 1 only to its own order.
            q = add(q, dq, sixth).normalized();
            r += sixth * (dr1 + 2.0 * (dr2 + dr3) + dr4);
            m += sixth * (dm1 + 2.0 * (dm2 + dm3) + dm4);
            force = f_end;
            if i + 1 < model.n() {
                // Past a node, its point load no longer acts on the distal part.
                force -= self.point[i + 1];
                m -= self.point_moment[i + 1];
            }
            if let Some(qs) = quats.as_mut() {
                qs[i + 1] = q;
            }
            if let Some(rs) = points.as_mut() {
                rs[i + 1] = r;
            }
        }
        TipState {
            position: r,
            quaternion: q,
            moment: m,
            force,
        }
    }

    /// What a held tip's support adds at the shot's tip: the force [N,
    /// world] and the moment in the tip's frame [N m].
    fn held_tip_reaction(&self, tip: &TipState) -> (Vector3<f64>, Vector3<f64>) {
        let n = self.model.n();
        (
            tip.force - (self.point[n] + self.tip_force),
            tip.quaternion
                .inverse_rotate(tip.moment - self.end_moment(tip.quaternion)),
        )
    }

    /// The scaled tip mismatch (dimensionless, angle-like): the moment rows
    /// over `k_c / L` in the tip's frame (free, pinned), the position over
    /// `L` (pinned, clamped), the orientation's rotation vector (clamped).
    fn mismatch(&self, tip: &TipState, target: &TipTarget) -> Vector6 {
        let model = self.model;
        let mut out = Vector6::zeros();
        match target.orientation {
            Some(q_target) => {
                let rel = q_target.conj() * tip.quaternion;
                let sign = if rel.w < 0.0 { -1.0 } else { 1.0 };
                out.fixed_rows_mut::<3>(0).copy_from(&(2.0 * sign * rel.v));
            }
            None => {
                let moment = tip
                    .quaternion
                    .inverse_rotate(tip.moment - self.end_moment(tip.quaternion))
                    .component_div(&model.residual_scale());
                out.fixed_rows_mut::<3>(0).copy_from(&moment);
            }
        }
        if let Some(p) = target.position {
            out.fixed_rows_mut::<3>(3)
                .copy_from(&((tip.position - p) / model.length()));
        }
        out
    }
}

/// `q + h dq` (no normalisation).
#[inline]
fn add(q: Quat, dq: Quat, h: f64) -> Quat {
    Quat {
        w: q.w + h * dq.w,
        v: q.v + h * dq.v,
    }
}

/// Newton on the base wrench `x = [m0; n0]` (the force only when `held`).
struct Newton<'r, 'a> {
    rod: &'r Rod<'a>,
    target: TipTarget,
    held: bool,
    /// Unknowns' scales: moments `k/L`, forces `k/L^2`.
    scale: Vector6,
}

impl<'r, 'a> Newton<'r, 'a> {
    /// Newton on `rod` (the loads at full scale) toward the scene's own
    /// tip: held where `held`, else free.
    fn at_full_load(rod: &'r Rod<'a>, model: &RodModel, held: bool) -> Self {
        Newton {
            rod,
            target: if held {
                held_tip_target(model)
            } else {
                TipTarget {
                    position: None,
                    orientation: None,
                }
            },
            held,
            scale: unknowns_scale(model),
        }
    }
    fn unknowns(&self) -> usize {
        if self.held {
            6
        } else {
            3
        }
    }

    fn split(&self, x: &Vector6) -> (Vector3<f64>, Vector3<f64>) {
        let m0 = x.fixed_rows::<3>(0).into_owned();
        let n0 = if self.held {
            x.fixed_rows::<3>(3).into_owned()
        } else {
            self.rod.free_base_force
        };
        (m0, n0)
    }

    fn residual(&self, x: &Vector6) -> Vector6 {
        let (m0, n0) = self.split(x);
        self.rod
            .mismatch(&self.rod.integrate(m0, n0, None, None), &self.target)
    }

    /// Iterate from `x` until the largest scaled mismatch is below `tol`;
    /// returns whether it converged and the iterations spent.
    fn run(&self, x: &mut Vector6, budget: usize, tol: f64) -> (bool, usize) {
        let ran = self.run_from(x, budget, (tol, 0.0), None);
        (ran.converged, ran.iterations)
    }

    /// [`Newton::run`], with chord steps on `chord` (a Jacobian of the same
    /// equations, e.g. a coarser solve's) while each shrinks the mismatch by
    /// [`CHORD_CONTRACTION`]; also returns the last Jacobian (the one used
    /// last, with Broyden's update of its step). It stops at `tol` or at
    /// `relative` times the first mismatch, if larger.
    fn run_from(
        &self,
        x: &mut Vector6,
        budget: usize,
        (tol, relative): (f64, f64),
        chord: Option<Matrix6>,
    ) -> Ran {
        let k = self.unknowns();
        let mut res = self.residual(x);
        let tol = tol.max(relative * res.amax());
        // One Jacobian in place (copies of a 6 x 6 were a twentieth of a
        // small solve): `chord` says whether a chord step may use it,
        // `known` whether it is set (the last one used).
        let (mut jac, mut chord, mut known) = match chord {
            Some(jac) => (jac, true, true),
            None => (Matrix6::identity(), false, false),
        };
        let last = |known: bool, jac: &Matrix6| known.then_some(*jac);
        for iteration in 0..budget {
            if !res.iter().all(|v| v.is_finite()) || interrupt::requested() {
                return Ran::ended(false, iteration, last(known, &jac), &res);
            }
            if res.amax() <= tol {
                return Ran::ended(true, iteration, last(known, &jac), &res);
            }
            if std::mem::take(&mut chord) {
                if let Some(dx) = Factored::new(&jac, self.held).solve(&(-res)) {
                    let trial = *x + dx;
                    let r = self.residual(&trial);
                    if r.iter().all(|v| v.is_finite()) && r.norm() <= CHORD_CONTRACTION * res.norm()
                    {
                        broyden_update(&mut jac, &dx, &(r - res));
                        *x = trial;
                        res = r;
                        chord = true;
                        continue;
                    }
                }
            }
            // Forward differences, one integration a column.
            jac = Matrix6::identity();
            for c in 0..k {
                let step = 1e-7 * x[c].abs().max(self.scale[c]);
                let mut probe = *x;
                probe[c] += step;
                let column = (self.residual(&probe) - res) / step;
                jac.set_column(c, &column);
            }
            known = true;
            let Some(lu) = Some(Factored::new(&jac, self.held)).filter(Factored::is_invertible)
            else {
                return Ran::ended(false, iteration + 1, Some(jac), &res);
            };
            let Some(dx) = lu.solve(&(-res)) else {
                return Ran::ended(false, iteration + 1, Some(jac), &res);
            };
            // Backtrack on the squared mismatch (Armijo, halving).
            let merit = res.norm_squared();
            let mut alpha = 1.0;
            let mut accepted = None;
            for _ in 0..30 {
                let trial = *x + alpha * dx;
                let r = self.residual(&trial);
                if r.iter().all(|v| v.is_finite())
                    && r.norm_squared() <= (1.0 - 1e-4 * alpha) * merit
                {
                    accepted = Some((trial, r));
                    break;
                }
                alpha *= 0.5;
            }
            match accepted {
                Some((trial, r)) => {
                    // A full step is near the answer: the next steps try the
                    // Jacobian with Broyden's update first (one integration,
                    // not one a column).
                    if alpha == 1.0 {
                        broyden_update(&mut jac, &dx, &(r - res));
                        chord = true;
                    }
                    *x = trial;
                    res = r;
                }
                None => return Ran::ended(false, iteration + 1, Some(jac), &res),
            }
        }
        Ran::ended(res.amax() <= tol, budget, last(known, &jac), &res)
    }
}

/// The LU factors of a shot's Jacobian: of its leading 3 x 3 block alone
/// for a free tip (its unknowns are the base moment; the rest of the 6 x 6
/// matrix is the identity and its steps and mismatch are nil there).
// Short-lived on the stack: boxing the larger variant would allocate.
#[allow(clippy::large_enum_variant)]
enum Factored {
    Free(nalgebra::linalg::LU<f64, nalgebra::U3, nalgebra::U3>),
    Held(nalgebra::linalg::LU<f64, nalgebra::U6, nalgebra::U6>),
}

impl Factored {
    fn new(jacobian: &Matrix6, held: bool) -> Self {
        if held {
            Factored::Held(jacobian.lu())
        } else {
            Factored::Free(jacobian.fixed_view::<3, 3>(0, 0).into_owned().lu())
        }
    }

    fn is_invertible(&self) -> bool {
        match self {
            Factored::Free(lu) => lu.is_invertible(),
            Factored::Held(lu) => lu.is_invertible(),
        }
    }

    fn solve(&self, rhs: &Vector6) -> Option<Vector6> {
        match self {
            Factored::Free(lu) => lu.solve(&rhs.fixed_rows::<3>(0).into_owned()).map(|x| {
                let mut out = Vector6::zeros();
                out.fixed_rows_mut::<3>(0).copy_from(&x);
                out
            }),
            Factored::Held(lu) => lu.solve(rhs),
        }
    }
}

/// How [`Newton::run_from`] ended.
struct Ran {
    converged: bool,
    iterations: usize,
    /// The last Jacobian used.
    jacobian: Option<Matrix6>,
    /// The largest scaled mismatch at the end.
    mismatch: f64,
}

impl Ran {
    fn ended(converged: bool, iterations: usize, jacobian: Option<Matrix6>, res: &Vector6) -> Ran {
        Ran {
            converged,
            iterations,
            jacobian,
            mismatch: res.amax(),
        }
    }
}

/// Broyden's rank-one update of `jac` to the secant of the step `dx` that
/// changed the mismatch by `dr`. (A free tip's unused rows and columns stay
/// the identity's: its steps and mismatch are nil there.)
fn broyden_update(jac: &mut Matrix6, dx: &Vector6, dr: &Vector6) {
    let length = dx.norm_squared();
    if length > 0.0 {
        *jac += (dr - *jac * dx) * (dx.transpose() / length);
    }
}

/// The outcome of a shooting solve: the base wrench and how it ended.
pub struct Shot {
    x: Vector6,
    pub converged: bool,
    /// Newton iterations spent.
    pub iterations: usize,
    /// Continuation steps taken.
    pub steps: usize,
    /// The largest scaled tip mismatch at the end.
    pub residual: f64,
    /// Why it did not converge, when a continuation stopped.
    pub note: Option<String>,
    /// The start of a finer solve: where the direct attempt converged.
    pub warm: Option<WarmShot>,
    /// Whether the answer is stable, where it was judged already (the
    /// direct attempt's answer).
    pub stable: Option<bool>,
    /// The answer's nodes and tip, where judging it drew them.
    drawn: Option<Drawn>,
}

/// An integrated shot: its node quaternions and positions and its tip.
struct Drawn {
    quaternions: Vec<Quat>,
    positions: Vec<Vector3<f64>>,
    tip: TipState,
}

impl Drawn {
    /// Its nodes into `quaternions` and `positions`; its tip.
    fn copy_into(&self, quaternions: &mut [Quat], positions: &mut [Vector3<f64>]) -> TipState {
        quaternions.copy_from_slice(&self.quaternions);
        positions.copy_from_slice(&self.positions);
        self.tip
    }
}

/// The tip of an integrated shot: a held tip's reactions.
pub struct ShotTip {
    /// The held tip's reaction force [N, world].
    pub reaction_force: Option<Vector3<f64>>,
    /// The moment the held tip's support exerts, in the tip's frame [N m].
    pub reaction_torque_body: Option<Vector3<f64>>,
    /// The same moment in the world frame [N m].
    pub reaction_moment: Option<Vector3<f64>>,
}

impl ShotTip {
    /// A free tip's: no reactions.
    const FREE: ShotTip = ShotTip {
        reaction_force: None,
        reaction_torque_body: None,
        reaction_moment: None,
    };
}

impl Shot {
    /// Integrate the shot into the node quaternions and positions (`n + 1`
    /// each) and give the held tip's reactions.
    pub fn shape(
        &self,
        model: &RodModel,
        scene: &Scene,
        quaternions: &mut [Quat],
        positions: &mut [Vector3<f64>],
    ) -> ShotTip {
        let held = !model.constraints().is_empty();
        if let (Some(drawn), false) = (&self.drawn, held) {
            // Drawn where it was judged, and a free tip has no reactions: no
            // rod to build.
            drawn.copy_into(quaternions, positions);
            return ShotTip::FREE;
        }
        let full = Rod::new(model, scene, 1.0);
        let m0 = self.x.fixed_rows::<3>(0).into_owned();
        let n0 = if held {
            self.x.fixed_rows::<3>(3).into_owned()
        } else {
            full.free_base_force
        };
        let tip = match &self.drawn {
            Some(drawn) => drawn.copy_into(quaternions, positions),
            None => full.integrate(m0, n0, Some(quaternions), Some(positions)),
        };
        if !held {
            return ShotTip::FREE;
        }
        let (force, torque) = full.held_tip_reaction(&tip);
        ShotTip {
            reaction_force: Some(force),
            reaction_torque_body: Some(torque),
            reaction_moment: Some(tip.moment - full.end_moment(tip.quaternion)),
        }
    }
}

/// Adaptive continuation over `t` in `[0, 1]`: `solve_at(t, x, budget)` runs
/// Newton at `t` from `x`. Starts from `x` at `t = 0` (a solved state).
/// A step is accepted only if no node's frame turned by more than
/// `MAX_FRAME_TURN` since the last accepted one (`frames(t, x, out)` puts the
/// node quaternions of `x` at `t` in `out`) and `stable(t, x)` is that of
/// the last accepted state: shooting problems have many roots, and a long
/// step can land on another branch (on 28 of 2 195 random free scenes the
/// path ended on an unstable one, 1.1 to 1.6 L from the load path's stable
/// equilibrium). A change of stability that persists down to a step of
/// [`CROSSING_STEP`] is the path's own (the loading itself loses stability,
/// as under a dead end moment past half a turn) and is crossed.
fn continuation(
    mut solve_at: impl FnMut(f64, &mut Vector6, usize) -> (bool, usize),
    mut frames: impl FnMut(f64, &Vector6, &mut [Quat]),
    mut stable: impl FnMut(f64, &Vector6) -> bool,
    nodes: usize,
    x: &mut Vector6,
    budget: usize,
    min_step: f64,
) -> (bool, usize, usize, f64) {
    let (mut t, mut dt, mut spent, mut steps) = (0.0f64, 0.25f64, 0usize, 0usize);
    let mut accepted = vec![Quat::IDENTITY; nodes];
    let mut trial_frames = accepted.clone();
    frames(0.0, x, &mut accepted);
    let mut accepted_stable = stable(0.0, x);
    while t < 1.0 && spent < budget && !interrupt::requested() {
        let next = (t + dt).min(1.0);
        let mut trial = *x;
        let (mut ok, its) = solve_at(next, &mut trial, (budget - spent).min(STEP_ITERATIONS));
        spent += its;
        steps += 1;
        let mut trial_stable = accepted_stable;
        if ok {
            frames(next, &trial, &mut trial_frames);
            ok = accepted
                .iter()
                .zip(&trial_frames)
                .all(|(a, b)| element_turn(*a, *b) <= MAX_FRAME_TURN);
            if ok {
                trial_stable = stable(next, &trial);
                ok = trial_stable == accepted_stable || next - t <= CROSSING_STEP;
            }
        }
        if ok {
            accepted_stable = trial_stable;
            *x = trial;
            std::mem::swap(&mut accepted, &mut trial_frames);
            t = next;
            dt = (2.0 * dt).min(1.0);
        } else {
            dt *= 0.5;
            if dt < min_step {
                return (false, spent, steps, t);
            }
        }
    }
    (t >= 1.0, spent, steps, t)
}

/// Newton iterations of a curvature under tendons (it converges in a few),
/// and the relative step after which it stops.
const CURVATURE_ITERATIONS: usize = 30;
const CURVATURE_STEP_TOL: f64 = 1e-8;

/// Largest turn of a node's frame in one continuation step [rad].
const MAX_FRAME_TURN: f64 = 0.5;

/// Continuation step (of the load scale) at which a change of stability
/// that persists is taken as the path's own rather than a jump to another
/// branch.
const CROSSING_STEP: f64 = 1e-3;

/// Newton iterations of one continuation step, and of the direct attempt.
const STEP_ITERATIONS: usize = 25;
const DIRECT_ITERATIONS: usize = 60;

/// Solve by shooting (see the module documentation) from a warm start's
/// shape or the rigid estimate; `stable` judges a candidate shape.
pub fn shoot(
    model: &RodModel,
    scene: &Scene,
    limits: Limits,
    (initial, warm): (Option<&[Quat]>, Option<&WarmShot>),
    stable: &mut dyn FnMut(&Candidate) -> bool,
) -> Shot {
    let tol = limits.tol;
    let budget = limits.max_iterations;
    let held = !model.constraints().is_empty();
    let scale = unknowns_scale(model);
    let full = Rod::new(model, scene, 1.0);
    let free_target = TipTarget {
        position: None,
        orientation: None,
    };
    let held_target = held_tip_target(model);
    let direct = Newton {
        rod: &full,
        target: if held { held_target } else { free_target },
        held,
        scale,
    };
    let warm = warm.filter(|w| w.held == held);
    let mut x = match warm {
        Some(w) => w.x,
        None => cold_start(model, &full, initial),
    };
    let Ran {
        mut converged,
        mut iterations,
        jacobian,
        mismatch: direct_mismatch,
    } = direct.run_from(
        &mut x,
        budget.min(DIRECT_ITERATIONS),
        (tol, 0.0),
        warm.and_then(|w| w.jacobian),
    );
    let direct_x = x;
    let mut steps = 0;
    // Shooting converges to whatever equilibrium is nearest its start: a
    // direct answer on an unstable branch (found on 8 of 426 random free
    // scenes) gives way to the load path from rest, which stays on the
    // stable branch, as in the finite-element driver.
    // The shape a candidate is judged at, drawn once for the whole solve.
    let mut shape = vec![Quat::IDENTITY; model.n() + 1];
    let mut positions = vec![Vector3::zeros(); model.n() + 1];
    let direct_judged =
        converged.then(|| shot_is_stable(&full, &x, held, (&mut shape, &mut positions), stable));
    let direct_stable = direct_judged.map(|(stable, _)| stable);
    let direct_unstable = direct_stable == Some(false);
    let mut note = None;
    if !converged || direct_unstable {
        // Leg 1: the loads from zero on the free rod (exact rest shape at 0).
        let mut free = Vector6::zeros();
        let (ok, spent, taken, reached) = continuation(
            |lambda, x, its| {
                let rod = Rod::new(model, scene, lambda);
                let newton = Newton {
                    rod: &rod,
                    target: free_target,
                    held: false,
                    scale,
                };
                newton.run(x, its, tol)
            },
            |lambda, x, out| {
                let rod = Rod::new(model, scene, lambda);
                let m0 = x.fixed_rows::<3>(0).into_owned();
                rod.integrate(m0, rod.free_base_force, Some(out), None);
            },
            // The rest shape is stable: the path keeps its stability but
            // where the loading itself changes it.
            |lambda, x| {
                let rod = Rod::new(model, scene, lambda);
                free_rod_is_stable(&rod, x, lambda, (&mut shape, None), stable).0
            },
            model.n() + 1,
            &mut free,
            budget - iterations.min(budget),
            limits.min_continuation_step,
        );
        iterations += spent;
        steps += taken;
        converged = ok;
        if !ok {
            note = Some(format!(
                "shooting could not follow the load path from the rest shape: it stopped \
                 at load scale {reached:.3} of 1"
            ));
        }
        x = free;
        x.fixed_rows_mut::<3>(3).copy_from(&full.free_base_force);
        if ok && held {
            // Leg 2: the held tip from where the loaded free rod puts it.
            let released = full.integrate(
                free.fixed_rows::<3>(0).into_owned(),
                full.free_base_force,
                None,
                None,
            );
            let goal = held_target;
            let start_q = goal.orientation.map(|g| {
                if g.dot(released.quaternion) < 0.0 {
                    -released.quaternion
                } else {
                    released.quaternion
                }
            });
            let (ok, spent, taken, reached) = continuation(
                |mu, x, its| {
                    let target = TipTarget {
                        position: goal
                            .position
                            .map(|p| released.position + mu * (p - released.position)),
                        orientation: goal.orientation.zip(start_q).map(|(g, s)| slerp(s, g, mu)),
                    };
                    let newton = Newton {
                        rod: &full,
                        target,
                        held: true,
                        scale,
                    };
                    newton.run(x, its, tol)
                },
                |_, x, out| {
                    let (m0, n0) = (x.fixed_rows::<3>(0), x.fixed_rows::<3>(3));
                    full.integrate(m0.into_owned(), n0.into_owned(), Some(out), None);
                },
                // The held leg moves the tip along an arbitrary route:
                // its stability is judged at the end, as the FE driver's.
                |_, _| true,
                model.n() + 1,
                &mut x,
                budget - iterations.min(budget),
                limits.min_continuation_step,
            );
            iterations += spent;
            steps += taken;
            converged = ok;
            if !ok {
                note = Some(format!(
                    "shooting could not move the held tip from where the loaded free rod \
                     puts it to its target: it stopped at {reached:.3} of the way"
                ));
            }
        }
        // An unstable direct answer is no answer: the load path from the
        // rest shape leads to the equilibrium the finite-element driver
        // finds, and when shooting cannot follow it, it says so.
    }
    let direct_answer = converged && steps == 0 && x == direct_x;
    let residual = if x == direct_x {
        direct_mismatch
    } else {
        direct.residual(&x).amax()
    };
    let warm = direct_answer.then_some(WarmShot { x, jacobian, held });
    // The direct answer's nodes, drawn where it was judged.
    let drawn = direct_judged
        .filter(|_| direct_answer)
        .map(|(_, tip)| Drawn {
            quaternions: shape,
            positions,
            tip,
        });
    Shot {
        x,
        converged,
        iterations,
        steps,
        residual,
        note,
        warm,
        stable: direct_stable.filter(|_| direct_answer),
        drawn,
    }
}

/// The scales of the unknowns: moments `k / L`, forces `k / L^2`.
fn unknowns_scale(model: &RodModel) -> Vector6 {
    let moment_scale = model.stiffness().max() / model.length();
    let mut scale = Vector6::repeat(moment_scale);
    scale
        .fixed_rows_mut::<3>(3)
        .fill(moment_scale / model.length());
    scale
}

/// What a held tip must meet: its position and, clamped, its orientation.
fn held_tip_target(model: &RodModel) -> TipTarget {
    TipTarget {
        position: model.constraints().last().map(|c| c.target),
        orientation: model.clamped_tip(),
    }
}

/// How far [`probe`] shrinks the tip mismatch of the rigid estimate: far
/// below a coarse shot's own error, whose wrench only starts a solve.
const PROBE_CONTRACTION: f64 = 1e-6;

/// A shot of few elements ([`probe`]): where a solve of the same scene
/// starts, and its shape.
pub struct Probe {
    /// Its base wrench and Jacobian.
    pub warm: WarmShot,
    /// Its rotations at the nodes, `n + 1` of them.
    pub quaternions: Vec<Quat>,
}

/// A coarse shot of `model` (few elements) for where a solve of the same
/// scene starts, its base wrench and Jacobian (a cold solve at a finer n
/// would draw that Jacobian at the finer n's cost), and its shape: Newton
/// directly from the rigid estimate, without the stability or solution of a
/// solve. `None` where it does not converge directly (the solve then starts
/// cold and takes its own load path) or is interrupted; with the
/// iterations it took. Its equilibrium is not judged: the solve that starts
/// from it judges its own.
pub fn probe(model: &RodModel, scene: &Scene, limits: Limits) -> (Option<Probe>, usize) {
    let held = !model.constraints().is_empty();
    let rod = Rod::new(model, scene, 1.0);
    let newton = Newton::at_full_load(&rod, model, held);
    let mut x = cold_start(model, &rod, None);
    let ran = newton.run_from(
        &mut x,
        limits.max_iterations.min(DIRECT_ITERATIONS),
        (limits.tol, PROBE_CONTRACTION),
        None,
    );
    if !ran.converged {
        return (None, ran.iterations);
    }
    let mut quaternions = vec![Quat::IDENTITY; model.n() + 1];
    let (m0, n0) = newton.split(&x);
    rod.integrate(m0, n0, Some(&mut quaternions), None);
    let warm = WarmShot {
        x,
        jacobian: ran.jacobian,
        held,
    };
    let probe = Probe { warm, quaternions };
    (Some(probe), ran.iterations)
}

/// How far [`finer_shot`] shrinks the tip mismatch the coarser wrench leaves
/// at the finer n (the coarser shot's error): what remains moves the finer
/// nodes by at most about this part of their difference from the coarser
/// ones (far less in practice: against 1e-3, which took one more chord step
/// on the race's precurved rod, the estimates moved by 2e-5 and, on the
/// cantilever alpha = 10 at n = 4, 1e-3 of themselves).
const ESTIMATE_CONTRACTION: f64 = 1e-2;

/// A finer shot for an error estimate ([`finer_shot`]): its node positions.
pub struct FinerShot {
    /// The node positions, `n + 1` of them [m].
    pub positions: Vec<Vector3<f64>>,
    /// Newton's iterations (chord steps count as one each).
    pub iterations: usize,
    /// Where a solve at this n or a finer one starts.
    pub warm: WarmShot,
}

/// The shot of `model` (a finer n of the scene a coarser solve solved
/// directly) from that solve's [`WarmShot`], for the coarser answer's error
/// estimate: the chord steps of a finer pass (Newton where they stall) and
/// one integration into the node positions, without the shape, reactions,
/// stability or solution of a pass. `Err` with the iterations spent where it
/// does not converge within the budget or is interrupted.
pub fn finer_shot(
    model: &RodModel,
    scene: &Scene,
    limits: Limits,
    warm: &WarmShot,
) -> Result<FinerShot, usize> {
    let held = !model.constraints().is_empty();
    if warm.held != held {
        return Err(0);
    }
    let rod = Rod::new(model, scene, 1.0);
    let newton = Newton::at_full_load(&rod, model, held);
    // Chord steps on the coarser Jacobian, each integration keeping the
    // nodes (the estimate needs the finer shot's nodes to a small part of
    // their difference from the coarser ones, not to the solve's
    // tolerance); Newton where a step does not contract.
    let mut x = warm.x;
    let nodes = model.n() + 1;
    let (mut positions, mut trial_positions) =
        (vec![Vector3::zeros(); nodes], vec![Vector3::zeros(); nodes]);
    let shot = |x: &Vector6, positions: &mut [Vector3<f64>]| {
        let (m0, n0) = newton.split(x);
        rod.mismatch(
            &rod.integrate(m0, n0, None, Some(positions)),
            &newton.target,
        )
    };
    let mut res = shot(&x, &mut positions);
    let tol = limits.tol.max(ESTIMATE_CONTRACTION * res.amax());
    let lu = warm.jacobian.map(|jacobian| Factored::new(&jacobian, held));
    let mut iterations = 0;
    while res.amax() > tol {
        if interrupt::requested() {
            return Err(iterations);
        }
        let step = lu
            .as_ref()
            .filter(|_| iterations < MAX_ESTIMATE_CHORDS)
            .and_then(|lu| lu.solve(&(-res)));
        let Some(dx) = step else {
            return finer_shot_by_newton(&newton, &mut x, (limits, tol), warm, iterations);
        };
        let trial = x + dx;
        let r = shot(&trial, &mut trial_positions);
        iterations += 1;
        if !(r.iter().all(|v| v.is_finite()) && r.norm() <= CHORD_CONTRACTION * res.norm()) {
            return finer_shot_by_newton(&newton, &mut x, (limits, tol), warm, iterations);
        }
        (x, res) = (trial, r);
        std::mem::swap(&mut positions, &mut trial_positions);
    }
    Ok(FinerShot {
        positions,
        iterations,
        warm: WarmShot { x, ..*warm },
    })
}

/// Chord steps [`finer_shot`] takes before it gives way to Newton.
const MAX_ESTIMATE_CHORDS: usize = 3;

/// [`finer_shot`] where the chord steps stall: Newton from `x` (iterations
/// `spent` already) to the estimate's tolerance `tol`, then the nodes.
fn finer_shot_by_newton(
    newton: &Newton,
    x: &mut Vector6,
    (limits, tol): (Limits, f64),
    warm: &WarmShot,
    spent: usize,
) -> Result<FinerShot, usize> {
    let budget = limits
        .max_iterations
        .min(DIRECT_ITERATIONS)
        .saturating_sub(spent);
    let Ran {
        converged,
        iterations,
        jacobian,
        ..
    } = newton.run_from(x, budget, (tol, 0.0), None);
    if !converged {
        return Err(spent + iterations);
    }
    let mut positions = vec![Vector3::zeros(); newton.rod.model.n() + 1];
    let (m0, n0) = newton.split(x);
    newton.rod.integrate(m0, n0, None, Some(&mut positions));
    Ok(FinerShot {
        positions,
        iterations: spent + iterations,
        warm: WarmShot {
            x: *x,
            jacobian: jacobian.or(warm.jacobian),
            held: warm.held,
        },
    })
}

/// Whether the rod shot with the base wrench `x` (the base force too when
/// `held`) is a stable equilibrium at full load, the held tip's reaction
/// included; its nodes drawn into `shape` and its tip returned.
fn shot_is_stable(
    rod: &Rod,
    x: &Vector6,
    held: bool,
    (shape, positions): (&mut [Quat], &mut [Vector3<f64>]),
    stable: &mut dyn FnMut(&Candidate) -> bool,
) -> (bool, TipState) {
    if !held {
        return free_rod_is_stable(rod, x, 1.0, (shape, Some(positions)), stable);
    }
    let (m0, n0) = (
        x.fixed_rows::<3>(0).into_owned(),
        x.fixed_rows::<3>(3).into_owned(),
    );
    let tip = rod.integrate(m0, n0, Some(&mut *shape), Some(positions));
    let verdict = stable(&Candidate {
        quaternions: shape,
        load_scale: 1.0,
        held_tip: Some(rod.held_tip_reaction(&tip)),
    });
    (verdict, tip)
}

/// Whether the free rod shot with the base wrench `x` at load scale
/// `lambda` is a stable equilibrium (its nodes drawn into `shape` and,
/// given, `positions`), and its tip.
fn free_rod_is_stable(
    rod: &Rod,
    x: &Vector6,
    lambda: f64,
    (shape, positions): (&mut [Quat], Option<&mut [Vector3<f64>]>),
    stable: &mut dyn FnMut(&Candidate) -> bool,
) -> (bool, TipState) {
    let tip = rod.integrate(
        x.fixed_rows::<3>(0).into_owned(),
        rod.free_base_force,
        Some(&mut *shape),
        positions,
    );
    let verdict = stable(&Candidate {
        quaternions: shape,
        load_scale: lambda,
        held_tip: None,
    });
    (verdict, tip)
}

/// The unknowns a cold shot starts from: the base moment of
/// [`start_moment`] and the free rod's base force.
fn cold_start(model: &RodModel, rod: &Rod, initial: Option<&[Quat]>) -> Vector6 {
    let mut x = Vector6::zeros();
    x.fixed_rows_mut::<3>(0)
        .copy_from(&start_moment(model, rod, initial));
    x.fixed_rows_mut::<3>(3).copy_from(&rod.free_base_force);
    x
}

/// The base moment to start from: the loads' moment about the base on the
/// warm start's shape for a free tip (the base moment of a free rod is that
/// statically: exact to the shape's error, a coarser solve's refined shape
/// gives Newton a start within O(h^2) of its answer where its first
/// element's bending was O(h) off), on the rest shape without one (exact
/// for a rigid rod); a held tip's unknown reaction leaves a warm start's
/// first element's bending.
fn start_moment(model: &RodModel, rod: &Rod, initial: Option<&[Quat]>) -> Vector3<f64> {
    let held = !model.constraints().is_empty();
    if let (Some(q), true) = (initial, held) {
        let (a, b) = (model.base(), q[1].normalized());
        let b = if a.dot(b) < 0.0 { -b } else { b };
        let u = (2.0 / model.h(1)) * (a.conj() * b).v;
        let stiffness = model.rod().loading.stiffness[0];
        return a.rotate(stiffness.component_mul(&(u - model.rod().loading.rest_curvature[0])));
    }
    let rest = match initial {
        Some(q) => q.iter().map(|q| q.normalized()).collect(),
        None => model.rest_shape(),
    };
    let mut r = vec![Vector3::zeros(); model.n() + 1];
    model.positions(&rest, &mut model.new_interior(), &mut r);
    let base = r[0];
    let mut moment = rod.end_moment(rest[model.n()]) - rod.point_moment[model.n()];
    for i in 0..model.n() {
        let (mid, h) = (0.5 * (r[i] + r[i + 1]) - base, model.h(i + 1));
        moment += mid.cross(&(rod.distributed[i] * h)) + rod.distributed_moment[i] * h;
        if rod.field != Vector3::zeros() {
            let next = if rest[i].dot(rest[i + 1]) < 0.0 {
                -rest[i + 1]
            } else {
                rest[i + 1]
            };
            let turn = slerp(rest[i], next, 0.5);
            moment += rod.magnetic_moment(i, turn) * h;
        }
    }
    for (node, (p, m)) in rod.point.iter().zip(&rod.point_moment).enumerate() {
        moment += (r[node] - base).cross(p) + m;
    }
    moment + (r[model.n()] - base).cross(&rod.tip_force)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broydens_update_meets_the_secant_and_leaves_a_free_tips_identity() {
        // A free tip's Newton has 3 unknowns in a 6 x 6 matrix: its steps
        // and mismatch are nil in the last three rows, whose identity block
        // must stay for the LU.
        let mut jac = Matrix6::identity();
        jac.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::new(2.0, 0.3, -0.1, 0.4, 1.5, 0.2, -0.2, 0.1, 3.0));
        let before = jac;
        let dx = Vector6::new(0.1, -0.2, 0.05, 0.0, 0.0, 0.0);
        let dr = Vector6::new(0.3, -0.1, 0.2, 0.0, 0.0, 0.0);
        broyden_update(&mut jac, &dx, &dr);
        assert!(
            (jac * dx - dr).amax() < 1e-15,
            "the secant: {}",
            jac * dx - dr
        );
        assert_eq!(
            jac.fixed_view::<3, 3>(3, 3),
            Matrix6::identity().fixed_view::<3, 3>(3, 3)
        );
        assert_eq!(
            jac.fixed_view::<3, 3>(0, 3),
            before.fixed_view::<3, 3>(0, 3)
        );
        assert_eq!(
            jac.fixed_view::<3, 3>(3, 0),
            before.fixed_view::<3, 3>(3, 0)
        );
        // Along directions orthogonal to the step it changes nothing.
        let across = Vector6::new(0.2, 0.1, 0.0, 0.0, 0.0, 0.0);
        assert!(across.dot(&dx).abs() < 1e-15);
        assert!((jac * across - before * across).amax() < 1e-15);
        // A nil step leaves it as it was.
        let mut same = before;
        broyden_update(&mut same, &Vector6::zeros(), &dr);
        assert_eq!(same, before);
    }
}
