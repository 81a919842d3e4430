//! The descent of the inverse kinematics, the same for every drive.
//!
//! Each iteration solves the forward statics (warm), takes the tip's
//! sensitivity to the drive from the factored equilibrium Jacobian (O(n) a
//! column) and steps by the minimum-norm Gauss-Newton rule
//! `d = r + J^T (J J^T)^{-1} (e - J r)`, `r = x_ref - x`, held within the
//! drive's admissible set (`DriveSpace::step`), with a backtracking line search on
//! the tip error. Only stable equilibria are accepted. At a solution,
//! `x - x_ref` is orthogonal to the directions that keep the tip in place
//! (within the active limits): the first-order condition of the minimum-norm
//! choice. A stalled descent ends in Levenberg-Marquardt on the tip error
//! alone, which finds the closest tip.
//!
//! Near the target (a warm solve without friction, contact or insertion)
//! the descent is preceded by the coupled iteration (`coupled`): the
//! equilibrium and the drive stepped together, the tip's Jacobian taken at
//! states that are not equilibria (`solver/coupled.rs`), and one forward
//! solve at the end that must confirm the answer; where it does not settle,
//! the descent starts over from the same start.
//!
//! The first descent starts at the reference when one is given (along a
//! path: the last answer), else at the last answer. When it misses, the
//! target is tried again from starts that do not depend on the reference:
//! continuation in the target from the reference's tip, then the drive's
//! starts (`DriveSpace::starts`), each with the same iteration budget, until one
//! reaches it; an answer found away from the reference then slides toward it.
//!
//! Endings are true: `out_of_reach` when the target is farther than the
//! robot is long, or the closest tip is a local minimum of the miss with no
//! limit active; `bounds_active` when the undamped step toward the target
//! runs into a limit there.

use super::drive::{ActuationSpace, DriveSpace};
use super::goal::{tool_point, Aim, Goal};
use super::{IkEnding, IkOptions, IkResult, IkSettings, IkStart, Strategy};
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::robot::{Actuation, Load, Robot};
use crate::solver::{Settings, Solution, Solver};
use crate::status::Status;
use nalgebra::{DMatrix, DVector, Matrix3xX, Vector3};

/// Relative accuracy to which the actuation is the one closest to the reference.
const MIN_NORM_ACCURACY: f64 = 1e-6;

/// Shortest line-search step before the descent counts as stalled; on
/// target, before the slide toward the reference counts as settled.
const MIN_ALPHA: f64 = 1e-4;
const SETTLED_ALPHA: f64 = 0.1;

/// A descent counts as stalled after `SLOW_STEPS` steps running that each
/// shrink the miss by less than `SLOW_GAIN` of itself.
const SLOW_GAIN: f64 = 0.01;
const SLOW_STEPS: usize = 4;

/// Damping of a step after a full step failed (relative to the mean
/// diagonal of `J^T J`), the smallest kept before it returns to zero, and
/// where the descent gives up.
const LM_START: f64 = 1e-3;
const LM_SMALLEST: f64 = 1e-9;
const LM_GIVE_UP: f64 = 1e10;

/// Miss [relative to L] within which a step's pull toward the reference is
/// kept whole (backtracked on a merit); farther off a refused step is damped.
const NEAR: f64 = 1e-3;

/// The slide toward the reference converges linearly, its steps shrinking
/// by a nearly constant ratio along a nearly constant direction (the tendon
/// robot's track: 0.28, cosines above 0.9999). Two full steps that agree so
/// (cosine above `SLIDE_ALIGNED`, ratio below `SLIDE_RATIO`) give the rest of
/// the geometric series in one step (Aitken's extrapolation), backtracked on
/// the merit as any step.
const SLIDE_ALIGNED: f64 = 0.99;
const SLIDE_RATIO: f64 = 0.8;

/// A ratio nearer one is taken once steady: within `SLIDE_STEADY` of
/// `1 - ratio` of the ratio before it, below `SLIDE_STEADY_LIMIT`. Where the
/// reference's choice is nearly degenerate the slide creeps at 0.99 (the
/// tendon robot's circle under 30 g, as the active tensions change over):
/// 430 steps to settle, or 7 to 10 with its series.
const SLIDE_STEADY: f64 = 0.05;
const SLIDE_STEADY_LIMIT: f64 = 0.999;

/// Whether a slide's ratio `ratio` (after `before`) is known well enough
/// for the rest of its series (see `SLIDE_RATIO`, `SLIDE_STEADY`).
fn series_ratio(ratio: f64, before: Option<f64>) -> bool {
    ratio < SLIDE_RATIO
        || before.is_some_and(|before| {
            ratio < SLIDE_STEADY_LIMIT && (ratio - before).abs() <= SLIDE_STEADY * (1.0 - ratio)
        })
}

/// Iterations of the coupled Newton (equilibrium and drive together) before
/// it gives way to the descent that solves the equilibrium at every step.
/// Near the target it settles in three to six (quadratically on the tip,
/// and the slide toward the reference is short along a path).
const COUPLED_ITERATIONS: usize = 10;

/// Where the coupled iteration's steps are undamped: within this fraction
/// of the length of the target, after Newton's step (the spiral's
/// quadratic prediction missed by 1e-3 of it; undamped there, 2.5 iterations
/// a point instead of 3.15).
const COUPLED_NEAR: f64 = 1e-2;

/// How much larger than Newton's rule the coupled iteration takes the miss
/// its last move leaves, to settle on it (see `coupled`).
const LANDING_MARGIN: f64 = 10.0;

/// Tip miss allowed while a restart's answer slides toward the reference [relative to L].
const POLISH_SLACK: f64 = 1e-2;

/// How far a path's next step may differ from its last (relative to it) for
/// the next answer to be predicted by extrapolation.
const PATH_EVENNESS: f64 = 0.5;

/// Lagrange's weights at `at` of the values at `nodes` (distinct).
fn lagrange_weights(nodes: &[f64], at: f64) -> Vec<f64> {
    (0..nodes.len())
        .map(|i| {
            (0..nodes.len())
                .filter(|&j| j != i)
                .map(|j| (at - nodes[j]) / (nodes[i] - nodes[j]))
                .product()
        })
        .collect()
}

/// How many answers the path keeps: enough for a fourth-order prediction
/// and the test of it on the last answer (see `predicted`).
const PATH_POINTS: usize = 6;

/// An answer reached along the path, with its target and equilibrium: the
/// inverse solver keeps the last `PATH_POINTS`, oldest first, to predict the
/// next start from (see `predicted`); none after a miss.
#[derive(Debug, Clone)]
struct PathPoint {
    target: Vector3<f64>,
    drive: DVector<f64>,
    state: Vec<Quat>,
}

/// A start predicted along the path: the drive and the equilibrium.
struct Prediction {
    drive: DVector<f64>,
    state: Vec<Quat>,
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
    x: DVector<f64>,
    sol: Solution,
    e: DVector<f64>,
}

impl State {
    /// Whether its equilibrium may serve as an answer and a warm start.
    fn usable(&self) -> bool {
        usable(&self.sol)
    }

    /// How far the aimed point is from the target [m].
    fn miss(&self) -> f64 {
        self.e.rows(0, 3).norm()
    }
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

/// How the coupled iteration ended (see `InverseSolver::coupled`).
enum Coupled {
    /// Settled: the answer, its equilibrium solved.
    Settled(State),
    /// On target with its slide toward the reference still creeping when
    /// the budget ran out: the equilibrium solved there, where the descent
    /// goes on (the iterations are not spent again from the start).
    Creeping(State),
    /// It does not apply or did not settle: the descent starts afresh.
    Fallback,
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
        self.state.usable() && goal.reached(&self.state.e)
    }

    /// Reached first, then any stable equilibrium, then the smaller miss.
    fn rank(&self, goal: &Goal) -> (u8, f64) {
        let tier = if self.reached(goal) {
            0
        } else if self.state.usable() {
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

/// Where the robot stands when a solve starts, which with friction is
/// where the loading history of its answer starts: every forward solve of
/// the search is one step of that history, from there to the trial's
/// actuation, so the answer's equilibrium is the one the robot reaches by
/// moving its drive from where it stood to the answer (docs/model.md,
/// "Inverse kinematics with friction").
#[derive(Debug, Clone)]
enum Stance {
    /// No friction: an equilibrium has no history, and forward solves
    /// start warm from the last accepted state.
    Frictionless,
    /// At rest: each forward solve follows the load path from the rest shape.
    Rest,
    /// At an equilibrium: its rotations and its base's position.
    At(Vec<Quat>, Vector3<f64>),
}

impl Stance {
    /// The stance at an equilibrium (frictionless stays frictionless).
    fn at(&self, sol: &Solution) -> Stance {
        match self {
            Stance::Frictionless => Stance::Frictionless,
            _ => Stance::At(sol.quaternions.clone(), sol.positions[0]),
        }
    }
}

/// Forward statics of `solver`'s scene: without friction warm from `warm`
/// (the straight rod again if that fails), with friction one step of the
/// history from `stance`.
fn forward_from(solver: &mut Solver, stance: &Stance, warm: Option<&[Quat]>) -> Result<Solution> {
    match stance {
        Stance::Frictionless => solver.solve_warm_or_cold(warm),
        Stance::Rest => solver.solve(None),
        Stance::At(q, base) => solver.solve_after_state(q, Some(*base)),
    }
}

/// Inverse kinematics of one robot under one load, whatever drives it,
/// reusing its forward solver and the last answer as the warm start of the
/// next (trajectories).
pub struct InverseSolver {
    robot: Robot,
    drive: DriveSpace,
    solver: Solver,
    /// The last answer's drive and equilibrium.
    last: DVector<f64>,
    q: Option<Vec<Quat>>,
    /// The last answers reached along the path (see `PathPoint`).
    path: Vec<PathPoint>,
    /// The current descent starts from the path's prediction: near the
    /// solution set, so its first step already pulls toward the reference
    /// (taken by the first `min_norm`).
    start_on_path: bool,
    /// The equilibrium predicted with that start (`Some` only then): where
    /// the coupled iteration linearises first.
    predicted_state: Option<Vec<Quat>>,
    /// Iterations of the current solve, all starts included.
    iterations: usize,
    /// The warm start the current solve was given (the last answer's equilibrium).
    given_warm: Option<Vec<Quat>>,
    /// Where the robot stands (with friction, where the answer's history starts).
    stance: Stance,
}

impl InverseSolver {
    /// The solver of `robot`'s own drive ([`Robot::actuation_space`]).
    pub fn new(robot: &Robot, load: &Load) -> Result<Self> {
        let drive = DriveSpace::of(robot)?;
        let scene = robot.scene(&Actuation::default(), load)?;
        let settings = Settings {
            n_elements: Some(robot.n_elements),
            residual_tol: 1e-12,
            ..Settings::default()
        };
        Ok(InverseSolver {
            robot: robot.clone(),
            last: DVector::zeros(drive.dimension()),
            drive,
            solver: Solver::new(&scene, settings)?,
            q: None,
            path: Vec::new(),
            start_on_path: false,
            predicted_state: None,
            iterations: 0,
            given_warm: None,
            stance: if robot.has_friction() {
                Stance::Rest
            } else {
                Stance::Frictionless
            },
        })
    }

    /// The robot it inverts.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The space it searches.
    pub fn space(&self) -> ActuationSpace {
        self.drive.space()
    }

    /// Whether a path's reference is its last answer (muscles), see `drive.rs`.
    pub fn follows_path(&self) -> bool {
        self.drive.follows_path()
    }

    /// The last answer in the drive's coordinates (zero before the first).
    pub fn last_answer(&self) -> &[f64] {
        self.last.as_slice()
    }

    /// Start the next solve from an earlier answer's equilibrium and actuation.
    pub fn warm_start(&mut self, start: &IkStart) -> Result<()> {
        if let Some(x) = self.drive.warm(&self.robot, start)? {
            self.last = x;
        }
        self.path.clear();
        self.q = Some(start.quaternions.clone());
        if !matches!(self.stance, Stance::Frictionless) {
            let base = self.robot.base_at(start.insertion.unwrap_or(0.0));
            self.stance = Stance::At(start.quaternions.clone(), base);
        }
        Ok(())
    }

    /// With friction, start the next solve's history at rest (the load path
    /// from the rest shape) rather than at the last answer: targets solved
    /// each on its own (a batch). Without friction nothing changes.
    pub fn stand_at_rest(&mut self) {
        if !matches!(self.stance, Stance::Frictionless) {
            self.stance = Stance::Rest;
        }
    }

    /// An answer's coordinates in this solver's space: its drive's, then its
    /// insertion's (the reference of a path that follows it).
    pub fn coordinates_of(&self, result: &IkResult) -> DVector<f64> {
        self.drive
            .coordinates(result.drive(self.drive.space()), result.insertion)
    }

    /// The reference of `options` in the drive's coordinates, checked (the
    /// muscles' `reference`, the tendons' `pretension`).
    pub fn reference_of(&self, options: &IkOptions) -> Result<Option<Vec<f64>>> {
        reference_of(&self.robot, &self.drive, options)
    }

    /// Forward statics at `x`, warm from the last accepted state (with
    /// friction, a step from where the robot stands).
    fn forward(&mut self, x: &DVector<f64>) -> Result<Solution> {
        self.drive.apply(&mut self.solver, x)?;
        forward_from(&mut self.solver, &self.stance, self.q.as_deref())
    }

    /// Put the forward solver back at an accepted state (its Jacobian is the
    /// one the next step needs).
    fn restore(&mut self, st: &State) -> Result<()> {
        self.q = Some(st.sol.quaternions.clone());
        self.forward(&st.x).map(|_| ())
    }

    /// The goal's rows differentiated in the drive at the forward solver's
    /// state (`None` at a bifurcation).
    fn jacobian(&mut self, goal: &Goal, sol: &Solution) -> Option<DMatrix<f64>> {
        // With friction, what sticks is let go (see `with_sticking_released`).
        let drive = &self.drive;
        let (position, rotation) = self
            .solver
            .with_sticking_released(|solver| drive.tip_jacobian(solver))?;
        Some(goal.jacobian(sol, &position, &rotation))
    }

    /// The actuation whose loaded equilibrium puts the tip at `target` (and
    /// its frame as `aim` says: a direction, `Option<Vector3>`, or a full
    /// pose, [`Aim::Orientation`]), closest to `reference` (in the drive's
    /// coordinates, see [`IkResult::drive`]; default zero).
    pub fn solve(
        &mut self,
        target: Vector3<f64>,
        aim: impl Into<Aim>,
        reference: Option<&[f64]>,
        tol: f64,
        max_iterations: usize,
    ) -> Result<IkResult> {
        let started = std::time::Instant::now();
        let goal = self.goal(target, aim.into(), reference, tol)?;
        self.iterations = 0;
        self.given_warm = self.q.clone();
        // At the reference the Gauss-Newton path to the nearest solution is
        // short; sliding along the solution set from elsewhere converges only
        // linearly (along a path the reference is the last answer).
        // From the last answer, the start is predicted along the path.
        let predicted = match reference {
            Some(_) if goal.reference != self.last => None,
            _ => self.predicted(&goal),
        };
        self.start_on_path = predicted.is_some();
        let (predicted, predicted_state) = predicted.map(|p| (p.drive, p.state)).unzip();
        self.predicted_state = predicted_state;
        let start = match (reference, predicted) {
            (_, Some(x)) => x,
            (Some(_), None) if goal.reference != self.last => goal.reference.clone(),
            _ => self.last.clone(),
        };
        let end = self.iterations + max_iterations;
        let first = match self.coupled(&goal, &start, end)? {
            Coupled::Settled(state) => Attempt {
                state,
                phase: PhaseEnd::Done,
            },
            Coupled::Creeping(state) => self.descend(&goal, state, Pull::Reference, end)?,
            Coupled::Fallback => self.reach(&goal, start, Pull::Reference, max_iterations)?,
        };
        let (mut best, starts) =
            if first.reached(&goal) || goal.unreachable(self.base_toward(&goal.target).0) {
                (first, 1)
            } else {
                self.retry(&goal, first, max_iterations)?
            };
        let ending = self.settle(&goal, &mut best, max_iterations)?;
        // On target when the budget ran out: the slide toward the reference
        // was still moving, so the drive is not yet the one closest to it.
        let unsettled = ending == IkEnding::Reached && best.phase == PhaseEnd::Budget;
        let mut result = self.conclude(&goal, best.state, ending, starts);
        if unsettled {
            result.message.push_str(&format!(
                "; not yet the choice closest to the reference: still moving toward it when \
                 max_iterations ({max_iterations}) ran out"
            ));
        }
        result.seconds = started.elapsed().as_secs_f64();
        Ok(result)
    }

    /// [`InverseSolver::solve`] with the direction, reference (or
    /// pretension) and settings of `options`. An inverse solver finds the
    /// equilibrium of the load it was built for: the geometric strategy is
    /// [`Robot::track`]'s.
    pub fn solve_with(&mut self, target: Vector3<f64>, options: &IkOptions) -> Result<IkResult> {
        let settings: &IkSettings = &options.settings;
        settings.validate()?;
        if settings.strategy != Strategy::Equilibrium {
            return Err(Error::argument(
                "strategy",
                "an InverseSolver finds the loaded equilibrium; the geometric strategy is \
                 Robot::inverse's and Robot::track's",
            ));
        }
        let reference = self.reference_of(options)?;
        self.solve(
            target,
            options.aim()?,
            reference.as_deref(),
            settings.tol,
            settings.max_iterations,
        )
    }

    /// The base's place nearest `target`: where the body puts it, or with
    /// an insertion the nearest its range allows, and the insertion there.
    fn base_toward(&self, target: &Vector3<f64>) -> (Vector3<f64>, f64) {
        let base = self.robot.body.base_position;
        match self.robot.insertion_range {
            None => (base, 0.0),
            Some([lo, hi]) => {
                let axis = self.robot.insertion_axis();
                let d = axis.dot(&(target - base)).clamp(lo, hi);
                (base + d * axis, d)
            }
        }
    }

    fn goal(
        &self,
        target: Vector3<f64>,
        aim: Aim,
        reference: Option<&[f64]>,
        tol: f64,
    ) -> Result<Goal> {
        if target.iter().any(|x| !x.is_finite()) {
            return Err(Error::argument("target", "must be finite"));
        }
        // 1e-12 L is what double precision leaves of a tip; 1e-2 L is a miss.
        let length = self.robot.body.length;
        crate::read::check_tolerance("tol", tol, (1e-12 * length, 1e-2 * length))?;
        let (direction, orientation) = match aim {
            Aim::Point => (None, None),
            Aim::Direction(d) if d.iter().all(|x| x.is_finite()) && d.norm() > 0.0 => {
                (Some(d.normalize()), None)
            }
            Aim::Direction(_) => {
                return Err(Error::argument(
                    "direction",
                    "must be a finite non-zero vector",
                ))
            }
            Aim::Orientation(q) if q.to_array().iter().all(|x| x.is_finite()) && q.norm() > 0.0 => {
                (None, Some(q.normalized()))
            }
            Aim::Orientation(_) => {
                return Err(Error::argument(
                    "orientation",
                    "must be a finite non-zero quaternion",
                ))
            }
        };
        let k = self.drive.dimension();
        let reference = match reference {
            Some(r) if r.len() != k => {
                return Err(Error::argument(
                    "reference",
                    format!("expected {k} values, got {}", r.len()),
                ))
            }
            Some(r) if r.iter().any(|x| !x.is_finite()) => {
                return Err(Error::argument("reference", "must be finite"))
            }
            Some(r) => DVector::from_column_slice(r),
            None => DVector::zeros(k),
        };
        Ok(Goal {
            target,
            direction,
            orientation,
            reference,
            tol,
            length,
            offset: self.robot.body.tool_offset,
            inside_obstacle: self.obstacle_at(target, tol),
        })
    }

    /// The obstacle a tip at `target` would be in (its surface within the
    /// robot's radius, less `tol`); none for a tool off the tip, whose point
    /// is not kept out of them.
    fn obstacle_at(&self, target: Vector3<f64>, tol: f64) -> Option<(usize, &'static str)> {
        if self.robot.body.tool_offset != Vector3::zeros() {
            return None;
        }
        let radius = self.robot.contact_radius();
        self.robot
            .obstacles
            .iter()
            .position(|o| o.proximity(&target).gap < radius - tol)
            .map(|k| (k, self.robot.obstacles[k].shape()))
    }

    /// One descent from `start` by minimum-norm Gauss-Newton within range, in
    /// at most `budget` iterations (a restart's answer then slides toward the reference).
    fn reach(
        &mut self,
        goal: &Goal,
        start: DVector<f64>,
        pull: Pull,
        budget: usize,
    ) -> Result<Attempt> {
        let end = self.iterations + budget;
        match self.begin_usable(goal, start)? {
            Ok(st) => self.descend(goal, st, pull, end),
            Err(stalled) => Ok(stalled),
        }
    }

    /// [`InverseSolver::reach`] from the usable state `st`, until iteration `end`.
    fn descend(&mut self, goal: &Goal, mut st: State, pull: Pull, end: usize) -> Result<Attempt> {
        let mut phase = self.min_norm(goal, &mut st, pull, end)?;
        if phase == (PhaseEnd::Stalled { unusable: false }) && !goal.reached(&st.e) {
            // Gauss-Newton creeps (a drive nearly rank-deficient at the start,
            // as a field along a magnet): Levenberg-Marquardt on the miss
            // alone, then the minimum-norm steps again if it gets there.
            phase = self.closest_tip(goal, &mut st, end)?;
            if goal.reached(&st.e) {
                phase = self.min_norm(goal, &mut st, pull, end)?;
            }
        }
        if pull == Pull::Free
            && goal.reached(&st.e)
            && self.polish(goal, &mut st, end)? == PhaseEnd::Budget
        {
            // Its slide toward the reference ran out of iterations.
            phase = PhaseEnd::Budget;
        }
        Ok(Attempt { state: st, phase })
    }

    /// Newton on the equilibrium and the drive together, from the drive at
    /// `start` and, along a path, the equilibrium predicted with it (else
    /// the last answer's): each iteration linearises the equations and the
    /// tip at the state, which need not be an equilibrium
    /// (`solver/coupled.rs`), and steps both, the drive by the minimum-norm
    /// rule toward where Newton's step and the drive's columns put the aimed
    /// point. Once undamped, what is left of the slide below
    /// `MIN_NORM_ACCURACY` of the drive and the tip on target or landing
    /// there by Newton's rule (see the loop), the last move is taken and one
    /// solve from there gives the answer, accepted if converged, stable and
    /// on target (where it is usable but short of the target, the iteration
    /// goes on from its equilibrium): what the descent's answer is, at about
    /// one solve's cost instead of one a step. It goes on past
    /// `COUPLED_ITERATIONS` while it converges (undamped, the miss falling
    /// or on target); where the budget then runs out on target, its
    /// equilibrium is where the descent goes on (`Coupled::Creeping`).
    /// `Coupled::Fallback` (the iterations spent counted) where it does not
    /// apply (friction, contact, an insertion, no warm state, a start away
    /// from it) or does not settle: the descent then starts from `start`.
    fn coupled(&mut self, goal: &Goal, start: &DVector<f64>, end: usize) -> Result<Coupled> {
        let model = self.solver.model();
        // The warm state is the last answer's equilibrium: near it only from
        // its own drive or the path's prediction (a start at a reference
        // elsewhere is a jump the descent makes, 25 coupled iterations
        // failing against its 15 steps, measured).
        let near = self.start_on_path || *start == self.last;
        let applies = near
            && matches!(self.stance, Stance::Frictionless)
            && !model.is_constrained()
            && !model.has_contact()
            && !self.drive.has_insertion();
        // Along the path the first linearisation is at the predicted
        // equilibrium: it starts as near the answer's state as the drive's
        // prediction is to its drive (one iteration fewer of four, measured).
        let warm = self.predicted_state.take().or_else(|| self.q.clone());
        let Some(q) = warm.filter(|_| applies) else {
            return Ok(Coupled::Fallback);
        };
        let mut x = start.clone();
        self.drive.clamp(&self.robot, &mut x);
        self.drive.apply(&mut self.solver, &x)?;
        self.solver.set_state(&q)?;
        let begun = self.iterations;
        // The last full step, not extrapolated, and the slide's ratio once
        // two full steps agreed (see the loop); the length of the last move.
        let mut last_slide = None;
        let mut rate: Option<f64> = None;
        let mut last_move: Option<f64> = None;
        let mut last_ratio: Option<f64> = None;
        // Undamped at the last linearisation, and on target or closing in:
        // the iteration converges, if slowly, and goes on past
        // COUPLED_ITERATIONS. Where the reference's choice is nearly
        // degenerate the slide toward it creeps at a ratio near one (0.99
        // and 0.89 on the tendon robot's circle under 30 g), the tip
        // following it: cheaper here, a linearisation a step, than in the
        // descent from the start, a solve a step.
        let mut creeping = false;
        let mut last_miss = f64::INFINITY;
        while self.iterations < end && (self.iterations - begun < COUPLED_ITERATIONS || creeping) {
            self.iterations += 1;
            let Some(lin) = self.drive.linearise(&mut self.solver, goal.turns()) else {
                break;
            };
            let frame = lin.tip_quaternion;
            let e = goal.error_at(lin.tip_position, frame);
            let j = goal.jacobian_at(frame, &lin.position, &lin.rotation);
            // The miss Newton's step leaves, to first order.
            let newton = goal.jacobian_at(
                frame,
                &Matrix3xX::from_column_slice(lin.newton_position.as_slice()),
                &Matrix3xX::from_column_slice(lin.newton_rotation.as_slice()),
            );
            let left = &e - newton.column(0);
            // Farther than COUPLED_NEAR, damped as the descent's first step (a
            // nearly singular drive, a field along a magnet, throws an
            // undamped step far), its pull toward the reference fading.
            let squared = j.norm_squared().max(f64::MIN_POSITIVE);
            let c = 1e-14 * squared;
            let damping = if left.norm() > COUPLED_NEAR * goal.length {
                LM_START * squared / j.ncols() as f64
            } else {
                0.0
            };
            creeping = damping == 0.0 && (goal.reached(&e) || e.norm() < last_miss);
            last_miss = e.norm();
            let r = (&goal.reference - &x) * (c / (c + damping));
            let Some(step) = self
                .drive
                .step(&x, &j, &left, &r, c + damping)
                .map(|s| s.step)
            else {
                break;
            };
            // The slide toward the reference converges linearly (see
            // SLIDE_ALIGNED): two full steps that agree give the rest of
            // their series, where it stays within range. As in `min_norm`,
            // what a full step leaves to go is the rest of its series once
            // the ratio is known, else itself (an extrapolated one: itself).
            let norm = step.norm();
            // A damped step is no term of the slide's series.
            let previous = last_slide.take().filter(|_| damping == 0.0);
            let ratio = previous
                .as_ref()
                .map(|last: &DVector<f64>| norm / last.norm());
            let known = ratio.filter(|r| series_ratio(*r, last_ratio));
            let series = previous.zip(known).and_then(|(last, ratio)| {
                let aligned = last.dot(&step) >= SLIDE_ALIGNED * last.norm() * norm;
                let whole = &step / (1.0 - ratio);
                (aligned && self.drive.within(&self.robot, &(&x + &whole))).then_some(whole)
            });
            last_ratio = ratio;
            // The slide's ratio grows as the state converges (0.12 to 0.24
            // on the tendon robot): the largest seen, for what is left.
            if let Some(r) = known {
                rate = Some(rate.map_or(r, |known| known.max(r)));
            }
            let (step, to_go) = match series {
                Some(whole) => (whole, norm),
                None => {
                    last_slide = (damping == 0.0).then(|| step.clone());
                    (step, rate.map_or(norm, |r| norm * r / (1.0 - r)))
                }
            };
            // Settled: undamped, the slide's rest below MIN_NORM_ACCURACY,
            // and on target, or landing there (within LANDING_MARGIN) by the
            // rule Newton's iteration has followed: a miss that falls with
            // the square of the move, `e (|step| / |last move|)^2`. Then the
            // last move, and the solve from there certifies the equilibrium,
            // its stability and the miss (a landing one iteration sooner
            // than on target, measured on the seed's robot: 2 instead of 3).
            let landing = last_move
                .filter(|last| *last > 0.0)
                .map(|last| &e * (LANDING_MARGIN * (step.norm() / last).powi(2)));
            let settled = damping == 0.0
                && to_go <= MIN_NORM_ACCURACY * self.drive.size(&x)
                && (goal.reached(&e) || landing.as_ref().is_some_and(|l| goal.reached(l)));
            if !self.solver.move_state(step.as_slice()) {
                break;
            }
            last_move = Some(step.norm());
            x += step;
            // Rounding only: the bounded step stays within range (a tension
            // of -1e-32 N would be refused).
            self.drive.clamp(&self.robot, &mut x);
            self.drive.apply(&mut self.solver, &x)?;
            if !settled {
                continue;
            }
            let q = self.solver.state().to_vec();
            let sol = self.solver.solve(Some(&q))?;
            let st = State {
                e: goal.error(&sol),
                x: x.clone(),
                sol,
            };
            if !st.usable() {
                return Ok(Coupled::Fallback);
            }
            if goal.reached(&st.e) {
                self.q = Some(st.sol.quaternions.clone());
                return Ok(Coupled::Settled(st));
            }
            // Landed short: its equilibrium is where the iteration goes on,
            // the slide's series begun afresh from there.
            self.solver.set_state(&st.sol.quaternions)?;
            last_move = None;
            last_slide = None;
        }
        if !creeping {
            return Ok(Coupled::Fallback);
        }
        // The budget ran out on a creeping slide: its equilibrium, where the
        // descent goes on within what is left of the budget.
        let q = self.solver.state().to_vec();
        let sol = self.solver.solve(Some(&q))?;
        let st = State {
            e: goal.error(&sol),
            x,
            sol,
        };
        if !st.usable() || !goal.reached(&st.e) {
            return Ok(Coupled::Fallback);
        }
        self.q = Some(st.sol.quaternions.clone());
        Ok(Coupled::Creeping(st))
    }

    /// The equilibrium at a starting actuation (brought within range), or
    /// the stalled attempt when it is unusable (not converged or unstable).
    fn begin_usable(
        &mut self,
        goal: &Goal,
        mut start: DVector<f64>,
    ) -> Result<std::result::Result<State, Attempt>> {
        self.drive.clamp(&self.robot, &mut start);
        let sol = self.forward(&start)?;
        let st = State {
            e: goal.error(&sol),
            x: start,
            sol,
        };
        if st.usable() {
            self.q = Some(st.sol.quaternions.clone());
            return Ok(Ok(st));
        }
        let phase = PhaseEnd::Stalled { unusable: true };
        Ok(Err(Attempt { state: st, phase }))
    }

    /// No start reached the target: the closest tip from the best attempt
    /// (Levenberg-Marquardt on the miss alone, `budget` iterations), and why it misses.
    fn settle(&mut self, goal: &Goal, best: &mut Attempt, budget: usize) -> Result<IkEnding> {
        if best.reached(goal) {
            return Ok(IkEnding::Reached);
        }
        if !best.state.usable() {
            return Ok(IkEnding::SolverFailure);
        }
        let end = self.iterations + budget;
        self.restore(&best.state)?;
        best.phase = self.closest_tip(goal, &mut best.state, end)?;
        if goal.reached(&best.state.e) {
            best.phase = self.polish(goal, &mut best.state, end)?;
            return Ok(IkEnding::Reached);
        }
        self.classify(goal, &mut best.state, best.phase)
    }

    /// Minimum-norm Gauss-Newton steps within range, damped where a full
    /// step fails (see [`InverseSolver::damped_step`]).
    fn min_norm(
        &mut self,
        goal: &Goal,
        st: &mut State,
        pull: Pull,
        end: usize,
    ) -> Result<PhaseEnd> {
        let mut slow = 0;
        // Far off, the first step is damped: a nearly singular drive (a field
        // along a magnet) throws an undamped step far, where the forward
        // solve is costly and the step refused; a good step cuts it by ten.
        let mut mu = LM_START;
        // The accepted state's Jacobian; a refused trial leaves the forward
        // solver at the trial (`away`), and the Jacobian is kept.
        let mut jac: Option<DMatrix<f64>> = None;
        let mut away = false;
        let mut near = std::mem::take(&mut self.start_on_path);
        // The last full step of the slide toward the reference (see SLIDE_ALIGNED).
        let mut last_slide: Option<DVector<f64>> = None;
        // Its ratio, once two full steps agreed: what a step leaves to go;
        // the ratio of the last two full steps, agreeing or not.
        let mut rate: Option<f64> = None;
        let mut last_ratio: Option<f64> = None;
        let ended = loop {
            if self.iterations >= end {
                break PhaseEnd::Budget;
            }
            self.iterations += 1;
            if jac.is_none() {
                jac = self.jacobian(goal, &st.sol);
            }
            let Some(j) = jac.as_ref() else {
                break PhaseEnd::Stalled { unusable: false };
            };
            // Once near, the merit steps go on, undamped (else the two
            // acceptances can take turns undoing each other, a cycle).
            near |= st.e.norm() <= NEAR * goal.length;
            if near {
                mu = 0.0;
            }
            // Far off, the steps close in on the target alone (the least
            // change); near it they pull toward the reference.
            let pulled = if near { pull } else { Pull::Free };
            let Some(step) = self.damped_step(goal, st, j, pulled, mu) else {
                break PhaseEnd::Stalled { unusable: false };
            };
            let (norm, size) = (step.norm(), self.drive.size(&st.x));
            let was_reached = goal.reached(&st.e);
            // On target, and the minimum-norm step (the rest of the way to the
            // linearised problem's answer) moves the actuation by less than
            // MIN_NORM_ACCURACY of its size: the choice is settled to that
            // accuracy (the step itself may drown in the tip's round-off).
            // The distance left is the step's series where its ratio is known.
            let to_go = rate.map_or(norm, |r| norm / (1.0 - r));
            if was_reached && mu == 0.0 && to_go <= MIN_NORM_ACCURACY * size {
                break PhaseEnd::Done;
            }
            let before = st.e.norm();
            if near {
                // Near the target: the minimum-norm step, backtracked on a
                // merit that may trade some miss for a smaller distance to the
                // reference (a curved solution set, as of tendons, refuses a
                // slide that must keep the tip within tol).
                if away {
                    self.restore(st)?;
                    away = false;
                }
                // Two aligned full steps in a row: the rest of their series.
                let previous = last_slide.take();
                if previous.is_none() {
                    last_ratio = None;
                }
                let series = previous.and_then(|last| {
                    let ratio = norm / last.norm();
                    let known = series_ratio(ratio, last_ratio.replace(ratio));
                    let aligned = last.dot(&step) >= SLIDE_ALIGNED * last.norm() * norm;
                    (aligned && known).then(|| {
                        rate = Some(ratio);
                        &step / (1.0 - ratio)
                    })
                });
                let extrapolated = series.is_some();
                let slide = series.unwrap_or_else(|| step.clone());
                match self.merit_search(goal, st, j, &slide, pull)? {
                    Search::Accepted(alpha) => {
                        if alpha == 1.0 && !extrapolated {
                            last_slide = Some(step.clone());
                        }
                        jac = None;
                        // What is left of the slide after a full step: the rest
                        // of its series where its ratio is known, else the step.
                        let left = match rate {
                            Some(r) if !extrapolated => norm * r / (1.0 - r),
                            _ => norm,
                        };
                        if alpha == 1.0 && goal.reached(&st.e) && left <= MIN_NORM_ACCURACY * size {
                            break PhaseEnd::Done;
                        }
                        // At the closest tip short of the target the miss stops falling.
                        slow = if !goal.reached(&st.e) && st.e.norm() > (1.0 - SLOW_GAIN) * before {
                            slow + 1
                        } else {
                            0
                        };
                        if slow >= SLOW_STEPS {
                            break PhaseEnd::Stalled { unusable: false };
                        }
                    }
                    Search::Stalled { unusable } => break PhaseEnd::Stalled { unusable },
                }
                continue;
            }
            let accept =
                |old: &DVector<f64>, new: &DVector<f64>| new.norm() < (1.0 - 1e-4) * old.norm();
            // The miss the linearisation predicts.
            let predicted = (&st.e - j * &step).norm();
            match self.trial(goal, st, &step, accept)? {
                Trial::Accepted => {
                    let full = mu == 0.0;
                    (jac, away) = (None, false);
                    // Trust the linearisation again as far as it was right: a
                    // tenth of the damping after a step that gained at least
                    // 3/4 of the predicted decrease (a third otherwise), none
                    // below LM_SMALLEST. (Undamped at once, a nearly singular
                    // drive, a field along a magnet, throws a long step again.)
                    let gained = before * before - st.e.norm_squared();
                    let promised = before * before - predicted * predicted;
                    mu /= if gained >= 0.75 * promised { 10.0 } else { 3.0 };
                    if mu <= LM_SMALLEST {
                        mu = 0.0;
                    }
                    // Creeping: Gauss-Newton toward a reachable target gains
                    // fast; slow gains several steps running mean a limit the
                    // closest-tip phase handles.
                    slow = if st.e.norm() > (1.0 - SLOW_GAIN) * before {
                        slow + 1
                    } else {
                        0
                    };
                    if slow >= SLOW_STEPS {
                        break PhaseEnd::Stalled { unusable: false };
                    }
                    // The tip is on target and the last full step, which moves
                    // along the solution set toward the reference, changed the
                    // actuation by less than MIN_NORM_ACCURACY of its size: the
                    // minimum-norm choice is settled to that accuracy
                    // (Gauss-Newton converges only linearly along the set; the
                    // tip itself converges quadratically and is at tol).
                    if full && goal.reached(&st.e) && norm <= MIN_NORM_ACCURACY * size {
                        break PhaseEnd::Done;
                    }
                }
                refused => {
                    away = true;
                    mu = if mu == 0.0 { LM_START } else { 4.0 * mu };
                    if mu > LM_GIVE_UP {
                        break PhaseEnd::Stalled {
                            unusable: refused == Trial::Unusable,
                        };
                    }
                }
            }
        };
        if away {
            self.restore(st)?;
        }
        Ok(ended)
    }

    /// Backtrack along the minimum-norm step `d` on the merit
    /// `|x - x_ref|^2 / 2 + rho |e|`, `rho` twice the step's multiplier
    /// (`d - r = J^T y`): the merit falls along `d` to first order, so some
    /// miss may be traded for a smaller distance, which the next steps
    /// restore. Only stable equilibria are accepted; the solver is left at
    /// the accepted state (or back at `st`).
    fn merit_search(
        &mut self,
        goal: &Goal,
        st: &mut State,
        j: &DMatrix<f64>,
        d: &DVector<f64>,
        pull: Pull,
    ) -> Result<Search> {
        let reference = match pull {
            Pull::Reference => goal.reference.clone(),
            Pull::Free => st.x.clone(),
        };
        let r = &reference - &st.x;
        // The multiplier from the coordinates the step leaves off the limits
        // (at a limit its row's own multiplier takes up the rest).
        let free = self.drive.free(&(&st.x + d));
        let jf = DMatrix::from_fn(
            j.nrows(),
            j.ncols(),
            |i, k| if free[k] { j[(i, k)] } else { 0.0 },
        );
        let rows = j.nrows();
        let c = 1e-14 * j.norm_squared().max(f64::MIN_POSITIVE);
        let y = (&jf * jf.transpose() + DMatrix::identity(rows, rows) * c)
            .cholesky()
            .map(|g| g.solve(&(&jf * (d - &r))))
            .unwrap_or_else(|| DVector::zeros(rows));
        let rho = 2.0 * y.norm() + f64::MIN_POSITIVE;
        let merit = |x: &DVector<f64>, e: &DVector<f64>| {
            0.5 * (x - &reference).norm_squared() + rho * e.norm()
        };
        let (x0, miss) = (st.x.clone(), st.e.norm());
        let phi = merit(&x0, &st.e);
        let slope = (&x0 - &reference).dot(d) - rho * miss;
        let accept = |_: &DVector<f64>, e: &DVector<f64>, alpha: f64| {
            // The step's point at `alpha` (the drive's clamp is rounding only).
            merit(&(&x0 + d * alpha), e) <= phi + 1e-4 * alpha * slope.min(0.0)
                && (e.norm() < miss || goal.reached(e) || slope < 0.0)
        };
        // On target the merit's fall drowns in `rho |e|` at the tip's
        // round-off once the step is below about `sqrt(rho |e|)`: a few
        // halvings tell, not the full search (each is a forward solve).
        let shortest = if goal.reached(&st.e) {
            SETTLED_ALPHA
        } else {
            MIN_ALPHA
        };
        self.line_search(goal, st, d, 1.0, shortest, accept)
    }

    /// The step from `st` toward the target, pulled toward the reference
    /// (`Pull::Reference`), damped by `mu` (relative to the mean diagonal of
    /// `J^T J`): the minimiser of
    /// `|J d - e|^2 + mu' |d|^2 + c |d - r|^2` within range, `c` at round-off.
    /// Undamped it is the minimum-norm Gauss-Newton step; damped, a
    /// Levenberg-Marquardt step whose pull fades as `c / (c + mu')`, so a
    /// poor linearisation (a field along a magnet, far from the target)
    /// gives a short step, not a long one toward the reference.
    fn damped_step(
        &self,
        goal: &Goal,
        st: &State,
        j: &DMatrix<f64>,
        pull: Pull,
        mu: f64,
    ) -> Option<DVector<f64>> {
        let r = match pull {
            Pull::Reference => &goal.reference - &st.x,
            Pull::Free => DVector::zeros(j.ncols()),
        };
        let squared = j.norm_squared().max(f64::MIN_POSITIVE);
        let c = 1e-14 * squared;
        let damping = mu * squared / j.ncols() as f64;
        let pulled = r * (c / (c + damping));
        let step = self.drive.step(&st.x, j, &st.e, &pulled, c + damping)?;
        Some(step.step)
    }

    /// The descent stalled: the closest tip, by Levenberg-Marquardt on the
    /// error alone within range.
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
            let Some(step) = self.drive.step(&st.x, &j, &st.e, &zero, mu * scale) else {
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
        if goal.unreachable(self.base_toward(&goal.target).0) {
            return Ok(IkEnding::OutOfReach);
        }
        match phase {
            PhaseEnd::Budget => return Ok(IkEnding::IterationLimit),
            PhaseEnd::Stalled { unusable: true } => return Ok(IkEnding::SolverFailure),
            _ => {}
        }
        // A limit holds the tip back if the undamped step toward the target
        // runs into it.
        self.restore(st)?;
        let Some(j) = self.jacobian(goal, &st.sol) else {
            return Ok(IkEnding::OutOfReach);
        };
        let zero = DVector::zeros(j.ncols());
        let c = 1e-10 * j.norm_squared() / j.ncols() as f64;
        let blocked = self
            .drive
            .step(&st.x, &j, &st.e, &zero, c)
            .is_some_and(|s| s.blocking > 0);
        Ok(if blocked {
            IkEnding::BoundsActive
        } else {
            IkEnding::OutOfReach
        })
    }

    /// Backtrack along `step` from `first` of it, down to `shortest`, until
    /// `accept(old error, new error, alpha)`.
    fn line_search(
        &mut self,
        goal: &Goal,
        st: &mut State,
        step: &DVector<f64>,
        first: f64,
        shortest: f64,
        accept: impl Fn(&DVector<f64>, &DVector<f64>, f64) -> bool,
    ) -> Result<Search> {
        let mut alpha = first;
        let mut last = Trial::Rejected;
        while alpha > shortest {
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

    /// Solve at `st.x + step` and move there if `accept(old error, new error)`.
    fn trial(
        &mut self,
        goal: &Goal,
        st: &mut State,
        step: &DVector<f64>,
        accept: impl Fn(&DVector<f64>, &DVector<f64>) -> bool,
    ) -> Result<Trial> {
        let mut x = &st.x + step;
        // Rounding only: the bounded step stays within range.
        self.drive.clamp(&self.robot, &mut x);
        // Warm from the equilibrium the step's tangent predicts (the drive's
        // sensitivity taken at the state), else from the state's.
        // With friction a step starts where the robot stands, not at a guess.
        let moved = &x - &st.x;
        let predicted = match self.stance {
            Stance::Frictionless => self
                .solver
                .predicted_state(&st.sol.quaternions, moved.as_slice()),
            _ => None,
        };
        let sol = match predicted {
            Some(q) => {
                self.drive.apply(&mut self.solver, &x)?;
                let sol = self.solver.solve(Some(&q))?;
                // Where the step's own branch is too curled for the mesh
                // (an element turning more than it resolves), the step is
                // too long: the straight rod's load path, a cold solve's
                // cost many times over, ends as curled (on an unreachable
                // target under load, every one of 61 such trials did).
                let sol = if usable(&sol) || sol.status == Status::Underresolved {
                    sol
                } else {
                    self.solver.solve(None)?
                };
                match (usable(&sol), self.q.as_deref()) {
                    (true, _) | (false, None) => sol,
                    // Warm from the state's equilibrium, as `forward` would
                    // start, without its fallback: the solve from the
                    // straight rod was tried (or judged vain) just above.
                    (false, Some(state)) => self.solver.solve(Some(state))?,
                }
            }
            None => self.forward(&x)?,
        };
        if !usable(&sol) {
            return Ok(Trial::Unusable);
        }
        let e = goal.error(&sol);
        if !accept(&st.e, &e) {
            return Ok(Trial::Rejected);
        }
        self.q = Some(sol.quaternions.clone());
        *st = State { x, sol, e };
        Ok(Trial::Accepted)
    }

    /// The first descent missed: try the other starts, each with `budget`
    /// iterations, until one reaches the target. Returns the best attempt and
    /// the number of starts tried.
    fn retry(&mut self, goal: &Goal, first: Attempt, budget: usize) -> Result<(Attempt, usize)> {
        let mut best = first;
        let mut starts = 1;
        let mut others = self.drive.starts(&goal.target, &self.last);
        others.retain(|x| x != &goal.reference);
        others.dedup();
        let others = others.into_iter().map(Start::Actuation);
        for start in std::iter::once(Start::Continuation).chain(others) {
            let attempt = match start {
                Start::Continuation => {
                    // From the reference's equilibrium, on the branch the first descent started on.
                    self.q = self.given_warm.clone();
                    self.continuation(goal, goal.reference.clone(), budget)?
                }
                Start::Actuation(x) => {
                    // Cold: the start's own equilibrium, not the last one's branch.
                    self.q = None;
                    self.reach(goal, x, Pull::Free, budget)?
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
    fn continuation(&mut self, goal: &Goal, start: DVector<f64>, budget: usize) -> Result<Attempt> {
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
            phase = self.polish(goal, &mut st, end)?;
        }
        Ok(Attempt { state: st, phase })
    }

    /// A restart reached the target away from the reference: slide along the
    /// solution set toward it (the tip may stray by `POLISH_SLACK` L on the
    /// way), then settle the tip again; keep the reached state if that fails.
    fn polish(&mut self, goal: &Goal, st: &mut State, end: usize) -> Result<PhaseEnd> {
        let reached = st.clone();
        let slack = POLISH_SLACK * goal.length;
        let distance = |x: &DVector<f64>| (&goal.reference - x).norm();
        while self.iterations < end {
            self.iterations += 1;
            let Some(j) = self.jacobian(goal, &st.sol) else {
                break;
            };
            let r = &goal.reference - &st.x;
            let c = 1e-14 * j.norm_squared().max(f64::MIN_POSITIVE);
            let Some(step) = self.drive.step(&st.x, &j, &st.e, &r, c) else {
                break;
            };
            // Close enough for the strict minimum-norm phase to finish.
            if step.step.norm() <= 1e-2 * self.drive.size(&st.x) {
                break;
            }
            let d0 = distance(&st.x);
            let accept = |old: &DVector<f64>, new: &DVector<f64>, _alpha: f64| {
                new.norm() <= slack.max(old.norm())
            };
            let search = self.line_search(goal, st, &step.step, 1.0, MIN_ALPHA, accept)?;
            if matches!(search, Search::Stalled { .. }) || distance(&st.x) >= d0 {
                break;
            }
        }
        let phase = self.min_norm(goal, st, Pull::Reference, end)?;
        if !goal.reached(&st.e) {
            *st = reached;
            self.restore(st)?;
        }
        Ok(phase)
    }

    /// The answer, its state kept as the warm start of the next solve.
    fn conclude(&mut self, goal: &Goal, state: State, ending: IkEnding, starts: usize) -> IkResult {
        match ending {
            IkEnding::Reached if state.usable() => {
                if self.path.len() == PATH_POINTS {
                    self.path.remove(0);
                }
                self.path.push(PathPoint {
                    target: goal.target,
                    drive: state.x.clone(),
                    state: state.sol.quaternions.clone(),
                });
            }
            _ => self.path.clear(),
        }
        if state.usable() {
            self.last = state.x.clone();
            self.q = Some(state.sol.quaternions.clone());
            self.stance = self.stance.at(&state.sol);
        } else {
            self.q = None;
        }
        let miss = state.miss();
        let message = self.message(goal, ending, miss, &state.x, starts);
        let mut r = self.result(&state.x, state.sol, miss, ending, message);
        r.iterations = self.iterations;
        r.starts = starts;
        r
    }

    /// Along a path, the start of the next solve: the last answers' drives
    /// and equilibria extrapolated to the new target, each answer placed at
    /// its target's distance along the path, over the tail of the path whose
    /// targets advance by nearly equal steps (each within `PATH_EVENNESS` of
    /// the one before), in the order (one to `PATH_POINTS - 2`) that predicted
    /// the last answer best. The slide along the solution set then begins as
    /// near its end as the path is smooth. `None`: start from the last answer.
    /// The descent's forward solve starts warm from the last answer's
    /// equilibrium (measured: from the extrapolated one it cost a fifth more
    /// on the pneumatic robot); the coupled iteration from the extrapolated
    /// one (a quarter fewer iterations).
    fn predicted(&self, goal: &Goal) -> Option<Prediction> {
        let path = &self.path;
        let last = path.last()?;
        if last.drive != self.last {
            return None;
        }
        // The steps between targets, the new one last; the even tail.
        let mut steps: Vec<Vector3<f64>> =
            path.windows(2).map(|w| w[1].target - w[0].target).collect();
        steps.push(goal.target - last.target);
        let even = |a: &Vector3<f64>, b: &Vector3<f64>| {
            a.norm() > 0.0 && (b - a).norm() <= PATH_EVENNESS * a.norm()
        };
        let evenly = steps
            .windows(2)
            .rev()
            .take_while(|w| even(&w[0], &w[1]))
            .count();
        if evenly == 0 {
            return None;
        }
        // The even tail's points and the new target at their distances along the path.
        let used = &path[path.len() - (evenly + 1)..];
        let mut along = vec![0.0];
        for step in &steps[steps.len() - evenly - 1..] {
            along.push(along.last().copied().unwrap_or(0.0) + step.norm());
        }
        let at = along.pop().unwrap_or(0.0);
        // The order that predicted the last answer best from the ones before
        // it (linear where there is no such test): a smooth path gains an
        // order a point, a noisy one keeps a low one.
        let last_at = along[evenly];
        let order = (1..evenly)
            .map(|order| {
                let before = evenly - order - 1..evenly;
                let weights = lagrange_weights(&along[before.clone()], last_at);
                let mut guess = -&last.drive;
                for (p, w) in used[before].iter().zip(&weights) {
                    guess += &p.drive * *w;
                }
                (order, guess.norm())
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(1, |(order, _)| order);
        let from = evenly - order..=evenly;
        let weights = lagrange_weights(&along[from.clone()], at);
        let used = &used[from];
        let mut drive = DVector::zeros(self.last.len());
        for (p, w) in used.iter().zip(&weights) {
            drive += &p.drive * *w;
        }
        let state = (0..last.state.len())
            .map(|node| {
                let newest = last.state[node];
                let mut sum = [0.0; 4];
                for (p, w) in used.iter().zip(&weights) {
                    // The same rotation's two quaternions: the one nearest the last.
                    let q = p.state[node];
                    let sign = if q.dot(newest) < 0.0 { -w } else { *w };
                    for (s, v) in sum.iter_mut().zip(q.to_array()) {
                        *s += sign * v;
                    }
                }
                Quat::from_array(sum).normalized()
            })
            .collect();
        Some(Prediction { drive, state })
    }

    fn message(
        &self,
        goal: &Goal,
        ending: IkEnding,
        miss: f64,
        x: &DVector<f64>,
        starts: usize,
    ) -> String {
        let from = if starts > 1 {
            format!(" (best of {starts} starts)")
        } else {
            String::new()
        };
        let length = self.robot.body.length;
        match ending {
            IkEnding::Reached => format!("reached{}", self.drive.describe(x)),
            IkEnding::OutOfReach if goal.beyond_length(self.base_toward(&goal.target).0) => {
                let (base, d) = self.base_toward(&goal.target);
                let inserted = match self.robot.insertion_range {
                    Some(_) => format!(" inserted by {d} m (the nearest its insertion_range allows)"),
                    None => String::new(),
                };
                format!(
                    "not reached: the target is out of reach, {:.4} m from the base{inserted} of a {length} m robot; the closest tip found misses by {miss:.3e} m",
                    (goal.target - base).norm()
                )
            }
            IkEnding::OutOfReach if goal.inside_obstacle.is_some() => {
                let (k, shape) = goal.inside_obstacle.expect("checked");
                format!(
                    "not reached: the target is inside obstacle {k} (a {shape}), where the tip cannot be (the robot's surface, {:.4} m off its backbone, keeps out of every obstacle); the closest tip found misses by {miss:.3e} m",
                    self.robot.contact_radius()
                )
            }
            IkEnding::OutOfReach => format!(
                "not reached: the target is out of reach{from}; the closest tip found misses by {miss:.3e} m, a local minimum of the miss with no drive at a limit"
            ),
            IkEnding::BoundsActive => format!(
                "not reached: {}{from}; the closest tip found misses by {miss:.3e} m",
                self.drive.limit()
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
    pub(super) fn apply_geometric_fit(
        &mut self,
        fit: IkResult,
        target: Vector3<f64>,
        tol: f64,
    ) -> Result<IkResult> {
        let started = std::time::Instant::now();
        let x = self.coordinates_of(&fit);
        let sol = self.forward(&x)?;
        self.q = usable(&sol).then(|| sol.quaternions.clone());
        if usable(&sol) {
            self.stance = self.stance.at(&sol);
        }
        let miss = (tool_point(&sol, self.robot.body.tool_offset) - target).norm();
        let ending = if miss <= tol && usable(&sol) {
            IkEnding::Reached
        } else {
            IkEnding::LoadIgnored
        };
        let message =
            format!("geometric fit (load ignored): the loaded tip misses by {miss:.3e} m");
        let mut r = self.result(&x, sol, miss, ending, message);
        r.iterations = fit.iterations;
        r.starts = fit.starts;
        r.seconds = fit.seconds + started.elapsed().as_secs_f64();
        Ok(r)
    }

    fn result(
        &self,
        x: &DVector<f64>,
        sol: Solution,
        miss: f64,
        ending: IkEnding,
        message: String,
    ) -> IkResult {
        let (rest_curvature, tensions, field) = self.drive.actuation(x);
        let insertion = self.drive.insertion(x);
        // The muscles' lengths and times, where muscles drive the robot.
        let (muscle_lengths, inflation_times) = match self.robot.drive.muscles() {
            Some(m) => {
                let lengths = m.lengths(self.robot.body.section_length(), &rest_curvature);
                (lengths.clone(), m.inflation_times(&lengths))
            }
            None => (Vec::new(), Vec::new()),
        };
        IkResult {
            inflation_times,
            muscle_lengths,
            rest_curvature,
            tensions,
            field,
            insertion,
            tip_position: tool_point(&sol, self.robot.body.tool_offset),
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

/// The reference of `options` in `drive`'s coordinates, checked (the
/// muscles' `reference`, the tendons' `pretension`); no solver needed.
pub(crate) fn reference_of(
    robot: &Robot,
    drive: &DriveSpace,
    options: &IkOptions,
) -> Result<Option<Vec<f64>>> {
    let space = drive.space();
    if options.settings.strategy != Strategy::Equilibrium && space != ActuationSpace::Curvature {
        return Err(Error::argument(
            "strategy",
            format!(
                "the geometric strategy fits muscle curvatures; this robot's actuation is its {}",
                space.name()
            ),
        ));
    }
    drive.reference(
        robot,
        options.reference.as_deref(),
        options.pretension.as_deref(),
    )
}

/// Where an inverse solve may start after the first descent missed.
enum Start {
    /// Continuation in the target from the reference's tip.
    Continuation,
    Actuation(DVector<f64>),
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

#[cfg(test)]
mod tests {
    use super::lagrange_weights;

    /// The path's extrapolation is exact on polynomials of lower degree than
    /// its points, at uneven distances too.
    #[test]
    fn lagrange_weights_extrapolate_polynomials_of_lower_degree_exactly() {
        let nodes = [0.0, 1.0, 1.8, 3.1, 4.0];
        let at = 5.2;
        for degree in 0..nodes.len() {
            let f = |s: f64| {
                (0..=degree)
                    .map(|k| (k as f64 + 1.0) * s.powi(k as i32))
                    .sum::<f64>()
            };
            let used = &nodes[nodes.len() - degree - 1..];
            let weights = lagrange_weights(used, at);
            let guess: f64 = used.iter().zip(&weights).map(|(s, w)| w * f(*s)).sum();
            assert!(
                (guess - f(at)).abs() <= 1e-10 * f(at).abs(),
                "degree {degree}: {guess} against {}",
                f(at)
            );
        }
        // Linear through two even points: the last step again.
        assert_eq!(lagrange_weights(&[0.0, 1.0], 2.0), vec![-1.0, 2.0]);
    }
}
