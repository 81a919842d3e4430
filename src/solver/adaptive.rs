//! Accuracy on demand: the solver chooses the discretisation. With a scheme
//! of order `p` (2 for `fd2`, 4 for `fe4` and shooting) the error of the
//! solve at `k n` is about the difference between the nodes of the solves at
//! `n` and `k n`, over `k^p - 1`. From a first resolving `n` (the base) the
//! solve at `2 n` gives an estimate, which predicts the `n` that meets the
//! tolerance with a small margin; that `n` (a multiple of the base) is solved
//! and estimated against the base in turn, until the largest estimate over
//! the backbone is below the tolerance. Richardson extrapolation `r_kn +
//! (r_kn - r_n) / (k^p - 1)` of the tip removes its leading error term.
//!
//! By shooting a solve is estimated by a finer shot at `2 n` from its base
//! wrench (chord steps and the nodes, no pass: [`shooting::finer_shot`]):
//! their difference over `1 - 2^-p` is the solve's own error (nearly the
//! whole difference is the coarser one's, so this estimate holds up to a
//! larger element turn, [`SHOT_OWN_ESTIMATE_TURN`], than the finer one's).
//! Where it meets the tolerance the solve is the answer; else the n it
//! predicts is solved and estimated in turn. Where no finer shot fits within
//! `max_elements`, or a finer shot does not converge directly, or the solve
//! needed its load path (no warm start), the pair of solves estimates the
//! finer one as above. The first shot is at the n a prior of RK4's error
//! predicts from the scene ([`SHOT_ERROR_CONSTANT`], bounded by a probe
//! shot's shape), from the probe's wrench and Jacobian ([`shot_first_pass`]).

use super::{check_tolerance, Engine, Method, Settings, Solution, Solver, Status, MAX_ELEMENTS};
use crate::error::{Error, Result};
use crate::methods::shooting::{self, WarmShot};
use crate::model::{element_turn, slerp, RodModel};
use crate::quat::Quat;
use crate::read::{as_argument, count, finite, Table};
use crate::scene::Scene;
use crate::terms::section_of;
use crate::value::Value;
use nalgebra::Vector3;

/// What accuracy to reach and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Accuracy {
    /// Tip error tolerance, relative to the length `L`.
    pub tol: f64,
    /// Return the Richardson-extrapolated tip (marked in the Solution).
    pub richardson: bool,
    /// Largest number of elements tried (default 10 240).
    pub max_elements: usize,
}

impl Accuracy {
    /// An accuracy of `tol` with the defaults: no extrapolation, at most 10 240 elements.
    pub fn new(tol: f64) -> Self {
        Accuracy {
            tol,
            richardson: false,
            max_elements: 10_240,
        }
    }
}

/// A value as the user wrote it, for a refusal.
fn shown_value(v: &Value) -> String {
    match v {
        Value::String(s) => format!("'{s}'"),
        other => other.kind().to_string(),
    }
}

/// Range of the relative tip tolerance: 1e-12 L is about what double
/// precision leaves of a tip at the largest n; above 0.1 L is no accuracy.
pub const ACCURACY_TOL_RANGE: (f64, f64) = (1e-12, 1e-1);

/// Largest turning of one element [rad] at which the error estimate from the
/// solves at n and 2n is trusted (the error is then in its asymptotic,
/// second-order regime); coarser solves only lead to finer ones.
pub const ASYMPTOTIC_TURN: f64 = 0.25;

/// [`ASYMPTOTIC_TURN`] of a scheme of order `order`: a quadratic element
/// (order 4) follows twice the turn of a linear one as closely.
pub fn asymptotic_turn(order: i32) -> f64 {
    if order >= 4 {
        2.0 * ASYMPTOTIC_TURN
    } else {
        ASYMPTOTIC_TURN
    }
}

/// The first n of accuracy on demand without `n_elements`: a fourth-order
/// solve of a few elements is often already within the tolerance.
const FOURTH_ORDER_START: usize = 4;

impl Accuracy {
    /// Every key of [`Accuracy::set`].
    pub const KEYS: [&'static str; 3] = ["tol", "refine", "max_elements"];

    /// Set one field from a value: `tol` a number, `refine` `"richardson"`
    /// or null (none), `max_elements` a count; ranges are
    /// [`validate`](Accuracy::validate)'s.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        match key {
            "tol" => self.tol = finite(value, key).map_err(as_argument)?,
            "refine" => {
                self.richardson = match value {
                    Value::Null => false,
                    Value::String(s) if s == "richardson" => true,
                    other => {
                        return Err(Error::argument(
                            key,
                            format!("expected 'richardson' or None, got {}", shown_value(other)),
                        ))
                    }
                }
            }
            "max_elements" => {
                self.max_elements = count(value, key, MAX_ELEMENTS).map_err(as_argument)?
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

    /// An accuracy from a table of [`Accuracy::KEYS`] (`tol` required), validated.
    pub fn from_value(v: &Value) -> Result<Accuracy> {
        let table = Table::top(v, "accuracy").map_err(as_argument)?;
        let Some(tol) = table.get("tol") else {
            // Named by what was given without it.
            let given = table.entries.first().map_or("tol", |(k, _)| k.as_str());
            return Err(Error::argument(
                given,
                "needs tol (accuracy on demand: refine and max_elements apply to it)",
            ));
        };
        let mut accuracy = Accuracy::new(f64::NAN);
        accuracy.set("tol", tol)?;
        for (k, x) in table.entries {
            accuracy.set(k, x)?;
        }
        accuracy.validate()?;
        Ok(accuracy)
    }

    /// Every field as a table ([`Accuracy::from_value`] reads it back).
    pub fn to_value(&self) -> Value {
        let refine = if self.richardson {
            Value::String("richardson".into())
        } else {
            Value::Null
        };
        Value::Map(vec![
            ("tol".into(), Value::Number(self.tol)),
            ("refine".into(), refine),
            (
                "max_elements".into(),
                Value::Number(self.max_elements as f64),
            ),
        ])
    }

    /// Refuse an accuracy out of range, naming the field.
    pub fn validate(&self) -> Result<()> {
        check_tolerance("tol", self.tol, ACCURACY_TOL_RANGE)?;
        if self.max_elements == 0 || self.max_elements > MAX_ELEMENTS {
            return Err(Error::argument(
                "max_elements",
                format!("must lie in [1, {MAX_ELEMENTS}], got {}", self.max_elements),
            ));
        }
        Ok(())
    }
}

/// The first n of accuracy on demand: at least `requested`, a count that
/// puts every located input on a node ([`Scene::node_multiple`]: so do its
/// multiples, the n that refinement tries), and fine enough that no element
/// turns by more than [`ASYMPTOTIC_TURN`] at rest (a coiled rod needs many
/// elements before any estimate means anything).
pub fn starting_elements(scene: &Scene, requested: usize) -> usize {
    starting_elements_of_order(scene, requested, 2)
}

/// [`starting_elements`] for a scheme of order `order` (see [`asymptotic_turn`]).
pub fn starting_elements_of_order(scene: &Scene, requested: usize, order: i32) -> usize {
    starting_elements_within(scene, requested, asymptotic_turn(order))
}

/// [`starting_elements`] with elements turning by at most `turn` [rad] at rest.
fn starting_elements_within(scene: &Scene, requested: usize, turn: f64) -> usize {
    let m = node_step(scene);
    let rest_turn = scene
        .rest_curvature
        .iter()
        .map(|k| k[0].hypot(k[1]))
        .fold(0.0, f64::max)
        * scene.length;
    let resolving = (rest_turn / turn).ceil().min(MAX_ELEMENTS as f64) as usize;
    requested.max(resolving).max(1).div_ceil(m) * m
}

/// What every n of accuracy on demand is a multiple of: the count that
/// puts every located input on a node ([`Scene::node_multiple`]).
fn node_step(scene: &Scene) -> usize {
    // A count no located input allows is refused by the solve's own check.
    scene
        .node_multiple(MAX_ELEMENTS)
        .unwrap_or_else(|_| scene.sections())
}

/// Solve `scene` to an accuracy of `accuracy.tol * L` over the whole
/// backbone, starting at [`starting_elements`] (see the module documentation).
pub fn solve_to_accuracy(
    scene: &Scene,
    settings: Settings,
    accuracy: &Accuracy,
) -> Result<Solution> {
    let started = std::time::Instant::now();
    let mut solution = refine_until_met(scene, settings, accuracy)?;
    solution.solve_time = started.elapsed().as_secs_f64();
    Ok(solution)
}

/// Margin of the predicted n: it aims at the tolerance over this factor.
const PREDICTION_MARGIN: f64 = 1.5;

/// The refinement of [`solve_to_accuracy`], by the method chosen for it
/// ([`Settings::method_for`]). Where the core chose shooting, its first
/// solve decides: one that shooting's Newton did not solve directly from
/// its rigid estimate (a large load: its load path then costs several times
/// Newton's on the potential, 1 283 iterations against 76 on a cantilever
/// under (0.5, -30) EI / L^2) or whose answer is unstable (a column past
/// buckling: the potential's load path finds the buckled equilibrium) hands
/// the refinement to the discrete potential; the iterations count both.
fn refine_until_met(scene: &Scene, settings: Settings, accuracy: &Accuracy) -> Result<Solution> {
    accuracy.validate()?;
    let method = settings.method_for(scene, Some(accuracy.tol));
    let chosen = settings.method == Method::Auto && method == Method::Shooting;
    let shooting_fits = |first: &Solution| {
        !chosen || (first.converged() && first.stable && first.continuation_steps == 0)
    };
    let first_try = Settings {
        method,
        // Chosen shooting is kept only where its Newton converges directly:
        // a budget for that alone (it takes 4 to 6 iterations on the race's
        // scenes, a warm finer solve fewer).
        max_iterations: if chosen {
            settings.max_iterations.min(CHOSEN_SHOOTING_ITERATIONS)
        } else {
            settings.max_iterations
        },
        ..settings.clone()
    };
    let probe = match refine_with(scene, first_try, accuracy, &shooting_fits)? {
        Refined::Done(solution)
            if !chosen
                || ((solution.converged() || solution.status == Status::ToleranceNotMet)
                    && solution.stable) =>
        {
            return Ok(solution)
        }
        // (A finer shot that failed hands over too.)
        Refined::Done(tried) | Refined::HandedOver(tried) => tried,
    };
    let settings = Settings {
        method: Method::Newton,
        ..settings
    };
    match refine_with(scene, settings, accuracy, &|_| true)? {
        Refined::Done(mut solution) | Refined::HandedOver(mut solution) => {
            solution.iterations += probe.iterations;
            solution.continuation_steps += probe.continuation_steps;
            Ok(solution)
        }
    }
}

/// The iteration budget of each solve of shooting that the core chose.
const CHOSEN_SHOOTING_ITERATIONS: usize = 30;

/// How [`refine_with`] ended: with the answer, or at its first solve, which
/// the caller's test refused (`keep_going`).
enum Refined {
    Done(Solution),
    HandedOver(Solution),
}

/// [`refine_until_met`] by the method of `settings`, while `keep_going`
/// accepts its first solve.
fn refine_with(
    scene: &Scene,
    settings: Settings,
    accuracy: &Accuracy,
    keep_going: &dyn Fn(&Solution) -> bool,
) -> Result<Refined> {
    let length = scene.length;
    let target = accuracy.tol * length;
    let settings = Settings {
        scheme: Some(settings.scheme_for(scene, Some(accuracy.tol))),
        ..settings
    };
    let order = settings.order();
    // Each pass on a worker thread only where it may outlast the interrupt
    // poll (see `interrupt::on_worker_if`): most solves end at a few
    // hundred elements, where a thread start would cost more than the solve.
    // A pass starts from the last one's shape refined and, by shooting, from
    // its base wrench and Jacobian (`WarmShot`: a few chord steps).
    let solve_at = |n: usize, initial: Vec<Quat>, warm: Option<WarmShot>| -> Result<Pass> {
        at_elements(scene, &settings, n, move |scene, settings| {
            let mut solver = Solver::new(&scene, settings)?;
            solver.warm_shot = warm;
            let solution = solver.solve(Some(&initial))?;
            Ok((solution, solver.last_shot))
        })
    };
    let requested = match (settings.n_elements, order) {
        (Some(n), _) => n,
        (None, 4..) => FOURTH_ORDER_START,
        (None, _) => settings.elements_for(scene),
    };
    let turn = asymptotic_turn(order);
    let n0 = starting_elements_within(scene, requested, turn);
    let shooting = settings.method.engine() == Engine::Shooting;
    let (n_first, warm, probed) = match shooting {
        true => shot_first_pass(scene, &settings, accuracy, (n0, requested))?,
        false => (n0, None, 0),
    };
    let first = Settings {
        n_elements: Some(n_first),
        ..settings.clone()
    };
    let (long, first_scene) = (first.has_long_passes(), scene.clone());
    let (trivial, (mut base, mut base_shot)) = crate::interrupt::on_worker_if(long, move || {
        let mut solver = Solver::new(&first_scene, first)?;
        solver.warm_shot = warm;
        let base = solver.solve(None)?;
        Ok((solver.model().is_trivial(), (base, solver.last_shot)))
    })?;
    base.iterations += probed;
    if !keep_going(&base) {
        return Ok(Refined::HandedOver(base));
    }
    let straight = scene
        .rest_curvature
        .iter()
        .all(|k| k[0] == 0.0 && k[1] == 0.0);
    if straight && trivial {
        // The unloaded straight rod is exact at any n: nothing to refine.
        base.error_estimate = Some(0.0);
        return Ok(Refined::Done(base));
    }
    let mut iterations = base.iterations;
    // An underresolved equilibrium is no answer yet, but a finer n may resolve it.
    let usable = |s: &Solution| s.converged() || s.status == Status::Underresolved;
    let not_met = |mut s: Solution, iterations: usize, why: String| {
        s.iterations = iterations;
        if s.converged() {
            s.status = Status::ToleranceNotMet;
            s.message = why;
        }
        s
    };
    // A shot's own error is estimated from a finer shot alone (see
    // `finer_shot_at`), trusted up to a larger element turn than the finer
    // pass's estimate.
    let own_turn = if shooting {
        SHOT_OWN_ESTIMATE_TURN
    } else {
        turn
    };
    let finer_shot_at = |n: usize, warm: WarmShot| {
        at_elements(scene, &settings, n, move |scene, settings| {
            let model = RodModel::new(&scene, n);
            let limits = shot_limits(&model, &settings);
            Ok(shooting::finer_shot(&model, &scene, limits, &warm))
        })
    };
    // Pre-asymptotic bases (an element turning by more than ASYMPTOTIC_TURN)
    // only lead to finer ones; a shot estimated by its own finer shot leads
    // to the n its estimate predicts.
    loop {
        if !usable(&base) {
            base.iterations = iterations;
            return Ok(Refined::Done(base));
        }
        let base_turn = if base.converged() {
            max_turn(scene, &base)
        } else {
            f64::INFINITY
        };
        let n = 2 * base.n_elements;
        if shooting && base_turn <= own_turn && n <= accuracy.max_elements {
            crate::interrupt::check()?;
            let finer = match base_shot.map(|warm| finer_shot_at(n, warm)).transpose()? {
                Some(Ok(finer)) => Some(finer),
                Some(Err(spent)) => {
                    iterations += spent;
                    None
                }
                None => None,
            };
            if let Some(finer) = finer {
                iterations += finer.iterations;
                let difference = node_difference(&base.positions, &finer.positions, 2);
                let ratio = 2f64.powi(order) - 1.0;
                // The base's own error: the difference over 1 - 2^-p.
                let own = difference * (ratio + 1.0) / ratio;
                base.error_estimate = Some(own);
                if accuracy.richardson {
                    let (r_n, r_kn) = (base.tip_position(), finer.positions[n]);
                    base.extrapolated_tip = Some(r_kn + (r_kn - r_n) / ratio);
                }
                if own <= target {
                    base.iterations = iterations;
                    return Ok(Refined::Done(base));
                }
                // The n whose own error meets the tolerance with a margin,
                // if the error falls as n^-p: a multiple of this one, at
                // most the largest allowed (2 m is: the finer shot was).
                let m = base.n_elements;
                let needed = m as f64 * (PREDICTION_MARGIN * own / target).powf(1.0 / order as f64);
                let k = ((needed / m as f64).ceil() as usize)
                    .max(2)
                    .min(accuracy.max_elements / m);
                crate::interrupt::check()?;
                let (mut fine, fine_shot) =
                    solve_at(k * m, refine(&base.quaternions, k), Some(finer.warm))?;
                iterations += fine.iterations;
                if fine.converged() && 2 * k * m > accuracy.max_elements {
                    // No finer shot fits within max_elements: the pair's
                    // estimate of the finer solve, as the passes' loop's.
                    let estimate =
                        estimate_by_pair(&base, &mut fine, k, order, accuracy.richardson);
                    if estimate <= target {
                        fine.iterations = iterations;
                        return Ok(Refined::Done(fine));
                    }
                    let why = format!(
                        "tolerance not met: {} elements reached the limit (max_elements {}), error estimate {estimate:.2e} m > tol * L = {target:.2e} m",
                        k * m,
                        accuracy.max_elements,
                    );
                    return Ok(Refined::Done(not_met(fine, iterations, why)));
                }
                (base, base_shot) = (fine, fine_shot);
                continue;
            }
        }
        if base_turn <= turn {
            break;
        }
        if n > accuracy.max_elements {
            let why = format!(
                "tolerance not met: no error estimate, the first resolving n = {} leaves no finer n within max_elements {}",
                base.n_elements, accuracy.max_elements
            );
            return Ok(Refined::Done(not_met(base, iterations, why)));
        }
        crate::interrupt::check()?;
        (base, base_shot) = solve_at(n, refine(&base.quaternions, 2), base_shot)?;
        iterations += base.iterations;
    }
    let n_base = base.n_elements;
    let mut k = 2;
    loop {
        if k * n_base > accuracy.max_elements {
            let why = format!(
                "tolerance not met: {} elements would be needed, beyond max_elements {}",
                k * n_base,
                accuracy.max_elements
            );
            return Ok(Refined::Done(not_met(base, iterations, why)));
        }
        crate::interrupt::check()?;
        let (mut fine, _) = solve_at(k * n_base, refine(&base.quaternions, k), base_shot)?;
        iterations += fine.iterations;
        if !usable(&fine) {
            fine.iterations = iterations;
            return Ok(Refined::Done(fine));
        }
        let estimate = estimate_by_pair(&base, &mut fine, k, order, accuracy.richardson);
        if estimate <= target {
            fine.iterations = iterations;
            return Ok(Refined::Done(fine));
        }
        // The n that meets the tolerance with a margin, if the error falls
        // as n^-p: a multiple of the base, finer than this one.
        let needed =
            (k * n_base) as f64 * (PREDICTION_MARGIN * estimate / target).powf(1.0 / order as f64);
        let next = ((needed / n_base as f64).ceil() as usize).max(k + 1);
        if next * n_base > accuracy.max_elements {
            if k * n_base < accuracy.max_elements / n_base * n_base {
                // The finest n allowed is worth one more solve.
                k = accuracy.max_elements / n_base;
                continue;
            }
            let why = format!(
                "tolerance not met: {} elements reached the limit (max_elements {}), error estimate {estimate:.2e} m > tol * L = {:.2e} m",
                k * n_base,
                accuracy.max_elements,
                target
            );
            return Ok(Refined::Done(not_met(fine, iterations, why)));
        }
        k = next;
    }
}

/// The prior of a shot's error: RK4 at `n` elements misses the rod's nodes
/// by about `C L (omega L / n)^4`, `omega` the scene's turning rate,
/// `omega^2 = kappa^2 + w F / EI` ([`crate::terms::Terms::turning`], a force
/// weighing `w` = [`SHOT_FORCE_WEIGHT`]). Measured `C` (the largest node error over `L`,
/// times `(n / (omega L))^4`, n = 4 to 32): free cantilevers alpha = 0.3 to
/// 30 in and out of plane 0.4e-3 (alpha = 30) to 1.3e-3 (alpha = 1), tip
/// moments and precurved or coiled rods 0.6e-3 to 1.0e-3, gravity 0.6e-3 to
/// 0.7e-3; combined, a precurved rod under a tip force 0.4e-3, the race's
/// precurved ten sections under gravity 1.1e-3, the same under a tip force
/// 4.5e-3.
const SHOT_ERROR_CONSTANT: f64 = 1e-3;

/// The weight of a force in the turning rate of [`SHOT_ERROR_CONSTANT`].
const SHOT_FORCE_WEIGHT: f64 = 1.4;

/// The margin of the prior: it aims at the tolerance over this factor.
const SHOT_PRIOR_MARGIN: f64 = 1.3;

/// The n whose shot the prior of [`SHOT_ERROR_CONSTANT`] expects to meet
/// `tol` (relative to the length) with its margin, for a rod that turns by
/// `turns` [rad] over its length at the prior's rate.
fn shot_prior_elements(turns: f64, tol: f64) -> usize {
    let n = turns * (SHOT_PRIOR_MARGIN * SHOT_ERROR_CONSTANT / tol).powf(0.25);
    n.ceil().min(MAX_ELEMENTS as f64) as usize
}

/// How much faster than the largest curvature it bends the rod to the
/// prior's rate may turn a rod it fits: 2.5 measured (a cantilever at alpha
/// = 0.3, where a force's rate is 2.5 times the curvature it bends the rod
/// to; 1.1 to 1.9 at alpha = 1 to 30 and under gravity). Bounding a
/// moment's part by the curvature alone was tried and not kept: on random
/// scenes with unequal bending stiffnesses under tip moments, whose error
/// constant is up to three times the prior's, it put four of 64 first
/// shots at 1e-8 short of the tolerance (a second pass: twice the time).
const SHOT_CURVATURE_BOUND: f64 = 2.5;

/// The first pass of accuracy on demand by shooting and where it starts:
/// `(n, warm start, the probe's iterations)`. At the n the prior predicts
/// ([`shot_prior_elements`] at the scene's turning rate,
/// [`crate::terms::Terms::turning`]) where that is finer than `n0`,
/// at most half `max_elements` (its own estimate's finer shot must fit),
/// from a probe at `n0` ([`shooting::probe`]: its wrench and Jacobian, a
/// fraction of a Jacobian's cost at that n). The probe's shape bounds the
/// rate: [`SHOT_CURVATURE_BOUND`] times its largest curvature (a load along
/// the rod, a hanging rod, turns it not at all; a force across the stiffer
/// axis of an unequal section less than across the softer). The pass's own
/// estimate decides as for any shot: a prior that falls short costs a finer
/// pass, as a first pass at `n0` always did. Where the probe does not
/// converge directly the first pass is at `n0`, cold (its own load path).
fn shot_first_pass(
    scene: &Scene,
    settings: &Settings,
    accuracy: &Accuracy,
    (n0, requested): (usize, usize),
) -> Result<(usize, Option<WarmShot>, usize)> {
    let step = node_step(scene);
    let room = accuracy.max_elements / 2 / step * step;
    let turn = asymptotic_turn(4);
    let at_rate = |rate: f64| {
        let prior = shot_prior_elements(rate * scene.length, accuracy.tol);
        starting_elements_within(scene, requested.max(prior), turn)
            .min(room)
            .max(n0)
    };
    let turning = crate::terms::Terms::new(scene, &scene.mesh(n0)).turning(scene.length);
    let rate = (turning.curvature_squared + SHOT_FORCE_WEIGHT * turning.force).sqrt();
    if at_rate(rate) <= n0 {
        return Ok((n0, None, 0));
    }
    let model = RodModel::new(scene, n0);
    let (probe, iterations) = shooting::probe(&model, scene, shot_limits(&model, settings));
    let Some(probe) = probe else {
        return Ok((n0, None, iterations));
    };
    let curvature = probe
        .quaternions
        .windows(2)
        .zip(model.mesh().element_lengths())
        .map(|(q, h)| element_turn(q[0], q[1]) / h)
        .fold(0.0, f64::max);
    let n = at_rate(rate.min(SHOT_CURVATURE_BOUND * curvature));
    Ok((n, Some(probe.warm), iterations))
}

/// Shooting's limits of a solve of `model` with `settings`.
fn shot_limits(model: &RodModel, settings: &Settings) -> shooting::Limits {
    shooting::Limits {
        tol: model.effective_tol(settings.residual_tol),
        max_iterations: settings.max_iterations,
        min_continuation_step: settings.min_continuation_step,
    }
}

/// Largest element turn [rad] at which a shot's own error is estimated from
/// a finer shot at twice its n (the difference over `1 - 2^-4`): within 1.5 %
/// of the true error up to 0.94 rad (the largest turn measured) on free
/// cantilevers (alpha = 1 to 30, in and out of plane), a tip moment,
/// precurved and coiled rods, where the finer shot's estimate (the
/// difference over `2^4 - 1`) is 27 % off at 0.94 rad. The coarse error is
/// nearly the whole difference, the fine one only its remainder.
pub const SHOT_OWN_ESTIMATE_TURN: f64 = 0.95;

/// `work` on the scene with `settings` at `n` elements, on a worker thread
/// only where the pass may outlast the interrupt poll.
fn at_elements<R: Send + 'static>(
    scene: &Scene,
    settings: &Settings,
    n: usize,
    work: impl FnOnce(Scene, Settings) -> Result<R> + Send + 'static,
) -> Result<R> {
    let settings = Settings {
        n_elements: Some(n),
        ..settings.clone()
    };
    let long = settings.has_long_passes();
    let scene = scene.clone();
    crate::interrupt::on_worker_if(long, move || work(scene, settings))
}

/// A pass's solution and, by shooting, where a finer pass starts.
type Pass = (Solution, Option<WarmShot>);

/// The error estimate of `fine`, the solve at `k` times `coarse`'s n, from
/// the pair: their largest node difference over `k^order - 1` (the whole
/// backbone: a held tip never moves, so the tip alone would estimate the
/// error of a pinned rod as zero), set in `fine` with, asked, the
/// Richardson-extrapolated tip.
fn estimate_by_pair(
    coarse: &Solution,
    fine: &mut Solution,
    k: usize,
    order: i32,
    richardson: bool,
) -> f64 {
    let ratio = (k as f64).powi(order) - 1.0;
    let estimate = node_difference(&coarse.positions, &fine.positions, k) / ratio;
    fine.error_estimate = Some(estimate);
    if richardson {
        let (r_n, r_kn) = (coarse.tip_position(), fine.tip_position());
        fine.extrapolated_tip = Some(r_kn + (r_kn - r_n) / ratio);
    }
    estimate
}

/// Largest distance between the nodes `coarse` and the same nodes of the `k`
/// times finer `fine` [m].
fn node_difference(coarse: &[Vector3<f64>], fine: &[Vector3<f64>], k: usize) -> f64 {
    coarse
        .iter()
        .zip(fine.iter().step_by(k))
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
}

/// Largest element turning of a solution [rad], rest turning included.
fn max_turn(scene: &Scene, sol: &Solution) -> f64 {
    let n = sol.n_elements;
    let mesh = scene.mesh(n);
    let sections = scene.rest_curvature.len().max(1);
    let rest = mesh
        .element_lengths()
        .iter()
        .enumerate()
        .filter_map(|(i, h)| {
            let k = scene.rest_curvature.get(section_of(i, sections, n))?;
            Some(h * k[0].hypot(k[1]))
        })
        .fold(0.0, f64::max);
    sol.quaternions
        .windows(2)
        .map(|p| element_turn(p[0], p[1]))
        .fold(rest, f64::max)
}

/// The nodes of a `k` times finer discretisation: every node kept, `k - 1`
/// evenly turned rotations between neighbours.
fn refine(q: &[Quat], k: usize) -> Vec<Quat> {
    let mut out = Vec::with_capacity(k * (q.len() - 1) + 1);
    for pair in q.windows(2) {
        let b = if pair[0].dot(pair[1]) < 0.0 {
            -pair[1]
        } else {
            pair[1]
        };
        out.push(pair[0]);
        out.extend((1..k).map(|j| slerp(pair[0], b, j as f64 / k as f64)));
    }
    out.push(q[q.len() - 1]);
    out
}
