//! A general band matrix and its LU factorisation with partial pivoting
//! (LAPACK's `dgbtf2`/`dgbtrs`, unblocked): the mixed form of the KKT step
//! (`solver/mixed.rs`) is banded but indefinite, and a block elimination
//! without pivoting would meet singular diagonal blocks (a contact's normal
//! along its element). O(N kl (kl + ku)) to factor, O(N (2 kl + ku)) to solve.

/// An `N x N` matrix with `kl` sub- and `ku` superdiagonals, stored by
/// columns with `kl` more superdiagonals for the fill-in of the row
/// exchanges: entry `(i, j)` at `data[(kl + ku + i - j) + j * stride]`.
#[derive(Debug, Clone, Default)]
pub(crate) struct BandLu {
    size: usize,
    kl: usize,
    ku: usize,
    data: Vec<f64>,
    pivots: Vec<usize>,
}

impl BandLu {
    /// A zero `size x size` matrix of these bandwidths (the buffers kept).
    pub fn reset(&mut self, size: usize, kl: usize, ku: usize) {
        self.size = size;
        self.kl = kl;
        self.ku = ku;
        let len = self.stride() * size;
        self.data.clear();
        self.data.resize(len, 0.0);
        self.pivots.clear();
        self.pivots.resize(size, 0);
    }

    fn stride(&self) -> usize {
        2 * self.kl + self.ku + 1
    }

    fn at(&self, i: usize, j: usize) -> usize {
        self.kl + self.ku + i - j + j * self.stride()
    }

    /// `A[i, j] += value`; `(i, j)` inside the band.
    pub fn add(&mut self, i: usize, j: usize, value: f64) {
        debug_assert!(
            i <= j + self.kl && j <= i + self.ku,
            "({i}, {j}) outside the band"
        );
        let at = self.at(i, j);
        self.data[at] += value;
    }

    /// Factor in place; `false` at an exactly singular or non-finite pivot.
    pub fn factor(&mut self) -> bool {
        let (n, kl, ku) = (self.size, self.kl, self.ku);
        let stride = self.stride();
        let kv = kl + ku;
        // The last column that row exchanges have reached.
        let mut reach = 0usize;
        for j in 0..n {
            let below = kl.min(n - 1 - j);
            let column = j * stride + kv;
            let mut pivot = 0;
            let mut largest = self.data[column].abs();
            for r in 1..=below {
                let v = self.data[column + r].abs();
                if v > largest {
                    largest = v;
                    pivot = r;
                }
            }
            self.pivots[j] = j + pivot;
            if largest == 0.0 || !largest.is_finite() {
                return false;
            }
            reach = reach.max((j + ku + pivot).min(n - 1));
            if pivot != 0 {
                for c in j..=reach {
                    let a = self.at(j, c);
                    let b = self.at(j + pivot, c);
                    self.data.swap(a, b);
                }
            }
            let inverse = 1.0 / self.data[column];
            for r in 1..=below {
                self.data[column + r] *= inverse;
            }
            for c in j + 1..=reach {
                let top = self.at(j, c);
                let factor = self.data[top];
                if factor == 0.0 {
                    continue;
                }
                // Rows j + 1..=j + below of column c follow its row j.
                for r in 1..=below {
                    let l = self.data[column + r];
                    self.data[top + r] -= l * factor;
                }
            }
        }
        true
    }

    /// `b = A^{-1} b` from the factors.
    pub fn solve(&self, b: &mut [f64]) {
        let (n, kl) = (self.size, self.kl);
        let stride = self.stride();
        let kv = kl + self.ku;
        for j in 0..n {
            let p = self.pivots[j];
            if p != j {
                b.swap(j, p);
            }
            let below = kl.min(n - 1 - j);
            let x = b[j];
            if x != 0.0 {
                let column = j * stride + kv;
                for r in 1..=below {
                    b[j + r] -= self.data[column + r] * x;
                }
            }
        }
        for j in (0..n).rev() {
            let column = j * stride + kv;
            b[j] /= self.data[column];
            let x = b[j];
            if x != 0.0 {
                for r in 1..=kv.min(j) {
                    b[j - r] -= self.data[column - r] * x;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::BandLu;
    use nalgebra::{DMatrix, DVector};

    /// A band matrix whose leading entries vanish (pivoting is needed)
    /// against nalgebra's dense LU.
    #[test]
    fn band_lu_solves_as_the_dense_lu() {
        for (size, kl, ku) in [(1, 0, 0), (7, 2, 1), (12, 3, 3), (20, 1, 4), (9, 5, 2)] {
            let entry = |i: usize, j: usize| {
                if i > j + kl || j > i + ku || (i == j && i % 3 == 0) {
                    0.0
                } else {
                    ((i * 7 + j * 13) % 11) as f64 - 5.0 + if i == j { 0.5 } else { 0.0 }
                }
            };
            let dense = DMatrix::from_fn(size, size, entry);
            let b = DVector::from_fn(size, |i, _| (i as f64 * 0.37).sin());
            let Some(expected) = dense.clone().lu().solve(&b) else {
                continue;
            };
            let mut band = BandLu::default();
            band.reset(size, kl, ku);
            for i in 0..size {
                for j in 0..size {
                    if entry(i, j) != 0.0 {
                        band.add(i, j, entry(i, j));
                    }
                }
            }
            assert!(band.factor());
            let mut x = b.as_slice().to_vec();
            band.solve(&mut x);
            let error = (DVector::from_vec(x) - &expected).amax();
            assert!(
                error <= 1e-10 * expected.amax().max(1.0),
                "{size} {kl} {ku}: {error}"
            );
        }
    }

    #[test]
    fn a_singular_band_matrix_is_refused() {
        let mut band = BandLu::default();
        band.reset(3, 1, 1);
        band.add(0, 0, 1.0);
        band.add(1, 0, 1.0);
        band.add(0, 1, 1.0);
        band.add(1, 1, 1.0);
        band.add(2, 2, 1.0);
        assert!(!band.factor());
    }
}
