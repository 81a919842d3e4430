//! The seed paper's method against Newton at n = 20, and its particle swarm on
//! one and on two threads (the swarm evaluates its particles in parallel).
//!
//! `cargo bench --bench paper`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softspine::methods::paper::{solve_paper, PaperSettings};
use softspine::{Method, Quat, Scene, Settings, Solver};
use std::hint::black_box;

fn scenes() -> Vec<(&'static str, Scene)> {
    let mut cantilever = Scene::new(1.0, 1.0, 1.0, 1.0);
    cantilever.tip_force = Vector3::new(3.0, 0.0, 0.0);
    let mut three_d = Scene::new(0.8, 0.7, 1.1, 0.5);
    three_d.rest_curvature = vec![[1.5, -0.5], [-1.0, 2.0]];
    three_d.distributed_force = Vector3::new(0.0, 0.0, -1.0);
    three_d.tip_force = Vector3::new(0.3, -0.2, 0.1);
    three_d.base_quaternion = Quat::new(0.9, 0.3, -0.2, 0.1).normalized();
    vec![("cantilever_alpha3", cantilever), ("scene_3d", three_d)]
}

fn paper_vs_newton(c: &mut Criterion) {
    let mut group = c.benchmark_group("paper_vs_newton_n20");
    for (name, scene) in scenes() {
        for method in [Method::Newton, Method::Paper] {
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
                "paper"
            };
            group.bench_function(BenchmarkId::new(label, name), |b| {
                b.iter(|| black_box(solver.solve(None).unwrap()))
            });
        }
    }
    group.finish();
}

/// The swarm phase alone (no Gauss-Newton, no LM), 1 and 2 threads.
fn swarm_threads(c: &mut Criterion) {
    let (_, scene) = scenes().remove(1);
    let settings = PaperSettings {
        gauss_newton_iterations: 0,
        lm_iterations: 0,
        ..PaperSettings::default()
    };
    let mut group = c.benchmark_group("paper_swarm_n20");
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        group.bench_function(BenchmarkId::new("threads", threads), |b| {
            b.iter(|| {
                pool.install(|| black_box(solve_paper(&scene, 20, &settings, false).unwrap()))
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(std::time::Duration::from_millis(300))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = paper_vs_newton, swarm_threads
}
criterion_main!(benches);
