//! The divergence watch: the windowed mean of the updates' NIS against a bound.

/// Mean NIS over the last [`NisMonitor::WINDOW`] updates above which the filter is
/// declared diverged: about 8× the consistent mean of 3, i.e. innovations some 3× larger
/// than the filter's own prediction of them, sustained for 20 updates. (For a consistent
/// filter the 20-update sum is χ² with 60 dof; exceeding 500 has probability < 1e-60.)
pub const DIVERGENCE_MEAN_NIS: f64 = 25.0;

/// Watches the NIS of every update, accepted or rejected by the gate, and remembers the
/// first time its windowed mean exceeds [`DIVERGENCE_MEAN_NIS`].
#[derive(Clone, Debug, Default)]
pub struct NisMonitor {
    recent: [f64; NisMonitor::WINDOW],
    count: usize,
    /// Time \[s\] at which divergence was first detected.
    pub diverged_at: Option<f64>,
}

impl NisMonitor {
    pub const WINDOW: usize = 20;

    /// Record the NIS of an update at time `t` \[s\].
    pub fn push(&mut self, nis: f64, t: f64) {
        self.recent[self.count % Self::WINDOW] = nis;
        self.count += 1;
        if self.count >= Self::WINDOW && self.diverged_at.is_none() {
            // Summed afresh, not kept running: one huge NIS must not leave rounding
            // debris behind. A NaN NIS counts as divergence.
            let mean = self.recent.iter().sum::<f64>() / Self::WINDOW as f64;
            if mean.is_nan() || mean > DIVERGENCE_MEAN_NIS {
                self.diverged_at = Some(t);
            }
        }
    }
}
