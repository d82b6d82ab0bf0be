//! Opt-in DVL error states: a scale factor and a three-axis mounting misalignment
//! between the DVL and the IMU (the calibration), and a time-correlated velocity error
//! per DVL axis, appended to the 15 error states (22 in all).
//!
//! The DVL reads `z = (1 + k) M v_b + b + n`, with `v_b = Cᵀ v + ω × r` the body-frame
//! velocity at the DVL, `k` the scale-factor error, `M = C_b^d` the rotation from the
//! body to the DVL's axes, `b` a first-order Gauss–Markov error in the DVL's axes
//! (`ḃ = −b/τ + w`, stationary 1σ `σ_b` per axis: a bottom-track bias, sound speed) and
//! `n` white. The estimate `M̂` carries the error `δμ` \[rad, body axes\] as
//! `M̂ = M (I + [δμ×])`, the scale the error `δk = k̂ − k`, the correlated error
//! `δb = b̂ − b`: state 15 is `δk`, states 16–18 are `δμ`, states 19–21 are `δb`.
//! `δk` and `δμ` are constants (optionally random walks), so their rows of F are zero;
//! `δb`'s are `−1/τ`. Propagation carries the cross-covariance `P_xc ← Φ P_xc Φ_ccᵀ`
//! and `P_cc ← Φ_cc P_cc Φ_ccᵀ + Q_c` with `Φ_cc = diag(1, 1, 1, 1, e, e, e)`,
//! `e = exp(−Δt/τ)`, the Gauss–Markov noise exact, `σ_b² (1 − e²)` (Gelb 1974, §4.2;
//! Groves 2013, §14.2.7), and the 15×15 block goes through the 15-state kernel
//! untouched. With `σ_b = 0` the correlated error stays exactly 0 (its rows of P are
//! zero, so is its gain) and the filter is the 19-state one. Every formula is in
//! `docs/reference/filter.md`.

use super::dynamics::ErrorDynamics;
use super::mounting::DvlMounting;
use super::state::Matrix15;
use super::transition::Transition;
use crate::attitude::{exp_so3, skew};
use crate::error::{check, Error, Result};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// The DVL error states: `[δk, δμ, δb]`.
pub const N_DVL: usize = 7;
/// Error states with the DVL error states appended.
pub const N_CALIBRATED: usize = 15 + N_DVL;
pub type Matrix19 = SMatrix<f64, N_CALIBRATED, N_CALIBRATED>;
pub type Rows3x19 = SMatrix<f64, 3, N_CALIBRATED>;
/// Covariance between the 15 navigation/bias errors and the DVL error states.
pub type Cross = SMatrix<f64, 15, N_DVL>;
/// Covariance of the DVL error states.
pub type DvlCov = SMatrix<f64, N_DVL, N_DVL>;
/// One value per DVL error state, `[δk, δμ, δb]` (or the estimates, σ, corrections).
pub type DvlErrors = [f64; N_DVL];

/// Offset of the scale-factor error in the full state vector.
pub const SCALE: usize = 15;
/// Offset of the misalignment errors `δμ` in the full state vector.
pub const MISALIGNMENT: usize = 16;
/// Offset of the correlated velocity errors `δb` in the full state vector.
pub const BIAS: usize = 19;
/// Offset of `δb` in the DVL error states.
const B: usize = BIAS - SCALE;

/// Prior and walks of the calibration states (see [`super::FilterConfig::dvl_calibration`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationConfig {
    /// Initial 1σ of the scale-factor error (0.01 = 1 %).
    pub scale_sigma: f64,
    /// Initial 1σ of the misalignment about body x, y, z \[rad\].
    pub misalignment_sigma: [f64; 3],
    /// Random-walk PSD of the scale factor \[1/s\] (0: a constant).
    pub scale_psd: f64,
    /// Random-walk PSD of each misalignment angle \[rad²/s\] (0: constants).
    pub misalignment_psd: f64,
    /// Whether the scale and misalignment are part of the model (false: held at their
    /// nominal values, σ 0, the correlated error alone estimated).
    pub calibrated: bool,
    /// Stationary 1σ of the DVL's correlated velocity error per DVL axis \[m/s\]
    /// (0: none; the prior is the same σ).
    pub bias_sigma: [f64; 3],
    /// Its correlation time τ \[s\].
    pub bias_time_constant: f64,
}

impl Default for CalibrationConfig {
    /// 1 % scale and 1° misalignment per axis, constants: a DVL installed with care
    /// but never calibrated against the IMU.
    fn default() -> Self {
        Self {
            scale_sigma: 0.01,
            misalignment_sigma: [1f64.to_radians(); 3],
            scale_psd: 0.0,
            misalignment_psd: 0.0,
            calibrated: true,
            bias_sigma: [0.0; 3],
            bias_time_constant: DEFAULT_BIAS_TIME_CONSTANT,
        }
    }
}

/// The correlated DVL error's τ where none is given \[s\] (unused while its σ is 0).
pub const DEFAULT_BIAS_TIME_CONSTANT: f64 = 60.0;

impl CalibrationConfig {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("dvl_scale_sigma", &[self.scale_sigma])?;
        check::non_negative("dvl_misalignment_sigma", &self.misalignment_sigma)?;
        check::non_negative("dvl_scale_psd", &[self.scale_psd])?;
        check::non_negative("dvl_misalignment_psd", &[self.misalignment_psd])?;
        check::non_negative("dvl_bias_sigma", &self.bias_sigma)?;
        check::positive("dvl_bias_time_constant", self.bias_time_constant)?;
        Ok(())
    }

    /// Whether the scale and misalignment are estimated ([`Self::calibrated`]).
    pub fn calibrates(&self) -> bool {
        self.calibrated
    }

    /// Whether the correlated velocity error is modelled (a σ above 0).
    pub fn correlated(&self) -> bool {
        self.bias_sigma.iter().any(|s| *s > 0.0)
    }

    /// The correlated error's transition over `dt` seconds, `e = exp(−Δt/τ)`.
    pub fn decay(&self, dt: f64) -> f64 {
        (-dt / self.bias_time_constant).exp()
    }

    /// `diag(σ²)` of `[δk, δμ, δb]`.
    fn p0(&self) -> DvlCov {
        let (m, b) = (self.misalignment_sigma, self.bias_sigma);
        let sigma = [self.scale_sigma, m[0], m[1], m[2], b[0], b[1], b[2]];
        DvlCov::from_diagonal(&SVector::from(sigma.map(|s| s * s)))
    }
}

/// The calibration part of the filter: the estimate and its covariance blocks.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    pub estimate: DvlMounting,
    /// `b̂`: the correlated velocity error's estimate \[m/s, DVL axes\].
    pub bias: Vector3<f64>,
    /// `P_xc`: covariance of the 15 navigation/bias errors with `[δk, δμ, δb]`.
    pub cross: Cross,
    /// `P_cc`: covariance of `[δk, δμ, δb]`.
    pub cov: DvlCov,
    cfg: CalibrationConfig,
}

impl Calibration {
    /// Start from the ideal mounting with the prior of `cfg`, uncorrelated with the
    /// navigation errors.
    pub fn new(cfg: &CalibrationConfig) -> Self {
        Self {
            estimate: DvlMounting::default(),
            bias: Vector3::zeros(),
            cross: Cross::zeros(),
            cov: cfg.p0(),
            cfg: *cfg,
        }
    }

    /// The same blocks zeroed: the start of the sensitivity `∂P/∂λ`, whose calibration
    /// blocks start at 0 like the rest.
    pub fn zeroed_like(&self) -> Self {
        Self {
            estimate: self.estimate,
            bias: self.bias,
            cross: Cross::zeros(),
            cov: DvlCov::zeros(),
            cfg: self.cfg,
        }
    }

    /// `[Φ P_xc Φ_ccᵀ, Φ_cc P_cc Φ_ccᵀ + Q_c]` over one step of the error dynamics
    /// (`with_noise`: add the walks' and the correlated error's noise; the sensitivity
    /// has none).
    pub(super) fn propagate(&mut self, dynamics: &ErrorDynamics, dt: f64, with_noise: bool) {
        // Without the correlated error its columns are zero and stay so: skipped.
        let columns = if self.cfg.correlated() { N_DVL } else { B };
        for j in 0..columns {
            let col: [f64; 15] = std::array::from_fn(|i| self.cross[(i, j)]);
            let fx = dynamics.apply(&col);
            for (i, v) in fx.iter().enumerate() {
                self.cross[(i, j)] += dt * v;
            }
        }
        self.decay(dt, with_noise);
        if with_noise {
            self.add_walks(dt);
        }
    }

    /// [`Self::propagate`] over a covariance step of `dt` seconds with transition `Φ`:
    /// `[Φ P_xc Φ_ccᵀ, Φ_cc P_cc Φ_ccᵀ + Q_c]`, the noise added whole after the
    /// transition (not half before and half after it as the 15 states' is): the walks'
    /// has no cross terms and Φ_cc is the identity on them, so it would not matter
    /// there, and the correlated error's is the exact discrete noise of the interval,
    /// `σ_b² (1 − e²)`, which halves would not be.
    pub(super) fn propagate_interval(&mut self, phi: &Transition, dt: f64, with_noise: bool) {
        phi.apply(&mut self.cross);
        self.decay(dt, with_noise);
        if with_noise {
            self.add_walks(dt);
        }
    }

    /// The correlated error's part of `Φ_cc` over `dt` seconds, `e = exp(−Δt/τ)`, on
    /// its columns of `P_xc` and its rows and columns of `P_cc`; with noise, its
    /// variance gains `σ_b² (1 − e²)` (nothing without the correlated error).
    fn decay(&mut self, dt: f64, with_noise: bool) {
        if !self.cfg.correlated() {
            return;
        }
        let e = self.cfg.decay(dt);
        for j in B..N_DVL {
            self.cross.column_mut(j).scale_mut(e);
            self.cov.column_mut(j).scale_mut(e);
            self.cov.row_mut(j).scale_mut(e);
        }
        if with_noise {
            for (i, s) in self.cfg.bias_sigma.iter().enumerate() {
                self.cov[(B + i, B + i)] += s * s * (1.0 - e * e);
            }
        }
    }

    /// The random walks' variance over `dt` seconds.
    fn add_walks(&mut self, dt: f64) {
        self.cov[(0, 0)] += self.cfg.scale_psd * dt;
        for i in 1..4 {
            self.cov[(i, i)] += self.cfg.misalignment_psd * dt;
        }
    }

    /// The full covariance `[[P, P_xc], [P_xcᵀ, P_cc]]`.
    pub fn assemble(&self, p: &Matrix15) -> Matrix19 {
        let mut full = Matrix19::zeros();
        full.fixed_view_mut::<15, 15>(0, 0).copy_from(p);
        full.fixed_view_mut::<15, N_DVL>(0, SCALE)
            .copy_from(&self.cross);
        full.fixed_view_mut::<N_DVL, 15>(SCALE, 0)
            .copy_from(&self.cross.transpose());
        full.fixed_view_mut::<N_DVL, N_DVL>(SCALE, SCALE)
            .copy_from(&self.cov);
        full
    }

    /// Take the blocks of a full covariance back: the 15×15 block into `p`.
    pub fn split(&mut self, full: &Matrix19, p: &mut Matrix15) {
        p.copy_from(&full.fixed_view::<15, 15>(0, 0));
        self.cross
            .copy_from(&full.fixed_view::<15, N_DVL>(0, SCALE));
        self.cov
            .copy_from(&full.fixed_view::<N_DVL, N_DVL>(SCALE, SCALE));
    }

    /// The reading predicted from the body-frame velocity at the DVL `v_b` and its
    /// Jacobian over the full error state, given the 15-state body-frame rows `h_body`
    /// (`∂v_b/∂δx`): `ẑ = (1 + k̂) M̂ v_b + b̂`,
    /// `H = [(1 + k̂) M̂ H_b, M̂ v_b, −(1 + k̂) M̂ [v_b×], I]`.
    pub fn measurement(
        &self,
        v_b: &Vector3<f64>,
        h_body: &SMatrix<f64, 3, 15>,
    ) -> (Vector3<f64>, Rows3x19) {
        let m = self.estimate.body_to_dvl;
        let gain = 1.0 + self.estimate.scale;
        let mut h = Rows3x19::zeros();
        h.fixed_view_mut::<3, 15>(0, 0)
            .copy_from(&(gain * (m * h_body)));
        h.fixed_view_mut::<3, 1>(0, SCALE).copy_from(&(m * v_b));
        h.fixed_view_mut::<3, 3>(0, MISALIGNMENT)
            .copy_from(&(-gain * (m * skew(v_b))));
        if self.cfg.correlated() {
            h.fixed_view_mut::<3, 3>(0, BIAS).fill_with_identity();
        }
        (self.estimate.reading(v_b) + self.bias, h)
    }

    /// A covariance of the body-frame velocity at the DVL \[(m/s)², body\] as the
    /// reading's \[DVL axes\]: `(1 + k̂)² M̂ Σ M̂ᵀ`, how [`Calibration::measurement`]
    /// carries a noise on `v_b`.
    pub fn body_noise_as_read(&self, sigma: &Matrix3<f64>) -> Matrix3<f64> {
        let (m, gain) = (self.estimate.body_to_dvl, 1.0 + self.estimate.scale);
        m * sigma * m.transpose() * (gain * gain)
    }

    /// Apply `[δk̂, δμ̂, δb̂]` (estimate minus truth): `k̂ ← k̂ − δk̂`,
    /// `M̂ ← M̂ exp(−[δμ̂×])`, `b̂ ← b̂ − δb̂`.
    pub fn feedback(&mut self, dc: &DvlErrors) {
        correct_dvl(&mut self.estimate, &mut self.bias, dc);
    }

    /// Whether the scale and misalignment are estimated
    /// ([`CalibrationConfig::calibrates`]).
    pub fn calibrates(&self) -> bool {
        self.cfg.calibrates()
    }

    /// 1σ of `[δk, δμ, δb]` (a negative rounding residue gives 0).
    pub fn sigma(&self) -> DvlErrors {
        std::array::from_fn(|i| self.cov[(i, i)].max(0.0).sqrt())
    }

    /// `[k̂, roll, pitch, yaw, b̂]`: the scale, the DVL's mounting angles \[rad\] and
    /// the correlated velocity error \[m/s, DVL axes\].
    pub fn reported(&self) -> DvlErrors {
        let a = self.estimate.angles();
        let b = self.bias;
        [self.estimate.scale, a[0], a[1], a[2], b[0], b[1], b[2]]
    }

    pub fn is_finite(&self) -> bool {
        self.estimate.scale.is_finite()
            && self.estimate.body_to_dvl.iter().all(|x| x.is_finite())
            && self.bias.iter().all(|x| x.is_finite())
            && (0..N_DVL).all(|i| self.cov[(i, i)].is_finite())
    }
}

/// Remove `[δk̂, δμ̂, δb̂]` (estimate minus truth) from the DVL error estimates:
/// `k̂ ← k̂ − δk̂`, `M̂ ← M̂ exp(−[δμ̂×])`, `b̂ ← b̂ − δb̂` (the filter's feedback, and
/// the smoother's).
pub fn correct_dvl(mounting: &mut DvlMounting, bias: &mut Vector3<f64>, dc: &DvlErrors) {
    mounting.scale -= dc[0];
    let mu = Vector3::new(dc[1], dc[2], dc[3]);
    mounting.body_to_dvl *= exp_so3(&(-mu));
    *bias -= Vector3::new(dc[B], dc[B + 1], dc[B + 2]);
}

/// `Err` unless the DVL error states of `cfg` can be estimated with this aiding: they
/// describe a DVL measuring in its own axes.
pub fn check_aiding(cfg: &CalibrationConfig, body: bool) -> Result<()> {
    match (body, cfg.calibrates()) {
        (true, _) => Ok(()),
        (false, true) => Err(Error::invalid(
            "dvl_calibration",
            "the DVL calibration states need body-frame aiding (aiding=\"body\")",
        )),
        (false, false) => Err(Error::invalid(
            "dvl_bias_sigma",
            "the DVL's correlated velocity error lies in its own axes: it needs \
             body-frame aiding (aiding=\"body\")",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feedback_removes_the_error_it_is_given() {
        let truth = DvlMounting::from_angles(0.004, [0.002, -0.001, 0.009]);
        let mut c = Calibration::new(&CalibrationConfig::default());
        let m = c.estimate.error_from(&truth);
        c.bias = Vector3::new(0.01, -0.02, 0.003);
        let e = [m[0], m[1], m[2], m[3], 0.01, -0.02, 0.003];
        c.feedback(&e);
        assert_eq!(c.bias, Vector3::zeros());
        let left = c.estimate.error_from(&truth);
        assert!(left[0].abs() < 1e-18, "{left:?}");
        assert!(left[1..].iter().all(|x| x.abs() < 1e-15), "{left:?}");
    }

    #[test]
    fn assemble_and_split_round_trip() {
        let mut c = Calibration::new(&CalibrationConfig::default());
        c.cross = Cross::from_fn(|i, j| (i * N_DVL + j) as f64 * 1e-3);
        let p = Matrix15::from_fn(|i, j| if i == j { 1.0 + i as f64 } else { 0.01 });
        let full = c.assemble(&p);
        assert_eq!(full, full.transpose());
        let mut back = Matrix15::zeros();
        let mut d = c.clone();
        d.cross = Cross::zeros();
        d.cov = DvlCov::zeros();
        d.split(&full, &mut back);
        assert_eq!((back, d.cross, d.cov), (p, c.cross, c.cov));
    }

    /// The correlated error's discrete model is exact: from its stationary variance
    /// it stays there, whatever the step, and its covariance with any other state
    /// decays by `exp(−t/τ)`; without it nothing moves.
    #[test]
    fn the_correlated_error_is_a_first_order_gauss_markov_process() {
        let cfg = CalibrationConfig {
            bias_sigma: [0.02, 0.03, 0.01],
            bias_time_constant: 40.0,
            ..CalibrationConfig::default()
        };
        let phi = Transition::second_order(&SMatrix::zeros()); // Φ = I on the 15
        let mut c = Calibration::new(&cfg);
        c.cross[(4, B)] = 1e-3;
        c.cov[(0, B + 1)] = 1e-5;
        c.cov[(B + 1, 0)] = 1e-5;
        let (cross, cov) = (c.cross, c.cov);
        for dt in [0.01, 0.1, 0.5, 2.0, 0.37] {
            c.propagate_interval(&phi, dt, true);
        }
        let e = (-2.98f64 / 40.0).exp();
        for i in 0..3 {
            let v = cfg.bias_sigma[i].powi(2);
            assert!((c.cov[(B + i, B + i)] - v).abs() <= 1e-15 * v, "{i}");
        }
        assert!((c.cross[(4, B)] - e * cross[(4, B)]).abs() <= 1e-15);
        assert!((c.cov[(0, B + 1)] - e * cov[(0, B + 1)]).abs() <= 1e-18);
        assert_eq!(c.cov[(0, B + 1)], c.cov[(B + 1, 0)]);
        assert_eq!(c.cov[(0, 0)], cov[(0, 0)]); // the constants untouched
        let mut off = Calibration::new(&CalibrationConfig::default());
        off.cross[(4, B)] = 1e-3; // not a state here: left as it is
        let before = off.clone();
        off.propagate_interval(&phi, 1.0, true);
        assert_eq!(off, before);
    }

    #[test]
    fn config_is_checked() {
        assert!(CalibrationConfig::default().validate().is_ok());
        let bad = CalibrationConfig {
            scale_sigma: -0.1,
            ..CalibrationConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("dvl_scale_sigma"));
        let bad = CalibrationConfig {
            misalignment_psd: f64::NAN,
            ..CalibrationConfig::default()
        };
        assert!(bad.validate().is_err());
        let cal = CalibrationConfig::default();
        assert!(check_aiding(&cal, false).is_err() && check_aiding(&cal, true).is_ok());
        let bias = CalibrationConfig {
            scale_sigma: 0.0,
            misalignment_sigma: [0.0; 3],
            calibrated: false,
            bias_sigma: [0.1; 3],
            ..cal
        };
        let e = check_aiding(&bias, false).unwrap_err().to_string();
        assert!(e.starts_with("dvl_bias_sigma"), "{e}");
        let bad = CalibrationConfig {
            bias_time_constant: 0.0,
            ..CalibrationConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("dvl_bias_time_constant"));
        let bad = CalibrationConfig {
            bias_sigma: [0.0, -1.0, 0.0],
            ..CalibrationConfig::default()
        };
        assert!(bad.validate().is_err());
    }
}
