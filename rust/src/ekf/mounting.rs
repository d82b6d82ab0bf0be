//! A DVL's scale factor and mounting ([`DvlMounting`]): the truth of a simulation, or
//! the estimate of the filter's DVL calibration states (`super::calibration`).

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
