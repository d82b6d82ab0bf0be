//! The σ a recorded pass reports at the epochs inside a covariance step.

use super::output::FilterOutput;
use crate::ekf::calibration::Calibration;
use crate::ekf::calibration::DvlErrors;
use crate::ekf::{classic_sigma, variance_between, ClosedSigma, Ekf, Matrix15, Point};

/// The σ of the epochs inside a covariance step. P stands at the step's start there, so
/// the σ an epoch records is the last close's; once the step closes (before the updates
/// of its last epoch), the variances of the epochs inside it are interpolated linearly
/// in time between the σ at the last epoch where P was up to date (after its updates)
/// and the σ at the close: the growth of P over a step of 0.1 s is smooth, and a stale
/// σ would read up to the whole step's growth too small (`docs/reference/filter.md`, "Covariance
/// step"). Without a covariance step every epoch is up to date. A pass that records
/// some epochs only (`Epochs::Step`) interpolates those; the last up-to-date epoch
/// need not be one of them. σ is computed only where a recorded epoch inside a step
/// reads it: the filter is asked for the σ at a close only while such an epoch is
/// pending, and at an up-to-date epoch that is not recorded its P and velocity are
/// copied (1.8 kB, cheap beside the mapping to classic coordinates), their σ computed
/// at the close, with the same operations, only if an epoch inside the step reads it.
#[derive(Default)]
pub(super) struct StaleSigma {
    /// The σ at the last close, before the updates of its epoch, where wanted.
    closed: Option<ClosedSigma>,
    /// Whether the σ at the next close is wanted: a recorded epoch inside its step reads it.
    wanted: bool,
    /// The time \[s\] of the last epoch whose P was up to date, and its σ.
    last_current: Option<(f64, Current)>,
    /// The recorded epochs since (indices into the output), whose σ is the last close's.
    pending: Vec<usize>,
}

/// The σ at an up-to-date epoch: its row's, or, at an epoch not recorded, what it is
/// computed from (see [`classic_sigma`]). One value, overwritten in place at
/// each up-to-date epoch: boxing the covariance would allocate there instead.
#[allow(clippy::large_enum_variant)]
enum Current {
    Recorded(ClosedSigma),
    Unrecorded {
        p: Matrix15,
        point: Point,
        calibration: Option<DvlErrors>,
    },
}

impl Current {
    fn sigma(&self) -> ClosedSigma {
        match self {
            Current::Recorded(sigma) => *sigma,
            Current::Unrecorded {
                p,
                point,
                calibration,
            } => (classic_sigma(point, p), *calibration),
        }
    }
}

impl StaleSigma {
    /// At a close of the covariance step, before the updates of its epoch: its σ, if
    /// a recorded epoch inside the step reads it.
    pub(super) fn on_close(&mut self, ekf: &Ekf) {
        if self.wanted {
            self.closed = Some(ekf.sigmas());
        }
    }

    /// After the epoch at time `t` \[s\]; `recorded`: it is the last of `out`.
    pub(super) fn after_epoch(
        &mut self,
        ekf: &Ekf,
        out: &mut FilterOutput,
        t: f64,
        recorded: bool,
    ) {
        if let Some((sigma, calibration)) = self.closed.take() {
            if let Some((t_a, current)) = &self.last_current {
                let (from, from_calibration) = current.sigma();
                for &e in &self.pending {
                    let w = (out.time[e] - t_a) / (t - t_a);
                    let between =
                        |from: f64, to: f64| variance_between(from * from, to * to, w).sqrt();
                    out.sigma[e] = std::array::from_fn(|i| between(from[i], sigma[i]));
                    if let (Some(c), Some(from)) = (calibration, from_calibration) {
                        out.calibration_sigma[e] = std::array::from_fn(|i| between(from[i], c[i]));
                    }
                }
            }
            self.pending.clear();
        }
        if ekf.is_up_to_date() {
            self.pending.clear();
            self.last_current = if recorded {
                let sigma = out.sigma.last().copied().unwrap_or_default();
                let current = (sigma, out.calibration_sigma.last().copied());
                Some((t, Current::Recorded(current)))
            } else if ekf.config().covariance_every_sample() {
                None // no epoch is ever inside a step
            } else {
                let calibration = ekf.calibration.as_ref().map(Calibration::sigma);
                let (p, point) = (ekf.p, ekf.point());
                Some((
                    t,
                    Current::Unrecorded {
                        p,
                        point,
                        calibration,
                    },
                ))
            };
        } else if recorded {
            self.pending.push(out.time.len() - 1);
        }
        // The σ at the next close is read by the recorded epochs inside its step only.
        self.wanted = !self.pending.is_empty();
    }
}
