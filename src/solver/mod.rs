//! Solvers of the discrete equilibrium. This file is the driver shared by
//! every local method ([`Solver`]: a coarse rod first at large n, a direct
//! attempt from the initial guess, then load continuation from the rest shape,
//! then the Levenberg-Marquardt fallback). One idea a file besides:
//!
//! ```text
//! settings.rs      Settings, Method, the limits and their checks
//! solution.rs      Solution, Status, the judgement of an end state
//! workspace.rs     the buffers of a solve and the LocalSolver interface
//! newton.rs        damped Newton on the block-tridiagonal system
//! lm.rs            Levenberg-Marquardt (dense, faer)
//! constrained.rs   held points: the KKT system by Schur complement
//! mixed.rs         the same system banded, for many contacts
//! continuation.rs  the load path from the rest shape
//! nested.rs        the coarse rod of nested iteration
//! homotopy.rs      a start where the rest shape passes through obstacles
//! adaptive.rs      accuracy on demand
//! sensitivity.rs   the tip's derivatives (implicit function theorem)
//! report.rs        shooting and the paper's method (crate::methods), reported like the others
//! ```

mod adaptive;
mod constrained;
mod contact;
mod continuation;
mod coupled;
mod dense;
mod friction;
mod homotopy;
mod lm;
mod mixed;
mod nested;
mod newton;
mod port;
mod report;
mod sensitivity;
mod settings;
mod solution;
mod workspace;

pub(crate) use crate::read::check_tolerance;
pub use adaptive::{solve_to_accuracy, Accuracy};
pub use contact::Contact;
pub use coupled::CoupledLinearisation;
pub use port::PortReaction;
pub use sensitivity::{DriveParameters, Sensitivity, TipSensitivity};
pub use settings::{
    default_elements, Engine, Local, Method, Settings, DEFAULT_ELEMENTS, MAX_DENSE_ELEMENTS,
    MAX_ELEMENTS, MAX_PAPER_ELEMENTS, RESIDUAL_TOL_RANGE,
};
pub use solution::{Solution, Status, MAX_RESOLVED_TURN};
pub(crate) use workspace::{step_limit, LocalOutcome, LocalSolver, Workspace};

use constrained::Snapshot;
use homotopy::Homotopy;
use solution::judge;
use workspace::residual_norm;
pub(crate) use workspace::{evaluate, is_stable};

use crate::error::{Error, Result};
use crate::interrupt;
use crate::model::{RodModel, Scheme};

use crate::quat::Quat;
use crate::scene::{ReachLimit, Scene};
use nalgebra::Vector3;
use std::time::Instant;

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
    /// The loading's derivative in each tendon's tension (at unit tension:
    /// the tensions do not change it), kept for the IK in tension space; and
    /// in each equal section's rest curvature, for the IK of a pneumatic robot.
    tension_tangents: Vec<crate::disc::Loading>,
    field_tangents: Vec<crate::disc::Loading>,
    curvature_tangents: Vec<crate::disc::Loading>,
    /// The node turns' derivative `d theta_i / d p_j` of the last tip
    /// sensitivity, `n` a column, and the state it was taken at: a tangent
    /// predictor of the equilibrium at moved parameters
    /// ([`Solver::predicted_state`]).
    state_tangents: Vec<Vector3<f64>>,
    state_tangents_at: Vec<Quat>,
    /// The inverse kinematics' coupled iteration's buffers (`coupled.rs`).
    coupled: coupled::CoupledWork,
    /// The workspace's Jacobian is the equations' at the workspace's state
    /// (a free rod's, at full load, of the model as it is), as a stable
    /// direct solve leaves it, or a coupled linearisation at a state that
    /// need not be an equilibrium: the tip sensitivity then needs no assembly,
    /// nor a factorisation if the workspace's is still of it
    /// ([`crate::blocktri::BlockLu::is_factor_of`]). Cleared by every change
    /// of the model, at every solve's start and by the general sensitivity.
    jacobian_at_solution: bool,
    /// The homotopies the last cold solve took to a start, in order, where
    /// its rest shape passes through an obstacle (see `homotopy.rs`).
    homotopies: Vec<Homotopy>,
    /// Where the next warm start's rod stood: its base position, where it
    /// differs from the scene's ([`Solver::solve_after`]). Friction's
    /// history starts there.
    history_base: Option<Vector3<f64>>,
    /// Shooting: where the next solve starts (a coarser solve's base wrench
    /// and Jacobian, set by accuracy on demand), and where the last one
    /// ended, for a finer one.
    pub(crate) warm_shot: Option<crate::methods::shooting::WarmShot>,
    pub(crate) last_shot: Option<crate::methods::shooting::WarmShot>,
}

impl Solver {
    pub fn new(scene: &Scene, settings: Settings) -> Result<Self> {
        let settings = settings.resolved(scene);
        settings.validate()?;
        let n = settings.elements_for(scene);
        scene.check_derived()?;
        scene.check_elements(n)?;
        let reach_limit = scene.check_constraints(n)?;
        // What only the discrete potential models (shooting and the paper's
        // system do not).
        if !settings.method.on_the_potential() {
            let beyond = if settings.method.engine() == Engine::Shooting {
                scene.beyond_shooting()
            } else {
                scene.only_the_potential_models()
            };
            if let Some(what) = beyond {
                return Err(Error::argument(
                    "method",
                    format!(
                        "{} does not model {what}; use 'newton' or 'lm'",
                        settings.method.name()
                    ),
                ));
            }
        }
        if settings.method.engine() == Engine::Shooting && !scene.guides.is_empty() {
            return Err(Error::argument(
                "method",
                "shooting does not support guides (held interior points); use 'newton'",
            ));
        }
        let scheme = settings.scheme_for(scene, None);
        if scene.has_contact() {
            if scheme != Scheme::Fd2 {
                return Err(Error::argument(
                    "scheme",
                    "contact with obstacles or ports is solved by the 'fd2' scheme so far",
                ));
            }
            if settings.method.local() != Local::Newton {
                return Err(Error::argument(
                    "method",
                    "contact with obstacles or ports is solved by 'newton' so far",
                ));
            }
        }
        let model = RodModel::new(scene, n).with_scheme(scheme);
        // A port's load path starts where the rest shape crosses its plane.
        if let Some(i) = model.ports().iter().position(|p| p.rest.is_none()) {
            return Err(Error::scene(
                format!("ports[{i}]"),
                "the rod's rest shape does not pass through the port's plane along its \
                 axis (a port stands ahead of the base, within the rod's reach)",
            ));
        }
        let work = Workspace::new(&model)?;
        let local: Box<dyn LocalSolver + Send + Sync> = match settings.method.local() {
            Local::Newton => Box::new(newton::Newton),
            Local::LevenbergMarquardt => Box::new(lm::LevenbergMarquardt::new(&model)),
        };
        Ok(Solver {
            model,
            settings,
            work,
            local,
            reach_limit,
            scene: scene.clone(),
            tension_tangents: Vec::new(),
            field_tangents: Vec::new(),
            curvature_tangents: Vec::new(),
            state_tangents: Vec::new(),
            state_tangents_at: Vec::new(),
            coupled: coupled::CoupledWork::default(),
            jacobian_at_solution: false,
            homotopies: Vec::new(),
            history_base: None,
            warm_shot: None,
            last_shot: None,
        })
    }

    /// The next equilibrium of a history from `previous` as it stood: warm
    /// from its rotations, and with friction the step starts from its rod
    /// where it was, its base included (a robot fed through a frictional
    /// port: the insertion since `previous` slides the rod through the port
    /// against its friction, where a warm start from the rotations alone
    /// would start the step with the rod already moved). Without friction,
    /// [`Solver::solve`] from its rotations.
    pub fn solve_after(&mut self, previous: &Solution) -> Result<Solution> {
        let base = previous.positions.first().copied();
        self.solve_after_state(&previous.quaternions, base)
    }

    /// [`Solver::solve_after`] from a state given by its rotations and
    /// where its base stood (`None`: where this scene puts it).
    pub fn solve_after_state(
        &mut self,
        quaternions: &[Quat],
        base: Option<Vector3<f64>>,
    ) -> Result<Solution> {
        self.history_base = base;
        let solution = self.solve(Some(quaternions));
        self.history_base = None;
        solution
    }

    pub fn model(&self) -> &RodModel {
        &self.model
    }

    /// Change the actuation (rest curvature per section) without rebuilding the
    /// solver: the next `solve` starts warm from wherever it is told.
    pub fn set_rest_curvature(&mut self, sections: &[[f64; 2]]) -> Result<()> {
        // One row a section of the scene: another count silently redrew the
        // sections (ten became one, and the solve converged on that rod).
        let m = sections.len();
        let expected = self.scene.sections();
        if m != expected {
            return Err(Error::argument(
                "rest_curvature",
                format!("expected one row a section of the scene ({expected}), got {m}"),
            ));
        }
        if sections.iter().flatten().any(|k| !k.is_finite()) {
            return Err(Error::argument("rest_curvature", "must be finite"));
        }
        self.jacobian_at_solution = false;
        self.model.set_section_curvature(sections);
        // The scene too: the paper's method and nested iteration rebuild from it.
        self.scene.rest_curvature = sections.to_vec();
        Ok(())
    }

    /// Change the dead load at the tip (force [N] and moment [N m], world
    /// frame) keeping the workspace: the next `solve` starts wherever it is
    /// told. The discretised loads are rebuilt (O(n)).
    pub fn set_tip_load(&mut self, force: Vector3<f64>, moment: Vector3<f64>) -> Result<()> {
        for (name, v) in [("tip_force", force), ("tip_moment", moment)] {
            if let Some(c) = v.iter().position(|x| !x.is_finite()) {
                return Err(Error::argument(
                    format!("{name}[{c}]"),
                    format!("must be finite, got {}", v[c]),
                ));
            }
        }
        let mut scene = self.scene.clone();
        scene.tip_force = force;
        scene.tip_moment = moment;
        scene.check_derived()?;
        // In place: nothing else of the discretisation depends on them.
        self.scene = scene;
        self.jacobian_at_solution = false;
        self.model.set_tip_load(force, moment);
        self.work.interior.forget();
        Ok(())
    }

    /// Change the tendons' tensions [N] (one each, in the scene's order,
    /// each >= 0) keeping the workspace; the discretised tendons are rebuilt.
    pub fn set_tensions(&mut self, tensions: &[f64]) -> Result<()> {
        self.check_tensions(tensions)?;
        self.scene.check_tension_load(tensions)?;
        // In place: the IK in tension space changes them at every trial.
        for (t, tension) in self.scene.tendons.iter_mut().zip(tensions) {
            t.tension = *tension;
        }
        self.jacobian_at_solution = false;
        self.model.set_tensions(tensions);
        // The interior belonged to the old drives: a fresh start, as a new solver's.
        self.work.interior.forget();
        Ok(())
    }

    /// Move the clamped base to `position` [m], world frame, keeping the
    /// workspace (a robot's insertion: its stage moves the base along its
    /// tangent). A port whose plane the moved rest shape does not cross is
    /// refused, naming it.
    pub fn set_base_position(&mut self, position: Vector3<f64>) -> Result<()> {
        if position.iter().any(|x| !x.is_finite()) {
            return Err(Error::argument("base_position", "must be finite"));
        }
        let before = self.model.base_position();
        // Every batch sample and IK trial sets it: the rest shape is
        // recomputed only when the base moves.
        if position == before {
            return Ok(());
        }
        self.model.set_base_position(position);
        if let Some(i) = self.model.ports().iter().position(|p| p.rest.is_none()) {
            self.model.set_base_position(before);
            return Err(Error::argument(
                "base_position",
                format!("the rod no longer passes through the plane of ports[{i}]"),
            ));
        }
        self.scene.base_position = position;
        self.jacobian_at_solution = false;
        Ok(())
    }

    /// Change the uniform magnetic field [T], world frame, keeping the workspace.
    pub fn set_magnetic_field(&mut self, field: Vector3<f64>) -> Result<()> {
        check_field(field)?;
        self.scene.check_field_load(field)?;
        self.scene.magnetic_field = field;
        self.jacobian_at_solution = false;
        self.model.set_magnetic_field(field);
        self.work.interior.forget();
        Ok(())
    }

    /// Change the rest curvature per section, the tensions (one a tendon)
    /// and the field at once, with one rebuild of the discretised loads:
    /// each checked as by its own setter.
    pub fn set_drives(
        &mut self,
        rest_curvature: &[[f64; 2]],
        tensions: &[f64],
        field: Vector3<f64>,
    ) -> Result<()> {
        self.check_tensions(tensions)?;
        check_field(field)?;
        if rest_curvature.iter().flatten().any(|k| !k.is_finite()) {
            return Err(Error::argument("rest_curvature", "must be finite"));
        }
        let mut scene = self.scene.clone();
        for (t, tension) in scene.tendons.iter_mut().zip(tensions) {
            t.tension = *tension;
        }
        scene.magnetic_field = field;
        scene.rest_curvature = rest_curvature.to_vec();
        scene.check_elements(self.model.n())?;
        self.rebuild(scene)
    }

    fn check_tensions(&self, tensions: &[f64]) -> Result<()> {
        let count = self.scene.tendons.len();
        if tensions.len() != count {
            return Err(Error::argument(
                "tensions",
                format!("expected {count} (one a tendon), got {}", tensions.len()),
            ));
        }
        if let Some(i) = tensions.iter().position(|t| !(t.is_finite() && *t >= 0.0)) {
            return Err(Error::argument(
                format!("tensions[{i}]"),
                format!(
                    "a tendon pulls: must be finite and >= 0 N, got {}",
                    tensions[i]
                ),
            ));
        }
        Ok(())
    }

    /// Take `scene` (the same rod with other loads or actuation): its
    /// discretised loads are rebuilt (O(n)), the workspace kept.
    fn rebuild(&mut self, scene: Scene) -> Result<()> {
        scene.check_derived()?;
        self.jacobian_at_solution = false;
        self.model = RodModel::new(&scene, self.model.n()).with_scheme(self.model.scheme());
        self.work.interior.forget();
        self.tension_tangents.clear();
        self.field_tangents.clear();
        self.curvature_tangents.clear();
        self.scene = scene;
        Ok(())
    }

    /// The scene as the solver holds it (with the last actuation and tip load).
    pub fn scene(&self) -> &Scene {
        &self.scene
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

    /// [`Solver::solve`] from `initial`, redone from the straight rod if a
    /// warm start does not end converged and stable (a far warm start can
    /// fail where the straight rod succeeds).
    pub fn solve_warm_or_cold(&mut self, initial: Option<&[Quat]>) -> Result<Solution> {
        let sol = self.solve(initial)?;
        if initial.is_none() || (sol.converged() && sol.stable) {
            return Ok(sol);
        }
        self.solve(None)
    }

    /// [`Solver::solve_strategy`], where a cold solve's rest shape passes
    /// through an obstacle from a start a homotopy gives (see
    /// `homotopy.rs`): the rod curled to its rest shape from straight,
    /// first with friction (the curl is then its history, the load path
    /// from that rest shape having none) and where the solve fails without;
    /// where that fails too (or the rest shape is straight), frictionless,
    /// the obstacles moved in from where the free equilibrium clears them.
    fn solve_uninterrupted(&mut self, initial: Option<&[Quat]>) -> Result<Solution> {
        self.homotopies.clear();
        let curvature = self.scene.rest_curvature.iter().any(|k| *k != [0.0, 0.0]);
        let friction = self.model.has_friction();
        let through = match initial {
            None if (curvature || !friction) && self.reach_limit.is_none() => {
                self.model.obstacle_at_rest()
            }
            _ => None,
        };
        let Some(obstacle) = through else {
            return self.solve_strategy(initial);
        };
        let first = if friction {
            None
        } else {
            let sol = self.solve_strategy(None)?;
            if sol.converged() && sol.stable {
                return Ok(sol);
            }
            Some(sol)
        };
        // A straight rod through an obstacle too cannot start the curl.
        let curled = if curvature && (friction || self.straight_rod_clears()) {
            self.curl_from_straight(obstacle).ok()
        } else {
            None
        };
        let start = match curled {
            None if !friction => self.approach_obstacles(obstacle).ok(),
            start => start,
        };
        match (start, first) {
            (Some(q), first) => {
                let mut sol = self.solve_strategy(Some(&q))?;
                // The failed cold attempt's iterations count too.
                sol.iterations += first.map_or(0, |f| f.iterations);
                Ok(sol)
            }
            (None, None) => self.solve_strategy(None),
            (None, Some(mut sol)) => {
                // Finished before the homotopies: their notes go on now.
                for homotopy in &self.homotopies {
                    sol.iterations += homotopy.iterations;
                    sol.continuation_steps += homotopy.steps;
                    sol.message.push_str(&homotopy.note());
                }
                Ok(sol)
            }
        }
    }

    /// The solve's strategy: a coarse rod's answer, the direct attempt, the
    /// load path, Levenberg-Marquardt (see `docs/model.md`).
    fn solve_strategy(&mut self, initial: Option<&[Quat]>) -> Result<Solution> {
        let n = self.model.n();
        self.jacobian_at_solution = false;
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
        if let Engine::Paper { literal } = self.settings.method.engine() {
            return self.solve_paper(literal);
        }
        let tol = self.model.effective_tol(self.settings.residual_tol);
        let (model, w) = (&self.model, &mut self.work);
        w.reached_load = 0.0;
        w.kkt.clear_multipliers();
        // Friction's relaxed levels are this solve's own: a solve before
        // that needed them must not start this one there.
        w.kkt.contact.friction.forget_levels();
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
        if self.settings.method.engine() == Engine::Shooting {
            return Ok(self.solve_shooting(initial));
        }
        if initial.is_none() && model.is_trivial() {
            // Nothing loads the rod: the rest shape is exact, no iteration needed.
            w.q.copy_from_slice(&model.rest_shape());
            evaluate(model, w, 1.0);
            return Ok(self.finish(Ending::Exact, 0, 0));
        }
        let budget = self.settings.max_iterations;
        let mut spent = 0;
        // With friction the answer is the end of a history: a cold solve's
        // is the load path from the rest shape (see `friction.rs`), so it
        // is neither started from a coarser rod nor tried directly.
        let follow_path = initial.is_none() && self.model.has_friction();
        if initial.is_none() && !follow_path {
            if let Some(n0) =
                nested::coarse_elements(&self.scene, &self.settings, self.model.load_parameter())
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
                w.q[0] = model.base();
                for (dst, src) in w.q.iter_mut().zip(q).skip(1) {
                    *dst = src.normalized();
                }
            }
            None => w.q.copy_from_slice(&model.initial_guess()),
        }
        w.kkt.clear_multipliers();
        if model.has_friction() {
            // A warm start's history starts at its shape: its contacts stick
            // there, where it stood (`solve_after`).
            w.saved.copy_from_slice(&w.q);
            let moved = match (initial, self.history_base) {
                (Some(_), Some(base)) => base - model.base_position(),
                _ => Vector3::zeros(),
            };
            friction::anchor_at_saved_moved(model, w, moved);
        }
        // Among obstacles only (nothing held, no friction, whose history
        // starts at rest), Newton may start from the free equilibrium.
        let among_obstacles = model.has_obstacles()
            && !model.has_friction()
            && model.constraints().is_empty()
            && model.clamped_tip().is_none()
            && model.ports().is_empty();
        if initial.is_none()
            && among_obstacles
            && self.settings.method.engine() == Engine::Potential(Local::Newton)
        {
            let budget = ((budget - spent).min(DIRECT_ITERATIONS), tol);
            spent += contact::start_from_free_equilibrium(model, w, budget);
        }
        let direct = if follow_path {
            LocalOutcome {
                converged: false,
                iterations: 0,
            }
        } else {
            self.local
                .attempt(model, w, 1.0, (budget - spent).min(DIRECT_ITERATIONS), tol)
        };
        let mut iterations = spent + direct.iterations;
        if direct.converged && is_stable(model, w) {
            // The local method leaves the Jacobian at its answer (see
            // `LocalSolver`); a free rod's is the equations' own.
            self.jacobian_at_solution = !model.is_constrained();
            return Ok(self.finish(Ending::DirectStable, iterations, 0));
        }
        // The direct attempt failed or found an unstable equilibrium: follow the
        // load path from the rest shape, which stays on the stable branch.
        let direct_state = direct.converged.then(|| Snapshot::take(w));
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
        let path_state = (cont.converged && direct_state.is_none()).then(|| Snapshot::take(w));
        // Newton's undamped steps can fail where Levenberg-Marquardt's damping
        // gets there: held points that only a strongly bent (buckled) rod
        // reaches, torsion far stiffer than bending. LM is dense, so it is only
        // a fallback, and only for moderate n. It shares the iteration budget.
        if self.settings.method.engine() == Engine::Potential(Local::Newton)
            && direct_state.is_none()
            && !model.has_contact()
            && 3 * (model.n() + model.constraints().len()) <= LM_FALLBACK_UNKNOWNS
        {
            let mut lm = lm::LevenbergMarquardt::new(model);
            w.q.copy_from_slice(&model.initial_guess());
            w.kkt.clear_multipliers();
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
            if let Some(state) = state {
                state.restore(w);
                evaluate(model, w, 1.0);
                return Ok(self.finish(ending, iterations, steps));
            }
        }
        let mut msg = format!(
            "no convergence: the direct solve and load continuation (stopped after {steps} steps \
             at load scale {:.3} of 1) both failed; the loads bend the rod to a curvature scale \
             kappa L = {:.2e}",
            w.reached_load,
            model.load_parameter()
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
        let slack = self.scene.reach_slack(model.n());
        if slack < DISCRETE_REACH_NOTE {
            let finer = 4 * model.n();
            msg.push_str(&format!(
                "; it is only {slack:.1e} of its span inside the farthest that {} elements reach \
                 (the clamped end cannot straighten within an element): {finer} elements leave \
                 {:.1e}",
                model.n(),
                self.scene.reach_slack(finer)
            ));
        }
        Ok(self.finish(Ending::Failed(msg), iterations, steps))
    }

    /// Build the Solution from the workspace (residual and Jacobian at `w.q` are current).
    fn finish(&mut self, ending: Ending, iterations: usize, continuation_steps: usize) -> Solution {
        let (model, w) = (&self.model, &mut self.work);
        let residual_norm = residual_norm(model, w);
        let mut positions = vec![Vector3::zeros(); model.n() + 1];
        model.positions(&w.q, &mut w.interior, &mut positions);
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
        let (mut iterations, mut continuation_steps) = (iterations, continuation_steps);
        for homotopy in &self.homotopies {
            iterations += homotopy.iterations;
            continuation_steps += homotopy.steps;
            message.push_str(&homotopy.note());
        }
        if let Some(note) = note {
            message = note;
        }
        let reactions = &w.kkt.reactions;
        let tip_held = model
            .constraints()
            .last()
            .is_some_and(|c| c.node == model.n());
        let guides = model.constraints().len() - usize::from(tip_held);
        let tip_q = w.q[model.n()];
        let tip_reaction_moment = model.clamped_tip().map(|_| tip_q.rotate(w.kkt.tip_torque));
        Solution {
            n_elements: model.n(),
            scheme: model.scheme(),
            length: model.length(),
            section_lengths: self.scene.section_lengths(),
            quaternions: w.q.clone(),
            positions,
            internal_quaternions: model.internal_nodes(&w.q, &mut w.interior),
            breaks: Some(model.breaks().to_vec()),
            forces: if model.has_contact() {
                model.internal_forces(w.kkt.contact.node_forces())
            } else {
                model.node_forces(reactions)
            },
            stiffness: model.stiffness(),
            rest_curvature: self.scene.rest_curvature.clone(),
            section_stiffness: (0..self.scene.sections.len())
                .map(|k| self.scene.section_stiffness(k))
                .collect(),
            tip_moment: model.tip_moment(),
            tip_reaction_force: tip_held.then(|| reactions[guides]),
            tip_reaction_moment,
            guide_reactions: reactions[..guides].to_vec(),
            contacts: contact::contacts(model, w),
            ports: port::reactions(model, w),
            status,
            iterations,
            continuation_steps,
            residual_norm,
            energy: model.energy(&w.q, &mut w.interior),
            stable,
            message,
            error_estimate: None,
            extrapolated_tip: None,
            solve_time: 0.0,
        }
    }
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
    solve_from(scene, settings, initial, None)
}

/// [`solve`] as the next equilibrium of a history from `previous` (see
/// [`Solver::solve_after`]: with friction, the step starts from its rod
/// where it stood, its base included).
pub fn solve_after(scene: &Scene, settings: Settings, previous: &Solution) -> Result<Solution> {
    solve_from(scene, settings, Some(&previous.quaternions), Some(previous))
}

fn solve_from(
    scene: &Scene,
    mut settings: Settings,
    initial: Option<&[Quat]>,
    previous: Option<&Solution>,
) -> Result<Solution> {
    let started = Instant::now();
    // A warm start brings its own n where none is asked for (a solution of
    // accuracy on demand, at the n it chose, warm-starts the next solve).
    let nodes = initial
        .filter(|_| settings.n_elements.is_none())
        .map(<[Quat]>::len);
    if let Some(nodes) = nodes {
        settings.n_elements = Some(nodes.saturating_sub(1));
    }
    let mut solver = Solver::new(scene, settings).map_err(|e| match (e, nodes) {
        (Error::InvalidArgument { name, reason }, Some(nodes)) if name == "n_elements" => {
            Error::argument(
                "initial",
                format!(
                    "has {nodes} nodes, {} elements: {reason}",
                    nodes.saturating_sub(1)
                ),
            )
        }
        (e, _) => e,
    })?;
    let mut solution = match previous {
        Some(previous) => solver.solve_after(previous)?,
        None => solver.solve(initial)?,
    };
    solution.solve_time = started.elapsed().as_secs_f64();
    Ok(solution)
}

/// Refuse a field with a component that is not finite, naming it.
fn check_field(field: Vector3<f64>) -> Result<()> {
    match field.iter().position(|x| !x.is_finite()) {
        Some(c) => Err(Error::argument(
            format!("magnetic_field[{c}]"),
            format!("must be finite, got {}", field[c]),
        )),
        None => Ok(()),
    }
}
