//! The backward pass with the covariance propagated at every IMU sample: the RTS
//! recursion chained over the samples between two nodes (see [`super`]).

use super::{
    full_p, restart, step_product, transposed, Covariances, Forward, NavRows, Node, Smoothed,
};
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::FilterConfig;
use crate::error::{Error, Result};
use crate::mechanization::ImuSample;
use nalgebra::{SMatrix, SVector};

/// The backward pass of [`super::smooth`] over `N` states, every sample.
pub(super) fn smooth_every<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    nodes: &[Node],
    covariances: Covariances<'_>,
    cancel: &Cancel,
) -> Result<Smoothed> {
    let mut out = Smoothed::start(forward, nodes.len());
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
        // Φ_{i→b}ᵀ, carried with Covariances::Every.
        let mut back = SMatrix::<f64, N, N>::identity();
        for i in (a.epoch..b.epoch).rev() {
            let k = i - a.epoch;
            let phi = &interval.phi[k];
            mu = transposed(phi, &mu);
            let dsi = interval.p[k] * mu;
            let transposed_product = if wanted.is_none() {
                back = transposed(phi, &back);
                Some(back)
            } else {
                interval.product_to_end(k)?
            };
            if let Some(bk) = transposed_product {
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
    out.node_covariance.reverse();
    Ok(out)
}

/// The forward covariances `P_i` (epochs `a..b`, `P_a` the node's after its update)
/// and the navigation rows of the transitions `Φ` of the steps `i → i+1`, rebuilt from
/// the forward solution; with a covariance predicate, the product `G_i = Φ_{a→i}` at
/// the epochs it holds for, and `G_b`.
pub(in crate::ekf) struct Interval<const N: usize> {
    pub(in crate::ekf) p: Vec<SMatrix<f64, N, N>>,
    pub(in crate::ekf) phi: Vec<NavRows>,
    /// The covariance after the last step (before the end node's update).
    pub(in crate::ekf) p_end: SMatrix<f64, N, N>,
    /// `(i − a, G_i)` at the wanted epochs inside the interval.
    g: Vec<(usize, SMatrix<f64, N, N>)>,
    g_end: SMatrix<f64, N, N>,
}

impl<const N: usize> Interval<N> {
    /// The interval from node `a` to the epoch `end`, rebuilt by the filter's own
    /// prediction from the forward solution at `a`: the same steps on the same numbers,
    /// so its last covariance is the forward pass's before `end`'s update, bit for bit.
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
            let step = ekf.transition_rows(&raw, dt);
            if let Some(wanted) = wanted {
                if epoch > a.epoch && wanted(epoch) {
                    g_at.push((epoch - a.epoch, g));
                }
                step_product(&step, &mut g);
            }
            phi.push(step);
            ekf.propagate(&raw, dt, noise)?;
        }
        Ok(Self {
            p,
            phi,
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
