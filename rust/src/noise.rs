//! Process-noise strategies behind one trait: constant Q^c, Mehra's
//! innovation-adaptive Q, the robust covariance-matching [`AdaptiveQ`], the simulation's
//! true variance ([`StrategySpec::Oracle`], the ceiling), and external Q set from outside
//! at tuning instants (the ProNet loop).
//!
//! `q` is always the per-sample variance of each IMU channel `[f_x, f_y, f_z, ω_x, ω_y,
//! ω_z]` in (m/s²)² and (rad/s)²; the filter turns it into the PSD `q·Δt_imu`.

use crate::ekf::{Matrix15, ProcessNoise, UpdateInfo};
use crate::error::{check, Error, Result};
use nalgebra::Matrix3;
use std::collections::VecDeque;

/// A process-noise strategy: tells the filter its noise for the next step and sees
/// every measurement update.
pub trait NoiseStrategy: Send + Sync + CloneStrategy {
    /// Noise for the next IMU step.
    fn process_noise(&self) -> ProcessNoise<'_>;

    /// Called after every measurement update; `steps`: IMU steps since the previous one.
    fn after_update(&mut self, _update: &UpdateInfo, _steps: usize) {}

    /// Replace the IMU noise variances (only strategies that accept outside tuning).
    fn set_imu_variance(&mut self, _q: &[f64; 6]) -> Result<()> {
        Err(Error::invalid(
            "strategy",
            "this strategy does not take q from outside; use an external strategy",
        ))
    }

    /// Whether [`NoiseStrategy::set_imu_variance`] is accepted.
    fn takes_outside_q(&self) -> bool {
        false
    }

    /// Whether the strategy is told the simulated IMU's true variance before every
    /// step ([`NoiseStrategy::set_true_variance`]); only the oracle is.
    fn wants_true_variance(&self) -> bool {
        false
    }

    /// The true IMU variances of the next sample (called only when
    /// [`NoiseStrategy::wants_true_variance`]).
    fn set_true_variance(&mut self, _q: &[f64; 6]) {}

    /// The IMU variances `q` whose common scale λ the filter should carry the sensitivity
    /// `∂P/∂λ` of (see `Ekf::track_sensitivity`); None for all but [`AdaptiveQ`].
    fn sensitivity_q(&self) -> Option<[f64; 6]> {
        None
    }

    /// The IMU variances in force, where the strategy has them as such.
    fn imu_variance(&self) -> Option<[f64; 6]>;

    /// The discrete per-IMU-step Q_d in force, where the strategy sets Q_d directly
    /// (Mehra, once it has its innovations) rather than through Q^c.
    fn discrete_q(&self) -> Option<&Matrix15> {
        None
    }
    /// Whether it may set Q_d itself (a pass keeps it at every velocity update).
    fn sets_discrete_q(&self) -> bool {
        false
    }
}

/// A copy of a strategy in its present state (a navigator's checkpoint, to run a stretch
/// again): every strategy that is `Clone`.
pub trait CloneStrategy {
    fn clone_box(&self) -> Box<dyn NoiseStrategy>;
}

impl<T: NoiseStrategy + Clone + 'static> CloneStrategy for T {
    fn clone_box(&self) -> Box<dyn NoiseStrategy> {
        Box::new(self.clone())
    }
}

/// Fixed Q^c.
#[derive(Clone, Debug)]
pub struct ConstantQ {
    q: [f64; 6],
    bias_psd: [f64; 6],
}

impl ConstantQ {
    pub fn new(q: [f64; 6], bias_psd: [f64; 6]) -> Self {
        Self { q, bias_psd }
    }
}

impl NoiseStrategy for ConstantQ {
    fn process_noise(&self) -> ProcessNoise<'_> {
        ProcessNoise::Continuous {
            imu_variance: &self.q,
            bias_psd: &self.bias_psd,
        }
    }

    fn imu_variance(&self) -> Option<[f64; 6]> {
        Some(self.q)
    }
}

/// Q^c whose IMU variances are set from outside (the ProNet regressor); bias PSDs stay.
#[derive(Clone, Debug)]
pub struct ExternalQ {
    inner: ConstantQ,
}

impl NoiseStrategy for ExternalQ {
    fn process_noise(&self) -> ProcessNoise<'_> {
        self.inner.process_noise()
    }

    fn set_imu_variance(&mut self, q: &[f64; 6]) -> Result<()> {
        check::non_negative("q", q)?;
        self.inner.q = *q;
        Ok(())
    }

    fn takes_outside_q(&self) -> bool {
        true
    }

    fn imu_variance(&self) -> Option<[f64; 6]> {
        Some(self.inner.q)
    }
}

/// Mehra's innovation-adaptive process noise with window ξ:
/// `Q̂ = K C Kᵀ`, `C = (1/ξ) Σ ν νᵀ` over the last ξ innovations. Q̂ is the discrete
/// noise of one DVL interval; each of the n IMU steps of the last interval adds Q̂/n.
/// Until ξ innovations exist the prior constant Q^c is used.
#[derive(Clone, Debug)]
pub struct MehraQ {
    window: usize,
    prior: ConstantQ,
    innovations: VecDeque<nalgebra::Vector3<f64>>,
    per_step: Option<Matrix15>,
}

impl NoiseStrategy for MehraQ {
    fn process_noise(&self) -> ProcessNoise<'_> {
        match &self.per_step {
            Some(q) => ProcessNoise::Discrete(q),
            None => self.prior.process_noise(),
        }
    }

    fn after_update(&mut self, update: &UpdateInfo, steps: usize) {
        if self.innovations.len() == self.window {
            self.innovations.pop_front();
        }
        self.innovations.push_back(update.innovation);
        if self.innovations.len() == self.window {
            let c = self
                .innovations
                .iter()
                .fold(Matrix3::zeros(), |acc, v| acc + v * v.transpose())
                / self.window as f64;
            let q = update.gain * c * update.gain.transpose();
            self.per_step = Some(q / steps.max(1) as f64);
        }
    }

    fn imu_variance(&self) -> Option<[f64; 6]> {
        match self.per_step {
            None => self.prior.imu_variance(),
            Some(_) => None,
        }
    }

    fn discrete_q(&self) -> Option<&Matrix15> {
        self.per_step.as_ref()
    }
    fn sets_discrete_q(&self) -> bool {
        true
    }
}

/// The simulation's true IMU variance, set before every step: the ceiling of any
/// strategy that estimates q (only a simulation knows it).
#[derive(Clone, Debug)]
pub struct OracleQ {
    inner: ConstantQ,
}

impl NoiseStrategy for OracleQ {
    fn process_noise(&self) -> ProcessNoise<'_> {
        self.inner.process_noise()
    }

    fn wants_true_variance(&self) -> bool {
        true
    }

    fn set_true_variance(&mut self, q: &[f64; 6]) {
        self.inner.q = *q;
    }

    fn imu_variance(&self) -> Option<[f64; 6]> {
        Some(self.inner.q)
    }
}

/// Bounds of the adaptive scale λ on the prior q: three decades either way.
pub const ADAPTIVE_SCALE_MIN: f64 = 1e-3;
pub const ADAPTIVE_SCALE_MAX: f64 = 1e3;

/// Robust innovation-adaptive IMU noise by covariance matching, with Q's structure kept:
/// the six IMU variances are `q = λ·prior_q` (full rank; the bias PSDs stay as
/// configured), and λ is estimated from the DVL innovations.
///
/// With `S_k = H P⁻ Hᵀ + R` the filter's innovation covariance at update k and
/// `M_k = ∂P⁻/∂λ` the sensitivity the filter carries beside P (`Ekf::track_sensitivity`),
/// `S(λ) ≈ S_k + (λ − λ_k) S'_k`, `S'_k = H M_k Hᵀ + ∂R/∂λ` (the update's report; `∂R/∂λ`
/// the DVL lever arm's gyro-noise term). Matching the expected NIS of a filter with the
/// true λ, `E[ν_kᵀ S_k⁻¹ ν_k] ≈ tr(S_k⁻¹ S(λ))`, gives one linear equation per update,
/// `a_k := NIS_k − 3 + λ_k b_k = λ b_k + e_k` with `b_k = tr(S_k⁻¹ S'_k)` and `e_k`
/// of variance 6 (the NIS is χ² with 3 dof). Its least-squares solution over an
/// exponentially forgetting window (factor `1 − 1/window`) is `λ̂ = Σ b_k a_k / Σ b_k²`
/// with standard error `σ = √(6 / Σ b_k²)`.
///
/// Robustness: where the innovations say little about q (the process noise's share of S
/// is small, so σ is large), λ̂ wanders far from the truth. The estimate is therefore
/// shrunk towards the prior by its own evidence (positive-part James–Stein): with
/// `d = λ̂ − 1`, `λ = 1 + d·max(0, 1 − σ²/d²)`, so the prior holds unless the data
/// depart from it by more than one standard error. λ is then projected onto
/// [[`ADAPTIVE_SCALE_MIN`], [`ADAPTIVE_SCALE_MAX`]]. Until `window` updates have been
/// seen the prior holds.
#[derive(Clone, Debug)]
pub struct AdaptiveQ {
    prior: [f64; 6],
    current: ConstantQ,
    lambda: f64,
    window: usize,
    forget: f64,
    /// Forgetting sums `Σ b_k a_k` and `Σ b_k²`.
    sum_ba: f64,
    sum_bb: f64,
    updates: usize,
}

impl AdaptiveQ {
    /// The scale λ on the prior q in force.
    pub fn scale(&self) -> f64 {
        self.lambda
    }
}

impl NoiseStrategy for AdaptiveQ {
    fn process_noise(&self) -> ProcessNoise<'_> {
        self.current.process_noise()
    }

    fn after_update(&mut self, update: &UpdateInfo, _steps: usize) {
        let Some(hmh) = update.sensitivity else {
            return;
        };
        let Some(s_inv) = update.s.cholesky().map(|c| c.inverse()) else {
            return;
        };
        let b = (s_inv * hmh).trace();
        if !(b.is_finite() && update.nis.is_finite()) {
            return;
        }
        let a = update.nis - 3.0 + self.lambda * b;
        self.sum_ba = self.forget * self.sum_ba + b * a;
        self.sum_bb = self.forget * self.sum_bb + b * b;
        self.updates += 1;
        if self.updates >= self.window && self.sum_bb > 0.0 {
            let d = self.sum_ba / self.sum_bb - 1.0;
            let variance = 6.0 / self.sum_bb;
            let shrink = if d * d > variance {
                1.0 - variance / (d * d)
            } else {
                0.0
            };
            self.lambda = (1.0 + d * shrink).clamp(ADAPTIVE_SCALE_MIN, ADAPTIVE_SCALE_MAX);
            self.current.q = self.prior.map(|v| v * self.lambda);
        }
    }

    fn sensitivity_q(&self) -> Option<[f64; 6]> {
        Some(self.prior)
    }

    fn imu_variance(&self) -> Option<[f64; 6]> {
        Some(self.current.q)
    }
}

/// A strategy by value: what a Monte Carlo builds one of per run.
#[derive(Clone, Debug, PartialEq)]
pub enum StrategySpec {
    Constant {
        q: [f64; 6],
    },
    Mehra {
        window: usize,
        prior_q: [f64; 6],
    },
    External {
        prior_q: [f64; 6],
    },
    /// The simulated IMU's true variance at every step.
    Oracle,
    /// [`AdaptiveQ`] over `window` DVL updates, starting from `prior_q`.
    Adaptive {
        window: usize,
        prior_q: [f64; 6],
    },
}

impl StrategySpec {
    pub fn validate(&self) -> Result<()> {
        match self {
            StrategySpec::Constant { q } => check::non_negative("q", q),
            StrategySpec::Mehra { window, prior_q }
            | StrategySpec::Adaptive { window, prior_q } => {
                if *window == 0 {
                    return Err(Error::invalid("window", "must be at least 1, got 0"));
                }
                check::non_negative("prior_q", prior_q)
            }
            StrategySpec::External { prior_q } => check::non_negative("prior_q", prior_q),
            StrategySpec::Oracle => Ok(()),
        }
    }

    /// A fresh strategy with the filter's bias random-walk PSDs.
    pub fn build(&self, bias_psd: [f64; 6]) -> Box<dyn NoiseStrategy> {
        match self {
            StrategySpec::Constant { q } => Box::new(ConstantQ::new(*q, bias_psd)),
            StrategySpec::Mehra { window, prior_q } => Box::new(MehraQ {
                window: *window,
                prior: ConstantQ::new(*prior_q, bias_psd),
                // Reserved up to a bound: an absurd window must not allocate terabytes.
                innovations: VecDeque::with_capacity((*window).min(4096)),
                per_step: None,
            }),
            StrategySpec::External { prior_q } => Box::new(ExternalQ {
                inner: ConstantQ::new(*prior_q, bias_psd),
            }),
            StrategySpec::Oracle => Box::new(OracleQ {
                inner: ConstantQ::new([0.0; 6], bias_psd),
            }),
            StrategySpec::Adaptive { window, prior_q } => Box::new(AdaptiveQ {
                prior: *prior_q,
                current: ConstantQ::new(*prior_q, bias_psd),
                lambda: 1.0,
                window: *window,
                forget: 1.0 - 1.0 / *window as f64,
                sum_ba: 0.0,
                sum_bb: 0.0,
                updates: 0,
            }),
        }
    }

    pub fn is_external(&self) -> bool {
        matches!(self, StrategySpec::External { .. })
    }

    /// Short label, e.g. `constant`, `mehra(5)`, `external`.
    pub fn label(&self) -> String {
        match self {
            StrategySpec::Constant { .. } => "constant".into(),
            StrategySpec::Mehra { window, .. } => format!("mehra({window})"),
            StrategySpec::External { .. } => "external".into(),
            StrategySpec::Oracle => "oracle".into(),
            StrategySpec::Adaptive { window, .. } => format!("adaptive({window})"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ekf::Gain;
    use nalgebra::Vector3;

    fn update(nu: Vector3<f64>) -> UpdateInfo {
        let mut gain = Gain::zeros();
        for i in 0..3 {
            gain[(3 + i, i)] = 0.5;
        }
        UpdateInfo {
            innovation: nu,
            s: Matrix3::identity(),
            nis: nu.norm_squared(),
            gain,
            accepted: true,
            sensitivity: None,
            correction: None,
            calibration_correction: None,
        }
    }

    #[test]
    fn constant_reports_its_q() {
        let s = StrategySpec::Constant {
            q: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        }
        .build([0.1; 6]);
        match s.process_noise() {
            ProcessNoise::Continuous {
                imu_variance,
                bias_psd,
            } => {
                assert_eq!(imu_variance[2], 3.0);
                assert_eq!(bias_psd[5], 0.1);
            }
            ProcessNoise::Discrete(_) => panic!("constant must be continuous"),
        }
    }

    #[test]
    fn mehra_waits_for_its_window_then_uses_k_c_kt_spread_over_the_interval() {
        let mut s = StrategySpec::Mehra {
            window: 2,
            prior_q: [1e-4; 6],
        }
        .build([0.0; 6]);
        s.after_update(&update(Vector3::new(1.0, 0.0, 0.0)), 100);
        assert!(matches!(s.process_noise(), ProcessNoise::Continuous { .. }));
        s.after_update(&update(Vector3::new(0.0, 2.0, 0.0)), 100);
        match s.process_noise() {
            ProcessNoise::Discrete(q) => {
                // C = diag(0.5, 2, 0); K C Kᵀ = 0.25 C on the velocity block; /100 steps.
                assert!((q[(3, 3)] - 0.25 * 0.5 / 100.0).abs() < 1e-15);
                assert!((q[(4, 4)] - 0.25 * 2.0 / 100.0).abs() < 1e-15);
                assert_eq!(q[(5, 5)], 0.0);
                assert_eq!(q[(0, 0)], 0.0);
            }
            ProcessNoise::Continuous { .. } => panic!("window is full"),
        }
        // The window slides: the oldest innovation drops out.
        s.after_update(&update(Vector3::new(0.0, 0.0, 0.0)), 50);
        match s.process_noise() {
            ProcessNoise::Discrete(q) => {
                assert_eq!(q[(3, 3)], 0.0);
                // C = ν νᵀ / 2 with ν = (0, 2, 0): diag(0, 2, 0).
                assert!((q[(4, 4)] - 0.25 * 2.0 / 50.0).abs() < 1e-15);
            }
            ProcessNoise::Continuous { .. } => panic!(),
        }
    }

    #[test]
    fn only_external_takes_q_from_outside() {
        let mut e = StrategySpec::External { prior_q: [1e-3; 6] }.build([0.0; 6]);
        e.set_imu_variance(&[2e-3; 6]).unwrap();
        assert_eq!(e.imu_variance(), Some([2e-3; 6]));
        assert!(e.set_imu_variance(&[-1.0; 6]).is_err());
        assert!(e.takes_outside_q());
        let mut c = StrategySpec::Constant { q: [1e-3; 6] }.build([0.0; 6]);
        assert!(c.set_imu_variance(&[2e-3; 6]).is_err());
        assert!(!c.takes_outside_q());
    }

    #[test]
    fn oracle_takes_the_true_variance_and_nothing_from_outside() {
        let mut s = StrategySpec::Oracle.build([0.0; 6]);
        assert!(s.wants_true_variance());
        s.set_true_variance(&[3e-4; 6]);
        assert_eq!(s.imu_variance(), Some([3e-4; 6]));
        assert!(s.set_imu_variance(&[1.0; 6]).is_err());
    }

    #[test]
    fn adaptive_solves_the_linearised_nis_matching_and_shrinks_by_its_evidence() {
        let prior = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
        let mut s = StrategySpec::Adaptive {
            window: 2,
            prior_q: prior,
        }
        .build([0.0; 6]);
        assert_eq!(s.sensitivity_q(), Some(prior));
        // S = I and H M Hᵀ = 2 I: b = 6 at every update. NIS 40 then 31 (λ_k = 1):
        // a = 43, 34; β = 1/2: λ̂ = (β·6·43 + 6·34) / (β·36 + 36) = 333 / 54,
        // σ² = 6 / 54, d = λ̂ − 1: λ = 1 + d (1 − σ²/d²).
        let mut u = update(Vector3::new(40f64.sqrt(), 0.0, 0.0));
        u.sensitivity = Some(Matrix3::identity() * 2.0);
        s.after_update(&u, 100);
        assert_eq!(s.imu_variance(), Some(prior), "the window is not full yet");
        u.nis = 31.0;
        s.after_update(&u, 100);
        let d = 333.0 / 54.0 - 1.0;
        let lambda = 1.0 + d * (1.0 - 6.0 / 54.0 / (d * d));
        let q = s.imu_variance().unwrap();
        assert!((q[0] / prior[0] - lambda).abs() < 1e-12, "{q:?} {lambda}");
        assert!((q[5] / prior[5] - lambda).abs() < 1e-12, "structure kept");
        // Innovations far smaller than predicted: λ is held at its floor, never 0.
        u.nis = 0.0;
        for _ in 0..50 {
            s.after_update(&u, 100);
        }
        assert_eq!(s.imu_variance().unwrap()[0], prior[0] * ADAPTIVE_SCALE_MIN);
        // Without a sensitivity (an untracked filter) nothing changes.
        u.sensitivity = None;
        u.nis = 1e6;
        s.after_update(&u, 100);
        assert_eq!(s.imu_variance().unwrap()[0], prior[0] * ADAPTIVE_SCALE_MIN);
    }

    #[test]
    fn adaptive_keeps_the_prior_where_the_innovations_say_little() {
        let prior = [1e-4; 6];
        let mut s = StrategySpec::Adaptive {
            window: 10,
            prior_q: prior,
        }
        .build([0.0; 6]);
        // b = 0.03, so λ̂ over the window has σ ≈ 25; the NIS alternates between 5.5
        // and 0.5 (mean 3), which moves λ̂ by up to ±10: no evidence, the prior holds.
        let mut u = update(Vector3::new(1.0, 0.0, 0.0));
        u.sensitivity = Some(Matrix3::identity() * 0.01);
        for k in 0..40 {
            u.nis = if k % 2 == 0 { 5.5 } else { 0.5 };
            s.after_update(&u, 100);
            assert_eq!(s.imu_variance(), Some(prior), "update {k}");
        }
    }

    #[test]
    fn specs_validate() {
        assert!(StrategySpec::Adaptive {
            window: 0,
            prior_q: [1.0; 6]
        }
        .validate()
        .is_err());
        assert!(StrategySpec::Mehra {
            window: 0,
            prior_q: [0.0; 6]
        }
        .validate()
        .is_err());
        assert!(StrategySpec::Constant { q: [f64::NAN; 6] }
            .validate()
            .is_err());
        assert!(StrategySpec::External { prior_q: [1.0; 6] }
            .validate()
            .is_ok());
    }
}
