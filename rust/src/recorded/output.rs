//! What a recorded pass reports ([`FilterOutput`]): the kept epochs, each stream's rows,
//! and the covariances asked for.

use crate::attitude::euler_from_dcm;
use crate::ekf::calibration::DvlErrors;
use crate::ekf::{Ekf, Matrix15, UpdateInfo};
use crate::mechanization::NavState;
use crate::pass::{Extent, NisMonitor};
use crate::smoother::Smoothed;

/// What a pass did with each row of one stream.
#[derive(Clone, Debug, Default)]
pub struct StreamRecord {
    /// For each row: the epoch it was applied at (None if outside the run).
    pub epoch: Vec<Option<usize>>,
    /// For each row: its NIS (the sum of its components'; NaN where not applied).
    pub nis: Vec<f64>,
    /// A velocity stream's: each row's update (None if outside the run; empty for
    /// other streams).
    pub updates: Vec<Option<UpdateInfo>>,
    /// A velocity stream's: for each row, the per-IMU-step Q_d the strategy set after
    /// that update, where it sets one directly (Mehra); boxed, so that a row without
    /// one costs 8 bytes, not 1,808.
    pub adaptive_q: Vec<Option<Box<Matrix15>>>,
}

/// Output of a recorded pass: the estimate after every IMU epoch (or some of them,
/// see [`super::Epochs`]) and the updates.
#[derive(Clone, Debug, Default)]
pub struct FilterOutput {
    /// Epoch times \[s\]: `t0` then every IMU sample time (the last one only with
    /// [`super::Epochs::Last`], the kept ones with [`super::Epochs::Step`]); the per-epoch vectors
    /// below follow them.
    pub time: Vec<f64>,
    /// With [`super::Epochs::Step`]: the index of each kept epoch among all (0 for `t0`, k for
    /// IMU sample k − 1); empty otherwise (every epoch, or the last).
    pub epoch: Vec<usize>,
    /// The solution per epoch, in one of two forms: as position `[lat, lon, h]`
    /// \[rad, rad, m\], NED velocity \[m/s\] and roll, pitch, yaw \[rad\]
    /// ([`euler_from_dcm`]) rows, written once, as they are handed over; or, where the
    /// smoother reads them (a smoothed pass), as whole navigation states in [`Self::nav`]
    /// (120 bytes an epoch, made into rows when handed over), these rows empty.
    pub lla: Vec<[f64; 3]>,
    pub vel: Vec<[f64; 3]>,
    pub rpy: Vec<[f64; 3]>,
    /// The whole navigation state per epoch, in a smoothed pass (empty otherwise).
    pub nav: Vec<NavState>,
    /// `[b_a, b_g]` estimates per epoch.
    pub bias: Vec<[f64; 6]>,
    /// 1σ of the 15 errors per epoch. With a covariance step
    /// ([`crate::ekf::FilterConfig::covariance_step`]), an epoch inside a step reads σ
    /// interpolated linearly in variance between the last up-to-date epoch (after its
    /// updates) and the close that ends the step (before the updates there); steps close
    /// when due, at every epoch with a reading and at the last epoch.
    pub sigma: Vec<[f64; 15]>,
    /// Each stream's rows, in the order of [`super::RecordedData::streams`].
    pub streams: Vec<StreamRecord>,
    /// `[k̂, roll, pitch, yaw, b̂]` of the DVL error states per epoch: the scale error,
    /// the DVL's mounting angles \[rad\] and its correlated velocity error \[m/s, DVL
    /// axes\] (empty without the states).
    pub calibration: Vec<DvlErrors>,
    /// 1σ of `[δk, δμ, δb]` per epoch (empty without the DVL error states).
    pub calibration_sigma: Vec<DvlErrors>,
    /// Covariance at the last epoch.
    pub final_covariance: Matrix15,
    /// For each of [`super::RecordedData::covariance_time`]: the epoch index it was kept at
    /// (None if outside the run) and the full covariance there, classic coordinates.
    pub covariance_epoch: Vec<Option<usize>>,
    pub covariances: Vec<Option<Matrix15>>,
    /// Divergence watch over every velocity update's NIS.
    pub nis_monitor: NisMonitor,
    /// What the pass watched at every epoch, kept or not.
    pub extent: Extent,
    /// The RTS-smoothed solution at the kept epochs, from
    /// [`super::smooth_recorded_until`].
    pub smoothed: Option<Smoothed>,
}

impl FilterOutput {
    /// Append the estimate at epoch time `t` \[s\]. Inside a covariance step its σ
    /// is NaN here: the recorder's [`super::stale::StaleSigma`] writes it when the
    /// step closes (the σ P gives there is the last close's, never reported).
    /// With `states`, the solution is kept as the whole navigation state
    /// ([`Self::nav`]), else as rows.
    pub(super) fn record(&mut self, ekf: &Ekf, t: f64, states: bool) {
        self.time.push(t);
        if states {
            self.nav.push(ekf.nav);
        } else {
            self.lla.push(ekf.nav.lla.into());
            self.vel.push(ekf.nav.vel.into());
            self.rpy.push(euler_from_dcm(&ekf.nav.dcm).into());
        }
        self.bias.push(ekf.bias());
        let sigma = if ekf.is_up_to_date() {
            ekf.sigma()
        } else {
            [f64::NAN; 15]
        };
        self.sigma.push(sigma);
        if let Some(c) = &ekf.calibration {
            self.calibration.push(c.reported());
            self.calibration_sigma.push(c.sigma());
        }
    }
}

#[cfg(test)]
impl FilterOutput {
    /// The solution kept at row `k`: position, velocity and Euler angles.
    pub(crate) fn solution(&self, k: usize) -> [[f64; 3]; 3] {
        match self.nav.get(k) {
            Some(nav) => solution_of(nav),
            None => [self.lla[k], self.vel[k], self.rpy[k]],
        }
    }

    /// The solution at the last row.
    pub(crate) fn last_solution(&self) -> [[f64; 3]; 3] {
        self.solution(self.time.len() - 1)
    }
}

/// The rows [`FilterOutput`] keeps of the state `nav`: position, velocity and Euler
/// angles.
#[cfg(test)]
pub(crate) fn solution_of(nav: &NavState) -> [[f64; 3]; 3] {
    [
        nav.lla.into(),
        nav.vel.into(),
        euler_from_dcm(&nav.dcm).into(),
    ]
}
