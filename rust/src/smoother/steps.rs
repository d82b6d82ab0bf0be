//! The backward pass over a covariance step ([`FilterConfig::covariance_step`]).
//!
//! With a covariance step the forward filter has a covariance only where a step closes
//! (when due, before every update, at the last epoch): those closes are the smoother's
//! grid, and each step's `Φ = I + F ΔT + ½(F ΔT)²` is the transition between two of
//! them. The backward pass rebuilds the closes between two nodes by the filter's own
//! prediction (bit for bit, as the every-sample pass does; a node inside a step
//! carries the step's sums, so the rebuild resumes it), then runs the RTS recursion
//! from close to close (`c` the earlier close, `d` the next), chained between updates
//! as [`smooth_steps`] says:
//!
//! ```text
//! A_c  = P⁺_c Φ_dᵀ (P⁻_d)⁻¹                 (Cholesky solves, no inverse)
//! δs_c = A_c (δs_d + δx̂_d)
//! Ps_c = P⁺_c + A_c (Ps_d − P⁻_d) A_cᵀ
//! ```
//!
//! with `δx̂_d` the error estimate fed back at `d` (zero where no update was). Between
//! two closes the filter has no covariance: the smoothed error of the forward solution
//! there is interpolated linearly in time between `δs_c` (after `c`'s updates) and
//! `δs⁻_d = δs_d + δx̂_d` (before `d`'s), and its variance linearly in time between
//! the smoothed ones at `c` and at `d` (the smoothed covariance is the same before and
//! after `d`'s updates), as the forward σ is interpolated.

use super::forward::{Covariances, Forward};
use super::kept::KeptCloses;
use super::node::{full_p, lift, restart, Node};
use super::sink::change;
use super::sink::Sink;
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::{Ekf, FilterConfig, Transition};
use crate::error::{Error, Result};
use crate::mechanization::{step_with_rates, FrameRates, ImuSample};
use nalgebra::{SMatrix, SVector, Vector3};

/// The navigation rows of a step's Φ (9 × 15; its other rows are the identity's).
type NavRows = SMatrix<f64, 9, 15>;

/// A close of the covariance step, rebuilt: its epoch, the navigation rows of the
/// step's Φ and the covariance it left (before the epoch's updates), over `N` states,
/// and the forward velocity \[m/s, NED\] at its epoch before the updates there and
/// after them: σ is read at the one the forward σ was (the covariance the close left
/// before the updates, the one after them after).
pub(crate) struct Close<const N: usize> {
    pub(crate) epoch: usize,
    pub(crate) phi: NavRows,
    pub(crate) p_prior: SMatrix<f64, N, N>,
    pub(crate) vel_prior: Vector3<f64>,
    pub(crate) vel: Vector3<f64>,
}

impl<const N: usize> Close<N> {
    /// The close `ekf` just made at `epoch` with the transition `phi`, the forward
    /// velocity there before the epoch's updates and after them `(vel_prior, vel)`.
    pub(super) fn of(
        ekf: &Ekf,
        epoch: usize,
        phi: &Transition,
        (vel_prior, vel): (Vector3<f64>, Vector3<f64>),
    ) -> Self {
        Self {
            epoch,
            phi: phi.nav_rows(),
            p_prior: full_p::<N>(ekf),
            vel_prior,
            vel,
        }
    }
}

/// The backward pass of [`super::smooth`] over `N` states under a covariance step,
/// chained as at every sample (see [`super::every`]): between two closes with updates
/// `P⁺ = P⁻` and `δx̂ = 0`, so `μ ← Φᵀ μ` and `Λ ← Φᵀ Λ Φ` carry `(P⁻_u)⁻¹ δs⁻_u` and
/// `(P⁻_u)⁻¹ (Ps_u − P⁻_u) (P⁻_u)⁻¹` of the next update `u` back, `δs_c = P_c μ` and
/// `Ps_c = P_c + P_c Λ P_c`; only at the nodes a Cholesky factor of `P⁻` is solved
/// with.
#[allow(clippy::too_many_arguments)]
pub(super) fn smooth_steps<const N: usize, S: Sink>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    kept: Option<&KeptCloses>,
    covariances: Covariances<'_>,
    out: &mut S,
    cancel: &Cancel,
) -> Result<()> {
    let wanted = |i: usize| match covariances {
        Covariances::Every => true,
        Covariances::Where(f) => f(i),
    };
    // After the last epoch nothing is left to learn: μ = 0, Λ = 0.
    let mut mu = SVector::<f64, N>::zeros();
    let mut lambda = SMatrix::<f64, N, N>::zeros();
    // The next close (the interpolation's far end).
    let mut later: Option<Later<N>> = None;
    for pair in nodes.windows(2).rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        let closes = match kept {
            Some(kept) => kept_between::<N>(forward, kept, a, b),
            None => rebuild::<N>(forward, cfg, a, b, cancel)?,
        };
        for (k, close) in closes.iter().enumerate().rev() {
            let at_node = close.epoch == b.epoch;
            let p = if at_node { b.p::<N>() } else { close.p_prior };
            let ds = p * mu;
            // Ps where it is read: at the nodes and where σ is wanted between the close
            // before and the next one (σ there is interpolated between the two).
            let end = later.as_ref().map_or(close.epoch + 1, |l| l.epoch);
            let since = previous_close(&closes, k, a);
            let (before, after) = (
                since.is_none_or(|s| (s + 1..close.epoch).any(wanted)),
                (close.epoch..end).any(wanted),
            );
            let at = AtClose::read(close, (&p, &lambda), (at_node, before, after), cfg);
            let near = at.near.as_ref();
            fill(
                out,
                forward,
                cfg,
                (close.epoch, &ds, near),
                later.as_ref(),
                &wanted,
            );
            if let (true, Some(ps)) = (at_node, at.ps.as_ref()) {
                out.keep_node(b.epoch, ps);
            }
            later = Some(at.back_through(close, (b, at_node), &ds, (&mut mu, &mut lambda))?);
        }
    }
    // The first epoch: the prior, a close of its own.
    let p = nodes[0].p::<N>();
    let (ds, ps) = (p * mu, symmetric(&(p + p * lambda * p)));
    let near = change(&ps, &p, cfg, &forward.nav[0].vel);
    fill(
        out,
        forward,
        cfg,
        (0, &ds, Some(&near)),
        later.as_ref(),
        &wanted,
    );
    out.keep_node(0, &ps);
    Ok(())
}

/// What a backward pass reads at a close: the smoothed covariance `Ps = P + P Λ P`
/// (`P` the forward one after the close's updates) where it is read, and the change
/// the smoother makes to each state's variance there (see [`super::sink`]) where σ is
/// wanted in the steps around it. Each change is read at the forward velocity the
/// forward σ it changes was read at: `near` after the updates (from `P`, at the
/// velocity after them: the near end of the step after the close), `far` before them
/// (from the covariance the close left, at the velocity before them: the far end of
/// the step before it; the smoothed covariance is the same before and after the
/// updates).
pub(super) struct AtClose<const N: usize> {
    pub(super) ps: Option<SMatrix<f64, N, N>>,
    pub(super) near: Option<SVector<f64, N>>,
    pub(super) far: Option<SVector<f64, N>>,
}

impl<const N: usize> AtClose<N> {
    /// At `close`, from the forward covariance after its updates `p` and `Λ` there;
    /// `at_node`: the close is a node's (updates, or a noise change, after it);
    /// `before`/`after`: σ is wanted in the step before the close / after it.
    pub(super) fn read(
        close: &Close<N>,
        (p, lambda): (&SMatrix<f64, N, N>, &SMatrix<f64, N, N>),
        (at_node, before, after): (bool, bool, bool),
        cfg: &FilterConfig,
    ) -> Self {
        let ps = (at_node || before || after).then(|| symmetric(&(p + p * lambda * p)));
        let (near, far) = match &ps {
            Some(ps) => {
                let near = change(ps, p, cfg, &close.vel);
                let far = match at_node {
                    true => before.then(|| change(ps, &close.p_prior, cfg, &close.vel_prior)),
                    false => before.then_some(near),
                };
                (after.then_some(near), far)
            }
            None => (None, None),
        };
        Self { ps, near, far }
    }

    /// Carry `μ` and `Λ` back through `close` (of the interval that ends at the node
    /// `b`; `at_node`: the close is `b`'s): through `b`'s updates there
    /// ([`at_update`], from `Ps` and `δs⁻ = δs + δx̂`, `ds` the smoothed error after
    /// them), then through the step's Φ. The close as the one before it sees it.
    pub(super) fn back_through(
        self,
        close: &Close<N>,
        (b, at_node): (&Node, bool),
        ds: &SVector<f64, N>,
        (mu, lambda): (&mut SVector<f64, N>, &mut SMatrix<f64, N, N>),
    ) -> Result<Later<N>> {
        let mut ds_prior = *ds;
        if let (true, Some(ps)) = (at_node, self.ps.as_ref()) {
            ds_prior += b.dx::<N>();
            (*mu, *lambda) = at_update(&close.p_prior, ps, &ds_prior).ok_or_else(|| {
                Error::Numerical(format!(
                    "the smoother: the covariance before epoch {} is not positive definite",
                    b.epoch
                ))
            })?;
        }
        *mu = transposed(&close.phi, mu);
        *lambda = congruence(&close.phi, lambda);
        Ok(Later {
            epoch: close.epoch,
            ds_prior,
            change: self.far,
        })
    }
}

/// `μ = (P⁻)⁻¹ δs⁻` and `Λ = (P⁻)⁻¹ (Ps − P⁻) (P⁻)⁻¹` at an update, by Cholesky
/// solves (None: `P⁻` not positive definite): `Mᵀ = ((P⁻)⁻¹ D)ᵀ` from `D = Ps − P⁻`,
/// then `Λᵀ = ((P⁻)⁻¹ Mᵀ)ᵀ` from `M`, each by [`solve_rows`].
pub(super) fn at_update<const N: usize>(
    p_prior: &SMatrix<f64, N, N>,
    ps: &SMatrix<f64, N, N>,
    ds_prior: &SVector<f64, N>,
) -> Option<(SVector<f64, N>, SMatrix<f64, N, N>)> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { at_update_avx2(p_prior, ps, ds_prior) };
    }
    at_update_portable(p_prior, ps, ds_prior)
}

/// [`at_update`] in AVX2 registers (the same operations: no fused multiply-add).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn at_update_avx2<const N: usize>(
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
    let chol = p_prior.cholesky()?;
    let l = chol.l_dirty();
    let mt = solve_rows(l, &(ps - p_prior));
    let lambda_t = solve_rows(l, &mt.transpose());
    Some((chol.solve(ds_prior), symmetric(&lambda_t)))
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

pub(super) fn symmetric<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (m + m.transpose()) * 0.5
}

/// `Φᵀ x` for `Φ = [[R], [0, I]]` (`R` its navigation rows, 9 × 15): entry `j` is
/// `Σ_k R_kj x_k` over the 9 navigation rows, plus `x_j` past them (summed in this
/// order, as nalgebra's product does: the same bits as `Rᵀ x` plus the identity).
pub(super) fn transposed<const N: usize>(rows: &NavRows, x: &SVector<f64, N>) -> SVector<f64, N> {
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
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { times_phi_avx2(rows, b) };
    }
    times_phi_portable(rows, b)
}

/// [`times_phi`] in AVX2 registers (the same products and sums: no fused multiply-add).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn times_phi_avx2<const N: usize>(
    rows: &NavRows,
    b: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    times_phi_portable(rows, b)
}

#[inline(always)]
fn times_phi_portable<const N: usize>(
    rows: &NavRows,
    b: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    let mut out = *b;
    let src = b.as_slice();
    let dst = out.as_mut_slice();
    for j in 0..15 {
        let mut col = [0.0; N];
        for k in 0..9 {
            let r = rows[(k, j)];
            for (c, s) in col.iter_mut().zip(&src[N * k..N * (k + 1)]) {
                *c += r * s;
            }
        }
        if j >= 9 {
            for (c, s) in col.iter_mut().zip(&src[N * j..N * (j + 1)]) {
                *c += s;
            }
        }
        dst[N * j..N * (j + 1)].copy_from_slice(&col);
    }
    out
}

/// `Φᵀ Λ Φ` for a symmetric Λ: `W = Λ Φ`, then `Wᵀ Φ = (Φᵀ W)ᵀ`, symmetrized. Each
/// entry is the sum of the same products in the same order as the dense
/// `Φᵀ (Φᵀ Λ)ᵀ` (Λ is symmetric bit for bit), so the result is too.
pub(super) fn congruence<const N: usize>(
    rows: &NavRows,
    lambda: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    let w = times_phi(rows, lambda);
    symmetric(&times_phi(rows, &w.transpose()))
}

/// A close already smoothed, seen from the one before it: its epoch, the smoothed error
/// before its updates `δs⁻` and the change the smoother makes to the variances there
/// before them ([`AtClose::far`], where σ is wanted in the step before it).
pub(super) struct Later<const N: usize> {
    pub(super) epoch: usize,
    pub(super) ds_prior: SVector<f64, N>,
    pub(super) change: Option<SVector<f64, N>>,
}

impl<const N: usize> Later<N> {
    /// Write the smoothed solution at the row `row` of `at` (its forward solution), an
    /// epoch a fraction `w` of the way in time from the close before (its smoothed
    /// error `ds`, and the change `near` to the variances after its updates, None where
    /// σ is not wanted) to this close: the error linear in time from `ds` to this
    /// close's `δs⁻`, the change to the variances linear in time from `near` to this
    /// close's before its updates, added to the forward variances at the epoch. The
    /// smoothed covariance given all the data is the same before and after an epoch's
    /// updates (they move the forward estimate by a known amount, not what the
    /// smoother knows); the forward pass interpolates its own variances between the
    /// same two ends (`docs/filter.md`, "With a covariance step").
    pub(super) fn write_between(
        &self,
        out: &mut impl Sink,
        (row, at): (usize, &Forward<'_>),
        w: f64,
        (ds, near): (&SVector<f64, N>, Option<&SVector<f64, N>>),
        cfg: &FilterConfig,
    ) {
        if let Some(near) = near {
            debug_assert!(
                self.change.is_some(),
                "σ wanted between closes, none at the far one"
            );
            let far = self.change.as_ref().unwrap_or(near);
            out.set_sigma_between(row, (near, far, w), at);
        }
        out.apply(row, &(ds * (1.0 - w) + self.ds_prior * w), cfg);
    }
}

/// The epoch of the close before the `k`-th of `closes` (the closes in `(a, b]`): the
/// one before it there, else `a`'s where no covariance step was under way after `a`
/// (the step closed at `a`, or `a` is the first epoch); None where unknown (`a` inside
/// a step).
pub(super) fn previous_close<const N: usize>(
    closes: &[Close<N>],
    k: usize,
    a: &Node,
) -> Option<usize> {
    match k {
        0 => a.step.is_none().then_some(a.epoch),
        _ => Some(closes[k - 1].epoch),
    }
}

/// Apply the smoothed error `ds` at the close `epoch` and interpolate it up to the
/// next close `later`; σ, at the wanted epochs, from the change `near` to the
/// variances after the close's updates (given where it was computed): at the close,
/// and interpolated towards the next close's ([`Later::write_between`]) before it.
fn fill<const N: usize>(
    out: &mut impl Sink,
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    (epoch, ds, near): (usize, &SVector<f64, N>, Option<&SVector<f64, N>>),
    later: Option<&Later<N>>,
    wanted: &dyn Fn(usize) -> bool,
) {
    let end = later.map_or(epoch + 1, |l| l.epoch);
    let t_close = forward.time(epoch);
    for i in epoch..end {
        let near = near.filter(|_| wanted(i));
        match later {
            Some(l) if i > epoch => {
                let w = (forward.time(i) - t_close) / (forward.time(l.epoch) - t_close);
                l.write_between(out, (i, forward), w, (ds, near), cfg);
            }
            _ => {
                if let Some(near) = near {
                    out.set_change(i, near, forward);
                }
                out.apply(i, ds, cfg);
            }
        }
    }
}

/// The closes in `(a, b]` of the covariance step that the forward pass kept (see
/// [`KeptCloses::note`]), as [`rebuild`] makes them (the velocity before
/// the updates the one the forward pass kept at the close).
fn kept_between<const N: usize>(
    forward: &Forward<'_>,
    kept: &KeptCloses,
    a: &Node,
    b: &Node,
) -> Vec<Close<N>> {
    let lo = kept.epochs.partition_point(|e| *e <= a.epoch);
    let hi = kept.epochs.partition_point(|e| *e <= b.epoch).max(lo);
    (lo..hi)
        .map(|k| {
            let c = &kept.closes[k];
            let epoch = kept.epochs[k];
            Close {
                epoch,
                phi: c.phi,
                p_prior: lift(&c.p(), c.calibration.as_deref().map(|(x, v)| (x, v))),
                vel_prior: c.vel,
                vel: forward.nav[epoch].vel,
            }
        })
        .collect()
}

/// The closes in `(a, b]` of the covariance step, rebuilt by the filter's prediction
/// along the forward solution from `a` (and the step `a` was inside, if any), the noise
/// of `a` throughout; `b`'s step is closed at `b` where the forward pass closed it
/// (the velocity there before `b`'s updates from [`velocity_before_updates`]; no
/// update between the nodes: before and after are the same elsewhere).
pub(crate) fn rebuild<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    a: &Node,
    b: &Node,
    cancel: &Cancel,
) -> Result<Vec<Close<N>>> {
    let mut ekf = restart(forward, cfg, a)?;
    let noise = a.noise.as_process_noise();
    let mut closes = Vec::new();
    let at_b = velocity_before_updates(forward, b.epoch);
    let mut push = |ekf: &Ekf, epoch: usize, phi: Transition| {
        let vel = forward.nav[epoch].vel;
        let vel_prior = if epoch == b.epoch { at_b } else { vel };
        closes.push(Close::of(ekf, epoch, &phi, (vel_prior, vel)));
    };
    for epoch in a.epoch..b.epoch {
        if (epoch - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let raw = ImuSample::from_array(&forward.imu[epoch]);
        let dt = forward.step(epoch);
        let (_, closed) = ekf.predict_covariance_from(&forward.nav[epoch], &raw, dt, noise);
        if let Some(phi) = closed {
            push(&ekf, epoch + 1, phi);
        }
    }
    if b.step.is_none() {
        if let Some(phi) = ekf.bring_up_to_date() {
            push(&ekf, b.epoch, phi);
        }
    }
    Ok(closes)
}

/// The forward velocity \[m/s, NED\] at `epoch` (≥ 1) before its updates: the strapdown
/// step from the solution after the updates of the epoch before, with its bias
/// estimates, as the forward pass took it (the same operations on the same numbers).
fn velocity_before_updates(forward: &Forward<'_>, epoch: usize) -> Vector3<f64> {
    let (nav, b) = (&forward.nav[epoch - 1], &forward.bias[epoch - 1]);
    let raw = ImuSample::from_array(&forward.imu[epoch - 1]);
    let imu = ImuSample {
        accel: raw.accel - Vector3::new(b[0], b[1], b[2]),
        gyro: raw.gyro - Vector3::new(b[3], b[4], b[5]),
    };
    let dt = forward.step(epoch - 1);
    step_with_rates(nav, &imu, dt, &FrameRates::at(nav)).vel
}
