//! The Joseph-form covariance update on a measurement's support: the same algebra as
//! the dense `P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ`, with the products that meet H
//! taken over H's non-zero columns only.
//!
//! A sensor's rows read few states (a DVL: velocity, attitude and, with a lever arm,
//! the gyro biases; a depth or a fix component: one position state), so `P Hᵀ` and
//! `H P` cost `R·|J|·N` for the support `J` instead of `R·N²`, and the Joseph form is
//! written `B = P − K (H P)`, `P ← B + (K R − B Hᵀ) Kᵀ`: two rank-`R` products of
//! `R·N²` each instead of two `N³` ones. The result is the dense form's to rounding
//! (tested against it to 1e-12 relative); `docs/reference/filter.md`, "The update".

use nalgebra::SMatrix;

/// The columns of `h` with a non-zero entry, in increasing order: the first `n` of
/// the array.
pub(super) struct Support<const N: usize> {
    columns: [usize; N],
    n: usize,
}

impl<const N: usize> Support<N> {
    pub(super) fn of<const R: usize>(h: &SMatrix<f64, R, N>) -> Self {
        let mut columns = [0; N];
        let mut n = 0;
        for (j, column) in h.column_iter().enumerate() {
            if column.iter().any(|&x| x != 0.0) {
                columns[n] = j;
                n += 1;
            }
        }
        Self { columns, n }
    }

    fn columns(&self) -> &[usize] {
        &self.columns[..self.n]
    }

    /// `A Hᵀ` for any `A` with `N` columns (`P Hᵀ`, `B Hᵀ`), over the support.
    pub(super) fn times_transpose<const R: usize>(
        &self,
        a: &SMatrix<f64, N, N>,
        h: &SMatrix<f64, R, N>,
    ) -> SMatrix<f64, N, R> {
        let mut out = SMatrix::<f64, N, R>::zeros();
        for k in 0..R {
            let mut column = out.column_mut(k);
            for &j in self.columns() {
                column.axpy(h[(k, j)], &a.column(j), 1.0);
            }
        }
        out
    }

    /// `H A` for any `A` with `N` rows, over the support.
    pub(super) fn left_times<const R: usize, const C: usize>(
        &self,
        h: &SMatrix<f64, R, N>,
        a: &SMatrix<f64, N, C>,
    ) -> SMatrix<f64, R, C> {
        let mut out = SMatrix::<f64, R, C>::zeros();
        for c in 0..C {
            for &j in self.columns() {
                let x = a[(j, c)];
                for k in 0..R {
                    out[(k, c)] += h[(k, j)] * x;
                }
            }
        }
        out
    }

    /// `A ← (I − K H) A (I − K H)ᵀ + K R Kᵀ` (no `K R Kᵀ` when `r` is None: the
    /// sensitivity of the covariance), symmetrized, for a symmetric `A` whose `A Hᵀ`
    /// is `aht` (so that `H A` is its transpose).
    pub(super) fn joseph<const R: usize>(
        &self,
        a: &mut SMatrix<f64, N, N>,
        aht: &SMatrix<f64, N, R>,
        gain: &SMatrix<f64, N, R>,
        h: &SMatrix<f64, R, N>,
        r: Option<&SMatrix<f64, R, R>>,
    ) {
        debug_assert!(
            *a == a.transpose(),
            "the Joseph update of a non-symmetric matrix"
        );
        let b = *a - gain * aht.transpose();
        let bht = self.times_transpose(&b, h);
        let left = match r {
            Some(r) => gain * r - bht,
            None => -bht,
        };
        *a = b + left * gain.transpose();
        *a = (*a + a.transpose()) * 0.5;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{SMatrix, Vector3};

    /// A symmetric positive definite `N × N` matrix with entries of mixed scale.
    fn covariance<const N: usize>(seed: u64) -> SMatrix<f64, N, N> {
        let mut x = seed;
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a = SMatrix::<f64, N, N>::from_fn(|i, j| next() * 10f64.powi((i + j) as i32 % 5 - 2));
        let p = a * a.transpose() + SMatrix::<f64, N, N>::identity() * 1e-3;
        (p + p.transpose()) * 0.5
    }

    fn dense<const N: usize, const R: usize>(
        p: &SMatrix<f64, N, N>,
        gain: &SMatrix<f64, N, R>,
        h: &SMatrix<f64, R, N>,
        r: &SMatrix<f64, R, R>,
    ) -> SMatrix<f64, N, N> {
        let ikh = SMatrix::<f64, N, N>::identity() - gain * h;
        let out = ikh * p * ikh.transpose() + gain * r * gain.transpose();
        (out + out.transpose()) * 0.5
    }

    fn relative<const N: usize>(a: &SMatrix<f64, N, N>, b: &SMatrix<f64, N, N>) -> f64 {
        (a - b).amax() / b.amax()
    }

    /// A DVL-shaped row block (velocity, attitude and gyro-bias columns) and a
    /// one-state row, on 15 and 19 states: the support's update is the dense one's to
    /// 1e-12 relative, and so are `P Hᵀ` and `H P Hᵀ`.
    #[test]
    fn the_support_gives_the_dense_update() {
        fn check<const N: usize>(seed: u64) {
            let p = covariance::<N>(seed);
            let mut h = SMatrix::<f64, 3, N>::zeros();
            for k in 0..3 {
                for j in [3, 4, 5, 6, 7, 8, 12, 13, 14] {
                    h[(k, j)] = ((k * 7 + j * 3) % 5) as f64 - 2.0;
                }
                if N > 15 {
                    h[(k, N - 1)] = 0.3;
                }
            }
            let r = SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::new(1e-4, 2e-4, 4e-4));
            let support = Support::of(&h);
            let pht = support.times_transpose(&p, &h);
            assert!((pht - p * h.transpose()).amax() <= 1e-12 * (p * h.transpose()).amax());
            let s = support.left_times(&h, &pht) + r;
            let dense_s = h * p * h.transpose() + r;
            assert!((s - dense_s).amax() <= 1e-12 * dense_s.amax());
            let gain = pht * s.try_inverse().unwrap();
            let mut sparse = p;
            support.joseph(&mut sparse, &pht, &gain, &h, Some(&r));
            assert!(relative(&sparse, &dense(&p, &gain, &h, &r)) <= 1e-12);
            assert_eq!(sparse, sparse.transpose());
            // A scalar row reading state 2 (a depth).
            let mut e = SMatrix::<f64, 1, N>::zeros();
            e[2] = 1.0;
            let r1 = SMatrix::<f64, 1, 1>::new(0.01);
            let unit = Support::of(&e);
            assert_eq!(unit.columns(), &[2]);
            let pe = unit.times_transpose(&p, &e);
            assert_eq!(pe.column(0), p.column(2));
            let k = pe / (p[(2, 2)] + 0.01);
            let mut sparse = p;
            unit.joseph(&mut sparse, &pe, &k, &e, Some(&r1));
            assert!(relative(&sparse, &dense(&p, &k, &e, &r1)) <= 1e-12);
            // Without R (the sensitivity's update).
            let mut m = p;
            support.joseph(&mut m, &pht, &gain, &h, None);
            let zero = SMatrix::<f64, 3, 3>::zeros();
            assert!(relative(&m, &dense(&p, &gain, &h, &zero)) <= 1e-12);
        }
        for seed in 1..20 {
            check::<15>(seed);
            check::<19>(seed);
        }
    }

    #[test]
    fn an_all_zero_block_reads_nothing() {
        let h = SMatrix::<f64, 3, 15>::zeros();
        let support = Support::of(&h);
        assert!(support.columns().is_empty());
        let p = covariance::<15>(3);
        let mut after = p;
        let zero = SMatrix::<f64, 15, 3>::zeros();
        support.joseph(&mut after, &zero, &zero, &h, None);
        assert_eq!(after, p);
    }
}
