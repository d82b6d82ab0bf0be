//! Opt-in DVL calibration states: a scale factor and a three-axis mounting misalignment
//! between the DVL and the IMU, appended to the 15 error states (19 in all).
//!
//! The DVL reads `z = (1 + k) M v_b + n`, with `v_b = Cᵀ v + ω × r` the body-frame
//! velocity at the DVL, `k` the scale-factor error and `M = C_b^d` the rotation from the
//! body to the DVL's axes. The estimate `M̂` carries the error `δμ` \[rad, body axes\]
//! as `M̂ = M (I + [δμ×])`, the scale the error `δk = k̂ − k`: state 15 is `δk`,
//! states 16..19 are `δμ`. Both are constants (optionally random walks), so their rows
//! of F are zero: propagation carries the cross-covariance `P_xc ← Φ P_xc` and leaves
//! `P_cc` unchanged (plus the walks' PSDs), and the 15×15 block goes through the
//! 15-state kernel untouched. Every formula is in `docs/reference/filter.md`.

use super::dynamics::ErrorDynamics;
use super::mounting::DvlMounting;
use super::state::Matrix15;
use super::transition::Transition;
use crate::attitude::{exp_so3, skew};
use crate::error::{check, Error, Result};
use nalgebra::{Matrix4, SMatrix, Vector3, Vector4};

/// Error states with the calibration appended.
pub const N_CALIBRATED: usize = 19;
pub type Matrix19 = SMatrix<f64, N_CALIBRATED, N_CALIBRATED>;
pub type Rows3x19 = SMatrix<f64, 3, N_CALIBRATED>;
/// Covariance between the 15 navigation/bias errors and the 4 calibration errors.
pub type Cross = SMatrix<f64, 15, 4>;

/// Offset of the scale-factor error in the 19-state vector.
pub const SCALE: usize = 15;
/// Offset of the misalignment errors `δμ` in the 19-state vector.
pub const MISALIGNMENT: usize = 16;

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
        }
    }
}

impl CalibrationConfig {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("dvl_scale_sigma", &[self.scale_sigma])?;
        check::non_negative("dvl_misalignment_sigma", &self.misalignment_sigma)?;
        check::non_negative("dvl_scale_psd", &[self.scale_psd])?;
        check::non_negative("dvl_misalignment_psd", &[self.misalignment_psd])?;
        Ok(())
    }

    /// `diag(σ²)` of `[δk, δμ]`.
    fn p0(&self) -> Matrix4<f64> {
        let m = self.misalignment_sigma;
        Matrix4::from_diagonal(&Vector4::new(
            self.scale_sigma.powi(2),
            m[0] * m[0],
            m[1] * m[1],
            m[2] * m[2],
        ))
    }
}

/// The calibration part of the filter: the estimate and its covariance blocks.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    pub estimate: DvlMounting,
    /// `P_xc`: covariance of the 15 navigation/bias errors with `[δk, δμ]`.
    pub cross: Cross,
    /// `P_cc`: covariance of `[δk, δμ]`.
    pub cov: Matrix4<f64>,
    cfg: CalibrationConfig,
}

impl Calibration {
    /// Start from the ideal mounting with the prior of `cfg`, uncorrelated with the
    /// navigation errors.
    pub fn new(cfg: &CalibrationConfig) -> Self {
        Self {
            estimate: DvlMounting::default(),
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
            cross: Cross::zeros(),
            cov: Matrix4::zeros(),
            cfg: self.cfg,
        }
    }

    /// `[Φ P_xc, P_cc + Q_c Δt]` over one step of the error dynamics (`with_noise`:
    /// add the walks' PSDs; the sensitivity has no calibration noise).
    pub(super) fn propagate(&mut self, dynamics: &ErrorDynamics, dt: f64, with_noise: bool) {
        for j in 0..4 {
            let col: [f64; 15] = std::array::from_fn(|i| self.cross[(i, j)]);
            let fx = dynamics.apply(&col);
            for (i, v) in fx.iter().enumerate() {
                self.cross[(i, j)] += dt * v;
            }
        }
        if with_noise {
            self.add_walks(dt);
        }
    }

    /// [`Self::propagate`] over a covariance step of `dt` seconds with transition `Φ`:
    /// `[Φ P_xc, P_cc + Q_c Δt]` (Φ is the identity on these states and the noise has no
    /// cross terms, so the half-and-half noise of a covariance step changes nothing here).
    pub(super) fn propagate_interval(&mut self, phi: &Transition, dt: f64, with_noise: bool) {
        phi.apply(&mut self.cross);
        if with_noise {
            self.add_walks(dt);
        }
    }

    /// The random walks' variance over `dt` seconds.
    fn add_walks(&mut self, dt: f64) {
        self.cov[(0, 0)] += self.cfg.scale_psd * dt;
        for i in 1..4 {
            self.cov[(i, i)] += self.cfg.misalignment_psd * dt;
        }
    }

    /// The 19×19 covariance `[[P, P_xc], [P_xcᵀ, P_cc]]`.
    pub fn assemble(&self, p: &Matrix15) -> Matrix19 {
        let mut full = Matrix19::zeros();
        full.fixed_view_mut::<15, 15>(0, 0).copy_from(p);
        full.fixed_view_mut::<15, 4>(0, SCALE)
            .copy_from(&self.cross);
        full.fixed_view_mut::<4, 15>(SCALE, 0)
            .copy_from(&self.cross.transpose());
        full.fixed_view_mut::<4, 4>(SCALE, SCALE)
            .copy_from(&self.cov);
        full
    }

    /// Take the blocks of a 19×19 covariance back: the 15×15 block into `p`.
    pub fn split(&mut self, full: &Matrix19, p: &mut Matrix15) {
        p.copy_from(&full.fixed_view::<15, 15>(0, 0));
        self.cross.copy_from(&full.fixed_view::<15, 4>(0, SCALE));
        self.cov.copy_from(&full.fixed_view::<4, 4>(SCALE, SCALE));
    }

    /// The reading predicted from the body-frame velocity at the DVL `v_b` and its
    /// Jacobian over the 19 errors, given the 15-state body-frame rows `h_body`
    /// (`∂v_b/∂δx`): `ẑ = (1 + k̂) M̂ v_b`, `H = [(1 + k̂) M̂ H_b, M̂ v_b, −(1 + k̂) M̂ [v_b×]]`.
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
        (self.estimate.reading(v_b), h)
    }

    /// Apply `[δk̂, δμ̂]` (estimate minus truth): `k̂ ← k̂ − δk̂`, `M̂ ← M̂ exp(−[δμ̂×])`.
    pub fn feedback(&mut self, dc: &[f64; 4]) {
        correct_mounting(&mut self.estimate, dc);
    }

    /// 1σ of `[δk, δμ]` (a negative rounding residue gives 0).
    pub fn sigma(&self) -> [f64; 4] {
        std::array::from_fn(|i| self.cov[(i, i)].max(0.0).sqrt())
    }

    /// `[k̂, roll, pitch, yaw]`: the scale and the DVL's mounting angles \[rad\].
    pub fn reported(&self) -> [f64; 4] {
        let a = self.estimate.angles();
        [self.estimate.scale, a[0], a[1], a[2]]
    }

    pub fn is_finite(&self) -> bool {
        self.estimate.scale.is_finite()
            && self.estimate.body_to_dvl.iter().all(|x| x.is_finite())
            && (0..4).all(|i| self.cov[(i, i)].is_finite())
    }
}

/// Remove `[δk̂, δμ̂]` (estimate minus truth) from a DVL mounting estimate:
/// `k̂ ← k̂ − δk̂`, `M̂ ← M̂ exp(−[δμ̂×])` (the filter's feedback, and the smoother's).
pub fn correct_mounting(mounting: &mut DvlMounting, dc: &[f64; 4]) {
    mounting.scale -= dc[0];
    let mu = Vector3::new(dc[1], dc[2], dc[3]);
    mounting.body_to_dvl *= exp_so3(&(-mu));
}

/// `Err` unless the calibration can be estimated with this aiding: the states describe
/// a DVL measuring in its own axes.
pub fn check_aiding(body: bool) -> Result<()> {
    if body {
        Ok(())
    } else {
        Err(Error::invalid(
            "dvl_calibration",
            "the DVL calibration states need body-frame aiding (aiding=\"body\")",
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feedback_removes_the_error_it_is_given() {
        let truth = DvlMounting::from_angles(0.004, [0.002, -0.001, 0.009]);
        let mut c = Calibration::new(&CalibrationConfig::default());
        let e = c.estimate.error_from(&truth);
        c.feedback(&e);
        let left = c.estimate.error_from(&truth);
        assert!(left[0].abs() < 1e-18, "{left:?}");
        assert!(left[1..].iter().all(|x| x.abs() < 1e-15), "{left:?}");
    }

    #[test]
    fn assemble_and_split_round_trip() {
        let mut c = Calibration::new(&CalibrationConfig::default());
        c.cross = Cross::from_fn(|i, j| (i * 4 + j) as f64 * 1e-3);
        let p = Matrix15::from_fn(|i, j| if i == j { 1.0 + i as f64 } else { 0.01 });
        let full = c.assemble(&p);
        assert_eq!(full, full.transpose());
        let mut back = Matrix15::zeros();
        let mut d = c.clone();
        d.cross = Cross::zeros();
        d.cov = Matrix4::zeros();
        d.split(&full, &mut back);
        assert_eq!((back, d.cross, d.cov), (p, c.cross, c.cov));
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
        assert!(check_aiding(false).is_err() && check_aiding(true).is_ok());
    }
}
