//! Time a solve at large n, split into building the solver (allocation) and
//! solving: `cargo run --release --example large_n -- 1000000`.

use softspine::{Scene, Settings, Solver};
use std::time::Instant;

fn main() -> softspine::Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse().expect("n: a positive integer"))
        .unwrap_or(1_000_000);
    let scenes = [
        (
            "cantilever alpha = 3",
            r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [3, 0, 0]}"#,
        ),
        (
            "stiff torsion, 3D",
            r#"{"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 300},
            "gravity": {"linear_density": 1, "vector": [2, 1, 0]},
            "rest_curvature": [[1, 0.5], [0.5, -1]]}"#,
        ),
    ];
    for (name, json) in scenes {
        let scene = Scene::from_json_str(json)?;
        let settings = Settings {
            n_elements: Some(n),
            ..Settings::default()
        };
        let start = Instant::now();
        let mut solver = Solver::new(&scene, settings)?;
        let built = start.elapsed();
        let solution = solver.solve(None)?;
        let solved = start.elapsed() - built;
        drop(solver);
        let total = start.elapsed();
        println!(
            "{name}: n = {n}, {:?} after {} iterations; build {:.3} s, solve {:.3} s, total with drop {:.3} s",
            solution.status,
            solution.iterations,
            built.as_secs_f64(),
            solved.as_secs_f64(),
            total.as_secs_f64()
        );
    }
    Ok(())
}
