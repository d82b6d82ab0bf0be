//! Which epochs a filter pass over recorded arrays keeps in its output.

use crate::error::{Error, Result};

/// Which epochs a pass keeps in its [`super::FilterOutput`] (the updates are always kept).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Epochs {
    /// The initial state and the estimate after every IMU sample.
    #[default]
    All,
    /// The estimate after the last IMU sample only: for passes whose updates alone are
    /// read, such as matching R to the innovations, which then neither compute nor
    /// store the estimate (~300 bytes here, ~70 more in the binding's arrays) at every
    /// IMU sample. Each stream still counts every epoch.
    Last,
    /// An output period \[s\] (finite, > 0): the initial state, the epoch nearest each
    /// multiple of it after `t0` (as a `covariance_time` is placed) and the last epoch,
    /// each with its estimate bit for bit as with [`Epochs::All`]. A long pass then
    /// stores ~300 bytes per kept epoch, not per IMU sample; smoothed
    /// ([`super::smooth_recorded_until`]), the forward pass keeps its solution at the nodes
    /// only and the backward pass re-integrates it between them ([`crate::smoother::thinned`]).
    /// Each stream still counts every epoch; [`super::FilterOutput::epoch`] maps the rows.
    Step(f64),
}

impl Epochs {
    /// Checked: a period must be finite and > 0.
    pub fn validate(self) -> Result<()> {
        match self {
            Epochs::Step(s) if !(s.is_finite() && s > 0.0) => Err(Error::invalid(
                "output_step",
                format!("must be a finite period > 0 [s], got {s}"),
            )),
            _ => Ok(()),
        }
    }

    /// How many epochs a pass of `n` IMU samples spanning `span` \[s\] after `t0`
    /// keeps, at most (with [`Epochs::Step`], one per period and the first and last).
    pub(super) fn kept(self, n: usize, span: f64) -> usize {
        match self {
            Epochs::All => n + 1,
            Epochs::Last => 1,
            Epochs::Step(step) => ((span / step) as usize).saturating_add(2).min(n + 1),
        }
    }
}

/// Which epochs an [`Epochs::Step`] pass keeps: the one nearest each multiple of the
/// period after `t0`.
pub(super) struct Thinning {
    t0: f64,
    step: f64,
    /// The next multiple not yet placed.
    next: f64,
}

impl Thinning {
    /// With [`Epochs::Step`], the multiples placed at the first epoch (`t0`, then a
    /// step of `first_dt` \[s\]) taken.
    pub(super) fn of(epochs: Epochs, t0: f64, first_dt: f64) -> Option<Self> {
        let Epochs::Step(step) = epochs else {
            return None;
        };
        let mut thinning = Self {
            t0,
            step,
            next: 0.0,
        };
        thinning.keeps(t0, first_dt);
        Some(thinning)
    }

    /// Whether the epoch at `t` \[s\] (`next_dt` \[s\] the step after it) is the nearest to
    /// a multiple not yet placed: one at or before `t + next_dt/2`.
    pub(super) fn keeps(&mut self, t: f64, next_dt: f64) -> bool {
        let limit = t + 0.5 * next_dt;
        if self.t0 + self.next * self.step > limit {
            return false;
        }
        // Past every multiple up to the limit at once (a gap may span many).
        self.next = (self.next + 1.0).max(((limit - self.t0) / self.step).floor() + 1.0);
        while self.t0 + self.next * self.step <= limit {
            self.next += 1.0;
        }
        true
    }
}
