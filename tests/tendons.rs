//! Tendons and magnetic actuation in the discrete potential: derivatives
//! against differences, the exact arc of a straight-routed tendon, an anchor
//! inside the rod.

use nalgebra::Vector3;
use softspine::blocktri::BlockTridiagonal;
use softspine::{Gravity, Method, Quat, RodModel, Scene, Scheme, Settings, Solver, Tendon};

fn tendon(tension: f64, offset: [f64; 2], twist: f64, end: f64) -> Tendon {
    Tendon {
        tension,
        offset,
        twist,
        end,
        ..Tendon::default()
    }
}

fn scene() -> Scene {
    let mut s = Scene::new(0.8, 0.9, 1.3, 0.7);
    s.rest_curvature = vec![[1.2, -0.4], [-0.6, 0.9]];
    s.gravity = Some(Gravity {
        linear_density: 0.5,
        vector: Vector3::new(0.0, 0.0, -9.81),
    });
    s.tendons = vec![
        tendon(8.0, [0.03, 0.01], 0.0, 0.4),
        tendon(5.0, [-0.01, 0.025], 4.0, 0.8),
    ];
    // Magnetic actuation too: two magnetised sections and a tip magnet.
    s.magnetization = vec![Vector3::new(0.5, -0.2, 1.0), Vector3::new(-0.3, 0.8, 0.4)];
    s.tip_magnet = Vector3::new(0.02, 0.05, -0.03);
    s.magnetic_field = Vector3::new(0.3, -0.6, 0.2);
    s
}

fn bent(model: &RodModel) -> Vec<Quat> {
    let mut q = vec![model.base(); model.n() + 1];
    for j in 1..=model.n() {
        let t = j as f64 / model.n() as f64;
        let d = Vector3::new(0.9 * t.sin(), -0.7 * t * t, 0.4 * t) * (3.0 / model.n() as f64);
        q[j] = q[j - 1].perturbed(d);
    }
    q
}

#[test]
fn the_residual_and_jacobian_are_the_derivatives_of_the_energy() {
    for scheme in [Scheme::Fd2, Scheme::Fe4] {
        let n = 8;
        let model = RodModel::new(&scene(), n).with_scheme(scheme);
        let q = bent(&model);
        let mut g = vec![Vector3::zeros(); n];
        let mut jac = BlockTridiagonal::zeros(n);
        model.residual_jacobian(&q, 1.0, &mut model.new_interior(), &mut g, &mut jac);
        let h = 1e-6;
        for node in 1..=n {
            for (c, analytic) in g[node - 1].iter().enumerate() {
                let d = Vector3::ith(c, h);
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[node] = q[node].perturbed(d);
                qm[node] = q[node].perturbed(-d);
                let de = (model.energy(&qp, &mut model.new_interior())
                    - model.energy(&qm, &mut model.new_interior()))
                    / (2.0 * h);
                assert!(
                    (de - analytic).abs() < 1e-6 * (1.0 + de.abs()),
                    "{scheme:?} node {node} row {c}: {de} vs {analytic}"
                );
                let (mut gp, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
                model.residual(&qp, 1.0, &mut model.new_interior(), &mut gp);
                model.residual(&qm, 1.0, &mut model.new_interior(), &mut gm);
                for row in 1..=n {
                    let fd = (gp[row - 1] - gm[row - 1]) / (2.0 * h);
                    let block = match (row as isize) - (node as isize) {
                        0 => jac.diag[row - 1],
                        -1 => jac.upper[row - 1],
                        1 => jac.lower[node - 1],
                        _ => nalgebra::Matrix3::zeros(),
                    };
                    assert!(
                        (fd - block.column(c)).amax() < 1e-6 * (1.0 + fd.amax()),
                        "{scheme:?} block ({row}, {node}) column {c}"
                    );
                }
            }
        }
    }
}

/// A straight-routed tendon along a rod without torsion or other loads.
fn arc_scene(end: f64) -> (Scene, f64) {
    let (ei, d, tension) = (0.5, 0.01, 20.0);
    let mut s = Scene::new(1.0, ei, ei, 0.4);
    s.tendons = vec![tendon(tension, [d, 0.0], 0.0, end)];
    (s, tension * d / ei)
}

/// The point at arc length `s` of the arc of curvature `kappa` in the x-z
/// plane from the base along z.
fn exact_arc(kappa: f64, s: f64) -> Vector3<f64> {
    Vector3::new(
        (1.0 - (kappa * s).cos()) / kappa,
        0.0,
        (kappa * s).sin() / kappa,
    )
}

fn solve(scene: &Scene, n: usize, scheme: Scheme) -> softspine::Solution {
    let settings = Settings {
        n_elements: Some(n),
        scheme: Some(scheme),
        residual_tol: 1e-13,
        ..Settings::default()
    };
    let sol = softspine::solve(scene, settings, None).unwrap();
    assert!(sol.converged() && sol.stable, "{}", sol.message);
    sol
}

#[test]
fn a_straight_tendon_bends_its_rod_into_the_exact_arc() {
    let (scene, kappa) = arc_scene(1.0);
    // The second-order scheme: every element's discrete curvature is exactly
    // tension x offset / EI (its positions are second order).
    let sol = solve(&scene, 10, Scheme::Fd2);
    for w in sol.quaternions.windows(2) {
        let omega = (2.0 / 0.1) * (w[0].conj() * w[1]).v;
        assert!(
            (omega - Vector3::new(0.0, kappa, 0.0)).norm() < 1e-10,
            "{omega}"
        );
    }
    // The fourth-order scheme: its Gauss points reach that curvature, which
    // puts the nodes on the exact arc to fourth order (the interpolated arc's
    // curvature there is kappa (1 + (h kappa / 4)^4 / 45)).
    let arc = |s: f64| exact_arc(kappa, s);
    let mut errors = Vec::new();
    for n in [10, 20, 40] {
        let sol = solve(&scene, n, Scheme::Fe4);
        let tip = sol.tip_quaternion();
        let exact = Quat::from_rotation_vector(Vector3::new(0.0, kappa, 0.0));
        let turn = 2.0 * (tip.conj() * exact).v.norm();
        let err = sol
            .positions
            .iter()
            .enumerate()
            .map(|(i, r)| (r - arc(i as f64 / n as f64)).norm())
            .fold(0.0, f64::max)
            .max(turn);
        errors.push(err);
    }
    assert!(errors[0] < 1e-8, "{errors:?}");
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!((3.8..4.2).contains(&order), "{errors:?}");
    }
}

#[test]
fn a_tendon_anchored_halfway_leaves_the_rest_straight() {
    let (scene, kappa) = arc_scene(0.5);
    for scheme in [Scheme::Fd2, Scheme::Fe4] {
        let sol = solve(&scene, 20, scheme);
        let q = &sol.quaternions;
        // The distal half carries nothing: it continues the tangent at the anchor.
        for w in q[10..].windows(2) {
            assert!((w[0].conj() * w[1]).v.norm() < 1e-11, "{scheme:?}");
        }
        let turn = 2.0 * (q[0].conj() * q[10]).v.norm().asin();
        assert!((turn - 0.5 * kappa).abs() < 1e-4, "{scheme:?}: {turn}");
    }
}

#[test]
fn the_papers_method_refuses_tendons_by_name() {
    let settings = Settings {
        method: Method::Paper,
        ..Settings::default()
    };
    let e = Solver::new(&arc_scene(1.0).0, settings).err().unwrap();
    assert!(e.to_string().contains("tendons"), "{e}");
}

#[test]
fn shooting_bends_a_rod_under_a_straight_tendon_into_the_exact_arc() {
    // Each stage solves for the curvature whose elastic and tendon moments
    // are the internal one (nil here): exactly tension x offset / EI, so
    // the nodes are RK4's of the exact arc, fourth order.
    let (scene, kappa) = arc_scene(1.0);
    let arc = |s: f64| exact_arc(kappa, s);
    let mut errors = Vec::new();
    for n in [4, 8, 16] {
        let settings = Settings {
            n_elements: Some(n),
            method: Method::Shooting,
            ..Settings::default()
        };
        let sol = softspine::solve(&scene, settings, None).unwrap();
        assert!(sol.converged() && sol.stable, "{}", sol.message);
        let err = sol
            .positions
            .iter()
            .enumerate()
            .map(|(i, r)| (r - arc(i as f64 / n as f64)).norm())
            .fold(0.0, f64::max);
        errors.push(err);
    }
    assert!(errors[0] < 1e-4, "{errors:?}");
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!((3.8..4.2).contains(&order), "{errors:?}");
    }
}

/// New tensions and fields are set in place where the discretisation keeps
/// its shape: the same equilibrium, bit for bit, as a solver built for them
/// (tendons given out of the model's order, a field switched on and off).
#[test]
fn drives_set_in_place_solve_as_a_solver_built_for_them() {
    let settings = || Settings {
        n_elements: Some(16),
        ..Settings::default()
    };
    let mut s = scene();
    // The shorter tendon first: the model orders them longest first.
    s.tendons.reverse();
    let mut solver = Solver::new(&s, settings()).unwrap();
    solver.solve(None).unwrap();
    for (tensions, field) in [
        ([3.0, 0.0], Vector3::new(0.1, 0.2, -0.3)),
        ([0.0, 6.5], Vector3::zeros()),
        ([2.0, 1.0], Vector3::new(-0.4, 0.0, 0.1)),
    ] {
        solver.set_tensions(&tensions).unwrap();
        solver.set_magnetic_field(field).unwrap();
        let mut fresh_scene = s.clone();
        for (t, x) in fresh_scene.tendons.iter_mut().zip(tensions) {
            t.tension = x;
        }
        fresh_scene.magnetic_field = field;
        let mut fresh = Solver::new(&fresh_scene, settings()).unwrap();
        assert_eq!(
            solver.model().load_parameter(),
            fresh.model().load_parameter()
        );
        let (a, b) = (solver.solve(None).unwrap(), fresh.solve(None).unwrap());
        assert!(a.converged(), "{}", a.message);
        assert_eq!(a.positions, b.positions);
    }
}
