//! Bytes -> `Scene::from_json_str`; a scene it accepts goes to the solver
//! (about 20 elements, a bounded budget). Refusals are fine, panics are not.
#![no_main]

use libfuzzer_sys::fuzz_target;
use softspine::{Scene, Settings, Solver};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(scene) = Scene::from_json_str(text) else {
        return;
    };
    // n must be a multiple of the sections: the one nearest above 20, while cheap.
    let sections = scene.sections();
    if sections > 20 {
        return;
    }
    let settings = Settings {
        n_elements: sections * 20usize.div_ceil(sections),
        max_iterations: 50,
        ..Settings::default()
    };
    if let Ok(mut solver) = Solver::new(&scene, settings) {
        let _ = solver.solve(None);
    }
});
