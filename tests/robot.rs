//! The robot: maps between spaces, load-aware inverse kinematics, trajectories.

use nalgebra::Vector3;
use softspine::robot::trajectory;
use softspine::robot::MAX_SECTIONS;
use softspine::{solve, Error, IkOptions, IkSettings, Robot, Settings, Strategy, Value};

#[test]
fn spaces_round_trip() {
    let robot = Robot::default();
    let kappa: Vec<[f64; 2]> = (0..10)
        .map(|k| [0.3 * k as f64 - 1.0, 2.0 - 0.25 * k as f64])
        .collect();
    let lengths = robot.muscle_lengths(&kappa).unwrap();
    let back = robot.rest_curvature(&lengths).unwrap();
    for (a, b) in kappa.iter().zip(&back) {
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
    }
    let times = robot.inflation_times(&lengths).unwrap();
    let again = robot.muscle_lengths_from_times(&times).unwrap();
    for (a, b) in lengths.iter().zip(&again) {
        for i in 0..3 {
            assert!((a[i] - b[i]).abs() < 1e-15);
        }
    }
}

#[test]
fn tracking_reaches_every_point_of_the_circle_with_30_g() {
    let robot = Robot::default();
    let points = trajectory::circle(60);
    let options = IkOptions {
        load: 0.03.into(),
        ..IkOptions::default()
    };
    let t0 = std::time::Instant::now();
    let results = robot.track(&points, &options).unwrap();
    eprintln!("60 points in {:?}", t0.elapsed());
    for (r, p) in results.iter().zip(&points) {
        assert!(r.reached, "{}: {}", p, r.message);
        assert!(r.tip_miss < 1e-9);
        assert!(robot.within_bounds(&r.rest_curvature).unwrap());
        // A true equilibrium: a fresh solve from the straight rod lands on the same tip.
        let scene = robot
            .scene(
                &softspine::Actuation::muscles(r.rest_curvature.clone()),
                &softspine::Load::from(0.03),
            )
            .unwrap();
        let fresh = solve(
            &scene,
            Settings {
                n_elements: Some(robot.n_elements),
                ..Settings::default()
            },
            None,
        )
        .unwrap();
        assert!(
            (fresh.tip_position() - p).norm() < 1e-8,
            "{}",
            (fresh.tip_position() - p).norm()
        );
    }
    let iters: Vec<usize> = results.iter().map(|r| r.iterations).collect();
    eprintln!("iterations {iters:?}");
}

#[test]
fn geometric_strategy_misses_under_load() {
    let robot = Robot::default();
    let target = Vector3::new(0.2, 0.0, -0.88);
    let options = IkOptions {
        load: 0.06.into(),
        settings: IkSettings {
            strategy: Strategy::Geometric,
            ..IkSettings::default()
        },
        ..IkOptions::default()
    };
    let r = robot.inverse(target, &options).unwrap();
    eprintln!("geometric miss {:.4} m: {}", r.tip_miss, r.message);
    assert!(r.tip_miss > 0.01);
}

#[test]
fn unreachable_target_returns_the_closest_tip() {
    let robot = Robot::default();
    // Farther from the base than the rod is long.
    let target = Vector3::new(1.0, 0.0, -1.0);
    let r = robot.inverse(target, &IkOptions::default()).unwrap();
    eprintln!("{} (tip {:?})", r.message, r.tip_position);
    assert!(!r.reached);
    assert!(r.message.contains("not reached"));
    // The closest tip found is much closer than the hanging rod's, and the
    // actuation respects the muscles' range.
    assert!(r.tip_miss < 0.5 * (Vector3::new(0.0, 0.0, -1.0) - target).norm());
    assert!(robot.within_bounds(&r.rest_curvature).unwrap());
}

/// The key a robot table is refused for.
fn refused_key(entries: &[(&str, Value)]) -> String {
    let table = Value::Map(
        entries
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect(),
    );
    match Robot::from_value(&table) {
        Err(Error::InvalidScene { key, .. }) => key,
        other => panic!("{entries:?} not refused by key: {other:?}"),
    }
}

#[test]
fn robot_input_is_refused_naming_the_key() {
    let n = Value::Number;
    let list = |xs: &[f64]| Value::List(xs.iter().map(|x| Value::Number(*x)).collect());
    // Derived quantities that underflow or overflow blame the field that sets them.
    assert_eq!(refused_key(&[("length", n(1e-300))]), "length");
    assert_eq!(
        refused_key(&[("muscle_radius", n(1e-300))]),
        "muscle_radius"
    );
    assert_eq!(
        refused_key(&[("inflation_rate", n(1e-320))]),
        "inflation_rate"
    );
    // Collinear muscles cannot bend a section in every direction.
    let collinear = list(&[0.0, 180.0, 360.0]);
    assert_eq!(
        refused_key(&[("muscle_angles", collinear)]),
        "muscle_angles"
    );
    // Counts are checked before anything is allocated, shown as given.
    assert_eq!(refused_key(&[("sections", n(1e19))]), "sections");
    assert_eq!(refused_key(&[("n_elements", n(1e12))]), "n_elements");
    let err = Robot::from_value(&Value::Map(vec![("sections".into(), n(1e19))])).unwrap_err();
    assert!(err.to_string().ends_with("got 1e19"), "{err}");
}

#[test]
fn robots_built_in_rust_are_checked_too() {
    let mut huge = Robot::default();
    huge.body.sections = MAX_SECTIONS + 1;
    assert!(matches!(huge.validate(), Err(Error::InvalidScene { key, .. }) if key == "sections"));
    let mut collinear = Robot::default();
    let softspine::robot::Drive::Muscles(m) = &mut collinear.drive else {
        panic!("the default robot is driven by muscles")
    };
    m.angles = [0.0, 180.0, 360.0];
    assert!(collinear
        .inverse(Vector3::new(0.1, 0.0, -0.9), &IkOptions::default())
        .is_err());
}
