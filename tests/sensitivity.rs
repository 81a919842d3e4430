//! Sensitivities by the implicit function theorem against central
//! differences of whole solves (tight tolerance), for free, pinned and
//! clamped tips and both schemes.

use nalgebra::Vector3;
use softspine::{Gravity, Quat, Scene, Scheme, Settings, Solution, Solver, TipCondition};

fn scene() -> Scene {
    let mut s = Scene::new(0.8, 0.9, 1.1, 0.7);
    s.rest_curvature = vec![[1.2, -0.4], [-0.6, 0.9]];
    s.gravity = Some(Gravity {
        linear_density: 0.6,
        vector: Vector3::new(0.0, 0.5, -9.81),
    });
    s.tip_force = Vector3::new(0.8, -0.3, -0.5);
    s.tip_moment = Vector3::new(0.05, 0.1, -0.02);
    s
}

fn settings(scheme: Scheme) -> Settings {
    Settings {
        n_elements: Some(20),
        scheme: Some(scheme),
        residual_tol: 1e-13,
        ..Settings::default()
    }
}

fn solve(scene: &Scene, scheme: Scheme) -> Solution {
    let sol = softspine::solve(scene, settings(scheme), None).unwrap();
    assert!(sol.converged() && sol.stable, "{}", sol.message);
    sol
}

/// The tip's outputs of a solve, stacked: position, orientation (as the
/// quaternion, turned into a rotation vector against `reference`), reactions.
fn outputs(sol: &Solution, reference: Quat) -> Vec<f64> {
    let mut out: Vec<f64> = sol.tip_position().iter().copied().collect();
    let q = sol.tip_quaternion();
    let turn = q * reference.conj();
    let turn = if turn.w < 0.0 { -turn } else { turn };
    out.extend((2.0 * turn.v).iter());
    out.extend(sol.tip_reaction_force.unwrap_or_default().iter());
    out.extend(sol.tip_reaction_moment.unwrap_or_default().iter());
    out
}

fn check(scene: &Scene, scheme: Scheme, parameters: &[&str]) {
    let mut solver = Solver::new(scene, settings(scheme)).unwrap();
    let sol = solver.solve(None).unwrap();
    assert!(sol.converged(), "{}", sol.message);
    let sens = solver.sensitivity(parameters).unwrap();
    let reference = sol.tip_quaternion();
    let base = scene.to_value();
    for (j, name) in sens.parameters.iter().enumerate() {
        let value = *base.clone().number_at_mut(name).unwrap();
        let h = 1e-4 * value.abs().max(0.1);
        let at = |delta: f64| {
            let mut v = base.clone();
            *v.number_at_mut(name).unwrap() += delta;
            let s = Scene::from_value(&v).unwrap();
            outputs(&solve(&s, scheme), reference)
        };
        let (plus, minus) = (at(h), at(-h));
        let fd: Vec<f64> = plus
            .iter()
            .zip(&minus)
            .map(|(a, b)| (a - b) / (2.0 * h))
            .collect();
        let mut ift: Vec<f64> = sens.tip_position.column(j).iter().copied().collect();
        ift.extend(sens.tip_rotation.column(j).iter());
        let zero = nalgebra::Matrix3xX::zeros(sens.parameters.len());
        ift.extend(
            sens.tip_reaction_force
                .as_ref()
                .unwrap_or(&zero)
                .column(j)
                .iter(),
        );
        ift.extend(
            sens.tip_reaction_moment
                .as_ref()
                .unwrap_or(&zero)
                .column(j)
                .iter(),
        );
        let scale = fd.iter().map(|x| x.abs()).fold(1.0, f64::max);
        for (row, (a, b)) in ift.iter().zip(&fd).enumerate() {
            assert!(
                (a - b).abs() < 1e-6 * scale,
                "{scheme:?} {name} row {row}: ift {a} vs differences {b}"
            );
        }
    }
}

const PARAMETERS: [&str; 4] = [
    "rest_curvature",
    "tip_wrench",
    "stiffness.kx",
    "gravity.linear_density",
];

#[test]
fn a_free_tip_matches_differences_of_solves() {
    for scheme in [Scheme::Fd2, Scheme::Fe4] {
        check(&scene(), scheme, &PARAMETERS);
    }
}

#[test]
fn held_tips_match_differences_of_solves() {
    for scheme in [Scheme::Fd2, Scheme::Fe4] {
        let free = solve(&scene(), scheme);
        let mut pinned = scene();
        pinned.tip = TipCondition::Pinned {
            position: free.tip_position() + Vector3::new(0.02, 0.0, -0.01),
        };
        check(&pinned, scheme, &PARAMETERS);
        // A clamped tip's wrench is the reaction: no tip loads.
        let mut clamped = scene();
        clamped.tip_force = Vector3::zeros();
        clamped.tip_moment = Vector3::zeros();
        clamped.tip = TipCondition::Clamped {
            position: free.tip_position() + Vector3::new(0.0, 0.02, 0.01),
            quaternion: free.tip_quaternion(),
        };
        check(
            &clamped,
            scheme,
            &[
                "rest_curvature",
                "stiffness.ky",
                "gravity.linear_density",
                "tip.position[0]",
            ],
        );
    }
}

#[test]
fn unknown_parameters_and_unsolved_states_are_refused_by_name() {
    let mut solver = Solver::new(&scene(), settings(Scheme::Fd2)).unwrap();
    let e = solver.sensitivity(&["tip_force[0]"]).unwrap_err();
    assert!(e.to_string().contains("solve first"), "{e}");
    solver.solve(None).unwrap();
    for (name, reason) in [
        ("tip_force[3]", "out of range"),
        ("stiffnes.kx", "no field"),
        ("name", "no field"),
    ] {
        let e = solver.sensitivity(&[name]).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains(reason), "{e}");
    }
}

#[test]
fn the_robot_sensitivity_matches_differences_of_forward_solves() {
    use softspine::Robot;
    let robot = Robot::default();
    let kappa = robot.random_drives(1, 5).unwrap()[0].rest_curvature.clone();
    let names = [
        "muscle_lengths[1][2]",
        "stiffness.E",
        "load",
        "disk_mass",
        "rest_curvature[9][0]",
    ];
    let (sol, sens) = robot
        .sensitivity(
            &softspine::Actuation {
                rest_curvature: kappa.clone(),
                ..Default::default()
            },
            &softspine::Load::from(0.03),
            &names,
            None,
        )
        .unwrap();
    assert!(sol.converged());
    let base = robot.to_value();
    for (j, name) in names.iter().enumerate() {
        let tip = |delta: f64| -> Vector3<f64> {
            let (mut r, mut k, mut mass) = (robot.clone(), kappa.clone(), 0.03);
            match *name {
                "load" => mass += delta,
                "rest_curvature[9][0]" => k[9][0] += delta,
                "muscle_lengths[1][2]" => {
                    let mut l = robot.muscle_lengths(&kappa).unwrap();
                    l[1][2] += delta;
                    k = robot.rest_curvature(&l).unwrap();
                }
                field => {
                    let mut v = base.clone();
                    *v.number_at_mut(field).unwrap() += delta;
                    r = Robot::from_value(&v).unwrap();
                }
            }
            let scene = r
                .scene(
                    &softspine::Actuation::muscles(k),
                    &softspine::Load::from(mass),
                )
                .unwrap();
            let settings = Settings {
                n_elements: Some(robot.n_elements),
                residual_tol: 1e-13,
                ..Settings::default()
            };
            softspine::solve(&scene, settings, None)
                .unwrap()
                .tip_position()
        };
        let value = match *name {
            "stiffness.E" => 2e11,
            _ => 0.01,
        };
        let h = 1e-4 * value;
        let fd = (tip(h) - tip(-h)) / (2.0 * h);
        let ift = sens.tip_position.column(j);
        assert!(
            (ift - fd).norm() < 1e-6 * fd.norm().max(1e-12),
            "{name}: {ift} vs {fd}"
        );
    }
}

#[test]
fn calibration_recovers_known_parameters_within_their_uncertainty() {
    use softspine::{CalibrationSettings, Robot};
    let truth = Robot::default();
    let fields = ["stiffness.E", "linear_density", "disk_mass"];
    let samples = 24;
    let drives = truth.random_drives(samples, 11).unwrap();
    let actuations: Vec<[f64; 2]> = drives
        .iter()
        .flat_map(|a| a.rest_curvature.iter().copied())
        .collect();
    let settings = Settings {
        n_elements: Some(truth.n_elements),
        ..Settings::default()
    };
    let exact: Vec<Vector3<f64>> = actuations
        .chunks(truth.body.sections)
        .map(|k| {
            let scene = truth
                .scene(
                    &softspine::Actuation::muscles(k.to_vec()),
                    &softspine::Load::from(0.03),
                )
                .unwrap();
            softspine::solve(&scene, settings.clone(), None)
                .unwrap()
                .tip_position()
        })
        .collect();
    let true_values: Vec<f64> = fields
        .iter()
        .map(|f| *truth.to_value().number_at_mut(f).unwrap())
        .collect();
    // A start 15 to 25 % off.
    let mut v = truth.to_value();
    for (f, factor) in fields.iter().zip([1.25, 0.8, 1.15]) {
        *v.number_at_mut(f).unwrap() *= factor;
    }
    let start = Robot::from_value(&v).unwrap();
    // Without noise: the truth, to the solver's tolerance.
    let fit = start
        .calibrate(
            &actuations,
            &exact,
            &softspine::Load::from(0.03),
            &fields,
            &CalibrationSettings::default(),
        )
        .unwrap();
    assert!(fit.converged, "{}", fit.message);
    for (e, t) in fit.estimates.iter().zip(&true_values) {
        assert!((e / t - 1.0).abs() < 1e-7, "{e} vs {t}");
    }
    // With 0.5 mm of noise (a deterministic sequence): within 3 standard
    // errors, and the residual rms near the noise.
    let sigma = 5e-4;
    let noisy: Vec<Vector3<f64>> = exact
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let u = |k: usize| ((i * 3 + k) as f64 * 2.399_963).sin() * 3f64.sqrt();
            t + sigma * Vector3::new(u(0), u(1), u(2))
        })
        .collect();
    let fit = start
        .calibrate(
            &actuations,
            &noisy,
            &softspine::Load::from(0.03),
            &fields,
            &CalibrationSettings::default(),
        )
        .unwrap();
    assert!(fit.converged, "{}", fit.message);
    for ((e, se), t) in fit
        .estimates
        .iter()
        .zip(&fit.standard_errors)
        .zip(&true_values)
    {
        assert!((e - t).abs() < 3.0 * se, "{e} +- {se} vs {t}");
        assert!(
            *se < 0.2 * t.abs(),
            "{se} of {t}: the fit should resolve it"
        );
    }
    assert!(
        fit.rms > 0.5 * sigma && fit.rms < 1.5 * sigma,
        "{}",
        fit.rms
    );
}

/// A precurved rod with a tendon whose tip, under its weight, rests on a
/// floor where it stood unloaded (`floor`: that height, with friction 0.3;
/// none: no floor, no weight).
fn tendon_arc(floor: Option<f64>) -> Scene {
    let mut text = String::from(
        r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
            "base_quaternion": [0.7071067811865476, 0, 0.7071067811865476, 0],
            "rest_curvature": [[0, 2]],
            "tendons": [{"tension": 0.1, "offset": [0.01, 0]}]"#,
    );
    if let Some(z) = floor {
        text += &format!(
            r#", "gravity": {{"linear_density": 1, "vector": [0, 0, -1]}},
            "obstacles": [{{"shape": "half_space", "point": [0, 0, {z}],
                            "normal": [0, 0, 1], "friction": 0.3}}]"#
        );
    }
    Scene::from_json_str(&(text + "}")).unwrap()
}

/// The inverse kinematics' Jacobian with friction lets what sticks go, its
/// friction held as a fixed force: the same equilibrium, so a differenced
/// drive (a tendon's tension, through the general sensitivity) is given
/// there. Releasing the contact's friction altogether had left the residual
/// far from converged, and that sensitivity refused ("needs a converged
/// equilibrium"): a tendon-driven robot's IK could not step where its
/// contact stuck. Held, the stuck tip does not move along the floor.
#[test]
fn what_sticks_is_let_go_at_the_same_equilibrium_for_every_drive() {
    let settings = Settings {
        n_elements: Some(40),
        ..Settings::default()
    };
    let rest = softspine::solve(&tendon_arc(None), settings.clone(), None).unwrap();
    let mut solver = Solver::new(&tendon_arc(Some(rest.tip_position().z)), settings).unwrap();
    let sol = solver.solve(None).unwrap();
    assert!(sol.converged() && sol.contacts.len() == 1 && !sol.contacts[0].sliding);
    let held = solver.sensitivity(&["tendons[0].tension"]).unwrap();
    assert!(
        held.tip_position.column(0).xy().norm() < 1e-9,
        "{}",
        held.tip_position
    );
    let released = solver
        .with_sticking_released(|s| s.sensitivity(&["tendons[0].tension"]))
        .unwrap();
    assert!(
        released.tip_position[(0, 0)].abs() > 1e-3,
        "{}",
        released.tip_position
    );
    // The workspace is the equilibrium's again.
    let again = solver.sensitivity(&["tendons[0].tension"]).unwrap();
    assert_eq!(again.tip_position, held.tip_position);
}

/// The coupled iteration's linearisation (`solver/coupled.rs`): at an
/// equilibrium its tip columns, by the adjoint (solves with `A^T`), are the
/// tip sensitivity's, by one solve a column, and Newton's step is nil; off
/// it, moving the state by Newton's step alone converges quadratically, and
/// the columns predict where the tip goes when the drive moves with it.
#[test]
fn the_coupled_linearisation_is_the_tip_sensitivity_and_newtons_step() {
    use softspine::solver::DriveParameters;
    let mut scene = Scene::new(0.8, 0.9, 1.3, 0.7);
    scene.rest_curvature = vec![[1.2, -0.4], [-0.6, 0.9]];
    scene.distributed_force = Vector3::new(0.3, -1.1, -2.0);
    scene.tip_force = Vector3::new(-0.7, 0.4, 0.5);
    let settings = Settings {
        n_elements: Some(20),
        residual_tol: 1e-13,
        ..Settings::default()
    };
    let exact_at = |rest_curvature: &[[f64; 2]]| {
        let mut moved = scene.clone();
        moved.rest_curvature = rest_curvature.to_vec();
        let sol = softspine::solver::solve(&moved, settings.clone(), None).unwrap();
        assert!(sol.converged(), "{}", sol.message);
        sol.tip_position()
    };
    let mut solver = softspine::Solver::new(&scene, settings.clone()).unwrap();
    let sol = solver.solve(None).unwrap();
    assert!(sol.converged(), "{}", sol.message);
    let sens = solver.tip_sensitivity(2).unwrap();
    let lin = solver
        .linearise_coupled(DriveParameters::SectionCurvature(2), true)
        .unwrap();
    assert!(lin.certified);
    assert!(
        lin.newton_position.norm() < 1e-12,
        "{}",
        lin.newton_position
    );
    let scale = sens.position.norm();
    assert!((&lin.position - &sens.position).norm() < 1e-10 * scale);
    assert!((&lin.rotation - &sens.rotation).norm() < 1e-10 * sens.rotation.norm());
    assert!((lin.tip_position - sol.tip_position()).norm() < 1e-15);

    // Off the equilibrium (the drive moved): Newton's step alone (dp = 0)
    // takes the state to the new equilibrium quadratically.
    let moved = [[1.25, -0.35], [-0.6, 0.9]];
    solver.set_rest_curvature(&moved).unwrap();
    solver.set_state(&sol.quaternions).unwrap();
    let mut misses = Vec::new();
    let exact = exact_at(&moved);
    for _ in 0..4 {
        let lin = solver
            .linearise_coupled(DriveParameters::SectionCurvature(2), false)
            .unwrap();
        misses.push((lin.tip_position - exact).norm());
        assert!(solver.move_state(&[0.0; 4]));
    }
    assert!(
        misses[1] < 1e-2 * misses[0] && misses[2] < 1e-4 * misses[1],
        "{misses:?}"
    );

    // From the first equilibrium, the drive moved by dp and the state by the
    // coupled move: the tip lands where the linearisation says, to second order.
    solver.set_rest_curvature(&scene.rest_curvature).unwrap();
    solver.set_state(&sol.quaternions).unwrap();
    let lin = solver
        .linearise_coupled(DriveParameters::SectionCurvature(2), false)
        .unwrap();
    let dp = [1e-3, -2e-3, 0.5e-3, 1e-3];
    let predicted = lin.tip_position
        + lin.newton_position
        + &lin.position * nalgebra::DVector::from_column_slice(&dp);
    let moved: Vec<[f64; 2]> = scene
        .rest_curvature
        .iter()
        .enumerate()
        .map(|(s, k)| [k[0] + dp[2 * s], k[1] + dp[2 * s + 1]])
        .collect();
    let exact = exact_at(&moved);
    let change = (exact - sol.tip_position()).norm();
    assert!(
        (predicted - exact).norm() < 1e-2 * change,
        "{predicted} {exact}"
    );
    // And the state moved with it is that close to the new equilibrium.
    assert!(solver.move_state(&dp));
    solver.set_rest_curvature(&moved).unwrap();
    let lin = solver
        .linearise_coupled(DriveParameters::SectionCurvature(2), false)
        .unwrap();
    assert!((lin.tip_position - exact).norm() < 1e-2 * change);
    // A linearisation of the model before a change is not moved along.
    solver.set_rest_curvature(&scene.rest_curvature).unwrap();
    assert!(
        !solver.move_state(&dp),
        "a stale linearisation moved the state"
    );
}
