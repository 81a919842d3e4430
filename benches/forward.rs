//! Forward statics: cold (straight guess) and warm (from the equilibrium of the
//! same scene with every load 2 % lower, as between two steps of a control loop);
//! held tips: warm from the equilibrium with the target 10 % closer to the free tip.
//!
//! `cargo bench --bench forward`; the medians go into the README's table.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softspine::{solve, Quat, Scene, Settings, Solver, TipCondition};
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
            n_elements: n,
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
        n_elements: n,
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
                n_elements: n,
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

fn forward(c: &mut Criterion) {
    bench_scene(c, "cantilever_alpha3", cantilever);
    bench_scene(c, "robot_3d", robot);
    held(c);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = forward
}
criterion_main!(benches);
