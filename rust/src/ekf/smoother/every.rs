//! The backward pass with the covariance propagated at every IMU sample: the RTS
//! recursion chained over the samples between two nodes (see [`super`]).

use super::{full_p, restart, Covariances, Forward, Node, Sink};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::dynamics::ErrorDynamics;
use crate::ekf::FilterConfig;
use crate::error::{Error, Result};
use crate::mechanization::ImuSample;
use nalgebra::{SMatrix, SVector};

/// The backward pass of [`super::smooth`] over `N` states, every sample.
pub(super) fn smooth_every<const N: usize, S: Sink>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    covariances: Covariances<'_>,
    out: &mut S,
    cancel: &Cancel,
) -> Result<()> {
    let last = &nodes[nodes.len() - 1];
    // After the last epoch nothing is left to learn: δs = 0, Ps = P.
    let mut ds = SVector::<f64, N>::zeros();
    let mut ps = last.p::<N>();
    out.set_sigma(last.epoch, &ps, cfg, forward);
    out.keep_node(last.epoch, &ps);
    let wanted = match covariances {
        Covariances::Every => None,
        Covariances::Where(f) => Some(f),
    };
    for pair in nodes.windows(2).rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        let interval = Interval::<N>::rebuild(forward, cfg, a, b.epoch, wanted, cancel)?;
        let chol = interval.p_end.cholesky().ok_or_else(|| {
            Error::Numerical(format!(
                "the smoother: the covariance before epoch {} is not positive definite",
                b.epoch
            ))
        })?;
        // μ_i = Φ_{i→b}ᵀ (P⁻_b)⁻¹ δs⁻_b and δs_i = P_i μ_i; M as in the module's text.
        let mut mu = chol.solve(&(ds + b.dx::<N>()));
        let m = chol.solve(&(ps - interval.p_end));
        let m = chol.solve(&m.transpose()).transpose();
        let m = (m + m.transpose()) * 0.5;
        // Λ_i = Φ_{i→b}ᵀ M Φ_{i→b}, carried with Covariances::Every: Ps_i = P_i + P_i Λ_i P_i.
        let mut lambda = m;
        for i in (a.epoch..b.epoch).rev() {
            let k = i - a.epoch;
            let (dynamics, dt) = &interval.steps[k];
            mu = transposed_step(dynamics, *dt, &mu);
            let dsi = interval.p[k] * mu;
            if wanted.is_none() {
                congruence(dynamics, *dt, &mut lambda);
                if i == a.epoch {
                    let p = &interval.p[k];
                    let psi = p + p * lambda * p;
                    ps = (psi + psi.transpose()) * 0.5;
                    out.set_sigma(i, &ps, cfg, forward);
                    out.keep_node(i, &ps);
                } else {
                    out.set_sigma_of(i, &interval.p[k], &lambda, cfg, forward);
                }
            } else if let Some(bk) = interval.product_to_end(k)? {
                let gain = interval.p[k] * bk;
                let psi = interval.p[k] + gain * m * gain.transpose();
                let psi = (psi + psi.transpose()) * 0.5;
                out.set_sigma(i, &psi, cfg, forward);
                if i == a.epoch {
                    ps = psi;
                    out.keep_node(i, &psi);
                }
            }
            out.apply(i, &dsi, cfg);
            if i == a.epoch {
                ds = dsi;
            }
        }
    }
    Ok(())
}

/// The forward covariances `P_i` (epochs `a..b`, `P_a` the node's after its update)
/// and the error dynamics F and step Δt of the steps `i → i+1` (`Φ = I + F Δt`),
/// rebuilt from the forward solution; with a covariance predicate, the product
/// `G_i = Φ_{a→i}` at the epochs it holds for, and `G_b`.
pub(in crate::ekf) struct Interval<const N: usize> {
    pub(in crate::ekf) p: Vec<SMatrix<f64, N, N>>,
    pub(super) steps: Vec<(ErrorDynamics, f64)>,
    /// The covariance after the last step (before the end node's update).
    pub(in crate::ekf) p_end: SMatrix<f64, N, N>,
    /// `(i − a, G_i)` at the wanted epochs inside the interval.
    g: Vec<(usize, SMatrix<f64, N, N>)>,
    g_end: SMatrix<f64, N, N>,
}

impl<const N: usize> Interval<N> {
    /// The interval from node `a` to the epoch `end`, rebuilt by the filter's own
    /// prediction along the forward solution (read, not integrated again): the same
    /// steps on the same numbers, so its last covariance is the forward pass's before
    /// `end`'s update, bit for bit.
    pub(in crate::ekf) fn rebuild(
        forward: &Forward<'_>,
        cfg: &FilterConfig,
        a: &Node,
        end: usize,
        wanted: Option<&dyn Fn(usize) -> bool>,
        cancel: &Cancel,
    ) -> Result<Self> {
        let mut ekf = restart(forward, cfg, a)?;
        let steps = end - a.epoch;
        let (mut p, mut phi) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
        let mut g_at = Vec::new();
        let mut g = SMatrix::<f64, N, N>::identity();
        let noise = a.noise.as_process_noise();
        for epoch in a.epoch..end {
            if (epoch - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
                cancel.check()?;
            }
            // The step from epoch i to i + 1 reads IMU row i.
            let raw = ImuSample::from_array(&forward.imu[epoch]);
            let dt = forward.step(epoch);
            p.push(full_p::<N>(&ekf));
            let (step, _) = ekf.predict_covariance_from(&forward.nav[epoch], &raw, dt, noise);
            let step = step.ok_or_else(|| {
                Error::Numerical("the smoother: a covariance step where none was".into())
            })?;
            if let Some(wanted) = wanted {
                if epoch > a.epoch && wanted(epoch) {
                    g_at.push((epoch - a.epoch, g));
                }
                step_product(&step, dt, &mut g);
            }
            phi.push((step, dt));
        }
        Ok(Self {
            p,
            steps: phi,
            p_end: full_p::<N>(&ekf),
            g: g_at,
            g_end: g,
        })
    }

    /// `Φ_{i→b}ᵀ` for the epoch `a + k` where it was wanted: `G_bᵀ` at the start,
    /// `(G_b G_i⁻¹)ᵀ` inside; None where it was not.
    fn product_to_end(&self, k: usize) -> Result<Option<SMatrix<f64, N, N>>> {
        if k == 0 {
            return Ok(Some(self.g_end.transpose()));
        }
        let Ok(at) = self.g.binary_search_by_key(&k, |(i, _)| *i) else {
            return Ok(None);
        };
        let inverse = inverse_transition(&self.g[at].1).ok_or_else(|| {
            Error::Numerical("the smoother: a transition product is singular".into())
        })?;
        Ok(Some((self.g_end * inverse).transpose()))
    }
}

/// The inverse of a product of transitions `G = [[A, B], [0, I]]` (`A` 9 × 9):
/// `[[A⁻¹, −A⁻¹ B], [0, I]]`, one 9 × 9 inversion.
fn inverse_transition<const N: usize>(g: &SMatrix<f64, N, N>) -> Option<SMatrix<f64, N, N>> {
    let a = g.fixed_view::<9, 9>(0, 0).into_owned().try_inverse()?;
    let mut out = SMatrix::<f64, N, N>::identity();
    out.fixed_view_mut::<9, 9>(0, 0).copy_from(&a);
    for c in 9..N {
        let col = -(a * g.fixed_view::<9, 1>(0, c));
        out.fixed_view_mut::<9, 1>(0, c).copy_from(&col);
    }
    Some(out)
}

/// `Φᵀ x` for a step `Φ = I + F Δt`: `x + Δt Fᵀ x` (F's navigation rows alone read).
pub(super) fn transposed_step<const N: usize>(
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
pub(super) fn congruence<const N: usize>(
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

/// `G ← Φ G = G + Δt F G` (F's navigation rows alone nonzero).
fn step_product<const N: usize>(dynamics: &ErrorDynamics, dt: f64, g: &mut SMatrix<f64, N, N>) {
    for c in 0..N {
        let f = dynamics.apply(&g.as_slice()[N * c..N * c + 15]);
        for (r, v) in f.iter().enumerate() {
            g[(r, c)] += dt * v;
        }
    }
}
