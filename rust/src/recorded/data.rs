//! The inputs of a filter pass over recorded (or user-simulated) sensor arrays, checked.

use super::stream::Stream;
use crate::error::{check, Error, Result};
use crate::mechanization::{imu_row_in_range, imu_row_problem};

/// Inputs of one filter pass over recorded (or user-simulated) sensor arrays.
#[derive(Clone, Debug, Default)]
pub struct RecordedData<'a> {
    /// IMU samples; row k covers `(imu_time[k-1], imu_time[k]]`, `imu_time[-1] = t0`.
    pub imu: &'a [[f64; 6]],
    /// End time of every IMU sample \[s\], strictly increasing, after `t0`.
    pub imu_time: &'a [f64],
    /// Time of the initial state \[s\].
    pub t0: f64,
    /// The aiding sensors' streams; at an epoch their due rows are applied stream by
    /// stream, in this order.
    pub streams: Vec<Stream<'a>>,
    /// Start times \[s\] of a per-sample IMU variance schedule for an external strategy
    /// (the ProNet loop on recorded data); empty for none. Strictly increasing.
    pub q_time: &'a [f64],
    /// The schedule's IMU variances, one row per `q_time` \[(m/s²)², (rad/s)²\].
    pub q_values: &'a [[f64; 6]],
    /// Times \[s\] at which to keep the full covariance, strictly increasing (empty for
    /// none): each is kept at the epoch nearest to it, after that epoch's update, so a
    /// pass stores 15 × 15 numbers (1,800 bytes) per time asked for, never per epoch.
    pub covariance_time: &'a [f64],
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
        // One pass the compiler vectorizes; the row is looked for only when one fails.
        if !self
            .imu
            .iter()
            .fold(true, |ok, row| ok & imu_row_in_range(row))
        {
            let bad = self.imu.iter().enumerate().find_map(|(i, row)| {
                imu_row_problem(row).map(|problem| format!("row {i} {problem}: {row:?}"))
            });
            return Err(Error::invalid("imu", bad.unwrap_or_default()));
        }
        check::finite("t0", &[self.t0])?;
        check::increasing("imu_time", self.imu_time)?;
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
        for stream in &self.streams {
            stream.validate()?;
        }
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

    /// The time \[s\] before which a row is outside the run: half the first step
    /// before `t0` (a row is applied at the epoch nearest to it).
    pub fn first_time(&self) -> f64 {
        self.t0 - 0.5 * (self.imu_time[0] - self.t0)
    }
}
