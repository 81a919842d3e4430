//! Frictionless contact (issue 28): a heavy rod lying on a floor (every node
//! in contact) and lifted off it, a cantilever pressed on a knife edge, and
//! the seed's robot bent into a wall and onto a ball, beside the same robot
//! without them.
//! Sliding ports: a heavy cantilever bent through a port off its line, the
//! seed's robot bent through a port, and its inverse kinematics along a
//! circle with the insertion as one more coordinate. Friction: the rod on a
//! floor with `mu = 0.3` (every node sticks), the same rod pushed sideways
//! at its tip by 0.05 of its weight (part sticks, part slides, some of it
//! backwards: the relaxed levels), the robot against the wall with
//! `mu = 0.5` (its contact slides down it), and its inverse kinematics
//! along 12 points leaning on a ball, without and with friction.
//!
//! `cargo bench --bench contact`; the medians go into docs/model.md's
//! "Contact with obstacles" and the notes.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softspine::contact::{Obstacle, Port};
use softspine::{Actuation, Gravity, IkOptions, Load, Quat, Robot, Scene, Settings, Solver};
use std::hint::black_box;

/// A heavy rod (EI = 1, 1 N/m, 1 m) along +x, clamped at `lift` above a floor.
fn rod_on_floor(lift: f64) -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 1.0);
    s.gravity = Some(Gravity {
        linear_density: 1.0,
        vector: Vector3::new(0.0, 0.0, -1.0),
    });
    let half = std::f64::consts::FRAC_1_SQRT_2;
    s.base_quaternion = Quat::new(half, 0.0, half, 0.0);
    s.base_position = Vector3::new(0.0, 0.0, lift);
    s.obstacles = vec![Obstacle::HalfSpace {
        point: Vector3::zeros(),
        normal: Vector3::z(),
    }];
    s
}

/// A weightless cantilever pressed by its tip force onto a thin capsule
/// across it at 0.6 L (P L^2 / EI = 0.5: the contact inside an element).
fn knife_edge() -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 1.0);
    let half = std::f64::consts::FRAC_1_SQRT_2;
    s.base_quaternion = Quat::new(half, 0.0, half, 0.0);
    s.tip_force = Vector3::new(0.0, 0.0, -0.5);
    s.obstacles = vec![Obstacle::Capsule {
        a: Vector3::new(0.6, -1.0, -1e-6),
        b: Vector3::new(0.6, 1.0, -1e-6),
        radius: 1e-6,
    }];
    s
}

/// A heavy cantilever (EI = 1, 1 N/m) along +x through a port at (0.5, 0,
/// 0.1) m, with 0.5 N down at its tip (`tests/test_ports.py`'s second case).
fn through_port() -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 1.0);
    let half = std::f64::consts::FRAC_1_SQRT_2;
    s.base_quaternion = Quat::new(half, 0.0, half, 0.0);
    s.tip_force = Vector3::new(0.0, 0.0, -0.5);
    s.gravity = Some(Gravity {
        linear_density: 1.0 / 9.81,
        vector: Vector3::new(0.0, 0.0, -9.81),
    });
    s.ports = vec![Port::new(Vector3::new(0.5, 0.0, 0.1), Vector3::x())];
    s
}

/// The rod on the floor pushed sideways (+y) at its tip by `push` [N].
fn pushed_along_floor(push: f64) -> Scene {
    let mut s = with_friction(rod_on_floor(0.0), 0.3);
    s.tip_force = Vector3::new(0.0, push, 0.0);
    s
}

/// `scene` with every obstacle's friction `mu`.
fn with_friction(mut scene: Scene, mu: f64) -> Scene {
    scene.friction = vec![mu; scene.obstacles.len()];
    scene
}

fn scenes(c: &mut Criterion) {
    let mut group = c.benchmark_group("contact");
    for (name, scene, sizes) in [
        ("rod_on_floor", rod_on_floor(0.0), &[20, 80, 320][..]),
        ("rod_lifted_5cm", rod_on_floor(0.05), &[20, 80, 320][..]),
        ("knife_edge", knife_edge(), &[20, 80][..]),
        ("through_port", through_port(), &[20, 80, 320][..]),
        (
            "rod_on_floor_friction",
            with_friction(rod_on_floor(0.0), 0.3),
            &[20, 80][..],
        ),
        (
            "rod_pushed_along_floor_friction",
            pushed_along_floor(0.05),
            &[20, 80][..],
        ),
    ] {
        for &n in sizes {
            let settings = Settings {
                n_elements: Some(n),
                ..Settings::default()
            };
            let mut solver = Solver::new(&scene, settings).unwrap();
            assert!(solver.solve(None).unwrap().converged());
            group.bench_with_input(BenchmarkId::new(name, n), &n, |b, _| {
                b.iter(|| black_box(solver.solve(None).unwrap()))
            });
        }
    }
    // The seed's robot bent toward a wall 15 cm off its axis, 30 g.
    let bend = Actuation::muscles(vec![[0.0, 0.6]; 10]);
    let load = Load {
        mass: 0.03,
        ..Load::default()
    };
    let walled = Robot {
        obstacles: vec![Obstacle::HalfSpace {
            point: Vector3::new(0.15, 0.0, 0.0),
            normal: -Vector3::x(),
        }],
        ..Robot::default()
    };
    // The same robot leaning on a ball of 10 cm its rest shape runs through
    // (one contact, on the ball's near side).
    let balled = Robot {
        obstacles: vec![Obstacle::Sphere {
            centre: Vector3::new(0.2, 0.0, -0.75),
            radius: 0.1,
        }],
        ..Robot::default()
    };
    // A wall 5 cm off the axis in front of that ball: the robot leans on
    // the wall alone, its rest shape deep in both.
    let walled_balled = Robot {
        obstacles: vec![
            Obstacle::HalfSpace {
                point: Vector3::new(0.05, 0.0, 0.0),
                normal: -Vector3::x(),
            },
            balled.obstacles[0].clone(),
        ],
        ..Robot::default()
    };
    let walled_friction = Robot {
        friction: vec![0.5],
        ..walled.clone()
    };
    // Through a port 0.3 m below its base, fed 0.1 m in by its stage.
    let ported = Robot {
        ports: vec![Port::new(Vector3::new(0.0, 0.0, -0.3), -Vector3::z())],
        insertion_range: Some([0.0, 0.2]),
        ..Robot::default()
    };
    let inserted = Actuation {
        insertion: 0.1,
        ..bend.clone()
    };
    // Its first five sections bent 2.8 /m, the last five straight: the
    // straight half lies on a floor 33 cm below the base (8 contacts).
    let half_bent = Actuation::muscles(
        (0..10)
            .map(|s| [0.0, if s < 5 { 2.8 } else { 0.0 }])
            .collect(),
    );
    let floored = Robot {
        obstacles: vec![Obstacle::HalfSpace {
            point: Vector3::new(0.0, 0.0, -0.33),
            normal: Vector3::z(),
        }],
        ..Robot::default()
    };
    for (name, robot, drive) in [
        ("robot_free", Robot::default(), &bend),
        ("robot_free_half_bent", Robot::default(), &half_bent),
        ("robot_floor", floored, &half_bent),
        ("robot_wall", walled, &bend),
        ("robot_ball", balled, &bend),
        ("robot_wall_ball", walled_balled, &bend),
        ("robot_wall_friction", walled_friction, &bend),
        ("robot_port", ported.clone(), &inserted),
    ] {
        let sol = robot.forward(drive, &load, None).unwrap();
        assert!(sol.converged());
        group.bench_function(name, |b| {
            b.iter(|| black_box(robot.forward(drive, &load, None).unwrap()))
        });
    }
    // 24 points of a circle 5 cm across the axis, 1.05 m below the base:
    // past the fixed robot's reach, so every answer inserts.
    let circle: Vec<Vector3<f64>> = (0..24)
        .map(|k| {
            let t = 2.0 * std::f64::consts::PI * k as f64 / 24.0;
            Vector3::new(0.05 * t.cos(), 0.05 * t.sin(), -1.05)
        })
        .collect();
    let options = IkOptions {
        load: 0.03.into(),
        ..IkOptions::default()
    };
    assert!(ported
        .track(&circle, &options)
        .unwrap()
        .iter()
        .all(|r| r.reached));
    group.bench_function("robot_port_track_24", |b| {
        b.iter(|| black_box(ported.track(&circle, &options).unwrap()))
    });
    // The robot's inverse kinematics leaning on a ball, 12 points a few mm
    // apart, without and with friction (mu = 0.3: each answer one step of
    // its history from the last; the first from rest).
    let ball = Obstacle::Sphere {
        centre: Vector3::new(0.08, 0.0, -0.5),
        radius: 0.08,
    };
    let leaning: Vec<Vector3<f64>> = (0..12)
        .map(|k| Vector3::new(0.1, 0.002 * k as f64, -0.93 - 0.001 * k as f64))
        .collect();
    for (name, friction) in [
        ("robot_ball_track_12", vec![]),
        ("robot_ball_friction_track_12", vec![0.3]),
    ] {
        let robot = Robot {
            obstacles: vec![ball.clone()],
            friction,
            ..Robot::default()
        };
        assert!(robot
            .track(&leaning, &options)
            .unwrap()
            .iter()
            .all(|r| r.reached));
        group.bench_function(name, |b| {
            b.iter(|| black_box(robot.track(&leaning, &options).unwrap()))
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = scenes
}
criterion_main!(benches);
