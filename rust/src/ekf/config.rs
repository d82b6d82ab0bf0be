//! The EKF's tuning: initial 1σ, bias random-walk PSDs, DVL noise and lever arm, aiding
//! and the innovation gate.

use super::calibration::{check_aiding, CalibrationConfig};
use super::formulation::{Coordinates, Formulation};
use super::state::{Matrix15, Vector15};
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
    /// Accelerometer-bias random-walk PSD ε_a \[(m/s²)²/s\] (paper: 0.001).
    pub accel_bias_psd: f64,
    /// Gyro-bias random-walk PSD ε_g \[(rad/s)²/s\] (paper: 0.001).
    pub gyro_bias_psd: f64,
    /// DVL noise variance per axis \[(m/s)²\] (R).
    pub dvl_variance: [f64; 3],
    /// DVL lever arm in the body frame \[m\].
    pub lever_arm: Vector3<f64>,
    pub aiding: Aiding,
    /// Nominal IMU period \[s\]: the white-noise PSD is q·imu_dt.
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
    /// The interval \[s\] over which the covariance is propagated in one step (Φ and Q_d
    /// accumulated over it, see `docs/reference/filter.md`, "Covariance step"); the navigation
    /// solution is still integrated at every IMU sample. [`DEFAULT_COVARIANCE_STEP`]
    /// (0.1 s) by default; 0, or anything shorter than 1.5 IMU periods: at every IMU
    /// sample. Longer steps are rounded to the
    /// nearest whole number of IMU periods (halves down): an interval closes at the
    /// first sample within half an IMU period of the step, before every DVL update and
    /// wherever the filter is brought up to date ([`super::Ekf::bring_up_to_date`]).
    pub covariance_step: f64,
    /// The anchor of [`Formulation::Se23`]'s position error (geodetic `[lat rad, lon
    /// rad, h m]`); None: the filter's initial position, set by [`super::Ekf::new`] in
    /// its own copy (a pass reads it back from [`super::Ekf::config`]).
    pub anchor: Option<Vector3<f64>>,
    /// Carry the second-order heading term of the position error (`super::second_order`):
    /// P then includes the along-track error a large heading error makes, whose variance
    /// the linear filter lacks. Off by default; not with [`Formulation::Se23`] (its
    /// position error is taken about the anchor) nor with the DVL calibration states.
    pub heading_second_order: bool,
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
            covariance_step: DEFAULT_COVARIANCE_STEP,
            anchor: None,
            heading_second_order: false,
        }
    }
}

/// The default covariance step \[s\]: pyins's default, and the step that the covariance
/// step's accuracy measurement found free (`docs/results/covariance-step.md`: on every built-in
/// scenario and the Snapir sections SRMSE inside the per-sample filter's 95 % CI, the
/// NEES shares in band within a point) at about half the per-sample filter's cost.
pub const DEFAULT_COVARIANCE_STEP: f64 = 0.1;

/// The longest covariance step \[s\]: Φ and Q_d accumulated over a step approximate the
/// error process over it, measured as accurate as every sample up to 0.5 s
/// (`docs/results/covariance-step.md`); far beyond (a step of 1e9 s through an 80 s DVL outage
/// cost 10× in position) the approximation, not the process, sets the covariance.
pub const MAX_COVARIANCE_STEP: f64 = 1.0;

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
        if let Some(anchor) = &self.anchor {
            check::finite("anchor", anchor.as_slice())?;
        }
        if self.dvl_variance.iter().any(|v| *v <= 0.0) {
            return Err(Error::invalid(
                "dvl_variance",
                format!("must be > 0 on every axis, got {:?}", self.dvl_variance),
            ));
        }
        check_lever_arm("lever_arm", self.lever_arm.as_slice())?;
        check::positive("imu_dt", self.imu_dt)?;
        if !(self.covariance_step.is_finite()
            && (0.0..=MAX_COVARIANCE_STEP).contains(&self.covariance_step))
        {
            return Err(Error::invalid(
                "covariance_step",
                format!(
                    "must be a finite number of seconds from 0 (every IMU sample) to \
                     {MAX_COVARIANCE_STEP} (MAX_COVARIANCE_STEP: its approximation of the \
                     process is measured up to 0.5 s), got {}",
                    self.covariance_step
                ),
            ));
        }
        if let Some(gate) = self.innovation_gate {
            check::positive("innovation_gate", gate)?;
        }
        if let Some(c) = &self.dvl_calibration {
            c.validate()?;
            check_aiding(c, self.aiding == Aiding::Body)?;
        }
        if self.heading_second_order {
            let against = if self.formulation.position_invariant() {
                Some("the se23 formulation, whose position error is taken about its anchor")
            } else if self.dvl_calibration.is_some() {
                Some("the DVL calibration or correlated-error states")
            } else {
                None
            };
            if let Some(against) = against {
                return Err(Error::invalid(
                    "heading_second_order",
                    format!("is not available with {against}"),
                ));
            }
        }
        Ok(())
    }

    /// Whether the covariance is propagated at every IMU sample: a covariance step
    /// shorter than 1.5 IMU periods rounds to one.
    /// This configuration with its SE₂(3) anchor at `lla` unless it has one already
    /// (the same configuration in the other formulations, which have none).
    pub fn anchored(&self, lla: &Vector3<f64>) -> Self {
        let mut cfg = self.clone();
        if cfg.formulation.position_invariant() {
            cfg.anchor.get_or_insert(*lla);
        }
        cfg
    }

    /// The formulation and its anchor (the origin where none is set: SE₂(3) needs one,
    /// [`FilterConfig::anchored`]).
    pub fn coordinates(&self) -> Coordinates {
        Coordinates {
            formulation: self.formulation,
            anchor: self.anchor.unwrap_or_else(Vector3::zeros),
        }
    }

    pub fn covariance_every_sample(&self) -> bool {
        self.covariance_step < 1.5 * self.imu_dt
    }

    /// Whether an interval that has run `elapsed` seconds is due to close: within half
    /// an IMU period of the covariance step.
    pub(crate) fn interval_due(&self, elapsed: f64) -> bool {
        elapsed + 0.5 * self.imu_dt >= self.covariance_step
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

/// The longest lever arm a sensor may have from the point it is referred to \[m\]: 1 km,
/// beyond any vehicle. A longer one is a mistake (a unit slip), and left unchecked it
/// turns into an error about something else (a latitude beyond the poles).
pub const MAX_LEVER_ARM: f64 = 1000.0;

/// `Err` naming `arg` unless the lever arm `values` \[m\] is finite and no component is
/// longer than [`MAX_LEVER_ARM`].
pub fn check_lever_arm(arg: &str, values: &[f64]) -> Result<()> {
    check::finite(arg, values)?;
    match values.iter().position(|v| v.abs() > MAX_LEVER_ARM) {
        None => Ok(()),
        Some(i) => Err(Error::invalid(
            arg,
            format!(
                "must be within ±{MAX_LEVER_ARM} m (no vehicle is longer), element {i} is {} m",
                values[i]
            ),
        )),
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
        for bad in [-0.1, f64::NAN, f64::INFINITY, 1.01, 1e9] {
            let c = FilterConfig {
                covariance_step: bad,
                ..FilterConfig::default()
            };
            let e = c.validate().unwrap_err().to_string();
            assert!(e.starts_with("covariance_step"), "{e}");
        }
        let longest = FilterConfig {
            covariance_step: MAX_COVARIANCE_STEP,
            ..FilterConfig::default()
        };
        assert!(longest.validate().is_ok());
    }

    #[test]
    fn covariance_step_rounds_to_whole_imu_periods() {
        let at = |step: f64| FilterConfig {
            covariance_step: step,
            ..FilterConfig::default()
        };
        for step in [0.0, 0.005, 0.01, 0.0149] {
            assert!(at(step).covariance_every_sample(), "{step}");
        }
        // 0.1 s at 100 Hz: ten samples, though ten 0.01 s steps sum to just under 0.1.
        let c = at(0.1);
        assert!(!c.covariance_every_sample());
        let elapsed = |n: usize| (0..n).map(|_| 0.01).sum::<f64>();
        assert!(!c.interval_due(elapsed(9)) && c.interval_due(elapsed(10)));
        // 0.026 s: rounded to three samples; 0.024 s to two.
        assert!(!at(0.026).interval_due(elapsed(2)) && at(0.026).interval_due(elapsed(3)));
        assert!(at(0.024).interval_due(elapsed(2)));
    }
}
