//! The DVL's error model: random bottom-lock loss ([`DvlDropout`]), and the instrument
//! as simulated ([`DvlModel`]: noise, rate, lever arm, outages, its scale factor and
//! mounting, a [`DvlMounting`]). Its readings are drawn by [`super::SensorSim`].

use crate::ekf::DvlMounting;
use crate::error::{Error, Result};
use nalgebra::Vector3;

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
