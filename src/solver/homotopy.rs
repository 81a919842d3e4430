//! A start for a cold solve whose rest shape passes through an obstacle.
//!
//! The load path starts at the rest shape, which is then no admissible
//! state, and Newton from it may land on the obstacle's far side or not
//! converge. Two homotopies bring the rod to a start instead, each a
//! sequence of warm solves with adaptive steps:
//!
//! * the curl ([`Solver::curl_from_straight`]): the rest curvature ramped
//!   from straight, the loads at full scale, as a robot's muscles curl it
//!   (with friction this is the history);
//! * the approach ([`Solver::approach_obstacles`]), where the straight rod
//!   passes through an obstacle too (a robot hanging closer to a floor than
//!   its length): the obstacles moved in from where the rod's free
//!   equilibrium clears them, every gap offset by the free equilibrium's
//!   depth and the offset ramped to zero. An offset gap is a contact radius
//!   `r - (1 - alpha) d`, so each step is the scene itself with another
//!   radius, whatever the obstacles' shapes.

use super::contact::{self, Site};
use super::Solver;
use crate::interrupt;
use crate::model::RodModel;
use crate::quat::Quat;
use crate::scene::Scene;
use nalgebra::Vector3;

/// A homotopy a cold solve took to its start: which, for which obstacle,
/// its steps, their Newton iterations, and why it stopped short.
#[derive(Debug, Clone)]
pub(super) struct Homotopy {
    kind: Kind,
    obstacle: usize,
    pub(super) steps: usize,
    pub(super) iterations: usize,
    failed: Option<String>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Curl,
    Approach,
    /// The approach's start, the free equilibrium, cleared them already.
    Free,
}

impl Homotopy {
    fn new(kind: Kind, obstacle: usize) -> Homotopy {
        Homotopy {
            kind,
            obstacle,
            steps: 0,
            iterations: 0,
            failed: None,
        }
    }

    /// The solve message's note: what was done and with how many solves.
    pub(super) fn note(&self) -> String {
        let o = self.obstacle;
        match (self.kind, &self.failed) {
            (Kind::Curl, None) => format!(
                "; the rest shape passes through obstacles[{o}], so the rod was curled to it from \
                 straight first ({} solves)",
                self.steps
            ),
            (Kind::Curl, Some(why)) => format!(
                "; the rest shape passes through obstacles[{o}], and curling the rod to it from \
                 straight failed: {why}"
            ),
            (Kind::Approach, None) => format!(
                "; the rest shape passes through obstacles[{o}], so the obstacles were moved in \
                 from where the rod's free equilibrium clears them first ({} solves)",
                self.steps
            ),
            (Kind::Free, _) => format!(
                "; the rest shape passes through obstacles[{o}], so the solve started from the \
                 rod's free equilibrium, which clears them"
            ),
            (Kind::Approach, Some(why)) => format!(
                "; the rest shape passes through obstacles[{o}], and moving the obstacles in from \
                 where the rod's free equilibrium clears them failed: {why}"
            ),
        }
    }
}

/// A homotopy's first step (of the way from 0 to 1), its shortest, and how
/// many iterations a step may take and still let the next one double.
const FIRST_STEP: f64 = 0.25;
const MIN_STEP: f64 = 1.0 / 64.0;
const EASY_STEP: usize = 8;

/// How far the approach's start clears every obstacle, of the rod's length.
const APPROACH_CLEARANCE: f64 = 1e-3;

/// How deep a straight rod may reach into an obstacle and still clear it,
/// of the rod's length (`RodModel::obstacle_at_rest`'s round-off).
const AT_REST_DEPTH: f64 = 1e-9;

/// The cosine of the largest angle between an obstacle's normal and a
/// straight rod's axis at which it presses the rod along its axis.
const ALONG_AXIS: f64 = 0.9;

impl Solver {
    /// Where the rest shape passes through an obstacle, the load path has no
    /// start (the rest shape is not admissible): the rod's rest curvature is
    /// ramped from straight instead, the loads at full scale, as a robot's
    /// muscles curl it. The straight rod is solved cold, then each scaled
    /// rest curvature warm from the last, with adaptive steps, up to the
    /// scene's own: the state its solve starts from (and certifies). With
    /// friction this is the history: the loads, then the curl. `Err`: why
    /// it could not (the straight rod fails too, or a step will not go).
    pub(super) fn curl_from_straight(
        &mut self,
        obstacle: usize,
    ) -> std::result::Result<Vec<Quat>, String> {
        let full = self.scene.rest_curvature.clone();
        let base = self.scene.clone();
        let scaled = move |alpha: f64| -> Scene {
            let mut scene = base.clone();
            scene.rest_curvature = full.iter().map(|k| [alpha * k[0], alpha * k[1]]).collect();
            scene
        };
        let mut settings = self.settings.clone();
        settings.n_elements = Some(self.model.n());
        let mut homotopy = Homotopy::new(Kind::Curl, obstacle);
        // `Err` where a curled scene cannot be solved at all (its reason),
        // `None` where its solve does not end converged and stable.
        let solve = |alpha: f64, initial: Option<&[Quat]>, h: &mut Homotopy| {
            let mut solver = Solver::new(&scaled(alpha), settings.clone()).map_err(|e| {
                format!("the rod curled to {alpha:.3} of its rest curvature is refused: {e}")
            })?;
            let sol = solver.solve_strategy(initial).map_err(|e| e.to_string())?;
            h.iterations += sol.iterations;
            h.steps += 1;
            Ok::<_, String>((sol.converged() && sol.stable).then_some(sol.quaternions))
        };
        let outcome = match solve(0.0, None, &mut homotopy) {
            Ok(Some(q)) => self.ramp(q, &mut homotopy, |alpha, q, h| solve(alpha, Some(q), h)),
            Ok(None) => Err("the straight rod does not converge either".to_string()),
            Err(why) => Err(why),
        };
        homotopy.failed = outcome.as_ref().err().cloned();
        self.homotopies.push(homotopy);
        outcome
    }

    /// Where the straight rod passes through an obstacle too, the obstacles
    /// are moved in instead (see the module's notes): from the rod's free
    /// equilibrium (every obstacle left out), every gap offset by its
    /// depth into them and a clearance, the offset ramped to zero with warm
    /// steps. Frictionless only: with friction the curl is the history.
    pub(super) fn approach_obstacles(
        &mut self,
        obstacle: usize,
    ) -> std::result::Result<Vec<Quat>, String> {
        let mut settings = self.settings.clone();
        settings.n_elements = Some(self.model.n());
        let mut homotopy = Homotopy::new(Kind::Approach, obstacle);
        let outcome = (|| {
            let mut free_scene = self.scene.clone();
            free_scene.obstacles.clear();
            free_scene.friction.clear();
            let free = Solver::new(&free_scene, settings.clone())
                .and_then(|mut solver| solver.solve_strategy(None))
                .map_err(|e| format!("the rod without its obstacles is refused: {e}"))?;
            homotopy.iterations += free.iterations;
            homotopy.steps += 1;
            if !(free.converged() && free.stable) {
                return Err("the rod without its obstacles does not converge either".to_string());
            }
            let radius = self.model.contact_radius();
            let deepest = deepest_point(&self.model, &free.positions);
            if deepest.depth <= 0.0 {
                // The free equilibrium clears every obstacle: it is a start.
                homotopy.kind = Kind::Free;
                return Ok(free.quaternions);
            }
            let offset = deepest.depth + APPROACH_CLEARANCE * self.model.length();
            let mut solver =
                Solver::new(&self.scene, settings.clone()).map_err(|e| e.to_string())?;
            let pressed = pressed_along_its_axis(&free.positions, &deepest.normal);
            let through = passed_through(&self.model, &free.positions);
            self.ramp(free.quaternions, &mut homotopy, |alpha, q, h| {
                solver
                    .model
                    .set_contact_radius(radius - (1.0 - alpha) * offset);
                let sol = solver.solve_strategy(Some(q)).map_err(|e| e.to_string())?;
                h.iterations += sol.iterations;
                h.steps += 1;
                Ok((sol.converged() && sol.stable).then_some(sol.quaternions))
            })
            .map_err(|why| {
                if pressed {
                    format!(
                        "{why} (its free equilibrium is straight: pressed along it, the rod \
                         buckles to a side that nothing in the scene chooses; a rest curvature \
                         or a load across it does)"
                    )
                } else if let Some(o) = through {
                    format!(
                        "{why} (its free equilibrium passes through obstacles[{o}] from side \
                         to side: which side the rod rests on is its history's, which the \
                         scene does not give; start it from a shape on that side, initial=)"
                    )
                } else {
                    why
                }
            })
        })();
        homotopy.failed = outcome.as_ref().err().cloned();
        self.homotopies.push(homotopy);
        outcome
    }

    /// Whether the straight rod (the base's tangent, unloaded) clears every
    /// obstacle: the curl's start.
    pub(super) fn straight_rod_clears(&self) -> bool {
        let model = &self.model;
        let mut nodes = vec![Vector3::zeros(); model.n() + 1];
        model.positions(&model.straight(), &mut model.new_interior(), &mut nodes);
        // As deep as `obstacle_at_rest` lets a rest shape be.
        deepest_point(model, &nodes).depth <= AT_REST_DEPTH * model.length()
    }

    /// A homotopy's steps from 0 (where `q` is its answer) to 1: each
    /// solved warm from the last by `solve` (`None`: not converged and
    /// stable, so the step halves), doubling after an easy one.
    fn ramp(
        &self,
        mut q: Vec<Quat>,
        homotopy: &mut Homotopy,
        mut solve: impl FnMut(f64, &[Quat], &mut Homotopy) -> Result<Option<Vec<Quat>>, String>,
    ) -> Result<Vec<Quat>, String> {
        let (mut alpha, mut step) = (0.0f64, FIRST_STEP);
        while alpha < 1.0 && !interrupt::requested() {
            let before = homotopy.iterations;
            let next_alpha = (alpha + step).min(1.0);
            match solve(next_alpha, &q, homotopy)? {
                Some(next) => {
                    q = next;
                    alpha = next_alpha;
                    if homotopy.iterations - before <= EASY_STEP {
                        step *= 2.0;
                    }
                }
                None if step > MIN_STEP => step *= 0.5,
                None => return Err(format!("it stopped at {alpha:.3} of the way")),
            }
            if homotopy.iterations >= self.settings.max_iterations {
                return Err(format!("it ran out of iterations at {alpha:.3} of the way"));
            }
        }
        Ok(q)
    }
}

/// The deepest point of a rod in its obstacles.
struct Deepest {
    /// How deep (negative where the rod clears them all) [m].
    depth: f64,
    /// The obstacle's normal there.
    normal: Vector3<f64>,
}

/// How deep the rod whose nodes are `nodes` reaches into the model's
/// obstacles, at its nodes and at its chords' nearest points (the contact
/// slots, located as a solve locates them).
fn deepest_point(model: &RodModel, nodes: &[Vector3<f64>]) -> Deepest {
    located(model, nodes).iter().fold(
        Deepest {
            depth: f64::NEG_INFINITY,
            normal: Vector3::zeros(),
        },
        |deepest, site| {
            if -site.gap > deepest.depth {
                Deepest {
                    depth: -site.gap,
                    normal: site.normal,
                }
            } else {
                deepest
            }
        },
    )
}

/// Every contact slot of the rod whose nodes are `nodes`, located as a
/// solve locates them (see `contact::slot`).
fn located(model: &RodModel, nodes: &[Vector3<f64>]) -> Vec<Site> {
    let mut sites = vec![Site::default(); contact::slot_count(model)];
    contact::locate(model, nodes, &mut sites);
    sites
}

/// The first obstacle that the rod whose nodes are `nodes` passes through
/// from side to side: it enters the obstacle and leaves it again toward its
/// tip on the opposite side (the clear places just before and just after
/// the stretch inside face it from directions more than a right angle
/// apart: the two faces of a slab the rod hangs through). The approach
/// grows such an obstacle back from its middle, which pushes the rod out of
/// both its faces at once: no start there, and the message says which side
/// is missing. A rod that dips into an obstacle and out on the side it came
/// from (a half-space, a lumen's wall at a bend) is not.
fn passed_through(model: &RodModel, nodes: &[Vector3<f64>]) -> Option<usize> {
    let sites = located(model, nodes);
    let n = model.n();
    (0..model.obstacles().len()).find(|&o| {
        // The obstacle's slots along the rod: element k's, then node k's.
        let first = 2 * n * o;
        let along = (1..=n).flat_map(|k| [&sites[first + n + k - 1], &sites[first + k - 1]]);
        let (mut before, mut inside) = (None::<Vector3<f64>>, false);
        for site in along {
            if site.gap < 0.0 {
                inside = true;
                continue;
            }
            if inside && before.is_some_and(|b| b.dot(&site.normal) < 0.0) {
                return true;
            }
            (before, inside) = (Some(site.normal), false);
        }
        false
    })
}

/// Whether the nodes lie on the line through the first and the last (to
/// round-off of the span) and `normal` presses along it: a rod that buckles
/// to a side nothing chooses.
fn pressed_along_its_axis(nodes: &[Vector3<f64>], normal: &Vector3<f64>) -> bool {
    let (Some(first), Some(last)) = (nodes.first(), nodes.last()) else {
        return false;
    };
    let span = last - first;
    let length = span.norm();
    if nodes.len() < 3 || length == 0.0 {
        return false;
    }
    let axis = span / length;
    let straight = nodes.iter().all(|p| {
        let d = p - first;
        (d - d.dot(&axis) * axis).norm() <= 1e-9 * length
    });
    straight && axis.dot(normal).abs() >= ALONG_AXIS
}
