//! Where a backward pass puts what it finds ([`Sink`]), and the change the smoother
//! makes to each state's variance in the classic coordinates.
//!
//! The smoothed σ of an epoch is its forward σ with the change added: the smoothed
//! variance minus the forward one, both read from their covariances by the same
//! operations at the same velocity. Without a measurement ahead the two covariances
//! are the same bits, the change is zero, and the smoothed σ is the forward σ exactly;
//! since `Ps ≤ P` the change is never positive, whatever map to the classic coordinates
//! reads them. Inside a covariance step the change is interpolated linearly in time
//! between the two closes around the epoch (`docs/reference/smoother.md`, "With a covariance
//! step"), so the smoothed σ stays below the forward one however the forward pass read
//! its own σ there.

use super::forward::Forward;
use crate::attitude::skew;
use crate::ekf::{variance_between, FilterConfig, Point, ATT, POS, VEL};
use nalgebra::{Matrix3, SMatrix, SVector};

/// Where a backward pass puts what it finds at each epoch: the smoothed error of the
/// forward solution there, σ where it is wanted, the smoothed covariance at the nodes
/// (each epoch's error once, in no set order). [`super::smoothed::Smoothed`] keeps the smoothed
/// solution at every epoch; a Monte Carlo run reduces it to its metrics as the pass
/// goes (`crate::run`), without a copy of the forward solution.
pub trait Sink {
    /// Remove the smoothed error `ds` from the forward solution at epoch `i` (the
    /// filter's feedback, [`crate::ekf::correct`]).
    fn apply<const N: usize>(&mut self, i: usize, ds: &SVector<f64, N>, cfg: &FilterConfig);
    /// σ at epoch `i`: the forward σ there with each state's variance changed by
    /// `change` (the smoothed variance minus the forward one, classic coordinates; the
    /// calibration states' past the first 15).
    fn set_change<const N: usize>(
        &mut self,
        i: usize,
        change: &SVector<f64, N>,
        forward: &Forward<'_>,
    );
    /// The smoothed covariance at a node's epoch.
    fn keep_node<const N: usize>(&mut self, epoch: usize, ps: &SMatrix<f64, N, N>);

    /// σ at epoch `i` inside a covariance step, a fraction `w` of the way in time from
    /// the close before it (the change `from` there, after its updates) to the one
    /// after (`to`, before its updates): the change linear in time between the two.
    fn set_sigma_between<const N: usize>(
        &mut self,
        i: usize,
        (from, to, w): (&SVector<f64, N>, &SVector<f64, N>, f64),
        forward: &Forward<'_>,
    ) {
        let between = SVector::<f64, N>::from_fn(|j, _| variance_between(from[j], to[j], w));
        self.set_change(i, &between, forward);
    }
}

/// The variance of each state `j` (classic coordinates at the point `at`) of the
/// covariance `ps` in the filter's coordinates: `(U P Uᵀ)_jj`, with `U = I + S` at
/// (velocity, attitude) in the invariant formulations (`S = [v̂×]`) and at (position,
/// attitude) in SE₂(3) (`[p̂×]`): `P_jj + 2 (S P_aj)_r + (S P_aa Sᵀ)_rr`.
pub(crate) fn classic_variances<'a, const N: usize>(
    ps: &'a SMatrix<f64, N, N>,
    at: &Point,
) -> impl Fn(usize) -> f64 + 'a {
    let shears = shears(at);
    move |j| {
        let mut v = ps[(j, j)];
        for (rows, s) in shears.iter().flatten() {
            if (*rows..*rows + 3).contains(&j) {
                let r = j - rows;
                for k in 0..3 {
                    v += 2.0 * s[(r, k)] * ps[(j, ATT + k)];
                    for l in 0..3 {
                        v += s[(r, k)] * s[(r, l)] * ps[(ATT + k, ATT + l)];
                    }
                }
            }
        }
        v
    }
}

/// The blocks `(rows, S)` of the map to the classic coordinates at `at`: `[v̂×]` at the
/// velocity rows in the invariant formulations, `[p̂×]` at the position rows in SE₂(3).
fn shears(at: &Point) -> [Option<(usize, Matrix3<f64>)>; 2] {
    let f = at.formulation;
    [
        f.velocity_invariant().then(|| (VEL, skew(&at.vel))),
        f.position_invariant().then(|| (POS, skew(&at.disp))),
    ]
}

/// The change of each state's variance (classic coordinates at the point `at`) from
/// the forward covariance `p` to the smoothed one `ps` (both in the filter's
/// coordinates): [`classic_variances`] of the two, subtracted. Zero, bit for bit, where
/// they are the same bits.
pub(crate) fn change<const N: usize>(
    ps: &SMatrix<f64, N, N>,
    p: &SMatrix<f64, N, N>,
    at: &Point,
) -> SVector<f64, N> {
    let (smoothed, filtered) = (classic_variances(ps, at), classic_variances(p, at));
    SVector::<f64, N>::from_fn(|j, _| smoothed(j) - filtered(j))
}

/// The change of each state's variance (as [`change`]) of `Ps = P + P Λ P` from `P`:
/// `diag(U P Λ P Uᵀ)` with `U` the map to the classic coordinates at `at`, read
/// directly (no `Ps` formed).
pub(crate) fn change_of<const N: usize>(
    p: &SMatrix<f64, N, N>,
    lambda: &SMatrix<f64, N, N>,
    at: &Point,
) -> SVector<f64, N> {
    let up = classic_rows(at, p);
    let upl = up * lambda;
    SVector::<f64, N>::from_fn(|j, _| upl.row(j).dot(&up.row(j)))
}

/// A forward σ with its variance changed by `change` (a negative variance read as
/// zero): `√(σ² + change)`, `σ` itself where the change is zero.
pub(crate) fn changed_sigma(sigma: f64, change: f64) -> f64 {
    (sigma * sigma + change).max(0.0).sqrt()
}

/// `U P`, the rows of a covariance in the filter's coordinates mapped to the classic
/// ones at `at` (`U = I + [v̂×]` at (velocity, attitude) in the invariant formulations,
/// and `+ [p̂×]` at (position, attitude) in SE₂(3); `I` in the classic one).
fn classic_rows<const N: usize>(at: &Point, p: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let mut up = *p;
    let att = up.fixed_rows::<3>(ATT).into_owned();
    for (rows, s) in shears(at).into_iter().flatten() {
        let mut block = up.fixed_rows_mut::<3>(rows);
        block += s * att;
    }
    up
}
