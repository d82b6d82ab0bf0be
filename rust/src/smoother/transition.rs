//! The transition between two closes of the forward pass, as the backward pass carries
//! `μ ← Φᵀ μ` and `Λ ← Φᵀ Λ Φ` through it ([`Step`]): one IMU sample's `Φ = I + F Δt`
//! through the sparse F ([`Sample`]), or a covariance step's
//! `Φ = I + F ΔT + ½(F ΔT)²` through its nine navigation rows ([`NavRows`]). With the DVL
//! calibration states (`N` = 19) their rows of F are zero and the navigation rows do
//! not read them: every product goes through the first 15.

use crate::ekf::calibration::{CalibrationConfig, BIAS, N_CALIBRATED};
use crate::ekf::dynamics::ErrorDynamics;
use crate::ekf::{FilterConfig, Matrix15};
use multiversion::multiversion;
use nalgebra::{SMatrix, SVector};

/// How the backward pass goes back through a transition `Φ` over `N` states.
pub(crate) trait Step<const N: usize> {
    /// Whether every epoch closes: no epoch lies between two closes, so nothing is
    /// interpolated (one IMU sample's Φ).
    const EVERY_EPOCH: bool;
    /// `Φᵀ x`.
    fn transposed(&self, x: &SVector<f64, N>) -> SVector<f64, N>;
    /// `Φᵀ Λ Φ` of a symmetric Λ, symmetric.
    fn congruence(&self, lambda: &mut SMatrix<f64, N, N>);
    /// `K ← K Φ`: a product of transitions carried instead of Λ over closes where Λ is
    /// not read (`Kᵀ Λ K` where it is next read).
    fn accumulate(&self, k: &mut SMatrix<f64, N, N>);
    /// The smoothed error after the step from the one before it `ds` and `μ` after it,
    /// without the covariance: `Φ δs + Q μ` (the Bryson–Frazier form, `Q` the noise the
    /// filter added after `Φ`), where the step carries its `Q`; None where not.
    fn next_mean(&self, ds: &SVector<f64, N>, mu: &SVector<f64, N>) -> Option<SVector<f64, N>>;
}

/// The navigation rows of a covariance step's Φ (9 × 15; its other rows are the
/// identity's).
pub(crate) type NavRows = SMatrix<f64, 9, 15>;

impl<const N: usize> Step<N> for NavRows {
    const EVERY_EPOCH: bool = false;

    fn transposed(&self, x: &SVector<f64, N>) -> SVector<f64, N> {
        transposed(self, x)
    }

    fn congruence(&self, lambda: &mut SMatrix<f64, N, N>) {
        *lambda = congruence(self, lambda);
    }

    fn accumulate(&self, k: &mut SMatrix<f64, N, N>) {
        times_phi_in_place(self, k);
    }

    fn next_mean(&self, _: &SVector<f64, N>, _: &SVector<f64, N>) -> Option<SVector<f64, N>> {
        None // a close always carries its covariance
    }
}

/// One IMU sample's transition `Φ = I + F Δt`: its error dynamics and step \[s\], and
/// where the backward pass takes the mean alone, the discrete noise `Q` the filter added
/// after it.
#[derive(Clone, Debug)]
pub(crate) struct Sample {
    pub(crate) dynamics: ErrorDynamics,
    pub(crate) dt: f64,
    pub(crate) q: Option<Matrix15>,
}

impl<const N: usize> Step<N> for Sample {
    const EVERY_EPOCH: bool = true;

    fn transposed(&self, x: &SVector<f64, N>) -> SVector<f64, N> {
        transposed_step(&self.dynamics, self.dt, x)
    }

    fn congruence(&self, lambda: &mut SMatrix<f64, N, N>) {
        congruence_sparse(&self.dynamics, self.dt, lambda);
    }

    /// Through Φ's navigation rows `[I 0] + F Δt` as a covariance step's are (whole
    /// columns of K combined).
    fn accumulate(&self, k: &mut SMatrix<f64, N, N>) {
        let mut rows = self.dynamics.nav_rows() * self.dt;
        for i in 0..9 {
            rows[(i, i)] += 1.0;
        }
        times_phi_in_place(&rows, k);
    }

    fn next_mean(&self, ds: &SVector<f64, N>, mu: &SVector<f64, N>) -> Option<SVector<f64, N>> {
        let q_mu = self.q.as_ref()? * mu.fixed_rows::<15>(0);
        let f = self.dynamics.apply(&ds.as_slice()[..15]);
        let mut next = *ds;
        for (r, v) in f.iter().enumerate() {
            next[r] += self.dt * v;
        }
        for (r, v) in q_mu.iter().enumerate() {
            next[r] += v;
        }
        Some(next)
    }
}

/// `Φᵀ x` for a step `Φ = I + F Δt`: `x + Δt Fᵀ x` (F's navigation rows alone read).
fn transposed_step<const N: usize>(
    dynamics: &ErrorDynamics,
    dt: f64,
    x: &SVector<f64, N>,
) -> SVector<f64, N> {
    let ft = dynamics.apply_transposed(&x.as_slice()[..15]);
    let mut out = *x;
    for (o, v) in out.iter_mut().zip(ft) {
        *o += dt * v;
    }
    out
}

/// `Λ ← Φᵀ Λ Φ = Λ + Δt (W + Wᵀ) + Δt² Fᵀ Wᵀ` with `W = Fᵀ Λ` (Λ symmetric), each
/// product column by column through the sparse F: about 2 × 60 multiply-adds per
/// column instead of a dense 9 × 15 product's 135.
fn congruence_sparse<const N: usize>(
    dynamics: &ErrorDynamics,
    dt: f64,
    lambda: &mut SMatrix<f64, N, N>,
) {
    let mut w = SMatrix::<f64, 15, N>::zeros();
    for c in 0..N {
        let col = dynamics.apply_transposed(&lambda.as_slice()[N * c..N * c + 15]);
        w.column_mut(c).copy_from_slice(&col);
    }
    // Column c of Fᵀ Wᵀ is Fᵀ times row c of W; Fᵀ Λ F is its transpose.
    let mut z = SMatrix::<f64, 15, 15>::zeros();
    for c in 0..15 {
        let row: [f64; 15] = std::array::from_fn(|k| w[(c, k)]);
        z.column_mut(c)
            .copy_from_slice(&dynamics.apply_transposed(&row));
    }
    for c in 0..N {
        for r in 0..15 {
            let v = dt * w[(r, c)];
            lambda[(r, c)] += v;
            lambda[(c, r)] += v;
        }
    }
    let dt2 = dt * dt;
    for c in 0..15 {
        for r in 0..15 {
            lambda[(r, c)] += dt2 * z[(c, r)];
        }
    }
}

/// `Φᵀ x` for `Φ = [[R], [0, I]]` (`R` its navigation rows, 9 × 15): entry `j` is
/// `Σ_k R_kj x_k` over the 9 navigation rows, plus `x_j` past them (summed in this
/// order, as nalgebra's product does: the same bits as `Rᵀ x` plus the identity).
fn transposed<const N: usize>(rows: &NavRows, x: &SVector<f64, N>) -> SVector<f64, N> {
    let mut out = *x;
    for j in 0..15 {
        let mut v = 0.0;
        for k in 0..9 {
            v += rows[(k, j)] * x[k];
        }
        out[j] = if j < 9 { v } else { x[j] + v };
    }
    out
}

/// `B Φ` (see [`transposed`]): column `j < 15` is `Σ_k R_kj B_{:,k}` over the 9
/// navigation columns, plus `B_{:,j}` past them; column by column over contiguous
/// columns (9 × 15 × N multiply-adds), summed in [`transposed`]'s order.
fn times_phi<const N: usize>(rows: &NavRows, b: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let mut out = *b;
    times_phi_in_place(rows, &mut out);
    out
}

/// `B ← B Φ` ([`times_phi`] in place: a product carried at every IMU sample moves no
/// matrix).
/// An AVX2 copy is chosen at run time where the CPU has it (`multiversion`; the same
/// products and sums, no fused multiply-add).
#[multiversion(targets("x86_64+avx2"))]
fn times_phi_in_place<const N: usize>(rows: &NavRows, b: &mut SMatrix<f64, N, N>) {
    times_phi_portable(rows, b)
}

/// Column `j` of `B Φ` reads B's nine navigation columns (kept aside: they are
/// overwritten first) and, past them, B's column `j` itself (not yet overwritten).
#[inline(always)]
fn times_phi_portable<const N: usize>(rows: &NavRows, b: &mut SMatrix<f64, N, N>) {
    let mut nav = [[0.0; N]; 9];
    for (k, col) in nav.iter_mut().enumerate() {
        col.copy_from_slice(&b.as_slice()[N * k..N * (k + 1)]);
    }
    let dst = b.as_mut_slice();
    for j in 0..15 {
        let mut col = [0.0; N];
        for (k, src) in nav.iter().enumerate() {
            let r = rows[(k, j)];
            for (c, s) in col.iter_mut().zip(src) {
                *c += r * s;
            }
        }
        if j >= 9 {
            for (c, s) in col.iter_mut().zip(&dst[N * j..N * (j + 1)]) {
                *c += s;
            }
        }
        dst[N * j..N * (j + 1)].copy_from_slice(&col);
    }
}

/// `Φᵀ Λ Φ` for a symmetric Λ: `W = Λ Φ`, then `Wᵀ Φ = (Φᵀ W)ᵀ`, symmetrized. Each
/// entry is the sum of the same products in the same order as the dense
/// `Φᵀ (Φᵀ Λ)ᵀ` (Λ is symmetric bit for bit), so the result is too.
fn congruence<const N: usize>(rows: &NavRows, lambda: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let w = times_phi(rows, lambda);
    symmetric(&times_phi(rows, &w.transpose()))
}

/// `(M + Mᵀ) / 2`.
pub(super) fn symmetric<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (m + m.transpose()) * 0.5
}

/// The DVL's correlated velocity error's part of a transition over `Δt`: its three
/// states decay by `e = exp(−Δt/τ)` (`Φ = Φ̃ D`, `D = diag(1, …, e, e, e)`, with `Φ̃`
/// the identity on the DVL error states as the [`Step`]s take it) and gain the noise
/// `σ_b² (1 − e²)` (`ekf::calibration`). Nothing without the correlated error, or
/// over 15 states.
#[derive(Clone, Copy)]
pub(super) struct Decay {
    model: Option<CalibrationConfig>,
}

impl Decay {
    pub(super) fn of<const N: usize>(cfg: &FilterConfig) -> Self {
        let model = (cfg.dvl_calibration).filter(|c| N == N_CALIBRATED && c.correlated());
        Self { model }
    }

    /// `e` over `dt` seconds, None without the correlated error.
    pub(super) fn factor(&self, dt: f64) -> Option<f64> {
        self.model.map(|c| c.decay(dt))
    }

    /// `μ ← D μ`: after `Φ̃ᵀ μ`, the rest of `Φᵀ μ`.
    pub(super) fn mean<const N: usize>(&self, dt: f64, mu: &mut SVector<f64, N>) {
        if let Some(e) = self.factor(dt) {
            for i in BIAS..BIAS + 3 {
                mu[i] *= e;
            }
        }
    }

    /// `Λ ← D Λ D`: after `Φ̃ᵀ Λ Φ̃`, the rest of `Φᵀ Λ Φ`.
    pub(super) fn congruence<const N: usize>(&self, dt: f64, lambda: &mut SMatrix<f64, N, N>) {
        if let Some(e) = self.factor(dt) {
            for i in BIAS..BIAS + 3 {
                lambda.row_mut(i).scale_mut(e);
                lambda.column_mut(i).scale_mut(e);
            }
        }
    }

    /// `K ← K D`: after `K Φ̃`, the rest of `K Φ`.
    pub(super) fn accumulate<const N: usize>(&self, dt: f64, k: &mut SMatrix<f64, N, N>) {
        if let Some(e) = self.factor(dt) {
            for i in BIAS..BIAS + 3 {
                k.column_mut(i).scale_mut(e);
            }
        }
    }

    /// The correlated error's part of the Bryson–Frazier mean `Φ δs + Q μ`, which a
    /// [`Step::next_mean`] leaves at `δs`: `e δs + σ_b² (1 − e²) μ`.
    pub(super) fn next_mean<const N: usize>(
        &self,
        dt: f64,
        mu: &SVector<f64, N>,
        next: &mut SVector<f64, N>,
    ) {
        if let (Some(c), Some(e)) = (self.model, self.factor(dt)) {
            for (k, i) in (BIAS..BIAS + 3).enumerate() {
                let q = c.bias_sigma[k].powi(2) * (1.0 - e * e);
                next[i] = e * next[i] + q * mu[i];
            }
        }
    }
}
