//! One simulated run of a scenario, stepped one IMU sample at a time: the sensor
//! simulation feeding the one epoch loop ([`crate::pass`]), and the metrics, NIS/NEES
//! and histories it reports against the truth.

use crate::attitude::exp_so3;
use crate::earth;
use crate::ekf::{Ekf, FilterConfig, ACC_BIAS, ATT, POS, VEL};
use crate::error::Result;
use crate::measurement::{Reading, Velocity};
use crate::mechanization::{ImuSample, NavState};
use crate::noise::{NoiseStrategy, StrategySpec};
use crate::pass::{Epoch, Pass};
use crate::scenario::Scenario;
use crate::sensors::{normal, stream_rng, AidingSim, SensorSim, Stream};
use crate::trajectory::Truth;
use nalgebra::Vector3;
use std::mem::size_of;

mod aiding;
mod memory;
mod metrics;
mod smoothing;
pub use memory::{RunMemory, RUN_BYTES};
use metrics::{calibration_error, state_error, Tally, Updates};
pub use metrics::{CalibrationSummary, History, RunSummary};
pub use smoothing::SmoothedRecord;
use smoothing::SmootherLog;

/// Everything one run reports.
#[derive(Clone, Debug, PartialEq)]
pub struct RunRecord {
    pub summary: RunSummary,
    /// NIS at each DVL epoch (gate-rejected updates included).
    pub nis: Vec<f64>,
    /// NEES of the position, velocity, attitude, accelerometer-bias and gyro-bias
    /// blocks after each DVL update (3 dof each).
    pub nees: Vec<[f64; 5]>,
    /// NEES of the DVL calibration states `[δk, δμ]` after each DVL update (4 dof);
    /// empty without them.
    pub calibration_nees: Vec<f64>,
    pub history: Option<History>,
    /// The RTS smoother's metrics of the run, when it was asked for
    /// ([`Run::keep_for_smoother`]) and the filter did not fail.
    pub smoothed: Option<SmoothedRecord>,
}

impl RunMemory {
    /// What one run of `scenario` filtered with `cfg` holds (`discrete`: its strategy
    /// sets the per-step Q itself), a DVL reading every `dvl_every` IMU steps, its
    /// histories every `record_every` (0: none), handing out `window` raw samples (0:
    /// none), smoothed or not.
    pub fn of(
        scenario: &Scenario,
        cfg: &FilterConfig,
        sizes: (Option<usize>, usize, usize),
        flags: (bool, bool),
    ) -> Self {
        let types = (size_of::<Run>(), size_of::<RunRecord>());
        Self::with_sizes(scenario, cfg, sizes, flags, types)
    }
}

/// The last N raw IMU samples of a run, as the regressor reads them.
struct ImuWindow {
    buf: Vec<[f32; 6]>,
    head: usize,
}

impl ImuWindow {
    fn new(n: usize) -> Self {
        Self {
            buf: vec![[0.0; 6]; n],
            head: 0,
        }
    }

    fn push(&mut self, s: &[f64; 6]) {
        self.buf[self.head] = s.map(|x| x as f32);
        self.head = (self.head + 1) % self.buf.len();
    }

    /// Write the window channel-major, oldest sample first, into `out` (6·N values).
    fn write_channels(&self, out: &mut [f32]) {
        let n = self.buf.len();
        for c in 0..6 {
            for j in 0..n {
                out[c * n + j] = self.buf[(self.head + j) % n][c];
            }
        }
    }
}

/// One simulated run, stepped one IMU sample at a time.
/// The scenario is passed to every call rather than stored, so stepping touches no
/// shared reference count.
pub struct Run {
    pass: Pass,
    strategy: Box<dyn NoiseStrategy>,
    /// Whether the strategy is told the true IMU variance before every step.
    oracle: bool,
    sim: SensorSim,
    /// IMU steps per DVL reading; None without a DVL.
    dvl_every: Option<usize>,
    /// The depth sensor and position fixes; None without them.
    aiding: Option<AidingSim>,
    /// The readings due at the epoch under way.
    readings: Vec<Reading>,
    record_every: usize,
    k: usize,
    true_bias: [f64; 6],
    sum_sq: f64,
    sum_abs: f64,
    /// North and east position error \[m\] now, and where its norm was largest (the norm
    /// is taken once at the end: `hypot` every step cost ~3 % of a Monte Carlo).
    horizontal: [f64; 2],
    max_horizontal: [f64; 2],
    max_horizontal_sq: f64,
    updates: Updates,
    history: Option<History>,
    window: Option<ImuWindow>,
    failure: Option<String>,
    smoother: Option<Box<SmootherLog>>,
}

/// Run `run_index`'s start: the filter's initial navigation solution and the IMU's
/// true turn-on bias `[b_a, b_g]`. The filter starts from its prior mean, the bias
/// estimates at zero; the turn-on bias is the configured one, less a draw from the
/// prior when initial errors are sampled, so that every initial error (the biases'
/// too) is a draw from P0 about the configured offset.
pub(crate) fn initial_state(
    scenario: &Scenario,
    filter: &FilterConfig,
    seed: u64,
    run_index: u64,
) -> (NavState, [f64; 6]) {
    let mut nav = scenario.truth.states[0];
    let mut bias = scenario.sensors.imu.bias;
    if scenario.sample_initial_error {
        let mut rng = stream_rng(seed, run_index, Stream::InitialError);
        let dx: [f64; 15] = std::array::from_fn(|i| filter.p0_sigma[i] * normal(&mut rng));
        let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
        nav.lla += earth::ned_delta_to_lla_delta(&nav.lla, &block(POS));
        nav.vel += block(VEL);
        nav.dcm = exp_so3(&(-block(ATT))) * nav.dcm;
        for (i, b) in bias.iter_mut().enumerate() {
            *b -= dx[ACC_BIAS + i];
        }
    }
    (nav, bias)
}

impl Run {
    pub fn new(
        scenario: &Scenario,
        filter: &FilterConfig,
        strategy: &StrategySpec,
        seed: u64,
        run_index: u64,
        record_every: usize,
        window: Option<usize>,
    ) -> Result<Self> {
        let dvl_every = scenario.dvl_every()?;
        let (nav, true_bias) = initial_state(scenario, filter, seed, run_index);
        let mut ekf = Ekf::new(filter, nav, Vector3::zeros(), Vector3::zeros())?;
        let strategy = strategy.build(filter.bias_psd());
        if let Some(q) = strategy.sensitivity_q() {
            ekf.track_sensitivity(q);
        }
        let n_epochs = dvl_every.map_or(0, |every| scenario.truth.len() / every);
        let aiding = AidingSim::new(scenario.sensors.aiding(), &scenario.truth, seed, run_index)?;
        let mut run = Self {
            sim: SensorSim::new(&scenario.sensors, seed, run_index).with_turn_on_bias(true_bias),
            pass: Pass::new(ekf),
            oracle: strategy.wants_true_variance(),
            strategy,
            dvl_every,
            aiding,
            readings: Vec::new(),
            record_every,
            k: 0,
            true_bias,
            sum_sq: 0.0,
            sum_abs: 0.0,
            horizontal: [0.0; 2],
            max_horizontal: [0.0; 2],
            max_horizontal_sq: 0.0,
            updates: Updates {
                nis: Vec::with_capacity(n_epochs),
                nees: Vec::with_capacity(n_epochs),
                ..Updates::default()
            },
            history: (record_every > 0)
                .then(|| History::with_capacity(scenario.truth.len() / record_every + 1)),
            window: window.map(ImuWindow::new),
            failure: None,
            smoother: None,
        };
        if run.oracle {
            // the q in force at the start, as the histories report it
            let q = run
                .sim
                .variance(&scenario.sensors.imu, scenario.truth.time[0]);
            run.strategy.set_true_variance(&q);
        }
        run.record_history(&scenario.truth);
        Ok(run)
    }

    fn ekf(&self) -> &Ekf {
        &self.pass.ekf
    }

    fn record_history(&mut self, truth: &Truth) {
        if let Some(h) = self.history.as_mut() {
            if self.k.is_multiple_of(self.record_every) {
                let ekf = &self.pass.ekf;
                let truth = &truth.states[self.k];
                h.error.push(state_error(ekf, truth, &self.true_bias));
                h.sigma.push(ekf.sigma_up_to_date());
                h.imu_variance
                    .push(self.strategy.imu_variance().unwrap_or([f64::NAN; 6]));
            }
        }
    }

    /// Advance by one IMU sample (and the updates due at its end).
    pub fn step(&mut self, scenario: &Scenario) {
        let truth = &*scenario.truth;
        let ideal = &truth.imu[self.k];
        self.true_bias = *self.sim.bias();
        if self.oracle {
            let q = self.sim.variance(&scenario.sensors.imu, truth.time[self.k]);
            self.strategy.set_true_variance(&q);
        }
        let raw = self
            .sim
            .imu(&scenario.sensors.imu, ideal, truth.time[self.k], truth.dt);
        if let Some(w) = self.window.as_mut() {
            w.push(&raw);
        }
        self.k += 1;
        let state = &truth.states[self.k];
        let t = truth.time[self.k];
        if self.failure.is_none() {
            self.sense(scenario, ideal, state);
            let at = Epoch {
                index: self.k,
                raw: &ImuSample::from_array(&raw),
                dt: truth.dt,
                t,
                last: false,
            };
            let tally = Tally {
                updates: &mut self.updates,
                truth: state,
                true_bias: &self.true_bias,
                mounting: &scenario.sensors.dvl.mounting,
            };
            let log = self.smoother.as_deref_mut().map(|log| {
                let recorded = self.record_every > 0 && self.k.is_multiple_of(self.record_every);
                log.at_epoch(raw, self.true_bias, recorded)
            });
            let strategy = self.strategy.as_mut();
            let done = self
                .pass
                .epoch(strategy, &at, &self.readings, &mut (tally, log));
            if let Err(f) = done {
                self.failure = Some(format!("t = {t} s: {}", f.error));
            }
        }
        let dv = self.pass.ekf.nav.vel - state.vel;
        self.sum_sq += dv.norm_squared();
        self.sum_abs += dv.abs().sum();
        let dp = truth.ned_scale[self.k].error(&self.pass.ekf.nav.lla, &state.lla);
        self.horizontal = [dp[0], dp[1]];
        let sq = dp[0] * dp[0] + dp[1] * dp[1];
        if sq > self.max_horizontal_sq {
            // a NaN never compares greater: skipped, as f64::max skips it
            self.max_horizontal_sq = sq;
            self.max_horizontal = self.horizontal;
        }
        self.record_history(truth);
    }

    /// The readings due at the epoch just reached (true state `state`, the step's ideal
    /// IMU sample `ideal`): the DVL's, unless its bottom lock is lost (a missed
    /// update: its noise is drawn all the same, so the stream stays aligned), then the
    /// depth and each fix source's.
    fn sense(&mut self, scenario: &Scenario, ideal: &[f64; 6], state: &NavState) {
        self.readings.clear();
        let dvl = &scenario.sensors.dvl;
        let due = self
            .dvl_every
            .is_some_and(|every| self.k.is_multiple_of(every))
            && dvl.available(scenario.truth.time[self.k]);
        if due {
            let gyro = Vector3::new(ideal[3], ideal[4], ideal[5]);
            let z = self.sim.dvl(dvl, state, &gyro);
            if self.sim.dvl_locked(dvl) {
                let cfg = self.pass.ekf.config();
                self.readings.push(Reading::Velocity(Velocity {
                    z,
                    variance: cfg.dvl_variance,
                    lever_arm: cfg.lever_arm,
                    frame: cfg.aiding,
                    gate: cfg.innovation_gate,
                }));
            } else {
                let calibrated =
                    (self.pass.ekf.calibration.as_ref()).is_some_and(|c| c.calibrates());
                self.updates.missed(calibrated);
                if let Some(log) = self.smoother.as_mut() {
                    log.update_epochs.push(None);
                }
            }
        }
        if let Some(sim) = self.aiding.as_mut() {
            sim.readings(scenario.sensors.aiding(), self.k, state, &mut self.readings);
        }
    }

    /// Write the last `window` raw IMU samples channel-major, oldest first, into `out`
    /// (6·window values); nothing for a run made without a window.
    pub(crate) fn write_window(&self, out: &mut [f32]) {
        if let Some(w) = self.window.as_ref() {
            w.write_channels(out);
        }
    }

    /// Steps taken so far.
    pub fn steps(&self) -> usize {
        self.k
    }

    pub fn strategy_mut(&mut self) -> &mut dyn NoiseStrategy {
        self.strategy.as_mut()
    }

    /// Keep what the RTS smoother needs from now on (call before the first step): the
    /// run's record then holds the smoothed metrics too ([`RunRecord::smoothed`]). It
    /// keeps the forward solution at every IMU epoch (120 bytes each; the raw sample
    /// and the bias estimates too, 96 bytes, without a covariance step), the covariance
    /// after each node's updates (and at every sample, with 15 states, the one before
    /// them: 1.8 kB each), the bias estimates and true bias where the whole
    /// smoothed solution is read, and under a covariance step each close the filter
    /// makes (2.0 kB per step): the backward pass reads them instead of rebuilding
    /// them, ~20 % of its work.
    pub fn keep_for_smoother(&mut self, scenario: &Scenario) {
        let cfg = self.pass.ekf.config();
        let mut log = SmootherLog::new(cfg, &scenario.truth, self.dvl_every);
        let recorded = self.record_every > 0;
        log.push(self.k, &self.pass.ekf, self.true_bias, recorded);
        self.smoother = Some(Box::new(log));
    }

    /// The run's log for the smoother, taken and completed at its last epoch (the last
    /// node), or None (not kept, or the filter failed). The run has brought its
    /// covariance up to date ([`Run::finish`]).
    fn finished_log(&mut self) -> Option<Box<SmootherLog>> {
        let mut log = self.smoother.take()?;
        if self.failure.is_some() {
            return None;
        }
        log.forward.finish(self.k, &self.pass.ekf);
        Some(log)
    }

    /// The smoothed metrics of a run kept for the smoother, or None (not kept, or the
    /// filter failed).
    fn smoothed_record(&mut self, scenario: &Scenario) -> Option<SmoothedRecord> {
        let log = self.finished_log()?;
        let history = self.history.as_ref().map_or(&[][..], |h| &h.sigma[..]);
        let cfg = self.pass.ekf.config();
        Some(log.smoothed_record(&scenario.truth, cfg, (history, self.record_every)))
    }

    /// The run's record (the DVL calibration judged against the scenario's DVL).
    pub fn finish(mut self, scenario: &Scenario) -> RunRecord {
        match self.smoother.as_deref_mut() {
            Some(log) => self.pass.close(self.k, &mut log.forward),
            None => self.pass.close(self.k, &mut ()),
        }
        let smoothed = self.smoothed_record(scenario);
        let mounting = &scenario.sensors.dvl.mounting;
        let n = self.k.max(1) as f64;
        let failed = self.failure.is_some();
        let nan_if_failed = |x: f64| if failed { f64::NAN } else { x };
        let u = &self.updates;
        let aiding = &u.aiding;
        RunRecord {
            summary: RunSummary {
                srmse: nan_if_failed((self.sum_sq / n).sqrt()),
                smae: nan_if_failed(self.sum_abs / n),
                final_horizontal_error: nan_if_failed(self.horizontal[0].hypot(self.horizontal[1])),
                max_horizontal_error: nan_if_failed(
                    self.max_horizontal[0].hypot(self.max_horizontal[1]),
                ),
                mean_nis: nan_if_failed(u.mean_nis()),
                rejected_updates: u.rejected,
                missed_updates: u.missed,
                depth_updates: aiding.depth_updates,
                fix_updates: aiding.fix_updates,
                aiding_nis: nan_if_failed(aiding.nis_sum),
                aiding_dof: aiding.dof,
                diverged_at: u.nis_monitor.diverged_at,
                calibration: calibration_error(self.ekf(), mounting)
                    .filter(|_| !failed)
                    .map(|(error, sigma, _)| CalibrationSummary { error, sigma }),
                failure: self.failure,
            },
            nis: self.updates.nis,
            nees: self.updates.nees,
            calibration_nees: self.updates.calibration_nees,
            history: self.history,
            smoothed,
        }
    }
}
