//! What a recorded pass reports ([`FilterOutput`]): the kept epochs, each stream's rows,
//! and the covariances asked for.

use crate::attitude::euler_from_dcm;
use crate::ekf::calibration::DvlErrors;
use crate::ekf::{Ekf, Matrix15, UpdateInfo};
use crate::mechanization::NavState;
use crate::pass::NisMonitor;
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

/// The heading 1σ \[°\] past which a pass says its heading error is no longer small:
/// the position σ, linear in it, can then understate the position error on a track
/// with a net drift (`docs/results/consistency.md`, "A long MEMS mission").
pub const MAX_LINEAR_HEADING_SIGMA_DEG: f64 = 5.0;
/// Beyond these the solution has left what any vehicle pronet navigates can do: a
/// speed \[m/s\], a height \[m\] and a horizontal 1σ \[m\] ([`Bound`]).
pub const MAX_SPEED: f64 = 100.0;
pub const MAX_ABS_HEIGHT: f64 = 20_000.0;
pub const MAX_POSITION_SIGMA: f64 = 1.0e6;

/// A physical bound of the solution, in the order they are checked at an epoch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Bound {
    /// A position or velocity is not finite.
    NonFinite,
    /// A speed over [`MAX_SPEED`].
    Speed,
    /// A height beyond ±[`MAX_ABS_HEIGHT`].
    Height,
    /// A horizontal 1σ over [`MAX_POSITION_SIGMA`].
    PositionSigma,
}

/// What a pass watches at every epoch, kept or not, so that its health
/// (`pronet.stats.divergence`, `pronet.stats.heading_linearity`) is told from every
/// epoch without the arrays, however few of them the output keeps: the first epoch
/// whose solution broke a [`Bound`], and the heading σ. The solution is read after
/// each epoch's updates; the covariance wherever P stood: after the updates where it
/// is up to date, and at each close of a covariance step before them (the σ a kept
/// epoch inside a step reports is interpolated between these, so never larger).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extent {
    /// The time \[s\] of the first epoch that broke a bound, and the bound (the first
    /// in [`Bound`]'s order at that epoch); None where none did.
    pub diverged: Option<(f64, Bound)>,
    /// The largest heading variance σ_ψD² \[rad²\] (the attitude error's down
    /// component); NaN before any.
    pub heading2: f64,
    /// The time \[s\] of the first of those epochs whose heading σ is over
    /// [`MAX_LINEAR_HEADING_SIGMA_DEG`] (with a covariance step, the close of the step
    /// it passed in, or an epoch with readings inside it); NaN where none is.
    pub heading_over: f64,
}

impl Bound {
    /// Its name in `pronet.stats.Extent`: `"non-finite"`, `"speed"`, `"height"` or
    /// `"position-sigma"`.
    pub fn name(self) -> &'static str {
        match self {
            Bound::NonFinite => "non-finite",
            Bound::Speed => "speed",
            Bound::Height => "height",
            Bound::PositionSigma => "position-sigma",
        }
    }
}

impl Default for Extent {
    fn default() -> Self {
        Self {
            diverged: None,
            heading2: f64::NAN,
            heading_over: f64::NAN,
        }
    }
}

impl Extent {
    /// Take in the solution at time `t` \[s\]: position `[lat, lon, h]` \[rad, rad, m\]
    /// and NED velocity \[m/s\].
    pub fn watch_solution(&mut self, lla: &[f64; 3], vel: &[f64; 3], t: f64) {
        let speed2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2];
        if !lla.iter().chain(vel).all(|x| x.is_finite()) {
            self.broke(Bound::NonFinite, t);
        } else if speed2 > MAX_SPEED * MAX_SPEED {
            self.broke(Bound::Speed, t);
        } else if lla[2].abs() > MAX_ABS_HEIGHT {
            self.broke(Bound::Height, t);
        }
    }

    /// Take in the horizontal position variance σ_N² + σ_E² \[m²\] and the heading
    /// variance σ_ψD² \[rad²\] P holds at time `t` \[s\] (classic coordinates).
    pub fn watch_covariance(&mut self, horizontal: f64, heading: f64, t: f64) {
        if horizontal > MAX_POSITION_SIGMA * MAX_POSITION_SIGMA {
            self.broke(Bound::PositionSigma, t);
        }
        self.heading2 = self.heading2.max(heading);
        let limit = MAX_LINEAR_HEADING_SIGMA_DEG.to_radians();
        if self.heading_over.is_nan() && heading > limit * limit {
            self.heading_over = t;
        }
    }

    /// Keep `bound` broken at `t` where it is the first (or, at the same epoch, comes
    /// first in [`Bound`]'s order).
    fn broke(&mut self, bound: Bound, t: f64) {
        match self.diverged {
            Some((at, first)) if at < t || (at == t && first <= bound) => {}
            _ => self.diverged = Some((t, bound)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_bound_broken_is_kept_and_at_one_epoch_the_first_in_order() {
        let mut e = Extent::default();
        let (lla, vel) = ([0.5, 0.5, -20.0], [1.0, 0.0, 0.0]);
        e.watch_solution(&lla, &vel, 0.0);
        e.watch_covariance(1.0, 1e-6, 0.0);
        assert_eq!(e.diverged, None);
        assert!(e.heading_over.is_nan());
        // σ breaks at a close, then the speed at the same epoch, then the height later
        e.watch_covariance(2e12, 1e-6, 1.0);
        e.watch_solution(&lla, &[150.0, 0.0, 0.0], 1.0);
        e.watch_solution(&[0.5, 0.5, 3e4], &vel, 2.0);
        assert_eq!(e.diverged, Some((1.0, Bound::Speed)));
        e.watch_solution(&[f64::NAN, 0.5, 0.0], &vel, 3.0);
        assert_eq!(e.diverged, Some((1.0, Bound::Speed)));
        // the heading: its largest variance and the first time past 5°
        let over = 6f64.to_radians().powi(2);
        e.watch_covariance(1.0, over, 4.0);
        e.watch_covariance(1.0, 1e-6, 5.0);
        e.watch_covariance(1.0, 2.0 * over, 6.0);
        assert_eq!((e.heading2, e.heading_over), (2.0 * over, 4.0));
        // NaN σ (not computed) breaks nothing
        e.watch_covariance(f64::NAN, f64::NAN, 7.0);
        assert_eq!(e.heading2, 2.0 * over);
    }
}
