//! Load-aware inverse kinematics of the default robot (n = 20): one trajectory
//! point warm from its neighbour, and whole 60-point trajectories. Then the
//! tendon robot and the magnetic catheter of `examples/robots`: a forward
//! solve of each kind of robot, a tracked trajectory, and a target out of reach.
//!
//! `cargo bench --bench robot`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softspine::robot::trajectory;
use softspine::{Actuation, IkOptions, InverseSolver, Robot, Settings};
use std::hint::black_box;

fn ik(c: &mut Criterion) {
    let robot = Robot::default();
    let mut group = c.benchmark_group("ik");
    for name in ["pentagram", "circle", "spiral"] {
        let points = trajectory::by_name(name, 60).unwrap();
        for grams in [0u32, 30, 60] {
            let mass = grams as f64 * 1e-3;
            // One point, warm, as in tracking: from the answer at the previous
            // point, with that answer as the reference (the timed solve only).
            let mut solver = InverseSolver::new(&robot, &softspine::Load::from(mass)).unwrap();
            let (a, b) = (points[10], points[11]);
            group.bench_function(
                BenchmarkId::new(format!("point_warm/{name}"), grams),
                |bench| {
                    bench.iter_custom(|iters| {
                        let mut total = std::time::Duration::ZERO;
                        for _ in 0..iters {
                            let previous = solver.solve(a, None, None, 1e-9, 60).unwrap();
                            let started = std::time::Instant::now();
                            let r = solver
                                .solve(b, None, Some(&previous.drive(solver.space())), 1e-9, 60)
                                .unwrap();
                            total += started.elapsed();
                            assert!(r.reached);
                            black_box(r);
                        }
                        total
                    })
                },
            );
            let options = IkOptions {
                load: mass.into(),
                ..IkOptions::default()
            };
            group.bench_function(
                BenchmarkId::new(format!("trajectory_60/{name}"), grams),
                |bench| bench.iter(|| black_box(robot.track(&points, &options).unwrap())),
            );
        }
    }
    group.finish();
}

/// Forward solves (from the straight robot) and tracking of the pneumatic,
/// tendon and magnetic robots.
fn actuated(c: &mut Criterion) {
    let tendon =
        Robot::from_toml_str(include_str!("../examples/robots/tendon_robot.toml")).unwrap();
    let catheter =
        Robot::from_toml_str(include_str!("../examples/robots/magnetic_catheter.toml")).unwrap();
    let pneumatic = Robot::default();
    let mut group = c.benchmark_group("actuated");
    let forward = |robot: &Robot, actuation: Actuation, mass: f64| {
        let scene = robot
            .scene(&actuation, &softspine::Load::from(mass))
            .unwrap();
        let settings = Settings {
            n_elements: Some(robot.n_elements),
            ..Settings::default()
        };
        move || softspine::solve(&scene, settings.clone(), None).unwrap()
    };
    let cases = [
        (
            "pneumatic",
            forward(
                &pneumatic,
                Actuation {
                    rest_curvature: vec![[1.0, -0.5]; pneumatic.body.sections],
                    ..Actuation::default()
                },
                0.02,
            ),
        ),
        (
            "tendons",
            forward(
                &tendon,
                Actuation {
                    tensions: vec![12.0, 0.0, 0.0, 0.0, 0.0, 14.0, 0.0, 10.0, 0.0],
                    ..Actuation::default()
                },
                0.02,
            ),
        ),
        (
            "magnetic",
            forward(
                &catheter,
                Actuation {
                    field: Vector3::new(0.02, 0.01, 0.0),
                    ..Actuation::default()
                },
                0.0,
            ),
        ),
    ];
    for (name, solve) in cases {
        group.bench_function(BenchmarkId::new("forward", name), |bench| {
            bench.iter(|| black_box(solve()))
        });
    }
    let options = IkOptions {
        load: 0.02.into(),
        ..IkOptions::default()
    };
    let circle = trajectory::placed(&trajectory::circle(60), &tendon);
    group.bench_function(
        BenchmarkId::new("trajectory_60", "tendons_circle_20g"),
        |bench| bench.iter(|| black_box(tendon.track(&circle, &options).unwrap())),
    );
    // The ring the catheter's tip sweeps as a 20 mT field turns about its axis.
    let bent = forward(
        &catheter,
        Actuation {
            field: Vector3::new(0.02, 0.0, 0.0),
            ..Actuation::default()
        },
        0.0,
    )();
    let tip = bent.tip_position();
    let ring: Vec<Vector3<f64>> = (0..60)
        .map(|i| {
            let a = i as f64 / 60.0 * std::f64::consts::TAU;
            Vector3::new(tip.x * a.cos(), tip.x * a.sin(), tip.z)
        })
        .collect();
    let unloaded = IkOptions::default();
    group.bench_function(
        BenchmarkId::new("trajectory_60", "catheter_ring"),
        |bench| bench.iter(|| black_box(catheter.track(&ring, &unloaded).unwrap())),
    );
    group.finish();
    // A target the loaded robot cannot reach: the tendon robot's first
    // pentagram point under 45 g (out of reach, all the starts tried, their
    // trials into the tensions' limits failing). What a user pays to learn it.
    let mut group = c.benchmark_group("out_of_reach");
    group.sample_size(10);
    let target = trajectory::placed(&trajectory::pentagram(60), &tendon)[0];
    let heavy = IkOptions {
        load: 0.045.into(),
        ..IkOptions::default()
    };
    group.bench_function(
        BenchmarkId::new("inverse", "tendons_pentagram_45g"),
        |bench| {
            bench.iter(|| {
                let ik = tendon.inverse(target, &heavy).unwrap();
                assert!(!ik.reached);
                black_box(ik)
            })
        },
    );
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(std::time::Duration::from_millis(300))
        .measurement_time(std::time::Duration::from_secs(1));
    targets = ik, actuated
}
criterion_main!(benches);
