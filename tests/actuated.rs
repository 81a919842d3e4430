//! Tendon-driven and magnetic robots: forward solves, inverse kinematics in
//! tension and field space, and their endings.

use nalgebra::{DMatrix, DVector, Vector3};
use softspine::{Actuation, IkEnding, IkOptions, Robot};

/// Three 0.1 m sections pointing up, three tendons a section 8 mm off the
/// backbone (turned 40 degrees a section), each anchored at its section's end.
fn tendon_robot(max_tension: Option<f64>) -> Robot {
    let mut tendons = Vec::new();
    for section in 0..3 {
        for k in 0..3 {
            let angle = (90.0 + 120.0 * k as f64 + 40.0 * section as f64).to_radians();
            tendons.push(format!(
                "{{offset = [{}, {}], section = {}}}",
                0.008 * angle.cos(),
                0.008 * angle.sin(),
                section + 1
            ));
        }
    }
    let limit = max_tension.map_or(String::new(), |t| format!("max_tension = {t}\n"));
    Robot::from_toml_str(&format!(
        "length = 0.3\nsections = 3\nlinear_density = 0.05\ndisk_mass = 0.002\n\
         base_quaternion = [1, 0, 0, 0]\nstiffness = {{E = 60e9, G = 23e9, diameter = 0.0015}}\n\
         {limit}tendons = [{}]\n",
        tendons.join(", ")
    ))
    .unwrap()
}

/// A 0.2 m catheter pointing up, its last quarter magnetised along its axis,
/// with a tip magnet.
fn catheter(max_field: f64) -> Robot {
    Robot::from_toml_str(&format!(
        "length = 0.2\nsections = 4\nlinear_density = 0.01\ndisk_mass = 0.0\n\
         base_quaternion = [1, 0, 0, 0]\nstiffness = {{kx = 2e-4, ky = 2e-4, kz = 1.5e-4}}\n\
         magnetization = [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0.05]]\n\
         tip_magnet = [0, 0, 0.05]\nmax_field = {max_field}\n"
    ))
    .unwrap()
}

fn tip_of(robot: &Robot, actuation: &Actuation, mass: f64) -> Vector3<f64> {
    let scene = robot
        .scene(actuation, &softspine::Load::from(mass))
        .unwrap();
    let settings = softspine::Settings {
        n_elements: Some(robot.n_elements),
        ..Default::default()
    };
    let sol = softspine::solve(&scene, settings, None).unwrap();
    assert!(sol.converged() && sol.stable);
    sol.tip_position()
}

fn options(mass: f64) -> IkOptions {
    IkOptions {
        load: mass.into(),
        ..IkOptions::default()
    }
}

/// The KKT conditions of `min |t - p|^2` over `tip(t) = target`, `t >= 0`:
/// the free tensions' offset from the pull lies in the span of their
/// sensitivity rows, with multipliers that would not pull a slack tendon.
fn assert_minimum_norm(robot: &Robot, tensions: &[f64], pull: &[f64], mass: f64) {
    let actuation = Actuation {
        tensions: tensions.to_vec(),
        ..Actuation::default()
    };
    let (_, sens) = robot
        .sensitivity(
            &actuation,
            &softspine::Load::from(mass),
            &["tensions"],
            None,
        )
        .unwrap();
    let free: Vec<usize> = (0..tensions.len())
        .filter(|&i| tensions[i] > 1e-8)
        .collect();
    let jf = DMatrix::from_fn(3, free.len(), |r, c| sens.tip_position[(r, free[c])]);
    let offset = DVector::from_iterator(free.len(), free.iter().map(|&i| tensions[i] - pull[i]));
    let y = jf
        .transpose()
        .svd(true, true)
        .solve(&offset, 1e-12)
        .unwrap();
    let off_span = (&offset - jf.transpose() * &y).norm() / offset.norm();
    assert!(off_span < 1e-5, "not stationary: {off_span:e}");
    for i in (0..tensions.len()).filter(|i| !free.contains(i)) {
        let pulls: f64 = (0..3)
            .map(|r| sens.tip_position[(r, i)] * y[r])
            .sum::<f64>()
            - pull[i];
        // A positive multiplier would lower the objective by engaging the tendon.
        assert!(
            pulls <= 1e-6 * y.norm(),
            "slack tendon {i} would pull: {pulls:e}"
        );
    }
}

#[test]
fn the_tensions_found_reach_the_target_with_the_least_norm() {
    let robot = tendon_robot(None);
    let given = [12.0, 0.0, 0.0, 0.0, 0.0, 14.0, 0.0, 10.0, 0.0];
    let actuation = Actuation {
        tensions: given.to_vec(),
        ..Actuation::default()
    };
    for (target, mass) in [
        (tip_of(&robot, &actuation, 0.02), 0.02),
        (Vector3::new(0.05, 0.02, 0.27), 0.02),
        (Vector3::new(0.1, 0.1, 0.2), 0.0),
    ] {
        let r = robot.inverse(target, &options(mass)).unwrap();
        assert_eq!(r.ending, IkEnding::Reached, "{}", r.message);
        assert!(r.tip_miss <= 1e-9);
        assert!(r.solution.stable);
        assert!(r.tensions.iter().all(|t| *t >= 0.0));
        // The forward solve of the answer puts the tip there.
        let again = Actuation {
            tensions: r.tensions.clone(),
            ..Actuation::default()
        };
        assert!((tip_of(&robot, &again, mass) - target).norm() < 1e-8);
        assert_minimum_norm(&robot, &r.tensions, &[0.0; 9], mass);
    }
}

#[test]
fn a_pretension_that_reaches_the_target_is_its_own_answer() {
    let robot = tendon_robot(None);
    let given = vec![12.0, 0.0, 0.0, 0.0, 0.0, 14.0, 0.0, 10.0, 0.0];
    let actuation = Actuation {
        tensions: given.clone(),
        ..Actuation::default()
    };
    let target = tip_of(&robot, &actuation, 0.02);
    let r = robot
        .inverse(
            target,
            &IkOptions {
                pretension: Some(given.clone()),
                ..options(0.02)
            },
        )
        .unwrap();
    assert!(r.reached, "{}", r.message);
    for (t, g) in r.tensions.iter().zip(&given) {
        assert!((t - g).abs() < 1e-6, "{:?}", r.tensions);
    }
}

#[test]
fn a_drive_at_its_limit_is_told_from_a_target_out_of_reach() {
    // Past the robot's length straight up: nothing holds the robot back but
    // its length.
    let robot = tendon_robot(None);
    let r = robot
        .inverse(Vector3::new(0.0, 0.0, 0.5), &options(0.0))
        .unwrap();
    assert_eq!(r.ending, IkEnding::OutOfReach, "{}", r.message);
    // A target 5 N of tension would not reach: the tensions stop at it.
    let limited = tendon_robot(Some(5.0));
    let r = limited
        .inverse(Vector3::new(0.1, 0.1, 0.2), &options(0.0))
        .unwrap();
    assert_eq!(r.ending, IkEnding::BoundsActive, "{}", r.message);
    assert!(r.tensions.iter().all(|t| (0.0..=5.0).contains(t)));
    assert!(r.tip_miss > 1e-3);
}

#[test]
fn the_field_found_reaches_a_tip_the_field_can_reach() {
    let robot = catheter(0.05);
    let field = Vector3::new(0.03, -0.01, 0.0);
    let target = tip_of(
        &robot,
        &Actuation {
            field,
            ..Actuation::default()
        },
        0.0,
    );
    let r = robot.inverse(target, &options(0.0)).unwrap();
    assert_eq!(r.ending, IkEnding::Reached, "{}", r.message);
    assert!(r.field.norm() <= 0.05);
    assert!(r.tensions.is_empty());
    // A stronger field than the system makes: its limit holds the tip back.
    let weak = catheter(0.01);
    let r = weak.inverse(target, &options(0.0)).unwrap();
    assert_eq!(r.ending, IkEnding::BoundsActive, "{}", r.message);
    assert!(r.field.norm() <= 0.01 * (1.0 + 1e-12));
}

#[test]
fn a_tip_magnet_reaches_a_surface_and_ends_at_its_closest_point_off_it() {
    // Off the surface of reachable tips the answer is the closest tip found:
    // no field in its neighbourhood (within 30 % of its size, sampled on a
    // grid) puts the tip noticeably closer.
    let robot = catheter(0.05);
    let target = Vector3::new(0.05, 0.05, 0.17);
    let r = robot.inverse(target, &options(0.0)).unwrap();
    assert_eq!(r.ending, IkEnding::OutOfReach, "{}", r.message);
    let radius = 0.3 * r.field.norm();
    let steps = [-1.0, -0.5, 0.0, 0.5, 1.0];
    let mut closest = f64::INFINITY;
    for a in steps {
        for b in steps {
            for c in steps {
                let field = r.field + Vector3::new(a, b, c) * radius;
                let actuation = Actuation {
                    field,
                    ..Actuation::default()
                };
                closest = closest.min((tip_of(&robot, &actuation, 0.0) - target).norm());
            }
        }
    }
    assert!(
        closest >= (1.0 - 1e-3) * r.tip_miss,
        "{closest} < {}",
        r.tip_miss
    );
}

#[test]
fn tracking_a_circle_reaches_every_point_with_tensions_that_move_smoothly() {
    let robot = tendon_robot(None);
    let points: Vec<Vector3<f64>> = (0..12)
        .map(|i| {
            let a = i as f64 / 12.0 * std::f64::consts::TAU;
            Vector3::new(0.06 * a.cos(), 0.06 * a.sin(), 0.27)
        })
        .collect();
    let results = robot.track(&points, &options(0.01)).unwrap();
    for r in &results {
        assert!(r.reached, "{}", r.message);
    }
    let largest_jump = results
        .windows(2)
        .map(|w| {
            w[0].tensions
                .iter()
                .zip(&w[1].tensions)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let largest = results
        .iter()
        .flat_map(|r| r.tensions.iter().copied())
        .fold(0.0, f64::max);
    assert!(largest_jump < 0.8 * largest, "{largest_jump} of {largest}");
}

#[test]
fn actuation_the_drives_cannot_apply_is_refused_by_name() {
    let robot = tendon_robot(Some(20.0));
    let scene = |tensions: Vec<f64>| {
        robot
            .scene(
                &Actuation {
                    tensions,
                    ..Actuation::default()
                },
                &softspine::Load::from(0.0),
            )
            .unwrap_err()
            .to_string()
    };
    assert!(scene(vec![1.0; 4]).contains("tensions"));
    let mut negative = vec![0.0; 9];
    negative[3] = -1.0;
    assert!(scene(negative).contains("tensions[3]"));
    let mut high = vec![0.0; 9];
    high[8] = 25.0;
    assert!(scene(high).contains("max_tension"));
    let magnet = catheter(0.05);
    let e = magnet
        .scene(
            &Actuation {
                field: Vector3::new(0.1, 0.0, 0.0),
                ..Actuation::default()
            },
            &softspine::Load::from(0.0),
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("max_field"), "{e}");
    let e = Robot::from_toml_str("sections = 2\ntendons = [{offset = [0.01, 0], section = 3}]")
        .unwrap_err()
        .to_string();
    assert!(e.contains("tendons[0].section"), "{e}");
    let e = Robot::from_toml_str("sections = 3\nmagnetization = [[0, 0, 1], [0, 0, 1]]")
        .unwrap_err()
        .to_string();
    assert!(e.contains("magnetization"), "{e}");
}

#[test]
fn the_tension_sensitivity_is_the_implicit_function_theorems_in_either_scheme() {
    // Solver::tension_sensitivity (each tendon's moment per unit tension, one
    // back-substitution) against the general path (the same analytic
    // derivatives through the scene's paths) and whole solves, fd2 and fe4.
    let robot = tendon_robot(None);
    let tensions = vec![3.0, 0.0, 1.0, 0.0, 2.0, 4.0, 0.5, 1.0, 0.0];
    for scheme in [softspine::Scheme::Fd2, softspine::Scheme::Fe4] {
        let actuation = Actuation {
            tensions: tensions.clone(),
            ..Actuation::default()
        };
        let scene = robot
            .scene(&actuation, &softspine::Load::from(0.02))
            .unwrap();
        let settings = softspine::Settings {
            n_elements: Some(robot.n_elements),
            scheme: Some(scheme),
            residual_tol: 1e-13,
            ..Default::default()
        };
        let mut solver = softspine::Solver::new(&scene, settings.clone()).unwrap();
        let sol = solver.solve(None).unwrap();
        assert!(sol.converged());
        let closed = solver.tension_sensitivity().unwrap();
        let names: Vec<String> = (0..9).map(|i| format!("tendons[{i}].tension")).collect();
        let names: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
        let general = solver.sensitivity(&names).unwrap();
        assert!(general.exact.iter().all(|e| *e));
        let scale = general.tip_position.norm();
        let gap = (&closed.position - &general.tip_position).norm() / scale;
        assert!(gap < 1e-10, "{scheme:?}: {gap:e}");
        // And whole solves with the sixth tension moved (a five-point
        // difference: truncation about h^4).
        let h = 1e-2;
        let tip = |dt: f64| {
            let mut moved = tensions.clone();
            moved[5] += dt;
            let moved = Actuation {
                tensions: moved,
                ..Actuation::default()
            };
            let scene = robot.scene(&moved, &softspine::Load::from(0.02)).unwrap();
            let sol = softspine::solve(&scene, settings.clone(), None).unwrap();
            assert!(sol.converged());
            sol.tip_position()
        };
        let difference =
            (-tip(2.0 * h) + 8.0 * tip(h) - 8.0 * tip(-h) + tip(-2.0 * h)) / (12.0 * h);
        let column = closed.position.column(5);
        assert!(
            (difference - column).norm() < 1e-7 * column.norm(),
            "{scheme:?}: {difference} vs {column}"
        );
    }
}

#[test]
fn tensions_reach_a_tip_position_and_direction_together() {
    let robot = tendon_robot(None);
    let actuation = Actuation {
        tensions: vec![5.0, 0.0, 2.0, 0.0, 3.0, 0.0, 1.0, 0.0, 4.0],
        ..Actuation::default()
    };
    let scene = robot
        .scene(&actuation, &softspine::Load::from(0.01))
        .unwrap();
    let settings = softspine::Settings {
        n_elements: Some(robot.n_elements),
        ..Default::default()
    };
    let sol = softspine::solve(&scene, settings, None).unwrap();
    let direction = sol.tip_quaternion().tangent();
    let r = robot
        .inverse(
            sol.tip_position(),
            &IkOptions {
                direction: Some(direction),
                ..options(0.01)
            },
        )
        .unwrap();
    assert!(r.reached, "{}", r.message);
    let reached = r.solution.tip_quaternion().tangent();
    assert!(
        (reached - direction).norm() < 1e-8,
        "{}",
        (reached - direction).norm()
    );
}

#[test]
fn the_predicted_equilibrium_is_first_order_in_the_drives_move() {
    // Solver::predicted_state turns the state along the sensitivity's state
    // columns: its distance from the true equilibrium at moved tensions falls
    // as the square of the move (by 4 when the move halves), it is far
    // closer than the unmoved state, and it is refused for another state.
    let robot = tendon_robot(None);
    let tensions = vec![3.0, 0.0, 1.0, 0.0, 2.0, 4.0, 0.5, 1.0, 0.0];
    let settings = softspine::Settings {
        n_elements: Some(robot.n_elements),
        residual_tol: 1e-13,
        ..Default::default()
    };
    let scene_at = |t: &[f64]| {
        let actuation = Actuation {
            tensions: t.to_vec(),
            ..Actuation::default()
        };
        robot
            .scene(&actuation, &softspine::Load::from(0.02))
            .unwrap()
    };
    let mut solver = softspine::Solver::new(&scene_at(&tensions), settings.clone()).unwrap();
    let q = solver.solve(None).unwrap().quaternions;
    solver.tension_sensitivity().unwrap();
    let direction = [0.5, 1.0, -0.3, 0.8, 0.0, -1.0, 0.4, 0.2, 0.6];
    let gap = |a: &[softspine::Quat], b: &[softspine::Quat]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x.rotation() - y.rotation()).norm())
            .fold(0.0, f64::max)
    };
    let misses: Vec<(f64, f64)> = [0.4, 0.2, 0.1]
        .iter()
        .map(|h| {
            let moved: Vec<f64> = tensions
                .iter()
                .zip(&direction)
                .map(|(t, d)| t + h * d)
                .collect();
            let dp: Vec<f64> = direction.iter().map(|d| h * d).collect();
            let predicted = solver.predicted_state(&q, &dp).unwrap();
            let truth = softspine::solve(&scene_at(&moved), settings.clone(), None)
                .unwrap()
                .quaternions;
            (gap(&predicted, &truth), gap(&q, &truth))
        })
        .collect();
    for pair in misses.windows(2) {
        let ratio = pair[0].0 / pair[1].0;
        assert!((3.0..5.0).contains(&ratio), "{misses:?}");
    }
    for (predicted, unmoved) in &misses {
        assert!(predicted * 10.0 < *unmoved, "{misses:?}");
    }
    let mut other = q.clone();
    other[3] = other[3].perturbed(nalgebra::Vector3::new(1e-9, 0.0, 0.0));
    assert!(solver.predicted_state(&other, &direction).is_none());
    assert!(solver.predicted_state(&q, &direction[..8]).is_none());
}
