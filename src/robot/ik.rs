//! Load-aware inverse kinematics: the section curvatures whose *loaded*
//! equilibrium puts the tip at the target, the one closest to a reference among
//! the many that do.
//!
//! Each iteration solves the forward statics (warm), takes the tip's sensitivity
//! to the curvatures from the factored equilibrium Jacobian (O(n) a column), and
//! steps by the minimum-norm Gauss-Newton rule
//! `delta = r + J^T (J J^T)^{-1} (e - J r)`, `r = kappa_ref - kappa`, held within
//! the muscles' length range (see `bounds.rs`), with a backtracking line search
//! on the tip error. Only stable equilibria are accepted. At a solution,
//! `kappa - kappa_ref` is orthogonal to the directions that keep the tip in
//! place: the first-order condition of the minimum-norm choice. A stalled
//! descent ends in Levenberg-Marquardt on the tip error alone, which finds the
//! closest tip.
//!
//! That fast path starts at the reference. When it misses, the target is tried
//! again from starts that do not depend on the reference (continuation in the
//! target from the reference's tip, a constant-curvature arc aimed at the
//! target, the last answer, the straight robot, a few actuations spread over the
//! range), each with the same iteration budget, until one reaches it.

use super::actuated::{ActuatedInverseSolver, ActuationSpace};
use super::bounds::Bounds;
use super::Robot;
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::read::{as_argument, count, finite, string, Table};
use crate::solver::{Settings, Solution, Solver};
use crate::value::Value;
use nalgebra::{DMatrix, DVector, Vector2, Vector3};

/// Relative accuracy to which the actuation is the one closest to the reference.
const MIN_NORM_ACCURACY: f64 = 1e-5;

/// Shortest line-search step before the descent counts as stalled.
const MIN_ALPHA: f64 = 1e-3;

/// A descent counts as stalled after `SLOW_STEPS` steps running that each
/// shrink the miss by less than `SLOW_GAIN` of itself.
const SLOW_GAIN: f64 = 0.01;
const SLOW_STEPS: usize = 4;

/// Actuations spread over the range among the restarts.
const SPREAD_STARTS: usize = 2;

/// Target tolerance of the intermediate targets of a continuation [relative to L].
const CONTINUATION_TOL: f64 = 1e-4;

/// Tip miss allowed while a restart's answer slides toward the reference [relative to L].
const POLISH_SLACK: f64 = 1e-2;

/// How the actuation is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// The loaded equilibrium reaches the target (default).
    Equilibrium,
    /// The seed's way: fit the sections to the target ignoring weight and load,
    /// then apply that actuation to the loaded robot (it misses under load).
    Geometric,
}

impl std::str::FromStr for Strategy {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "equilibrium" => Ok(Strategy::Equilibrium),
            "geometric" => Ok(Strategy::Geometric),
            other => Err(Error::argument(
                "strategy",
                format!("unknown strategy '{other}' (expected 'equilibrium' or 'geometric')"),
            )),
        }
    }
}

impl Strategy {
    /// The name [`Strategy::from_str`](std::str::FromStr) reads.
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Equilibrium => "equilibrium",
            Strategy::Geometric => "geometric",
        }
    }
}

/// Settings of inverse kinematics; every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSettings {
    /// How the actuation is found (default [`Strategy::Equilibrium`]).
    pub strategy: Strategy,
    /// Tip position tolerance [m] (default 1e-9, in [1e-12 L, 1e-2 L]); a
    /// direction's tolerance is tol / L.
    pub tol: f64,
    /// Iteration limit of one descent (default 60). A missed target is retried
    /// from at most 6 other starts and then settled on its closest tip, each
    /// with this limit: at most 8 times it in all.
    pub max_iterations: usize,
}

impl Default for IkSettings {
    fn default() -> Self {
        IkSettings {
            strategy: Strategy::Equilibrium,
            tol: 1e-9,
            max_iterations: 60,
        }
    }
}

/// Largest iteration limit of one descent a setting accepts.
const MAX_IK_ITERATIONS: usize = 1_000_000;

impl IkSettings {
    /// Every key of [`IkSettings::set`].
    pub const KEYS: [&'static str; 3] = ["strategy", "tol", "max_iterations"];

    /// Set one field from a value, named by [`IkSettings::KEYS`]; the range
    /// of `tol` is [`validate`](IkSettings::validate)'s.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        match key {
            "strategy" => self.strategy = string(value, key).map_err(as_argument)?.parse()?,
            "tol" => self.tol = finite(value, key).map_err(as_argument)?,
            "max_iterations" => {
                self.max_iterations = count(value, key, MAX_IK_ITERATIONS).map_err(as_argument)?
            }
            other => {
                return Err(Error::argument(
                    other,
                    format!(
                        "unknown setting (expected one of: {})",
                        Self::KEYS.join(", ")
                    ),
                ))
            }
        }
        Ok(())
    }

    /// Settings from a table of [`IkSettings::KEYS`] over the defaults.
    pub fn from_value(v: &Value) -> Result<IkSettings> {
        let mut settings = IkSettings::default();
        for (k, x) in Table::top(v, "settings").map_err(as_argument)?.entries {
            settings.set(k, x)?;
        }
        settings.validate()?;
        Ok(settings)
    }

    /// Every field as a table ([`IkSettings::from_value`] reads it back).
    pub fn to_value(&self) -> Value {
        Value::Map(vec![
            (
                "strategy".into(),
                Value::String(self.strategy.name().into()),
            ),
            ("tol".into(), Value::Number(self.tol)),
            (
                "max_iterations".into(),
                Value::Number(self.max_iterations as f64),
            ),
        ])
    }

    /// Refuse a tolerance that is not positive and finite (its range relative
    /// to a robot's length is checked by the inverse solve).
    pub fn validate(&self) -> Result<()> {
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(Error::argument(
                "tol",
                format!("must be positive, got {}", self.tol),
            ));
        }
        Ok(())
    }
}

/// Options of one inverse solve: what it aims at, under which load, and the
/// settings of the solver.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IkOptions {
    /// Tip mass [kg] (default 0).
    pub tip_mass: f64,
    /// Actuation to stay closest to (default: zero curvature).
    pub reference: Option<Vec<[f64; 2]>>,
    /// Also reach this tip direction (unit vector, world frame).
    pub direction: Option<Vector3<f64>>,
    pub settings: IkSettings,
    /// Tendon-driven robots: the tensions to stay closest to [N] (default
    /// zero: the least tension, in norm, that reaches the target).
    pub pretension: Option<Vec<f64>>,
    /// A warm start: an earlier answer's equilibrium (node quaternions) and
    /// actuation. The forward solves start from the equilibrium, and the
    /// actuation is the reference when none is given (the search starts at
    /// the reference).
    pub initial: Option<IkStart>,
}

/// A warm start of an inverse solve (see [`IkOptions::initial`]).
#[derive(Debug, Clone, PartialEq)]
pub struct IkStart {
    pub quaternions: Vec<Quat>,
    pub rest_curvature: Option<Vec<[f64; 2]>>,
    /// A tendon-driven or magnetic robot's actuation: its tensions [N] or
    /// its field [T] (`None`: from slack, or zero field).
    pub actuation: Option<Vec<f64>>,
}

/// Why an inverse solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IkEnding {
    /// The tip (and direction) is within the tolerance, on a stable equilibrium.
    Reached,
    /// The closest tip found is limited by the robot, not by its muscles:
    /// farther than the robot is long, or a local minimum of the miss with no
    /// muscle at a length limit holding it back.
    OutOfReach,
    /// Drives at their limits hold the closest tip found back: muscles at
    /// their length limits, tendons slack or at `max_tension`, the field at
    /// `max_field`.
    BoundsActive,
    /// No stable equilibrium was found where the descent had to go.
    SolverFailure,
    /// The iteration budget ran out while the miss was still shrinking.
    IterationLimit,
    /// The geometric strategy's fit, applied to the loaded robot, misses.
    LoadIgnored,
}

impl IkEnding {
    /// Every ending, in the order of the declaration.
    pub const ALL: [IkEnding; 6] = [
        IkEnding::Reached,
        IkEnding::OutOfReach,
        IkEnding::BoundsActive,
        IkEnding::SolverFailure,
        IkEnding::IterationLimit,
        IkEnding::LoadIgnored,
    ];

    /// The snake_case name used by the Python API.
    pub fn name(self) -> &'static str {
        match self {
            IkEnding::Reached => "reached",
            IkEnding::OutOfReach => "out_of_reach",
            IkEnding::BoundsActive => "bounds_active",
            IkEnding::SolverFailure => "solver_failure",
            IkEnding::IterationLimit => "iteration_limit",
            IkEnding::LoadIgnored => "load_ignored",
        }
    }
}

impl std::str::FromStr for IkEnding {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        IkEnding::ALL
            .into_iter()
            .find(|ending| ending.name() == s)
            .ok_or_else(|| Error::argument("ending", format!("unknown ending '{s}'")))
    }
}

/// The actuation found, in every space, with the equilibrium it produces.
#[derive(Debug, Clone)]
pub struct IkResult {
    /// `[kappa_x, kappa_y]` per section [1/m].
    pub rest_curvature: Vec<[f64; 2]>,
    /// Three muscle lengths per section [m].
    pub muscle_lengths: Vec<[f64; 3]>,
    /// Three inflation times per section [s].
    pub inflation_times: Vec<[f64; 3]>,
    /// Tendon tensions [N] (a tendon-driven robot; empty otherwise).
    pub tensions: Vec<f64>,
    /// Uniform magnetic field, world frame [T] (a magnetic robot; zero otherwise).
    pub field: Vector3<f64>,
    /// The loaded equilibrium with this actuation.
    pub solution: Solution,
    /// The point aimed at the target: the tool's, or the tip without a tool [m].
    pub tip_position: Vector3<f64>,
    /// Distance from the aimed point (the tool's, or the tip) to the target [m].
    pub tip_miss: f64,
    /// Whether the target (and direction) was reached within the tolerance on
    /// a stable equilibrium.
    pub reached: bool,
    pub ending: IkEnding,
    pub message: String,
    /// Gauss-Newton and Levenberg-Marquardt iterations, all starts included.
    pub iterations: usize,
    /// Starting actuations tried (1: the fast path from the reference).
    pub starts: usize,
    /// Wall-clock time of this inverse solve [s].
    pub seconds: f64,
}

impl IkResult {
    /// Refuse a stored result (`IkResult.from_dict`) that no inverse solve
    /// returns: a NaN anywhere, a negative miss or time, a reached target
    /// with a non-finite answer or an equilibrium that did not converge.
    pub fn check_stored(&self) -> Result<()> {
        let rows = self
            .rest_curvature
            .iter()
            .enumerate()
            .map(|(i, k)| (format!("rest_curvature[{i}]"), k.to_vec()))
            .chain(
                self.muscle_lengths
                    .iter()
                    .enumerate()
                    .map(|(i, l)| (format!("muscle_lengths[{i}]"), l.to_vec())),
            )
            .chain(
                self.inflation_times
                    .iter()
                    .enumerate()
                    .map(|(i, t)| (format!("inflation_times[{i}]"), t.to_vec())),
            )
            .chain([
                ("tensions".to_string(), self.tensions.clone()),
                ("field".to_string(), self.field.iter().copied().collect()),
                (
                    "tip_position".to_string(),
                    self.tip_position.iter().copied().collect(),
                ),
            ]);
        for (name, values) in rows {
            let bad = values
                .iter()
                .find(|x| x.is_nan() || (self.reached && !x.is_finite()));
            if let Some(x) = bad {
                return Err(Error::argument(
                    format!("ik_result.{name}"),
                    format!("an inverse solve never answers {x}"),
                ));
            }
        }
        if self.tip_miss.is_nan()
            || self.tip_miss < 0.0
            || (self.reached && self.tip_miss.is_infinite())
        {
            return Err(Error::argument(
                "ik_result.tip_miss",
                format!("a distance: finite and >= 0, got {}", self.tip_miss),
            ));
        }
        if !(self.seconds.is_finite() && self.seconds >= 0.0) {
            return Err(Error::argument(
                "ik_result.time",
                format!("a duration: finite and >= 0 s, got {}", self.seconds),
            ));
        }
        if self.reached && !self.solution.converged() {
            return Err(Error::argument(
                "ik_result.reached",
                "a target is reached only on a converged equilibrium",
            ));
        }
        Ok(())
    }
}

/// What one inverse solve aims at.
struct Goal {
    target: Vector3<f64>,
    direction: Option<Vector3<f64>>,
    reference: Vec<[f64; 2]>,
    tol: f64,
    /// Robot length: weight of the direction rows.
    length: f64,
    /// The point aimed, from the tip in its frame (the tool's; zero: the tip).
    offset: Vector3<f64>,
}

impl Goal {
    /// Tip error (and weighted direction error) of an equilibrium.
    fn error(&self, sol: &Solution) -> DVector<f64> {
        let mut e = DVector::zeros(if self.direction.is_some() { 6 } else { 3 });
        e.rows_mut(0, 3)
            .copy_from(&(self.target - tool_point(sol, self.offset)));
        if let Some(dir) = self.direction {
            let t = sol.tip_quaternion().tangent();
            e.rows_mut(3, 3).copy_from(&((dir - t) * self.length));
        }
        e
    }

    /// Direction rows are weighted by L: tol on them is an angle of tol / L.
    fn reached(&self, e: &DVector<f64>) -> bool {
        e.rows(0, 3).norm() <= self.tol && (e.len() == 3 || e.rows(3, 3).norm() <= self.tol)
    }

    /// The goal a fraction `t` of the way from the tip of `from` to this one.
    fn partway(&self, from: &Solution, t: f64) -> Goal {
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
            reference: self.reference.clone(),
            tol: if t < 1.0 {
                CONTINUATION_TOL * self.length
            } else {
                self.tol
            },
            length: self.length,
            offset: self.offset,
        }
    }
}

/// What a step is pulled toward besides the target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pull {
    /// The reference: the minimum-norm choice.
    Reference,
    /// Nothing: the smallest change of the actuation (the reach phase of a restart).
    Free,
}

/// An accepted point of a descent: always a converged, stable equilibrium,
/// except the start of a failed attempt.
#[derive(Debug, Clone)]
struct State {
    kappa: Vec<[f64; 2]>,
    sol: Solution,
    e: DVector<f64>,
}

/// How a descent phase ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PhaseEnd {
    /// Converged (the target reached, or the closest tip settled).
    Done,
    /// No acceptable step; `unusable` if the last trials found no stable equilibrium.
    Stalled { unusable: bool },
    /// The iteration budget ran out.
    Budget,
}

/// One descent toward the target from one start.
#[derive(Debug, Clone)]
struct Attempt {
    state: State,
    /// How its last phase ended.
    phase: PhaseEnd,
}

impl Attempt {
    fn reached(&self, goal: &Goal) -> bool {
        usable(&self.state.sol) && goal.reached(&self.state.e)
    }

    /// Reached first, then any stable equilibrium, then the smaller miss.
    fn rank(&self, goal: &Goal) -> (u8, f64) {
        let tier = if self.reached(goal) {
            0
        } else if usable(&self.state.sol) {
            1
        } else {
            2
        };
        (tier, self.state.e.norm())
    }
}

/// An equilibrium the IK may stand on: converged and stable.
fn usable(sol: &Solution) -> bool {
    sol.converged() && sol.stable
}

/// Inverse kinematics of one robot under one tip mass, reusing its forward
/// solver and the last answer as the warm start of the next (trajectories).
pub struct InverseSolver {
    robot: Robot,
    bounds: Bounds,
    solver: Solver,
    kappa: Vec<[f64; 2]>,
    q: Option<Vec<Quat>>,
    /// Iterations of the current solve, all starts included.
    iterations: usize,
    /// The warm start the current solve was given (the last answer's equilibrium).
    given_warm: Option<Vec<Quat>>,
}

impl InverseSolver {
    pub fn new(robot: &Robot, tip_mass: f64) -> Result<Self> {
        if robot.actuation_space() != ActuationSpace::Curvature {
            return Err(Error::argument(
                "robot",
                format!(
                    "an InverseSolver searches muscle curvatures; this robot's actuation is its {} (use Robot::inverse or track)",
                    robot.actuation_space().name()
                ),
            ));
        }
        let zero = vec![[0.0; 2]; robot.sections];
        let scene = robot.scene(&zero, tip_mass)?;
        let settings = Settings {
            n_elements: Some(robot.n_elements),
            residual_tol: 1e-12,
            ..Settings::default()
        };
        Ok(InverseSolver {
            robot: robot.clone(),
            bounds: Bounds::new(robot),
            solver: Solver::new(&scene, settings)?,
            kappa: zero,
            q: None,
            iterations: 0,
            given_warm: None,
        })
    }

    /// Forward statics at `kappa`, warm from the last accepted state.
    fn forward(&mut self, kappa: &[[f64; 2]]) -> Result<Solution> {
        self.solver.set_rest_curvature(kappa)?;
        self.solver.solve_warm_or_cold(self.q.as_deref())
    }

    /// Put the forward solver back at an accepted state (its Jacobian is the
    /// one the next step needs).
    fn restore(&mut self, st: &State) -> Result<()> {
        self.q = Some(st.sol.quaternions.clone());
        self.forward(&st.kappa).map(|_| ())
    }

    /// Tip sensitivity at the forward solver's state (`None` at a bifurcation).
    fn jacobian(&mut self, goal: &Goal, sol: &Solution) -> Option<DMatrix<f64>> {
        let sens = self.solver.tip_sensitivity(self.robot.sections).ok()?;
        let cols = 2 * self.robot.sections;
        let mut j = DMatrix::zeros(if goal.direction.is_some() { 6 } else { 3 }, cols);
        j.rows_mut(0, 3).copy_from(&sens.position);
        if goal.offset != Vector3::zeros() {
            // The tool point moves with the tip's turn too: phi x (R c).
            let arm = sol.tip_quaternion().rotate(goal.offset);
            j.rows_mut(0, 3)
                .copy_from(&(&sens.position - crate::quat::skew(&arm) * &sens.rotation));
        }
        if goal.direction.is_some() {
            j.rows_mut(3, 3)
                .copy_from(&(sens.tangent * self.robot.length));
        }
        Some(j)
    }

    /// The actuation whose loaded equilibrium puts the tip at `target`.
    pub fn solve(
        &mut self,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        reference: Option<&[[f64; 2]]>,
        tol: f64,
        max_iterations: usize,
    ) -> Result<IkResult> {
        let started = std::time::Instant::now();
        let goal = self.goal(target, direction, reference, tol)?;
        self.iterations = 0;
        self.given_warm = self.q.clone();
        // Start at the reference: the Gauss-Newton path from there to the nearest
        // solution is short, while sliding along the solution set from elsewhere
        // converges only linearly (for tracking, the reference is the last answer).
        let first = self.reach(
            &goal,
            goal.reference.clone(),
            Pull::Reference,
            max_iterations,
        )?;
        let (mut best, starts) = if first.reached(&goal) || self.beyond_length(&goal) {
            (first, 1)
        } else {
            self.retry(&goal, first, max_iterations)?
        };
        let ending = self.settle(&goal, &mut best, max_iterations)?;
        let mut result = self.conclude(&goal, best.state, ending, starts);
        result.seconds = started.elapsed().as_secs_f64();
        Ok(result)
    }

    /// [`InverseSolver::solve`] with the tolerance and iteration limit of
    /// `settings`. An inverse solver finds the equilibrium of the load it was
    /// built for: the geometric strategy is [`Robot::track`]'s.
    pub fn solve_with(
        &mut self,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        reference: Option<&[[f64; 2]]>,
        settings: &IkSettings,
    ) -> Result<IkResult> {
        settings.validate()?;
        if settings.strategy != Strategy::Equilibrium {
            return Err(Error::argument(
                "strategy",
                "an InverseSolver finds the loaded equilibrium; the geometric strategy is \
                 Robot::inverse's and Robot::track's",
            ));
        }
        self.solve(
            target,
            direction,
            reference,
            settings.tol,
            settings.max_iterations,
        )
    }

    fn goal(
        &self,
        target: Vector3<f64>,
        direction: Option<Vector3<f64>>,
        reference: Option<&[[f64; 2]]>,
        tol: f64,
    ) -> Result<Goal> {
        let m = self.robot.sections;
        if target.iter().any(|x| !x.is_finite()) {
            return Err(Error::argument("target", "must be finite"));
        }
        // 1e-12 L is what double precision leaves of a tip; 1e-2 L is a miss.
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
        let reference = match reference {
            Some(r) if r.len() != m => {
                return Err(Error::argument(
                    "reference",
                    format!("expected {m} sections, got {}", r.len()),
                ))
            }
            Some(r) if r.iter().flatten().any(|k| !k.is_finite()) => {
                return Err(Error::argument("reference", "must be finite"))
            }
            Some(r) => r.to_vec(),
            None => vec![[0.0; 2]; m],
        };
        Ok(Goal {
            target,
            direction,
            reference,
            tol,
            length: self.robot.length,
            offset: self.robot.tool_offset,
        })
    }

    /// An inextensible backbone cannot put its tip farther from the base than its length.
    fn beyond_length(&self, goal: &Goal) -> bool {
        let reach = self.robot.length + goal.offset.norm();
        (goal.target - self.robot.base_position).norm() > reach + goal.tol
    }

    /// One descent from `start` by minimum-norm Gauss-Newton within range, in
    /// at most `budget` iterations (a restart's answer then slides toward the reference).
    fn reach(
        &mut self,
        goal: &Goal,
        start: Vec<[f64; 2]>,
        pull: Pull,
        budget: usize,
    ) -> Result<Attempt> {
        let end = self.iterations + budget;
        let mut st = match self.begin_usable(goal, start)? {
            Ok(st) => st,
            Err(stalled) => return Ok(stalled),
        };
        let phase = self.min_norm(goal, &mut st, pull, end)?;
        if pull == Pull::Free && goal.reached(&st.e) {
            self.polish(goal, &mut st, end)?;
        }
        Ok(Attempt { state: st, phase })
    }

    /// The equilibrium at a starting actuation (brought within range); the
    /// warm state of the next solves if it is stable.
    /// [`Self::begin`], or the stalled attempt when the start's equilibrium
    /// is unusable (not converged or unstable).
    fn begin_usable(
        &mut self,
        goal: &Goal,
        start: Vec<[f64; 2]>,
    ) -> Result<std::result::Result<State, Attempt>> {
        let st = self.begin(goal, start)?;
        if usable(&st.sol) {
            return Ok(Ok(st));
        }
        let phase = PhaseEnd::Stalled { unusable: true };
        Ok(Err(Attempt { state: st, phase }))
    }

    fn begin(&mut self, goal: &Goal, mut start: Vec<[f64; 2]>) -> Result<State> {
        self.robot.clamp_to_bounds(&mut start);
        let sol = self.forward(&start)?;
        if usable(&sol) {
            self.q = Some(sol.quaternions.clone());
        }
        Ok(State {
            e: goal.error(&sol),
            kappa: start,
            sol,
        })
    }

    /// No start reached the target: the closest tip from the best attempt
    /// (Levenberg-Marquardt on the miss alone, `budget` iterations), and why it misses.
    fn settle(&mut self, goal: &Goal, best: &mut Attempt, budget: usize) -> Result<IkEnding> {
        if best.reached(goal) {
            return Ok(IkEnding::Reached);
        }
        if !usable(&best.state.sol) {
            return Ok(IkEnding::SolverFailure);
        }
        let end = self.iterations + budget;
        self.restore(&best.state)?;
        best.phase = self.closest_tip(goal, &mut best.state, end)?;
        if goal.reached(&best.state.e) {
            self.polish(goal, &mut best.state, end)?;
            return Ok(IkEnding::Reached);
        }
        self.classify(goal, &mut best.state, best.phase)
    }

    /// Phase 1: minimum-norm Gauss-Newton steps within range, backtracking on the tip error.
    fn min_norm(
        &mut self,
        goal: &Goal,
        st: &mut State,
        pull: Pull,
        end: usize,
    ) -> Result<PhaseEnd> {
        let mut slow = 0;
        while self.iterations < end {
            self.iterations += 1;
            let Some(j) = self.jacobian(goal, &st.sol) else {
                return Ok(PhaseEnd::Stalled { unusable: false });
            };
            let r = match pull {
                Pull::Reference => flatten(&goal.reference) - flatten(&st.kappa),
                Pull::Free => DVector::zeros(j.ncols()),
            };
            let c = 1e-14 * j.norm_squared().max(f64::MIN_POSITIVE);
            let Some(step) = self.bounds.step(&st.kappa, &j, &st.e, &r, c) else {
                return Ok(PhaseEnd::Stalled { unusable: false });
            };
            let (norm, size) = (step.step.norm(), 1.0 + flatten(&st.kappa).norm());
            let was_reached = goal.reached(&st.e);
            if was_reached && norm <= 1e-12 * size {
                return Ok(PhaseEnd::Done);
            }
            // Decrease the error, or keep it within tolerance while moving
            // toward the reference (the minimum-norm part of the step).
            let accept = |old: &DVector<f64>, new: &DVector<f64>, alpha: f64| {
                new.norm() < (1.0 - 1e-4 * alpha) * old.norm() || (was_reached && goal.reached(new))
            };
            let before = st.e.norm();
            let search = self.line_search(goal, st, &step.step, accept)?;
            // Creeping: Gauss-Newton toward a reachable target gains fast; slow
            // gains several steps running mean a limit the closest-tip phase handles.
            slow = if !was_reached && st.e.norm() > (1.0 - SLOW_GAIN) * before {
                slow + 1
            } else {
                0
            };
            if slow >= SLOW_STEPS {
                return Ok(PhaseEnd::Stalled { unusable: false });
            }
            match search {
                Search::Stalled { unusable } => return Ok(PhaseEnd::Stalled { unusable }),
                // The tip is on target and the last full step, which moves along
                // the solution set toward the reference, changed the actuation by
                // less than 1e-5 of its size: the minimum-norm choice is settled to
                // that accuracy (Gauss-Newton converges only linearly along the set;
                // the tip itself converges quadratically and is at tol).
                Search::Accepted(alpha)
                    if goal.reached(&st.e) && alpha == 1.0 && norm <= MIN_NORM_ACCURACY * size =>
                {
                    return Ok(PhaseEnd::Done)
                }
                Search::Accepted(_) => {}
            }
        }
        Ok(PhaseEnd::Budget)
    }

    /// Phase 2 (the descent stalled): the closest tip, by Levenberg-Marquardt on
    /// the error alone within range.
    fn closest_tip(&mut self, goal: &Goal, st: &mut State, end: usize) -> Result<PhaseEnd> {
        let mut mu = 1e-6;
        let mut unusable = false;
        while self.iterations < end {
            self.iterations += 1;
            let Some(j) = self.jacobian(goal, &st.sol) else {
                return Ok(PhaseEnd::Stalled { unusable });
            };
            let scale = j.norm_squared() / j.ncols() as f64;
            let zero = DVector::zeros(j.ncols());
            let Some(step) = self.bounds.step(&st.kappa, &j, &st.e, &zero, mu * scale) else {
                return Ok(PhaseEnd::Stalled { unusable });
            };
            let before = st.e.norm();
            match self.trial(goal, st, &step.step, |old, new| new.norm() < old.norm())? {
                Trial::Accepted => {
                    mu = (mu / 3.0).max(1e-12);
                    // Settled: the miss shrinks by less than a millionth a step.
                    if before - st.e.norm() <= 1e-6 * before || goal.reached(&st.e) {
                        return Ok(PhaseEnd::Done);
                    }
                }
                rejected => {
                    unusable = rejected == Trial::Unusable;
                    self.restore(st)?;
                    mu *= 4.0;
                    if mu > 1e8 {
                        return Ok(PhaseEnd::Stalled { unusable });
                    }
                }
            }
        }
        Ok(PhaseEnd::Budget)
    }

    /// Why a descent that did not reach the target ended.
    fn classify(&mut self, goal: &Goal, st: &mut State, phase: PhaseEnd) -> Result<IkEnding> {
        if self.beyond_length(goal) {
            return Ok(IkEnding::OutOfReach);
        }
        match phase {
            PhaseEnd::Budget => return Ok(IkEnding::IterationLimit),
            PhaseEnd::Stalled { unusable: true } => return Ok(IkEnding::SolverFailure),
            _ => {}
        }
        // Bounds hold the tip back if the undamped step toward the target
        // runs into them.
        self.restore(st)?;
        let Some(j) = self.jacobian(goal, &st.sol) else {
            return Ok(IkEnding::OutOfReach);
        };
        let zero = DVector::zeros(j.ncols());
        let c = 1e-10 * j.norm_squared() / j.ncols() as f64;
        let blocked = self
            .bounds
            .step(&st.kappa, &j, &st.e, &zero, c)
            .is_some_and(|s| s.blocking > 0);
        Ok(if blocked {
            IkEnding::BoundsActive
        } else {
            IkEnding::OutOfReach
        })
    }

    /// Backtrack along `step` until `accept(old error, new error, alpha)`.
    fn line_search(
        &mut self,
        goal: &Goal,
        st: &mut State,
        step: &DVector<f64>,
        accept: impl Fn(&DVector<f64>, &DVector<f64>, f64) -> bool,
    ) -> Result<Search> {
        let mut alpha = 1.0;
        let mut last = Trial::Rejected;
        while alpha > MIN_ALPHA {
            last = self.trial(goal, st, &(step * alpha), |old, new| {
                accept(old, new, alpha)
            })?;
            if last == Trial::Accepted {
                return Ok(Search::Accepted(alpha));
            }
            alpha *= 0.5;
        }
        self.restore(st)?;
        Ok(Search::Stalled {
            unusable: last == Trial::Unusable,
        })
    }

    /// Solve at `st.kappa + step` and move there if `accept(old error, new error)`.
    fn trial(
        &mut self,
        goal: &Goal,
        st: &mut State,
        step: &DVector<f64>,
        accept: impl Fn(&DVector<f64>, &DVector<f64>) -> bool,
    ) -> Result<Trial> {
        let mut kappa = unflatten(&(flatten(&st.kappa) + step));
        // Rounding only: the bounded step stays within range.
        self.robot.clamp_to_bounds(&mut kappa);
        let sol = self.forward(&kappa)?;
        if !usable(&sol) {
            return Ok(Trial::Unusable);
        }
        let e = goal.error(&sol);
        if !accept(&st.e, &e) {
            return Ok(Trial::Rejected);
        }
        self.q = Some(sol.quaternions.clone());
        *st = State { kappa, sol, e };
        Ok(Trial::Accepted)
    }

    /// The fast path missed: try the other starts, each with `budget`
    /// iterations, until one reaches the target. Returns the best attempt and
    /// the number of starts tried.
    fn retry(&mut self, goal: &Goal, first: Attempt, budget: usize) -> Result<(Attempt, usize)> {
        let mut best = first;
        let mut starts = 1;
        let others = self.starts(goal).into_iter().map(Start::Actuation);
        for start in std::iter::once(Start::Continuation).chain(others) {
            let attempt = match start {
                Start::Continuation => {
                    // From the reference's equilibrium, on the branch the fast path started on.
                    self.q = self.given_warm.clone();
                    self.continuation(goal, goal.reference.clone(), budget)?
                }
                Start::Actuation(kappa) => {
                    // Cold: the start's own equilibrium, not the last one's branch.
                    self.q = None;
                    self.reach(goal, kappa, Pull::Free, budget)?
                }
            };
            starts += 1;
            if attempt.rank(goal) < best.rank(goal) {
                best = attempt;
            }
            if best.reached(goal) {
                break;
            }
        }
        Ok((best, starts))
    }

    /// Continuation in the target: from the tip at `start` toward the target in
    /// straight steps (halved when one fails), each reached loosely, the last exactly.
    fn continuation(
        &mut self,
        goal: &Goal,
        start: Vec<[f64; 2]>,
        budget: usize,
    ) -> Result<Attempt> {
        let end = self.iterations + budget;
        let mut st = match self.begin_usable(goal, start)? {
            Ok(st) => st,
            Err(stalled) => return Ok(stalled),
        };
        let origin = st.sol.clone();
        let (mut done, mut h) = (0.0f64, 0.25f64);
        let mut phase = PhaseEnd::Stalled { unusable: false };
        while done < 1.0 && self.iterations < end && h >= 1.0 / 64.0 {
            let t = (done + h).min(1.0);
            let sub = goal.partway(&origin, t);
            let saved = st.clone();
            st.e = sub.error(&st.sol);
            let before = self.iterations;
            phase = self.min_norm(&sub, &mut st, Pull::Free, end)?;
            if sub.reached(&st.e) {
                done = t;
                if self.iterations - before <= 4 {
                    h *= 2.0;
                }
            } else {
                st = saved;
                self.restore(&st)?;
                h *= 0.5;
            }
        }
        st.e = goal.error(&st.sol);
        if goal.reached(&st.e) {
            self.polish(goal, &mut st, end)?;
        }
        Ok(Attempt { state: st, phase })
    }

    /// A restart reached the target away from the reference: slide along the
    /// solution set toward it (the tip may stray by `POLISH_SLACK` L on the
    /// way), then settle the tip again; keep the reached state if that fails.
    fn polish(&mut self, goal: &Goal, st: &mut State, end: usize) -> Result<()> {
        let reached = st.clone();
        let slack = POLISH_SLACK * goal.length;
        let distance = |k: &[[f64; 2]]| (flatten(&goal.reference) - flatten(k)).norm();
        while self.iterations < end {
            self.iterations += 1;
            let Some(j) = self.jacobian(goal, &st.sol) else {
                break;
            };
            let r = flatten(&goal.reference) - flatten(&st.kappa);
            let c = 1e-14 * j.norm_squared().max(f64::MIN_POSITIVE);
            let Some(step) = self.bounds.step(&st.kappa, &j, &st.e, &r, c) else {
                break;
            };
            // Close enough for the strict minimum-norm phase to finish.
            if step.step.norm() <= 1e-2 * (1.0 + flatten(&st.kappa).norm()) {
                break;
            }
            let d0 = distance(&st.kappa);
            let accept = |old: &DVector<f64>, new: &DVector<f64>, _alpha: f64| {
                new.norm() <= slack.max(old.norm())
            };
            let search = self.line_search(goal, st, &step.step, accept)?;
            if matches!(search, Search::Stalled { .. }) || distance(&st.kappa) >= d0 {
                break;
            }
        }
        self.min_norm(goal, st, Pull::Reference, end)?;
        if !goal.reached(&st.e) {
            *st = reached;
            self.restore(st)?;
        }
        Ok(())
    }

    /// Starting actuations that do not depend on the reference: the arc aimed
    /// at the target, the last answer, the straight robot, and a few spread over
    /// the range (fixed, so that results are reproducible).
    fn starts(&self, goal: &Goal) -> Vec<Vec<[f64; 2]>> {
        let m = self.robot.sections;
        let mut out = vec![
            self.arc_toward(goal.target),
            self.kappa.clone(),
            vec![[0.0; 2]; m],
        ];
        let reach = self.max_curvature();
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..SPREAD_STARTS {
            out.push(
                (0..m)
                    .map(|_| [reach * uniform(&mut seed), reach * uniform(&mut seed)])
                    .collect(),
            );
        }
        out.retain(|k| k != &goal.reference);
        out.dedup();
        out
    }

    /// Constant curvature in the plane of the base axis and the target, of the
    /// arc from the base through the target (weight ignored): the chord of an
    /// arc turning by `theta` leaves the tangent at `theta / 2`.
    fn arc_toward(&self, target: Vector3<f64>) -> Vec<[f64; 2]> {
        let local = self.robot.base_quaternion.inverse_rotate(target);
        let lateral = Vector2::new(local.x, local.y);
        let u = lateral.try_normalize(1e-12).unwrap_or(Vector2::x());
        let kappa = 2.0 * lateral.norm().atan2(local.z) / self.robot.length;
        // Bending toward u: (kappa_y, -kappa_x) = kappa u.
        vec![[-kappa * u.y, kappa * u.x]; self.robot.sections]
    }

    /// Curvature scale of the spread starts: twice the range across the first
    /// two muscles (the starts are clamped into range).
    fn max_curvature(&self) -> f64 {
        let lever = self.robot.lever();
        let [lo, hi] = self.robot.muscle_length_range;
        let per = (lever[0][0] - lever[1][0]).hypot(lever[0][1] - lever[1][1]);
        2.0 * (hi - lo) / per.max(f64::MIN_POSITIVE)
    }

    /// The answer, its state kept as the warm start of the next solve.
    fn conclude(&mut self, goal: &Goal, state: State, ending: IkEnding, starts: usize) -> IkResult {
        self.kappa = state.kappa.clone();
        self.q = usable(&state.sol).then(|| state.sol.quaternions.clone());
        let miss = state.e.rows(0, 3).norm();
        let message = self.message(goal, ending, miss, starts);
        let mut r = self.result(state.kappa, state.sol, miss, ending, message);
        r.iterations = self.iterations;
        r.starts = starts;
        r
    }

    fn message(&self, goal: &Goal, ending: IkEnding, miss: f64, starts: usize) -> String {
        let from = if starts > 1 {
            format!(" (best of {starts} starting actuations)")
        } else {
            String::new()
        };
        let length = self.robot.length;
        match ending {
            IkEnding::Reached => "reached".to_string(),
            IkEnding::OutOfReach if self.beyond_length(goal) => format!(
                "not reached: the target is out of reach, {:.4} m from the base of a {length} m robot; the closest tip found misses by {miss:.3e} m",
                (goal.target - self.robot.base_position).norm()
            ),
            IkEnding::OutOfReach => format!(
                "not reached: the target is out of reach{from}; the closest tip found misses by {miss:.3e} m with no muscle at a length limit"
            ),
            IkEnding::BoundsActive => format!(
                "not reached: the muscles' length range limits the actuation{from}; the closest tip found misses by {miss:.3e} m with muscles at their length limits"
            ),
            IkEnding::SolverFailure => format!(
                "not reached: the forward solver found no stable equilibrium where the descent had to go{from}; the closest tip found misses by {miss:.3e} m"
            ),
            IkEnding::LoadIgnored => "not reached: the geometric fit ignores the load".to_string(),
            IkEnding::IterationLimit => format!(
                "not reached after {} iterations{from}: the tip misses by {miss:.3e} m and was still closing in (raise max_iterations)",
                self.iterations
            ),
        }
    }

    /// The seed's way: the weightless robot's answer applied to this (loaded) robot.
    fn apply_geometric_fit(
        &mut self,
        fit: IkResult,
        target: Vector3<f64>,
        tol: f64,
    ) -> Result<IkResult> {
        let started = std::time::Instant::now();
        let sol = self.forward(&fit.rest_curvature)?;
        self.q = usable(&sol).then(|| sol.quaternions.clone());
        let miss = (tool_point(&sol, self.robot.tool_offset) - target).norm();
        let ending = if miss <= tol && usable(&sol) {
            IkEnding::Reached
        } else {
            IkEnding::LoadIgnored
        };
        let message =
            format!("geometric fit (load ignored): the loaded tip misses by {miss:.3e} m");
        let mut r = self.result(fit.rest_curvature, sol, miss, ending, message);
        r.iterations = fit.iterations;
        r.starts = fit.starts;
        r.seconds = fit.seconds + started.elapsed().as_secs_f64();
        Ok(r)
    }

    fn result(
        &self,
        kappa: Vec<[f64; 2]>,
        sol: Solution,
        miss: f64,
        ending: IkEnding,
        message: String,
    ) -> IkResult {
        let lengths = self.robot.muscle_lengths(&kappa);
        IkResult {
            inflation_times: self.robot.inflation_times(&lengths),
            muscle_lengths: lengths,
            rest_curvature: kappa,
            tensions: Vec::new(),
            field: Vector3::zeros(),
            tip_position: tool_point(&sol, self.robot.tool_offset),
            solution: sol,
            tip_miss: miss,
            reached: ending == IkEnding::Reached,
            ending,
            message,
            iterations: 0,
            starts: 1,
            seconds: 0.0,
        }
    }
}

/// Where an inverse solve may start after the fast path missed.
enum Start {
    /// Continuation in the target from the reference's tip.
    Continuation,
    Actuation(Vec<[f64; 2]>),
}

/// The outcome of a line search.
enum Search {
    Accepted(f64),
    /// No step length was accepted; `unusable` if the last trial found no stable equilibrium.
    Stalled {
        unusable: bool,
    },
}

/// The outcome of one trial step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Trial {
    Accepted,
    Rejected,
    /// The forward solve found no stable equilibrium there.
    Unusable,
}

/// Uniform in [-1, 1) from a splitmix64 sequence.
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    2.0 * (z >> 11) as f64 / (1u64 << 53) as f64 - 1.0
}

fn flatten(k: &[[f64; 2]]) -> DVector<f64> {
    DVector::from_iterator(2 * k.len(), k.iter().flat_map(|x| x.iter().copied()))
}

/// The point an inverse solve aims: `offset` from the tip in its frame (a
/// tool's point), the tip itself for a zero offset.
pub(crate) fn tool_point(sol: &Solution, offset: Vector3<f64>) -> Vector3<f64> {
    sol.tip_position() + sol.tip_quaternion().rotate(offset)
}

/// Refuse a warm start that does not fit the robot's discretisation.
fn check_initial(start: &IkStart, n_elements: usize) -> Result<()> {
    if start.quaternions.len() != n_elements + 1 {
        return Err(Error::argument(
            "initial",
            format!(
                "has {} nodes, the robot's discretisation {}",
                start.quaternions.len(),
                n_elements + 1
            ),
        ));
    }
    if start
        .quaternions
        .iter()
        .any(|q| !q.to_array().iter().all(|x| x.is_finite()) || q.norm() < 1e-6)
    {
        return Err(Error::argument(
            "initial",
            "quaternions must be finite and non-zero",
        ));
    }
    Ok(())
}

fn unflatten(v: &DVector<f64>) -> Vec<[f64; 2]> {
    v.as_slice().chunks(2).map(|c| [c[0], c[1]]).collect()
}

impl Robot {
    /// Load-aware inverse kinematics of one target (see [`IkOptions`]).
    pub fn inverse(&self, target: Vector3<f64>, options: &IkOptions) -> Result<IkResult> {
        Ok(self.track(&[target], options)?.remove(0))
    }

    /// Inverse kinematics of a sequence of targets, each warm-started from the
    /// previous one and choosing the actuation closest to it (smooth motion).
    pub fn track(&self, targets: &[Vector3<f64>], options: &IkOptions) -> Result<Vec<IkResult>> {
        let settings = &options.settings;
        settings.validate()?;
        if self.actuation_space() != ActuationSpace::Curvature {
            return self.track_actuated(targets, options);
        }
        if options.pretension.is_some() {
            return Err(Error::argument(
                "pretension",
                "the robot has no tendons (its actuation is the muscles' curvature)",
            ));
        }
        let mut loaded = InverseSolver::new(self, options.tip_mass)?;
        let mut weightless = match settings.strategy {
            Strategy::Equilibrium => None,
            Strategy::Geometric => Some(InverseSolver::new(&self.weightless(), 0.0)?),
        };
        let mut reference = options.reference.clone();
        if let Some(start) = &options.initial {
            check_initial(start, self.n_elements)?;
            loaded.q = Some(start.quaternions.clone());
            if reference.is_none() {
                reference.clone_from(&start.rest_curvature);
            }
        }
        let mut out = Vec::with_capacity(targets.len());
        for target in targets {
            let result = match weightless.as_mut() {
                None => loaded.solve(
                    *target,
                    options.direction,
                    reference.as_deref(),
                    settings.tol,
                    settings.max_iterations,
                )?,
                Some(geometric) => {
                    let fit = geometric.solve(
                        *target,
                        options.direction,
                        reference.as_deref(),
                        settings.tol,
                        settings.max_iterations,
                    )?;
                    loaded.apply_geometric_fit(fit, *target, settings.tol)?
                }
            };
            reference = Some(result.rest_curvature.clone());
            out.push(result);
        }
        Ok(out)
    }

    /// [`Robot::track`] of a tendon-driven or magnetic robot, in tension or
    /// field space (see `actuated.rs`).
    fn track_actuated(
        &self,
        targets: &[Vector3<f64>],
        options: &IkOptions,
    ) -> Result<Vec<IkResult>> {
        self.check_actuated_ik(options)?;
        let mut solver = ActuatedInverseSolver::new(self, options.tip_mass)?;
        if let Some(start) = &options.initial {
            check_initial(start, self.n_elements)?;
            solver.warm_start(start)?;
        }
        targets
            .iter()
            .map(|target| solver.solve_with(*target, options))
            .collect()
    }

    /// Refuse the IK options that steer muscles, for a robot driven by its
    /// tensions or a field, naming them.
    pub(crate) fn check_actuated_ik(&self, options: &IkOptions) -> Result<()> {
        let space = self.actuation_space();
        if options.settings.strategy != Strategy::Equilibrium {
            return Err(Error::argument(
                "strategy",
                format!(
                    "the geometric strategy fits muscle curvatures; this robot's actuation is its {}",
                    space.name()
                ),
            ));
        }
        if options.reference.is_some() {
            return Err(Error::argument(
                "reference",
                format!(
                    "a curvature reference steers muscles; this robot's actuation is its {} (use pretension for tendons)",
                    space.name()
                ),
            ));
        }
        Ok(())
    }
}
