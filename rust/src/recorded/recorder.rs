//! The observer that writes a recorded pass's [`FilterOutput`] as the pass runs: the
//! kept epochs (with their σ inside a covariance step, [`StaleSigma`]), each stream's
//! rows, and the covariances asked for.

use super::data::RecordedData;
use super::epochs::{Epochs, Thinning};
use super::output::{FilterOutput, StreamRecord};
use super::stale::StaleSigma;
use crate::ekf::{Applied, Ekf, Matrix15, ProcessNoise, Transition};
use crate::measurement::Reading;
use crate::noise::NoiseStrategy;
use crate::pages::vec_with_capacity;
use crate::pass::{Epoch, Observer, Updated, Watch};

/// The observer that writes a recorded pass's [`FilterOutput`].
pub(super) struct Recorder<'d> {
    pub(super) out: FilterOutput,
    data: &'d RecordedData<'d>,
    /// Whether the epochs are kept at all (not [`Epochs::Last`]), and which.
    some: bool,
    /// Whether the solution is kept as whole navigation states, for the smoother.
    states: bool,
    thinning: Option<Thinning>,
    stale: StaleSigma,
    watch: Watch,
    next_covariance: usize,
    /// The stream and row of each reading of the epoch under way.
    pub(super) sources: Vec<(usize, usize)>,
    /// The step \[s\] after the epoch under way.
    pub(super) next_dt: f64,
}

impl<'d> Recorder<'d> {
    /// An empty output with room for the epochs `epochs` keeps of `data` (as whole
    /// navigation `states`, for the smoother, or as rows), and the initial state `ekf`
    /// kept.
    pub(super) fn start(
        data: &'d RecordedData<'d>,
        epochs: Epochs,
        states: bool,
        ekf: &Ekf,
    ) -> Self {
        let n = data.imu.len();
        let kept = epochs.kept(n, data.imu_time[n - 1] - data.t0);
        let streams = data
            .streams
            .iter()
            .map(|s| {
                let (rows, velocity) = (s.len(), s.is_velocity());
                StreamRecord {
                    epoch: vec![None; rows],
                    nis: vec![f64::NAN; rows],
                    updates: if velocity {
                        vec![None; rows]
                    } else {
                        Vec::new()
                    },
                    adaptive_q: if velocity {
                        vec![None; rows]
                    } else {
                        Vec::new()
                    },
                }
            })
            .collect();
        let calibrated = ekf.calibration.is_some();
        let rows = if states { 0 } else { kept };
        let mut out = FilterOutput {
            time: vec_with_capacity(kept),
            lla: vec_with_capacity(rows),
            vel: vec_with_capacity(rows),
            rpy: vec_with_capacity(rows),
            nav: vec_with_capacity(kept - rows),
            bias: vec_with_capacity(kept),
            sigma: vec_with_capacity(kept),
            streams,
            ..FilterOutput::default()
        };
        if calibrated {
            out.calibration = vec_with_capacity(kept);
            out.calibration_sigma = vec_with_capacity(kept);
        }
        if matches!(epochs, Epochs::Step(_)) {
            out.epoch = vec_with_capacity(kept);
        }
        // Room for every covariance asked for at once (grown as they come, up to twice).
        let asked = data.covariance_time.len();
        out.covariance_epoch.reserve_exact(asked);
        out.covariances.reserve_exact(asked);
        let first_dt = data.imu_time[0] - data.t0;
        let mut recorder = Self {
            out,
            data,
            some: epochs != Epochs::Last,
            states,
            thinning: Thinning::of(epochs, data.t0, first_dt),
            stale: StaleSigma::default(),
            watch: Watch::start(ekf, data.t0),
            next_covariance: 0,
            sources: Vec::new(),
            next_dt: first_dt,
        };
        if recorder.some {
            recorder.out.record(ekf, data.t0, states);
            if recorder.thinning.is_some() {
                recorder.out.epoch.push(0);
            }
            recorder
                .stale
                .after_epoch(ekf, &mut recorder.out, data.t0, true);
        }
        recorder.keep_covariances(ekf, 0, data.t0);
        recorder
    }

    /// At the end of the pass: the last epoch's estimate where no epoch was kept
    /// ([`Epochs::Last`]), the last covariance, and the asked-for covariances beyond
    /// the last epoch's half step outside the run.
    pub(super) fn finish(mut self, ekf: &Ekf, t_last: f64) -> FilterOutput {
        if !self.some {
            self.out.record(ekf, t_last, self.states);
        }
        self.out.final_covariance = ekf.covariance();
        self.out.extent = self.watch.extent;
        let asked = self.data.covariance_time.len();
        self.out.covariance_epoch.resize(asked, None);
        self.out.covariances.resize(asked, None);
        self.out
    }

    /// Keep the covariance (classic coordinates) for every asked-for time whose
    /// nearest epoch is `epoch` (time `t` \[s\]): the times before or at
    /// `t + next_dt/2` not yet taken. Times before the run's first half step are outside
    /// it (None), as readings are.
    fn keep_covariances(&mut self, ekf: &Ekf, epoch: usize, t: f64) {
        let times = self.data.covariance_time;
        let first = self.data.first_time();
        let mut kept: Option<Matrix15> = None;
        while self.next_covariance < times.len()
            && times[self.next_covariance] <= t + 0.5 * self.next_dt
        {
            if times[self.next_covariance] < first {
                self.out.covariance_epoch.push(None);
                self.out.covariances.push(None);
            } else {
                let p = *kept.get_or_insert_with(|| ekf.covariance_up_to_date());
                self.out.covariance_epoch.push(Some(epoch));
                self.out.covariances.push(Some(p));
            }
            self.next_covariance += 1;
        }
    }
}

impl Observer for Recorder<'_> {
    fn on_close(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        self.stale.on_close(ekf);
        self.watch.on_close(epoch, ekf, phi);
    }

    fn on_reading(
        &mut self,
        at: &Epoch<'_>,
        i: usize,
        reading: &Reading,
        applied: &mut Applied,
        _ekf: &Ekf,
        strategy: &dyn NoiseStrategy,
    ) {
        let (stream, row) = self.sources[i];
        let record = &mut self.out.streams[stream];
        record.epoch[row] = Some(at.index);
        record.nis[row] = applied.nis;
        if let Reading::Velocity(_) = reading {
            self.out.nis_monitor.push(applied.nis, at.t);
            // Mehra's Q̂ is built from the reported (classic) gain: classic already.
            record.adaptive_q[row] = strategy.discrete_q().map(|q| Box::new(*q));
            record.updates[row] = applied.report.take();
        }
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        updated: Option<&mut Updated>,
        noise: ProcessNoise<'_>,
    ) {
        self.keep_covariances(ekf, at.index, at.t);
        self.watch.after_epoch(at, ekf, updated, noise);
        if self.some {
            let recorded = match self.thinning.as_mut() {
                None => true,
                Some(thin) => thin.keeps(at.t, self.next_dt) || at.last,
            };
            if recorded {
                self.out.record(ekf, at.t, self.states);
                if self.thinning.is_some() {
                    self.out.epoch.push(at.index);
                }
            }
            self.stale.after_epoch(ekf, &mut self.out, at.t, recorded);
        }
    }
}
