//! What the backward pass reads of the forward pass ([`Forward`]), and which epochs'
//! smoothed covariance it computes ([`Covariances`]).

use crate::ekf::calibration::DvlErrors;
use crate::mechanization::NavState;

/// What the backward pass reads of the forward one: its solution at every epoch and the
/// sensor rows it ran on.
pub struct Forward<'a> {
    pub imu: &'a [[f64; 6]],
    pub imu_time: &'a [f64],
    pub t0: f64,
    pub nav: &'a [NavState],
    pub bias: &'a [[f64; 6]],
    /// With the DVL error states, their estimate `[k̂, roll, pitch, yaw, b̂]` at every
    /// epoch (empty without).
    pub calibration: &'a [DvlErrors],
    /// The forward σ of the 15 states at every epoch, and of the calibration states'
    /// (empty without them), that [`super::Smoothed`] changes into the smoothed σ (NaN at an
    /// epoch without it: empty where σ is not wanted, or a [`super::Sink`] reads the forward
    /// σ elsewhere).
    pub sigma: &'a [[f64; 15]],
    pub calibration_sigma: &'a [DvlErrors],
    /// The step every sample was propagated over, when the forward pass used one
    /// (a simulation's `truth.dt`), so that the rebuilt steps are its steps bit for bit;
    /// None: each sample's stamped step.
    pub dt: Option<f64>,
}

impl Forward<'_> {
    /// The time \[s\] of epoch `i` (`t0` for the first).
    pub(super) fn time(&self, i: usize) -> f64 {
        if i == 0 {
            self.t0
        } else {
            self.imu_time[i - 1]
        }
    }

    /// The step \[s\] from epoch `i` to `i + 1` (the one IMU row `i` is propagated over).
    pub(super) fn step(&self, i: usize) -> f64 {
        self.dt.unwrap_or_else(|| self.imu_time[i] - self.time(i))
    }
}

/// Which epochs' smoothed covariance (σ) a backward pass computes; the nodes' it
/// always does (for the recursion). The mean it computes at every epoch.
#[derive(Clone, Copy)]
pub enum Covariances<'a> {
    /// Every epoch (`run_filter`): `Λ_i = Φ_{i→b}ᵀ M Φ_{i→b}` is carried back step by
    /// step, `Ps_i = P_i + P_i Λ_i P_i`.
    Every,
    /// Only the epochs where this holds (a Monte Carlo's recorded ones), the others'
    /// σ left NaN; at every IMU sample Λ is carried as the product of the transitions
    /// where it is not read.
    Where(&'a dyn Fn(usize) -> bool),
}
