//! Rust-side checks of the discrete model: the analytic Jacobian against central
//! differences, the closed-form Bisshopp-Drucker cantilever and end-moment arcs.

use nalgebra::Vector3;
use softspine::blocktri::BlockTridiagonal;
use softspine::{solve, Quat, RodModel, Scene, Settings};

fn loaded_scene() -> Scene {
    let mut s = Scene::new(0.8, 0.9, 1.3, 0.7);
    s.rest_curvature = vec![[1.2, -0.4], [-0.6, 0.9]];
    s.distributed_force = Vector3::new(0.3, -1.1, -2.0);
    s.tip_force = Vector3::new(-0.7, 0.4, 0.5);
    s.tip_moment = Vector3::new(0.2, -0.3, 0.15);
    s.base_quaternion = Quat::new(0.9, 0.2, -0.3, 0.1).normalized();
    s
}

/// A smooth, non-equilibrium configuration (so every Jacobian term is exercised).
fn bent_configuration(model: &RodModel) -> Vec<Quat> {
    let mut q = vec![model.base(); model.n() + 1];
    for j in 1..=model.n() {
        let t = j as f64 / model.n() as f64;
        let d = Vector3::new(0.9 * t.sin(), -0.7 * t * t, 0.4 * t) * (1.0 / model.n() as f64) * 3.0;
        q[j] = q[j - 1].perturbed(d);
    }
    q
}

#[test]
fn analytic_jacobian_matches_central_differences() {
    let scene = loaded_scene();
    let n = 8;
    let model = RodModel::new(&scene, n);
    let q = bent_configuration(&model);
    let mut g = vec![Vector3::zeros(); n];
    let mut jac = BlockTridiagonal::zeros(n);
    model.residual_jacobian(&q, 1.0, &mut model.new_interior(), &mut g, &mut jac);
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for col_node in 1..=n {
        for c in 0..3 {
            let mut dq = Vector3::zeros();
            dq[c] = h;
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[col_node] = q[col_node].perturbed(dq);
            qm[col_node] = q[col_node].perturbed(-dq);
            let (mut gp, mut gm) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
            model.residual(&qp, 1.0, &mut model.new_interior(), &mut gp);
            model.residual(&qm, 1.0, &mut model.new_interior(), &mut gm);
            for row_node in 1..=n {
                let fd = (gp[row_node - 1] - gm[row_node - 1]) / (2.0 * h);
                let (r, k) = (row_node - 1, col_node - 1);
                let block = if r == k {
                    jac.diag[r]
                } else if k == r + 1 {
                    jac.upper[r]
                } else if r == k + 1 {
                    jac.lower[k]
                } else {
                    nalgebra::Matrix3::zeros()
                };
                let err = (fd - block.column(c)).amax();
                worst = worst.max(err / (1.0 + fd.amax()));
            }
        }
    }
    assert!(worst < 1e-7, "largest relative Jacobian error {worst:e}");
}

#[test]
fn cantilever_matches_bisshopp_drucker() {
    // alpha = P L^2 / EI, tip deflection and shortening over L (MODEL.md).
    for (alpha, deflection, shortening) in [
        (1.0, 0.30172077, 0.05643324),
        (3.0, 0.60325344, 0.25442018),
        (10.0, 0.81060902, 0.55499560),
    ] {
        let mut scene = Scene::new(1.0, 1.0, 1.0, 1.0);
        scene.tip_force = Vector3::new(alpha, 0.0, 0.0);
        let settings = Settings {
            n_elements: Some(160),
            ..Settings::default()
        };
        let sol = solve(&scene, settings, None).unwrap();
        assert!(
            sol.converged() && sol.stable,
            "alpha {alpha}: {}",
            sol.message
        );
        let tip = sol.tip_position();
        assert!(
            (tip.x - deflection).abs() < 2e-5,
            "alpha {alpha}: deflection {}",
            tip.x
        );
        assert!(
            (1.0 - tip.z - shortening).abs() < 2e-5,
            "alpha {alpha}: shortening {}",
            1.0 - tip.z
        );
    }
}

#[test]
fn full_roll_up_by_end_moment() {
    let mut scene = Scene::new(1.0, 1.0, 1.0, 1.0);
    scene.tip_moment = Vector3::new(0.0, 2.0 * std::f64::consts::PI, 0.0);
    for n in [20, 40, 80] {
        let settings = Settings {
            n_elements: Some(n),
            ..Settings::default()
        };
        let sol = solve(&scene, settings, None).unwrap();
        assert!(sol.converged(), "n {n}: {}", sol.message);
        // The tip returns to the base; the discrete error is second order.
        let err = sol.tip_position().norm();
        assert!(
            err < 10.0 / (n * n) as f64,
            "n {n}: tip {err:e} from the base"
        );
    }
}

#[test]
fn tip_sensitivity_matches_finite_differences() {
    let mut scene = Scene::new(0.8, 0.9, 1.3, 0.7);
    scene.rest_curvature = vec![[1.2, -0.4], [-0.6, 0.9]];
    scene.distributed_force = Vector3::new(0.3, -1.1, -2.0);
    scene.tip_force = Vector3::new(-0.7, 0.4, 0.5);
    scene.base_quaternion = Quat::new(0.9, 0.2, -0.3, 0.1).normalized();
    let settings = Settings {
        n_elements: Some(20),
        residual_tol: 1e-13,
        ..Settings::default()
    };
    let mut solver = softspine::Solver::new(&scene, settings).unwrap();
    let sol = solver.solve(None).unwrap();
    let sens = solver.tip_sensitivity(2).unwrap();
    let h = 1e-6;
    for col in 0..4 {
        let tip_at = |delta: f64, solver: &mut softspine::Solver| {
            let mut k = scene.rest_curvature.clone();
            k[col / 2][col % 2] += delta;
            solver.set_rest_curvature(&k).unwrap();
            let s = solver.solve(Some(&sol.quaternions)).unwrap();
            (s.tip_position(), s.tip_quaternion().tangent())
        };
        let (rp, tp) = tip_at(h, &mut solver);
        let (rm, tm) = tip_at(-h, &mut solver);
        let fd_r = (rp - rm) / (2.0 * h);
        let fd_t = (tp - tm) / (2.0 * h);
        assert!(
            (fd_r - sens.position.column(col)).norm() < 1e-6 * (1.0 + fd_r.norm()),
            "{col}: {fd_r:?} vs {:?}",
            sens.position.column(col)
        );
        assert!((fd_t - sens.tangent.column(col)).norm() < 1e-6 * (1.0 + fd_t.norm()));
    }
}
