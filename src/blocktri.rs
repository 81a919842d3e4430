//! Block-tridiagonal matrices of 3x3 blocks and their O(n) factorisation.
//!
//! The Jacobian of a rod chain couples node `j` only with `j - 1` and `j + 1`.
//! Block Gaussian elimination without pivoting between blocks (block Thomas)
//! costs about 150 flops a node; it is safe here because the Jacobian is nearly
//! symmetric and positive definite at stable equilibria, and a singular pivot is
//! reported so that the caller can damp.

use nalgebra::{Matrix3, Vector3};

/// `diag[j]` is block `(j, j)`, `upper[j]` block `(j, j+1)`, `lower[j]` block `(j+1, j)`.
#[derive(Debug, Clone)]
pub struct BlockTridiagonal {
    pub diag: Vec<Matrix3<f64>>,
    pub upper: Vec<Matrix3<f64>>,
    pub lower: Vec<Matrix3<f64>>,
}

impl BlockTridiagonal {
    pub fn zeros(n: usize) -> Self {
        BlockTridiagonal {
            diag: vec![Matrix3::zeros(); n],
            upper: vec![Matrix3::zeros(); n.saturating_sub(1)],
            lower: vec![Matrix3::zeros(); n.saturating_sub(1)],
        }
    }

    /// [`BlockTridiagonal::zeros`] for a large n: fallible and interruptible.
    pub fn try_zeros(n: usize) -> crate::Result<Self> {
        let zeros = |len| crate::interrupt::filled(len, Matrix3::zeros(), "Jacobian");
        Ok(BlockTridiagonal {
            diag: zeros(n)?,
            upper: zeros(n.saturating_sub(1))?,
            lower: zeros(n.saturating_sub(1))?,
        })
    }

    pub fn n(&self) -> usize {
        self.diag.len()
    }

    /// `y = A x`.
    pub fn mul_vec(&self, x: &[Vector3<f64>], y: &mut [Vector3<f64>]) {
        let n = self.n();
        for j in 0..n {
            let mut s = self.diag[j] * x[j];
            if j + 1 < n {
                s += self.upper[j] * x[j + 1];
            }
            if j > 0 {
                s += self.lower[j - 1] * x[j - 1];
            }
            y[j] = s;
        }
    }

    /// Visit every stored entry as `(row, column, value)` of the full `3n x 3n`
    /// matrix (to copy it into a dense or sparse matrix of another library).
    pub fn for_each_entry(&self, mut visit: impl FnMut(usize, usize, f64)) {
        let n = self.n();
        let mut block = |bi: usize, bj: usize, m: &Matrix3<f64>| {
            for r in 0..3 {
                for c in 0..3 {
                    visit(3 * bi + r, 3 * bj + c, m[(r, c)]);
                }
            }
        };
        for j in 0..n {
            block(j, j, &self.diag[j]);
            if j + 1 < n {
                block(j, j + 1, &self.upper[j]);
                block(j + 1, j, &self.lower[j]);
            }
        }
    }

    /// Largest absolute diagonal entry (a scale for damping).
    pub fn max_diagonal(&self) -> f64 {
        self.diag
            .iter()
            .map(|d| d[(0, 0)].abs().max(d[(1, 1)].abs()).max(d[(2, 2)].abs()))
            .fold(0.0, f64::max)
    }
}

/// A block LU factorisation, reusable across iterations without allocation.
#[derive(Debug, Clone)]
pub struct BlockLu {
    /// Inverses of the pivot blocks `C_j`.
    inv_pivot: Vec<Matrix3<f64>>,
    /// `C_j^{-1} U_j`, for back substitution.
    coupling: Vec<Matrix3<f64>>,
    lower: Vec<Matrix3<f64>>,
    /// The diagonal and upper blocks factored, and whether the factors are
    /// those of the matrix itself (unshifted, complete): see
    /// [`BlockLu::is_factor_of`].
    diag: Vec<Matrix3<f64>>,
    upper: Vec<Matrix3<f64>>,
    plain: bool,
    /// The multiple of the identity added to the matrix factored.
    shift: f64,
}

/// A pivot block was (numerically) singular.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingularPivot(pub usize);

impl BlockLu {
    pub fn new(n: usize) -> Self {
        BlockLu {
            inv_pivot: vec![Matrix3::zeros(); n],
            coupling: vec![Matrix3::zeros(); n.saturating_sub(1)],
            lower: vec![Matrix3::zeros(); n.saturating_sub(1)],
            diag: vec![Matrix3::zeros(); n],
            upper: vec![Matrix3::zeros(); n.saturating_sub(1)],
            plain: false,
            shift: 0.0,
        }
    }

    /// [`BlockLu::new`] for a large n: fallible and interruptible.
    pub fn try_new(n: usize) -> crate::Result<Self> {
        let zeros = |len| crate::interrupt::filled(len, Matrix3::zeros(), "factorisation");
        Ok(BlockLu {
            inv_pivot: zeros(n)?,
            coupling: zeros(n.saturating_sub(1))?,
            lower: zeros(n.saturating_sub(1))?,
            diag: zeros(n)?,
            upper: zeros(n.saturating_sub(1))?,
            plain: false,
            shift: 0.0,
        })
    }

    /// The multiple of the identity the last [`BlockLu::factor`] added (a
    /// damped step's): a solve of the same system in another form adds it too.
    pub fn shift(&self) -> f64 {
        self.shift
    }

    /// Whether this is the unshifted factorisation of `a` as `a` is now
    /// (every block equal to the one factored): a caller that needs `a`'s
    /// factors may skip factoring it again.
    pub fn is_factor_of(&self, a: &BlockTridiagonal) -> bool {
        self.plain && self.diag == a.diag && self.upper == a.upper && self.lower == a.lower
    }

    /// Factor `A + shift I`.
    pub fn factor(&mut self, a: &BlockTridiagonal, shift: f64) -> Result<(), SingularPivot> {
        let n = a.n();
        self.plain = false;
        self.shift = shift;
        let scale = a.max_diagonal().max(shift.abs()).max(f64::MIN_POSITIVE);
        let mut pivot = a.diag[0] + Matrix3::identity() * shift;
        for j in 0..n {
            // A huge n takes long here: an interrupt fails the factorisation,
            // and the solver's loops stop on the same flag.
            if j % crate::interrupt::POLL_STRIDE == 0 && j > 0 && crate::interrupt::requested() {
                return Err(SingularPivot(j));
            }
            if j > 0 {
                pivot =
                    a.diag[j] + Matrix3::identity() * shift - a.lower[j - 1] * self.coupling[j - 1];
            }
            let inv = invert_checked(&pivot, scale).ok_or(SingularPivot(j))?;
            self.inv_pivot[j] = inv;
            self.diag[j] = a.diag[j];
            if j + 1 < n {
                self.coupling[j] = inv * a.upper[j];
                self.lower[j] = a.lower[j];
                self.upper[j] = a.upper[j];
            }
        }
        self.plain = shift == 0.0;
        Ok(())
    }

    /// Factor the symmetric part `S = (A + A^T) / 2` of `a` (as [`factor`]
    /// does `A`) and count the negative eigenvalues of `S`: by Sylvester's law
    /// of inertia, those of its block pivots. One pass, no allocation. None if
    /// a pivot is (numerically) singular: no inertia, no factorisation.
    ///
    /// [`factor`]: BlockLu::factor
    pub fn factor_symmetric_part(&mut self, a: &BlockTridiagonal) -> Option<usize> {
        let n = a.n();
        self.plain = false;
        self.shift = 0.0;
        let sym = |m: Matrix3<f64>| 0.5 * (m + m.transpose());
        let scale = a.max_diagonal().max(f64::MIN_POSITIVE);
        let mut negative = 0;
        for j in 0..n {
            if j % crate::interrupt::POLL_STRIDE == 0 && j > 0 && crate::interrupt::requested() {
                return None;
            }
            let mut pivot = sym(a.diag[j]);
            if j > 0 {
                pivot -= self.lower[j - 1] * self.coupling[j - 1];
            }
            let pivot = sym(pivot);
            negative += negative_count(&pivot, 1e-12 * scale)?;
            let inv = invert_checked(&pivot, scale)?;
            self.inv_pivot[j] = inv;
            if j + 1 < n {
                let upper = 0.5 * (a.upper[j] + a.lower[j].transpose());
                self.coupling[j] = inv * upper;
                self.lower[j] = upper.transpose();
            }
        }
        Some(negative)
    }

    /// Solve `(A + shift I) x = b` in place.
    pub fn solve_in_place(&self, b: &mut [Vector3<f64>]) {
        let n = b.len();
        b[0] = self.inv_pivot[0] * b[0];
        for j in 1..n {
            let r = b[j] - self.lower[j - 1] * b[j - 1];
            b[j] = self.inv_pivot[j] * r;
        }
        for j in (0..n.saturating_sub(1)).rev() {
            let r = self.coupling[j] * b[j + 1];
            b[j] -= r;
        }
    }

    /// Solve `(A + shift I)^T x = b` in place: the adjoint of
    /// [`BlockLu::solve_in_place`], a few rows of `A^{-1}` (a tip's
    /// sensitivity to many parameters) for as many solves as rows. With
    /// `A = L U`, `L` block lower bidiagonal (pivots `C_j`, the matrix's lower
    /// blocks) and `U` unit upper (`C_j^{-1} U_j`): `U^T z = b` forward, then
    /// `L^T x = z` backward.
    pub fn solve_transposed_in_place(&self, b: &mut [Vector3<f64>]) {
        let n = b.len();
        for j in 1..n {
            let r = self.coupling[j - 1].transpose() * b[j - 1];
            b[j] -= r;
        }
        if n == 0 {
            return;
        }
        b[n - 1] = self.inv_pivot[n - 1].transpose() * b[n - 1];
        for j in (0..n - 1).rev() {
            let r = b[j] - self.lower[j].transpose() * b[j + 1];
            b[j] = self.inv_pivot[j].transpose() * r;
        }
    }

    /// Solve `(A + shift I) x = b` in place for each of `columns` (all of
    /// one length), block by block for all at once: each block of the
    /// factors is read once, and the columns' recurrences, independent,
    /// overlap (one column's is a chain of dependent 3 x 3 products).
    pub fn solve_columns_in_place(&self, columns: &mut [Vec<Vector3<f64>>]) {
        let Some(n) = columns.first().map(Vec::len) else {
            return;
        };
        if n == 0 {
            return;
        }
        for b in columns.iter_mut() {
            b[0] = self.inv_pivot[0] * b[0];
        }
        for j in 1..n {
            let (lower, inv_pivot) = (self.lower[j - 1], self.inv_pivot[j]);
            for b in columns.iter_mut() {
                let r = b[j] - lower * b[j - 1];
                b[j] = inv_pivot * r;
            }
        }
        for j in (0..n - 1).rev() {
            let coupling = self.coupling[j];
            for b in columns.iter_mut() {
                let r = coupling * b[j + 1];
                b[j] -= r;
            }
        }
    }
}

/// Inverse of a 3x3 block, refused when the block is numerically singular: its
/// smallest singular value (bounded below by `1 / |inv|_F`) is negligible
/// against `scale`, the largest diagonal entry of the matrix. The pivots of a
/// rod chain legitimately fall to `scale / n` toward a free tip (the discrete
/// Laplacian), so the test is on one singular value, not on the determinant,
/// which is the product of three such small values at large n.
fn invert_checked(m: &Matrix3<f64>, scale: f64) -> Option<Matrix3<f64>> {
    let inv = m.try_inverse()?;
    let norm = inv.norm();
    if !norm.is_finite() || norm * scale >= SINGULAR_PIVOT {
        return None;
    }
    Some(inv)
}

/// Number of negative eigenvalues of a symmetric 3x3 matrix, None if one is
/// within `tiny` of zero. A positive definite one (the usual pivot of a
/// stable rod) is told by its Cholesky factor at a fraction of the cost of
/// an eigensolver, which was a tenth of a held rod's solve at n = 1e6.
fn negative_count(m: &Matrix3<f64>, tiny: f64) -> Option<usize> {
    if let Some(ch) = m.cholesky() {
        let l = ch.l_dirty();
        if (0..3).all(|d| l[(d, d)] * l[(d, d)] > tiny) {
            return Some(0);
        }
    }
    let eig = m.symmetric_eigenvalues();
    if eig.iter().any(|v| v.abs() <= tiny) {
        return None;
    }
    Some(eig.iter().filter(|v| **v < 0.0).count())
}

/// A pivot block whose inverse exceeds `SINGULAR_PIVOT / scale` is singular.
/// Round-off in a Schur-complement pivot is about `1e-16 scale`; 1e-12 leaves
/// four digits above it and admits the `scale / n` pivots of n up to 1e11.
const SINGULAR_PIVOT: f64 = 1e12;

/// Whether the symmetric part of `a` is positive definite, by block Cholesky
/// (Sylvester's law of inertia: it is iff every Schur-complement pivot is).
pub fn symmetric_part_is_positive_definite(a: &BlockTridiagonal) -> bool {
    let n = a.n();
    let sym = |m: Matrix3<f64>| 0.5 * (m + m.transpose());
    let mut prev_inv = Matrix3::zeros();
    let mut prev_off = Matrix3::zeros();
    let scale = a.max_diagonal().max(f64::MIN_POSITIVE);
    for j in 0..n {
        // Interrupted: no verdict, and the caller's loops stop on the flag.
        if j % crate::interrupt::POLL_STRIDE == 0 && j > 0 && crate::interrupt::requested() {
            return false;
        }
        let mut pivot = sym(a.diag[j]);
        if j > 0 {
            pivot -= prev_off.transpose() * prev_inv * prev_off;
        }
        let pivot = sym(pivot);
        // A pivot that is positive but negligible is a singular (neutral) direction.
        match pivot.cholesky() {
            Some(ch) => {
                let l = ch.l();
                if (0..3).any(|d| l[(d, d)] * l[(d, d)] <= 1e-12 * scale) {
                    return false;
                }
                prev_inv = ch.inverse();
            }
            None => return false,
        }
        if j + 1 < n {
            prev_off = 0.5 * (a.upper[j] + a.lower[j].transpose());
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_factorisation_knows_the_matrix_it_factored() {
        let mut a = sample(6);
        let mut lu = BlockLu::new(6);
        assert!(!lu.is_factor_of(&a), "nothing factored yet");
        lu.factor(&a, 0.0).unwrap();
        assert!(lu.is_factor_of(&a));
        // Any block changed since, a shifted or a symmetric-part factorisation: not a's.
        for change in 0..3 {
            let mut b = a.clone();
            match change {
                0 => b.diag[5][(2, 2)] += 1e-15,
                1 => b.upper[0][(0, 1)] += 1e-15,
                _ => b.lower[4][(1, 0)] += 1e-15,
            }
            assert!(!lu.is_factor_of(&b), "change {change}");
        }
        lu.factor(&a, 1e-3).unwrap();
        assert!(!lu.is_factor_of(&a));
        lu.factor(&a, 0.0).unwrap();
        lu.factor_symmetric_part(&a).unwrap();
        assert!(!lu.is_factor_of(&a));
        a.diag[0] = Matrix3::zeros();
        assert!(lu.factor(&a, 0.0).is_err());
        assert!(!lu.is_factor_of(&a), "a failed factorisation is of nothing");
    }

    fn sample(n: usize) -> BlockTridiagonal {
        let mut a = BlockTridiagonal::zeros(n);
        for j in 0..n {
            let t = j as f64;
            a.diag[j] = Matrix3::new(4.0 + t, 0.3, -0.2, 0.1, 5.0, 0.4, -0.3, 0.2, 6.0 - 0.1 * t);
            if j + 1 < n {
                a.upper[j] = Matrix3::new(-1.0, 0.2, 0.0, 0.1, -1.2, 0.3, 0.0, 0.2, -0.9);
                a.lower[j] = Matrix3::new(-0.8, 0.0, 0.1, 0.3, -1.1, 0.0, 0.2, 0.1, -1.3);
            }
        }
        a
    }

    #[test]
    fn solve_inverts_multiply() {
        let n = 7;
        let a = sample(n);
        let x: Vec<Vector3<f64>> = (0..n)
            .map(|j| Vector3::new(j as f64, 1.0 - j as f64, 0.5 * j as f64 * j as f64))
            .collect();
        let mut b = vec![Vector3::zeros(); n];
        a.mul_vec(&x, &mut b);
        let mut lu = BlockLu::new(n);
        lu.factor(&a, 0.0).unwrap();
        lu.solve_in_place(&mut b);
        for j in 0..n {
            assert!(
                (b[j] - x[j]).norm() < 1e-12,
                "{j}: {:?} vs {:?}",
                b[j],
                x[j]
            );
        }
    }

    #[test]
    fn columns_solved_together_are_each_solved() {
        let n = 9;
        let mut lu = BlockLu::new(n);
        lu.factor(&sample(n), 0.3).unwrap();
        let columns: Vec<Vec<Vector3<f64>>> = (0..5)
            .map(|c| {
                (0..n)
                    .map(|j| Vector3::new((c + j) as f64, 1.0 - (c * j) as f64, 0.1 * c as f64))
                    .collect()
            })
            .collect();
        let mut together = columns.clone();
        lu.solve_columns_in_place(&mut together);
        for (mut one, both) in columns.into_iter().zip(&together) {
            lu.solve_in_place(&mut one);
            assert_eq!(&one, both);
        }
    }

    #[test]
    fn the_transposed_solve_solves_the_transpose() {
        // x^T A y = (A^T x)^T y for the solves of A^T x = b and A y = c: b^T y = x^T c.
        let n = 7;
        let mut lu = BlockLu::new(n);
        lu.factor(&sample(n), 0.2).unwrap();
        let b: Vec<Vector3<f64>> = (0..n)
            .map(|j| Vector3::new(j as f64, 1.0, -0.5 * j as f64))
            .collect();
        let c: Vec<Vector3<f64>> = (0..n)
            .map(|j| Vector3::new(1.0, (j * j) as f64 * 0.1, 2.0 - j as f64))
            .collect();
        let (mut x, mut y) = (b.clone(), c.clone());
        lu.solve_transposed_in_place(&mut x);
        lu.solve_in_place(&mut y);
        let by: f64 = b.iter().zip(&y).map(|(p, q)| p.dot(q)).sum();
        let xc: f64 = x.iter().zip(&c).map(|(p, q)| p.dot(q)).sum();
        assert!((by - xc).abs() <= 1e-12 * by.abs().max(1.0), "{by} {xc}");
        // And the plain solve is not its own transpose here (the test can fail).
        let mut z = b.clone();
        lu.solve_in_place(&mut z);
        let zc: f64 = z.iter().zip(&c).map(|(p, q)| p.dot(q)).sum();
        assert!((zc - xc).abs() > 1e-6 * xc.abs());
    }

    #[test]
    fn the_symmetric_part_is_factored_with_its_inertia() {
        // Against the dense symmetric part: its eigenvalues and its solve.
        let n = 6;
        let mut a = sample(n);
        a.diag[2] = -a.diag[2];
        a.diag[4] *= -0.5;
        let mut dense = nalgebra::DMatrix::<f64>::zeros(3 * n, 3 * n);
        for j in 0..n {
            dense.view_mut((3 * j, 3 * j), (3, 3)).copy_from(&a.diag[j]);
            if j + 1 < n {
                dense
                    .view_mut((3 * j, 3 * j + 3), (3, 3))
                    .copy_from(&a.upper[j]);
                dense
                    .view_mut((3 * j + 3, 3 * j), (3, 3))
                    .copy_from(&a.lower[j]);
            }
        }
        let sym = 0.5 * (&dense + dense.transpose());
        let negative = sym
            .clone()
            .symmetric_eigenvalues()
            .iter()
            .filter(|v| **v < 0.0)
            .count();
        assert_eq!(negative, 6);
        let mut lu = BlockLu::new(n);
        assert_eq!(lu.factor_symmetric_part(&a), Some(negative));
        let b = nalgebra::DVector::from_fn(3 * n, |i, _| (i as f64).sin());
        let mut x: Vec<Vector3<f64>> = (0..n).map(|j| b.fixed_rows::<3>(3 * j).into()).collect();
        lu.solve_in_place(&mut x);
        let x = nalgebra::DVector::from_iterator(3 * n, x.iter().flat_map(|v| v.iter().copied()));
        assert!((sym * x - b).amax() < 1e-12);
    }

    #[test]
    fn negative_counts_match_the_eigenvalues() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for k in 0..300 {
            let a = Matrix3::from_fn(|_, _| next());
            // Positive definite, indefinite and negative definite cases.
            let m = a * a.transpose() + Matrix3::identity() * (0.5 - (k % 3) as f64 * 0.4);
            let eig = m.symmetric_eigenvalues();
            let expected = eig.iter().filter(|v| **v < 0.0).count();
            assert_eq!(negative_count(&m, 1e-12), Some(expected), "{m}");
        }
        let singular = Matrix3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 2.0);
        assert_eq!(negative_count(&singular, 1e-12), None);
    }

    #[test]
    fn definiteness() {
        let mut a = sample(5);
        assert!(symmetric_part_is_positive_definite(&a));
        a.diag[3] = -a.diag[3];
        assert!(!symmetric_part_is_positive_definite(&a));
    }
}
