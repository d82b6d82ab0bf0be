//! What a navigator keeps to run a stretch of its pass again when a reading arrives
//! late: the IMU steps of the lag window, the readings applied in it, and copies of the
//! filter (with its noise strategy) every few epochs.

use crate::error::Result;
use crate::measurement::Reading;
use crate::memory::Estimate;
use crate::noise::NoiseStrategy;
use crate::pass::{Pass, Watch};
use crate::smoother::memory::BOX_OVERHEAD;
use std::collections::VecDeque;
use std::mem::{size_of, size_of_val};

/// What one reading's update did: its NIS over `dof` components, and whether its gate
/// accepted it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    pub nis: f64,
    pub dof: usize,
    pub accepted: bool,
}

/// One IMU step kept: its end time `t` \[s\], length `dt` \[s\], raw sample and the IMU
/// variances set before it (from outside), if any.
#[derive(Clone, Debug)]
pub(super) struct Step {
    pub t: f64,
    pub dt: f64,
    pub raw: [f64; 6],
    pub q: Option<[f64; 6]>,
}

impl Step {
    /// The latest reading time \[s\] applied at this step's epoch: half a step after it.
    pub fn reach(&self) -> f64 {
        self.t + 0.5 * self.dt
    }
}

/// A reading kept with the epoch it is applied at, its sensor and time \[s\], and what
/// its update did (None until applied).
#[derive(Clone, Debug)]
pub(super) struct Kept {
    pub epoch: usize,
    pub sensor: usize,
    pub time: f64,
    pub reading: Reading,
    pub outcome: Option<Outcome>,
    /// Whether it arrived late: stamped before the newest IMU sample then.
    pub late: bool,
}

impl Kept {
    /// Whether it comes after `(epoch, sensor, time)` in the order readings are applied:
    /// by epoch, then sensor, then time (a tie: the one that arrived first).
    pub fn after(&self, epoch: usize, sensor: usize, time: f64) -> bool {
        (self.epoch, self.sensor) > (epoch, sensor)
            || ((self.epoch, self.sensor) == (epoch, sensor) && self.time > time)
    }
}

/// The filter, its noise strategy and its watch at the end of epoch `epoch`, and the
/// latest reading time `reach` \[s\] any epoch up to it takes.
pub(super) struct Checkpoint {
    pub epoch: usize,
    pub reach: f64,
    pub pass: Pass,
    pub strategy: Box<dyn NoiseStrategy>,
    /// What the pass had watched by then.
    pub watch: Watch,
}

impl Clone for Checkpoint {
    fn clone(&self) -> Self {
        Self {
            epoch: self.epoch,
            reach: self.reach,
            pass: self.pass.clone(),
            strategy: self.strategy.clone_box(),
            watch: self.watch,
        }
    }
}

/// The history: checkpoints (the first at the oldest epoch a late reading may need),
/// the IMU steps after the first checkpoint and the readings applied at them, in the
/// order they are applied.
pub(super) struct History {
    pub checkpoints: VecDeque<Checkpoint>,
    pub steps: VecDeque<Step>,
    pub kept: VecDeque<Kept>,
    /// The epoch before the first step kept (the first checkpoint's).
    origin: usize,
}

impl History {
    /// A history starting at `start`.
    pub fn new(start: Checkpoint) -> Self {
        Self {
            checkpoints: VecDeque::from([start]),
            steps: VecDeque::new(),
            kept: VecDeque::new(),
            origin: 0,
        }
    }

    /// The epoch of the first step kept.
    pub fn first_epoch(&self) -> usize {
        self.origin + 1
    }

    /// The step of epoch `epoch` (kept).
    pub fn step(&self, epoch: usize) -> &Step {
        &self.steps[epoch - self.first_epoch()]
    }

    /// The first kept epoch that takes a reading at `time` \[s\]: the first whose reach
    /// is at or after it (None: none kept does).
    pub fn epoch_of(&self, time: f64) -> Option<usize> {
        let first = self.first_epoch();
        self.steps
            .iter()
            .position(|s| s.reach() >= time)
            .map(|i| first + i)
    }

    /// Where a reading of `(epoch, sensor, time)` goes among the kept ones.
    pub fn position(&self, epoch: usize, sensor: usize, time: f64) -> usize {
        // From the back: a late reading is usually recent.
        let mut i = self.kept.len();
        while i > 0 && self.kept[i - 1].after(epoch, sensor, time) {
            i -= 1;
        }
        i
    }

    /// The index of the latest checkpoint before `epoch`.
    pub fn checkpoint_before(&self, epoch: usize) -> usize {
        self.checkpoints
            .iter()
            .rposition(|c| c.epoch < epoch)
            .unwrap_or(0)
    }

    /// `Err` naming `lag` when the history's next growth would not fit in the memory
    /// this process can still take: checked when the epoch under way may fill the
    /// steps' or the checkpoints' buffer (the next push doubles it), for the doubled
    /// buffers and the checkpoints (one every `every` epochs) of as many epochs again.
    /// A few times per doubling: a lag window that fits costs nothing per step.
    pub fn check_growth(&self, every: usize) -> Result<()> {
        let filling = |len: usize, capacity: usize| len + 1 >= capacity;
        let (steps, checkpoints) = (&self.steps, &self.checkpoints);
        if !filling(steps.len(), steps.capacity())
            && !filling(checkpoints.len(), checkpoints.capacity())
        {
            return Ok(());
        }
        let more = (steps.capacity().max(checkpoints.capacity() * every)).max(4) as f64;
        let first = &self.checkpoints[0];
        // Its slot (the buffer doubles too) and its boxed strategy.
        let checkpoint = 2 * size_of::<Checkpoint>() + size_of_val(&*first.strategy) + BOX_OVERHEAD;
        let remedy = "a shorter lag, or a checkpoint every more epochs (checkpoint_every)";
        let mut e = Estimate::default();
        e.add(
            "lag",
            "IMU steps of the lag window",
            (2.0 * more, size_of::<Step>() as f64),
            remedy,
        );
        e.add(
            "lag",
            "checkpoints of the lag window",
            ((more / every as f64).ceil(), checkpoint as f64),
            remedy,
        );
        e.check("the lag window's history")
    }

    /// Drop what no reading at or after `oldest` \[s\] needs: the checkpoints whose
    /// successor already reaches no such reading, then the steps and readings up to the
    /// first checkpoint left. `settle` is told each reading dropped.
    pub fn prune(&mut self, oldest: f64, mut settle: impl FnMut(&Kept)) {
        while self.checkpoints.len() >= 2 && self.checkpoints[1].reach < oldest {
            self.checkpoints.pop_front();
        }
        let origin = self.checkpoints[0].epoch;
        if origin == self.origin {
            return;
        }
        self.steps.drain(..origin - self.origin);
        self.origin = origin;
        while self.kept.front().is_some_and(|k| k.epoch <= origin) {
            if let Some(k) = self.kept.pop_front() {
                settle(&k);
            }
        }
    }
}
