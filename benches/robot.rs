//! Load-aware inverse kinematics of the default robot (n = 20): one trajectory
//! point warm from its neighbour, and whole 60-point trajectories.
//!
//! `cargo bench --bench robot`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use softspine::robot::trajectory;
use softspine::{IkOptions, InverseSolver, Robot};
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
            let mut solver = InverseSolver::new(&robot, mass).unwrap();
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
                                .solve(b, None, Some(&previous.rest_curvature), 1e-9, 60)
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
                tip_mass: mass,
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

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(std::time::Duration::from_millis(300))
        .measurement_time(std::time::Duration::from_secs(1));
    targets = ik
}
criterion_main!(benches);
