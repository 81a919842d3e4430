//! The fourth-order discretisations, `Method::Shooting` and `Scheme::Fe4`,
//! against closed forms and against the finite-difference scheme's Richardson
//! limit (an independent discretisation of the same rod): order 4 at the
//! nodes, point loads at section ends, held tips and their reactions.

use nalgebra::Vector3;
use softspine::{solve, Method, PointLoad, Quat, Scene, Scheme, Settings, Solution, TipCondition};

fn settings(n: usize, method: Method) -> Settings {
    Settings {
        n_elements: Some(n),
        method,
        ..Settings::default()
    }
}

fn shoot(scene: &Scene, n: usize) -> Solution {
    let sol = solve(scene, settings(n, Method::Shooting), None).unwrap();
    assert!(sol.converged(), "n = {n}: {}", sol.message);
    sol
}

/// Largest node distance between two solutions at the nodes of the coarser.
fn distance(coarse: &[Vector3<f64>], fine: &[Vector3<f64>]) -> f64 {
    let stride = (fine.len() - 1) / (coarse.len() - 1);
    coarse
        .iter()
        .enumerate()
        .map(|(i, r)| (r - fine[i * stride]).norm())
        .fold(0.0, f64::max)
}

#[test]
fn the_cantilever_tip_converges_at_order_four_to_bisshopp_drucker() {
    // alpha = P L^2 / EI = 10: deflection and shortening over L (docs/model.md).
    let mut scene = Scene::new(1.0, 1.0, 1.0, 1.0 / 1.3);
    scene.tip_force = Vector3::new(10.0, 0.0, 0.0);
    let exact = Vector3::new(0.810_609_02, 0.0, 1.0 - 0.554_995_60);
    let errors: Vec<f64> = [10, 20, 40]
        .iter()
        .map(|&n| (shoot(&scene, n).tip_position() - exact).norm())
        .collect();
    for pair in errors.windows(2) {
        let order = (pair[0] / pair[1]).log2();
        assert!((3.7..4.3).contains(&order), "{errors:?}");
    }
}

/// A 3D rod of four sections with rest curvature, gravity and point loads at
/// two section ends, its base turned and moved.
fn loaded_sections() -> Scene {
    let mut s = Scene::new(0.8, 0.9, 1.3, 0.7);
    s.rest_curvature = vec![[1.2, -0.4], [-0.6, 0.9], [2.0, 0.5], [0.0, -1.5]];
    s.distributed_force = Vector3::new(0.3, -1.1, -2.0);
    s.tip_force = Vector3::new(-0.7, 0.4, 0.5);
    s.tip_moment = Vector3::new(0.2, -0.3, 0.15);
    s.base_quaternion = Quat::new(0.9, 0.2, -0.3, 0.1).normalized();
    s.base_position = Vector3::new(0.1, -0.2, 0.3);
    s.point_loads = vec![
        PointLoad {
            s: 0.2,
            force: Vector3::new(0.5, 0.2, -0.8),
            ..Default::default()
        },
        PointLoad {
            s: 0.6,
            force: Vector3::new(-0.3, 0.6, 0.1),
            ..Default::default()
        },
    ];
    s
}

/// The whole backbone of `loaded_sections` to about 1e-10 L: the
/// finite-difference scheme is second order with an even expansion, so
/// Richardson from n = 640 and 1280 removes its leading error.
fn richardson_reference(scene: &Scene) -> Vec<Vector3<f64>> {
    let fd = |n| solve(scene, settings(n, Method::Newton), None).unwrap();
    let (a, b) = (fd(640), fd(1280));
    a.positions
        .iter()
        .enumerate()
        .map(|(i, r)| (4.0 * b.positions[2 * i] - r) / 3.0)
        .collect()
}

/// Errors at n = 16, 32, 64 are of order 4 and below `finest` at n = 64.
fn assert_fourth_order(errors: &[f64], finest: f64) {
    for pair in errors.windows(2) {
        let order = (pair[0] / pair[1]).log2();
        assert!((3.7..4.3).contains(&order), "{errors:?}");
    }
    assert!(errors[errors.len() - 1] < finest, "{errors:?}");
}

#[test]
fn shooting_and_the_finite_difference_scheme_agree_on_the_whole_backbone() {
    let scene = loaded_sections();
    let reference = richardson_reference(&scene);
    let errors: Vec<f64> = [16, 32, 64]
        .iter()
        .map(|&n| distance(&shoot(&scene, n).positions, &reference))
        .collect();
    assert_fourth_order(&errors, 1e-7 * scene.length);
    // Base force explicit: every load summed (the point loads included).
    let sol = shoot(&scene, 16);
    let total = scene.tip_force
        + scene.distributed_force * scene.length
        + scene
            .point_loads
            .iter()
            .map(|p| p.force)
            .sum::<Vector3<f64>>();
    assert!((sol.forces[0] - total).norm() < 1e-12);
}

#[test]
fn the_fourth_order_scheme_agrees_with_the_finite_difference_limit() {
    let scene = loaded_sections();
    let reference = richardson_reference(&scene);
    let errors: Vec<f64> = [16, 32, 64]
        .iter()
        .map(|&n| {
            let fe4 = Settings {
                scheme: Some(Scheme::Fe4),
                ..settings(n, Method::Newton)
            };
            let sol = solve(&scene, fe4, None).unwrap();
            assert!(sol.converged() && sol.stable, "n = {n}: {}", sol.message);
            distance(&sol.positions, &reference)
        })
        .collect();
    assert_fourth_order(&errors, 1e-7 * scene.length);
}

/// A converged solve by shooting or by Newton on the fourth-order scheme.
fn solve_fourth_order(scene: &Scene, n: usize, shooting: bool) -> Solution {
    let settings = if shooting {
        settings(n, Method::Shooting)
    } else {
        Settings {
            scheme: Some(Scheme::Fe4),
            ..settings(n, Method::Newton)
        }
    };
    let sol = solve(scene, settings, None).unwrap();
    assert!(sol.converged(), "n = {n}: {}", sol.message);
    sol
}

#[test]
fn holding_the_tip_where_the_free_rod_puts_it_returns_the_tip_loads() {
    for shooting in [true, false] {
        let scene = loaded_sections();
        let free = solve_fourth_order(&scene, 40, shooting);
        let mut pinned = scene.clone();
        pinned.tip_force = Vector3::zeros();
        pinned.tip = TipCondition::Pinned {
            position: free.tip_position(),
        };
        let sol = solve_fourth_order(&pinned, 40, shooting);
        assert!(sol.stable);
        let reaction = sol.tip_reaction_force.unwrap();
        assert!((reaction - scene.tip_force).norm() < 1e-8, "{reaction}");
        assert!(distance(&sol.positions, &free.positions) < 1e-9);

        let mut clamped = pinned.clone();
        clamped.tip_moment = Vector3::zeros();
        clamped.tip = TipCondition::Clamped {
            position: free.tip_position(),
            quaternion: free.tip_quaternion(),
        };
        let sol = solve_fourth_order(&clamped, 40, shooting);
        let moment = sol.tip_reaction_moment.unwrap();
        assert!((moment - scene.tip_moment).norm() < 1e-8, "{moment}");
        assert!((sol.tip_reaction_force.unwrap() - scene.tip_force).norm() < 1e-8);
    }
}

#[test]
fn a_held_point_starts_its_load_path_where_the_unloaded_fe4_rod_puts_it() {
    // The rest positions of held points are where the rest shape puts them,
    // its internal nodes those of the unloaded elements (not of the loads).
    let mut scene = loaded_sections();
    scene.tip_force = Vector3::zeros();
    scene.tip = TipCondition::Pinned {
        position: Vector3::new(0.3, -0.2, 0.9),
    };
    let loaded = softspine::RodModel::new(&scene, 16).with_scheme(Scheme::Fe4);
    let mut unloaded_scene = scene.clone();
    unloaded_scene.distributed_force = Vector3::zeros();
    unloaded_scene.point_loads.clear();
    unloaded_scene.tip_moment = Vector3::zeros();
    let unloaded = softspine::RodModel::new(&unloaded_scene, 16).with_scheme(Scheme::Fe4);
    let rest = unloaded.rest_shape();
    let mut expected = vec![Vector3::zeros(); 17];
    unloaded.positions(&rest, &mut unloaded.new_interior(), &mut expected);
    let start = loaded.constraints().last().unwrap().rest;
    assert!(
        (start - expected[16]).norm() < 1e-14,
        "{start} vs {}",
        expected[16]
    );
}
