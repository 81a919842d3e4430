//! Frictionless contact with rigid obstacles: closed forms and exact checks.

use nalgebra::Vector3;
use softspine::contact::Obstacle;
use softspine::{solve, Gravity, Quat, Scene, Settings};

fn settings(n: usize) -> Settings {
    Settings {
        n_elements: Some(n),
        ..Settings::default()
    }
}

/// A heavy rod (EI = 1, weight 1 a length) clamped horizontally at height
/// `lift` above a frictionless table, along +x.
fn lifted_rod(length: f64, lift: f64) -> Scene {
    let mut s = Scene::new(length, 1.0, 1.0, 1.0);
    s.gravity = Some(Gravity {
        linear_density: 1.0,
        vector: Vector3::new(0.0, 0.0, -1.0),
    });
    // The material z axis (the tangent) along world +x.
    s.base_quaternion = Quat::new(
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
    );
    s.base_position = Vector3::new(0.0, 0.0, lift);
    s.obstacles = vec![Obstacle::HalfSpace {
        point: Vector3::zeros(),
        normal: Vector3::z(),
    }];
    s
}

/// The arc length where the rod first touches the table.
fn lift_off(sol: &softspine::Solution) -> f64 {
    sol.contacts
        .iter()
        .map(|c| c.arc_length)
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn a_rod_held_horizontal_above_a_table_lifts_off_at_the_closed_form() {
    let (length, lift): (f64, f64) = (2.0, 1e-4);
    let a = (72.0 * lift).powf(0.25);
    for n in [40, 80] {
        let sol = solve(&lifted_rod(length, lift), settings(n), None).unwrap();
        assert!(sol.converged(), "{}", sol.message);
        assert!(sol.stable);
        let h = length / n as f64;
        let touch = lift_off(&sol);
        eprintln!(
            "n = {n}: lift-off {touch}, closed form {a}, iterations {}",
            sol.iterations
        );
        assert!((touch - a).abs() <= h, "n = {n}: {touch} against {a}");
        // Every contact pushes; every node stays above the table.
        assert!(sol.contacts.iter().all(|c| c.force >= 0.0));
        let lowest = sol
            .positions
            .iter()
            .map(|p| p.z)
            .fold(f64::INFINITY, f64::min);
        eprintln!("lowest {lowest:e}");
        assert!(lowest >= -1e-12);
        // The table carries the weight beyond the lift-off point, and the
        // clamp the rest: the forces balance.
        let table: f64 = sol.contacts.iter().map(|c| c.force).sum();
        // `forces[0]` is what the rod exerts on its clamp.
        let base = -sol.forces[0].z;
        assert!((table + base - length).abs() < 1e-9, "{table} + {base}");
    }
}

#[test]
fn a_rod_lifted_by_a_force_at_its_end_lifts_off_at_the_closed_form() {
    // Clamped flat on the table at the origin, its end lifted by a force
    // alone: the lifted length is a = 2 F / w and the end rises by
    // h = w a^4 / (24 EI) (small deflection).
    let length = 2.0;
    let a: f64 = 0.3;
    let mut scene = lifted_rod(length, 0.0);
    scene.tip_force = Vector3::new(0.0, 0.0, 0.5 * a);
    let height = a.powi(4) / 24.0;
    for n in [40, 80, 160] {
        let sol = solve(&scene, settings(n), None).unwrap();
        assert!(sol.converged(), "{}", sol.message);
        let h = length / n as f64;
        let last = sol
            .contacts
            .iter()
            .map(|c| c.arc_length)
            .fold(0.0, f64::max);
        let tip = sol.tip_position().z;
        eprintln!(
            "n = {n}: lifted {}, closed form {a}; tip {tip:.6e} against {height:.6e}; iterations {}",
            length - last,
            sol.iterations
        );
        assert!((length - last - a).abs() <= h);
    }
}

/// A rod bent by rest curvature against a wall it presses on with its tip.
fn pressed_rod(curvature: f64) -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 2.0);
    s.rest_curvature = vec![[0.0, curvature], [0.0, curvature]];
    s.obstacles = vec![Obstacle::HalfSpace {
        point: Vector3::new(0.25, 0.0, 0.0),
        normal: -Vector3::x(),
    }];
    s
}

#[test]
fn the_tip_sensitivity_in_contact_holds_the_contacts_on_their_obstacles() {
    use softspine::Solver;
    let scene = pressed_rod(1.5);
    let mut solver = Solver::new(&scene, settings(40)).unwrap();
    let sol = solver.solve(None).unwrap();
    assert!(sol.converged(), "{}", sol.message);
    assert_eq!(sol.contacts.len(), 1, "{:?}", sol.contacts);
    assert_eq!(sol.contacts[0].arc_length, 1.0);
    let sensitivity = solver.tip_sensitivity(2).unwrap();
    // The tip slides on the wall: it cannot move along its normal.
    for column in sensitivity.position.column_iter() {
        assert!(column.x.abs() < 1e-9 * column.norm().max(1.0), "{column:?}");
    }
    assert_matches_differences(&scene, &sol, &sensitivity.position, 40);
}

/// Each column of `position` (the tip's sensitivity to each section's rest
/// curvature) against central differences of the forward solve, from the
/// equilibrium `sol` of `scene` at `n` elements, its one contact held.
fn assert_matches_differences(
    scene: &Scene,
    sol: &softspine::Solution,
    position: &nalgebra::Matrix3xX<f64>,
    n: usize,
) {
    let step = 1e-6;
    for column in 0..position.ncols() {
        let tip = |delta: f64| {
            let mut moved = scene.clone();
            moved.rest_curvature[column / 2][column % 2] += delta;
            let sol = solve(&moved, settings(n), Some(&sol.quaternions)).unwrap();
            assert!(sol.converged() && sol.contacts.len() == 1);
            sol.tip_position()
        };
        let difference = (tip(step) - tip(-step)) / (2.0 * step);
        let exact = position.column(column);
        assert!(
            (difference - exact).norm() < 1e-6 * exact.norm().max(1e-3),
            "column {column}: {difference:?} against {exact:?}"
        );
    }
}

#[test]
fn the_jacobian_turns_a_contact_force_with_a_curved_obstacle() {
    // The rod of the test above pressed onto a ball instead of a wall, the
    // contact inside an element: its force turns with the ball's normal as
    // the rod moves, which the tip sensitivity (the KKT system's columns)
    // sees only with the contacts' curvature in the Jacobian.
    use softspine::Solver;
    let mut scene = pressed_rod(1.5);
    scene.obstacles = vec![Obstacle::Sphere {
        centre: Vector3::new(0.45, 0.0, 0.55),
        radius: 0.2,
    }];
    let mut solver = Solver::new(&scene, settings(20)).unwrap();
    let sol = solver.solve(None).unwrap();
    assert!(sol.converged(), "{}", sol.message);
    assert_eq!(sol.contacts.len(), 1, "{:?}", sol.contacts);
    let s = sol.contacts[0].arc_length * 20.0;
    assert!((s - s.round()).abs() > 1e-3, "inside an element: {s}");
    let sensitivity = solver.tip_sensitivity(2).unwrap();
    assert_matches_differences(&scene, &sol, &sensitivity.position, 20);
}
