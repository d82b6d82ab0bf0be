//! The backward pass with the covariance propagated at every IMU sample: the RTS
//! recursion chained over the samples between two nodes (see [`super`]).

use super::forward::{Covariances, Forward};
use super::node::{full_p, lift, restart, Node};
use super::sink::Sink;
use crate::cancel::{Cancel, STEPS_PER_CHECK};
use crate::ekf::dynamics::{add_imu_noise, ErrorDynamics};
use crate::ekf::formulation::from_classic;
use crate::ekf::{FilterConfig, Matrix15, ProcessNoise, ACC_BIAS};
use crate::error::{Error, Result};
use crate::mechanization::{FrameRates, ImuSample, NavState};
use nalgebra::{SMatrix, SVector, Vector3};

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
    out.set_sigma(last.epoch, (&ps, &ps), cfg, forward);
    out.keep_node(last.epoch, &ps);
    let wanted = match covariances {
        Covariances::Every => None,
        Covariances::Where(f) => Some(f),
    };
    for pair in nodes.windows(2).rev() {
        let (a, b) = (&pair[0], &pair[1]);
        cancel.check()?;
        // No σ wanted inside the interval and the covariance before b's updates kept:
        // the mean needs no covariance inside it ([`bryson_frazier`]).
        let inside = |w: &dyn Fn(usize) -> bool| (a.epoch + 1..b.epoch).any(w);
        if let (15, Some(p_prior), Some(false)) = (N, &b.p_prior, wanted.map(inside)) {
            let p_prior = lift::<N>(p_prior, None);
            (ds, ps) = bryson_frazier(forward, cfg, (a, b), &p_prior, (&ds, &ps), out, cancel)?;
            continue;
        }
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
                    out.set_sigma(i, (&ps, p), cfg, forward);
                    out.keep_node(i, &ps);
                } else {
                    out.set_sigma_of(i, &interval.p[k], &lambda, cfg, forward);
                }
            } else if let Some(bk) = interval.product_to_end(k)? {
                let gain = interval.p[k] * bk;
                let psi = interval.p[k] + gain * m * gain.transpose();
                let psi = (psi + psi.transpose()) * 0.5;
                out.set_sigma(i, (&psi, &interval.p[k]), cfg, forward);
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

/// The interval from node `a` to node `b` of [`smooth_every`] where no σ is wanted
/// inside it, given the forward covariance `p_prior` before `b`'s updates and the
/// smoothed error `ds` and covariance `ps` at `b` (after its updates): the
/// Bryson–Frazier form of the same recursion. `μ_i = Φ_iᵀ μ_{i+1}` back from
/// `μ_b = (P⁻_b)⁻¹ δs⁻_b`, then forward from `δs_a = P_a μ_a`:
/// `δs_{i+1} = P_{i+1} μ_{i+1} = (Φ_i P_i Φ_iᵀ + Q_i) μ_{i+1} = Φ_i δs_i + Q_i μ_{i+1}`
/// (`Q_i` the noise the filter adds after `Φ_i` at sample `i`), so no `P_i` is
/// re-predicted inside; `Ps_a = P_a + P_a G_bᵀ M G_b P_a` (`G_b = Φ_{a→b}`) as in the
/// re-predicting pass. Writes the smoothed error at `[a, b)` and σ at `a`; gives `δs_a`
/// and `Ps_a`. In exact arithmetic the same numbers; in floating point the errors inside
/// the interval differ by rounding, those at the nodes are the same bits.
fn bryson_frazier<const N: usize, S: Sink>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    (a, b): (&Node, &Node),
    p_prior: &SMatrix<f64, N, N>,
    (ds, ps): (&SVector<f64, N>, &SMatrix<f64, N, N>),
    out: &mut S,
    cancel: &Cancel,
) -> Result<(SVector<f64, N>, SMatrix<f64, N, N>)> {
    let (steps, g_end) = transitions::<N>(forward, cfg, a, b.epoch, cancel)?;
    let chol = p_prior.cholesky().ok_or_else(|| {
        Error::Numerical(format!(
            "the smoother: the covariance before epoch {} is not positive definite",
            b.epoch
        ))
    })?;
    let mut mu = chol.solve(&(ds + b.dx::<N>()));
    let m = chol.solve(&(ps - p_prior));
    let m = chol.solve(&m.transpose()).transpose();
    let m = (m + m.transpose()) * 0.5;
    // μ at every epoch of [a, b], back from b.
    let mut mus = vec![SVector::<f64, N>::zeros(); steps.len() + 1];
    mus[steps.len()] = mu;
    for (k, (dynamics, dt)) in steps.iter().enumerate().rev() {
        mu = transposed_step(dynamics, *dt, &mu);
        mus[k] = mu;
    }
    let p_a = a.p::<N>();
    let ds_a = p_a * mus[0];
    let mut dsi = ds_a;
    let noise = a.noise.as_process_noise();
    for (k, (dynamics, dt)) in steps.iter().enumerate() {
        let i = a.epoch + k;
        out.apply(i, &dsi, cfg);
        if k + 1 < steps.len() {
            let q = discrete_noise(cfg, &forward.nav[i], noise, *dt);
            let q_mu = q * mus[k + 1].fixed_rows::<15>(0);
            let f = dynamics.apply(&dsi.as_slice()[..15]);
            for (r, v) in f.iter().enumerate() {
                dsi[r] += dt * v;
            }
            for (r, v) in q_mu.iter().enumerate() {
                dsi[r] += v;
            }
        }
    }
    let gain = p_a * g_end.transpose();
    let psi = p_a + gain * m * gain.transpose();
    let ps_a = (psi + psi.transpose()) * 0.5;
    out.set_sigma(a.epoch, (&ps_a, &p_a), cfg, forward);
    out.keep_node(a.epoch, &ps_a);
    Ok((ds_a, ps_a))
}

/// The error dynamics and step of each sample from node `a` to the epoch `end`, at the
/// forward solution (as [`Interval::rebuild`] makes them, without the covariances), and
/// their product `G = Φ_{a→end}`.
#[allow(clippy::type_complexity)]
fn transitions<const N: usize>(
    forward: &Forward<'_>,
    cfg: &FilterConfig,
    a: &Node,
    end: usize,
    cancel: &Cancel,
) -> Result<(Vec<(ErrorDynamics, f64)>, SMatrix<f64, N, N>)> {
    let b = &forward.bias[a.epoch];
    let accel_bias = Vector3::new(b[0], b[1], b[2]);
    let mut steps = Vec::with_capacity(end - a.epoch);
    let mut g = Product::<N>::identity();
    for epoch in a.epoch..end {
        if (epoch - a.epoch) % STEPS_PER_CHECK == STEPS_PER_CHECK - 1 {
            cancel.check()?;
        }
        let raw = ImuSample::from_array(&forward.imu[epoch]);
        let dt = forward.step(epoch);
        let nav = &forward.nav[epoch];
        let accel = raw.accel - accel_bias;
        let dynamics = ErrorDynamics::new(nav, &FrameRates::at(nav), &accel, cfg.formulation);
        g.step(&dynamics, dt);
        steps.push((dynamics, dt));
    }
    Ok((steps, g.get()))
}

/// The discrete noise `Q` the filter adds after `Φ` at one sample of `dt` seconds at
/// the solution `nav` (its `add_process_noise`, added to zeros).
fn discrete_noise(
    cfg: &FilterConfig,
    nav: &NavState,
    noise: ProcessNoise<'_>,
    dt: f64,
) -> Matrix15 {
    let mut q = Matrix15::zeros();
    match noise {
        ProcessNoise::Continuous {
            imu_variance,
            bias_psd,
        } => {
            add_imu_noise(&mut q, nav, cfg.formulation, imu_variance, cfg.imu_dt * dt);
            for (i, psd) in bias_psd.iter().enumerate() {
                q[(ACC_BIAS + i, ACC_BIAS + i)] += psd * dt;
            }
        }
        ProcessNoise::Discrete(qd) => {
            q = (qd + qd.transpose()) * 0.5;
            from_classic(cfg.formulation, &mut q, &nav.vel);
        }
    }
    q
}

/// The forward covariances `P_i` (epochs `a..b`, `P_a` the node's after its update)
/// and the error dynamics F and step Δt of the steps `i → i+1` (`Φ = I + F Δt`),
/// rebuilt from the forward solution; with a covariance predicate, the product
/// `G_i = Φ_{a→i}` at the epochs it holds for, and `G_b`.
pub(crate) struct Interval<const N: usize> {
    pub(crate) p: Vec<SMatrix<f64, N, N>>,
    pub(super) steps: Vec<(ErrorDynamics, f64)>,
    /// The covariance after the last step (before the end node's update).
    pub(crate) p_end: SMatrix<f64, N, N>,
    /// `(i − a, G_i)` at the wanted epochs inside the interval.
    g: Vec<(usize, SMatrix<f64, N, N>)>,
    g_end: SMatrix<f64, N, N>,
}

impl<const N: usize> Interval<N> {
    /// The interval from node `a` to the epoch `end`, rebuilt by the filter's own
    /// prediction along the forward solution (read, not integrated again): the same
    /// steps on the same numbers, so its last covariance is the forward pass's before
    /// `end`'s update, bit for bit.
    pub(crate) fn rebuild(
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
        let mut g = Product::<N>::identity();
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
                    g_at.push((epoch - a.epoch, g.get()));
                }
                g.step(&step, dt);
            }
            phi.push((step, dt));
        }
        Ok(Self {
            p,
            steps: phi,
            p_end: full_p::<N>(&ekf),
            g: g_at,
            g_end: g.get(),
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

/// A product of transitions `G = Φ_{a→i}` as it is carried: for 15 states its
/// transpose `H`, `H ← H Φᵀ` through whole columns of H
/// ([`ErrorDynamics::advance_transposed`]); for 19, `G ← Φ G` column by column through
/// F.
struct Product<const N: usize>(SMatrix<f64, N, N>);

impl<const N: usize> Product<N> {
    fn identity() -> Self {
        Self(SMatrix::identity())
    }

    /// `G ← Φ G` with `Φ = I + F Δt` (F's navigation rows alone nonzero).
    fn step(&mut self, dynamics: &ErrorDynamics, dt: f64) {
        if N == 15 {
            dynamics.advance_transposed(self.0.as_mut_slice(), dt);
            return;
        }
        let g = &mut self.0;
        for c in 0..N {
            let f = dynamics.apply(&g.as_slice()[N * c..N * c + 15]);
            for (r, v) in f.iter().enumerate() {
                g[(r, c)] += dt * v;
            }
        }
    }

    /// G itself.
    fn get(&self) -> SMatrix<f64, N, N> {
        if N == 15 {
            self.0.transpose()
        } else {
            self.0
        }
    }
}
