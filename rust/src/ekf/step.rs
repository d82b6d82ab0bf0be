//! The covariance step: P propagated once over an interval of several IMU samples
//! ([`super::FilterConfig::covariance_step`]) while the navigation solution is still
//! integrated at every sample.
//!
//! Over the interval `ΔT = Σ Δt_k` the filter accumulates what the per-sample
//! propagation would consume: the NED specific force `Σ Ĉ_k f̂_k Δt_k` (F is then
//! evaluated once, at the navigation state of the interval's start with the mean
//! specific force), the IMU white noise `Σ q_k Δt_imu Δt_k` of each channel, the bias
//! walks `Σ ε_k Δt_k`, and a strategy's discrete `Σ Q_d,k` (each sample's noise as the
//! strategy gave it, so that a q set from outside or Mehra's Q̂ changing between two
//! samples counts from the sample it takes effect at). Closing the interval applies
//! `Φ = I + F ΔT + ½(F ΔT)²` and `P ← Φ (P + ½Q) Φᵀ + ½Q`, with `Q` the accumulated
//! noise mapped through Γ at the interval's start (`docs/reference/filter.md`, "Covariance
//! step"). The sensitivity `M` and the DVL calibration blocks go through the same Φ.

use super::calibration::Calibration;
use super::dynamics::{ErrorDynamics, ImuNoise};
use super::formulation::Coordinates;
use super::process_noise::ProcessNoise;
use super::second_order::SecondOrder;
use super::state::{Matrix15, ACC_BIAS};
use super::transition::Transition;
use super::FilterConfig;
use crate::mechanization::{FrameRates, NavState};
use nalgebra::Vector3;

/// What closing a covariance step propagates: the covariance `p` in the formulation's
/// coordinates `coordinates`, the DVL calibration blocks, and the sensitivity `M`, the IMU
/// variances it is taken for and its calibration blocks.
pub(crate) struct Covariance<'a> {
    pub(crate) coordinates: Coordinates,
    pub(crate) p: &'a mut Matrix15,
    pub(crate) calibration: Option<&'a mut Calibration>,
    pub(crate) sensitivity: Option<(&'a mut Matrix15, &'a [f64; 6], Option<&'a mut Calibration>)>,
    /// The second-order heading term and P's heading variance at the step's start.
    pub(crate) second_order: Option<(&'a mut SecondOrder, f64)>,
}

/// A covariance step under way.
#[derive(Clone, Debug)]
pub struct CovarianceStep {
    /// The navigation solution at the interval's start (F and Γ are evaluated there).
    start: NavState,
    /// `ΔT` \[s\].
    elapsed: f64,
    /// `Σ Ĉ_k f̂_k Δt_k` \[m/s\]: the bias-corrected specific force in NED, integrated.
    force: Vector3<f64>,
    /// `Σ q_k Δt_imu Δt_k` per IMU channel (the white noise of `Continuous` samples).
    imu_noise: [f64; 6],
    /// `Σ ε_k Δt_k` per bias.
    bias_noise: [f64; 6],
    /// `Σ Q_d,k` of `Discrete` samples (classic coordinates), if any; boxed, so that
    /// the step moves as a few hundred bytes, not 2 kB, where no strategy sets Q_d.
    discrete: Option<Box<Matrix15>>,
    /// `Σ Δt_imu Δt_k` for the sensitivity's noise, when it is tracked.
    sensitivity_white: Option<f64>,
}

impl CovarianceStep {
    /// An interval starting at `nav`; `sensitivity`: whether M is tracked.
    pub(crate) fn open(nav: &NavState, sensitivity: bool) -> Self {
        Self {
            start: *nav,
            elapsed: 0.0,
            force: Vector3::zeros(),
            imu_noise: [0.0; 6],
            bias_noise: [0.0; 6],
            discrete: None,
            sensitivity_white: sensitivity.then_some(0.0),
        }
    }

    /// Add one IMU sample of `dt` seconds taken at `nav` with the bias-corrected
    /// specific force `f_body`, white-noise factor `white = Δt_imu Δt` and `noise`.
    pub(crate) fn add(
        &mut self,
        nav: &NavState,
        f_body: &Vector3<f64>,
        dt: f64,
        white: f64,
        noise: ProcessNoise<'_>,
    ) {
        self.elapsed += dt;
        self.force += nav.dcm * (f_body * dt);
        match noise {
            ProcessNoise::Continuous {
                imu_variance,
                bias_psd,
            } => {
                for i in 0..6 {
                    self.imu_noise[i] += imu_variance[i] * white;
                    self.bias_noise[i] += bias_psd[i] * dt;
                }
            }
            ProcessNoise::Discrete(qd) => {
                **self
                    .discrete
                    .get_or_insert_with(|| Box::new(Matrix15::zeros())) += qd;
            }
        }
        if let Some(w) = self.sensitivity_white.as_mut() {
            *w += white;
        }
    }

    /// Whether the interval has reached the configured covariance step.
    pub(crate) fn due(&self, cfg: &FilterConfig) -> bool {
        cfg.interval_due(self.elapsed)
    }

    /// Propagate the filter's P, M and calibration blocks over the interval:
    /// `P ← Φ (P + ½Q) Φᵀ + ½Q`, the noise added to the blocks it has, half on either
    /// side of Φ. The interval's Φ, or None for an empty interval (P unchanged).
    pub(crate) fn close(self, covariance: Covariance<'_>) -> Option<Transition> {
        if self.elapsed <= 0.0 {
            return None;
        }
        let start = &self.start;
        let at = covariance.coordinates.at(start);
        let rates = FrameRates::at(start);
        let force = self.force / self.elapsed;
        let phi = ErrorDynamics::with_force(start, &rates, &force, &at).transition(self.elapsed);
        let discrete = self.discrete.map(|qd| {
            let mut qd = (*qd + qd.transpose()) * 0.25; // symmetrized, halved
            at.from_classic(&mut qd);
            qd
        });
        let imu_noise = ImuNoise::new(start, &at, &self.imu_noise, 0.5);
        let noise = |p: &mut Matrix15| {
            imu_noise.add_to(p);
            for (i, v) in self.bias_noise.iter().enumerate() {
                p[(ACC_BIAS + i, ACC_BIAS + i)] += 0.5 * v;
            }
            if let Some(qd) = &discrete {
                *p += qd;
            }
        };
        noise(covariance.p);
        phi.propagate(covariance.p);
        noise(covariance.p);
        if let Some(c) = covariance.calibration {
            c.propagate_interval(&phi, self.elapsed, true);
        }
        if let (Some((m, qm, calibration)), Some(white)) =
            (covariance.sensitivity, self.sensitivity_white)
        {
            let noise = ImuNoise::new(start, &at, qm, 0.5 * white);
            noise.add_to(m);
            phi.propagate(m);
            noise.add_to(m);
            if let Some(c) = calibration {
                c.propagate_interval(&phi, self.elapsed, false);
            }
        }
        if let Some((s, heading_variance)) = covariance.second_order {
            s.transition(|u| phi.apply(u));
            s.grow(covariance.p, heading_variance);
        }
        Some(phi)
    }
}

/// A variance linear in time between `from` and `to`, a fraction `w` of the way: how
/// a pass interpolates its variances inside a covariance step and the smoother the
/// change it makes to them.
pub fn variance_between(from: f64, to: f64, w: f64) -> f64 {
    from + w * (to - from)
}

#[cfg(test)]
mod tests {
    use super::super::calibration::CalibrationConfig;
    use super::super::tests::{dvl_at_estimate, moving_state};
    use super::super::{Ekf, Formulation, Vector15};
    use super::*;
    use crate::mechanization::ImuSample;

    const Q: [f64; 6] = [1e-4, 2e-4, 1e-4, 1e-6, 3e-6, 1e-6];

    fn config(formulation: Formulation, step: f64) -> FilterConfig {
        FilterConfig {
            formulation,
            covariance_step: step,
            lever_arm: Vector3::new(0.5, -0.3, 1.2),
            dvl_calibration: Some(CalibrationConfig::default()),
            ..FilterConfig::default()
        }
    }

    /// 3 s of a turning, accelerating vehicle with a zero-innovation DVL update every
    /// second (so that the state, and with it F, is the same whatever the noise);
    /// `discrete`: Mehra-like Q_d per sample instead of Q^c; `scale` multiplies q.
    fn run(cfg: &FilterConfig, discrete: bool, scale: f64, track: bool) -> Ekf {
        let mut ekf = Ekf::new(cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
        if track {
            ekf.track_sensitivity(Q);
        }
        let q = Q.map(|v| v * scale);
        let bias = cfg.bias_psd();
        let qd = Matrix15::from_diagonal(&Vector15::from_fn(|i, _| 1e-7 * (1 + i % 4) as f64));
        let sample = ImuSample::from_array(&[0.3, -0.2, -9.79, 0.01, 0.004, 0.05]);
        for k in 1..=300 {
            let noise = if discrete {
                ProcessNoise::Discrete(&qd)
            } else {
                ProcessNoise::Continuous {
                    imu_variance: &q,
                    bias_psd: &bias,
                }
            };
            ekf.propagate(&sample, 0.01, noise).unwrap();
            if k % 100 == 0 {
                ekf.bring_up_to_date();
                ekf.apply(&dvl_at_estimate(&ekf)).unwrap();
            }
        }
        ekf.bring_up_to_date();
        ekf
    }

    /// The largest relative difference of the 19 variances.
    fn variance_gap(a: &Ekf, b: &Ekf) -> f64 {
        let (pa, pb) = (
            a.calibration.as_ref().unwrap(),
            b.calibration.as_ref().unwrap(),
        );
        let (fa, fb) = (pa.assemble(&a.p), pb.assemble(&b.p));
        (0..19)
            .map(|i| (fa[(i, i)] - fb[(i, i)]).abs() / fb[(i, i)])
            .fold(0.0, f64::max)
    }

    #[test]
    fn longer_steps_approach_the_per_sample_covariance_as_they_shorten() {
        for formulation in [Formulation::Classic, Formulation::Invariant] {
            for discrete in [false, true] {
                let every = run(&config(formulation, 0.0), discrete, 1.0, false);
                let gap = |step| {
                    variance_gap(
                        &run(&config(formulation, step), discrete, 1.0, false),
                        &every,
                    )
                };
                // The per-sample filter is itself first order in its 0.01 s: the two
                // differ by about 1 % even at short steps (the paper's bias walks,
                // 1e-3 per second, make the lag of its noise visible).
                let (fine, coarse) = (gap(0.05), gap(0.5));
                assert!(fine < 0.02, "{formulation:?} {discrete}: {fine}");
                assert!(
                    fine < coarse,
                    "{formulation:?} {discrete}: {fine} vs {coarse}"
                );
                assert!(
                    gap(0.0149) == 0.0,
                    "under 1.5 samples: every sample, bit for bit"
                );
            }
        }
    }

    /// M = ∂P/∂λ stays exact over a step: P is affine in the accumulated noise.
    #[test]
    fn the_sensitivity_is_the_derivative_of_p_over_steps() {
        for formulation in [Formulation::Classic, Formulation::Invariant] {
            let cfg = config(formulation, 0.2);
            let tracked = run(&cfg, false, 1.3, true);
            let eps = 1e-3;
            let (up, down) = (
                run(&cfg, false, 1.3 + eps, false),
                run(&cfg, false, 1.3 - eps, false),
            );
            let fd = (up.p - down.p) / (2.0 * eps);
            let m = tracked.sensitivity_matrix().unwrap();
            assert!(
                (m - fd).abs().max() < 1e-6 * fd.abs().max(),
                "{formulation:?}"
            );
        }
    }

    #[test]
    fn reading_sigma_up_to_date_leaves_the_filter_alone() {
        let cfg = config(Formulation::Invariant, 0.1);
        let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
        let bias = cfg.bias_psd();
        let noise = ProcessNoise::Continuous {
            imu_variance: &Q,
            bias_psd: &bias,
        };
        let sample = ImuSample::from_array(&[0.3, -0.2, -9.79, 0.01, 0.004, 0.05]);
        for _ in 0..5 {
            ekf.propagate(&sample, 0.01, noise).unwrap();
        }
        let before = ekf.sigma();
        let now = ekf.sigma_up_to_date();
        assert_eq!(
            ekf.sigma(),
            before,
            "the copy was brought up to date, not the filter"
        );
        assert!(now[0] > before[0] && now[6] > before[6]);
        let mut closed = ekf.clone();
        closed.bring_up_to_date();
        assert_eq!(closed.sigma(), now);
        // Five more samples close the 0.1 s step on their own.
        for _ in 0..5 {
            ekf.propagate(&sample, 0.01, noise).unwrap();
        }
        assert!(ekf.step.is_none());
    }

    /// A q changed inside a step counts from its sample on: P is affine in the summed
    /// noise, so q_a for five samples and q_b for five gives the mean of the two
    /// filters' covariances (without updates the state, and with it F, is the same).
    #[test]
    fn a_q_changed_inside_a_step_counts_from_its_sample() {
        let cfg = FilterConfig {
            covariance_step: 0.1,
            ..FilterConfig::default()
        };
        let bias = cfg.bias_psd();
        let sample = ImuSample::from_array(&[0.3, -0.2, -9.79, 0.01, 0.004, 0.05]);
        let run = |first: &[f64; 6], second: &[f64; 6]| {
            let mut ekf =
                Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
            for k in 0..10 {
                let noise = ProcessNoise::Continuous {
                    imu_variance: if k < 5 { first } else { second },
                    bias_psd: &bias,
                };
                ekf.propagate(&sample, 0.01, noise).unwrap();
            }
            assert!(ekf.step.is_none(), "the tenth sample closes the step");
            ekf.p
        };
        let loud = Q.map(|v| 9.0 * v);
        let (quiet, noisy, mixed) = (run(&Q, &Q), run(&loud, &loud), run(&Q, &loud));
        // Against the part of P that q moves (the prior's variances are far larger).
        let moved = noisy - quiet;
        assert!(moved.abs().max() > 0.0, "q mattered");
        let off = (mixed - quiet - moved * 0.5).abs().max();
        assert!(off < 1e-6 * moved.abs().max(), "{off}");
    }
}
