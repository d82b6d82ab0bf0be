//! What a pass watches at every epoch, kept or not: the first epoch whose solution
//! left a physical bound, and the heading σ ([`Watch`], an [`Observer`] of the pass).

use super::epoch::{Epoch, Observer, Updated};
use crate::ekf::{Ekf, ProcessNoise, Transition};

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

/// The [`Observer`] that keeps a pass's [`Extent`]: the solution after each epoch's
/// updates; the covariance wherever P stands, after the updates where it is up to date
/// and at each close of a covariance step before them (taken in at the epoch's end,
/// where its time is known). A copy of it is a checkpoint of what it watched.
#[derive(Clone, Copy, Debug, Default)]
pub struct Watch {
    pub extent: Extent,
    /// The horizontal and heading variances at a close, until its epoch ends.
    closed: Option<(f64, f64)>,
}

impl Watch {
    /// A watch of a pass starting from `ekf` at time `t0` \[s\].
    pub fn start(ekf: &Ekf, t0: f64) -> Self {
        let mut watch = Self::default();
        watch.epoch(ekf, t0);
        watch
    }

    fn epoch(&mut self, ekf: &Ekf, t: f64) {
        let extent = &mut self.extent;
        if let Some((horizontal, heading)) = self.closed.take() {
            extent.watch_covariance(horizontal, heading, t);
        }
        extent.watch_solution(&ekf.nav.lla.into(), &ekf.nav.vel.into(), t);
        if ekf.is_up_to_date() {
            extent.watch_covariance(ekf.horizontal_variance(), ekf.heading_variance(), t);
        }
    }
}

impl Observer for Watch {
    fn on_close(&mut self, _epoch: usize, ekf: &Ekf, _phi: &Transition) {
        self.closed = Some((ekf.horizontal_variance(), ekf.heading_variance()));
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        _updated: Option<&mut Updated>,
        _noise: ProcessNoise<'_>,
    ) {
        self.epoch(ekf, at.t);
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
