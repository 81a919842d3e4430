//! Small dense solves of the KKT system's Schur complement `S x = b` (one
//! row per held coordinate or contact, tens of rows).
//!
//! `S` is often singular: rows repeat (a pinned tip on a floor holds its
//! height twice; where a stretch of a rod sticks to a surface, each chord's
//! length is held by both its nodes) or a held point cannot move to first
//! order (a straight rod along its axis). The step then takes the
//! minimum-norm least-squares solution `S^+ b`, the pseudo-inverse's, which
//! leaves the undetermined part of the multipliers alone. For a symmetric
//! `S` a Cholesky factorisation with diagonal pivoting finds its rank and
//! null space at a tenth of a singular value decomposition's cost; the SVD
//! stays for what that does not settle (an indefinite or unsymmetric `S`).

use nalgebra::{DMatrix, DVector};

/// Singular values (or pivots) below this fraction of the largest are zero.
const RANK_CUTOFF: f64 = 1e-11;

/// The largest difference of `a_ij` and `a_ji` (of the largest entry) of a
/// symmetric `a`: the round-off of the Schur complement's two triangles.
const SYMMETRY_CUTOFF: f64 = 1e-10;

/// What may remain of a symmetric `S` past its rank, relative to its largest
/// diagonal entry, for it to be semidefinite of that rank (round-off of the
/// repeated rows' Schur complement); more, and the SVD decides.
const TRAILING_CUTOFF: f64 = 1e-9;

/// Solve `a x = b` for a symmetric `a`, `x` into `b`: by Cholesky where
/// `a` is positive definite; where it is singular and semidefinite, `a^+ b` by
/// pivoted Cholesky; else (indefinite: a held rod under compression, whose
/// free stiffness has negative directions) as a general `a`. An `a` that is
/// not symmetric after all (a dead moment's unsymmetric stiffness: the
/// factorisations read one triangle) is solved as a general one.
pub(crate) fn solve_symmetric_in_place(a: &mut DMatrix<f64>, b: &mut DVector<f64>) -> bool {
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    let symmetric = (0..a.nrows())
        .all(|i| (0..i).all(|j| (a[(i, j)] - a[(j, i)]).abs() <= SYMMETRY_CUTOFF * scale));
    if !symmetric {
        return solve_general_in_place(a, b);
    }
    if let Some(chol) = a.clone().cholesky() {
        // A pivot of round-off (two rows that repeat to round-off, a contact
        // on a node and on the element beside it) passes here with huge
        // multipliers of opposite signs; the contacts' QP then bounds the
        // negative one and drops its row. The pseudo-inverse would split
        // the force between the two (a knife edge under a node reported as
        // two contacts at one point).
        let x = chol.solve(b);
        if x.iter().all(|v| v.is_finite()) {
            b.copy_from(&x);
            return true;
        }
    }
    if let Some(x) = semidefinite_solve(a, b) {
        b.copy_from(&x);
        return true;
    }
    solve_general_in_place(a, b)
}

/// Solve `a x = b` for a general `a`, `x` into `b`: by LU with complete
/// pivoting where its pivots show `a` regular (the smallest above
/// [`RANK_CUTOFF`] of the largest), else `a^+ b` by SVD.
pub(crate) fn solve_general_in_place(a: &mut DMatrix<f64>, b: &mut DVector<f64>) -> bool {
    let m = a.nrows();
    if m == 0 {
        return true;
    }
    let lu = a.clone().full_piv_lu();
    let pivots = lu.u().diagonal();
    let (smallest, largest) = pivots.iter().fold((f64::INFINITY, 0.0f64), |(s, l), p| {
        (s.min(p.abs()), l.max(p.abs()))
    });
    if smallest > RANK_CUTOFF * largest {
        if let Some(x) = lu.solve(b) {
            if x.iter().all(|v| v.is_finite()) {
                b.copy_from(&x);
                return true;
            }
        }
    }
    pseudo_inverse_solve_in_place(a, b)
}

/// Minimum-norm least-squares solution `a^+ b` by SVD, into `b`.
pub(crate) fn pseudo_inverse_solve_in_place(a: &mut DMatrix<f64>, b: &mut DVector<f64>) -> bool {
    if a.nrows() == 0 {
        // No row held (obstacles, none touched): the free step.
        return true;
    }
    let svd = a.clone().svd(true, true);
    let cutoff = RANK_CUTOFF * svd.singular_values.max();
    if cutoff.is_nan() || cutoff <= 0.0 {
        return false;
    }
    match svd.solve(b, cutoff) {
        Ok(x) if x.iter().all(|v| v.is_finite()) => {
            b.copy_from(&x);
            true
        }
        _ => false,
    }
}

/// `a^+ b` for a symmetric positive semidefinite `a` of rank `r < m`, by a
/// Cholesky factorisation with diagonal pivoting, `P a P^T = [L1; L2]
/// [L1; L2]^T` (`L1` r x r): the null space is spanned by the columns of
/// `N = P^T [-L1^-T L2^T; I]`. With `b` projected off `N` (the least-squares
/// part) the pivots' equations `L1 L1^T y = b1` give a solution `y` (zero
/// off the pivots), and `y` projected off `N` is the minimum-norm one.
/// `None` where `a` is not semidefinite to round-off past its pivots.
fn semidefinite_solve(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    let m = a.nrows();
    let scale = a.diagonal().iter().fold(0.0f64, |s, d| s.max(d.abs()));
    if m == 0 || !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let mut l = a.clone();
    let mut order: Vec<usize> = (0..m).collect();
    let mut rank = 0;
    while rank < m {
        let k = rank;
        let (p, largest) =
            (k..m)
                .map(|i| (i, l[(i, i)]))
                .fold(
                    (k, f64::NEG_INFINITY),
                    |best, x| if x.1 > best.1 { x } else { best },
                );
        if largest <= RANK_CUTOFF * scale {
            break;
        }
        l.swap_rows(k, p);
        l.swap_columns(k, p);
        order.swap(k, p);
        let pivot = largest.sqrt();
        l[(k, k)] = pivot;
        for i in k + 1..m {
            l[(i, k)] /= pivot;
            l[(k, i)] = l[(i, k)];
        }
        // The whole trailing block, both triangles: the next pivot's swap
        // moves entries across its diagonal.
        for j in k + 1..m {
            let ljk = l[(j, k)];
            for i in k + 1..m {
                l[(i, j)] -= l[(i, k)] * ljk;
            }
        }
        rank += 1;
    }
    // What is left past the rank must be round-off (an indefinite or
    // unsymmetric `a` leaves more).
    for j in rank..m {
        for i in j..m {
            if l[(i, j)].abs() > TRAILING_CUTOFF * scale {
                return None;
            }
        }
    }
    let r = rank;
    let l1 = l.view((0, 0), (r, r)).lower_triangle();
    let l2 = l.view((r, 0), (m - r, r)).into_owned();
    // N in pivoted order: [-L1^-T L2^T; I].
    let mut top = l2.transpose();
    if !l1.transpose().solve_upper_triangular_mut(&mut top) {
        return None;
    }
    let mut null = DMatrix::zeros(m, m - r);
    null.view_mut((0, 0), (r, m - r)).copy_from(&(-top));
    null.view_mut((r, 0), (m - r, m - r)).fill_with_identity();
    let gram = (null.transpose() * &null).cholesky()?;
    let off_null = |v: &DVector<f64>| v - &null * gram.solve(&(null.transpose() * v));
    let pivoted = DVector::from_fn(m, |i, _| b[order[i]]);
    let consistent = off_null(&pivoted);
    let mut y1 = consistent.rows(0, r).into_owned();
    if !l1.solve_lower_triangular_mut(&mut y1)
        || !l1.transpose().solve_upper_triangular_mut(&mut y1)
    {
        return None;
    }
    let mut y = DVector::zeros(m);
    y.rows_mut(0, r).copy_from(&y1);
    let x = off_null(&y);
    if !x.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut out = DVector::zeros(m);
    for (i, &row) in order.iter().enumerate() {
        out[row] = x[i];
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric semidefinite matrix `G G^T` of rank `rank` with rows
    /// that repeat, and a right side with a part outside its range.
    fn repeated_rows(m: usize, rank: usize, seed: u64) -> (DMatrix<f64>, DVector<f64>) {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let g = DMatrix::from_fn(m, rank, |_, _| next());
        let mut a = &g * g.transpose();
        // Scale the rows apart as the Schur complement's are (forces and
        // positions in one system).
        for i in 0..m {
            let s = 10f64.powi((i % 4) as i32 - 2);
            a.row_mut(i).scale_mut(s);
            a.column_mut(i).scale_mut(s);
        }
        let b = DVector::from_fn(m, |_, _| next());
        (a, b)
    }

    #[test]
    fn the_pivoted_cholesky_is_the_pseudo_inverse() {
        for (m, rank, seed) in [(6, 4, 1), (20, 17, 2), (31, 29, 3), (12, 1, 4), (8, 7, 5)] {
            let (a, b) = repeated_rows(m, rank, seed);
            assert!(a.clone().cholesky().is_none() || rank == m);
            let fast = semidefinite_solve(&a, &b).expect("semidefinite");
            let mut slow = b.clone();
            assert!(pseudo_inverse_solve_in_place(&mut a.clone(), &mut slow));
            let error = (&fast - &slow).norm() / slow.norm();
            assert!(error < 1e-8, "m {m} rank {rank}: {error:e}");
        }
    }

    #[test]
    fn a_regular_indefinite_or_unsymmetric_matrix_is_solved_exactly() {
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 0.0, 1.0, -3.0, 0.5, 0.0, 0.5, 1e-3]);
        let x = DVector::from_row_slice(&[1.0, -2.0, 3.0]);
        let mut b = &a * &x;
        assert!(solve_symmetric_in_place(&mut a.clone(), &mut b));
        assert!((&b - &x).norm() < 1e-12 * x.norm());
        let u = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 0.0, 0.3, -3.0, 0.5, 0.0, 0.7, 1e-3]);
        let mut b = &u * &x;
        assert!(solve_general_in_place(&mut u.clone(), &mut b));
        assert!((&b - &x).norm() < 1e-12 * x.norm());
    }

    #[test]
    fn a_singular_unsymmetric_matrix_gets_the_pseudo_inverse() {
        // Rank 2 to round-off (a contact held twice): LU with partial
        // pivoting divides by round-off there.
        let g = DMatrix::from_row_slice(3, 2, &[0.1, 0.7, 0.3, -0.2, 0.9, 0.35]);
        let h = DMatrix::from_row_slice(3, 2, &[0.3, 0.1, -0.6, 0.8, 0.45, 0.2]);
        let a = &g * h.transpose();
        let b = DVector::from_row_slice(&[1.0, 1.0, 2.0]);
        let expected = a.clone().pseudo_inverse(1e-12).unwrap() * &b;
        let mut fast = b.clone();
        assert!(solve_general_in_place(&mut a.clone(), &mut fast));
        assert!((&fast - &expected).norm() < 1e-10 * expected.norm());
        let partial = a.clone().lu().solve(&b);
        assert!(partial.is_none_or(|x| (x - &expected).norm() > expected.norm()));
    }

    #[test]
    fn an_unsymmetric_matrix_marked_symmetric_is_solved_as_it_is() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.0, 0.5, 3.0, 0.2, 0.0, 0.7, 2.0]);
        let x = DVector::from_row_slice(&[1.0, -2.0, 3.0]);
        let mut b = &a * &x;
        assert!(solve_symmetric_in_place(&mut a.clone(), &mut b));
        assert!((&b - &x).norm() < 1e-12 * x.norm());
    }

    #[test]
    fn an_indefinite_matrix_is_solved_as_a_general_one() {
        let a = DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0]);
        assert!(semidefinite_solve(&a, &DVector::from_element(3, 1.0)).is_none());
        let mut b = DVector::from_element(3, 1.0);
        assert!(solve_symmetric_in_place(&mut a.clone(), &mut b));
        assert!((b - DVector::from_row_slice(&[1.0, 0.0, -1.0])).norm() < 1e-12);
    }
}
