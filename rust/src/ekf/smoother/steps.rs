//! The backward pass over a covariance step ([`FilterConfig::covariance_step`]).
//!
//! With a covariance step the forward filter has a covariance only where a step closes
//! (when due, before every update, at the last epoch): those closes are the smoother's
//! grid, and each step's `Φ = I + F ΔT + ½(F ΔT)²` is the transition between two of
//! them. The backward pass rebuilds the closes between two nodes by the filter's own
//! prediction (bit for bit, as [`super::Interval::rebuild`] does at every sample;
//! a node inside a step carries the step's sums, so the rebuild resumes it), then runs
//! the RTS recursion from close to close (`c` the earlier close, `d` the next):
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
//! `δs⁻_d = δs_d + δx̂_d` (before `d`'s), and its σ repeats the smoothed σ at `c`,
//! as the forward σ repeats the last closed one.

use super::{full_p, restart, Covariances, Forward, Node, Smoothed, STEPS_PER_CHECK};
use crate::cancel::Cancel;
use crate::ekf::dynamics::Transition;
use crate::ekf::FilterConfig;
use crate::error::{Error, Result};
use crate::mechanization::ImuSample;
use nalgebra::{SMatrix, SVector};

/// A close of the covariance step, rebuilt: its epoch, the step's Φ and the
/// covariance it left (before the epoch's updates), over `N` states.
pub(in crate::ekf) struct Close<const N: usize> {
    pub(in crate::ekf) epoch: usize,
    phi: Transition,
    pub(in crate::ekf) p_prior: SMatrix<f64, N, N>,
}

/// The smoothed close after the ones still to be processed, with its step.
struct Later<const N: usize> {
    epoch: usize,
    /// `δs⁻ = δs + δx̂`: the smoothed error of the forward solution before its updates.
    ds_prior: SVector<f64, N>,
    ps: SMatrix<f64, N, N>,
    phi: Transition,
    p_prior: SMatrix<f64, N, N>,
}

/// The backward pass of [`super::smooth`] over `N` states under a covariance step.
pub(super) fn smooth_steps<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    covariances: Covariances<'_>,
    cancel: &Cancel,
) -> Result<Smoothed> {
    let mut out = Smoothed::start(forward, nodes.len());
    let wanted = |i: usize| match covariances {
        Covariances::Every => true,
        Covariances::Where(f) => f(i),
    };
    let mut later: Option<Later<N>> = None;
    for pair in nodes.windows(2).rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        let closes = rebuild::<N>(forward, cfg, a, b, cancel)?;
        for close in closes.into_iter().rev() {
            let (p_post, correction) = if close.epoch == b.epoch {
                (b.p::<N>(), b.dx::<N>())
            } else {
                (close.p_prior, SVector::zeros())
            };
            let (ds, ps) = step_back(&p_post, later.as_ref())?;
            fill(
                &mut out,
                forward,
                cfg,
                close.epoch,
                &ds,
                &ps,
                later.as_ref(),
                &wanted,
            );
            if close.epoch == b.epoch {
                out.keep_node(b.epoch, &ps);
            }
            later = Some(Later {
                epoch: close.epoch,
                ds_prior: ds + correction,
                ps,
                phi: close.phi,
                p_prior: close.p_prior,
            });
        }
    }
    // The first epoch: the prior, a close of its own.
    let (ds, ps) = step_back(&nodes[0].p::<N>(), later.as_ref())?;
    fill(&mut out, forward, cfg, 0, &ds, &ps, later.as_ref(), &wanted);
    out.keep_node(0, &ps);
    out.node_covariance.reverse();
    Ok(out)
}

/// `Φ X` for a step's Φ (its rows past the first 15 are the identity's).
fn phi_times<const N: usize>(phi: &Transition, x: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let mut top: SMatrix<f64, 15, N> = x.fixed_rows::<15>(0).into_owned();
    phi.apply(&mut top);
    let mut out = *x;
    out.fixed_rows_mut::<15>(0).copy_from(&top);
    out
}

/// The smoothed error and covariance at a close whose covariance after its updates is
/// `p_post`, from the next close `later` (None: the last epoch, where `δs = 0`,
/// `Ps = P`).
type SmoothedAt<const N: usize> = (SVector<f64, N>, SMatrix<f64, N, N>);
fn step_back<const N: usize>(
    p_post: &SMatrix<f64, N, N>,
    later: Option<&Later<N>>,
) -> Result<SmoothedAt<N>> {
    let Some(later) = later else {
        return Ok((SVector::zeros(), *p_post));
    };
    let chol = later.p_prior.cholesky().ok_or_else(|| {
        Error::Numerical(format!(
            "the smoother: the covariance before epoch {} is not positive definite",
            later.epoch
        ))
    })?;
    // Aᵀ = (P⁻_d)⁻¹ Φ_d P⁺_c (P⁻ and P⁺ symmetric).
    let gain_t = chol.solve(&phi_times(&later.phi, p_post));
    let ds = gain_t.transpose() * later.ds_prior;
    let ps = p_post + gain_t.transpose() * (later.ps - later.p_prior) * gain_t;
    Ok((ds, (ps + ps.transpose()) * 0.5))
}

/// Apply the smoothed error `ds` at the close `epoch` and interpolate it up to the
/// next close; σ at the close and, repeated, at the epochs before the next one.
#[allow(clippy::too_many_arguments)]
fn fill<const N: usize>(
    out: &mut Smoothed,
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    epoch: usize,
    ds: &SVector<f64, N>,
    ps: &SMatrix<f64, N, N>,
    later: Option<&Later<N>>,
    wanted: &dyn Fn(usize) -> bool,
) {
    let end = later.map_or(epoch + 1, |l| l.epoch);
    let t_close = forward.time(epoch);
    for i in epoch..end {
        if wanted(i) {
            out.set_sigma(i, ps, cfg, forward);
        }
        let dsi = match later {
            Some(l) if i > epoch => {
                let w = (forward.time(i) - t_close) / (forward.time(l.epoch) - t_close);
                ds * (1.0 - w) + l.ds_prior * w
            }
            _ => *ds,
        };
        out.apply(i, &dsi, cfg);
    }
}

/// The closes in `(a, b]` of the covariance step, rebuilt by the filter's prediction
/// from the forward solution at `a` (and the step `a` was inside, if any), the noise
/// of `a` throughout; `b`'s step is closed at `b` where the forward pass closed it.
pub(in crate::ekf) fn rebuild<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    a: &Node,
    b: &Node,
    cancel: &Cancel,
) -> Result<Vec<Close<N>>> {
    let mut ekf = restart(forward, cfg, a)?;
    let noise = a.noise.as_process_noise();
    let mut closes = Vec::new();
    for epoch in a.epoch..b.epoch {
        if (epoch - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let raw = ImuSample::from_array(&forward.imu[epoch]);
        let dt = forward.step(epoch);
        if let Some(phi) = ekf.propagate_closing(&raw, dt, noise)? {
            closes.push(Close {
                epoch: epoch + 1,
                phi,
                p_prior: full_p::<N>(&ekf),
            });
        }
    }
    if b.interval.is_none() {
        if let Some(phi) = ekf.close_interval() {
            closes.push(Close {
                epoch: b.epoch,
                phi,
                p_prior: full_p::<N>(&ekf),
            });
        }
    }
    Ok(closes)
}
