//! The DVL's error model: its scale factor and mounting ([`DvlMounting`]), random
//! bottom-lock loss ([`DvlDropout`]), and the instrument as simulated ([`DvlModel`]:
//! noise, rate, lever arm, outages). Its readings are drawn by [`super::SensorSim`].

use crate::attitude::{dcm_from_euler, euler_from_dcm, log_so3};
use crate::error::{check, Error, Result};
use nalgebra::{Matrix3, Vector3};

/// A DVL's scale factor and mounting, as the truth of a simulation or an estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DvlMounting {
    /// Scale-factor error k: the DVL reads `(1 + k)` times the true velocity.
    pub scale: f64,
    /// Rotation from the body axes to the DVL's, `M = C_b^d`.
    pub body_to_dvl: Matrix3<f64>,
}

impl Default for DvlMounting {
    fn default() -> Self {
        Self {
            scale: 0.0,
            body_to_dvl: Matrix3::identity(),
        }
    }
}

impl DvlMounting {
    /// A mounting from the scale error and the DVL's roll, pitch, yaw in the body frame
    /// \[rad\] (ZYX, the DVL's axes rotated from the body's: `C_d^b = R(roll, pitch, yaw)`).
    pub fn from_angles(scale: f64, rpy: [f64; 3]) -> Self {
        Self {
            scale,
            body_to_dvl: dcm_from_euler(rpy[0], rpy[1], rpy[2]).transpose(),
        }
    }

    /// The DVL's roll, pitch, yaw in the body frame \[rad\].
    pub fn angles(&self) -> [f64; 3] {
        let e = euler_from_dcm(&self.body_to_dvl.transpose());
        [e[0], e[1], e[2]]
    }

    /// `Err` naming `dvl_scale` or `dvl_misalignment` unless the scale error is finite
    /// and above −1 (a DVL reading zero or reversed) and the rotation finite.
    pub fn validate(&self) -> Result<()> {
        if !(self.scale.is_finite() && self.scale > -1.0) {
            return Err(Error::invalid(
                "dvl_scale",
                format!(
                    "must be finite and > -1 (a factor 1 + k > 0), got {}",
                    self.scale
                ),
            ));
        }
        check::finite("dvl_misalignment", self.body_to_dvl.as_slice())
    }

    /// Whether this is the identity mounting (no scale error, aligned axes).
    pub fn is_ideal(&self) -> bool {
        self.scale == 0.0 && self.body_to_dvl == Matrix3::identity()
    }

    /// What the DVL reads of the body-frame velocity `v_b` at its position \[m/s\], in
    /// its own axes: `(1 + k) M v_b`.
    pub fn reading(&self, v_b: &Vector3<f64>) -> Vector3<f64> {
        (1.0 + self.scale) * (self.body_to_dvl * v_b)
    }

    /// `[δk, δμ]` of this mounting as an estimate of `truth` (estimate minus truth):
    /// `δμ = log(Mᵀ M̂)`.
    pub fn error_from(&self, truth: &DvlMounting) -> [f64; 4] {
        let mu = log_so3(&(truth.body_to_dvl.transpose() * self.body_to_dvl));
        [self.scale - truth.scale, mu[0], mu[1], mu[2]]
    }
}

/// Random bottom-lock loss: a two-state (locked, lost) Markov chain stepped at each
/// reading that is due. A locked DVL loses the bottom before the next reading with
/// probability `1 − exp(−T/mean_interval)`, a lost one regains it with probability
/// `1 − exp(−T/mean_length)` (`T` the DVL period): exponential stretches sampled at the
/// readings, so a loss lasts a geometric number of readings with mean
/// `1 / (1 − exp(−T/mean_length))` (≈ `mean_length / T` when that is long). A run starts
/// locked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DvlDropout {
    /// Mean time between losses of bottom lock (the mean locked stretch) \[s\].
    pub mean_interval: f64,
    /// Mean length of a loss \[s\].
    pub mean_length: f64,
}

impl DvlDropout {
    /// `Err` naming `dvl_dropout` unless both times are finite and > 0.
    pub fn validate(&self) -> Result<()> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if ok(self.mean_interval) && ok(self.mean_length) {
            return Ok(());
        }
        Err(Error::invalid(
            "dvl_dropout",
            format!(
                "needs [mean_interval, mean_length], both finite and > 0 s; got [{}, {}]",
                self.mean_interval, self.mean_length
            ),
        ))
    }

    /// The probabilities of losing lock and of regaining it between two readings
    /// `period` \[s\] apart.
    pub fn probabilities(&self, period: f64) -> (f64, f64) {
        (
            -(-period / self.mean_interval).exp_m1(),
            -(-period / self.mean_length).exp_m1(),
        )
    }
}

/// DVL model: body-frame velocity at the DVL, every `period` seconds, white noise.
#[derive(Clone, Debug, PartialEq)]
pub struct DvlModel {
    /// Per-axis noise variance \[(m/s)²\].
    pub variance: [f64; 3],
    /// Measurement period \[s\] (1 s in the paper); 0: no DVL.
    pub period: f64,
    /// DVL position relative to the IMU, body frame \[m\].
    pub lever_arm: Vector3<f64>,
    /// Outages `[start, end)` \[s\]: no reading is due inside one (bottom lock lost,
    /// acoustic dropouts). Sorted, not overlapping.
    pub outages: Vec<[f64; 2]>,
    /// The true scale factor and mounting of the DVL (ideal by default): it reads
    /// `(1 + k) M v_b` in its own axes (estimated by [`crate::ekf::calibration`]).
    pub mounting: DvlMounting,
    /// Random bottom-lock loss (`None`: never; the default).
    pub dropout: Option<DvlDropout>,
}

impl DvlModel {
    /// Whether there is a DVL (a period > 0).
    #[inline]
    pub fn enabled(&self) -> bool {
        self.period != 0.0
    }

    /// Whether a reading due at time `t` \[s\] exists (`t` is in no outage).
    #[inline]
    pub fn available(&self, t: f64) -> bool {
        !self.outages.iter().any(|o| t >= o[0] && t < o[1])
    }
}
