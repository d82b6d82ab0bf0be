//! The learned loop's instants and window in a navigator: every `every` IMU samples once
//! `window` exist, the last `window` raw samples, as the batch loop places them
//! ([`TuningSchedule`]).

use crate::ensemble::TuningSchedule;
use crate::error::Result;

/// When the learned loop sets q: after epoch k for k a multiple of `every` and at least
/// `first` (the first such multiple with `window` samples).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tuning {
    pub every: usize,
    pub first: usize,
    pub window: usize,
}

impl Tuning {
    /// The instants every `tuning_period` \[s\] of IMU samples of step `dt` \[s\]
    /// (rounded to whole samples, at least one), each reading `window` samples: those
    /// of [`TuningSchedule::new`], errors naming `dt`, `tuning_period` or `window`.
    pub fn new(dt: f64, window: usize, tuning_period: f64) -> Result<Self> {
        let schedule = TuningSchedule::new(usize::MAX, dt, window, tuning_period)?;
        Ok(Self {
            every: schedule.every,
            first: schedule.first,
            window,
        })
    }

    /// Whether epoch `epoch` (samples fed) is an instant.
    pub fn due_after(&self, epoch: usize) -> bool {
        epoch >= self.first && epoch.is_multiple_of(self.every)
    }
}

/// The last `len` raw samples, in a ring.
#[derive(Clone, Debug)]
pub struct Window {
    samples: Vec<[f64; 6]>,
    len: usize,
    next: usize,
}

impl Window {
    pub fn new(len: usize) -> Self {
        Self {
            samples: Vec::with_capacity(len.min(1 << 16)),
            len,
            next: 0,
        }
    }

    pub fn push(&mut self, raw: &[f64; 6]) {
        if self.samples.len() < self.len {
            self.samples.push(*raw);
        } else {
            self.samples[self.next] = *raw;
            self.next = (self.next + 1) % self.len;
        }
    }

    /// The samples oldest first, once there are `len` of them.
    pub fn samples(&self) -> Option<Vec<[f64; 6]>> {
        if self.samples.len() < self.len {
            return None;
        }
        let (newer, older) = self.samples.split_at(self.next);
        Some(older.iter().chain(newer).copied().collect())
    }
}
