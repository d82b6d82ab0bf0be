//! The transition matrix of a covariance step, `Φ = I + F ΔT + ½ (F ΔT)²` with the bias
//! rows of the identity, and `P ← Φ P Φᵀ` with it (`docs/reference/filter.md`, "Covariance
//! step"). Φ's navigation rows are kept as 15 columns padded to 12 rows, three 4-lane
//! vectors, so that every column operation vectorizes whole.

use super::state::{Matrix15, NAV};
use multiversion::multiversion;
use nalgebra::SMatrix;

/// The navigation rows (0..9) padded to 12, so that a column is three 4-lane vectors.
const PAD: usize = 12;

/// `acc += x·c` over a padded column (no FMA: the same bits on every CPU).
#[inline(always)]
fn axpy(acc: &mut [f64; PAD], x: &[f64; PAD], c: f64) {
    for (a, x) in acc.iter_mut().zip(x) {
        *a += x * c;
    }
}

/// A transition matrix whose bias rows are those of the identity,
/// `Φ = [[Φ_nn, Φ_nb], [0, I]]`, kept as the 15 columns of its 9 navigation rows
/// (each padded with zeros to 12 rows).
#[derive(Clone, Debug)]
pub struct Transition {
    cols: [[f64; PAD]; 15],
    /// The time it spans \[s\] (the DVL error states' decay over it).
    pub(crate) dt: f64,
}

impl Transition {
    /// `Φ = I + F Δt + ½ (F Δt)²` from the navigation rows `fd` of `F Δt` (its bias rows
    /// are zero). F² has zero bias rows too: its navigation rows are `F_nn (F Δt)_nav`,
    /// so column j of Φ's navigation rows is `(F Δt)[:, j] + ½ Σ_k (F Δt)[:, k] (F Δt)[k, j]`
    /// over the nine navigation columns k.
    #[inline(always)]
    pub(crate) fn second_order(fd: &SMatrix<f64, NAV, 15>) -> Self {
        let mut f = [[0.0; PAD]; 15];
        for (k, col) in f.iter_mut().enumerate() {
            col[..NAV].copy_from_slice(&fd.as_slice()[NAV * k..NAV * k + NAV]);
        }
        let mut cols = f;
        for (j, col) in cols.iter_mut().enumerate() {
            for (fk, c) in f.iter().zip(&f[j][..NAV]) {
                axpy(col, fk, 0.5 * c);
            }
            if j < NAV {
                col[j] += 1.0;
            }
        }
        Self { cols, dt: 0.0 }
    }

    /// The same transition, spanning `dt` seconds.
    #[inline(always)]
    pub(crate) fn spanning(self, dt: f64) -> Self {
        Self { dt, ..self }
    }

    /// `P ← Φ P Φᵀ` with the bias rows of Φ those of the identity: `Z = W P` for the
    /// navigation rows `W` (9×15) of Φ, column by column (P is symmetric, so its
    /// column j is its row j); then the navigation block is `Z Wᵀ` (written
    /// symmetrized), the navigation-bias block `Z[:, 9..15]`, and the bias block stays.
    /// The noise of a covariance step is added around it (see `super::interval`). An
    /// AVX2 copy is chosen at run time where the CPU has it (no FMA: the same bits
    /// either way).
    pub(crate) fn propagate(&self, p: &mut Matrix15) {
        propagate(self, p)
    }

    #[inline(always)]
    fn propagate_portable(&self, p: &mut Matrix15) {
        let w = &self.cols;
        let mut z = [[0.0; PAD]; 15];
        for (j, zj) in z.iter_mut().enumerate() {
            let pj = &p.as_slice()[15 * j..15 * j + 15];
            for (wk, c) in w.iter().zip(pj) {
                axpy(zj, wk, *c);
            }
        }
        let mut nav = [[0.0; PAD]; NAV];
        for (j, nj) in nav.iter_mut().enumerate() {
            for (zk, wk) in z.iter().zip(w) {
                axpy(nj, zk, wk[j]);
            }
        }
        let s = p.as_mut_slice(); // column-major
        for j in 0..NAV {
            for i in 0..NAV {
                s[15 * j + i] = 0.5 * (nav[j][i] + nav[i][j]);
            }
        }
        for j in NAV..15 {
            for i in 0..NAV {
                s[15 * j + i] = z[j][i];
                s[15 * i + j] = z[j][i];
            }
        }
    }

    /// `X ← Φ X` for the 15 rows of `X` (a cross-covariance with other states).
    pub(crate) fn apply<const C: usize>(&self, x: &mut SMatrix<f64, 15, C>) {
        for c in 0..C {
            let mut acc = [0.0; PAD];
            for (k, wk) in self.cols.iter().enumerate() {
                axpy(&mut acc, wk, x[(k, c)]);
            }
            for i in 0..NAV {
                x[(i, c)] = acc[i];
            }
        }
    }

    /// The navigation rows of Φ, `[Φ_nn, Φ_nb]` (9 × 15; its other rows are the
    /// identity's).
    pub(crate) fn nav_rows(&self) -> SMatrix<f64, NAV, 15> {
        SMatrix::<f64, NAV, 15>::from_fn(|i, k| self.cols[k][i])
    }

    /// The dense 15×15 Φ.
    #[cfg(test)]
    pub(crate) fn dense(&self) -> Matrix15 {
        let mut phi = Matrix15::identity();
        for (k, col) in self.cols.iter().enumerate() {
            for i in 0..NAV {
                phi[(i, k)] = col[i];
            }
        }
        phi
    }
}

/// [`Transition::propagate`]'s kernel, with an AVX2 copy chosen at run time where the
/// CPU has it (`multiversion`, which does not take `self`).
#[multiversion(targets("x86_64+avx2"))]
fn propagate(phi: &Transition, p: &mut Matrix15) {
    phi.propagate_portable(p)
}
