//! Inverse kinematics of tendon-driven and magnetic robots: the tendon
//! tensions, or the uniform field, whose *loaded* equilibrium puts the tip
//! (or the tool's point) at the target, and optionally along a direction.
//!
//! Each iteration solves the forward statics (warm) and takes the tip's
//! sensitivity to the actuation from the factored equilibrium Jacobian: for
//! the tensions of a free tip from the tendons' analytic derivatives
//! ([`Solver::tension_sensitivity`], one back-substitution a tendon), else by
//! [`Solver::sensitivity_with`]. Then:
//!
//! * Far from the target (more than `POLISH_RADIUS` L): Levenberg-Marquardt
//!   steps on the tip error inside the drives' limits (`0 <= t <= max_tension`,
//!   `|B| <= max_field`), the damping adapted as a trust region; only
//!   converged, stable equilibria are accepted.
//! * Near it, the minimum-norm step. Tensions: the minimiser of `|t - p|^2`
//!   (`p` the pretension, default zero) over the tensions that reach the
//!   linearised target `J t = e + J t_k`, a small QP solved exactly through its
//!   dual `t = clip(p + J^T y)` by semismooth Newton, and backtracked on the
//!   merit `|t - p|^2 / 2 + rho |e|`. At a fixed point the tip is on target and
//!   `t = clip(p + J^T y)` with `J` the sensitivity *there*: the KKT conditions
//!   of the minimum-norm choice on the nonlinear problem. Field: the smallest
//!   field among those that reach the linearised target.
//! * A descent that gains too little for `SLOW_STEPS` steps is at the closest
//!   tip: `bounds_active` if a drive at its limit holds it back, else
//!   `out_of_reach` (a magnet at the tip of a passive rod only turns it, and
//!   its tips form a surface).

use super::ik::{tool_point, IkEnding, IkResult};
use super::{Actuation, Robot};
use crate::error::{Error, Result};
use crate::quat::skew;
use crate::quat::Quat;
use crate::solver::{Settings, Solution, Solver};
use nalgebra::{DMatrix, DVector, Vector3};

/// Relative accuracy to which the tensions are the minimum-norm choice.
const MIN_NORM_ACCURACY: f64 = 1e-6;

/// Shortest line-search step of a minimum-norm step.
const MIN_ALPHA: f64 = 1e-4;

/// Levenberg-Marquardt damping, relative to the largest diagonal entry of
/// `J^T J`: at the first step, at most, and where the descent gives up.
const LM_START: f64 = 1e-3;
const LM_SMALLEST: f64 = 1e-12;
const LM_GIVE_UP: f64 = 1e10;

/// Tip error [relative to L] from which the minimum-norm steps take over.
const POLISH_RADIUS: f64 = 1e-3;

/// The damped descent is at the closest tip after `SLOW_STEPS` accepted
/// steps in a row that each shrink the miss by less than `SLOW_GAIN` of it.
const SLOW_GAIN: f64 = 0.01;
const SLOW_STEPS: usize = 4;

/// At the closest tip, how much a minimum-norm step may grow the miss.
const LEVEL_SLACK: f64 = 1e-6;

/// Starts tried, after the last answer, when a descent ends short of the
/// target: the middle of the drives' range, then seeded points drawn in it.
/// A descent from slack stalled on 38 of 150 reachable targets of the
/// example tendon robot, its tensions pressed to 0 and `max_tension` far
/// from the generating ones (tools/reach_campaign.py); 4 starts left 8
/// unreached, 10 leave 2.
const RESTARTS: usize = 10;

/// Stages of the continuation in the target tried last (from the slack
/// robot's tip), when no start reaches.
const TARGET_STAGES: usize = 4;

/// Gradient of the dual QP, relative to the target's scale, at which a
/// semismooth Newton iteration that can no longer progress has its answer
/// (the outer iteration's tip tolerance is 3e-9 of the robot's length).
const DUAL_ROUNDOFF: f64 = 1e-10;

/// Iterations of the dual QP's semismooth Newton method (it ends when its
/// active set repeats, in a few for a handful of tendons).
const DUAL_ITERATIONS: usize = 100;

/// What an inverse solve searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActuationSpace {
    /// The muscles' rest curvature per section (pneumatic robots).
    Curvature,
    /// The tendons' tensions.
    Tensions,
    /// The uniform external magnetic field.
    Field,
}

impl ActuationSpace {
    /// The snake_case name used by the Python API.
    pub fn name(self) -> &'static str {
        match self {
            ActuationSpace::Curvature => "curvature",
            ActuationSpace::Tensions => "tensions",
            ActuationSpace::Field => "field",
        }
    }
}

/// The tip goal of one solve: position, and optionally direction.
struct Goal {
    target: Vector3<f64>,
    direction: Option<Vector3<f64>>,
    tol: f64,
    length: f64,
    /// The point aimed, from the tip in its frame (the tool's; zero: the tip).
    offset: Vector3<f64>,
}

impl Goal {
    /// Position error, then (with a direction) the direction's error in the
    /// plane across the tip tangent, weighted by `L`.
    fn error(&self, sol: &Solution) -> DVector<f64> {
        let mut e = DVector::zeros(if self.direction.is_some() { 5 } else { 3 });
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

    fn reached(&self, e: &DVector<f64>) -> bool {
        e.rows(0, 3).norm() <= self.tol && (e.len() == 3 || e.rows(3, 2).norm() <= self.tol)
    }

    /// The rows of [`Goal::error`] differentiated (negated) from the tip's
    /// sensitivities: its position and its turn (a world rotation vector),
    /// one column a parameter. The aimed point moves with the turn too,
    /// `phi x (R c)`; the direction's rows are the turn across the tangent.
    fn jacobian(
        &self,
        sol: &Solution,
        position: &nalgebra::Matrix3xX<f64>,
        rotation: &nalgebra::Matrix3xX<f64>,
    ) -> DMatrix<f64> {
        let k = position.ncols();
        let mut jac = DMatrix::zeros(if self.direction.is_some() { 5 } else { 3 }, k);
        let arm = sol.tip_quaternion().rotate(self.offset);
        jac.rows_mut(0, 3)
            .copy_from(&(position - skew(&arm) * rotation));
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

/// An accepted point of the descent: a converged, stable equilibrium.
struct State {
    x: DVector<f64>,
    sol: Solution,
    e: DVector<f64>,
}

impl State {
    /// Whether its equilibrium may serve as an answer and a warm start (an
    /// ending may return a state that is not).
    fn usable(&self) -> bool {
        self.sol.converged() && self.sol.stable
    }

    /// How far the tip is from the target [m].
    fn miss(&self) -> f64 {
        self.e.rows(0, 3).norm()
    }
}

/// Inverse kinematics of a tendon-driven or magnetic robot under one tip
/// mass, reusing its forward solver and the last answer as the warm start of
/// the next (trajectories).
pub struct ActuatedInverseSolver {
    robot: Robot,
    space: ActuationSpace,
    solver: Solver,
    /// The last answer's actuation and equilibrium.
    x: DVector<f64>,
    q: Option<Vec<Quat>>,
    iterations: usize,
    /// Whether the last answer's minimum-norm refinement stalled.
    unrefined: bool,
}

impl ActuatedInverseSolver {
    /// The solver of `robot`'s own space ([`Robot::actuation_space`]: tensions
    /// if it has tendons, else the field); a pneumatic robot has
    /// [`super::InverseSolver`].
    pub fn new(robot: &Robot, tip_mass: f64) -> Result<Self> {
        let space = robot.actuation_space();
        let variables =
            match space {
                ActuationSpace::Tensions => robot.tendons.len(),
                ActuationSpace::Field => 3,
                ActuationSpace::Curvature => return Err(Error::argument(
                    "robot",
                    "has neither tendons nor magnets: its inverse kinematics is in curvature space",
                )),
            };
        let scene = robot.actuated_scene(&Actuation::default(), tip_mass)?;
        let settings = Settings {
            n_elements: Some(robot.n_elements),
            residual_tol: 1e-12,
            ..Settings::default()
        };
        Ok(ActuatedInverseSolver {
            robot: robot.clone(),
            space,
            solver: Solver::new(&scene, settings)?,
            x: DVector::zeros(variables),
            q: None,
            iterations: 0,
            unrefined: false,
        })
    }

    /// The robot it inverts.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    pub fn space(&self) -> ActuationSpace {
        self.space
    }

    /// Start the next solve from an earlier answer's equilibrium and actuation.
    pub fn warm_start(&mut self, start: &super::IkStart) -> Result<()> {
        if let Some(x) = &start.actuation {
            if x.len() != self.x.len() {
                return Err(Error::argument(
                    "initial",
                    format!(
                        "has {} actuation values, the robot's {} space {}",
                        x.len(),
                        self.space.name(),
                        self.x.len()
                    ),
                ));
            }
            match self.space {
                ActuationSpace::Tensions => self.robot.check_actuation(x, Vector3::zeros())?,
                _ => self
                    .robot
                    .check_actuation(&[], Vector3::new(x[0], x[1], x[2]))?,
            }
            self.x = DVector::from_column_slice(x);
        }
        self.q = Some(start.quaternions.clone());
        Ok(())
    }

    /// Forward statics at `x`, warm from the last accepted state.
    fn forward(&mut self, x: &DVector<f64>) -> Result<Solution> {
        match self.space {
            ActuationSpace::Tensions => self.solver.set_tensions(x.as_slice())?,
            _ => self
                .solver
                .set_magnetic_field(Vector3::new(x[0], x[1], x[2]))?,
        }
        self.solver.solve_warm_or_cold(self.q.as_deref())
    }

    /// Rows of the goal's error differentiated in the actuation, at the
    /// solver's (accepted) state; `None` at a bifurcation.
    fn jacobian(&mut self, goal: &Goal, sol: &Solution) -> Option<DMatrix<f64>> {
        let (position, rotation) =
            if self.space == ActuationSpace::Tensions && !self.solver.model().is_constrained() {
                // Tensions enter the equations linearly: their columns in closed
                // form, one back-substitution each.
                let sens = self.solver.tension_sensitivity().ok()?;
                (sens.position, sens.rotation)
            } else {
                // The scene's own values: each through its term's derivative.
                let names = (0..self.x.len())
                    .map(|j| match self.space {
                        ActuationSpace::Tensions => format!("tendons[{j}].tension"),
                        _ => format!("magnetic_field[{j}]"),
                    })
                    .collect();
                let scene = self.solver.scene().clone();
                let space = self.space;
                let values: Vec<f64> = match space {
                    ActuationSpace::Tensions => scene.tendons.iter().map(|t| t.tension).collect(),
                    _ => scene.magnetic_field.iter().copied().collect(),
                };
                let sens = self
                    .solver
                    .sensitivity_of_paths(names, &values, |j, delta| {
                        let mut moved = scene.clone();
                        match space {
                            ActuationSpace::Tensions => moved.tendons[j].tension += delta,
                            _ => moved.magnetic_field[j] += delta,
                        }
                        Ok(moved)
                    })
                    .ok()?;
                (sens.tip_position, sens.tip_rotation)
            };
        Some(goal.jacobian(sol, &position, &rotation))
    }

    /// The tensions (or field) whose loaded equilibrium puts the tip at
    /// `target` (and along `direction`), starting from the last answer.
    /// Tensions: the one closest to `pretension` (default zero).
    pub fn solve(
        &mut self,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        pretension: Option<&[f64]>,
        tol: f64,
        max_iterations: usize,
    ) -> Result<IkResult> {
        let started = std::time::Instant::now();
        let goal = self.goal(target, direction, tol)?;
        let pull = self.pull(pretension)?;
        self.iterations = 0;
        self.unrefined = false;
        let (mut state, mut ending) = self.descend(&goal, &pull, max_iterations)?;
        let (mut spent, mut starts, mut unrefined) = (self.iterations, 1, self.unrefined);
        let restarts = match ending {
            IkEnding::Reached => Vec::new(),
            _ => self.restarts(&target),
        };
        for start in restarts {
            if ending == IkEnding::Reached {
                break;
            }
            self.x = start;
            self.q = None;
            self.iterations = 0;
            self.unrefined = false;
            let (other, other_ending) = self.descend(&goal, &pull, max_iterations)?;
            spent += self.iterations;
            starts += 1;
            let better = match (
                other_ending == IkEnding::Reached,
                other.usable(),
                state.usable(),
            ) {
                (true, true, _) => true,
                (false, true, true) => other.miss() < state.miss(),
                (false, true, false) => true,
                _ => false,
            };
            if better {
                (state, ending, unrefined) = (other, other_ending, self.unrefined);
            }
        }
        if ending != IkEnding::Reached {
            // Continuation in the target, from the slack robot's tip.
            let (other, other_ending, used) =
                self.follow_target(&pull, target, direction, tol, max_iterations)?;
            spent += used;
            starts += 1;
            if other_ending == IkEnding::Reached && other.usable() {
                (state, ending, unrefined) = (other, other_ending, self.unrefined);
            }
        }
        self.iterations = spent;
        self.unrefined = unrefined;
        let reach = self.robot.length + self.robot.tool_offset.norm();
        let beyond = (target - self.robot.base_position).norm() > reach;
        if beyond && ending != IkEnding::Reached {
            ending = IkEnding::OutOfReach;
        }
        let mut result = self.conclude(state, ending);
        result.starts = starts;
        result.seconds = started.elapsed().as_secs_f64();
        Ok(result)
    }

    /// Descents to targets on the straight line from the slack robot's tip to
    /// `target`, each from the last one's answer ([`TARGET_STAGES`] of them):
    /// the last stage's state and ending, and the iterations spent.
    fn follow_target(
        &mut self,
        pull: &DVector<f64>,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        tol: f64,
        max_iterations: usize,
    ) -> Result<(State, IkEnding, usize)> {
        let k = self.x.len();
        self.q = None;
        let slack = self.forward(&DVector::zeros(k))?;
        let from = tool_point(&slack, self.robot.tool_offset);
        self.x = DVector::zeros(k);
        let mut spent = 0;
        let mut last = None;
        for stage in 1..=TARGET_STAGES {
            let along = stage as f64 / TARGET_STAGES as f64;
            let staged = match stage {
                TARGET_STAGES => self.goal(target, direction, tol)?,
                _ => self.goal(from + along * (target - from), direction, tol)?,
            };
            self.iterations = 0;
            self.unrefined = false;
            let (state, ending) = self.descend(&staged, pull, max_iterations)?;
            spent += self.iterations;
            if !state.usable() || (stage < TARGET_STAGES && ending != IkEnding::Reached) {
                return Ok((state, ending, spent));
            }
            self.x = state.x.clone();
            self.q = Some(state.sol.quaternions.clone());
            last = Some((state, ending));
        }
        let (state, ending) = last.expect("at least one stage");
        Ok((state, ending, spent))
    }

    /// The starts after the last answer ([`RESTARTS`]): the middle of the
    /// tensions' range (or the zero field), then points drawn uniformly in
    /// the range (the ball of fields), seeded by the target so that an answer
    /// depends on nothing else. None without a bounded range.
    fn restarts(&self, target: &Vector3<f64>) -> Vec<DVector<f64>> {
        use rand::{RngExt, SeedableRng};
        let k = self.x.len();
        let seed = target.iter().fold(0x9e37_79b9_7f4a_7c15u64, |h, x| {
            h.rotate_left(17) ^ x.to_bits()
        });
        let mut rng = rand::rngs::SmallRng::seed_from_u64(seed);
        match self.space {
            ActuationSpace::Tensions => {
                let Some(upper) = self.robot.max_tension else {
                    return Vec::new();
                };
                let mut starts = vec![DVector::from_element(k, 0.5 * upper)];
                starts.extend(
                    (1..RESTARTS).map(|_| DVector::from_fn(k, |_, _| upper * rng.random::<f64>())),
                );
                starts
            }
            _ => {
                let Some(limit) = self.robot.max_field else {
                    return Vec::new();
                };
                let mut starts = vec![DVector::zeros(k)];
                starts.extend((1..RESTARTS).map(|_| {
                    // Uniform in the ball: a direction and radius^(1/3).
                    let v = Vector3::from_fn(|_, _| rng.random::<f64>() * 2.0 - 1.0);
                    let radius = limit * rng.random::<f64>().cbrt();
                    DVector::from_column_slice((v.normalize() * radius).as_slice())
                }));
                starts
            }
        }
    }

    /// [`ActuatedInverseSolver::solve`] with the direction, pretension and
    /// settings of `options`.
    pub fn solve_with(
        &mut self,
        target: Vector3<f64>,
        options: &super::IkOptions,
    ) -> Result<IkResult> {
        self.solve(
            target,
            options.direction,
            options.pretension.as_deref(),
            options.settings.tol,
            options.settings.max_iterations,
        )
    }

    fn goal(
        &self,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        tol: f64,
    ) -> Result<Goal> {
        if target.iter().any(|x| !x.is_finite()) {
            return Err(Error::argument("target", "must be finite"));
        }
        let length = self.robot.length;
        crate::read::check_tolerance("tol", tol, (1e-12 * length, 1e-2 * length))?;
        let direction = match direction {
            Some(d) if d.iter().all(|x| x.is_finite()) && d.norm() > 0.0 => Some(d.normalize()),
            Some(_) => {
                return Err(Error::argument(
                    "direction",
                    "must be a finite non-zero vector",
                ))
            }
            None => None,
        };
        Ok(Goal {
            target,
            direction,
            tol,
            length,
            offset: self.robot.tool_offset,
        })
    }

    /// The point the minimum-norm choice is pulled to (tensions) or from
    /// (zero field).
    fn pull(&self, pretension: Option<&[f64]>) -> Result<DVector<f64>> {
        let k = self.x.len();
        match (pretension, self.space) {
            (None, _) => Ok(DVector::zeros(k)),
            (Some(_), ActuationSpace::Field) => Err(Error::argument(
                "pretension",
                "a magnetic robot has no tendons to pretension",
            )),
            (Some(p), _) => {
                self.robot
                    .check_actuation(p, Vector3::zeros())
                    .map_err(|e| match e {
                        Error::InvalidArgument { name, reason } => {
                            Error::argument(name.replacen("tensions", "pretension", 1), reason)
                        }
                        other => other,
                    })?;
                if p.len() != k {
                    return Err(Error::argument(
                        "pretension",
                        format!("expected one a tendon ({k}), got {}", p.len()),
                    ));
                }
                Ok(DVector::from_column_slice(p))
            }
        }
    }

    /// Accept `x` if its equilibrium is converged and stable.
    fn try_state(&mut self, goal: &Goal, x: DVector<f64>) -> Result<Option<State>> {
        let sol = self.forward(&x)?;
        if !(sol.converged() && sol.stable) {
            return Ok(None);
        }
        let e = goal.error(&sol);
        Ok(Some(State { x, sol, e }))
    }

    /// From the last answer: Levenberg-Marquardt steps on the tip error
    /// (damping adapted as a trust region) until the tip is near the target,
    /// then, for tensions, the minimum-norm steps (see the module's notes).
    fn descend(
        &mut self,
        goal: &Goal,
        pull: &DVector<f64>,
        max_iterations: usize,
    ) -> Result<(State, IkEnding)> {
        let k = self.x.len();
        let start = self.x.clone();
        let mut state = match self.try_state(goal, start)? {
            Some(s) => s,
            None => {
                // The last answer's equilibrium is gone (another load?): from slack.
                self.q = None;
                match self.try_state(goal, DVector::zeros(k))? {
                    Some(s) => s,
                    None => {
                        let sol = self.forward(&DVector::zeros(k))?;
                        let e = goal.error(&sol);
                        let x = DVector::zeros(k);
                        return Ok((State { x, sol, e }, IkEnding::SolverFailure));
                    }
                }
            }
        };
        self.q = Some(state.sol.quaternions.clone());
        let mut damping = LM_START;
        let mut unusable = false;
        let mut jac = None;
        // Accepted damped steps in a row that each gained less than SLOW_GAIN.
        let mut slow = 0;
        loop {
            let reached = goal.reached(&state.e);
            if self.iterations >= max_iterations {
                let ending = if reached {
                    IkEnding::Reached
                } else {
                    IkEnding::IterationLimit
                };
                return Ok((state, ending));
            }
            if jac.is_none() {
                jac = self.jacobian(goal, &state.sol);
            }
            let Some(j) = jac.as_ref() else {
                return Ok((state, IkEnding::SolverFailure));
            };
            let b = &state.e + j * &state.x;
            let near = state.e.norm() <= POLISH_RADIUS * goal.length;
            let stalled = slow >= SLOW_STEPS;
            if near || stalled {
                // The minimum-norm choice among the actuations that reach
                // the (linearised) target, or come closest to it.
                if let Some((y, multiplier)) = self.min_norm_step(j, &b, pull) {
                    let d = &y - &state.x;
                    let settled = d.norm() <= MIN_NORM_ACCURACY * state.x.norm().max(y.norm());
                    if settled && (reached || stalled) {
                        let ending = if reached {
                            IkEnding::Reached
                        } else {
                            self.blocked_ending(&state.x, j, &state.e)
                        };
                        return Ok((state, ending));
                    }
                    self.iterations += 1;
                    if let Some(next) =
                        self.merit_search(goal, &state, &y, &multiplier, pull, stalled)?
                    {
                        state = next;
                        jac = None;
                        continue;
                    }
                }
                if reached || stalled {
                    // On target (or at the closest tip), the pull toward the
                    // minimum norm is blocked.
                    self.unrefined = true;
                    let ending = if reached {
                        IkEnding::Reached
                    } else {
                        self.blocked_ending(&state.x, j, &state.e)
                    };
                    return Ok((state, ending));
                }
            }
            // A damped step on the tip error alone.
            let y = match self.space {
                ActuationSpace::Tensions => {
                    let upper = self.robot.max_tension.unwrap_or(f64::INFINITY);
                    lm_step_in_box(j, &b, &state.x, upper, damping)
                }
                _ => {
                    let limit = self.robot.max_field.unwrap_or(f64::INFINITY);
                    lm_step_in_ball(j, &b, &state.x, limit, damping)
                }
            };
            let d = &y - &state.x;
            if d.norm() <= 1e-15 * state.x.norm() || damping > LM_GIVE_UP {
                let ending = if reached {
                    IkEnding::Reached
                } else if unusable && damping > LM_GIVE_UP {
                    IkEnding::SolverFailure
                } else {
                    self.blocked_ending(&state.x, j, &state.e)
                };
                self.forward(&state.x.clone())?;
                return Ok((state, ending));
            }
            self.iterations += 1;
            match self.try_state(goal, y)? {
                Some(next) if next.e.norm() < state.e.norm() => {
                    let gain = 1.0 - next.e.norm() / state.e.norm();
                    slow = if gain < SLOW_GAIN { slow + 1 } else { 0 };
                    self.q = Some(next.sol.quaternions.clone());
                    state = next;
                    jac = None;
                    damping = (damping / 3.0).max(LM_SMALLEST);
                    unusable = false;
                }
                trial => {
                    unusable |= trial.is_none();
                    damping *= 4.0;
                    // The solver's state is the trial's; the Jacobian kept is
                    // the accepted state's.
                }
            }
        }
    }

    /// The minimum-norm step of the space and its multiplier, `None` where
    /// it has none: the tensions closest to the pull that reach `J t = b`
    /// (see [`min_norm_in_box`]); the smallest field among those that come
    /// closest to it (`B = J^T y`), inside `|B| <= max_field`.
    fn min_norm_step(
        &self,
        jac: &DMatrix<f64>,
        b: &DVector<f64>,
        pull: &DVector<f64>,
    ) -> Option<(DVector<f64>, DVector<f64>)> {
        match self.space {
            ActuationSpace::Tensions => {
                let upper = self.robot.max_tension.unwrap_or(f64::INFINITY);
                min_norm_in_box(jac, b, pull, upper)
            }
            _ => {
                let cut = 1e-9 * jac.amax();
                let gram = jac * jac.transpose();
                let y = gram.svd(true, true).solve(b, cut * cut).ok()?;
                let field = jac.transpose() * &y;
                let limit = self.robot.max_field.unwrap_or(f64::INFINITY);
                (field.norm() <= limit).then_some((field, y))
            }
        }
    }

    /// A minimum-norm step from `state` toward `target` (multiplier `y`),
    /// backtracked on the merit `|x - p|^2 / 2 + rho |e|` with `rho` twice
    /// the multiplier: it may trade some miss for a smaller norm, which the
    /// next steps restore. At the closest tip (`level`) the miss is the
    /// least the drives reach: there a step must keep it. Only converged,
    /// stable equilibria are accepted; the solver is left at the accepted
    /// state (or back at `state`).
    fn merit_search(
        &mut self,
        goal: &Goal,
        state: &State,
        target: &DVector<f64>,
        y: &DVector<f64>,
        pull: &DVector<f64>,
        level: bool,
    ) -> Result<Option<State>> {
        let d = target - &state.x;
        let rho = 2.0 * y.norm() + f64::MIN_POSITIVE;
        let merit =
            |x: &DVector<f64>, e: &DVector<f64>| 0.5 * (x - pull).norm_squared() + rho * e.norm();
        let miss = state.e.norm();
        let phi = merit(&state.x, &state.e);
        let slope = (&state.x - pull).dot(&d) - rho * miss;
        let mut alpha = 1.0;
        while alpha >= MIN_ALPHA {
            let x = &state.x + &d * alpha;
            if let Some(next) = self.try_state(goal, x)? {
                let new_miss = next.e.norm();
                let accept = if level {
                    new_miss < (1.0 - 1e-4 * alpha) * miss
                        || (new_miss <= (1.0 + LEVEL_SLACK) * miss
                            && (&next.x - pull).norm() < (&state.x - pull).norm())
                } else {
                    merit(&next.x, &next.e) <= phi + 1e-4 * alpha * slope.min(0.0)
                        && (new_miss < miss || goal.reached(&next.e) || slope < 0.0)
                };
                if accept {
                    self.q = Some(next.sol.quaternions.clone());
                    return Ok(Some(next));
                }
            }
            alpha *= 0.5;
        }
        self.forward(&state.x.clone())?;
        Ok(None)
    }

    /// Why a descent that cannot move misses: a drive at its limit holds it
    /// back (the error's descent direction `J^T e` points out of the
    /// admissible set there), or no admissible actuation brings the tip closer.
    fn blocked_ending(&self, x: &DVector<f64>, jac: &DMatrix<f64>, e: &DVector<f64>) -> IkEnding {
        let descent = jac.transpose() * e;
        let scale = descent.amax();
        let pushed = match self.space {
            ActuationSpace::Tensions => {
                let upper = self.robot.max_tension.unwrap_or(f64::INFINITY);
                (0..x.len()).any(|i| {
                    (x[i] <= 0.0 && descent[i] < -1e-6 * scale)
                        || (x[i] >= upper && descent[i] > 1e-6 * scale)
                })
            }
            _ => self.robot.max_field.is_some_and(|limit| {
                x.norm() >= limit * (1.0 - 1e-9) && descent.dot(x) > 1e-6 * scale * x.norm()
            }),
        };
        if pushed {
            IkEnding::BoundsActive
        } else {
            IkEnding::OutOfReach
        }
    }

    fn conclude(&mut self, state: State, ending: IkEnding) -> IkResult {
        let usable = state.usable();
        self.q = usable.then(|| state.sol.quaternions.clone());
        if usable {
            self.x = state.x.clone();
        }
        let miss = state.miss();
        let message = self.message(ending, miss, &state.x);
        let kappa = vec![[0.0; 2]; self.robot.sections];
        let lengths = self.robot.muscle_lengths(&kappa);
        let (tensions, field) = match self.space {
            ActuationSpace::Tensions => (state.x.iter().copied().collect(), Vector3::zeros()),
            _ => (Vec::new(), Vector3::new(state.x[0], state.x[1], state.x[2])),
        };
        IkResult {
            inflation_times: self.robot.inflation_times(&lengths),
            muscle_lengths: lengths,
            rest_curvature: kappa,
            tensions,
            field,
            tip_position: tool_point(&state.sol, self.robot.tool_offset),
            solution: state.sol,
            tip_miss: miss,
            reached: ending == IkEnding::Reached,
            ending,
            message,
            iterations: self.iterations,
            starts: 1,
            seconds: 0.0,
        }
    }

    fn message(&self, ending: IkEnding, miss: f64, x: &DVector<f64>) -> String {
        let (drive, limit) = match self.space {
            ActuationSpace::Tensions => (
                "tensions",
                "tendons at zero tension or at max_tension hold it back",
            ),
            _ => ("field", "the field is at max_field"),
        };
        match ending {
            IkEnding::Reached => {
                let choice = match (self.space, self.unrefined) {
                    (ActuationSpace::Tensions, false) => "the least, in norm, that reach it",
                    (ActuationSpace::Tensions, true) => {
                        "they reach it; the refinement toward the least norm stalled"
                    }
                    (_, false) => "the smallest that reaches it",
                    (_, true) => "it reaches it; the refinement toward the smallest stalled",
                };
                match self.space {
                    ActuationSpace::Tensions => {
                        format!("reached with tensions of {:.6} N in all ({choice})", x.sum())
                    }
                    _ => format!("reached with a field of {:.6} T ({choice})", x.norm()),
                }
            }
            IkEnding::OutOfReach => format!(
                "not reached: no {drive} put the tip closer; the closest tip found misses by {miss:.3e} m"
            ),
            IkEnding::BoundsActive => format!(
                "not reached: {limit}; the closest tip found misses by {miss:.3e} m"
            ),
            IkEnding::SolverFailure => format!(
                "not reached: the forward solver found no stable equilibrium where the descent had to go; the closest tip found misses by {miss:.3e} m"
            ),
            IkEnding::IterationLimit => format!(
                "not reached after {} iterations: the tip misses by {miss:.3e} m and was still closing in (raise max_iterations)",
                self.iterations
            ),
            IkEnding::LoadIgnored => unreachable!("no geometric strategy in {drive} space"),
        }
    }
}

/// The minimiser of `|t - p|^2` over `J t = b`, `0 <= t <= upper`, with the
/// multiplier `y` of `J t = b`, or `None` when no such `t` exists (to the
/// round-off of the dual's gradient).
///
/// Through the dual: `t(y) = clip(p + J^T y)` and the concave dual's
/// gradient is `b - J t(y)`. Semismooth Newton on `y` with the generalised
/// Hessian `J_F J_F^T` (the free tensions' columns) and an Armijo search on
/// the dual objective; an infeasible primal sends the dual to infinity.
pub(crate) fn min_norm_in_box(
    jac: &DMatrix<f64>,
    b: &DVector<f64>,
    p: &DVector<f64>,
    upper: f64,
) -> Option<(DVector<f64>, DVector<f64>)> {
    let (rows, k) = jac.shape();
    let clip = |z: f64| z.clamp(0.0, upper);
    // The primal Psi(z) whose derivative is clip(z).
    let psi = |z: f64| {
        if z <= 0.0 {
            0.0
        } else if z <= upper {
            0.5 * z * z
        } else {
            upper * z - 0.5 * upper * upper
        }
    };
    let dual = |y: &DVector<f64>| -> f64 {
        let z = p + jac.transpose() * y;
        z.iter().map(|z| psi(*z)).sum::<f64>() - b.dot(y)
    };
    let scale = b.norm() + (jac * p.map(clip)).norm();
    if scale == 0.0 {
        return Some((p.map(clip), DVector::zeros(rows)));
    }
    let gram_scale = (jac * jac.transpose()).diagonal().max();
    if gram_scale.is_nan() || gram_scale <= 0.0 {
        return None;
    }
    let mut y = DVector::zeros(rows);
    for _ in 0..DUAL_ITERATIONS {
        let z = p + jac.transpose() * &y;
        let t = z.map(clip);
        let grad = jac * &t - b;
        if grad.norm() <= 1e-13 * scale {
            return Some((t, y));
        }
        let mut hess = DMatrix::<f64>::identity(rows, rows) * (1e-13 * gram_scale);
        // At a kink (z = 0: a tension about to engage) the element of the
        // generalised Hessian that counts the tendon keeps the step finite.
        for c in (0..k).filter(|&c| z[c] >= 0.0 && z[c] <= upper) {
            let col = jac.column(c);
            hess += col * col.transpose();
        }
        let step = hess.cholesky()?.solve(&(-&grad));
        // The full step where it shrinks the gradient (near the answer the
        // dual's own decrease drowns in its round-off), else Armijo on the dual.
        let full = &y + &step;
        let full_grad = jac * (p + jac.transpose() * &full).map(clip) - b;
        if full_grad.norm() < 0.5 * grad.norm() {
            y = full;
            continue;
        }
        let f0 = dual(&y);
        let slope = grad.dot(&step);
        let mut alpha = 1.0;
        loop {
            let trial = &y + &step * alpha;
            if dual(&trial) < f0 + 1e-4 * alpha * slope {
                y = trial;
                break;
            }
            alpha *= 0.5;
            if alpha < 1e-12 {
                // No progress left: the answer if the gradient is at the
                // level of the dual's round-off.
                return (grad.norm() <= DUAL_ROUNDOFF * scale).then_some((t, y));
            }
        }
        // An unbounded dual: no admissible tensions reach the target.
        if (jac.transpose() * &y).amax() > 1e12 * (p.amax() + scale / gram_scale.sqrt()) {
            return None;
        }
    }
    None
}

/// A Levenberg-Marquardt step toward `J x = b` from `x0`, inside
/// `0 <= x <= upper`: the minimiser of `|J x - b|^2 + mu |x - x0|^2` over the
/// box (`mu` is `damping` times the largest diagonal entry of `J^T J`), by
/// projected Newton with the box's active set (Bertsekas). Worked in the
/// step `delta = x - x0`, so that the objective's decrease is resolved down
/// to the last digits of the tip error.
pub(crate) fn lm_step_in_box(
    jac: &DMatrix<f64>,
    b: &DVector<f64>,
    x0: &DVector<f64>,
    upper: f64,
    damping: f64,
) -> DVector<f64> {
    let k = x0.len();
    let jtj = jac.transpose() * jac;
    let mu = damping * jtj.diagonal().max().max(f64::MIN_POSITIVE);
    let hess = &jtj + DMatrix::<f64>::identity(k, k) * mu;
    // The steepest descent of the miss at x0: J^T (b - J x0).
    let pull = jac.transpose() * (b - jac * x0);
    let objective = |d: &DVector<f64>| 0.5 * d.dot(&(&hess * d)) - pull.dot(d);
    let (lo, hi) = (-x0, x0.map(|t| upper - t));
    let mut d = DVector::<f64>::zeros(k);
    for _ in 0..(10 * k + 20) {
        let grad = &hess * &d - &pull;
        let free: Vec<usize> = (0..k)
            .filter(|&i| !((d[i] <= lo[i] && grad[i] > 0.0) || (d[i] >= hi[i] && grad[i] < 0.0)))
            .collect();
        if free.is_empty() {
            break;
        }
        let sub = DMatrix::from_fn(free.len(), free.len(), |r, s| hess[(free[r], free[s])]);
        let rhs = DVector::from_fn(free.len(), |r, _| -grad[free[r]]);
        let Some(chol) = sub.cholesky() else { break };
        let dir = chol.solve(&rhs);
        if dir.amax() <= 1e-15 * d.amax() {
            break;
        }
        let f0 = objective(&d);
        let mut alpha = 1.0;
        let mut moved = false;
        while alpha > 1e-12 {
            let mut trial = d.clone();
            for (r, &i) in free.iter().enumerate() {
                trial[i] = (d[i] + alpha * dir[r]).clamp(lo[i], hi[i]);
            }
            if objective(&trial) < f0 {
                d = trial;
                moved = true;
                break;
            }
            alpha *= 0.5;
        }
        if !moved {
            break;
        }
    }
    // On the bounds exactly where the step took a tension to them.
    (x0 + d).map(|t| t.clamp(0.0, upper))
}

/// A Levenberg-Marquardt step toward `J x = b` from `x0` inside the ball
/// `|x| <= limit`: `(J^T J + mu I + nu I) x = J^T b + mu x0` with the
/// smallest `nu >= 0` that keeps `x` in the ball (found by bisection).
pub(crate) fn lm_step_in_ball(
    jac: &DMatrix<f64>,
    b: &DVector<f64>,
    x0: &DVector<f64>,
    limit: f64,
    damping: f64,
) -> DVector<f64> {
    let k = x0.len();
    let jtj = jac.transpose() * jac;
    let mu = damping * jtj.diagonal().max().max(f64::MIN_POSITIVE);
    let rhs = jac.transpose() * b + x0 * mu;
    let solve = |nu: f64| -> DVector<f64> {
        let h = &jtj + DMatrix::<f64>::identity(k, k) * (mu + nu);
        h.cholesky()
            .map(|c| c.solve(&rhs))
            .unwrap_or_else(|| x0.clone())
    };
    let x = solve(0.0);
    if x.norm() <= limit {
        return x;
    }
    let (mut lo, mut hi) = (0.0, mu.max(1e-300));
    while solve(hi).norm() > limit && hi < 1e300 {
        hi *= 4.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if solve(mid).norm() > limit {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let x = solve(hi);
    // On the sphere to round-off, never outside it.
    let shrink = (limit / x.norm()).min(1.0);
    x * shrink
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_dual_qp_gives_the_minimum_norm_admissible_tensions() {
        // Two tendons pull one way, one the other: J t = b with t >= 0.
        let jac = DMatrix::from_row_slice(1, 3, &[1.0, 2.0, -1.0]);
        let b = DVector::from_element(1, 2.0);
        let p = DVector::zeros(3);
        let (t, _) = min_norm_in_box(&jac, &b, &p, f64::INFINITY).unwrap();
        // The minimum-norm solution is J^T (J J^T)^-1 b restricted to the
        // positive columns: t = [1, 2, 0] * 2 / 5.
        assert!((t - DVector::from_row_slice(&[0.4, 0.8, 0.0])).norm() < 1e-12);
        // With an upper bound of 0.7, the second tendon saturates and the
        // first makes up the rest: t1 + 2 (0.7) = 2.
        let (t, _) = min_norm_in_box(&jac, &b, &p, 0.7).unwrap();
        assert!((jac.clone() * &t - &b).norm() < 1e-12);
        assert!((t[1] - 0.7).abs() < 1e-12 && t[2] == 0.0 && (t[0] - 0.6).abs() < 1e-12);
        // Past what the bounds allow (1.5 at most): none.
        assert!(min_norm_in_box(&jac, &b, &p, 0.5).is_none());
        // Unreachable: only the third tendon moves the other way.
        let b = DVector::from_element(1, -1.0);
        let jac_pos = DMatrix::from_row_slice(1, 2, &[1.0, 2.0]);
        assert!(min_norm_in_box(&jac_pos, &b, &DVector::zeros(2), f64::INFINITY).is_none());
    }

    #[test]
    fn the_box_step_keeps_the_bounds_and_minimises() {
        let jac = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1.0]);
        let b = DVector::from_row_slice(&[-1.0, 2.0]);
        let x = lm_step_in_box(&jac, &b, &DVector::zeros(2), 1.5, 1e-12);
        assert!((x - DVector::from_row_slice(&[0.0, 1.5])).norm() < 1e-8);
    }

    #[test]
    fn the_ball_step_stays_inside() {
        let jac = DMatrix::identity(3, 3);
        let b = DVector::from_row_slice(&[3.0, 4.0, 0.0]);
        let x = lm_step_in_ball(&jac, &b, &DVector::zeros(3), 1.0, 1e-12);
        assert!((x.norm() - 1.0).abs() < 1e-12);
        assert!((x - DVector::from_row_slice(&[0.6, 0.8, 0.0])).norm() < 1e-6);
    }
}
