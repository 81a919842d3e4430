//! Forward statics: cold (straight guess) and warm (from the equilibrium of the
//! same scene with every load 2 % lower, as between two steps of a control loop);
//! held tips: warm from the equilibrium with the target 10 % closer to the free tip.
//!
//! `cargo bench --bench forward`; the medians go into the README's table.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softspine::{solve, Method, Quat, Scene, Settings, Solver, TipCondition};
use std::hint::black_box;

const SIZES: [usize; 6] = [10, 20, 40, 80, 160, 1000];

/// Bisshopp-Drucker cantilever, alpha = P L^2 / EI = 3.
fn cantilever(scale: f64) -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 1.0);
    s.tip_force = Vector3::new(3.0 * scale, 0.0, 0.0);
    s
}

/// A 1 m, 10-section robot with 3D rest curvature under gravity and a tip load.
fn robot(scale: f64) -> Scene {
    let mut s = Scene::new(1.0, 0.8, 0.8, 0.6);
    s.rest_curvature = (0..10)
        .map(|k| {
            let phi = k as f64 * 0.6;
            [2.0 * phi.cos(), 2.0 * phi.sin()]
        })
        .collect();
    s.distributed_force = Vector3::new(0.0, -0.5, -2.0) * scale;
    s.tip_force = Vector3::new(0.1, 0.0, -0.3) * scale;
    s.base_quaternion = Quat::new(0.0, 1.0, 0.0, 0.0);
    s
}

fn bench_scene(c: &mut Criterion, name: &str, make: fn(f64) -> Scene) {
    let mut group = c.benchmark_group(name);
    for n in SIZES {
        let settings = Settings {
            n_elements: Some(n),
            ..Settings::default()
        };
        let mut solver = Solver::new(&make(1.0), settings.clone()).unwrap();
        let neighbour = Solver::new(&make(0.98), settings)
            .unwrap()
            .solve(None)
            .unwrap();
        assert!(neighbour.converged() && solver.solve(None).unwrap().converged());
        group.bench_with_input(BenchmarkId::new("cold", n), &n, |b, _| {
            b.iter(|| black_box(solver.solve(None).unwrap()))
        });
        let warm = neighbour.quaternions.clone();
        group.bench_with_input(BenchmarkId::new("warm", n), &n, |b, _| {
            b.iter(|| black_box(solver.solve(Some(&warm)).unwrap()))
        });
    }
    group.finish();
}

/// The 3D robot with its tip held 2 cm (times `scale`) off where it hangs freely:
/// by a ball joint, or clamped in the free tip's orientation.
fn held_tip(scale: f64, clamped: bool, n: usize) -> Scene {
    let mut s = robot(1.0);
    let settings = Settings {
        n_elements: Some(n),
        ..Settings::default()
    };
    let free = solve(&s, settings, None).unwrap();
    let position = free.tip_position() + Vector3::new(0.02, -0.01, 0.01) * scale;
    s.tip_force = Vector3::zeros();
    s.tip = if clamped {
        TipCondition::Clamped {
            position,
            quaternion: free.tip_quaternion(),
        }
    } else {
        TipCondition::Pinned { position }
    };
    s
}

fn held(c: &mut Criterion) {
    let mut group = c.benchmark_group("robot_3d_held_tip");
    for clamped in [false, true] {
        let kind = if clamped { "clamped" } else { "pinned" };
        for n in [20, 80] {
            let settings = Settings {
                n_elements: Some(n),
                ..Settings::default()
            };
            let mut solver = Solver::new(&held_tip(1.0, clamped, n), settings.clone()).unwrap();
            let neighbour = Solver::new(&held_tip(0.9, clamped, n), settings)
                .unwrap()
                .solve(None)
                .unwrap();
            assert!(neighbour.converged() && solver.solve(None).unwrap().converged());
            group.bench_with_input(BenchmarkId::new(format!("{kind}/cold"), n), &n, |b, _| {
                b.iter(|| black_box(solver.solve(None).unwrap()))
            });
            let warm = neighbour.quaternions.clone();
            group.bench_with_input(BenchmarkId::new(format!("{kind}/warm"), n), &n, |b, _| {
                b.iter(|| black_box(solver.solve(Some(&warm)).unwrap()))
            });
        }
    }
    group.finish();
}

/// Every method and tip condition at n = 20, cold.
fn methods(c: &mut Criterion) {
    let mut group = c.benchmark_group("methods_n20");
    let scenes = [
        ("cantilever_alpha3", cantilever(1.0)),
        ("robot_3d", robot(1.0)),
        ("robot_3d_pinned", held_tip(1.0, false, 20)),
        ("robot_3d_clamped", held_tip(1.0, true, 20)),
    ];
    for (name, scene) in scenes {
        for method in [Method::Newton, Method::LevenbergMarquardt] {
            let settings = Settings {
                n_elements: Some(20),
                method,
                ..Settings::default()
            };
            let mut solver = Solver::new(&scene, settings).unwrap();
            assert!(solver.solve(None).unwrap().converged());
            let label = if method == Method::Newton {
                "newton"
            } else {
                "lm"
            };
            group.bench_function(BenchmarkId::new(label, name), |b| {
                b.iter(|| black_box(solver.solve(None).unwrap()))
            });
        }
    }
    group.finish();
}

/// The hard cases of the test suite, cold, Newton.
fn hard(c: &mut Criterion) {
    let round = |l: f64| Scene::new(l, 1.0, 1.0, 1.0);
    let mut roll_up = round(1.0);
    roll_up.tip_moment = Vector3::new(0.0, 2.0 * std::f64::consts::PI, 0.0);
    let mut column = round(1.0);
    column.distributed_force = Vector3::new(0.0, 0.0, -1.3 * 7.837);
    column.rest_curvature = vec![[0.0, 0.01]];
    let mut spiral = Scene::new(1.0, 1.0, 1.0, 0.7);
    spiral.rest_curvature = (0..10)
        .map(|k| [8.0 * (0.5 * k as f64).cos(), 8.0 * (0.5 * k as f64).sin()])
        .collect();
    spiral.distributed_force = Vector3::new(0.0, 0.0, -0.981);
    let mut stiff_torsion = Scene::new(1.0, 1.0, 2.0, 1000.0);
    stiff_torsion.rest_curvature = vec![[2.0, -1.0], [0.0, 3.0]];
    stiff_torsion.tip_force = Vector3::new(1.0, -0.5, 0.2);
    let mut soft = round(1.0);
    soft.tip_force = Vector3::new(50.0, 0.0, 0.0);
    let cases = [
        ("roll_up_2pi", roll_up.clone(), 20),
        ("roll_up_2pi", roll_up, 80),
        ("column_beyond_buckling", column, 20),
        ("spiral_8rad_gravity", spiral, 20),
        ("torsion_1000x", stiff_torsion, 20),
        ("cantilever_alpha50", soft, 20),
        ("cantilever_alpha3", cantilever(1.0), 2000),
        ("cantilever_alpha3", cantilever(1.0), 5000),
    ];
    let mut group = c.benchmark_group("hard");
    for (name, scene, n) in cases {
        let settings = Settings {
            n_elements: Some(n),
            ..Settings::default()
        };
        let mut solver = Solver::new(&scene, settings).unwrap();
        assert!(solver.solve(None).unwrap().converged(), "{name}");
        group.bench_function(BenchmarkId::new(name, n), |b| {
            b.iter(|| black_box(solver.solve(None).unwrap()))
        });
    }
    group.finish();
}

fn forward(c: &mut Criterion) {
    bench_scene(c, "cantilever_alpha3", cantilever);
    bench_scene(c, "robot_3d", robot);
    held(c);
    methods(c);
    hard(c);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = forward
}
criterion_main!(benches);
