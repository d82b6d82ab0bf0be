//! Monte Carlo over simulated runs of a scenario, in parallel with rayon, and the
//! lockstep [`Ensemble`] that pauses all runs at tuning instants so that outside code
//! (the ProNet regressor) can set each run's IMU noise variances.
//!
//! Run `i` of a Monte Carlo with seed `s` draws all its randomness from streams keyed
//! by `(s, i)` (see [`crate::sensors`]), so its results are the same whatever the thread
//! count, whichever other runs are in the batch, and whatever the strategy: every
//! strategy sees the same noise (common random numbers).

use crate::attitude::{exp_so3, log_so3};
use crate::earth;
use crate::ekf::{
    Ekf, FilterConfig, Matrix15, NisMonitor, UpdateInfo, ACC_BIAS, ATT, GYRO_BIAS, POS, VEL,
};
use crate::error::{Error, Result};
use crate::mechanization::{ImuSample, NavState};
use crate::noise::{NoiseStrategy, StrategySpec};
use crate::sensors::{normal, stream_rng, SensorConfig, SensorSim, Stream};
use crate::trajectory::Truth;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::sync::Arc;

/// A simulated scenario: a truth with its ideal IMU, and the sensor models.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Shared, so that many scenarios (strategies, sweeps) over one trajectory do not
    /// copy it.
    pub truth: Arc<Truth>,
    pub sensors: SensorConfig,
    /// Start each run from the truth plus an error drawn from N(0, P0) (true), or
    /// exactly at the truth (false).
    pub sample_initial_error: bool,
}

impl Scenario {
    /// IMU steps per DVL period, checking that the period is a whole number of steps.
    pub fn dvl_every(&self) -> Result<usize> {
        self.sensors.validate()?;
        if self.truth.is_empty() {
            return Err(Error::invalid("trajectory", "has no IMU samples"));
        }
        let ratio = self.sensors.dvl.period / self.truth.dt;
        let steps = ratio.round();
        if steps < 1.0 || (ratio - steps).abs() > 1e-6 * ratio {
            return Err(Error::invalid(
                "dvl_period",
                format!(
                    "must be a whole multiple of the IMU period {} s, got {} s",
                    self.truth.dt, self.sensors.dvl.period
                ),
            ));
        }
        Ok(steps as usize)
    }
}

/// One past the largest run index: run i's random streams are numbered 4·i + k.
pub const MAX_RUN_INDEX: u64 = 1 << 62;

/// Monte Carlo size and recording options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct McOptions {
    pub n_runs: usize,
    pub seed: u64,
    /// Record the error and 1σ history every this many IMU steps (0: no history).
    pub record_every: usize,
    /// Index of the first run: the runs are `first_run .. first_run + n_runs`, each on
    /// the random streams of `(seed, index)`, so shards of a Monte Carlo computed apart
    /// are bit-identical to the same runs computed whole.
    pub first_run: u64,
}

impl McOptions {
    pub fn validate(&self) -> Result<()> {
        if self.n_runs == 0 {
            return Err(Error::invalid("n_runs", "must be at least 1"));
        }
        // Run i's random streams are numbered 4·i + k (sensors::stream_rng): indices
        // beyond 2^62 would wrap onto other runs' noise.
        let last = self.first_run.checked_add(self.n_runs as u64);
        if last.is_none_or(|last| last > MAX_RUN_INDEX) {
            return Err(Error::invalid(
                "first_run",
                format!(
                    "first_run + n_runs must be at most 2^62, got {} + {}",
                    self.first_run, self.n_runs
                ),
            ));
        }
        Ok(())
    }
}

/// Per-run scalar metrics. Velocity errors are taken at every IMU epoch.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// `sqrt(mean_k Σ_{N,E,D} δv²)` [m/s].
    pub srmse: f64,
    /// `mean_k Σ_{N,E,D} |δv|` [m/s].
    pub smae: f64,
    /// Horizontal position error at the end [m].
    pub final_horizontal_error: f64,
    /// Largest horizontal position error over the run [m].
    pub max_horizontal_error: f64,
    /// Mean NIS over the applied DVL updates.
    pub mean_nis: f64,
    /// DVL updates the innovation gate rejected.
    pub rejected_updates: usize,
    /// Time [s] at which the NIS showed divergence (see [`NisMonitor`]), if it did.
    pub diverged_at: Option<f64>,
    /// Set when the filter failed numerically; the run's metrics are then NaN.
    pub failure: Option<String>,
}

/// Recorded histories of one run, at `record_time` epochs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// True estimation error `[δp, δv, ψ, δb_a, δb_g]` (estimate minus truth).
    pub error: Vec<[f64; 15]>,
    /// Filter 1σ of the same states.
    pub sigma: Vec<[f64; 15]>,
    /// IMU variances q the strategy used (NaN where it has none, e.g. Mehra).
    pub imu_variance: Vec<[f64; 6]>,
}

/// Everything one run reports.
#[derive(Clone, Debug, PartialEq)]
pub struct RunRecord {
    pub summary: RunSummary,
    /// NIS at each DVL epoch (gate-rejected updates included).
    pub nis: Vec<f64>,
    /// NEES of the position, velocity, attitude, accelerometer-bias and gyro-bias
    /// blocks after each DVL update (3 dof each).
    pub nees: Vec<[f64; 5]>,
    pub history: Option<History>,
}

/// All runs of a Monte Carlo, in run order.
#[derive(Clone, Debug, PartialEq)]
pub struct McResult {
    pub runs: Vec<RunRecord>,
    /// Times of the DVL epochs [s].
    pub dvl_time: Vec<f64>,
    /// Times of the recorded history epochs [s] (empty without history).
    pub record_time: Vec<f64>,
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
    ekf: Ekf,
    strategy: Box<dyn NoiseStrategy>,
    sim: SensorSim,
    dvl_every: usize,
    record_every: usize,
    k: usize,
    steps_since_update: usize,
    true_bias: [f64; 6],
    sum_sq: f64,
    sum_abs: f64,
    horizontal_error: f64,
    max_horizontal_error: f64,
    nis: Vec<f64>,
    rejected_updates: usize,
    accepted_nis_sum: f64,
    nis_monitor: NisMonitor,
    nees: Vec<[f64; 5]>,
    history: Option<History>,
    window: Option<ImuWindow>,
    failure: Option<String>,
}

/// Estimate-minus-truth error of the full state.
fn state_error(ekf: &Ekf, truth: &NavState, true_bias: &[f64; 6]) -> [f64; 15] {
    let dp = earth::position_error_ned(&ekf.nav.lla, &truth.lla);
    let dv = ekf.nav.vel - truth.vel;
    // Ĉ = (I − [ψ×]) C ≈ Exp(−ψ) C.
    let psi = -log_so3(&(ekf.nav.dcm * truth.dcm.transpose()));
    let ba = ekf.accel_bias - Vector3::new(true_bias[0], true_bias[1], true_bias[2]);
    let bg = ekf.gyro_bias - Vector3::new(true_bias[3], true_bias[4], true_bias[5]);
    let mut e = [0.0; 15];
    for (offset, v) in [
        (POS, dp),
        (VEL, dv),
        (ATT, psi),
        (ACC_BIAS, ba),
        (GYRO_BIAS, bg),
    ] {
        e[offset..offset + 3].copy_from_slice(v.as_slice());
    }
    e
}

/// NEES of each 3-block: `e_bᵀ P_bb⁻¹ e_b` (NaN where the block is singular).
fn block_nees(error: &[f64; 15], p: &Matrix15) -> [f64; 5] {
    [POS, VEL, ATT, ACC_BIAS, GYRO_BIAS].map(|b| {
        let e = Vector3::new(error[b], error[b + 1], error[b + 2]);
        match p.fixed_view::<3, 3>(b, b).into_owned().cholesky() {
            Some(ch) => e.dot(&ch.solve(&e)),
            None => f64::NAN,
        }
    })
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
        let truth0 = scenario.truth.states[0];
        let true_bias = scenario.sensors.imu.bias;
        let mut nav = truth0;
        let mut bias = true_bias;
        if scenario.sample_initial_error {
            let mut rng = stream_rng(seed, run_index, Stream::InitialError);
            let dx: [f64; 15] = std::array::from_fn(|i| filter.p0_sigma[i] * normal(&mut rng));
            let block = |i: usize| Vector3::new(dx[i], dx[i + 1], dx[i + 2]);
            nav.lla += earth::ned_delta_to_lla_delta(&nav.lla, &block(POS));
            nav.vel += block(VEL);
            nav.dcm = exp_so3(&(-block(ATT))) * nav.dcm;
            for i in 0..6 {
                bias[i] += dx[ACC_BIAS + i];
            }
        }
        let ekf = Ekf::new(
            filter,
            nav,
            Vector3::new(bias[0], bias[1], bias[2]),
            Vector3::new(bias[3], bias[4], bias[5]),
        )?;
        let n_epochs = scenario.truth.len() / dvl_every;
        let mut run = Self {
            sim: SensorSim::new(&scenario.sensors, seed, run_index),
            ekf,
            strategy: strategy.build(filter.bias_psd()),
            dvl_every,
            record_every,
            k: 0,
            steps_since_update: 0,
            true_bias,
            sum_sq: 0.0,
            sum_abs: 0.0,
            horizontal_error: 0.0,
            max_horizontal_error: 0.0,
            nis: Vec::with_capacity(n_epochs),
            rejected_updates: 0,
            accepted_nis_sum: 0.0,
            nis_monitor: NisMonitor::default(),
            nees: Vec::with_capacity(n_epochs),
            history: (record_every > 0).then(History::default),
            window: window.map(ImuWindow::new),
            failure: None,
        };
        run.record_history(&scenario.truth);
        Ok(run)
    }

    fn record_history(&mut self, truth: &Truth) {
        if let Some(h) = self.history.as_mut() {
            if self.k.is_multiple_of(self.record_every) {
                let truth = &truth.states[self.k];
                h.error.push(state_error(&self.ekf, truth, &self.true_bias));
                h.sigma.push(self.ekf.sigma());
                h.imu_variance
                    .push(self.strategy.imu_variance().unwrap_or([f64::NAN; 6]));
            }
        }
    }

    /// Advance by one IMU sample (and a DVL update when one is due).
    pub fn step(&mut self, scenario: &Scenario) {
        let truth = &*scenario.truth;
        let ideal = &truth.imu[self.k];
        self.true_bias = *self.sim.bias();
        let raw = self
            .sim
            .imu(&scenario.sensors.imu, ideal, truth.time[self.k], truth.dt);
        if let Some(w) = self.window.as_mut() {
            w.push(&raw);
        }
        self.k += 1;
        self.steps_since_update += 1;
        let state = &truth.states[self.k];
        if self.failure.is_none() {
            let z = self.k.is_multiple_of(self.dvl_every).then(|| {
                let gyro = Vector3::new(ideal[3], ideal[4], ideal[5]);
                self.sim.dvl(&scenario.sensors.dvl, state, &gyro)
            });
            match self.ekf.step(
                &ImuSample::from_array(&raw),
                truth.dt,
                self.strategy.as_mut(),
                z.as_ref(),
                self.steps_since_update,
            ) {
                Ok(Some(info)) => self.after_update(&info, state, truth.time[self.k]),
                Ok(None) => {}
                Err(e) => self.failure = Some(format!("t = {} s: {e}", truth.time[self.k])),
            }
        }
        let dv = self.ekf.nav.vel - state.vel;
        self.sum_sq += dv.norm_squared();
        self.sum_abs += dv.abs().sum();
        let dp = earth::position_error_ned(&self.ekf.nav.lla, &state.lla);
        self.horizontal_error = dp[0].hypot(dp[1]);
        self.max_horizontal_error = self.max_horizontal_error.max(self.horizontal_error);
        self.record_history(truth);
    }

    fn after_update(&mut self, info: &UpdateInfo, state: &NavState, t: f64) {
        self.nis_monitor.push(info.nis, t);
        if info.accepted {
            self.steps_since_update = 0;
            self.accepted_nis_sum += info.nis;
        } else {
            self.rejected_updates += 1;
        }
        // Every epoch is recorded, applied or not, so that the histories stay aligned.
        self.nis.push(info.nis);
        let e = state_error(&self.ekf, state, &self.true_bias);
        self.nees.push(block_nees(&e, &self.ekf.p));
    }

    /// Steps taken so far.
    pub fn steps(&self) -> usize {
        self.k
    }

    pub fn strategy_mut(&mut self) -> &mut dyn NoiseStrategy {
        self.strategy.as_mut()
    }

    pub fn finish(self) -> RunRecord {
        let n = self.k.max(1) as f64;
        let failed = self.failure.is_some();
        let nan_if_failed = |x: f64| if failed { f64::NAN } else { x };
        let accepted = self.nis.len() - self.rejected_updates;
        // Every update rejected by the gate: no NIS to average (0 would look healthy).
        let mean_nis = if accepted == 0 && self.rejected_updates > 0 {
            f64::NAN
        } else {
            self.accepted_nis_sum / accepted.max(1) as f64
        };
        RunRecord {
            summary: RunSummary {
                srmse: nan_if_failed((self.sum_sq / n).sqrt()),
                smae: nan_if_failed(self.sum_abs / n),
                final_horizontal_error: nan_if_failed(self.horizontal_error),
                max_horizontal_error: nan_if_failed(self.max_horizontal_error),
                mean_nis: nan_if_failed(mean_nis),
                rejected_updates: self.rejected_updates,
                diverged_at: self.nis_monitor.diverged_at,
                failure: self.failure,
            },
            nis: self.nis,
            nees: self.nees,
            history: self.history,
        }
    }
}

fn epoch_times(truth: &Truth, every: usize, include_start: bool) -> Vec<f64> {
    let start = if include_start { 0 } else { every };
    (start..=truth.len())
        .step_by(every)
        .map(|k| truth.time[k])
        .collect()
}

fn check_strategy(filter: &FilterConfig, strategy: &StrategySpec, opts: &McOptions) -> Result<()> {
    filter.validate()?;
    strategy.validate()?;
    opts.validate()
}

/// Run `opts.n_runs` runs of `scenario` with one strategy, in parallel on the current
/// rayon pool. Run i uses the random streams of `(opts.seed, i)`.
pub fn run_monte_carlo(
    scenario: &Arc<Scenario>,
    filter: &FilterConfig,
    strategy: &StrategySpec,
    opts: &McOptions,
) -> Result<McResult> {
    check_strategy(filter, strategy, opts)?;
    let dvl_every = scenario.dvl_every()?;
    let n_steps = scenario.truth.len();
    let runs = (0..opts.n_runs)
        .into_par_iter()
        .map(|i| {
            let mut run = Run::new(
                scenario,
                filter,
                strategy,
                opts.seed,
                opts.first_run + i as u64,
                opts.record_every,
                None,
            )?;
            for _ in 0..n_steps {
                run.step(scenario);
            }
            Ok(run.finish())
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(McResult {
        runs,
        dvl_time: epoch_times(&scenario.truth, dvl_every, false),
        record_time: if opts.record_every > 0 {
            epoch_times(&scenario.truth, opts.record_every, true)
        } else {
            Vec::new()
        },
    })
}

/// The most worker threads a pool may have: far above any core count this runs on, and
/// low enough that a mistyped count fails at once instead of spawning for minutes.
pub const MAX_THREADS: usize = 1024;

/// Run `f` on a rayon pool of `threads` threads, or on the global pool for `None`.
pub fn with_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(Error::invalid("threads", "must be at least 1")),
        Some(n) if n > MAX_THREADS => Err(Error::invalid(
            "threads",
            format!("must be at most {MAX_THREADS}, got {n}"),
        )),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(|pool| pool.install(f))
            .map_err(|e| Error::invalid("threads", format!("cannot start {n} threads: {e}"))),
    }
}

/// All runs of a Monte Carlo stepped in lockstep, pausing at tuning instants so that
/// the caller can read each run's last `window` raw IMU samples and set its IMU noise
/// variances (external strategy).
pub struct Ensemble {
    scenario: Arc<Scenario>,
    runs: Vec<Run>,
    k: usize,
    window: usize,
    tuning_every: usize,
    dvl_every: usize,
    record_every: usize,
}

impl Ensemble {
    /// `tuning_every`: IMU steps between tuning instants; `window`: samples handed out.
    /// The first tuning instant is the first multiple of `tuning_every` at which
    /// `window` samples exist; until then every run uses `prior_q`.
    pub fn new(
        scenario: Arc<Scenario>,
        filter: &FilterConfig,
        prior_q: [f64; 6],
        opts: &McOptions,
        window: usize,
        tuning_every: usize,
    ) -> Result<Self> {
        let strategy = StrategySpec::External { prior_q };
        check_strategy(filter, &strategy, opts)?;
        if window == 0 || window > scenario.truth.len() {
            return Err(Error::invalid(
                "window",
                format!(
                    "must be 1 to {} samples (the trajectory's length), got {window}",
                    scenario.truth.len()
                ),
            ));
        }
        if tuning_every == 0 {
            return Err(Error::invalid(
                "tuning_period",
                "must be at least one IMU step",
            ));
        }
        let dvl_every = scenario.dvl_every()?;
        let runs = (0..opts.n_runs)
            .map(|i| {
                Run::new(
                    &scenario,
                    filter,
                    &strategy,
                    opts.seed,
                    opts.first_run + i as u64,
                    opts.record_every,
                    Some(window),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            scenario,
            runs,
            k: 0,
            window,
            tuning_every,
            dvl_every,
            record_every: opts.record_every,
        })
    }

    pub fn n_runs(&self) -> usize {
        self.runs.len()
    }

    pub fn window(&self) -> usize {
        self.window
    }

    /// IMU steps taken so far (the same for every run).
    pub fn steps(&self) -> usize {
        self.k
    }

    /// Time of the current epoch [s].
    pub fn time(&self) -> f64 {
        self.scenario.truth.time[self.k]
    }

    pub fn is_done(&self) -> bool {
        self.k >= self.scenario.truth.len()
    }

    fn next_stop(&self) -> usize {
        let n = self.scenario.truth.len();
        let mut t = (self.k / self.tuning_every + 1) * self.tuning_every;
        if t < self.window {
            t = self.window.div_ceil(self.tuning_every) * self.tuning_every;
        }
        t.min(n)
    }

    /// Step every run (in parallel) to the next tuning instant. Returns the windows as
    /// a flat `(n_runs, 6, window)` float32 buffer, oldest sample first, or `None` once
    /// the end of the trajectory is reached.
    pub fn advance(&mut self) -> Option<Vec<f32>> {
        if self.is_done() {
            return None;
        }
        let stop = self.next_stop();
        let steps = stop - self.k;
        let scenario = &*self.scenario;
        self.runs.par_iter_mut().for_each(|r| {
            for _ in 0..steps {
                r.step(scenario);
            }
        });
        self.k = stop;
        if self.is_done() {
            return None;
        }
        let per_run = 6 * self.window;
        let mut out = vec![0f32; self.runs.len() * per_run];
        out.par_chunks_mut(per_run)
            .zip(self.runs.par_iter())
            .for_each(|(chunk, run)| {
                if let Some(w) = run.window.as_ref() {
                    w.write_channels(chunk);
                }
            });
        Some(out)
    }

    /// Set each run's IMU noise variances q (one row of 6 per run).
    pub fn set_q(&mut self, q: &[[f64; 6]]) -> Result<()> {
        if q.len() != self.runs.len() {
            return Err(Error::invalid(
                "q",
                format!(
                    "needs one row per run: {} rows for {} runs",
                    q.len(),
                    self.runs.len()
                ),
            ));
        }
        for (i, row) in q.iter().enumerate() {
            if row.iter().any(|v| !v.is_finite() || *v < 0.0) {
                return Err(Error::invalid(
                    "q",
                    format!("row {i} must be finite and >= 0, got {row:?}"),
                ));
            }
        }
        for (run, row) in self.runs.iter_mut().zip(q) {
            run.strategy_mut().set_imu_variance(row)?;
        }
        Ok(())
    }

    /// Run to the end (if not there yet) and collect the results.
    pub fn finish(mut self) -> McResult {
        while self.advance().is_some() {}
        let truth = &self.scenario.truth;
        McResult {
            dvl_time: epoch_times(truth, self.dvl_every, false),
            record_time: if self.record_every > 0 {
                epoch_times(truth, self.record_every, true)
            } else {
                Vec::new()
            },
            runs: self.runs.into_iter().map(Run::finish).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::VarianceSchedule;
    use crate::trajectory::{builtin, Segment, TrajectorySpec};

    const TRUE_Q: [f64; 6] = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];

    fn short_scenario(seconds: f64) -> Arc<Scenario> {
        let mut spec = builtin("paper", 0.01).unwrap();
        let mut left = seconds;
        spec.segments.retain_mut(|s| {
            if left <= 0.0 {
                return false;
            }
            s.duration = s.duration.min(left);
            left -= s.duration;
            true
        });
        Arc::new(Scenario {
            truth: Arc::new(spec.generate().unwrap()),
            sensors: SensorConfig::paper(),
            sample_initial_error: true,
        })
    }

    fn tuned_filter() -> FilterConfig {
        FilterConfig {
            accel_bias_psd: 1e-10,
            gyro_bias_psd: 1e-14,
            ..FilterConfig::default()
        }
    }

    #[test]
    fn results_do_not_depend_on_thread_count() {
        let sc = short_scenario(30.0);
        let opts = McOptions {
            n_runs: 6,
            seed: 42,
            record_every: 50,
            first_run: 0,
        };
        let strat = StrategySpec::Mehra {
            window: 3,
            prior_q: TRUE_Q,
        };
        let one = with_threads(Some(1), || {
            run_monte_carlo(&sc, &tuned_filter(), &strat, &opts)
        })
        .unwrap()
        .unwrap();
        let two = with_threads(Some(2), || {
            run_monte_carlo(&sc, &tuned_filter(), &strat, &opts)
        })
        .unwrap()
        .unwrap();
        // Debug output prints every f64 exactly (shortest round trip) and NaN as NaN, so
        // equal text means bit-identical numbers.
        assert_eq!(format!("{one:?}"), format!("{two:?}"));
        // A run's numbers do not depend on the batch it is in.
        let three = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &strat,
            &McOptions { n_runs: 3, ..opts },
        )
        .unwrap();
        assert_eq!(format!("{:?}", three.runs), format!("{:?}", &one.runs[..3]));
        // Run indices stop short of wrapping onto other runs' random streams.
        for (first_run, n_runs) in [(MAX_RUN_INDEX, 1), (u64::MAX, 2), (MAX_RUN_INDEX - 1, 2)] {
            let bad = McOptions {
                n_runs,
                first_run,
                ..opts
            };
            assert!(bad.validate().is_err(), "{first_run} + {n_runs} accepted");
        }
        assert!(McOptions {
            n_runs: 1,
            first_run: MAX_RUN_INDEX - 1,
            ..opts
        }
        .validate()
        .is_ok());
        // Nor on the shard: runs 3..6 computed apart are runs 3..6 of the whole.
        let last_three = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &strat,
            &McOptions {
                n_runs: 3,
                first_run: 3,
                ..opts
            },
        )
        .unwrap();
        assert_eq!(
            format!("{:?}", last_three.runs),
            format!("{:?}", &one.runs[3..])
        );
        assert_eq!(one.dvl_time.len(), 30);
        assert_eq!(one.record_time.len(), 61);
    }

    #[test]
    fn dvl_aiding_bounds_the_velocity_error() {
        let sc = short_scenario(60.0);
        let opts = McOptions {
            n_runs: 4,
            seed: 1,
            record_every: 0,
            first_run: 0,
        };
        let res = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap();
        for r in &res.runs {
            assert!(r.summary.failure.is_none());
            assert!(r.summary.srmse < 0.1, "srmse {}", r.summary.srmse);
            assert_eq!(r.nis.len(), 60);
        }
        // Without DVL (a period longer than the run) the same filter drifts far more.
        let mut free = (*sc).clone();
        free.sensors.dvl.period = 100.0;
        let free = run_monte_carlo(
            &Arc::new(free),
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap();
        let aided: f64 = res
            .runs
            .iter()
            .map(|r| r.summary.final_horizontal_error)
            .sum();
        let unaided: f64 = free
            .runs
            .iter()
            .map(|r| r.summary.final_horizontal_error)
            .sum();
        assert!(unaided > aided, "aided {aided} unaided {unaided}");
    }

    #[test]
    fn ensemble_without_outside_tuning_equals_the_monte_carlo_with_the_prior() {
        let sc = short_scenario(20.0);
        let opts = McOptions {
            n_runs: 3,
            seed: 9,
            record_every: 100,
            first_run: 0,
        };
        let mc = run_monte_carlo(
            &sc,
            &tuned_filter(),
            &StrategySpec::External { prior_q: TRUE_Q },
            &opts,
        )
        .unwrap();
        let mut ens =
            Ensemble::new(Arc::clone(&sc), &tuned_filter(), TRUE_Q, &opts, 200, 100).unwrap();
        let mut stops = Vec::new();
        while let Some(w) = ens.advance() {
            assert_eq!(w.len(), 3 * 6 * 200);
            stops.push(ens.steps());
        }
        assert_eq!(stops.first(), Some(&200));
        assert_eq!(stops.last(), Some(&1900));
        assert_eq!(format!("{:?}", ens.finish()), format!("{mc:?}"));
    }

    #[test]
    fn ensemble_windows_hold_the_raw_samples_oldest_first() {
        let sc = short_scenario(5.0);
        let opts = McOptions {
            n_runs: 2,
            seed: 3,
            record_every: 0,
            first_run: 0,
        };
        let mut ens =
            Ensemble::new(Arc::clone(&sc), &tuned_filter(), TRUE_Q, &opts, 50, 50).unwrap();
        let w = ens.advance().unwrap();
        // Regenerate run 1's first 50 raw samples from its stream.
        let mut sim = SensorSim::new(&sc.sensors, 3, 1);
        let raw: Vec<[f64; 6]> = (0..50)
            .map(|k| {
                sim.imu(
                    &sc.sensors.imu,
                    &sc.truth.imu[k],
                    sc.truth.time[k],
                    sc.truth.dt,
                )
            })
            .collect();
        for c in 0..6 {
            for j in 0..50 {
                assert_eq!(w[300 + c * 50 + j], raw[j][c] as f32);
            }
        }
        // Setting q changes what the filter uses from then on.
        ens.set_q(&[[1e-2; 6], [1e-2; 6]]).unwrap();
        assert!(ens.set_q(&[[1e-2; 6]]).is_err());
        assert!(ens.set_q(&[[f64::NAN; 6], [1.0; 6]]).is_err());
    }

    #[test]
    fn varying_noise_and_bias_are_simulated() {
        let spec = TrajectorySpec {
            name: "still".into(),
            lla0: crate::trajectory::paper_origin(),
            speed0: 0.0,
            rpy0: Vector3::zeros(),
            segments: vec![Segment::new(10.0, 0.0, 0.0, 0.0)],
            dt: 0.01,
        };
        let mut sensors = SensorConfig::paper();
        sensors.imu.variance =
            VarianceSchedule::new(vec![0.0, 5.0], vec![[1e-4; 6], [4e-2; 6]]).unwrap();
        let sc = Arc::new(Scenario {
            truth: Arc::new(spec.generate().unwrap()),
            sensors,
            sample_initial_error: false,
        });
        let opts = McOptions {
            n_runs: 1,
            seed: 0,
            record_every: 0,
            first_run: 0,
        };
        let mut ens = Ensemble::new(sc, &tuned_filter(), TRUE_Q, &opts, 400, 100).unwrap();
        let mut variances = Vec::new();
        while let Some(w) = ens.advance() {
            // Variance of the x-accelerometer window about its mean.
            let x = &w[..400];
            let m = x.iter().map(|v| *v as f64).sum::<f64>() / 400.0;
            variances.push((
                ens.time(),
                x.iter().map(|v| (*v as f64 - m).powi(2)).sum::<f64>() / 399.0,
            ));
        }
        let (early, late) = (variances[0].1, variances.last().unwrap().1);
        assert!(early < 3e-4 && late > 2e-2, "{variances:?}");
    }

    #[test]
    fn bad_dvl_period_is_rejected() {
        let mut sc = (*short_scenario(5.0)).clone();
        sc.sensors.dvl.period = 0.015;
        let opts = McOptions {
            n_runs: 1,
            seed: 0,
            record_every: 0,
            first_run: 0,
        };
        let err = run_monte_carlo(
            &Arc::new(sc),
            &tuned_filter(),
            &StrategySpec::Constant { q: TRUE_Q },
            &opts,
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("dvl_period"), "{err}");
    }
}
