//! [`Tally`]: what a navigator did with one sensor's readings so far.

use super::history::Kept;

/// Each sensor's tally.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tally {
    /// Readings fed (checked: an invalid one is an error, not counted).
    pub received: usize,
    /// Waiting for their epoch.
    pub queued: usize,
    /// Applied and accepted by their gate.
    pub accepted: usize,
    /// Applied and rejected by their gate.
    pub rejected: usize,
    /// Of the applied ones, those that arrived late: stamped before the newest IMU
    /// sample.
    pub late: usize,
    /// Stamped before the lag window.
    pub refused: usize,
    /// Stamped before the pass's start.
    pub skipped: usize,
    /// The sum of the applied readings' NIS, and of their components.
    pub nis_sum: f64,
    pub dof: usize,
}

impl Tally {
    pub(super) fn add(&mut self, kept: &Kept) {
        let Some(o) = kept.outcome else { return };
        if o.accepted {
            self.accepted += 1;
        } else {
            self.rejected += 1;
        }
        self.late += usize::from(kept.late);
        self.nis_sum += o.nis;
        self.dof += o.dof;
    }
}
