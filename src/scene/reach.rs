//! How far the discrete rod reaches: the scene refuses a held point beyond it.

/// How much less than `k ds` a chain of `k` elements reaches along a
/// direction at angle `theta` from the tangent of its clamped first node, in
/// units of `ds`. The discrete rod cannot straighten at once: an element's
/// mean tangent `(T(a) + T(a, b) + T(b)) / 3` keeps a third of its clamped
/// end's direction, so even an infinite pull leaves a deficit of about
/// `0.2 theta^2 ds` (the optimal chain turns its nodes by `theta r^j`,
/// `r = sqrt(24) - 5`: the deficit sits in the first two elements). The
/// continuous rod's deficit vanishes; the discrete one falls as `1 / n`.
///
/// Computed exactly for the planar chain (twist only shortens it): maximise
/// `sum_i [cos x_{i-1} + cos((x_{i-1} + x_i) / 2) + cos x_i] / 3` over the
/// node angles `x_j` from the direction of reach, `x_0 = theta`, by
/// Gauss-Seidel sweeps of one-dimensional Newton steps. Nodes beyond the
/// 24th are held aligned (their optimal angle is below `1e-23 theta`).
pub fn clamped_end_deficit(theta: f64, elements: usize) -> f64 {
    let k = elements;
    let m = k.min(24);
    if k == 0 || theta == 0.0 {
        return 0.0;
    }
    let ratio = 24f64.sqrt() - 5.0;
    let mut x: Vec<f64> = (0..=m).map(|j| theta * ratio.powi(j as i32)).collect();
    let next = |x: &[f64], j: usize| if j < m { x[j + 1] } else { 0.0 };
    for _ in 0..100 {
        let mut largest = 0.0f64;
        for j in 1..=m {
            let interior = j < k;
            let own = if interior { 2.0 } else { 1.0 } / 3.0;
            let (left, right) = (0.5 * (x[j - 1] + x[j]), 0.5 * (x[j] + next(&x, j)));
            let mut slope = -own * x[j].sin() - left.sin() / 6.0;
            let mut curvature = -own * x[j].cos() - left.cos() / 12.0;
            if interior {
                slope -= right.sin() / 6.0;
                curvature -= right.cos() / 12.0;
            }
            // A maximum: Newton where the objective is concave, else uphill.
            let step = if curvature < 0.0 {
                -slope / curvature
            } else {
                slope
            };
            let step = step.clamp(-0.5, 0.5);
            x[j] += step;
            largest = largest.max(step.abs());
        }
        if largest < 1e-15 {
            break;
        }
    }
    (1..=k.min(m + 1))
        .map(|i| {
            let (a, b) = (x[i - 1], next(&x, i - 1));
            1.0 - (a.cos() + (0.5 * (a + b)).cos() + b.cos()) / 3.0
        })
        .sum()
}
