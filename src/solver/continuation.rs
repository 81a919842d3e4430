//! Load continuation: the path from the unloaded rest shape (a chain of
//! arcs, an exact equilibrium) to the scene, followed on its stable branch,
//! as a loading experiment would. A direct solve that fails or lands on an
//! unstable equilibrium falls back to it.
//!
//! A held scene takes the path in two legs: the loads are ramped on the free
//! rod, then the held points move from where the loaded rod puts them to
//! their targets. A single leg that moves the targets and the loads together
//! starts, for a straight rest shape, at full reach (its tip is exactly `L`
//! from the base), where the reaction is indeterminate: a target on the axis
//! with a small lateral load was not found that way. The single leg stays as
//! the fallback.

use super::constrained::Snapshot;
use super::{evaluate, is_stable, LocalOutcome, LocalSolver, Workspace};
use crate::interrupt;
use crate::model::RodModel;
use crate::quat::Quat;
use nalgebra::Vector3;

/// The whole load path of `model` from its rest shape, within `budget`
/// iterations (see the module). On success `w.q` is the equilibrium at
/// `lambda = 1` with `w.g` and `w.jac` current.
pub(crate) fn load_path(
    local: &mut dyn LocalSolver,
    model: &RodModel,
    w: &mut Workspace,
    tol: f64,
    budget: usize,
    min_step: f64,
) -> (LocalOutcome, usize) {
    let mut iterations = 0;
    let mut steps = 0;
    if model.is_constrained() {
        // First leg: the loads on the released rod.
        let released = model.released();
        let mut free_local = local.for_model(&released);
        start_from_rest(&released, w);
        let (first, first_steps) = continuation(
            free_local.as_mut(),
            &released,
            w,
            tol,
            budget,
            min_step,
            false,
        );
        iterations += first.iterations;
        steps += first_steps;
        if first.converged && model.constraints().is_empty() && model.clamped_tip().is_none() {
            // Nothing is held: the first leg was the whole path (a second
            // would hold the loads still, and start the contacts' friction
            // over).
            evaluate(model, w, 1.0);
            return (first, steps);
        }
        if first.converged && !interrupt::requested() {
            // Second leg: the held points from where the loaded rod puts them
            // (bent a little first where they would buckle it); where that
            // fails on a planar stretch, again bent out of its plane. A
            // planar stretch that rests on an obstacle is bent out of its
            // plane first: in it the rod could only arch up off what it
            // lies on, against its loads (an arch that would fall over),
            // and that path fails from the flat rod at its first step.
            let loaded = Snapshot::take(w);
            let resting = !super::contact::held_slots(w).is_empty();
            let order = if resting && buckling_bump(model, w, true).is_some() {
                [true, false]
            } else {
                [false, true]
            };
            let mut second = LocalOutcome {
                converged: false,
                iterations: 0,
            };
            for (attempt, out_of_plane) in order.into_iter().enumerate() {
                loaded.restore(w);
                let bent = bend_a_straight_stretch(model, w, out_of_plane);
                if (out_of_plane && !bent) || (attempt > 0 && interrupt::requested()) {
                    break;
                }
                let holding = model.holding_from(&w.q, &mut w.interior);
                w.saved.copy_from_slice(&w.q);
                w.kkt.clear_saved();
                super::friction::anchor_at_saved(&holding, w);
                // With obstacles, half of what is left stays for the one-leg
                // path below: the held leg drags the loaded rod's contacts
                // along (a clamped tip lifted off a wall it lay on), where
                // loads and held points together from rest find them as they
                // come. A resting stretch bent out of its plane first takes
                // three quarters: the in-plane leg after it is the one
                // expected to fail.
                let left = budget - iterations.min(budget);
                let share = match (model.has_obstacles(), attempt == 0 && order[0]) {
                    (false, _) => left,
                    (true, true) => 3 * left / 4,
                    (true, false) => left / 2,
                };
                let (out, more) = continuation(local, &holding, w, tol, share, min_step, bent);
                iterations += out.iterations;
                steps += more;
                second = out;
                if second.converged {
                    break;
                }
            }
            if second.converged {
                // At lambda = 1 the holding model is the scene itself.
                evaluate(model, w, 1.0);
                return (
                    LocalOutcome {
                        converged: true,
                        iterations,
                    },
                    steps,
                );
            }
        }
    }
    // One leg: loads and held points together from the rest shape.
    start_from_rest(model, w);
    let (out, more) = continuation(
        local,
        model,
        w,
        tol,
        budget - iterations.min(budget),
        min_step,
        false,
    );
    iterations += out.iterations;
    (
        LocalOutcome {
            converged: out.converged,
            iterations,
        },
        steps + more,
    )
}

/// A held point (not a clamped tip) whose stretch from the base is straight
/// and which is pushed along that stretch's line towards the base: the stretch must
/// buckle, and no Newton step from the straight rod finds how (the point's
/// motion along the line is of second order in the bending: its row's
/// derivative along the line is zero, and the straight rod under any
/// compression is an equilibrium). Bend the rod's rotations in `w.q` into
/// a small bump first, which keeps the point near the line: in the plane of
/// the line and the target's offset from it, or, on the line, sideways to
/// the loads across it (no work against them: a heavy rod pushed along a
/// floor snakes along it, an arch standing up from it would fall over), else
/// in the base's plane of the softer bending. The held leg then starts on
/// the buckled branch. Returns whether it bent the rod.
///
/// `out_of_plane`: a retry where the held leg failed, for a stretch that is
/// not straight but lies in a plane with its target and its loads (a heavy
/// rod sagging from a base just above a floor, pushed along it): no step
/// leaves that plane, and in it the rod can only arch up off the floor.
/// The bump is then out of the plane.
fn bend_a_straight_stretch(model: &RodModel, w: &mut Workspace, out_of_plane: bool) -> bool {
    let Some(bump) = buckling_bump(model, w, out_of_plane) else {
        return false;
    };
    // Turned by BUCKLE_TILT at the base, down to -BUCKLE_TILT at the held
    // node: a bump of height about BUCKLE_TILT s_k / 4, the node kept near
    // the line (and beyond it, the rod turned as the node).
    let s_k = model.arc(bump.node);
    for (j, q) in w.q.iter_mut().enumerate().skip(1) {
        let s = model.arc(j).min(s_k);
        let tilt = BUCKLE_TILT * (1.0 - 2.0 * s / s_k);
        *q = (Quat::from_rotation_vector(tilt * bump.axis) * *q).normalized();
    }
    true
}

/// The bump [`bend_a_straight_stretch`] would bend into the rod in `w.q`:
/// the held node that ends its stretch and the axis the stretch turns about.
struct Bump {
    node: usize,
    axis: Vector3<f64>,
}

/// The bump of [`bend_a_straight_stretch`], if the rod in `w.q` has a
/// stretch to bend (`w.q` unchanged).
fn buckling_bump(model: &RodModel, w: &mut Workspace, out_of_plane: bool) -> Option<Bump> {
    let mut r = vec![Vector3::zeros(); model.n() + 1];
    model.positions(&w.q, &mut w.interior, &mut r);
    let length = model.length();
    let loads = model
        .rod()
        .loading
        .node_force
        .first()
        .copied()
        .unwrap_or_default();
    // A clamped tip's path tries both ways at its bifurcation already
    // (`mirror` below, the tangent's buckling mode).
    let clamped = model.clamped_tip().map(|_| model.n());
    let mut pinned = model
        .constraints()
        .iter()
        .filter(|c| Some(c.node) != clamped);
    let (node, line, offset) = pinned.find_map(|c| {
        let chord = r[c.node] - r[0];
        let line = chord.try_normalize(0.0)?;
        let across_line = |p: &Vector3<f64>| {
            let v = p - r[0];
            v - line * line.dot(&v)
        };
        let straight = r[..=c.node]
            .iter()
            .all(|p| across_line(p).norm() <= STRAIGHT * length);
        let along = line.dot(&(c.target - r[0]));
        let offset = c.target - r[0] - along * line;
        let shortening = chord.norm() - along;
        if !out_of_plane {
            return (straight && shortening > 0.0 && offset.norm() <= shortening)
                .then_some((c.node, line, offset));
        }
        // The plane of the line and the node farthest from it.
        let farthest = r[..=c.node]
            .iter()
            .map(across_line)
            .max_by(|a, b| a.norm().total_cmp(&b.norm()))?;
        let normal = line.cross(&farthest).try_normalize(STRAIGHT * length)?;
        let planar = r[..=c.node]
            .iter()
            .all(|p| normal.dot(&(p - r[0])).abs() <= STRAIGHT * length);
        let in_plane = normal.dot(&(c.target - r[0])).abs() <= STRAIGHT * length
            && normal.dot(&loads).abs() <= STRAIGHT * loads.norm();
        (!straight && planar && in_plane && shortening > 0.0).then_some((c.node, line, normal))
    })?;
    // The unit part of `v` across the line; none where it is round-off of
    // `scale` (a load along the line: its cross product with it).
    let across =
        |v: Vector3<f64>, scale: f64| (v - line * line.dot(&v)).try_normalize(STRAIGHT * scale);
    // Bending towards d2 turns about d1 (stiffness kx), and the other way.
    let stiffness = model.stiffness();
    let (softer, stiffer) = if stiffness.x <= stiffness.y {
        (Vector3::y(), Vector3::x())
    } else {
        (Vector3::x(), Vector3::y())
    };
    // Out of the plane, `offset` is the plane's normal.
    let towards = (out_of_plane || offset.norm() > OFFSET * length)
        .then(|| offset.normalize())
        .or_else(|| across(line.cross(&loads), loads.norm()))
        .or_else(|| across(model.base().rotate(softer), 1.0))
        .or_else(|| across(model.base().rotate(stiffer), 1.0))?;
    Some(Bump {
        node,
        axis: line.cross(&towards),
    })
}

/// A target this far (of the length) off the line picks the bump's
/// direction; nearer, round-off (a rod lying on a floor to the contacts'
/// tolerance) would.
const OFFSET: f64 = 1e-6;

/// A stretch whose nodes lie within this (of the length) of a line is straight.
const STRAIGHT: f64 = 1e-9;

/// The tilt of the bump that starts a straight stretch buckling [rad].
const BUCKLE_TILT: f64 = 0.01;

fn start_from_rest(model: &RodModel, w: &mut Workspace) {
    w.saved.copy_from_slice(&model.rest_shape());
    w.kkt.clear_saved();
    // Nothing acts at the rest shape: no reaction, no contact held (an
    // attempt before may have left some; a sticking port's anchor is offset
    // by its multiplier's spring).
    w.kkt.clear_multipliers();
    w.kkt.contact.friction.last_level = 0.0;
    super::friction::anchor_at_saved(model, w);
}

/// Continuation steps shorter than this may end on an unstable equilibrium.
const STABILITY_STEP: f64 = 1e-3;

/// Largest rotation of a node by the predictor [rad].
const MAX_PREDICTION: f64 = 0.5;

/// A step that converged within this many iterations (beyond the fewest
/// a frictional step takes) doubles the next.
const EASY_STEP: usize = 6;

/// Iteration limit of one continuation step.
const STEP_ITERATIONS: usize = 25;

/// Follow `lambda` from 0 to 1 with a tangent predictor and an adaptive step,
/// within `budget` iterations, from the equilibrium at `lambda = 0` in
/// `w.saved` (reactions in `w.kkt.reactions_saved`). Returns the outcome at
/// `lambda = 1` and the steps taken. A `bumped` start (see
/// [`bend_a_straight_stretch`]) is no equilibrium: the first step's
/// corrector may move far from it.
fn continuation(
    local: &mut dyn LocalSolver,
    model: &RodModel,
    w: &mut Workspace,
    tol: f64,
    budget: usize,
    min_step: f64,
    bumped: bool,
) -> (LocalOutcome, usize) {
    let n = model.n();
    let (mut lambda, mut dlambda) = (0.0f64, 0.25f64);
    let mut prediction = w.saved.clone();
    let (mut iterations, mut steps) = (0usize, 0usize);
    // The unloaded rest shape is stable; the path is followed on the stable
    // branch as long as there is one.
    let mut path_stable = true;
    // With friction a step costs the relaxed levels' iterations whatever
    // its length: a step is easy when it takes few more than the fewest of
    // any step so far (else the path crawls at a step of 1e-3).
    let mut fewest = if model.has_friction() { usize::MAX } else { 0 };
    while lambda < 1.0 && !interrupt::requested() {
        let target = (lambda + dlambda).min(1.0);
        // Tangent predictor: dq/dlambda = -J^{-1} dg/dlambda at the last
        // equilibrium (a held scene: the KKT system's, reactions included).
        w.kkt.restore_saved();
        let predicted = if model.is_constrained() {
            w.q.copy_from_slice(&w.saved);
            super::constrained::tangent(model, w, lambda)
        } else {
            model.residual_jacobian(&w.saved, lambda, &mut w.interior, &mut w.g, &mut w.jac);
            model.residual_lambda_derivative(
                &w.saved,
                &mut w.interior,
                &mut w.step,
                &mut w.scratch,
            );
            let factored = w.lu.factor(&w.jac, 0.0).is_ok();
            if factored {
                w.lu.solve_in_place(&mut w.step);
            }
            factored
        };
        let h = target - lambda;
        w.q[0] = w.saved[0];
        let mut clipped = false;
        if model.is_constrained() {
            // The whole state along the tangent, scaled so that no node turns
            // by more than MAX_PREDICTION (the mode shape is kept).
            let largest = if predicted {
                h * w.step.iter().map(|d| d.norm()).fold(0.0, f64::max)
            } else {
                0.0
            };
            clipped = largest > MAX_PREDICTION;
            let scale = if clipped {
                -h * MAX_PREDICTION / largest
            } else {
                -h
            };
            for j in 1..=n {
                let d = if predicted {
                    scale * w.step[j - 1]
                } else {
                    Vector3::zeros()
                };
                w.q[j] = w.saved[j].perturbed(d);
            }
            if predicted {
                let m = model.constraints().len();
                for (r, d) in w.kkt.reactions[..m].iter_mut().zip(&w.kkt.reaction_step) {
                    *r -= scale * d;
                }
            }
            // A prediction that carries the rod through an obstacle (it
            // holds only the contacts already held) starts the corrector
            // from the last equilibrium instead.
            if predicted && model.has_obstacles() {
                let mut moved = std::mem::take(&mut w.kkt.contact.moved);
                model.positions(&w.q, &mut w.interior, &mut moved);
                let crossed = !super::contact::crossing(model, w, &moved, false).is_empty();
                w.kkt.contact.moved = moved;
                if crossed {
                    w.q.copy_from_slice(&w.saved);
                    w.kkt.restore_saved();
                }
            }
        } else {
            for j in 1..=n {
                let d = if predicted {
                    -h * w.step[j - 1]
                } else {
                    Vector3::zeros()
                };
                let d = if d.norm() > MAX_PREDICTION {
                    d * (MAX_PREDICTION / d.norm())
                } else {
                    d
                };
                w.q[j] = w.saved[j].perturbed(d);
            }
        }
        prediction.copy_from_slice(&w.q);
        // A held path that starts at a bifurcation (its tangent is huge, the
        // buckling mode) may go either way: both are tried on the first step.
        let mirrored = (clipped && steps == 0).then(|| mirror(w));
        let out = local.run(
            model,
            w,
            target,
            STEP_ITERATIONS.min(budget.saturating_sub(iterations)),
            tol,
        );
        iterations += out.iterations;
        let out = match mirrored {
            Some(other) => {
                let max_iter = STEP_ITERATIONS.min(budget.saturating_sub(iterations));
                let (out, spent) = better_branch(
                    local,
                    model,
                    w,
                    (out, other),
                    &mut prediction,
                    (target, max_iter, tol),
                );
                iterations += spent;
                out
            }
            None => out,
        };
        // A large step that ends on an unstable equilibrium has likely jumped to
        // another branch near a (perturbed) bifurcation: retry it shorter. Only a
        // short step may lose stability (a genuine limit, e.g. a perfect column
        // past its buckling load, or lateral buckling under a dead moment).
        // A corrector that moves far from the prediction has left the path for
        // another equilibrium, stable or not: retry the step shorter too.
        let jumped = out.converged
            && dlambda > STABILITY_STEP
            && (left_the_path(&prediction, w, bumped && steps == 0)
                || (path_stable && !is_stable(model, w)));
        if out.converged && !jumped {
            steps += 1;
            path_stable = path_stable && (dlambda > STABILITY_STEP || is_stable(model, w));
            lambda = target;
            w.reached_load = w.reached_load.max(lambda);
            w.saved.copy_from_slice(&w.q);
            w.kkt.save();
            super::friction::anchor_at_saved(model, w);
            fewest = fewest.min(out.iterations);
            if out.iterations <= EASY_STEP + fewest {
                dlambda = (dlambda * 2.0).min(1.0);
            }
        } else {
            dlambda *= 0.5;
            if dlambda < min_step || iterations >= budget {
                w.q.copy_from_slice(&w.saved);
                w.kkt.restore_saved();
                evaluate(model, w, 1.0);
                return (
                    LocalOutcome {
                        converged: false,
                        iterations,
                    },
                    steps,
                );
            }
        }
    }
    // w.q is the equilibrium at lambda = 1 (unless interrupted); w.g and
    // w.jac are current.
    (
        LocalOutcome {
            converged: lambda >= 1.0,
            iterations,
        },
        steps,
    )
}

/// The prediction reflected through the last equilibrium (`w.saved`), with
/// its reactions: the other side of a bifurcation.
fn mirror(w: &Workspace) -> (Vec<Quat>, Vec<Vector3<f64>>) {
    let q = w
        .saved
        .iter()
        .zip(&w.q)
        .map(|(s, p)| *s * (s.conj() * *p).conj())
        .collect();
    let reactions = w
        .kkt
        .reactions_saved
        .iter()
        .zip(&w.kkt.reactions)
        .map(|(s, p)| 2.0 * s - p)
        .collect();
    (q, reactions)
}

/// Run the corrector from the mirrored prediction too and keep the better of
/// the two ends in the workspace: converged first, then stable, then the
/// lower energy. The second run takes at most `max_iter` iterations. Returns
/// the kept outcome and the iterations the second run took.
fn better_branch(
    local: &mut dyn LocalSolver,
    model: &RodModel,
    w: &mut Workspace,
    (first, (q, reactions)): (LocalOutcome, (Vec<Quat>, Vec<Vector3<f64>>)),
    prediction: &mut [Quat],
    (lambda, max_iter, tol): (f64, usize, f64),
) -> (LocalOutcome, usize) {
    let rank = |out: &LocalOutcome, w: &mut Workspace| {
        (
            out.converged,
            out.converged && is_stable(model, w),
            -model.energy_at(&w.q, lambda, &mut w.interior),
        )
    };
    let first_rank = rank(&first, w);
    let kept = (Snapshot::take(w), prediction.to_vec());
    prediction.copy_from_slice(&q);
    w.q.copy_from_slice(&q);
    w.kkt.reactions.copy_from_slice(&reactions);
    let second = local.run(model, w, lambda, max_iter, tol);
    let second_rank = rank(&second, w);
    // Lexicographic: converged, then stable, then lower energy.
    let better = second_rank > first_rank;
    if better {
        return (second, second.iterations);
    }
    kept.0.restore(w);
    prediction.copy_from_slice(&kept.1);
    evaluate(model, w, lambda);
    (first, second.iterations)
}

/// Largest rotation [rad] by which a continuation step's corrector may move a
/// node from the tangent prediction: beyond it the step is taken to have
/// jumped to another branch.
const MAX_CORRECTION: f64 = 0.2;

/// Largest angle between corresponding nodes of two chains [rad].
/// Whether the corrector's answer `w.q` has left the path: far from the
/// `prediction`, unless it started from a bump (no equilibrium: a rod on a
/// frictional floor snakes in a shape of its own, far from any small bump
/// whatever the step; retried shorter, its steps failed). A column may
/// then buckle against the bump: either way is an equilibrium of the same
/// energy.
fn left_the_path(prediction: &[Quat], w: &Workspace, from_a_bump: bool) -> bool {
    !from_a_bump && max_node_distance(prediction, &w.q) > MAX_CORRECTION
}

fn max_node_distance(a: &[Quat], b: &[Quat]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            // A rotation angle, whichever sign the two quaternions have.
            let turn = crate::model::element_turn(*x, *y);
            turn.min(2.0 * std::f64::consts::PI - turn)
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::Port;
    use crate::quat::Quat;
    use crate::scene::Scene;
    use nalgebra::Vector3;

    /// A path from the rest shape starts with nothing acting on the rod,
    /// whatever an attempt before left in the workspace: a sticking port's
    /// anchor is offset by its multiplier's spring, so that a multiplier
    /// left over (of a relaxed level, whose compliance is the whole rod's)
    /// anchored it metres away (the one-leg path after a failed two-leg
    /// one started from such an anchor).
    #[test]
    fn a_path_from_rest_starts_with_no_multiplier_left_over() {
        let mut scene = Scene::new(1.0, 1.0, 1.0, 1.0);
        let half = std::f64::consts::FRAC_1_SQRT_2;
        scene.base_quaternion = Quat::new(half, 0.0, half, 0.0);
        scene.ports = vec![Port::new(Vector3::new(0.5, 0.0, 0.0), Vector3::x()).with_friction(5.0)];
        let model = RodModel::new(&scene, 20);
        let mut w = Workspace::new(&model).unwrap();
        let rest = model.rest_shape();
        w.q.copy_from_slice(&rest);
        evaluate(&model, &mut w, 0.0);
        w.kkt.contact.friction.compliance = super::super::friction::relaxed_compliance(&model);
        w.kkt
            .reactions
            .iter_mut()
            .for_each(|r| *r = Vector3::new(1.0, -2.0, -40.0));
        start_from_rest(&model, &mut w);
        assert!(w.kkt.reactions.iter().all(|r| *r == Vector3::zeros()));
        let anchor = w.kkt.contact.friction.ports[0].anchor.unwrap();
        assert!((anchor - 0.5).abs() < 1e-12, "anchor {anchor}");
    }
}
