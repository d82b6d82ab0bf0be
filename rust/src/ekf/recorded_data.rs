//! The inputs of a filter pass over recorded (or user-simulated) sensor arrays, checked.

use crate::error::{check, Error, Result};

/// Inputs of one filter pass over recorded (or user-simulated) sensor arrays.
#[derive(Clone, Copy, Debug, Default)]
pub struct RecordedData<'a> {
    /// IMU samples; row k covers `(imu_time[k-1], imu_time[k]]`, `imu_time[-1] = t0`.
    pub imu: &'a [[f64; 6]],
    /// End time of every IMU sample \[s\], strictly increasing, after `t0`.
    pub imu_time: &'a [f64],
    /// DVL rows (body or NED velocity per the aiding) \[m/s\].
    pub dvl: &'a [[f64; 3]],
    /// DVL times \[s\], strictly increasing.
    pub dvl_time: &'a [f64],
    /// Time of the initial state \[s\].
    pub t0: f64,
    /// Start times \[s\] of a per-sample IMU variance schedule for an external strategy
    /// (the ProNet loop on recorded data); empty for none. Strictly increasing.
    pub q_time: &'a [f64],
    /// The schedule's IMU variances, one row per `q_time` \[(m/s²)², (rad/s)²\].
    pub q_values: &'a [[f64; 6]],
    /// Times \[s\] at which to keep the full covariance, strictly increasing (empty for
    /// none): each is kept at the epoch nearest to it, after that epoch's update, so a
    /// pass stores 15 × 15 numbers (1,800 bytes) per time asked for, never per epoch.
    pub covariance_time: &'a [f64],
    /// Depth readings \[m, positive down\] at `depth_time` \[s\] (strictly increasing),
    /// each of 1σ `depth_sigma` \[m\] (see [`super::position`]); empty for none.
    pub depth: &'a [f64],
    pub depth_time: &'a [f64],
    pub depth_sigma: f64,
    /// Position fixes `[φ (rad), λ (rad), h (m, up)]` (a NaN height: horizontal only)
    /// at `fix_time` \[s\] (strictly increasing), each with its 1σ `[north, east, down]`
    /// \[m\] in `fix_sigma`; empty for none.
    pub fix: &'a [[f64; 3]],
    pub fix_time: &'a [f64],
    pub fix_sigma: &'a [[f64; 3]],
}

impl RecordedData<'_> {
    pub fn validate(&self) -> Result<()> {
        if self.imu.is_empty() {
            return Err(Error::invalid("imu", "needs at least one sample"));
        }
        if self.imu.len() != self.imu_time.len() {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "has {} rows but imu has {}",
                    self.imu_time.len(),
                    self.imu.len()
                ),
            ));
        }
        if self.dvl.len() != self.dvl_time.len() {
            return Err(Error::invalid(
                "dvl_time",
                format!(
                    "has {} rows but dvl has {}",
                    self.dvl_time.len(),
                    self.dvl.len()
                ),
            ));
        }
        for (i, row) in self.imu.iter().enumerate() {
            check::finite("imu", row)
                .map_err(|_| Error::invalid("imu", format!("row {i} is not finite: {row:?}")))?;
        }
        for (i, row) in self.dvl.iter().enumerate() {
            check::finite("dvl", row)
                .map_err(|_| Error::invalid("dvl", format!("row {i} is not finite: {row:?}")))?;
        }
        check::finite("t0", &[self.t0])?;
        check::increasing("imu_time", self.imu_time)?;
        check::increasing("dvl_time", self.dvl_time)?;
        if self.q_time.len() != self.q_values.len() {
            return Err(Error::invalid(
                "q_time",
                format!(
                    "has {} rows but q has {}",
                    self.q_time.len(),
                    self.q_values.len()
                ),
            ));
        }
        check::increasing("q_time", self.q_time)?;
        check::increasing("covariance_time", self.covariance_time)?;
        super::position::check_aiding(
            self.depth,
            self.depth_time,
            self.depth_sigma,
            self.fix,
            self.fix_time,
            self.fix_sigma,
        )?;
        for (i, row) in self.q_values.iter().enumerate() {
            check::non_negative("q", row).map_err(|_| {
                Error::invalid(
                    "q",
                    format!("row {i} must be finite and >= 0 (variances), got {row:?}"),
                )
            })?;
        }
        if self.imu_time[0] <= self.t0 {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "the first sample time {} must be after t0 = {} (a positive time step)",
                    self.imu_time[0], self.t0
                ),
            ));
        }
        Ok(())
    }
}
