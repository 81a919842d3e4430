//! Many forward solves of the default robot (10 sections, n = 20, 30 g at the
//! tip) at random actuations within the muscles' range: the batch on one
//! thread and on every core, cold and warm along each chunk.
//!
//! `cargo bench --bench batch`. Criterion reports the time of 10 000 solves.

use criterion::{criterion_group, criterion_main, Criterion};
use softspine::{BatchControl, BatchSettings, Robot};
use std::hint::black_box;

const SAMPLES: usize = 10_000;

fn batch(c: &mut Criterion) {
    let robot = Robot::default();
    let actuations = robot.random_drives(SAMPLES, 1).unwrap();
    let mut group = c.benchmark_group("forward_batch_10000");
    group.sample_size(10);
    for (label, threads, warm_start) in [
        ("1_thread_cold", Some(1), false),
        ("1_thread_warm", Some(1), true),
        ("all_cores_cold", None, false),
        ("all_cores_warm", None, true),
    ] {
        let settings = BatchSettings {
            threads,
            warm_start,
            ..BatchSettings::default()
        };
        let out = robot
            .forward_batch(
                &actuations,
                &softspine::Load::from(0.03),
                &settings,
                &BatchControl::default(),
            )
            .unwrap();
        let converged = out.iter().filter(|s| s.converged() && s.stable).count();
        eprintln!("{label}: {converged} of {SAMPLES} converged and stable");
        group.bench_function(label, |b| {
            b.iter(|| {
                black_box(
                    robot
                        .forward_batch(
                            &actuations,
                            &softspine::Load::from(0.03),
                            &settings,
                            &BatchControl::default(),
                        )
                        .unwrap(),
                )
            })
        });
    }
    // Along a path (a slow sweep of the actuation): where warm starts pay.
    let path: Vec<softspine::Actuation> = (0..SAMPLES)
        .map(|i| {
            let t = i as f64 / SAMPLES as f64;
            softspine::Actuation::muscles(
                (0..robot.body.sections)
                    .map(|k| {
                        let phi = 40.0 * t + 0.5 * k as f64;
                        [3.0 * phi.cos(), 3.0 * phi.sin()]
                    })
                    .collect(),
            )
        })
        .collect();
    for (label, warm_start) in [
        ("path_all_cores_cold", false),
        ("path_all_cores_warm", true),
    ] {
        let settings = BatchSettings {
            warm_start,
            ..BatchSettings::default()
        };
        group.bench_function(label, |b| {
            b.iter(|| {
                black_box(
                    robot
                        .forward_batch(
                            &path,
                            &softspine::Load::from(0.03),
                            &settings,
                            &BatchControl::default(),
                        )
                        .unwrap(),
                )
            })
        });
    }
    group.finish();
}

criterion_group!(benches, batch);
criterion_main!(benches);
