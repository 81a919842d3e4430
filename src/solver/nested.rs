//! Nested iteration: a fine rod starts from the equilibrium of a coarse one.
//!
//! The direct attempt from the initial guess and the load path are global
//! searches whose course depends on n: at fine n the direct attempt found
//! another equilibrium or none where it had converged at coarse n, and the
//! iteration count grew with n (a held tip reached by 10 iterations at
//! n = 24 took 100 at n = 3 072 through continuation). A solve of many
//! elements therefore first solves the same scene on a coarse rod (the whole
//! strategy, at a small fraction of the cost), interpolates that equilibrium
//! to the fine nodes, and finishes with Newton. The coarse equilibrium is
//! within the discretisation error of the fine one, so Newton converges in a
//! few iterations whatever n is (mesh independence), on the same branch at
//! every n. If it does not (a coarse rod that misses a feature of the scene),
//! the fine solve falls back to the full strategy.

use super::{is_stable, Engine, Local, Settings, Solver};
use crate::error::Result;
use crate::quat::Quat;
use crate::scene::Scene;
use nalgebra::Vector3;

/// Fewest elements of the coarse rod (more if the scene needs them: see
/// [`coarse_elements`]).
const COARSE_ELEMENTS: usize = 24;

/// A rod of n elements starts from a coarse rod of n0 when n >= NEST_FACTOR n0.
const NEST_FACTOR: usize = 4;

/// The coarse rod has at least n / LEVEL_RATIO elements; it is itself solved
/// from a coarser one when it is long enough (the levels nest). From n0 = 24
/// Newton needs 3 to 5 iterations on the fine rod, each a full pass over it;
/// from a coarse rod 256 times shorter at most 2 (its discretisation error
/// is below 1e-7 of the fine rod's scale), so n = 1e6 goes through 3 906.
const LEVEL_RATIO: usize = 256;

/// The coarse rod reaches every held point with at least this share of the
/// fine rod's slack (see [`Scene::reach_slack`]): a coarse rod strained to
/// the edge of its shorter reach would be a far harder problem than the fine
/// one (a target 1e-5 L inside the reach of 80 elements took the coarse solve
/// the whole budget at n = 640, and the fine rod alone 242 iterations).
const REACH_SLACK_SHARE: f64 = 0.5;

/// Iteration limit of the fine Newton from the interpolated equilibrium.
const FINE_ITERATIONS: usize = 25;

/// Largest rotation of a node [rad] between the interpolated coarse
/// equilibrium and the fine one; a larger correction means Newton went to
/// another equilibrium. The discretisation error of a coarse rod is smaller
/// but not small: up to 0.26 rad was seen at n0 = 24 on a strongly twisted
/// scene whose fine equilibrium was the one load continuation finds.
const MAX_CORRECTION: f64 = 0.5;

/// The coarse rod for a solve of `n` elements, if nesting pays: the fewest
/// elements from [`COARSE_ELEMENTS`] (or `n / LEVEL_RATIO`) up that resolve the rest shape (as
/// accuracy on demand starts), are a multiple of the sections, put every point
/// load and held point on a node and reach the held points with slack to
/// spare, and resolve the loads' curvature scale (`load_parameter`, see
/// `RodModel::load_parameter`); at most `n / NEST_FACTOR`.
pub(crate) fn coarse_elements(
    scene: &Scene,
    settings: &Settings,
    load_parameter: f64,
) -> Option<usize> {
    let n = settings.elements_for(scene);
    // A coarse rod's contacts are other slots than the fine rod's.
    if settings.method.engine() != Engine::Potential(Local::Newton)
        || scene.has_contact()
        || n < NEST_FACTOR * COARSE_ELEMENTS
    {
        return None;
    }
    let m = scene.sections();
    // The loads bend the rod too: their curvature scale `kappa L` turns no
    // coarse element by more than half a radian. A coarse rod near the
    // scheme's limit of a radian an element (a tip moment of 26 EI/L coils the
    // rod four times: 24 and 26 elements fail) only spends the budget.
    let loaded = (2.0 * load_parameter).ceil().min(n as f64) as usize;
    let requested = COARSE_ELEMENTS.max(n / LEVEL_RATIO).max(loaded);
    let first = super::adaptive::starting_elements(scene, requested);
    let slack = scene.reach_slack(n);
    (first..=n / NEST_FACTOR).step_by(m).find(|&n0| {
        scene.check_elements(n0).is_ok()
            && matches!(scene.check_constraints(n0), Ok(None))
            && scene.reach_slack(n0) >= REACH_SLACK_SHARE * slack
    })
}

/// The coarse chain `coarse` (n0 + 1 nodes) at the n + 1 nodes of `out`:
/// node i sits at `s = i L / n`, between two coarse nodes, and takes the
/// rotation part way between theirs (about the axis of their relative
/// rotation, which is found once per coarse element).
pub(crate) fn interpolate(coarse: &[Quat], out: &mut [Quat]) {
    let n = out.len() - 1;
    for_each_interpolated(coarse, n, |i, q| out[i] = q);
}

/// Call `f(i, q_i)` with the coarse chain interpolated at each node `i` of
/// a chain of `n` elements, in order.
fn for_each_interpolated(coarse: &[Quat], n: usize, mut f: impl FnMut(usize, Quat)) {
    let n0 = coarse.len() - 1;
    let mut element = usize::MAX;
    let mut turn = Vector3::zeros();
    for i in 0..=n {
        // In floating point: `i * n0` may overflow a 32-bit usize.
        let x = i as f64 * n0 as f64 / n as f64;
        let j = (x.floor() as usize).min(n0 - 1);
        if j != element {
            element = j;
            // The relative rotation as a rotation vector (slerp's).
            let rel = coarse[j].conj() * coarse[j + 1];
            let sine = rel.v.norm();
            turn = if sine > 0.0 {
                rel.v * (2.0 * sine.atan2(rel.w) / sine)
            } else {
                Vector3::zeros()
            };
        }
        let t = x - j as f64;
        f(
            i,
            (coarse[j] * Quat::from_rotation_vector(turn * t)).normalized(),
        );
    }
}

/// How the nested start ended.
pub(crate) struct Nested {
    /// The fine rod converged to an equilibrium next to the coarse one, stable
    /// if that one is.
    pub converged: bool,
    /// The fine equilibrium is stable (tested).
    pub stable: bool,
    /// Iterations spent, the coarse solve's included.
    pub iterations: usize,
    /// The coarse solve's load-continuation steps.
    pub continuation_steps: usize,
}

impl Solver {
    /// Solve on the coarse rod of `n0` elements, then Newton on this rod from
    /// the interpolated equilibrium (reactions included), within `budget`
    /// iterations. On success the workspace holds the fine equilibrium. The
    /// coarse answer counts whether stable or not: a free rod's load path
    /// that ends unstable (the loading itself lost stability) stands at
    /// every n.
    pub(super) fn start_from_coarse(
        &mut self,
        n0: usize,
        budget: usize,
        tol: f64,
    ) -> Result<Nested> {
        // At most three quarters of the budget: a coarse rod that fails
        // leaves the fine rod's full strategy the rest.
        let coarse_settings = Settings {
            n_elements: Some(n0),
            max_iterations: (3 * budget / 4).max(1),
            ..self.settings.clone()
        };
        let mut coarse = Solver::new(&self.scene, coarse_settings)?;
        let solution = coarse.solve(None)?;
        let mut nested = Nested {
            converged: false,
            iterations: solution.iterations,
            continuation_steps: solution.continuation_steps,
            stable: false,
        };
        // A clamped tip's quaternion is taken on the side of each rod's own
        // rest tip, which moves with n: near a half turn from it the two rods
        // may pose problems a full turn apart.
        let same_tip = match (coarse.model.clamped_tip(), self.model.clamped_tip()) {
            (Some(a), Some(b)) => a.dot(b) > 0.0,
            _ => true,
        };
        if !solution.converged() || solution.iterations >= budget || !same_tip {
            return Ok(nested);
        }
        let (model, w) = (&self.model, &mut self.work);
        interpolate(&solution.quaternions, &mut w.q);
        w.q[0] = model.base();
        w.kkt.reactions.copy_from_slice(&coarse.work.kkt.reactions);
        let max_iter = FINE_ITERATIONS.min(budget - solution.iterations);
        let out = self.local.run(model, w, 1.0, max_iter, tol);
        nested.iterations += out.iterations;
        let resolved =
            model.max_element_turn(&w.q).max(model.max_rest_turn()) <= super::MAX_RESOLVED_TURN;
        if out.converged && resolved && next_to(&solution.quaternions, &w.q) {
            // A free rod loaded beyond its stability is answered unstable at
            // every n; otherwise the fine rod must be stable like the coarse.
            nested.stable = is_stable(model, w);
            nested.converged = nested.stable || !solution.stable;
        }
        Ok(nested)
    }
}

/// True if no node of the fine chain `q` is turned by more than
/// [`MAX_CORRECTION`] from the interpolated coarse chain: `|a . b|`, the
/// cosine of half the angle between two rotations whichever their signs.
fn next_to(coarse: &[Quat], q: &[Quat]) -> bool {
    let least = (0.5 * MAX_CORRECTION).cos();
    let mut next = true;
    for_each_interpolated(coarse, q.len() - 1, |i, x| {
        next &= x.dot(q[i]).abs() >= least;
    });
    next
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::element_turn;
    use crate::solver::Method;

    fn scene(json: &str) -> Scene {
        Scene::from_json_str(json).unwrap()
    }

    fn settings(n: usize) -> Settings {
        Settings {
            n_elements: Some(n),
            ..Settings::default()
        }
    }

    #[test]
    fn interpolation_of_a_uniform_arc_is_exact() {
        // A chain turning uniformly about a fixed axis: every fine node lies
        // on it, between the coarse nodes as well as on them.
        let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
        let chain = |n: usize| -> Vec<Quat> {
            (0..=n)
                .map(|i| Quat::from_rotation_vector(axis * (2.0 * i as f64 / n as f64)))
                .collect()
        };
        let mut fine = vec![Quat::IDENTITY; 61];
        interpolate(&chain(6), &mut fine);
        for (a, b) in fine.iter().zip(chain(60)) {
            assert!(
                element_turn(*a, b).min(2.0 * std::f64::consts::PI - element_turn(*a, b)) < 1e-14
            );
        }
    }

    #[test]
    fn the_coarse_rod_is_only_used_where_it_pays_and_fits() {
        let plain = scene(
            r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [1, 0, 0]}"#,
        );
        assert_eq!(coarse_elements(&plain, &settings(80), 0.2), None);
        assert_eq!(
            coarse_elements(&plain, &settings(96), 0.2),
            Some(COARSE_ELEMENTS)
        );
        let lm = Settings {
            method: Method::LevenbergMarquardt,
            ..settings(960)
        };
        assert_eq!(coarse_elements(&plain, &lm, 0.2), None);
        // A point load at 0.35 L is on a node only for multiples of 20.
        let loaded = scene(
            r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
                "point_loads": [{"s": 0.35, "force": [1, 0, 0]}]}"#,
        );
        assert_eq!(coarse_elements(&loaded, &settings(960), 0.35), Some(40));
        // A coiled rod: the coarse rod resolves its rest shape (0.25 rad per element).
        let coiled = scene(
            r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
                "rest_curvature": [[0, 20]], "tip_force": [1, 0, 0]}"#,
        );
        assert_eq!(coarse_elements(&coiled, &settings(960), 0.2), Some(80));
    }

    #[test]
    fn a_coarse_rod_strained_to_its_reach_is_not_used() {
        // The clamped base keeps n elements about 0.2 theta^2 L / n short of
        // full reach at theta from the base tangent: a target 0.02 % short of
        // full reach at 0.3 rad is just inside the reach of 80 elements.
        let (theta, distance) = (0.3f64, 0.9998f64);
        let target = [0.0, distance * theta.sin(), distance * theta.cos()];
        let pinned = scene(&format!(
            r#"{{"length": 1, "stiffness": {{"kx": 1, "ky": 1, "kz": 1}},
                "tip": {{"type": "pinned", "position": {target:?}}}}}"#
        ));
        let n0 = coarse_elements(&pinned, &settings(3072), 0.0).unwrap();
        assert!(pinned.reach_slack(n0) >= REACH_SLACK_SHARE * pinned.reach_slack(3072));
        assert!(pinned.reach_slack(COARSE_ELEMENTS) < REACH_SLACK_SHARE * pinned.reach_slack(3072));
    }
}
