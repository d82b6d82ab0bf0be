//! The EKF's tuning: initial 1σ, bias random-walk PSDs, DVL noise and lever arm, aiding
//! and the innovation gate.

use super::calibration::{check_aiding, CalibrationConfig};
use super::formulation::Formulation;
use super::{Matrix15, Vector15};
use crate::error::{check, Error, Result};
use nalgebra::Vector3;

/// What the DVL measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aiding {
    /// Body-frame velocity at the DVL, `Ĉᵀ v̂ + ω̂ × r` (a real DVL).
    Body,
    /// NED velocity `v̂` (a DVL already rotated by an external attitude source).
    Nav,
}

/// Filter tuning that does not change while it runs.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterConfig {
    /// Initial 1σ of the 15 error states (units as the state).
    pub p0_sigma: [f64; 15],
    /// Accelerometer-bias random-walk PSD ε_a [(m/s²)²/s] (paper: 0.001).
    pub accel_bias_psd: f64,
    /// Gyro-bias random-walk PSD ε_g [(rad/s)²/s] (paper: 0.001).
    pub gyro_bias_psd: f64,
    /// DVL noise variance per axis [(m/s)²] (R).
    pub dvl_variance: [f64; 3],
    /// DVL lever arm in the body frame [m].
    pub lever_arm: Vector3<f64>,
    pub aiding: Aiding,
    /// Nominal IMU period [s]: the white-noise PSD is q·imu_dt.
    pub imu_dt: f64,
    /// Chi-square innovation gate: a DVL update whose NIS exceeds this is rejected (not
    /// applied, and unseen by the noise strategy). With 3 dof, 16.27 rejects 0.1 % of
    /// consistent updates. `None` (the default, as in the paper's table) applies all.
    pub innovation_gate: Option<f64>,
    /// DVL scale-factor and misalignment states appended to the 15 (body-frame aiding
    /// only); `None` (the default): the 15-state filter.
    pub dvl_calibration: Option<CalibrationConfig>,
    /// The coordinates of the velocity error the filter runs in (see
    /// [`super::formulation`]); `p0_sigma` is always given in the classic ones.
    pub formulation: Formulation,
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            p0_sigma: DEFAULT_P0_SIGMA,
            accel_bias_psd: 1e-3,
            gyro_bias_psd: 1e-3,
            dvl_variance: [0.01; 3],
            lever_arm: Vector3::zeros(),
            aiding: Aiding::Body,
            imu_dt: 0.01,
            innovation_gate: None,
            dvl_calibration: None,
            formulation: Formulation::default(),
        }
    }
}

/// Default initial 1σ: position 1 m, velocity 0.1 m/s, roll/pitch 1 mrad, yaw 5 mrad,
/// accelerometer bias 1e-3 m/s², gyro bias 1e-4 rad/s.
pub const DEFAULT_P0_SIGMA: [f64; 15] = [
    1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4,
];

impl FilterConfig {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("p0_sigma", &self.p0_sigma)?;
        check::non_negative("accel_bias_psd", &[self.accel_bias_psd])?;
        check::non_negative("gyro_bias_psd", &[self.gyro_bias_psd])?;
        check::finite("dvl_variance", &self.dvl_variance)?;
        if self.dvl_variance.iter().any(|v| *v <= 0.0) {
            return Err(Error::invalid(
                "dvl_variance",
                format!("must be > 0 on every axis, got {:?}", self.dvl_variance),
            ));
        }
        check::finite("lever_arm", self.lever_arm.as_slice())?;
        check::positive("imu_dt", self.imu_dt)?;
        if let Some(gate) = self.innovation_gate {
            check::positive("innovation_gate", gate)?;
        }
        if let Some(c) = &self.dvl_calibration {
            c.validate()?;
            check_aiding(self.aiding == Aiding::Body)?;
        }
        Ok(())
    }

    /// `diag(p0_sigma²)`.
    pub fn p0(&self) -> Matrix15 {
        Matrix15::from_diagonal(&Vector15::from_iterator(
            self.p0_sigma.iter().map(|s| s * s),
        ))
    }

    /// Bias random-walk PSDs per channel `[ε_a ×3, ε_g ×3]`.
    pub fn bias_psd(&self) -> [f64; 6] {
        let (a, g) = (self.accel_bias_psd, self.gyro_bias_psd);
        [a, a, a, g, g, g]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_rejects_bad_values() {
        let c = FilterConfig {
            dvl_variance: [0.01, 0.0, 0.01],
            ..FilterConfig::default()
        };
        assert!(c.validate().is_err());
        let mut c = FilterConfig::default();
        c.p0_sigma[4] = -1.0;
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("p0_sigma"));
        let c = FilterConfig {
            imu_dt: 0.0,
            ..FilterConfig::default()
        };
        assert!(c.validate().is_err());
    }
}
