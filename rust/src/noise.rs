//! Process-noise strategies behind one trait: constant Q^c, Mehra's
//! innovation-adaptive Q, and external Q set from outside at tuning instants (the
//! ProNet loop).
//!
//! `q` is always the per-sample variance of each IMU channel `[f_x, f_y, f_z, ω_x, ω_y,
//! ω_z]` in (m/s²)² and (rad/s)²; the filter turns it into the PSD `q·Δt_imu`.

use crate::ekf::{Matrix15, UpdateInfo};
use crate::error::{check, Error, Result};
use nalgebra::Matrix3;
use std::collections::VecDeque;

/// Process noise for one IMU step, as the filter consumes it.
#[derive(Clone, Copy, Debug)]
pub enum ProcessNoise<'a> {
    /// `Q^c = diag(q·Δt_imu, bias_psd)`, discretized by the filter as `Γ Q^c Γᵀ Δt`.
    Continuous {
        imu_variance: &'a [f64; 6],
        bias_psd: &'a [f64; 6],
    },
    /// A discrete 15×15 matrix added as it is at each IMU step.
    Discrete(&'a Matrix15),
}

/// A process-noise strategy: tells the filter its noise for the next step and sees
/// every measurement update.
pub trait NoiseStrategy: Send + Sync {
    /// Noise for the next IMU step.
    fn process_noise(&self) -> ProcessNoise<'_>;

    /// Called after every measurement update; `steps` is the number of IMU steps since
    /// the previous update.
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

    /// The IMU variances in force, where the strategy has them as such.
    fn imu_variance(&self) -> Option<[f64; 6]>;

    /// The discrete per-IMU-step Q_d in force, where the strategy sets Q_d directly
    /// (Mehra, once it has its innovations) rather than through Q^c.
    fn discrete_q(&self) -> Option<&Matrix15> {
        None
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
}

/// A strategy by value: what a Monte Carlo builds one of per run.
#[derive(Clone, Debug, PartialEq)]
pub enum StrategySpec {
    Constant { q: [f64; 6] },
    Mehra { window: usize, prior_q: [f64; 6] },
    External { prior_q: [f64; 6] },
}

impl StrategySpec {
    pub fn validate(&self) -> Result<()> {
        match self {
            StrategySpec::Constant { q } => check::non_negative("q", q),
            StrategySpec::Mehra { window, prior_q } => {
                if *window == 0 {
                    return Err(Error::invalid("window", "must be at least 1, got 0"));
                }
                check::non_negative("prior_q", prior_q)
            }
            StrategySpec::External { prior_q } => check::non_negative("prior_q", prior_q),
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
    fn specs_validate() {
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
