//! Time to a whole-backbone accuracy: every discretisation (Newton on the
//! second- and fourth-order schemes, shooting) at n = 10 ... 320, cold solves
//! from the straight rod, on the cantilevers alpha = 3 and 10 and the default
//! robot (10 sections, gravity, 30 g at the tip, a 3D actuation).
//!
//! `cargo bench --bench accuracy`. Before the timings it prints, per scene,
//! method and n, the largest node distance from a reference (shooting at
//! n = 5120, fourth order: about 1e-13 L off) over L; with the medians, that
//! gives the time to reach 1e-4, 1e-6 and 1e-8 L (the README's table).
//! Beside them, the default path (`default_tol`): accuracy on demand with
//! the default settings at tol = 1e-3 ... 1e-8, its choice printed.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::Vector3;
use softspine::{solve_to_accuracy, Accuracy, Method, Robot, Scene, Scheme, Settings, Solver};
use std::hint::black_box;

const SIZES: [usize; 6] = [10, 20, 40, 80, 160, 320];
const REFERENCE_ELEMENTS: usize = 5120;

fn cantilever(alpha: f64) -> Scene {
    let mut s = Scene::new(1.0, 1.0, 1.0, 1.0 / 1.3);
    s.tip_force = Vector3::new(alpha, 0.0, 0.0);
    s
}

/// The default robot with an actuation that bends it in 3D, 30 g at the tip.
fn robot() -> Scene {
    let robot = Robot::default();
    let kappa: Vec<[f64; 2]> = (0..robot.body.sections)
        .map(|k| {
            let phi = 0.7 * k as f64;
            [1.5 * phi.cos(), 1.5 * phi.sin()]
        })
        .collect();
    robot
        .scene(
            &softspine::Actuation::muscles(kappa),
            &softspine::Load::from(0.03),
        )
        .unwrap()
}

fn settings(n: usize, method: Method, scheme: Scheme) -> Settings {
    Settings {
        n_elements: Some(n),
        method,
        scheme: Some(scheme),
        ..Settings::default()
    }
}

fn accuracy(c: &mut Criterion) {
    let scenes = [
        ("cantilever_alpha3", cantilever(3.0)),
        ("cantilever_alpha10", cantilever(10.0)),
        ("robot_30g", robot()),
    ];
    let kinds = [
        ("newton_fd2", Method::Newton, Scheme::Fd2),
        ("newton_fe4", Method::Newton, Scheme::Fe4),
        ("shooting", Method::Shooting, Scheme::Fd2),
    ];
    for (name, scene) in scenes {
        let reference = Solver::new(
            &scene,
            settings(REFERENCE_ELEMENTS, Method::Shooting, Scheme::Fd2),
        )
        .unwrap()
        .solve(None)
        .unwrap();
        assert!(reference.converged());
        let mut group = c.benchmark_group(format!("accuracy/{name}"));
        for (label, method, scheme) in kinds {
            for n in SIZES {
                if n % scene.sections() != 0 {
                    continue;
                }
                let mut solver = Solver::new(&scene, settings(n, method, scheme)).unwrap();
                let sol = solver.solve(None).unwrap();
                assert!(sol.converged(), "{name} {label} n = {n}: {}", sol.message);
                let stride = REFERENCE_ELEMENTS / n;
                let error = sol
                    .positions
                    .iter()
                    .enumerate()
                    .map(|(i, r)| (r - reference.positions[i * stride]).norm())
                    .fold(0.0, f64::max)
                    / scene.length;
                eprintln!("error {name} {label} n={n}: {error:.2e}");
                group.bench_with_input(BenchmarkId::new(label, n), &n, |b, _| {
                    b.iter(|| black_box(solver.solve(None).unwrap()))
                });
            }
        }
        // The call a user makes: accuracy on demand with the default
        // settings (method "auto"), time to each tolerance.
        for exponent in [3, 4, 5, 6, 8] {
            let accuracy = Accuracy::new(10f64.powi(-exponent));
            let sol = solve_to_accuracy(&scene, Settings::default(), &accuracy).unwrap();
            assert!(
                sol.converged(),
                "{name} default tol 1e-{exponent}: {}",
                sol.message
            );
            eprintln!(
                "default {name} tol=1e-{exponent}: {:?} n={}, estimate {:.2e}",
                sol.scheme,
                sol.n_elements,
                sol.error_estimate.unwrap_or(f64::NAN) / scene.length
            );
            group.bench_with_input(
                BenchmarkId::new("default_tol", format!("1e-{exponent}")),
                &exponent,
                |b, _| {
                    b.iter(|| {
                        black_box(
                            solve_to_accuracy(&scene, Settings::default(), &accuracy).unwrap(),
                        )
                    })
                },
            );
        }
        group.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(200)).measurement_time(std::time::Duration::from_millis(800));
    targets = accuracy
}
criterion_main!(benches);
