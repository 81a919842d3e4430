//! Solvers of the discrete equilibrium: settings, the result type, and the
//! driver shared by every local method (a direct attempt from the initial
//! guess, then load continuation from the rest shape when that fails).

mod adaptive;
mod constrained;
mod continuation;
mod lm;
mod nested;
mod newton;
mod settings;

pub use adaptive::{solve_to_accuracy, Accuracy};
pub(crate) use settings::check_tolerance;
pub use settings::{
    default_elements, Method, Settings, DEFAULT_ELEMENTS, MAX_DENSE_ELEMENTS, MAX_ELEMENTS,
    MAX_PAPER_ELEMENTS, RESIDUAL_TOL_RANGE,
};

use crate::blocktri::{symmetric_part_is_positive_definite, BlockLu, BlockTridiagonal};
use crate::error::{Error, Result};
use crate::interrupt;
use crate::model::RodModel;
use crate::paper_method::solve_paper;
use crate::quat::Quat;
use crate::scene::{ReachLimit, Scene};
use nalgebra::{Matrix3, Vector3};
use std::time::Instant;

/// How a solve ended. Only `Converged` is an answer; every other ending
/// carries the best state reached, its residual and a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The relative residual is below `residual_tol`, the state is finite and
    /// every element turns within what the scheme resolves.
    Converged,
    /// The methods stalled before the iteration budget ran out: the line
    /// search or the load continuation (below `min_continuation_step`) could
    /// not progress, or the paper's method ended above its tolerance.
    NotConverged,
    /// The iteration budget (`max_iterations`) ran out before convergence.
    IterationLimit,
    /// Accuracy on demand stopped at its largest `n` with the error estimate
    /// above the tolerance (the state is a converged equilibrium at that `n`).
    ToleranceNotMet,
    /// The discrete rod cannot follow the shape; solve with more elements.
    /// Either an equilibrium whose elements turn by more than
    /// [`MAX_RESOLVED_TURN`] (a coiled rod folds onto itself), or, not
    /// attempted, a held point beyond the discrete rod's reach (see
    /// [`crate::model::clamped_end_deficit`]).
    Underresolved,
    /// The state or the residual is not finite (an overflow).
    NumericalError,
    /// Not attempted: the scene has no well-defined answer (a held point
    /// within [`crate::scene::FULL_REACH_BAND`] of full reach, whose reaction
    /// is indeterminate or unbounded).
    Indeterminate,
}

impl Status {
    /// Every status, in the order of the declaration.
    pub const ALL: [Status; 7] = [
        Status::Converged,
        Status::NotConverged,
        Status::IterationLimit,
        Status::ToleranceNotMet,
        Status::Underresolved,
        Status::NumericalError,
        Status::Indeterminate,
    ];

    /// The snake_case name used by the Python API and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Status::Converged => "converged",
            Status::NotConverged => "not_converged",
            Status::IterationLimit => "iteration_limit",
            Status::ToleranceNotMet => "tolerance_not_met",
            Status::Underresolved => "underresolved",
            Status::NumericalError => "numerical_error",
            Status::Indeterminate => "indeterminate",
        }
    }
}

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
    /// Length of the rod [m]: node `i` sits at arc length `i L / n`.
    pub length: f64,
    /// Node quaternions `q_0..q_n`, `q_0` the base.
    pub quaternions: Vec<Quat>,
    /// Node positions `r_0..r_n` [m], `r_0` the scene's base position.
    pub positions: Vec<Vector3<f64>>,
    /// Internal force at the nodes, world frame [N] (force the distal part exerts on the proximal one).
    pub forces: Vec<Vector3<f64>>,
    /// Curvature and twist of each element in its own (material) frame
    /// [1/m], `n` entries: `(2/ds) vec(conj(q_{i-1}) q_i)`, the scheme's
    /// discrete curvature (see [`RodModel::curvatures_and_moments`]).
    pub curvatures: Vec<Vector3<f64>>,
    /// Internal moment at the nodes, world frame [N m]: the moment the distal
    /// part exerts on the proximal one (`moments[0]` is the moment of the rod
    /// on its base support; see [`RodModel::curvatures_and_moments`]).
    pub moments: Vec<Vector3<f64>>,
    /// Force that a pinned or clamped tip's support exerts on the rod, world frame [N].
    pub tip_reaction_force: Option<Vector3<f64>>,
    /// Moment that a clamped tip's support exerts on the rod, world frame [N m].
    pub tip_reaction_moment: Option<Vector3<f64>>,
    /// Force of each guide on the rod, in the scene's order, world frame [N].
    pub guide_reactions: Vec<Vector3<f64>>,
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
    /// the continuous rod's [m], over the whole backbone (from the solves at
    /// n/2 and n, second order).
    pub error_estimate: Option<f64>,
    /// Accuracy on demand with Richardson extrapolation: `(4 r_n - r_{n/2}) / 3`,
    /// returned by [`Solution::tip_position`] in place of the last node.
    pub extrapolated_tip: Option<Vector3<f64>>,
    /// Wall-clock time of the solve [s], the set-up of the discretisation
    /// included (every n of accuracy on demand).
    pub solve_time: f64,
}

impl Solution {
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

    /// Arc length of the nodes, `s_i = i L / n` [m].
    pub fn arc_length(&self) -> Vec<f64> {
        let n = self.n_elements as f64;
        (0..=self.n_elements)
            .map(|i| self.length * i as f64 / n)
            .collect()
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
            ("moments", self.moments.len(), n + 1),
            ("curvatures", self.curvatures.len(), n),
        ] {
            if len != expected {
                return Err(Error::argument(
                    format!("solution.{name}"),
                    format!("has {len} rows, n_elements = {n} needs {expected}"),
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

/// Buffers of one solve, allocated once and reused by warm-started solves.
#[derive(Debug, Clone)]
pub(crate) struct Workspace {
    pub q: Vec<Quat>,
    pub trial: Vec<Quat>,
    pub saved: Vec<Quat>,
    pub g: Vec<Vector3<f64>>,
    pub g_trial: Vec<Vector3<f64>>,
    pub step: Vec<Vector3<f64>>,
    pub scratch: Vec<Vector3<f64>>,
    pub jac: BlockTridiagonal,
    pub lu: BlockLu,
    /// Constrained scenes only (empty otherwise): see `constrained.rs`.
    pub kkt: constrained::KktWorkspace,
}

impl Workspace {
    /// Allocated fallibly and between interrupt polls (about 0.5 KB a node).
    fn new(model: &RodModel) -> Result<Self> {
        let n = model.n;
        let nodes = || interrupt::filled(n + 1, model.base, "workspace");
        let vectors = || interrupt::filled(n, Vector3::zeros(), "workspace");
        Ok(Workspace {
            q: nodes()?,
            trial: nodes()?,
            saved: nodes()?,
            g: vectors()?,
            g_trial: vectors()?,
            step: vectors()?,
            scratch: vectors()?,
            jac: BlockTridiagonal::try_zeros(n)?,
            lu: BlockLu::try_new(n)?,
            kkt: constrained::KktWorkspace::new(model),
        })
    }
}

/// Result of one local solve at a fixed load scale.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LocalOutcome {
    pub converged: bool,
    pub iterations: usize,
}

/// A local method: drive `w.q` to an equilibrium at load scale `lambda`.
/// On return `w.g` and `w.jac` hold the residual and Jacobian at `w.q`.
pub(crate) trait LocalSolver {
    fn run(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome;

    /// A direct attempt from an arbitrary start (the initial guess, a warm
    /// start), with load continuation as the fallback: it may give up as soon
    /// as it stops making progress. By default the same as `run`.
    fn attempt(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome {
        self.run(model, w, lambda, max_iter, tol)
    }

    /// The same method, with its buffers sized for `model`.
    fn for_model(&self, model: &RodModel) -> Box<dyn LocalSolver + Send + Sync>;
}

/// A reusable solver of one scene at one discretisation: build it once, call
/// [`Solver::solve`] many times (warm starts cost no allocation in the core).
pub struct Solver {
    model: RodModel,
    settings: Settings,
    work: Workspace,
    local: Box<dyn LocalSolver + Send + Sync>,
    /// Why the scene cannot be solved as posed (a held point at full reach).
    reach_limit: Option<ReachLimit>,
    /// The scene itself, for the paper's method (which builds its own system).
    scene: Scene,
}

impl Solver {
    pub fn new(scene: &Scene, settings: Settings) -> Result<Self> {
        let settings = settings.resolved(scene);
        settings.validate()?;
        let n = settings.elements_for(scene);
        scene.check_derived()?;
        scene.check_elements(n)?;
        let reach_limit = scene.check_constraints(n)?;
        let model = RodModel::new(scene, n);
        let work = Workspace::new(&model)?;
        let local: Box<dyn LocalSolver + Send + Sync> = match settings.method {
            Method::Newton => Box::new(newton::Newton),
            Method::LevenbergMarquardt | Method::Paper | Method::PaperLiteral => {
                Box::new(lm::LevenbergMarquardt::new(&model))
            }
        };
        Ok(Solver {
            model,
            settings,
            work,
            local,
            reach_limit,
            scene: scene.clone(),
        })
    }

    pub fn model(&self) -> &RodModel {
        &self.model
    }

    /// Change the actuation (rest curvature per section) without rebuilding the
    /// solver: the next `solve` starts warm from wherever it is told.
    pub fn set_rest_curvature(&mut self, sections: &[[f64; 2]]) -> Result<()> {
        let m = sections.len();
        if m == 0 || self.model.n % m != 0 {
            return Err(Error::argument(
                "rest_curvature",
                format!("{m} sections do not divide the {} elements", self.model.n),
            ));
        }
        if sections.iter().flatten().any(|k| !k.is_finite()) {
            return Err(Error::argument("rest_curvature", "must be finite"));
        }
        self.model.set_section_curvature(sections);
        // The scene too: the paper's method and nested iteration rebuild from it.
        self.scene.rest_curvature = sections.to_vec();
        Ok(())
    }

    /// Sensitivity of the tip of the last (converged, free-tip) equilibrium to the
    /// rest curvature of each of `sections` equal sections: columns `2s` and
    /// `2s + 1` are `d/d kappa_x` and `d/d kappa_y` of section `s`. Costs two
    /// O(n) back-substitutions a column with the Jacobian already factored.
    pub fn tip_sensitivity(&mut self, sections: usize) -> Result<TipSensitivity> {
        let n = self.model.n;
        if self.model.is_constrained() {
            return Err(Error::argument("tip_sensitivity", "needs a free tip"));
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

    /// Solve from `initial` (node quaternions `q_0..q_n`; `q_0` is replaced by the
    /// base) or from the straight rod (a clamped tip: the rod turning uniformly to
    /// the tip orientation). Errors only on invalid `initial`; otherwise the
    /// Solution's status says how the solve ended.
    pub fn solve(&mut self, initial: Option<&[Quat]>) -> Result<Solution> {
        let started = Instant::now();
        let solution = self.solve_uninterrupted(initial);
        // An interrupt winds every loop down; its partial state is no answer.
        interrupt::check()?;
        let mut solution = solution?;
        solution.solve_time = started.elapsed().as_secs_f64();
        Ok(solution)
    }

    fn solve_uninterrupted(&mut self, initial: Option<&[Quat]>) -> Result<Solution> {
        let n = self.model.n;
        if let Some(q) = initial {
            if q.len() != n + 1 {
                return Err(Error::argument(
                    "initial",
                    format!("has {} nodes, the discretisation has {}", q.len(), n + 1),
                ));
            }
            if q.iter()
                .any(|x| !x.to_array().iter().all(|v| v.is_finite()) || x.norm() < 1e-6)
            {
                return Err(Error::argument(
                    "initial",
                    "quaternions must be finite and non-zero",
                ));
            }
        }
        if matches!(self.settings.method, Method::Paper | Method::PaperLiteral) {
            return self.solve_paper();
        }
        let tol = self.model.effective_tol(self.settings.residual_tol);
        let (model, w) = (&self.model, &mut self.work);
        w.kkt
            .reactions
            .iter_mut()
            .for_each(|r| *r = Vector3::zeros());
        if let Some(limit) = &self.reach_limit {
            w.q.copy_from_slice(&model.initial_guess());
            evaluate(model, w, 1.0);
            let ending = match limit {
                ReachLimit::FullReach(reason) => {
                    Ending::Refused(Status::Indeterminate, format!("not solved: {reason}"))
                }
                ReachLimit::BeyondDiscreteReach(reason) => Ending::Refused(
                    Status::Underresolved,
                    format!("underresolved, not solved: {reason}"),
                ),
            };
            return Ok(self.finish(ending, 0, 0));
        }
        if initial.is_none() && model.is_trivial() {
            // Nothing loads the rod: the rest shape is exact, no iteration needed.
            w.q.copy_from_slice(&model.rest_shape());
            evaluate(model, w, 1.0);
            return Ok(self.finish(Ending::Exact, 0, 0));
        }
        let budget = self.settings.max_iterations;
        let mut spent = 0;
        if initial.is_none() {
            if let Some(n0) =
                nested::coarse_elements(&self.scene, &self.settings, self.model.load_parameter)
            {
                let nested = self.start_from_coarse(n0, budget, tol)?;
                if nested.converged {
                    let ending = Ending::FromCoarse {
                        coarse_elements: n0,
                        stable: nested.stable,
                    };
                    return Ok(self.finish(ending, nested.iterations, nested.continuation_steps));
                }
                // The full strategy on this rod, with what is left.
                spent = nested.iterations.min(budget);
            }
        }
        let (model, w) = (&self.model, &mut self.work);
        match initial {
            Some(q) => {
                w.q[0] = model.base;
                for (dst, src) in w.q.iter_mut().zip(q).skip(1) {
                    *dst = src.normalized();
                }
            }
            None => w.q.copy_from_slice(&model.initial_guess()),
        }
        w.kkt
            .reactions
            .iter_mut()
            .for_each(|r| *r = Vector3::zeros());
        let direct =
            self.local
                .attempt(model, w, 1.0, (budget - spent).min(DIRECT_ITERATIONS), tol);
        let mut iterations = spent + direct.iterations;
        if direct.converged && is_stable(model, w) {
            return Ok(self.finish(Ending::DirectStable, iterations, 0));
        }
        // The direct attempt failed or found an unstable equilibrium: follow the
        // load path from the rest shape, which stays on the stable branch.
        let direct_state = direct
            .converged
            .then(|| (w.q.clone(), w.kkt.reactions.clone()));
        let remaining = budget - iterations.min(budget);
        let min_step = self.settings.min_continuation_step;
        let (cont, steps) =
            continuation::load_path(self.local.as_mut(), model, w, tol, remaining, min_step);
        iterations += cont.iterations;
        // Continuation is there to find the stable branch. A free rod's load
        // path ends unstable only where the loading itself loses stability,
        // so that end stands unless a direct answer (the caller's warm
        // start's neighbourhood) does. A held scene's path moves its held
        // points along an arbitrary route: an unstable end of it is kept as
        // a candidate while the LM fallback looks for a stable equilibrium.
        if cont.converged
            && ((direct_state.is_none() && !model.is_constrained()) || is_stable(model, w))
        {
            return Ok(self.finish(Ending::Continuation, iterations, steps));
        }
        let path_state = (cont.converged && direct_state.is_none())
            .then(|| (w.q.clone(), w.kkt.reactions.clone()));
        // Newton's undamped steps can fail where Levenberg-Marquardt's damping
        // gets there: held points that only a strongly bent (buckled) rod
        // reaches, torsion far stiffer than bending. LM is dense, so it is only
        // a fallback, and only for moderate n. It shares the iteration budget.
        if self.settings.method == Method::Newton
            && direct_state.is_none()
            && 3 * (model.n + model.constraints.len()) <= LM_FALLBACK_UNKNOWNS
        {
            let mut lm = lm::LevenbergMarquardt::new(model);
            w.q.copy_from_slice(&model.initial_guess());
            w.kkt
                .reactions
                .iter_mut()
                .for_each(|r| *r = Vector3::zeros());
            let direct = lm.run(model, w, 1.0, budget - iterations.min(budget), tol);
            iterations += direct.iterations;
            if direct.converged && is_stable(model, w) {
                return Ok(self.finish(Ending::LmFallback, iterations, steps));
            }
            let remaining = budget - iterations.min(budget);
            let (out, lm_steps) =
                continuation::load_path(&mut lm, model, w, tol, remaining, min_step);
            iterations += out.iterations;
            if out.converged && (path_state.is_none() || is_stable(model, w)) {
                return Ok(self.finish(Ending::LmFallback, iterations, steps + lm_steps));
            }
        }
        for (state, ending) in [
            (path_state, Ending::Continuation),
            (direct_state, Ending::DirectUnstable),
        ] {
            if let Some((q, reactions)) = state {
                w.q.copy_from_slice(&q);
                w.kkt.reactions.copy_from_slice(&reactions);
                evaluate(model, w, 1.0);
                return Ok(self.finish(ending, iterations, steps));
            }
        }
        let mut msg = format!(
            "no convergence: the direct solve and load continuation (stopped after {steps} steps) both failed"
        );
        let reach = model.tightest_reach();
        if reach > 0.98 {
            msg.push_str(&format!(
                "; a held point is at {:.1} % of its reach, which only a very strained rod attains",
                100.0 * reach
            ));
        }
        // Just inside what the n elements reach, the rod is strained to its
        // limit: a finer rod reaches further and has slack to spare.
        let slack = self.scene.reach_slack(model.n);
        if slack < DISCRETE_REACH_NOTE {
            let finer = 4 * model.n;
            msg.push_str(&format!(
                "; it is only {slack:.1e} of its span inside the farthest that {} elements reach \
                 (the clamped end cannot straighten within an element): {finer} elements leave \
                 {:.1e}",
                model.n,
                self.scene.reach_slack(finer)
            ));
        }
        Ok(self.finish(Ending::Failed(msg), iterations, steps))
    }

    /// The seed paper's method (see `paper_method`); its answer is reported with
    /// the model's residual and stability at the renormalised quaternions.
    fn solve_paper(&mut self) -> Result<Solution> {
        let literal = self.settings.method == Method::PaperLiteral;
        if let Some(ReachLimit::FullReach(reason) | ReachLimit::BeyondDiscreteReach(reason)) =
            &self.reach_limit
        {
            return Err(Error::argument("tip", reason.clone()));
        }
        let out = solve_paper(&self.scene, self.model.n, &self.settings.paper, literal)?;
        let (model, w) = (&self.model, &mut self.work);
        for (dst, src) in w.q.iter_mut().zip(&out.quaternions) {
            *dst = src.normalized();
        }
        w.q[0] = model.base;
        let n = model.n;
        if let Some(r) = w.kkt.reactions.last_mut() {
            *r = out.forces[n] - self.scene.tip_force;
        }
        evaluate(model, w, 1.0);
        // The literal system is solved when its rows vanish, but a drifted |q| is
        // no equilibrium of the rod: never report that as converged.
        let drifted = out.max_norm_deviation > 1e-8;
        let converged = out.converged && !drifted;
        let message = if out.converged && drifted {
            format!(
                "not an equilibrium: the literal system's rows vanish (largest {:.1e}) but |q| drifted from 1 by up to {:.3}",
                out.residual_norm, out.max_norm_deviation
            )
        } else {
            format!(
                "{}; max | |q| - 1 | = {:.2e}",
                out.message, out.max_norm_deviation
            )
        };
        // The method's verdict covers its own residual (the paper's rows).
        let verdict = if converged {
            Ok(())
        } else {
            Err(Status::NotConverged)
        };
        let (status, note) = judge(
            model,
            &out.quaternions,
            &out.positions,
            out.residual_norm,
            verdict,
            f64::INFINITY,
        );
        let message = note.unwrap_or(message);
        let stable = status == Status::Converged && is_stable(model, w);
        let tip_held = model.constraints.last().is_some_and(|c| c.node == n);
        let tip_reaction_moment = model.clamped_tip.map(|_| w.q[n].rotate(w.kkt.tip_torque));
        let (curvatures, moments) = model.curvatures_and_moments(
            &out.quaternions,
            model.tip_moment + tip_reaction_moment.unwrap_or_default(),
        );
        Ok(Solution {
            n_elements: n,
            length: model.length,
            quaternions: out.quaternions.clone(),
            positions: out.positions,
            forces: out.forces.clone(),
            curvatures,
            moments,
            tip_reaction_force: tip_held.then(|| out.forces[n] - self.scene.tip_force),
            tip_reaction_moment,
            guide_reactions: Vec::new(),
            status,
            iterations: out.pso_iterations + out.lm_iterations,
            continuation_steps: 0,
            residual_norm: out.residual_norm,
            energy: model.energy(&out.quaternions),
            stable,
            message,
            error_estimate: None,
            extrapolated_tip: None,
            solve_time: 0.0,
        })
    }

    /// Build the Solution from the workspace (residual and Jacobian at `w.q` are current).
    fn finish(&mut self, ending: Ending, iterations: usize, continuation_steps: usize) -> Solution {
        let (model, w) = (&self.model, &mut self.work);
        let residual_norm = residual_norm(model, w);
        let mut positions = vec![Vector3::zeros(); model.n + 1];
        model.positions(&w.q, &mut positions);
        let solved = match &ending {
            Ending::Refused(status, _) => Err(*status),
            Ending::Failed(_) if iterations >= self.settings.max_iterations => {
                Err(Status::IterationLimit)
            }
            Ending::Failed(_) => Err(Status::NotConverged),
            _ => Ok(()),
        };
        let (status, note) = judge(
            model,
            &w.q,
            &positions,
            residual_norm,
            solved,
            model.effective_tol(self.settings.residual_tol),
        );
        let converged = status == Status::Converged;
        let stable = converged
            && match ending {
                Ending::DirectStable => true,
                Ending::FromCoarse { stable, .. } => stable,
                _ => is_stable(model, w),
            };
        let mut message = ending.message();
        if converged && !stable && ending != Ending::DirectUnstable {
            message.push_str(" (unstable equilibrium)");
        }
        if let Some(note) = note {
            message = note;
        }
        let reactions = &w.kkt.reactions;
        let tip_held = model.constraints.last().is_some_and(|c| c.node == model.n);
        let guides = model.constraints.len() - usize::from(tip_held);
        let tip_q = w.q[model.n];
        let tip_reaction_moment = model.clamped_tip.map(|_| tip_q.rotate(w.kkt.tip_torque));
        let (curvatures, moments) = model.curvatures_and_moments(
            &w.q,
            model.tip_moment + tip_reaction_moment.unwrap_or_default(),
        );
        Solution {
            n_elements: model.n,
            length: model.length,
            quaternions: w.q.clone(),
            positions,
            forces: model.node_forces(reactions),
            curvatures,
            moments,
            tip_reaction_force: tip_held.then(|| reactions[guides]),
            tip_reaction_moment,
            guide_reactions: reactions[..guides].to_vec(),
            status,
            iterations,
            continuation_steps,
            residual_norm,
            energy: model.energy(&w.q),
            stable,
            message,
            error_estimate: None,
            extrapolated_tip: None,
            solve_time: 0.0,
        }
    }
}

/// The one judgement of every method's end state: `solved` is the method's own
/// verdict (`Err` with the status of its failure). A converged answer must
/// also be finite, meet the residual tolerance and be resolved by the scheme.
/// Returns the status and, where the judgement overrules the method, the
/// message that says why.
fn judge(
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
        let needed = (model.n as f64 * turn / MAX_RESOLVED_TURN).ceil();
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

/// Derivatives of the tip of an equilibrium with respect to the actuation.
#[derive(Debug, Clone)]
pub struct TipSensitivity {
    /// `d r_tip / d kappa` [m^2], 3 x 2m.
    pub position: nalgebra::Matrix3xX<f64>,
    /// `d T_tip / d kappa` (tip tangent) [m], 3 x 2m.
    pub tangent: nalgebra::Matrix3xX<f64>,
}

/// How a solve ended (the Solution's message says it in words).
#[derive(Debug, Clone, PartialEq)]
enum Ending {
    /// Nothing loads the rod: the rest shape, without iterating.
    Exact,
    /// The direct solve converged to an equilibrium already tested stable.
    DirectStable,
    /// Load continuation from the rest shape converged.
    Continuation,
    /// Levenberg-Marquardt converged after Newton failed (held points).
    LmFallback,
    /// Only the direct solve converged, to an unstable equilibrium.
    DirectUnstable,
    /// Newton from the equilibrium of a coarse rod (nested iteration)
    /// converged next to it; its stability already tested.
    FromCoarse {
        coarse_elements: usize,
        stable: bool,
    },
    /// Not attempted: the scene has no well-defined answer.
    Refused(Status, String),
    Failed(String),
}

impl Ending {
    fn message(&self) -> String {
        match self {
            Ending::Exact => "unloaded: the rest shape, exact without iteration".into(),
            Ending::DirectStable => "converged".into(),
            Ending::Continuation => "converged by load continuation".into(),
            Ending::LmFallback => "converged (Levenberg-Marquardt fallback)".into(),
            Ending::DirectUnstable => "converged (unstable equilibrium)".into(),
            Ending::FromCoarse {
                coarse_elements, ..
            } => format!("converged from the equilibrium at n = {coarse_elements}"),
            Ending::Refused(_, m) | Ending::Failed(m) => m.clone(),
        }
    }
}

/// Residual and Jacobian at the workspace state, free or constrained.
fn evaluate(model: &RodModel, w: &mut Workspace, lambda: f64) {
    if model.is_constrained() {
        constrained::evaluate(model, w, lambda, true);
    } else {
        model.residual_jacobian(&w.q, lambda, &mut w.g, &mut w.jac);
    }
}

fn residual_norm(model: &RodModel, w: &Workspace) -> f64 {
    if model.is_constrained() {
        constrained::residual_norm(model, w)
    } else {
        model.residual_norm(&w.g)
    }
}

fn is_stable(model: &RodModel, w: &mut Workspace) -> bool {
    if model.is_constrained() {
        constrained::is_stable(model, w)
    } else {
        symmetric_part_is_positive_definite(&w.jac)
    }
}

/// A failed held scene whose slack to the discrete reach (see
/// [`Scene::reach_slack`]) is below this says so.
const DISCRETE_REACH_NOTE: f64 = 1e-3;

/// Largest system (unknowns) that a failed Newton solve retries with dense LM.
const LM_FALLBACK_UNKNOWNS: usize = 600;

/// Iteration limit of the direct attempt.
const DIRECT_ITERATIONS: usize = 60;

/// Solve a scene once (see [`Solver`] to reuse the workspace).
/// `solve_time` counts the set-up of the discretisation.
pub fn solve(scene: &Scene, settings: Settings, initial: Option<&[Quat]>) -> Result<Solution> {
    let started = Instant::now();
    let mut solution = Solver::new(scene, settings)?.solve(initial)?;
    solution.solve_time = started.elapsed().as_secs_f64();
    Ok(solution)
}

/// Scale the step so that no node turns by more than `max_node` and no element
/// by more than `max_element` radians in one update (keeps `conj(a) b` far from
/// the antipodal branch of the curvature formula).
pub(crate) fn step_limit(step: &[Vector3<f64>], max_node: f64, max_element: f64) -> f64 {
    let mut limit = 1.0f64;
    let mut prev = Vector3::zeros();
    for d in step {
        let node = d.norm();
        if node > max_node {
            limit = limit.min(max_node / node);
        }
        let rel = (d - prev).norm();
        if rel > max_element {
            limit = limit.min(max_element / rel);
        }
        prev = *d;
    }
    limit
}
