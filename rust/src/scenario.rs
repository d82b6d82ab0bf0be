//! A simulated scenario: a truth with its ideal IMU, and the sensor models, checked.

use crate::error::{Error, Result};
use crate::sensors::aiding::steps_per;
use crate::sensors::SensorConfig;
use crate::trajectory::Truth;
use std::sync::Arc;

/// A simulated scenario: a truth with its ideal IMU, and the sensor models.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Shared, so that many scenarios (strategies, sweeps) over one trajectory do not
    /// copy it.
    pub truth: Arc<Truth>,
    pub sensors: SensorConfig,
    /// Start each run from the truth plus an error drawn from N(0, P0) (true), or
    /// exactly at the truth (false).
    pub sample_initial_error: bool,
}

impl Scenario {
    /// IMU steps per DVL period (None without a DVL), checking that the period is a
    /// whole number of steps, and the aiding sensors' periods too.
    pub fn dvl_every(&self) -> Result<Option<usize>> {
        self.sensors.validate()?;
        if self.truth.is_empty() {
            return Err(Error::invalid("trajectory", "has no IMU samples"));
        }
        if let Some(d) = &self.sensors.depth {
            steps_per(d.period, self.truth.dt, "depth_period")?;
        }
        if let Some(h) = &self.sensors.heading {
            steps_per(h.period, self.truth.dt, "heading_period")?;
        }
        for (j, f) in self.sensors.fixes.iter().enumerate() {
            if f.period > 0.0 {
                steps_per(f.period, self.truth.dt, &format!("fixes[{j}].period"))?;
            }
        }
        if !self.sensors.dvl.enabled() {
            return Ok(None);
        }
        steps_per(self.sensors.dvl.period, self.truth.dt, "dvl_period").map(Some)
    }

    /// `Err` naming `fixes[j]` where fix source `j` takes no fix on this truth
    /// ([`crate::sensors::FixModel::check_fires`]). The Monte Carlo runs such a source
    /// (its runs report the fixes taken); a scenario file is refused with it.
    pub fn check_fixes_fire(&self) -> Result<()> {
        for (j, f) in self.sensors.fixes.iter().enumerate() {
            f.check_fires(j, &self.truth)?;
        }
        Ok(())
    }

    /// Times \[s\] of the DVL epochs (every `dvl_every` IMU steps) outside the outages;
    /// none without a DVL.
    pub fn dvl_epoch_times(&self, dvl_every: Option<usize>) -> Vec<f64> {
        let Some(dvl_every) = dvl_every else {
            return Vec::new();
        };
        let mut times = epoch_times(&self.truth, dvl_every, false);
        times.retain(|&t| self.sensors.dvl.available(t));
        times
    }
}

/// The times \[s\] of every `every`-th epoch of `truth` (from the first, or from
/// epoch `every`).
pub fn epoch_times(truth: &Truth, every: usize, include_start: bool) -> Vec<f64> {
    let start = if include_start { 0 } else { every };
    (start..=truth.len())
        .step_by(every)
        .map(|k| truth.time[k])
        .collect()
}
