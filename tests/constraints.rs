//! Pinned and clamped tips and guides: exact checks that need no reference.

use nalgebra::Vector3;
use softspine::{solve, Quat, Scene, Settings, TipCondition};

fn loaded() -> Scene {
    let mut s = Scene::new(0.9, 0.8, 1.1, 0.6);
    s.rest_curvature = vec![[1.5, -0.5], [-1.0, 2.0]];
    s.distributed_force = Vector3::new(0.1, -0.2, -1.2);
    s.tip_force = Vector3::new(0.7, -0.4, 0.3);
    s.base_quaternion = Quat::new(0.9, 0.3, -0.2, 0.1).normalized();
    s
}

fn settings(n: usize) -> Settings {
    Settings {
        n_elements: Some(n),
        ..Settings::default()
    }
}

#[test]
fn pinning_the_free_tip_returns_the_tip_force_as_reaction() {
    let free = loaded();
    let sol = solve(&free, settings(20), None).unwrap();
    assert!(sol.converged());
    let mut pinned = free.clone();
    pinned.tip_force = Vector3::zeros();
    pinned.tip = TipCondition::Pinned {
        position: sol.tip_position(),
    };
    let held = solve(&pinned, settings(20), None).unwrap();
    assert!(held.converged(), "{}", held.message);
    let reaction = held.tip_reaction_force.unwrap();
    assert!((reaction - free.tip_force).norm() < 1e-9, "{reaction:?}");
    assert!((held.tip_position() - sol.tip_position()).norm() < 1e-12);
    for (a, b) in held.positions.iter().zip(&sol.positions) {
        assert!((a - b).norm() < 1e-9);
    }
}

#[test]
fn clamping_the_free_tip_returns_force_and_moment() {
    let mut free = loaded();
    free.tip_moment = Vector3::new(0.05, -0.1, 0.02);
    let sol = solve(&free, settings(20), None).unwrap();
    assert!(sol.converged());
    let mut clamped = free.clone();
    clamped.tip_force = Vector3::zeros();
    clamped.tip_moment = Vector3::zeros();
    clamped.tip = TipCondition::Clamped {
        position: sol.tip_position(),
        quaternion: sol.tip_quaternion(),
    };
    let held = solve(&clamped, settings(20), None).unwrap();
    assert!(held.converged(), "{}", held.message);
    assert!((held.tip_reaction_force.unwrap() - free.tip_force).norm() < 1e-9);
    assert!(
        (held.tip_reaction_moment.unwrap() - free.tip_moment).norm() < 1e-9,
        "{:?}",
        held.tip_reaction_moment
    );
}

#[test]
fn a_guide_where_the_free_rod_passes_carries_no_force() {
    let free = loaded();
    let sol = solve(&free, settings(20), None).unwrap();
    let mut guided = free.clone();
    guided.guides = vec![softspine::scene::Guide {
        s: 0.45,
        position: sol.positions[10],
    }];
    let held = solve(&guided, settings(20), None).unwrap();
    assert!(held.converged(), "{}", held.message);
    assert!(held.guide_reactions[0].norm() < 1e-9);
    // Moving the guide sideways pushes the rod: the reaction points that way.
    guided.guides[0].position += Vector3::new(0.05, 0.0, 0.0);
    let pushed = solve(&guided, settings(20), None).unwrap();
    assert!(pushed.converged(), "{}", pushed.message);
    assert!((pushed.positions[10] - guided.guides[0].position).norm() < 1e-10);
    assert!(pushed.guide_reactions[0].x > 0.0);
}

#[test]
fn position_jacobian_matches_central_differences() {
    let scene = loaded();
    let n = 6;
    let model = softspine::RodModel::new(&scene, n);
    let mut q = vec![model.base(); n + 1];
    for j in 1..=n {
        q[j] = q[j - 1].perturbed(Vector3::new(0.2, -0.1 * j as f64, 0.05));
    }
    let mut d = vec![nalgebra::Matrix3::zeros(); n];
    let mut r = vec![Vector3::zeros(); n + 1];
    for k in [3, n] {
        model.position_jacobian(&q, k, &softspine::disc::Interior::none(), &mut d);
        for j in 1..=n {
            for c in 0..3 {
                let mut dq = Vector3::zeros();
                dq[c] = 1e-6;
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[j] = q[j].perturbed(dq);
                qm[j] = q[j].perturbed(-dq);
                model.positions(&qp, &mut model.new_interior(), &mut r);
                let rp = r[k];
                model.positions(&qm, &mut model.new_interior(), &mut r);
                let fd = (rp - r[k]) / 2e-6;
                assert!(
                    (fd - d[j - 1].column(c)).norm() < 1e-8,
                    "k {k} j {j} c {c}: {fd:?} vs {:?}",
                    d[j - 1].column(c)
                );
            }
        }
    }
}

#[test]
fn lm_solves_held_tips_too() {
    let free = loaded();
    let sol = solve(&free, settings(20), None).unwrap();
    let mut held_tip = free.clone();
    held_tip.tip_force = Vector3::zeros();
    held_tip.tip = TipCondition::Clamped {
        position: sol.tip_position(),
        quaternion: sol.tip_quaternion(),
    };
    let held = solve(&held_tip, lm_settings(), None).unwrap();
    assert!(held.converged(), "{}", held.message);
    let err = (held.tip_reaction_force.unwrap() - free.tip_force).norm();
    assert!(
        err < 1e-8,
        "{err:e} {} {:e}",
        held.iterations,
        held.residual_norm
    );
    held_tip.tip = TipCondition::Pinned {
        position: sol.tip_position(),
    };
    let held = solve(&held_tip, lm_settings(), None).unwrap();
    assert!(held.converged(), "{}", held.message);
    assert!((held.tip_reaction_force.unwrap() - free.tip_force).norm() < 1e-8);
}

/// LM converges linearly near the end: ask it for a residual two digits below
/// Newton's default so that the reactions can be compared to 1e-8.
fn lm_settings() -> Settings {
    Settings {
        method: softspine::Method::LevenbergMarquardt,
        residual_tol: 1e-12,
        ..settings(20)
    }
}

#[test]
fn a_guide_where_a_point_load_put_the_rod_carries_that_load() {
    let mut loaded_point = loaded();
    let q = Vector3::new(0.3, 0.5, -0.8);
    loaded_point.point_loads = vec![softspine::PointLoad {
        s: 0.54,
        force: q,
        ..Default::default()
    }];
    let sol = solve(&loaded_point, settings(20), None).unwrap();
    assert!(sol.converged());
    // Whole-rod balance: base force = tip force + distributed load + point load.
    let expected = loaded_point.tip_force + 0.9 * loaded_point.distributed_force + q;
    assert!((sol.forces[0] - expected).norm() < 1e-12);
    let mut guided = loaded();
    guided.guides = vec![softspine::Guide {
        s: 0.54,
        position: sol.positions[12],
    }];
    let held = solve(&guided, settings(20), None).unwrap();
    assert!(held.converged(), "{}", held.message);
    assert!(
        (held.guide_reactions[0] - q).norm() < 1e-9,
        "{:?}",
        held.guide_reactions
    );
    // A point load at the tip node is a tip force.
    let mut at_tip = loaded();
    at_tip.point_loads = vec![softspine::PointLoad {
        s: 0.9,
        force: q,
        ..Default::default()
    }];
    let mut as_tip_force = loaded();
    as_tip_force.tip_force += q;
    let (a, b) = (
        solve(&at_tip, settings(20), None).unwrap(),
        solve(&as_tip_force, settings(20), None).unwrap(),
    );
    assert!((a.tip_position() - b.tip_position()).norm() < 1e-14);
}
