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

// --- Settings read by name (issue 11, item 6) --------------------------------

use softspine::methods::paper::PaperSettings;
use softspine::{Accuracy, Error, Method, Value};

fn json(text: &str) -> Value {
    Value::from_json_str(text).unwrap()
}

fn refusal(e: Error) -> (String, String) {
    match e {
        Error::InvalidArgument { name, reason } => (name, reason),
        other => panic!("expected an invalid argument, got {other:?}"),
    }
}

#[test]
fn settings_round_trip_through_their_value_tree() {
    let mut settings = Settings::from_value(&json(
        r#"{"n_elements": 40, "method": "lm", "residual_tol": 1e-12,
            "paper": {"particles": 12, "seed": 7}}"#,
    ))
    .unwrap();
    assert_eq!(settings.n_elements, Some(40));
    assert_eq!(settings.method, Method::LevenbergMarquardt);
    assert_eq!(settings.paper.swarm.particles, 12);
    assert_eq!(settings.paper.swarm.seed, 7);
    // Untouched fields keep the defaults.
    assert_eq!(settings.max_iterations, Settings::default().max_iterations);
    assert_eq!(
        Settings::from_value(&settings.to_value()).unwrap(),
        settings
    );
    settings.set("n_elements", &Value::Null).unwrap();
    assert_eq!(settings.n_elements, None);
    for key in Settings::KEYS {
        let value = match Settings::default().to_value() {
            Value::Map(entries) => entries.into_iter().find(|(k, _)| k == key).unwrap().1,
            _ => unreachable!(),
        };
        settings.set(key, &value).unwrap();
    }
    assert_eq!(settings, Settings::default());
}

#[test]
fn a_bad_setting_is_refused_by_its_name() {
    let cases = [
        (
            r#"{"residual_tol": "small"}"#,
            "residual_tol",
            "expected a number",
        ),
        (
            r#"{"n_elements": 2.5}"#,
            "n_elements",
            "integer in [1, 4000000]",
        ),
        (r#"{"method": "fast"}"#, "method", "unknown method 'fast'"),
        (
            r#"{"paper": {"chi": null}}"#,
            "paper.chi",
            "expected a number",
        ),
        (
            r#"{"paper": {"swarm": 3}}"#,
            "paper.swarm",
            "unknown setting",
        ),
        (r#"{"tolerance": 1e-9}"#, "tolerance", "unknown setting"),
        (r#"{"residual_tol": 1.0}"#, "residual_tol", "must lie in"),
        (
            r#"{"n_elements": 2000, "method": "lm"}"#,
            "n_elements",
            "for method",
        ),
    ];
    for (text, name, reason) in cases {
        let (got_name, got_reason) = refusal(Settings::from_value(&json(text)).unwrap_err());
        assert_eq!(got_name, name, "{text}");
        assert!(got_reason.contains(reason), "{text}: {got_reason}");
    }
}

#[test]
fn accuracy_reads_tol_refine_and_max_elements() {
    let accuracy = Accuracy::from_value(&json(
        r#"{"tol": 1e-6, "refine": "richardson", "max_elements": 640}"#,
    ))
    .unwrap();
    assert_eq!(
        accuracy,
        Accuracy {
            richardson: true,
            max_elements: 640,
            ..Accuracy::new(1e-6)
        }
    );
    assert_eq!(
        Accuracy::from_value(&accuracy.to_value()).unwrap(),
        accuracy
    );
    let (name, reason) =
        refusal(Accuracy::from_value(&json(r#"{"refine": "richardson"}"#)).unwrap_err());
    assert_eq!(name, "refine");
    assert!(reason.contains("needs tol"), "{reason}");
    let (name, _) =
        refusal(Accuracy::from_value(&json(r#"{"tol": 1e-6, "refine": "cubic"}"#)).unwrap_err());
    assert_eq!(name, "refine");
}

#[test]
fn paper_settings_read_every_key() {
    let mut paper = PaperSettings::default();
    for key in PaperSettings::KEYS {
        paper.set(key, &Value::Number(3.0)).unwrap();
    }
    assert_eq!(paper.swarm.particles, 3);
    assert_eq!(paper.lm_iterations, 3);
    assert_eq!(paper.tol, 3.0);
    let (name, _) = refusal(paper.set("seed", &Value::Number(-1.0)).unwrap_err());
    assert_eq!(name, "seed");
}

#[test]
fn ik_settings_read_by_name() {
    use softspine::{IkSettings, Strategy};
    let settings = IkSettings::from_value(&json(
        r#"{"strategy": "geometric", "tol": 1e-8, "max_iterations": 30}"#,
    ))
    .unwrap();
    assert_eq!(settings.strategy, Strategy::Geometric);
    assert_eq!(
        IkSettings::from_value(&settings.to_value()).unwrap(),
        settings
    );
    let (name, _) = refusal(IkSettings::from_value(&json(r#"{"strategy": "fast"}"#)).unwrap_err());
    assert_eq!(name, "strategy");
    let (name, _) = refusal(IkSettings::from_value(&json(r#"{"tol": 0}"#)).unwrap_err());
    assert_eq!(name, "tol");
    let (name, _) = refusal(IkSettings::from_value(&json(r#"{"load": 1}"#)).unwrap_err());
    assert_eq!(name, "load");
}

/// The core chooses the method (issue 30): Newton at a given n; shooting
/// for accuracy on demand where it models the scene, its tip free and no
/// scheme set; an explicit method is kept.
#[test]
fn the_default_method_is_the_cores_choice() {
    use softspine::Method;
    let free = Scene::from_json_str(
        r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [3, 0, 0]}"#,
    )
    .unwrap();
    let pinned = Scene::from_json_str(
        r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
            "tip": {"type": "pinned", "position": [0.5, 0, 0.8]}}"#,
    )
    .unwrap();
    let tendon = Scene::from_json_str(
        r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1},
            "tendons": [{"tension": 1, "offset": [0.01, 0]}]}"#,
    )
    .unwrap();
    let auto = Settings::default();
    assert_eq!(auto.method, Method::Auto);
    assert_eq!(auto.method_for(&free, None), Method::Newton);
    assert_eq!(auto.method_for(&free, Some(1e-4)), Method::Shooting);
    assert_eq!(auto.method_for(&pinned, Some(1e-4)), Method::Newton);
    assert_eq!(auto.method_for(&tendon, Some(1e-4)), Method::Newton);
    let fe4 = Settings {
        scheme: Some(softspine::Scheme::Fe4),
        ..Settings::default()
    };
    assert_eq!(fe4.method_for(&free, Some(1e-4)), Method::Newton);
    let newton = Settings {
        method: Method::Newton,
        ..Settings::default()
    };
    assert_eq!(newton.method_for(&free, Some(1e-4)), Method::Newton);
    assert_eq!(auto.resolved(&free).method, Method::Newton);
}
