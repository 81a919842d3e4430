//! Reliability of the load-aware IK: the tips that the forward model reaches
//! with in-range actuations are reached again by the IK, on a stable
//! equilibrium, and a miss says why.
//!
//! `cargo test --release --test ik_reliability -- --nocapture` prints the
//! fractions reached and the times.

use nalgebra::Vector3;
use softspine::quat::Quat;
use softspine::robot::{trajectory, Body, Drive, IkEnding, Muscles};
use softspine::{solve, IkOptions, IkSettings, Robot, Settings};

/// Uniform in [0, 1) from a splitmix64 sequence (reproducible, no dependency).
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Actuations with every muscle length drawn uniformly in its range.
fn in_range_actuations(robot: &Robot, count: usize, seed: u64) -> Vec<Vec<[f64; 2]>> {
    let [lo, hi] = robot.muscles("test").unwrap().length_range;
    let mut state = seed;
    (0..count)
        .map(|_| {
            let lengths: Vec<[f64; 3]> = (0..robot.body.sections)
                .map(|_| [0; 3].map(|_| lo + (hi - lo) * uniform(&mut state)))
                .collect();
            robot.rest_curvature(&lengths).unwrap()
        })
        .collect()
}

fn forward(robot: &Robot, kappa: &[[f64; 2]], load: f64) -> softspine::Solution {
    let scene = robot
        .scene(
            &softspine::Actuation::muscles(kappa.to_vec()),
            &softspine::Load::from(load),
        )
        .unwrap();
    let settings = Settings {
        n_elements: Some(robot.n_elements),
        ..Settings::default()
    };
    solve(&scene, settings, None).unwrap()
}

fn tilted() -> Robot {
    let q = Quat::new(0.92388, 0.38268, 0.0, 0.0);
    let body = Body {
        sections: 5,
        base_quaternion: q.normalized(),
        ..Body::default()
    };
    Robot {
        n_elements: 20,
        ..Robot::new(body, Drive::default())
    }
}

fn upright() -> Robot {
    let body = Body {
        sections: 3,
        base_quaternion: Quat::new(1.0, 0.0, 0.0, 0.0),
        ..Body::default()
    };
    let muscles = Muscles::for_sections_of(body.section_length());
    Robot::new(body, Drive::Muscles(muscles))
}

/// Ask the IK for the tip of each stable forward solve of in-range actuations;
/// print and return (reached, asked). A reached answer is a stable
/// equilibrium within range at the tolerance.
fn reach_fraction(name: &str, robot: &Robot, load: f64, count: usize, seed: u64) -> (usize, usize) {
    let options = IkOptions {
        load: load.into(),
        ..IkOptions::default()
    };
    let (mut reached, mut total) = (0, 0);
    let mut times = Vec::new();
    for kappa in in_range_actuations(robot, count, seed) {
        let fw = forward(robot, &kappa, load);
        if !(fw.converged() && fw.stable) {
            continue;
        }
        total += 1;
        let r = robot.inverse(fw.tip_position(), &options).unwrap();
        times.push(r.seconds);
        if r.reached {
            assert!(r.solution.converged() && r.solution.stable);
            assert!(r.tip_miss <= options.settings.tol);
            assert!(robot.within_bounds(&r.rest_curvature).unwrap());
            reached += 1;
        } else {
            eprintln!("  {name}: {} ({} starts)", r.message, r.starts);
        }
    }
    times.sort_by(f64::total_cmp);
    eprintln!(
        "{name}, {:.0} g: reached {reached}/{total}; IK median {:.0} us, max {:.1} ms",
        load * 1e3,
        times[times.len() / 2] * 1e6,
        times[times.len() - 1] * 1e3
    );
    (reached, total)
}

#[test]
fn tilted_robot_reaches_what_its_forward_model_reaches() {
    let (reached, total) = reach_fraction("tilted, 5 sections", &tilted(), 0.03, 135, 7);
    assert_eq!(reached, total);
}

#[test]
fn upright_robot_reaches_what_its_forward_model_reaches() {
    let (reached, total) = reach_fraction("upright, 3 sections", &upright(), 0.08, 135, 7);
    assert_eq!(reached, total);
}

/// Past buckling the straight upright robot (the zero reference) is an
/// unstable equilibrium: never an answer, and no obstacle to reaching.
#[test]
fn upright_robot_past_buckling_answers_only_with_stable_equilibria() {
    let robot = upright();
    let straight = forward(&robot, &[[0.0; 2]; 3], 0.2);
    assert!(straight.converged() && !straight.stable);
    let (reached, total) = reach_fraction("upright, 3 sections", &robot, 0.2, 30, 11);
    assert!(total >= 25);
    assert_eq!(reached, total);
}

/// Tracking stays on the fast path: one start a point (restarts only when it misses).
#[test]
fn tracking_needs_no_restarts() {
    let robot = Robot::default();
    let options = IkOptions {
        load: 0.06.into(),
        ..IkOptions::default()
    };
    let results = robot.track(&trajectory::spiral(60), &options).unwrap();
    assert!(results.iter().all(|r| r.reached && r.starts == 1));
}

#[test]
fn a_target_beyond_the_robots_length_is_out_of_reach() {
    let robot = Robot::default();
    let r = robot
        .inverse(Vector3::new(1.0, 0.0, -1.0), &IkOptions::default())
        .unwrap();
    assert_eq!(r.ending, IkEnding::OutOfReach, "{}", r.message);
    assert!(r.message.contains("out of reach"));
    // Nothing to retry: no start puts the tip farther than the robot is long.
    assert_eq!(r.starts, 1);
}

#[test]
fn a_target_beyond_the_muscles_range_says_the_bounds_limit_it() {
    let mut robot = Robot::default();
    let Drive::Muscles(muscles) = &mut robot.drive else {
        panic!("the default robot is driven by muscles")
    };
    muscles.length_range = [0.098, 0.1005];
    let options = IkOptions {
        load: 0.03.into(),
        ..IkOptions::default()
    };
    let r = robot
        .inverse(Vector3::new(0.5, 0.0, -0.5), &options)
        .unwrap();
    assert_eq!(r.ending, IkEnding::BoundsActive, "{}", r.message);
    assert!(r.message.contains("length range limits"));
    assert!(r.solution.stable && robot.within_bounds(&r.rest_curvature).unwrap());
}

#[test]
fn running_out_of_iterations_says_so() {
    let options = IkOptions {
        load: 0.08.into(),
        settings: IkSettings {
            max_iterations: 1,
            ..IkSettings::default()
        },
        ..IkOptions::default()
    };
    let r = upright()
        .inverse(Vector3::new(0.3, 0.2, -0.3), &options)
        .unwrap();
    assert_eq!(r.ending, IkEnding::IterationLimit, "{}", r.message);
    assert!(r.message.contains("max_iterations"));
}

/// Along a path the inverse kinematics steps the equilibrium and the drive
/// together (the coupled iteration, `engine.rs`): each tracked answer is the
/// one the descent finds from scratch (a new solver, no warm state, so no
/// coupled iteration) with the previous answer as its reference, to the
/// minimum-norm accuracy, and costs a few coupled iterations a point.
#[test]
fn tracked_answers_are_the_descents_answers_with_the_same_reference() {
    let robot = Robot::default();
    let circle = trajectory::placed(&trajectory::circle(60), &robot);
    let options = IkOptions {
        load: 0.03.into(),
        ..IkOptions::default()
    };
    let tracked = robot.track(&circle[..12], &options).unwrap();
    for (k, pair) in tracked.windows(2).enumerate() {
        let (before, answer) = (&pair[0], &pair[1]);
        assert!(answer.reached, "point {}: {}", k + 1, answer.message);
        assert!(
            answer.iterations <= 6,
            "point {}: {} iterations",
            k + 1,
            answer.iterations
        );
        let alone = robot
            .inverse(
                circle[k + 1],
                &IkOptions {
                    reference: Some(before.rest_curvature.clone()),
                    ..options.clone()
                },
            )
            .unwrap();
        assert!(alone.reached, "{}", alone.message);
        let flat = |r: &softspine::robot::IkResult| -> Vec<f64> {
            r.rest_curvature.iter().flatten().copied().collect()
        };
        let (a, b) = (flat(answer), flat(&alone));
        let gap: f64 = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt();
        let size: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(gap <= 1e-5 * size, "point {}: {gap:e} of {size:e}", k + 1);
    }
}
