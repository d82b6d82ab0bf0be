//! [`Navigator`]: the filter pass fed as the data arrives.

use super::history::{Checkpoint, History, Kept, Outcome, Step};
use super::sensor::Sensor;
use super::stamps::Stamps;
use super::tally::Tally;
use super::tuning::{Tuning, Window};
use crate::ekf::calibration::DvlErrors;
use crate::ekf::{Applied, Ekf, FilterConfig};
use crate::error::{check, Error, Result};
use crate::measurement::Reading;
use crate::mechanization::{imu_row_problem, ImuSample, NavState};
use crate::noise::NoiseStrategy;
use crate::pass::{Epoch, Extent, Failure, Observer, Pass, Watch};
use crate::recorded::start_filter;
use std::collections::VecDeque;

/// How a navigator keeps its history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lag {
    /// How long \[s\] before the newest IMU sample a reading may be stamped and still be
    /// applied at its own epoch (finite, ≥ 0).
    pub window: f64,
    /// A copy of the filter every `every` epochs (≥ 1): a late reading runs the pass
    /// again from the last copy before its epoch, at most `every` epochs more than the
    /// stretch after it.
    pub every: usize,
}

impl Default for Lag {
    fn default() -> Self {
        Self {
            window: 1.0,
            every: 32,
        }
    }
}

impl Lag {
    pub fn validate(&self) -> Result<()> {
        if !(self.window.is_finite() && self.window >= 0.0) {
            return Err(Error::invalid(
                "lag",
                format!("must be a finite time >= 0 [s], got {}", self.window),
            ));
        }
        if self.every == 0 {
            return Err(Error::invalid(
                "checkpoint_every",
                "must be at least 1 epoch",
            ));
        }
        Ok(())
    }
}

/// Where a navigator starts: the time `t0` \[s\], the navigation state and the bias
/// estimates `[b_a (m/s²), b_g (rad/s)]`.
#[derive(Clone, Copy, Debug)]
pub struct Start {
    pub t0: f64,
    pub nav: NavState,
    pub bias: [f64; 6],
}

/// What became of a reading fed to a navigator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// Stamped after the newest epoch's reach: applied when the IMU gets there.
    Queued,
    /// Stamped after the newest IMU sample but within its epoch's half step: applied
    /// at that epoch (in time: the pass run again from the last checkpoint).
    Current,
    /// Stamped before the newest IMU sample, within the lag window: applied at its
    /// own epoch, and the pass run again since.
    Late,
    /// Stamped before the lag window: refused (counted).
    Refused,
    /// Stamped before the first IMU sample's half step: outside the pass, as a
    /// stream's row there is (counted).
    Skipped,
}

/// The navigation state at the newest epoch, its covariance brought up to date.
#[derive(Clone, Debug)]
pub struct Estimate {
    /// The epoch (0: the initial state; k: after the k-th IMU sample) and its time \[s\].
    pub epoch: usize,
    pub t: f64,
    pub nav: NavState,
    /// `[b_a (m/s²), b_g (rad/s)]`.
    pub bias: [f64; 6],
    /// 1σ of the 15 errors (classic coordinates).
    pub sigma: [f64; 15],
    /// With the DVL error states: `[k̂, roll, pitch, yaw, b̂]` and the 1σ of
    /// `[δk, δμ, δb]`.
    pub calibration: Option<(DvlErrors, DvlErrors)>,
}

/// The filter pass fed as the data arrives: IMU samples one at a time (or in blocks),
/// each sensor's readings by time, in any order within the lag window. Fed in time
/// order, every epoch is the batch pass's ([`crate::recorded::filter_recorded`]) bit
/// for bit: a reading is applied at the first epoch that reaches it (its time at most
/// half a step after the epoch's), stream by stream in the sensors' order. A reading
/// for an epoch already run is applied there by running the pass again from the last
/// checkpoint before it; memory is bounded by the lag window, whatever the mission's
/// length.
pub struct Navigator {
    pass: Pass,
    strategy: Box<dyn NoiseStrategy>,
    sensors: Vec<Sensor>,
    lag: Lag,
    /// The newest epoch, its time \[s\] and step \[s\] (0 before the first sample).
    epoch: usize,
    t: f64,
    dt: f64,
    /// The time \[s\] before which a reading is outside the pass (known at the first
    /// IMU sample), and the latest reading time any epoch so far takes.
    first: Option<f64>,
    reach: f64,
    pending: Vec<VecDeque<(f64, Reading)>>,
    history: History,
    settled: Vec<Tally>,
    /// The IMU variances set for the next step.
    q_next: Option<[f64; 6]>,
    tuning: Option<(Tuning, Window)>,
    /// A failure that stopped the pass, repeated to every later call.
    failed: Option<Error>,
    readings: Vec<Reading>,
    outcomes: Vec<Option<Outcome>>,
    /// What the pass watched for its health, every epoch so far.
    watch: Watch,
    /// The IMU's steps so far and the gaps among them.
    stamps: Stamps,
}

impl Navigator {
    /// A navigator from `start` with the filter `cfg`, the noise `strategy` and the
    /// `sensors`, whose readings are applied at an epoch in this order. `tuning`: the
    /// learned loop's instants (see [`Navigator::tuning_due`]).
    pub fn new(
        start: Start,
        cfg: &FilterConfig,
        strategy: Box<dyn NoiseStrategy>,
        sensors: Vec<Sensor>,
        lag: Lag,
        tuning: Option<Tuning>,
    ) -> Result<Self> {
        lag.validate()?;
        check::finite("t0", &[start.t0])?;
        for sensor in &sensors {
            sensor.check_config(cfg)?;
        }
        let ekf = start_filter(&start.nav, &start.bias, cfg, strategy.as_ref())?;
        let watch = Watch::start(&ekf, start.t0);
        let pass = Pass::new(ekf);
        let t0 = start.t0;
        let start = Checkpoint {
            epoch: 0,
            reach: f64::NEG_INFINITY,
            pass: pass.clone(),
            strategy: strategy.clone_box(),
            watch,
        };
        let n = sensors.len();
        Ok(Self {
            pass,
            strategy,
            sensors,
            lag,
            epoch: 0,
            t: t0,
            dt: 0.0,
            first: None,
            reach: f64::NEG_INFINITY,
            pending: vec![VecDeque::new(); n],
            history: History::new(start),
            settled: vec![Tally::default(); n],
            q_next: None,
            tuning: tuning.map(|t| (t, Window::new(t.window))),
            failed: None,
            readings: Vec::new(),
            outcomes: Vec::new(),
            watch,
            stamps: Stamps::default(),
        })
    }

    /// The sensors, in the order their readings are applied at an epoch.
    pub fn sensors(&self) -> &[Sensor] {
        &self.sensors
    }

    /// The filter at the newest epoch.
    pub fn filter(&self) -> &Ekf {
        &self.pass.ekf
    }

    /// The newest epoch (the number of IMU samples fed).
    pub fn epoch(&self) -> usize {
        self.epoch
    }

    /// The estimate at the newest epoch, σ brought up to date (on a copy: asking
    /// changes nothing that follows).
    pub fn estimate(&self) -> Estimate {
        let ekf = &self.pass.ekf;
        let current;
        let up_to_date = if ekf.is_up_to_date() {
            ekf
        } else {
            let mut copy = ekf.clone();
            copy.bring_up_to_date();
            current = copy;
            &current
        };
        Estimate {
            epoch: self.epoch,
            t: self.t,
            nav: ekf.nav,
            bias: ekf.bias(),
            sigma: up_to_date.sigma(),
            calibration: (up_to_date.calibration.as_ref()).map(|c| (c.reported(), c.sigma())),
        }
    }

    /// What the pass watched for its health over every epoch so far: the first epoch
    /// whose solution left a physical bound, and the heading σ.
    pub fn extent(&self) -> Extent {
        self.watch.extent
    }

    /// The IMU's steps so far and the gaps among them.
    pub fn stamps(&self) -> Stamps {
        self.stamps
    }

    /// Each sensor's tally so far.
    pub fn tally(&self) -> Vec<Tally> {
        let mut tally = self.settled.clone();
        for kept in &self.history.kept {
            tally[kept.sensor].add(kept);
        }
        for (t, pending) in tally.iter_mut().zip(&self.pending) {
            t.queued = pending.len();
        }
        tally
    }

    /// The IMU steps its history keeps.
    #[cfg(test)]
    pub(super) fn kept_steps(&self) -> usize {
        self.history.steps.len()
    }

    /// The error that stopped the pass, if one did.
    pub fn failure(&self) -> Option<&Error> {
        self.failed.as_ref()
    }

    /// Ok while the pass runs; the failure that stopped it after (every call that
    /// feeds it, or asks for its state, answers so).
    pub fn alive(&self) -> Result<()> {
        match &self.failed {
            None => Ok(()),
            Some(e) => Err(e.clone()),
        }
    }

    /// Set the IMU variances `q` \[(m/s²)², (rad/s)²\] from the next IMU step on (a
    /// strategy that takes q from outside: the learned loop).
    pub fn set_q(&mut self, q: [f64; 6]) -> Result<()> {
        self.alive()?;
        if !self.strategy.takes_outside_q() {
            return Err(Error::invalid(
                "strategy",
                "q set from outside needs an external strategy (Strategy.external)",
            ));
        }
        check::non_negative("q", &q)?;
        self.q_next = Some(q);
        Ok(())
    }

    /// Whether the newest epoch is a tuning instant of the learned loop: its window of
    /// raw samples ([`Navigator::window`]) is full and the instant is due, so the q it
    /// gives should be set ([`Navigator::set_q`]) before the next sample.
    pub fn tuning_due(&self) -> bool {
        self.tuning
            .as_ref()
            .is_some_and(|(t, _)| t.due_after(self.epoch))
    }

    /// The learned loop's window: the last raw IMU samples, oldest first (None without
    /// a tuning, or before it is full).
    pub fn window(&self) -> Option<Vec<[f64; 6]>> {
        self.tuning.as_ref().and_then(|(_, w)| w.samples())
    }

    /// Feed the IMU samples `raw` ending at `times` \[s\] in order, stopping after a
    /// tuning instant ([`Navigator::tuning_due`]): the number fed. Every sample and time
    /// is checked first, so that a block with a bad one feeds none.
    pub fn feed_imu_block(&mut self, times: &[f64], raw: &[[f64; 6]]) -> Result<usize> {
        self.alive()?;
        let mut last = self.t;
        for (k, (&t, row)) in times.iter().zip(raw).enumerate() {
            if !(t.is_finite() && t > last) {
                let before = if k == 0 {
                    "the newest epoch's time"
                } else {
                    "the row before's"
                };
                return Err(Error::invalid(
                    "imu_time",
                    format!(
                        "row {k} ({t} s) must be finite and after {before} {last} [s]; none fed"
                    ),
                ));
            }
            if let Some(problem) = imu_row_problem(row) {
                let what = format!("row {k} (at {t} s) {problem}: {row:?}; none fed");
                return Err(Error::invalid("imu", what));
            }
            last = t;
        }
        for (k, (&t, row)) in times.iter().zip(raw).enumerate() {
            self.feed_imu(t, row)?;
            if self.tuning_due() {
                return Ok(k + 1);
            }
        }
        Ok(times.len())
    }

    /// Feed the IMU sample `raw` (`[f (m/s²), ω (rad/s)]`, body FRD) ending at `t` \[s\]
    /// (after the newest): the epoch it ends, with the readings due there.
    pub fn feed_imu(&mut self, t: f64, raw: &[f64; 6]) -> Result<()> {
        self.alive()?;
        if !(t.is_finite() && t > self.t) {
            return Err(Error::invalid(
                "imu_time",
                format!(
                    "{t} must be finite and after the newest epoch's time {} [s]",
                    self.t
                ),
            ));
        }
        if let Some(problem) = imu_row_problem(raw) {
            return Err(Error::invalid(
                "imu",
                format!("the sample at {t} s {problem}: {raw:?}"),
            ));
        }
        self.history.check_growth(self.lag.every)?;
        let dt = t - self.t;
        let epoch = self.epoch + 1;
        if self.first.is_some() {
            self.stamps.push(t, dt);
        } else {
            let first = self.t - 0.5 * dt;
            self.first = Some(first);
            for (tally, pending) in self.settled.iter_mut().zip(&mut self.pending) {
                while pending.front().is_some_and(|(time, _)| *time < first) {
                    pending.pop_front();
                    tally.skipped += 1;
                }
            }
        }
        let step = Step {
            t,
            dt,
            raw: *raw,
            q: self.q_next.take(),
        };
        if let Some(q) = step.q {
            self.strategy.set_imu_variance(&q)?;
        }
        let reach = step.reach();
        for (sensor, pending) in self.pending.iter_mut().enumerate() {
            while let Some(&(time, reading)) = pending.front().filter(|(time, _)| *time <= reach) {
                pending.pop_front();
                self.history.kept.push_back(Kept {
                    epoch,
                    sensor,
                    time,
                    reading,
                    outcome: None,
                    late: false,
                });
            }
        }
        let from = self.history.kept.len()
            - self
                .history
                .kept
                .iter()
                .rev()
                .take_while(|k| k.epoch == epoch)
                .count();
        self.run(epoch, &step, from)?;
        self.history.steps.push_back(step);
        self.epoch = epoch;
        self.t = t;
        self.dt = dt;
        self.reach = self.reach.max(reach);
        if epoch.is_multiple_of(self.lag.every) {
            self.checkpoint();
        }
        let settled = &mut self.settled;
        self.history
            .prune(t - self.lag.window, |k| settled[k.sensor].add(k));
        if let Some((_, window)) = self.tuning.as_mut() {
            window.push(raw);
        }
        Ok(())
    }

    /// Feed the reading `value` of sensor `sensor` stamped `time` \[s\], with its own
    /// 1σ `sigma` (None: the sensor's); see [`Fate`].
    pub fn feed_reading(
        &mut self,
        sensor: usize,
        time: f64,
        value: &[f64],
        sigma: Option<&[f64]>,
    ) -> Result<Fate> {
        self.alive()?;
        let Some(s) = self.sensors.get(sensor) else {
            return Err(Error::invalid(
                "stream",
                format!(
                    "must be the index of one of the {} streams, got {sensor}",
                    self.sensors.len()
                ),
            ));
        };
        let reading = s.reading(time, value, sigma)?;
        self.settled[sensor].received += 1;
        if self.first.is_some_and(|first| time < first) {
            self.settled[sensor].skipped += 1;
            return Ok(Fate::Skipped);
        }
        if self.epoch == 0 || time > self.t + 0.5 * self.dt {
            let pending = &mut self.pending[sensor];
            let at = pending.len() - pending.iter().rev().take_while(|(t, _)| *t > time).count();
            pending.insert(at, (time, reading));
            return Ok(Fate::Queued);
        }
        let oldest = self.t - self.lag.window;
        let epoch = self.history.epoch_of(time);
        let (Some(epoch), false) = (
            epoch,
            time < oldest || time <= self.history.checkpoints[0].reach,
        ) else {
            self.settled[sensor].refused += 1;
            return Ok(Fate::Refused);
        };
        let at = self.history.position(epoch, sensor, time);
        let late = time < self.t;
        self.history.kept.insert(
            at,
            Kept {
                epoch,
                sensor,
                time,
                reading,
                outcome: None,
                late,
            },
        );
        self.rerun_from(epoch)?;
        Ok(if late { Fate::Late } else { Fate::Current })
    }

    /// Run the pass again from the last checkpoint before `epoch` to the newest epoch.
    fn rerun_from(&mut self, epoch: usize) -> Result<()> {
        let c = self.history.checkpoint_before(epoch);
        self.history.checkpoints.truncate(c + 1);
        let start = self.history.checkpoints[c].clone();
        self.pass = start.pass;
        self.strategy = start.strategy;
        self.watch = start.watch;
        let mut from = self
            .history
            .position(start.epoch, usize::MAX, f64::INFINITY);
        let mut reach = start.reach;
        for e in start.epoch + 1..=self.epoch {
            let step = self.history.step(e).clone();
            if let Some(q) = step.q {
                self.strategy.set_imu_variance(&q)?;
            }
            self.run(e, &step, from)?;
            from += self
                .history
                .kept
                .range(from..)
                .take_while(|k| k.epoch == e)
                .count();
            reach = reach.max(step.reach());
            if e.is_multiple_of(self.lag.every) {
                self.history.checkpoints.push_back(Checkpoint {
                    epoch: e,
                    reach,
                    pass: self.pass.clone(),
                    strategy: self.strategy.clone_box(),
                    watch: self.watch,
                });
            }
        }
        Ok(())
    }

    /// Run epoch `epoch` over `step` with the kept readings of that epoch from index
    /// `from` on, writing their outcomes. A failure stops the navigator.
    fn run(&mut self, epoch: usize, step: &Step, from: usize) -> Result<()> {
        self.readings.clear();
        self.readings.extend(
            self.history
                .kept
                .range(from..)
                .take_while(|k| k.epoch == epoch)
                .map(|k| k.reading),
        );
        self.outcomes.clear();
        self.outcomes.resize(self.readings.len(), None);
        let raw = ImuSample::from_array(&step.raw);
        let at = Epoch {
            index: epoch,
            raw: &raw,
            dt: step.dt,
            t: step.t,
            last: false,
        };
        let mut observer = (Outcomes(&mut self.outcomes), &mut self.watch);
        if let Err(f) = self
            .pass
            .epoch(self.strategy.as_mut(), &at, &self.readings, &mut observer)
        {
            let error = self.context(f, from, step.t);
            self.failed = Some(error.clone());
            return Err(error);
        }
        for (k, o) in self.history.kept.range_mut(from..).zip(&self.outcomes) {
            k.outcome = *o;
        }
        Ok(())
    }

    fn checkpoint(&mut self) {
        self.history.checkpoints.push_back(Checkpoint {
            epoch: self.epoch,
            reach: self.reach,
            pass: self.pass.clone(),
            strategy: self.strategy.clone_box(),
            watch: self.watch,
        });
    }

    /// A failure of the pass at time `t` \[s\], named with its sensor and reading time.
    fn context(&self, failure: Failure, from: usize, t: f64) -> Error {
        let stopped = "the navigator stopped (make a new one to go on)";
        match (failure.error, failure.reading) {
            (Error::Numerical(m), None) => {
                Error::Numerical(format!("{m} (the IMU step to t = {t} s); {stopped}"))
            }
            (Error::Numerical(m), Some(i)) => {
                let k = &self.history.kept[from + i];
                let name = self.sensors[k.sensor].name();
                Error::Numerical(format!(
                    "{m} ({name} reading at {} s, epoch t = {t} s); {stopped}",
                    k.time
                ))
            }
            (other, _) => other,
        }
    }
}

/// Writes each reading's outcome.
struct Outcomes<'a>(&'a mut Vec<Option<Outcome>>);

impl Observer for Outcomes<'_> {
    fn on_reading(
        &mut self,
        _at: &Epoch<'_>,
        i: usize,
        _reading: &Reading,
        applied: &mut Applied,
        _ekf: &Ekf,
        _strategy: &dyn NoiseStrategy,
    ) {
        self.0[i] = Some(Outcome {
            nis: applied.nis,
            dof: applied.dof,
            accepted: applied.accepted,
        });
    }
}
