//! The default number of elements: one rule in the core (issue 11, item 1).

use softspine::solver::default_elements;
use softspine::{solve, Scene, Settings};

#[test]
fn the_default_n_is_the_smallest_multiple_of_the_sections_from_20() {
    let expected = [
        (1, 20),
        (3, 21),
        (4, 20),
        (7, 21),
        (11, 22),
        (20, 20),
        (25, 25),
    ];
    for (sections, n) in expected {
        assert_eq!(default_elements(sections), n, "{sections} sections");
    }
}

#[test]
fn a_three_section_scene_solves_with_default_settings() {
    let scene = Scene::from_json_str(
        r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
            "rest_curvature": [[1, 0], [0, -1], [0.5, 0.5]], "tip_force": [0.2, 0, 0]}"#,
    )
    .unwrap();
    let sol = solve(&scene, Settings::default(), None).unwrap();
    assert!(sol.converged(), "{}", sol.message);
    assert_eq!(sol.n_elements, 21);
    assert_eq!(Settings::default().elements_for(&scene), 21);
}
