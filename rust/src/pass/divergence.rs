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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nis_monitor_flags_a_sustained_large_nis_only() {
        let mut m = NisMonitor::default();
        // A consistent filter: mean 3, with single outliers.
        for k in 0..200 {
            m.push(if k % 37 == 0 { 60.0 } else { 3.0 }, k as f64);
        }
        assert_eq!(m.diverged_at, None);
        // Innovations 4× their predicted σ (NIS ≈ 48) from t = 200 s on.
        for k in 200..260 {
            m.push(48.0, k as f64);
        }
        let t = m.diverged_at.expect("a sustained NIS of 48 is divergence");
        assert!((200.0..220.0).contains(&t), "detected at {t}");
        // The first detection is kept; a NaN NIS also counts.
        m.push(f64::NAN, 999.0);
        assert_eq!(m.diverged_at, Some(t));
        let mut m = NisMonitor::default();
        for k in 0..NisMonitor::WINDOW {
            m.push(if k == 5 { f64::NAN } else { 3.0 }, k as f64);
        }
        assert!(m.diverged_at.is_some());
    }
}
