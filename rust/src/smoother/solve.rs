//! The solves at an update of the backward pass: `μ` and `Λ` from the covariance before
//! the update, by its Cholesky factor.

use super::transition::symmetric;
use multiversion::multiversion;
use nalgebra::{SMatrix, SVector};

/// `μ = (P⁻)⁻¹ δs⁻` and `Λ = (P⁻)⁻¹ (Ps − P⁻) (P⁻)⁻¹` at an update, by Cholesky
/// solves over the states that are not held fixed (None: `P⁻` not positive definite
/// on them): `Mᵀ = ((P⁻)⁻¹ D)ᵀ` from `D = Ps − P⁻`,
/// then `Λᵀ = ((P⁻)⁻¹ Mᵀ)ᵀ` from `M`, each by [`solve_rows`].
///
/// An AVX2 copy is chosen at run time where the CPU has it (`multiversion`; the same
/// operations, no fused multiply-add).
#[multiversion(targets("x86_64+avx2"))]
pub(super) fn at_update<const N: usize>(
    p_prior: &SMatrix<f64, N, N>,
    ps: &SMatrix<f64, N, N>,
    ds_prior: &SVector<f64, N>,
) -> Option<(SVector<f64, N>, SMatrix<f64, N, N>)> {
    at_update_portable(p_prior, ps, ds_prior)
}

#[inline(always)]
fn at_update_portable<const N: usize>(
    p_prior: &SMatrix<f64, N, N>,
    ps: &SMatrix<f64, N, N>,
    ds_prior: &SVector<f64, N>,
) -> Option<(SVector<f64, N>, SMatrix<f64, N, N>)> {
    // A state held fixed (a DVL error state whose σ is 0: its row and column of P⁻
    // are zero) takes no part: it is solved as if its variance were 1, which leaves
    // the others' solution as it is (P⁻ is block diagonal), and its μ and Λ are 0.
    let held: [bool; N] = std::array::from_fn(|i| p_prior.column(i).iter().all(|v| *v == 0.0));
    let mut p = *p_prior;
    for i in (0..N).filter(|&i| held[i]) {
        p[(i, i)] = 1.0;
    }
    let chol = p.cholesky()?;
    let l = chol.l_dirty();
    let mt = solve_rows(l, &(ps - p_prior));
    let mut lambda = symmetric(&solve_rows(l, &mt.transpose()));
    let mut mu = chol.solve(ds_prior);
    for i in (0..N).filter(|&i| held[i]) {
        mu[i] = 0.0;
        lambda.row_mut(i).fill(0.0);
        lambda.column_mut(i).fill(0.0);
    }
    Some((mu, lambda))
}

/// `(P⁻¹ B)ᵀ` for `P = L Lᵀ` (`l`'s lower triangle), given `Bᵀ`: the forward and back
/// substitutions row by row of `B`, each row a contiguous column of `Bᵀ`, so that every
/// step is one multiply-add over `N` columns at once.
#[inline(always)]
fn solve_rows<const N: usize>(
    l: &SMatrix<f64, N, N>,
    bt: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    let mut t = *bt;
    let s = t.as_mut_slice();
    let mut substitute = |i: usize, others: std::ops::Range<usize>, lower: bool| {
        let mut col = [0.0; N];
        col.copy_from_slice(&s[N * i..N * (i + 1)]);
        for k in others {
            let f = if lower { l[(i, k)] } else { l[(k, i)] };
            for (c, v) in col.iter_mut().zip(&s[N * k..N * (k + 1)]) {
                *c -= f * v;
            }
        }
        let d = l[(i, i)];
        for c in col.iter_mut() {
            *c /= d;
        }
        s[N * i..N * (i + 1)].copy_from_slice(&col);
    };
    // L Y = B, then Lᵀ X = Y, rows of Y and X in place of those of B.
    for i in 0..N {
        substitute(i, 0..i, true);
    }
    for i in (0..N).rev() {
        substitute(i, i + 1..N, false);
    }
    t
}
