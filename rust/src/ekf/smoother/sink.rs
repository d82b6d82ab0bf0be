//! Where a backward pass puts what it finds ([`Sink`]), and σ from a smoothed
//! covariance in the classic coordinates.

use super::{classic_rows, classic_variance, Forward};
use crate::attitude::skew;
use crate::ekf::{FilterConfig, Formulation, ATT, VEL};
use crate::mechanization::NavState;
use nalgebra::{SMatrix, SVector, Vector3};

/// Where a backward pass puts what it finds at each epoch: the smoothed error of the
/// forward solution there, σ where it is wanted, the smoothed covariance at the nodes
/// (each epoch's error once, in no set order). [`super::Smoothed`] keeps the smoothed
/// solution at every epoch; a Monte Carlo run reduces it to its metrics as the pass
/// goes (`crate::run`), without a copy of the forward solution.
pub trait Sink {
    /// Remove the smoothed error `ds` from the forward solution at epoch `i` (the
    /// filter's feedback, [`crate::ekf::correct`]).
    fn apply<const N: usize>(&mut self, i: usize, ds: &SVector<f64, N>, cfg: &FilterConfig);
    /// σ at epoch `i` from the smoothed covariance `ps` (see `classic_variances`).
    fn set_sigma<const N: usize>(
        &mut self,
        i: usize,
        ps: &SMatrix<f64, N, N>,
        cfg: &FilterConfig,
        forward: &Forward<'_>,
    );
    /// σ at epoch `i` of `Ps = P + P Λ P` (see `classic_variances_of`).
    fn set_sigma_of<const N: usize>(
        &mut self,
        i: usize,
        p: &SMatrix<f64, N, N>,
        lambda: &SMatrix<f64, N, N>,
        cfg: &FilterConfig,
        forward: &Forward<'_>,
    );
    /// σ at epoch `i` inside a covariance step, a fraction `w` of the way in time from
    /// the close before it (smoothed covariance `from`) to the one after (`to`): see
    /// `between_variances`.
    fn set_sigma_between<const N: usize>(
        &mut self,
        i: usize,
        between: (&SMatrix<f64, N, N>, &SMatrix<f64, N, N>, f64),
        cfg: &FilterConfig,
        forward: &Forward<'_>,
    );
    /// The smoothed covariance at a node's epoch.
    fn keep_node<const N: usize>(&mut self, epoch: usize, ps: &SMatrix<f64, N, N>);
}

/// The variance of each state `j` (classic coordinates at the velocity `vel`) of the
/// covariance `ps` in the filter's coordinates: `(U P Uᵀ)_jj`, with `U = I + S` at
/// (velocity, attitude) in the invariant formulation (`S = [v̂×]`):
/// `P_jj + 2 (S P_aj)_r + (S P_aa Sᵀ)_rr`.
pub(crate) fn classic_variances<'a, const N: usize>(
    ps: &'a SMatrix<f64, N, N>,
    cfg: &FilterConfig,
    vel: &Vector3<f64>,
) -> impl Fn(usize) -> f64 + 'a {
    let invariant = cfg.formulation == Formulation::Invariant;
    let s = skew(vel);
    move |j| {
        let mut v = ps[(j, j)];
        if invariant && (VEL..VEL + 3).contains(&j) {
            let r = j - VEL;
            for k in 0..3 {
                v += 2.0 * s[(r, k)] * ps[(j, ATT + k)];
                for l in 0..3 {
                    v += s[(r, k)] * s[(r, l)] * ps[(ATT + k, ATT + l)];
                }
            }
        }
        v
    }
}

/// The variance of each state (as [`classic_variances`]) of the covariance linear in
/// time between two closes, a fraction `w` of the way from `from` to `to`, mapped at
/// the velocity `vel` of the epoch between them: `(1 − w) (U P_from Uᵀ)_jj + w (U P_to
/// Uᵀ)_jj` (`docs/filter.md`, "With a covariance step").
pub(crate) fn between_variances<'a, const N: usize>(
    (from, to, w): (&'a SMatrix<f64, N, N>, &'a SMatrix<f64, N, N>, f64),
    cfg: &FilterConfig,
    vel: &Vector3<f64>,
) -> impl Fn(usize) -> f64 + 'a {
    let (a, b) = (
        classic_variances(from, cfg, vel),
        classic_variances(to, cfg, vel),
    );
    move |j| (1.0 - w) * a(j) + w * b(j)
}

/// The variance of each state (as [`classic_variances`]) of `Ps = P + P Λ P`, its
/// diagonal alone: `diag(U P Uᵀ) + diag(U P Λ P Uᵀ)` with `U` the map to the classic
/// coordinates at `nav`'s velocity.
pub(crate) fn classic_variances_of<'a, const N: usize>(
    p: &SMatrix<f64, N, N>,
    lambda: &SMatrix<f64, N, N>,
    cfg: &'a FilterConfig,
    nav: &'a NavState,
) -> impl Fn(usize) -> f64 + 'a {
    let up = classic_rows(cfg, nav, p);
    let upl = up * lambda;
    move |j| classic_variance(cfg, nav, &up, j) + upl.row(j).dot(&up.row(j))
}

/// The 15 σ from each state's variance (a negative one read as zero).
pub(crate) fn sigma15(variance: &impl Fn(usize) -> f64) -> [f64; 15] {
    std::array::from_fn(|j| variance(j).max(0.0).sqrt())
}
