//! Sliding ports from Rust: the base's sensitivity (a robot's insertion)
//! against differences, through a port and on an obstacle.

use nalgebra::Vector3;
use softspine::contact::{Obstacle, Port};
use softspine::{Gravity, Quat, Scene, Settings, Solver};

/// A heavy rod (EI = 1) along +x through a port off its line, with a tip
/// load; the port bends it up, onto a ceiling where `obstacle`.
fn through_a_port(obstacle: bool) -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 1.0);
    s.base_quaternion = Quat::new(
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
        std::f64::consts::FRAC_1_SQRT_2,
        0.0,
    );
    s.gravity = Some(Gravity {
        linear_density: 0.1,
        vector: Vector3::new(0.0, 0.0, -9.81),
    });
    s.tip_force = Vector3::new(0.0, 0.3, -0.5);
    s.ports = vec![Port::new(Vector3::new(0.4, 0.02, 0.05), Vector3::x())];
    if obstacle {
        s.obstacles = vec![Obstacle::HalfSpace {
            point: Vector3::new(0.0, 0.0, 0.07),
            normal: -Vector3::z(),
        }];
    }
    s
}

fn settings() -> Settings {
    Settings {
        n_elements: Some(40),
        residual_tol: 1e-13,
        ..Settings::default()
    }
}

#[test]
fn the_base_sensitivity_is_the_difference_of_moved_bases() {
    for obstacle in [false, true] {
        let scene = through_a_port(obstacle);
        let mut solver = Solver::new(&scene, settings()).unwrap();
        let sol = solver.solve(None).unwrap();
        assert!(sol.converged(), "{}", sol.message);
        assert_eq!(!sol.contacts.is_empty(), obstacle);
        let direction = Vector3::new(1.0, 0.2, -0.1).normalize();
        let sens = solver.base_sensitivity(direction).unwrap();
        let step = 1e-6;
        let tip = |sign: f64| {
            let mut moved = scene.clone();
            moved.base_position += sign * step * direction;
            let s = softspine::solve(&moved, settings(), Some(&sol.quaternions)).unwrap();
            assert!(s.converged());
            assert_eq!(s.contacts.len(), sol.contacts.len());
            s.positions[s.positions.len() - 1]
        };
        let difference = (tip(1.0) - tip(-1.0)) / (2.0 * step);
        let analytic: Vector3<f64> = sens.position.column(0).into();
        eprintln!("obstacle {obstacle}: {analytic:?} against {difference:?}");
        assert!(
            (analytic - difference).norm() < 1e-8,
            "{analytic} {difference}"
        );
        // The port holds the rod back: not a rigid translation.
        assert!((analytic - direction).norm() > 1e-2);
    }
}
