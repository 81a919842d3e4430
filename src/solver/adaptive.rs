//! Accuracy on demand: the solver chooses the discretisation. The scheme is
//! second order, so the tip error of the solve at 2n is about a third of the
//! difference between the tips at n and 2n; n doubles until that estimate is
//! below the tolerance. Richardson extrapolation `(4 r_2n - r_n) / 3` removes
//! the leading error term and typically gains two to four digits.

use super::{Settings, Solution, Solver};
use crate::error::{Error, Result};
use crate::model::slerp;
use crate::quat::Quat;
use crate::scene::Scene;

/// What accuracy to reach and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Accuracy {
    /// Tip error tolerance, relative to the length `L`.
    pub tol: f64,
    /// Return the Richardson-extrapolated tip (marked in the Solution).
    pub richardson: bool,
    /// Largest number of elements tried (default 10 240).
    pub max_elements: usize,
}

impl Accuracy {
    pub fn new(tol: f64) -> Self {
        Accuracy {
            tol,
            richardson: false,
            max_elements: 10_240,
        }
    }
}

/// Solve `scene` to a tip accuracy of `accuracy.tol * L`, starting at
/// `settings.n_elements` (a multiple of the sections) and doubling.
pub fn solve_to_accuracy(
    scene: &Scene,
    settings: Settings,
    accuracy: &Accuracy,
) -> Result<Solution> {
    if !(accuracy.tol.is_finite() && accuracy.tol > 0.0) {
        return Err(Error::argument(
            "tol",
            format!("must be positive and finite, got {}", accuracy.tol),
        ));
    }
    let length = scene.length;
    let mut n = settings.n_elements;
    let mut solver = Solver::new(
        scene,
        Settings {
            n_elements: n,
            ..settings.clone()
        },
    )?;
    let mut coarse = solver.solve(None)?;
    if solver.model().is_trivial() {
        // The straight rod is exact at any n: nothing to refine.
        coarse.error_estimate = Some(0.0);
        return Ok(coarse);
    }
    let mut iterations = coarse.iterations;
    loop {
        if !coarse.converged() {
            coarse.iterations = iterations;
            return Ok(coarse);
        }
        let warm = refine(&coarse.quaternions);
        let mut fine = Solver::new(
            scene,
            Settings {
                n_elements: 2 * n,
                ..settings.clone()
            },
        )?
        .solve(Some(&warm))?;
        iterations += fine.iterations;
        if !fine.converged() {
            fine.iterations = iterations;
            return Ok(fine);
        }
        let (r_n, r_2n) = (coarse.tip_position(), fine.tip_position());
        let estimate = (r_2n - r_n).norm() / 3.0;
        if estimate <= accuracy.tol * length || 4 * n > accuracy.max_elements {
            fine.iterations = iterations;
            fine.error_estimate = Some(estimate);
            if accuracy.richardson {
                fine.extrapolated_tip = Some((4.0 * r_2n - r_n) / 3.0);
            }
            if estimate > accuracy.tol * length {
                fine.message = format!(
                    "{}; tolerance not met: {} elements reached the limit, error estimate {estimate:.2e} m",
                    fine.message,
                    2 * n
                );
            }
            return Ok(fine);
        }
        coarse = fine;
        n *= 2;
    }
}

/// The nodes of a twice finer discretisation: every node kept, a midpoint
/// (half-way rotation) between neighbours.
fn refine(q: &[Quat]) -> Vec<Quat> {
    let mut out = Vec::with_capacity(2 * q.len() - 1);
    for pair in q.windows(2) {
        out.push(pair[0]);
        out.push(slerp(pair[0], pair[1], 0.5));
    }
    out.push(q[q.len() - 1]);
    out
}
